//! `rtls`: the command-line front end of the RTLS engine.
//!
//! ```text
//! rtls repro <mekf|ukf-uwb|lwknn|wsn-ekf|vdkf|all> [--runs N] [--seed S] [--out DIR] [--json]
//!            [--scenarios DIR] [--threads N]
//! ```
//!
//! `repro` reruns the seed papers' experiments (seeded Monte Carlo, in parallel), prints
//! "metric | paper | ours | PCRB" per experiment, and with `--out` writes a markdown report with
//! SVG and PNG figures (`rtls repro all --out docs` regenerates `docs/REPRODUCTIONS.md`).

mod markdown;
mod plot;
mod repro;

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
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Repro(args) => repro::run(&args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
