//! The extended Kalman filter.

use nalgebra::DVector;

use super::predict::control_effect;
use super::update::{
    check_measurement, check_model_shapes, linearized_update, sequential_update, CovarianceUpdate, Updated,
};
use crate::error::{EstimationError, Result};
use crate::gaussian::Gaussian;
use crate::measurement::MeasurementModel;
use crate::motion::MotionModel;

/// The extended Kalman filter: the Kalman filter with nonlinear models linearised at the
/// current estimate by their analytic Jacobians.
///
/// ```text
/// predict:  x⁻ = f(x̂, dt) + B u      F = ∂f/∂x |x̂      P⁻ = F P Fᵀ + Q
/// update:   ν = z − h(x⁻)             H = ∂h/∂x |x⁻      S = H P⁻ Hᵀ + R
///           K = P⁻ Hᵀ S⁻¹             x̂ = x⁻ + K ν       P = (I−KH) P⁻ (I−KH)ᵀ + K R Kᵀ
/// ```
///
/// # Errors
/// As [`crate::filter::KalmanFilter`], plus [`EstimationError::SingularMeasurement`] where a
/// model's Jacobian is undefined (e.g. the state sits on a range anchor).
///
/// # Example
/// Seed 003's single-range EKF: one ultrasonic range per cycle.
/// ```
/// use rtls_estimation::filter::ExtendedKalmanFilter;
/// use rtls_estimation::measurement::{NoiseCovariance, Ranges};
/// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// use nalgebra::DVector;
///
/// let motion = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic()))?;
/// let ekf = ExtendedKalmanFilter::default();
/// let x0 = Gaussian::new(Vector::<4>::new(1.0, 0.5, 1.0, 0.0), Matrix::<4>::identity(), 0.0)?;
/// let prior = ekf.predict(&x0, &motion, 0.2)?;
/// let node = Ranges::planar(&[[4.0, 0.0]], NoiseCovariance::isotropic(1, 0.0004)?)?;
/// let updated = ekf.update(&prior, &node, &DVector::from_vec(vec![3.0]))?;
/// assert_eq!(updated.measurement_dim(), 1);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan (2001) §10.3; seed 003 eq. (6)–(9) (single-range EKF).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ExtendedKalmanFilter {
    /// Posterior covariance form (Joseph by default).
    pub covariance_update: CovarianceUpdate,
}

impl ExtendedKalmanFilter {
    /// A filter using the given covariance update form.
    #[must_use]
    pub fn new(covariance_update: CovarianceUpdate) -> Self {
        Self { covariance_update }
    }

    /// Predicts `state` to `to_time_s` through the (nonlinear) motion model.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`], [`EstimationError::NonFinite`].
    pub fn predict<const N: usize, M: MotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        predict_linearized(state, model, None, to_time_s)
    }

    /// Predicts with a control input: `x⁻ = f(x̂, dt) + B u`.
    ///
    /// # Errors
    /// As [`ExtendedKalmanFilter::predict`], plus [`EstimationError::NoControlInput`] and
    /// [`EstimationError::DimensionMismatch`] for the control.
    pub fn predict_with_control<const N: usize, M: MotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        control: &DVector<f64>,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        predict_linearized(state, model, Some(control), to_time_s)
    }

    /// Updates with measurement `z` of a (possibly nonlinear) model.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`], [`EstimationError::NonFinite`],
    /// [`EstimationError::SingularMeasurement`], [`EstimationError::InnovationNotPositiveDefinite`].
    pub fn update<const N: usize, H: MeasurementModel<N>>(
        &self,
        prior: &Gaussian<N>,
        model: &H,
        z: &DVector<f64>,
    ) -> Result<Updated<N>> {
        check_measurement(z, model.dim())?;
        let h = model.jacobian(prior.mean())?;
        let r = model.noise_covariance();
        check_model_shapes(&h, r, model.dim())?;
        // ν = z − h(x⁻)
        let innovation = model.residual(z, &model.predict(prior.mean())?);
        linearized_update(prior, innovation, &h, r, self.covariance_update)
    }

    /// Updates with the components of `z` one at a time, re-linearising `h` at the current
    /// estimate before each scalar update (needs a diagonal `R`).
    ///
    /// The returned innovation, `S`, gain and NIS are the batch quantities at the prior; the
    /// state is the result of the scalar updates. For a single range (seed 003) it equals
    /// [`ExtendedKalmanFilter::update`].
    ///
    /// # Errors
    /// As [`ExtendedKalmanFilter::update`], plus [`EstimationError::CorrelatedNoise`].
    pub fn update_sequential<const N: usize, H: MeasurementModel<N>>(
        &self,
        prior: &Gaussian<N>,
        model: &H,
        z: &DVector<f64>,
    ) -> Result<Updated<N>> {
        sequential_update(prior, model, z, self.covariance_update)
    }
}

/// `x⁻ = f(x̂) + B u`, `P⁻ = F P Fᵀ + Q` with `F` the Jacobian at `x̂`.
pub(crate) fn predict_linearized<const N: usize, M: MotionModel<N>>(
    state: &Gaussian<N>,
    model: &M,
    control: Option<&DVector<f64>>,
    to_time_s: f64,
) -> Result<Gaussian<N>> {
    let dt_s = state.step_to(to_time_s)?;
    // F = ∂f/∂x at x̂
    let f = model.transition_jacobian(state.mean(), dt_s);
    // x⁻ = f(x̂, dt)
    let mut mean = model.transition(state.mean(), dt_s);
    if let Some(u) = control {
        let b = model.control_gain(dt_s).ok_or(EstimationError::NoControlInput)?;
        // x⁻ += B u
        mean += control_effect(&b, u)?;
    }
    // P⁻ = F P Fᵀ + Q
    let covariance = f * state.covariance() * f.transpose() + model.process_noise(state.mean(), dt_s);
    Gaussian::from_step(mean, covariance, to_time_s, "predicted state")
}
