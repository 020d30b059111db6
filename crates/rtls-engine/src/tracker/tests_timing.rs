//! Ticks and records in time order. A tick at `τ` runs before any record later than `τ` is
//! applied, whether or not other tags' records fall between: so a track started or updated at
//! `t` is never ticked at an earlier time afterwards, and a tag's outputs do not depend on the
//! other tags in the feed.

use super::tests::{site, slant, ANCHORS};
use super::*;
use crate::lifecycle::LifecycleEvent;
use crate::record::Measurement;

/// RSSI `ρ = P₀ − 10 n log₁₀ d` of the test site's readers (P₀ = −40 dBm at 1 m, n = 2.5) from
/// `position` to anchor `index`, noise free.
fn rssi_dbm(position: [f64; 2], index: usize) -> f64 {
    -40.0 - 25.0 * slant(position, ANCHORS[index].1).log10()
}

/// One scan of `tag` at `time_s` by the anchors `indices`, in that order: one RSSI record per
/// reader, all with the same time (as `rtls_sim::mine::MineSimulation::step` emits them).
fn scan(tag: &str, time_s: f64, position: [f64; 2], indices: &[usize]) -> Vec<Record> {
    indices
        .iter()
        .map(|&i| Record {
            time_s,
            tag: tag.into(),
            measurement: Measurement::Rssi {
                anchor: ANCHORS[i].0.into(),
                rssi_dbm: rssi_dbm(position, i),
            },
        })
        .collect()
}

/// The mine's tracker settings on the test site: tightly coupled EKF, 1 s outputs (ticks every
/// 0.5 s); the site's 0.5 s re-ordering window holds a scan until the next one, as the mine's
/// 1 s window does.
fn mine_like() -> Tracker {
    Tracker::new(&site("tightly-coupled", "ekf", "output_interval_s = 1.0")).unwrap()
}

/// Pushes every record (panicking with the record's time on an error), then finishes.
fn run_checked(tracker: &mut Tracker, records: Vec<Record>, case: &str) -> Output {
    let mut out = Output::default();
    for record in records {
        let time_s = record.time_s;
        if let Err(error) = tracker.push(record, &mut out) {
            panic!("{case}: push at {time_s} s failed: {error}");
        }
    }
    tracker.finish(&mut out).unwrap();
    out
}

/// `tag`'s updates and lifecycle events, each with its time.
fn of_tag(out: &Output, tag: &str) -> (Vec<TrackUpdate>, Vec<(f64, LifecycleEvent)>) {
    let updates = out.updates.iter().filter(|u| &*u.tag == tag).cloned().collect();
    let events = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Lifecycle {
                tag: t, time_s, event, ..
            } if &**t == tag => Some((*time_s, *event)),
            _ => None,
        })
        .collect();
    (updates, events)
}

/// The regression (seen on the mine site at every roaming miner's track start): a first scan too
/// small to start a track, then full scans once a second. The track starts with a reading of
/// the second scan, ahead of the ticks the earlier records had driven (1 s between scans, ticks
/// every 0.5 s); those ticks must run first, so every push succeeds and the track confirms.
#[test]
fn a_track_started_between_ticks_is_not_ticked_back_in_time() {
    // (first scan, order of the later scans): 2 readers, then a third one first, so the first
    // reading of the second scan starts the track; 3 readers start it in the first scan and
    // the second scan's first reading updates it while still tentative
    let cases: [(&[usize], &[usize]); 2] = [(&[0, 1], &[2, 3, 0, 1]), (&[0, 1, 2], &[0, 1, 2, 3])];
    for (first, later) in cases {
        let case = format!("first scan {first:?}, then {later:?}");
        let position = [6.0, 7.0];
        let mut records = scan("m1", 0.5, position, first);
        for k in 1..8 {
            records.extend(scan("m1", 0.5 + f64::from(k), position, later));
        }
        let mut tracker = mine_like();
        let out = run_checked(&mut tracker, records, &case);
        assert_eq!(tracker.status("m1"), Some(TrackStatus::Confirmed), "{case}");
        let (updates, events) = of_tag(&out, "m1");
        let confirmed_s = events
            .iter()
            .find(|(_, e)| *e == LifecycleEvent::Confirmed)
            .map(|(t, _)| *t);
        assert!(
            confirmed_s.is_some_and(|t| t <= 2.5),
            "{case}: confirmed at {confirmed_s:?}"
        );
        assert!(events.windows(2).all(|w| w[0].0 <= w[1].0), "{case}: {events:?}");
        assert!(updates.windows(2).all(|w| w[0].time_s <= w[1].time_s), "{case}");
        let last = updates.last().unwrap();
        let error_m = (last.position_m[0] - position[0]).hypot(last.position_m[1] - position[1]);
        assert!(error_m < 0.5, "{case}: last position {:?}", last.position_m);
    }
}

/// A tag scanned once a second with a 4 s silence: alone, or with another tag's records between
/// its scans, it gets the same updates and lifecycle events, and the gap is filled with
/// coasting predictions at most an output interval and a tick period apart (the ticks in the
/// silence run before the scan that ends it, not after).
#[test]
fn a_tags_outputs_do_not_depend_on_other_tags_records() {
    let path = |t: f64| [3.0 + 0.5 * t, 4.0 + 0.3 * t];
    let mut alone = Vec::new();
    for t in [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 9.5, 10.5, 11.5, 12.5] {
        alone.extend(scan("m1", t, path(t), &[0, 1, 2, 3]));
    }
    // another tag scanned every 0.25 s off the tick grid, from after m1's first scan
    let mut mixed = alone.clone();
    for k in 0..50 {
        let t = 0.6 + 0.25 * f64::from(k);
        mixed.extend(scan("m2", t, [12.0, 12.0], &[0, 1, 2, 3]));
    }
    mixed.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let out_alone = run_checked(&mut mine_like(), alone, "m1 alone");
    let out_mixed = run_checked(&mut mine_like(), mixed, "m1 with m2");
    let (updates, events) = of_tag(&out_alone, "m1");
    assert_eq!(
        (&updates, &events),
        (&of_tag(&out_mixed, "m1").0, &of_tag(&out_mixed, "m1").1)
    );
    // the silence from 5.5 s to 9.5 s: coasting predictions, then the track resumes
    let predicted: Vec<f64> = updates.iter().filter(|u| u.predicted).map(|u| u.time_s).collect();
    assert!(
        !predicted.is_empty() && predicted.iter().all(|&t| t > 5.5 && t < 9.5),
        "{predicted:?}"
    );
    assert!(events.contains(&(9.5, LifecycleEvent::Resumed)), "{events:?}");
    let confirmed_s = events.iter().find(|(_, e)| *e == LifecycleEvent::Confirmed).unwrap().0;
    let times: Vec<f64> = updates.iter().map(|u| u.time_s).filter(|&t| t >= confirmed_s).collect();
    let widest_s = times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(widest_s <= 1.5, "outputs {widest_s} s apart: {times:?}");
}

/// Fix-then-filter with `epoch_s` = 0.3: each second's readings (two anchors at +0.3 s, two at
/// +0.45 s) form one epoch that a tick (on the 0.5 s grid from another tag's record at 0)
/// falls inside. The track is not ticked past its open epoch's readings: every push succeeds,
/// and each fix updates the track at its epoch's mean reading time, in order.
#[test]
fn a_tick_inside_an_open_epoch_waits_for_its_fix() {
    let site = site("fix-then-filter", "kf", "output_interval_s = 1.0\nepoch_s = 0.3");
    let mut tracker = Tracker::new(&site).unwrap();
    let path = |t: f64| [3.0 + 0.5 * t, 4.0 + 0.3 * t];
    let ranges = |t: f64, indices: &[usize]| -> Vec<Record> {
        indices.iter().map(|&i| range_from("w1", t, path(t), i)).collect()
    };
    let mut records = scan("w0", 0.0, [12.0, 12.0], &[0]);
    // a silence from 6.45 s to 9.3 s, so the track also coasts with an epoch open
    for k in [0, 1, 2, 3, 4, 5, 6, 9, 10, 11] {
        let second = f64::from(k);
        records.extend(ranges(second + 0.3, &[0, 1]));
        records.extend(ranges(second + 0.45, &[2, 3]));
    }
    let out = run_checked(&mut tracker, records, "fix-then-filter");
    assert_eq!(tracker.status("w1"), Some(TrackStatus::Confirmed));
    let (updates, events) = of_tag(&out, "w1");
    let measured: Vec<f64> = updates.iter().filter(|u| !u.predicted).map(|u| u.time_s).collect();
    // each fix at its epoch's mean reading time, k + 0.375 s
    let expected: Vec<f64> = [0, 1, 2, 3, 4, 5, 6, 9, 10, 11]
        .iter()
        .map(|&k| f64::from(k) + 0.375)
        .collect();
    assert_eq!(measured.len(), expected.len(), "{measured:?}");
    assert!(
        measured.iter().zip(&expected).all(|(m, e)| (m - e).abs() < 1e-9),
        "{measured:?}"
    );
    assert!(updates.windows(2).all(|w| w[0].time_s <= w[1].time_s));
    assert!(events.windows(2).all(|w| w[0].0 <= w[1].0), "{events:?}");
    assert!(
        updates.iter().any(|u| u.predicted),
        "the silence is filled with predictions"
    );
}

/// `tag`'s range at `time_s` from `position` to anchor `index`, noise free apart from the
/// site's +0.2 m bias.
fn range_from(tag: &str, time_s: f64, position: [f64; 2], index: usize) -> Record {
    Record {
        time_s,
        tag: tag.into(),
        measurement: Measurement::Range {
            anchor: ANCHORS[index].0.into(),
            range_m: slant(position, ANCHORS[index].1) + 0.2,
            std_m: None,
            anchor_position_m: None,
        },
    }
}

/// Ranges of `tag` walking `path`, one anchor at a time: in second `k`, anchor `i` at
/// `k + 0.2 i` (Wi-Fi RTT, TDMA UWB).
fn staggered_ranges(tag: &str, seconds: u32, path: fn(f64) -> [f64; 2]) -> Vec<Record> {
    (0..seconds)
        .flat_map(|k| (0..ANCHORS.len()).map(move |i| (f64::from(k) + 0.2 * i as f64, i)))
        .map(|(t, i)| range_from(tag, t, path(t), i))
        .collect()
}

/// Without `epoch_s`, fix-then-filter collects the readings of a tag whose anchors report one
/// at a time until an anchor repeats: the first lone reading is refused (the tag's readers are
/// not yet known to report one at a time), then one fix per round (A2, A3, A4, A1), dated at
/// its readings' mean time, `k + 0.55` s, and the last, cut short by the end, at 7.4 s.
/// With `epoch_s = 0` (equal time stamps only) every one-reading epoch is refused.
#[test]
fn without_epoch_s_readings_one_anchor_at_a_time_give_one_fix_per_round() {
    let path = |t: f64| [5.0 + 0.4 * t, 6.0 + 0.2 * t];
    let records = staggered_ranges("w1", 8, path);
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "output_interval_s = 1.0")).unwrap();
    let out = run_checked(&mut tracker, records.clone(), "automatic epochs");
    let refused: Vec<(f64, &str)> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { time_s, reason, .. } => Some((*time_s, reason.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0].0 == 0.0 && refused[0].1.contains("1 distinct anchor position"),
        "{refused:?}"
    );
    let (updates, _) = of_tag(&out, "w1");
    let measured: Vec<&TrackUpdate> = updates.iter().filter(|u| !u.predicted).collect();
    let times: Vec<f64> = measured.iter().map(|u| u.time_s).collect();
    let expected: Vec<f64> = (0..7).map(|k| f64::from(k) + 0.55).chain([7.4]).collect();
    assert_eq!(times.len(), expected.len(), "{times:?}");
    assert!(
        times.iter().zip(&expected).all(|(t, e)| (t - e).abs() < 1e-9),
        "{times:?}"
    );
    // the truth at the fix's time: within a few centimetres of the noise-free fixes
    for update in &measured {
        let truth = path(update.time_s);
        let error_m = (update.position_m[0] - truth[0]).hypot(update.position_m[1] - truth[1]);
        assert!(error_m < 0.1, "{error_m} m off at {} s", update.time_s);
    }

    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "output_interval_s = 1.0\nepoch_s = 0.0")).unwrap();
    let out = run_checked(&mut tracker, records, "equal time stamps only");
    assert!(out.updates.iter().all(|u| &*u.tag != "w1"));
    let refused = out
        .events
        .iter()
        .filter(|e| matches!(e, Event::Rejected { reason, .. } if reason.contains("1 distinct anchor position")))
        .count();
    assert_eq!(refused, 32);
}

/// A live clock (`advance_to`, as the server calls it with the wall clock) releases a silent
/// tag's last scan from the re-ordering window, then coasts and loses the track; a record
/// that arrives after the clock passed its time is reported late, not applied behind a tick.
#[test]
fn the_live_clock_releases_the_window_and_reports_records_it_passed_as_late() {
    let mut tracker = mine_like();
    let mut out = Output::default();
    let position = [10.0, 5.0];
    for k in 0..6 {
        for record in scan("live", f64::from(k), position, &[0, 1, 2, 3]) {
            tracker.push(record, &mut out).unwrap();
        }
    }
    let latest = |out: &Output| {
        out.updates
            .iter()
            .filter(|u| !u.predicted)
            .map(|u| u.time_s)
            .fold(f64::NAN, f64::max)
    };
    // the scan at 5 s waits in the 0.5 s window for newer data that never comes
    assert!(latest(&out) < 5.0, "latest measured update {}", latest(&out));
    out.clear();
    tracker.advance_to(5.4, &mut out).unwrap();
    assert!(
        out.updates.iter().all(|u| u.time_s < 5.0),
        "5.4 s − 0.5 s window: the 5 s scan stays held"
    );
    tracker.advance_to(6.6, &mut out).unwrap();
    assert_eq!(
        latest(&out),
        5.0,
        "the clock released the last scan (reported at the next output tick)"
    );
    // silence: coasting predictions, then lost after the coast timeout
    for k in 1..=40 {
        tracker.advance_to(6.6 + 0.5 * f64::from(k), &mut out).unwrap();
    }
    assert!(out.updates.iter().any(|u| u.predicted && u.time_s > 7.0));
    let lost = out.events.iter().any(|e| {
        matches!(
            e,
            Event::Lifecycle {
                event: LifecycleEvent::Lost,
                ..
            }
        )
    });
    assert!(lost, "the silent track is lost");
    // a scan from 20 s ago arrives now: late, not an error
    out.clear();
    for record in scan("live", 6.0, position, &[0, 1]) {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.advance_to(27.0, &mut out).unwrap();
    let late = out.events.iter().filter(|e| matches!(e, Event::Late { .. })).count();
    assert_eq!(late, 2);
    assert!(out.updates.iter().all(|u| u.time_s > 6.0));
}
