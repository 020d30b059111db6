//! The tracker's parts against independent computations: pair scores against the filters,
//! the gating sweep against the dense check, a JPDA scan against a hand-computed mixture, the
//! detection counts, and every error.

use nalgebra::{DVector, Matrix2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::gating::{clusters, gate, GatedPair};
use super::test_support::{brute_force_jpda, lifecycle, settings};
use super::*;
use crate::error::EngineError;
use crate::lifecycle::{LifecycleEvent, TrackStatus};

fn random_prior(rng: &mut ChaCha8Rng, wide: bool) -> Gaussian<4> {
    let scale: f64 = if wide { 50.0 } else { 0.2 };
    // P = A Aᵀ + εI: symmetric positive definite with correlations
    let a = Matrix::<4>::from_fn(|_, _| rng.gen_range(-1.0..1.0) * scale.sqrt());
    let mean = Vector::<4>::new(
        rng.gen_range(0.0..40.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(0.0..40.0),
        rng.gen_range(-1.0..1.0),
    );
    Gaussian::new(mean, a * a.transpose() + Matrix::<4>::identity() * 1e-3, 2.0).unwrap()
}

fn random_detection(rng: &mut ChaCha8Rng) -> Detection {
    if rng.gen_bool(0.5) {
        let (a, c, b) = (
            rng.gen_range(0.01..0.5),
            rng.gen_range(0.01..0.5),
            rng.gen_range(-0.005..0.005),
        );
        Detection::fix([rng.gen_range(0.0..40.0), rng.gen_range(0.0..40.0)], [[a, b], [b, c]]).unwrap()
    } else {
        Detection::range(
            [rng.gen_range(0.0..40.0), rng.gen_range(0.0..40.0)],
            rng.gen_range(0.0..30.0),
            rng.gen_range(1e-4..0.3),
        )
        .unwrap()
    }
}

#[test]
fn pair_scores_equal_the_filters_nis_and_log_det() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..200 {
        let wide = rng.gen_bool(0.2);
        let prior = random_prior(&mut rng, wide);
        let detection = random_detection(&mut rng);
        let score = detection.score(&prior).unwrap();
        let updated = detection.update(&prior).unwrap();
        assert!(
            (score.nis - updated.nis).abs() <= 1e-9 * updated.nis.max(1.0),
            "{detection:?}"
        );
        assert!((score.log_det_s - updated.log_det_innovation_covariance).abs() < 1e-9);
        assert!((score.log_likelihood(detection.dim()) - updated.log_likelihood()).abs() < 1e-9);
    }
    // a track sitting on the node of a range: no score (S undefined), the filter refuses too
    let prior = Gaussian::new(Vector::<4>::new(3.0, 0.0, 4.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
    let on_node = Detection::range([3.0, 4.0], 1.0, 0.01).unwrap();
    assert!(on_node.score(&prior).is_none());
    assert!(on_node.update(&prior).is_err());
}

#[test]
fn the_gating_sweep_equals_the_dense_check() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let gates = [6.634896601021214, 9.21034037197618]; // χ²₀.₉₉(1), χ²₀.₉₉(2)
    for _ in 0..20 {
        let priors: Vec<Gaussian<4>> = (0..60)
            .map(|_| {
                let wide = rng.gen_bool(0.05);
                random_prior(&mut rng, wide)
            })
            .collect();
        let detections: Vec<Detection> = (0..80).map(|_| random_detection(&mut rng)).collect();
        let swept = gate(&priors, &detections, gates, 0.0);
        let mut dense = Vec::new();
        for (d, detection) in detections.iter().enumerate() {
            for (t, prior) in priors.iter().enumerate() {
                if let Some(score) = detection.score(prior) {
                    if score.nis <= gates[detection.dim() - 1] {
                        dense.push((d, t));
                    }
                }
            }
        }
        let got: Vec<(usize, usize)> = swept.pairs.iter().map(|p| (p.detection, p.track)).collect();
        assert_eq!(got, dense);
        assert!(!dense.is_empty());
    }
}

#[test]
fn clusters_are_the_connected_components() {
    let pair = |detection, track| GatedPair {
        detection,
        track,
        score: super::detection::PairScore {
            nis: 0.0,
            log_det_s: 0.0,
        },
    };
    // d0–t2, d1–t0, d2–t0, d2–t3, d3–t1 (t4 and d4 alone): {d1, d2 | t0, t3}, {d0 | t2}, {d3 | t1}
    let pairs = [pair(0, 2), pair(1, 0), pair(2, 0), pair(2, 3), pair(3, 1)];
    let found = clusters(&pairs, 5, 5);
    assert_eq!(found.len(), 3);
    assert_eq!(
        (found[0].tracks.clone(), found[0].detections.clone()),
        (vec![2], vec![0])
    );
    assert_eq!(
        (found[1].tracks.clone(), found[1].detections.clone()),
        (vec![0, 3], vec![1, 2])
    );
    assert_eq!(found[1].pairs, vec![1, 2, 3]);
    assert_eq!(
        (found[2].tracks.clone(), found[2].detections.clone()),
        (vec![1], vec![3])
    );
}

/// A tracker with confirmed stationary tracks at `positions` (three exact fixes 0.5 s apart),
/// at t = 1 s.
fn tracker_with_tracks(settings: AnonymousTrackerSettings, positions: &[[f64; 2]], cov: f64) -> AnonymousTracker {
    let mut tracker = AnonymousTracker::new(settings).unwrap();
    for k in 0..3 {
        let fixes: Vec<Detection> = positions
            .iter()
            .map(|&p| Detection::fix(p, [[cov, 0.0], [0.0, cov]]).unwrap())
            .collect();
        tracker.process_scan(0.5 * k as f64, &fixes).unwrap();
    }
    tracker
}

#[test]
fn a_jpda_scan_is_the_mixture_of_the_brute_force_weights() {
    let s = settings(Association::Jpda, lifecycle(1, 1.0, 5.0, 10.0));
    let mut tracker = AnonymousTracker::new(s).unwrap();
    let r = 0.04;
    let start = [
        Detection::fix([0.0, 0.0], [[r, 0.0], [0.0, r]]).unwrap(),
        Detection::fix([0.6, 0.0], [[r, 0.0], [0.0, r]]).unwrap(),
    ];
    tracker.process_scan(0.0, &start).unwrap();
    let states: Vec<Gaussian<4>> = tracker.tracks().iter().map(|t| *t.state()).collect();
    let z = [[0.1, 0.05], [0.5, -0.1], [0.3, 0.4]];
    let detections: Vec<Detection> = z
        .iter()
        .map(|&p| Detection::fix(p, [[r, 0.0], [0.0, r]]).unwrap())
        .collect();
    let report = tracker.process_scan(0.5, &detections).unwrap();

    // Independently: predict, likelihoods with nalgebra's inverse and determinant, brute force.
    let motion = ConstantVelocity::new(ProcessNoise::discrete(0.25, NoiseGain::kinematic())).unwrap();
    let kf = KalmanFilter::default();
    let priors: Vec<Gaussian<4>> = states.iter().map(|s| kf.predict(s, &motion, 0.5).unwrap()).collect();
    let (p_d, p_g, lambda) = (0.9, 0.99, 1e-3);
    let mut table = vec![vec![None; 3]; 2];
    for (t, prior) in priors.iter().enumerate() {
        let p = prior.covariance();
        let s = Matrix2::new(p[(0, 0)] + r, p[(0, 2)], p[(2, 0)], p[(2, 2)] + r);
        for (d, z) in z.iter().enumerate() {
            let nu = Vector2::new(z[0] - prior.mean()[0], z[1] - prior.mean()[2]);
            let d2 = (nu.transpose() * s.try_inverse().unwrap() * nu)[0];
            assert!(d2 < 9.21, "every pair is gated in this geometry");
            let n = (-0.5 * d2).exp() / (std::f64::consts::TAU * s.determinant().sqrt());
            table[t][d] = Some(p_d * n / lambda);
        }
    }
    let (miss, beta, events) = brute_force_jpda(&table, 3, 1.0 - p_d * p_g);
    assert_eq!(events, 1 + 6 + 6); // none, one of 6 pairs, two detections to two tracks (3·2)
    let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, r).unwrap()).unwrap();
    for (t, prior) in priors.iter().enumerate() {
        let mut mean = prior.mean() * miss[t];
        for (d, z) in z.iter().enumerate() {
            let posterior = kf.update(prior, &fix, &DVector::from_column_slice(z)).unwrap().state;
            mean += posterior.mean() * beta[t][d];
        }
        let got = report.updates[t].state.mean();
        assert!((got - mean).amax() < 1e-9, "track {t}: {got} vs {mean}");
    }
    assert_eq!(report.clusters, 1);
    assert_eq!(report.counts.assigned, 3);
    let DetectionFate::Weighted { tracks } = &report.detections[2].fate else {
        panic!("{:?}", report.detections[2]);
    };
    assert_eq!(&*tracks[1].0, "anon-2");
    assert!((tracks[1].1 - beta[1][2]).abs() < 1e-12);
}

#[test]
fn counts_and_fates_of_a_scan() {
    let mut tracker = tracker_with_tracks(AnonymousTrackerSettings::default(), &[[0.0, 0.0]], 0.01);
    assert_eq!(tracker.tracks()[0].status(), TrackStatus::Confirmed);
    let scan = [
        Detection::fix([0.05, 0.0], [[0.01, 0.0], [0.0, 0.01]]).unwrap(), // the track's
        Detection::fix([10.0, 10.0], [[0.01, 0.0], [0.0, 0.01]]).unwrap(), // a new target
        Detection::range([3.0, 0.0], 3.0, 0.0004).unwrap(),               // fits, but the fix is likelier
        Detection::range([3.0, 0.0], 8.0, 0.0004).unwrap(),               // fits nothing
    ];
    let report = tracker.process_scan(1.5, &scan).unwrap();
    let gated: Vec<usize> = report.detections.iter().map(|d| d.gated_tracks).collect();
    assert_eq!(gated, vec![1, 0, 1, 0]);
    assert_eq!(
        report.detections[0].fate,
        DetectionFate::Assigned { track: "anon-1".into() }
    );
    assert_eq!(
        report.detections[1].fate,
        DetectionFate::StartedTrack { track: "anon-2".into() }
    );
    assert_eq!(report.detections[2].fate, DetectionFate::UnusedRange);
    assert_eq!(report.detections[3].fate, DetectionFate::UnusedRange);
    assert_eq!(
        report.counts,
        DetectionCounts {
            total: 4,
            assigned: 1,
            unassigned: 3,
            gated_out: 2,
            started_tracks: 1,
            unused_ranges: 2
        }
    );
    assert_eq!(
        report.events,
        vec![TrackEvent {
            track: "anon-2".into(),
            kind: TrackEventKind::Started
        }]
    );
    assert_eq!(report.updates.len(), 2);
    assert!(!report.updates[0].predicted && report.updates[1].status == TrackStatus::Tentative);
}

#[test]
fn ranges_alone_never_start_tracks() {
    let mut tracker = AnonymousTracker::new(AnonymousTrackerSettings::default()).unwrap();
    let ranges: Vec<Detection> = (0..3)
        .map(|k| Detection::range([k as f64, 0.0], 2.0, 0.01).unwrap())
        .collect();
    let report = tracker.process_scan(0.0, &ranges).unwrap();
    assert!(tracker.tracks().is_empty());
    assert_eq!(
        (
            report.counts.unused_ranges,
            report.counts.gated_out,
            report.counts.assigned
        ),
        (3, 3, 0)
    );
}

#[test]
fn jpda_falls_back_to_gnn_beyond_its_caps() {
    for (max_tracks, max_events) in [(1, 100_000), (8, 2)] {
        let s = AnonymousTrackerSettings {
            association: Association::Jpda,
            jpda_max_cluster_tracks: max_tracks,
            jpda_max_joint_events: max_events,
            ..AnonymousTrackerSettings::default()
        };
        let mut tracker = tracker_with_tracks(s, &[[0.0, 0.0], [0.3, 0.0]], 0.04);
        let cov = [[0.04, 0.0], [0.0, 0.04]];
        let scan = [
            Detection::fix([0.02, 0.0], cov).unwrap(),
            Detection::fix([0.28, 0.0], cov).unwrap(),
        ];
        let report = tracker.process_scan(1.5, &scan).unwrap();
        assert_eq!((report.clusters, report.gnn_fallback_clusters), (1, 1));
        assert_eq!(
            report.detections[0].fate,
            DetectionFate::Assigned { track: "anon-1".into() }
        );
        assert_eq!(
            report.detections[1].fate,
            DetectionFate::Assigned { track: "anon-2".into() }
        );
    }
}

#[test]
fn bad_settings_name_the_field() {
    let d = AnonymousTrackerSettings::default();
    let cases = [
        (
            AnonymousTrackerSettings {
                acceleration_noise_std_mps2: 0.0,
                ..d
            },
            "acceleration_noise_std_mps2",
        ),
        (
            AnonymousTrackerSettings {
                initial_velocity_std_mps: f64::NAN,
                ..d
            },
            "initial_velocity_std_mps",
        ),
        (
            AnonymousTrackerSettings {
                gate_probability: 1.0,
                ..d
            },
            "gate_probability",
        ),
        (
            AnonymousTrackerSettings {
                detection_probability: 1.5,
                ..d
            },
            "detection_probability",
        ),
        (
            AnonymousTrackerSettings {
                fix_clutter_density_per_m2: -1.0,
                ..d
            },
            "fix_clutter_density_per_m2",
        ),
        (
            AnonymousTrackerSettings {
                range_clutter_density_per_m: f64::INFINITY,
                ..d
            },
            "range_clutter_density_per_m",
        ),
        (
            AnonymousTrackerSettings {
                jpda_max_cluster_tracks: 0,
                ..d
            },
            "jpda_max_cluster_tracks",
        ),
        (
            AnonymousTrackerSettings {
                jpda_max_cluster_tracks: 65,
                ..d
            },
            "jpda_max_cluster_tracks",
        ),
        (
            AnonymousTrackerSettings {
                jpda_max_joint_events: 0,
                ..d
            },
            "jpda_max_joint_events",
        ),
        (
            AnonymousTrackerSettings {
                lifecycle: lifecycle(0, 1.0, 1.0, 1.0),
                ..d
            },
            "lifecycle.confirm_updates",
        ),
        (
            AnonymousTrackerSettings {
                lifecycle: lifecycle(2, 1.0, 5.0, 1.0),
                ..d
            },
            "lifecycle.delete_timeout_s",
        ),
    ];
    for (bad, field) in cases {
        let error = AnonymousTracker::new(bad).unwrap_err();
        assert!(
            matches!(error, EngineError::InvalidParameter { name, .. } if name == field),
            "{error}"
        );
        assert!(error.to_string().contains(field));
    }
    // the settings also read from TOML, unknown keys refused
    let text = r#"
        association = "jpda"
        acceleration_noise_std_mps2 = 0.5
        initial_velocity_std_mps = 1.0
        gate_probability = 0.99
        detection_probability = 0.9
        fix_clutter_density_per_m2 = 0.001
        range_clutter_density_per_m = 0.01
        lifecycle = { confirm_updates = 3, confirm_window_s = 3.0, coast_timeout_s = 5.0, delete_timeout_s = 30.0 }
        jpda_max_cluster_tracks = 8
        jpda_max_joint_events = 100000
    "#;
    let parsed: AnonymousTrackerSettings = toml::from_str(text).unwrap();
    assert_eq!(
        parsed,
        AnonymousTrackerSettings {
            association: Association::Jpda,
            ..d
        }
    );
    assert!(toml::from_str::<AnonymousTrackerSettings>(&format!("{text}\ncolour = 1")).is_err());
}

#[test]
fn bad_detections_name_the_field() {
    let name = |e: EngineError| match e {
        EngineError::InvalidParameter { name, .. } => name,
        other => panic!("{other}"),
    };
    let ok = [[0.01, 0.0], [0.0, 0.01]];
    assert_eq!(name(Detection::fix([f64::NAN, 0.0], ok).unwrap_err()), "position_m");
    assert_eq!(
        name(Detection::fix([0.0, 0.0], [[0.01, 0.002], [0.0, 0.01]]).unwrap_err()),
        "covariance_m2"
    );
    assert_eq!(
        name(Detection::fix([0.0, 0.0], [[0.01, 0.1], [0.1, 0.01]]).unwrap_err()),
        "covariance_m2"
    );
    assert_eq!(
        name(Detection::fix([0.0, 0.0], [[0.0, 0.0], [0.0, 0.01]]).unwrap_err()),
        "covariance_m2"
    );
    assert_eq!(
        name(Detection::range([0.0, f64::INFINITY], 1.0, 0.01).unwrap_err()),
        "node_m"
    );
    assert_eq!(
        name(Detection::range([0.0, 0.0], f64::NAN, 0.01).unwrap_err()),
        "range_m"
    );
    assert_eq!(name(Detection::range([0.0, 0.0], 1.0, 0.0).unwrap_err()), "variance_m2");
}

#[test]
fn a_scan_back_in_time_is_refused_and_changes_nothing() {
    let mut tracker = tracker_with_tracks(AnonymousTrackerSettings::default(), &[[0.0, 0.0], [5.0, 5.0]], 0.01);
    let before: Vec<AnonymousTrack> = tracker.tracks().to_vec();
    let fix = [Detection::fix([0.0, 0.0], [[0.01, 0.0], [0.0, 0.01]]).unwrap()];
    let error = tracker.process_scan(0.5, &fix).unwrap_err();
    assert!(
        error.to_string().contains("time_s") && error.to_string().contains("backwards"),
        "{error}"
    );
    assert!(tracker.process_scan(f64::NAN, &fix).is_err());
    assert_eq!(tracker.tracks(), &before[..]);
    // the same time as the last scan is fine (another sensor's scan)
    let report = tracker.process_scan(1.0, &fix).unwrap();
    assert_eq!(report.counts.assigned, 1);
    assert_eq!(
        report
            .events
            .iter()
            .filter(|e| e.kind == TrackEventKind::Lifecycle(LifecycleEvent::Deleted))
            .count(),
        0
    );
}
