//! `rtls eval`: compares a track file with ground truth.
//!
//! ```text
//! rtls eval --truth truth.csv --tracks tracks.jsonl [--dimensions 2|3] [--max-gap S]
//!           [--skip-initial S] [--include-predicted] [--json]
//! ```
//!
//! Every track sample is compared with the truth of its tag at its time, interpolated linearly
//! between the bracketing truth samples (`rtls_engine::evaluation`). Prints a table (overall and
//! per tag: count, RMSE, mean, median, p90, p95, max, in m), the consistency of the reported
//! covariances where the track lines carry `cov` (mean and median NEES, the share of truths
//! inside the reported 68 % and 95 % ellipses) and the samples that could not be scored, by
//! reason; `--json` prints one JSON object instead.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use rtls_engine::evaluation::{
    evaluate, parse_track_lines, parse_truth_csv, Consistency, ErrorStatistics, Evaluation, EvaluationSettings,
    Unmatched, TRACKS_SOURCE, TRUTH_SOURCE,
};
use rtls_engine::EngineError;
use serde::Serialize;

/// Arguments of `rtls eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Ground truth: CSV with the header `t,tag,x,y,z` (s, m; `z` empty for 2-D), as written by
    /// `rtls import`.
    #[arg(long, value_name = "FILE")]
    truth: PathBuf,
    /// Track file: JSON Lines as written by `rtls track` (or raw fixes in the same shape); reads
    /// `t`, `tag`, `x`, `y`, optional `z` and `predicted`, ignores other keys.
    #[arg(long, value_name = "FILE")]
    tracks: PathBuf,
    /// 2: horizontal error; 3: 3-D error (needs `z` in both files).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    dimensions: u8,
    /// Longest truth gap, s, that a track sample may be interpolated across ("inf": no limit).
    #[arg(long, value_name = "S", default_value_t = 0.5, value_parser = non_negative_seconds, allow_negative_numbers = true)]
    max_gap: f64,
    /// Ignore each tag's first S seconds of track (filter convergence).
    #[arg(
        long,
        value_name = "S",
        default_value_t = 0.0,
        value_parser = finite_non_negative_seconds,
        allow_negative_numbers = true
    )]
    skip_initial: f64,
    /// Score predicted (coasting) samples too; by default they are excluded and counted.
    #[arg(long)]
    include_predicted: bool,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    json: bool,
}

fn non_negative_seconds(text: &str) -> core::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value >= 0.0 => Ok(value),
        _ => Err(format!("`{text}` is not a number of seconds ≥ 0")),
    }
}

fn finite_non_negative_seconds(text: &str) -> core::result::Result<f64, String> {
    non_negative_seconds(text).and_then(|value| {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(format!("`{text}` is not a finite number of seconds"))
        }
    })
}

/// Replaces the evaluation's placeholder file names ([`TRUTH_SOURCE`], [`TRACKS_SOURCE`]) with
/// the real ones; an error about the track file as a whole (line 0) names just the file.
fn name_files(error: EngineError, truth: &str, tracks: &str) -> anyhow::Error {
    match error {
        EngineError::Parse {
            file,
            line,
            field,
            reason,
        } => {
            let reason = reason.replace(&format!("({TRACKS_SOURCE} line "), &format!("({tracks} line "));
            let file = match file.as_str() {
                TRUTH_SOURCE => truth.to_string(),
                TRACKS_SOURCE if line == 0 => return anyhow::anyhow!("{tracks}: {reason}"),
                TRACKS_SOURCE => tracks.to_string(),
                _ => file,
            };
            EngineError::Parse {
                file,
                line,
                field,
                reason,
            }
            .into()
        }
        other => other.into(),
    }
}

fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// Runs `rtls eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    let truth_name = args.truth.display().to_string();
    let tracks_name = args.tracks.display().to_string();
    let truth = parse_truth_csv(&read(&args.truth)?, &truth_name)?;
    let tracks = parse_track_lines(&read(&args.tracks)?, &tracks_name)?;
    let settings = EvaluationSettings {
        max_gap_s: args.max_gap,
        skip_initial_s: args.skip_initial,
        include_predicted: args.include_predicted,
        dimensions: usize::from(args.dimensions),
    };
    let evaluation = evaluate(&truth, &tracks, &settings).map_err(|e| name_files(e, &truth_name, &tracks_name))?;
    let counts = Counts {
        truth_samples: truth.len(),
        truth_tags: distinct(truth.iter().map(|s| s.tag.as_str())),
        track_samples: tracks.len(),
        track_tags: distinct(tracks.iter().map(|s| s.tag.as_str())),
    };
    let output = if args.json {
        json_report(args, &settings, &counts, &evaluation)? + "\n"
    } else {
        table_report(args, &settings, &counts, &evaluation)
    };
    print!("{output}");
    Ok(())
}

/// Sizes of the inputs.
struct Counts {
    truth_samples: usize,
    truth_tags: usize,
    track_samples: usize,
    track_tags: usize,
}

fn distinct<'a>(tags: impl Iterator<Item = &'a str>) -> usize {
    tags.collect::<std::collections::BTreeSet<_>>().len()
}

/// The counts of [`Unmatched`] in the order of [`unmatched_lines`].
fn reason_counts(unmatched: &Unmatched) -> [usize; 5] {
    [
        unmatched.predicted_excluded,
        unmatched.initial_skipped,
        unmatched.tag_not_in_truth,
        unmatched.outside_truth_span,
        unmatched.truth_gap,
    ]
}

/// The reasons a sample is not scored: (label, count, the tags it applies to).
fn unmatched_lines(settings: &EvaluationSettings, evaluation: &Evaluation) -> Vec<(String, usize, Vec<String>)> {
    let labels = [
        "predicted, excluded (--include-predicted scores them)".to_string(),
        format!("in a track's first {} s (--skip-initial)", settings.skip_initial_s),
        "tag without ground truth".to_string(),
        "outside the ground truth's time span".to_string(),
        format!("in a ground-truth gap longer than {} s (--max-gap)", settings.max_gap_s),
    ];
    let totals = reason_counts(&evaluation.unmatched);
    labels
        .into_iter()
        .enumerate()
        .map(|(reason, label)| {
            let tags = evaluation
                .unmatched_per_tag
                .iter()
                .filter(|(_, unmatched)| reason_counts(unmatched)[reason] > 0)
                .map(|(tag, _)| tag.clone())
                .collect();
            (label, totals[reason], tags)
        })
        .collect()
}

fn table_report(args: &EvalArgs, settings: &EvaluationSettings, counts: &Counts, evaluation: &Evaluation) -> String {
    let mut out = String::new();
    let plural = |n: usize| if n == 1 { "" } else { "s" };
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "ground truth: {} ({} samples, {} tag{})",
        args.truth.display(),
        counts.truth_samples,
        counts.truth_tags,
        plural(counts.truth_tags)
    );
    let _ = writeln!(
        out,
        "tracks:       {} ({} samples, {} tag{})",
        args.tracks.display(),
        counts.track_samples,
        counts.track_tags,
        plural(counts.track_tags)
    );
    let _ =
        writeln!(
        out,
        "{} error; truth interpolated across gaps up to {} s; first {} s of each track skipped; predicted samples {}",
        if settings.dimensions == 3 { "3-D" } else { "2-D (horizontal)" },
        settings.max_gap_s,
        settings.skip_initial_s,
        if settings.include_predicted { "scored" } else { "excluded" }
    );
    out.push('\n');

    let rows: Vec<(&str, &ErrorStatistics)> = std::iter::once(("overall", &evaluation.overall))
        .chain(evaluation.per_tag.iter().map(|(tag, stats)| (tag.as_str(), stats)))
        .collect();
    let width = rows
        .iter()
        .map(|(tag, _)| tag.chars().count())
        .max()
        .unwrap_or(0)
        .max(3);
    let _ = writeln!(
        out,
        "{:<width$}  {:>7}  {:>8}  {:>8}  {:>8}  {:>8}  {:>8}  {:>8}",
        "tag", "count", "RMSE m", "mean m", "median m", "p90 m", "p95 m", "max m"
    );
    for (tag, s) in rows {
        let _ = writeln!(
            out,
            "{tag:<width$}  {:>7}  {:>8.3}  {:>8.3}  {:>8.3}  {:>8.3}  {:>8.3}  {:>8.3}",
            s.count, s.rmse_m, s.mean_m, s.median_m, s.p90_m, s.p95_m, s.max_m
        );
    }
    out.push('\n');

    if let Some(overall) = &evaluation.consistency {
        let rows: Vec<(&str, &Consistency)> = std::iter::once(("overall", overall))
            .chain(evaluation.consistency_per_tag.iter().map(|(tag, c)| (tag.as_str(), c)))
            .collect();
        let _ = writeln!(
            out,
            "covariance consistency (NEES = eᵀP⁻¹e, consistent: mean {}, 95 % of truths inside the 95 % ellipse; \
             k²: what the covariances need multiplying by for 95 % inside)",
            overall.dimensions
        );
        let _ = writeln!(
            out,
            "{:<width$}  {:>7}  {:>9}  {:>11}  {:>9}  {:>9}  {:>7}",
            "tag", "count", "mean NEES", "median NEES", "in 68 %", "in 95 %", "k²"
        );
        for (tag, c) in rows {
            let _ = writeln!(
                out,
                "{tag:<width$}  {:>7}  {:>9.2}  {:>11.2}  {:>8.1}%  {:>8.1}%  {:>7.2}",
                c.count,
                c.mean_nees,
                c.median_nees,
                100.0 * c.inside_68,
                100.0 * c.inside_95,
                c.covariance_scale_95
            );
        }
        if overall.not_positive_definite > 0 {
            let _ = writeln!(
                out,
                "{} scored samples had a covariance that is not positive definite (not counted above)",
                overall.not_positive_definite
            );
        }
        out.push('\n');
    }

    let _ = writeln!(
        out,
        "unmatched track samples: {} of {}",
        evaluation.unmatched.total(),
        counts.track_samples
    );
    let lines = unmatched_lines(settings, evaluation);
    let label_width = lines.iter().map(|(label, ..)| label.chars().count()).max().unwrap_or(0);
    for (label, count, tags) in lines {
        let _ = write!(out, "  {label:<label_width$}  {count:>7}");
        if !tags.is_empty() {
            let _ = write!(out, "  (tag{}: {})", plural(tags.len()), tags.join(", "));
        }
        out.push('\n');
    }
    out
}

/// One per-tag entry of the JSON output.
#[derive(Serialize)]
struct TagStatistics<'a> {
    tag: &'a str,
    #[serde(flatten)]
    statistics: &'a ErrorStatistics,
}

/// One per-tag consistency entry of the JSON output.
#[derive(Serialize)]
struct TagConsistency<'a> {
    tag: &'a str,
    #[serde(flatten)]
    consistency: &'a Consistency,
}

/// One per-tag unmatched entry of the JSON output.
#[derive(Serialize)]
struct TagUnmatched<'a> {
    tag: &'a str,
    #[serde(flatten)]
    unmatched: &'a Unmatched,
    total: usize,
}

fn json_report(
    args: &EvalArgs,
    settings: &EvaluationSettings,
    counts: &Counts,
    evaluation: &Evaluation,
) -> Result<String> {
    let per_tag: Vec<_> = evaluation
        .per_tag
        .iter()
        .map(|(tag, statistics)| TagStatistics { tag, statistics })
        .collect();
    let unmatched_per_tag: Vec<_> = evaluation
        .unmatched_per_tag
        .iter()
        .map(|(tag, unmatched)| TagUnmatched {
            tag,
            unmatched,
            total: unmatched.total(),
        })
        .collect();
    let mut unmatched = serde_json::to_value(evaluation.unmatched)?;
    if let Some(object) = unmatched.as_object_mut() {
        object.insert("total".into(), evaluation.unmatched.total().into());
    }
    let value = serde_json::json!({
        "truth": args.truth.display().to_string(),
        "tracks": args.tracks.display().to_string(),
        "truth_samples": counts.truth_samples,
        "track_samples": counts.track_samples,
        "dimensions": settings.dimensions,
        // null when unlimited (JSON has no infinity)
        "max_gap_s": settings.max_gap_s.is_finite().then_some(settings.max_gap_s),
        "skip_initial_s": settings.skip_initial_s,
        "include_predicted": settings.include_predicted,
        "overall": evaluation.overall,
        "per_tag": per_tag,
        "consistency": evaluation.consistency,
        "consistency_per_tag": evaluation.consistency_per_tag.iter()
            .map(|(tag, c)| TagConsistency { tag, consistency: c })
            .collect::<Vec<_>>(),
        "unmatched": unmatched,
        "unmatched_per_tag": unmatched_per_tag,
    });
    Ok(serde_json::to_string(&value)?)
}
