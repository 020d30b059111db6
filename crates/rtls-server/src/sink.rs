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
    ///
    /// `order` is the sender's (one per MQTT connection): payloads ingested through one
    /// [`IngestOrder`] are queued for tracking in the order of these calls, however their
    /// futures are polled. A connection keeps many payloads in flight, and an MQTT client's
    /// records of one tag arrive in time order; queued out of order, each would make its
    /// track rewind and re-filter.
    fn ingest(&self, source: &str, payload: bytes::Bytes, order: &mut IngestOrder) -> IngestFuture;
}

/// The order of one sender's payloads: each call to [`IngestOrder::next_turn`] gives a
/// [`Turn`] that waits for the previous one's.
///
/// A sink's future does what can run in parallel (parsing, checking) first, then
/// [`Turn::wait`]s, queues its records and lets the next payload go ([`Turn::done`], or
/// by dropping the turn — a payload refused or failed does not hold the others).
///
/// # Example
/// ```
/// # tokio::runtime::Builder::new_current_thread().build().unwrap().block_on(async {
/// use rtls_server::sink::IngestOrder;
/// let mut order = IngestOrder::default();
/// let (mut first, mut second) = (order.next_turn(), order.next_turn());
/// first.wait().await; // the first has no one to wait for
/// first.done();
/// second.wait().await; // returns once the first is done (or dropped)
/// # });
/// ```
#[derive(Debug, Default)]
pub struct IngestOrder {
    /// Resolves when the latest turn given out is done.
    latest: Option<tokio::sync::oneshot::Receiver<()>>,
}

impl IngestOrder {
    /// The next payload's turn, after every turn given out before.
    pub fn next_turn(&mut self) -> Turn {
        let (done, finished) = tokio::sync::oneshot::channel();
        Turn {
            previous: self.latest.replace(finished),
            done: Some(done),
        }
    }
}

/// One payload's place in its sender's [`IngestOrder`].
#[derive(Debug)]
pub struct Turn {
    previous: Option<tokio::sync::oneshot::Receiver<()>>,
    done: Option<tokio::sync::oneshot::Sender<()>>,
}

impl Turn {
    /// A turn that waits for nobody (a payload whose order does not matter).
    pub fn alone() -> Self {
        Self {
            previous: None,
            done: None,
        }
    }

    /// Waits until the previous payload's turn is done or dropped.
    pub async fn wait(&mut self) {
        if let Some(previous) = self.previous.take() {
            // an error is a dropped turn: the payload before gave up its place
            let _ = previous.await;
        }
    }

    /// Lets the next payload go (dropping the turn does the same).
    pub fn done(&mut self) {
        if let Some(done) = self.done.take() {
            let _ = done.send(());
        }
    }
}

/// One outgoing message: a topic (MQTT topic name) and its payload (JSON).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Publication {
    /// The MQTT topic, e.g. `rtls/v1/tracks/{tag}` or `rtls/v1/events/{type}`.
    pub topic: String,
    /// The JSON payload.
    pub payload: bytes::Bytes,
}
