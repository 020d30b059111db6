//! A Zebra Dart hub's output read directly (`[adapters.zebra] hub = "HOST:PORT"`,
//! `rtls serve --zebra-hub HOST:PORT`): the hub is a TCP *server* that streams its packets as
//! ASCII lines (Dart format, port 5117), so the server connects to it as a client.
//!
//! ```text
//!  hub:5117 ──TCP──▶ client: lines (≤ 4 KiB each) ──▶ up to 64 at a time through
//!     ▲                 │ closed, failed, silent            Pipeline::submit_adapter(zebra, …),
//!     └── reconnect ◀───┘ after 1 s, doubling to 30 s       one line = one payload, in order
//! ```
//!
//! - **One line, one payload.** Each line goes through
//!   [`crate::pipeline::Pipeline::submit_adapter`] as a payload of its own (read by
//!   [`crate::adapters::ZebraAdapter`], as `POST /api/v1/adapters/zebra` reads a body), so a
//!   malformed line or one outside the time window costs that line only. Lines read together
//!   are submitted together (their records share the ingest log's group commit). The source
//!   of the stored records is `tcp:adapters/zebra`.
//! - **Reconnects.** A refused or failed connection, one the hub closes, and one that brings
//!   no byte for `idle_timeout_s` (a connection a network fault left half open) are opened
//!   again after a back-off of 1 s, doubling to 30 s; a connection that delivered a line
//!   starts the back-off again at 1 s. A line cut off by a closed connection is dropped.
//! - **Nothing silent.** `rtls_zebra_hub_lines_total{hub, outcome}` counts each line as
//!   `rtls_udp_datagrams_total` counts datagrams: `accepted` (stored; a packet without a
//!   position — P, N, D, I — is counted in `rtls_ingest_refused_total{reason="no_position"}`
//!   too), `refused` (malformed, over 4 KiB, an unknown reader, outside the time window — also
//!   in `rtls_ingest_refused_total{reason}`), `dropped` (the pipeline unavailable, a line cut
//!   off by a closed connection). `rtls_zebra_hub_connected{hub}` is 1 while connected.
//!   Refusals, drops and failed connections are logged as warnings at most every 10 s
//!   ([`crate::log_limit`]).
//! - **Backpressure.** Lines are read only as fast as the pipeline takes them; a hub that
//!   sends faster fills the connection's TCP window (the hub's own buffering then decides).
//!
//! # References
//! Zebra, "Dart RTLS User Guide" D2119 Rev F, chapter 11 "System output", page 83: "To
//! retrieve tag data from the Hub, you need a client program using the stream communication
//! protocol and a connection to the output port."

use std::time::Duration;

use bytes::Bytes;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::gauge::Gauge;
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;
use tokio::sync::watch;
use tokio::task::JoinHandle;

use crate::adapters::Vendor;
use crate::log_limit::LogLimiter;
use crate::metrics::outcome_counter;
use crate::pipeline::Pipeline;
use crate::sink::IngestError;

/// The longest line taken (bytes, without its LF); a Dart packet is under 200. A longer one
/// is refused and skipped to its end.
pub const MAX_LINE: usize = 4096;

/// Lines submitted at once.
pub const IN_FLIGHT: usize = 64;

/// How long a connection attempt may take.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// The first wait before a reconnection; it doubles up to [`MAX_BACKOFF`].
pub const FIRST_BACKOFF: Duration = Duration::from_secs(1);

/// The longest wait between reconnections.
pub const MAX_BACKOFF: Duration = Duration::from_secs(30);

/// The source of the records read from the hub.
pub const SOURCE: &str = "tcp:adapters/zebra";

/// Why a connection ended.
#[derive(Debug)]
enum Ended {
    /// The server is stopping.
    Stopped,
    /// The hub closed it.
    Closed,
    /// No byte for the idle timeout.
    Silent,
    /// A read failed.
    Failed(std::io::Error),
}

/// A hub's `rtls_zebra_hub_lines_total` counters and its connection gauge.
#[derive(Clone)]
struct Counters {
    accepted: Counter,
    refused: Counter,
    dropped: Counter,
    connected: Gauge,
}

/// The client of one Zebra Dart hub, not yet connected.
pub struct ZebraHub {
    address: String,
    idle_timeout: Duration,
    pipeline: Pipeline,
    counters: Counters,
    refusals: LogLimiter,
    drops: LogLimiter,
}

impl ZebraHub {
    /// A client of the hub at `address` (`HOST:PORT`) feeding `pipeline`; a connection silent
    /// for `idle_timeout` is opened again. Its metrics series are registered (at 0) at once.
    #[must_use]
    pub fn new(address: &str, idle_timeout: Duration, pipeline: Pipeline) -> Self {
        let metrics = pipeline.metrics();
        let counter = |outcome: &str| outcome_counter(&metrics.zebra_hub_lines, "hub", address, outcome);
        let counters = Counters {
            accepted: counter("accepted"),
            refused: counter("refused"),
            dropped: counter("dropped"),
            connected: metrics
                .zebra_hub_connected
                .get_or_create(&vec![("hub".into(), address.to_string())])
                .clone(),
        };
        Self {
            address: address.to_string(),
            idle_timeout,
            pipeline,
            counters,
            refusals: LogLimiter::default(),
            drops: LogLimiter::default(),
        }
    }

    /// Connects and reads the hub's lines until `stop` turns true, reconnecting as the
    /// [module](self) says.
    pub fn start(self, stop: watch::Receiver<bool>) -> JoinHandle<()> {
        tokio::spawn(self.run(stop))
    }

    async fn run(mut self, mut stop: watch::Receiver<bool>) {
        let mut backoff = FIRST_BACKOFF;
        let mut failures = LogLimiter::default();
        loop {
            let connecting = tokio::time::timeout(CONNECT_TIMEOUT, TcpStream::connect(self.address.as_str()));
            let connected = tokio::select! {
                biased;
                _ = stop.wait_for(|stop| *stop) => return,
                connected = connecting => connected,
            };
            match connected {
                Ok(Ok(stream)) => {
                    self.counters.connected.set(1);
                    tracing::info!(hub = %self.address, "Zebra hub: connected, reading its Dart output");
                    let (lines, ended) = self.read(stream, &mut stop).await;
                    self.counters.connected.set(0);
                    if lines > 0 {
                        backoff = FIRST_BACKOFF;
                    }
                    match ended {
                        Ended::Stopped => return,
                        Ended::Closed => {
                            tracing::warn!(hub = %self.address, lines, retry_s = backoff.as_secs_f64(), "Zebra hub: the hub closed the connection; reconnecting");
                        }
                        Ended::Silent => {
                            tracing::warn!(hub = %self.address, lines, idle_s = self.idle_timeout.as_secs_f64(), retry_s = backoff.as_secs_f64(),
                                "Zebra hub: no byte for the idle timeout; reconnecting");
                        }
                        Ended::Failed(error) => {
                            tracing::warn!(hub = %self.address, lines, %error, retry_s = backoff.as_secs_f64(), "Zebra hub: reading failed; reconnecting");
                        }
                    }
                }
                failed => {
                    let error = match failed {
                        Ok(Err(e)) => e.to_string(),
                        _ => format!("no answer in {CONNECT_TIMEOUT:?}"),
                    };
                    if let Some(count) = failures.occurred() {
                        tracing::warn!(hub = %self.address, %error, count, retry_s = backoff.as_secs_f64(),
                            "Zebra hub: cannot connect (the count is since the last such line)");
                    }
                }
            }
            tokio::select! {
                biased;
                _ = stop.wait_for(|stop| *stop) => return,
                () = tokio::time::sleep(backoff) => {}
            }
            backoff = (backoff * 2).min(MAX_BACKOFF);
        }
    }

    /// Reads one connection's lines until it ends; the lines read, and why it ended.
    async fn read(&mut self, mut stream: TcpStream, stop: &mut watch::Receiver<bool>) -> (u64, Ended) {
        let mut buffer = vec![0_u8; 16 * 1024];
        // the start of a line whose LF has not come yet
        let mut pending = Vec::new();
        // skipping the rest of an over-long line
        let mut skipping = false;
        let mut count = 0_u64;
        loop {
            let read = tokio::select! {
                biased;
                _ = stop.wait_for(|stop| *stop) => return (count, Ended::Stopped),
                read = tokio::time::timeout(self.idle_timeout, stream.read(&mut buffer)) => read,
            };
            let length = match read {
                Err(_) => return (count, self.cut_off(&pending, Ended::Silent)),
                Ok(Err(error)) => return (count, self.cut_off(&pending, Ended::Failed(error))),
                Ok(Ok(0)) => return (count, self.cut_off(&pending, Ended::Closed)),
                Ok(Ok(length)) => length,
            };
            let mut lines = Vec::new();
            for piece in buffer[..length].split_inclusive(|&b| b == b'\n') {
                let complete = piece.ends_with(b"\n");
                if skipping {
                    skipping = !complete;
                    continue;
                }
                pending.extend_from_slice(piece);
                if pending.len() > MAX_LINE + usize::from(complete) {
                    pending.clear();
                    skipping = !complete;
                    self.too_long();
                } else if complete {
                    let line = std::mem::take(&mut pending);
                    if !line.trim_ascii().is_empty() {
                        lines.push(Bytes::from(line));
                    }
                }
            }
            count += lines.len() as u64;
            for batch in lines.chunks(IN_FLIGHT) {
                let outcomes = futures_util::future::join_all(
                    batch
                        .iter()
                        .map(|line| self.pipeline.submit_adapter(Vendor::Zebra, SOURCE, line)),
                )
                .await;
                for outcome in outcomes {
                    self.tally(outcome.map(|o| o.accepted));
                }
            }
        }
    }

    /// A line cut off by the end of its connection: dropped (counted).
    fn cut_off(&mut self, pending: &[u8], ended: Ended) -> Ended {
        if !pending.trim_ascii().is_empty() {
            self.tally(Err(IngestError::Unavailable(format!(
                "{} bytes of a line without its LF when the connection ended",
                pending.len()
            ))));
        }
        ended
    }

    /// A line over [`MAX_LINE`]: refused (counted with reason `format`).
    fn too_long(&mut self) {
        self.pipeline
            .metrics()
            .ingest_refused
            .get_or_create(&vec![("reason".into(), "format".into())])
            .inc();
        self.tally(Err(IngestError::Invalid(format!(
            "{SOURCE}: a line over {MAX_LINE} bytes (a Dart packet is under 200): is this the hub's Dart output port?"
        ))));
    }

    /// Counts a line's outcome; logs refusals and drops, rate-limited.
    fn tally(&mut self, outcome: Result<usize, IngestError>) {
        match outcome {
            Ok(_) => {
                self.counters.accepted.inc();
            }
            Err(IngestError::Invalid(reason) | IngestError::Unauthorized(reason)) => {
                self.counters.refused.inc();
                if let Some(count) = self.refusals.occurred() {
                    tracing::warn!(hub = %self.address, %reason, count,
                        "Zebra hub line refused (the count is since the last such line; rtls_zebra_hub_lines_total counts every one)");
                }
            }
            Err(IngestError::Unavailable(reason)) => {
                self.counters.dropped.inc();
                if let Some(count) = self.drops.occurred() {
                    tracing::warn!(hub = %self.address, %reason, count,
                        "Zebra hub line dropped (the count is since the last such line)");
                }
            }
        }
    }
}
