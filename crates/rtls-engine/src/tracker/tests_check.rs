//! A tightly coupled track checked against fixes of its own readings ([`super::check`]): a
//! track started far outside the anchors, where RSSI readings hardly move it, jumps back to
//! where its readings' fixes agree; a track that follows its readings never jumps; and a track
//! does not start from a fix that says no more than "among the anchors".

use super::tests::{jump_times, run, site, standing_rssi_records};
use super::*;
use crate::record::Measurement;

/// The tag stands at (8, 6); a first `fix` record (σ 0.5 m) puts it at `start`, then RSSI
/// readings round robin over the four anchors every 50 ms (the site's law, 2 dB shadowing)
/// for 20 s.
fn records(start: [f64; 2]) -> Vec<Record> {
    let mut records = vec![Record {
        time_s: 0.0,
        tag: "w1".into(),
        measurement: Measurement::Fix {
            position_m: start.to_vec(),
            covariance_m2: vec![0.25, 0.0, 0.0, 0.25],
        },
    }];
    records.extend(standing_rssi_records(9, 2.0, 1..401));
    records
}

/// The `jumped` events' times, and the last measured position.
fn tracked(start: [f64; 2]) -> (Vec<f64>, [f64; 3]) {
    let site = site("tightly-coupled", "ekf", "");
    let out = run(&mut Tracker::new(&site).unwrap(), records(start));
    let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap().position_m;
    (jump_times(&out), last)
}

#[test]
fn a_track_stuck_outside_the_anchors_jumps_to_its_readings_fixes() {
    let (jumps, last) = tracked([60.0, 60.0]);
    let error_m = (last[0] - 8.0).hypot(last[1] - 6.0);
    assert!(!jumps.is_empty(), "never jumped; last position {last:?}");
    // (the track swings through the anchors with a covariance its consistency test widened
    // until it explains the check fixes, then settles 10–20 m off, and three agreeing check
    // fixes, one a second, make the evidence a jump needs)
    assert!(jumps[0] <= 15.0, "{jumps:?}");
    assert!(error_m < 1.5, "{last:?}");
}

#[test]
fn a_track_that_follows_its_readings_never_jumps() {
    let (jumps, last) = tracked([8.5, 6.5]);
    assert!(jumps.is_empty(), "{jumps:?}");
    assert!((last[0] - 8.0).hypot(last[1] - 6.0) < 1.5, "{last:?}");
}

#[test]
fn a_track_does_not_start_from_a_fix_that_says_only_among_the_anchors() {
    // 10 dB shadowing: a fix of the first three or four readings is tens of metres uncertain;
    // the track waits (up to 1 s) for readings whose fix is surer than the anchors' spread
    // (10 m along each axis of the 20 m square)
    let site = site("tightly-coupled", "ekf", "");
    for seed in 0..10 {
        let records = standing_rssi_records(seed, 10.0, 0..100);
        let out = run(&mut Tracker::new(&site).unwrap(), records);
        let first = out.fixes.first().expect("a start fix");
        // √(σₓ² + σ_y²) of the 2 × 2 covariance
        let sigma_m = (first.covariance_m2[0] + first.covariance_m2[3]).sqrt();
        assert!(
            sigma_m <= 10.0 || first.time_s >= super::epoch::SPANNING_WAIT_S,
            "seed {seed}: started at {} s from a fix of σ {sigma_m:.1} m",
            first.time_s
        );
    }
}

#[test]
fn a_run_of_check_fixes_each_inside_the_gate_can_say_the_track_is_off() {
    use super::check::{run_disagrees, CHECK_RUN};
    // the tracker's own thresholds at the test site's gate probability, 0.999
    let tracker = Tracker::new(&site("tightly-coupled", "ekf", "")).unwrap();
    let [_, gate_2, _] = tracker.shared().gates;
    let [_, run_2, run_3] = tracker.shared().check_run_gates;
    assert!(
        (run_2 - 29.588).abs() < 1e-3 && (run_3 - 37.697).abs() < 1e-3,
        "{run_2} {run_3}"
    );
    // five fixes at d² = 6.5, each well inside the single fix's gate (13.8), together
    // T = 32.5 > χ²₁₀(0.999) = 29.6
    assert!(6.5 < gate_2);
    assert!(run_disagrees(&[6.5; CHECK_RUN], run_2));
    // what a consistent track's fixes give (E d² = 2), and a run not yet complete
    assert!(!run_disagrees(&[2.0; CHECK_RUN], run_2));
    assert!(!run_disagrees(&[13.0; CHECK_RUN - 1], run_2));
    // in 3-D the same distances are fewer standard deviations: T ~ χ²₁₅, quantile 37.7
    assert!(!run_disagrees(&[6.5; CHECK_RUN], run_3));
}

#[test]
fn honest_readings_never_make_a_standing_track_jump() {
    // the run test on a track that explains its readings: a false jump per run has the
    // probability 1 − 0.999; 20 s of 20 readings a second, ten seeds
    let site = site("tightly-coupled", "ekf", "");
    for seed in 0..10 {
        let out = run(
            &mut Tracker::new(&site).unwrap(),
            standing_rssi_records(seed, 2.0, 0..400),
        );
        assert!(jump_times(&out).is_empty(), "seed {seed}: {:?}", jump_times(&out));
    }
}
