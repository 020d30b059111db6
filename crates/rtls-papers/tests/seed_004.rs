//! Seed 004 end to end: TDOA fixes (Chan + Taylor, cyclic master), odometry, KF on fixes, the
//! VD-KF fused with odometry, and ours — the engine's tracker (CV/CA/CT IMM) on the run's
//! recording — over seeded runs of the paper's scenario.

use rtls_estimation::manoeuvre::VdMode;
use rtls_papers::reproduction::{run_seed_004, seed_004_recording, Seed004Config, Seed004Run, SEED_004_TAG};
use rtls_sim::ErrorSummary;

const RUNS: u64 = 10;

fn runs() -> Vec<Seed004Run> {
    let config = Seed004Config::default();
    (0..RUNS).map(|seed| run_seed_004(&config, seed).unwrap()).collect()
}

fn rmse(run: &Seed004Run, estimates: &[[f64; 2]]) -> f64 {
    ErrorSummary::from_positions(&run.truth_positions(), estimates)
        .unwrap()
        .rmse_m
}

fn first_switch_to_ca_after(run: &Seed004Run, start_s: f64) -> Option<f64> {
    run.vd_events
        .iter()
        .find(|e| e.to == VdMode::ConstantAcceleration && e.time_s >= start_s)
        .map(|e| e.time_s)
}

/// Fraction of epochs in `(from_s, to_s]` the VD-KF spent in `mode`.
fn fraction_in(run: &Seed004Run, mode: VdMode, from_s: f64, to_s: f64) -> f64 {
    let picked: Vec<_> = run
        .truth
        .iter()
        .zip(&run.vd_modes)
        .filter(|(s, _)| s.time_s > from_s && s.time_s <= to_s)
        .collect();
    picked.iter().filter(|(_, m)| **m == mode).count() as f64 / picked.len() as f64
}

/// Fraction of epochs in `(from_s, to_s]` whose most probable engine IMM mode is `mode`.
fn engine_fraction_in(run: &Seed004Run, mode: &str, from_s: f64, to_s: f64) -> f64 {
    let picked: Vec<_> = run
        .truth
        .iter()
        .zip(&run.engine)
        .filter(|(s, _)| s.time_s > from_s && s.time_s <= to_s)
        .collect();
    picked
        .iter()
        .filter(|(_, e)| e.as_ref().and_then(|e| e.mode) == Some(mode))
        .count() as f64
        / picked.len() as f64
}

#[test]
fn vd_kf_detects_manoeuvres_returns_to_cv_and_beats_the_kf_and_the_engine_beats_the_vd_kf() {
    let runs = runs();
    let (mut raw, mut kf, mut vd, mut imm) = (0.0, 0.0, 0.0, 0.0);
    let (mut stop_found, mut start_found, mut turn_found) = (0, 0, 0);
    for run in &runs {
        let (fix_truth, fixes) = run.available_fixes();
        raw += ErrorSummary::from_positions(&fix_truth, &fixes).unwrap().rmse_m;
        kf += rmse(run, &run.kf);
        vd += rmse(run, &run.vd);
        imm += rmse(run, &run.engine_positions().unwrap());

        // Onsets: the stop at 400 s and the start at 450 s are velocity steps of 10 m/s; the
        // turn at 900 s is a 0.16 m/s² centripetal acceleration.
        stop_found += usize::from(first_switch_to_ca_after(run, 400.0).is_some_and(|t| t <= 403.0));
        start_found += usize::from(first_switch_to_ca_after(run, 450.0).is_some_and(|t| t <= 453.0));
        turn_found += usize::from(first_switch_to_ca_after(run, 895.0).is_some_and(|t| t <= 920.0));
        // Back to CV after each manoeuvre: mostly CV on the straight legs that follow.
        assert!(
            fraction_in(run, VdMode::ConstantVelocity, 500.0, 890.0) > 0.9,
            "seed {}: VD-KF not back in CV on the 450–900 s leg",
            run.seed
        );
        assert!(
            fraction_in(run, VdMode::ConstantVelocity, 1030.0, 1500.0) > 0.9,
            "seed {}: VD-KF not back in CV after the turn",
            run.seed
        );
        assert!(
            fraction_in(run, VdMode::ConstantVelocity, 20.0, 395.0) > 0.9,
            "seed {}: VD-KF false alarms on the first straight leg",
            run.seed
        );
        // The engine runs its IMM (a mode at every epoch). With the vehicle platform's
        // defaults its CV mode (σ_a 2 m/s²) is noisier than its CA mode (jerk 1 m/s³) at 1 Hz
        // with an odometer, so CA is the most probable mode throughout, also on the straight
        // legs; the IMM does not follow the phases as the hand-written one with a quiet CV did.
        let modes = ["CV", "CA", "CT"];
        let all = modes
            .iter()
            .map(|m| engine_fraction_in(run, m, 0.0, 1500.0))
            .sum::<f64>();
        assert!(
            (all - 1.0).abs() < 1e-9,
            "seed {}: epochs without an IMM mode",
            run.seed
        );
        let straight_ca = engine_fraction_in(run, "CA", 20.0, 395.0);
        eprintln!(
            "seed {}: engine in CA on the first straight leg {straight_ca:.2}",
            run.seed
        );
    }
    let n = RUNS as f64;
    let (raw, kf, vd, imm) = (raw / n, kf / n, vd / n, imm / n);
    eprintln!("seed 004, {RUNS} runs, mean RMSE: fixes {raw:.1} m, KF {kf:.1} m, VD-KF {vd:.1} m, IMM {imm:.1} m");
    eprintln!("onsets detected: stop {stop_found}/{RUNS} (≤ 3 s), start {start_found}/{RUNS} (≤ 3 s), turn {turn_found}/{RUNS} (≤ 20 s)");
    assert_eq!(
        stop_found as u64, RUNS,
        "the stop must be detected within 3 s in every run"
    );
    assert_eq!(
        start_found as u64, RUNS,
        "the start must be detected within 3 s in every run"
    );
    assert!(
        turn_found as u64 >= RUNS * 7 / 10,
        "turn detected in {turn_found}/{RUNS} runs"
    );
    // The paper's ranking: fusing odometry in the VD-KF beats the KF on fixes, which beats the
    // raw fixes; ours (the engine on the raw range differences) beats the VD-KF.
    assert!(kf < raw, "KF {kf} vs fixes {raw}");
    assert!(vd < 0.8 * kf, "VD-KF {vd} vs KF {kf}");
    assert!(imm < 0.9 * vd, "engine IMM {imm} vs VD-KF {vd}");
}

#[test]
fn without_drift_estimation_the_heading_drift_costs_accuracy() {
    // Seed 004 notes the fused track degrades as the heading drifts; the drift estimator removes
    // most of that loss. Same seeds, with and without it.
    let with = Seed004Config::default();
    let without = Seed004Config {
        estimate_heading_drift: false,
        ..Seed004Config::default()
    };
    let (mut a, mut b) = (0.0, 0.0);
    for seed in 0..3 {
        let run = run_seed_004(&with, seed).unwrap();
        a += rmse(&run, &run.vd);
        let run = run_seed_004(&without, seed).unwrap();
        b += rmse(&run, &run.vd);
    }
    eprintln!(
        "VD-KF mean RMSE over 3 runs: drift estimated {:.1} m, drift as variance {:.1} m",
        a / 3.0,
        b / 3.0
    );
    assert!(a < 0.8 * b, "drift estimation {a} vs none {b}");
}

#[test]
fn the_engine_tracks_the_recording_to_the_measured_accuracy() {
    // `rtls repro vdkf --runs 10` (seed 2026) measured 6.33 m pooled RMSE for the engine
    // (√PCRB 4.35 m); seeds 0–2 give 5.98 m. They must stay within 15 % of 6.3 m, with every
    // epoch scored and nothing refused.
    let config = Seed004Config::default();
    let (mut squared, mut epochs) = (0.0, 0usize);
    for seed in 0..3 {
        let recording = seed_004_recording(&config, seed).unwrap();
        let tracked = recording.track().unwrap();
        assert!(tracked.refused.is_empty(), "seed {seed}: {:?}", tracked.refused);
        let times: Vec<f64> = recording.truth.iter().map(|row| row.time_s).collect();
        for (update, truth) in tracked.latest_at(SEED_004_TAG, &times).iter().zip(&recording.truth) {
            let update = update.expect("a state at every epoch");
            squared += (update.position_m[0] - truth.position_m[0]).powi(2)
                + (update.position_m[1] - truth.position_m[1]).powi(2);
            epochs += 1;
        }
    }
    let rmse = (squared / epochs as f64).sqrt();
    eprintln!("engine on seed 004 recordings 0–2: pooled RMSE {rmse:.2} m");
    assert!(rmse < 1.15 * 6.3, "engine RMSE {rmse} m");
    assert!(rmse > 4.3, "engine RMSE {rmse} m below the √PCRB: the scoring is wrong");
}
