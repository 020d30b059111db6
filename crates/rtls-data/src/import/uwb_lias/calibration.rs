//! Range-bias calibration of the LIAS TWR ranges from the STATIC runs only (known poses; the
//! dynamic runs we evaluate on never enter it).
//!
//! # Model
//! Per (anchor, tag) pair `r = (1 + s)·d + b + ε`, with `d` the true 3-D distance from the
//! surveyed pose. The bias is the median of `r − (1 + s)·d` over every static sample of the
//! pair (robust to the occasional multipath outlier), and a corrected range is
//! `r̂ = (r − b) / (1 + s)`.
//!
//! # Is a slope needed?
//! Five static poses give each pair five distances. Three models are compared by
//! leave-one-run-out prediction of the held-out run's median residual `median(r − d)`:
//! bias only (`s = 0`), a slope per pair (least squares through the other runs' medians) and
//! one slope common to all pairs with a bias per pair. A slope model is adopted only when it
//! cuts the leave-one-out RMS by at least [`SLOPE_ADOPTION_GAIN`]; otherwise `s = 0`. The
//! figures go into the import notes.
//!
//! # Residual spread
//! `std_m` of a pair is the sample standard deviation of `r̂ − d` over all its static samples:
//! it holds the pose-to-pose variation of the bias as well as the noise, which is what a filter
//! sees. The per-anchor figure pools the anchor's three tags.

use super::parse::{pair_anchor, pair_tag, StaticPose, UwbRow};
use super::{distance_m, tag_position_m, ANCHORS, PAIRS};
use crate::import::util::{mean_std, median, rms};

/// Fraction by which a slope model must cut the leave-one-run-out RMS to be adopted (10 %).
pub(super) const SLOPE_ADOPTION_GAIN: f64 = 0.10;

/// One static run: its surveyed pose and its UWB rows.
#[derive(Debug, Clone)]
pub(super) struct StaticRun {
    /// The pose.
    pub pose: StaticPose,
    /// The ranges.
    pub rows: Vec<UwbRow>,
}

impl StaticRun {
    /// True 3-D distance of `pair` at this run's pose, m.
    fn distance_m(&self, pair: usize) -> f64 {
        let [x, y] = self.pose.centroid_m;
        let tag = tag_position_m([x, y, super::RIGID_BODY_HEIGHT_M], self.pose.yaw_rad, pair_tag(pair));
        distance_m(tag, ANCHORS[pair_anchor(pair)].1)
    }

    /// The pair's ranges in this run, m (empty cells and zero ranges are not ranges).
    fn ranges_m(&self, pair: usize) -> impl Iterator<Item = f64> + '_ {
        self.rows
            .iter()
            .filter_map(move |row| row.ranges_m[pair])
            .filter(|&r| r > 0.0)
    }
}

/// The calibration of one (anchor, tag) pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PairCalibration {
    /// Additive bias `b`, m.
    pub bias_m: f64,
    /// Scale error `s` (dimensionless; 0 when no slope model was adopted).
    pub slope: f64,
    /// Standard deviation of the corrected range minus the true distance on the static runs, m.
    pub std_m: f64,
    /// Static samples used.
    pub samples: usize,
}

impl PairCalibration {
    /// The corrected range `(r − b) / (1 + s)`, m.
    pub(super) fn correct(&self, range_m: f64) -> f64 {
        (range_m - self.bias_m) / (1.0 + self.slope)
    }
}

/// Which slope model the leave-one-out test chose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum SlopeModel {
    /// `s = 0` for every pair.
    BiasOnly,
    /// A least-squares slope per pair.
    PerPair,
    /// One slope for all pairs.
    Common(f64),
}

/// Leave-one-run-out RMS prediction error of a run's median residual, m, per model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SlopeTest {
    /// Bias only.
    pub bias_only_m: f64,
    /// A slope per pair.
    pub per_pair_m: f64,
    /// One common slope.
    pub common_m: f64,
    /// The common slope fitted on all runs.
    pub common_slope: f64,
    /// Mean and standard deviation of the 24 per-pair slopes fitted on all runs.
    pub per_pair_slopes_mean_std: (f64, f64),
    /// The model adopted.
    pub adopted: SlopeModel,
}

/// The calibration table and its statistics.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Calibration {
    /// One entry per pair, anchor-major (`a0-t0, a0-t1, …`).
    pub pairs: Vec<PairCalibration>,
    /// Post-calibration residual standard deviation per anchor (three tags pooled), m.
    pub anchor_std_m: Vec<f64>,
    /// Pooled residual standard deviation before calibration (raw `r − d`), m.
    pub raw_std_m: f64,
    /// Median raw residual `r − d` over all static samples, m.
    pub raw_median_m: f64,
    /// The slope test.
    pub slope_test: SlopeTest,
}

/// Least-squares line `y = s·x + b`; `None` for fewer than 2 points or constant `x`.
fn fit_line(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = x.len() as f64;
    if x.len() < 2 || x.len() != y.len() {
        return None;
    }
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    // s = Σ(x−x̄)(y−ȳ) / Σ(x−x̄)²
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    (sxx > 0.0).then(|| (sxy / sxx, my - sxy / sxx * mx))
}

/// One pair's data: per static run the true distance, the residuals `r − d` and their median.
struct PairRuns {
    distance_m: Vec<f64>,
    residuals_m: Vec<Vec<f64>>,
    median_residual_m: Vec<f64>,
}

/// `None` when a run has no range of the pair.
fn pair_runs(runs: &[StaticRun], pair: usize) -> Option<PairRuns> {
    let mut out = PairRuns {
        distance_m: Vec::new(),
        residuals_m: Vec::new(),
        median_residual_m: Vec::new(),
    };
    for run in runs {
        let d = run.distance_m(pair);
        let residuals: Vec<f64> = run.ranges_m(pair).map(|r| r - d).collect();
        out.median_residual_m.push(median(&residuals)?);
        out.distance_m.push(d);
        out.residuals_m.push(residuals);
    }
    Some(out)
}

impl PairRuns {
    /// Median of `r − (1 + s)·d = (r − d) − s·d` over the samples of `runs`.
    fn bias(&self, runs: &[usize], slope: f64) -> Option<f64> {
        let values: Vec<f64> = runs
            .iter()
            .flat_map(|&i| self.residuals_m[i].iter().map(move |e| e - slope * self.distance_m[i]))
            .collect();
        median(&values)
    }

    /// Least-squares slope and intercept of the median residuals of `runs` against distance.
    fn line(&self, runs: &[usize]) -> Option<(f64, f64)> {
        let x: Vec<f64> = runs.iter().map(|&i| self.distance_m[i]).collect();
        let y: Vec<f64> = runs.iter().map(|&i| self.median_residual_m[i]).collect();
        fit_line(&x, &y)
    }
}

/// The common slope of the pairs' median residuals against distance (within-pair least
/// squares: each pair keeps its own intercept), over `runs`.
fn common_slope(stats: &[PairRuns], runs: &[usize]) -> Option<f64> {
    let (mut sxy, mut sxx) = (0.0, 0.0);
    let n = runs.len() as f64;
    for pair in stats {
        let mx = runs.iter().map(|&i| pair.distance_m[i]).sum::<f64>() / n;
        let my = runs.iter().map(|&i| pair.median_residual_m[i]).sum::<f64>() / n;
        for &i in runs {
            sxy += (pair.distance_m[i] - mx) * (pair.median_residual_m[i] - my);
            sxx += (pair.distance_m[i] - mx).powi(2);
        }
    }
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Leave-one-run-out comparison of the three models (see the module docs).
fn slope_test(stats: &[PairRuns], runs: usize) -> Option<SlopeTest> {
    let (mut bias_errors, mut pair_errors, mut common_errors) = (Vec::new(), Vec::new(), Vec::new());
    for held in 0..runs {
        let kept: Vec<usize> = (0..runs).filter(|&i| i != held).collect();
        let s_common = common_slope(stats, &kept)?;
        for pair in stats {
            let (d, observed) = (pair.distance_m[held], pair.median_residual_m[held]);
            bias_errors.push(observed - pair.bias(&kept, 0.0)?);
            let (s, b_line) = pair.line(&kept)?;
            pair_errors.push(observed - (s * d + b_line));
            common_errors.push(observed - (s_common * d + pair.bias(&kept, s_common)?));
        }
    }
    let all: Vec<usize> = (0..runs).collect();
    let slopes: Vec<f64> = stats.iter().filter_map(|p| p.line(&all).map(|(s, _)| s)).collect();
    let (bias_only_m, per_pair_m, common_m) = (rms(&bias_errors)?, rms(&pair_errors)?, rms(&common_errors)?);
    let common = common_slope(stats, &all)?;
    let adopted = if per_pair_m.min(common_m) > (1.0 - SLOPE_ADOPTION_GAIN) * bias_only_m {
        SlopeModel::BiasOnly
    } else if per_pair_m < common_m {
        SlopeModel::PerPair
    } else {
        SlopeModel::Common(common)
    };
    Some(SlopeTest {
        bias_only_m,
        per_pair_m,
        common_m,
        common_slope: common,
        per_pair_slopes_mean_std: mean_std(&slopes)?,
        adopted,
    })
}

/// Calibrates every pair from the static runs. `None` when the runs hold too little data (fewer
/// than three runs, so that a leave-one-out line still has two points, or a pair without
/// ranges in some run).
pub(super) fn calibrate(runs: &[StaticRun]) -> Option<Calibration> {
    if runs.len() < 3 {
        return None;
    }
    let stats: Vec<PairRuns> = (0..PAIRS).map(|pair| pair_runs(runs, pair)).collect::<Option<_>>()?;
    let test = slope_test(&stats, runs.len())?;
    let all: Vec<usize> = (0..runs.len()).collect();
    let mut pairs = Vec::with_capacity(PAIRS);
    let mut per_anchor: Vec<Vec<f64>> = vec![Vec::new(); ANCHORS.len()];
    let mut raw = Vec::new();
    for (pair, pair_stats) in stats.iter().enumerate() {
        let slope = match test.adopted {
            SlopeModel::BiasOnly => 0.0,
            SlopeModel::PerPair => pair_stats.line(&all)?.0,
            SlopeModel::Common(s) => s,
        };
        let mut calibration = PairCalibration {
            bias_m: pair_stats.bias(&all, slope)?,
            slope,
            std_m: 0.0,
            samples: 0,
        };
        let mut residuals = Vec::new();
        for (d, errors) in pair_stats.distance_m.iter().zip(&pair_stats.residuals_m) {
            raw.extend_from_slice(errors);
            // corrected − d, with r = (r − d) + d
            residuals.extend(errors.iter().map(|e| calibration.correct(e + d) - d));
        }
        calibration.std_m = mean_std(&residuals)?.1;
        calibration.samples = residuals.len();
        per_anchor[pair_anchor(pair)].extend_from_slice(&residuals);
        pairs.push(calibration);
    }
    let anchor_std_m = per_anchor
        .iter()
        .map(|r| mean_std(r).map(|(_, s)| s))
        .collect::<Option<Vec<f64>>>()?;
    Some(Calibration {
        pairs,
        anchor_std_m,
        raw_std_m: mean_std(&raw)?.1,
        raw_median_m: median(&raw)?,
        slope_test: test,
    })
}

impl Calibration {
    /// The table as CSV: `anchor,tag,bias_m,slope,std_m,samples`, anchor-major.
    pub(super) fn to_csv(&self) -> String {
        let mut text = String::from("anchor,tag,bias_m,slope,std_m,samples\n");
        for (pair, c) in self.pairs.iter().enumerate() {
            text.push_str(&format!(
                "{},{},{},{},{},{}\n",
                ANCHORS[pair_anchor(pair)].0,
                super::TAGS[pair_tag(pair)].0,
                c.bias_m,
                c.slope,
                c.std_m,
                c.samples
            ));
        }
        text
    }

    /// Human-readable notes: the model, the slope test, the spreads.
    pub(super) fn notes(&self) -> Vec<String> {
        let t = &self.slope_test;
        let adopted = match t.adopted {
            SlopeModel::BiasOnly => "bias only (slope 0)".to_string(),
            SlopeModel::PerPair => "a slope per pair".to_string(),
            SlopeModel::Common(s) => format!("one common slope {s:.4}"),
        };
        let biases: Vec<f64> = self.pairs.iter().map(|p| p.bias_m).collect();
        let (bias_mean, bias_std) = mean_std(&biases).unwrap_or_default();
        let min = biases.iter().copied().fold(f64::INFINITY, f64::min);
        let max = biases.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        vec![
            format!(
                "range-bias calibration from the 5 static runs only (surveyed poses, Static/README.md): per (anchor, tag) \
                 r = (1 + s)·d + b, b = median over {} static ranges per pair; corrected range = (r − b)/(1 + s); \
                 table in calibration.csv",
                self.pairs.first().map_or(0, |p| p.samples)
            ),
            format!(
                "static raw residual r − d: median {:+.3} m, std {:.3} m; biases b: mean {bias_mean:.3} m, spread (std) \
                 {bias_std:.3} m, range {min:.3}..{max:.3} m",
                self.raw_median_m, self.raw_std_m
            ),
            format!(
                "slope test (leave-one-static-run-out RMS error of a run's median residual): bias only {:.4} m, slope per \
                 pair {:.4} m, common slope {:.4} m (s = {:.4}; per-pair slopes {:.4} ± {:.4}); a slope model must cut the \
                 RMS by ≥ {:.0} % to be adopted → adopted: {adopted}",
                t.bias_only_m,
                t.per_pair_m,
                t.common_m,
                t.common_slope,
                t.per_pair_slopes_mean_std.0,
                t.per_pair_slopes_mean_std.1,
                SLOPE_ADOPTION_GAIN * 100.0
            ),
            format!(
                "post-calibration residual std per anchor (static runs, 3 tags pooled; the readers' range_std_m): {}",
                self.anchor_std_m
                    .iter()
                    .enumerate()
                    .map(|(a, s)| format!("{} {s:.3} m", ANCHORS[a].0))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ]
    }
}
