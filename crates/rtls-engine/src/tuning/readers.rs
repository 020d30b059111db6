//! Reader calibration against ground truth: range bias and noise, log-distance path loss.

use std::collections::BTreeMap;

use super::truth_by_tag;
use crate::evaluation::TruthSample;
use crate::record::{Measurement, Record};
use crate::site::{PathLoss, Radio, RangeErrors, Site};

/// Fewer residuals than this leave a reader as it was.
const MIN_SAMPLES: usize = 30;

/// A range scale is fitted only when the truth distances of a reader's ranges have at least
/// this standard deviation, m (over a narrow spread of distances a scale is a bias).
pub const MIN_SCALE_SPREAD_M: f64 = 1.0;

/// Ranges further than this many robust σ from the median of `r − d` are left out of the
/// scale's line fit.
const SCALE_FIT_OUTLIER_SIGMAS: f64 = 5.0;

/// The scale bounds the site accepts.
const SCALE_RANGE: (f64, f64) = (0.5, 2.0);

/// Distances below this are clamped in the path-loss fit (the law is a far-field one), m.
const MIN_FIT_DISTANCE_M: f64 = 0.5;

/// The spread of one site's links' path-loss exponents about the site's law: the prior a
/// refitted exponent is shrunk toward ([`shrunk_exponent`]). An assumption: across sites,
/// in-building exponents run from 1.6–1.8 in line of sight to 4–6 obstructed (Rappaport,
/// Table 4.2); one site's links differ from its law by less, taken as about ±1 (2σ).
const EXPONENT_PRIOR_STD: f64 = 0.5;

/// Path-loss exponents outside this interval are not physical for a site; the fit is clamped.
const EXPONENT_RANGE: (f64, f64) = (1.0, 6.0);

/// A reader's range errors fitted against truth: `r = d + bias + N(0, std²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeFit {
    /// `b` of `r = s d + b`, m (`median(r − d)` when no scale is fitted).
    pub bias_m: f64,
    /// `1.4826 · MAD(r − s d − b)`, m (at least 1 mm).
    pub range_std_m: f64,
    /// `s` of `r = s d + b` (1 unless the distances have a standard deviation of at least
    /// 1 m, enough to tell a scale from a bias, and it differs from 1 by more than 3 standard
    /// errors).
    pub scale: f64,
    /// The standard deviation of the offset that remains after `bias_m` (and `scale`), m: how
    /// much the mean residual moves between contiguous blocks of the recording beyond what the
    /// noise explains, with the bias's own standard error (at least 1 cm); `None` for fewer
    /// than 200 ranges (10 blocks of 20), too few to tell (the site's prior then stays). Written as the reader's `offset_std_m`: the prior of
    /// the offset a track learns.
    pub offset_std_m: Option<f64>,
    /// Residuals used.
    pub samples: usize,
}

/// The least offset standard deviation `rtls tune` writes, m: a calibrated delay is known to
/// about a centimetre (a tag's antenna turning changes it by that much).
pub const MIN_OFFSET_STD_M: f64 = 0.01;

/// The contiguous blocks of a reader's ranges whose means estimate the spread of its offset
/// (the spread's estimate has `B − 1` degrees of freedom: with three blocks, as a minute of
/// calibration walk gives, it is off by a factor of two one time in four).
pub const OFFSET_BLOCKS: usize = 10;

/// The least ranges a block holds.
pub const OFFSET_BLOCK_SAMPLES: usize = 20;

/// Contiguous blocks of a reader's RSSI samples (in record order) for the path-loss
/// cross-validation; contiguous because shadowing persists along a walk, so interleaved folds
/// would hold out samples their neighbours already told the fit.
const PATH_LOSS_FOLDS: usize = 5;

/// A reader's log-distance law fitted against truth: `ρ = ρ₀ − 10 n log₁₀(d / 1 m) + N(0, σ²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathLossFit {
    /// `ρ₀` at 1 m, dBm.
    pub reference_power_dbm: f64,
    /// `n` (clamped to 1–6).
    pub exponent: f64,
    /// Residual standard deviation, dB (at least 0.1).
    pub shadowing_std_db: f64,
    /// Samples used.
    pub samples: usize,
    /// Which law the cross-validation chose.
    pub choice: PathLossChoice,
    /// Its root-mean-square error on held-out blocks, dB.
    pub held_out_rms_db: f64,
}

/// The laws `rtls tune` weighs for a reader's RSSI, from fewest to most fitted parameters. A
/// calibration walk of a minute or two spans a narrow range of distances, over which the
/// exponent is barely determined: refitting it can make a law that explains the walk and
/// fails the next one. The simplest law whose error on held-out blocks of the samples
/// (5-fold, contiguous blocks) is within one standard error of the smallest is
/// chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathLossChoice {
    /// The site's law as it was (0 parameters fitted).
    Kept,
    /// The site's exponent (2, free space, when the site has no law) with `ρ₀` refitted.
    Offset,
    /// `ρ₀` and `n` both refitted (`n` the least-squares exponent shrunk toward the site's by
    /// how well the samples determine it, then clamped to 1–6).
    Refitted,
}

impl PathLossChoice {
    /// Its name in `rtls tune`'s report: `kept`, `offset`, `refitted`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Kept => "kept",
            Self::Offset => "offset",
            Self::Refitted => "refitted",
        }
    }
}

/// What the truth says about one reader.
#[derive(Debug, Clone, PartialEq)]
pub struct ReaderCalibration {
    /// Reader id.
    pub reader: String,
    /// Range fit, when the reader gave at least 30 ranges with truth.
    pub range: Option<RangeFit>,
    /// Path-loss fit, when it gave at least 30 RSSI samples with truth.
    pub path_loss: Option<PathLossFit>,
}

/// The true position of `tag` at `time_s`, linearly interpolated between the bracketing truth
/// samples no more than `max_gap_s` apart; `z` is the truth's or `tag_height_m`.
fn truth_at(truth: &[&TruthSample], time_s: f64, max_gap_s: f64, tag_height_m: f64) -> Option<[f64; 3]> {
    let after = truth.partition_point(|s| s.time_s <= time_s);
    let lower = truth.get(after.checked_sub(1)?)?;
    let z = |s: &TruthSample| if s.has_z { s.position_m[2] } else { tag_height_m };
    if lower.time_s == time_s {
        return Some([lower.position_m[0], lower.position_m[1], z(lower)]);
    }
    let upper = truth.get(after)?;
    if upper.time_s - lower.time_s > max_gap_s {
        return None;
    }
    // p = p₀ + w (p₁ − p₀), w = (t − t₀) / (t₁ − t₀)
    let w = (time_s - lower.time_s) / (upper.time_s - lower.time_s);
    let lerp = |a: f64, b: f64| a + w * (b - a);
    Some([
        lerp(lower.position_m[0], upper.position_m[0]),
        lerp(lower.position_m[1], upper.position_m[1]),
        lerp(z(lower), z(upper)),
    ])
}

/// The median of `values` (not empty), reordering them.
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// `1.4826 · MAD` of `values` about `centre` (consistent for Gaussian errors), at least 1 mm.
fn robust_std(values: impl Iterator<Item = f64>, centre: f64) -> f64 {
    let mut deviations: Vec<f64> = values.map(|v| (v - centre).abs()).collect();
    (1.4826 * median(&mut deviations)).max(1e-3)
}

/// Range bias, scale and robust noise from `(d, r)` pairs: true slant distance and measured
/// range. `b₀ = median(r − d)`, `σ₀ = 1.4826 · MAD`; then, if the distances spread at least
/// [`MIN_SCALE_SPREAD_M`], least squares `r = s d + b` over the ranges within
/// [`SCALE_FIT_OUTLIER_SIGMAS`] `σ₀` of `b₀`, kept when `|s − 1| > 3 se(s)` (else `s = 1`,
/// `b = b₀`); `σ = 1.4826 · MAD(r − s d − b)`.
fn fit_range(samples: &[(f64, f64)]) -> RangeFit {
    let mut residuals: Vec<f64> = samples.iter().map(|(d, r)| r - d).collect();
    let bias_0 = median(&mut residuals);
    let std_0 = robust_std(samples.iter().map(|(d, r)| r - d), bias_0);
    let inliers: Vec<(f64, f64)> = samples
        .iter()
        .copied()
        .filter(|(d, r)| (r - d - bias_0).abs() <= SCALE_FIT_OUTLIER_SIGMAS * std_0)
        .collect();
    let (bias_m, scale) = line_fit(&inliers).unwrap_or((bias_0, 1.0));
    let range_std_m = robust_std(samples.iter().map(|(d, r)| r - scale * d), bias_m);
    let residuals: Vec<f64> = samples
        .iter()
        .map(|(d, r)| r - scale * d - bias_m)
        .filter(|e| e.abs() <= SCALE_FIT_OUTLIER_SIGMAS * std_0)
        .collect();
    RangeFit {
        bias_m,
        range_std_m,
        scale,
        offset_std_m: offset_spread(&residuals),
        samples: samples.len(),
    }
}

/// The standard deviation of the offset left in `residuals` (`e = r − s d − b`, record order):
/// split into `B` contiguous blocks of `nⱼ` residuals with means `ēⱼ`,
///
/// ```text
/// σ_o² = max(0, var(ēⱼ) − mean(σ̂²/nⱼ)) + σ̂²/n,   σ̂² = var(e)
/// ```
///
/// the spread of the block means beyond white noise (an offset that moves with position,
/// NLOS or temperature; noise correlated over less than a block counts as white) plus the
/// squared standard error of `b`; at least [`MIN_OFFSET_STD_M`]. `None` for fewer than
/// `B` × [`OFFSET_BLOCK_SAMPLES`] residuals, `B` = [`OFFSET_BLOCKS`].
fn offset_spread(residuals: &[f64]) -> Option<f64> {
    let n = residuals.len();
    let blocks = OFFSET_BLOCKS;
    if n < blocks * OFFSET_BLOCK_SAMPLES {
        return None;
    }
    let mean = |values: &[f64]| values.iter().sum::<f64>() / values.len() as f64;
    let total_mean = mean(residuals);
    // σ̂² = Σ (e − ē)² / (n − 1)
    let variance = residuals.iter().map(|e| (e - total_mean).powi(2)).sum::<f64>() / (n as f64 - 1.0).max(1.0);
    let (block_means, noise_parts): (Vec<f64>, Vec<f64>) = (0..blocks)
        .map(|j| {
            let block = &residuals[j * n / blocks..(j + 1) * n / blocks];
            (mean(block), variance / block.len() as f64)
        })
        .unzip();
    let centre = mean(&block_means);
    // var(ēⱼ) over the blocks, and what white noise alone would give it
    let between = block_means.iter().map(|m| (m - centre).powi(2)).sum::<f64>() / (blocks as f64 - 1.0);
    let white = mean(&noise_parts);
    let offset_variance = (between - white).max(0.0) + variance / n as f64;
    Some(offset_variance.sqrt().max(MIN_OFFSET_STD_M))
}

/// `(b, s)` of least squares `r = s d + b`, when the distances spread enough and `s` differs
/// from 1 by more than three standard errors and lies in the site's bounds.
fn line_fit(samples: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = samples.len() as f64;
    if samples.len() < MIN_SAMPLES {
        return None;
    }
    let mean_d = samples.iter().map(|s| s.0).sum::<f64>() / n;
    let mean_r = samples.iter().map(|s| s.1).sum::<f64>() / n;
    // S_dd = Σ (d − d̄)², S_dr = Σ (d − d̄)(r − r̄)
    let s_dd: f64 = samples.iter().map(|s| (s.0 - mean_d).powi(2)).sum();
    let s_dr: f64 = samples.iter().map(|s| (s.0 - mean_d) * (s.1 - mean_r)).sum();
    if s_dd / n < MIN_SCALE_SPREAD_M * MIN_SCALE_SPREAD_M {
        return None;
    }
    // s = S_dr / S_dd, b = r̄ − s d̄
    let scale = s_dr / s_dd;
    let bias = mean_r - scale * mean_d;
    // se(s) = √(Σ e² / (n − 2) / S_dd)
    let residual_variance = samples.iter().map(|s| (s.1 - scale * s.0 - bias).powi(2)).sum::<f64>() / (n - 2.0);
    let standard_error = (residual_variance / s_dd).sqrt();
    let significant = (scale - 1.0).abs() > 3.0 * standard_error;
    let bounded = (SCALE_RANGE.0..=SCALE_RANGE.1).contains(&scale);
    (significant && bounded && bias.is_finite()).then_some((bias, scale))
}

/// `(ρ₀, n)` of a law `ρ = ρ₀ − 10 n x`, `x = log₁₀ d`, fitted to `(x, ρ)` samples as
/// `choice` says; `prior` is the site's law at 1 m, if any.
fn law_of(choice: PathLossChoice, samples: &[(f64, f64)], prior: Option<(f64, f64)>) -> Option<(f64, f64)> {
    let n = samples.len() as f64;
    if samples.is_empty() {
        return None;
    }
    let mean_x = samples.iter().map(|s| s.0).sum::<f64>() / n;
    let mean_rho = samples.iter().map(|s| s.1).sum::<f64>() / n;
    match choice {
        PathLossChoice::Kept => prior,
        PathLossChoice::Offset => {
            // n fixed; ρ₀ = ρ̄ + 10 n x̄
            let exponent = prior.map_or(2.0, |(_, n)| n);
            Some((mean_rho + 10.0 * exponent * mean_x, exponent))
        }
        PathLossChoice::Refitted => {
            let prior_exponent = prior.map_or(2.0, |(_, n)| n);
            let exponent = shrunk_exponent(samples, prior_exponent);
            // n clamped to a physical range; ρ₀ = ρ̄ + 10 n x̄
            let exponent = exponent.clamp(EXPONENT_RANGE.0, EXPONENT_RANGE.1);
            Some((mean_rho + 10.0 * exponent * mean_x, exponent))
        }
    }
}

/// The least-squares exponent of `(x, ρ)` samples: `n = −Sxρ / (10 Sxx)`; `None` when the
/// distances do not spread.
fn least_squares_exponent(samples: &[(f64, f64)]) -> Option<f64> {
    let n = samples.len() as f64;
    let mean_x = samples.iter().map(|s| s.0).sum::<f64>() / n;
    let mean_rho = samples.iter().map(|s| s.1).sum::<f64>() / n;
    // Sxx = Σ (x − x̄)², Sxρ = Σ (x − x̄)(ρ − ρ̄)
    let sxx: f64 = samples.iter().map(|s| (s.0 - mean_x).powi(2)).sum();
    let sxr: f64 = samples.iter().map(|s| (s.0 - mean_x) * (s.1 - mean_rho)).sum();
    // slope b = Sxρ / Sxx = −10 n
    (sxx > 1e-9).then(|| -sxr / sxx / 10.0)
}

/// The exponent of `(x, ρ)` samples (record order) shrunk toward `prior_exponent` by how well
/// the samples determine it:
///
/// ```text
/// n = n₀ + (n̂ − n₀) · τ² / (τ² + se²),   se² = (B−1)/B · Σ_b (n̂₍₋b₎ − n̄₍·₎)²
/// ```
///
/// `n̂` the least-squares exponent, `se` its delete-one-block jackknife standard error over
/// `B` = [`PATH_LOSS_FOLDS`] contiguous blocks (shadowing persists along a walk, so the
/// samples' own residuals would overstate what they say), `τ` =
/// [`EXPONENT_PRIOR_STD`] the spread of a site's links' exponents about its law. A walk over a
/// narrow band of distances barely determines `n`: its `se` is large and the site's law
/// stays; a walk that spans the distances moves it. `n₀` when the samples do not spread.
///
/// # References
/// B. Efron, C. Stein, "The jackknife estimate of variance", *Ann. Stat.* 9(3), 1981 (the
/// delete-a-group jackknife); T. S. Rappaport, *Wireless Communications*, 2nd ed. (2002),
/// Table 4.2 (path-loss exponents by environment).
fn shrunk_exponent(samples: &[(f64, f64)], prior_exponent: f64) -> f64 {
    let Some(exponent) = least_squares_exponent(samples) else {
        return prior_exponent;
    };
    let block = samples.len().div_ceil(PATH_LOSS_FOLDS).max(1);
    // n̂₍₋b₎: the exponent without block b
    let deleted: Vec<f64> = (0..samples.len())
        .step_by(block)
        .filter_map(|start| {
            let end = (start + block).min(samples.len());
            let kept: Vec<(f64, f64)> = samples[..start].iter().chain(&samples[end..]).copied().collect();
            least_squares_exponent(&kept)
        })
        .collect();
    let blocks = deleted.len() as f64;
    if blocks < 2.0 {
        return prior_exponent;
    }
    let centre = deleted.iter().sum::<f64>() / blocks;
    // se² = (B − 1)/B Σ (n̂₍₋b₎ − n̄)²
    let jackknife_variance = (blocks - 1.0) / blocks * deleted.iter().map(|e| (e - centre).powi(2)).sum::<f64>();
    let tau2 = EXPONENT_PRIOR_STD * EXPONENT_PRIOR_STD;
    // n = n₀ + (n̂ − n₀) τ² / (τ² + se²)
    prior_exponent + (exponent - prior_exponent) * tau2 / (tau2 + jackknife_variance)
}

/// `Σ (ρ − ρ₀ + 10 n x)²` over `samples`.
fn squared_error(samples: &[(f64, f64)], (reference_power_dbm, exponent): (f64, f64)) -> f64 {
    samples
        .iter()
        .map(|s| (s.1 - reference_power_dbm + 10.0 * exponent * s.0).powi(2))
        .sum()
}

/// The law of `(x, ρ)` samples (`x = log₁₀ d`, in record order) chosen by cross-validation
/// among [`PathLossChoice`]s: each candidate is fitted on all blocks but one and scored on it,
/// `MSE_k = mean_{i ∈ k} (ρᵢ − ρ̂₀⁽⁻ᵏ⁾ + 10 n̂⁽⁻ᵏ⁾ xᵢ)²`, `CV = mean_k MSE_k`; by the
/// one-standard-error rule the simplest law whose `CV` is within one standard error
/// (`std_k(MSE_k)/√K`) of the least `CV` wins (Hastie, Tibshirani, Friedman, *The Elements of
/// Statistical Learning*, 2nd ed., §7.10). The winner is refitted on every sample; `σ² = Σ residual² / (N − p)`, `p` its
/// fitted parameters. `prior` is the site's law at 1 m (`ρ₀`, `n`), if it has one.
fn fit_path_loss(samples: &[(f64, f64)], prior: Option<(f64, f64)>) -> PathLossFit {
    let n = samples.len();
    let block = n.div_ceil(PATH_LOSS_FOLDS).max(1);
    // per candidate: the held-out mean squared error of each block, MSE_k
    let mut scored: Vec<(PathLossChoice, Vec<f64>)> = Vec::new();
    for choice in [PathLossChoice::Kept, PathLossChoice::Offset, PathLossChoice::Refitted] {
        let folds: Option<Vec<f64>> = (0..n)
            .step_by(block)
            .map(|start| {
                let end = (start + block).min(n);
                let training: Vec<(f64, f64)> = samples[..start].iter().chain(&samples[end..]).copied().collect();
                law_of(choice, &training, prior)
                    .map(|law| squared_error(&samples[start..end], law) / (end - start) as f64)
            })
            .collect();
        if let Some(folds) = folds.filter(|f| f.iter().all(|e| e.is_finite())) {
            scored.push((choice, folds));
        }
    }
    // CV = mean_k MSE_k, SE = std_k(MSE_k) / √K
    let summary = |folds: &[f64]| {
        let k = folds.len() as f64;
        let mean = folds.iter().sum::<f64>() / k;
        let variance = folds.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
        (mean, (variance / k).sqrt())
    };
    // the one-standard-error rule: the simplest law whose CV is within one SE of the least
    let least = scored
        .iter()
        .map(|(_, folds)| summary(folds))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    let (choice, cv) = match least {
        Some((least_cv, least_se)) => scored
            .iter()
            .map(|(choice, folds)| (*choice, summary(folds).0))
            .find(|(_, cv)| *cv <= least_cv + least_se)
            .unwrap_or((PathLossChoice::Refitted, least_cv)),
        None => (PathLossChoice::Refitted, f64::NAN),
    };
    let law = law_of(choice, samples, prior).unwrap_or((0.0, 2.0));
    let parameters = match choice {
        PathLossChoice::Kept => 0.0,
        PathLossChoice::Offset => 1.0,
        PathLossChoice::Refitted => 2.0,
    };
    // σ² = Σ (ρ − ρ₀ + 10 n x)² / (N − p)
    let residual_variance = squared_error(samples, law) / (n as f64 - parameters).max(1.0);
    PathLossFit {
        reference_power_dbm: law.0,
        exponent: law.1,
        shadowing_std_db: residual_variance.sqrt().max(0.1),
        samples: n,
        choice,
        held_out_rms_db: cv.sqrt(),
    }
}

/// Fits every reader that gave enough ranges or RSSI with truth at their time.
pub(super) fn calibrate(
    site: &Site,
    records: &[Record],
    truth: &[TruthSample],
    max_gap_s: f64,
) -> Vec<ReaderCalibration> {
    let by_tag = truth_by_tag(truth);
    let tag_height_m = site.tracker.tag_height_m.unwrap_or(0.0);
    let mut ranges: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
    let mut rssi: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
    for record in records {
        let Some(tag_truth) = by_tag.get(record.tag.as_str()) else {
            continue;
        };
        let (anchor, value, is_range) = match &record.measurement {
            Measurement::Range { anchor, range_m, .. } => (anchor, *range_m, true),
            Measurement::Rssi { anchor, rssi_dbm } => (anchor, *rssi_dbm, false),
            _ => continue,
        };
        let (Some(reader), Some(position)) = (
            site.reader(anchor),
            truth_at(tag_truth, record.time_s, max_gap_s, tag_height_m),
        ) else {
            continue;
        };
        let a = reader.position_xyz_m();
        // d = |p − a| (slant)
        let d = ((position[0] - a[0]).powi(2) + (position[1] - a[1]).powi(2) + (position[2] - a[2]).powi(2)).sqrt();
        if !(value.is_finite() && d.is_finite()) {
            continue;
        }
        if is_range {
            ranges.entry(&reader.id).or_default().push((d, value));
        } else {
            rssi.entry(&reader.id)
                .or_default()
                .push((d.max(MIN_FIT_DISTANCE_M).log10(), value));
        }
    }
    site.readers
        .iter()
        .filter_map(|reader| {
            let range = ranges
                .get(reader.id.as_str())
                .filter(|r| r.len() >= MIN_SAMPLES)
                .map(|r| fit_range(r));
            // the site's law at 1 m: ρ₀(1 m) = ρ₀(d₀) + 10 n log₁₀ d₀
            let prior = reader.radio.as_ref().and_then(|r| r.path_loss).map(|law| {
                (
                    law.reference_power_dbm + 10.0 * law.exponent * law.reference_distance_m.log10(),
                    law.exponent,
                )
            });
            let path_loss = rssi
                .get(reader.id.as_str())
                .filter(|s| s.len() >= MIN_SAMPLES)
                .map(|s| fit_path_loss(s, prior));
            (range.is_some() || path_loss.is_some()).then(|| ReaderCalibration {
                reader: reader.id.clone(),
                range,
                path_loss,
            })
        })
        .collect()
}

/// Writes the fits into the site's readers.
pub(super) fn apply(site: &mut Site, calibration: &[ReaderCalibration]) {
    for fit in calibration {
        let Some(reader) = site.readers.iter_mut().find(|r| r.id == fit.reader) else {
            continue;
        };
        let radio = reader.radio.get_or_insert(Radio {
            path_loss: None,
            range: None,
            sensitivity_dbm: None,
        });
        if let Some(range) = fit.range {
            radio.range = Some(RangeErrors {
                range_std_m: range.range_std_m,
                bias_m: range.bias_m,
                scale: range.scale,
                offset_std_m: range.offset_std_m,
            });
        }
        if let Some(law) = fit.path_loss {
            radio.path_loss = Some(PathLoss {
                reference_power_dbm: law.reference_power_dbm,
                exponent: law.exponent,
                shadowing_std_db: law.shadowing_std_db,
                reference_distance_m: 1.0,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White noise leaves only the bias's standard error (σ/√n, floored at 1 cm); an offset
    /// that moves along the recording (a different value each minute, std 0.1 m) is found.
    #[test]
    fn the_offsets_spread_is_what_the_noise_does_not_explain() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, 0.1).unwrap();
        let white: Vec<f64> = (0..3000).map(|_| noise.sample(&mut rng)).collect();
        assert_eq!(offset_spread(&white), Some(MIN_OFFSET_STD_M));
        let loud = Normal::new(0.0, 1.0).unwrap();
        let white_loud: Vec<f64> = (0..3000).map(|_| loud.sample(&mut rng)).collect();
        // σ/√n = 1/√3000 = 0.018 m, and the block means' spread is noise
        let spread = offset_spread(&white_loud).unwrap();
        assert!((0.01..0.04).contains(&spread), "{spread}");
        // ten minutes of 5 Hz ranges whose offset takes a new value N(0, 0.1²) each minute
        let offsets: Vec<f64> = (0..10).map(|_| noise.sample(&mut rng)).collect();
        let offset_std = {
            let m = offsets.iter().sum::<f64>() / 10.0;
            (offsets.iter().map(|o| (o - m).powi(2)).sum::<f64>() / 9.0).sqrt()
        };
        let moving: Vec<f64> = (0..3000).map(|k| offsets[k / 300] + noise.sample(&mut rng)).collect();
        let spread = offset_spread(&moving).unwrap();
        assert!(
            (spread - offset_std).abs() < 0.2 * offset_std,
            "{spread} vs {offset_std}"
        );
        // too few residuals to tell
        assert_eq!(offset_spread(&moving[..199]), None);
    }

    #[test]
    fn range_fit_is_robust_to_outliers() {
        // bias 0.2 m, σ 0.1 m (normal quantiles), plus 10 % wild outliers at ±25 m: the median
        // stays put and the MAD grows only to 0.1·Φ⁻¹(0.778)/0.6745 ≈ 0.113 m
        let normal_quantile = |p: f64| {
            // Φ⁻¹ by bisection on the error function's series-free form: Φ(x) = ½ erfc(−x/√2)
            let (mut lo, mut hi) = (-8.0f64, 8.0f64);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                let cdf = 0.5 * (1.0 + libm_erf(mid / 2f64.sqrt()));
                if cdf < p {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            0.5 * (lo + hi)
        };
        // all at 5 m (no spread: no scale is fitted)
        let mut samples: Vec<(f64, f64)> = (0..900)
            .map(|i| (5.0, 5.2 + 0.1 * normal_quantile((i as f64 + 0.5) / 900.0)))
            .collect();
        samples.extend((0..100).map(|k| (5.0, if k % 2 == 0 { 30.0 } else { -20.0 })));
        let fit = fit_range(&samples);
        assert!((fit.bias_m - 0.2).abs() < 0.01, "{fit:?}");
        assert!((0.10..0.125).contains(&fit.range_std_m), "{fit:?}");
        assert_eq!(fit.scale, 1.0);

        // the same errors over 2–20 m with a 2 % scale: r = 1.02 d + 0.2
        let mut scaled: Vec<(f64, f64)> = (0..900)
            .map(|i| {
                let d = 2.0 + 18.0 * ((i * 691) % 900) as f64 / 900.0;
                (d, 1.02 * d + 0.2 + 0.1 * normal_quantile((i as f64 + 0.5) / 900.0))
            })
            .collect();
        scaled.extend((0..100).map(|k| (10.0, if k % 2 == 0 { 35.0 } else { -15.0 })));
        let fit = fit_range(&scaled);
        assert!((fit.scale - 1.02).abs() < 0.003, "{fit:?}");
        assert!((fit.bias_m - 0.2).abs() < 0.03, "{fit:?}");
        assert!((0.09..0.125).contains(&fit.range_std_m), "{fit:?}");
        // a scale within its standard error of 1 is not kept: exact ranges plus noise
        let unscaled: Vec<(f64, f64)> = scaled.iter().map(|&(d, _)| (d, d + 0.2)).collect();
        assert_eq!(fit_range(&unscaled).scale, 1.0);
    }

    /// erf by Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7), enough for a test's quantiles.
    fn libm_erf(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let poly =
            t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        let y = 1.0 - poly * (-x * x).exp();
        if x >= 0.0 {
            y
        } else {
            -y
        }
    }

    #[test]
    fn path_loss_fit_recovers_the_law() {
        // ρ = −45 − 10·2.5·log₁₀ d exactly
        let samples: Vec<(f64, f64)> = (1..100)
            .map(|k| {
                let x = (k as f64 * 0.2).log10();
                (x, -45.0 - 25.0 * x)
            })
            .collect();
        let fit = fit_path_loss(&samples, None);
        assert!(
            (fit.exponent - 2.5).abs() < 1e-9 && (fit.reference_power_dbm + 45.0).abs() < 1e-9,
            "{fit:?}"
        );
        assert_eq!(fit.choice, PathLossChoice::Refitted);
        assert_eq!(fit.shadowing_std_db, 0.1);
        // a site law that is right is kept, one off by an offset gets its ρ₀ refitted
        assert_eq!(fit_path_loss(&samples, Some((-45.0, 2.5))).choice, PathLossChoice::Kept);
        let offset = fit_path_loss(&samples, Some((-50.0, 2.5)));
        assert_eq!(offset.choice, PathLossChoice::Offset);
        assert!((offset.reference_power_dbm + 45.0).abs() < 1e-9, "{offset:?}");
    }

    /// Uniform numbers in `[0, 1)` from SplitMix64 seeded with `seed`.
    fn split_mix(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1_u64 << 53) as f64
        }
    }

    #[test]
    fn a_walk_over_few_distances_keeps_the_site_exponent() {
        // a law ρ = −50 − 20 log₁₀ d, shadowing ±6 dB persisting over blocks of 10 samples,
        // walked over 2–3 m only: the exponent is barely determined there, so a refit of it
        // predicts held-out blocks worse than the site's law with ρ₀ refitted
        let mut uniform = split_mix(7);
        let mut samples = Vec::new();
        for _ in 0..10 {
            let shadow = 12.0 * (uniform() - 0.5);
            for _ in 0..10 {
                let x = (2.0 + uniform()).log10();
                samples.push((x, -50.0 - 20.0 * x + shadow + (uniform() - 0.5)));
            }
        }
        let fit = fit_path_loss(&samples, Some((-52.0, 2.0)));
        assert_ne!(fit.choice, PathLossChoice::Refitted, "{fit:?}");
        assert_eq!(fit.exponent, 2.0);
        assert!(fit.held_out_rms_db.is_finite() && fit.held_out_rms_db > 0.0);
    }

    /// A walk that spans 1–30 m determines the exponent and moves it off the site's; a walk
    /// from 2 to 3 m whose shadowing persists over blocks of ten samples does not, and keeps
    /// it near the site's whatever slope its least squares finds.
    #[test]
    fn a_refitted_exponent_moves_as_far_as_the_walk_determines_it() {
        let mut uniform = split_mix(11);
        // ρ = −45 − 30 log₁₀ d ± 2 dB over 1–30 m, the site saying n = 2
        let wide: Vec<(f64, f64)> = (0..200)
            .map(|k| {
                let x = (1.0 + 29.0 * f64::from(k) / 199.0).log10();
                (x, -45.0 - 30.0 * x + 4.0 * (uniform() - 0.5))
            })
            .collect();
        let n = shrunk_exponent(&wide, 2.0);
        assert!((n - 3.0).abs() < 0.1, "{n}");
        // ρ = −50 − 20 log₁₀ d walking from 2 to 3 m, shadowing ±6 dB per block of ten
        let mut narrow = Vec::new();
        for block in 0..10 {
            let shadow = 12.0 * (uniform() - 0.5);
            for _ in 0..10 {
                let x = (2.0 + 0.1 * f64::from(block) + 0.1 * uniform()).log10();
                narrow.push((x, -50.0 - 20.0 * x + shadow + (uniform() - 0.5)));
            }
        }
        let least_squares = least_squares_exponent(&narrow).unwrap();
        let n = shrunk_exponent(&narrow, 2.0);
        assert!((least_squares - 2.0).abs() > 1.0, "least squares {least_squares}");
        assert!(
            (n - 2.0).abs() < 0.5 * (least_squares - 2.0).abs(),
            "{n} against {least_squares}"
        );
    }

    #[test]
    fn truth_is_interpolated_and_gaps_are_not() {
        let sample = |t: f64, x: f64| TruthSample {
            time_s: t,
            tag: "a".into(),
            position_m: [x, 0.0, 0.0],
            has_z: false,
            line: 0,
        };
        let truth = [sample(0.0, 0.0), sample(1.0, 10.0), sample(5.0, 10.0)];
        let refs: Vec<&TruthSample> = truth.iter().collect();
        assert_eq!(truth_at(&refs, 0.25, 2.0, 1.5), Some([2.5, 0.0, 1.5]));
        assert_eq!(truth_at(&refs, 3.0, 2.0, 1.5), None);
        assert_eq!(truth_at(&refs, -1.0, 2.0, 1.5), None);
        assert_eq!(truth_at(&refs, 5.0, 2.0, 0.0), Some([10.0, 0.0, 0.0]));
    }
}
