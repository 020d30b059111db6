//! Seed 000 (ME-KF, mine personnel location) as `rtls repro mekf` runs it: the mine walk over
//! seeded Monte Carlo runs and the re-evaluation of the paper's Table 1, with the embedded
//! scenarios `scenarios/000-mine-walk.toml` and `scenarios/000-table-1.toml`.
//!
//! Prints every metric as `name | unit | paper | ours | bound`, the tables, the notes and the
//! elapsed time.
//!
//! Run: `cargo run --release -p rtls-sim --example repro_mekf [runs]` (default 50; seed 2026).
use std::time::Instant;

use rtls_sim::experiments::{ExperimentId, ReproOptions};
use rtls_sim::montecarlo::Progress;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: usize = match std::env::args().nth(1) {
        Some(arg) => arg
            .parse()
            .map_err(|e| format!("runs must be a positive integer, got {arg:?}: {e}"))?,
        None => 50,
    };
    let options = ReproOptions { runs, seed: 2026 };
    let sources = ExperimentId::Mekf.embedded_scenarios();
    let start = Instant::now();
    let report = ExperimentId::Mekf.reproduce(&sources, &options, Progress::none())?;
    let elapsed = start.elapsed();
    let show = |v: Option<f64>| v.map_or_else(|| "–".to_string(), |v| format!("{v:.3}"));
    println!("# {}\n", report.title);
    println!(
        "runs = {}, seed = {}, scenarios: {}\n",
        report.runs,
        report.seed,
        report.scenarios.join(", ")
    );
    println!("name | unit | paper | ours | bound");
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
        println!("\n## {}\n", table.title);
        println!("{}", table.header.join(" | "));
        for row in &table.rows {
            println!("{}", row.join(" | "));
        }
    }
    println!("\n## Figures\n");
    for f in &report.figures {
        let points: usize = f.series.iter().map(|s| s.points.len()).sum();
        println!("{}: {} series, {} points — {}", f.id, f.series.len(), points, f.title);
    }
    println!("\n## Notes\n");
    for note in &report.notes {
        println!("{note}\n");
    }
    println!("elapsed: {:.2} s for {runs} runs", elapsed.as_secs_f64());
    Ok(())
}
