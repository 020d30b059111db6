//! Time alignment of track samples with ground truth, and the error summary.

use std::collections::BTreeMap;

use super::consistency::nees;
use super::truth::check_same_time_same_position;
use super::{
    Consistency, ErrorStatistics, Evaluation, EvaluationSettings, TrackSample, TruthSample, Unmatched, TRACKS_SOURCE,
    TRUTH_SOURCE,
};
use crate::error::{EngineError, Result};

/// Why a track sample was not scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reason {
    PredictedExcluded,
    InitialSkipped,
    TagNotInTruth,
    OutsideTruthSpan,
    TruthGap,
}

impl Unmatched {
    fn count(&mut self, reason: Reason) {
        let counter = match reason {
            Reason::PredictedExcluded => &mut self.predicted_excluded,
            Reason::InitialSkipped => &mut self.initial_skipped,
            Reason::TagNotInTruth => &mut self.tag_not_in_truth,
            Reason::OutsideTruthSpan => &mut self.outside_truth_span,
            Reason::TruthGap => &mut self.truth_gap,
        };
        *counter += 1;
    }
}

/// The truth at a track sample's time: `lower` alone when the time is a truth sample's time,
/// else `lower + weight·(upper − lower)`.
struct Bracket<'a> {
    lower: &'a TruthSample,
    upper: Option<(&'a TruthSample, f64)>,
}

/// Finds the truth samples around `time_s` in one tag's time-sorted truth.
fn bracket<'a>(truth: &[&'a TruthSample], time_s: f64, max_gap_s: f64) -> core::result::Result<Bracket<'a>, Reason> {
    // Number of samples at or before time_s.
    let at_or_before = truth.partition_point(|s| s.time_s <= time_s);
    let Some(&lower) = at_or_before.checked_sub(1).and_then(|i| truth.get(i)) else {
        return Err(Reason::OutsideTruthSpan);
    };
    if lower.time_s == time_s {
        return Ok(Bracket { lower, upper: None });
    }
    let Some(&upper) = truth.get(at_or_before) else {
        return Err(Reason::OutsideTruthSpan);
    };
    let gap_s = upper.time_s - lower.time_s;
    if gap_s > max_gap_s {
        return Err(Reason::TruthGap);
    }
    // w = (t − t₀) / (t₁ − t₀), in (0, 1)
    let weight = (time_s - lower.time_s) / gap_s;
    Ok(Bracket {
        lower,
        upper: Some((upper, weight)),
    })
}

/// The error naming a sample's line and field in [`evaluate`] (whose callers know the file).
fn sample_error(file: &str, line: usize, field: &str, reason: String) -> EngineError {
    EngineError::Parse {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    }
}

/// The error vector of a track sample against the truth at its time (the first `dimensions`
/// axes; the others 0), m.
fn position_error(sample: &TrackSample, truth: &Bracket<'_>, dimensions: usize) -> Result<[f64; 3]> {
    if dimensions == 3 {
        let need_z = |line: usize| {
            sample_error(
                TRUTH_SOURCE,
                line,
                "z",
                format!(
                    "is empty but a 3-D evaluation needs it to score tag `{}` at t = {} s ({TRACKS_SOURCE} line {}); \
                     evaluate in 2-D for the horizontal error",
                    sample.tag, sample.time_s, sample.line
                ),
            )
        };
        if !sample.has_z {
            return Err(sample_error(
                TRACKS_SOURCE,
                sample.line,
                "z",
                format!(
                    "is missing for tag `{}` at t = {} s; a 3-D evaluation needs z on every scored track sample \
                     (evaluate in 2-D for the horizontal error)",
                    sample.tag, sample.time_s
                ),
            ));
        }
        if !truth.lower.has_z {
            return Err(need_z(truth.lower.line));
        }
        if let Some((upper, _)) = truth.upper {
            if !upper.has_z {
                return Err(need_z(upper.line));
            }
        }
    }
    let mut error_m = [0.0; 3];
    for (axis, error) in error_m.iter_mut().enumerate().take(dimensions) {
        let lower = truth.lower.position_m[axis];
        // p = p₀ + w·(p₁ − p₀)
        let true_m = match truth.upper {
            Some((upper, weight)) => lower + weight * (upper.position_m[axis] - lower),
            None => lower,
        };
        *error = sample.position_m[axis] - true_m;
    }
    Ok(error_m)
}

/// The NEES values of one tag's scored samples with a covariance, and how many covariances
/// could not be used.
#[derive(Default)]
struct NeesValues {
    values: Vec<f64>,
    not_positive_definite: usize,
}

fn check_settings(settings: &EvaluationSettings) -> Result<()> {
    if settings.dimensions != 2 && settings.dimensions != 3 {
        return Err(EngineError::InvalidParameter {
            name: "dimensions",
            reason: "must be 2 (horizontal error) or 3",
        });
    }
    if settings.max_gap_s.is_nan() || settings.max_gap_s < 0.0 {
        return Err(EngineError::InvalidParameter {
            name: "max_gap_s",
            reason: "must be at least 0 s (infinity for no limit)",
        });
    }
    if !(settings.skip_initial_s.is_finite() && settings.skip_initial_s >= 0.0) {
        return Err(EngineError::InvalidParameter {
            name: "skip_initial_s",
            reason: "must be a finite number of seconds, at least 0",
        });
    }
    Ok(())
}

/// The first coordinate of a position that is not finite (`z` only when present).
fn non_finite_field(time_s: f64, position_m: &[f64; 3], has_z: bool) -> Option<&'static str> {
    let axes = if has_z { 3 } else { 2 };
    if !time_s.is_finite() {
        return Some("t");
    }
    ["x", "y", "z"][..axes]
        .iter()
        .zip(position_m)
        .find(|(_, value)| !value.is_finite())
        .map(|(name, _)| *name)
}

/// Scores every track sample against the ground truth of its tag at its time.
///
/// For each track sample, in this order: a predicted sample is excluded unless
/// `include_predicted`; a sample within `skip_initial_s` of its tag's first track sample is
/// skipped; a tag without truth, a time before the tag's first or after its last truth sample,
/// and a time between two truth samples more than `max_gap_s` apart are counted as unmatched.
/// Otherwise the truth is interpolated linearly between the two bracketing truth samples (or
/// taken as is at a truth sample's exact time) and the error is the 2-D or 3-D distance.
/// Truth need not be sorted. The counts satisfy
/// `overall.count + unmatched.total() == tracks.len()`.
///
/// # Errors
/// - [`EngineError::InvalidParameter`] for `dimensions` other than 2 or 3, a negative or NaN
///   `max_gap_s`, a negative or non-finite `skip_initial_s`.
/// - [`EngineError::Parse`] with `file` [`TRUTH_SOURCE`] or [`TRACKS_SOURCE`] and the sample's
///   line: a non-finite time or coordinate; two truth samples of a tag at the same time with
///   different positions; in 3-D, a scored track sample without `z`, or a truth sample used to
///   score one without `z`; and (`file` [`TRACKS_SOURCE`], line 0) no sample scored at all, with
///   the counts of why.
///
/// # Examples
/// ```
/// use rtls_engine::evaluation::{evaluate, EvaluationSettings, TrackSample, TruthSample};
///
/// let truth = |time_s: f64, x: f64| TruthSample { time_s, tag: "a".into(), position_m: [x, 0.0, 0.0], has_z: false, line: 0 };
/// let track = |time_s: f64, x: f64, y: f64| TrackSample {
///     time_s, tag: "a".into(), position_m: [x, y, 0.0], has_z: false, predicted: false, covariance_m2: None, line: 0,
/// };
/// let evaluation = evaluate(
///     &[truth(0.0, 0.0), truth(0.4, 4.0), truth(2.0, 4.0)],
///     &[track(0.1, 1.3, 0.4), track(1.0, 4.0, 0.0)],
///     &EvaluationSettings::default(),
/// )?;
/// assert_eq!(evaluation.overall.count, 1); // truth at 0.1 s: (1, 0); error |(0.3, 0.4)| = 0.5 m
/// assert!((evaluation.overall.max_m - 0.5).abs() < 1e-12);
/// assert_eq!(evaluation.unmatched.truth_gap, 1); // 1.0 s lies in a 1.6 s truth gap
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
pub fn evaluate(truth: &[TruthSample], tracks: &[TrackSample], settings: &EvaluationSettings) -> Result<Evaluation> {
    check_settings(settings)?;
    for sample in truth {
        if let Some(field) = non_finite_field(sample.time_s, &sample.position_m, sample.has_z) {
            return Err(sample_error(
                TRUTH_SOURCE,
                sample.line,
                field,
                "is not a finite number".into(),
            ));
        }
    }
    for sample in tracks {
        if let Some(field) = non_finite_field(sample.time_s, &sample.position_m, sample.has_z) {
            return Err(sample_error(
                TRACKS_SOURCE,
                sample.line,
                field,
                "is not a finite number".into(),
            ));
        }
    }
    check_same_time_same_position(truth, TRUTH_SOURCE)?;

    let mut truth_by_tag: BTreeMap<&str, Vec<&TruthSample>> = BTreeMap::new();
    for sample in truth {
        truth_by_tag.entry(&sample.tag).or_default().push(sample);
    }
    for samples in truth_by_tag.values_mut() {
        samples.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    }
    let mut first_track_s: BTreeMap<&str, f64> = BTreeMap::new();
    for sample in tracks {
        let first = first_track_s.entry(&sample.tag).or_insert(sample.time_s);
        *first = first.min(sample.time_s);
    }

    let mut errors_by_tag: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    let mut nees_by_tag: BTreeMap<&str, NeesValues> = BTreeMap::new();
    let mut unmatched = Unmatched::default();
    let mut unmatched_by_tag: BTreeMap<&str, Unmatched> = BTreeMap::new();
    for sample in tracks {
        let first_s = first_track_s.get(sample.tag.as_str()).copied().unwrap_or(sample.time_s);
        let matched = if sample.predicted && !settings.include_predicted {
            Err(Reason::PredictedExcluded)
        } else if sample.time_s < first_s + settings.skip_initial_s {
            Err(Reason::InitialSkipped)
        } else {
            match truth_by_tag.get(sample.tag.as_str()) {
                None => Err(Reason::TagNotInTruth),
                Some(tag_truth) => bracket(tag_truth, sample.time_s, settings.max_gap_s),
            }
        };
        match matched {
            Ok(bracket) => {
                let error_m = position_error(sample, &bracket, settings.dimensions)?;
                // |e| = √(Σ eᵢ²)
                let distance_m = error_m.iter().map(|e| e * e).sum::<f64>().sqrt();
                errors_by_tag.entry(&sample.tag).or_default().push(distance_m);
                if let Some(covariance_m2) = &sample.covariance_m2 {
                    let entry = nees_by_tag.entry(&sample.tag).or_default();
                    match nees(&error_m, covariance_m2, settings.dimensions) {
                        Some(value) => entry.values.push(value),
                        None => entry.not_positive_definite += 1,
                    }
                }
            }
            Err(reason) => {
                unmatched.count(reason);
                unmatched_by_tag.entry(&sample.tag).or_default().count(reason);
            }
        }
    }

    let all_errors: Vec<f64> = errors_by_tag.values().flatten().copied().collect();
    if all_errors.is_empty() {
        return Err(sample_error(
            TRACKS_SOURCE,
            0,
            "-",
            format!(
                "no track sample could be scored against the ground truth: of {} samples, {} predicted \
                 (excluded), {} in a track's first {} s (skipped), {} of tags without truth, {} outside the \
                 truth's time span, {} in truth gaps longer than {} s",
                tracks.len(),
                unmatched.predicted_excluded,
                unmatched.initial_skipped,
                settings.skip_initial_s,
                unmatched.tag_not_in_truth,
                unmatched.outside_truth_span,
                unmatched.truth_gap,
                settings.max_gap_s
            ),
        ));
    }
    let overall = ErrorStatistics::from_errors(&all_errors)?;
    let per_tag = errors_by_tag
        .into_iter()
        .map(|(tag, errors)| Ok((tag.to_string(), ErrorStatistics::from_errors(&errors)?)))
        .collect::<Result<Vec<_>>>()?;
    let all_nees: Vec<f64> = nees_by_tag.values().flat_map(|n| n.values.iter().copied()).collect();
    let not_positive_definite = nees_by_tag.values().map(|n| n.not_positive_definite).sum();
    let consistency = Consistency::from_nees(&all_nees, settings.dimensions, not_positive_definite)?;
    let mut consistency_per_tag = Vec::new();
    for (tag, values) in nees_by_tag {
        if let Some(summary) =
            Consistency::from_nees(&values.values, settings.dimensions, values.not_positive_definite)?
        {
            consistency_per_tag.push((tag.to_string(), summary));
        }
    }
    Ok(Evaluation {
        overall,
        per_tag,
        consistency,
        consistency_per_tag,
        unmatched,
        unmatched_per_tag: unmatched_by_tag
            .into_iter()
            .map(|(tag, counts)| (tag.to_string(), counts))
            .collect(),
    })
}
