//! A validated measurement noise covariance `R`.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim, OMatrix};

use crate::error::{EstimationError, Result};

/// Relative tolerance of the symmetry check of [`NoiseCovariance::full`].
const SYMMETRY_TOLERANCE: f64 = 1e-12;

/// A measurement noise covariance `R`: finite, symmetric and positive definite.
///
/// Every measurement model holds one; building it through these constructors is the single
/// place where `R` is checked, so filters can rely on it (a Cholesky factorisation of `R`
/// exists, and `S = H P Hᵀ + R` is positive definite whenever `P` is positive semi-definite).
///
/// # Units
/// Squared units of the measurement components: m² for ranges and positions, dB² for RSS,
/// (m/s)² for speeds, rad² for angles; off-diagonal entries carry the product of the two
/// components' units.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::NoiseCovariance;
/// // Seed 000: R = σ_v² I₃ with σ_v² = 5 m².
/// let r = NoiseCovariance::isotropic(3, 5.0)?;
/// assert_eq!(r.dim(), 3);
/// assert!(r.is_diagonal());
/// assert_eq!(r.matrix()[(1, 1)], 5.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseCovariance(DMatrix<f64>);

impl NoiseCovariance {
    /// Independent components: `R = diag(σ₁², …, σ_m²)`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `variances` is empty or a variance is not
    /// strictly positive; [`EstimationError::NonFinite`] if a variance is NaN or infinite.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::NoiseCovariance;
    /// // Seed 002: observation noise U = diag(1.5, 2) m².
    /// let u = NoiseCovariance::diagonal(&[1.5, 2.0])?;
    /// assert_eq!(u.matrix()[(1, 1)], 2.0);
    /// assert_eq!(u.matrix()[(0, 1)], 0.0);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn diagonal(variances: &[f64]) -> Result<Self> {
        if variances.is_empty() {
            return Err(EstimationError::InvalidParameter {
                name: "variances",
                reason: "a measurement needs at least one component",
            });
        }
        if variances.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "measurement noise variances",
            });
        }
        if variances.iter().any(|&v| v <= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "variances",
                reason: "every variance must be strictly positive",
            });
        }
        Ok(Self(DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(
            variances,
        ))))
    }

    /// Independent components of equal variance: `R = σ² I_m`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `dim` is 0 or `variance` is not strictly
    /// positive; [`EstimationError::NonFinite`] if `variance` is NaN or infinite.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::NoiseCovariance;
    /// let r = NoiseCovariance::isotropic(2, 0.01)?; // σ = 0.1 m on each axis
    /// assert_eq!(r.matrix()[(0, 0)], 0.01);
    /// assert!(NoiseCovariance::isotropic(2, 0.0).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 000: `R = σ_v² I₃`.
    pub fn isotropic(dim: usize, variance: f64) -> Result<Self> {
        if dim == 0 {
            return Err(EstimationError::InvalidParameter {
                name: "dim",
                reason: "a measurement needs at least one component",
            });
        }
        if !variance.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "measurement noise variance",
            });
        }
        if variance <= 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "variance",
                reason: "the variance must be strictly positive",
            });
        }
        Ok(Self(DMatrix::from_diagonal_element(dim, dim, variance)))
    }

    /// A full covariance (correlated components), checked and exactly symmetrised.
    ///
    /// The matrix must be finite, square, non-empty, symmetric to a relative tolerance of
    /// `1e-12` (`|Rᵢⱼ − Rⱼᵢ| ≤ 1e-12 · maxₖₗ |Rₖₗ|`) and positive definite (its Cholesky
    /// factorisation must succeed). The stored matrix is `(R + Rᵀ)/2`.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞ entries; [`EstimationError::InvalidParameter`]
    /// naming `covariance` for an empty, non-square, asymmetric or not positive definite matrix.
    ///
    /// # Example
    /// ```
    /// use nalgebra::DMatrix;
    /// use rtls_estimation::measurement::NoiseCovariance;
    /// let r = NoiseCovariance::full(DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]))?;
    /// assert!(!r.is_diagonal());
    /// let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
    /// assert!(NoiseCovariance::full(indefinite).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn full(matrix: DMatrix<f64>) -> Result<Self> {
        checked_covariance(matrix).map(Self)
    }

    /// The block-diagonal covariance `blockdiag(A, B)` of two independent measurements
    /// stacked as `z = [z_A; z_B]`.
    ///
    /// Cannot fail: a block-diagonal matrix of two positive definite blocks is positive
    /// definite.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::NoiseCovariance;
    /// let toa = NoiseCovariance::isotropic(2, 0.01)?; // m²
    /// let rss = NoiseCovariance::isotropic(2, 4.0)?; // dB²
    /// let joint = NoiseCovariance::block_diagonal(&toa, &rss);
    /// assert_eq!(joint.dim(), 4);
    /// assert_eq!(joint.matrix()[(3, 3)], 4.0);
    /// assert_eq!(joint.matrix()[(0, 3)], 0.0);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 001, §2: joint TOA + RSS measurement `z = [z_TOA; z_RSS]`.
    #[must_use]
    pub fn block_diagonal(a: &Self, b: &Self) -> Self {
        let (ma, mb) = (a.dim(), b.dim());
        let mut joint = DMatrix::zeros(ma + mb, ma + mb);
        // R = [[R_A, 0], [0, R_B]]
        joint.view_mut((0, 0), (ma, ma)).copy_from(&a.0);
        joint.view_mut((ma, ma), (mb, mb)).copy_from(&b.0);
        Self(joint)
    }

    /// Wraps a matrix the caller has built from validated covariances (e.g. a block-diagonal
    /// of model covariances); checked only in debug builds.
    pub(super) fn from_trusted(matrix: DMatrix<f64>) -> Self {
        debug_assert!(
            matrix.is_square() && !matrix.is_empty(),
            "covariance must be square and non-empty"
        );
        debug_assert!(matrix.iter().all(|v| v.is_finite()), "covariance must be finite");
        Self(matrix)
    }

    /// The covariance matrix `R` (`m × m`).
    #[inline]
    #[must_use]
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.0
    }

    /// Number of measurement components `m`.
    #[inline]
    #[must_use]
    pub fn dim(&self) -> usize {
        self.0.nrows()
    }

    /// Whether every off-diagonal entry is exactly zero (independent components), as a
    /// sequential (component-by-component) update requires.
    #[must_use]
    pub fn is_diagonal(&self) -> bool {
        let m = self.dim();
        (0..m).all(|i| (0..m).all(|j| i == j || self.0[(i, j)] == 0.0))
    }
}

/// The checks of [`NoiseCovariance::full`] on a matrix of any size type (a fixed-size `R` of
/// [`FixedSelection`](super::FixedSelection) too): finite, non-empty, square, symmetric to
/// [`SYMMETRY_TOLERANCE`] relative to its largest entry, positive definite; returns `(R + Rᵀ)/2`.
///
/// # Errors
/// As [`NoiseCovariance::full`].
pub(crate) fn checked_covariance<D: Dim>(matrix: OMatrix<f64, D, D>) -> Result<OMatrix<f64, D, D>>
where
    DefaultAllocator: Allocator<D, D>,
{
    if matrix.iter().any(|v| !v.is_finite()) {
        return Err(EstimationError::NonFinite {
            what: "measurement noise covariance",
        });
    }
    if matrix.is_empty() {
        return Err(EstimationError::InvalidParameter {
            name: "covariance",
            reason: "the matrix is empty: a measurement needs at least one component",
        });
    }
    if !matrix.is_square() {
        return Err(EstimationError::InvalidParameter {
            name: "covariance",
            reason: "the matrix is not square",
        });
    }
    // Symmetry relative to the largest entry.
    let tolerance = SYMMETRY_TOLERANCE * matrix.amax();
    let m = matrix.nrows();
    for i in 0..m {
        for j in (i + 1)..m {
            if (matrix[(i, j)] - matrix[(j, i)]).abs() > tolerance {
                return Err(EstimationError::InvalidParameter {
                    name: "covariance",
                    reason: "the matrix is not symmetric",
                });
            }
        }
    }
    let mut matrix = matrix;
    crate::math::symmetrize(&mut matrix);
    if matrix.clone().cholesky().is_none() {
        return Err(EstimationError::InvalidParameter {
            name: "covariance",
            reason: "the matrix is not positive definite (cholesky factorisation failed)",
        });
    }
    Ok(matrix)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_and_isotropic_build_the_expected_matrices() {
        let r = NoiseCovariance::diagonal(&[1.5, 2.0, 0.25]).unwrap();
        assert_eq!(r.dim(), 3);
        assert!(r.is_diagonal());
        assert_eq!(r.matrix()[(0, 0)], 1.5);
        assert_eq!(r.matrix()[(2, 2)], 0.25);
        assert_eq!(r.matrix()[(2, 0)], 0.0);
        let s = NoiseCovariance::isotropic(2, 5.0).unwrap();
        assert_eq!(s.matrix(), &DMatrix::from_row_slice(2, 2, &[5.0, 0.0, 0.0, 5.0]));
    }

    #[test]
    fn bad_diagonals_are_rejected_with_the_right_variant() {
        assert!(matches!(
            NoiseCovariance::diagonal(&[]),
            Err(EstimationError::InvalidParameter { name: "variances", .. })
        ));
        assert!(matches!(
            NoiseCovariance::diagonal(&[1.0, 0.0]),
            Err(EstimationError::InvalidParameter { name: "variances", .. })
        ));
        assert!(matches!(
            NoiseCovariance::diagonal(&[1.0, -2.0]),
            Err(EstimationError::InvalidParameter { name: "variances", .. })
        ));
        assert!(matches!(
            NoiseCovariance::diagonal(&[f64::NAN]),
            Err(EstimationError::NonFinite { .. })
        ));
        assert!(matches!(
            NoiseCovariance::isotropic(0, 1.0),
            Err(EstimationError::InvalidParameter { name: "dim", .. })
        ));
        assert!(matches!(
            NoiseCovariance::isotropic(2, -1.0),
            Err(EstimationError::InvalidParameter { name: "variance", .. })
        ));
        assert!(matches!(
            NoiseCovariance::isotropic(2, f64::INFINITY),
            Err(EstimationError::NonFinite { .. })
        ));
    }

    #[test]
    fn full_checks_shape_symmetry_finiteness_and_definiteness() {
        let ok = NoiseCovariance::full(DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0])).unwrap();
        assert!(!ok.is_diagonal());
        assert_eq!(ok.matrix()[(0, 1)], 1.0);

        let non_square = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        assert_eq!(
            NoiseCovariance::full(non_square),
            Err(EstimationError::InvalidParameter {
                name: "covariance",
                reason: "the matrix is not square"
            })
        );
        let asymmetric = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0 + 1e-9, 2.0]);
        assert_eq!(
            NoiseCovariance::full(asymmetric),
            Err(EstimationError::InvalidParameter {
                name: "covariance",
                reason: "the matrix is not symmetric"
            })
        );
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        assert!(matches!(
            NoiseCovariance::full(indefinite),
            Err(EstimationError::InvalidParameter { name: "covariance", .. })
        ));
        let singular = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert!(NoiseCovariance::full(singular).is_err());
        let nan = DMatrix::from_row_slice(1, 1, &[f64::NAN]);
        assert!(matches!(
            NoiseCovariance::full(nan),
            Err(EstimationError::NonFinite { .. })
        ));
        assert!(matches!(
            NoiseCovariance::full(DMatrix::zeros(0, 0)),
            Err(EstimationError::InvalidParameter { name: "covariance", .. })
        ));
    }

    #[test]
    fn full_symmetrises_rounding_level_asymmetry() {
        let nearly = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0 + 1e-13, 2.0]);
        let r = NoiseCovariance::full(nearly).unwrap();
        assert_eq!(r.matrix()[(0, 1)], r.matrix()[(1, 0)]);
    }

    #[test]
    fn block_diagonal_places_blocks_and_zeros() {
        let a = NoiseCovariance::full(DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0])).unwrap();
        let b = NoiseCovariance::diagonal(&[7.0]).unwrap();
        let joint = NoiseCovariance::block_diagonal(&a, &b);
        let expected = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 7.0]);
        assert_eq!(joint.matrix(), &expected);
        assert!(!joint.is_diagonal());
        let d = NoiseCovariance::block_diagonal(&b, &b);
        assert!(d.is_diagonal());
    }
}
