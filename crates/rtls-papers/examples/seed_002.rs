//! Seed 002 reproduction: L-WKNN fingerprint fixes and accelerometer-aided Kalman tracking,
//! the paper's first- and second-order models (as printed) and the textbook `[p, v]` model.
//!
//! Run: `cargo run --release -p rtls-papers --example seed_002 [runs]` (default 50, the paper's).
use rtls_papers::reproduction::{run_seed_002, Seed002Config};
use rtls_sim::ErrorSummary;

fn report(title: &str, config: &Seed002Config, runs: u64) -> Result<(), Box<dyn std::error::Error>> {
    let mut all: [Vec<f64>; 4] = Default::default();
    for seed in 0..runs {
        let run = run_seed_002(config, seed)?;
        for (errors, estimates) in all
            .iter_mut()
            .zip([&run.fixes, &run.first_order, &run.second_order, &run.textbook])
        {
            errors.extend(rtls_sim::euclidean_errors(&run.truth, estimates)?);
        }
    }
    println!("{title} ({runs} runs)");
    println!(
        "  {:<28} {:>8} {:>8} {:>8} {:>8}",
        "estimator", "mean m", "RMSE m", "p90 m", "max m"
    );
    for (name, errors) in [
        "L-WKNN fixes",
        "1st order (as printed)",
        "2nd order (as printed)",
        "textbook [p, v] + accel",
    ]
    .iter()
    .zip(&all)
    {
        let s = ErrorSummary::from_errors(errors)?;
        println!(
            "  {name:<28} {:>8.2} {:>8.2} {:>8.2} {:>8.2}",
            s.mean_m, s.rmse_m, s.p90_m, s.max_m
        );
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    report(
        "Fig. 1 tracking: 100 s, accelerometer ε = 0.01 m/s², σ_p² = 16 (paper: L-WKNN < 3.1 m, 2nd order 1.4 m)",
        &Seed002Config::default(),
        runs,
    )?;
    report(
        "Fig. 6 model order: 80 s, accelerometer noise 10 % of the reading (paper: 2nd 1.1 m, 1st 1.6 m)",
        &Seed002Config::model_order_comparison(),
        runs,
    )?;
    Ok(())
}
