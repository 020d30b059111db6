//! Seeded tracks, fields of view and the manoeuvre fallback: what seed 003's reproduction
//! needs, each against a hand-worked case (moved here with the logic from
//! `rtls-papers`' seed 003 trackers).

use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::*;
use crate::error::EngineError;
use crate::lifecycle::{LifecycleSettings, TrackStatus};

/// SRF08's range variance (σ = 3 cm), m².
const SONAR_VARIANCE_M2: f64 = 0.03 * 0.03;

/// Seed 003's tracker settings: continuous white acceleration `q = 0.05` m²/s³, `P_G` = 0.99,
/// tracks never lost within a test, and the fallback when asked for.
fn settings(fallback: bool) -> AnonymousTrackerSettings {
    AnonymousTrackerSettings {
        acceleration_psd_m2ps3: Some(0.05),
        lifecycle: LifecycleSettings {
            confirm_updates: 3,
            confirm_window_s: 3.0,
            coast_timeout_s: 100.0,
            delete_timeout_s: 100.0,
        },
        manoeuvre: fallback.then_some(ManoeuvreFallback {
            margin_m: 0.5,
            velocity_std_mps: 0.5,
            speed_change_mps: 1.0,
        }),
        ..AnonymousTrackerSettings::default()
    }
}

fn state(x: f64, y: f64, variance: f64, time_s: f64) -> Gaussian<4> {
    let p = Matrix::<4>::from_diagonal(&Vector::<4>::new(variance, variance, variance, variance));
    Gaussian::new(Vector::<4>::new(x, 0.0, y, 0.0), p, time_s).unwrap()
}

fn seeded(settings: AnonymousTrackerSettings, states: &[Gaussian<4>]) -> AnonymousTracker {
    let mut tracker = AnonymousTracker::new(settings).unwrap();
    for (i, s) in states.iter().enumerate() {
        tracker.seed_track(format!("robot-{i}"), *s).unwrap();
    }
    tracker
}

/// Sonar sector 0 of an SRF08 ring (0°–60°) from a node, widened by 10° on each side, 3 m.
fn sector_0() -> FieldOfView {
    FieldOfView::new(30f64.to_radians(), 40f64.to_radians(), 3.0).unwrap()
}

fn echo(node: [f64; 2], range_m: f64) -> Detection {
    Detection::range(node, range_m, SONAR_VARIANCE_M2)
        .unwrap()
        .within(sector_0())
        .unwrap()
}

fn assigned(id: &str) -> DetectionFate {
    DetectionFate::Assigned { track: id.into() }
}

#[test]
fn seeded_tracks_are_confirmed_and_keep_their_ids() {
    let mut tracker = seeded(settings(false), &[state(1.0, 1.0, 0.01, 0.0)]);
    assert_eq!(tracker.tracks()[0].id(), "robot-0");
    assert_eq!(tracker.tracks()[0].status(), TrackStatus::Confirmed);
    assert_eq!(tracker.last_scan_s(), Some(0.0));
    for bad in ["robot-0", "anon-1", ""] {
        assert!(matches!(
            tracker.seed_track(bad, state(2.0, 2.0, 0.01, 0.0)),
            Err(EngineError::InvalidParameter { name: "id", .. })
        ));
    }
    tracker.process_scan(1.0, &[]).unwrap();
    assert!(matches!(
        tracker.seed_track("late", state(2.0, 2.0, 0.01, 0.5)),
        Err(EngineError::InvalidParameter { name: "time_s", .. })
    ));
    // a seeded track coasts like any confirmed one, and a fix elsewhere still starts anon-1
    assert_eq!(tracker.tracks()[0].status(), TrackStatus::Coasting);
    let fix = Detection::fix([5.0, 5.0], [[0.01, 0.0], [0.0, 0.01]]).unwrap();
    let report = tracker.process_scan(1.5, &[fix]).unwrap();
    assert_eq!(
        report.detections[0].fate,
        DetectionFate::StartedTrack { track: "anon-1".into() }
    );
    assert_eq!(tracker.tracks().len(), 2);
}

#[test]
fn predict_tracks_looks_ahead_without_changing_the_tracks() {
    let tracker = seeded(settings(false), &[state(1.0, 1.0, 0.01, 0.0)]);
    let ahead = tracker.predict_tracks(0.7).unwrap();
    // the continuous CV model of rtls-estimation, in one step
    let motion = ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap();
    let direct = KalmanFilter::default()
        .predict(&state(1.0, 1.0, 0.01, 0.0), &motion, 0.7)
        .unwrap();
    assert!((ahead[0].covariance() - direct.covariance()).abs().max() < 1e-15);
    assert_eq!(tracker.tracks()[0].state().time_s(), 0.0);
    assert!(tracker.predict_tracks(-1.0).is_err());
    // continuous noise: predicting scan by scan equals one jump
    let mut stepped = seeded(settings(false), &[state(1.0, 1.0, 0.01, 0.0)]);
    for k in 1..=7 {
        stepped.process_scan(0.1 * f64::from(k), &[]).unwrap();
    }
    let p = stepped.tracks()[0].state().covariance();
    assert!(
        (p - direct.covariance()).abs().max() < 1e-12,
        "{p} vs {}",
        direct.covariance()
    );
}

#[test]
fn the_field_of_view_decides_who_can_have_made_an_echo() {
    // node at the origin aiming sector 0 (0°–60°): robot 0 at (1.5, 0.5) is in it, robot 1 at
    // (−0.5, 1.5) is not, though both are √2.5 m away
    let tracks = [state(1.5, 0.5, 0.0025, 0.0), state(-0.5, 1.5, 0.0025, 0.0)];
    let range = 1.5f64.hypot(0.5);
    let mut tracker = seeded(settings(false), &tracks);
    let report = tracker.process_scan(0.1, &[echo([0.0, 0.0], range)]).unwrap();
    assert_eq!(report.detections[0].gated_tracks, 1);
    assert_eq!(report.detections[0].fate, assigned("robot-0"));
    // without the view both gate it
    let mut all_round = seeded(settings(false), &tracks);
    let plain = Detection::range([0.0, 0.0], range, SONAR_VARIANCE_M2).unwrap();
    let report = all_round.process_scan(0.1, &[plain]).unwrap();
    assert_eq!(report.detections[0].gated_tracks, 2);
    // a track surely beyond the maximum range is no candidate: d̂ − 3 √S > r_max
    let short = FieldOfView::new(30f64.to_radians(), 40f64.to_radians(), 1.2).unwrap();
    let mut far = seeded(settings(false), &tracks);
    let beyond = Detection::range([0.0, 0.0], range, SONAR_VARIANCE_M2)
        .unwrap()
        .within(short)
        .unwrap();
    let report = far.process_scan(0.1, &[beyond]).unwrap();
    assert_eq!(
        (report.detections[0].gated_tracks, &report.detections[0].fate),
        (0, &DetectionFate::UnusedRange)
    );
}

#[test]
fn the_bearing_test_wraps_around() {
    let east = FieldOfView::new(-0.1, 0.3, 2.0).unwrap();
    assert!(east.contains_bearing([1.0, 1.0], [2.0, 0.9]));
    assert!(east.contains_bearing([1.0, 1.0], [2.0, 1.1]));
    assert!(!east.contains_bearing([1.0, 1.0], [1.0, 2.0]));
    let west = FieldOfView::new(std::f64::consts::PI, 0.2, 2.0).unwrap();
    assert!(west.contains_bearing([0.0, 0.0], [-1.0, 0.1]));
    assert!(west.contains_bearing([0.0, 0.0], [-1.0, -0.1]));
    assert!(!west.contains_bearing([0.0, 0.0], [1.0, 0.0]));
    assert!(east.within_range(2.05, 0.0009) && !east.within_range(2.1, 0.0009));
    for (aim, half, max, name) in [
        (f64::NAN, 0.3, 2.0, "aim_rad"),
        (0.0, 0.0, 2.0, "half_width_rad"),
        (0.0, 4.0, 2.0, "half_width_rad"),
        (0.0, 0.3, 0.0, "max_range_m"),
        (0.0, 0.3, f64::NAN, "max_range_m"),
    ] {
        assert!(matches!(
            FieldOfView::new(aim, half, max),
            Err(EngineError::InvalidParameter { name: n, .. }) if n == name
        ));
    }
    assert!(FieldOfView::new(0.0, 0.3, f64::INFINITY).is_ok());
}

#[test]
fn a_foreign_echo_goes_to_the_robot_that_made_it_and_a_stray_one_to_nobody() {
    // robot 0 at (1.5, 0.5), robot 1 at (0.6, 0.3): both in sector 0 of node 0, robot 1 nearer,
    // so the sonar aimed at robot 0 hears robot 1
    let mut tracker = seeded(
        settings(true),
        &[state(1.5, 0.5, 0.01, 0.0), state(0.6, 0.3, 0.01, 0.0)],
    );
    let report = tracker
        .process_scan(0.1, &[echo([0.0, 0.0], 0.6f64.hypot(0.3))])
        .unwrap();
    assert_eq!(report.detections[0].fate, assigned("robot-1"));
    let robot_0 = report.updates[0].state.mean();
    assert!(
        (robot_0[0] - 1.5).abs() < 1e-12 && report.updates[0].predicted,
        "robot 0 untouched"
    );
    // an echo no track explains, not even after a manoeuvre, is unused
    let report = tracker.process_scan(0.2, &[echo([0.0, 0.0], 2.9)]).unwrap();
    assert_eq!(report.detections[0].fate, DetectionFate::UnusedRange);
    assert_eq!((report.counts.gated_out, report.manoeuvre_ambiguous), (1, 0));
}

#[test]
fn simultaneous_echoes_are_assigned_jointly() {
    // two echoes of one instant from nodes 0 and 3, each within the gates of both tracks:
    // each track takes one
    let nodes = [[0.0, 0.0], [2.0, 2.0]];
    let mut tracker = seeded(
        settings(true),
        &[state(1.0, 1.0, 0.01, 0.0), state(1.0, 1.04, 0.01, 0.0)],
    );
    let view = |aim_deg: f64| FieldOfView::new(aim_deg.to_radians(), 40f64.to_radians(), 3.0).unwrap();
    let echoes = [
        Detection::range(nodes[0], 1.0f64.hypot(1.02), SONAR_VARIANCE_M2)
            .unwrap()
            .within(view(30.0))
            .unwrap(),
        Detection::range(nodes[1], 1.0f64.hypot(1.0), SONAR_VARIANCE_M2)
            .unwrap()
            .within(view(210.0))
            .unwrap(),
    ];
    let report = tracker.process_scan(0.1, &echoes).unwrap();
    assert_eq!(report.counts.assigned, 2);
    assert_ne!(report.detections[0].fate, report.detections[1].fate);
}

/// Two tracks 1.044 m from node 0, one updated at `recent_s`, the other at 0; an echo 0.45 m
/// longer: outside both gates, within the 0.5 m margin of both.
fn drifted(recent_s: f64, fallback: bool) -> (AnonymousTracker, Detection) {
    let r = 1.0f64.hypot(0.3);
    let y1 = 0.53;
    let x1 = (r * r - y1 * y1).sqrt();
    // seeded in time order: the older state first
    let p = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.0025, 1e-4, 0.0025, 1e-4));
    let at = |x: f64, y: f64, t: f64| Gaussian::new(Vector::<4>::new(x, 0.0, y, 0.0), p, t).unwrap();
    let tracker = seeded(settings(fallback), &[at(x1, y1, 0.0), at(1.0, 0.3, recent_s)]);
    (tracker, echo([0.0, 0.0], r + 0.45))
}

#[test]
fn an_echo_two_tracks_could_explain_goes_to_the_one_that_can_have_drifted_that_far() {
    // robot-1 was updated 0.05 s before the echo (√S ≈ 6 cm: it can be 3 √S + 1 m/s × 0.05 s
    // ≈ 0.22 m off), robot-0 a second before (√S ≈ 14 cm, 1.43 m): robot-0 takes it
    let (mut tracker, echo) = drifted(0.95, true);
    let report = tracker.process_scan(1.0, &[echo]).unwrap();
    assert_eq!(
        report.detections[0].fate,
        DetectionFate::Manoeuvre {
            track: "robot-0".into()
        }
    );
    assert_eq!((report.manoeuvre_assigned, report.manoeuvre_ambiguous), (1, 0));
    assert_eq!((report.counts.assigned, report.counts.gated_out), (1, 1));
    // both updated long ago: either may have manoeuvred, the echo is unused and ambiguous
    let (mut tracker, echo) = drifted(0.0, true);
    let report = tracker.process_scan(1.0, &[echo]).unwrap();
    assert_eq!(report.detections[0].fate, DetectionFate::UnusedRange);
    assert_eq!((report.manoeuvre_assigned, report.manoeuvre_ambiguous), (0, 1));
    // without the fallback the echo is simply unused
    let (mut plain, echo) = drifted(0.95, false);
    let report = plain.process_scan(1.0, &[echo]).unwrap();
    assert_eq!(
        (&report.detections[0].fate, report.manoeuvre_ambiguous),
        (&DetectionFate::UnusedRange, 0)
    );
}

#[test]
fn a_manoeuvring_track_has_its_velocity_reopened_before_the_update() {
    // the only track in view, 0.3 m short of the echo: outside the gate, inside the margin
    let prior = state(1.0, 0.3, 0.0025, 0.0);
    let mut tracker = seeded(settings(true), &[prior]);
    let echo = echo([0.0, 0.0], 1.0f64.hypot(0.3) + 0.3);
    let report = tracker.process_scan(0.1, &[echo]).unwrap();
    assert_eq!(
        report.detections[0].fate,
        DetectionFate::Manoeuvre {
            track: "robot-0".into()
        }
    );
    // the same update by hand: predict, P⁻ += diag(0, σ_m², 0, σ_m²), EKF range update
    let motion = ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap();
    let predicted = KalmanFilter::default().predict(&prior, &motion, 0.1).unwrap();
    let mut p = *predicted.covariance();
    p[(1, 1)] += 0.25;
    p[(3, 3)] += 0.25;
    let opened = Gaussian::new(*predicted.mean(), p, 0.1).unwrap();
    let expected = echo.update(&opened).unwrap().state;
    let got = tracker.tracks()[0].state();
    assert!((got.mean() - expected.mean()).abs().max() < 1e-12);
    assert!((got.covariance() - expected.covariance()).abs().max() < 1e-12);
    // the velocity stays open (σ_v² ≥ 0.25 m²/s² before the update), so the next ranges can
    // correct the velocity the CV model held from before the manoeuvre
    assert!(got.covariance()[(1, 1)] > 0.2, "{}", got.covariance());
}

#[test]
fn a_track_a_gated_echo_updated_takes_no_ungated_one() {
    // robot-0 gates echo 0 (node 0); echo 1 (node 1, 0.3 m long) gates nobody and robot-0 is
    // its only plausible track, but robot-0 is taken: echo 1 is unused
    let mut tracker = seeded(settings(true), &[state(1.0, 0.3, 0.0025, 0.0)]);
    let r0 = 1.0f64.hypot(0.3);
    let view_1 = FieldOfView::new(150f64.to_radians(), 40f64.to_radians(), 3.0).unwrap();
    let r1 = 1.0f64.hypot(0.3) + 0.3;
    let echoes = [
        echo([0.0, 0.0], r0),
        Detection::range([2.0, 0.0], r1, SONAR_VARIANCE_M2)
            .unwrap()
            .within(view_1)
            .unwrap(),
    ];
    let report = tracker.process_scan(0.1, &echoes).unwrap();
    assert_eq!(report.detections[0].fate, assigned("robot-0"));
    assert_eq!(report.detections[1].fate, DetectionFate::UnusedRange);
    assert_eq!(report.manoeuvre_assigned, 0);
    // two ungated echoes whose only plausible track is robot-0: it takes the closer one
    let mut tracker = seeded(settings(true), &[state(1.0, 0.3, 0.0025, 0.0)]);
    let echoes = [echo([0.0, 0.0], r0 + 0.4), echo([0.0, 0.0], r0 + 0.3)];
    let report = tracker.process_scan(0.1, &echoes).unwrap();
    assert_eq!(report.detections[0].fate, DetectionFate::UnusedRange);
    assert_eq!(
        report.detections[1].fate,
        DetectionFate::Manoeuvre {
            track: "robot-0".into()
        }
    );
}

#[test]
fn bad_fallback_settings_and_views_name_the_field() {
    for (fallback, name) in [
        (
            ManoeuvreFallback {
                margin_m: -1.0,
                velocity_std_mps: 0.5,
                speed_change_mps: 1.0,
            },
            "manoeuvre.margin_m",
        ),
        (
            ManoeuvreFallback {
                margin_m: 0.5,
                velocity_std_mps: f64::NAN,
                speed_change_mps: 1.0,
            },
            "manoeuvre.velocity_std_mps",
        ),
        (
            ManoeuvreFallback {
                margin_m: 0.5,
                velocity_std_mps: 0.5,
                speed_change_mps: f64::INFINITY,
            },
            "manoeuvre.speed_change_mps",
        ),
    ] {
        let s = AnonymousTrackerSettings {
            manoeuvre: Some(fallback),
            ..AnonymousTrackerSettings::default()
        };
        assert!(matches!(
            AnonymousTracker::new(s),
            Err(EngineError::InvalidParameter { name: n, .. }) if n == name
        ));
    }
    let s = AnonymousTrackerSettings {
        acceleration_psd_m2ps3: Some(0.0),
        ..AnonymousTrackerSettings::default()
    };
    assert!(matches!(
        s.validate(),
        Err(EngineError::InvalidParameter {
            name: "acceleration_psd_m2ps3",
            ..
        })
    ));
    let fix = Detection::fix([0.0, 0.0], [[0.01, 0.0], [0.0, 0.01]]).unwrap();
    assert!(matches!(
        fix.within(sector_0()),
        Err(EngineError::InvalidParameter { name: "view", .. })
    ));
}
