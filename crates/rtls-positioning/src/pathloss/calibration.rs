//! Least-squares calibration of the log-distance law from surveyed `(distance, RSSI)` samples:
//! one model, one per anchor, one shared by all anchors, or a shared exponent with one
//! reference power per anchor.

use nalgebra::Matrix2;

use super::{positive, LogDistance};
use crate::error::{PositioningError, Result};

/// The table name used in [`PositioningError::NonFiniteEntry`] for sample tables.
const SAMPLE_TABLE: &str = "rssi samples (row = sample, column 0 = distance_m, 1 = rssi_dbm)";

/// One calibration measurement: the RSSI an anchor received from a tag at a surveyed distance.
///
/// # Units
/// `distance_m` in m (> 0), `rssi_dbm` in dBm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RssiSample {
    /// Index of the anchor that measured (0-based, below the number of anchors).
    pub anchor: usize,
    /// Surveyed tag–anchor distance (m).
    pub distance_m: f64,
    /// Measured RSSI (dBm).
    pub rssi_dbm: f64,
}

/// The result of a log-distance fit ([`fit_log_distance`], [`fit_shared`],
/// [`fit_per_anchor`]).
///
/// `model` carries `ρ̂_T`, `η̂`, `d₀` and `σ̂_X` (the residual standard deviation with
/// `n − 2` degrees of freedom, unbiased in variance). The standard errors and the parameter
/// covariance are the ordinary-least-squares ones, `s² (AᵀA)⁻¹`: exact for independent
/// Gaussian shadowing at the surveyed distances, optimistic when samples are correlated
/// (several samples at one spot share its shadowing: average them first, or survey more spots).
///
/// # Units
/// Standard errors in dB (`ρ_T`) and dimensionless (`η`); `parameter_covariance` ordered
/// `(ρ_T, η)` in dB², dB, 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogDistanceFit {
    /// The fitted law.
    pub model: LogDistance,
    /// Standard error of `ρ̂_T` (dB).
    pub reference_rssi_std_error_db: f64,
    /// Standard error of `η̂`.
    pub exponent_std_error: f64,
    /// Covariance of `(ρ̂_T, η̂)`: `s² (AᵀA)⁻¹`.
    pub parameter_covariance: Matrix2<f64>,
    /// Number of samples used.
    pub samples: usize,
}

/// The fitted reference power of one anchor in a [`SharedExponentFit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorOffset {
    /// `ρ̂_T` of this anchor (dBm at `d₀`).
    pub reference_rssi_dbm: f64,
    /// Standard error of `ρ̂_T` (dB).
    pub std_error_db: f64,
    /// Number of this anchor's samples.
    pub samples: usize,
}

/// The result of [`fit_shared_exponent`]: one exponent and shadowing for the site, one
/// reference power per anchor (`None` for anchors without samples).
#[derive(Debug, Clone, PartialEq)]
pub struct SharedExponentFit {
    /// `η̂`, shared by all anchors.
    pub exponent: f64,
    /// Standard error of `η̂`.
    pub exponent_std_error: f64,
    /// `σ̂_X` (dB): residual standard deviation with `n − A − 1` degrees of freedom
    /// (`A` anchors with samples).
    pub shadowing_std_db: f64,
    /// `d₀` (m) of every anchor's `ρ_T`.
    pub reference_distance_m: f64,
    /// Per anchor, in anchor order.
    pub offsets: Vec<Option<AnchorOffset>>,
    /// Number of samples used.
    pub samples: usize,
}

impl SharedExponentFit {
    /// The law of anchor `anchor`, or `None` if it had no samples (or does not exist).
    ///
    /// # Example
    /// See [`fit_shared_exponent`].
    #[must_use]
    pub fn model(&self, anchor: usize) -> Option<LogDistance> {
        let offset = self.offsets.get(anchor).copied().flatten()?;
        LogDistance::new(
            offset.reference_rssi_dbm,
            self.exponent,
            self.reference_distance_m,
            self.shadowing_std_db,
        )
        .ok()
    }
}

/// Fits the log-distance law `ρ = ρ_T − 10 η lg(d/d₀) + X` to samples `[distance_m, rssi_dbm]`
/// by ordinary least squares.
///
/// With `x_k = −10 lg(d_k/d₀)` the law is the straight line `ρ_k = ρ_T + η x_k + X_k`:
/// ```text
/// x̄ = (1/n) Σ x_k,  ρ̄ = (1/n) Σ ρ_k
/// S_xx = Σ (x_k − x̄)²,  S_xρ = Σ (x_k − x̄)(ρ_k − ρ̄)
/// η̂ = S_xρ / S_xx,  ρ̂_T = ρ̄ − η̂ x̄
/// s² = Σ (ρ_k − ρ̂_T − η̂ x_k)² / (n − 2)                      σ̂_X = s
/// Var η̂ = s² / S_xx,  Var ρ̂_T = s² (1/n + x̄² / S_xx),  Cov = −s² x̄ / S_xx
/// ```
/// Survey over a wide range of distances: `Var η̂` falls with the spread of `lg d`, not with
/// the number of samples at one distance.
///
/// # Units
/// Distances in m, RSSI in dBm.
///
/// # Errors
/// - [`PositioningError::InvalidParameter`] (`reference_distance_m`) unless `d₀` is finite and
///   positive; (`distance_m`) for a sample distance `≤ 0`;
/// - [`PositioningError::NonFiniteEntry`] (row = sample, column 0 = distance, 1 = RSSI) for
///   a NaN/∞ entry;
/// - [`PositioningError::TooFewSamples`] for fewer than 3 samples (2 leave no degree of
///   freedom for `σ_X`);
/// - [`PositioningError::DegenerateGeometry`] if all samples are at one distance (the slope
///   is undetermined);
/// - [`PositioningError::NoConsistentSolution`] if the fitted exponent is not positive (RSSI
///   does not fall with distance in these samples).
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{fit_log_distance, PathLossModel};
/// // ρ = −40 − 25 lg d, exactly
/// let samples: Vec<[f64; 2]> = [1.0, 2.0, 5.0, 10.0, 20.0]
///     .iter()
///     .map(|&d: &f64| [d, -40.0 - 25.0 * d.log10()])
///     .collect();
/// let fit = fit_log_distance(&samples, 1.0)?;
/// assert!((fit.model.exponent() - 2.5).abs() < 1e-12);
/// assert!((fit.model.reference_rssi_dbm() + 40.0).abs() < 1e-12);
/// assert!(fit.model.shadowing_std_db() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002 eq. (1); Rappaport (2002), §4.9.2 (minimum-mean-square-error fit of `n` and `σ`
/// from measurements); any regression text for the OLS standard errors, e.g. N. R. Draper,
/// H. Smith, *Applied Regression Analysis*, 3rd ed., 1998, §1.4 and §3.
pub fn fit_log_distance(samples: &[[f64; 2]], reference_distance_m: f64) -> Result<LogDistanceFit> {
    let rows: Vec<(f64, f64)> = samples.iter().map(|s| (s[0], s[1])).collect();
    fit_rows(&rows, reference_distance_m)
}

/// One log-distance law for all anchors, fitted to their pooled samples (anchor indices are
/// ignored): [`fit_log_distance`] on every sample.
///
/// Use it when anchors are identical hardware at similar mounting; per-anchor differences
/// (antenna gain, cable loss, mounting) then appear as extra shadowing in `σ̂_X`. Compare with
/// [`fit_shared_exponent`], which removes them.
///
/// # Errors
/// As [`fit_log_distance`].
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{fit_shared, RssiSample};
/// let samples: Vec<RssiSample> = (0..6)
///     .map(|k| {
///         let d = 2f64.powi(k);
///         RssiSample { anchor: k as usize % 2, distance_m: d, rssi_dbm: -30.0 - 20.0 * d.log10() }
///     })
///     .collect();
/// let fit = fit_shared(&samples, 1.0)?;
/// assert!((fit.model.exponent() - 2.0).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// As [`fit_log_distance`].
pub fn fit_shared(samples: &[RssiSample], reference_distance_m: f64) -> Result<LogDistanceFit> {
    let rows: Vec<(f64, f64)> = samples.iter().map(|s| (s.distance_m, s.rssi_dbm)).collect();
    fit_rows(&rows, reference_distance_m)
}

/// One log-distance law per anchor: [`fit_log_distance`] on each anchor's samples.
///
/// The whole table is validated first (an invalid row fails the call); then each anchor gets
/// its own result, so one anchor with too few samples (or all at one distance) does not hide
/// the others' fits: element `a` is `Err(TooFewSamples { found: 0, .. })` for an anchor
/// without samples. Anchors with few samples are better served by [`fit_shared_exponent`].
///
/// # Errors
/// Outer: [`PositioningError::InvalidParameter`] (`anchors`) if a sample's anchor index is
/// `≥ anchors`, and the table errors of [`fit_log_distance`] (`NonFiniteEntry` with the row
/// in `samples`, `distance_m`, `reference_distance_m`). Inner (per anchor): the remaining
/// errors of [`fit_log_distance`].
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{fit_per_anchor, RssiSample};
/// let mut samples = Vec::new();
/// for (anchor, rho_t) in [(0, -30.0), (1, -36.0)] {
///     for d in [1.0_f64, 3.0, 9.0, 27.0] {
///         samples.push(RssiSample { anchor, distance_m: d, rssi_dbm: rho_t - 30.0 * d.log10() });
///     }
/// }
/// let fits = fit_per_anchor(&samples, 3, 1.0)?;
/// assert!((fits[1].as_ref().unwrap().model.reference_rssi_dbm() + 36.0).abs() < 1e-9);
/// assert!(fits[2].is_err()); // anchor 2 has no samples
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// As [`fit_log_distance`].
pub fn fit_per_anchor(
    samples: &[RssiSample],
    anchors: usize,
    reference_distance_m: f64,
) -> Result<Vec<Result<LogDistanceFit>>> {
    validate_samples(samples, anchors, reference_distance_m)?;
    let mut per_anchor: Vec<Vec<(f64, f64)>> = vec![Vec::new(); anchors];
    for s in samples {
        per_anchor[s.anchor].push((s.distance_m, s.rssi_dbm));
    }
    Ok(per_anchor
        .iter()
        .map(|rows| fit_rows(rows, reference_distance_m))
        .collect())
}

/// A shared exponent and shadowing with one reference power per anchor:
/// `ρ_k = ρ_T[a_k] + η x_k + X_k`, `x_k = −10 lg(d_k/d₀)`, by least squares.
///
/// This absorbs per-anchor gain differences (antenna, cable, mounting) into `ρ_T[a]` while
/// pooling every sample for the exponent, which is a property of the environment; an anchor
/// needs only one sample to be calibrated. The least-squares solution of this
/// `(A + 1)`-parameter linear model (`A` anchors with samples) is the within-anchor
/// regression:
/// ```text
/// x̄_a, ρ̄_a                              per-anchor means (n_a samples)
/// S_xx = Σ_a Σ_k (x_k − x̄_a)²,  S_xρ = Σ_a Σ_k (x_k − x̄_a)(ρ_k − ρ̄_a)
/// η̂ = S_xρ / S_xx,  ρ̂_T[a] = ρ̄_a − η̂ x̄_a
/// s² = Σ_k (ρ_k − ρ̂_T[a_k] − η̂ x_k)² / (n − A − 1)          σ̂_X = s
/// Var η̂ = s² / S_xx,  Var ρ̂_T[a] = s² (1/n_a + x̄_a² / S_xx)
/// ```
///
/// # Errors
/// - the table errors of [`fit_per_anchor`];
/// - [`PositioningError::TooFewSamples`] unless there are at least `A + 2` samples (one
///   degree of freedom for `σ_X`) and at least 3;
/// - [`PositioningError::DegenerateGeometry`] if no anchor has samples at two different
///   distances (the exponent is undetermined);
/// - [`PositioningError::NoConsistentSolution`] if the fitted exponent is not positive.
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{fit_shared_exponent, PathLossModel, RssiSample};
/// let mut samples = Vec::new();
/// for (anchor, rho_t) in [(0, -30.0), (1, -36.0), (2, -33.0)] {
///     for d in [1.0_f64, 4.0, 16.0] {
///         samples.push(RssiSample { anchor, distance_m: d, rssi_dbm: rho_t - 27.0 * d.log10() });
///     }
/// }
/// let fit = fit_shared_exponent(&samples, 3, 1.0)?;
/// assert!((fit.exponent - 2.7).abs() < 1e-12);
/// let law = fit.model(1).unwrap();
/// assert!((law.mean_rssi_dbm(1.0) + 36.0).abs() < 1e-9);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Analysis of covariance with a common slope (e.g. Draper & Smith (1998), §14 on dummy
/// variables); Rappaport (2002), §4.9.2.
pub fn fit_shared_exponent(
    samples: &[RssiSample],
    anchors: usize,
    reference_distance_m: f64,
) -> Result<SharedExponentFit> {
    validate_samples(samples, anchors, reference_distance_m)?;
    let d0 = reference_distance_m;
    // x_k = −10 lg(d_k/d₀)
    let x = |s: &RssiSample| -10.0 * (s.distance_m / d0).log10();
    // per-anchor counts and sums → x̄_a, ρ̄_a
    let mut count = vec![0usize; anchors];
    let mut sum_x = vec![0.0; anchors];
    let mut sum_rho = vec![0.0; anchors];
    for s in samples {
        count[s.anchor] += 1;
        sum_x[s.anchor] += x(s);
        sum_rho[s.anchor] += s.rssi_dbm;
    }
    let mean = |sum: &[f64], a: usize| sum[a] / count[a] as f64;
    let used = count.iter().filter(|&&c| c > 0).count();
    let n = samples.len();
    let needed = (used + 2).max(3);
    if n < needed {
        return Err(PositioningError::TooFewSamples { found: n, needed });
    }
    // S_xx = Σ (x_k − x̄_a)²,  S_xρ = Σ (x_k − x̄_a)(ρ_k − ρ̄_a)
    let (mut s_xx, mut s_xr) = (0.0, 0.0);
    for s in samples {
        let dx = x(s) - mean(&sum_x, s.anchor);
        s_xx += dx * dx;
        s_xr += dx * (s.rssi_dbm - mean(&sum_rho, s.anchor));
    }
    if s_xx.is_nan() || s_xx <= 0.0 {
        return Err(PositioningError::DegenerateGeometry {
            reason: "no anchor has samples at two different distances, so the path-loss exponent is \
                     undetermined; survey each anchor at several distances",
        });
    }
    // η̂ = S_xρ / S_xx
    let exponent = s_xr / s_xx;
    // ρ̂_T[a] = ρ̄_a − η̂ x̄_a
    let offset = |a: usize| mean(&sum_rho, a) - exponent * mean(&sum_x, a);
    // s² = Σ (ρ_k − ρ̂_T[a_k] − η̂ x_k)² / (n − A − 1)
    let dof = (n - used - 1) as f64;
    let residual_sq: f64 = samples
        .iter()
        .map(|s| {
            let e = s.rssi_dbm - offset(s.anchor) - exponent * x(s);
            e * e
        })
        .sum();
    let variance = residual_sq / dof;
    let offsets = (0..anchors)
        .map(|a| {
            (count[a] > 0).then(|| {
                let x_bar = mean(&sum_x, a);
                AnchorOffset {
                    reference_rssi_dbm: offset(a),
                    // Var ρ̂_T[a] = s² (1/n_a + x̄_a²/S_xx)
                    std_error_db: (variance * (1.0 / count[a] as f64 + x_bar * x_bar / s_xx)).sqrt(),
                    samples: count[a],
                }
            })
        })
        .collect::<Vec<_>>();
    let fit = SharedExponentFit {
        exponent,
        // Var η̂ = s² / S_xx
        exponent_std_error: (variance / s_xx).sqrt(),
        shadowing_std_db: variance.sqrt(),
        reference_distance_m: d0,
        offsets,
        samples: n,
    };
    let finite = [fit.exponent, fit.exponent_std_error, fit.shadowing_std_db]
        .into_iter()
        .chain(
            fit.offsets
                .iter()
                .flatten()
                .flat_map(|o| [o.reference_rssi_dbm, o.std_error_db]),
        )
        .all(f64::is_finite);
    if !finite {
        return Err(PositioningError::NonFinite {
            what: "path-loss fit (samples too extreme)",
        });
    }
    if fit.exponent.is_nan() || fit.exponent <= 0.0 {
        return Err(not_decreasing());
    }
    Ok(fit)
}

/// Validates a multi-anchor sample table: `d₀`, anchor indices, finite entries, `d > 0`.
fn validate_samples(samples: &[RssiSample], anchors: usize, reference_distance_m: f64) -> Result<()> {
    positive(
        reference_distance_m,
        "reference_distance_m",
        "the reference distance must be positive (usually 1 m)",
    )?;
    if samples.iter().any(|s| s.anchor >= anchors) {
        return Err(PositioningError::InvalidParameter {
            name: "anchors",
            reason: "a sample names an anchor index not below `anchors`; pass the number of anchors of the site",
        });
    }
    let rows: Vec<(f64, f64)> = samples.iter().map(|s| (s.distance_m, s.rssi_dbm)).collect();
    validate_rows(&rows)
}

/// Finite entries (`NonFiniteEntry` with row and column) and positive distances.
fn validate_rows(rows: &[(f64, f64)]) -> Result<()> {
    for (row, &(d, rho)) in rows.iter().enumerate() {
        for (column, value) in [d, rho].into_iter().enumerate() {
            if !value.is_finite() {
                return Err(PositioningError::NonFiniteEntry {
                    what: SAMPLE_TABLE,
                    row,
                    column,
                });
            }
        }
    }
    if rows.iter().any(|&(d, _)| d <= 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "distance_m",
            reason: "every sample distance must be positive (the log-distance law is undefined at d ≤ 0)",
        });
    }
    Ok(())
}

/// The OLS fit of [`fit_log_distance`] on `(distance_m, rssi_dbm)` rows.
fn fit_rows(rows: &[(f64, f64)], reference_distance_m: f64) -> Result<LogDistanceFit> {
    positive(
        reference_distance_m,
        "reference_distance_m",
        "the reference distance must be positive (usually 1 m)",
    )?;
    validate_rows(rows)?;
    let n = rows.len();
    if n < 3 {
        return Err(PositioningError::TooFewSamples { found: n, needed: 3 });
    }
    if rows.iter().all(|&(d, _)| d == rows[0].0) {
        return Err(PositioningError::DegenerateGeometry {
            reason: "all samples are at one distance, so the path-loss exponent is undetermined; \
                     survey at two or more distances (ideally spanning a decade)",
        });
    }
    let count = n as f64;
    // x_k = −10 lg(d_k/d₀)
    let x: Vec<f64> = rows
        .iter()
        .map(|&(d, _)| -10.0 * (d / reference_distance_m).log10())
        .collect();
    // x̄, ρ̄
    let x_bar = x.iter().sum::<f64>() / count;
    let rho_bar = rows.iter().map(|&(_, rho)| rho).sum::<f64>() / count;
    // S_xx = Σ (x_k − x̄)²,  S_xρ = Σ (x_k − x̄)(ρ_k − ρ̄)
    let s_xx: f64 = x.iter().map(|xk| (xk - x_bar) * (xk - x_bar)).sum();
    let s_xr: f64 = x
        .iter()
        .zip(rows)
        .map(|(xk, &(_, rho))| (xk - x_bar) * (rho - rho_bar))
        .sum();
    if s_xx.is_nan() || s_xx <= 0.0 {
        return Err(PositioningError::DegenerateGeometry {
            reason: "the sample distances are too close to each other to determine the path-loss exponent",
        });
    }
    // η̂ = S_xρ / S_xx,  ρ̂_T = ρ̄ − η̂ x̄
    let exponent = s_xr / s_xx;
    let reference_rssi_dbm = rho_bar - exponent * x_bar;
    // s² = Σ (ρ_k − ρ̂_T − η̂ x_k)² / (n − 2)
    let residual_sq: f64 = x
        .iter()
        .zip(rows)
        .map(|(xk, &(_, rho))| {
            let e = rho - reference_rssi_dbm - exponent * xk;
            e * e
        })
        .sum();
    let variance = residual_sq / (count - 2.0);
    // s² (AᵀA)⁻¹ = s² [[1/n + x̄²/S_xx, −x̄/S_xx], [−x̄/S_xx, 1/S_xx]]
    let parameter_covariance = Matrix2::new(
        variance * (1.0 / count + x_bar * x_bar / s_xx),
        -variance * x_bar / s_xx,
        -variance * x_bar / s_xx,
        variance / s_xx,
    );
    let finite = [exponent, reference_rssi_dbm, variance]
        .into_iter()
        .chain(parameter_covariance.iter().copied())
        .all(f64::is_finite);
    if !finite {
        return Err(PositioningError::NonFinite {
            what: "path-loss fit (samples too extreme)",
        });
    }
    if exponent.is_nan() || exponent <= 0.0 {
        return Err(not_decreasing());
    }
    let model = LogDistance::new(reference_rssi_dbm, exponent, reference_distance_m, variance.sqrt())?;
    Ok(LogDistanceFit {
        model,
        reference_rssi_std_error_db: parameter_covariance[(0, 0)].sqrt(),
        exponent_std_error: parameter_covariance[(1, 1)].sqrt(),
        parameter_covariance,
        samples: n,
    })
}

/// The error for a fit whose exponent is not positive.
fn not_decreasing() -> PositioningError {
    PositioningError::NoConsistentSolution {
        reason: "the fitted path-loss exponent is not positive: rssi does not fall with distance in \
                 these samples; check the distances and the anchor assignment",
    }
}

#[cfg(test)]
#[path = "calibration_tests.rs"]
mod tests;
