//! Small fallible linear-algebra helpers shared by the estimators: SPD solves with a
//! conditioning check, covariance validation. Nothing here panics or returns a NaN.

use nalgebra::{allocator::Allocator, Cholesky, DMatrix, DefaultAllocator, Dim, OMatrix, OVector};

use crate::error::{PositioningError, Result};

/// Reciprocal condition number (1-norm, after unit-diagonal scaling) below which a normal
/// matrix is treated as singular. `1e-12` leaves about four significant digits in the solution.
pub(crate) const MIN_RECIPROCAL_CONDITION: f64 = 1e-12;

/// `(x, N⁻¹)` of an SPD solve.
pub(crate) type SpdSolution<D> = (OVector<f64, D>, OMatrix<f64, D, D>);

/// Solves the symmetric positive definite system `N x = b` (normal equations of a weighted
/// least-squares problem) and returns `(x, N⁻¹)`.
///
/// The matrix is scaled to unit diagonal, `Ñ = S N S` with `S = diag(1/√N_ii)`, factorised by
/// Cholesky, and its 1-norm reciprocal condition `1 / (‖Ñ‖₁ ‖Ñ⁻¹‖₁)` is checked against
/// [`MIN_RECIPROCAL_CONDITION`]; a failure of any step is
/// [`PositioningError::DegenerateGeometry`] with `reason`.
pub(crate) fn solve_spd<D: Dim>(
    normal: &OMatrix<f64, D, D>,
    rhs: &OVector<f64, D>,
    reason: &'static str,
) -> Result<SpdSolution<D>>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let degenerate = PositioningError::DegenerateGeometry { reason };
    if !normal.iter().chain(rhs.iter()).all(|v| v.is_finite()) {
        return Err(degenerate);
    }
    // S = diag(1/√N_ii)
    let mut scale = normal.diagonal();
    for s in scale.iter_mut() {
        if *s <= 0.0 {
            return Err(degenerate);
        }
        *s = 1.0 / s.sqrt();
    }
    // Ñ = S N S
    let mut scaled = normal.clone();
    for (j, mut column) in scaled.column_iter_mut().enumerate() {
        for (i, v) in column.iter_mut().enumerate() {
            *v *= scale[i] * scale[j];
        }
    }
    let norm_1 = one_norm(&scaled);
    let Some(cholesky) = Cholesky::new(scaled) else {
        return Err(degenerate);
    };
    // Ñ⁻¹, rcond = 1 / (‖Ñ‖₁ ‖Ñ⁻¹‖₁)
    let scaled_inverse = cholesky.inverse();
    let reciprocal_condition = 1.0 / (norm_1 * one_norm(&scaled_inverse));
    if reciprocal_condition.is_nan() || reciprocal_condition < MIN_RECIPROCAL_CONDITION {
        return Err(degenerate);
    }
    // N⁻¹ = S Ñ⁻¹ S
    let mut inverse = scaled_inverse;
    for (j, mut column) in inverse.column_iter_mut().enumerate() {
        for (i, v) in column.iter_mut().enumerate() {
            *v *= scale[i] * scale[j];
        }
    }
    // x = N⁻¹ b
    let solution = &inverse * rhs;
    if solution.iter().chain(inverse.iter()).all(|v| v.is_finite()) {
        Ok((solution, inverse))
    } else {
        Err(degenerate)
    }
}

/// `‖A‖₁ = max_j Σ_i |a_ij|`.
fn one_norm<D: Dim>(a: &OMatrix<f64, D, D>) -> f64
where
    DefaultAllocator: Allocator<D, D>,
{
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Validates a covariance (`dim × dim`, finite, symmetric to `1e-9` relative, positive definite)
/// and returns its inverse.
///
/// # Errors
/// [`PositioningError::DimensionMismatch`], [`PositioningError::NonFinite`],
/// [`PositioningError::InvalidParameter`] (asymmetric, `name`),
/// [`PositioningError::NotPositiveDefinite`].
pub(crate) fn covariance_inverse(
    covariance: &DMatrix<f64>,
    dim: usize,
    name: &'static str,
    what: &'static str,
) -> Result<DMatrix<f64>> {
    if covariance.nrows() != dim || covariance.ncols() != dim {
        return Err(PositioningError::DimensionMismatch {
            what,
            expected: dim,
            found: if covariance.nrows() == dim {
                covariance.ncols()
            } else {
                covariance.nrows()
            },
        });
    }
    if !covariance.iter().all(|v| v.is_finite()) {
        return Err(PositioningError::NonFinite { what });
    }
    let magnitude = covariance.amax();
    let asymmetry = (covariance - covariance.transpose()).amax();
    if asymmetry > 1e-9 * magnitude {
        return Err(PositioningError::InvalidParameter {
            name,
            reason: "a covariance must be symmetric",
        });
    }
    // Q⁻¹ through Q = L Lᵀ
    let inverse = Cholesky::new(covariance.clone())
        .ok_or(PositioningError::NotPositiveDefinite { what })?
        .inverse();
    if inverse.iter().all(|v| v.is_finite()) {
        Ok(inverse)
    } else {
        Err(PositioningError::NotPositiveDefinite { what })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

    #[test]
    fn solve_spd_matches_the_direct_inverse() {
        let n = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0) * 1e6;
        let b = Vector3::new(1.0, -2.0, 3.0);
        let (x, inverse) = solve_spd(&n, &b, "test").unwrap();
        let direct = n.try_inverse().unwrap();
        assert!((inverse - direct).amax() < 1e-12 * direct.amax());
        assert!((n * x - b).amax() < 1e-9);
    }

    #[test]
    fn solve_spd_rejects_singular_and_ill_conditioned_systems() {
        let singular = Matrix2::new(1.0, 2.0, 2.0, 4.0);
        assert!(matches!(
            solve_spd(&singular, &Vector2::new(1.0, 1.0), "collinear"),
            Err(PositioningError::DegenerateGeometry { reason: "collinear" })
        ));
        let nearly = Matrix2::new(1.0, 1.0 - 1e-14, 1.0 - 1e-14, 1.0);
        assert!(solve_spd(&nearly, &Vector2::new(1.0, 1.0), "x").is_err());
        let zero_column = Matrix2::new(1.0, 0.0, 0.0, 0.0);
        assert!(solve_spd(&zero_column, &Vector2::new(1.0, 1.0), "x").is_err());
        let nan = Matrix2::new(1.0, 0.0, 0.0, f64::NAN);
        assert!(solve_spd(&nan, &Vector2::new(1.0, 1.0), "x").is_err());
    }

    #[test]
    fn covariance_validation() {
        let q = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]);
        let inverse = covariance_inverse(&q, 2, "q", "q").unwrap();
        assert!((&q * inverse - DMatrix::identity(2, 2)).amax() < 1e-12);
        assert!(matches!(
            covariance_inverse(&q, 3, "q", "q"),
            Err(PositioningError::DimensionMismatch {
                expected: 3,
                found: 2,
                ..
            })
        ));
        let asymmetric = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 0.0, 2.0]);
        assert!(matches!(
            covariance_inverse(&asymmetric, 2, "q", "q"),
            Err(PositioningError::InvalidParameter { name: "q", .. })
        ));
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        assert!(matches!(
            covariance_inverse(&indefinite, 2, "q", "q"),
            Err(PositioningError::NotPositiveDefinite { .. })
        ));
        let nan = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, f64::NAN]);
        assert!(matches!(
            covariance_inverse(&nan, 2, "q", "q"),
            Err(PositioningError::NonFinite { .. })
        ));
    }
}
