//! Conformance: compaction into blocks (history_blocks.rs, log_blocks.rs) changes no answer.

use super::harness::{location, record, track_state};
use crate::store::{HistoryQuery, NewRecord, Pruned, Store};

/// Packing old states into blocks changes no query's answer: states whose numbers lie on the
/// blocks' grid (and states kept verbatim) come back exactly, in the same order, with limits
/// and ranges that cut across blocks and rows; pruning counts what the blocks held.
pub(super) fn compaction_keeps_the_history(store: &mut dyn Store) {
    let mut old = Vec::new();
    for k in 0..40 {
        old.push(track_state(1_000 + k, k as f64, "a"));
        // not a track line: kept verbatim
        old.push(location(1_000 + k, k as f64 + 0.5, "b"));
    }
    store.append_locations(&old).unwrap();
    store
        .append_locations(&[track_state(9_000, 40.0, "a"), location(9_000, 40.5, "b")])
        .unwrap();
    let query = |tag: Option<&str>, from_s: f64, to_s: f64, limit: usize| HistoryQuery {
        tag: tag.map(str::to_owned),
        from_s,
        to_s,
        limit,
    };
    let queries = [
        query(Some("a"), 0.0, 100.0, 1_000),
        query(Some("b"), 10.0, 20.0, 1_000),
        query(Some("a"), 30.0, 41.0, 3),
        query(None, 5.0, 45.0, 1_000),
        query(None, 0.0, 100.0, 7),
        query(None, 39.0, 100.0, 3),
    ];
    let before: Vec<_> = queries.iter().map(|q| store.history(q).unwrap()).collect();
    assert_eq!(before[0].len(), 41);

    assert_eq!(store.compact_history(5_000, 30).unwrap(), 30, "at most the limit");
    assert_eq!(
        store.compact_history(5_000, 1_000).unwrap(),
        50,
        "the rest, not the recent"
    );
    assert_eq!(store.compact_history(5_000, 1_000).unwrap(), 0);
    for (query, expected) in queries.iter().zip(&before) {
        assert_eq!(&store.history(query).unwrap(), expected, "{query:?}");
    }

    assert_eq!(
        store.prune(5_000).unwrap(),
        Pruned {
            records: 0,
            locations: 80,
            events: 0
        }
    );
    let left = store.history(&query(None, 0.0, 100.0, 100)).unwrap();
    assert_eq!(left.iter().map(|row| row.time_s).collect::<Vec<_>>(), [40.0, 40.5]);
}

/// Packing checkpointed records into blocks changes nothing a replay reads, never packs one
/// after the checkpoint, and pruning counts what the blocks held.
pub(super) fn compaction_keeps_the_ingest_log(store: &mut dyn Store) {
    let records: Vec<NewRecord> = (0..30)
        .map(|i| {
            record(
                1_000 + i,
                i as f64,
                if i % 2 == 0 { "t1" } else { "t2" },
                &format!("r{i}"),
            )
        })
        .collect();
    let ids = store.append_records(&records).unwrap();
    store.append_records(&[record(9_000, 99.0, "t1", "recent")]).unwrap();
    let all = store.records_after(0, 100).unwrap();
    assert_eq!(all.len(), 31);

    assert_eq!(
        store.compact_ingest_log(5_000, ids[19], 8).unwrap(),
        8,
        "at most the limit"
    );
    assert_eq!(
        store.compact_ingest_log(5_000, ids[19], 1_000).unwrap(),
        12,
        "up to the checkpoint"
    );
    assert_eq!(store.compact_ingest_log(5_000, ids[19], 1_000).unwrap(), 0);
    assert_eq!(store.record_count().unwrap(), 31);
    for after in [0, ids[5], ids[7], ids[19], ids[25]] {
        for limit in [1, 3, 100] {
            let expected: Vec<_> = all.iter().filter(|r| r.id > after).take(limit).cloned().collect();
            assert_eq!(
                store.records_after(after, limit).unwrap(),
                expected,
                "after {after}, limit {limit}"
            );
        }
    }

    assert_eq!(
        store.prune_ingest_log(5_000, ids[9]).unwrap(),
        8,
        "whole blocks behind the checkpoint"
    );
    assert_eq!(store.record_count().unwrap(), 23);
    assert_eq!(
        store.prune(5_000).unwrap(),
        Pruned {
            records: 22,
            locations: 0,
            events: 0
        }
    );
    assert_eq!(store.records_after(0, 100).unwrap(), all[30..].to_vec());
    assert_eq!(store.last_record_id().unwrap(), all[30].id);
    // with the newest record packed and its row gone, its id still counts
    let given = all[30].id + 10;
    store
        .append_records_with_ids(&[given], &[record(1_000, 100.0, "t1", "given")])
        .unwrap();
    assert_eq!(store.compact_ingest_log(5_000, given, 100).unwrap(), 1);
    assert_eq!(store.last_record_id().unwrap(), given);
}
