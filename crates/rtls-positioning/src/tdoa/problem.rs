//! The validated TDOA problem shared by Chan's estimator and the Taylor refinement: inputs
//! checked once, coordinates centred on the reference station, Chan's pseudo-linear system
//! `h = G_a z_a + ψ`, and the first-order covariance of a fix.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::linalg::{covariance_inverse, solve_spd};

/// Distances below `COINCIDENCE_TOLERANCE × scale` (scale = largest station distance from the
/// reference) count as "at a station"; a station-span thinner than this fraction of the scale
/// counts as collinear (plane) or coplanar (space).
pub(crate) const COINCIDENCE_TOLERANCE: f64 = 1e-9;

/// Compile-time guard: the TDOA solvers work in the plane (`D = 2`) and in space (`D = 3`).
pub(crate) const fn assert_dimension<const D: usize>() {
    assert!(
        D == 2 || D == 3,
        "tdoa solvers support the plane (D = 2) and space (D = 3) only"
    );
}

/// A validated TDOA problem in `D` dimensions, in coordinates centred on the reference station.
pub(crate) struct Problem<const D: usize> {
    /// `s_ref` (m), the origin of the centred coordinates.
    pub(crate) reference_m: SVector<f64, D>,
    /// `s_i − s_ref` for every `i ≠ ref`, in station order (m).
    pub(crate) others_m: Vec<SVector<f64, D>>,
    /// `r_{i,ref}` (m).
    pub(crate) differences_m: DVector<f64>,
    /// `Q⁻¹` (1/m²).
    pub(crate) q_inverse: DMatrix<f64>,
    /// `G_a` (`(n − 1) × (D + 1)`), rows `−[s_iᵀ, r_{i,ref}]`.
    pub(crate) g: DMatrix<f64>,
    /// `h_i = ½ (r_{i,ref}² − K_i)`, `K_i = ‖s_i‖²`.
    pub(crate) h: DVector<f64>,
    /// Largest `‖s_i − s_ref‖` (m), the length scale of relative tolerances.
    pub(crate) scale_m: f64,
}

impl<const D: usize> Problem<D> {
    /// Validates the inputs and builds `G_a`, `h` and `Q⁻¹`.
    ///
    /// Checks, in order: at least `D + 1` stations (`Underdetermined`), the reference index, the
    /// number of range differences, finite stations (`NonFiniteEntry`) and differences, no two
    /// stations at one position (`DuplicateAnchors`), and `Q` (size, finite, symmetric, SPD).
    /// It does **not** check that the stations span the space: Chan needs that
    /// ([`Problem::require_full_span`]), a Taylor refinement from a good guess does not.
    pub(crate) fn new(
        stations_m: &[[f64; D]],
        reference: usize,
        range_differences_m: &[f64],
        covariance_m2: &DMatrix<f64>,
    ) -> Result<Self> {
        const { assert_dimension::<D>() };
        check_inputs(stations_m, reference, range_differences_m, D + 1)?;
        let n = stations_m.len();
        let reference_m = SVector::<f64, D>::from(stations_m[reference]);
        // s_i ← s_i − s_ref
        let others_m: Vec<SVector<f64, D>> = stations_m
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != reference)
            .map(|(_, s)| SVector::<f64, D>::from(*s) - reference_m)
            .collect();
        let scale_m = others_m.iter().map(|s| s.norm()).fold(0.0, f64::max);
        if !scale_m.is_finite() {
            return Err(PositioningError::NonFinite {
                what: "station spread (coordinates too large)",
            });
        }
        check_duplicates(stations_m, COINCIDENCE_TOLERANCE * scale_m)?;
        let q_inverse = covariance_inverse(covariance_m2, n - 1, "covariance_m2", "range-difference covariance")?;

        let differences_m = DVector::from_column_slice(range_differences_m);
        let m = others_m.len();
        // G_a = −[s_iᵀ, r_{i,ref}]
        let g = DMatrix::from_fn(m, D + 1, |i, j| if j < D { -others_m[i][j] } else { -differences_m[i] });
        // h_i = ½ (r_{i,ref}² − K_i),  K_i = ‖s_i‖²  (K_ref = 0)
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

    /// [`PositioningError::DegenerateGeometry`] unless the stations span the space: not all on
    /// one line (plane, `D = 2`) or in one plane (space, `D = 3`).
    ///
    /// Chan's pseudo-linear system is singular for such stations (a column of `G_a` is a
    /// combination of the others), and the TDOAs cannot tell the tag from its mirror image in
    /// the line or plane.
    ///
    /// The test is a modified Gram–Schmidt with column pivoting on the centred stations
    /// `s_i − s_ref`: at step `k` the longest remaining vector is taken as the next direction
    /// and projected out of the others; the stations span the space iff the `D`-th pivot is
    /// longer than [`COINCIDENCE_TOLERANCE`] × the largest station distance.
    pub(crate) fn require_full_span(&self) -> Result<()> {
        let mut residuals = self.others_m.clone();
        let floor_m = COINCIDENCE_TOLERANCE * self.scale_m;
        for _ in 0..D {
            // pivot: the longest residual
            let Some(pivot) = residuals
                .iter()
                .map(|v| v.norm())
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(&b.1))
            else {
                return Err(span_error::<D>());
            };
            if pivot.1 <= floor_m {
                return Err(span_error::<D>());
            }
            // u = v_pivot / ‖v_pivot‖,  v ← v − (uᵀ v) u
            let u = residuals.swap_remove(pivot.0) / pivot.1;
            for v in &mut residuals {
                *v -= u * u.dot(v);
            }
        }
        Ok(())
    }

    /// Chan's covariance at a centred position `p`: `Φ = (Mᵀ F M)⁻¹`,
    /// `M = [I_D; pᵀ/r_ref]`, `F = G_aᵀ Ψ⁻¹ G_a` with `B = diag(‖p − s_i‖)`.
    pub(crate) fn covariance_at(&self, p: &SVector<f64, D>) -> Result<SMatrix<f64, D, D>> {
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
        let fisher = self.g.transpose() * self.psi_inverse(&b) * &self.g;
        // M = ∂z_a/∂p = [I_D; pᵀ/r_ref]   (= B'⁻¹ G' B'' at the fix)
        let m = constraint_jacobian(p, r_ref);
        // Φ = (Mᵀ F M)⁻¹   (= ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹, eq. 25)
        let information = fixed_square::<D>(&(m.transpose() * fisher * &m));
        let (_, covariance) = solve_spd(
            &information,
            &SVector::<f64, D>::zeros(),
            "the tdoa information matrix Jᵀ Q⁻¹ J is singular at the fix (stations and fix nearly collinear/coplanar)",
        )?;
        // symmetrise against round-off
        Ok((covariance + covariance.transpose()) * 0.5)
    }

    /// `Ψ⁻¹ = B⁻¹ Q⁻¹ B⁻¹` for `B = diag(b)`.
    pub(crate) fn psi_inverse(&self, b: &[f64]) -> DMatrix<f64> {
        DMatrix::from_fn(b.len(), b.len(), |i, j| self.q_inverse[(i, j)] / (b[i] * b[j]))
    }

    /// The fix (absolute coordinates) at a centred position, with its covariance.
    pub(crate) fn fix_at(&self, p: SVector<f64, D>) -> Result<Fix<D>> {
        let covariance = self.covariance_at(&p)?;
        Fix {
            position: p + self.reference_m,
            covariance,
        }
        .checked()
    }

    /// The stations' centroid in centred coordinates, `(1/n) Σ (s_i − s_ref)` (the reference
    /// contributes the origin).
    pub(crate) fn centroid(&self) -> SVector<f64, D> {
        let n = self.others_m.len() as f64 + 1.0;
        self.others_m.iter().fold(SVector::zeros(), |acc, s| acc + s) / n
    }
}

/// `M = [I_D; pᵀ/r]`, the `(D + 1) × D` Jacobian of `z_a = [p; ‖p‖]` (with `r = ‖p‖`), or of
/// step 2's constraint `r_ref² = ‖p‖²` in the substituted form.
pub(crate) fn constraint_jacobian<const D: usize>(p: &SVector<f64, D>, r: f64) -> DMatrix<f64> {
    DMatrix::from_fn(D + 1, D, |i, j| match i {
        _ if i == D => p[j] / r,
        _ if i == j => 1.0,
        _ => 0.0,
    })
}

/// Copies a `D × D` dynamic matrix into a fixed-size one (the caller guarantees the size).
pub(crate) fn fixed_square<const D: usize>(a: &DMatrix<f64>) -> SMatrix<f64, D, D> {
    debug_assert_eq!(a.shape(), (D, D));
    SMatrix::<f64, D, D>::from_fn(|i, j| a[(i, j)])
}

/// The degenerate-geometry error for stations that do not span the plane or space.
fn span_error<const D: usize>() -> PositioningError {
    PositioningError::DegenerateGeometry {
        reason: if D == 2 {
            "the stations are collinear: the range differences cannot tell the tag from its mirror \
             image and chan's system is singular; move a station off the line"
        } else {
            "the stations are coplanar (e.g. all at one height): the range differences cannot tell \
             the tag from its mirror image and chan's system is singular; move a station out of the \
             plane, or refine from a prior on the correct side with `taylor`"
        },
    }
}

/// [`PositioningError::DuplicateAnchors`] for the first pair of stations closer than
/// `tolerance_m`.
fn check_duplicates<const D: usize>(stations_m: &[[f64; D]], tolerance_m: f64) -> Result<()> {
    for (first, a) in stations_m.iter().enumerate() {
        for (offset, b) in stations_m[first + 1..].iter().enumerate() {
            // ‖s_a − s_b‖ ≤ tolerance
            let distance_m = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt();
            if distance_m <= tolerance_m {
                return Err(PositioningError::DuplicateAnchors {
                    first,
                    second: first + 1 + offset,
                });
            }
        }
    }
    Ok(())
}

/// The checks every TDOA solver makes on its inputs, in order: at least `needed` stations
/// (`Underdetermined`), the reference index, one range difference per non-reference station,
/// finite stations (`NonFiniteEntry`, naming row and axis) and finite differences.
pub(super) fn check_inputs<const A: usize>(
    stations_m: &[[f64; A]],
    reference: usize,
    range_differences_m: &[f64],
    needed: usize,
) -> Result<()> {
    let n = stations_m.len();
    if n < needed {
        return Err(PositioningError::Underdetermined { anchors: n, needed });
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
    Ok(())
}
