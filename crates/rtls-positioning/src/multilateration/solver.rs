//! The weighted Gauss–Newton / Levenberg–Marquardt engine shared by the range and TOA + RSS
//! solvers, its options, its starting point and its result.

use nalgebra::{SMatrix, SVector};

use super::dop::dop_at;
use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::linalg::solve_spd;

/// Damping attempts per iteration before the current point is declared a minimum.
const MAX_DAMPING_ATTEMPTS: usize = 40;

/// Largest step scale `α` of the interpolating line search (extrapolation limit).
const MAX_STEP_SCALE: f64 = 4.0;

/// The line search tries `α*` only when it differs from 1 by more than this.
const LINE_SEARCH_TRIGGER: f64 = 0.1;

/// A step that lowers the cost by less than this fraction of it ends the iteration: the
/// point is a minimum to round-off, even if the step itself is still long (a flat valley,
/// where the position is not determined better than the covariance says anyway).
const FUNCTION_TOLERANCE: f64 = 1e-12;

/// Iteration limit and tolerance of the Gauss–Newton / Levenberg–Marquardt solvers
/// ([`super::gauss_newton`], [`super::toa_rss`], DV-Hop refinement).
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::GaussNewtonOptions;
/// let options = GaussNewtonOptions { max_iterations: 20, ..GaussNewtonOptions::default() };
/// assert_eq!(options.relative_tolerance, 1e-10);
/// ```
///
/// # References
/// K. Madsen, H. B. Nielsen, O. Tingleff, *Methods for non-linear least squares problems*,
/// 2nd ed., DTU, 2004, §3.2 (stopping criteria).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussNewtonOptions {
    /// Accepted steps allowed before [`PositioningError::DidNotConverge`] (≥ 1). Default 100.
    pub max_iterations: usize,
    /// Stop when a step is shorter than `relative_tolerance ×` the anchors' spread (largest
    /// distance from their centroid); in (0, 1). Default `1e-10`.
    pub relative_tolerance: f64,
}

impl Default for GaussNewtonOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            relative_tolerance: 1e-10,
        }
    }
}

impl GaussNewtonOptions {
    /// # Errors
    /// [`PositioningError::InvalidParameter`] for `max_iterations = 0` or a tolerance outside
    /// (0, 1).
    pub(crate) fn validate(&self) -> Result<()> {
        if self.max_iterations == 0 {
            return Err(PositioningError::InvalidParameter {
                name: "max_iterations",
                reason: "at least one iteration is needed",
            });
        }
        if !(self.relative_tolerance > 0.0 && self.relative_tolerance < 1.0) {
            return Err(PositioningError::InvalidParameter {
                name: "relative_tolerance",
                reason: "the relative step tolerance must lie in (0, 1), e.g. 1e-10",
            });
        }
        Ok(())
    }
}

/// Where an iterative solver starts.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::Initial;
/// let from_tracker = Initial::Guess(Vector2::new(3.0, 4.0)); // e.g. a Kalman prediction
/// assert_ne!(from_tracker, Initial::default());
/// ```
///
/// # References
/// Foy (1976), §II (Taylor-series estimation needs an initial guess near the solution).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Initial<const D: usize> {
    /// The weighted linear least-squares fix of the same ranges
    /// ([`super::weighted_linear_least_squares`]). Needs `D + 1` anchors not collinear
    /// (2-D) / coplanar (3-D).
    #[default]
    Linear,
    /// A caller's guess (m), e.g. a tracker's prediction or the previous fix. It also picks
    /// the side of a mirror ambiguity, so `D` anchors (two in the plane, as in seed 001) or
    /// collinear/coplanar anchors are accepted.
    Guess(SVector<f64, D>),
}

/// The result of [`super::gauss_newton`] and [`super::toa_rss`]: the fix with its covariance
/// and the diagnostics a tracker needs to trust or reject it.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::{gauss_newton, GaussNewtonOptions, Initial};
/// let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
/// let ranges = [5.0, 65.0_f64.sqrt(), 45.0_f64.sqrt(), 85.0_f64.sqrt() + 3.0]; // last one NLOS
/// let solution = gauss_newton(&anchors, &ranges, &[0.01; 4], Initial::Linear, &GaussNewtonOptions::default())?;
/// assert_eq!(solution.degrees_of_freedom, 2);
/// // χ² far above its 99.9 % quantile for 2 dof (13.8): inconsistent ranges
/// assert!(solution.chi_square > 13.8);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Torrieri (1984), §II (covariance of the ML fix); seed 003 (NLOS / spurious ultrasonic
/// ranges to be detected).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussNewtonFix<const D: usize> {
    /// Position (m) and covariance `σ̂₀² (JᵀWJ)⁻¹` at the solution (m²): the Cramér–Rao bound
    /// there (a first-order, small-noise estimate), inflated by the a-posteriori variance
    /// factor when the residuals exceed the stated noise.
    pub fix: Fix<D>,
    /// `√tr((UᵀU)⁻¹)` of the unit line-of-sight vectors to the anchors used, at the fix
    /// (geometry only, unweighted; see [`super::gdop`]).
    pub gdop: f64,
    /// Accepted Gauss–Newton steps.
    pub iterations: usize,
    /// Normalised residual `χ² = Σ e_k² / σ_k²` at the fix; `~ χ²(dof)` when the noise model
    /// holds, larger with NLOS or inconsistent measurements.
    pub chi_square: f64,
    /// Degrees of freedom of `chi_square`: scalar measurements minus `D` (0 when exactly
    /// determined).
    pub degrees_of_freedom: usize,
    /// The a-posteriori variance factor `σ̂₀² = max(1, χ²/dof)` (1 when `dof = 0`) by which
    /// `(JᵀWJ)⁻¹` was multiplied: above 1 when the residuals are larger than the stated noise.
    pub variance_factor: f64,
}

impl<const D: usize> GaussNewtonFix<D> {
    /// `χ² / dof` (≈ 1 when consistent), or `None` without redundancy (`dof = 0`).
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_positioning::{multilateration::GaussNewtonFix, Fix2};
    /// let fix = Fix2 { position: Vector2::zeros(), covariance: Matrix2::identity() };
    /// let s = GaussNewtonFix { fix, gdop: 1.0, iterations: 3, chi_square: 6.0, degrees_of_freedom: 3, variance_factor: 2.0 };
    /// assert_eq!(s.reduced_chi_square(), Some(2.0));
    /// ```
    ///
    /// # References
    /// Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and
    /// Navigation*, 2001, §5.4 (consistency tests on normalised residuals).
    #[must_use]
    pub fn reduced_chi_square(&self) -> Option<f64> {
        (self.degrees_of_freedom > 0).then(|| self.chi_square / self.degrees_of_freedom as f64)
    }
}

/// The weighted normal equations of a cost `Σ w_k e_k²` at one point:
/// `cost`, `N = Σ w_k h_k h_kᵀ`, `g = Σ w_k e_k h_k` with `e_k = z_k − h_k(p)` and
/// `h_k = ∂h_k/∂p`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NormalEquations<const D: usize> {
    /// `Σ w_k e_k²` (unitless: χ²).
    pub(crate) cost: f64,
    /// `N = JᵀWJ`.
    pub(crate) information: SMatrix<f64, D, D>,
    /// `g = JᵀW e`.
    pub(crate) gradient: SVector<f64, D>,
}

impl<const D: usize> NormalEquations<D> {
    /// Zero cost, zero information.
    pub(crate) fn zero() -> Self {
        Self {
            cost: 0.0,
            information: SMatrix::zeros(),
            gradient: SVector::zeros(),
        }
    }

    /// Adds one measurement: residual `e`, Jacobian row `h`, weight `w = 1/σ²`.
    #[inline]
    pub(crate) fn add(&mut self, residual: f64, row: &SVector<f64, D>, weight: f64) {
        // cost += w e²,  N += w h hᵀ,  g += w e h
        self.cost += weight * residual * residual;
        self.information += row * row.transpose() * weight;
        self.gradient += row * (weight * residual);
    }
}

/// A weighted nonlinear least-squares problem in a position `p ∈ ℝ^D`.
pub(crate) trait Model<const D: usize> {
    /// The normal equations at `p`; an error where the model is undefined (at an anchor).
    fn normal_equations(&self, p: &SVector<f64, D>) -> Result<NormalEquations<D>>;
}

/// A converged minimum.
pub(crate) struct Minimum<const D: usize> {
    /// The solution (m).
    pub(crate) position: SVector<f64, D>,
    /// Normal equations at the solution.
    pub(crate) normal: NormalEquations<D>,
    /// Accepted steps.
    pub(crate) iterations: usize,
}

/// Minimises the model's cost by Gauss–Newton with Levenberg–Marquardt damping from `start`.
///
/// ```text
/// δ = (N + μ tr(N)/D · I)⁻¹ g              damped Gauss–Newton step
/// α δ, α ∈ {1, α*}                          the better of the full and the interpolated step
///                                           (see line_search)
/// accept it if the cost does not increase (μ ← μ/10), else retry with μ ← 10 μ
/// stop when ‖α δ‖ < tolerance_m, when the cost falls by less than FUNCTION_TOLERANCE × cost,
///     or when no damping lowers the cost (p is a minimum)
/// ```
///
/// # Errors
/// The model's error at `start`; [`PositioningError::DidNotConverge`] after
/// `options.max_iterations` accepted steps.
pub(crate) fn levenberg_marquardt<const D: usize>(
    model: &impl Model<D>,
    start: SVector<f64, D>,
    tolerance_m: f64,
    options: &GaussNewtonOptions,
) -> Result<Minimum<D>> {
    let mut p = start;
    let mut normal = model.normal_equations(&p)?;
    // μ, relative to the mean diagonal of N
    let mut damping = 1e-6;
    for iteration in 1..=options.max_iterations {
        let scale = (normal.information.trace() / D as f64).max(f64::MIN_POSITIVE);
        let mut accepted = None;
        for _ in 0..MAX_DAMPING_ATTEMPTS {
            // (N + μ s I) δ = g
            let damped = normal.information + SMatrix::<f64, D, D>::identity() * (damping * scale);
            let Some(delta) = damped.cholesky().map(|c| c.solve(&normal.gradient)) else {
                damping *= 10.0;
                continue;
            };
            if !delta.iter().all(|v| v.is_finite()) {
                damping *= 10.0;
                continue;
            }
            if let Some((step, next)) = line_search(model, &p, &normal, &delta) {
                accepted = Some((p + step, next, step.norm()));
                damping = (damping / 10.0).max(1e-12);
                break;
            }
            damping *= 10.0;
        }
        let Some((candidate, next, step_m)) = accepted else {
            // no step lowers the cost: p is a (local) minimum
            return Ok(Minimum {
                position: p,
                normal,
                iterations: iteration - 1,
            });
        };
        // Δc = c(p) − c(p + α δ) ≥ 0
        let decrease = normal.cost - next.cost;
        p = candidate;
        normal = next;
        if step_m < tolerance_m || decrease <= FUNCTION_TOLERANCE * normal.cost {
            return Ok(Minimum {
                position: p,
                normal,
                iterations: iteration,
            });
        }
    }
    Err(PositioningError::DidNotConverge {
        iterations: options.max_iterations,
    })
}

/// The better of the full step `δ` and the minimiser `α* δ` of the quadratic through `c(0)`,
/// `c'(0)` and `c(1)` along it, if either does not increase the cost: `(α δ, normal equations
/// there)`.
///
/// ```text
/// c(α) ≈ c₀ + c'₀ α + κ α²,   c'₀ = −2 gᵀδ,   κ = c(1) − c₀ − c'₀
/// α* = −c'₀ / (2κ)   (κ > 0, α* ∈ (0, MAX_STEP_SCALE])
/// ```
/// Plain Gauss–Newton converges only linearly where the neglected second-order term
/// `Σ w_k e_k ∇²h_k` is comparable to `JᵀWJ` (a weakly determined direction, e.g. height
/// with all anchors near one plane), and it then overshoots back and forth (`α* ≈ ½`) or
/// creeps (`α* > 1`); the interpolated step removes the dominant slow mode in one iteration.
fn line_search<const D: usize>(
    model: &impl Model<D>,
    p: &SVector<f64, D>,
    normal: &NormalEquations<D>,
    delta: &SVector<f64, D>,
) -> Option<(SVector<f64, D>, NormalEquations<D>)> {
    let full = model.normal_equations(&(p + delta)).ok();
    let full_cost = full.as_ref().map_or(f64::INFINITY, |n| n.cost);
    // c'₀ = −2 gᵀδ (< 0 for a descent direction)
    let slope = -2.0 * normal.gradient.dot(delta);
    let mut best = full.filter(|n| n.cost <= normal.cost).map(|n| (*delta, n));
    if slope < 0.0 {
        // κ = c(1) − c₀ − c'₀; an infeasible full step (at an anchor) is treated as a large cost
        let curvature = if full_cost.is_finite() {
            full_cost - normal.cost - slope
        } else {
            f64::INFINITY
        };
        // α* = −c'₀ / (2κ); an infinite κ gives a short trial step
        let alpha = if curvature.is_finite() && curvature > 0.0 {
            -slope / (2.0 * curvature)
        } else if curvature.is_infinite() {
            0.5
        } else {
            MAX_STEP_SCALE
        };
        let alpha = alpha.min(MAX_STEP_SCALE);
        if (alpha - 1.0).abs() > LINE_SEARCH_TRIGGER && alpha > 0.0 {
            let scaled = delta * alpha;
            if let Ok(n) = model.normal_equations(&(p + scaled)) {
                let bar = best.as_ref().map_or(normal.cost, |b| b.1.cost);
                if n.cost <= bar {
                    best = Some((scaled, n));
                }
            }
        }
    }
    best
}

/// Builds the result: covariance `σ̂₀² N⁻¹`, GDOP over `anchors_used`, χ² and its dof.
///
/// ```text
/// dof = m − D,   σ̂₀² = max(1, χ²/dof) when dof > 0, else 1
/// P = σ̂₀² N⁻¹
/// ```
///
/// # Errors
/// [`PositioningError::DegenerateGeometry`] if `N` (or `UᵀU`) is singular at the solution;
/// [`PositioningError::NonFinite`] for a non-finite result.
pub(crate) fn finish<'a, const D: usize>(
    minimum: &Minimum<D>,
    anchors_used: impl Iterator<Item = &'a [f64; D]>,
    measurements: usize,
    coincidence_m: f64,
) -> Result<GaussNewtonFix<D>> {
    // (JᵀWJ)⁻¹
    let (_, covariance) = solve_spd(
        &minimum.normal.information,
        &SVector::zeros(),
        "the information matrix JᵀWJ is singular at the fix (the fix lies on the line or plane of the anchors)",
    )?;
    if !minimum.normal.cost.is_finite() {
        return Err(PositioningError::NonFinite {
            what: "normalised residual (chi-square)",
        });
    }
    let degrees_of_freedom = measurements.saturating_sub(D);
    let variance_factor = variance_factor(minimum.normal.cost, degrees_of_freedom);
    let fix = Fix {
        position: minimum.position,
        // P = σ̂₀² (JᵀWJ)⁻¹, symmetrised against round-off
        covariance: (covariance + covariance.transpose()) * (0.5 * variance_factor),
    }
    .checked()?;
    let gdop = dop_at(anchors_used, &minimum.position, coincidence_m)?.gdop;
    Ok(GaussNewtonFix {
        fix,
        gdop,
        iterations: minimum.iterations,
        chi_square: minimum.normal.cost,
        degrees_of_freedom,
        variance_factor,
    })
}

/// The a-posteriori variance factor `σ̂₀² = max(1, χ²/dof)`, or 1 without redundancy
/// (`dof = 0`): the factor by which a least-squares covariance is inflated when the residuals
/// exceed the stated noise, never shrunk below the a-priori one.
///
/// # References
/// P. J. G. Teunissen, *Adjustment Theory*, Delft, 2000, §4.4.
pub(crate) fn variance_factor(chi_square: f64, degrees_of_freedom: usize) -> f64 {
    if degrees_of_freedom == 0 {
        return 1.0;
    }
    // σ̂₀² = χ² / (m − n), floored at the a-priori 1
    (chi_square / degrees_of_freedom as f64).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    /// `Σ (z_k − c_kᵀ p)²`: a linear model, solved in one step.
    struct Linear;
    impl Model<2> for Linear {
        fn normal_equations(&self, p: &Vector2<f64>) -> Result<NormalEquations<2>> {
            let mut n = NormalEquations::zero();
            for (c, z) in [([1.0, 0.0], 1.0), ([0.0, 1.0], 2.0), ([1.0, 1.0], 3.0)] {
                let row = Vector2::from(c);
                n.add(z - row.dot(p), &row, 4.0);
            }
            Ok(n)
        }
    }

    /// A model whose cost never decreases from the start (a flat cost).
    struct Flat;
    impl Model<2> for Flat {
        fn normal_equations(&self, _: &Vector2<f64>) -> Result<NormalEquations<2>> {
            let mut n = NormalEquations::zero();
            n.add(0.0, &Vector2::new(1.0, 0.0), 1.0);
            n.add(0.0, &Vector2::new(0.0, 1.0), 1.0);
            Ok(n)
        }
    }

    #[test]
    fn linear_model_converges_to_the_least_squares_solution() {
        let m = levenberg_marquardt(
            &Linear,
            Vector2::new(50.0, -20.0),
            1e-12,
            &GaussNewtonOptions::default(),
        )
        .unwrap();
        assert!((m.position - Vector2::new(1.0, 2.0)).norm() < 1e-9);
        assert!(m.normal.cost < 1e-18);
        assert!((m.normal.information - nalgebra::Matrix2::new(8.0, 4.0, 4.0, 8.0)).amax() < 1e-12);
        let flat = levenberg_marquardt(&Flat, Vector2::new(1.0, 1.0), 1e-12, &GaussNewtonOptions::default()).unwrap();
        assert_eq!(flat.position, Vector2::new(1.0, 1.0));
    }

    #[test]
    fn iteration_limit_is_an_error() {
        let options = GaussNewtonOptions {
            max_iterations: 1,
            relative_tolerance: 1e-10,
        };
        // the first step is damped (μ > 0), so a tiny tolerance is not met after one step
        assert_eq!(
            levenberg_marquardt(&Linear, Vector2::new(5e3, -2e3), 1e-15, &options).err(),
            Some(PositioningError::DidNotConverge { iterations: 1 })
        );
    }

    #[test]
    fn options_validation() {
        assert!(GaussNewtonOptions::default().validate().is_ok());
        let zero = GaussNewtonOptions {
            max_iterations: 0,
            ..Default::default()
        };
        assert!(matches!(
            zero.validate(),
            Err(PositioningError::InvalidParameter {
                name: "max_iterations",
                ..
            })
        ));
        for tolerance in [0.0, -1.0, 1.0, f64::NAN] {
            let bad = GaussNewtonOptions {
                relative_tolerance: tolerance,
                ..Default::default()
            };
            assert!(matches!(
                bad.validate(),
                Err(PositioningError::InvalidParameter {
                    name: "relative_tolerance",
                    ..
                })
            ));
        }
    }
}
