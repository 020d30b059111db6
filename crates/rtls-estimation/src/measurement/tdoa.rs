//! Time difference of arrival (TDOA) as range differences to a reference anchor.

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::range::{
    check_noise_dim, offset, planar_anchors, position_of, set_position_row, spatial_anchors, unit_vector,
};
use super::{MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;

/// Range differences to a reference anchor: `z_j = ‖p − a_j‖ − ‖p − a_ref‖ + v_j` for every
/// anchor `j ≠ ref`, in anchor order (`m = n − 1` components).
///
/// A TDOA `τ_j` in seconds becomes the range difference `c τ_j` in metres before it enters the
/// filter. The Jacobian row of anchor `j` is `(p − a_j)ᵀ/d_j − (p − a_ref)ᵀ/d_ref` at the
/// position indices (0, 2 and, for spatial models, 4), 0 elsewhere.
///
/// Differencing independent TOAs of equal variance `σ²` against one reference makes the
/// differences correlated, `R = σ² (I + 1 1ᵀ)` (diagonal `2σ²`, off-diagonal `σ²`); the
/// `*_from_toa_variance` constructors build that matrix.
///
/// # Units
/// Anchors, positions and range differences in metres; `R` in m².
///
/// # Errors
/// [`MeasurementModel::predict`] and [`MeasurementModel::jacobian`] return
/// [`EstimationError::DimensionMismatch`] if the state is too small (planar needs `N ≥ 4`,
/// spatial `N ≥ 6`); the Jacobian returns [`EstimationError::SingularMeasurement`] (model
/// `"tdoa"`) when the tag is within `1e-9` m of any anchor.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{MeasurementModel, Tdoa};
/// use rtls_estimation::Vector;
/// // Four base stations, the first one the master; TOA noise σ = 30 m (100 ns · c).
/// let stations = [[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]];
/// let tdoa = Tdoa::planar_from_toa_variance(&stations, 0, 900.0)?;
/// let x = Vector::<4>::new(0.0, 0.0, 4000.0, 0.0);
/// let z = tdoa.predict(&x)?;
/// assert_eq!(z.len(), 3);
/// assert!((z[0] - 1000.0).abs() < 1e-9); // ‖(−3000, 4000)‖ − 4000
/// assert!((z[1] + 3000.0).abs() < 1e-9); // 1000 − 4000
/// assert_eq!(tdoa.noise().matrix()[(0, 0)], 1800.0);
/// assert_eq!(tdoa.noise().matrix()[(0, 1)], 900.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 (cellular TDOA, its ref. 3); Y. T. Chan, K. C. Ho, "A simple and efficient
/// estimator for hyperbolic location", *IEEE Trans. Signal Processing* 42(8), 1994: range
/// differences `r_{i,1} = r_i − r_1` to the first station.
#[derive(Debug, Clone, PartialEq)]
pub struct Tdoa {
    anchors: Vec<[f64; 3]>,
    spatial: bool,
    reference: usize,
    noise: NoiseCovariance,
}

impl Tdoa {
    /// Range differences between anchors in the plane (`(x, y)` in m) and the anchor at index
    /// `reference`, measured from the state's x and y (indices 0 and 2); `noise` has `n − 1`
    /// components.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for fewer than two anchors or
    /// `reference ≥ n`; [`EstimationError::NonFinite`] for a NaN/∞ coordinate;
    /// [`EstimationError::DimensionMismatch`] if `noise.dim() ≠ n − 1`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{NoiseCovariance, Tdoa};
    /// let stations = [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]];
    /// let tdoa = Tdoa::planar(&stations, 2, NoiseCovariance::isotropic(2, 4.0)?)?;
    /// assert_eq!(tdoa.reference(), 2);
    /// assert!(Tdoa::planar(&stations, 3, NoiseCovariance::isotropic(2, 4.0)?).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn planar(anchors: &[[f64; 2]], reference: usize, noise: NoiseCovariance) -> Result<Self> {
        Self::build(planar_anchors(anchors)?, false, reference, noise)
    }

    /// Range differences between anchors in space (`(x, y, z)` in m) and the anchor at index
    /// `reference`, measured from the state's x, y, z (indices 0, 2, 4; `N ≥ 6`).
    ///
    /// # Errors
    /// As [`Tdoa::planar`].
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{NoiseCovariance, Tdoa};
    /// let anchors = [[0.0, 0.0, 3.0], [10.0, 0.0, 3.0], [0.0, 10.0, 3.0], [10.0, 10.0, 2.0]];
    /// let tdoa = Tdoa::spatial(&anchors, 0, NoiseCovariance::isotropic(3, 0.02)?)?;
    /// assert!(tdoa.is_spatial());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn spatial(anchors: &[[f64; 3]], reference: usize, noise: NoiseCovariance) -> Result<Self> {
        Self::build(spatial_anchors(anchors)?, true, reference, noise)
    }

    /// As [`Tdoa::planar`], with the covariance `R = σ² (I + 1 1ᵀ)` of differences of
    /// independent TOA ranges of variance `σ² = range_variance_m2` (m²).
    ///
    /// # Errors
    /// As [`Tdoa::planar`]; also [`EstimationError::InvalidParameter`] /
    /// [`EstimationError::NonFinite`] unless `range_variance_m2` is finite and positive.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::Tdoa;
    /// let tdoa = Tdoa::planar_from_toa_variance(&[[0.0, 0.0], [50.0, 0.0], [0.0, 50.0]], 0, 0.25)?;
    /// assert_eq!(tdoa.noise().matrix()[(1, 1)], 0.5); // 2σ²
    /// assert_eq!(tdoa.noise().matrix()[(1, 0)], 0.25); // σ², shared reference
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn planar_from_toa_variance(anchors: &[[f64; 2]], reference: usize, range_variance_m2: f64) -> Result<Self> {
        let anchors = planar_anchors(anchors)?;
        let noise = differenced_toa_covariance(anchors.len(), range_variance_m2)?;
        Self::build(anchors, false, reference, noise)
    }

    /// As [`Tdoa::spatial`], with the covariance `R = σ² (I + 1 1ᵀ)` of differences of
    /// independent TOA ranges of variance `σ² = range_variance_m2` (m²).
    ///
    /// # Errors
    /// As [`Tdoa::planar_from_toa_variance`].
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::Tdoa;
    /// let anchors = [[0.0, 0.0, 3.0], [10.0, 0.0, 3.0], [0.0, 10.0, 3.0]];
    /// let tdoa = Tdoa::spatial_from_toa_variance(&anchors, 1, 0.01)?;
    /// assert_eq!(tdoa.noise().dim(), 2);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn spatial_from_toa_variance(anchors: &[[f64; 3]], reference: usize, range_variance_m2: f64) -> Result<Self> {
        let anchors = spatial_anchors(anchors)?;
        let noise = differenced_toa_covariance(anchors.len(), range_variance_m2)?;
        Self::build(anchors, true, reference, noise)
    }

    /// Anchor positions `(x, y, z)` in m, including the reference (`z = 0` for planar models).
    #[inline]
    #[must_use]
    pub fn anchors(&self) -> &[[f64; 3]] {
        &self.anchors
    }

    /// Index of the reference anchor in [`Tdoa::anchors`].
    #[inline]
    #[must_use]
    pub fn reference(&self) -> usize {
        self.reference
    }

    /// Whether the model is spatial (3-D) rather than planar.
    #[inline]
    #[must_use]
    pub fn is_spatial(&self) -> bool {
        self.spatial
    }

    /// The measurement noise covariance (`(n − 1) × (n − 1)`).
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }

    /// Checks the anchor count, reference index and noise size.
    fn build(anchors: Vec<[f64; 3]>, spatial: bool, reference: usize, noise: NoiseCovariance) -> Result<Self> {
        if anchors.len() < 2 {
            return Err(EstimationError::InvalidParameter {
                name: "anchors",
                reason: "tdoa needs at least two anchors (a reference and one other)",
            });
        }
        if reference >= anchors.len() {
            return Err(EstimationError::InvalidParameter {
                name: "reference",
                reason: "the reference index must be below the number of anchors",
            });
        }
        check_noise_dim(&noise, anchors.len() - 1)?;
        Ok(Self {
            anchors,
            spatial,
            reference,
            noise,
        })
    }

    /// The non-reference anchors, in measurement order.
    fn others(&self) -> impl Iterator<Item = &[f64; 3]> {
        self.anchors
            .iter()
            .enumerate()
            .filter(move |&(j, _)| j != self.reference)
            .map(|(_, a)| a)
    }
}

/// `σ² (I + 1 1ᵀ)` of size `n − 1`: the covariance of `r_j − r_ref` for independent ranges of
/// variance `σ²` (`Var = 2σ²`, `Cov = σ²` through the shared reference).
fn differenced_toa_covariance(anchor_count: usize, range_variance_m2: f64) -> Result<NoiseCovariance> {
    if !range_variance_m2.is_finite() {
        return Err(EstimationError::NonFinite { what: "range variance" });
    }
    if range_variance_m2 <= 0.0 {
        return Err(EstimationError::InvalidParameter {
            name: "range_variance_m2",
            reason: "the range variance must be strictly positive",
        });
    }
    if anchor_count < 2 {
        return Err(EstimationError::InvalidParameter {
            name: "anchors",
            reason: "tdoa needs at least two anchors (a reference and one other)",
        });
    }
    let m = anchor_count - 1;
    // R = σ² (I + 1 1ᵀ)
    let r = (DMatrix::identity(m, m) + DMatrix::from_element(m, m, 1.0)) * range_variance_m2;
    NoiseCovariance::full(r)
}

impl<const N: usize> MeasurementModel<N> for Tdoa {
    #[inline]
    fn dim(&self) -> usize {
        self.anchors.len() - 1
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        let p = position_of(x, self.spatial)?;
        // d_ref = ‖p − a_ref‖
        let (_, reference_m) = offset(&p, &self.anchors[self.reference]);
        // z_j = ‖p − a_j‖ − d_ref
        Ok(DVector::from_iterator(
            self.anchors.len() - 1,
            self.others().map(|a| offset(&p, a).1 - reference_m),
        ))
    }

    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        let p = position_of(x, self.spatial)?;
        // u_ref = (p − a_ref) / d_ref
        let (delta, distance_m) = offset(&p, &self.anchors[self.reference]);
        let u_ref = unit_vector(&delta, distance_m, "tdoa")?;
        let mut h = MeasurementJacobian::<N>::zeros(self.anchors.len() - 1);
        for (row, a) in self.others().enumerate() {
            let (delta, distance_m) = offset(&p, a);
            // u_j = (p − a_j) / d_j
            let u = unit_vector(&delta, distance_m, "tdoa")?;
            // ∂z_j/∂p = u_jᵀ − u_refᵀ
            set_position_row(
                &mut h,
                row,
                &[u[0] - u_ref[0], u[1] - u_ref[1], u[2] - u_ref[2]],
                self.spatial,
            );
        }
        Ok(h)
    }

    #[inline]
    fn noise_covariance(&self) -> &DMatrix<f64> {
        self.noise.matrix()
    }

    fn residuals(&self, points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
        super::subtract_from_columns(points, mean)
    }
}

#[cfg(test)]
mod tests {
    use super::super::range::testing::{assert_jacobian_matches_finite_differences, random_states};
    use super::*;
    use crate::math::sqrt;

    const SQUARE: [[f64; 2]; 4] = [[0.0, 0.0], [30.0, 0.0], [0.0, 30.0], [30.0, 30.0]];

    #[test]
    fn range_differences_skip_the_reference_in_anchor_order() {
        let tdoa = Tdoa::planar_from_toa_variance(&SQUARE, 1, 1.0).unwrap();
        let x = Vector::<4>::new(3.0, 0.0, 4.0, 0.0);
        let z = tdoa.predict(&x).unwrap();
        let d = |a: [f64; 2]| sqrt((3.0 - a[0]) * (3.0 - a[0]) + (4.0 - a[1]) * (4.0 - a[1]));
        let reference = d(SQUARE[1]);
        assert_eq!(z.len(), 3);
        assert!((z[0] - (5.0 - reference)).abs() < 1e-12);
        assert!((z[1] - (d(SQUARE[2]) - reference)).abs() < 1e-12);
        assert!((z[2] - (d(SQUARE[3]) - reference)).abs() < 1e-12);
    }

    #[test]
    fn toa_differencing_covariance_is_sigma2_i_plus_ones() {
        let tdoa = Tdoa::planar_from_toa_variance(&SQUARE, 0, 2.5).unwrap();
        let r = tdoa.noise().matrix();
        assert_eq!(r.nrows(), 3);
        for i in 0..3 {
            for j in 0..3 {
                let expected = if i == j { 5.0 } else { 2.5 };
                assert_eq!(r[(i, j)], expected, "R[{i}, {j}]");
            }
        }
        assert!(!tdoa.noise().is_diagonal());
        // The same covariance as differencing: D diag(σ²) Dᵀ with D = [−1 | I] (reference 0).
        let mut d = DMatrix::zeros(3, 4);
        for j in 0..3 {
            d[(j, 0)] = -1.0;
            d[(j, j + 1)] = 1.0;
        }
        let differenced = &d * DMatrix::identity(4, 4) * 2.5 * d.transpose();
        assert_eq!(r, &differenced);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for reference in 0..4 {
            let tdoa = Tdoa::planar_from_toa_variance(&SQUARE, reference, 1.0).unwrap();
            for x in random_states::<4>(31 + reference as u64, 15, 50.0) {
                assert_jacobian_matches_finite_differences(&tdoa, &x);
            }
        }
        let spatial = Tdoa::spatial_from_toa_variance(
            &[[0.0, 0.0, 3.0], [10.0, 0.0, 3.0], [0.0, 10.0, 3.0], [10.0, 10.0, 0.5]],
            2,
            0.01,
        )
        .unwrap();
        for x in random_states::<6>(41, 20, 20.0) {
            assert_jacobian_matches_finite_differences(&spatial, &x);
        }
    }

    #[test]
    fn jacobian_rows_are_differences_of_unit_vectors() {
        let tdoa = Tdoa::planar(
            &[[0.0, 0.0], [6.0, 0.0]],
            0,
            NoiseCovariance::isotropic(1, 1.0).unwrap(),
        )
        .unwrap();
        let x = Vector::<4>::new(3.0, 0.0, 4.0, 0.0);
        let h = tdoa.jacobian(&x).unwrap();
        // u₁ = (−3, 4)/5, u_ref = (3, 4)/5
        assert!((h[(0, 0)] + 1.2).abs() < 1e-12);
        assert!(h[(0, 2)].abs() < 1e-12);
        assert_eq!(h[(0, 1)], 0.0);
    }

    #[test]
    fn jacobian_at_any_anchor_is_an_error() {
        let tdoa = Tdoa::planar_from_toa_variance(&SQUARE, 0, 1.0).unwrap();
        for anchor in SQUARE {
            let x = Vector::<4>::new(anchor[0], 1.0, anchor[1], 1.0);
            assert!(matches!(
                tdoa.jacobian(&x),
                Err(EstimationError::SingularMeasurement { model: "tdoa", .. })
            ));
            assert!(tdoa.predict(&x).unwrap().iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn bad_constructors_are_rejected() {
        let two = NoiseCovariance::isotropic(2, 1.0).unwrap();
        assert!(matches!(
            Tdoa::planar(&[[0.0, 0.0]], 0, NoiseCovariance::isotropic(1, 1.0).unwrap()),
            Err(EstimationError::InvalidParameter { name: "anchors", .. })
        ));
        assert!(matches!(
            Tdoa::planar(&[], 0, two.clone()),
            Err(EstimationError::InvalidParameter { name: "anchors", .. })
        ));
        assert!(matches!(
            Tdoa::planar(&SQUARE[..3], 3, two.clone()),
            Err(EstimationError::InvalidParameter { name: "reference", .. })
        ));
        assert_eq!(
            Tdoa::planar(&SQUARE, 0, two.clone()),
            Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: 3,
                found: 2
            })
        );
        assert!(matches!(
            Tdoa::spatial(&[[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], [1.0, 1.0, 1.0]], 0, two),
            Err(EstimationError::NonFinite { .. })
        ));
        assert!(matches!(
            Tdoa::planar_from_toa_variance(&SQUARE, 0, 0.0),
            Err(EstimationError::InvalidParameter {
                name: "range_variance_m2",
                ..
            })
        ));
        assert!(matches!(
            Tdoa::spatial_from_toa_variance(&[[0.0, 0.0, 0.0]], 0, 1.0),
            Err(EstimationError::InvalidParameter { name: "anchors", .. })
        ));
        assert!(matches!(
            Tdoa::planar_from_toa_variance(&SQUARE, 0, f64::NAN),
            Err(EstimationError::NonFinite { .. })
        ));
    }
}
