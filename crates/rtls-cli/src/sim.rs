//! `rtls sim`: writes a simulated scenario as files a user can run the tracker on.
//!
//! ```text
//! rtls sim mine --out DIR [--miners N] [--duration-s S] [--seed N] [--without-map]
//! rtls sim mekf|ukf-uwb|lwknn|vdkf --out DIR [--seed N] [--run I] [--scenarios DIR]
//! ```
//!
//! `DIR/site.toml` (the site the tracker needs), `DIR/measurements.jsonl` (the records, JSON
//! Lines as `rtls track` reads them) and `DIR/truth.csv` (`t,tag,x,y,z` every 0.25 s, as
//! `rtls eval` reads it), so that
//!
//! ```text
//! rtls track --site DIR/site.toml --input DIR/measurements.jsonl --output DIR/tracks.jsonl
//! rtls eval --truth DIR/truth.csv --tracks DIR/tracks.jsonl
//! ```
//!
//! scores the tracker on a known truth from files, and a user can start a deployment from it.
//!
//! A paper scenario (`mekf`, `ukf-uwb`, `lwknn`, `vdkf`: seeds 000, 001, 002, 004) is written as run `I` of
//! `rtls repro <experiment> --seed N`: the same site, records and truth its "ours" row tracks,
//! so the row's figures can be reproduced from the files.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use rtls_engine::record::to_json_line;
use rtls_papers::experiments::ExperimentId;
use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, SiteOptions};

/// Truth is written this often, s (`rtls eval` interpolates across at most 0.5 s by default).
const TRUTH_INTERVAL_S: f64 = 0.25;

/// The scenarios `rtls sim` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Scenario {
    /// Seed 000's mine: 307 RSSI readers along seven drifts and a cross-cut, roaming miners,
    /// a roof fall on drift 3 whose reader is broken (the `rtls serve --demo` feed).
    Mine,
    /// Seed 000's mine walk (`rtls repro mekf`): one miner past the readers of a decline, a
    /// main drift and a cross-cut with a coverage hole; the site carries the tunnels and the
    /// tracker settings of the reproduction's "ours" row.
    Mekf,
    /// Seed 001's turn (`rtls repro ukf-uwb`): a walker turning between two UWB stations that
    /// range (TOA) and measure RSS; the site runs the coordinated-turn UKF of the "ours" row.
    UkfUwb,
    /// Seed 002's field (`rtls repro lwknn`, Fig. 1): a node crossing a 100 m × 100 m field of
    /// 25 anchors, its L-WKNN fixes and accelerometer samples; the site runs the textbook
    /// `[p, v]` KF with the accelerometer as control input.
    Lwknn,
    /// Seed 004's vehicle (`rtls repro vdkf`): cellular TDOA from four stations and on-board
    /// odometry with a drifting heading; the site runs the IMM with the heading channel.
    Vdkf,
}

/// Arguments of `rtls sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// The scenario to write.
    #[arg(value_enum)]
    scenario: Scenario,
    /// Directory for site.toml, measurements.jsonl and truth.csv (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Miners (tags); the first 1 in 60 (1 to 10) start heading into the collapse.
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    miners: u64,
    /// Simulated time, s.
    #[arg(long, value_name = "S", default_value_t = 600.0, allow_negative_numbers = true)]
    duration_s: f64,
    /// Seed of every random draw (a paper scenario: the base seed of `rtls repro`).
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// A paper scenario: which Monte Carlo run of `rtls repro --seed N` to write.
    #[arg(long, default_value_t = 0)]
    run: usize,
    /// A paper scenario: read its scenario files from DIR (edited copies) instead of the shipped
    /// ones, as `rtls repro --scenarios DIR` does.
    #[arg(long, value_name = "DIR")]
    scenarios: Option<PathBuf>,
    /// Leave the tunnels (`[[corridors]]`) and the readers' sensitivity out of the site file:
    /// the tracker without the map and negative information, for comparison.
    #[arg(long)]
    without_map: bool,
}

/// Runs `rtls sim`.
///
/// # Errors
/// A duration that is not a positive number of seconds up to a day, or a file that cannot be
/// written.
pub fn run(args: &SimArgs) -> Result<()> {
    if !(args.duration_s > 0.0 && args.duration_s <= 86_400.0) {
        bail!("--duration-s must be a number of seconds in (0, 86 400]");
    }
    match args.scenario {
        Scenario::Mine => mine(args),
        Scenario::Mekf => paper(args, ExperimentId::Mekf),
        Scenario::UkfUwb => paper(args, ExperimentId::UkfUwb),
        Scenario::Lwknn => paper(args, ExperimentId::Lwknn),
        Scenario::Vdkf => paper(args, ExperimentId::Vdkf),
    }
}

/// Writes run `--run` of a paper experiment's scenario.
fn paper(args: &SimArgs, id: ExperimentId) -> Result<()> {
    let sources = crate::repro::scenario_sources(id, args.scenarios.as_deref())?;
    let recording = id
        .recording(&sources, args.seed, args.run)
        .with_context(|| format!("`{}` has no recording", id.name()))?
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let tags: std::collections::BTreeSet<&str> = recording.records.iter().map(|r| r.tag.as_str()).collect();
    write_files(
        &args.out,
        &recording.site_toml,
        &recording.measurements_jsonl(),
        &recording.truth_csv(),
    )?;
    eprintln!(
        "wrote {}: site.toml, measurements.jsonl ({} records of {} tags), truth.csv ({} rows)",
        args.out.display(),
        recording.records.len(),
        tags.len(),
        recording.truth.len()
    );
    Ok(())
}

/// Writes the three files into `dir` (created if missing).
fn write_files(dir: &std::path::Path, site: &str, measurements: &str, truth: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, text) in [
        ("site.toml", site),
        ("measurements.jsonl", measurements),
        ("truth.csv", truth),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn mine(args: &SimArgs) -> Result<()> {
    let miners = usize::try_from(args.miners)?;
    let layout = MineLayout::seed000();
    let config = MineConfig {
        miners,
        entering_miners: (miners / 60).clamp(1, 10),
        seed: args.seed,
        ..MineConfig::default()
    };
    let site = layout.site_toml(&SiteOptions {
        name: Some(format!(
            "Simulated mine (seed 000), {miners} miners, seed {}",
            args.seed
        )),
        drift_zones: false,
        without_map: args.without_map,
    });
    let mut simulation = MineSimulation::new(layout, config.clone()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut measurements = String::new();
    let mut truth = String::from("t,tag,x,y,z\n");
    let steps = (args.duration_s / TRUTH_INTERVAL_S).ceil() as usize;
    let (mut records, mut rows) = (0usize, 0usize);
    for k in 0..=steps {
        let t_s = config.start_time_s + (k as f64 * TRUTH_INTERVAL_S).min(args.duration_s);
        for record in simulation.step(t_s) {
            measurements.push_str(&to_json_line(&record));
            measurements.push('\n');
            records += 1;
        }
        for (tag, [x, y]) in simulation.truth() {
            // writing into a String cannot fail
            let _ = writeln!(truth, "{t_s},{tag},{x},{y},");
            rows += 1;
        }
    }
    write_files(&args.out, &site, &measurements, &truth)?;
    eprintln!(
        "wrote {}: site.toml ({miners} miners' site), measurements.jsonl ({records} records), truth.csv ({rows} rows)",
        args.out.display()
    );
    Ok(())
}
