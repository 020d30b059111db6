//! `rtls repro`: runs the paper reproductions and reports them.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rtls_papers::experiments::{ExperimentId, ReproOptions, ScenarioSource};
use rtls_papers::report::{ExperimentReport, Metric};
use rtls_sim::montecarlo::Progress;
use serde::Serialize;

/// Which experiment to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Which {
    /// Seed 000: ME-KF on a mine walk (PEL, error rates, Table 1 re-evaluated).
    Mekf,
    /// Seed 001: UKF vs EKF over UWB TOA + RSS.
    UkfUwb,
    /// Seed 002: L-WKNN fingerprinting + accelerometer-aided KF.
    Lwknn,
    /// Seed 003: single-range EKF with node scheduling, three robots.
    WsnEkf,
    /// Seed 004: variable-dimension KF, cellular TDOA + odometry.
    Vdkf,
    /// All five, in paper order.
    All,
}

impl Which {
    fn experiments(self) -> Vec<ExperimentId> {
        match self {
            Self::Mekf => vec![ExperimentId::Mekf],
            Self::UkfUwb => vec![ExperimentId::UkfUwb],
            Self::Lwknn => vec![ExperimentId::Lwknn],
            Self::WsnEkf => vec![ExperimentId::WsnEkf],
            Self::Vdkf => vec![ExperimentId::Vdkf],
            Self::All => ExperimentId::ALL.to_vec(),
        }
    }
}

/// Arguments of `rtls repro`.
#[derive(Debug, Args)]
pub struct ReproArgs {
    /// The experiment.
    #[arg(value_enum)]
    experiment: Which,
    /// Monte Carlo runs per configuration (the papers use 50; seed 002's Table 2 used 100).
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    runs: u64,
    /// Base seed: run i of every configuration draws from a seed derived from (seed, i).
    #[arg(long, default_value_t = 2026)]
    seed: u64,
    /// Write REPRODUCTIONS.md and figures/ (SVG + PNG) into this directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print one JSON object per experiment on its own line instead of tables.
    #[arg(long)]
    json: bool,
    /// Read the scenario TOML files from this directory instead of the shipped ones.
    #[arg(long)]
    scenarios: Option<PathBuf>,
    /// Worker threads (default: one per core). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1024))]
    threads: Option<u64>,
}

/// One line of `--json` output.
#[derive(Debug, Serialize)]
struct JsonLine<'a> {
    experiment: &'a str,
    runs: usize,
    seed: u64,
    metrics: &'a [Metric],
}

/// Runs `rtls repro`.
///
/// # Errors
/// Unreadable scenario files, a failing simulation, or an unwritable output directory.
pub fn run(args: &ReproArgs) -> Result<()> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        pool = pool.num_threads(usize::try_from(threads)?);
    }
    let pool = pool.build().context("starting the worker threads")?;
    let options = ReproOptions {
        runs: usize::try_from(args.runs)?,
        seed: args.seed,
    };
    let mut reports = Vec::new();
    for id in args.experiment.experiments() {
        let sources = scenario_sources(id, args.scenarios.as_deref())?;
        let units = id
            .work_units(&sources, &options)
            .with_context(|| format!("reading the scenarios of `{}`", id.name()))?;
        let bar = progress_bar(id, units, args.json);
        let tick = |n: u64| bar.inc(n);
        let started = Instant::now();
        let report = pool
            .install(|| id.reproduce(&sources, &options, Progress::new(&tick)))
            .with_context(|| format!("experiment `{}`", id.name()))?;
        bar.finish_and_clear();
        let elapsed_s = started.elapsed().as_secs_f64();
        if args.json {
            let line = JsonLine {
                experiment: &report.experiment,
                runs: report.runs,
                seed: report.seed,
                metrics: &report.metrics,
            };
            writeln!(std::io::stdout().lock(), "{}", serde_json::to_string(&line)?).context("writing to stdout")?;
        } else {
            print_table(&mut std::io::stdout().lock(), &report, elapsed_s).context("writing to stdout")?;
        }
        reports.push(report);
    }
    if let Some(dir) = &args.out {
        write_report(dir, &reports, args)?;
        if !args.json {
            writeln!(
                std::io::stdout().lock(),
                "report: {}",
                dir.join("REPRODUCTIONS.md").display()
            )
            .context("writing to stdout")?;
        }
    }
    Ok(())
}

/// The experiment's scenario files, from `dir` if given, else the shipped ones.
pub(crate) fn scenario_sources(id: ExperimentId, dir: Option<&Path>) -> Result<Vec<ScenarioSource>> {
    let Some(dir) = dir else {
        return Ok(id.embedded_scenarios());
    };
    id.scenario_files()
        .iter()
        .map(|name| {
            let path = dir.join(name);
            let text =
                std::fs::read_to_string(&path).with_context(|| format!("reading scenario file {}", path.display()))?;
            Ok(ScenarioSource {
                name: (*name).to_string(),
                text,
            })
        })
        .collect()
}

fn progress_bar(id: ExperimentId, units: u64, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(units), ProgressDrawTarget::stderr());
    if quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    if let Ok(style) = ProgressStyle::with_template("{prefix:>8} [{bar:40}] {pos}/{len} runs {elapsed_precise}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(id.name());
    bar
}

fn format_value(value: Option<f64>) -> String {
    match value {
        None => "–".to_string(),
        Some(v) if v != 0.0 && (v.abs() >= 1e5 || v.abs() < 1e-3) => format!("{v:.3e}"),
        Some(v) => format!("{v:.3}"),
    }
}

fn print_table(out: &mut impl Write, report: &ExperimentReport, elapsed_s: f64) -> std::io::Result<()> {
    writeln!(out, "\n{} ({} runs, seed {})", report.title, report.runs, report.seed)?;
    let width = report
        .metrics
        .iter()
        .map(|m| m.name.chars().count())
        .max()
        .unwrap_or(6)
        .max(6);
    writeln!(
        out,
        "{:<width$} | {:>6} | {:>10} | {:>10} | {:>10}",
        "metric", "unit", "paper", "ours", "PCRB"
    )?;
    writeln!(out, "{}", "-".repeat(width + 47))?;
    for m in &report.metrics {
        writeln!(
            out,
            "{:<width$} | {:>6} | {:>10} | {:>10} | {:>10}",
            m.name,
            m.unit,
            format_value(m.paper),
            format_value(Some(m.ours)),
            format_value(m.bound)
        )?;
    }
    writeln!(out, "({elapsed_s:.1} s)")
}

fn write_report(dir: &Path, reports: &[ExperimentReport], args: &ReproArgs) -> Result<()> {
    let figures = dir.join("figures");
    std::fs::create_dir_all(&figures).with_context(|| format!("creating {}", figures.display()))?;
    for report in reports {
        for figure in &report.figures {
            crate::plot::render(figure, &figures).with_context(|| format!("drawing figure `{}`", figure.id))?;
        }
    }
    let command = command_line(args);
    let text = crate::markdown::report(reports, &command);
    let path = dir.join("REPRODUCTIONS.md");
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    if reports.is_empty() {
        bail!("no experiment ran");
    }
    Ok(())
}

/// The command that regenerates the report (without `--threads`, which does not change it).
fn command_line(args: &ReproArgs) -> String {
    let experiment = args
        .experiment
        .to_possible_value()
        .map_or_else(|| "all".to_string(), |v| v.get_name().to_string());
    let mut command = format!("rtls repro {experiment} --runs {} --seed {}", args.runs, args.seed);
    if let Some(out) = &args.out {
        command.push_str(&format!(" --out {}", out.display()));
    }
    if let Some(dir) = &args.scenarios {
        command.push_str(&format!(" --scenarios {}", dir.display()));
    }
    command
}
