//! # rtls-engine
//!
//! The manager layer of seed 000's architecture: it turns raw reader measurements into clean,
//! predictive tracks for every tag. Synchronous and deterministic: records in, track updates
//! and events out, no threads, no clocks, no I/O beyond parsing text handed to it.
//!
//! ## What this crate owns and may import
//! It owns the record formats, the site model, the tracker (`rtls_engine::Tracker`, the one
//! tracking loop of the workspace), zones and alarms, association, scheduling, the survey,
//! tuning and evaluation against ground truth. It may import `rtls-estimation` and
//! `rtls-positioning` (the numeric crates) and no crate above it: rtls-sim, rtls-papers,
//! rtls-server and the `rtls` binary import it.
//!
//! ## Vocabulary
//! - [`record`] — the measurement record format (JSON Lines and CSV): a time stamp, a tag id and
//!   one measurement (range, RSSI, TDOA, RSSI vector, position fix, accelerometer, odometry,
//!   velocity), parsed with errors that name the file, line and field.
//! - [`site`] — the site model (TOML): readers/anchors, zones, tracker settings.
//! - [`lifecycle`] — track initiation, M-of-N confirmation, coasting (000's gap filling), lost
//!   and deleted states.
//! - [`tuning`] — fitting a site to a recording: process noise by innovation likelihood, and
//!   with ground truth the readers' range bias / noise and path-loss laws (`rtls tune`).
//! - [`zones`] — zone geometry (2-D polygons with floor or height range, 3-D boxes), and
//!   enter / exit / dwell events with anti-flap tolerance.

pub mod association;
pub mod corridors;
mod error;
pub mod evaluation;
pub mod lifecycle;
pub mod radio_map;
pub mod record;
pub mod scheduling;
pub mod site;
pub mod survey;
pub mod tracker;
pub mod tuning;
pub mod zones;

pub use error::{EngineError, Result};
