//! UDP ingest (`rtls serve --udp-listen ADDR`, `--udp-adapter VENDOR=ADDR`; `[udp]` in the
//! configuration, [`crate::config::UdpSection`]): gateways that push datagrams — Quuppa's "UDP
//! output target", Sewio and generic UWB gateways.
//!
//! ```text
//!  socket ──▶ receiver: one datagram = one payload (≤ 64 KiB)
//!               │ try_send (full: dropped, counted, logged)
//!               ▼
//!      [queue, 1024 datagrams] ──▶ worker: up to 64 at a time through the pipeline's submit
//!                                  functions, in arrival order
//! ```
//!
//! - **Which parser: by port.** A listener reads one format, chosen when it is configured, not
//!   by looking at the bytes: `udp.listen` takes our measurement JSON lines (the body of
//!   `POST /api/v1/measurements`, [`crate::pipeline::Pipeline::submit_lines`]);
//!   `udp.adapters.{vendor}` takes that vendor's messages through its adapter
//!   ([`crate::pipeline::Pipeline::submit_adapter`], as `POST /api/v1/adapters/{vendor}`).
//!   The records take the path of any other payload: checked against the site, stored in the
//!   ingest log, tracked. The source of the stored records is `udp:ADDR` (the bound address)
//!   or `udp:adapters/{vendor}`.
//! - **Best-effort.** UDP has no acknowledgement and no authentication: a datagram lost on the
//!   wire, dropped by the kernel's socket buffer, or dropped here under overload is gone, and
//!   anyone who can reach the port can write. Bind it to a gateway network; use MQTT QoS 1 or
//!   HTTP where every record must arrive.
//! - **Nothing silent.** `rtls_udp_datagrams_total{listener, outcome}` counts each datagram:
//!   `accepted` (stored; a vendor message without a position is counted in
//!   `rtls_ingest_refused_total{reason}` as over HTTP), `refused` (malformed, an unknown reader,
//!   outside the time window, over 64 KiB — also in `rtls_ingest_refused_total{reason}`),
//!   `dropped` (the queue full, the pipeline unavailable or shutting down). Refusals and drops
//!   are logged as warnings at most every 10 s per listener ([`crate::log_limit`]), with the
//!   count since. One bad datagram never stops the listener.
//! - **Shutdown.** The listener stops on the server's stop signal; datagrams still queued then
//!   are dropped (counted).

use std::net::SocketAddr;

use bytes::Bytes;
use prometheus_client::metrics::counter::Counter;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

use crate::adapters::Vendor;
use crate::log_limit::LogLimiter;
use crate::metrics::{outcome_counter, Metrics};
use crate::pipeline::Pipeline;
use crate::sink::IngestError;

/// The largest datagram taken (bytes); a larger one is refused.
pub const MAX_DATAGRAM: usize = 64 * 1024;

/// Datagrams waiting per listener for the pipeline; beyond, new ones are dropped.
pub const QUEUE_CAPACITY: usize = 1024;

/// Datagrams a listener submits at once (their records share the ingest log's group commit).
pub const IN_FLIGHT: usize = 64;

/// A listener's `rtls_udp_datagrams_total` counters.
#[derive(Clone)]
struct Counters {
    accepted: Counter,
    refused: Counter,
    dropped: Counter,
}

impl Counters {
    /// Registers (at 0) the listener's three series.
    fn new(metrics: &Metrics, listener: &str) -> Self {
        let counter = |outcome: &str| outcome_counter(&metrics.udp_datagrams, "listener", listener, outcome);
        Self {
            accepted: counter("accepted"),
            refused: counter("refused"),
            dropped: counter("dropped"),
        }
    }
}

/// A bound UDP listener, not yet reading.
pub struct UdpListener {
    socket: UdpSocket,
    vendor: Option<Vendor>,
    source: String,
    counters: Counters,
}

impl UdpListener {
    /// Binds `address`: `vendor` `None` reads measurement JSON lines, `Some` that vendor's
    /// messages.
    ///
    /// # Errors
    /// The socket cannot be bound (address in use, not a local address).
    pub async fn bind(address: SocketAddr, vendor: Option<Vendor>, metrics: &Metrics) -> std::io::Result<Self> {
        let socket = UdpSocket::bind(address).await?;
        let source = match vendor {
            None => format!("udp:{}", socket.local_addr()?),
            Some(vendor) => format!("udp:adapters/{}", vendor.name()),
        };
        let counters = Counters::new(metrics, &source);
        Ok(Self {
            socket,
            vendor,
            source,
            counters,
        })
    }

    /// The bound address (the port resolved, for `:0`).
    ///
    /// # Errors
    /// The OS cannot tell (not expected for a bound socket).
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// `None` for measurement lines, else the vendor whose messages it reads.
    #[must_use]
    pub fn vendor(&self) -> Option<Vendor> {
        self.vendor
    }

    /// The `listener` label and records' source: `udp:ADDR` or `udp:adapters/{vendor}`.
    #[must_use]
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Reads datagrams into `pipeline` until `stop` turns true; the receiver and the worker
    /// as two tasks (the returned one ends when both have).
    pub fn start(self, pipeline: Pipeline, stop: watch::Receiver<bool>) -> JoinHandle<()> {
        let (queue, queued) = mpsc::channel(QUEUE_CAPACITY);
        let Self {
            socket,
            vendor,
            source,
            counters,
        } = self;
        let address = socket.local_addr().map_or_else(|e| e.to_string(), |a| a.to_string());
        tracing::info!(listener = %source, %address, "UDP ingest listening (best-effort: no acknowledgement)");
        let worker = Worker {
            pipeline,
            vendor,
            source: source.clone(),
            counters: counters.clone(),
            refusals: LogLimiter::default(),
            drops: LogLimiter::default(),
        };
        let working = tokio::spawn(worker.run(queued, stop.clone()));
        let receiving = tokio::spawn(receive(socket, queue, source, counters, stop));
        tokio::spawn(async move {
            let _ = receiving.await;
            let _ = working.await;
        })
    }
}

/// Reads the socket until stopped; queues each datagram for the worker.
async fn receive(
    socket: UdpSocket,
    queue: mpsc::Sender<(Bytes, SocketAddr)>,
    source: String,
    counters: Counters,
    mut stop: watch::Receiver<bool>,
) {
    // one byte more than the largest datagram taken, to tell a larger one
    let mut buffer = vec![0_u8; MAX_DATAGRAM + 1];
    let mut drops = LogLimiter::default();
    let mut errors = LogLimiter::default();
    loop {
        let received = tokio::select! {
            biased;
            _ = stop.wait_for(|stop| *stop) => return,
            received = socket.recv_from(&mut buffer) => received,
        };
        let (length, from) = match received {
            Ok(received) => received,
            Err(e) => {
                // e.g. an ICMP port unreachable reported on the socket: not a datagram
                if let Some(count) = errors.occurred() {
                    tracing::warn!(listener = %source, error = %e, count, "UDP receive error (the count is since the last such line)");
                }
                continue;
            }
        };
        let datagram = Bytes::copy_from_slice(&buffer[..length]);
        if let Err(error) = queue.try_send((datagram, from)) {
            counters.dropped.inc();
            let reason = match error {
                mpsc::error::TrySendError::Full(_) => "the queue is full (the pipeline is behind)",
                mpsc::error::TrySendError::Closed(_) => "the listener is stopping",
            };
            if let Some(count) = drops.occurred() {
                tracing::warn!(listener = %source, %from, reason, count,
                    "UDP datagrams dropped (the count is since the last such line; rtls_udp_datagrams_total counts every one)");
            }
        }
    }
}

/// Submits the queued datagrams to the pipeline, [`IN_FLIGHT`] at a time.
struct Worker {
    pipeline: Pipeline,
    vendor: Option<Vendor>,
    source: String,
    counters: Counters,
    refusals: LogLimiter,
    drops: LogLimiter,
}

impl Worker {
    async fn run(mut self, mut queued: mpsc::Receiver<(Bytes, SocketAddr)>, mut stop: watch::Receiver<bool>) {
        let mut batch = Vec::with_capacity(IN_FLIGHT);
        loop {
            let received = tokio::select! {
                biased;
                _ = stop.wait_for(|stop| *stop) => break,
                received = queued.recv_many(&mut batch, IN_FLIGHT) => received,
            };
            if received == 0 {
                break;
            }
            let outcomes =
                futures_util::future::join_all(batch.iter().map(|(datagram, _)| self.submit(datagram))).await;
            for ((_, from), outcome) in batch.drain(..).zip(outcomes) {
                self.tally(from, outcome);
            }
        }
        queued.close();
        let mut unsent = 0_u64;
        while queued.try_recv().is_ok() {
            unsent += 1;
        }
        if unsent > 0 {
            self.counters.dropped.inc_by(unsent);
            tracing::warn!(listener = %self.source, unsent, "UDP datagrams dropped at shutdown: still queued");
        }
    }

    /// One datagram through the pipeline: the records stored, or why not.
    async fn submit(&self, datagram: &[u8]) -> Result<usize, IngestError> {
        if datagram.len() > MAX_DATAGRAM {
            self.pipeline
                .metrics()
                .ingest_refused
                .get_or_create(&vec![("reason".into(), "format".into())])
                .inc();
            return Err(IngestError::Invalid(format!(
                "{}: a datagram over {MAX_DATAGRAM} bytes; split it",
                self.source
            )));
        }
        match self.vendor {
            None => self.pipeline.submit_lines(&self.source, datagram).await,
            Some(vendor) => self
                .pipeline
                .submit_adapter(vendor, &self.source, datagram)
                .await
                .map(|outcome| outcome.accepted),
        }
    }

    /// Counts a datagram's outcome; logs refusals and drops, rate-limited.
    fn tally(&mut self, from: SocketAddr, outcome: Result<usize, IngestError>) {
        match outcome {
            Ok(_) => {
                self.counters.accepted.inc();
            }
            Err(IngestError::Invalid(reason) | IngestError::Unauthorized(reason)) => {
                self.counters.refused.inc();
                if let Some(count) = self.refusals.occurred() {
                    tracing::warn!(listener = %self.source, %from, %reason, count,
                        "UDP datagram refused (the count is since the last such line; rtls_udp_datagrams_total counts every one)");
                }
            }
            Err(IngestError::Unavailable(reason)) => {
                self.counters.dropped.inc();
                if let Some(count) = self.drops.occurred() {
                    tracing::warn!(listener = %self.source, %from, %reason, count,
                        "UDP datagram dropped: the pipeline could not take it (the count is since the last such line)");
                }
            }
        }
    }
}

/// Binds every listener of `[udp]` (the addresses resolved, in [`crate::config::UdpSection::listeners`]'s
/// order).
///
/// # Errors
/// The first listener that cannot be bound: its address and the OS error.
pub async fn bind_all(
    config: &crate::config::UdpSection,
    metrics: &Metrics,
) -> Result<Vec<UdpListener>, (SocketAddr, std::io::Error)> {
    let mut listeners = Vec::new();
    for (vendor, address) in config.listeners() {
        listeners.push(
            UdpListener::bind(address, vendor, metrics)
                .await
                .map_err(|e| (address, e))?,
        );
    }
    Ok(listeners)
}
