//! Received signal strength (RSS) to fixed anchors through a [`PathLoss`] law.

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::path_loss::{finite, PathLoss};
use super::range::{
    check_noise_dim, ensure_separated, offset, planar_anchors, position_of, set_position_row, spatial_anchors,
    unit_vector,
};
use super::{MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::Result;
use crate::gaussian::Vector;

/// RSS to fixed anchors through a path-loss law: `zᵢ = L(‖p − aᵢ‖) + θᵢ`, one component per
/// anchor, with `θ ~ N(0, R)` the shadowing.
///
/// The Jacobian row of anchor `i` is `L′(dᵢ) · (p − aᵢ)ᵀ/dᵢ` at the position indices (0, 2
/// and, for spatial models, 4) and 0 elsewhere.
///
/// # Units
/// Those of the law: dBm for [`LogDistancePathLoss`](super::LogDistancePathLoss) (received power), dB for
/// [`BreakpointPathLoss`](super::BreakpointPathLoss) (path loss); `R` in dB². Anchors and positions in m.
///
/// # Errors
/// [`MeasurementModel::predict`] and [`MeasurementModel::jacobian`] return
/// [`EstimationError::SingularMeasurement`](crate::EstimationError::SingularMeasurement) (model `"rss"`) when the tag is within `1e-9` m
/// of an anchor (the logarithm diverges), [`EstimationError::NonFinite`](crate::EstimationError::NonFinite) if the law returns
/// NaN/∞, and [`EstimationError::DimensionMismatch`](crate::EstimationError::DimensionMismatch) if the state is too small (planar needs
/// `N ≥ 4`, spatial `N ≥ 6`).
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{LogDistancePathLoss, MeasurementModel, NoiseCovariance, RssPathLoss};
/// use rtls_estimation::Vector;
/// // Seed 002: ρ_T = 0 dBm, η = 4, online RSSI variance σ_p² = 16 dB².
/// let rss = RssPathLoss::planar(
///     LogDistancePathLoss::seed_002(),
///     &[[0.0, 0.0], [20.0, 0.0]],
///     NoiseCovariance::isotropic(2, 16.0)?,
/// )?;
/// let z = rss.predict(&Vector::<4>::new(10.0, 0.0, 0.0, 0.0))?;
/// assert!((z[0] + 40.0).abs() < 1e-12 && (z[1] + 40.0).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 001, §2.2 (`z_RSS = [P₁ … P_k]ᵀ + θ`); seed 002, eq. (14).
#[derive(Debug, Clone, PartialEq)]
pub struct RssPathLoss<L> {
    law: L,
    anchors: Vec<[f64; 3]>,
    spatial: bool,
    noise: NoiseCovariance,
}

impl<L: PathLoss> RssPathLoss<L> {
    /// RSS from anchors in the plane (`(x, y)` in m), measured from the state's x and y
    /// (indices 0 and 2); `noise` has one component per anchor.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`](crate::EstimationError::InvalidParameter) for an empty anchor list;
    /// [`EstimationError::NonFinite`](crate::EstimationError::NonFinite) for a NaN/∞ coordinate;
    /// [`EstimationError::DimensionMismatch`](crate::EstimationError::DimensionMismatch) if `noise.dim()` is not the number of anchors.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{BreakpointPathLoss, NoiseCovariance, RssPathLoss};
    /// // Seed 001 scenario 1: base stations at (2, 2) and (20, 40) m, σ_s = 2 dB.
    /// let law = BreakpointPathLoss::seed_001(40.0, 1.0)?;
    /// let rss = RssPathLoss::planar(law, &[[2.0, 2.0], [20.0, 40.0]], NoiseCovariance::isotropic(2, 4.0)?)?;
    /// assert_eq!(rss.anchors().len(), 2);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn planar(law: L, anchors: &[[f64; 2]], noise: NoiseCovariance) -> Result<Self> {
        let anchors = planar_anchors(anchors)?;
        check_noise_dim(&noise, anchors.len())?;
        Ok(Self {
            law,
            anchors,
            spatial: false,
            noise,
        })
    }

    /// RSS from anchors in space (`(x, y, z)` in m), measured from the state's x, y, z
    /// (indices 0, 2, 4; the state needs `N ≥ 6`).
    ///
    /// # Errors
    /// As [`RssPathLoss::planar`].
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{LogDistancePathLoss, MeasurementModel, NoiseCovariance, RssPathLoss};
    /// use rtls_estimation::Vector;
    /// let law = LogDistancePathLoss::new(-40.0, 1.0, 2.0)?;
    /// let rss = RssPathLoss::spatial(law, &[[0.0, 0.0, 10.0]], NoiseCovariance::isotropic(1, 9.0)?)?;
    /// let z = rss.predict(&Vector::<6>::zeros())?;
    /// assert!((z[0] + 60.0).abs() < 1e-12); // −40 − 20 lg 10
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn spatial(law: L, anchors: &[[f64; 3]], noise: NoiseCovariance) -> Result<Self> {
        let anchors = spatial_anchors(anchors)?;
        check_noise_dim(&noise, anchors.len())?;
        Ok(Self {
            law,
            anchors,
            spatial: true,
            noise,
        })
    }

    /// The path-loss law.
    #[inline]
    #[must_use]
    pub fn law(&self) -> &L {
        &self.law
    }

    /// Anchor positions `(x, y, z)` in m, in measurement order (`z = 0` for planar models).
    #[inline]
    #[must_use]
    pub fn anchors(&self) -> &[[f64; 3]] {
        &self.anchors
    }

    /// Whether the model is spatial (3-D) rather than planar.
    #[inline]
    #[must_use]
    pub fn is_spatial(&self) -> bool {
        self.spatial
    }

    /// The measurement noise covariance (shadowing).
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }
}

impl<L: PathLoss, const N: usize> MeasurementModel<N> for RssPathLoss<L> {
    #[inline]
    fn dim(&self) -> usize {
        self.anchors.len()
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        let p = position_of(x, self.spatial)?;
        let mut z = DVector::zeros(self.anchors.len());
        for (zi, a) in z.iter_mut().zip(&self.anchors) {
            // dᵢ = ‖p − aᵢ‖ (> 0: the law diverges at the anchor)
            let (_, distance_m) = offset(&p, a);
            ensure_separated(distance_m, "rss")?;
            // zᵢ = L(dᵢ)
            *zi = finite(self.law.value_db(distance_m), "path-loss value")?;
        }
        Ok(z)
    }

    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        let p = position_of(x, self.spatial)?;
        let mut h = MeasurementJacobian::<N>::zeros(self.anchors.len());
        for (row, a) in self.anchors.iter().enumerate() {
            let (delta, distance_m) = offset(&p, a);
            // uᵢ = (p − aᵢ) / dᵢ
            let u = unit_vector(&delta, distance_m, "rss")?;
            // ∂zᵢ/∂p = L′(dᵢ) uᵢᵀ
            let slope = finite(self.law.slope_db_per_m(distance_m), "path-loss slope")?;
            set_position_row(&mut h, row, &[slope * u[0], slope * u[1], slope * u[2]], self.spatial);
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
    use core::f64::consts::LN_10;

    use super::super::path_loss::{BreakpointForm, BreakpointPathLoss, LogDistancePathLoss};
    use super::super::range::testing::{assert_jacobian_matches_finite_differences, random_states};
    use super::*;
    use crate::error::EstimationError;
    use crate::math::log10;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn rss_predicts_the_law_at_each_anchor_distance() {
        let law = BreakpointPathLoss::seed_001(40.0, 1.0).unwrap();
        let noise = NoiseCovariance::isotropic(2, 4.0).unwrap();
        let rss = RssPathLoss::planar(law, &[[2.0, 2.0], [20.0, 40.0]], noise).unwrap();
        let x = Vector::<4>::new(5.0, 0.1, 6.0, 0.5);
        let z = rss.predict(&x).unwrap();
        assert!(close(z[0], 40.0 + 20.0 * log10(5.0)));
        let d1 = crate::math::sqrt(15.0 * 15.0 + 34.0 * 34.0);
        assert!(close(z[1], 60.0 + 20.0 * log10(d1)));
        let h = rss.jacobian(&x).unwrap();
        // slope · (x − xₐ)/d = 20/(5 ln 10) · 0.6
        assert!(close(h[(0, 0)], 20.0 / (5.0 * LN_10) * 0.6));
        assert!(close(h[(0, 2)], 20.0 / (5.0 * LN_10) * 0.8));
        assert_eq!(h[(0, 1)], 0.0);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let anchors = [[0.0, 0.0], [10.0, 0.0], [3.0, 8.0]];
        let noise = NoiseCovariance::isotropic(3, 4.0).unwrap();
        let log_distance = RssPathLoss::planar(LogDistancePathLoss::seed_002(), &anchors, noise.clone()).unwrap();
        let printed = RssPathLoss::planar(
            BreakpointPathLoss::seed_001(40.0, 1.0).unwrap(),
            &anchors,
            noise.clone(),
        )
        .unwrap();
        let dual = RssPathLoss::planar(
            BreakpointPathLoss::new(40.0, 1.0, 2.0, 10.0, BreakpointForm::Continuous)
                .unwrap()
                .with_far_exponent(3.3)
                .unwrap(),
            &anchors,
            noise.clone(),
        )
        .unwrap();
        // States up to ±25 m put anchors on both sides of the 10 m breakpoint.
        for x in random_states::<4>(11, 25, 25.0) {
            assert_jacobian_matches_finite_differences(&log_distance, &x);
            assert_jacobian_matches_finite_differences(&printed, &x);
            assert_jacobian_matches_finite_differences(&dual, &x);
        }
        let spatial = RssPathLoss::spatial(
            LogDistancePathLoss::new(-40.0, 1.0, 2.5).unwrap(),
            &[[0.0, 0.0, 3.0], [10.0, 0.0, 3.0], [0.0, 10.0, 3.0]],
            noise,
        )
        .unwrap();
        for x in random_states::<6>(12, 20, 25.0) {
            assert_jacobian_matches_finite_differences(&spatial, &x);
        }
    }

    #[test]
    fn rss_at_an_anchor_is_an_error_not_nan() {
        let rss = RssPathLoss::planar(
            LogDistancePathLoss::seed_002(),
            &[[3.0, 4.0]],
            NoiseCovariance::isotropic(1, 16.0).unwrap(),
        )
        .unwrap();
        let x = Vector::<4>::new(3.0, 1.0, 4.0, 1.0);
        assert!(matches!(
            rss.predict(&x),
            Err(EstimationError::SingularMeasurement { model: "rss", .. })
        ));
        assert!(matches!(
            rss.jacobian(&x),
            Err(EstimationError::SingularMeasurement { model: "rss", .. })
        ));
    }

    #[test]
    fn bad_rss_constructors_are_rejected() {
        let law = LogDistancePathLoss::seed_002();
        let one = NoiseCovariance::isotropic(1, 16.0).unwrap();
        assert!(matches!(
            RssPathLoss::planar(law, &[], one.clone()),
            Err(EstimationError::InvalidParameter { name: "anchors", .. })
        ));
        assert!(matches!(
            RssPathLoss::spatial(law, &[[f64::NAN, 0.0, 0.0]], one.clone()),
            Err(EstimationError::NonFinite { .. })
        ));
        assert!(matches!(
            RssPathLoss::planar(law, &[[0.0, 0.0], [1.0, 0.0]], one),
            Err(EstimationError::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
    }
}
