//! Evaluation of tracks against ground truth: time-aligned position errors and their statistics.
//!
//! The inputs are text handed in by the caller (no file I/O here):
//! - ground truth, CSV with the header `t,tag,x,y,z` ([`parse_truth_csv`]): time in s, tag id,
//!   position in m; `z` empty for 2-D rows (the format the importers write);
//! - a track file, JSON Lines with one object per track update or fix ([`parse_track_line`],
//!   [`parse_track_lines`]): only `t`, `tag`, `x`, `y`, optional `z` and optional `predicted` are
//!   read, every other key is ignored.
//!
//! [`evaluate`] compares every track sample with the ground truth of the same tag at the same
//! time, linearly interpolated between the two truth samples that bracket it, and summarises the
//! errors ([`ErrorStatistics`]) overall and per tag. Track samples that cannot be scored are
//! counted by reason ([`Unmatched`]), never dropped silently.
//!
//! # Units
//! Times in s, positions and errors in m.
//!
//! # Examples
//! ```
//! use rtls_engine::evaluation::{evaluate, parse_track_lines, parse_truth_csv, EvaluationSettings};
//!
//! let truth = parse_truth_csv("t,tag,x,y,z\n0,a,0,0,\n0.5,a,10,0,\n", "truth.csv")?;
//! let tracks = parse_track_lines(
//!     "{\"t\": 0.25, \"tag\": \"a\", \"x\": 5.3, \"y\": 0.4, \"status\": \"confirmed\"}\n",
//!     "tracks.jsonl",
//! )?;
//! let evaluation = evaluate(&truth, &tracks, &EvaluationSettings::default())?;
//! assert_eq!(evaluation.overall.count, 1);
//! assert!((evaluation.overall.rmse_m - 0.5).abs() < 1e-12); // truth (5, 0), track (5.3, 0.4)
//! # Ok::<(), rtls_engine::EngineError>(())
//! ```

mod consistency;
mod evaluate;
mod statistics;
mod track;
mod truth;

pub use evaluate::evaluate;
pub use track::{parse_track_line, parse_track_lines};
pub use truth::parse_truth_csv;

use serde::Serialize;

/// The `file` that [`evaluate`]'s errors name for a ground-truth sample ([`evaluate`] does not
/// know file names; a caller that does can replace it, as `rtls eval` does).
pub const TRUTH_SOURCE: &str = "ground truth";

/// The `file` that [`evaluate`]'s errors name for a track sample (see [`TRUTH_SOURCE`]).
pub const TRACKS_SOURCE: &str = "tracks";

/// One ground-truth position of a tag.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthSample {
    /// Time, s.
    pub time_s: f64,
    /// Tag id.
    pub tag: String,
    /// Position `[x, y, z]`, m; `z` is 0 and meaningless when `has_z` is false.
    pub position_m: [f64; 3],
    /// Whether the row gave a height (`z` not empty).
    pub has_z: bool,
    /// 1-based line of the file the sample was read from (0 when built in code); errors name it.
    pub line: usize,
}

/// One position of a tag from a track file (a track update or a raw fix).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSample {
    /// Time, s.
    pub time_s: f64,
    /// Tag id.
    pub tag: String,
    /// Position `[x, y, z]`, m; `z` is 0 and meaningless when `has_z` is false.
    pub position_m: [f64; 3],
    /// Whether the line gave a height (`z` present).
    pub has_z: bool,
    /// Whether the position is a prediction without a measurement (coasting), not an update.
    pub predicted: bool,
    /// The reported position covariance, m², row-major `D × D` (4 or 9 entries), when the line
    /// gave one (`cov`); [`evaluate`] scores its consistency with the errors ([`Consistency`]).
    pub covariance_m2: Option<Vec<f64>>,
    /// 1-based line of the file the sample was read from (0 when built in code); errors name it.
    pub line: usize,
}

/// How [`evaluate`] matches track samples with ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct EvaluationSettings {
    /// Longest time between the two truth samples that bracket a track sample, s; a track sample
    /// in a longer truth gap is not scored (interpolating across it would invent the truth).
    /// `0` scores only track samples at a truth sample's exact time; `f64::INFINITY` means no
    /// limit.
    pub max_gap_s: f64,
    /// Track samples in each tag's first `skip_initial_s` seconds (from the tag's first track
    /// sample, predicted or not) are not scored: the filter is still converging.
    pub skip_initial_s: f64,
    /// Whether predicted (coasting) samples are scored; when false they are counted as excluded.
    pub include_predicted: bool,
    /// 2: horizontal error `√(Δx² + Δy²)`; 3: `√(Δx² + Δy² + Δz²)`, which needs `z` on every
    /// scored track sample and on the truth samples used for it.
    pub dimensions: usize,
}

impl Default for EvaluationSettings {
    /// 2-D, truth gaps up to 0.5 s, no initial skip, predicted samples excluded.
    fn default() -> Self {
        Self {
            max_gap_s: 0.5,
            skip_initial_s: 0.0,
            include_predicted: false,
            dimensions: 2,
        }
    }
}

/// Summary of a set of position errors, m.
///
/// Percentiles (median = 50th) interpolate linearly between order statistics (Hyndman & Fan's
/// type 7, the default of R and NumPy): for sorted errors `e₀ ≤ … ≤ e₍ₙ₋₁₎` the `p`-th is
/// `e_⌊h⌋ + (h − ⌊h⌋)(e_⌊h⌋₊₁ − e_⌊h⌋)` with `h = (n − 1)·p`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorStatistics {
    /// Number of errors.
    pub count: usize,
    /// Root mean square error, m.
    pub rmse_m: f64,
    /// Mean error, m.
    pub mean_m: f64,
    /// Median error, m.
    pub median_m: f64,
    /// 90th percentile, m.
    pub p90_m: f64,
    /// 95th percentile, m.
    pub p95_m: f64,
    /// Largest error, m.
    pub max_m: f64,
}

/// Whether the reported covariances hold the errors as often as they claim: the normalised
/// estimation error squared (NEES) of the position, `ε = eᵀ P⁻¹ e` with `e` the error and `P`
/// the reported position covariance on the evaluated axes (the top-left 2 × 2 block in 2-D).
///
/// For a consistent estimator `ε ~ χ²(d)`: its mean is `d` (2 or 3) and the reported 95 %
/// ellipse (`ε ≤ χ²_d(0.95)`: 5.991 in 2-D, 7.815 in 3-D) holds the truth 95 % of the time. A
/// larger mean NEES and a smaller coverage mean an overconfident tracker; the reverse, a
/// pessimistic one.
///
/// # References
/// Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
/// 2001, §5.4.2 (NEES).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Consistency {
    /// Scored samples with a covariance (those without one are not counted here).
    pub count: usize,
    /// Degrees of freedom `d` (the evaluated axes).
    pub dimensions: usize,
    /// Mean NEES; `d` when consistent.
    pub mean_nees: f64,
    /// Median NEES; `χ²_d(0.5)` (1.386 in 2-D) when consistent.
    pub median_nees: f64,
    /// Share of samples inside the reported 95 % ellipse (ellipsoid in 3-D), 0–1.
    pub inside_95: f64,
    /// Share inside the reported 68.3 % ellipse (the "1 σ" region of `d` dimensions), 0–1.
    pub inside_68: f64,
    /// Samples whose covariance block was not positive definite (counted apart, not scored).
    pub not_positive_definite: usize,
    /// `k² = ε₉₅ / χ²_d(0.95)`: the factor every reported covariance needs for 95 % of the
    /// truths to fall inside their 95 % ellipse (the 95th percentile of the NEES over its
    /// gate); 1 when consistent, above 1 when overconfident.
    pub covariance_scale_95: f64,
}

/// Track samples that were not scored, by reason. Each sample is counted once, under the first
/// reason in field order that applies.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Unmatched {
    /// Predicted (coasting) samples, excluded because `include_predicted` is false.
    pub predicted_excluded: usize,
    /// Samples in the tag's first `skip_initial_s` seconds.
    pub initial_skipped: usize,
    /// Samples of a tag that has no ground truth.
    pub tag_not_in_truth: usize,
    /// Samples before the tag's first or after its last truth sample.
    pub outside_truth_span: usize,
    /// Samples whose bracketing truth samples are more than `max_gap_s` apart.
    pub truth_gap: usize,
}

impl Unmatched {
    /// All unmatched samples.
    #[must_use]
    pub fn total(&self) -> usize {
        self.predicted_excluded
            + self.initial_skipped
            + self.tag_not_in_truth
            + self.outside_truth_span
            + self.truth_gap
    }
}

/// What [`evaluate`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// All scored samples together.
    pub overall: ErrorStatistics,
    /// Per tag with at least one scored sample, sorted by tag id.
    pub per_tag: Vec<(String, ErrorStatistics)>,
    /// The consistency of the reported covariances over all scored samples that carry one;
    /// `None` when none does.
    pub consistency: Option<Consistency>,
    /// The same per tag, for the tags with at least one scored sample with a covariance.
    pub consistency_per_tag: Vec<(String, Consistency)>,
    /// Samples not scored, by reason (all tags).
    pub unmatched: Unmatched,
    /// The same per tag, for the tags with at least one unmatched sample, sorted by tag id (so a
    /// tag that was never scored is still named).
    pub unmatched_per_tag: Vec<(String, Unmatched)>,
}

#[cfg(test)]
mod parse_tests;
#[cfg(test)]
mod tests;
