//! The due-track schedule ([`super::due`]: a tick visits only the tracks it can change)
//! against a tick over every track, its reference, through the whole tracker: the same records
//! give the same updates, fixes and events, in the same order — with tentative tracks that die,
//! confirmation, coasting, loss, recovery and deletion, fix-then-filter epochs with held
//! velocities, late records re-filtered, a clock advanced without records, pending updates
//! reported between batches, and tightly coupled tracks.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::core::TICK_EVERY_TRACK;
use super::tests::{range_record, site_text, slant, ANCHORS};
use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// One step of the input: a record, the clock advanced, or the pending updates reported.
#[derive(Clone)]
enum Step {
    Push(Record),
    Advance(f64),
    Report,
}

/// Eight fix tags with silences (coasting, lost, recovered, deleted), one-off tags that stay
/// tentative and die, velocities, a ranging tag (fix-then-filter epochs), out of order records
/// up to 1.2 s late, clock advances and reports between batches.
fn steps(seed: u64, ranges: bool) -> Vec<Step> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.3).unwrap();
    let mut steps = Vec::new();
    for k in 0..480 {
        let t = 0.25 * f64::from(k);
        for i in 0..8 {
            // tag i is silent over its own stretch: short (coasting), longer than the coast
            // timeout (lost) or than the delete timeout (deleted, then a new track)
            let silent = match i % 4 {
                0 => (20.0..22.0).contains(&t),
                1 => (30.0..40.0).contains(&t),
                2 => (50.0..75.0).contains(&t),
                _ => rng.gen_bool(0.3),
            };
            if silent {
                continue;
            }
            let truth = [3.0 + 0.1 * t + 2.0 * f64::from(i), 4.0 + 0.05 * t];
            let late = if rng.gen_bool(0.05) { 1.2 } else { 0.0 };
            let time_s = t + 0.003 * f64::from(i) - late;
            steps.push(Step::Push(Record {
                time_s,
                tag: format!("f{i}"),
                measurement: Measurement::Fix {
                    position_m: vec![truth[0] + noise.sample(&mut rng), truth[1] + noise.sample(&mut rng)],
                    covariance_m2: vec![0.09, 0.0, 0.0, 0.09],
                },
            }));
            if k % 6 == i {
                steps.push(Step::Push(Record {
                    time_s: time_s + 0.05,
                    tag: format!("f{i}"),
                    measurement: Measurement::Velocity {
                        velocity_mps: vec![0.1, 0.05],
                        covariance_m2ps2: Some(vec![0.04, 0.0, 0.0, 0.04]),
                    },
                }));
            }
        }
        if k % 37 == 3 {
            // a one-off tag: tentative, never confirmed, deleted
            steps.push(Step::Push(Record {
                time_s: t + 0.1,
                tag: format!("once-{k}"),
                measurement: Measurement::Fix {
                    position_m: vec![10.0, 10.0],
                    covariance_m2: vec![0.09, 0.0, 0.0, 0.09],
                },
            }));
        }
        if ranges && !(60.0..70.0).contains(&t) {
            let walker = [10.0 + 0.05 * t, 8.0 - 0.03 * t];
            for (id, a) in ANCHORS {
                steps.push(Step::Push(range_record(
                    t + 0.02,
                    "r1",
                    id,
                    slant(walker, a) + 0.1 * noise.sample(&mut rng),
                )));
            }
        }
        if k % 10 == 9 {
            steps.push(Step::Report);
        }
        if k % 40 == 39 {
            // a live clock running ahead of the records
            steps.push(Step::Advance(t + 0.2));
        }
    }
    steps
}

/// The outputs of `steps` through a tracker of the test site with `extra` tracker settings,
/// every tick over every track or not; updates, raw fixes and events as text.
fn run(pipeline: &str, filter: &str, extra: &str, steps: &[Step], every_track: bool) -> Vec<String> {
    let mut text = site_text(pipeline, filter, extra);
    if extra.contains("rewind_horizon_s") {
        text = text.replace("reorder_window_s = 0.5", "reorder_window_s = 0.0");
    }
    let site = Site::from_toml_str(&text, "due-ticks.toml").unwrap();
    TICK_EVERY_TRACK.with(|flag| flag.set(every_track));
    let mut tracker = Tracker::new(&site).unwrap();
    assert_eq!(tracker.shared().constraints.is_some(), extra.contains("max_speed_mps"));
    let mut out = Output::default();
    for step in steps {
        match step {
            Step::Push(record) => tracker.push(record.clone(), &mut out).unwrap(),
            Step::Advance(time_s) => tracker.advance_to(*time_s, &mut out).unwrap(),
            Step::Report => tracker.report_pending(&mut out).unwrap(),
        }
    }
    tracker.finish(&mut out).unwrap();
    TICK_EVERY_TRACK.with(|flag| flag.set(false));
    let mut lines: Vec<String> = out.updates.iter().map(|u| format!("{u:?}")).collect();
    lines.extend(out.fixes.iter().map(|f| format!("{f:?}")));
    lines.extend(out.events.iter().map(|e| format!("{e:?}")));
    lines
}

fn assert_same(pipeline: &str, filter: &str, extra: &str, ranges: bool, seed: u64) {
    let steps = steps(seed, ranges);
    let due = run(pipeline, filter, extra, &steps, false);
    let every = run(pipeline, filter, extra, &steps, true);
    assert_eq!(due.len(), every.len(), "{extra}: output count");
    for (d, e) in due.iter().zip(&every) {
        assert_eq!(d, e, "{extra}");
    }
    // the scenario reaches every part of the lifecycle
    for needed in [
        "Confirmed",
        "StartedCoasting",
        "Lost",
        "Recovered",
        "Deleted",
        "predicted: true",
    ] {
        assert!(due.iter().any(|line| line.contains(needed)), "{extra}: no {needed}");
    }
}

#[test]
fn due_ticks_track_as_ticks_over_every_track() {
    assert_same("fix-then-filter", "kf", "", true, 1);
}

#[test]
fn due_ticks_track_as_ticks_over_every_track_with_rewinds() {
    assert_same("fix-then-filter", "kf", "rewind_horizon_s = 2.0", true, 2);
}

#[test]
fn due_ticks_track_as_ticks_over_every_track_tightly_coupled() {
    assert_same("tightly-coupled", "ekf", "rewind_horizon_s = 2.0", true, 3);
}

#[test]
fn due_ticks_track_as_ticks_over_every_track_with_constraints() {
    // a speed limit: the constraints' epochs close on ticks, so every tick visits every track
    assert_same("fix-then-filter", "kf", "max_speed_mps = 3.0", true, 4);
}
