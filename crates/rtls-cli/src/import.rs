//! `rtls import`: converts a recorded dataset into the engine's files.
//!
//! ```text
//! rtls import <DATASET_DIR> --out DIR
//! ```
//!
//! Recognises the dataset by its files (`rtls_data::import::Dataset::detect`) and writes, per
//! run, `DIR/<run>/site.toml`, `measurements.jsonl` and `truth.csv`; prints per run its name,
//! the files written, the record and ground-truth row counts and the importer's notes (choices,
//! corrections, skipped rows and why).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rtls_data::import::{import_dataset, ImportSummary};

/// Arguments of `rtls import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The dataset directory: one of the folders of ../shared/data (e.g.
    /// ../shared/data/uwb_odometry_labyrinth_tuc).
    #[arg(value_name = "DATASET_DIR")]
    dataset_dir: PathBuf,
    /// Output directory (created if needed): one sub-directory per run.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// Runs `rtls import`.
pub fn run(args: &ImportArgs) -> Result<()> {
    let summary = import_dataset(&args.dataset_dir, &args.out)?;
    print!("{}", report(args, &summary));
    Ok(())
}

fn report(args: &ImportArgs, summary: &ImportSummary) -> String {
    let mut out = String::new();
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "{} dataset in {} → {}: {} run{}",
        summary.dataset.name(),
        args.dataset_dir.display(),
        args.out.display(),
        summary.runs.len(),
        if summary.runs.len() == 1 { "" } else { "s" }
    );
    for run in &summary.runs {
        let _ = writeln!(
            out,
            "\nrun {}: {} measurement records, {} ground-truth rows",
            run.name, run.records, run.truth_rows
        );
        for file in &run.files {
            let _ = writeln!(out, "  wrote {}", file.display());
        }
        for note in &run.notes {
            let _ = writeln!(out, "  note: {note}");
        }
    }
    out
}
