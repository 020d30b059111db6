//! The server's periodic maintenance of the store: compaction of old rows into blocks, and
//! retention.

use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::http::QueryStore;
use crate::metrics::Metrics;
use crate::pipeline::unix_ms;

/// How often retention runs.
const RETENTION_PERIOD: Duration = Duration::from_secs(3600);

/// Track states and tracked records packed per compaction transaction (the query connection
/// is free between two).
const COMPACTION_CHUNK_ROWS: usize = 100_000;

/// Packs track states and tracked raw records older than `compact_after_s` into compressed
/// blocks, every `compact_after_s` (store/history_blocks.rs, store/log_blocks.rs).
pub(super) async fn compaction(
    queries: Arc<Mutex<QueryStore>>,
    metrics: Arc<Metrics>,
    compact_after_s: f64,
    stopped: impl Future<Output = ()>,
) {
    let counter = |kind: &str| {
        metrics
            .store_compacted
            .get_or_create(&vec![("kind".to_owned(), kind.to_owned())])
            .clone()
    };
    let (states_packed, records_packed) = (counter("states"), counter("records"));
    tokio::pin!(stopped);
    let period = Duration::from_secs_f64(compact_after_s);
    loop {
        tokio::select! {
            () = &mut stopped => return,
            () = tokio::time::sleep(period) => {}
        }
        let before_ms = unix_ms() - (compact_after_s * 1000.0) as i64;
        let (mut states, mut records) = (0u64, 0u64);
        let started = Instant::now();
        loop {
            let store = Arc::clone(&queries);
            let packing = tokio::task::spawn_blocking(move || match store.lock() {
                Ok(mut store) => store.compact(before_ms, COMPACTION_CHUNK_ROWS),
                Err(_) => Err("the query store's lock is poisoned".to_owned()),
            });
            // a shutdown does not wait for the rest of the pass (each chunk is a transaction
            // of its own: what is packed is committed, the rest waits for the next start)
            let chunk = tokio::select! {
                biased;
                () = &mut stopped => return,
                chunk = packing => chunk,
            };
            match chunk {
                Ok(Ok((0, 0))) => break,
                Ok(Ok((packed_states, packed_records))) => {
                    states += packed_states;
                    records += packed_records;
                    states_packed.inc_by(packed_states);
                    records_packed.inc_by(packed_records);
                }
                Ok(Err(e)) => {
                    metrics.store_compaction_failures.inc();
                    tracing::error!(error = %e, "compaction failed; the rows stay as they are");
                    break;
                }
                Err(e) => {
                    metrics.store_compaction_failures.inc();
                    tracing::error!(error = %e, "compaction task failed");
                    break;
                }
            }
        }
        if states + records > 0 {
            let elapsed_ms = started.elapsed().as_millis() as u64;
            tracing::info!(
                states,
                records,
                elapsed_ms,
                compact_after_s,
                "compacted history and ingest log into blocks"
            );
        }
    }
}

/// Deletes what is older than the retention period, and raw records older than theirs, hourly.
pub(super) async fn retention(
    queries: Arc<Mutex<QueryStore>>,
    retention_days: f64,
    raw_retention_days: f64,
    stopped: impl Future<Output = ()>,
) {
    tokio::pin!(stopped);
    loop {
        let cutoff_ms = unix_ms() - (retention_days * 86_400_000.0) as i64;
        let raw_cutoff_ms = unix_ms() - (raw_retention_days * 86_400_000.0) as i64;
        let store = Arc::clone(&queries);
        let pruned = tokio::task::spawn_blocking(move || match store.lock() {
            Ok(mut store) => {
                match store.prune_ingest_log(raw_cutoff_ms) {
                    Ok(records) if records > 0 => {
                        tracing::info!(
                            records,
                            raw_retention_days,
                            "raw-record retention pruned the ingest log"
                        );
                    }
                    Ok(_) => {}
                    Err(e) => tracing::error!(error = %e, "raw-record retention failed"),
                }
                Ok(store.prune(cutoff_ms))
            }
            Err(_) => Err(()),
        })
        .await;
        match pruned {
            Ok(Ok(Ok(p))) if p.records + p.locations + p.events > 0 => {
                tracing::info!(
                    records = p.records,
                    locations = p.locations,
                    events = p.events,
                    retention_days,
                    "retention pruned"
                );
            }
            Ok(Ok(Err(e))) => tracing::error!(error = %e, "retention failed"),
            _ => {}
        }
        tokio::select! {
            () = &mut stopped => return,
            () = tokio::time::sleep(RETENTION_PERIOD) => {}
        }
    }
}
