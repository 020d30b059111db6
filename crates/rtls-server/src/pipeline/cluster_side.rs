//! The pipeline's side of a cluster (`crate::cluster`): the replicated ingest log it appends
//! to, the records a partition's stream delivers, partition warm-ups and resets, and the other
//! nodes' outputs.

use std::sync::Arc;

use rtls_engine::record::{parse_json_line, Record};
use tokio::sync::{mpsc, oneshot};

use super::fanout::PeerMessage;
use super::ingest_log::PartitionInput;
use super::{IngestBatch, Pipeline};
use crate::sink::{IngestError, IngestFuture};
use crate::store::NewRecord;

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

impl Pipeline {
    /// Notes a location a provider pushed, here and (in a cluster) on every node: the tag's
    /// track outputs keep what the provider said ([`crate::pushed`]).
    pub fn note_pushed(&self, pushed: crate::pushed::PushedLocation) {
        self.inner.fanout.to_peers(|| PeerMessage::Pushed {
            location: Box::new(pushed.location.clone()),
            time_s: pushed.time_s,
        });
        self.inner.live.note_pushed(pushed);
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

    /// Partition `index`'s state, encoded (a cluster's checkpoint): taken after every record
    /// already handed to the pipeline has reached the partition, so it holds each record
    /// [`Self::take_from_stream`] stored before this call.
    ///
    /// # Errors
    /// Why there is none (the server is stopping, the encoding failed).
    pub async fn checkpoint_partition(&self, index: usize) -> Result<Vec<u8>, String> {
        let (reply, _) = oneshot::channel();
        let (state, answer) = oneshot::channel();
        let sender = self.ingest_sender().map_err(|e| e.to_string())?;
        sender
            .send(IngestBatch {
                records: Vec::new(),
                rows: Vec::new(),
                reply,
                then: Some((index, PartitionInput::Checkpoint(state))),
            })
            .await
            .map_err(|_| "the server is shutting down".to_string())?;
        answer.await.map_err(|_| "the partition stopped".to_string())?
    }

    /// Makes partition `index` continue from an encoded checkpoint (a cluster's takeover);
    /// answers its track count.
    ///
    /// # Errors
    /// Why the checkpoint was not taken (see the partition's restore); the partition keeps
    /// its state then.
    pub async fn restore_partition(&self, index: usize, bytes: Vec<u8>) -> Result<usize, String> {
        let (reply, answer) = oneshot::channel();
        let pipeline = self.clone();
        tokio::task::spawn_blocking(move || pipeline.to_partition(index, PartitionInput::Restore(bytes, reply)))
            .await
            .map_err(|e| e.to_string())?;
        answer.await.map_err(|_| "the partition stopped".to_string())?
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
        let sender = self.ingest_sender()?;
        sender
            .send(IngestBatch {
                records,
                rows,
                reply,
                then: None,
            })
            .await
            .map_err(|_| IngestError::Unavailable("the server is shutting down".into()))?;
        answer
            .await
            .map_err(|_| IngestError::Unavailable("the ingest log stopped".into()))?
            .map(|_| count)
    }
}
