//! The ingest-log thread: appends payloads to the store with group commit, acknowledges them,
//! and dispatches their records to the tag partitions in id order.

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::mpsc::SyncSender;
use std::sync::Arc;

use rtls_engine::record::{parse_json_line, Record};
use tokio::sync::{mpsc, oneshot};

use super::{partition_of, quarantine, IngestBatch, Progress};
use crate::metrics::Metrics;
use crate::sink::IngestError;
use crate::store::Store;

/// Records (with their ingest-log ids) for one partition.
pub(super) type PartitionBatch = Vec<(i64, Record)>;

/// What a partition thread is sent.
pub(super) enum PartitionInput {
    /// Records to track and publish, in ingest-log order.
    Records(PartitionBatch),
    /// Records another node of the cluster tracked and stored already: they rebuild the
    /// tracks' state; nothing is published or stored for them.
    WarmUp(Vec<Record>),
    /// Forget every track: the partition moved to another node.
    Reset,
    /// Encode the partition's state (a cluster's checkpoint): it holds every record sent
    /// to the partition before this input.
    Checkpoint(oneshot::Sender<Result<Vec<u8>, String>>),
    /// Continue from an encoded checkpoint (a cluster's takeover); answers the track count.
    Restore(Vec<u8>, oneshot::Sender<Result<usize, String>>),
}

/// At most this many records are committed in one transaction.
const GROUP_COMMIT_RECORDS: usize = 20_000;
/// Records replayed per store query on start.
const REPLAY_PAGE: usize = 10_000;

pub(super) struct IngestLogWorker {
    pub store: Box<dyn Store>,
    pub rx: mpsc::Receiver<IngestBatch>,
    pub partitions: Vec<SyncSender<PartitionInput>>,
    pub progress: Arc<Progress>,
    pub metrics: Arc<Metrics>,
    /// Replay the ingest log after this id on start; `None` in a cluster (the ingest stream
    /// is the log there, and a partition's new owner warms up from it).
    pub replay_after_id: Option<i64>,
}

impl IngestLogWorker {
    pub fn run(mut self) {
        self.replay();
        while let Some(first) = self.rx.blocking_recv() {
            // group commit: every payload already waiting joins this transaction
            let mut batches = vec![first];
            let mut total = batches[0].rows.len();
            while total < GROUP_COMMIT_RECORDS {
                match self.rx.try_recv() {
                    Ok(batch) => {
                        total += batch.rows.len();
                        batches.push(batch);
                    }
                    Err(_) => break,
                }
            }
            let rows: Vec<_> = batches.iter_mut().flat_map(|b| std::mem::take(&mut b.rows)).collect();
            let stored = if rows.is_empty() {
                Ok(Vec::new())
            } else {
                self.store.append_records(&rows)
            };
            let ids = match stored {
                Ok(ids) if ids.len() == rows.len() => ids,
                Ok(ids) => {
                    let reason = format!("the store returned {} ids for {} records", ids.len(), rows.len());
                    self.fail(batches, &reason);
                    continue;
                }
                Err(e) => {
                    tracing::error!(error = %e, records = rows.len(), "ingest log append failed");
                    self.fail(batches, &e.to_string());
                    continue;
                }
            };
            self.metrics.ingest_records.inc_by(rows.len() as u64);
            self.metrics.ingest_commits.inc();
            // acknowledge first (the records are durable), then track them
            let mut ids = ids.into_iter();
            let mut records = Vec::with_capacity(rows.len());
            let mut then = Vec::new();
            for batch in batches {
                let count = batch.records.len();
                records.extend(batch.records.into_iter().zip(ids.by_ref()).map(|(r, id)| (id, r)));
                let _ = batch.reply.send(Ok(count));
                then.extend(batch.then);
            }
            self.dispatch(records);
            // after the records committed with them (a checkpoint holds them)
            for (index, input) in then {
                if let Some(partition) = self.partitions.get(index) {
                    let _ = partition.send(input);
                }
            }
        }
        tracing::info!("ingest log closed");
        // dropping the partition senders lets the partitions drain and stop
    }

    fn fail(&self, batches: Vec<IngestBatch>, reason: &str) {
        self.metrics.ingest_store_failures.inc();
        for batch in batches {
            let _ = batch.reply.send(Err(IngestError::Unavailable(format!(
                "storing the records failed: {reason}"
            ))));
        }
    }

    /// Sends records to their partitions, in id order; blocks while a partition is full
    /// (back-pressure reaches `submit` through the bounded ingest queue).
    fn dispatch(&self, records: Vec<(i64, Record)>) {
        let count = self.partitions.len();
        let mut per_partition: Vec<PartitionBatch> = vec![Vec::new(); count];
        for (id, record) in records {
            per_partition[partition_of(&record.tag, count)].push((id, record));
        }
        for (index, batch) in per_partition.into_iter().enumerate() {
            let Some(&(last_id, _)) = batch.last() else { continue };
            self.progress.dispatched[index].fetch_max(last_id, Ordering::AcqRel);
            if self.partitions[index].send(PartitionInput::Records(batch)).is_err() {
                tracing::error!(partition = index, "partition stopped; records not tracked");
            }
        }
    }

    /// Replays the ingest log after the checkpoint through the trackers.
    fn replay(&mut self) {
        let Some(replay_after_id) = self.replay_after_id else {
            return;
        };
        let mut after = replay_after_id;
        let mut replayed = 0usize;
        let mut skipped = 0usize;
        // a record that failed its partition before must not fail it again
        let quarantined = quarantine::quarantined_ids(self.store.as_mut()).unwrap_or_else(|e| {
            tracing::error!(error = %e, "reading the quarantined records failed; the replay skips none");
            HashSet::new()
        });
        loop {
            let page = match self.store.records_after(after, REPLAY_PAGE) {
                Ok(page) => page,
                Err(e) => {
                    tracing::error!(error = %e, after_id = after, "replay of the ingest log failed");
                    break;
                }
            };
            let Some(last) = page.last() else { break };
            after = last.id;
            let mut records = Vec::with_capacity(page.len());
            for stored in page {
                if quarantined.contains(&stored.id) {
                    skipped += 1;
                    continue;
                }
                match parse_json_line(&stored.json, "ingest log", 0) {
                    Ok(record) => records.push((stored.id, record)),
                    Err(e) => tracing::error!(id = stored.id, error = %e, "stored record does not parse; skipped"),
                }
            }
            replayed += records.len();
            self.dispatch(records);
        }
        if replayed > 0 || skipped > 0 {
            tracing::info!(
                records = replayed,
                quarantined_skipped = skipped,
                after_id = replay_after_id,
                "replayed the ingest log"
            );
        }
    }
}
