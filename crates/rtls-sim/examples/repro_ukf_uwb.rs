//! Seed 001 (`ukf-uwb`): the UKF over joint UWB TOA + RSS, reproduced with the shipped
//! scenarios; prints every metric (`name | unit | paper | ours | bound`), the tables, the notes
//! and the elapsed time.
//!
//! Run: `cargo run --release -p rtls-sim --example repro_ukf_uwb [runs]` (default 50, the
//! paper's).
use std::time::Instant;

use rtls_sim::experiments::{ExperimentId, ReproOptions};
use rtls_sim::montecarlo::Progress;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: usize = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let options = ReproOptions { runs, seed: 2026 };
    let sources = ExperimentId::UkfUwb.embedded_scenarios();
    let start = Instant::now();
    let report = ExperimentId::UkfUwb.reproduce(&sources, &options, Progress::none())?;
    let elapsed = start.elapsed();
    println!("{} — {} runs, seed {}", report.title, report.runs, report.seed);
    println!("name | unit | paper | ours | bound");
    let show = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.3}"));
    for m in &report.metrics {
        println!(
            "{} | {} | {} | {:.3} | {}",
            m.name,
            m.unit,
            show(m.paper),
            m.ours,
            show(m.bound)
        );
    }
    for table in &report.tables {
        println!("\n{}", table.title);
        println!("{}", table.header.join(" | "));
        for row in &table.rows {
            println!("{}", row.join(" | "));
        }
    }
    println!(
        "\nfigures: {}",
        report
            .figures
            .iter()
            .map(|f| f.id.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    for note in &report.notes {
        println!("\n{note}");
    }
    println!("\nelapsed: {:.3} s", elapsed.as_secs_f64());
    Ok(())
}
