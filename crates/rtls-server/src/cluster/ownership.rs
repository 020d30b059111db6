//! Which node runs which partition: leases in the `rtls_leases` bucket, renewed by their
//! owner, claimed up to each live node's fair share; the nodes' heartbeats on core NATS say
//! which owners are alive.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_nats::jetstream::kv::{Operation, UpdateErrorKind};
use bytes::Bytes;
use futures_util::StreamExt;
use tokio::sync::watch;
use tokio::task::JoinHandle;

use super::{consumer, Cluster, HEARTBEAT_SUBJECT};
use crate::pipeline::Pipeline;

/// A partition this node holds.
struct Owned {
    /// The lease entry's revision (the next renewal's expected one).
    revision: u64,
    /// When the last renewal was sent that succeeded.
    renewed: Instant,
    stop: watch::Sender<bool>,
    task: JoinHandle<()>,
}

/// Leases, node announcements and the partitions' consumers of this node.
pub struct Ownership {
    cluster: Cluster,
    pipeline: Pipeline,
    owned: BTreeMap<usize, Owned>,
    /// When each other node was last heard (its heartbeats on `rtls.nodes.<node>`).
    heard: Arc<Mutex<HashMap<String, Instant>>>,
    /// When this node started: it takes no lease from a silent owner before it could have
    /// heard that owner.
    started: Instant,
}

/// The fair share of `partitions` among `nodes` live nodes: ⌈partitions / nodes⌉.
#[must_use]
pub fn fair_share(partitions: usize, nodes: usize) -> usize {
    partitions.div_ceil(nodes.max(1))
}

impl Ownership {
    /// This node's ownership, owning nothing yet.
    #[must_use]
    pub fn new(cluster: Cluster, pipeline: Pipeline) -> Self {
        Self {
            cluster,
            pipeline,
            owned: BTreeMap::new(),
            heard: Arc::default(),
            started: Instant::now(),
        }
    }

    /// Runs rounds every quarter of `failover_s` until `shutdown`, then hands every partition
    /// back (its records acknowledged so far stay acknowledged; the next owner starts there).
    pub async fn run(mut self, mut shutdown: watch::Receiver<bool>) {
        let round = self.cluster.settings.failover().mul_f64(0.25);
        let listener = match self.cluster.client.subscribe(format!("{HEARTBEAT_SUBJECT}.*")).await {
            Ok(mut heartbeats) => {
                let heard = Arc::clone(&self.heard);
                let prefix = format!("{HEARTBEAT_SUBJECT}.");
                Some(tokio::spawn(async move {
                    while let Some(beat) = heartbeats.next().await {
                        if let Some(node) = beat.subject.as_str().strip_prefix(&prefix) {
                            if let Ok(mut heard) = heard.lock() {
                                heard.insert(node.to_string(), Instant::now());
                            }
                        }
                    }
                }))
            }
            Err(e) => {
                tracing::error!(error = %e, "the nodes' heartbeats cannot be heard; this node takes free partitions only");
                None
            }
        };
        loop {
            self.round().await;
            tokio::select! {
                () = tokio::time::sleep(round) => {}
                _ = shutdown.changed() => break,
            }
        }
        let partitions: Vec<usize> = self.owned.keys().copied().collect();
        for partition in partitions {
            self.release(partition, "shutdown").await;
        }
        if let Some(listener) = listener {
            listener.abort();
        }
    }

    async fn round(&mut self) {
        let beat = format!("{HEARTBEAT_SUBJECT}.{}", self.cluster.node);
        if let Err(e) = self.cluster.client.publish(beat, Bytes::new()).await {
            tracing::warn!(error = %e, "this node's heartbeat was not sent");
        }
        let nodes = 1 + self.live_peers();
        self.renew().await;
        self.reap_finished().await;
        let fair = fair_share(self.cluster.settings.partitions, nodes);
        if self.owned.len() > fair {
            // a node joined: give one back a round, so the others pick them up evenly
            if let Some(&partition) = self.owned.keys().next_back() {
                self.release(partition, "rebalance").await;
            }
        } else if self.owned.len() < fair {
            self.claim(fair).await;
        }
        self.pipeline
            .metrics()
            .cluster_partitions_owned
            .set(i64::try_from(self.owned.len()).unwrap_or(i64::MAX));
        self.pipeline
            .set_cluster_status(&self.cluster.node, self.owned.keys().copied().collect());
    }

    /// The other nodes heard within `failover_s`.
    fn live_peers(&self) -> usize {
        let failover = self.cluster.settings.failover();
        self.heard.lock().map_or(0, |heard| {
            heard
                .iter()
                .filter(|(node, at)| **node != self.cluster.node && at.elapsed() < failover)
                .count()
        })
    }

    /// Whether `node` was heard within `failover_s` (this node is).
    fn alive(&self, node: &str) -> bool {
        node == self.cluster.node
            || self.heard.lock().is_ok_and(|heard| {
                heard
                    .get(node)
                    .is_some_and(|at| at.elapsed() < self.cluster.settings.failover())
            })
    }

    /// Renews every lease; a lease another node holds now, or one not renewed for a TTL, is
    /// given up at once (its consumer stops).
    async fn renew(&mut self) {
        let ttl = self.cluster.settings.lease_ttl();
        let mut lost = Vec::new();
        for (&partition, owned) in &mut self.owned {
            let sent = Instant::now();
            match self
                .cluster
                .leases
                .update(
                    lease_key(partition),
                    Bytes::from(self.cluster.node.clone()),
                    owned.revision,
                )
                .await
            {
                Ok(revision) => {
                    owned.revision = revision;
                    owned.renewed = sent;
                }
                Err(e) if e.kind() == UpdateErrorKind::WrongLastRevision => {
                    // a renewal that NATS retried, or an entry that expired while NATS could
                    // not be reached (a server died and its streams elected new leaders): still
                    // ours if the entry says so, or if nobody took it meanwhile
                    match reclaim(&self.cluster, partition).await {
                        Some(revision) => {
                            owned.revision = revision;
                            owned.renewed = sent;
                        }
                        None => lost.push((partition, e.to_string())),
                    }
                }
                Err(e) if owned.renewed.elapsed() >= ttl.mul_f64(0.8) => lost.push((partition, e.to_string())),
                Err(e) => tracing::warn!(partition, error = %e, "renewing a lease failed; retrying"),
            }
        }
        for (partition, reason) in lost {
            tracing::warn!(partition, reason, "partition lease lost");
            self.stop(partition, false).await;
        }
    }

    /// Partitions whose consumer ended on its own (the stream failed): their lease is given up
    /// so that a node that can read the stream takes them.
    async fn reap_finished(&mut self) {
        let finished: Vec<usize> = self
            .owned
            .iter()
            .filter(|(_, o)| o.task.is_finished())
            .map(|(&p, _)| p)
            .collect();
        for partition in finished {
            self.release(partition, "consumer stopped").await;
        }
    }

    /// Claims partitions up to `fair`: free ones, and those of owners silent for `failover_s`
    /// (by compare-and-set on the lease's revision, so that two nodes cannot both take one).
    /// It starts at a place of this node's own, so that nodes starting together do not all race
    /// for the same keys.
    async fn claim(&mut self, fair: usize) {
        let count = self.cluster.settings.partitions;
        let offset = self
            .cluster
            .node
            .bytes()
            .fold(0usize, |h, b| h.wrapping_mul(31).wrapping_add(usize::from(b)))
            % count;
        let me = Bytes::from(self.cluster.node.clone());
        let may_take = self.started.elapsed() >= self.cluster.settings.failover();
        for step in 0..count {
            if self.owned.len() >= fair {
                break;
            }
            let partition = (offset + step) % count;
            if self.owned.contains_key(&partition) {
                continue;
            }
            let key = lease_key(partition);
            let claimed = match self.cluster.leases.entry(key.clone()).await {
                Ok(Some(entry)) if entry.operation == Operation::Put => {
                    let owner = String::from_utf8_lossy(&entry.value).into_owned();
                    if owner != self.cluster.node && (!may_take || self.alive(&owner)) {
                        continue;
                    }
                    tracing::info!(partition, from = %owner, "taking over the lease of a silent node");
                    self.cluster.leases.update(&key, me.clone(), entry.revision).await.ok()
                }
                Ok(_) => self.cluster.leases.create(&key, me.clone()).await.ok(),
                Err(_) => None,
            };
            if let Some(revision) = claimed {
                self.start(partition, revision);
            }
        }
    }

    fn start(&mut self, partition: usize, revision: u64) {
        let (stop, stopped) = watch::channel(false);
        let (cluster, pipeline) = (self.cluster.clone(), self.pipeline.clone());
        let task = tokio::spawn(async move {
            if let Err(e) = consumer::run(cluster, pipeline, partition, stopped).await {
                tracing::error!(partition, error = %e, "the partition's consumer failed");
            }
        });
        self.pipeline.metrics().cluster_takeovers.inc();
        tracing::info!(partition, node = %self.cluster.node, "partition lease won");
        self.owned.insert(
            partition,
            Owned {
                revision,
                renewed: Instant::now(),
                stop,
                task,
            },
        );
    }

    /// Stops the partition's consumer (its in-flight batch is stored and acknowledged first),
    /// resets its tracker and, when `hand_back`, deletes the lease so another node takes it at
    /// once.
    async fn stop(&mut self, partition: usize, hand_back: bool) {
        let Some(owned) = self.owned.remove(&partition) else {
            return;
        };
        let _ = owned.stop.send(true);
        let mut task = owned.task;
        if tokio::time::timeout(Duration::from_secs(10), &mut task).await.is_err() {
            tracing::error!(partition, "the partition's consumer did not stop in 10 s; aborted");
            task.abort();
        }
        let pipeline = self.pipeline.clone();
        let _ = tokio::task::spawn_blocking(move || pipeline.reset_partition(partition)).await;
        if hand_back {
            // only the entry this node wrote: a lease another node won since stays theirs
            if let Err(e) = self
                .cluster
                .leases
                .delete_expect_revision(lease_key(partition), Some(owned.revision))
                .await
            {
                tracing::warn!(partition, error = %e, "handing the lease back failed; it expires");
            }
        }
        self.pipeline.metrics().cluster_releases.inc();
    }

    async fn release(&mut self, partition: usize, why: &str) {
        tracing::info!(partition, why, "partition released");
        self.stop(partition, true).await;
    }
}

/// The lease's revision when the entry still names this node, or when it is gone and this
/// node could create it again; `None` when another node holds it.
async fn reclaim(cluster: &Cluster, partition: usize) -> Option<u64> {
    let key = lease_key(partition);
    match cluster.leases.entry(key.clone()).await {
        Ok(Some(entry)) if entry.operation == Operation::Put => {
            (entry.value.as_ref() == cluster.node.as_bytes()).then_some(entry.revision)
        }
        Ok(_) => cluster
            .leases
            .create(&key, Bytes::from(cluster.node.clone()))
            .await
            .ok(),
        Err(_) => None,
    }
}

/// The lease key of a partition.
fn lease_key(partition: usize) -> String {
    format!("p{partition}")
}

#[cfg(test)]
mod tests {
    use super::fair_share;

    #[test]
    fn every_partition_has_room_among_the_live_nodes() {
        for partitions in 1..40 {
            for nodes in 1..8 {
                let fair = fair_share(partitions, nodes);
                assert!(fair * nodes >= partitions, "{partitions} / {nodes}");
                assert!((fair - 1) * nodes < partitions, "{partitions} / {nodes}: not the least");
            }
        }
        assert_eq!(fair_share(12, 0), 12);
    }
}
