//! The manager layer behind ingest: records are stored durably, acknowledged, and tracked on
//! worker threads, one [`Tracker`] per tag partition, so no async task ever runs filter work.
//!
//! ```text
//!  transports ──submit()──▶ [bounded queue] ──▶ ingest-log thread ──append+commit──▶ store
//!  (HTTP, MQTT)   ◀──── ack after commit ─────────┘      │ dispatch by tag hash (bounded)
//!                                                        ▼
//!                                  partition threads (Tracker each)
//!                                    │ live state, hub broadcast, MQTT publications
//!                                    ▼ (bounded)
//!                                  output thread ──▶ store (history, events, checkpoint)
//! ```
//!
//! Every queue is bounded: a full partition blocks the ingest-log thread, which fills the
//! ingest queue, so `submit` waits (and after [`PipelineConfig::submit_timeout`] answers
//! [`IngestError::Unavailable`]); producers are slowed, never dropped. Broadcasts to
//! WebSocket and MQTT subscribers are bounded ring buffers: a slow subscriber misses
//! messages (counted) instead of slowing ingest.
//!
//! Restart: the output thread checkpoints the highest ingest-log id below which every record's
//! outputs are stored; on start the records after it are replayed through the trackers. An
//! acknowledged record is in the ingest log, so it is never lost; its outputs may be stored
//! twice if the server died between storing them and the next checkpoint.

mod admission;
pub(crate) mod collisions;
mod fanout;
mod ingest_log;
mod live;
mod outputs;
mod partition;
mod quarantine;
pub mod readers;
pub mod trackables;

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use rtls_engine::record::{parse_json_line, to_json_line, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Output, Tracker};
use tokio::sync::{broadcast, mpsc, oneshot};

pub use admission::TimeWindow;
pub use fanout::PeerMessage;
pub use live::{HubMessage, LastSeen, LiveState, TagState};
pub use quarantine::QUARANTINE;
pub use readers::{ReaderHealth, ReaderMonitor};

use crate::metrics::Metrics;
use crate::sink::{IngestError, IngestFuture, MeasurementSink, Publication};
use crate::store::{NewRecord, Store, StoreError};
use fanout::Fanout;
use ingest_log::PartitionInput;

/// One record into a partition's tracker: [`Tracker::push`] (the default). Its error or panic
/// quarantines the record (tests put in a failing step to exercise that path).
pub type TrackStep = fn(&mut Tracker, Record, &mut Output) -> rtls_engine::Result<()>;

/// Sizes of the pipeline's queues and threads.
#[derive(Debug, Clone)]
pub struct PipelineConfig {
    /// Tag partitions, each a worker thread with its own tracker.
    pub partitions: usize,
    /// Payloads waiting for the ingest-log thread.
    pub ingest_queue_batches: usize,
    /// Batches waiting for each partition.
    pub partition_queue_batches: usize,
    /// Batches waiting for the output thread.
    pub output_queue_batches: usize,
    /// Messages a WebSocket / MQTT subscriber may fall behind before it misses some.
    pub broadcast_capacity: usize,
    /// Records in one payload at most.
    pub max_records_per_payload: usize,
    /// How long `submit` waits for room in the ingest queue before answering
    /// [`IngestError::Unavailable`].
    pub submit_timeout: Duration,
    /// Advance the trackers with the wall clock (Unix seconds, minus `clock_lag_s`) so silent
    /// tags coast, get lost and are deleted in real time; off: only records move time.
    pub live_clock: bool,
    /// How far behind the wall clock the trackers are advanced (s): records may arrive this
    /// late without being judged late.
    pub clock_lag_s: f64,
    /// With `live_clock`: records outside this window around the server clock are refused at
    /// ingest ([`TimeWindow`]); `None`: any time the parser accepts.
    pub time_window: Option<TimeWindow>,
    /// One record into a partition's tracker.
    pub track_step: TrackStep,
    /// A partition that has not come round its loop for this long (s) is stalled: `/health`
    /// answers 503 (an idle partition comes round every 250 ms).
    pub stall_after_s: f64,
    /// In a cluster (`rtls serve --cluster`): the replicated ingest log and the way to the
    /// other nodes; `None`: one process, the ingest log in the store.
    pub cluster: Option<ClusterHooks>,
    /// The accuracy (σ, m) of a vendor adapter's fix whose message gives none
    /// (`server.default_accuracy_m`; [`crate::adapters`]).
    pub default_accuracy_m: f64,
    /// The generic adapter's field names (`[adapters.generic]`); `None`: `generic` payloads
    /// are refused.
    pub generic_adapter: Option<crate::adapters::GenericAdapter>,
}

/// The replicated ingest log of a cluster (NATS JetStream, `crate::cluster`).
pub trait ReplicatedLog: Send + Sync {
    /// Appends `lines` (each record's JSON line with its tag partition) durably; resolves
    /// once the log has acknowledged every one of them.
    ///
    /// # Errors
    /// [`IngestError::Unavailable`] when any was not acknowledged (the reader retries all).
    fn append(&self, source: &str, received_ms: i64, lines: Vec<(usize, String)>) -> IngestFuture;
}

/// What the pipeline needs of a cluster: the replicated ingest log records are appended to
/// before they are acknowledged, and the queue of outputs for the other nodes.
#[derive(Clone)]
pub struct ClusterHooks {
    /// The replicated ingest log.
    pub log: Arc<dyn ReplicatedLog>,
    /// Outputs for the other nodes (bounded; a full queue drops and counts).
    pub peers: mpsc::Sender<PeerMessage>,
}

impl std::fmt::Debug for ClusterHooks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClusterHooks").finish_non_exhaustive()
    }
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            partitions: std::thread::available_parallelism().map_or(2, |n| n.get()),
            ingest_queue_batches: 1024,
            partition_queue_batches: 256,
            output_queue_batches: 256,
            broadcast_capacity: 65_536,
            max_records_per_payload: 100_000,
            submit_timeout: Duration::from_secs(5),
            live_clock: true,
            clock_lag_s: 2.0,
            time_window: Some(TimeWindow {
                max_age_s: 86_400.0,
                max_lead_s: 60.0,
            }),
            default_accuracy_m: 1.0,
            generic_adapter: None,
            track_step: Tracker::push,
            stall_after_s: 10.0,
            cluster: None,
        }
    }
}

/// A partition's liveness ([`Pipeline::partition_health`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartitionHealth {
    /// Seconds since it last came round its loop.
    pub silent_s: f64,
    /// Silent for longer than [`PipelineConfig::stall_after_s`].
    pub stalled: bool,
}

/// A failure to start the pipeline.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The site cannot be tracked.
    #[error("site: {0}")]
    Site(String),
    /// The store failed while replaying.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A thread could not be started.
    #[error("starting thread {name}: {reason}")]
    Thread {
        /// The thread's name.
        name: String,
        /// The OS error.
        reason: String,
    },
}

/// A payload of parsed records on its way to the ingest log.
struct IngestBatch {
    records: Vec<Record>,
    rows: Vec<NewRecord>,
    reply: oneshot::Sender<Result<usize, IngestError>>,
}

/// Progress counters shared by the threads, for the restart checkpoint.
struct Progress {
    /// Highest ingest-log id dispatched to each partition.
    dispatched: Vec<AtomicI64>,
    /// Highest ingest-log id whose outputs are stored, per partition.
    stored: Vec<AtomicI64>,
    /// When each partition last came round its loop (ms since the Unix epoch).
    heartbeat_ms: Vec<AtomicI64>,
}

impl Progress {
    fn new(partitions: usize, start_id: i64) -> Self {
        Self {
            dispatched: (0..partitions).map(|_| AtomicI64::new(start_id)).collect(),
            stored: (0..partitions).map(|_| AtomicI64::new(start_id)).collect(),
            heartbeat_ms: (0..partitions).map(|_| AtomicI64::new(unix_ms())).collect(),
        }
    }

    /// Partition `index` is alive now.
    fn beat(&self, index: usize) {
        self.heartbeat_ms[index].store(unix_ms(), Ordering::Release);
    }

    /// The highest id at or below which every record's outputs are stored: the lowest stored
    /// id of a partition with work in flight, else the highest dispatched id.
    fn watermark(&self) -> i64 {
        let mut lowest_busy = i64::MAX;
        let mut highest = i64::MIN;
        for (dispatched, stored) in self.dispatched.iter().zip(&self.stored) {
            let (dispatched, stored) = (dispatched.load(Ordering::Acquire), stored.load(Ordering::Acquire));
            highest = highest.max(dispatched);
            if stored < dispatched {
                lowest_busy = lowest_busy.min(stored);
            }
        }
        if lowest_busy == i64::MAX {
            highest
        } else {
            lowest_busy
        }
    }
}

/// The running pipeline: the [`MeasurementSink`] the transports feed, the live state the APIs
/// read, and the broadcasts they subscribe to. Cheap to clone.
#[derive(Clone)]
pub struct Pipeline {
    inner: Arc<Inner>,
}

struct Inner {
    ingest_tx: Mutex<Option<mpsc::Sender<IngestBatch>>>,
    validator: Mutex<Tracker>,
    config: PipelineConfig,
    live: Arc<LiveState>,
    readers: Arc<ReaderMonitor>,
    hub: broadcast::Sender<Arc<HubMessage>>,
    publications: broadcast::Sender<Publication>,
    metrics: Arc<Metrics>,
    threads: Mutex<Vec<JoinHandle<()>>>,
    progress: Arc<Progress>,
    fanout: Fanout,
    /// The partition threads' queues, for a cluster's warm-ups and resets (emptied at
    /// shutdown, so that the threads see their queues close).
    partition_txs: Mutex<Vec<std::sync::mpsc::SyncSender<PartitionInput>>>,
    /// In a cluster: this node's id and the partitions it owns now (for `/health`).
    cluster_status: Mutex<Option<(String, Vec<usize>)>>,
}

/// The checkpoint's name in the store.
pub const CHECKPOINT: &str = "tracked_record_id";

impl Pipeline {
    /// Starts the threads: `ingest_store` takes the ingest log (and replays it from the
    /// checkpoint), `output_store` the history and events. Two connections, so that appends
    /// of records never wait behind history writes.
    ///
    /// # Errors
    /// [`PipelineError::Site`] when the site cannot be tracked, [`PipelineError::Store`] when
    /// the checkpoint cannot be read, [`PipelineError::Thread`].
    pub fn start(
        site: &Site,
        mut ingest_store: Box<dyn Store>,
        output_store: Box<dyn Store>,
        config: PipelineConfig,
        metrics: Arc<Metrics>,
    ) -> Result<Self, PipelineError> {
        let partitions = config.partitions.max(1);
        let tracker = || Tracker::new(site).map_err(|e| PipelineError::Site(e.to_string()));
        let validator = tracker()?;
        let checkpoint = ingest_store.checkpoint(CHECKPOINT)?.unwrap_or(0);
        let progress = Arc::new(Progress::new(partitions, checkpoint));
        let live = Arc::new(LiveState::new(site, partitions));
        let readers = Arc::new(ReaderMonitor::new(site, unix_ms()));
        let (hub, _) = broadcast::channel(config.broadcast_capacity.max(16));
        let (publications, _) = broadcast::channel(config.broadcast_capacity.max(16));
        let clustered = config.cluster.is_some();
        let fanout = Fanout {
            live: Arc::clone(&live),
            hub: hub.clone(),
            publications: publications.clone(),
            peers: config.cluster.as_ref().map(|c| c.peers.clone()),
            readers: Arc::clone(&readers),
            local: clustered.then(|| {
                (
                    broadcast::channel(config.broadcast_capacity.max(16)).0,
                    broadcast::channel(config.broadcast_capacity.max(16)).0,
                )
            }),
            metrics: Arc::clone(&metrics),
        };
        let site_arc = Arc::new(site.clone());
        if let Some(peers) = config.cluster.as_ref().map(|c| c.peers.clone()) {
            // a zone edit made through this node's API reaches the other nodes
            let dropped = metrics.cluster_peer_messages_dropped.clone();
            live.on_zone_edit(Box::new(move |zones| {
                if peers.try_send(PeerMessage::Zones { zones: zones.to_vec() }).is_err() {
                    dropped.inc();
                }
            }));
        }
        // the collision thread is not joined at shutdown: it ends when the hub's last sender
        // (this pipeline's, its partitions') is gone
        let collision_worker = collisions::CollisionWorker::new(Arc::clone(&live), &hub, Default::default());
        std::thread::Builder::new()
            .name("rtls-collisions".into())
            .spawn(move || collision_worker.run())
            .map_err(|e| PipelineError::Thread {
                name: "rtls-collisions".into(),
                reason: e.to_string(),
            })?;
        let mut threads = Vec::new();
        let spawn = |name: String, body: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.clone())
                .spawn(body)
                .map_err(|e| PipelineError::Thread {
                    name,
                    reason: e.to_string(),
                })
        };

        let (output_tx, output_rx) = std::sync::mpsc::sync_channel(config.output_queue_batches.max(1));
        let output_worker = outputs::OutputWorker {
            store: output_store,
            rx: output_rx,
            progress: Arc::clone(&progress),
            metrics: Arc::clone(&metrics),
            quarantine_stored: 0,
            write_checkpoint: !clustered,
        };
        threads.push(spawn("rtls-outputs".into(), Box::new(move || output_worker.run()))?);

        let mut partition_txs = Vec::with_capacity(partitions);
        for index in 0..partitions {
            let (tx, rx) = std::sync::mpsc::sync_channel(config.partition_queue_batches.max(1));
            partition_txs.push(tx);
            let worker = partition::PartitionWorker {
                index,
                offsets_posted: None,
                offsets_dirty: false,
                tracker: tracker()?,
                rx,
                outputs: output_tx.clone(),
                fanout: fanout.clone(),
                site: Arc::clone(&site_arc),
                metrics: Arc::clone(&metrics),
                progress: Arc::clone(&progress),
                live_clock: config.live_clock,
                clock_lag_s: config.clock_lag_s,
                zone_entries: Default::default(),
                reported_lost: Default::default(),
                source: site.name.clone().unwrap_or_else(|| "rtls".into()),
                zones_version: 0,
                track_step: config.track_step,
                pending_events: Vec::new(),
                last_unused_log: None,
                unused_since_log: 0,
            };
            threads.push(spawn(
                format!("rtls-partition-{index}"),
                Box::new(move || worker.run()),
            )?);
        }
        drop(output_tx);

        let (ingest_tx, ingest_rx) = mpsc::channel(config.ingest_queue_batches.max(1));
        let ingest_worker = ingest_log::IngestLogWorker {
            store: ingest_store,
            rx: ingest_rx,
            partitions: partition_txs.clone(),
            progress: Arc::clone(&progress),
            metrics: Arc::clone(&metrics),
            replay_after_id: (!clustered).then_some(checkpoint),
        };
        threads.push(spawn("rtls-ingest-log".into(), Box::new(move || ingest_worker.run()))?);

        Ok(Self {
            inner: Arc::new(Inner {
                ingest_tx: Mutex::new(Some(ingest_tx)),
                validator: Mutex::new(validator),
                config,
                live,
                readers,
                hub,
                publications,
                metrics,
                threads: Mutex::new(threads),
                progress,
                fanout,
                partition_txs: Mutex::new(if clustered { partition_txs } else { Vec::new() }),
                cluster_status: Mutex::new(None),
            }),
        })
    }

    /// The live state (latest location per tag, head counts per zone).
    #[must_use]
    pub fn live(&self) -> &Arc<LiveState> {
        &self.inner.live
    }

    /// Each partition's seconds since it last came round its loop, and whether that is more
    /// than [`PipelineConfig::stall_after_s`] (a stalled partition).
    #[must_use]
    pub fn partition_health(&self) -> Vec<PartitionHealth> {
        let now_ms = unix_ms();
        self.inner
            .progress
            .heartbeat_ms
            .iter()
            .map(|beat| {
                let silent_s = (now_ms - beat.load(Ordering::Acquire)).max(0) as f64 / 1e3;
                PartitionHealth {
                    silent_s,
                    stalled: silent_s > self.inner.config.stall_after_s,
                }
            })
            .collect()
    }

    /// Each reader's health (last heard, record rate).
    #[must_use]
    pub fn readers(&self) -> &ReaderMonitor {
        &self.inner.readers
    }

    /// Sends a message to every WebSocket subscriber (an alarm acknowledgement, a zone edit).
    pub fn broadcast(&self, message: HubMessage) {
        // in a cluster, every node's subscribers
        self.inner.fanout.hub(message);
    }

    /// Applies another node's output to this node's live state and broadcasts.
    pub fn apply_peer(&self, message: PeerMessage) {
        self.inner.fanout.apply(message);
    }

    /// Records this node's id and the partitions it owns (the cluster's ownership does).
    pub fn set_cluster_status(&self, node: &str, owned: Vec<usize>) {
        if let Ok(mut status) = self.inner.cluster_status.lock() {
            *status = Some((node.to_string(), owned));
        }
    }

    /// In a cluster: this node's id and the partitions it owns now.
    #[must_use]
    pub fn cluster_status(&self) -> Option<(String, Vec<usize>)> {
        self.inner.cluster_status.lock().ok().and_then(|status| status.clone())
    }

    /// The tag partition of `tag` (the same on every node of a cluster with the same count).
    #[must_use]
    pub fn partition_of(&self, tag: &str) -> usize {
        partition_of(tag, self.inner.config.partitions.max(1))
    }

    /// The number of tag partitions.
    #[must_use]
    pub fn partitions(&self) -> usize {
        self.inner.config.partitions.max(1)
    }

    /// Sends partition `index` records to rebuild its tracks from (a cluster's takeover);
    /// blocks while the partition's queue is full.
    pub fn warm_up_partition(&self, index: usize, records: Vec<Record>) {
        self.to_partition(index, PartitionInput::WarmUp(records));
    }

    /// Makes partition `index` forget its tracks (a cluster's partition moved away); blocks
    /// while its queue is full.
    pub fn reset_partition(&self, index: usize) {
        self.to_partition(index, PartitionInput::Reset);
    }

    fn to_partition(&self, index: usize, input: PartitionInput) {
        let sender = self
            .inner
            .partition_txs
            .lock()
            .ok()
            .and_then(|txs| txs.get(index).cloned());
        if let Some(sender) = sender {
            if sender.send(input).is_err() {
                tracing::error!(partition = index, "partition stopped");
            }
        }
    }

    /// Stores and tracks records a cluster's ingest stream delivered to this node: messages
    /// as `(source, received_ms, JSON lines)`, as [`ReplicatedLog::append`] wrote them. A line
    /// that does not parse is counted and logged, and costs that record only. Resolves once
    /// the records are in the store.
    ///
    /// # Errors
    /// [`IngestError::Unavailable`] when they could not be stored (the stream redelivers).
    pub async fn take_from_stream(&self, messages: &[(String, i64, String)]) -> Result<usize, IngestError> {
        let mut records = Vec::new();
        let mut rows = Vec::new();
        for (source, received_ms, lines) in messages {
            for (index, line) in lines.lines().enumerate() {
                if line.trim().is_empty() {
                    continue;
                }
                match parse_json_line(line, source, index + 1) {
                    Ok(record) => {
                        rows.push(NewRecord {
                            received_ms: *received_ms,
                            source: source.clone(),
                            time_s: record.time_s,
                            tag: record.tag.clone(),
                            json: line.to_string(),
                        });
                        records.push(record);
                    }
                    Err(e) => {
                        self.inner.metrics.cluster_records_unparseable.inc();
                        tracing::error!(error = %e, "a record of the ingest stream does not parse; skipped");
                    }
                }
            }
        }
        if records.is_empty() {
            return Ok(0);
        }
        let count = records.len();
        let (reply, answer) = oneshot::channel();
        let sender = self
            .inner
            .ingest_tx
            .lock()
            .ok()
            .and_then(|guard| guard.clone())
            .ok_or_else(|| IngestError::Unavailable("the server is shutting down".into()))?;
        sender
            .send(IngestBatch { records, rows, reply })
            .await
            .map_err(|_| IngestError::Unavailable("the server is shutting down".into()))?;
        answer
            .await
            .map_err(|_| IngestError::Unavailable("the ingest log stopped".into()))?
            .map(|_| count)
    }

    /// Subscribes to the hub's messages (locations, fence events, extension events).
    #[must_use]
    pub fn subscribe(&self) -> broadcast::Receiver<Arc<HubMessage>> {
        self.inner.hub.subscribe()
    }

    /// The MQTT publications' channel (tracks and events), for the embedded broker: in a
    /// cluster, every node's.
    #[must_use]
    pub fn publications(&self) -> broadcast::Sender<Publication> {
        self.inner.publications.clone()
    }

    /// The publications this node produced (all of them without a cluster), for what must
    /// leave the cluster once: the bridge to an external broker.
    #[must_use]
    pub fn local_publications(&self) -> broadcast::Sender<Publication> {
        self.inner.fanout.local_publications()
    }

    /// Subscribes to the hub messages this node produced (all of them without a cluster), for
    /// what must leave the cluster once: the webhooks.
    #[must_use]
    pub fn subscribe_local(&self) -> broadcast::Receiver<Arc<HubMessage>> {
        self.inner.fanout.subscribe_local()
    }

    /// The metrics.
    #[must_use]
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.inner.metrics
    }

    /// Parses a payload of JSON lines (`source` names it in errors, e.g. `http body`), checks
    /// every record against the site, and stores and queues them all (or none).
    ///
    /// # Errors
    /// [`IngestError::Invalid`] naming `source:line: field` for the first bad line;
    /// [`IngestError::Unavailable`] when the payload could not be stored.
    pub async fn submit_lines(&self, source: &str, payload: &[u8]) -> Result<usize, IngestError> {
        let text = std::str::from_utf8(payload).map_err(|e| {
            let line = 1 + payload[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
            IngestError::Invalid(format!("{source}:{line}: not UTF-8 text"))
        })?;
        let mut records = Vec::new();
        for (index, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            if records.len() == self.inner.config.max_records_per_payload {
                return Err(IngestError::Invalid(format!(
                    "{source}: more than {} records in one payload; split it",
                    self.inner.config.max_records_per_payload
                )));
            }
            let record = parse_json_line(line, source, index + 1).map_err(|e| self.refused("format", e.to_string()))?;
            records.push((index + 1, record));
        }
        self.submit_numbered(source, records).await
    }

    /// Stores and queues records built elsewhere (the omlox location ingest); `source` names
    /// them in errors, with the 1-based index as the line.
    ///
    /// # Errors
    /// As [`Pipeline::submit_lines`].
    pub async fn submit_records(&self, source: &str, records: Vec<Record>) -> Result<usize, IngestError> {
        let numbered = records.into_iter().enumerate().map(|(i, r)| (i + 1, r)).collect();
        self.submit_numbered(source, numbered).await
    }

    async fn submit_numbered(&self, source: &str, records: Vec<(usize, Record)>) -> Result<usize, IngestError> {
        if records.is_empty() {
            return Ok(0);
        }
        {
            let validator = self
                .inner
                .validator
                .lock()
                .map_err(|_| IngestError::Unavailable("the record validator failed".into()))?;
            for (line, record) in &records {
                validator
                    .check_record(record, source, *line)
                    .map_err(|e| self.refused("site", e.to_string()))?;
            }
        }
        if let Some(window) = self.inner.config.time_window.filter(|_| self.inner.config.live_clock) {
            let now_s = unix_s();
            for (line, record) in &records {
                if let Some(reason) = window.refusal(record.time_s, now_s) {
                    return Err(self.refused("time_window", format!("{source}:{line}: field `t`: {reason}")));
                }
            }
        }
        let received_ms = unix_ms();
        self.inner.readers.heard(records.iter().map(|(_, r)| r), received_ms);
        if let Some(cluster) = &self.inner.config.cluster {
            // every node's reader health counts the records any node received
            self.inner.fanout.to_peers(|| PeerMessage::ReadersHeard {
                counts: ReaderMonitor::counts(records.iter().map(|(_, r)| r)),
                at_ms: received_ms,
            });
            let partitions = self.inner.config.partitions.max(1);
            let lines = records
                .iter()
                .map(|(_, r)| (partition_of(&r.tag, partitions), to_json_line(r)))
                .collect();
            let started = std::time::Instant::now();
            let count = records.len();
            cluster.log.append(source, received_ms, lines).await?;
            self.inner
                .metrics
                .ingest_ack_seconds
                .observe(started.elapsed().as_secs_f64());
            return Ok(count);
        }
        let rows = records
            .iter()
            .map(|(_, r)| NewRecord {
                received_ms,
                source: source.to_string(),
                time_s: r.time_s,
                tag: r.tag.clone(),
                json: to_json_line(r),
            })
            .collect();
        let count = records.len();
        let (reply, answer) = oneshot::channel();
        let batch = IngestBatch {
            records: records.into_iter().map(|(_, r)| r).collect(),
            rows,
            reply,
        };
        let sender = self
            .inner
            .ingest_tx
            .lock()
            .ok()
            .and_then(|guard| guard.clone())
            .ok_or_else(|| IngestError::Unavailable("the server is shutting down".into()))?;
        let started = std::time::Instant::now();
        match tokio::time::timeout(self.inner.config.submit_timeout, sender.send(batch)).await {
            Ok(Ok(())) => {}
            Ok(Err(_)) => return Err(IngestError::Unavailable("the server is shutting down".into())),
            Err(_) => {
                self.inner.metrics.ingest_overloaded.inc();
                return Err(IngestError::Unavailable(format!(
                    "ingest queue full for {:?}; retry later",
                    self.inner.config.submit_timeout
                )));
            }
        }
        let result = answer
            .await
            .map_err(|_| IngestError::Unavailable("the ingest log stopped".into()))?;
        self.inner
            .metrics
            .ingest_ack_seconds
            .observe(started.elapsed().as_secs_f64());
        result.map(|_| count)
    }

    /// Parses a payload of a vendor's feed with its adapter ([`crate::adapters`]), counts each
    /// message without a position in `rtls_ingest_refused_total{reason}` (`no_position`,
    /// `anchor`) and stores and queues the fixes as [`Pipeline::submit_records`] does.
    ///
    /// # Errors
    /// [`IngestError::Invalid`] naming `source: field` when the payload is malformed (counted
    /// with reason `format`; nothing of it is stored); otherwise as [`Pipeline::submit_records`].
    pub async fn submit_adapter(
        &self,
        vendor: crate::adapters::Vendor,
        source: &str,
        payload: &[u8],
    ) -> Result<AdapterOutcome, IngestError> {
        let default_accuracy_m = self.inner.config.default_accuracy_m;
        let parsed = match (vendor, &self.inner.config.generic_adapter) {
            (crate::adapters::Vendor::Generic, Some(generic)) => generic.parse(payload, default_accuracy_m),
            _ => crate::adapters::parse(vendor, payload, default_accuracy_m),
        }
        .map_err(|e| self.refused("format", format!("{source}: {e}")))?;
        for refusal in &parsed.refusals {
            self.inner
                .metrics
                .ingest_refused
                .get_or_create(&vec![("reason".into(), refusal.reason.into())])
                .inc();
            tracing::debug!(%source, at = %refusal.at, tag = ?refusal.tag, reason = refusal.reason,
                detail = %refusal.detail, "adapter: message without a position refused");
        }
        let accepted = self.submit_records(source, parsed.records).await?;
        Ok(AdapterOutcome {
            accepted,
            refusals: parsed.refusals,
        })
    }

    /// A payload refused for `reason` (`format`, `site`, `time_window`): counted in
    /// `rtls_ingest_refused_total{reason}` (nothing of the payload is stored).
    fn refused(&self, reason: &str, message: String) -> IngestError {
        self.inner
            .metrics
            .ingest_refused
            .get_or_create(&vec![("reason".into(), reason.into())])
            .inc();
        IngestError::Invalid(message)
    }

    /// Stops taking records, lets every thread drain its queue (the trackers flush, the
    /// outputs are stored, the checkpoint is written) and waits for them.
    pub fn shutdown(&self) {
        if let Ok(mut sender) = self.inner.ingest_tx.lock() {
            sender.take();
        }
        if let Ok(mut partitions) = self.inner.partition_txs.lock() {
            partitions.clear();
        }
        let threads = self
            .inner
            .threads
            .lock()
            .map(|mut t| std::mem::take(&mut *t))
            .unwrap_or_default();
        for thread in threads {
            let name = thread.thread().name().unwrap_or("?").to_string();
            if thread.join().is_err() {
                tracing::error!(thread = %name, "pipeline thread panicked");
            }
        }
    }
}

/// What [`Pipeline::submit_adapter`] did with a vendor payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AdapterOutcome {
    /// Fixes stored and queued.
    pub accepted: usize,
    /// Messages without a position (counted, not stored).
    pub refusals: Vec<crate::adapters::Refusal>,
}

impl MeasurementSink for Pipeline {
    /// JSON lines of our format, or — from an MQTT topic `rtls/v1/adapters/{vendor}/…` — a
    /// vendor's message through its adapter (refused messages are counted and logged).
    fn ingest(&self, source: &str, payload: bytes::Bytes) -> IngestFuture {
        let pipeline = self.clone();
        let source = source.to_string();
        let vendor = source
            .strip_prefix("mqtt:")
            .and_then(crate::adapters::Vendor::from_topic);
        Box::pin(async move {
            match vendor {
                Some(vendor) => pipeline
                    .submit_adapter(vendor, &source, &payload)
                    .await
                    .map(|outcome| outcome.accepted),
                None => pipeline.submit_lines(&source, &payload).await,
            }
        })
    }
}

/// Milliseconds since the Unix epoch by the wall clock.
#[must_use]
pub fn unix_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// Seconds since the Unix epoch by the wall clock.
#[must_use]
pub fn unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The partition of a tag: FNV-1a of its bytes modulo the partition count (stable across
/// restarts, so a tag's track always lives on the same thread).
fn partition_of(tag: &str, partitions: usize) -> usize {
    // h ← (h ⊕ byte) · 16777619, from the FNV offset basis
    let hash = tag
        .bytes()
        .fold(0x811c_9dc5_u32, |h, b| (h ^ u32::from(b)).wrapping_mul(0x0100_0193));
    hash as usize % partitions.max(1)
}
