//! The service layer of rtls. What exists so far is the data model of the omlox™ hub API 2.0.0
//! that `rtls serve` will speak; the server itself (REST under `/v2`, WebSocket
//! `/v2/ws/socket`, storage) is issue 8.
//!
//! - [`omlox`] — serde types for the objects the hub API serves and accepts (`Location`,
//!   `Trackable`, `LocationProvider`, `Zone`, `Fence`, `FenceEvent`, WebSocket messages) and the
//!   field-level validation of the ingest body (`PUT /v2/providers/locations`).
//! - [`convert`] — the engine's outputs in omlox terms (`TrackUpdate` → `Location`, `ZoneEvent`
//!   → `FenceEvent`, site zones → `Fence`, other events → the `rtls:alarms` / `rtls:events`
//!   extension topics) and ingested `Location`s → engine `Record`s.
//!
//! No async and no I/O here: everything is a pure function of its inputs, testable without a
//! port.
//!
//! # References
//! - omlox™ hub API 2.0.0, OpenAPI 3.0.2 description (PROFIBUS & PROFINET International).

pub mod auth;
pub mod config;
pub mod convert;
mod error;
pub mod http;
pub mod metrics;
pub mod omlox;
pub mod pipeline;
pub mod sink;
pub mod store;

pub use error::{Result, ServerError};

#[cfg(test)]
mod tests;
