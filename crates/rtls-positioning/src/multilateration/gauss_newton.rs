//! Maximum-likelihood multilateration from ranges: weighted Gauss–Newton with
//! Levenberg–Marquardt damping.

use nalgebra::SVector;

use super::linear::{resolve_reference, solve, ReferenceAnchor};
use super::solver::{finish, levenberg_marquardt, GaussNewtonFix, GaussNewtonOptions, Initial, Model, NormalEquations};
use super::validate::{self, unit_from};
use crate::error::Result;

/// Maximum-likelihood position from ranges (TOA, ultrasonic time of flight, RSSI-derived
/// distances) with independent Gaussian errors of known variances, in 2-D or 3-D.
///
/// With `d_i(p) = ‖p − a_i‖` and `u_i = (p − a_i)/d_i` (the rows of the Jacobian `J`),
/// `W = diag(1/σ_i²)`:
/// ```text
/// cost(p) = Σ (r_i − d_i(p))² / σ_i²                 (the negative log-likelihood, ×2)
/// δ = (JᵀWJ + μ tr(JᵀWJ)/D · I)⁻¹ JᵀW (r − d(p))     Gauss–Newton step, Levenberg–Marquardt damped
/// α* = −c'(0) / (2 (c(1) − c(0) − c'(0)))              quadratic interpolation of the cost along δ
/// p ← p + α δ with the better of α = 1 and α* if the cost does not increase (μ ← μ/10),
///     else μ ← 10 μ and retry
/// stop when ‖α δ‖ < relative_tolerance · (anchor spread), or when no step lowers the cost
/// χ² = cost at the solution,  dof = N − D
/// σ̂₀² = max(1, χ²/dof) if dof > 0, else 1             a-posteriori variance factor
/// P = σ̂₀² (JᵀWJ)⁻¹ at the solution                    (the Cramér–Rao bound there, inflated)
/// GDOP = √tr((JᵀJ)⁻¹) with unit rows u_i              (geometry only)
/// ```
/// The a-posteriori variance factor keeps the covariance honest when the residuals are larger
/// than the stated noise (NLOS, a wrong `σ`): `(JᵀWJ)⁻¹` alone trusts the a-priori variances
/// whatever the data say. It never shrinks the covariance below the a-priori one (residuals
/// smaller than expected are no evidence of better ranges at a handful of redundant
/// measurements); [`GaussNewtonFix::variance_factor`] reports the factor applied.
///
/// Negative ranges are accepted: a range is a noisy `r = d + e ≥ −∞`, and close to an anchor
/// Wi-Fi FTM / RTT (or a bias-corrected UWB range) can be negative; the cost weighs it like any
/// other value. The linear start squares ranges, so it uses `max(r, 0)`.
/// The interpolated step matters where one direction is weakly determined (height, with all
/// anchors near one plane): there the neglected second-order term `Σ w_i e_i ∇²d_i` is
/// comparable to `JᵀWJ`, and plain Gauss–Newton oscillates and converges slowly (often beyond
/// 100 iterations at σ = 10 cm in a room); with the interpolation it takes about ten.
///
/// The start is the weighted linear least-squares fix ([`Initial::Linear`], needs `D + 1`
/// anchors spanning the space) or a caller's guess ([`Initial::Guess`], e.g. a tracker's
/// prediction; `D` anchors suffice and collinear/coplanar anchors are accepted, the guess
/// choosing the side of the mirror ambiguity). A large `χ²` (above the `χ²(dof)` quantile of
/// the caller's false-alarm rate) flags an NLOS or otherwise inconsistent range.
///
/// # Units
/// Anchors, ranges and the fix in m; variances and the covariance in m².
///
/// # Errors
/// - [`crate::PositioningError::Underdetermined`] for fewer than `D + 1` anchors (`D` with a
///   guess);
/// - [`crate::PositioningError::DimensionMismatch`] unless there is one range and one variance
///   per anchor;
/// - [`crate::PositioningError::NonFiniteEntry`] for a NaN/∞ anchor coordinate, range or
///   variance; [`crate::PositioningError::NonFinite`] for a NaN/∞ guess;
/// - [`crate::PositioningError::InvalidParameter`] for a variance `≤ 0` or invalid options;
/// - [`crate::PositioningError::DuplicateAnchors`] for two anchors at one position;
/// - [`crate::PositioningError::DegenerateGeometry`] for collinear/coplanar anchors (linear
///   start), a start at an anchor, or a singular `JᵀWJ` at the solution;
/// - [`crate::PositioningError::DidNotConverge`] after `options.max_iterations` steps.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::{gauss_newton, GaussNewtonOptions, Initial};
/// // seed 003's 4 m × 6 m ultrasonic test bed (m), a robot at (1.3, 2.2)
/// let nodes = [[0.0, 0.0], [4.0, 0.0], [0.0, 6.0], [4.0, 6.0], [2.0, 3.0]];
/// let truth = Vector2::new(1.3, 2.2);
/// let ranges: Vec<f64> = nodes.iter().map(|a| (truth - Vector2::from(*a)).norm()).collect();
/// let variances = [0.0004; 5]; // σ = 2 cm
/// let solution = gauss_newton(&nodes, &ranges, &variances, Initial::Linear, &GaussNewtonOptions::default())?;
/// assert!((solution.fix.position - truth).norm() < 1e-9);
/// assert!(solution.chi_square < 1e-12 && solution.degrees_of_freedom == 3);
/// // P = σ² (JᵀJ)⁻¹ for equal variances: DRMS = σ · GDOP
/// assert!((solution.fix.drms_m() - 0.02 * solution.gdop).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// W. H. Foy, "Position-location solutions by Taylor-series estimation", *IEEE Trans. AES*
/// 12(2), 1976 (the linearised iteration); D. J. Torrieri, "Statistical theory of passive location
/// systems", *IEEE Trans. AES* 20(2), 1984, §II (ML estimator and its covariance);
/// K. Levenberg, *Q. Appl. Math.* 2(2), 1944; D. W. Marquardt, *J. SIAM* 11(2), 1963 (damping);
/// J. Nocedal, S. J. Wright, *Numerical Optimization*, 2nd ed., 2006, §3.5 (interpolating line
/// search) and §10.3 (Gauss–Newton's linear convergence on large-residual problems);
/// P. J. G. Teunissen, *Adjustment Theory*, Delft, 2000, §4.4 (the a-posteriori variance
/// factor `σ̂₀² = êᵀ W ê / (m − n)`);
/// seed 003 (multi-point LS multilateration baseline).
pub fn gauss_newton<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    variances_m2: &[f64],
    initial: Initial<D>,
    options: &GaussNewtonOptions,
) -> Result<GaussNewtonFix<D>> {
    options.validate()?;
    let scale = match initial {
        Initial::Linear => validate::anchors(anchors_m, D + 1, true)?,
        Initial::Guess(_) => validate::anchors(anchors_m, D, false)?,
    };
    let n = anchors_m.len();
    validate::signed_ranges(ranges_m, n, "ranges (one per anchor)")?;
    validate::variances(variances_m2, n, "variances_m2", "range variances (one per anchor)")?;
    let start = match initial {
        Initial::Linear => {
            // the differenced equations square the ranges: a negative range means "close", r⁺ = max(r, 0)
            let clamped: Vec<f64> = ranges_m.iter().map(|r| r.max(0.0)).collect();
            let reference = resolve_reference(ReferenceAnchor::NearestRange, &clamped)?;
            solve(anchors_m, &clamped, Some(variances_m2), reference)?.0
        }
        Initial::Guess(p) => {
            validate::finite_point(&p, "initial position")?;
            p
        }
    };
    let model = Ranges {
        anchors_m,
        ranges_m,
        variances_m2,
        floor_m: scale.coincidence_m,
    };
    let minimum = levenberg_marquardt(&model, start, options.relative_tolerance * scale.spread_m, options)?;
    finish(&minimum, anchors_m.iter(), n, scale.coincidence_m)
}

/// `Σ (r_i − ‖p − a_i‖)² / σ_i²` on validated inputs.
pub(crate) struct Ranges<'a, const D: usize> {
    pub(crate) anchors_m: &'a [[f64; D]],
    pub(crate) ranges_m: &'a [f64],
    pub(crate) variances_m2: &'a [f64],
    /// Distances at or below this count as "at an anchor" (m).
    pub(crate) floor_m: f64,
}

impl<const D: usize> Model<D> for Ranges<'_, D> {
    fn normal_equations(&self, p: &SVector<f64, D>) -> Result<NormalEquations<D>> {
        let mut normal = NormalEquations::zero();
        for ((a, &r), &variance) in self.anchors_m.iter().zip(self.ranges_m).zip(self.variances_m2) {
            // d_i = ‖p − a_i‖,  J_i = u_iᵀ = (p − a_i)ᵀ/d_i
            let (u, d) = unit_from(p, a, self.floor_m)?;
            // e_i = r_i − d_i,  w_i = 1/σ_i²
            normal.add(r - d, &u, 1.0 / variance);
        }
        Ok(normal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::PositioningError;
    use nalgebra::{Vector2, Vector3};

    fn ranges_to<const D: usize>(anchors: &[[f64; D]], p: &SVector<f64, D>) -> Vec<f64> {
        anchors.iter().map(|a| (p - SVector::from(*a)).norm()).collect()
    }

    #[test]
    fn recovers_the_truth_from_a_far_guess_and_reports_diagnostics() {
        let anchors = [
            [0.0, 0.0, 0.0],
            [20.0, 0.0, 1.0],
            [0.0, 20.0, 2.0],
            [10.0, 10.0, 6.0],
            [20.0, 20.0, 0.5],
        ];
        let truth = Vector3::new(7.0, 11.0, 1.2);
        let r = ranges_to(&anchors, &truth);
        let solution = gauss_newton(
            &anchors,
            &r,
            &[0.01; 5],
            Initial::Guess(Vector3::new(15.0, 2.0, 3.0)),
            &GaussNewtonOptions::default(),
        )
        .unwrap();
        assert!((solution.fix.position - truth).norm() < 1e-9);
        assert!(solution.iterations >= 2);
        assert_eq!(solution.degrees_of_freedom, 2);
        assert!(solution.reduced_chi_square().unwrap() < 1e-12);
        // equal variances: P = σ² (JᵀJ)⁻¹, so tr P = σ² GDOP²
        assert!((solution.fix.covariance.trace() - 0.01 * solution.gdop * solution.gdop).abs() < 1e-12);
    }

    #[test]
    fn a_guess_resolves_the_mirror_ambiguity_of_two_anchors() {
        // seed 001: two base stations in the plane; the tracker's prediction picks the side
        let anchors = [[2.0, 2.0], [20.0, 40.0]];
        let truth = Vector2::new(12.0, 10.0);
        let r = ranges_to(&anchors, &truth);
        let options = GaussNewtonOptions::default();
        let solution = gauss_newton(
            &anchors,
            &r,
            &[0.01; 2],
            Initial::Guess(Vector2::new(14.0, 8.0)),
            &options,
        )
        .unwrap();
        assert!((solution.fix.position - truth).norm() < 1e-9);
        assert_eq!(solution.degrees_of_freedom, 0);
        assert_eq!(solution.reduced_chi_square(), None);
        // but not without a guess
        assert_eq!(
            gauss_newton(&anchors, &r, &[0.01; 2], Initial::Linear, &options).unwrap_err(),
            PositioningError::Underdetermined { anchors: 2, needed: 3 }
        );
    }

    #[test]
    fn errors() {
        let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        let r = [5.0, 8.0, 8.0];
        let v = [1.0; 3];
        let options = GaussNewtonOptions::default();
        assert!(matches!(
            gauss_newton(
                &[[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]],
                &r,
                &v,
                Initial::Linear,
                &options
            ),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert!(matches!(
            gauss_newton(&anchors, &r, &v, Initial::Guess(Vector2::new(f64::NAN, 0.0)), &options),
            Err(PositioningError::NonFinite { .. })
        ));
        assert!(matches!(
            gauss_newton(&anchors, &r, &v, Initial::Guess(Vector2::new(10.0, 0.0)), &options),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert!(matches!(
            gauss_newton(&anchors, &r, &[1.0, -1.0, 1.0], Initial::Linear, &options),
            Err(PositioningError::InvalidParameter {
                name: "variances_m2",
                ..
            })
        ));
        assert!(matches!(
            gauss_newton(&anchors, &r[..2], &v, Initial::Linear, &options),
            Err(PositioningError::DimensionMismatch { .. })
        ));
        let bad = GaussNewtonOptions {
            max_iterations: 0,
            ..options
        };
        assert!(matches!(
            gauss_newton(&anchors, &r, &v, Initial::Linear, &bad),
            Err(PositioningError::InvalidParameter { .. })
        ));
        // guess on the line of two anchors, ranges consistent with a point on that line:
        // JᵀWJ singular at the solution
        let line = [[0.0, 0.0], [10.0, 0.0]];
        assert!(matches!(
            gauss_newton(
                &line,
                &[4.0, 6.0],
                &[1.0; 2],
                Initial::Guess(Vector2::new(3.0, 0.0)),
                &options
            ),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
    }
}
