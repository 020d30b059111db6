//! Late records re-filtered (`rewind_horizon_s`): the same records out of order give the same
//! tracks as in order, the updates they revise are flagged, and records beyond the horizon are
//! reported late; `report_pending` publishes an update when it is produced.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{site_text, slant, ANCHORS};
use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// The test site without a re-ordering window, re-filtering records up to 2 s late.
pub(super) fn rewinding(pipeline: &str) -> Tracker {
    let text = site_text(pipeline, "ekf", "").replace(
        "reorder_window_s = 0.5",
        "reorder_window_s = 0.0\nrewind_horizon_s = 2.0",
    );
    Tracker::new(&Site::from_toml_str(&text, "rewind.toml").unwrap()).unwrap()
}

/// Ranges at 10 Hz to all four anchors (equal time stamps per epoch) of three walkers, σ = 0.1 m.
pub(super) fn three_walkers(seconds: f64, seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut records = Vec::new();
    for k in 0..(seconds * 10.0) as usize {
        let t = k as f64 * 0.1;
        for (w, tag) in ["w1", "w2", "w3"].into_iter().enumerate() {
            let offset = 3.0 * w as f64;
            let position = [2.0 + offset + 0.6 * t, 3.0 + offset + 0.4 * t];
            for (id, a) in ANCHORS {
                records.push(Record {
                    time_s: t,
                    tag: tag.into(),
                    measurement: Measurement::Range {
                        anchor: id.into(),
                        range_m: slant(position, a) + 0.2 + noise.sample(&mut rng),
                        std_m: None,
                        anchor_position_m: None,
                    },
                });
            }
        }
    }
    records
}

pub(super) fn run(mut tracker: Tracker, records: Vec<Record>) -> Output {
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out
}

/// Each (tag, time)'s last measured update (the final revision), position and covariance.
fn final_revisions(out: &Output) -> BTreeMap<(String, i64), ([f64; 3], [f64; 9])> {
    out.updates
        .iter()
        .filter(|u| !u.predicted)
        .map(|u| {
            let key = (u.tag.to_string(), (u.time_s * 1e6).round() as i64);
            (key, (u.position_m, u.position_covariance_m2))
        })
        .collect()
}

/// `got` reports every (tag, time) `expected` does, and nothing else, with the same final
/// position (1e-9 m) and covariance (1e-12 m²).
pub(super) fn assert_same_final_revisions(expected: &Output, got: &Output, label: &str) {
    let (expected, got) = (final_revisions(expected), final_revisions(got));
    let missing: Vec<_> = expected.keys().filter(|k| !got.contains_key(*k)).collect();
    assert!(missing.is_empty(), "{label}: (tag, time)s not reported: {missing:?}");
    let extra: Vec<_> = got.keys().filter(|k| !expected.contains_key(*k)).collect();
    assert!(extra.is_empty(), "{label}: (tag, time)s reported only here: {extra:?}");
    for (key, (position, covariance)) in &expected {
        let (p, c) = &got[key];
        for axis in 0..3 {
            assert!(
                (p[axis] - position[axis]).abs() < 1e-9,
                "{label} {key:?}: {p:?} vs {position:?}"
            );
        }
        for k in 0..9 {
            assert!((c[k] - covariance[k]).abs() < 1e-12, "{label} {key:?}: covariance");
        }
    }
}

#[test]
fn late_records_within_the_horizon_give_the_tracks_of_the_records_in_order() {
    for pipeline in ["tightly-coupled", "fix-then-filter"] {
        let records = three_walkers(20.0, 7);
        let in_order = run(rewinding(pipeline), records.clone());
        assert!(
            in_order.updates.iter().all(|u| !u.revised),
            "{pipeline}: in order, nothing is revised"
        );
        // each tag's epoch (its readings of one time, in their order) delayed by up to 1 s, then
        // sent by arrival: readings of equal time in another order are not late, and
        // sequential EKF updates in another order give (slightly) another state
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut delays: BTreeMap<(String, i64), f64> = BTreeMap::new();
        let mut arriving: Vec<(f64, Record)> = records
            .into_iter()
            .map(|r| {
                let key = (r.tag.to_string(), (r.time_s * 1e6).round() as i64);
                let delay_s = *delays.entry(key).or_insert_with(|| rng.gen_range(0.0..1.0));
                (r.time_s + delay_s, r)
            })
            .collect();
        arriving.sort_by(|a, b| a.0.total_cmp(&b.0));
        let shuffled: Vec<Record> = arriving.into_iter().map(|(_, r)| r).collect();
        let late = run(rewinding(pipeline), shuffled);
        let late_events: Vec<&Event> = late.events.iter().filter(|e| matches!(e, Event::Late { .. })).collect();
        assert!(
            late_events.is_empty(),
            "{pipeline}: within the horizon nothing is late: {late_events:?}"
        );
        let revised = late.updates.iter().filter(|u| u.revised).count();
        assert!(revised > 0, "{pipeline}: no update flagged revised");
        assert_same_final_revisions(&in_order, &late, pipeline);
    }
}

#[test]
fn a_record_beyond_the_horizon_is_reported_late_and_changes_nothing() {
    let records = three_walkers(6.0, 3);
    let mut tracker = rewinding("tightly-coupled");
    let mut out = Output::default();
    for record in records.iter().cloned() {
        tracker.push(record, &mut out).unwrap();
    }
    let updates_before = out.updates.len();
    // a range of w1 from t = 1 s, 5 s behind its newest input (the horizon is 2 s)
    let mut stale = records
        .iter()
        .find(|r| r.time_s >= 1.0 && &*r.tag == "w1")
        .unwrap()
        .clone();
    stale.time_s = 1.0;
    tracker.push(stale, &mut out).unwrap();
    let late: Vec<f64> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Late { tag, lateness_s, .. } if &**tag == "w1" => Some(*lateness_s),
            _ => None,
        })
        .collect();
    assert_eq!(late.len(), 1, "one late event");
    assert!((late[0] - 4.9).abs() < 1e-9, "lateness {} s", late[0]);
    assert_eq!(
        out.updates.len(),
        updates_before,
        "no update from a record beyond the horizon"
    );
}

#[test]
fn report_pending_publishes_at_once_and_flags_a_same_time_revision() {
    let mut tracker = rewinding("tightly-coupled");
    let mut out = Output::default();
    let records = three_walkers(2.0, 5);
    let last_s = records.last().unwrap().time_s;
    let (first, rest): (Vec<Record>, Vec<Record>) = records.into_iter().partition(|r| r.time_s < last_s);
    for record in first {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.report_pending(&mut out).unwrap();
    // the last epoch's w1 ranges, one at a time: each is reported when pending is flushed
    let w1: Vec<Record> = rest.into_iter().filter(|r| &*r.tag == "w1").collect();
    assert_eq!(w1.len(), 4);
    out.clear();
    tracker.push(w1[0].clone(), &mut out).unwrap();
    tracker.report_pending(&mut out).unwrap();
    let first_report: Vec<&TrackUpdate> = out.updates.iter().filter(|u| &*u.tag == "w1").collect();
    assert_eq!(first_report.len(), 1, "reported without waiting for the next epoch");
    assert!((first_report[0].time_s - w1[0].time_s).abs() < 1e-12);
    assert!(!first_report[0].revised);
    out.clear();
    tracker.push(w1[1].clone(), &mut out).unwrap();
    tracker.report_pending(&mut out).unwrap();
    let second: Vec<&TrackUpdate> = out.updates.iter().filter(|u| &*u.tag == "w1").collect();
    assert_eq!(second.len(), 1);
    assert!(second[0].revised, "a second update at the same time revises the first");
}

/// The test site re-ordering in a 0.5 s window, without rewinding: the reference.
fn windowed(pipeline: &str) -> Tracker {
    Tracker::new(&super::tests::site(pipeline, "ekf", "")).unwrap()
}

#[test]
fn an_epoch_closes_when_its_readers_have_reported_and_a_straggler_reopens_it() {
    // fix-then-filter, each epoch's readings in anchor order; one epoch in four misses A4, so
    // the next epoch closes on A1–A3 and its A4 arrives as a straggler
    let records: Vec<Record> = three_walkers(12.0, 21)
        .into_iter()
        .filter(|r| {
            let epoch = (r.time_s * 10.0).round() as i64;
            !(epoch % 4 == 1 && matches!(&r.measurement, Measurement::Range { anchor, .. } if anchor == "A4"))
        })
        .collect();
    let reference = run(windowed("fix-then-filter"), records.clone());
    let mut tracker = rewinding("fix-then-filter");
    let mut out = Output::default();
    let mut closed_at_once = 0;
    for (k, record) in records.iter().enumerate() {
        let (time_s, tag) = (record.time_s, record.tag.clone());
        tracker.push(record.clone(), &mut out).unwrap();
        // a server reports after each batch (here, each record)
        tracker.report_pending(&mut out).unwrap();
        // the epoch's last reading: its update is out before any later record arrives
        let last_of_epoch = records
            .get(k + 1)
            .is_none_or(|next| next.tag != tag || next.time_s > time_s);
        if last_of_epoch && time_s > 0.5 {
            tracker.report_pending(&mut out).unwrap();
            if out
                .updates
                .iter()
                .rev()
                .take(20)
                .any(|u| *u.tag == *tag && u.time_s == time_s)
            {
                closed_at_once += 1;
            }
        }
    }
    tracker.finish(&mut out).unwrap();
    // every epoch holding the readers of the one before (all but those missing A4)
    let complete = records
        .iter()
        .filter(|r| r.time_s > 0.5 && (r.time_s * 10.0).round() as i64 % 4 != 1)
        .map(|r| (r.tag.clone(), (r.time_s * 10.0).round() as i64))
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    assert_eq!(
        closed_at_once, complete,
        "each complete epoch's update was out when its last reading was in"
    );
    let stragglers = out.updates.iter().filter(|u| u.revised).count();
    assert!(stragglers > 0, "the stragglers' epochs were revised");
    let (expected, got) = (final_revisions(&reference), final_revisions(&out));
    assert_eq!(expected.len(), got.len());
    for (key, (position, _)) in &expected {
        let (p, _) = &got[key];
        for axis in 0..2 {
            assert!(
                (p[axis] - position[axis]).abs() < 1e-9,
                "{key:?}: {p:?} vs {position:?}"
            );
        }
    }
}

/// Fixes at 10 Hz of two walkers; `w2`'s sender runs `skew_s` ahead of `w1`'s, so its records
/// move the clock past `w1`'s silence and `w1`'s track coasts before its records arrive.
fn skewed_senders(seconds: f64, skew_s: f64) -> (Vec<Record>, Vec<Record>) {
    let fix = |tag: &str, t: f64, offset: f64| Record {
        time_s: t,
        tag: tag.into(),
        measurement: Measurement::Fix {
            position_m: vec![2.0 + offset + 0.5 * t + 0.05 * (7.0 * t).sin(), 3.0 + 0.3 * t],
            covariance_m2: vec![0.04, 0.0, 0.0, 0.04],
        },
    };
    let mut in_order = Vec::new();
    let mut arriving = Vec::new();
    for k in 0..(seconds * 10.0) as usize {
        let t = k as f64 * 0.1;
        in_order.push(fix("w1", t, 0.0));
        in_order.push(fix("w2", t, 4.0));
        arriving.push((t + skew_s, fix("w1", t, 0.0)));
        arriving.push((t, fix("w2", t, 4.0)));
    }
    arriving.sort_by(|a, b| a.0.total_cmp(&b.0));
    (in_order, arriving.into_iter().map(|(_, r)| r).collect())
}

#[test]
fn a_sender_behind_another_gives_the_tracks_of_the_records_in_order() {
    // w1's records arrive 1.5 s after w2's of the same time: beyond the output interval, so
    // w1's track is ticked (it coasts) before each of its records, within the horizon (2 s)
    let (in_order, skewed) = skewed_senders(20.0, 1.5);
    let expected = run(rewinding("fix-then-filter"), in_order);
    let got = run(rewinding("fix-then-filter"), skewed);
    assert!(
        got.events.iter().all(|e| !matches!(e, Event::Late { .. })),
        "within the horizon nothing is late"
    );
    assert_same_final_revisions(&expected, &got, "fix-then-filter");
}

#[test]
fn a_record_behind_a_tick_rewinds_over_the_ticks_only() {
    use super::rewind::{History, Input};
    use super::track::Track;
    let horizon_s = 2.0;
    let track = Track::<4>::new(std::sync::Arc::from("w1"), 0, 0);
    let record = || {
        Input::Record(Measurement::Fix {
            position_m: vec![1.0, 2.0],
            covariance_m2: vec![0.04, 0.0, 0.0, 0.04],
        })
    };
    let mut history = History::new(&track);
    // records every 10 ms for 0.4 s: copies only every quarter horizon (0.5 s)
    for k in 0..40 {
        let t = k as f64 * 0.01;
        let copy = history.copy_due(t, horizon_s).then(|| track.clone());
        history.push(t, record(), copy, horizon_s);
    }
    assert!(history.last_is_record());
    // two ticks that changed the track (it coasts): the first after the records keeps a copy
    history.push_tick(0.9, Some(track.clone()), horizon_s);
    assert!(!history.last_is_record());
    history.push_tick(1.15, Some(track.clone()), horizon_s);
    // a record between the last record (0.39 s) and the ticks re-applies the ticks only
    let rewind = history.rewind(0.5).expect("within the horizon");
    let replayed: Vec<f64> = rewind.inputs.iter().map(|(t, _)| *t).collect();
    assert_eq!(replayed, vec![0.9, 1.15]);
    assert!(rewind.inputs.iter().all(|(_, i)| matches!(i, Input::Tick)));
    // a record before the last record rewinds to the periodic copy, as before
    let mut history = History::new(&track);
    for k in 0..40 {
        let t = k as f64 * 0.01;
        let copy = history.copy_due(t, horizon_s).then(|| track.clone());
        history.push(t, record(), copy, horizon_s);
    }
    history.push_tick(0.9, Some(track.clone()), horizon_s);
    let rewind = history.rewind(0.2).expect("within the horizon");
    assert_eq!(
        rewind.inputs.len(),
        40 + 1,
        "every record since the copy at 0 s, and the tick"
    );
}
