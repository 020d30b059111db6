//! The ingest log of one node: records reach their trackers before they are stored, and are
//! acknowledged only once committed; a failed commit is not acknowledged and its ids are not
//! given out again, nor are ids at or below the checkpoint or a quarantined record's after a
//! restart.

mod common;

use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::time::Duration;

use rtls_server::metrics::Metrics;
use rtls_server::pipeline::{Pipeline, PipelineConfig, CHECKPOINT, QUARANTINE};
use rtls_server::sink::IngestError;
use rtls_server::store::{
    EventQuery, EventRow, HistoryQuery, LocationRow, NewRecord, Pruned, Store, StoreError, StoredRecord,
};

use common::{db_path, eventually, open_sqlite, site, temp_dir, walk};

/// What the ingest log's store does before it appends records under given ids: `Ok` to go on,
/// or the error to fail with.
type BeforeAppend = Box<dyn FnMut(&[i64]) -> Result<(), StoreError> + Send>;

/// A store whose appends under given ids first run a hook (which may wait, or fail them).
struct Hooked {
    inner: Box<dyn Store>,
    before_append: BeforeAppend,
}

impl Store for Hooked {
    fn backend(&self) -> &'static str {
        self.inner.backend()
    }
    fn defer_wal_checkpoints(&mut self) -> Result<(), StoreError> {
        self.inner.defer_wal_checkpoints()
    }
    fn append_records_then_commit(
        &mut self,
        records: &[NewRecord],
        inserted: &mut dyn FnMut(&[i64]),
    ) -> Result<Vec<i64>, StoreError> {
        self.inner.append_records_then_commit(records, inserted)
    }
    fn last_record_id(&mut self) -> Result<i64, StoreError> {
        self.inner.last_record_id()
    }
    fn append_records_with_ids(&mut self, ids: &[i64], records: &[NewRecord]) -> Result<(), StoreError> {
        (self.before_append)(ids)?;
        self.inner.append_records_with_ids(ids, records)
    }
    fn records_after(&mut self, after_id: i64, limit: usize) -> Result<Vec<StoredRecord>, StoreError> {
        self.inner.records_after(after_id, limit)
    }
    fn record_count(&mut self) -> Result<u64, StoreError> {
        self.inner.record_count()
    }
    fn append_locations(&mut self, rows: &[LocationRow]) -> Result<(), StoreError> {
        self.inner.append_locations(rows)
    }
    fn append_events(&mut self, rows: &[EventRow]) -> Result<(), StoreError> {
        self.inner.append_events(rows)
    }
    fn history(&mut self, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError> {
        self.inner.history(query)
    }
    fn events(&mut self, query: &EventQuery) -> Result<Vec<EventRow>, StoreError> {
        self.inner.events(query)
    }
    fn put_config(&mut self, kind: &str, id: &str, json: &str) -> Result<bool, StoreError> {
        self.inner.put_config(kind, id, json)
    }
    fn get_config(&mut self, kind: &str, id: &str) -> Result<Option<String>, StoreError> {
        self.inner.get_config(kind, id)
    }
    fn list_config(&mut self, kind: &str) -> Result<Vec<(String, String)>, StoreError> {
        self.inner.list_config(kind)
    }
    fn delete_config(&mut self, kind: &str, id: &str) -> Result<bool, StoreError> {
        self.inner.delete_config(kind, id)
    }
    fn checkpoint(&mut self, name: &str) -> Result<Option<i64>, StoreError> {
        self.inner.checkpoint(name)
    }
    fn set_checkpoint(&mut self, name: &str, value: i64) -> Result<(), StoreError> {
        self.inner.set_checkpoint(name, value)
    }
    fn prune(&mut self, before_ms: i64) -> Result<Pruned, StoreError> {
        self.inner.prune(before_ms)
    }
    fn prune_ingest_log(&mut self, before_ms: i64, through_id: i64) -> Result<u64, StoreError> {
        self.inner.prune_ingest_log(before_ms, through_id)
    }
    fn compact_history(&mut self, before_ms: i64, max_rows: usize) -> Result<u64, StoreError> {
        self.inner.compact_history(before_ms, max_rows)
    }
    fn compact_ingest_log(&mut self, before_ms: i64, through_id: i64, max_rows: usize) -> Result<u64, StoreError> {
        self.inner.compact_ingest_log(before_ms, through_id, max_rows)
    }
}

/// A pipeline (2 partitions, the clock from the records) over the SQLite file of `name`, its
/// ingest log's appends through `before_append`.
fn pipeline(name: &str, before_append: BeforeAppend) -> Pipeline {
    let path = db_path(name);
    let ingest = Hooked {
        inner: open_sqlite(&path),
        before_append,
    };
    let config = PipelineConfig {
        partitions: 2,
        live_clock: false,
        ..PipelineConfig::default()
    };
    Pipeline::start(
        &site(),
        Box::new(ingest),
        open_sqlite(&path),
        config,
        Arc::new(Metrics::new()),
    )
    .expect("pipeline")
}

/// The ids in the ingest log of `name`.
fn stored_ids(name: &str) -> Vec<i64> {
    let mut store = open_sqlite(&db_path(name));
    store
        .records_after(0, 1_000)
        .expect("records")
        .iter()
        .map(|r| r.id)
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_are_tracked_before_their_commit_and_acknowledged_only_after_it() {
    let name = "ingest-commit-gated";
    temp_dir(name);
    let (entered_tx, entered_rx) = channel::<Vec<i64>>();
    let (open_tx, open_rx) = channel::<()>();
    // every append waits until the test lets it through
    let pipeline = pipeline(
        name,
        Box::new(move |ids| {
            let _ = entered_tx.send(ids.to_vec());
            let _ = open_rx.recv();
            Ok(())
        }),
    );
    let lines = walk("walker", 1_000.0, 5.0);
    let submit = {
        let pipeline = pipeline.clone();
        tokio::spawn(async move { pipeline.submit_lines("test", lines.as_bytes()).await })
    };
    let entered = tokio::task::spawn_blocking(move || entered_rx.recv_timeout(Duration::from_secs(10)))
        .await
        .expect("join")
        .expect("the append began");
    assert_eq!(
        entered,
        (1..=11).collect::<Vec<i64>>(),
        "ids from 1 on an empty log, one per record"
    );
    // tracked while its commit waits …
    let tracked = eventually(Duration::from_secs(10), || pipeline.live().tag("walker").is_some()).await;
    assert!(tracked, "the walker is tracked before its records are stored");
    assert_eq!(stored_ids(name), Vec::<i64>::new(), "nothing committed yet");
    // … and not acknowledged
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(!submit.is_finished(), "acknowledged before the commit");
    open_tx.send(()).expect("open");
    let acknowledged = tokio::time::timeout(Duration::from_secs(10), submit)
        .await
        .expect("acknowledged after the commit")
        .expect("join");
    assert_eq!(acknowledged.expect("stored"), 11);
    assert_eq!(stored_ids(name), entered);
    drop(open_tx);
    pipeline.shutdown();
}

/// Whether `ids` is the run `first..first + count`.
fn is_run(ids: &[i64], first: i64, count: i64) -> bool {
    ids == (first..first + count).collect::<Vec<_>>()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_commit_is_not_acknowledged_and_its_ids_stay_a_gap() {
    let name = "ingest-commit-failed";
    temp_dir(name);
    let (seen_tx, seen_rx): (Sender<Vec<i64>>, Receiver<Vec<i64>>) = channel();
    let mut appends = 0;
    let pipeline = pipeline(
        name,
        Box::new(move |ids| {
            appends += 1;
            let _ = seen_tx.send(ids.to_vec());
            if appends == 1 {
                return Err(StoreError::Database {
                    backend: "sqlite",
                    operation: "append records",
                    reason: "disk full (test)".into(),
                });
            }
            Ok(())
        }),
    );
    let first = pipeline.submit_lines("test", walk("a", 1_000.0, 1.0).as_bytes()).await;
    assert!(
        matches!(&first, Err(IngestError::Unavailable(reason)) if reason.contains("disk full (test)")),
        "{first:?}"
    );
    // tracked though not stored (the tracker takes the repeats as late or revised records)
    let tracked = eventually(Duration::from_secs(10), || pipeline.live().tag("a").is_some()).await;
    assert!(tracked, "the records of the failed commit were tracked");
    // the sender sends again: new ids, after the failed ones
    let again = pipeline.submit_lines("test", walk("a", 1_000.0, 1.0).as_bytes()).await;
    assert_eq!(again.expect("stored"), 3);
    let seen: Vec<Vec<i64>> = seen_rx.try_iter().collect();
    assert_eq!(seen.len(), 2, "{seen:?}");
    assert!(is_run(&seen[0], 1, 3) && is_run(&seen[1], 4, 3), "{seen:?}");
    assert_eq!(stored_ids(name), seen[1]);
    pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_restart_ids_start_above_the_checkpoint_and_the_quarantined_records() {
    let name = "ingest-commit-restart";
    temp_dir(name);
    let path = db_path(name);
    // ids given to records whose commit failed before the restart (tracked, not stored): the
    // output checkpoint and a quarantined record passed them, the log holds none of them
    for (checkpoint, quarantined, first) in [(40, None, 41), (40, Some(57), 58)] {
        let mut store = open_sqlite(&path);
        store.set_checkpoint(CHECKPOINT, checkpoint).expect("checkpoint");
        if let Some(id) = quarantined {
            store
                .put_config(QUARANTINE, &format!("{id:020}"), r#"{"record": null}"#)
                .expect("quarantine");
        }
        let before = stored_ids(name);
        let pipeline = pipeline(name, Box::new(|_| Ok(())));
        let stored = pipeline
            .submit_lines("test", walk("b", 2_000.0, 0.5).as_bytes())
            .await
            .expect("stored");
        assert_eq!(stored, 2);
        pipeline.shutdown();
        let after = stored_ids(name);
        assert!(is_run(&after[before.len()..], first, 2), "{before:?} then {after:?}");
        // the next run starts above what this one stored (its checkpoint is past it now)
        store.delete_config(QUARANTINE, "00000000000000000057").expect("delete");
        store.set_checkpoint(CHECKPOINT, 0).expect("checkpoint");
        let next = pipeline_and_submit_one(name).await;
        assert_eq!(next, after.last().expect("stored") + 1);
    }
}

/// Starts a pipeline on `name`, submits one record and stops it; the record's id.
async fn pipeline_and_submit_one(name: &str) -> i64 {
    let before = stored_ids(name).len();
    let pipeline = pipeline(name, Box::new(|_| Ok(())));
    let line = r#"{"t": 3000.0, "tag": "c", "kind": "fix", "position_m": [1.0, 1.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}"#;
    pipeline.submit_lines("test", line.as_bytes()).await.expect("stored");
    pipeline.shutdown();
    let ids = stored_ids(name);
    assert_eq!(ids.len(), before + 1);
    ids[before]
}
