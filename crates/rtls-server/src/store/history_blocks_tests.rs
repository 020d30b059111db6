use rtls_engine::lifecycle::TrackStatus;
use rtls_engine::tracker::{TrackUpdate, UpdateSource};
use serde_json::Value;

use super::*;
use crate::convert::accuracy_m;

/// A walk of `n` states at 1 Hz, 2-D or 3-D, as the pipeline stores them (engine JSON lines).
fn walk(tag: &str, n: usize, dimensions: usize) -> Vec<LocationRow> {
    (0..n)
        .map(|k| {
            let k_f = k as f64;
            let update = TrackUpdate {
                time_s: 1_795_697_830.853_307_2 + k_f * 1.000_3,
                tag: tag.into(),
                dimensions,
                position_m: [
                    459.492_668_629 - 1.2 * k_f,
                    79.769_992 + 0.3 * k_f.sin(),
                    1.1 + 0.01 * k_f,
                ],
                velocity_mps: [-1.2, 0.3 * k_f.cos(), 0.01],
                position_covariance_m2: if dimensions == 3 {
                    [1.06, -0.51, 0.02, -0.51, 1.70, 0.01, 0.02, 0.01, 0.3]
                } else {
                    [1.063_347, -0.515_032, -0.515_032, 1.706_975, 0.0, 0.0, 0.0, 0.0, 0.0]
                },
                predicted: k % 7 == 3,
                status: if k % 7 == 3 {
                    TrackStatus::Coasting
                } else {
                    TrackStatus::Confirmed
                },
                source: UpdateSource::Fix,
                mode: (k % 2 == 0).then_some("CV"),
                revised: k == 5,
                smoothed: false,
            };
            LocationRow {
                received_ms: 1_795_697_831_000 + 1000 * k as i64 + (k as i64 % 3),
                time_s: update.time_s,
                tag: tag.into(),
                x_m: update.position_m[0],
                y_m: update.position_m[1],
                z_m: (dimensions == 3).then_some(update.position_m[2]),
                accuracy_m: Some(accuracy_m(&update.position_covariance_m2, dimensions)),
                predicted: update.predicted,
                json: update.to_json_line(),
            }
        })
        .collect()
}

fn assert_close(original: &LocationRow, read: &LocationRow) {
    assert_eq!(read.tag, original.tag);
    assert_eq!(read.received_ms, original.received_ms);
    assert_eq!(read.predicted, original.predicted);
    assert!(
        (read.time_s - original.time_s).abs() <= 1e-6,
        "time {} vs {}",
        read.time_s,
        original.time_s
    );
    assert!((read.x_m - original.x_m).abs() <= 5e-4 && (read.y_m - original.y_m).abs() <= 5e-4);
    assert_eq!(read.z_m.is_some(), original.z_m.is_some());
    if let (Some(a), Some(b)) = (read.z_m, original.z_m) {
        assert!((a - b).abs() <= 5e-4);
    }
    // derived from the covariance on the σ grid: within 0.3 %
    let accuracy = original.accuracy_m.unwrap();
    assert!((read.accuracy_m.unwrap() - accuracy).abs() <= 3e-3 * accuracy);
    let a: Value = serde_json::from_str(&read.json).unwrap();
    let b: Value = serde_json::from_str(&original.json).unwrap();
    let (a, b) = (a.as_object().unwrap(), b.as_object().unwrap());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "same keys, same order"
    );
    for (key, value) in b {
        match value {
            Value::Number(n) => {
                let tolerance = if key == "t" { 1e-6 } else { 5e-4 };
                assert!(
                    (a[key].as_f64().unwrap() - n.as_f64().unwrap()).abs() <= tolerance,
                    "{key}"
                );
            }
            // covariance: σ to 0.14 % and ρ to 5e-4 give each entry to 0.3 % of the largest
            Value::Array(entries) => {
                let largest = entries.iter().map(|e| e.as_f64().unwrap().abs()).fold(0.0, f64::max);
                for (x, y) in a[key].as_array().unwrap().iter().zip(entries) {
                    let error = (x.as_f64().unwrap() - y.as_f64().unwrap()).abs();
                    assert!(error <= 3e-3 * largest, "{key}: {x} vs {y}");
                }
            }
            other => assert_eq!(&a[key], other, "{key}"),
        }
    }
}

#[test]
fn a_walk_comes_back_within_the_quantisation_in_2d_and_3d_and_is_small() {
    for dimensions in [2, 3] {
        let rows = walk("miner-576", 300, dimensions);
        let json_bytes: usize = rows.iter().map(|row| row.json.len()).sum();
        let block = encode_block("miner-576", &rows);
        assert_eq!(
            (block.count, block.from_s, block.to_s),
            (300, rows[0].time_s, rows[299].time_s)
        );
        assert_eq!(block.received_ms, rows[299].received_ms);
        let per_state = block.payload.len() as f64 / 300.0;
        // the JSON lines are ~300 bytes a state; compact states are ~10-15
        assert!(
            per_state < 16.0,
            "{dimensions}-D: {per_state:.1} bytes a state (JSON {json_bytes} bytes)"
        );
        let read = decode_block("miner-576", &block.payload).unwrap();
        assert_eq!(read.len(), rows.len());
        for (original, read) in rows.iter().zip(&read) {
            assert_close(original, read);
        }
    }
}

#[test]
fn a_state_that_does_not_quantise_is_kept_verbatim_and_exact() {
    let mut rows = walk("t1", 4, 2);
    // an unknown key, and columns that disagree with the line: both kept exactly as stored
    rows[1].json = rows[1].json.replace("\"predicted\"", "\"extra\":1,\"predicted\"");
    rows[2].x_m = f64::NAN;
    rows[3].accuracy_m = None;
    let block = encode_block("t1", &rows);
    let read = decode_block("t1", &block.payload).unwrap();
    assert_eq!(read[1], rows[1]);
    assert_eq!(read[2].json, rows[2].json);
    assert!(read[2].x_m.is_nan());
    assert_eq!(read[3].accuracy_m, None);
    assert_close(&rows[0], &read[0]);
}

#[test]
fn a_corrupt_or_foreign_block_is_an_error() {
    let block = encode_block("t1", &walk("t1", 10, 2));
    let mut foreign = block.payload.clone();
    foreign[0] = 9;
    assert!(decode_block("t1", &foreign).unwrap_err().contains("format 9"));
    assert!(decode_block("t1", &block.payload[..block.payload.len() / 2]).is_err());
    assert!(decode_block("t1", &[]).is_err());
}

#[test]
fn packing_cuts_blocks_per_tag_and_at_the_span() {
    let mut rows: Vec<LocationRow> = walk("b", 5, 2).into_iter().chain(walk("a", 5, 2)).collect();
    // one state of `a` an hour and more later: a block of its own
    let mut late = walk("a", 1, 2).remove(0);
    late.time_s += MAX_BLOCK_SPAN_S + 10.0;
    late.json = late.json.replace("1795697830.8533072", &late.time_s.to_string());
    // stored first, packed last: by tag, then time
    rows.insert(0, late.clone());
    let blocks = pack(rows.clone());
    let shape: Vec<(&str, i64)> = blocks.iter().map(|b| (b.tag.as_str(), b.count)).collect();
    assert_eq!(shape, [("a", 5), ("a", 1), ("b", 5)]);
    assert_close(&late, &decode_block("a", &blocks[1].payload).unwrap()[0]);
    let first_a = decode_block("a", &blocks[0].payload).unwrap();
    assert_eq!(first_a.len(), 5);
    for (read, stored) in first_a.iter().zip(&rows[6..11]) {
        assert_close(stored, read);
    }
}

#[test]
fn the_collector_keeps_the_first_states_in_time_order_and_stops_reading_early() {
    let rows = walk("a", 20, 2);
    let query = HistoryQuery {
        tag: None,
        from_s: rows[2].time_s,
        to_s: rows[15].time_s,
        limit: 5,
    };
    // rows 10.. are still in the table; 0..10 in two blocks
    let mut collector = HistoryCollector::new(&query, rows[10..15].to_vec());
    let first = encode_block("a", &rows[0..5]);
    let second = encode_block("a", &rows[5..10]);
    assert!(collector.wants_block_from(first.from_s));
    collector.add_block("a", &first.payload).unwrap();
    assert!(collector.wants_block_from(second.from_s));
    collector.add_block("a", &second.payload).unwrap();
    // five states before 12 s are in hand: a block starting later cannot enter
    assert!(!collector.wants_block_from(rows[12].time_s));
    let states = collector.finish();
    let times: Vec<f64> = states.iter().map(|row| row.time_s).collect();
    assert_eq!(states.len(), 5);
    for (read, expected) in times.iter().zip(&rows[2..7]) {
        assert!((read - expected.time_s).abs() <= 1e-6);
    }
}
