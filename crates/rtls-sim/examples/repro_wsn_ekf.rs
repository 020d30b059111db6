//! Runs the `wsn-ekf` reproduction (seed 003: single-observation EKF with adaptive node
//! scheduling in an ultrasonic WSN) with the shipped scenario and prints every metric, the
//! tables and the notes, with the elapsed time.
//!
//! Run: `cargo run --release -p rtls-sim --example repro_wsn_ekf [runs]` (default 50).
use std::time::Instant;

use rtls_sim::experiments::{ExperimentId, ReproOptions};
use rtls_sim::montecarlo::Progress;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: usize = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(50);
    let options = ReproOptions { runs, seed: 2026 };
    let sources = ExperimentId::WsnEkf.embedded_scenarios();
    let start = Instant::now();
    let report = ExperimentId::WsnEkf.reproduce(&sources, &options, Progress::none())?;
    let elapsed = start.elapsed();
    println!("{} ({} runs, seed {})", report.title, report.runs, report.seed);
    println!("name | unit | paper | ours | bound");
    let show = |v: Option<f64>| v.map_or_else(|| "—".to_string(), |v| format!("{v:.4}"));
    for m in &report.metrics {
        println!(
            "{} | {} | {} | {:.4} | {}",
            m.name,
            m.unit,
            show(m.paper),
            m.ours,
            show(m.bound)
        );
    }
    for table in &report.tables {
        println!("\n{}\n{}", table.title, table.header.join(" | "));
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
    println!("\nelapsed: {:.2} s", elapsed.as_secs_f64());
    Ok(())
}
