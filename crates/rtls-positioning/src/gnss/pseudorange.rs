//! The pseudorange point solver: weighted Gauss–Newton for position and receiver clock bias,
//! with an optional clock prior, DOP and RAIM-style fault detection and exclusion.

use nalgebra::{DMatrix, SMatrix, SVector, Vector3};
use rtls_estimation::stats::chi_square_quantile;

use super::{rotate_for_transit, LocalFrame};
use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::linalg::solve_spd;
use crate::multilateration::{levenberg_marquardt, variance_factor, GaussNewtonOptions, Model, NormalEquations};

/// A receiver closer than this to a satellite is at a singular point of the model, m.
const MIN_SATELLITE_DISTANCE_M: f64 = 1.0;

/// One pseudorange, ready for the solver.
///
/// # Units
/// `satellite_ecef_m` (WGS-84 ECEF at transmit time) and `pseudorange_m` in m (corrected for the
/// satellite clock, ionosphere and troposphere), `variance_m2` in m².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pseudorange {
    /// The satellite's ECEF position at transmit time, m.
    pub satellite_ecef_m: [f64; 3],
    /// The corrected pseudorange, m.
    pub pseudorange_m: f64,
    /// Its variance, m² (> 0).
    pub variance_m2: f64,
}

/// A Gaussian prior on the receiver clock bias `b = c δt`, e.g. a clock filter's prediction.
/// It counts as one more measurement, so three satellites fix a 3-D position (two at a known
/// height).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockPrior {
    /// Predicted bias, m.
    pub mean_m: f64,
    /// Its variance, m² (> 0).
    pub variance_m2: f64,
}

/// Options of [`pseudorange_fix`] and [`pseudorange_fix_at_height`].
///
/// # Example
/// ```
/// use rtls_positioning::gnss::{ClockPrior, PseudorangeOptions};
/// let options = PseudorangeOptions {
///     clock_prior: Some(ClockPrior { mean_m: 3.0e5, variance_m2: 25.0 }),
///     ..PseudorangeOptions::default()
/// };
/// assert_eq!(options.false_alarm_probability, 1e-3);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PseudorangeOptions {
    /// A prior on the clock bias; `None`: the bias is free.
    pub clock_prior: Option<ClockPrior>,
    /// Where the iteration starts, ENU m (a tracker's prediction); `None`: the frame's origin.
    /// Satellites are 20 000 km away, so a start anywhere near the Earth's surface converges.
    pub start_enu_m: Option<[f64; 3]>,
    /// Probability that the χ² residual test fails on fault-free pseudoranges, in (0, 1).
    /// Default `1e-3`.
    pub false_alarm_probability: f64,
    /// Exclude the satellite with the largest standardised residual while the test fails and
    /// redundancy remains. Default true.
    pub exclude_faults: bool,
    /// Accepted Gauss–Newton steps allowed per solve (≥ 1). Default 50.
    pub max_iterations: usize,
    /// Stop when a step is shorter than this, m (> 0). Default `1e-4`.
    pub tolerance_m: f64,
}

impl Default for PseudorangeOptions {
    fn default() -> Self {
        Self {
            clock_prior: None,
            start_enu_m: None,
            false_alarm_probability: 1e-3,
            exclude_faults: true,
            max_iterations: 50,
            tolerance_m: 1e-4,
        }
    }
}

/// Dilution of precision of a pseudorange geometry (unitless; position and clock standard
/// deviations are `DOP × σ` for equal, independent pseudorange errors).
///
/// With the rows `[−u_iᵀ, 1]` of `H` (`u_i` the unit line of sight to satellite `i` in ENU) and
/// `G = (HᵀH)⁻¹`: `GDOP = √tr G`, `PDOP = √(G_ee + G_nn + G_uu)`, `HDOP = √(G_ee + G_nn)`,
/// `VDOP = √G_uu`, `TDOP = √G_bb`.
///
/// # References
/// Misra & Enge, *Global Positioning System*, 2nd ed., 2006 (DOP); Kaplan & Hegarty,
/// *Understanding GPS/GNSS*, 3rd ed., 2017, §11.2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssDop {
    /// Geometric DOP (position and clock).
    pub gdop: f64,
    /// Position DOP (the horizontal one at a known height).
    pub pdop: f64,
    /// Horizontal DOP.
    pub hdop: f64,
    /// Vertical DOP; `None` at a known height.
    pub vdop: Option<f64>,
    /// Time (clock) DOP.
    pub tdop: f64,
}

/// The outcome of the χ² residual test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrity {
    /// The residuals are consistent with the stated noise (after any exclusions).
    Passed,
    /// The test fails and no exclusion is possible (too little redundancy, or exclusion off):
    /// the covariance is inflated by the variance factor, but a fault may remain.
    Failed,
    /// No redundancy (`dof = 0`): nothing can be tested.
    Untestable,
}

/// The result of [`pseudorange_fix`] (`D = 3`) and [`pseudorange_fix_at_height`] (`D = 2`).
#[derive(Debug, Clone, PartialEq)]
pub struct PseudorangeSolution<const D: usize> {
    /// Position in the local frame (ENU, m; east and north at a known height) and its marginal
    /// covariance (m²), `σ̂₀²`-inflated like [`Self::covariance_m2`].
    pub fix: Fix<D>,
    /// Receiver clock bias `b = c δt`, m.
    pub clock_bias_m: f64,
    /// Its marginal variance, m².
    pub clock_variance_m2: f64,
    /// The joint covariance of `[position, b]`, `(D + 1) × (D + 1)`, m²:
    /// `σ̂₀² (HᵀWH)⁻¹` at the solution, the clock prior included in `HᵀWH`.
    pub covariance_m2: DMatrix<f64>,
    /// DOP of the satellites used; `None` when they alone do not determine `[p, b]` (the clock
    /// prior made up the difference).
    pub dop: Option<GnssDop>,
    /// `ρ_i − ‖s'_i − p‖ − b` at the solution for every input pseudorange (excluded ones
    /// included), m.
    pub residuals_m: Vec<f64>,
    /// Indices of the excluded pseudoranges, in the order they were excluded.
    pub excluded: Vec<usize>,
    /// `χ² = Σ e_i²/σ_i²` over the used pseudoranges plus the clock prior's term.
    pub chi_square: f64,
    /// Measurements used (pseudoranges, plus one for a clock prior) minus `D + 1`.
    pub degrees_of_freedom: usize,
    /// `σ̂₀² = max(1, χ²/dof)` (1 without redundancy), applied to the covariance.
    pub variance_factor: f64,
    /// The residual test's outcome.
    pub integrity: Integrity,
    /// Gauss–Newton steps of the last solve.
    pub iterations: usize,
}

/// The 3-D fix: position (ENU in `frame`) and receiver clock bias from pseudoranges.
///
/// With `p` the ECEF position of the ENU point `x`, `s'_i` the Sagnac-corrected satellite
/// ([`super::earth_rotation_correction`]), `u_i = R (s'_i − p)/‖s'_i − p‖` in ENU and
/// `W = diag(1/σ_i²)`:
/// ```text
/// ρ̂_i(x, b) = ‖s'_i − p(x)‖ + b
/// H_i = [−u_iᵀ, 1]                              (∂ρ̂_i/∂[x, b]; s'_i's own dependence on x,
///                                                 of relative size ω_E‖s‖/c ≈ 10⁻⁵, is left out)
/// prior (optional): b̄ = b + v_b, v_b ~ N(0, σ_b²), row [0, 0, 0, 1]
/// [δx, δb] = (HᵀWH + μ D)⁻¹ HᵀW (ρ − ρ̂)         Levenberg–Marquardt damped Gauss–Newton
/// χ² = Σ (ρ_i − ρ̂_i)²/σ_i² (+ (b̄ − b)²/σ_b²),   dof = m − 4
/// P = σ̂₀² (HᵀWH)⁻¹,  σ̂₀² = max(1, χ²/dof)
/// ```
/// Start: `start_enu_m` (or the origin) and the prior's mean, or without a prior the median
/// of `ρ_i − ‖s'_i − p₀‖`; Gauss–Newton converges from anywhere near the Earth's surface.
///
/// Fault detection and exclusion (when `exclude_faults`): while `χ² > χ²_{1−P_fa}(dof)` and
/// `dof ≥ 2`, the pseudorange with the largest standardised residual
/// `|e_i| / √(σ_i² − h_iᵀ (HᵀWH)⁻¹ h_i)` (Baarda's w-test) is excluded and the fix solved
/// again from the previous one. [`PseudorangeSolution::integrity`] reports the final test.
///
/// # Units
/// ECEF and ENU positions, pseudoranges and the clock bias in m; variances in m².
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than 4 pseudoranges (3 with a clock
///   prior);
/// - [`PositioningError::NonFiniteEntry`] for a NaN/∞ satellite coordinate or pseudorange
///   (row = pseudorange); [`PositioningError::InvalidParameter`] for a variance `≤ 0` or bad
///   options;
/// - [`PositioningError::DegenerateGeometry`] when `HᵀWH` is singular (satellites in a line, or
///   the iteration reaches a satellite);
/// - [`PositioningError::DidNotConverge`] after `max_iterations` steps.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use rtls_positioning::gnss::{earth_rotation_correction, pseudorange_fix, Geodetic, LocalFrame, Pseudorange, PseudorangeOptions};
/// let frame = LocalFrame::new(Geodetic { latitude_deg: 47.0, longitude_deg: 8.0, height_m: 400.0 })?;
/// let truth = Vector3::new(120.0, -40.0, 2.0); // ENU, m
/// let receiver = frame.ecef_from_enu(&truth);
/// let satellites = [[15.6e6, 7.5e6, 20.1e6], [-2.0e6, 14.0e6, 22.0e6], [20.0e6, -6.0e6, 16.0e6], [10.0e6, 18.0e6, 14.0e6], [22.0e6, 9.0e6, 10.0e6]];
/// let clock_m = 3.0e5;
/// let observations: Vec<Pseudorange> = satellites.iter().map(|s| {
///     let s = Vector3::from(*s);
///     let corrected = earth_rotation_correction(&s, &receiver).unwrap();
///     Pseudorange { satellite_ecef_m: *s.as_ref(), pseudorange_m: (corrected - receiver).norm() + clock_m, variance_m2: 9.0 }
/// }).collect();
/// let solution = pseudorange_fix(&frame, &observations, &PseudorangeOptions::default())?;
/// assert!((solution.fix.position - truth).norm() < 1e-3);
/// assert!((solution.clock_bias_m - clock_m).abs() < 1e-3);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Misra & Enge, *Global Positioning System*, 2nd ed., 2006 (the linearised pseudorange
/// solution and its covariance); W. Baarda, *A testing procedure for use in geodetic
/// networks*, 1968 (w-test); Brown (1992) (RAIM); P. J. G. Teunissen, *Adjustment Theory*,
/// 2000, §4.4 (variance factor).
pub fn pseudorange_fix(
    frame: &LocalFrame,
    observations: &[Pseudorange],
    options: &PseudorangeOptions,
) -> Result<PseudorangeSolution<3>> {
    solve_with_exclusion::<4, 3>(frame, observations, None, options)
}

/// The planar fix at a known height: east, north and clock bias from pseudoranges, with the
/// receiver at `height_m` on the ENU `z` axis of `frame` (a site whose tags move on a plane).
///
/// The model and the fault exclusion are those of [`pseudorange_fix`] with `p = (x, y, h)`,
/// rows `H_i = [−u_e, −u_n, 1]` and `dof = m − 3`; fixing the height removes the weakest
/// direction of GNSS (VDOP) and one unknown, so three pseudoranges (two with a clock prior)
/// suffice.
///
/// # Errors
/// As [`pseudorange_fix`], with 3 pseudoranges needed (2 with a clock prior), and
/// [`PositioningError::NonFinite`] for a NaN/∞ height.
///
/// # References
/// As [`pseudorange_fix`]; Misra & Enge (2006) (height aiding).
pub fn pseudorange_fix_at_height(
    frame: &LocalFrame,
    observations: &[Pseudorange],
    height_m: f64,
    options: &PseudorangeOptions,
) -> Result<PseudorangeSolution<2>> {
    if !height_m.is_finite() {
        return Err(PositioningError::NonFinite { what: "known height" });
    }
    solve_with_exclusion::<3, 2>(frame, observations, Some(height_m), options)
}

/// Checks inputs and options, and that there are enough pseudoranges for `unknowns`.
fn validate(observations: &[Pseudorange], unknowns: usize, options: &PseudorangeOptions) -> Result<()> {
    for (row, o) in observations.iter().enumerate() {
        if let Some(column) = o.satellite_ecef_m.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: "satellite positions (row = pseudorange, column = axis)",
                row,
                column,
            });
        }
        if !o.pseudorange_m.is_finite() {
            return Err(PositioningError::NonFiniteEntry {
                what: "pseudoranges (row = pseudorange)",
                row,
                column: 0,
            });
        }
        if !(o.variance_m2.is_finite() && o.variance_m2 > 0.0) {
            return Err(PositioningError::InvalidParameter {
                name: "variance_m2",
                reason: "every pseudorange variance must be finite and > 0",
            });
        }
    }
    if let Some(prior) = options.clock_prior {
        if !(prior.mean_m.is_finite() && prior.variance_m2.is_finite() && prior.variance_m2 > 0.0) {
            return Err(PositioningError::InvalidParameter {
                name: "clock_prior",
                reason: "the clock prior needs a finite mean and a finite variance > 0",
            });
        }
    }
    if options.start_enu_m.is_some_and(|s| !s.iter().all(|v| v.is_finite())) {
        return Err(PositioningError::NonFinite { what: "start position" });
    }
    if !(options.false_alarm_probability > 0.0 && options.false_alarm_probability < 1.0) {
        return Err(PositioningError::InvalidParameter {
            name: "false_alarm_probability",
            reason: "must lie in (0, 1), e.g. 1e-3",
        });
    }
    if !(options.tolerance_m.is_finite() && options.tolerance_m > 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "tolerance_m",
            reason: "must be finite and > 0, e.g. 1e-4 m",
        });
    }
    let needed = unknowns - usize::from(options.clock_prior.is_some());
    if observations.len() < needed {
        return Err(PositioningError::Underdetermined {
            anchors: observations.len(),
            needed,
        });
    }
    Ok(())
}

/// `Σ (ρ_i − ρ̂_i)²/σ_i² (+ prior)` over the `active` pseudoranges, in the unknowns
/// `x = [e, n, (u,) b]` (`U = 4`) or `[e, n, b]` at a known height (`U = 3`).
struct PseudorangeModel<'a, const U: usize> {
    frame: &'a LocalFrame,
    observations: &'a [Pseudorange],
    active: &'a [usize],
    height_m: Option<f64>,
    prior: Option<ClockPrior>,
}

impl<const U: usize> PseudorangeModel<'_, U> {
    /// The ENU position of the unknowns.
    fn enu(&self, x: &SVector<f64, U>) -> Vector3<f64> {
        match self.height_m {
            Some(h) => Vector3::new(x[0], x[1], h),
            None => Vector3::new(x[0], x[1], x[2]),
        }
    }

    /// `(ρ̂_i − b, H_i)`: the geometric range to the Sagnac-corrected satellite and the row.
    fn range_and_row(&self, receiver_ecef: &Vector3<f64>, o: &Pseudorange) -> Result<(f64, SVector<f64, U>)> {
        // s' = R_z(ω_E τ) s
        let satellite = rotate_for_transit(&Vector3::from(o.satellite_ecef_m), receiver_ecef);
        let line = satellite - receiver_ecef;
        let distance = line.norm();
        if distance.is_nan() || distance <= MIN_SATELLITE_DISTANCE_M {
            return Err(PositioningError::DegenerateGeometry {
                reason: "the receiver position reached a satellite; check the satellite positions",
            });
        }
        // u = R (s' − p)/‖s' − p‖ in ENU;  H_i = [−u_e, −u_n, (−u_u,) 1]
        let u = self.frame.rotation() * line / distance;
        let mut row = SVector::<f64, U>::zeros();
        for axis in 0..U - 1 {
            row[axis] = -u[axis];
        }
        row[U - 1] = 1.0;
        Ok((distance, row))
    }
}

impl<const U: usize> Model<U> for PseudorangeModel<'_, U> {
    fn normal_equations(&self, x: &SVector<f64, U>) -> Result<NormalEquations<U>> {
        let receiver = self.frame.ecef_from_enu(&self.enu(x));
        let bias = x[U - 1];
        let mut normal = NormalEquations::zero();
        for &i in self.active {
            let o = &self.observations[i];
            let (distance, row) = self.range_and_row(&receiver, o)?;
            // e_i = ρ_i − (‖s'_i − p‖ + b),  w_i = 1/σ_i²
            normal.add(o.pseudorange_m - distance - bias, &row, 1.0 / o.variance_m2);
        }
        if let Some(prior) = self.prior {
            // e_b = b̄ − b,  row [0, …, 0, 1],  w_b = 1/σ_b²
            let mut row = SVector::<f64, U>::zeros();
            row[U - 1] = 1.0;
            normal.add(prior.mean_m - bias, &row, 1.0 / prior.variance_m2);
        }
        Ok(normal)
    }
}

/// One solve on the `active` set from `start`: the minimum and `(HᵀWH)⁻¹` there.
fn solve_once<const U: usize>(
    model: &PseudorangeModel<'_, U>,
    start: SVector<f64, U>,
    options: &PseudorangeOptions,
) -> Result<(SVector<f64, U>, NormalEquations<U>, SMatrix<f64, U, U>, usize)> {
    let solver = GaussNewtonOptions {
        max_iterations: options.max_iterations,
        relative_tolerance: 0.5,
    };
    solver.validate()?;
    let minimum = levenberg_marquardt(model, start, options.tolerance_m, &solver)?;
    // (HᵀWH)⁻¹
    let (_, inverse) = solve_spd(
        &minimum.normal.information,
        &SVector::zeros(),
        "the pseudorange normal matrix HᵀWH is singular (satellites in a line or too few for the unknowns)",
    )?;
    Ok((minimum.position, minimum.normal, inverse, minimum.iterations))
}

/// The start: the caller's position (or the origin) and the prior's mean, or the median of
/// `ρ_i − ‖s'_i − p₀‖`.
fn start<const U: usize>(model: &PseudorangeModel<'_, U>, options: &PseudorangeOptions) -> Result<SVector<f64, U>> {
    let enu = options.start_enu_m.unwrap_or([0.0; 3]);
    let mut x = SVector::<f64, U>::zeros();
    for axis in 0..U - 1 {
        x[axis] = enu[axis];
    }
    x[U - 1] = match options.clock_prior {
        Some(prior) => prior.mean_m,
        None => {
            let receiver = model.frame.ecef_from_enu(&model.enu(&x));
            let mut offsets = model
                .active
                .iter()
                .map(|&i| {
                    let o = &model.observations[i];
                    model.range_and_row(&receiver, o).map(|(d, _)| o.pseudorange_m - d)
                })
                .collect::<Result<Vec<f64>>>()?;
            offsets.sort_by(f64::total_cmp);
            offsets[offsets.len() / 2]
        }
    };
    Ok(x)
}

fn solve_with_exclusion<const U: usize, const D: usize>(
    frame: &LocalFrame,
    observations: &[Pseudorange],
    height_m: Option<f64>,
    options: &PseudorangeOptions,
) -> Result<PseudorangeSolution<D>> {
    debug_assert_eq!(U, D + 1);
    validate(observations, U, options)?;
    let mut active: Vec<usize> = (0..observations.len()).collect();
    let mut excluded = Vec::new();
    let mut x: Option<SVector<f64, U>> = None;
    loop {
        let model = PseudorangeModel::<U> {
            frame,
            observations,
            active: &active,
            height_m,
            prior: options.clock_prior,
        };
        let from = match x {
            Some(previous) => previous,
            None => start(&model, options)?,
        };
        let (solution, normal, inverse, iterations) = solve_once(&model, from, options)?;
        x = Some(solution);
        let measurements = active.len() + usize::from(options.clock_prior.is_some());
        let dof = measurements - U;
        let chi_square = normal.cost;
        let integrity = if dof == 0 {
            Integrity::Untestable
        } else {
            let threshold = chi_square_quantile(1.0 - options.false_alarm_probability, dof as f64).map_err(|_| {
                PositioningError::InvalidParameter {
                    name: "false_alarm_probability",
                    reason: "no chi-square quantile for this probability",
                }
            })?;
            if chi_square <= threshold {
                Integrity::Passed
            } else {
                Integrity::Failed
            }
        };
        if integrity == Integrity::Failed && options.exclude_faults && dof >= 2 {
            let worst = worst_standardised(&model, &solution, &inverse)?;
            excluded.push(active.remove(worst));
            continue;
        }
        return finish::<U, D>(
            &model,
            &solution,
            &inverse,
            Summary {
                chi_square,
                dof,
                integrity,
                iterations,
                excluded,
            },
        );
    }
}

/// The position in `active` of the pseudorange with the largest `|e_i| / √(σ_i² − h_iᵀ N⁻¹ h_i)`.
fn worst_standardised<const U: usize>(
    model: &PseudorangeModel<'_, U>,
    x: &SVector<f64, U>,
    inverse: &SMatrix<f64, U, U>,
) -> Result<usize> {
    let receiver = model.frame.ecef_from_enu(&model.enu(x));
    let mut worst = (0, f64::NEG_INFINITY);
    for (k, &i) in model.active.iter().enumerate() {
        let o = &model.observations[i];
        let (distance, row) = model.range_and_row(&receiver, o)?;
        // e_i = ρ_i − ρ̂_i,  Q_e,ii = σ_i² − h_iᵀ N⁻¹ h_i (floored: a satellite that alone fixes an
        // unknown has no testable residual)
        let residual = o.pseudorange_m - distance - x[U - 1];
        let redundancy = (o.variance_m2 - (row.transpose() * inverse * row)[0]).max(1e-12 * o.variance_m2);
        let w = residual.abs() / redundancy.sqrt();
        if w > worst.1 {
            worst = (k, w);
        }
    }
    Ok(worst.0)
}

/// The test's numbers, carried to [`finish`].
struct Summary {
    chi_square: f64,
    dof: usize,
    integrity: Integrity,
    iterations: usize,
    excluded: Vec<usize>,
}

/// Builds the solution: covariance `σ̂₀² N⁻¹`, residuals of every pseudorange, DOP.
fn finish<const U: usize, const D: usize>(
    model: &PseudorangeModel<'_, U>,
    x: &SVector<f64, U>,
    inverse: &SMatrix<f64, U, U>,
    summary: Summary,
) -> Result<PseudorangeSolution<D>> {
    let factor = variance_factor(summary.chi_square, summary.dof);
    // P = σ̂₀² N⁻¹, symmetrised against round-off
    let covariance = (inverse + inverse.transpose()) * (0.5 * factor);
    let receiver = model.frame.ecef_from_enu(&model.enu(x));
    let bias = x[U - 1];
    let mut residuals_m = Vec::with_capacity(model.observations.len());
    let mut geometry = SMatrix::<f64, U, U>::zeros();
    for (i, o) in model.observations.iter().enumerate() {
        let (distance, row) = model.range_and_row(&receiver, o)?;
        // e_i = ρ_i − ‖s'_i − p‖ − b
        residuals_m.push(o.pseudorange_m - distance - bias);
        if !summary.excluded.contains(&i) {
            // HᵀH (unweighted)
            geometry += row * row.transpose();
        }
    }
    let dop = dop::<U>(&geometry, model.height_m.is_none());
    let fix = Fix {
        position: SVector::<f64, D>::from_fn(|i, _| x[i]),
        covariance: SMatrix::<f64, D, D>::from_fn(|i, j| covariance[(i, j)]),
    }
    .checked()?;
    let clock_variance_m2 = covariance[(U - 1, U - 1)];
    if !(bias.is_finite() && clock_variance_m2.is_finite() && summary.chi_square.is_finite())
        || residuals_m.iter().any(|r| !r.is_finite())
    {
        return Err(PositioningError::NonFinite {
            what: "pseudorange solution",
        });
    }
    Ok(PseudorangeSolution {
        fix,
        clock_bias_m: bias,
        clock_variance_m2,
        covariance_m2: DMatrix::from_fn(U, U, |i, j| covariance[(i, j)]),
        dop,
        residuals_m,
        excluded: summary.excluded,
        chi_square: summary.chi_square,
        degrees_of_freedom: summary.dof,
        variance_factor: factor,
        integrity: summary.integrity,
        iterations: summary.iterations,
    })
}

/// DOP from `HᵀH`; `None` when it is singular.
fn dop<const U: usize>(geometry: &SMatrix<f64, U, U>, vertical: bool) -> Option<GnssDop> {
    // G = (HᵀH)⁻¹
    let (_, g) = solve_spd(geometry, &SVector::zeros(), "dop").ok()?;
    let horizontal = g[(0, 0)] + g[(1, 1)];
    let vertical_variance = if vertical { g[(2, 2)] } else { 0.0 };
    let clock = g[(U - 1, U - 1)];
    Some(GnssDop {
        // GDOP = √tr G
        gdop: g.trace().max(0.0).sqrt(),
        // PDOP = √(G_ee + G_nn + G_uu)
        pdop: (horizontal + vertical_variance).max(0.0).sqrt(),
        // HDOP = √(G_ee + G_nn)
        hdop: horizontal.max(0.0).sqrt(),
        // VDOP = √G_uu
        vdop: vertical.then(|| vertical_variance.max(0.0).sqrt()),
        // TDOP = √G_bb
        tdop: clock.max(0.0).sqrt(),
    })
}
