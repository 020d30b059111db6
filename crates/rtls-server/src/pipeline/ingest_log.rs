//! The ingest-log thread: appends payloads to the store with group commit, dispatches their
//! records to the tag partitions in id order, and acknowledges them.
//!
//! The records go to the partitions once inserted, while their commit waits for the disk
//! ([`crate::store::Store::append_records_then_commit`]): a track update does not wait for the
//! fsync, the acknowledgement does. A partition whose queue is full then gets its batch after
//! the commit (the transaction holds SQLite's write lock, which the output thread needs to
//! drain the partitions). Should the commit fail, the records were tracked but are neither
//! stored nor acknowledged: the sender sends them again, and the tracker takes the repeats as
//! late or revised records.

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{SyncSender, TrySendError};
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
            let counts: Vec<usize> = batches.iter().map(|b| b.records.len()).collect();
            let mut records: Option<Vec<Record>> = Some(
                batches
                    .iter_mut()
                    .flat_map(|b| std::mem::take(&mut b.records))
                    .collect(),
            );
            // the records go to their partitions once inserted, while the commit waits for the
            // disk: a record's update does not wait for the fsync, its acknowledgement does
            let mut held_back = Vec::new();
            let (partitions, progress) = (&self.partitions, &self.progress);
            let mut dispatch_inserted = |ids: &[i64]| {
                if let Some(inserted) = records.take_if(|records| records.len() == ids.len()) {
                    let batches = partition_batches(inserted.into_iter().zip(ids.iter().copied()), partitions.len());
                    held_back = send_without_waiting(partitions, progress, batches);
                }
            };
            let stored = if rows.is_empty() {
                Ok(Vec::new())
            } else {
                self.store.append_records_then_commit(&rows, &mut dispatch_inserted)
            };
            // partitions whose queues were full get theirs now (the write lock is released);
            // after a failed commit too, as the others have theirs (the records are tracked
            // though not stored, and the sender, unacknowledged, sends them again)
            for (index, batch) in held_back {
                if self.partitions[index].send(PartitionInput::Records(batch)).is_err() {
                    tracing::error!(partition = index, "partition stopped; records not tracked");
                }
            }
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
            // acknowledge: the records are durable
            let mut then = Vec::new();
            for (batch, count) in batches.into_iter().zip(counts) {
                let _ = batch.reply.send(Ok(count));
                then.extend(batch.then);
            }
            debug_assert!(
                records.is_none() || ids.is_empty(),
                "every inserted record was dispatched"
            );
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
        let batches = partition_batches(records.into_iter().map(|(id, r)| (r, id)), self.partitions.len());
        for (index, batch) in send_without_waiting(&self.partitions, &self.progress, batches) {
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

/// Records (with their ingest-log ids, increasing) split by partition, each in id order;
/// partitions without records are left out.
fn partition_batches(records: impl Iterator<Item = (Record, i64)>, count: usize) -> Vec<(usize, PartitionBatch)> {
    let mut per_partition: Vec<PartitionBatch> = vec![Vec::new(); count];
    for (record, id) in records {
        per_partition[partition_of(&record.tag, count)].push((id, record));
    }
    per_partition
        .into_iter()
        .enumerate()
        .filter(|(_, batch)| !batch.is_empty())
        .collect()
}

/// Marks every batch dispatched, then sends each whose partition has room; returns the
/// others, to be sent by the caller (blocking). All are marked first, so the output
/// checkpoint ([`Progress::watermark`]) never passes a record still to be sent.
fn send_without_waiting(
    partitions: &[SyncSender<PartitionInput>],
    progress: &Progress,
    batches: Vec<(usize, PartitionBatch)>,
) -> Vec<(usize, PartitionBatch)> {
    for (index, batch) in &batches {
        if let Some(&(last_id, _)) = batch.last() {
            progress.dispatched[*index].fetch_max(last_id, Ordering::AcqRel);
        }
    }
    let mut full = Vec::new();
    for (index, batch) in batches {
        match partitions[index].try_send(PartitionInput::Records(batch)) {
            Ok(()) => {}
            Err(TrySendError::Full(PartitionInput::Records(batch))) => full.push((index, batch)),
            Err(TrySendError::Full(_)) => unreachable!("a batch of records comes back as one"),
            Err(TrySendError::Disconnected(_)) => {
                tracing::error!(partition = index, "partition stopped; records not tracked");
            }
        }
    }
    full
}
