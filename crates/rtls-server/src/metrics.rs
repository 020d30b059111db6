//! Prometheus metrics (`GET /metrics`, OpenMetrics text format via `prometheus-client`).

use prometheus_client::encoding::text::encode;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{exponential_buckets, Histogram};
use prometheus_client::registry::Registry;

/// Labels of a family: `(name, value)` pairs.
pub type Labels = Vec<(String, String)>;

/// The counter of `family` labelled `{owner_label}="{owner}", outcome="{outcome}"` (registered
/// at 0, so a scrape shows every outcome of a webhook, NATS forward or UDP listener from its
/// start).
#[must_use]
pub fn outcome_counter(family: &Family<Labels, Counter>, owner_label: &str, owner: &str, outcome: &str) -> Counter {
    family
        .get_or_create(&vec![
            (owner_label.to_string(), owner.to_string()),
            ("outcome".into(), outcome.to_string()),
        ])
        .clone()
}

/// The server's metrics; every field is registered under `rtls_…`.
#[derive(Debug)]
pub struct Metrics {
    registry: Registry,
    /// Records appended to the ingest log.
    pub ingest_records: Counter,
    /// Ingest-log transactions (group commits).
    pub ingest_commits: Counter,
    /// Payloads refused with a client error, by transport.
    pub ingest_rejected: Family<Labels, Counter>,
    /// Payloads refused at ingest, by reason (`format`, `site`, `time_window`), and vendor
    /// messages without a position (`no_position`, `anchor`; [`crate::adapters`]) or, in a
    /// Zebra payload of several lines, malformed lines (`format`).
    pub ingest_refused: Family<Labels, Counter>,
    /// Payloads refused because the ingest queue stayed full.
    pub ingest_overloaded: Counter,
    /// Ingest-log appends that failed.
    pub ingest_store_failures: Counter,
    /// From submit to acknowledgement (s).
    pub ingest_ack_seconds: Histogram,
    /// From a track update's time to its publication (s): the ingest-to-output latency when
    /// record times are the wall clock.
    pub pipeline_latency_seconds: Histogram,
    /// Tracker time per batch of records (s).
    pub tracking_seconds: Histogram,
    /// How far a batch's newest record is ahead of the slowest active sender, which the
    /// tracker's clock ticks wait for (s, at most the rewind horizon).
    pub watermark_lag_seconds: Histogram,
    /// How far behind the wall clock an idle partition's live clock moves its tracker (s;
    /// `pipeline.clock_lag_s`, measured when `"auto"`), at each such move.
    pub live_clock_lag_seconds: Histogram,
    /// Track updates produced.
    pub track_updates: Counter,
    /// Track updates that replace one already published (a late record re-filtered, or a
    /// record of an update's time arriving after it).
    pub track_updates_revised: Counter,
    /// Records the tracker refused.
    pub tracker_errors: Counter,
    /// Records quarantined: their partition's tracker failed on them (an error or a panic).
    pub records_quarantined: Counter,
    /// Audit events (of changes already made) the store failed to keep.
    pub audit_store_failures: Counter,
    /// Records the trackers did not use, by `event` (`rejected`, `late`) and measurement `kind`.
    pub records_unused: Family<Labels, Counter>,
    /// Alarms raised, by type.
    pub alarms: Family<Labels, Counter>,
    /// Track states stored.
    pub stored_locations: Counter,
    /// Events stored.
    pub stored_events: Counter,
    /// Output writes that failed.
    pub output_store_failures: Counter,
    /// Output batches a partition had to wait for the store with (its queue full): the store
    /// is the pipeline's limit (`server.history_interval_s` stores fewer rows).
    pub output_store_waits: Counter,
    /// Tags with a live track.
    pub tags: Gauge,
    /// Open WebSocket connections.
    pub websocket_clients: Gauge,
    /// Messages a slow WebSocket client missed.
    pub websocket_dropped: Counter,
    /// Locations a WebSocket subscription's `crs` / `zone_id` could not project (not sent).
    pub websocket_unprojected: Counter,
    /// HTTP requests, by route and status class.
    pub http_requests: Family<Labels, Counter>,
    /// HTTP connections closed at accept by a limit (`reason`: `per_ip`, `total`).
    pub http_connections_refused: Family<Labels, Counter>,
    /// HTTP requests refused with 429 (over `max_requests_per_s_per_ip`).
    pub http_requests_limited: Counter,
    /// Webhook deliveries, by `webhook` and `outcome` (`delivered`, `retried` — one per retry,
    /// `failed` — given up or refused, `dropped` — queue full, missed hub messages, or left at
    /// shutdown).
    pub webhook_deliveries: Family<Labels, Counter>,
    /// UDP datagrams, by `listener` (`udp:ADDR`, `udp:adapters/{vendor}`) and `outcome`
    /// (`accepted`, `refused` — malformed or refused at ingest, `dropped` — overload or
    /// shutdown; [`crate::udp`]).
    pub udp_datagrams: Family<Labels, Counter>,
    /// Lines read from a Zebra Dart hub, by `hub` (`HOST:PORT`) and `outcome` (`accepted`,
    /// `refused`, `dropped`, as [`Metrics::udp_datagrams`]; [`crate::zebra_hub`]).
    pub zebra_hub_lines: Family<Labels, Counter>,
    /// Whether the connection to a Zebra Dart hub is open (1) or not (0), by `hub`.
    pub zebra_hub_connected: Family<Labels, Gauge>,
    /// Messages forwarded to NATS, by `forward` and `outcome` (`published` — handed to the
    /// client, `dropped` — queue full, missed hub messages, a publish error, or left at
    /// shutdown; [`crate::nats_forward`]).
    pub nats_forward: Family<Labels, Counter>,
    /// Rows packed into compressed blocks by the compaction pass, by `kind` (`states`,
    /// `records`).
    pub store_compacted: Family<Labels, Counter>,
    /// Compaction passes that failed (the rows stay as they are; the log says why).
    pub store_compaction_failures: Counter,
    /// Track updates the collision detection missed by falling behind the hub (the trackables
    /// concerned are judged again at their next update).
    pub collision_updates_missed: Counter,
    /// Cluster: outputs not sent to the other nodes because the outbound queue was full.
    pub cluster_peer_messages_dropped: Counter,
    /// Cluster: tag partitions this node owns now.
    pub cluster_partitions_owned: Gauge,
    /// Cluster: partitions this node took over (a lease won).
    pub cluster_takeovers: Counter,
    /// Cluster: partitions this node gave up (released, or the lease lost).
    pub cluster_releases: Counter,
    /// Cluster: ingest-stream messages whose records do not parse (acknowledged, not stored).
    pub cluster_records_unparseable: Counter,
    /// Cluster: partition checkpoints by `outcome` (`written`, `failed`).
    pub cluster_checkpoints: Family<Labels, Counter>,
    /// Cluster: the last partition checkpoint's size, bytes.
    pub cluster_checkpoint_bytes: Gauge,
    /// Cluster: takeovers by how the partition's tracks resumed (`outcome`: `restored` from a
    /// checkpoint, `warmed-up` on the last `warmup_s` without one, `refused` a checkpoint
    /// that could not be restored, then warmed up).
    pub cluster_resumes: Family<Labels, Counter>,
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

impl Metrics {
    /// Creates and registers every metric.
    #[must_use]
    pub fn new() -> Self {
        let mut registry = Registry::with_prefix("rtls");
        let latency = || Histogram::new(exponential_buckets(0.0005, 2.0, 16));
        let metrics = Self {
            ingest_records: Counter::default(),
            ingest_commits: Counter::default(),
            ingest_rejected: Family::default(),
            ingest_refused: Family::default(),
            ingest_overloaded: Counter::default(),
            ingest_store_failures: Counter::default(),
            ingest_ack_seconds: latency(),
            pipeline_latency_seconds: latency(),
            tracking_seconds: latency(),
            watermark_lag_seconds: latency(),
            live_clock_lag_seconds: latency(),
            track_updates: Counter::default(),
            track_updates_revised: Counter::default(),
            tracker_errors: Counter::default(),
            records_quarantined: Counter::default(),
            audit_store_failures: Counter::default(),
            records_unused: Family::default(),
            alarms: Family::default(),
            stored_locations: Counter::default(),
            stored_events: Counter::default(),
            output_store_failures: Counter::default(),
            output_store_waits: Counter::default(),
            tags: Gauge::default(),
            websocket_clients: Gauge::default(),
            websocket_dropped: Counter::default(),
            websocket_unprojected: Counter::default(),
            http_requests: Family::default(),
            http_connections_refused: Family::default(),
            http_requests_limited: Counter::default(),
            webhook_deliveries: Family::default(),
            udp_datagrams: Family::default(),
            zebra_hub_lines: Family::default(),
            zebra_hub_connected: Family::default(),
            nats_forward: Family::default(),
            store_compacted: Family::default(),
            store_compaction_failures: Counter::default(),
            collision_updates_missed: Counter::default(),
            cluster_peer_messages_dropped: Counter::default(),
            cluster_partitions_owned: Gauge::default(),
            cluster_takeovers: Counter::default(),
            cluster_releases: Counter::default(),
            cluster_records_unparseable: Counter::default(),
            cluster_checkpoints: Family::default(),
            cluster_checkpoint_bytes: Gauge::default(),
            cluster_resumes: Family::default(),
            registry: Registry::default(),
        };
        let m = &metrics;
        registry.register(
            "ingest_records",
            "Records appended to the ingest log",
            m.ingest_records.clone(),
        );
        registry.register(
            "ingest_commits",
            "Ingest-log transactions (group commits)",
            m.ingest_commits.clone(),
        );
        registry.register(
            "ingest_rejected",
            "Payloads refused with a client error",
            m.ingest_rejected.clone(),
        );
        registry.register(
            "ingest_refused",
            "Payloads refused at ingest (nothing of them stored), by reason: format, site, time_window; vendor adapter messages without a position: no_position, anchor; malformed lines of a Zebra payload: format",
            m.ingest_refused.clone(),
        );
        registry.register(
            "ingest_overloaded",
            "Payloads refused because the ingest queue stayed full",
            m.ingest_overloaded.clone(),
        );
        registry.register(
            "ingest_store_failures",
            "Ingest-log appends that failed",
            m.ingest_store_failures.clone(),
        );
        registry.register(
            "ingest_ack_seconds",
            "Submit to acknowledgement",
            m.ingest_ack_seconds.clone(),
        );
        registry.register(
            "pipeline_latency_seconds",
            "Track update time to publication",
            m.pipeline_latency_seconds.clone(),
        );
        registry.register(
            "tracking_seconds",
            "Tracker time per batch of records",
            m.tracking_seconds.clone(),
        );
        registry.register(
            "watermark_lag_seconds",
            "How far a batch's newest record is ahead of the slowest active sender (the ticks wait for it)",
            m.watermark_lag_seconds.clone(),
        );
        registry.register(
            "live_clock_lag_seconds",
            "How far behind the wall clock an idle partition's live clock moves its tracker",
            m.live_clock_lag_seconds.clone(),
        );
        registry.register("track_updates", "Track updates produced", m.track_updates.clone());
        registry.register(
            "track_updates_revised",
            "Track updates that replace one already published (late records re-filtered)",
            m.track_updates_revised.clone(),
        );
        registry.register(
            "tracker_errors",
            "Records the tracker refused",
            m.tracker_errors.clone(),
        );
        registry.register(
            "records_quarantined",
            "Records quarantined: their partition's tracker failed on them (stored apart, skipped by replay)",
            m.records_quarantined.clone(),
        );
        registry.register(
            "audit_store_failures",
            "Audit events of changes already made that the store failed to keep (each logged at error level)",
            m.audit_store_failures.clone(),
        );
        registry.register(
            "records_unused",
            "Records the trackers did not use, by event (rejected, late) and measurement kind; each is an event with its reason",
            m.records_unused.clone(),
        );
        registry.register("alarms", "Alarms raised", m.alarms.clone());
        registry.register("stored_locations", "Track states stored", m.stored_locations.clone());
        registry.register("stored_events", "Events stored", m.stored_events.clone());
        registry.register(
            "store_compacted",
            "Track states and raw records packed into compressed blocks",
            m.store_compacted.clone(),
        );
        registry.register(
            "store_compaction_failures",
            "Compaction passes that failed",
            m.store_compaction_failures.clone(),
        );
        registry.register(
            "output_store_failures",
            "Output writes that failed",
            m.output_store_failures.clone(),
        );
        registry.register(
            "output_store_waits",
            "Output batches a partition waited for the store with (the store is the limit)",
            m.output_store_waits.clone(),
        );
        registry.register("tags", "Tags with a live track", m.tags.clone());
        registry.register(
            "websocket_clients",
            "Open WebSocket connections",
            m.websocket_clients.clone(),
        );
        registry.register(
            "websocket_dropped",
            "Messages slow WebSocket clients missed",
            m.websocket_dropped.clone(),
        );
        registry.register(
            "websocket_unprojected",
            "Locations a WebSocket subscription's crs or zone_id could not project, not sent",
            m.websocket_unprojected.clone(),
        );
        registry.register(
            "http_requests",
            "HTTP requests by route and status",
            m.http_requests.clone(),
        );
        registry.register(
            "http_connections_refused",
            "HTTP connections closed at accept by a limit (reason: per_ip, total)",
            m.http_connections_refused.clone(),
        );
        registry.register(
            "http_requests_limited",
            "HTTP requests refused with 429: over max_requests_per_s_per_ip",
            m.http_requests_limited.clone(),
        );
        registry.register(
            "webhook_deliveries",
            "Webhook deliveries by webhook and outcome (delivered, retried, failed, dropped)",
            m.webhook_deliveries.clone(),
        );
        registry.register(
            "udp_datagrams",
            "UDP datagrams by listener and outcome (accepted, refused, dropped); UDP is best-effort",
            m.udp_datagrams.clone(),
        );
        registry.register(
            "zebra_hub_lines",
            "Lines read from a Zebra Dart hub by hub and outcome (accepted, refused, dropped)",
            m.zebra_hub_lines.clone(),
        );
        registry.register(
            "zebra_hub_connected",
            "Whether the connection to a Zebra Dart hub is open (1) or not (0), by hub",
            m.zebra_hub_connected.clone(),
        );
        registry.register(
            "nats_forward",
            "Messages forwarded to NATS by forward and outcome (published, dropped)",
            m.nats_forward.clone(),
        );
        registry.register(
            "collision_updates_missed",
            "Track updates the collision detection missed by falling behind the hub",
            m.collision_updates_missed.clone(),
        );
        registry.register(
            "cluster_peer_messages_dropped",
            "Cluster: outputs not sent to the other nodes (outbound queue full)",
            m.cluster_peer_messages_dropped.clone(),
        );
        registry.register(
            "cluster_partitions_owned",
            "Cluster: tag partitions this node owns",
            m.cluster_partitions_owned.clone(),
        );
        registry.register(
            "cluster_takeovers",
            "Cluster: tag partitions this node took over",
            m.cluster_takeovers.clone(),
        );
        registry.register(
            "cluster_releases",
            "Cluster: tag partitions this node gave up (released or lease lost)",
            m.cluster_releases.clone(),
        );
        registry.register(
            "cluster_records_unparseable",
            "Cluster: ingest-stream records that do not parse (acknowledged, not stored)",
            m.cluster_records_unparseable.clone(),
        );
        registry.register(
            "cluster_checkpoints",
            "Cluster: partition checkpoints stored (outcome written) or not (failed)",
            m.cluster_checkpoints.clone(),
        );
        registry.register(
            "cluster_checkpoint_bytes",
            "Cluster: size of the last partition checkpoint, bytes",
            m.cluster_checkpoint_bytes.clone(),
        );
        registry.register(
            "cluster_resumes",
            "Cluster: takeovers by how the tracks resumed (restored, warmed-up, refused)",
            m.cluster_resumes.clone(),
        );
        Self { registry, ..metrics }
    }

    /// The OpenMetrics text exposition.
    ///
    /// # Errors
    /// [`std::fmt::Error`] if encoding fails.
    pub fn encode(&self) -> Result<String, std::fmt::Error> {
        let mut text = String::new();
        encode(&mut text, &self.registry)?;
        Ok(text)
    }
}
