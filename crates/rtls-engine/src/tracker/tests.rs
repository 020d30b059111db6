//! Tracker behaviour on simulated tags: both pipelines, every measurement kind, order,
//! lifecycle, zones and alarms.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::lifecycle::LifecycleEvent;
use crate::record::Measurement;
use crate::site::Site;
use crate::zones::ZoneEvent;

/// Four UWB anchors on a 20 m × 20 m square at 2.5 m height, plus a broken one, a hazard box at
/// x ≥ 30 and an area without a working reader around the broken one.
pub(super) fn site_text(pipeline: &str, filter: &str, extra_tracker: &str) -> String {
    let radio = "radio = { range = { range_std_m = 0.1, bias_m = 0.2 }, path_loss = { reference_power_dbm = -40.0, \
                 exponent = 2.5, shadowing_std_db = 2.0, reference_distance_m = 1.0 } }";
    let readers: String = ANCHORS
        .iter()
        .map(|(id, [x, y, z])| {
            format!(
                "[[readers]]\nid = \"{id}\"\nposition_m = [{x:.1}, {y:.1}, {z:.1}]\ntechnology = \"uwb\"\n{radio}\n"
            )
        })
        .collect();
    format!(
        r#"
{readers}[[readers]]
id = "X"
position_m = [45.0, 10.0, 2.5]
technology = "uwb"
working = false

[[zones]]
id = "pit"
name = "Open pit"
kind = "hazard"
shape = {{ type = "box", min_m = [30.0, -50.0, -10.0], max_m = [40.0, 50.0, 10.0] }}

[[zones]]
id = "dead-end"
name = "Drift with a broken reader"
kind = "area-of-interest"
readers = ["X"]
shape = {{ type = "polygon", vertices_m = [[40.0, -50.0], [60.0, -50.0], [60.0, 50.0], [40.0, 50.0]] }}

[[zones]]
id = "office"
name = "Office"
kind = "area-of-interest"
shape = {{ type = "polygon", vertices_m = [[8.0, 8.0], [12.0, 8.0], [12.0, 12.0], [8.0, 12.0]] }}

[tracker]
pipeline = "{pipeline}"
motion_model = "cv"
filter = "{filter}"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 5.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 20.0
reorder_window_s = 0.5
tag_height_m = 1.0
{extra_tracker}
"#
    )
}

pub(super) fn site(pipeline: &str, filter: &str, extra: &str) -> Site {
    Site::from_toml_str(&site_text(pipeline, filter, extra), "test-site.toml").unwrap()
}

/// A walker: starts at (2, 3), walks at (0.8, 0.5) m/s.
fn walker(t: f64) -> [f64; 2] {
    [2.0 + 0.8 * t, 3.0 + 0.5 * t]
}

pub(super) const ANCHORS: [(&str, [f64; 3]); 4] = [
    ("A1", [0.0, 0.0, 2.5]),
    ("A2", [20.0, 0.0, 2.5]),
    ("A3", [20.0, 20.0, 2.5]),
    ("A4", [0.0, 20.0, 2.5]),
];

pub(super) fn slant(p: [f64; 2], a: [f64; 3]) -> f64 {
    ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (1.0 - a[2]).powi(2)).sqrt()
}

/// Ranges at 10 Hz, all four anchors per epoch (equal time stamps), biased by +0.2 m and with
/// σ = 0.1 m noise, for `seconds`.
pub(super) fn range_records(seconds: f64, seed: u64, path: fn(f64) -> [f64; 2]) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut records = Vec::new();
    let epochs = (seconds * 10.0) as usize;
    for k in 0..epochs {
        let t = k as f64 * 0.1;
        for (id, a) in ANCHORS {
            records.push(Record {
                time_s: t,
                tag: "w1".into(),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: slant(path(t), a) + 0.2 + noise.sample(&mut rng),
                    std_m: None,
                    anchor_position_m: None,
                },
            });
        }
    }
    records
}

/// A range of `tag` to `anchor` at `time_s`, with the site's σ and the anchor's surveyed
/// position.
pub(super) fn range_record(time_s: f64, tag: impl Into<String>, anchor: &str, range_m: f64) -> Record {
    Record {
        time_s,
        tag: tag.into(),
        measurement: Measurement::Range {
            anchor: anchor.into(),
            range_m,
            std_m: None,
            anchor_position_m: None,
        },
    }
}

/// RSSI readings `readings` (indices of a round robin over the four anchors, one every 50 ms
/// from t = 0) of a tag standing at (8, 6): the site's law with `std_db` shadowing drawn from
/// `seed`.
pub(super) fn standing_rssi_records(seed: u64, std_db: f64, readings: std::ops::Range<usize>) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let shadowing = Normal::new(0.0, std_db).unwrap();
    readings
        .map(|k| {
            let (id, a) = ANCHORS[k % 4];
            Record {
                time_s: k as f64 * 0.05,
                tag: "w1".into(),
                measurement: Measurement::Rssi {
                    anchor: id.into(),
                    rssi_dbm: -40.0 - 25.0 * slant([8.0, 6.0], a).log10() + shadowing.sample(&mut rng),
                },
            }
        })
        .collect()
}

/// The times of `out`'s `jumped` lifecycle events.
pub(super) fn jump_times(out: &Output) -> Vec<f64> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Lifecycle {
                event: crate::lifecycle::LifecycleEvent::Jumped,
                time_s,
                ..
            } => Some(*time_s),
            _ => None,
        })
        .collect()
}

/// Fixes of tag `phone`, σ = 3 m, every `step_s` for `count` steps: at rest at the origin until
/// t = 5 s, then running east at 8 m/s (fixes that run away, as a fingerprint's on the wrong
/// floor do).
pub(super) fn running_fixes(step_s: f64, count: u32) -> Vec<Record> {
    (0..count)
        .map(|k| {
            let t = step_s * f64::from(k);
            Record {
                time_s: t,
                tag: "phone".into(),
                measurement: Measurement::Fix {
                    position_m: vec![8.0 * (t - 5.0).max(0.0), 0.0],
                    covariance_m2: vec![9.0, 0.0, 0.0, 9.0],
                },
            }
        })
        .collect()
}

pub(super) fn run(tracker: &mut Tracker, records: Vec<Record>) -> Output {
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out
}

/// `P`'s horizontal block of an update: `[P_xx, P_xy, P_yy]` (`position_covariance_m2` is
/// `D × D` row-major in its first `D²` entries, so `P_yy` is entry `D + 1`).
pub(super) fn horizontal_covariance_m2(update: &TrackUpdate) -> [f64; 3] {
    let c = &update.position_covariance_m2;
    let d = update.dimensions;
    [c[0], c[1], c[d + 1]]
}

/// `eᵀ P⁻¹ e` of a horizontal error `e` (m) against the update's horizontal covariance: inside
/// the 95 % ellipse when ≤ χ²₂(0.95) = 5.991.
pub(super) fn horizontal_nees(update: &TrackUpdate, e: [f64; 2]) -> f64 {
    let [a, b, d] = horizontal_covariance_m2(update);
    (d * e[0] * e[0] - 2.0 * b * e[0] * e[1] + a * e[1] * e[1]) / (a * d - b * b)
}

/// A confirmed 2-D fix update of `tag` at `time_s`, at `(x_m, 0)`, at rest, with the position
/// covariance `P = diag(σx², σy²)`.
pub(super) fn fix_update_at(tag: &str, time_s: f64, x_m: f64, [var_x_m2, var_y_m2]: [f64; 2]) -> TrackUpdate {
    TrackUpdate {
        time_s,
        tag: tag.into(),
        dimensions: 2,
        position_m: [x_m, 0.0, 0.0],
        velocity_mps: [0.0; 3],
        position_covariance_m2: [var_x_m2, 0.0, 0.0, var_y_m2, 0.0, 0.0, 0.0, 0.0, 0.0],
        predicted: false,
        status: TrackStatus::Confirmed,
        source: UpdateSource::Fix,
        mode: None,
        revised: false,
        smoothed: false,
    }
}

#[test]
fn the_horizontal_nees_reads_the_covariance_of_either_dimension() {
    let mut update = fix_update_at("t", 0.0, 0.0, [4.0, 1.0]);
    // P = diag(4, 1): e = (2, 1) is 1 + 1
    assert!((horizontal_nees(&update, [2.0, 1.0]) - 2.0).abs() < 1e-12);
    update.dimensions = 3;
    update.position_covariance_m2 = [4.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 9.0];
    assert!((horizontal_nees(&update, [2.0, 1.0]) - 2.0).abs() < 1e-12);
}

pub(super) fn rmse(updates: &[(f64, [f64; 3])], path: fn(f64) -> [f64; 2], after_s: f64) -> f64 {
    let errors: Vec<f64> = updates
        .iter()
        .filter(|(t, _)| *t >= after_s)
        .map(|(t, p)| {
            let truth = path(*t);
            (p[0] - truth[0]).powi(2) + (p[1] - truth[1]).powi(2)
        })
        .collect();
    assert!(!errors.is_empty());
    (errors.iter().sum::<f64>() / errors.len() as f64).sqrt()
}

#[test]
fn fix_then_filter_smooths_the_epoch_fixes() {
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let out = run(&mut tracker, range_records(20.0, 1, walker));
    // one fix and one update per 10 Hz epoch
    assert_eq!(out.fixes.len(), 200);
    assert_eq!(out.updates.len(), 200);
    assert!(
        out.events.iter().all(|e| !matches!(e, Event::Rejected { .. })),
        "{:?}",
        out.events
    );
    let fixes: Vec<_> = out.fixes.iter().map(|f| (f.time_s, f.position_m)).collect();
    let tracks: Vec<_> = out.updates.iter().map(|u| (u.time_s, u.position_m)).collect();
    let (raw, filtered) = (rmse(&fixes, walker, 2.0), rmse(&tracks, walker, 2.0));
    // the bias is removed (raw fixes near σ·GDOP ≈ 0.1 m), and the KF beats the raw fixes
    assert!(raw < 0.2, "raw {raw}");
    assert!(filtered < 0.8 * raw, "filtered {filtered} vs raw {raw}");
    // the velocity is estimated: σ_a = 0.5 m/s² with 0.1 m fixes at 10 Hz gives a steady-state
    // velocity std of ≈ √2 q^¾ (R T)^¼ ≈ 0.3 m/s per update, so compare the 15 s average
    let late: Vec<&TrackUpdate> = out.updates.iter().filter(|u| u.time_s >= 5.0).collect();
    let mean_v = |axis: usize| late.iter().map(|u| u.velocity_mps[axis]).sum::<f64>() / late.len() as f64;
    assert!(
        (mean_v(0) - 0.8).abs() < 0.05 && (mean_v(1) - 0.5).abs() < 0.05,
        "{} {}",
        mean_v(0),
        mean_v(1)
    );
    let last = out.updates.last().unwrap();
    assert!(!last.predicted && last.status == TrackStatus::Confirmed);
}

#[test]
fn tightly_coupled_ekf_and_ukf_track_from_single_ranges() {
    for filter in ["ekf", "ukf"] {
        let mut tracker = Tracker::new(&site("tightly-coupled", filter, "")).unwrap();
        // one anchor per 25 ms slot, round robin (seed 003's one-observation updates)
        let mut records = range_records(20.0, 2, walker);
        for (i, record) in records.iter_mut().enumerate() {
            record.time_s += (i % 4) as f64 * 0.025;
        }
        let out = run(&mut tracker, records);
        let tracks: Vec<_> = out.updates.iter().map(|u| (u.time_s, u.position_m)).collect();
        let error = rmse(&tracks, walker, 2.0);
        assert!(error < 0.12, "{filter}: {error}");
        // an update per range once started, each reported once
        assert!(out.updates.len() > 780, "{filter}: {}", out.updates.len());
        assert!(out.updates.windows(2).all(|w| w[0].time_s < w[1].time_s));
    }
}

#[test]
fn rssi_in_both_pipelines_uses_the_path_loss_law() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let shadowing = Normal::new(0.0, 2.0).unwrap();
    let mut records = Vec::new();
    for k in 0..400 {
        let t = k as f64 * 0.05;
        let (id, a) = ANCHORS[k % 4];
        let d = slant(walker(t), a);
        records.push(Record {
            time_s: t,
            tag: "w1".into(),
            measurement: Measurement::Rssi {
                anchor: id.into(),
                rssi_dbm: -40.0 - 25.0 * d.log10() + shadowing.sample(&mut rng),
            },
        });
    }
    let coupled = run(
        &mut Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap(),
        records.clone(),
    );
    let fixed = run(
        &mut Tracker::new(&site("fix-then-filter", "kf", "epoch_s = 0.19")).unwrap(),
        records,
    );
    for (name, out) in [("coupled", coupled), ("fix-then-filter", fixed)] {
        let tracks: Vec<_> = out.updates.iter().map(|u| (u.time_s, u.position_m)).collect();
        let error = rmse(&tracks, walker, 5.0);
        // 2 dB shadowing at 5–20 m with n = 2.5 is roughly 0.5–2 m of range error per reading
        assert!(error < 2.0, "{name}: {error}");
    }
}

#[test]
fn tdoa_fixes_and_tdoa_updates() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut records = Vec::new();
    for k in 0..150 {
        let t = k as f64 * 0.1;
        let reference = ANCHORS[0];
        for (id, a) in &ANCHORS[1..] {
            let p = walker(t);
            records.push(Record {
                time_s: t,
                tag: "w1".into(),
                measurement: Measurement::Tdoa {
                    anchor: (*id).into(),
                    reference: reference.0.into(),
                    // the reader biases (0.2 m each) cancel
                    range_difference_m: slant(p, *a) - slant(p, reference.1) + noise.sample(&mut rng),
                    std_m: Some(0.05),
                },
            });
        }
    }
    // 2-D TDOA fixes treat the anchors as coplanar: all at 2.5 m and the tag at 1 m is a
    // model error of ≈ Δz²/(2d) ≈ 0.1 m, so test the fix pipeline in a coplanar frame
    let fixed = run(
        &mut Tracker::new(&site("fix-then-filter", "kf", "")).unwrap(),
        records.clone(),
    );
    assert_eq!(fixed.fixes.len(), 150);
    let tracks: Vec<_> = fixed.updates.iter().map(|u| (u.time_s, u.position_m)).collect();
    assert!(rmse(&tracks, walker, 2.0) < 0.3);
    // the coupled TDOA model uses the slant geometry exactly; it starts from a TDOA fix
    let coupled = run(&mut Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap(), records);
    let tracks: Vec<_> = coupled.updates.iter().map(|u| (u.time_s, u.position_m)).collect();
    assert!(rmse(&tracks, walker, 2.0) < 0.1, "{}", rmse(&tracks, walker, 2.0));
}

#[test]
fn shuffled_records_within_the_window_give_the_same_tracks_and_late_ones_are_reported() {
    let records = range_records(10.0, 5, walker);
    let sorted = run(
        &mut Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap(),
        records.clone(),
    );
    // swap neighbouring epochs (0.1 s apart, window 0.5 s)
    let mut shuffled = records.clone();
    for chunk in shuffled.chunks_mut(8) {
        if chunk.len() == 8 {
            let (a, b) = chunk.split_at_mut(4);
            a.swap_with_slice(b);
        }
    }
    let reordered = run(
        &mut Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap(),
        shuffled,
    );
    assert_eq!(sorted, reordered);
    // a record 3.9 s behind the newest (3.4 s beyond the 0.5 s window) is late: reported, not
    // applied
    let mut late = records;
    let mut stale = late[40].clone();
    stale.time_s = 1.0;
    late.insert(200, stale);
    let out = run(&mut Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap(), late);
    let lates: Vec<_> = out.events.iter().filter(|e| matches!(e, Event::Late { .. })).collect();
    assert_eq!(lates.len(), 1, "{lates:?}");
    assert!(
        matches!(lates[0], Event::Late { lateness_s, .. } if (*lateness_s - 3.4).abs() < 1e-9),
        "{lates:?}"
    );
    assert_eq!(out.updates.len(), sorted.updates.len());
}

#[test]
fn a_silent_tag_coasts_with_growing_covariance_then_is_lost_then_deleted() {
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut out = Output::default();
    for record in range_records(5.0, 6, walker) {
        tracker.push(record, &mut out).unwrap();
    }
    // a second tag keeps the clock running for 40 s; w1 is silent from t = 4.9 s
    for k in 0..400 {
        let t = 5.0 + k as f64 * 0.1;
        let record = Record {
            time_s: t,
            tag: "clock".into(),
            measurement: Measurement::Fix {
                position_m: vec![10.0, 10.0],
                covariance_m2: vec![0.01, 0.0, 0.0, 0.01],
            },
        };
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let w1: Vec<&TrackUpdate> = out.updates.iter().filter(|u| &*u.tag == "w1").collect();
    let predicted: Vec<&&TrackUpdate> = w1
        .iter()
        .filter(|u| u.predicted && u.status == TrackStatus::Coasting)
        .collect();
    // coasting: a prediction every second from when an update is overdue (> 1 s) until lost (5 s)
    assert!((4..=6).contains(&predicted.len()), "{}", predicted.len());
    assert!(predicted.iter().all(|u| u.source == UpdateSource::Prediction));
    // the covariance grows and the prediction follows the walker's velocity
    assert!(predicted
        .windows(2)
        .all(|w| w[1].position_covariance_m2[0] > w[0].position_covariance_m2[0]));
    let first = predicted[0];
    let truth = walker(first.time_s);
    assert!((first.position_m[0] - truth[0]).abs() < 0.3 && (first.position_m[1] - truth[1]).abs() < 0.3);
    let lifecycle: Vec<(LifecycleEvent, f64, [f64; 3])> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Lifecycle {
                tag,
                event,
                time_s,
                position_m,
            } if &**tag == "w1" => Some((*event, *time_s, *position_m)),
            _ => None,
        })
        .collect();
    let kinds: Vec<LifecycleEvent> = lifecycle.iter().map(|(e, _, _)| *e).collect();
    assert_eq!(
        kinds,
        vec![
            LifecycleEvent::Confirmed,
            LifecycleEvent::StartedCoasting,
            LifecycleEvent::Lost,
            LifecycleEvent::Deleted
        ]
    );
    // lost after > 5 s of silence, keeping the last estimate (within the walker's last fix area)
    let (_, lost_s, lost_at) = lifecycle[2];
    assert!(lost_s > 4.9 + 5.0 && lost_s < 4.9 + 6.5, "{lost_s}");
    let last = walker(4.9);
    assert!(
        (lost_at[0] - last[0]).abs() < 0.3 && (lost_at[1] - last[1]).abs() < 0.3,
        "{lost_at:?}"
    );
    assert!(lifecycle[3].1 > 4.9 + 20.0);
    // while lost, the last estimated position is reported every second, until deletion
    let lost: Vec<&&TrackUpdate> = w1.iter().filter(|u| u.status == TrackStatus::Lost).collect();
    assert!((14..=16).contains(&lost.len()), "{}", lost.len());
    assert!(lost.iter().all(|u| u.predicted && u.position_m == lost_at));
    assert!(w1.iter().all(|u| u.time_s <= lifecycle[3].1));
    assert_eq!(tracker.track_count(), 1);
    assert_eq!(tracker.status("w1"), None);
}

#[test]
fn unusable_measurements_are_reported_with_the_reason() {
    let site = site("tightly-coupled", "ekf", "");
    let tracker = Tracker::new(&site).unwrap();
    let unknown = Record {
        time_s: 0.0,
        tag: "w1".into(),
        measurement: Measurement::Tdoa {
            anchor: "A1".into(),
            reference: "A9".into(),
            range_difference_m: 1.0,
            std_m: None,
        },
    };
    let error = tracker.check_record(&unknown, "in.jsonl", 12).unwrap_err().to_string();
    assert!(error.starts_with("in.jsonl:12: field `reference`"), "{error}");
    let mut records = range_records(6.0, 7, walker);
    records.push(Record {
        time_s: 5.95,
        tag: "w1".into(),
        measurement: Measurement::Range {
            anchor: "X".into(),
            range_m: 3.0,
            std_m: None,
            anchor_position_m: None,
        },
    });
    // a gross outlier once confirmed
    records.push(Record {
        time_s: 5.96,
        tag: "w1".into(),
        measurement: Measurement::Range {
            anchor: "A1".into(),
            range_m: 50.0,
            std_m: None,
            anchor_position_m: None,
        },
    });
    records.push(Record {
        time_s: 5.97,
        ..unknown
    });
    let mut tracker = tracker;
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let reasons: Vec<&str> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { reason, .. } => Some(reason.as_str()),
            _ => None,
        })
        .collect();
    assert!(
        reasons.iter().any(|r| r.contains("`X` is marked broken")),
        "{reasons:?}"
    );
    assert!(reasons.iter().any(|r| r.contains("validation gate")), "{reasons:?}");
    assert!(
        reasons.iter().any(|r| r.contains("`A9` is not a reader")),
        "{reasons:?}"
    );
    assert_eq!(reasons.len(), 3, "{reasons:?}");
}

#[test]
fn fixes_velocities_and_odometry_update_the_track() {
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut out = Output::default();
    for k in 0..50 {
        let t = k as f64 * 0.2;
        let p = walker(t);
        let fix = Record {
            time_s: t,
            tag: "r1".into(),
            measurement: Measurement::Fix {
                position_m: vec![p[0], p[1], 1.0],
                covariance_m2: vec![0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 0.25],
            },
        };
        tracker.push(fix, &mut out).unwrap();
        let odometry = Record {
            time_s: t + 0.1,
            tag: "r1".into(),
            measurement: Measurement::Odometry {
                speed_mps: (0.8f64 * 0.8 + 0.5 * 0.5).sqrt(),
                heading_rad: Some(0.5f64.atan2(0.8)),
                speed_std_mps: Some(0.02),
                heading_std_rad: Some(0.02),
            },
        };
        tracker.push(odometry, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    assert!(
        out.events.iter().all(|e| !matches!(e, Event::Rejected { .. })),
        "{:?}",
        out.events
    );
    assert!(out.updates.iter().any(|u| u.source == UpdateSource::Velocity));
    let last = out.updates.last().unwrap();
    // odometry pins the velocity far tighter than 0.5 m fixes alone could
    assert!((last.velocity_mps[0] - 0.8).abs() < 0.03 && (last.velocity_mps[1] - 0.5).abs() < 0.03);
    // a velocity before any position is reported, not applied
    let mut fresh = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut out = Output::default();
    let velocity = Record {
        time_s: 0.0,
        tag: "r2".into(),
        measurement: Measurement::Velocity {
            velocity_mps: vec![1.0, 0.0],
            covariance_m2ps2: Some(vec![0.01, 0.0, 0.0, 0.01]),
        },
    };
    fresh.push(velocity, &mut out).unwrap();
    fresh.finish(&mut out).unwrap();
    assert!(matches!(&out.events[..], [Event::Rejected { kind: "velocity", .. }]));
}

/// A walker heading east at 1 m/s along y = 10 from x = 2: reaches the pit (x = 30) at 28 s and
/// the dead-end (x = 40) at 38 s; crosses the office (x 8–12) at 6–10 s.
fn eastward(t: f64) -> [f64; 2] {
    [2.0 + t, 10.0]
}

#[test]
fn zone_events_and_predictive_alarms_with_lead_time() {
    let site = site("fix-then-filter", "kf", "");
    let mut tracker = Tracker::new(&site).unwrap();
    let mut out = Output::default();
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut office_count_inside = 0;
    for k in 0..450 {
        let t = k as f64 * 0.1;
        let p = eastward(t);
        let record = Record {
            time_s: t,
            tag: "m1".into(),
            measurement: Measurement::Fix {
                position_m: vec![p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)],
                covariance_m2: vec![0.0025, 0.0, 0.0, 0.0025],
            },
        };
        tracker.push(record, &mut out).unwrap();
        if (t - 8.0).abs() < 1e-9 {
            office_count_inside = tracker.head_count("office");
        }
    }
    tracker.finish(&mut out).unwrap();
    assert_eq!(office_count_inside, 1);
    assert_eq!(tracker.head_count("office"), 0);
    let time_of = |f: &dyn Fn(&Event) -> bool| out.events.iter().find(|e| f(e)).map(Event::time_s);
    let pit_alarm = out
        .events
        .iter()
        .find_map(|e| match e {
            Event::HazardPredicted {
                zone,
                time_s,
                time_to_entry_s,
                ..
            } if zone == "pit" => Some((*time_s, *time_to_entry_s)),
            _ => None,
        })
        .expect("an alarm for the pit");
    let pit_entry = time_of(&|e| matches!(e, Event::Zone(ZoneEvent::Enter { zone, .. }) if zone == "pit")).unwrap();
    // default horizon 10 s: raised about 10 s before the entry (earlier when the velocity
    // estimate, σ ≈ 0.25 m/s here, runs high), and the predicted entry time is close
    let lead_s = pit_entry - pit_alarm.0;
    assert!(lead_s > 9.0 && lead_s <= 14.0, "lead {lead_s}");
    assert!((pit_entry - 28.0).abs() < 0.3, "{pit_entry}");
    assert!((pit_alarm.0 + pit_alarm.1 - 28.0).abs() < 3.0, "{pit_alarm:?}");
    // the area with only a broken reader is alarmed in advance and its entry reported
    let dead_end_alarm = time_of(&|e| matches!(e, Event::HazardPredicted { zone, .. } if zone == "dead-end")).unwrap();
    let no_coverage = time_of(&|e| matches!(e, Event::NoCoverage { zone, .. } if zone == "dead-end")).unwrap();
    assert!(no_coverage - dead_end_alarm > 9.0, "{dead_end_alarm} {no_coverage}");
    assert!((no_coverage - 38.0).abs() < 0.3, "{no_coverage}");
    // office: enter and exit, no alarm (not a hazard)
    assert!(time_of(&|e| matches!(e, Event::Zone(ZoneEvent::Exit { zone, .. }) if zone == "office")).is_some());
    assert!(out
        .events
        .iter()
        .all(|e| !matches!(e, Event::HazardPredicted { zone, .. } if zone == "office")));
}

#[test]
fn a_tag_that_turns_away_clears_its_alarm() {
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut out = Output::default();
    // east at 1 m/s to x = 25 (alarm: pit ahead), then north
    let path = |t: f64| {
        if t < 23.0 {
            [2.0 + t, 10.0]
        } else {
            [25.0, 10.0 + (t - 23.0)]
        }
    };
    for k in 0..400 {
        let t = k as f64 * 0.1;
        let p = path(t);
        let record = Record {
            time_s: t,
            tag: "m2".into(),
            measurement: Measurement::Fix {
                position_m: p.to_vec(),
                covariance_m2: vec![0.0025, 0.0, 0.0, 0.0025],
            },
        };
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let raised = out
        .events
        .iter()
        .position(|e| matches!(e, Event::HazardPredicted { zone, .. } if zone == "pit"));
    let cleared = out
        .events
        .iter()
        .position(|e| matches!(e, Event::HazardCleared { zone, .. } if zone == "pit"));
    assert!(raised.is_some() && cleared.is_some() && raised < cleared);
    assert!(out
        .events
        .iter()
        .all(|e| !matches!(e, Event::Zone(ZoneEvent::Enter { zone, .. }) if zone == "pit")));
}

#[test]
fn three_dimensional_tracks_use_the_spatial_geometry() {
    let text = site_text("tightly-coupled", "ekf", "")
        .replace("tag_height_m = 1.0", "dimensions = 3")
        .replace("position_m = [20.0, 20.0, 2.5]", "position_m = [20.0, 20.0, 6.0]");
    let site = Site::from_toml_str(&text, "3d.toml").unwrap();
    let mut tracker = Tracker::new(&site).unwrap();
    let anchors = [[0.0, 0.0, 2.5], [20.0, 0.0, 2.5], [20.0, 20.0, 6.0], [0.0, 20.0, 2.5]];
    let truth = |t: f64| [2.0 + 0.8 * t, 3.0 + 0.5 * t, 1.0 + 0.05 * t];
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut records = Vec::new();
    for k in 0..400 {
        let t = k as f64 * 0.05;
        let (id, a) = (["A1", "A2", "A3", "A4"][k % 4], anchors[k % 4]);
        let p = truth(t);
        let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt();
        records.push(Record {
            time_s: t,
            tag: "d1".into(),
            measurement: Measurement::Range {
                anchor: id.into(),
                range_m: d + 0.2 + noise.sample(&mut rng),
                std_m: Some(0.05),
                anchor_position_m: None,
            },
        });
    }
    let out = run(&mut tracker, records);
    let last = out.updates.last().unwrap();
    assert_eq!(last.dimensions, 3);
    let p = truth(last.time_s);
    let error = ((last.position_m[0] - p[0]).powi(2)
        + (last.position_m[1] - p[1]).powi(2)
        + (last.position_m[2] - p[2]).powi(2))
    .sqrt();
    assert!(error < 0.3, "{error}");
    let line: serde_json::Value = serde_json::from_str(&last.to_json_line()).unwrap();
    assert_eq!(line["cov"].as_array().unwrap().len(), 9);
    assert!(line["z"].is_number() && line["vz"].is_number());
}

#[test]
fn unsupported_motion_models_are_refused_by_name() {
    let text = site_text("fix-then-filter", "kf", "").replace("motion_model = \"cv\"", "motion_model = \"ca\"");
    let site = Site::from_toml_str(&text, "ca.toml").unwrap();
    let error = Tracker::new(&site).unwrap_err().to_string();
    assert!(error.contains("tracker.motion_model"), "{error}");
}
