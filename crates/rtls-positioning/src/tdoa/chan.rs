//! Chan & Ho's closed-form TDOA estimator in the plane and in space: two-step weighted least
//! squares for `D + 2` or more stations, the exact quadratic solution for `D + 1`.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::problem::{constraint_jacobian, fixed_square, Problem, COINCIDENCE_TOLERANCE};
use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::linalg::solve_spd;

/// The result of [`chan`]: a fix and, for `D + 1` stations only, a possible second fix.
///
/// With the minimum number of stations (three in the plane, four in space) the hyperbolae
/// (hyperboloids) can intersect twice; when both intersections have non-negative ranges the
/// measurements cannot tell them apart, so both are returned: `fix` is the one nearer the
/// reference station (smaller `r_ref`) and `alternative` the other. Resolve with prior
/// knowledge, e.g. a tracker's prediction and [`ChanSolution::closest_to`], or add a station.
/// With more stations `alternative` is always `None`.
///
/// `D` defaults to 2, so `ChanSolution` alone names the planar solution.
///
/// # Example
/// ```
/// use nalgebra::DMatrix;
/// use rtls_positioning::tdoa::{chan, range_differences_at};
/// let stations = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [1000.0, 1000.0]];
/// let truth = nalgebra::Vector2::new(300.0, 450.0);
/// let r = range_differences_at(&stations, 0, &truth)?;
/// let solution = chan(&stations, 0, &r, &DMatrix::identity(3, 3))?;
/// assert!(!solution.is_ambiguous());
/// assert!((solution.fix.position - truth).norm() < 1e-6);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Y. T. Chan, K. C. Ho, "A simple and efficient estimator for hyperbolic location",
/// *IEEE Trans. Signal Processing* 42(8), 1994, §IV (minimum number of stations: two solutions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChanSolution<const D: usize = 2> {
    /// The fix (the only one with more than `D + 1` stations).
    pub fix: Fix<D>,
    /// The second intersection, when `D + 1` stations leave two valid ones.
    pub alternative: Option<Fix<D>>,
}

impl<const D: usize> ChanSolution<D> {
    /// Whether two fixes fit the measurements equally well (`D + 1` stations only).
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_positioning::{tdoa::ChanSolution, Fix2};
    /// let fix = Fix2 { position: Vector2::new(1.0, 2.0), covariance: Matrix2::identity() };
    /// let solution = ChanSolution { fix, alternative: None };
    /// assert!(!solution.is_ambiguous());
    /// ```
    ///
    /// # References
    /// Chan & Ho (1994), §IV.
    #[inline]
    #[must_use]
    pub fn is_ambiguous(&self) -> bool {
        self.alternative.is_some()
    }

    /// The candidate fix nearest to a prior position `prior_m` (m), e.g. a tracker's predicted
    /// position; `fix` when there is no alternative.
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_positioning::{tdoa::ChanSolution, Fix2};
    /// let at = |x: f64, y: f64| Fix2 { position: Vector2::new(x, y), covariance: Matrix2::identity() };
    /// let solution = ChanSolution { fix: at(0.0, 0.0), alternative: Some(at(100.0, 0.0)) };
    /// assert_eq!(solution.closest_to(&Vector2::new(90.0, 5.0)).position.x, 100.0);
    /// assert_eq!(solution.closest_to(&Vector2::new(10.0, 5.0)).position.x, 0.0);
    /// ```
    ///
    /// # References
    /// Chan & Ho (1994), §IV: the ambiguity "can be resolved by a priori information".
    #[must_use]
    pub fn closest_to(&self, prior_m: &SVector<f64, D>) -> &Fix<D> {
        match &self.alternative {
            Some(other) if (other.position - prior_m).norm() < (self.fix.position - prior_m).norm() => other,
            _ => &self.fix,
        }
    }
}

/// Chan's closed-form TDOA fix in the plane (`D = 2`) or in space (`D = 3`).
///
/// Stations `s_i` (m, `[x, y]` or `[x, y, z]`), a reference station `s_ref` (any index), and
/// the range differences `r_{i,ref} = ‖p − s_i‖ − ‖p − s_ref‖` (m) for every station `i ≠ ref`
/// **in station order, skipping the reference** (the convention of
/// `rtls_estimation::measurement::Tdoa`), with covariance `Q` (m², `(n − 1) × (n − 1)`,
/// symmetric positive definite). A TDOA `τ` in seconds is the range difference `c τ`, and
/// `Q = c² Q_τ`.
///
/// Working in coordinates centred on the reference (`s_ref = 0`, `K_i = ‖s_i‖²`), squaring
/// `r_i = r_{i,ref} + r_ref` gives the pseudo-linear equations (Chan & Ho eq. 5)
///
/// `h = G_a z_a + ψ`, `h_i = ½ (r_{i,ref}² − K_i)`, `G_a` rows `−[s_iᵀ, r_{i,ref}]`,
/// `z_a = [pᵀ, r_ref]ᵀ` (`D + 1` unknowns), `ψ ≈ B n`, `B = diag(r_i)`.
///
/// **`D + 2` or more stations** (four in the plane, five in space) — two-step WLS:
/// 1. `z_a = (G_aᵀ Q⁻¹ G_a)⁻¹ G_aᵀ Q⁻¹ h` (eq. 14, `B ≈ r⁰ I`), then, with `B` from that
///    solution, `Ψ = B Q B` (eq. 10, `Ψ = c² B Q B` for TDOAs in seconds) and
///    `z_a = (G_aᵀ Ψ⁻¹ G_a)⁻¹ G_aᵀ Ψ⁻¹ h` (eq. 12), `cov z_a = (G_aᵀ Ψ⁻¹ G_a)⁻¹` (eq. 17).
/// 2. The constraint `r_ref² = ‖p‖²` in squared coordinates: `h' = z_a ⊙ z_a`,
///    `G' = [I_D; 1ᵀ]` (`[[1, 0], [0, 1], [1, 1]]` in the plane, `[I₃; 1 1 1]` in space),
///    `B' = diag(z_a)`, `Ψ' = 4 B' cov(z_a) B'` (eq. 21),
///    `z'_a = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h'` (eq. 22), and
///    `p = s_ref + sign(p̂) ⊙ √z'_a` (eq. 24; the sign is the step-1 solution's).
///
/// Step 2 is evaluated in the algebraically identical form
/// `z'_a = E (Mᵀ F M)⁻¹ Mᵀ F z_a`, `E = diag(p̂)`, `M = B'⁻¹ G' E = [I_D; p̂ᵀ/r̂_ref]`,
/// `F = G_aᵀ Ψ⁻¹ G_a`, which never divides by a coordinate of `p̂` (the printed form is
/// singular when the tag shares a coordinate with the reference station). If step 1 gives
/// `r̂_ref ≤ 0` or step 2 a negative squared coordinate (noise with the tag near the reference
/// or near a coordinate plane through it), the step-1 position is returned, as Sun & Ho's
/// reference implementation does.
///
/// **Covariance** — Chan's step-2 covariance `Φ = ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹`
/// (eq. 25, `B'' = diag(p)`), with `B`, `B'` and `B''` evaluated at the final fix. In the
/// same substitution it is `Φ = (Mᵀ F M)⁻¹` with `M = [I_D; pᵀ/r_ref] = ∂z_a/∂p`, which is
/// what is computed. Since `G_a M = B J` (`J` the TDOA Jacobian), `Φ = (Jᵀ Q⁻¹ J)⁻¹`: the
/// Cramér–Rao bound at the fix. It is a first-order (small-noise) estimate.
///
/// **`D + 1` stations** (three in the plane, four in space) — no redundancy:
/// `S p = ½ (K − r ⊙ r) − r r_ref` with `S = [s_iᵀ]` (`D × D`) gives `p = a + b r_ref`;
/// substituting into `r_ref² = ‖p‖²` gives the quadratic
/// `(bᵀb − 1) r_ref² + 2 aᵀb r_ref + aᵀa = 0`. Roots with `r_ref ≥ 0` and `r_i = r_{i,ref} +
/// r_ref ≥ 0` are valid; if both are valid the result carries both
/// ([`ChanSolution::alternative`]). Covariance as above, `(Jᵀ Q⁻¹ J)⁻¹` at each root.
///
/// **Space** — the paper derives the plane; the spatial form is the same derivation with a
/// third coordinate (`z_a = [x, y, z, r_ref]`, `G'` gains the row `[0, 0, 1]`), as Chan & Ho
/// indicate. Stations must not be coplanar: anchors all mounted at one ceiling height are, and
/// then the TDOAs cannot tell the tag from its mirror image in that plane (use [`super::taylor`]
/// from a prior on the right side, or mount one anchor lower). Near-coplanar layouts are
/// accepted but leave `z` much less certain than `x` and `y`, which the covariance shows.
/// Indoors the tag's height relative to the reference is small against step 1's noise, and
/// step 2 squares it, so Chan's second-order bias appears at lower noise than in the plane:
/// in a 20 m × 15 m hall with anchors at 3 m and 0.5 m, σ = 2 cm per TOA biases `z` by 8 mm
/// (a tenth of the position standard deviation; NEES 3.35 instead of 3 at σ = 1 cm).
/// [`super::chan_taylor`] removes the bias.
///
/// Chan's estimator reaches the bound only at small noise: its step-1 intermediate
/// `z_a` is typically 10–30× noisier than the final fix, and once that error is a
/// few per cent of `r_ref` the fix is biased and the reported covariance is optimistic (four
/// stations on a 3 km square, tag at (1200, 800) m, σ = 10 m per TOA: empirical covariance
/// 2.6× the bound). It also degrades (as the paper notes) when the tag is near a coordinate axis
/// through the reference station, where the sign of step 1 and the square root of step 2
/// are unreliable, and far outside the station hull, where `G_a` is ill-conditioned. Rotating
/// the reference ([`super::cyclic_reference`]) or choosing a reference away from the tag
/// mitigates the former.
///
/// # Units
/// Stations, range differences and the fix in m; `Q` and the fix covariance in m².
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than `D + 1` stations;
/// - [`PositioningError::InvalidParameter`] (`reference`) if `reference ≥ n`, (`covariance_m2`)
///   if `Q` is not symmetric;
/// - [`PositioningError::DimensionMismatch`] unless there are `n − 1` range differences and
///   `Q` is `(n − 1) × (n − 1)`;
/// - [`PositioningError::NonFiniteEntry`] (station, axis) / [`PositioningError::NonFinite`]
///   for NaN/∞ stations, differences or `Q`;
/// - [`PositioningError::DuplicateAnchors`] for two stations at one position;
/// - [`PositioningError::NotPositiveDefinite`] if `Q` is not positive definite;
/// - [`PositioningError::DegenerateGeometry`] for collinear (plane) or coplanar (space)
///   stations, a singular or ill-conditioned normal matrix, or a solution at a station (where
///   the TDOA Jacobian is undefined);
/// - [`PositioningError::NoConsistentSolution`] (`D + 1` stations) when no root of the
///   quadratic gives non-negative ranges, usually noise making the hyperbolas miss each other;
/// - [`PositioningError::NonFinite`] if the result would not be finite.
///
/// # Example
/// ```
/// use nalgebra::{DMatrix, Vector2, Vector3};
/// use rtls_positioning::tdoa::{chan, differenced_range_covariance, range_differences_at};
/// // Seed 004: four cellular base stations; the master (reference) is station 2.
/// let stations = [[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]];
/// let truth = Vector2::new(-1000.0, 2000.0);
/// let r = range_differences_at(&stations, 2, &truth)?;
/// // 100 ns TOA noise per station → σ = 30 m; differences share the master's error.
/// let q = differenced_range_covariance(&[900.0; 4], 2)?;
/// let fix = chan(&stations, 2, &r, &q)?.fix;
/// assert!((fix.position - truth).norm() < 1e-6);
/// assert!(fix.drms_m() > 30.0); // outside the hull: worse than one TOA
///
/// // Indoor UWB in space: five anchors, two of them low on the walls; reference station 4.
/// let anchors = [[0.0, 0.0, 3.0], [20.0, 0.0, 3.0], [20.0, 15.0, 3.0], [0.0, 15.0, 0.5], [10.0, 7.5, 0.5]];
/// let tag = Vector3::new(6.0, 4.0, 1.2);
/// let r = range_differences_at(&anchors, 4, &tag)?;
/// let q = differenced_range_covariance(&[0.01; 5], 4)?; // σ = 10 cm per TOA
/// let fix = chan(&anchors, 4, &r, &q)?.fix;
/// assert!((fix.position - tag).norm() < 1e-6);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Y. T. Chan, K. C. Ho, "A simple and efficient estimator for hyperbolic location",
/// *IEEE Trans. Signal Processing* 42(8), 1994: eqs. (5), (10)–(14), (17), (21)–(25); §IV for
/// the minimum number of stations. M. Sun, K. C. Ho, `TDOALoc.m` (reference MATLAB
/// implementation, University of Missouri, 2009/2010: step-1 fallback). Seed 004 (cellular TDOA
/// fixes, its ref. 3).
pub fn chan<const D: usize>(
    stations_m: &[[f64; D]],
    reference: usize,
    range_differences_m: &[f64],
    covariance_m2: &DMatrix<f64>,
) -> Result<ChanSolution<D>> {
    let problem = Problem::new(stations_m, reference, range_differences_m, covariance_m2)?;
    problem.require_full_span()?;
    if problem.others_m.len() == D {
        return problem.exact_minimal();
    }
    let (z_a, fisher) = problem.step_one()?;
    let position = step_two::<D>(&z_a, &fisher, problem.scale_m)?;
    let fix = problem.fix_at(position)?;
    Ok(ChanSolution { fix, alternative: None })
}

impl<const D: usize> Problem<D> {
    /// Chan's step 1 (≥ `D + 2` stations): returns `z_a = [p, r_ref]` (centred) and the
    /// information matrix `F = G_aᵀ Ψ⁻¹ G_a = cov(z_a)⁻¹`.
    pub(crate) fn step_one(&self) -> Result<(DVector<f64>, DMatrix<f64>)> {
        const SINGULAR: &str = "chan step 1: singular normal matrix G_aᵀ Ψ⁻¹ G_a (stations nearly \
                                collinear/coplanar, or a tag far outside them)";
        // z_a = (G_aᵀ Q⁻¹ G_a)⁻¹ G_aᵀ Q⁻¹ h        (eq. 14: Ψ ≈ Q when B ≈ r⁰ I)
        let (first, _) = self.weighted_least_squares(&self.q_inverse, SINGULAR)?;
        let first_position = SVector::<f64, D>::from_fn(|i, _| first[i]);
        // B = diag(r_i⁰), r_i⁰ = ‖p⁰ − s_i‖ from the first solution (floored: weights only)
        let floor_m = COINCIDENCE_TOLERANCE * self.scale_m;
        let b: Vec<f64> = self
            .others_m
            .iter()
            .map(|s| (first_position - s).norm().max(floor_m))
            .collect();
        // Ψ⁻¹ = B⁻¹ Q⁻¹ B⁻¹                         (eq. 10: Ψ = B Q B)
        let psi_inverse = self.psi_inverse(&b);
        // z_a = (G_aᵀ Ψ⁻¹ G_a)⁻¹ G_aᵀ Ψ⁻¹ h         (eq. 12), F = G_aᵀ Ψ⁻¹ G_a (eq. 17)
        self.weighted_least_squares(&psi_inverse, SINGULAR)
    }

    /// `z = (G_aᵀ W G_a)⁻¹ G_aᵀ W h`; returns `(z, G_aᵀ W G_a)`.
    fn weighted_least_squares(
        &self,
        weight: &DMatrix<f64>,
        reason: &'static str,
    ) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let gt_w = self.g.transpose() * weight;
        // N = G_aᵀ W G_a,  b = G_aᵀ W h
        let normal = &gt_w * &self.g;
        let rhs = &gt_w * &self.h;
        let (z, _) = solve_spd(&normal, &rhs, reason)?;
        Ok((z, normal))
    }

    /// Chan & Ho §IV: the exact solution for `D + 1` stations (`D` differences).
    fn exact_minimal(&self) -> Result<ChanSolution<D>> {
        // S = [s_iᵀ]  (D × D, centred stations as rows)
        let s = SMatrix::<f64, D, D>::from_fn(|i, j| self.others_m[i][j]);
        let r = SVector::<f64, D>::from_fn(|i, _| self.differences_m[i]);
        let k = SVector::<f64, D>::from_fn(|i, _| self.others_m[i].norm_squared());
        // S⁻¹ (S is invertible: require_full_span has checked that the stations span the space)
        let s_inverse = s
            .try_inverse()
            .filter(|inverse| inverse.iter().all(|v| v.is_finite()))
            .ok_or(PositioningError::DegenerateGeometry {
                reason: "the stations are collinear/coplanar; move one off the line/plane or add a station",
            })?;
        // S p = ½ (K − r ⊙ r) − r r_ref  ⇒  p = a + b r_ref
        // a = S⁻¹ ½ (K − r ⊙ r),  b = −S⁻¹ r
        let a = s_inverse * ((k - r.component_mul(&r)) * 0.5);
        let b = -(s_inverse * r);
        // ‖a + b r_ref‖² = r_ref²  ⇒  α r_ref² + β r_ref + γ = 0
        let alpha = b.norm_squared() - 1.0;
        let beta = 2.0 * a.dot(&b);
        let gamma = a.norm_squared();
        // Δ = β² − 4 α γ
        let discriminant = beta * beta - 4.0 * alpha * gamma;
        if discriminant.is_nan() || discriminant < 0.0 {
            return Err(PositioningError::NoConsistentSolution {
                reason: "chan's quadratic in r_ref has no real root (the hyperbolas do not intersect, \
                         usually because of noise); add a station or filter the raw range differences",
            });
        }
        // Numerically stable roots: q = −½ (β + sign(β) √Δ), r = q/α and γ/q.
        let q = -0.5 * (beta + beta.signum() * discriminant.sqrt());
        let mut roots: Vec<f64> = Vec::with_capacity(2);
        if alpha != 0.0 {
            roots.push(q / alpha);
        }
        if q != 0.0 {
            roots.push(gamma / q);
        }
        // Valid: r_ref ≥ 0 and r_i = r_{i,ref} + r_ref ≥ 0 (the squared equations lost the signs).
        let tolerance_m = COINCIDENCE_TOLERANCE * self.scale_m;
        roots
            .retain(|root| root.is_finite() && *root >= -tolerance_m && r.iter().all(|r_i| root + r_i >= -tolerance_m));
        roots.sort_by(f64::total_cmp);
        roots.dedup_by(|x, y| (*x - *y).abs() <= tolerance_m);
        let mut fixes = roots.iter().map(|&r_ref| self.fix_at(a + b * r_ref));
        match (fixes.next(), fixes.next()) {
            (Some(fix), alternative) => Ok(ChanSolution {
                fix: fix?,
                alternative: alternative.transpose()?,
            }),
            (None, _) => Err(PositioningError::NoConsistentSolution {
                reason: "no root of chan's quadratic gives non-negative ranges (the hyperbola branches do \
                         not meet, usually because of noise); add a station or check the measurements",
            }),
        }
    }
}

/// Chan's step 2 (centred coordinates): from `z_a = [p̂, r̂_ref]` and `F = cov(z_a)⁻¹`
/// returns the position `sign(p̂) ⊙ √z'_a`.
///
/// `z'_a = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h'` with `Ψ' = 4 B' F⁻¹ B'` equals `E v`,
/// `v = (Mᵀ F M)⁻¹ Mᵀ F z_a`, `E = diag(p̂)`, `M = [I_D; p̂ᵀ/r̂_ref]`
/// (substitute `z'_a = E v` and multiply the normal equations by `E`).
pub(crate) fn step_two<const D: usize>(
    z_a: &DVector<f64>,
    fisher: &DMatrix<f64>,
    scale_m: f64,
) -> Result<SVector<f64, D>> {
    debug_assert_eq!(z_a.len(), D + 1);
    let p_hat = SVector::<f64, D>::from_fn(|i, _| z_a[i]);
    let r_ref = z_a[D];
    if r_ref <= COINCIDENCE_TOLERANCE * scale_m {
        // r̂_ref ≤ 0: step 2's weighting is meaningless; keep step 1 (Sun & Ho's reference code)
        return Ok(p_hat);
    }
    // M = B'⁻¹ G' E = [I_D; p̂ᵀ/r̂_ref]
    let m = constraint_jacobian(&p_hat, r_ref);
    let mt_f = m.transpose() * fisher;
    // v = (Mᵀ F M)⁻¹ Mᵀ F z_a      (B'⁻¹ h' = z_a)
    let normal = fixed_square::<D>(&(&mt_f * &m));
    let rhs = SVector::<f64, D>::from_iterator((&mt_f * z_a).iter().copied());
    let (v, _) = solve_spd(&normal, &rhs, "chan step 2: singular normal matrix G'ᵀ Ψ'⁻¹ G'")?;
    // z'_a = E v = p̂ ⊙ v  (squared coordinates)
    let squared = p_hat.component_mul(&v);
    if squared.iter().any(|&c| c < 0.0) {
        // a negative square: keep step 1 (Sun & Ho's reference code)
        return Ok(p_hat);
    }
    // p = sign(p̂) ⊙ √z'_a     (eq. 24)
    let sign = |c: f64| if c < 0.0 { -1.0 } else { 1.0 };
    Ok(SVector::<f64, D>::from_fn(|i, _| sign(p_hat[i]) * squared[i].sqrt()))
}

#[cfg(test)]
#[path = "chan_tests.rs"]
mod tests;

#[cfg(test)]
#[path = "chan_tests_3d.rs"]
mod tests_3d;
