//! Seed 004 reproduction: raw TDOA fixes, KF on fixes, VD-KF fused with odometry, and IMM.
//!
//! Run: `cargo run --release -p rtls-sim --example seed_004 [runs]`
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let mut config = rtls_sim::reproduction::Seed004Config::default();
    if let Ok(v) = std::env::var("DRIFT") {
        config.odometer.heading_drift_rad_per_s = v.parse::<f64>()?.to_radians() / 3600.0;
    }
    if std::env::var("NOBIAS").is_ok() {
        config.estimate_heading_drift = false;
    }
    if let Ok(v) = std::env::var("IMMQ") {
        config.imm_cv_variance = v.parse()?;
    }
    if let Ok(v) = std::env::var("IMMCA") {
        config.imm_ca_variance = v.parse()?;
    }
    if let Ok(v) = std::env::var("IMMW") {
        config.imm_turn_rate_variance = v.parse()?;
    }
    if let Ok(v) = std::env::var("EXITP") {
        config.detector.exit = rtls_estimation::manoeuvre::Threshold::ChiSquare {
            probability: v.parse()?,
        };
    }
    if let Ok(v) = std::env::var("EXITW") {
        config.detector.exit_window_steps = v.parse()?;
    }
    if let Ok(v) = std::env::var("CVQ") {
        config.cv_variance = v.parse()?;
    }
    if let Ok(v) = std::env::var("CAQ") {
        config.ca_variance = v.parse()?;
    }
    if let Ok(v) = std::env::var("ALPHA") {
        config.detector.fading_factor = v.parse()?;
    }
    let mut sums = [0.0f64; 4];
    for seed in 0..runs {
        let run = rtls_sim::reproduction::run_seed_004(&config, seed)?;
        let truth = run.truth_positions();
        let (ft, fe) = run.available_fixes();
        let raw = rtls_sim::ErrorSummary::from_positions(&ft, &fe)?;
        let kf = rtls_sim::ErrorSummary::from_positions(&truth, &run.kf)?;
        let vd = rtls_sim::ErrorSummary::from_positions(&truth, &run.vd)?;
        let imm = rtls_sim::ErrorSummary::from_positions(&truth, &run.imm)?;
        sums[0] += raw.rmse_m;
        sums[1] += kf.rmse_m;
        sums[2] += vd.rmse_m;
        sums[3] += imm.rmse_m;
        if seed < 3 {
            println!("seed {seed}: R = {:?}", run.fix_covariance_m2.as_slice());
            for e in &run.vd_events {
                println!(
                    "  t={:7.1} -> {:?} stat {:.1} th {:.1} onset {:.1}",
                    e.time_s, e.to, e.statistic, e.threshold, e.onset_time_s
                );
            }
            for (a, b, phase) in rtls_sim::seed_004_phases() {
                let sel: Vec<_> = run
                    .imm_probabilities
                    .iter()
                    .zip(&run.truth)
                    .filter(|(_, s)| s.time_s > a + 10.0 && s.time_s <= b)
                    .map(|(p, _)| *p)
                    .collect();
                let n = sel.len() as f64;
                let m = sel.iter().fold([0.0; 3], |acc, p| {
                    [acc[0] + p[0] / n, acc[1] + p[1] / n, acc[2] + p[2] / n]
                });
                println!(
                    "  {phase:?} {a}-{b}: IMM mean P [CV, CA, CT] = [{:.2}, {:.2}, {:.2}]",
                    m[0], m[1], m[2]
                );
            }
        }
        for (a, b, phase) in rtls_sim::seed_004_phases() {
            let idx: Vec<usize> = (0..run.truth.len())
                .filter(|&i| run.truth[i].time_s > a && run.truth[i].time_s <= b)
                .collect();
            let rm = |est: &Vec<[f64; 2]>| {
                let t: Vec<[f64; 2]> = idx.iter().map(|&i| truth[i]).collect();
                let e: Vec<[f64; 2]> = idx.iter().map(|&i| est[i]).collect();
                rtls_sim::ErrorSummary::from_positions(&t, &e).unwrap().rmse_m
            };
            if seed < 2 {
                println!(
                    "   {phase:?}: kf {:.1} vd {:.1} imm {:.1}",
                    rm(&run.kf),
                    rm(&run.vd),
                    rm(&run.imm)
                );
            }
        }
        println!(
            "seed {seed}: RMSE raw {:.1} kf {:.1} vd {:.1} imm {:.1}",
            raw.rmse_m, kf.rmse_m, vd.rmse_m, imm.rmse_m
        );
    }
    let n = runs as f64;
    println!(
        "mean RMSE over {runs} runs: raw {:.1} m, KF {:.1} m, VD-KF {:.1} m, IMM {:.1} m",
        sums[0] / n,
        sums[1] / n,
        sums[2] / n,
        sums[3] / n
    );
    Ok(())
}
