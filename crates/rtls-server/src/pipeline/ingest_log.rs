//! The ingest log: payloads are appended to the store with group commit, their records
//! dispatched to the tag partitions in id order, and acknowledged once committed.
//!
//! One node (the store's ingest log is this process's alone): two threads. The dispatcher
//! ([`DispatchWorker`]) takes each payload off the ingest queue as it comes, gives its records
//! the next ingest-log ids, counted in memory, and sends them to their partitions at once; the
//! committer ([`CommitWorker`]) inserts them under those ids, commits (group commit: every
//! payload waiting joins the transaction) and acknowledges. A track update waits neither for
//! the insert nor for the fsync, nor for the commit of the group before; the acknowledgement
//! waits for its commit. Should a commit fail, its records were tracked but are neither stored
//! nor acknowledged: the sender sends them again (under new ids; the failed ones stay a gap),
//! and the tracker takes the repeats as late or revised records. The dispatcher never holds
//! the database's write lock, so it may wait for a full partition (the output thread, which
//! drains the partitions, needs that lock); the committer never waits for a partition while it
//! holds the lock.
//!
//! A cluster (`rtls serve --cluster`: the nodes share the store, the replicated stream is the
//! log): one thread ([`SharedLogWorker`]); the ids come from the store's sequence, so records
//! go to their partitions once inserted, while the commit waits for the disk
//! ([`crate::store::Store::append_records_then_commit`]).

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
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

/// At most this many records are committed in one transaction (and dispatched at once).
const GROUP_COMMIT_RECORDS: usize = 20_000;
/// At most this many records go to a partition in one batch ([`chunked`]).
pub(super) const PARTITION_BATCH_RECORDS: usize = 1_024;
/// Records replayed per store query on start.
const REPLAY_PAGE: usize = 10_000;
/// Groups of payloads dispatched and waiting for their commit: with the ingest queue before
/// it, this bounds how far tracking runs ahead of the store (a full queue stops the
/// dispatcher, and back-pressure reaches `submit`).
pub(super) const COMMIT_QUEUE_GROUPS: usize = 16;

/// Payloads whose records were dispatched under the ids from `first_id` on (consecutive, in
/// the payloads' order), for the committer.
pub(super) struct Dispatched {
    first_id: i64,
    batches: Vec<IngestBatch>,
}

/// One node's dispatcher: ids in memory, records to their partitions before they are stored.
pub(super) struct DispatchWorker {
    pub rx: mpsc::Receiver<IngestBatch>,
    pub partitions: Vec<SyncSender<PartitionInput>>,
    pub progress: Arc<Progress>,
    /// The first id to give, sent by the committer once the replay is done (the replayed
    /// records go to the partitions first).
    pub first_id: Receiver<i64>,
    pub commits: SyncSender<Dispatched>,
}

impl DispatchWorker {
    pub fn run(mut self) {
        let Ok(mut next_id) = self.first_id.recv() else {
            tracing::error!("the ingest log's committer stopped before the replay ended; no records are taken");
            return;
        };
        while let Some(mut batches) = take_group(&mut self.rx) {
            let first_id = next_id;
            let mut records = Vec::new();
            for batch in &mut batches {
                debug_assert_eq!(batch.records.len(), batch.rows.len(), "a row per record");
                for record in std::mem::take(&mut batch.records) {
                    records.push((record, next_id));
                    next_id += 1;
                }
            }
            dispatch(
                &self.partitions,
                &self.progress,
                partition_batches(records.into_iter(), self.partitions.len()),
            );
            if self.commits.send(Dispatched { first_id, batches }).is_err() {
                // their senders hear that the log stopped; nothing more is tracked unstored
                tracing::error!("the ingest log's committer stopped; no more records are taken");
                return;
            }
        }
        tracing::info!("ingest log closed");
        // dropping the committer's queue lets it commit what it has and stop
    }
}

/// One node's committer: replays the log on start, then stores dispatched records under their
/// ids, commits and acknowledges them.
pub(super) struct CommitWorker {
    pub store: Box<dyn Store>,
    pub rx: Receiver<Dispatched>,
    pub partitions: Vec<SyncSender<PartitionInput>>,
    pub progress: Arc<Progress>,
    pub metrics: Arc<Metrics>,
    /// The output checkpoint: the log is replayed after it.
    pub replay_after_id: i64,
    /// The store's [`Store::last_record_id`] at start.
    pub last_record_id: i64,
    /// Where the dispatcher learns its first id.
    pub first_id: SyncSender<i64>,
}

impl CommitWorker {
    pub fn run(mut self) {
        let quarantined = replay(
            self.store.as_mut(),
            &self.partitions,
            &self.progress,
            self.replay_after_id,
        );
        // above every id the log gave out, the checkpoint, and every quarantined record's id:
        // the ids of records tracked whose commit failed before a restart are not given again
        let first_id = self
            .last_record_id
            .max(self.replay_after_id)
            .max(quarantined.into_iter().max().unwrap_or(0))
            + 1;
        if self.first_id.send(first_id).is_err() {
            return;
        }
        while let Ok(first) = self.rx.recv() {
            let mut group = vec![first];
            let mut total = group[0].batches.iter().map(|b| b.rows.len()).sum::<usize>();
            while total < GROUP_COMMIT_RECORDS {
                match self.rx.try_recv() {
                    Ok(dispatched) => {
                        total += dispatched.batches.iter().map(|b| b.rows.len()).sum::<usize>();
                        group.push(dispatched);
                    }
                    Err(_) => break,
                }
            }
            let mut ids = Vec::with_capacity(total);
            let mut rows = Vec::with_capacity(total);
            let mut batches = Vec::new();
            let mut counts = Vec::new();
            for dispatched in group {
                let mut id = dispatched.first_id;
                for mut batch in dispatched.batches {
                    counts.push(batch.rows.len());
                    for row in std::mem::take(&mut batch.rows) {
                        ids.push(id);
                        rows.push(row);
                        id += 1;
                    }
                    batches.push(batch);
                }
            }
            debug_assert!(ids.windows(2).all(|pair| pair[0] < pair[1]), "ids increase");
            match self.store.append_records_with_ids(&ids, &rows) {
                Ok(()) => acknowledge(&self.partitions, &self.metrics, batches, counts),
                Err(e) => {
                    tracing::error!(error = %e, records = rows.len(), "ingest log append failed");
                    fail(&self.metrics, batches, &e.to_string());
                }
            }
        }
        // dropping the partition senders (with the dispatcher's) lets the partitions drain
    }
}

/// A cluster's ingest-log thread: the store gives the ids, so records go to their partitions
/// once inserted, during the commit.
pub(super) struct SharedLogWorker {
    pub store: Box<dyn Store>,
    pub rx: mpsc::Receiver<IngestBatch>,
    pub partitions: Vec<SyncSender<PartitionInput>>,
    pub progress: Arc<Progress>,
    pub metrics: Arc<Metrics>,
}

impl SharedLogWorker {
    pub fn run(mut self) {
        while let Some(mut batches) = take_group(&mut self.rx) {
            let counts: Vec<usize> = batches.iter().map(|b| b.records.len()).collect();
            let rows: Vec<_> = batches.iter_mut().flat_map(|b| std::mem::take(&mut b.rows)).collect();
            let mut records: Option<Vec<Record>> = Some(
                batches
                    .iter_mut()
                    .flat_map(|b| std::mem::take(&mut b.records))
                    .collect(),
            );
            // the records go to their partitions once inserted, while the commit waits for the
            // disk; a full partition gets its batch after the commit (the transaction holds
            // the write lock, which the output thread needs to drain the partitions)
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
            // after a failed commit too, as the others have theirs (the records are tracked
            // though not stored, and the sender, unacknowledged, sends them again)
            send_waiting(&self.partitions, held_back);
            match stored {
                Ok(ids) if ids.len() == rows.len() => {
                    debug_assert!(
                        records.is_none() || ids.is_empty(),
                        "every inserted record was dispatched"
                    );
                    acknowledge(&self.partitions, &self.metrics, batches, counts);
                }
                Ok(ids) => {
                    let reason = format!("the store returned {} ids for {} records", ids.len(), rows.len());
                    fail(&self.metrics, batches, &reason);
                }
                Err(e) => {
                    tracing::error!(error = %e, records = rows.len(), "ingest log append failed");
                    fail(&self.metrics, batches, &e.to_string());
                }
            }
        }
        tracing::info!("ingest log closed");
        // dropping the partition senders lets the partitions drain and stop
    }
}

/// The next payload and every one already waiting behind it, up to [`GROUP_COMMIT_RECORDS`]
/// records; `None` once the queue is closed and empty.
fn take_group(rx: &mut mpsc::Receiver<IngestBatch>) -> Option<Vec<IngestBatch>> {
    let first = rx.blocking_recv()?;
    let mut total = first.rows.len();
    let mut batches = vec![first];
    while total < GROUP_COMMIT_RECORDS {
        match rx.try_recv() {
            Ok(batch) => {
                total += batch.rows.len();
                batches.push(batch);
            }
            Err(_) => break,
        }
    }
    Some(batches)
}

/// Acknowledges committed payloads (their records are durable), then sends the partitions
/// the inputs that were to follow them (a checkpoint then holds their records).
fn acknowledge(
    partitions: &[SyncSender<PartitionInput>],
    metrics: &Metrics,
    batches: Vec<IngestBatch>,
    counts: Vec<usize>,
) {
    let records: usize = counts.iter().sum();
    metrics.ingest_records.inc_by(records as u64);
    metrics.ingest_commits.inc();
    let mut then = Vec::new();
    for (batch, count) in batches.into_iter().zip(counts) {
        let _ = batch.reply.send(Ok(count));
        then.extend(batch.then);
    }
    for (index, input) in then {
        if let Some(partition) = partitions.get(index) {
            let _ = partition.send(input);
        }
    }
}

/// Answers payloads whose commit failed: not stored, so not acknowledged.
fn fail(metrics: &Metrics, batches: Vec<IngestBatch>, reason: &str) {
    metrics.ingest_store_failures.inc();
    for batch in batches {
        let _ = batch.reply.send(Err(IngestError::Unavailable(format!(
            "storing the records failed: {reason}"
        ))));
    }
}

/// Sends records to their partitions, in id order; blocks while a partition is full (never
/// with the database's write lock held: back-pressure reaches `submit` through the bounded
/// ingest queue).
fn dispatch(partitions: &[SyncSender<PartitionInput>], progress: &Progress, batches: Vec<(usize, PartitionBatch)>) {
    let full = send_without_waiting(partitions, progress, chunked(batches));
    send_waiting(partitions, full);
}

/// Sends each batch, waiting while its partition is full.
fn send_waiting(partitions: &[SyncSender<PartitionInput>], batches: Vec<(usize, PartitionBatch)>) {
    for (index, batch) in batches {
        if partitions[index].send(PartitionInput::Records(batch)).is_err() {
            tracing::error!(partition = index, "partition stopped; records not tracked");
        }
    }
}

/// Each partition's records in batches of at most [`PARTITION_BATCH_RECORDS`], in order: a
/// partition's queue is bounded in batches, so a batch's size bounds the records waiting for
/// it (a commit group of 20 000 records would otherwise make 256 queued batches seconds of
/// backlog and gigabytes of memory under overload).
fn chunked(batches: Vec<(usize, PartitionBatch)>) -> Vec<(usize, PartitionBatch)> {
    if batches.iter().all(|(_, batch)| batch.len() <= PARTITION_BATCH_RECORDS) {
        return batches;
    }
    let mut chunks = Vec::new();
    for (index, mut batch) in batches {
        while batch.len() > PARTITION_BATCH_RECORDS {
            let rest = batch.split_off(PARTITION_BATCH_RECORDS);
            chunks.push((index, std::mem::replace(&mut batch, rest)));
        }
        chunks.push((index, batch));
    }
    chunks
}

/// Replays the ingest log after `after_id` through the trackers; returns the ids of the
/// quarantined records (which it skips: a record that failed its partition before must not
/// fail it again).
fn replay(
    store: &mut dyn Store,
    partitions: &[SyncSender<PartitionInput>],
    progress: &Progress,
    after_id: i64,
) -> HashSet<i64> {
    let mut after = after_id;
    let mut replayed = 0usize;
    let mut skipped = 0usize;
    let quarantined = quarantine::quarantined_ids(store).unwrap_or_else(|e| {
        tracing::error!(error = %e, "reading the quarantined records failed; the replay skips none");
        HashSet::new()
    });
    loop {
        let page = match store.records_after(after, REPLAY_PAGE) {
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
                Ok(record) => records.push((record, stored.id)),
                Err(e) => tracing::error!(id = stored.id, error = %e, "stored record does not parse; skipped"),
            }
        }
        replayed += records.len();
        dispatch(
            partitions,
            progress,
            partition_batches(records.into_iter(), partitions.len()),
        );
    }
    if replayed > 0 || skipped > 0 {
        tracing::info!(
            records = replayed,
            quarantined_skipped = skipped,
            after_id,
            "replayed the ingest log"
        );
    }
    quarantined
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
    // behind a batch that found its partition full, the partition's later batches wait too
    // (in order)
    let mut blocked = vec![false; partitions.len()];
    for (index, batch) in batches {
        if blocked[index] {
            full.push((index, batch));
            continue;
        }
        match partitions[index].try_send(PartitionInput::Records(batch)) {
            Ok(()) => {}
            Err(TrySendError::Full(PartitionInput::Records(batch))) => {
                blocked[index] = true;
                full.push((index, batch));
            }
            Err(TrySendError::Full(_)) => unreachable!("a batch of records comes back as one"),
            Err(TrySendError::Disconnected(_)) => {
                tracing::error!(partition = index, "partition stopped; records not tracked");
            }
        }
    }
    full
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_engine::record::Measurement;

    fn batch(first_id: i64, n: usize) -> PartitionBatch {
        (0..n as i64)
            .map(|k| {
                let record = Record {
                    time_s: k as f64,
                    tag: "t".into(),
                    measurement: Measurement::Fix {
                        position_m: vec![0.0, 0.0],
                        covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
                    },
                };
                (first_id + k, record)
            })
            .collect()
    }

    #[test]
    fn a_large_batch_goes_to_its_partition_in_bounded_chunks_in_order() {
        let n = 2 * PARTITION_BATCH_RECORDS + 5;
        let chunks = chunked(vec![(0, batch(1, n)), (1, batch(10_000, 3))]);
        let sizes: Vec<(usize, usize)> = chunks.iter().map(|(p, b)| (*p, b.len())).collect();
        assert_eq!(
            sizes,
            vec![
                (0, PARTITION_BATCH_RECORDS),
                (0, PARTITION_BATCH_RECORDS),
                (0, 5),
                (1, 3)
            ]
        );
        let ids: Vec<i64> = chunks
            .iter()
            .filter(|(p, _)| *p == 0)
            .flat_map(|(_, b)| b.iter().map(|(id, _)| *id))
            .collect();
        assert_eq!(ids, (1..=n as i64).collect::<Vec<_>>());
    }

    #[test]
    fn behind_a_full_partition_its_later_batches_wait_in_order() {
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let progress = Progress::new(1, 0);
        // the queue holds one batch: the first goes, the second finds it full, and the third
        // must wait behind it even when the partition makes room in between
        let full = send_without_waiting(
            std::slice::from_ref(&tx),
            &progress,
            vec![(0, batch(1, 2)), (0, batch(3, 2)), (0, batch(5, 2))],
        );
        let waiting: Vec<i64> = full.iter().map(|(_, b)| b[0].0).collect();
        assert_eq!(waiting, vec![3, 5]);
        assert!(matches!(rx.try_recv(), Ok(PartitionInput::Records(b)) if b[0].0 == 1));
    }
}
