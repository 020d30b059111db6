//! Tuning a site to a recording (`rtls tune`): the process noise by maximum likelihood on the
//! innovations (no truth needed), and with ground truth the readers' range bias and noise and
//! their path-loss laws, and the process noise that minimises the position error.
//!
//! Every candidate runs the one tracker ([`Tracker`]) over the records, exactly as
//! `rtls track` would; nothing is simulated.
//!
//! # Without truth: innovation likelihood
//! For each candidate white-acceleration density `σ_a` on a logarithmic grid the records are
//! tracked and the innovation log-likelihood `ℓ(σ_a) = Σₖ ln N(νₖ; 0, Sₖ)` (each NIS clipped at
//! its gate, [`crate::tracker::InnovationTotals`]) is summed over every update; the `σ_a` of
//! the largest `ℓ` is chosen (Mehra 1970's maximum-likelihood identification of the noise
//! from the innovations). The adaptive measurement-noise scales `λ` the run ends with tell
//! how much noisier each class of measurement was than the site stated; `rtls tune` writes
//! `√λ̄` times the stated standard deviations.
//!
//! # With truth
//! - Ranges: per reader, the residuals `rᵢ − dᵢ` against the slant distance from the reader to
//!   the true position at the record's time give `bias_m = median(r − d)` and
//!   `range_std_m = 1.4826 · MAD(r − d)` (a robust standard deviation).
//! - RSSI: per reader, the log-distance law `ρ = ρ₀ − 10 n log₁₀(d / 1 m)` on `(log₁₀ d, ρ)`:
//!   the site's law kept, its `ρ₀` refitted, or both `ρ₀` and `n` refitted by least squares,
//!   whichever is simplest within one standard error of the least 5-fold cross-validated error
//!   ([`PathLossChoice`]), with the residual standard deviation as the shadowing.
//! - `σ_a`: the grid value whose tracks (with the calibrated readers) have the smallest RMSE
//!   against the truth; each candidate's RMSE comes with its standard error (batch means over
//!   [`RMSE_BATCHES`] contiguous batches in time), printed by `rtls tune`, so a user sees
//!   whether the calibration part determines `σ_a` at all (on a short walk it often does not:
//!   the tuned value is then a guess, and the recording's later manoeuvres may need more).
//! - The error-correlation settings (with or without truth, at the chosen `σ_a`):
//!   `adaptive_noise.correlation_s` at the site's and at [`CORRELATION_CANDIDATES_S`],
//!   `adaptive_noise.correlation_from_innovations` on and off and, when the recording has
//!   speeds (odometry) taken with the heading's variance as fresh noise (the IMM, or
//!   `heading.consider_heading_error = false`), `heading.heading_error_correlation_s` at 0 and
//!   [`HEADING_CORRELATION_CANDIDATE_S`]; the combination with the smallest RMSE (with truth)
//!   or the largest innovation likelihood (without) is kept ([`ModelChoice`]). With truth, when
//!   that combination's ellipses hold the truth less than 90 % of the time, the one whose
//!   coverage is nearest 95 % is kept instead among those wider than it and within one
//!   standard error of its RMSE (`model::choose_model_run`): errors that persist for seconds make
//!   a track that averages many fixes (a velocity from odometry lets it) overconfident, and
//!   the RMSE hardly tells the correlation time, the coverage does. Whether a site's errors
//!   persist is a property of its radios and its odometer, so it is fitted like the noise, not
//!   assumed.
//! - The covariance: if fewer than 95 % of the truths lie inside the chosen tracks'
//!   95 % ellipses, `σ_a` and every calibrated reader's standard deviation are multiplied by
//!   `k = √(ε₉₅ / χ²_d(0.95))` (the NEES's 95th percentile over its gate). Scaling every
//!   noise of a Kalman filter by `k²` leaves its gains, and so its track, unchanged and scales
//!   its covariance by `k²` (exactly for a linear filter, to first order for the EKF; the
//!   adaptive noise scales and the noises the readers do not set, fixes' and fingerprints',
//!   break the invariance), so the track keeps its accuracy and its ellipses hold the truth as
//!   often as they claim. Only coverage below 90 % is scaled; the scaled site is run again
//!   and `k` refined (at most four runs); the run nearest 95 % is kept if it is nearer than the
//!   unscaled one and costs at most 10 % of RMSE
//!   ([`CovarianceCalibration`]). Ellipses too cautious on the calibration part are not
//!   narrowed (`k ≥ 1`): a calibration part of a minute holds a few independent looks at
//!   errors correlated over seconds, and narrowing on them is a promise the rest of the
//!   recording breaks. On docs/EVALUATION.md's recordings, 4 of the 9 narrowed sites held the
//!   truth 21–88 % of the time on the scored half (BLE straight_03 `k` 0.60: 21 %; LIAS mid
//!   0.77–0.79: 87–88 %); every widened one 90–100 %.
//!
//! # Errors
//! Settings the tracker refuses; no update at all on any candidate (nothing to tune on).
//!
//! # References
//! R. K. Mehra, "On the identification of variances and adaptive Kalman filtering", IEEE
//! Trans. Automatic Control 15(2), 1970; Bar-Shalom, Li & Kirubarajan 2001, §5.4 and §11.
//!
//! # Example
//! ```
//! use rtls_engine::record::{Measurement, Record};
//! use rtls_engine::site::Site;
//! use rtls_engine::tuning::{tune, TuningSettings};
//! let site = Site::from_toml_str(r#"
//!     readers = [
//!       { id = "A", position_m = [0.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
//!       { id = "B", position_m = [20.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
//!       { id = "C", position_m = [0.0, 20.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
//!     ]
//!     [tracker]
//!     pipeline = "tightly-coupled"
//!     motion_model = "cv"
//!     filter = "ekf"
//!     acceleration_noise_std_mps2 = 0.5
//!     gate_probability = 0.999
//!     initiation = { confirm_updates = 3, within_s = 5.0 }
//!     coast_timeout_s = 5.0
//!     delete_timeout_s = 60.0
//!     reorder_window_s = 0.0
//! "#, "site.toml")?;
//! // a tag walking at 1 m/s along x, exact ranges
//! let records: Vec<Record> = (0..300).map(|k| {
//!     let t = k as f64 * 0.1;
//!     let anchor = ["A", "B", "C"][k % 3];
//!     let a = site.reader(anchor).unwrap().position_xyz_m();
//!     let p = [2.0 + 0.5 * t, 5.0];
//!     let range_m = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
//!     Record { time_s: t, tag: "w".into(), measurement: Measurement::Range { anchor: anchor.into(), range_m, std_m: None, anchor_position_m: None } }
//! }).collect();
//! let tuned = tune(&site, None, &records, None, &TuningSettings::default())?;
//! assert!(tuned.acceleration_noise_std_mps2 < 0.5); // a steady walk: a quieter model fits better
//! # Ok::<(), rtls_engine::EngineError>(())
//! ```

mod model;
mod readers;

use model::choose_model;
#[cfg(test)]
use model::choose_model_run;
pub use model::{ModelChoice, ModelSettings, CORRELATION_CANDIDATES_S, HEADING_CORRELATION_CANDIDATE_S};
pub use readers::{PathLossChoice, PathLossFit, RangeFit, ReaderCalibration};

use std::collections::BTreeMap;

use crate::error::{EngineError, Result};
use crate::evaluation::{evaluate, EvaluationSettings, TrackSample, TruthSample};
use crate::radio_map::RadioMap;
use crate::record::Record;
use crate::site::Site;
use crate::tracker::{Innovations, NoiseClass, Output, Tracker};

/// What [`tune`] searches.
#[derive(Debug, Clone, PartialEq)]
pub struct TuningSettings {
    /// Candidate white-acceleration standard deviations `σ_a`, m/s² (each > 0).
    pub acceleration_grid_mps2: Vec<f64>,
    /// Truth samples more than this far apart are not interpolated across, s.
    pub max_truth_gap_s: f64,
    /// With truth: the first seconds of each track that are not scored (convergence).
    pub skip_initial_s: f64,
}

impl Default for TuningSettings {
    /// `σ_a` from 0.02 to 10 m/s² in 14 log-spaced steps (a parked asset to a braking car);
    /// truth gaps up to 0.5 s; 1 s skipped.
    fn default() -> Self {
        Self {
            acceleration_grid_mps2: vec![
                0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0,
            ],
            max_truth_gap_s: 0.5,
            skip_initial_s: 1.0,
        }
    }
}

/// One candidate `σ_a` and how it did.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The white-acceleration standard deviation, m/s².
    pub acceleration_noise_std_mps2: f64,
    /// Innovation log-likelihood `Σ ln N(ν; 0, S)` over all updates.
    pub log_likelihood: f64,
    /// Updates computed.
    pub updates: u64,
    /// With truth: RMSE of the non-predicted track updates, m.
    pub rmse_m: Option<f64>,
    /// With truth: the standard error of `rmse_m` from [`RMSE_BATCHES`] contiguous batches of
    /// the scored samples (batch means, so that errors correlated in time are not counted as
    /// independent), m: `SE(MSE) = std_b(MSE_b)/√B`, `SE(RMSE) ≈ SE(MSE) / (2 RMSE)`.
    pub rmse_standard_error_m: Option<f64>,
    /// With truth: the share of truths inside the reported 95 % ellipse.
    pub inside_95: Option<f64>,
    /// With truth: `k² = ε₉₅ / χ²_d(0.95)`, the factor the reported covariances needed.
    pub covariance_scale_95: Option<f64>,
    /// The innovation totals per measurement class.
    pub innovations: Innovations,
}

/// What [`tune`] chose, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Tuning {
    /// The chosen `σ_a`, m/s².
    pub acceleration_noise_std_mps2: f64,
    /// Every candidate, in grid order.
    pub candidates: Vec<Candidate>,
    /// Index of the chosen candidate.
    pub chosen: usize,
    /// With truth: the readers' calibration (empty without truth).
    pub readers: Vec<ReaderCalibration>,
    /// Without truth: the factor `√λ̄` by which each measurement class's stated standard
    /// deviation should grow (≥ 1; 1 when the class was not seen or was consistent), from the
    /// run of the chosen `σ_a` and error-correlation settings (its mean adaptive noise scale).
    pub noise_std_factors: Vec<(NoiseClass, f64)>,
    /// The error-correlation settings chosen, and the runs that chose them.
    pub model: ModelChoice,
    /// With truth: the covariance calibration applied to `acceleration_noise_std_mps2` and
    /// `readers` (`None` when the chosen candidate was already consistent, or scaling did not
    /// bring its coverage nearer 95 %).
    pub covariance: Option<CovarianceCalibration>,
}

/// How [`tune`] widened the noises so that the tracks' 95 % ellipses hold the truth 95 % of the
/// time on the tuning recording (it never narrows them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceCalibration {
    /// `k`, the factor on `σ_a` and on the readers' standard deviations.
    pub std_factor: f64,
    /// Share of truths inside the 95 % ellipse before and after, 0–1.
    pub inside_95_before: f64,
    /// As `inside_95_before`, with the scaled noises.
    pub inside_95_after: f64,
    /// RMSE before and after, m (unchanged for a linear filter).
    pub rmse_before_m: f64,
    /// As `rmse_before_m`, with the scaled noises.
    pub rmse_after_m: f64,
}

/// Bounds on `k²`: never narrower (see the [module documentation](self)); a covariance a
/// hundred times off is a model error, not a scale.
const COVARIANCE_SCALE_BOUNDS: (f64, f64) = (1.0, 100.0);

/// Runs of the scaled site at most (each refines `k²` by the last run's `ε₉₅ / χ²_d(0.95)`).
const CALIBRATION_RUNS: usize = 4;

/// Coverage within this band needs no scaling (the band a consistent track's coverage falls in
/// on a recording of a few hundred correlated samples).
const COVERAGE_BAND: (f64, f64) = (0.90, 0.98);

/// Contiguous batches of a candidate's scored samples (in time) for the standard error of its
/// RMSE.
pub const RMSE_BATCHES: usize = 10;

/// A scaling that costs more than this factor of RMSE is refused: the invariance it relies on
/// does not hold for the site, and a consistent covariance is no excuse for a worse track.
const MAX_RMSE_COST: f64 = 1.1;

/// Tunes `site` to `records` (time-ordered or not; they pass the tracker's re-ordering window
/// like any input), with the tracks' range-offset learning off (what it would learn is what
/// the tuning writes into the site). See the [module documentation](self).
///
/// # Errors
/// [`EngineError::InvalidParameter`] for an empty or non-positive grid; those of
/// [`Tracker::new`] and [`Tracker::push`]; when no candidate computed a single update.
pub fn tune(
    site: &Site,
    radio_map: Option<&RadioMap>,
    records: &[Record],
    truth: Option<&[TruthSample]>,
    settings: &TuningSettings,
) -> Result<Tuning> {
    if settings.acceleration_grid_mps2.is_empty()
        || settings
            .acceleration_grid_mps2
            .iter()
            .any(|s| !(s.is_finite() && *s > 0.0))
    {
        return Err(EngineError::InvalidParameter {
            name: "acceleration_grid_mps2",
            reason: "must hold at least one finite value > 0, m/s²",
        });
    }
    let mut site = site.clone();
    // the candidates run on the stated ranges: the tracks' own range-offset learning
    // ([tracker.range_bias]) would absorb the biases and the noise excess this fits into the
    // site; the tuned site keeps the file's setting
    site.tracker.range_bias.enabled = false;
    let mut readers = match truth {
        Some(truth) => {
            let calibration = readers::calibrate(&site, records, truth, settings.max_truth_gap_s);
            readers::apply(&mut site, &calibration);
            calibration
        }
        None => Vec::new(),
    };
    let mut candidates = Vec::with_capacity(settings.acceleration_grid_mps2.len());
    for &sigma in &settings.acceleration_grid_mps2 {
        site.tracker.acceleration_noise_std_mps2 = sigma;
        candidates.push(run_candidate(&site, radio_map, records, truth, settings)?);
    }
    let chosen = choose(&candidates).ok_or(EngineError::InvalidParameter {
        name: "records",
        reason: "gave no filter update on any candidate: nothing to tune on (check that the \
                 records' readers are in the site and that tracks start)",
    })?;
    let mut acceleration_noise_std_mps2 = candidates[chosen].acceleration_noise_std_mps2;
    site.tracker.acceleration_noise_std_mps2 = acceleration_noise_std_mps2;
    let model = choose_model(&mut site, radio_map, records, truth, settings, &candidates[chosen])?;
    // the noise excess as the chosen settings saw it
    let noise_std_factors = NoiseClass::ALL
        .iter()
        .map(|&class| {
            let scale = model.tried[model.chosen]
                .1
                .innovations
                .of(class)
                .mean_noise_scale()
                .unwrap_or(1.0);
            (class, scale.max(1.0).sqrt())
        })
        .collect();
    let covariance = match truth {
        Some(_) => {
            let calibration = calibrate_covariance(
                &site,
                radio_map,
                records,
                truth,
                settings,
                &readers,
                &model.tried[model.chosen].1,
            )?;
            if let Some(c) = calibration {
                acceleration_noise_std_mps2 *= c.std_factor;
                readers = scaled_readers(&readers, c.std_factor);
            }
            calibration
        }
        None => None,
    };
    Ok(Tuning {
        acceleration_noise_std_mps2,
        candidates,
        chosen,
        readers,
        noise_std_factors,
        model,
        covariance,
    })
}

/// The readers' fits with every standard deviation multiplied by `k`.
fn scaled_readers(readers: &[ReaderCalibration], std_factor: f64) -> Vec<ReaderCalibration> {
    readers
        .iter()
        .map(|fit| {
            let mut fit = fit.clone();
            if let Some(range) = fit.range.as_mut() {
                range.range_std_m *= std_factor;
            }
            if let Some(law) = fit.path_loss.as_mut() {
                law.shadowing_std_db *= std_factor;
            }
            fit
        })
        .collect()
}

/// `k ≥ 1` such that the chosen candidate's 95 % ellipses hold 95 % of the truths (see the
/// [module documentation](self)); `None` when they hold at least 90 % already or widening
/// does not help.
fn calibrate_covariance(
    site: &Site,
    radio_map: Option<&RadioMap>,
    records: &[Record],
    truth: Option<&[TruthSample]>,
    settings: &TuningSettings,
    readers: &[ReaderCalibration],
    chosen: &Candidate,
) -> Result<Option<CovarianceCalibration>> {
    let (Some(inside_before), Some(scale), Some(rmse_before)) =
        (chosen.inside_95, chosen.covariance_scale_95, chosen.rmse_m)
    else {
        return Ok(None);
    };
    let miss = |inside: f64| (inside - 0.95).abs();
    let within = |inside: f64| (COVERAGE_BAND.0..=COVERAGE_BAND.1).contains(&inside);
    // cautious ellipses are not narrowed
    if inside_before >= COVERAGE_BAND.0 || !scale.is_finite() {
        return Ok(None);
    }
    let (low, high) = COVARIANCE_SCALE_BOUNDS;
    // k² ← k² · ε₉₅/χ²_d(0.95), refined by up to CALIBRATION_RUNS runs: the adaptive scales
    // and the unscaled noises make one step inexact
    let mut variance_factor = scale.clamp(low, high);
    let mut best: Option<CovarianceCalibration> = None;
    for _ in 0..CALIBRATION_RUNS {
        let std_factor = variance_factor.sqrt();
        let mut scaled = site.clone();
        scaled.tracker.acceleration_noise_std_mps2 *= std_factor;
        readers::apply(&mut scaled, &scaled_readers(readers, std_factor));
        let run = run_candidate(&scaled, radio_map, records, truth, settings)?;
        let (Some(inside_after), Some(rmse_after), Some(next)) = (run.inside_95, run.rmse_m, run.covariance_scale_95)
        else {
            break;
        };
        let nearer = best.map_or(miss(inside_before), |b| miss(b.inside_95_after));
        if miss(inside_after) < nearer && rmse_after <= MAX_RMSE_COST * rmse_before {
            best = Some(CovarianceCalibration {
                std_factor,
                inside_95_before: inside_before,
                inside_95_after: inside_after,
                rmse_before_m: rmse_before,
                rmse_after_m: rmse_after,
            });
        }
        if within(inside_after) || !next.is_finite() {
            break;
        }
        variance_factor = (variance_factor * next).clamp(low, high);
    }
    Ok(best)
}

/// The best candidate: smallest RMSE when truth scored them all, else the largest innovation
/// log-likelihood; `None` when none computed an update.
fn choose(candidates: &[Candidate]) -> Option<usize> {
    let usable = || candidates.iter().enumerate().filter(|(_, c)| c.updates > 0);
    if candidates.iter().all(|c| c.rmse_m.is_some()) {
        usable()
            .min_by(|a, b| {
                a.1.rmse_m
                    .unwrap_or(f64::INFINITY)
                    .total_cmp(&b.1.rmse_m.unwrap_or(f64::INFINITY))
            })
            .map(|(i, _)| i)
    } else {
        usable()
            .max_by(|a, b| a.1.log_likelihood.total_cmp(&b.1.log_likelihood))
            .map(|(i, _)| i)
    }
}

/// Tracks `records` on `site` and scores the run.
fn run_candidate(
    site: &Site,
    radio_map: Option<&RadioMap>,
    records: &[Record],
    truth: Option<&[TruthSample]>,
    settings: &TuningSettings,
) -> Result<Candidate> {
    let mut tracker = Tracker::new(site)?;
    if let Some(map) = radio_map {
        tracker = tracker.with_radio_map(map.clone());
    }
    let mut out = Output::default();
    let mut innovations = Innovations::default();
    let mut samples = Vec::new();
    let mut drain = |out: &mut Output, innovations: &mut Innovations| {
        innovations.merge(&out.innovations);
        if truth.is_some() {
            samples.extend(out.updates.iter().filter(|u| !u.predicted).map(|u| TrackSample {
                time_s: u.time_s,
                tag: u.tag.to_string(),
                position_m: u.position_m,
                has_z: u.dimensions == 3,
                predicted: false,
                covariance_m2: Some(u.position_covariance_m2[..u.dimensions * u.dimensions].to_vec()),
                line: 0,
            }));
        }
        out.clear();
    };
    for record in records {
        tracker.push(record.clone(), &mut out)?;
        drain(&mut out, &mut innovations);
    }
    tracker.finish(&mut out)?;
    drain(&mut out, &mut innovations);
    let updates = innovations.0.iter().map(|t| t.updates).sum();
    let (rmse_m, inside_95, covariance_scale_95) = match truth {
        Some(truth) if !samples.is_empty() => {
            let evaluation = EvaluationSettings {
                max_gap_s: settings.max_truth_gap_s,
                skip_initial_s: settings.skip_initial_s,
                ..EvaluationSettings::default()
            };
            match evaluate(truth, &samples, &evaluation) {
                Ok(scored) => (
                    Some(scored.overall.rmse_m),
                    scored.consistency.as_ref().map(|c| c.inside_95),
                    scored.consistency.map(|c| c.covariance_scale_95),
                ),
                Err(_) => (Some(f64::INFINITY), None, None),
            }
        }
        Some(_) => (Some(f64::INFINITY), None, None),
        None => (None, None, None),
    };
    let rmse_standard_error_m = match (truth, rmse_m) {
        (Some(truth), Some(rmse)) if rmse.is_finite() && rmse > 0.0 => {
            rmse_standard_error(truth, &samples, settings, rmse)
        }
        _ => None,
    };
    Ok(Candidate {
        acceleration_noise_std_mps2: site.tracker.acceleration_noise_std_mps2,
        log_likelihood: innovations.log_likelihood(),
        updates,
        rmse_m,
        rmse_standard_error_m,
        inside_95,
        covariance_scale_95,
        innovations,
    })
}

/// The standard error of a run's RMSE (see [`Candidate::rmse_standard_error_m`]): its scored
/// samples cut into [`RMSE_BATCHES`] contiguous batches in time (after each tag's first
/// `skip_initial_s`), each batch's MSE, `SE(MSE) = std_b(MSE_b)/√B`, `SE(RMSE) = SE(MSE) /
/// (2 RMSE)`; `None` with fewer than two batches that scored.
fn rmse_standard_error(
    truth: &[TruthSample],
    samples: &[TrackSample],
    settings: &TuningSettings,
    rmse_m: f64,
) -> Option<f64> {
    // each tag's first sample: the start of its skipped part
    let mut first_s: BTreeMap<&str, f64> = BTreeMap::new();
    for sample in samples {
        let first = first_s.entry(&sample.tag).or_insert(sample.time_s);
        *first = first.min(sample.time_s);
    }
    let mut kept: Vec<TrackSample> = samples
        .iter()
        .filter(|s| s.time_s >= first_s[s.tag.as_str()] + settings.skip_initial_s)
        .cloned()
        .collect();
    kept.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let evaluation = EvaluationSettings {
        max_gap_s: settings.max_truth_gap_s,
        skip_initial_s: 0.0,
        ..EvaluationSettings::default()
    };
    let batch = kept.len().div_ceil(RMSE_BATCHES).max(1);
    // MSE_b of each batch that scored
    let batch_mse: Vec<f64> = kept
        .chunks(batch)
        .filter_map(|chunk| evaluate(truth, chunk, &evaluation).ok())
        .filter(|scored| scored.overall.count > 0)
        .map(|scored| scored.overall.rmse_m.powi(2))
        .collect();
    let b = batch_mse.len() as f64;
    if batch_mse.len() < 2 {
        return None;
    }
    // SE(MSE) = std_b(MSE_b)/√B;  SE(RMSE) = SE(MSE) / (2 RMSE)
    let mean = batch_mse.iter().sum::<f64>() / b;
    let variance = batch_mse.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (b - 1.0);
    Some((variance / b).sqrt() / (2.0 * rmse_m))
}

/// Samples of each tag's truth, time-sorted, for interpolation.
pub(crate) fn truth_by_tag(truth: &[TruthSample]) -> BTreeMap<&str, Vec<&TruthSample>> {
    let mut by_tag: BTreeMap<&str, Vec<&TruthSample>> = BTreeMap::new();
    for sample in truth {
        by_tag.entry(&sample.tag).or_default().push(sample);
    }
    for samples in by_tag.values_mut() {
        samples.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    }
    by_tag
}

#[cfg(test)]
mod tests;
