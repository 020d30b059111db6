//! The manager layer behind ingest: records are stored durably, acknowledged, and tracked on
//! worker threads, one [`Tracker`] per tag partition, so no async task ever runs filter work.
//!
//! ```text
//!  transports ──submit()──▶ [bounded queue] ──▶ ingest-log thread ──[bounded]──▶ commit thread
//!  (HTTP, MQTT)                                   │ ids counted in memory;         │ insert,
//!       ▲                                         │ dispatch by tag hash           │ commit ──▶ store
//!       │                                         │ (bounded), before the insert   │
//!       └────────────── ack after commit ─────────┼────────────────────────────────┘
//!                                                 ▼
//!                                  partition threads (Tracker each)
//!                                    │ live state, hub broadcast, MQTT publications
//!                                    ▼ (bounded)
//!                                  output thread ──▶ store (history, events, checkpoint)
//! ```
//!
//! (In a cluster one ingest-log thread inserts, dispatches during the commit, and acknowledges:
//! the store gives the ids there; see `ingest_log`.)
//!
//! Every queue is bounded: a full partition or commit queue blocks the ingest-log thread,
//! which fills the ingest queue, so `submit` waits (and after
//! [`PipelineConfig::submit_timeout`] answers [`IngestError::Unavailable`]); producers are
//! slowed, never dropped. Broadcasts to
//! WebSocket and MQTT subscribers are bounded ring buffers: a slow subscriber misses
//! messages (counted) instead of slowing ingest.
//!
//! Restart: the output thread checkpoints the highest ingest-log id below which every record's
//! outputs are stored; on start the records after it are replayed through the trackers. An
//! acknowledged record is in the ingest log, so it is never lost; its outputs may be stored
//! twice if the server died between storing them and the next checkpoint. Records are tracked
//! before they are committed, so the checkpoint may pass ids whose commit then failed (or never
//! came: the server died); those records were not acknowledged, and the ids of a new run start
//! above the checkpoint, the log's last id and every quarantined record's.

mod admission;
pub mod clock_lag;
mod cluster_side;
pub mod collision_news;
pub(crate) mod collisions;
mod event_clock;
mod fanout;
mod history_rate;
mod ingest_log;
mod live;
mod outputs;
mod partition;
mod partition_state;
mod quarantine;
pub mod readers;
mod submit;
mod trackable_fences;
pub mod trackable_location;
pub mod trackables;
mod watermark;

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use rtls_engine::record::Record;
use rtls_engine::site::Site;
use rtls_engine::tracker::{Output, Tracker};
use tokio::sync::{broadcast, mpsc, oneshot};

pub use admission::TimeWindow;
pub use clock_lag::ClockLag;
pub use cluster_side::{ClusterHooks, ReplicatedLog};
pub use fanout::PeerMessage;
pub use live::{CollisionListener, HubMessage, LastSeen, LiveState, TagState};
pub use partition_state::site_fingerprint;
pub use quarantine::QUARANTINE;
pub use readers::{ReaderHealth, ReaderMonitor};
pub use submit::AdapterOutcome;

use crate::metrics::Metrics;
use crate::sink::{IngestError, Publication};
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
    /// Advance the trackers with the wall clock (Unix seconds, minus `clock_lag`) so silent
    /// tags coast, get lost and are deleted in real time; off: only records move time.
    pub live_clock: bool,
    /// How far behind the wall clock the trackers are advanced: records may arrive this late
    /// without being judged late. [`ClockLag::Auto`] (the default) measures it from the
    /// records' delivery delays ([`clock_lag`]).
    pub clock_lag: ClockLag,
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
    /// A tag's stored track states at least this far apart (s; 0: every one;
    /// `server.history_interval_s`, `src/pipeline/history_rate.rs`).
    pub history_interval_s: f64,
    /// The generic adapter's field names (`[adapters.generic]`); `None`: `generic` payloads
    /// are refused.
    pub generic_adapter: Option<crate::adapters::GenericAdapter>,
    /// How Zebra Dart lines are read (`[adapters.zebra]`: unit, accuracies).
    pub zebra_adapter: crate::adapters::ZebraAdapter,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            partitions: std::thread::available_parallelism().map_or(2, |n| n.get()),
            ingest_queue_batches: 1024,
            // at most 16 × 1 024 records wait for a partition (`ingest_log::PARTITION_BATCH_RECORDS`)
            // and 32 batches of outputs for the store: under overload the queues fill in
            // about a second and back-pressure reaches the senders, instead of a backlog of
            // minutes in memory
            partition_queue_batches: 16,
            output_queue_batches: 32,
            broadcast_capacity: 65_536,
            max_records_per_payload: 100_000,
            submit_timeout: Duration::from_secs(5),
            live_clock: true,
            clock_lag: ClockLag::Auto,
            time_window: Some(TimeWindow {
                max_age_s: 86_400.0,
                max_lead_s: 60.0,
            }),
            default_accuracy_m: 1.0,
            history_interval_s: 0.0,
            generic_adapter: None,
            zebra_adapter: crate::adapters::ZebraAdapter::default(),
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
    /// An input for a partition, sent after the batch's records (and every record before
    /// them) were dispatched: a checkpoint then holds them.
    then: Option<(usize, PartitionInput)>,
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

/// The running pipeline: the [`MeasurementSink`](crate::sink::MeasurementSink) the transports feed, the live state the APIs
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
    /// of records do not wait behind history writes (on PostgreSQL; SQLite has one writer
    /// per file, so there they wait for the lock, never for a write-ahead-log checkpoint:
    /// [`Store::defer_wal_checkpoints`]).
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
        ingest_store.defer_wal_checkpoints()?;
        let checkpoint = ingest_store.checkpoint(CHECKPOINT)?.unwrap_or(0);
        let clustered = config.cluster.is_some();
        // one node counts the ingest log's ids on from here (a cluster's come from the store)
        let last_record_id = if clustered { 0 } else { ingest_store.last_record_id()? };
        let progress = Arc::new(Progress::new(partitions, checkpoint));
        let live = Arc::new(LiveState::new(site, partitions));
        let readers = Arc::new(ReaderMonitor::new(site, unix_ms()));
        let (hub, _) = broadcast::channel(config.broadcast_capacity.max(16));
        let (publications, _) = broadcast::channel(config.broadcast_capacity.max(16));
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
        let collision_worker = collisions::CollisionWorker::new(
            Arc::clone(&live),
            &hub,
            Default::default(),
            metrics.collision_updates_missed.clone(),
        );
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
                clock_lag: clock_lag::LiveClockLag::new(config.clock_lag),
                event_clock: Default::default(),
                watermark: Default::default(),
                history: history_rate::HistoryRate::new(config.history_interval_s),
                zone_entries: Default::default(),
                reported_lost: Default::default(),
                source: site.name.clone().unwrap_or_else(|| "rtls".into()),
                zones_version: 0,
                site_fingerprint: partition_state::site_fingerprint(&site_arc),
                track_step: config.track_step,
                pending_events: Vec::new(),
                unused_log: crate::log_limit::LogLimiter::default(),
                store_wait_log: crate::log_limit::LogLimiter::default(),
            };
            threads.push(spawn(
                format!("rtls-partition-{index}"),
                Box::new(move || worker.run()),
            )?);
        }
        drop(output_tx);

        let (ingest_tx, ingest_rx) = mpsc::channel(config.ingest_queue_batches.max(1));
        if clustered {
            let worker = ingest_log::SharedLogWorker {
                store: ingest_store,
                rx: ingest_rx,
                partitions: partition_txs.clone(),
                progress: Arc::clone(&progress),
                metrics: Arc::clone(&metrics),
            };
            threads.push(spawn("rtls-ingest-log".into(), Box::new(move || worker.run()))?);
        } else {
            let (first_id_tx, first_id_rx) = std::sync::mpsc::sync_channel(1);
            let (commit_tx, commit_rx) = std::sync::mpsc::sync_channel(ingest_log::COMMIT_QUEUE_GROUPS);
            let committer = ingest_log::CommitWorker {
                store: ingest_store,
                rx: commit_rx,
                partitions: partition_txs.clone(),
                progress: Arc::clone(&progress),
                metrics: Arc::clone(&metrics),
                replay_after_id: checkpoint,
                last_record_id,
                first_id: first_id_tx,
            };
            threads.push(spawn("rtls-ingest-commit".into(), Box::new(move || committer.run()))?);
            let dispatcher = ingest_log::DispatchWorker {
                rx: ingest_rx,
                partitions: partition_txs.clone(),
                progress: Arc::clone(&progress),
                first_id: first_id_rx,
                commits: commit_tx,
            };
            threads.push(spawn("rtls-ingest-log".into(), Box::new(move || dispatcher.run()))?);
        }

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

    /// The ingest-log thread's queue, while the server takes records.
    ///
    /// # Errors
    /// [`IngestError::Unavailable`] once it is shutting down.
    fn ingest_sender(&self) -> Result<mpsc::Sender<IngestBatch>, IngestError> {
        self.inner
            .ingest_tx
            .lock()
            .ok()
            .and_then(|guard| guard.clone())
            .ok_or_else(|| IngestError::Unavailable("the server is shutting down".into()))
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
