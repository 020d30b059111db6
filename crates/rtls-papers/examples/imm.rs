//! The engine's IMM (CV 4-state KF, CA 6-state KF, coordinated turn 5-state EKF) on seed 004's
//! vehicle, tracked from the run's recording: the most probable mode per motion phase and the
//! RMSE against the VD-KF on the same data.
//!
//! Run: `cargo run --release -p rtls-papers --example imm [runs]` (default 50).
use rtls_papers::reproduction::{run_seed_004, Seed004Config};
use rtls_sim::{seed_004_phases, ErrorSummary};

const MODES: [&str; 3] = ["CV", "CA", "CT"];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let config = Seed004Config::default();
    let mut per_phase = vec![([0usize; 3], 0usize); seed_004_phases().len()];
    let (mut vd, mut imm) = (0.0, 0.0);
    for seed in 0..runs {
        let run = run_seed_004(&config, seed)?;
        vd += ErrorSummary::from_positions(&run.truth_positions(), &run.vd)?.rmse_m;
        imm += ErrorSummary::from_positions(&run.truth_positions(), &run.engine_positions()?)?.rmse_m;
        for (sample, estimate) in run.truth.iter().zip(&run.engine) {
            let phase = seed_004_phases()
                .iter()
                .position(|(a, b, _)| sample.time_s > *a && sample.time_s <= *b);
            let mode = estimate
                .as_ref()
                .and_then(|e| e.mode)
                .and_then(|m| MODES.iter().position(|n| *n == m));
            if let (Some(i), Some(j)) = (phase, mode) {
                per_phase[i].0[j] += 1;
                per_phase[i].1 += 1;
            }
        }
    }
    println!("Engine IMM: share of epochs in each most probable mode per phase of seed 004 ({runs} runs):");
    println!("  {:<28} {:>6} {:>6} {:>6}", "phase", "CV", "CA", "CT");
    for ((a, b, phase), (counts, n)) in seed_004_phases().iter().zip(&per_phase) {
        let n = (*n).max(1) as f64;
        println!(
            "  {:<28} {:>6.2} {:>6.2} {:>6.2}",
            format!("{phase:?} {a:.0}–{b:.0} s"),
            counts[0] as f64 / n,
            counts[1] as f64 / n,
            counts[2] as f64 / n
        );
    }
    let n = runs as f64;
    println!(
        "RMSE (mean of per-run RMSE): engine IMM {:.1} m, VD-KF {:.1} m",
        imm / n,
        vd / n
    );
    Ok(())
}
