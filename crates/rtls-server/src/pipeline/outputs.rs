//! The output thread: stores track states and events, and the restart checkpoint.

use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::quarantine::{self, Quarantined, MAX_STORED_PER_RUN};
use super::{Progress, CHECKPOINT};
use crate::metrics::Metrics;
use crate::store::{EventRow, LocationRow, Store};

/// How often the checkpoint is written.
const CHECKPOINT_PERIOD: Duration = Duration::from_secs(1);
/// At most this many rows are written in one transaction.
const GROUP_ROWS: usize = 50_000;

/// What one partition produced from one batch of records.
pub(super) struct OutputBatch {
    pub partition: usize,
    /// The last ingest-log id the partition has taken, if the batch followed records.
    pub processed_id: Option<i64>,
    pub locations: Vec<LocationRow>,
    pub events: Vec<EventRow>,
    /// Records the partition's tracker failed on, to be stored apart.
    pub quarantined: Vec<Quarantined>,
}

pub(super) struct OutputWorker {
    pub store: Box<dyn Store>,
    pub rx: Receiver<OutputBatch>,
    pub progress: Arc<Progress>,
    pub metrics: Arc<Metrics>,
    /// Quarantined records stored in this run ([`MAX_STORED_PER_RUN`] at most).
    pub quarantine_stored: usize,
    /// Write the restart checkpoint (not in a cluster: the ingest stream's consumers are the
    /// checkpoints there, and the store is shared by every node).
    pub write_checkpoint: bool,
}

impl OutputWorker {
    pub fn run(mut self) {
        let mut last_checkpoint = Instant::now();
        let mut checkpointed = i64::MIN;
        loop {
            let first = match self.rx.recv_timeout(CHECKPOINT_PERIOD) {
                Ok(batch) => Some(batch),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => break,
            };
            let mut batches: Vec<OutputBatch> = first.into_iter().collect();
            let mut rows: usize = batches.iter().map(|b| b.locations.len() + b.events.len()).sum();
            while rows < GROUP_ROWS {
                match self.rx.try_recv() {
                    Ok(batch) => {
                        rows += batch.locations.len() + batch.events.len();
                        batches.push(batch);
                    }
                    Err(_) => break,
                }
            }
            if !batches.is_empty() {
                self.store_batches(batches);
            }
            if last_checkpoint.elapsed() >= CHECKPOINT_PERIOD {
                last_checkpoint = Instant::now();
                checkpointed = self.checkpoint(checkpointed);
            }
        }
        self.checkpoint(checkpointed);
        tracing::info!("output thread stopped");
    }

    fn store_batches(&mut self, batches: Vec<OutputBatch>) {
        // move the rows out (no copies); keep which partitions they complete
        let mut processed = Vec::with_capacity(batches.len());
        let mut locations = Vec::new();
        let mut events = Vec::new();
        let mut quarantined = Vec::new();
        for batch in batches {
            processed.push((batch.partition, batch.processed_id));
            locations.extend(batch.locations);
            events.extend(batch.events);
            quarantined.extend(batch.quarantined);
        }
        self.store_quarantined(&quarantined);
        let result = self
            .store
            .append_locations(&locations)
            .and_then(|()| self.store.append_events(&events));
        match result {
            Ok(()) => {
                self.metrics.stored_locations.inc_by(locations.len() as u64);
                self.metrics.stored_events.inc_by(events.len() as u64);
                for (partition, id) in processed {
                    if let Some(id) = id {
                        self.progress.stored[partition].fetch_max(id, Ordering::AcqRel);
                    }
                }
            }
            Err(e) => {
                // the records are in the ingest log: the checkpoint stays behind them, so a
                // restart replays them and regenerates these outputs
                self.metrics.output_store_failures.inc();
                tracing::error!(error = %e, locations = locations.len(), events = events.len(), "storing outputs failed");
            }
        }
    }

    /// Stores quarantined records apart — before the outputs, so that the checkpoint can pass
    /// them only once a restart would skip them — up to [`MAX_STORED_PER_RUN`] per run.
    fn store_quarantined(&mut self, quarantined: &[Quarantined]) {
        if quarantined.is_empty() {
            return;
        }
        let room = MAX_STORED_PER_RUN.saturating_sub(self.quarantine_stored);
        let (kept, dropped) = quarantined.split_at(room.min(quarantined.len()));
        if !dropped.is_empty() {
            tracing::error!(
                records = dropped.len(),
                limit = MAX_STORED_PER_RUN,
                "quarantined records not stored: this run's limit is reached (they are counted and logged)"
            );
        }
        match quarantine::store(self.store.as_mut(), kept) {
            Ok(()) => self.quarantine_stored += kept.len(),
            Err(e) => tracing::error!(error = %e, records = kept.len(), "storing quarantined records failed"),
        }
    }

    fn checkpoint(&mut self, previous: i64) -> i64 {
        if !self.write_checkpoint {
            return previous;
        }
        let watermark = self.progress.watermark();
        if watermark <= previous {
            return previous;
        }
        match self.store.set_checkpoint(CHECKPOINT, watermark) {
            Ok(()) => watermark,
            Err(e) => {
                tracing::error!(error = %e, "writing the checkpoint failed");
                previous
            }
        }
    }
}
