//! `rtls`: the command-line front end of the RTLS engine.
//!
//! ```text
//! rtls repro <mekf|ukf-uwb|lwknn|wsn-ekf|vdkf|all> [--runs N] [--seed S] [--out DIR] [--json]
//!            [--scenarios DIR] [--threads N]
//! rtls track --site SITE --input FILE [--output FILE] [--events FILE] [--fixes FILE]
//!            [--pipeline fix-then-filter|tightly-coupled] [--filter kf|ekf|ukf] [--motion-model cv|imm]
//!            [--quiet]
//! rtls import <DATASET_DIR> --out DIR
//! rtls eval --truth FILE --tracks FILE [--dimensions 2|3] [--max-gap S] [--skip-initial S]
//!           [--include-predicted] [--json]
//! rtls survey --site SITE --input RECORDS --tracks TRACKS --out CELLS.csv [--readers-out CSV]
//!             [--png PNG] [--cell-m M] …
//! rtls tune --site SITE --input FILE --out TUNED.toml [--truth TRUTH.csv] [--until-s T]
//!           [--grid A,B,…] [--json]
//! rtls sim mine --out DIR [--miners N] [--duration-s S] [--seed N] [--without-map]
//! ```
//!
//! `track` runs a measurement file through the tracker of a site (docs/FORMATS.md), `import`
//! converts a recorded dataset into site, measurement and ground-truth files, `eval` scores a
//! track file against ground truth (docs/EVALUATION.md) with the consistency of its covariances,
//! `tune` fits a site's noise settings to a recording (with or without ground truth), `survey` maps where the radio
//! environment is degraded (seed 000's obstacle map: residual bias per area cell and reader).
//!
//! `repro` reruns the seed papers' experiments (seeded Monte Carlo, in parallel), prints
//! "metric | paper | ours | PCRB" per experiment, and with `--out` writes a markdown report with
//! SVG and PNG figures (`rtls repro all --out docs` regenerates `docs/REPRODUCTIONS.md`).
//! `serve` runs the control-room server; `--demo` feeds it seed 000's simulated mine.
//!
//! ## Layer
//! The top of the workspace: the binary composes the crates below it and may import every one
//! of them (the experiments of rtls-papers for `repro`, rtls-sim's mine for `serve --demo`,
//! rtls-server, rtls-engine, rtls-data); nothing imports it. Errors are `anyhow` here only.

mod demo;
mod eval;
mod import;
mod malformed;
mod markdown;
mod plot;
mod repro;
mod serve;
mod sim;
mod survey;
mod track;
mod tune;

use clap::{Parser, Subcommand};

/// Real-time location system engine.
#[derive(Debug, Parser)]
#[command(name = "rtls", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Reproduce the seed papers' experiments: seeded Monte Carlo, the papers' metrics beside
    /// ours and the posterior Cramér–Rao bound, plots and a markdown report.
    Repro(repro::ReproArgs),
    /// Track tags from a measurement file (JSON Lines or CSV) on a site model: one JSON line per
    /// track update, zone / alarm / lifecycle events to an events file.
    Track(track::TrackArgs),
    /// Convert a recorded dataset (../shared/data) into a site file, a measurement file and a
    /// ground-truth file per run.
    Import(import::ImportArgs),
    /// Compare a track file with ground truth: RMSE, mean error and percentiles, time-aligned by
    /// interpolation.
    Eval(eval::EvalArgs),
    /// Map the radio environment from measurements and their tracks: per area cell and reader,
    /// the bias and spread of the residuals; flags degraded readers and cells (CSV and PNG).
    Survey(survey::SurveyArgs),
    /// Fit a site to a recording: the process noise by innovation likelihood (or, with ground
    /// truth, the readers' range bias and noise, path-loss laws and the process noise by RMSE);
    /// writes the tuned site file.
    Tune(tune::TuneArgs),
    /// Run the control-room server: MQTT and HTTP ingest, omlox REST and WebSocket APIs,
    /// history, alarms, metrics. `--demo` runs seed 000's simulated mine through it.
    Serve(serve::ServeArgs),
    /// Write a simulated scenario (site file, measurements, ground truth) for `rtls track` and
    /// `rtls eval`.
    Sim(sim::SimArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Repro(args) => repro::run(&args),
        Command::Track(args) => track::run(&args),
        Command::Import(args) => import::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Survey(args) => survey::run(&args),
        Command::Tune(args) => tune::run(&args),
        Command::Serve(args) => serve::run(&args),
        Command::Sim(args) => sim::run(&args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) if error.downcast_ref::<track::UntrackedTags>().is_some() => {
            eprintln!("error: {error:#}");
            std::process::ExitCode::from(track::EXIT_UNTRACKED)
        }
        Err(error) => {
            eprintln!("error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// Every `--flag` of every command and subcommand, with the command's path.
    fn flags(command: &clap::Command, path: &str, out: &mut Vec<(String, String)>) {
        for arg in command.get_arguments() {
            if let Some(long) = arg.get_long().filter(|l| !matches!(*l, "help" | "version")) {
                out.push((path.to_string(), format!("--{long}")));
            }
        }
        for sub in command.get_subcommands() {
            flags(sub, &format!("{path} {}", sub.get_name()), out);
        }
    }

    /// The README's command table names every flag the `rtls` binary takes.
    #[test]
    fn every_flag_is_in_the_readme() {
        let readme = include_str!("../../../README.md");
        let mut all = Vec::new();
        flags(&super::Cli::command(), "rtls", &mut all);
        assert!(all.iter().any(|(_, f)| f == "--udp-adapter"), "{all:?}");
        let missing: Vec<_> = all.iter().filter(|(_, flag)| !readme.contains(flag.as_str())).collect();
        assert!(missing.is_empty(), "flags not in README.md: {missing:?}");
    }
}
