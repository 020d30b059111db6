//! The service layer of rtls: `rtls serve`, the control-room server (docs/SERVER.md).
//!
//! - [`pipeline`] — the manager layer behind ingest: the ingest log (durable before any
//!   acknowledgement, group commit), tag partitions on worker threads each with a tracker, the
//!   output thread (history, events, restart checkpoint), bounded queues throughout.
//! - [`mqtt`] — the embedded MQTT 3.1.1 broker (PUBACK only after commit) and the bridge to an
//!   external broker; [`http`] — the omlox hub API under `/v2`, the WebSocket, `/api/v1`
//!   (ingest, history with CSV/GeoJSON, events, head counts) and `/health`, `/metrics`,
//!   `/openapi.json`.
//! - [`store`] — SQLite (default, WAL) and PostgreSQL with schema migrations and retention.
//! - [`omlox`] and [`convert`] — the omlox hub API 2.0.0 data model and the engine's outputs in
//!   its terms; [`auth`] — write and read tokens; [`config`] — the configuration file;
//!   [`serve`] — starting and stopping it all; [`feed`] — a live feed of records from any
//!   [`feed::RecordSource`] (the binary's `--demo` mine) through the ingest path;
//!   [`webhooks`] — alarms POSTed to HTTP(S) endpoints (signed, retried, in order);
//!   [`udp`] — best-effort UDP ingest of measurement lines or vendor messages;
//!   [`adapters`] — vendor engines' own messages as fixes; [`zebra_hub`] — a Zebra Dart
//!   hub's output read over TCP, reconnecting;
//!   [`nats_forward`] — positions and events published to NATS; [`log_limit`] — warnings
//!   that may repeat, logged at most every 10 s.
//!
//! ## Layer
//! It owns the service (ingest, pipeline, APIs, storage, auth, live feeds) and may import
//! `rtls-engine` only among the rtls crates: it does not depend on the simulator (`rtls serve
//! --demo`'s mine is composed in the binary and handed over as a [`feed::RecordSource`]), the
//! datasets or the paper experiments.
//!
//! # References
//! - omlox™ hub API 2.0.0, OpenAPI 3.0.2 description (PROFIBUS & PROFINET International).
//! - OASIS MQTT 3.1.1 (2014).

pub mod adapters;
pub mod auth;
pub mod cluster;
pub mod config;
pub mod convert;
mod error;
pub mod feed;
pub mod http;
pub mod limits;
pub mod log_limit;
pub mod metrics;
pub mod mqtt;
pub mod nats_forward;
pub mod omlox;
pub mod pipeline;
pub mod pushed;
pub mod serve;
pub mod sink;
pub mod store;
pub mod tls;
pub mod udp;
pub mod webhooks;
pub mod zebra_hub;

pub use error::{Result, ServerError};

#[cfg(test)]
mod tests;
