//! One interface over the KF, EKF and UKF, for algorithms that run "a Kalman filter" of any kind
//! (the IMM's mode-matched filters).

use nalgebra::DVector;

use super::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter, Updated};
use crate::error::Result;
use crate::gaussian::Gaussian;
use crate::measurement::{LinearMeasurementModel, MeasurementModel};
use crate::motion::{LinearMotionModel, MotionModel};

/// A Kalman-type filter for motion model `M` and measurement model `H` over an `N`-entry state:
/// [`KalmanFilter`] for linear models, [`ExtendedKalmanFilter`] and [`UnscentedKalmanFilter`]
/// for any models. Each implementation forwards to the filter's own `predict` and `update`.
///
/// # Example
/// ```
/// use rtls_estimation::filter::{GaussianFilter, KalmanFilter, UnscentedKalmanFilter};
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// use nalgebra::DVector;
///
/// fn one_step<F: GaussianFilter<4, ConstantVelocity, ComponentSelection<4>>>(filter: &F) -> f64 {
///     let motion = ConstantVelocity::new(ProcessNoise::discrete(1.0, NoiseGain::kinematic())).unwrap();
///     let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 4.0).unwrap()).unwrap();
///     let x0 = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::identity(), 0.0).unwrap();
///     let prior = filter.predict(&x0, &motion, 1.0).unwrap();
///     filter.update(&prior, &fix, &DVector::from_vec(vec![1.0, 1.0])).unwrap().state.mean()[0]
/// }
/// // On linear models the KF and the UKF agree.
/// assert!((one_step(&KalmanFilter::default()) - one_step(&UnscentedKalmanFilter::default())).abs() < 1e-9);
/// ```
pub trait GaussianFilter<const N: usize, M, H> {
    /// Predicts `state` to `to_time_s` with `motion`.
    ///
    /// # Errors
    /// As the filter's own `predict`.
    fn predict(&self, state: &Gaussian<N>, motion: &M, to_time_s: f64) -> Result<Gaussian<N>>;
    /// Updates `prior` with measurement `z` of `measurement`.
    ///
    /// # Errors
    /// As the filter's own `update`.
    fn update(&self, prior: &Gaussian<N>, measurement: &H, z: &DVector<f64>) -> Result<Updated<N>>;
}

impl<const N: usize, M: LinearMotionModel<N>, H: LinearMeasurementModel<N>> GaussianFilter<N, M, H> for KalmanFilter {
    fn predict(&self, state: &Gaussian<N>, motion: &M, to_time_s: f64) -> Result<Gaussian<N>> {
        KalmanFilter::predict(self, state, motion, to_time_s)
    }
    fn update(&self, prior: &Gaussian<N>, measurement: &H, z: &DVector<f64>) -> Result<Updated<N>> {
        KalmanFilter::update(self, prior, measurement, z)
    }
}

impl<const N: usize, M: MotionModel<N>, H: MeasurementModel<N>> GaussianFilter<N, M, H> for ExtendedKalmanFilter {
    fn predict(&self, state: &Gaussian<N>, motion: &M, to_time_s: f64) -> Result<Gaussian<N>> {
        ExtendedKalmanFilter::predict(self, state, motion, to_time_s)
    }
    fn update(&self, prior: &Gaussian<N>, measurement: &H, z: &DVector<f64>) -> Result<Updated<N>> {
        ExtendedKalmanFilter::update(self, prior, measurement, z)
    }
}

impl<const N: usize, M: MotionModel<N>, H: MeasurementModel<N>> GaussianFilter<N, M, H> for UnscentedKalmanFilter {
    fn predict(&self, state: &Gaussian<N>, motion: &M, to_time_s: f64) -> Result<Gaussian<N>> {
        UnscentedKalmanFilter::predict(self, state, motion, to_time_s)
    }
    fn update(&self, prior: &Gaussian<N>, measurement: &H, z: &DVector<f64>) -> Result<Updated<N>> {
        UnscentedKalmanFilter::update(self, prior, measurement, z)
    }
}
