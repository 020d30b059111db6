//! Chan & Ho's closed-form TDOA estimator (planar): two-step weighted least squares for four
//! or more stations, the exact quadratic solution for three.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Matrix3x2, MatrixXx3, Vector2, Vector3};

use crate::error::{PositioningError, Result};
use crate::fix::Fix2;
use crate::linalg::{covariance_inverse, solve_spd};

/// Distances below `COINCIDENCE_TOLERANCE × scale` (scale = largest station distance from the
/// reference) count as "at a station".
const COINCIDENCE_TOLERANCE: f64 = 1e-9;

/// The result of [`chan`]: a fix and, for three stations only, a possible second fix.
///
/// With three stations (two range differences) two hyperbolas can intersect twice; when both
/// intersections have non-negative ranges the measurements cannot tell them apart, so both
/// are returned: `fix` is the one nearer the reference station (smaller `r_ref`) and
/// `alternative` the other. Resolve with prior knowledge, e.g. a tracker's prediction and
/// [`ChanSolution::closest_to`], or add a fourth station. With four or more stations
/// `alternative` is always `None`.
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
/// *IEEE Trans. Signal Processing* 42(8), 1994, §IV (three stations: two solutions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChanSolution {
    /// The fix (the only one for four or more stations).
    pub fix: Fix2,
    /// The second intersection of the hyperbolas, when three stations leave two valid ones.
    pub alternative: Option<Fix2>,
}

impl ChanSolution {
    /// Whether two fixes fit the measurements equally well (three stations only).
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
    pub fn closest_to(&self, prior_m: &Vector2<f64>) -> &Fix2 {
        match &self.alternative {
            Some(other) if (other.position - prior_m).norm() < (self.fix.position - prior_m).norm() => other,
            _ => &self.fix,
        }
    }
}

/// Chan's closed-form TDOA fix in the plane.
///
/// Stations `s_i` (m), a reference station `s_ref` (any index), and the range differences
/// `r_{i,ref} = ‖p − s_i‖ − ‖p − s_ref‖` (m) for every station `i ≠ ref` **in station order,
/// skipping the reference** (the convention of `rtls_estimation::measurement::Tdoa`), with
/// covariance `Q` (m², `(n − 1) × (n − 1)`, symmetric positive definite). A TDOA `τ` in
/// seconds is the range difference `c τ`, and `Q = c² Q_τ`.
///
/// Working in coordinates centred on the reference (`s_ref = 0`, `K_i = ‖s_i‖²`), squaring
/// `r_i = r_{i,ref} + r_ref` gives the pseudo-linear equations (Chan & Ho eq. 5)
///
/// `h = G_a z_a + ψ`, `h_i = ½ (r_{i,ref}² − K_i)`, `G_a` rows `−[x_i, y_i, r_{i,ref}]`,
/// `z_a = [x, y, r_ref]ᵀ`, `ψ ≈ B n`, `B = diag(r_i)`.
///
/// **Four or more stations** — two-step WLS:
/// 1. `z_a = (G_aᵀ Q⁻¹ G_a)⁻¹ G_aᵀ Q⁻¹ h` (eq. 14, `B ≈ r⁰ I`), then, with `B` from that
///    solution, `Ψ = B Q B` (eq. 10, `Ψ = c² B Q B` for TDOAs in seconds) and
///    `z_a = (G_aᵀ Ψ⁻¹ G_a)⁻¹ G_aᵀ Ψ⁻¹ h` (eq. 12), `cov z_a = (G_aᵀ Ψ⁻¹ G_a)⁻¹` (eq. 17).
/// 2. The constraint `r_ref² = x² + y²` in squared coordinates: `h' = [x̂², ŷ², r̂_ref²]ᵀ`,
///    `G' = [[1, 0], [0, 1], [1, 1]]`, `B' = diag(x̂, ŷ, r̂_ref)`, `Ψ' = 4 B' cov(z_a) B'`
///    (eq. 21), `z'_a = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h'` (eq. 22), and
///    `p = s_ref + sign(x̂, ŷ) ⊙ √z'_a` (eq. 24; the sign is the step-1 solution's).
///
/// Step 2 is evaluated in the algebraically identical form
/// `z'_a = E (Mᵀ F M)⁻¹ Mᵀ F z_a`, `E = diag(x̂, ŷ)`, `M = B'⁻¹ G' E = [I₂; [x̂, ŷ]/r̂_ref]`,
/// `F = G_aᵀ Ψ⁻¹ G_a`, which never divides by `x̂` or `ŷ` (the printed form is singular when
/// the tag shares a coordinate with the reference station). If step 1 gives `r̂_ref ≤ 0` or
/// step 2 a negative squared coordinate (noise with the tag near the reference or near a
/// coordinate axis through it), the step-1 position is returned, as Sun & Ho's reference
/// implementation does.
///
/// **Covariance** — Chan's step-2 covariance `Φ = ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹`
/// (eq. 25, `B'' = diag(x, y)`), with `B`, `B'` and `B''` evaluated at the final fix. In the
/// same substitution it is `Φ = (Mᵀ F M)⁻¹` with `M = [I₂; pᵀ/r_ref] = ∂z_a/∂p`, which is what
/// is computed. Since `G_a M = B J` (`J` the TDOA Jacobian), `Φ = (Jᵀ Q⁻¹ J)⁻¹`: the
/// Cramér–Rao bound at the fix. It is a first-order (small-noise) estimate.
///
/// **Three stations** — no redundancy: `S p = ½ (K − r ⊙ r) − r r_ref` with `S = [s_iᵀ]`
/// gives `p = a + b r_ref`; substituting into `r_ref² = ‖p‖²` gives the quadratic
/// `(bᵀb − 1) r_ref² + 2 aᵀb r_ref + aᵀa = 0`. Roots with `r_ref ≥ 0` and `r_i = r_{i,ref} +
/// r_ref ≥ 0` are valid; if both are valid the result carries both
/// ([`ChanSolution::alternative`]). Covariance as above, `(Jᵀ Q⁻¹ J)⁻¹` at each root.
///
/// Chan's estimator reaches the bound only at small noise: its step-1 intermediate
/// `(x, y, r_ref)` is typically 10–30× noisier than the final fix, and once that error is a
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
/// - [`PositioningError::Underdetermined`] for fewer than 3 stations;
/// - [`PositioningError::InvalidParameter`] (`reference`) if `reference ≥ n`, (`covariance_m2`)
///   if `Q` is not symmetric;
/// - [`PositioningError::DimensionMismatch`] unless there are `n − 1` range differences and
///   `Q` is `(n − 1) × (n − 1)`;
/// - [`PositioningError::NonFiniteEntry`] (station, axis) / [`PositioningError::NonFinite`]
///   for NaN/∞ stations, differences or `Q`;
/// - [`PositioningError::NotPositiveDefinite`] if `Q` is not positive definite;
/// - [`PositioningError::DegenerateGeometry`] for coincident or collinear stations, a singular
///   or ill-conditioned normal matrix, or a solution at a station (where the TDOA Jacobian is
///   undefined);
/// - [`PositioningError::NoConsistentSolution`] (three stations) when no root of the quadratic
///   gives non-negative ranges, usually noise making the hyperbolas miss each other;
/// - [`PositioningError::NonFinite`] if the result would not be finite.
///
/// # Example
/// ```
/// use nalgebra::{DMatrix, Vector2};
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
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Y. T. Chan, K. C. Ho, "A simple and efficient estimator for hyperbolic location",
/// *IEEE Trans. Signal Processing* 42(8), 1994: eqs. (5), (10)–(14), (17), (21)–(25); §IV for
/// three stations. M. Sun, K. C. Ho, `TDOALoc.m` (reference MATLAB implementation, University
/// of Missouri, 2009/2010: step-1 fallback). Seed 004 (cellular TDOA fixes, its ref. 3).
pub fn chan(
    stations_m: &[[f64; 2]],
    reference: usize,
    range_differences_m: &[f64],
    covariance_m2: &DMatrix<f64>,
) -> Result<ChanSolution> {
    let problem = Problem::new(stations_m, reference, range_differences_m, covariance_m2)?;
    if problem.others_m.len() == 2 {
        return problem.exact_three();
    }
    let (z_a, fisher) = problem.step_one()?;
    let position = step_two(&z_a, &fisher, problem.scale_m)?;
    let fix = problem.fix_at(position)?;
    Ok(ChanSolution { fix, alternative: None })
}

/// A validated TDOA problem in coordinates centred on the reference station.
pub(crate) struct Problem {
    /// `s_ref` (m), the origin of the centred coordinates.
    pub(crate) reference_m: Vector2<f64>,
    /// `s_i − s_ref` for every `i ≠ ref`, in station order (m).
    pub(crate) others_m: Vec<Vector2<f64>>,
    /// `r_{i,ref}` (m).
    pub(crate) differences_m: DVector<f64>,
    /// `Q⁻¹` (1/m²).
    pub(crate) q_inverse: DMatrix<f64>,
    /// `G_a`, rows `−[x_i, y_i, r_{i,ref}]`.
    g: MatrixXx3<f64>,
    /// `h_i = ½ (r_{i,ref}² − K_i)`.
    h: DVector<f64>,
    /// Largest `‖s_i − s_ref‖` (m), the length scale of relative tolerances.
    pub(crate) scale_m: f64,
}

impl Problem {
    /// Validates the inputs and builds `G_a`, `h` and `Q⁻¹`.
    pub(crate) fn new(
        stations_m: &[[f64; 2]],
        reference: usize,
        range_differences_m: &[f64],
        covariance_m2: &DMatrix<f64>,
    ) -> Result<Self> {
        let n = stations_m.len();
        if n < 3 {
            return Err(PositioningError::Underdetermined { anchors: n, needed: 3 });
        }
        if reference >= n {
            return Err(PositioningError::InvalidParameter {
                name: "reference",
                reason: "the reference index must be below the number of stations",
            });
        }
        if range_differences_m.len() != n - 1 {
            return Err(PositioningError::DimensionMismatch {
                what: "range differences (one per non-reference station)",
                expected: n - 1,
                found: range_differences_m.len(),
            });
        }
        for (row, s) in stations_m.iter().enumerate() {
            if let Some(column) = s.iter().position(|v| !v.is_finite()) {
                return Err(PositioningError::NonFiniteEntry {
                    what: "station positions (row = station, column = axis)",
                    row,
                    column,
                });
            }
        }
        if !range_differences_m.iter().all(|v| v.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "range differences",
            });
        }
        let q_inverse = covariance_inverse(covariance_m2, n - 1, "covariance_m2", "range-difference covariance")?;

        let reference_m = Vector2::new(stations_m[reference][0], stations_m[reference][1]);
        // s_i ← s_i − s_ref
        let others_m: Vec<Vector2<f64>> = stations_m
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != reference)
            .map(|(_, s)| Vector2::new(s[0], s[1]) - reference_m)
            .collect();
        let scale_m = others_m.iter().map(|s| s.norm()).fold(0.0, f64::max);
        if !(scale_m > 0.0 && scale_m.is_finite()) {
            return Err(PositioningError::DegenerateGeometry {
                reason: "all stations coincide with the reference; stations must be spread out",
            });
        }
        let differences_m = DVector::from_column_slice(range_differences_m);
        let m = others_m.len();
        // G_a = −[x_i, y_i, r_{i,ref}]
        let g = MatrixXx3::from_fn(m, |i, j| match j {
            0 => -others_m[i].x,
            1 => -others_m[i].y,
            _ => -differences_m[i],
        });
        // h_i = ½ (r_{i,ref}² − K_i),  K_i = x_i² + y_i²  (K_ref = 0)
        let h = DVector::from_fn(m, |i, _| {
            0.5 * (differences_m[i] * differences_m[i] - others_m[i].norm_squared())
        });
        Ok(Self {
            reference_m,
            others_m,
            differences_m,
            q_inverse,
            g,
            h,
            scale_m,
        })
    }

    /// Chan's step 1 (≥ 4 stations): returns `z_a = [x, y, r_ref]` (centred) and the
    /// information matrix `F = G_aᵀ Ψ⁻¹ G_a = cov(z_a)⁻¹`.
    pub(crate) fn step_one(&self) -> Result<(Vector3<f64>, Matrix3<f64>)> {
        const SINGULAR: &str =
            "chan step 1: singular normal matrix G_aᵀ Ψ⁻¹ G_a (collinear stations or a tag far outside them)";
        // z_a = (G_aᵀ Q⁻¹ G_a)⁻¹ G_aᵀ Q⁻¹ h        (eq. 14: Ψ ≈ Q when B ≈ r⁰ I)
        let (first, _) = self.weighted_least_squares(&self.q_inverse, SINGULAR)?;
        // B = diag(r_i⁰), r_i⁰ = ‖p⁰ − s_i‖ from the first solution (floored: weights only)
        let floor_m = COINCIDENCE_TOLERANCE * self.scale_m;
        let b: Vec<f64> = self
            .others_m
            .iter()
            .map(|s| (first.xy() - s).norm().max(floor_m))
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
    ) -> Result<(Vector3<f64>, Matrix3<f64>)> {
        let gt_w = self.g.transpose() * weight;
        // N = G_aᵀ W G_a,  b = G_aᵀ W h
        let normal: Matrix3<f64> = &gt_w * &self.g;
        let rhs: Vector3<f64> = &gt_w * &self.h;
        let (z, _) = solve_spd(&normal, &rhs, reason)?;
        Ok((z, normal))
    }

    /// `Ψ⁻¹ = B⁻¹ Q⁻¹ B⁻¹` for `B = diag(b)`.
    fn psi_inverse(&self, b: &[f64]) -> DMatrix<f64> {
        DMatrix::from_fn(b.len(), b.len(), |i, j| self.q_inverse[(i, j)] / (b[i] * b[j]))
    }

    /// Chan's covariance at a centred position `p`: `Φ = (Mᵀ F M)⁻¹`,
    /// `M = [I₂; pᵀ/r_ref]`, `F = G_aᵀ Ψ⁻¹ G_a` with `B = diag(‖p − s_i‖)`.
    pub(crate) fn covariance_at(&self, p: &Vector2<f64>) -> Result<Matrix2<f64>> {
        const AT_STATION: PositioningError = PositioningError::DegenerateGeometry {
            reason: "the fix coincides with a station, where the tdoa jacobian is undefined; \
                     use another reference station or method",
        };
        let floor_m = COINCIDENCE_TOLERANCE * self.scale_m;
        // r_ref = ‖p‖, r_i = ‖p − s_i‖
        let r_ref = p.norm();
        let b: Vec<f64> = self.others_m.iter().map(|s| (p - s).norm()).collect();
        if r_ref <= floor_m || b.iter().any(|&r| r <= floor_m) {
            return Err(AT_STATION);
        }
        // F = G_aᵀ Ψ⁻¹ G_a,  Ψ⁻¹ = B⁻¹ Q⁻¹ B⁻¹
        let fisher: Matrix3<f64> = self.g.transpose() * self.psi_inverse(&b) * &self.g;
        // M = ∂z_a/∂p = [I₂; pᵀ/r_ref]   (= B'⁻¹ G' B'' at the fix)
        let m = Matrix3x2::new(1.0, 0.0, 0.0, 1.0, p.x / r_ref, p.y / r_ref);
        // Φ = (Mᵀ F M)⁻¹   (= ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹, eq. 25)
        let information = m.transpose() * fisher * m;
        let (_, covariance) = solve_spd(
            &information,
            &Vector2::zeros(),
            "the tdoa information matrix Jᵀ Q⁻¹ J is singular at the fix (stations and fix nearly collinear)",
        )?;
        // symmetrise against round-off
        Ok((covariance + covariance.transpose()) * 0.5)
    }

    /// The fix (absolute coordinates) at a centred position, with its covariance.
    pub(crate) fn fix_at(&self, p: Vector2<f64>) -> Result<Fix2> {
        let covariance = self.covariance_at(&p)?;
        Fix2 {
            position: p + self.reference_m,
            covariance,
        }
        .checked()
    }

    /// Chan & Ho §IV: the exact solution for three stations (two differences).
    fn exact_three(&self) -> Result<ChanSolution> {
        let (s2, s3) = (self.others_m[0], self.others_m[1]);
        let (r2, r3) = (self.differences_m[0], self.differences_m[1]);
        // S = [s_2ᵀ; s_3ᵀ]
        let s = Matrix2::new(s2.x, s2.y, s3.x, s3.y);
        let collinear = PositioningError::DegenerateGeometry {
            reason: "the three stations are collinear (or two coincide); move one off the line or add a station",
        };
        if s.determinant().abs() <= 1e-12 * s2.norm() * s3.norm() {
            return Err(collinear);
        }
        let s_inverse = s.try_inverse().ok_or(collinear)?;
        // S p = ½ (K − r ⊙ r) − r r_ref  ⇒  p = a + b r_ref
        // a = S⁻¹ ½ (K − r ⊙ r),  b = −S⁻¹ r
        let a = s_inverse * Vector2::new(0.5 * (s2.norm_squared() - r2 * r2), 0.5 * (s3.norm_squared() - r3 * r3));
        let b = -(s_inverse * Vector2::new(r2, r3));
        // ‖a + b r_ref‖² = r_ref²  ⇒  α r_ref² + β r_ref + γ = 0
        let alpha = b.norm_squared() - 1.0;
        let beta = 2.0 * a.dot(&b);
        let gamma = a.norm_squared();
        // Δ = β² − 4 α γ
        let discriminant = beta * beta - 4.0 * alpha * gamma;
        if discriminant.is_nan() || discriminant < 0.0 {
            return Err(PositioningError::NoConsistentSolution {
                reason: "chan's quadratic in r_ref has no real root (the two hyperbolas do not intersect, \
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
        roots.retain(|r| r.is_finite() && *r >= -tolerance_m && r + r2 >= -tolerance_m && r + r3 >= -tolerance_m);
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

/// Chan's step 2 (centred coordinates): from `z_a = [x̂, ŷ, r̂_ref]` and `F = cov(z_a)⁻¹`
/// returns the position `sign(x̂, ŷ) ⊙ √z'_a`.
///
/// `z'_a = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h'` with `Ψ' = 4 B' F⁻¹ B'` equals `E v`,
/// `v = (Mᵀ F M)⁻¹ Mᵀ F z_a`, `E = diag(x̂, ŷ)`, `M = [I₂; [x̂, ŷ]/r̂_ref]`
/// (substitute `z'_a = E v` and multiply the normal equations by `E`).
pub(crate) fn step_two(z_a: &Vector3<f64>, fisher: &Matrix3<f64>, scale_m: f64) -> Result<Vector2<f64>> {
    let r_ref = z_a.z;
    if r_ref <= COINCIDENCE_TOLERANCE * scale_m {
        // r̂_ref ≤ 0: step 2's weighting is meaningless; keep step 1 (Sun & Ho's reference code)
        return Ok(z_a.xy());
    }
    // M = B'⁻¹ G' E = [I₂; [x̂, ŷ]/r̂_ref]
    let m = Matrix3x2::new(1.0, 0.0, 0.0, 1.0, z_a.x / r_ref, z_a.y / r_ref);
    let mt_f = m.transpose() * fisher;
    // v = (Mᵀ F M)⁻¹ Mᵀ F z_a      (B'⁻¹ h' = z_a)
    let (v, _) = solve_spd(
        &(mt_f * m),
        &(mt_f * z_a),
        "chan step 2: singular normal matrix G'ᵀ Ψ'⁻¹ G'",
    )?;
    // z'_a = E v = [x̂ v_x, ŷ v_y]  (squared coordinates)
    let squared = Vector2::new(z_a.x * v.x, z_a.y * v.y);
    if squared.x < 0.0 || squared.y < 0.0 {
        // a negative square: keep step 1 (Sun & Ho's reference code)
        return Ok(z_a.xy());
    }
    // p = sign(x̂, ŷ) ⊙ √z'_a     (eq. 24)
    let sign = |c: f64| if c < 0.0 { -1.0 } else { 1.0 };
    Ok(Vector2::new(
        sign(z_a.x) * squared.x.sqrt(),
        sign(z_a.y) * squared.y.sqrt(),
    ))
}

#[cfg(test)]
#[path = "chan_tests.rs"]
mod tests;
