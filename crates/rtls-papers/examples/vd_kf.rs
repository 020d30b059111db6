//! Seed 004's variable-dimension Kalman filter on the paper's vehicle scenario: model switches
//! with their times, and RMSE against the raw TDOA fixes and a KF on the fixes.
//!
//! Run: `cargo run --release -p rtls-papers --example vd_kf [runs]` (default 50, the paper's).
use rtls_papers::reproduction::{run_seed_004, Seed004Config};
use rtls_sim::ErrorSummary;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let config = Seed004Config::default();
    let first = run_seed_004(&config, 0)?;
    println!("Seed 004, run 0: VD-KF model switches (truth: stop 400 s, start 450 s, turn 900–1000 s, deceleration 1000–1500 s)");
    for event in &first.vd_events {
        println!(
            "  t = {:6.0} s  → {:?}  (statistic {:.1}, threshold {:.1}, onset assumed at {:.0} s)",
            event.time_s, event.to, event.statistic, event.threshold, event.onset_time_s
        );
    }
    let mut rmse = [Vec::new(), Vec::new(), Vec::new()];
    for seed in 0..runs {
        let run = run_seed_004(&config, seed)?;
        let (fix_truth, fixes) = run.available_fixes();
        rmse[0].push(ErrorSummary::from_positions(&fix_truth, &fixes)?.rmse_m);
        rmse[1].push(ErrorSummary::from_positions(&run.truth_positions(), &run.kf)?.rmse_m);
        rmse[2].push(ErrorSummary::from_positions(&run.truth_positions(), &run.vd)?.rmse_m);
    }
    println!("RMSE over {runs} runs (mean of per-run RMSE):");
    for (name, values) in ["TDOA fixes (Chan + Taylor)", "KF on fixes", "VD-KF + odometry"]
        .iter()
        .zip(&rmse)
    {
        println!(
            "  {name:<28} {:6.1} m",
            values.iter().sum::<f64>() / values.len() as f64
        );
    }
    Ok(())
}
