//! The linear Kalman filter.

use nalgebra::DVector;

use super::predict::control_effect;
use super::update::{
    check_measurement, check_model_shapes, linearized_update, sequential_update, CovarianceUpdate, Updated,
};
use crate::error::{EstimationError, Result};
use crate::gaussian::Gaussian;
use crate::measurement::LinearMeasurementModel;
use crate::motion::LinearMotionModel;

/// The linear Kalman filter for linear motion and measurement models.
///
/// ```text
/// predict:  x⁻ = F x̂ + B u          P⁻ = F P Fᵀ + Q                       (seed 000 eq. 16–17)
/// update:   S = H P⁻ Hᵀ + R         K = P⁻ Hᵀ S⁻¹                         (eq. 18)
///           x̂ = x⁻ + K (z − H x⁻)   P = (I−KH) P⁻ (I−KH)ᵀ + K R Kᵀ        (eq. 19–20, Joseph form)
/// ```
///
/// The filter holds only its configuration; the state is passed in and returned.
///
/// # Errors
/// Steps return [`EstimationError`] values for time going backwards, dimension mismatches,
/// non-finite inputs or results, and a non-positive-definite innovation covariance.
///
/// # Example
/// ```
/// use rtls_estimation::filter::KalmanFilter;
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// use nalgebra::DVector;
///
/// let motion = ConstantVelocity::new(ProcessNoise::discrete(5.0, NoiseGain::kinematic()))?;
/// let fix = ComponentSelection::<6>::position(3, NoiseCovariance::isotropic(3, 5.0)?)?;
/// let kf = KalmanFilter::default();
/// let x0 = Gaussian::new(Vector::<6>::zeros(), Matrix::<6>::identity() * 10.0, 0.0)?;
/// let prior = kf.predict(&x0, &motion, 1.0)?;
/// let updated = kf.update(&prior, &fix, &DVector::from_vec(vec![1.0, 2.0, 0.5]))?;
/// assert!(updated.nis >= 0.0);
/// assert!(updated.state.covariance()[(0, 0)] < prior.covariance()[(0, 0)]);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Kalman (1960); seed 000 (ME-KF) eq. (16)–(20); Bar-Shalom, Li, Kirubarajan (2001) §5.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KalmanFilter {
    /// Posterior covariance form (Joseph by default).
    pub covariance_update: CovarianceUpdate,
}

impl KalmanFilter {
    /// A filter using the given covariance update form.
    #[must_use]
    pub fn new(covariance_update: CovarianceUpdate) -> Self {
        Self { covariance_update }
    }

    /// Predicts `state` forward to `to_time_s` (a predict-only step when no fix arrives).
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if `to_time_s` precedes the state;
    /// [`EstimationError::NonFinite`] if the model produces NaN/∞.
    pub fn predict<const N: usize, M: LinearMotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        linear_predict(state, model, None, to_time_s)
    }

    /// Predicts with a control input `u` (e.g. acceleration in m/s² from an on-tag
    /// accelerometer, seed 002, or force/mass, seed 003): `x⁻ = F x̂ + B u`.
    ///
    /// # Errors
    /// As [`KalmanFilter::predict`], plus [`EstimationError::NoControlInput`] if the model has
    /// no control gain and [`EstimationError::DimensionMismatch`] if `u` has the wrong size.
    pub fn predict_with_control<const N: usize, M: LinearMotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        control: &DVector<f64>,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        linear_predict(state, model, Some(control), to_time_s)
    }

    /// Updates a predicted state with measurement `z` of a linear model.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `z` does not have the model's size;
    /// [`EstimationError::NonFinite`] for NaN/∞ in `z` or the result;
    /// [`EstimationError::InnovationNotPositiveDefinite`] if `S` cannot be factorised.
    pub fn update<const N: usize, H: LinearMeasurementModel<N>>(
        &self,
        prior: &Gaussian<N>,
        model: &H,
        z: &DVector<f64>,
    ) -> Result<Updated<N>> {
        let h = model.matrix();
        let r = model.noise_covariance();
        check_measurement(z, model.dim())?;
        check_model_shapes(h, r, model.dim())?;
        // ν = z − H x⁻
        let innovation = model.residual(z, &(h * prior.mean()));
        linearized_update(prior, innovation, h, r, self.covariance_update)
    }

    /// Updates with the components of `z` one at a time (scalar updates), which needs a
    /// diagonal `R`; equal to [`KalmanFilter::update`] in exact arithmetic.
    ///
    /// The returned innovation, `S`, gain and NIS are the batch quantities at the prior (what a
    /// gate needs); the state is the result of the scalar updates.
    ///
    /// # Errors
    /// As [`KalmanFilter::update`], plus [`EstimationError::CorrelatedNoise`] if `R` is not
    /// diagonal.
    pub fn update_sequential<const N: usize, H: LinearMeasurementModel<N>>(
        &self,
        prior: &Gaussian<N>,
        model: &H,
        z: &DVector<f64>,
    ) -> Result<Updated<N>> {
        sequential_update(prior, model, z, self.covariance_update)
    }
}

/// `x⁻ = F x̂ (+ B u)`, `P⁻ = F P Fᵀ + Q` with `F` built once.
fn linear_predict<const N: usize, M: LinearMotionModel<N>>(
    state: &Gaussian<N>,
    model: &M,
    control: Option<&DVector<f64>>,
    to_time_s: f64,
) -> Result<Gaussian<N>> {
    let dt_s = state.step_to(to_time_s)?;
    let f = model.transition_matrix(dt_s);
    // x⁻ = F x̂
    let mut mean = f * state.mean();
    if let Some(u) = control {
        let b = model.control_matrix(dt_s).ok_or(EstimationError::NoControlInput)?;
        // x⁻ += B u
        mean += control_effect(&b, u)?;
    }
    // P⁻ = F P Fᵀ + Q
    let covariance = f * state.covariance() * f.transpose() + model.process_noise_matrix(dt_s);
    Gaussian::from_step(mean, covariance, to_time_s, "predicted state")
}
