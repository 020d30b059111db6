//! Two measurement models taken at the same instant, stacked into one measurement.

use nalgebra::{DMatrix, DVector};

use super::{MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;

/// Two independent measurements of the same state stacked into one:
/// `z = [h_A(x); h_B(x)] + v`, `v ~ N(0, blockdiag(R_A, R_B))`.
///
/// The Jacobian stacks the blocks' Jacobians, `R` is block diagonal (built once by
/// [`Stacked::new`]), and [`MeasurementModel::residual`] and
/// [`MeasurementModel::weighted_mean`] are delegated block by block (the first `m_A` rows to
/// `A`, the rest to `B`), so angle wrapping inside a block is kept. Stack more than two models
/// by nesting (`Stacked<A, Stacked<B, C>>`).
///
/// # Units
/// Each block keeps its own units (e.g. m for TOA, dB for RSS).
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{
///     BreakpointPathLoss, MeasurementModel, NoiseCovariance, Ranges, RssPathLoss, Stacked,
/// };
/// use rtls_estimation::Vector;
/// // Seed 001: joint TOA (σ = 0.1 m) + RSS (σ_s = 2 dB) from base stations (2, 2), (20, 40).
/// let stations = [[2.0, 2.0], [20.0, 40.0]];
/// let toa = Ranges::planar(&stations, NoiseCovariance::isotropic(2, 0.01)?)?;
/// let law = BreakpointPathLoss::seed_001(40.0, 1.0)?;
/// let rss = RssPathLoss::planar(law, &stations, NoiseCovariance::isotropic(2, 4.0)?)?;
/// let joint = Stacked::new::<4>(toa, rss);
/// let x = Vector::<4>::new(5.0, 0.1, 6.0, 0.5);
/// let z = joint.predict(&x)?;
/// assert_eq!(z.len(), 4);
/// assert!((z[0] - 5.0).abs() < 1e-12); // TOA to (2, 2) first, RSS after
/// assert_eq!(joint.noise().matrix()[(2, 2)], 4.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 001, §2.2: `z_k = [z_k^TOA; z_k^RSS]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Stacked<A, B> {
    first: A,
    second: B,
    noise: NoiseCovariance,
}

impl<A, B> Stacked<A, B> {
    /// Stacks `first` over `second` (in that order) and builds `R = blockdiag(R_A, R_B)`.
    ///
    /// `N` is the state size; models that work for any state size (ranges, RSS, TDOA,
    /// speed + heading) need it spelled out: `Stacked::new::<4>(toa, rss)`.
    ///
    /// The blocks' covariances are trusted (each model validated its own); should one of
    /// them not be symmetric positive definite, the stacked `R` is not either.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{ComponentSelection, MeasurementModel, NoiseCovariance, SpeedHeading, Stacked};
    /// // Seed 004's fusion with raw odometry: TDOA position fix + speed and heading.
    /// let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 2500.0)?)?;
    /// let odometry = SpeedHeading::new(NoiseCovariance::diagonal(&[1.0, 0.01])?)?;
    /// let fused = Stacked::new(fix, odometry);
    /// assert_eq!(MeasurementModel::<4>::dim(&fused), 4);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[must_use]
    pub fn new<const N: usize>(first: A, second: B) -> Self
    where
        A: MeasurementModel<N>,
        B: MeasurementModel<N>,
    {
        let (ra, rb) = (first.noise_covariance(), second.noise_covariance());
        let (ma, mb) = (ra.nrows(), rb.nrows());
        // R = [[R_A, 0], [0, R_B]]
        let mut r = DMatrix::zeros(ma + mb, ma + mb);
        r.view_mut((0, 0), (ma, ma)).copy_from(ra);
        r.view_mut((ma, ma), (mb, mb)).copy_from(rb);
        Self {
            first,
            second,
            noise: NoiseCovariance::from_trusted(r),
        }
    }

    /// The first (upper) block's model.
    #[inline]
    #[must_use]
    pub fn first(&self) -> &A {
        &self.first
    }

    /// The second (lower) block's model.
    #[inline]
    #[must_use]
    pub fn second(&self) -> &B {
        &self.second
    }

    /// The block-diagonal noise covariance `blockdiag(R_A, R_B)`.
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }
}

impl<A, B, const N: usize> MeasurementModel<N> for Stacked<A, B>
where
    A: MeasurementModel<N>,
    B: MeasurementModel<N>,
{
    #[inline]
    fn dim(&self) -> usize {
        self.first.dim() + self.second.dim()
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        let (za, zb) = (self.first.predict(x)?, self.second.predict(x)?);
        check_block_rows("stacked prediction (first block)", self.first.dim(), za.nrows())?;
        check_block_rows("stacked prediction (second block)", self.second.dim(), zb.nrows())?;
        // z = [h_A(x); h_B(x)]
        let mut z = DVector::zeros(za.nrows() + zb.nrows());
        z.rows_mut(0, za.nrows()).copy_from(&za);
        z.rows_mut(za.nrows(), zb.nrows()).copy_from(&zb);
        Ok(z)
    }

    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        let (ha, hb) = (self.first.jacobian(x)?, self.second.jacobian(x)?);
        check_block_rows("stacked jacobian (first block)", self.first.dim(), ha.nrows())?;
        check_block_rows("stacked jacobian (second block)", self.second.dim(), hb.nrows())?;
        // H = [H_A; H_B]
        let mut h = MeasurementJacobian::<N>::zeros(ha.nrows() + hb.nrows());
        h.rows_mut(0, ha.nrows()).copy_from(&ha);
        h.rows_mut(ha.nrows(), hb.nrows()).copy_from(&hb);
        Ok(h)
    }

    #[inline]
    fn noise_covariance(&self) -> &DMatrix<f64> {
        self.noise.matrix()
    }

    fn residual(&self, z: &DVector<f64>, predicted: &DVector<f64>) -> DVector<f64> {
        let (ma, mb) = (self.first.dim(), self.second.dim());
        debug_assert_eq!(z.nrows(), ma + mb, "measurement length");
        debug_assert_eq!(predicted.nrows(), ma + mb, "prediction length");
        // ν = [z_A ⊖_A ẑ_A; z_B ⊖_B ẑ_B]
        let ya = self
            .first
            .residual(&z.rows(0, ma).into_owned(), &predicted.rows(0, ma).into_owned());
        let yb = self
            .second
            .residual(&z.rows(ma, mb).into_owned(), &predicted.rows(ma, mb).into_owned());
        let mut y = DVector::zeros(ma + mb);
        y.rows_mut(0, ma).copy_from(&ya);
        y.rows_mut(ma, mb).copy_from(&yb);
        y
    }

    fn weighted_mean(&self, points: &DMatrix<f64>, weights: &[f64]) -> DVector<f64> {
        let (ma, mb) = (self.first.dim(), self.second.dim());
        debug_assert_eq!(points.nrows(), ma + mb, "sigma-point rows");
        // z̄ = [mean_A(rows of A); mean_B(rows of B)]
        let za = self.first.weighted_mean(&points.rows(0, ma).into_owned(), weights);
        let zb = self.second.weighted_mean(&points.rows(ma, mb).into_owned(), weights);
        let mut mean = DVector::zeros(ma + mb);
        mean.rows_mut(0, ma).copy_from(&za);
        mean.rows_mut(ma, mb).copy_from(&zb);
        mean
    }
}

/// `DimensionMismatch` when a block returned a different number of rows than its `dim()`.
fn check_block_rows(what: &'static str, expected: usize, found: usize) -> Result<()> {
    if expected == found {
        Ok(())
    } else {
        Err(EstimationError::DimensionMismatch { what, expected, found })
    }
}

#[cfg(test)]
mod tests {
    use alloc::vec;

    use super::super::range::testing::{assert_jacobian_matches_finite_differences, random_states};
    use super::super::{BreakpointPathLoss, ComponentSelection, Ranges, RssPathLoss, SpeedHeading};
    use super::*;

    fn seed_001_joint() -> Stacked<Ranges, RssPathLoss<BreakpointPathLoss>> {
        let stations = [[2.0, 2.0], [20.0, 40.0]];
        let toa = Ranges::planar(&stations, NoiseCovariance::diagonal(&[0.01, 0.02]).unwrap()).unwrap();
        let law = BreakpointPathLoss::seed_001(40.0, 1.0).unwrap();
        let rss = RssPathLoss::planar(law, &stations, NoiseCovariance::isotropic(2, 4.0).unwrap()).unwrap();
        Stacked::new::<4>(toa, rss)
    }

    #[test]
    fn dims_predictions_and_jacobian_blocks() {
        let joint = seed_001_joint();
        let x = Vector::<4>::new(5.0, 0.1, 6.0, 0.5);
        assert_eq!(MeasurementModel::<4>::dim(&joint), 4);
        let z = joint.predict(&x).unwrap();
        let (za, zb) = (joint.first().predict(&x).unwrap(), joint.second().predict(&x).unwrap());
        assert_eq!(z.rows(0, 2), za.rows(0, 2));
        assert_eq!(z.rows(2, 2), zb.rows(0, 2));
        let h = joint.jacobian(&x).unwrap();
        assert_eq!(h.nrows(), 4);
        assert_eq!(h.rows(0, 2), joint.first().jacobian(&x).unwrap().rows(0, 2));
        assert_eq!(h.rows(2, 2), joint.second().jacobian(&x).unwrap().rows(0, 2));
    }

    #[test]
    fn noise_is_block_diagonal() {
        let joint = seed_001_joint();
        let r = MeasurementModel::<4>::noise_covariance(&joint);
        let expected = DMatrix::from_row_slice(
            4,
            4,
            &[
                0.01, 0.0, 0.0, 0.0, 0.0, 0.02, 0.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 0.0, 4.0,
            ],
        );
        assert_eq!(r, &expected);
        assert!(joint.noise().is_diagonal());
        // A correlated block keeps its correlation and stays apart from the other block.
        let correlated = NoiseCovariance::full(DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0])).unwrap();
        let fix = ComponentSelection::<4>::position(2, correlated).unwrap();
        let ranges = Ranges::planar(&[[0.0, 0.0]], NoiseCovariance::isotropic(1, 9.0).unwrap()).unwrap();
        let both = Stacked::new(fix, ranges);
        let r = both.noise().matrix();
        assert_eq!(r.nrows(), 3);
        assert_eq!(r[(0, 1)], 1.0);
        assert_eq!(r[(2, 2)], 9.0);
        assert_eq!(r[(0, 2)], 0.0);
        assert_eq!(r[(2, 1)], 0.0);
        assert!(!both.noise().is_diagonal());
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let joint = seed_001_joint();
        for x in random_states::<4>(21, 20, 25.0) {
            assert_jacobian_matches_finite_differences(&joint, &x);
        }
    }

    #[test]
    fn errors_of_a_block_propagate() {
        let joint = seed_001_joint();
        let at_station = Vector::<4>::new(2.0, 0.0, 2.0, 0.0);
        assert!(matches!(
            joint.jacobian(&at_station),
            Err(EstimationError::SingularMeasurement { model: "ranges", .. })
        ));
        assert!(matches!(
            joint.predict(&at_station),
            Err(EstimationError::SingularMeasurement { model: "rss", .. })
        ));
    }

    #[test]
    fn residual_and_mean_are_delegated_per_block() {
        let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 1.0).unwrap()).unwrap();
        let odometry = SpeedHeading::new(NoiseCovariance::diagonal(&[1.0, 0.01]).unwrap()).unwrap();
        let fused = Stacked::new(fix, odometry);
        let z = DVector::from_vec(vec![1.0, 2.0, 1.5, 3.1]);
        let predicted = DVector::from_vec(vec![0.5, 2.5, 1.0, -3.1]);
        let y = MeasurementModel::<4>::residual(&fused, &z, &predicted);
        assert!((y[0] - 0.5).abs() < 1e-15);
        assert!((y[1] + 0.5).abs() < 1e-15);
        assert!((y[2] - 0.5).abs() < 1e-15);
        // The heading row wraps: 3.1 − (−3.1) − 2π
        assert!((y[3] - (6.2 - core::f64::consts::TAU)).abs() < 1e-12);

        // Sigma points with headings on both sides of ±π average to ≈ π, not 0.
        let points = DMatrix::from_row_slice(4, 2, &[0.0, 2.0, 4.0, 6.0, 1.0, 3.0, 3.1, -3.1]);
        let mean = MeasurementModel::<4>::weighted_mean(&fused, &points, &[0.5, 0.5]);
        assert!((mean[0] - 1.0).abs() < 1e-15);
        assert!((mean[1] - 5.0).abs() < 1e-15);
        assert!((mean[2] - 2.0).abs() < 1e-15);
        assert!((crate::math::wrap_angle(mean[3] - core::f64::consts::PI)).abs() < 1e-12);
    }
}
