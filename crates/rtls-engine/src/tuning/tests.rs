//! Tuning on simulated ranges with known errors: the truth-based calibration finds the biases
//! and noise, and the innovation likelihood orders the process noise sensibly.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::record::Measurement;

const SITE: &str = r#"
readers = [
  { id = "A", position_m = [0.0, 0.0, 2.0], technology = "uwb", radio = { range = { range_std_m = 0.02, bias_m = 0.0 } } },
  { id = "B", position_m = [20.0, 0.0, 2.0], technology = "uwb", radio = { range = { range_std_m = 0.02, bias_m = 0.0 } } },
  { id = "C", position_m = [0.0, 20.0, 2.0], technology = "uwb", radio = { range = { range_std_m = 0.02, bias_m = 0.0 } } },
  { id = "D", position_m = [20.0, 20.0, 2.0], technology = "uwb", radio = { range = { range_std_m = 0.02, bias_m = 0.0 } } },
]
[tracker]
pipeline = "tightly-coupled"
motion_model = "cv"
filter = "ekf"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
tag_height_m = 1.0
"#;

/// A walker circling at 1 m/s (radius 5 m around (10, 10)); ranges at 10 Hz round robin with
/// per-anchor biases and σ = 0.15 m (the site says 0.02 m and no bias); truth at 20 Hz.
fn recording(seconds: f64) -> (Site, Vec<Record>, Vec<TruthSample>) {
    correlated_recording(seconds, 0.0)
}

/// As [`recording`], each anchor's range error an AR(1) sequence with lag-one correlation
/// `rho` from one of its readings to the next (still σ = 0.15 m).
fn correlated_recording(seconds: f64, rho: f64) -> (Site, Vec<Record>, Vec<TruthSample>) {
    recording_with(seconds, rho, [1.0; 4])
}

/// As [`correlated_recording`], each anchor's ranges also scaled: `r = s d + b + e`.
fn recording_with(seconds: f64, rho: f64, scales: [f64; 4]) -> (Site, Vec<Record>, Vec<TruthSample>) {
    let site = Site::from_toml_str(SITE, "site.toml").unwrap();
    let biases = [0.30, -0.10, 0.05, 0.20];
    let noise = Normal::new(0.0, 0.15).unwrap();
    let mut errors = [0.0f64; 4];
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let position = |t: f64| [10.0 + 5.0 * (t / 5.0).cos(), 10.0 + 5.0 * (t / 5.0).sin(), 1.0];
    let mut records = Vec::new();
    let steps = (seconds * 10.0) as usize;
    for k in 0..steps {
        let t = k as f64 * 0.1;
        let index = k % 4;
        let anchor = ["A", "B", "C", "D"][index];
        let a = site.reader(anchor).unwrap().position_xyz_m();
        let p = position(t);
        let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt();
        records.push(Record {
            time_s: t,
            tag: "w".into(),
            measurement: Measurement::Range {
                anchor: anchor.into(),
                range_m: scales[index] * d + biases[index] + {
                    // eₖ = ρ eₖ₋₁ + √(1 − ρ²) wₖ
                    errors[index] = rho * errors[index] + (1.0 - rho * rho).sqrt() * noise.sample(&mut rng);
                    errors[index]
                },
                std_m: None,
                anchor_position_m: None,
            },
        });
    }
    let truth = (0..(steps * 2))
        .map(|k| {
            let t = k as f64 * 0.05;
            TruthSample {
                time_s: t,
                tag: "w".into(),
                position_m: position(t),
                has_z: true,
                line: 0,
            }
        })
        .collect();
    (site, records, truth)
}

#[test]
fn truth_calibrates_every_reader_and_picks_the_process_noise() {
    let (site, records, truth) = recording(120.0);
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.02, 0.2, 5.0],
        ..TuningSettings::default()
    };
    let tuned = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    assert_eq!(tuned.readers.len(), 4);
    for (fit, bias) in tuned.readers.iter().zip([0.30, -0.10, 0.05, 0.20]) {
        let range = fit.range.unwrap();
        assert!((range.bias_m - bias).abs() < 0.03, "{fit:?}");
        assert!((range.range_std_m - 0.15).abs() < 0.03, "{fit:?}");
    }
    // the walker's centripetal acceleration is 0.2 m/s²: the middle candidate tracks best
    let chosen = &tuned.candidates[tuned.chosen];
    assert_eq!(chosen.acceleration_noise_std_mps2, 0.2, "{:#?}", tuned.candidates);
    let factor = tuned.covariance.map_or(1.0, |c| c.std_factor);
    assert!((tuned.acceleration_noise_std_mps2 - 0.2 * factor).abs() < 1e-12);
    assert!(chosen.rmse_m.unwrap() < 0.15, "{chosen:?}");
    // with the calibrated readers the covariance holds the truth about as often as it claims
    let inside = chosen.inside_95.unwrap();
    assert!((0.85..=0.995).contains(&inside), "{chosen:?}");
    // no speeds: the correlation times and the innovation correlation are tried (3 × 2), and
    // the smallest RMSE kept, its ellipses holding the truth at least 90 % of the time
    assert_eq!(tuned.model.tried.len(), 6, "{:#?}", tuned.model);
    let runs: Vec<&Candidate> = tuned.model.tried.iter().map(|(_, c)| c).collect();
    let best_m = runs.iter().map(|c| c.rmse_m.unwrap()).fold(f64::INFINITY, f64::min);
    let chosen = runs[tuned.model.chosen];
    assert_eq!(chosen.rmse_m.unwrap(), best_m, "{:#?}", tuned.model);
    assert!(chosen.inside_95.unwrap() >= 0.9, "{chosen:?}");
}

#[test]
fn truth_fits_a_range_scale_where_the_distances_tell_it() {
    // A's ranges read 3 % long; the walker's distances to each anchor span ~6–15 m
    let (site, records, truth) = recording_with(120.0, 0.0, [1.03, 1.0, 1.0, 1.0]);
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.2],
        ..TuningSettings::default()
    };
    let tuned = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    let fits: Vec<RangeFit> = tuned.readers.iter().map(|r| r.range.unwrap()).collect();
    assert!((fits[0].scale - 1.03).abs() < 0.01, "{fits:?}");
    assert!((fits[0].bias_m - 0.30).abs() < 0.1, "{fits:?}");
    for fit in &fits[1..] {
        assert!((fit.scale - 1.0).abs() < 0.01, "{fits:?}");
    }
    // with the scale the track is as good as on unscaled ranges
    let (_, plain, _) = recording_with(120.0, 0.0, [1.0; 4]);
    let unscaled = tune(&site, None, &plain, Some(&truth), &settings).unwrap();
    let rmse = |t: &Tuning| t.candidates[t.chosen].rmse_m.unwrap();
    assert!(
        rmse(&tuned) < 1.2 * rmse(&unscaled),
        "{} vs {}",
        rmse(&tuned),
        rmse(&unscaled)
    );
}

#[test]
fn with_speeds_the_heading_error_correlation_is_tried_too() {
    let (site, mut records, truth) = recording(60.0);
    // wheel speed along the circle's tangent, heading exact to 0.02 rad
    for k in 0..600 {
        let t = k as f64 * 0.1 + 0.05;
        records.push(Record {
            time_s: t,
            tag: "w".into(),
            measurement: Measurement::Odometry {
                speed_mps: 1.0,
                heading_rad: Some(t / 5.0 + core::f64::consts::FRAC_PI_2),
                speed_std_mps: Some(0.05),
                heading_std_rad: Some(0.02),
            },
        });
    }
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.2],
        ..TuningSettings::default()
    };
    let tried_in = |tuned: &Tuning| -> Vec<(f64, bool, f64)> {
        tuned
            .model
            .tried
            .iter()
            .map(|(s, _)| {
                (
                    s.correlation_s,
                    s.correlation_from_innovations,
                    s.heading_error_correlation_s,
                )
            })
            .collect()
    };
    let [one, three] = CORRELATION_CANDIDATES_S;
    // with the heading's error considered (the default) the inflation has no effect: not tried
    let considered = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    assert_eq!(
        tried_in(&considered),
        [
            (0.25, false, 0.0),
            (0.25, true, 0.0),
            (one, false, 0.0),
            (one, true, 0.0),
            (three, false, 0.0),
            (three, true, 0.0)
        ]
    );
    let mut site = site;
    site.tracker.heading.consider_heading_error = false;
    let tuned = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    let h = HEADING_CORRELATION_CANDIDATE_S;
    let expected: Vec<(f64, bool, f64)> = [0.25, one, three]
        .into_iter()
        .flat_map(|c| [(c, false, 0.0), (c, true, 0.0), (c, false, h), (c, true, h)])
        .collect();
    assert_eq!(tried_in(&tuned), expected);
    // the least RMSE, or within a standard error of it when that run's ellipses were too small
    let runs = &tuned.model.tried;
    let best_m = runs
        .iter()
        .map(|(_, c)| c.rmse_m.unwrap())
        .fold(f64::INFINITY, f64::min);
    let best = runs.iter().find(|(_, c)| c.rmse_m.unwrap() == best_m).unwrap();
    let chosen = &runs[tuned.model.chosen].1;
    assert!(
        chosen.rmse_m.unwrap() == best_m
            || (best.1.inside_95.unwrap() < 0.9
                && chosen.rmse_m.unwrap() <= best_m + best.1.rmse_standard_error_m.unwrap()),
        "{runs:#?}"
    );
}

#[test]
fn cautious_ellipses_are_not_narrowed() {
    // range errors that persist over ~50 readings of an anchor (ρ = 0.98): the truth's robust
    // per-reader fit takes much of the slow error for bias, and the tracks come out too
    // cautious (≈ 99 % inside the 95 % ellipse); a calibration part of correlated errors is
    // too few independent looks to narrow them on
    let (site, records, truth) = correlated_recording(120.0, 0.98);
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.02, 0.2, 5.0],
        ..TuningSettings::default()
    };
    let tuned = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    let chosen = &tuned.candidates[tuned.chosen];
    assert!(chosen.inside_95.unwrap() > 0.97, "{chosen:?}");
    assert_eq!(tuned.covariance, None);
    assert_eq!(tuned.acceleration_noise_std_mps2, chosen.acceleration_noise_std_mps2);
}

#[test]
fn without_truth_the_innovations_choose_and_report_the_noise_excess() {
    let (site, records, _) = recording(120.0);
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.02, 0.2, 5.0],
        ..TuningSettings::default()
    };
    let tuned = tune(&site, None, &records, None, &settings).unwrap();
    assert!(tuned.candidates.iter().all(|c| c.rmse_m.is_none() && c.updates > 1000));
    assert_ne!(tuned.acceleration_noise_std_mps2, 5.0, "{:#?}", tuned.candidates);
    // the ranges are ~8× noisier than the stated 0.02 m (biases included): the adaptive
    // scale says so
    let (_, factor) = tuned
        .noise_std_factors
        .iter()
        .find(|(c, _)| *c == NoiseClass::Range)
        .unwrap();
    assert!(*factor > 3.0, "{:?}", tuned.noise_std_factors);
}

#[test]
fn an_empty_grid_or_no_usable_record_is_an_error() {
    let (site, records, _) = recording(5.0);
    let empty = TuningSettings {
        acceleration_grid_mps2: vec![],
        ..TuningSettings::default()
    };
    assert!(tune(&site, None, &records, None, &empty).is_err());
    assert!(tune(&site, None, &[], None, &TuningSettings::default()).is_err());
}

/// A walker on the test circle, fixes at 1 Hz whose errors persist (AR(1), 3 s correlation
/// time, σ = 0.5 m per axis, stated as such), and velocities at 2 Hz accurate to 0.05 m/s; truth
/// at 10 Hz. Fix-then-filter KF.
fn persistent_fix_errors(seconds: usize) -> (Site, Vec<Record>, Vec<TruthSample>) {
    let text = SITE
        .replace("pipeline = \"tightly-coupled\"", "pipeline = \"fix-then-filter\"")
        .replace("filter = \"ekf\"", "filter = \"kf\"");
    let site = Site::from_toml_str(&text, "site.toml").unwrap();
    let position = |t: f64| [10.0 + 5.0 * (t / 5.0).cos(), 10.0 + 5.0 * (t / 5.0).sin()];
    let velocity = |t: f64| [-(t / 5.0).sin(), (t / 5.0).cos()];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let white = Normal::new(0.0, 1.0).unwrap();
    let rho = (-1.0f64 / 3.0).exp();
    let mut error = [0.0f64; 2];
    let mut records = Vec::new();
    for k in 0..seconds {
        let t = k as f64;
        for e in &mut error {
            // eₖ = ρ eₖ₋₁ + √(1 − ρ²) σ wₖ
            *e = rho * *e + (1.0 - rho * rho).sqrt() * 0.5 * white.sample(&mut rng);
        }
        let p = position(t);
        records.push(Record {
            time_s: t,
            tag: "w".into(),
            measurement: Measurement::Fix {
                position_m: vec![p[0] + error[0], p[1] + error[1]],
                covariance_m2: vec![0.25, 0.0, 0.0, 0.25],
            },
        });
        for half in [0.25, 0.75] {
            let v = velocity(t + half);
            records.push(Record {
                time_s: t + half,
                tag: "w".into(),
                measurement: Measurement::Velocity {
                    velocity_mps: vec![v[0], v[1]],
                    covariance_m2ps2: Some(vec![0.0025, 0.0, 0.0, 0.0025]),
                },
            });
        }
    }
    let truth = (0..seconds * 10)
        .map(|k| {
            let t = k as f64 * 0.1;
            let p = position(t);
            TruthSample {
                time_s: t,
                tag: "w".into(),
                position_m: [p[0], p[1], 0.0],
                has_z: false,
                line: 0,
            }
        })
        .collect();
    (site, records, truth)
}

#[test]
fn persistent_errors_that_the_velocity_lets_a_track_average_are_not_left_overconfident() {
    let (site, records, truth) = persistent_fix_errors(240);
    let settings = TuningSettings {
        acceleration_grid_mps2: vec![0.3],
        ..TuningSettings::default()
    };
    let tuned = tune(&site, None, &records, Some(&truth), &settings).unwrap();
    let runs = &tuned.model.tried;
    // the site's 0.25 s counts every 1 Hz fix as independent: its ellipses are too small
    let own = &runs[0].1;
    assert!(own.inside_95.unwrap() < 0.8, "{runs:#?}");
    // settings that count the persistence are tried, and the one kept holds the truth
    assert!(runs.iter().any(|(s, _)| s.correlation_s > 0.25), "{runs:#?}");
    let chosen = &runs[tuned.model.chosen].1;
    assert!(chosen.inside_95.unwrap() >= 0.9, "{runs:#?}");
    assert!(
        chosen.rmse_m.unwrap() <= own.rmse_m.unwrap() + own.rmse_standard_error_m.unwrap(),
        "{runs:#?}"
    );
}

/// A run of the error-correlation choice with the given RMSE, its standard error and coverage.
fn scored(rmse_m: f64, standard_error_m: f64, inside_95: f64) -> Candidate {
    Candidate {
        acceleration_noise_std_mps2: 1.0,
        log_likelihood: 0.0,
        updates: 100,
        rmse_m: Some(rmse_m),
        rmse_standard_error_m: Some(standard_error_m),
        inside_95: Some(inside_95),
        covariance_scale_95: None,
        innovations: Innovations::default(),
    }
}

#[test]
fn an_overconfident_least_rmse_run_gives_way_to_the_wider_one_nearest_95_percent_within_its_standard_error() {
    // consistent enough: the least RMSE stays
    let runs = [scored(1.0, 0.1, 0.92), scored(1.05, 0.1, 0.95)];
    assert_eq!(choose_model_run(&runs), Some(0));
    // 70 %: the wider run nearest 95 % within 1.0 + 0.1 m, not the one outside it
    let runs = [
        scored(1.0, 0.1, 0.70),
        scored(1.08, 0.1, 0.99),
        scored(1.09, 0.1, 0.94),
        scored(1.2, 0.1, 0.95),
    ];
    assert_eq!(choose_model_run(&runs), Some(2));
    // never narrower than the least-RMSE run's
    let runs = [scored(1.0, 0.1, 0.80), scored(1.05, 0.1, 0.60)];
    assert_eq!(choose_model_run(&runs), Some(0));
    // wider, but only beyond one standard error of the least RMSE
    let runs = [scored(1.0, 0.1, 0.80), scored(1.11, 0.1, 0.95)];
    assert_eq!(choose_model_run(&runs), Some(0));
}
