//! The storage conformance suite: every function here takes a `&mut dyn Store` and is run by
//! [`conformance!`] against an in-memory SQLite database, an SQLite file and, when
//! `RTLS_TEST_POSTGRES_URL` is set, PostgreSQL (a schema of its own per test, dropped after).
//! Back-end-specific tests (durability across reopening, WAL, migrations, URLs) are in
//! `tests/backends.rs`.

mod backends;
mod compaction;
mod harness;

use self::compaction::{compaction_keeps_the_history, compaction_keeps_the_ingest_log};
use self::harness::{event, location, record, PgSchema, TempDb};
use super::{EventQuery, HistoryQuery, NewRecord, Pruned, SqliteStore, Store, StoreError};

/// Runs each named conformance function against every back end, one `#[test]` per pair.
macro_rules! conformance {
    ($($test:ident),* $(,)?) => {
        mod sqlite_memory {
            $(#[test]
            fn $test() {
                let mut store = super::SqliteStore::open_in_memory().expect("open in memory");
                super::$test(&mut store);
            })*
        }
        mod sqlite_file {
            $(#[test]
            fn $test() {
                let file = super::TempDb::new(stringify!($test));
                let mut store = file.open();
                super::$test(&mut store);
            })*
        }
        mod postgres {
            $(#[test]
            fn $test() {
                let Some(schema) = super::PgSchema::new() else { return };
                let mut store = schema.open();
                super::$test(&mut store);
            })*
        }
    };
}

conformance!(
    ids_increase_and_records_page,
    large_batch_keeps_its_order,
    failed_batch_stores_nothing,
    inserted_records_are_handed_over_once_before_the_commit,
    given_ids_are_kept_and_counted_on,
    given_ids_must_be_new_and_increasing,
    ids_are_not_reused_after_pruning,
    history_bounds_limit_and_tags,
    event_filters,
    config_crud,
    checkpoints,
    prune_deletes_exactly_the_older_rows,
    ingest_log_pruning_stops_at_the_checkpoint,
    compaction_keeps_the_history,
    compaction_keeps_the_ingest_log,
);

/// Whether `ids` strictly increase.
fn strictly_increasing(ids: &[i64]) -> bool {
    ids.windows(2).all(|pair| pair[0] < pair[1])
}

fn ids_increase_and_records_page(store: &mut dyn Store) {
    assert_eq!(store.record_count().unwrap(), 0);
    assert!(store.records_after(0, 10).unwrap().is_empty());
    assert!(store.append_records(&[]).unwrap().is_empty());
    assert_eq!(store.record_count().unwrap(), 0);

    let first: Vec<NewRecord> = (0..5)
        .map(|i| record(1_000 + i, i as f64, "tag-1", &format!("a{i}")))
        .collect();
    let second: Vec<NewRecord> = (0..3)
        .map(|i| record(2_000 + i, 10.0 + i as f64, "*", &format!("b{i}")))
        .collect();
    let first_ids = store.append_records(&first).unwrap();
    let second_ids = store.append_records(&second).unwrap();
    assert_eq!((first_ids.len(), second_ids.len()), (5, 3));
    let all_ids: Vec<i64> = first_ids.iter().chain(&second_ids).copied().collect();
    assert!(strictly_increasing(&all_ids), "ids {all_ids:?}");
    assert_eq!(store.record_count().unwrap(), 8);

    // Every field comes back as written, under the id the append returned.
    let all_new: Vec<&NewRecord> = first.iter().chain(&second).collect();
    let stored = store.records_after(0, 100).unwrap();
    assert_eq!(stored.len(), 8);
    for ((stored, new), id) in stored.iter().zip(&all_new).zip(&all_ids) {
        assert_eq!(stored.id, *id);
        assert_eq!(
            (
                stored.received_ms,
                &stored.source,
                stored.time_s,
                &stored.tag,
                &stored.json
            ),
            (new.received_ms, &new.source, new.time_s, &new.tag, &new.json)
        );
    }

    // Paging by the last id seen visits every record once, in order, then stops.
    let mut paged = Vec::new();
    let mut after_id = 0;
    loop {
        let page = store.records_after(after_id, 3).unwrap();
        assert!(page.len() <= 3);
        let Some(last) = page.last() else { break };
        after_id = last.id;
        paged.extend(page.iter().map(|record| record.id));
    }
    assert_eq!(paged, all_ids);
    let after_fifth: Vec<i64> = store
        .records_after(all_ids[4], 100)
        .unwrap()
        .iter()
        .map(|r| r.id)
        .collect();
    assert_eq!(after_fifth, second_ids);
    assert!(store.records_after(all_ids[7], 100).unwrap().is_empty());
    assert!(store.records_after(0, 0).unwrap().is_empty());
}

fn large_batch_keeps_its_order(store: &mut dyn Store) {
    let batch: Vec<NewRecord> = (0..1_000)
        .map(|i| record(5_000, f64::from(i) * 0.5, &format!("tag-{}", i % 7), &format!("n{i}")))
        .collect();
    let ids = store.append_records(&batch).unwrap();
    assert_eq!(ids.len(), batch.len());
    assert!(strictly_increasing(&ids));
    let stored = store.records_after(0, 2_000).unwrap();
    let stored_json: Vec<&str> = stored.iter().map(|record| record.json.as_str()).collect();
    let batch_json: Vec<&str> = batch.iter().map(|record| record.json.as_str()).collect();
    assert_eq!(stored_json, batch_json);
    assert_eq!(stored.iter().map(|record| record.id).collect::<Vec<_>>(), ids);
}

/// A record this back end refuses: SQLite stores NaN as NULL, which `time_s NOT NULL`
/// rejects; PostgreSQL's text type cannot hold a NUL character.
fn poisoned_record(backend: &str) -> NewRecord {
    let mut poisoned = record(1_000, 2.0, "tag-1", "poisoned");
    match backend {
        "sqlite" => poisoned.time_s = f64::NAN,
        _ => poisoned.json = "{\"t\":2,\0}".to_owned(),
    }
    poisoned
}

fn inserted_records_are_handed_over_once_before_the_commit(store: &mut dyn Store) {
    let batch: Vec<NewRecord> = (0..4)
        .map(|i| record(1_000 + i, i as f64, "tag-1", &format!("a{i}")))
        .collect();
    let mut handed_over = Vec::new();
    let ids = store
        .append_records_then_commit(&batch, &mut |ids| handed_over.push(ids.to_vec()))
        .unwrap();
    assert_eq!(handed_over, vec![ids.clone()], "once, with the ids returned");
    assert!(strictly_increasing(&ids), "ids {ids:?}");
    assert_eq!(store.record_count().unwrap(), 4);
    // a batch whose insert fails is not handed over
    let mut called = false;
    let bad = [record(2_000, 5.0, "tag-1", "good"), poisoned_record(store.backend())];
    assert!(store.append_records_then_commit(&bad, &mut |_| called = true).is_err());
    assert!(!called);
    assert_eq!(store.record_count().unwrap(), 4);
}

fn given_ids_are_kept_and_counted_on(store: &mut dyn Store) {
    assert_eq!(store.last_record_id().unwrap(), 0, "an empty log");
    store.append_records_with_ids(&[], &[]).unwrap();
    let batch: Vec<NewRecord> = (0..3)
        .map(|i| record(1_000 + i, i as f64, "tag-1", &format!("a{i}")))
        .collect();
    // gaps between the ids (a failed commit's) are kept
    store.append_records_with_ids(&[5, 9, 10], &batch).unwrap();
    let stored = store.records_after(0, 10).unwrap();
    assert_eq!(stored.iter().map(|r| r.id).collect::<Vec<_>>(), [5, 9, 10]);
    for (stored, new) in stored.iter().zip(&batch) {
        assert_eq!(
            (
                stored.received_ms,
                &stored.source,
                stored.time_s,
                &stored.tag,
                &stored.json
            ),
            (new.received_ms, &new.source, new.time_s, &new.tag, &new.json)
        );
    }
    assert_eq!(store.records_after(5, 1).unwrap()[0].id, 9);
    assert_eq!(store.last_record_id().unwrap(), 10);
    // the back end's own ids continue above the given ones
    let next = store.append_records(&[record(2_000, 4.0, "tag-1", "b")]).unwrap();
    assert!(next[0] > 10, "id {} after the given 10", next[0]);
    assert_eq!(store.last_record_id().unwrap(), next[0]);
    // and given ids above those
    store
        .append_records_with_ids(&[next[0] + 1], &[record(3_000, 5.0, "tag-2", "c")])
        .unwrap();
    assert_eq!(store.last_record_id().unwrap(), next[0] + 1);
    // an id once given out stays counted after its row is pruned
    assert_eq!(store.prune(10_000).unwrap().records, 5);
    assert_eq!(store.record_count().unwrap(), 0);
    assert_eq!(store.last_record_id().unwrap(), next[0] + 1);
    assert!(store.append_records(&[record(4_000, 6.0, "t", "d")]).unwrap()[0] > next[0] + 1);
}

fn given_ids_must_be_new_and_increasing(store: &mut dyn Store) {
    let two = [record(1_000, 1.0, "t", "a"), record(1_000, 2.0, "t", "b")];
    store.append_records_with_ids(&[3, 4], &two).unwrap();
    let refused = |result: Result<(), StoreError>| {
        matches!(
            result,
            Err(StoreError::Database {
                operation: "append records",
                ..
            })
        )
    };
    // one already in the log: the whole batch is refused
    assert!(refused(store.append_records_with_ids(&[4, 5], &two)));
    assert!(refused(store.append_records_with_ids(&[7, 6], &two)), "decreasing");
    assert!(refused(store.append_records_with_ids(&[8, 8], &two)), "repeated");
    assert!(
        refused(store.append_records_with_ids(&[9], &two)),
        "one id for two records"
    );
    let with_poison = [record(1_000, 3.0, "t", "c"), poisoned_record(store.backend())];
    assert!(refused(store.append_records_with_ids(&[11, 12], &with_poison)));
    assert_eq!(store.record_count().unwrap(), 2);
    assert_eq!(
        store
            .records_after(0, 10)
            .unwrap()
            .iter()
            .map(|r| r.id)
            .collect::<Vec<_>>(),
        [3, 4]
    );
    // the store stays usable
    store.append_records_with_ids(&[20], &two[..1]).unwrap();
    assert_eq!(store.record_count().unwrap(), 3);
}

fn failed_batch_stores_nothing(store: &mut dyn Store) {
    store.append_records(&[record(500, 0.5, "tag-0", "before")]).unwrap();
    let batch = [
        record(1_000, 1.0, "tag-1", "good"),
        poisoned_record(store.backend()),
        record(1_000, 3.0, "tag-1", "good"),
    ];
    let error = store.append_records(&batch).unwrap_err();
    assert!(
        matches!(error, StoreError::Database { operation: "append records", backend, .. } if backend == store.backend()),
        "{error:?}"
    );
    assert_eq!(store.record_count().unwrap(), 1);
    let stored = store.records_after(0, 10).unwrap();
    assert_eq!(stored.len(), 1);
    assert!(stored[0].json.contains("before"));
    // The store stays usable.
    assert_eq!(
        store
            .append_records(&[record(2_000, 4.0, "tag-1", "after")])
            .unwrap()
            .len(),
        1
    );
}

fn ids_are_not_reused_after_pruning(store: &mut dyn Store) {
    let ids = store
        .append_records(&[
            record(1_000, 1.0, "t", "x"),
            record(1_000, 2.0, "t", "y"),
            record(1_000, 3.0, "t", "z"),
        ])
        .unwrap();
    assert_eq!(store.prune(2_000).unwrap().records, 3);
    assert_eq!(store.record_count().unwrap(), 0);
    let new_ids = store.append_records(&[record(3_000, 4.0, "t", "w")]).unwrap();
    assert!(
        new_ids[0] > ids[2],
        "id {} reused after {ids:?} were pruned",
        new_ids[0]
    );
}

fn history_bounds_limit_and_tags(store: &mut dyn Store) {
    // Appended out of time order, in two batches, interleaved with other tags.
    let mut rows = Vec::new();
    for time_s in [5.0, 1.0, 9.0, 3.0, 7.0, 10.0, 2.0, 6.0, 8.0, 4.0] {
        rows.push(location(100, time_s, "miner-1"));
        rows.push(location(100, time_s, "miner-2"));
        rows.push(location(100, time_s, "miner-10"));
    }
    let (early, late) = rows.split_at(12);
    store.append_locations(early).unwrap();
    store.append_locations(late).unwrap();
    store.append_locations(&[]).unwrap();
    // Two states at the same time come back in the order they were stored.
    let mut twin = location(200, 7.0, "miner-1");
    twin.json = r#"{"twin":true}"#.to_owned();
    store.append_locations(&[twin.clone()]).unwrap();

    let query = |from_s: f64, to_s: f64, limit: usize| HistoryQuery {
        tag: Some("miner-1".into()),
        from_s,
        to_s,
        limit,
    };
    let got = store.history(&query(3.0, 7.0, 100)).unwrap();
    let times: Vec<f64> = got.iter().map(|row| row.time_s).collect();
    assert_eq!(
        times,
        [3.0, 4.0, 5.0, 6.0, 7.0, 7.0],
        "bounds are inclusive, oldest first"
    );
    assert!(got.iter().all(|row| row.tag == "miner-1"), "other tags are excluded");
    assert_eq!(
        got[4],
        location(100, 7.0, "miner-1"),
        "every field comes back as written"
    );
    assert_eq!(got[5], twin);
    assert_eq!(got[1], location(100, 4.0, "miner-1"));
    assert!(got.iter().any(|row| row.z_m.is_none()) && got.iter().any(|row| row.accuracy_m.is_none()));
    assert!(got.iter().any(|row| row.predicted) && got.iter().any(|row| !row.predicted));

    let limited: Vec<f64> = store
        .history(&query(3.0, 7.0, 2))
        .unwrap()
        .iter()
        .map(|row| row.time_s)
        .collect();
    assert_eq!(limited, [3.0, 4.0]);
    let point: Vec<f64> = store
        .history(&query(10.0, 10.0, 5))
        .unwrap()
        .iter()
        .map(|row| row.time_s)
        .collect();
    assert_eq!(point, [10.0]);
    assert!(store.history(&query(7.5, 7.9, 5)).unwrap().is_empty());
    assert!(store.history(&query(7.0, 3.0, 5)).unwrap().is_empty());
    assert!(store.history(&query(3.0, 7.0, 0)).unwrap().is_empty());
    let unknown = HistoryQuery {
        tag: Some("miner-3".into()),
        from_s: 0.0,
        to_s: 100.0,
        limit: 10,
    };
    assert!(store.history(&unknown).unwrap().is_empty());

    // without a tag: every tag's states in the range, by time (a replay)
    let everyone = store
        .history(&HistoryQuery {
            tag: None,
            from_s: 2.0,
            to_s: 3.0,
            limit: 100,
        })
        .unwrap();
    let by_time: Vec<(f64, &str)> = everyone.iter().map(|row| (row.time_s, row.tag.as_str())).collect();
    assert_eq!(
        by_time,
        [
            (2.0, "miner-1"),
            (2.0, "miner-2"),
            (2.0, "miner-10"),
            (3.0, "miner-1"),
            (3.0, "miner-2"),
            (3.0, "miner-10")
        ]
    );
}

fn event_filters(store: &mut dyn Store) {
    let odd_kind = "it's \"odd\"";
    let events = [
        event(10, 1.0, "zone-enter", Some("a"), false),
        event(10, 2.0, "hazard-predicted", Some("a"), true),
        event(10, 3.0, "zone-exit", Some("b"), false),
        event(10, 4.0, "no-coverage", None, true),
        event(10, 5.0, "zone-enter", Some("b"), false),
        event(10, 6.0, "model-switch", Some("a"), false),
        event(10, 7.0, odd_kind, Some("c"), false),
    ];
    // Stored out of time order.
    store.append_events(&events[3..]).unwrap();
    store.append_events(&events[..3]).unwrap();
    store.append_events(&[]).unwrap();

    let mut run = |query: EventQuery| -> Vec<f64> {
        store
            .events(&EventQuery { limit: 100, ..query })
            .unwrap()
            .iter()
            .map(|row| row.time_s)
            .collect()
    };
    let all = EventQuery {
        from_s: 0.0,
        to_s: 10.0,
        ..EventQuery::default()
    };
    let kinds = |names: &[&str]| names.iter().map(|name| (*name).to_owned()).collect::<Vec<_>>();
    assert_eq!(run(all.clone()), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    assert_eq!(
        run(EventQuery {
            from_s: 2.0,
            to_s: 5.0,
            ..all.clone()
        }),
        [2.0, 3.0, 4.0, 5.0]
    );
    assert_eq!(
        run(EventQuery {
            tag: Some("a".into()),
            ..all.clone()
        }),
        [1.0, 2.0, 6.0]
    );
    assert_eq!(
        run(EventQuery {
            kinds: kinds(&["zone-enter", "zone-exit"]),
            ..all.clone()
        }),
        [1.0, 3.0, 5.0]
    );
    assert_eq!(
        run(EventQuery {
            kinds: kinds(&[odd_kind]),
            ..all.clone()
        }),
        [7.0]
    );
    assert_eq!(
        run(EventQuery {
            alarms_only: true,
            ..all.clone()
        }),
        [2.0, 4.0]
    );
    assert_eq!(
        run(EventQuery {
            tag: Some("a".into()),
            alarms_only: true,
            ..all.clone()
        }),
        [2.0]
    );
    assert_eq!(
        run(EventQuery {
            tag: Some("b".into()),
            kinds: kinds(&["zone-enter"]),
            ..all.clone()
        }),
        [5.0]
    );
    assert!(run(EventQuery {
        kinds: kinds(&["zone-enter"]),
        alarms_only: true,
        ..all.clone()
    })
    .is_empty());
    assert!(run(EventQuery {
        kinds: kinds(&["nothing-like-it"]),
        ..all.clone()
    })
    .is_empty());

    // newest first: the limit keeps the latest rows (the alarm console's query)
    let newest: Vec<f64> = store
        .events(&EventQuery {
            limit: 2,
            newest_first: true,
            ..all.clone()
        })
        .unwrap()
        .iter()
        .map(|row| row.time_s)
        .collect();
    assert_eq!(newest, [7.0, 6.0]);
    let limited = store
        .events(&EventQuery {
            limit: 2,
            ..all.clone()
        })
        .unwrap();
    assert_eq!(
        limited,
        [events[0].clone(), events[1].clone()],
        "every field comes back as written"
    );
    let no_tag = store
        .events(&EventQuery {
            alarms_only: true,
            limit: 10,
            ..all
        })
        .unwrap();
    assert_eq!(no_tag[1], events[3]);
}

fn config_crud(store: &mut dyn Store) {
    assert_eq!(store.get_config("trackable", "t2").unwrap(), None);
    assert!(store.put_config("trackable", "t2", r#"{"v":1}"#).unwrap(), "created");
    assert!(!store.put_config("trackable", "t2", r#"{"v":2}"#).unwrap(), "replaced");
    assert_eq!(
        store.get_config("trackable", "t2").unwrap().as_deref(),
        Some(r#"{"v":2}"#)
    );
    for id in ["t3", "t10", "T1", "t1"] {
        assert!(store
            .put_config("trackable", id, &format!(r#"{{"id":"{id}"}}"#))
            .unwrap());
    }
    // Same ids under another kind are other objects.
    assert!(store.put_config("zone", "t1", r#"{"zone":true}"#).unwrap());

    let ids: Vec<String> = store
        .list_config("trackable")
        .unwrap()
        .into_iter()
        .map(|(id, _)| id)
        .collect();
    assert_eq!(ids, ["T1", "t1", "t10", "t2", "t3"], "ordered by id, byte-wise");
    assert_eq!(
        store.list_config("zone").unwrap(),
        [("t1".to_owned(), r#"{"zone":true}"#.to_owned())]
    );
    assert!(store.list_config("fence").unwrap().is_empty());

    assert!(store.delete_config("trackable", "t2").unwrap(), "existed");
    assert!(!store.delete_config("trackable", "t2").unwrap(), "already gone");
    assert_eq!(store.get_config("trackable", "t2").unwrap(), None);
    assert_eq!(
        store.get_config("zone", "t1").unwrap().as_deref(),
        Some(r#"{"zone":true}"#)
    );
    assert_eq!(store.list_config("trackable").unwrap().len(), 4);
    assert!(
        store.put_config("trackable", "t2", r#"{"v":3}"#).unwrap(),
        "created again after deletion"
    );
}

fn checkpoints(store: &mut dyn Store) {
    assert_eq!(store.checkpoint("tracker").unwrap(), None);
    store.set_checkpoint("tracker", 5).unwrap();
    assert_eq!(store.checkpoint("tracker").unwrap(), Some(5));
    store.set_checkpoint("tracker", 7).unwrap();
    assert_eq!(store.checkpoint("tracker").unwrap(), Some(7));
    store.set_checkpoint("replay", i64::MAX).unwrap();
    store.set_checkpoint("offset", -3).unwrap();
    assert_eq!(store.checkpoint("tracker").unwrap(), Some(7));
    assert_eq!(store.checkpoint("replay").unwrap(), Some(i64::MAX));
    assert_eq!(store.checkpoint("offset").unwrap(), Some(-3));
}

fn prune_deletes_exactly_the_older_rows(store: &mut dyn Store) {
    let received = [1_000, 1_999, 2_000, 2_001, 3_000];
    let records: Vec<NewRecord> = received
        .iter()
        .enumerate()
        .map(|(i, &ms)| record(ms, i as f64, "t", &format!("r{i}")))
        .collect();
    store.append_records(&records).unwrap();
    store
        .append_locations(&[
            location(1_000, 1.0, "t"),
            location(2_000, 2.0, "t"),
            location(1_500, 3.0, "t"),
        ])
        .unwrap();
    store
        .append_events(&[
            event(1_500, 1.0, "zone-enter", Some("t"), false),
            event(2_000, 2.0, "zone-dwell", Some("t"), false),
            event(2_500, 3.0, "zone-exit", Some("t"), false),
        ])
        .unwrap();
    store.put_config("site", "mine", "{}").unwrap();
    store.set_checkpoint("tracker", 5).unwrap();

    assert_eq!(
        store.prune(2_000).unwrap(),
        Pruned {
            records: 2,
            locations: 2,
            events: 1
        }
    );

    let kept: Vec<i64> = store
        .records_after(0, 10)
        .unwrap()
        .iter()
        .map(|r| r.received_ms)
        .collect();
    assert_eq!(kept, [2_000, 2_001, 3_000]);
    let history = store
        .history(&HistoryQuery {
            tag: Some("t".into()),
            from_s: 0.0,
            to_s: 10.0,
            limit: 10,
        })
        .unwrap();
    assert_eq!(history.iter().map(|row| row.received_ms).collect::<Vec<_>>(), [2_000]);
    let events = store
        .events(&EventQuery {
            from_s: 0.0,
            to_s: 10.0,
            limit: 10,
            ..EventQuery::default()
        })
        .unwrap();
    assert_eq!(
        events.iter().map(|row| row.received_ms).collect::<Vec<_>>(),
        [2_000, 2_500]
    );
    assert_eq!(
        store.get_config("site", "mine").unwrap().as_deref(),
        Some("{}"),
        "configuration is kept"
    );
    assert_eq!(store.checkpoint("tracker").unwrap(), Some(5), "checkpoints are kept");
    assert_eq!(store.prune(2_000).unwrap(), Pruned::default(), "nothing older is left");
}

/// Raw-record retention: old records go, but never one after the output checkpoint (a restart
/// replays those), and nothing else is touched.
fn ingest_log_pruning_stops_at_the_checkpoint(store: &mut dyn Store) {
    let ids = store
        .append_records(&[
            record(1_000, 1.0, "t", "a"),
            record(1_000, 2.0, "t", "b"),
            record(1_000, 3.0, "t", "c"),
            record(5_000, 4.0, "t", "d"),
        ])
        .unwrap();
    // outputs stored through the second record: the third is old but not yet tracked
    assert_eq!(store.prune_ingest_log(2_000, ids[1]).unwrap(), 2);
    assert_eq!(store.record_count().unwrap(), 2);
    let left: Vec<i64> = store.records_after(0, 10).unwrap().iter().map(|r| r.id).collect();
    assert_eq!(left, vec![ids[2], ids[3]]);
    // everything tracked: the old one goes, the recent one stays
    assert_eq!(store.prune_ingest_log(2_000, ids[3]).unwrap(), 1);
    let left: Vec<i64> = store.records_after(0, 10).unwrap().iter().map(|r| r.id).collect();
    assert_eq!(left, vec![ids[3]]);
}
