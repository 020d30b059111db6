//! The seam between the transports (HTTP, MQTT) and the ingest pipeline.
//!
//! A transport hands each received payload of measurement records to a [`MeasurementSink`] and
//! acknowledges to its client (HTTP 2xx, MQTT PUBACK) only after the sink's future resolves
//! with `Ok`: by then the records are stored durably and queued for the tracker. Outgoing
//! messages (tracks, events) reach the transports as [`Publication`]s on a bounded
//! `tokio::sync::broadcast` channel.

use std::future::Future;
use std::pin::Pin;

/// Why a payload was not accepted.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IngestError {
    /// The payload is malformed or names something unknown; the message names the line and the
    /// field. Resending the same payload fails again (HTTP 400/422; MQTT: acknowledged and
    /// reported on the error topic so the reader does not resend it for ever).
    #[error("{0}")]
    Invalid(String),
    /// The writer lacks the write token (HTTP 401/403; MQTT: connection refused).
    #[error("{0}")]
    Unauthorized(String),
    /// The server cannot take the payload now (storage failure, back-pressure, shutting down);
    /// resending later may succeed (HTTP 503; MQTT: no PUBACK, the connection is closed).
    #[error("{0}")]
    Unavailable(String),
}

/// The future a sink returns: the number of records stored.
pub type IngestFuture = Pin<Box<dyn Future<Output = Result<usize, IngestError>> + Send>>;

/// Where payloads of measurement records go.
pub trait MeasurementSink: Send + Sync + 'static {
    /// Parses `payload` (JSON lines of the measurement record format, `docs/FORMATS.md`),
    /// stores every record durably and queues it for tracking. `source` names the sender for
    /// logs and error messages (e.g. `mqtt:rtls/v1/measurements/reader-7`, `http`).
    ///
    /// # Errors
    /// [`IngestError::Invalid`] when a line does not parse (nothing of the payload is stored),
    /// [`IngestError::Unavailable`] when it could not be stored.
    fn ingest(&self, source: &str, payload: bytes::Bytes) -> IngestFuture;
}

/// One outgoing message: a topic (MQTT topic name) and its payload (JSON).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Publication {
    /// The MQTT topic, e.g. `rtls/v1/tracks/{tag}` or `rtls/v1/events/{type}`.
    pub topic: String,
    /// The JSON payload.
    pub payload: bytes::Bytes,
}
