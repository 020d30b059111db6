//! IMM across models of different state size (CV 4-state KF, CA 6-state KF, coordinated turn
//! 5-state EKF) on seed 004's vehicle: mode probabilities per motion phase and RMSE against the
//! VD-KF on the same data.
//!
//! Run: `cargo run --release -p rtls-papers --example imm [runs]` (default 50).
use rtls_papers::reproduction::{run_seed_004, Seed004Config};
use rtls_sim::{seed_004_phases, ErrorSummary};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let config = Seed004Config::default();
    let mut per_phase = vec![([0.0; 3], 0usize); seed_004_phases().len()];
    let (mut vd, mut imm) = (0.0, 0.0);
    for seed in 0..runs {
        let run = run_seed_004(&config, seed)?;
        vd += ErrorSummary::from_positions(&run.truth_positions(), &run.vd)?.rmse_m;
        imm += ErrorSummary::from_positions(&run.truth_positions(), &run.imm)?.rmse_m;
        for (sample, p) in run.truth.iter().zip(&run.imm_probabilities) {
            if let Some(i) = seed_004_phases()
                .iter()
                .position(|(a, b, _)| sample.time_s > *a && sample.time_s <= *b)
            {
                for (sum, pj) in per_phase[i].0.iter_mut().zip(p) {
                    *sum += pj;
                }
                per_phase[i].1 += 1;
            }
        }
    }
    println!("IMM mean mode probabilities per phase of seed 004 ({runs} runs):");
    println!("  {:<28} {:>6} {:>6} {:>6}", "phase", "P(CV)", "P(CA)", "P(CT)");
    for ((a, b, phase), (sum, n)) in seed_004_phases().iter().zip(&per_phase) {
        let n = *n as f64;
        println!(
            "  {:<28} {:>6.2} {:>6.2} {:>6.2}",
            format!("{phase:?} {a:.0}–{b:.0} s"),
            sum[0] / n,
            sum[1] / n,
            sum[2] / n
        );
    }
    let n = runs as f64;
    println!(
        "RMSE (mean of per-run RMSE): IMM {:.1} m, VD-KF {:.1} m",
        imm / n,
        vd / n
    );
    Ok(())
}
