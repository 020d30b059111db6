//! `rtls serve --cluster`: many `rtls serve` processes as one service on NATS JetStream.
//!
//! ```text
//!  reader ──HTTP/MQTT──▶ any node ──publish──▶ JetStream stream RTLS_INGEST (R3)
//!            ◀── ack after JetStream's ack ──┘      subjects rtls.ingest.<partition>
//!                                                    │ durable consumer rtls-p<partition>
//!                                                    ▼ (one node holds its lease)
//!                       owner: store the records (shared PostgreSQL) ─▶ ack the stream
//!                              track them (the partition's thread) ─▶ history (PostgreSQL)
//!                              outputs ─▶ rtls.out.<node> ─▶ every other node's live state,
//!                                         WebSocket, MQTT and dashboard subscribers
//! ```
//!
//! - **Ingest** (`StreamLog`, [`Cluster::log`]): a payload's records are published per tag partition (one
//!   message per partition and payload, their JSON lines) and acknowledged to the reader only
//!   once JetStream acknowledged every message — then they are replicated on the stream's
//!   `replicas` servers.
//! - **Ownership** ([`ownership`]): each partition is leased to one node through the key
//!   `p<n>` of the key-value bucket `rtls_leases` (entries renewed every round, expiring after
//!   `lease_ttl_s` as a safety net). Nodes say they are alive on core NATS
//!   (`rtls.nodes.<node>`, four times per `failover_s`), which works while JetStream elects
//!   leaders (4–9 s after a server dies); a node silent for `failover_s` is dead, and its
//!   leases are taken over by compare-and-set on their revision. A node claims partitions up
//!   to its fair share ⌈partitions / live nodes⌉ and releases one a round while above it, so a
//!   new node gets work and a dead node's work is shared out.
//! - **Takeover** ([`consumer`]): the new owner reads the partition's durable consumer's ack
//!   floor (every record at or below it is stored), restores the partition's tracker from its
//!   newest checkpoint ([`checkpoints`]) and tracks the records after it up to the floor (or,
//!   without a usable checkpoint, the records of the last `warmup_s`; tracked, not published
//!   or stored again), replaces the consumer to deliver from the floor on at once (not after
//!   the dead owner's acknowledgement timeout), then takes the records after the floor as live
//!   ones.
//! - **Outputs** ([`peers`]): the partition threads' outputs go to this node's subscribers and,
//!   as [`PeerMessage`](crate::pipeline::PeerMessage)s, to `rtls.out.<node>`, which every other node applies to its own.
//!   Zone edits and alarm acknowledgements are stored in the shared PostgreSQL and announced
//!   the same way.
//!
//! A checkpoint ([`checkpoints`]) is the partition tracker's state, stored every
//! `checkpoint_s` and when the partition is given up, with the stream sequence up to which it
//! holds the records: a partition that moves continues from it plus the records after it,
//! never replayed from the start.

pub mod checkpoints;
pub mod consumer;
pub mod ownership;
pub mod peers;

use std::sync::Arc;
use std::time::Duration;

use async_nats::jetstream;
use async_nats::HeaderMap;
use bytes::Bytes;

pub use crate::config::cluster::ClusterSection;
use crate::pipeline::{Pipeline, ReplicatedLog};
use crate::sink::IngestError;
use crate::sink::IngestFuture;

/// Outputs waiting to be sent to the other nodes, at most.
pub const PEER_QUEUE: usize = 65_536;
/// The ingest stream's name.
pub const STREAM: &str = "RTLS_INGEST";
/// The ingest stream's subject prefix: `rtls.ingest.<partition>`.
pub const INGEST_SUBJECT: &str = "rtls.ingest";
/// The outputs' subject prefix: `rtls.out.<node>`.
pub const OUTPUT_SUBJECT: &str = "rtls.out";
/// The partition leases' bucket.
pub const LEASES: &str = "rtls_leases";
/// The subject prefix of the nodes' heartbeats on core NATS: `rtls.nodes.<node>`.
pub const HEARTBEAT_SUBJECT: &str = "rtls.nodes";
/// The cluster-wide settings' bucket (the partition count every node must share).
pub const SETTINGS: &str = "rtls_cluster";
/// A message's payload stays below this (NATS' default `max_payload` is 1 MiB).
const MAX_MESSAGE_BYTES: usize = 512 * 1024;
/// How long joining is retried before `rtls serve` gives up.
const JOIN_PATIENCE: Duration = Duration::from_secs(30);
/// How long a payload's publication is retried before the reader is answered 503: longer than a
/// JetStream leader election (4–9 s after a server dies).
const PUBLISH_RETRY_FOR: Duration = Duration::from_secs(12);
/// The pause between two attempts.
const PUBLISH_BACKOFF: Duration = Duration::from_millis(250);
/// The header naming a message's source (the transport, e.g. `http body`).
const SOURCE_HEADER: &str = "Rtls-Source";
/// The header with a message's reception time (ms since the Unix epoch).
const RECEIVED_HEADER: &str = "Rtls-Received-Ms";

/// A failure to join the cluster.
#[derive(Debug, thiserror::Error)]
#[error("cluster: {0}")]
pub struct ClusterError(pub String);

fn cluster_error(what: &str, error: impl std::fmt::Display) -> ClusterError {
    ClusterError(format!("{what}: {error}"))
}

/// This node's connection to the cluster: the NATS client, JetStream, the stream and buckets.
#[derive(Clone)]
pub struct Cluster {
    /// The settings.
    pub settings: ClusterSection,
    /// This node's id.
    pub node: String,
    client: async_nats::Client,
    jetstream: jetstream::Context,
    stream: jetstream::stream::Stream,
    leases: jetstream::kv::Store,
    checkpoints: jetstream::kv::Store,
}

impl Cluster {
    /// Connects to the NATS servers and makes sure the ingest stream and the buckets exist
    /// (creating them with `replicas` copies), and that the cluster's partition count is this
    /// node's.
    ///
    /// # Errors
    /// [`ClusterError`] naming what failed (connection, stream, bucket, a partition count
    /// other than the cluster's).
    pub async fn join(settings: ClusterSection) -> Result<Self, ClusterError> {
        // a NATS cluster that is starting too has no JetStream leader for a few seconds
        let started = tokio::time::Instant::now();
        loop {
            match Self::try_join(settings.clone()).await {
                Ok(cluster) => return Ok(cluster),
                Err(e) if started.elapsed() < JOIN_PATIENCE => {
                    tracing::warn!(error = %e, "joining the cluster failed; retrying");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
                Err(e) => return Err(e),
            }
        }
    }

    async fn try_join(settings: ClusterSection) -> Result<Self, ClusterError> {
        let node = settings.node_name();
        let client = async_nats::ConnectOptions::new()
            .name(format!("rtls {node}"))
            .connection_timeout(Duration::from_secs(5))
            .request_timeout(Some(Duration::from_secs(5)))
            .connect(settings.servers.clone())
            .await
            .map_err(|e| cluster_error(&format!("connecting to {}", settings.servers.join(",")), e))?;
        let jetstream = jetstream::new(client.clone());
        let stream = jetstream
            .get_or_create_stream(jetstream::stream::Config {
                name: STREAM.into(),
                subjects: vec![format!("{INGEST_SUBJECT}.>")],
                max_age: Duration::from_secs_f64(settings.stream_max_age_h * 3600.0),
                num_replicas: settings.replicas,
                storage: jetstream::stream::StorageType::File,
                ..Default::default()
            })
            .await
            .map_err(|e| cluster_error(&format!("the stream {STREAM} ({} replicas)", settings.replicas), e))?;
        let bucket = |name: &str, max_age: Duration| jetstream::kv::Config {
            bucket: name.into(),
            history: 1,
            max_age,
            num_replicas: settings.replicas,
            storage: jetstream::stream::StorageType::Memory,
            ..Default::default()
        };
        let leases = key_value(&jetstream, bucket(LEASES, settings.lease_ttl())).await?;
        let shared = key_value(
            &jetstream,
            jetstream::kv::Config {
                storage: jetstream::stream::StorageType::File,
                ..bucket(SETTINGS, Duration::ZERO)
            },
        )
        .await?;
        // a checkpoint is of no use once the records after it have left the stream
        let checkpoints = key_value(
            &jetstream,
            jetstream::kv::Config {
                storage: jetstream::stream::StorageType::File,
                ..bucket(
                    checkpoints::CHECKPOINTS,
                    Duration::from_secs_f64(settings.stream_max_age_h * 3600.0),
                )
            },
        )
        .await?;
        let count = settings.partitions.to_string();
        match shared.create("partitions", Bytes::from(count.clone())).await {
            Ok(_) => {}
            Err(e) if e.kind() == jetstream::kv::CreateErrorKind::AlreadyExists => {
                let theirs = shared
                    .get("partitions")
                    .await
                    .map_err(|e| cluster_error("reading the cluster's partition count", e))?
                    .map(|v| String::from_utf8_lossy(&v).into_owned())
                    .unwrap_or_default();
                if theirs != count {
                    return Err(ClusterError(format!(
                        "the cluster has {theirs} partitions, this node's [cluster] partitions is {count}: \
                         every node must use the same count"
                    )));
                }
            }
            Err(e) => return Err(cluster_error("writing the cluster's partition count", e)),
        }
        tracing::info!(node = %node, servers = %settings.servers.join(","), partitions = settings.partitions,
            replicas = settings.replicas, "joined the cluster");
        Ok(Self {
            settings,
            node,
            client,
            jetstream,
            stream,
            leases,
            checkpoints,
        })
    }

    /// The replicated ingest log for the pipeline.
    #[must_use]
    pub fn log(&self) -> Arc<dyn ReplicatedLog> {
        Arc::new(StreamLog {
            jetstream: self.jetstream.clone(),
        })
    }
}

/// Starts this node's cluster tasks: partition ownership (and the consumers of the partitions
/// it wins), sending its outputs to the other nodes and applying theirs. They stop when
/// `stop` turns true; ownership hands its partitions back first.
pub fn start_node(
    cluster: Cluster,
    pipeline: Pipeline,
    outputs: tokio::sync::mpsc::Receiver<crate::pipeline::PeerMessage>,
    stop: &tokio::sync::watch::Receiver<bool>,
) -> Vec<tokio::task::JoinHandle<()>> {
    let receiving = (cluster.clone(), pipeline.clone(), stop.clone());
    vec![
        tokio::spawn(ownership::Ownership::new(cluster.clone(), pipeline).run(stop.clone())),
        tokio::spawn(peers::send(cluster, outputs, stop.clone())),
        tokio::spawn(async move {
            let (cluster, pipeline, stop) = receiving;
            if let Err(e) = peers::receive(cluster, pipeline, stop).await {
                tracing::error!(error = %e, "the other nodes' outputs are not received");
            }
        }),
    ]
}

/// The external MQTT broker's URL for this node: a client id of its own (`<id>-<node>`, or
/// `rtls-<node>` when the URL names none), since a broker disconnects a client whose id
/// another takes. A URL that does not parse is returned as it is (the bridge reports it).
#[must_use]
pub fn node_mqtt_url(url: &str, node: &str) -> String {
    let Ok(mut parsed) = url::Url::parse(url) else {
        return url.to_string();
    };
    let pairs: Vec<(String, String)> = parsed.query_pairs().into_owned().collect();
    let client_id = pairs
        .iter()
        .find(|(k, _)| k == "client_id")
        .map_or_else(|| format!("rtls-{node}"), |(_, id)| format!("{id}-{node}"));
    {
        let mut query = parsed.query_pairs_mut();
        query.clear();
        for (key, value) in pairs.iter().filter(|(k, _)| k != "client_id") {
            query.append_pair(key, value);
        }
        query.append_pair("client_id", &client_id);
    }
    parsed.to_string()
}

/// The external broker's measurement subscription in a cluster: a shared subscription
/// (`$share/rtls/…`, MQTT 5 and mosquitto ≥ 1.6 for 3.1.1 clients), so that each message
/// reaches one node, not every node.
#[must_use]
pub fn shared_measurement_filter() -> String {
    format!("$share/rtls/{}", crate::mqtt::MEASUREMENT_FILTER)
}

/// Opens the key-value bucket, creating its stream first if needed. The stream is created
/// here with the key-value layout (`KV_<bucket>`, subjects `$KV.<bucket>.>`, one value per
/// key, rollups, reads from the leader) rather than through `create_key_value`, which asks for the
/// account's limits in a form nats-server 2.9 (Debian 12's) does not answer.
async fn key_value(
    jetstream: &jetstream::Context,
    config: jetstream::kv::Config,
) -> Result<jetstream::kv::Store, ClusterError> {
    let name = config.bucket.clone();
    let duplicate_window = if config.max_age.is_zero() {
        Duration::from_secs(120)
    } else {
        config.max_age.min(Duration::from_secs(120))
    };
    jetstream
        .get_or_create_stream(jetstream::stream::Config {
            name: format!("KV_{name}"),
            subjects: vec![format!("$KV.{name}.>")],
            max_messages_per_subject: config.history.max(1),
            max_age: config.max_age,
            storage: config.storage,
            num_replicas: config.num_replicas.max(1),
            allow_rollup: true,
            deny_delete: true,
            // reads from the stream's leader: a lagging replica's answer could show a lease
            // that changed hands
            allow_direct: false,
            discard: jetstream::stream::DiscardPolicy::New,
            duplicate_window,
            ..Default::default()
        })
        .await
        .map_err(|e| cluster_error(&format!("the bucket {name}"), e))?;
    jetstream
        .get_key_value(&name)
        .await
        .map_err(|e| cluster_error(&format!("the bucket {name}"), e))
}

/// The ingest stream as the pipeline's [`ReplicatedLog`].
struct StreamLog {
    jetstream: jetstream::Context,
}

impl ReplicatedLog for StreamLog {
    fn append(&self, source: &str, received_ms: i64, lines: Vec<(usize, String)>) -> IngestFuture {
        let jetstream = self.jetstream.clone();
        let source = source.to_string();
        Box::pin(async move {
            let messages = messages_by_partition(lines);
            let count = messages.iter().map(|(_, _, n)| n).sum();
            let deadline = tokio::time::Instant::now() + PUBLISH_RETRY_FOR;
            let mut acks = Vec::with_capacity(messages.len());
            for (partition, payload, _) in messages {
                let mut headers = HeaderMap::new();
                headers.insert(SOURCE_HEADER, source.as_str());
                headers.insert(RECEIVED_HEADER, received_ms.to_string().as_str());
                // JetStream drops a retried message it already has (its duplicate window)
                headers.insert("Nats-Msg-Id", uuid::Uuid::new_v4().to_string().as_str());
                let subject = format!("{INGEST_SUBJECT}.{partition}");
                acks.push(tokio::spawn(publish_until_acknowledged(
                    jetstream.clone(),
                    subject,
                    headers,
                    payload,
                    deadline,
                )));
            }
            for ack in acks {
                ack.await
                    .map_err(|e| IngestError::Unavailable(format!("publishing failed: {e}")))??;
            }
            Ok(count)
        })
    }
}

/// Publishes one message to the ingest stream and waits for JetStream's acknowledgement,
/// publishing it again (same `Nats-Msg-Id`) after a failure until `deadline`: a NATS server
/// that dies, or a stream leader being elected, costs a retry, not the reader's payload.
async fn publish_until_acknowledged(
    jetstream: jetstream::Context,
    subject: String,
    headers: HeaderMap,
    payload: Bytes,
    deadline: tokio::time::Instant,
) -> Result<(), IngestError> {
    loop {
        let attempt = async {
            jetstream
                .publish_with_headers(subject.clone(), headers.clone(), payload.clone())
                .await
                .map_err(|e| e.to_string())?
                .await
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        match attempt.await {
            Ok(()) => return Ok(()),
            Err(reason) if tokio::time::Instant::now() + PUBLISH_BACKOFF >= deadline => {
                return Err(IngestError::Unavailable(format!(
                    "the ingest stream did not acknowledge the records: {reason}"
                )))
            }
            Err(reason) => {
                tracing::debug!(subject, reason, "publishing to the ingest stream failed; retrying");
                tokio::time::sleep(PUBLISH_BACKOFF).await;
            }
        }
    }
}

/// The records' JSON lines grouped into messages: one per partition, split where a message
/// would pass [`MAX_MESSAGE_BYTES`]; `(partition, payload, records)`.
fn messages_by_partition(lines: Vec<(usize, String)>) -> Vec<(usize, Bytes, usize)> {
    let mut open: std::collections::BTreeMap<usize, (String, usize)> = std::collections::BTreeMap::new();
    let mut done = Vec::new();
    for (partition, line) in lines {
        let (text, count) = open.entry(partition).or_default();
        if !text.is_empty() && text.len() + line.len() + 1 > MAX_MESSAGE_BYTES {
            done.push((partition, Bytes::from(std::mem::take(text)), std::mem::take(count)));
        }
        text.push_str(&line);
        text.push('\n');
        *count += 1;
    }
    done.extend(
        open.into_iter()
            .map(|(partition, (text, count))| (partition, Bytes::from(text), count)),
    );
    done
}

/// The source and reception time a message carries (`unknown` and now when absent).
fn message_origin(headers: Option<&HeaderMap>) -> (String, i64) {
    let source = headers
        .and_then(|h| h.get(SOURCE_HEADER))
        .map_or_else(|| "cluster".to_string(), |v| v.as_str().to_string());
    let received_ms = headers
        .and_then(|h| h.get(RECEIVED_HEADER))
        .and_then(|v| v.as_str().parse().ok())
        .unwrap_or_else(crate::pipeline::unix_ms);
    (source, received_ms)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_node_has_a_client_id_of_its_own_at_the_external_broker() {
        assert_eq!(
            node_mqtt_url("mqtt://broker:1883?client_id=site-1", "n2"),
            "mqtt://broker:1883?client_id=site-1-n2"
        );
        assert_eq!(
            node_mqtt_url("mqtt://u:p@broker:1883", "n2"),
            "mqtt://u:p@broker:1883?client_id=rtls-n2"
        );
        assert_eq!(
            node_mqtt_url("mqtts://broker:8883?ca_file=ca.pem&client_id=a", "n1"),
            "mqtts://broker:8883?ca_file=ca.pem&client_id=a-n1"
        );
    }

    #[test]
    fn records_are_grouped_by_partition_and_split_below_the_message_limit() {
        let long = "x".repeat(100_000);
        let lines: Vec<(usize, String)> = (0..12).map(|i| (i % 2, long.clone())).collect();
        let messages = messages_by_partition(lines);
        // 6 lines of 100 001 bytes per partition: 5 fit in 512 KiB, the sixth opens a second
        let shape: Vec<(usize, usize)> = messages.iter().map(|(p, _, n)| (*p, *n)).collect();
        assert_eq!(shape, vec![(0, 5), (1, 5), (0, 1), (1, 1)]);
        assert!(messages
            .iter()
            .all(|(_, payload, _)| payload.len() <= MAX_MESSAGE_BYTES));
    }
}
