//! The Rauch–Tung–Striebel fixed-interval smoother for the KF, EKF and UKF.
//!
//! Given the filtered states `x̂ₖ|ₖ, Pₖ|ₖ` of a whole track (posteriors, or priors where no
//! measurement arrived), the smoother runs backwards:
//! ```text
//! x⁻ₖ₊₁ = f(x̂ₖ|ₖ)                 P⁻ₖ₊₁ = F Pₖ|ₖ Fᵀ + Q        (KF/EKF; unscented transform for the UKF)
//! Cₖ   = Pₖ|ₖ Fᵀ                   (UKF: Σ Wᶜ (χₖ − x̂ₖ)(χᶠ − x⁻ₖ₊₁)ᵀ)
//! Gₖ   = Cₖ (P⁻ₖ₊₁)⁻¹
//! x̂ₖ|ₙ = x̂ₖ|ₖ + Gₖ (x̂ₖ₊₁|ₙ − x⁻ₖ₊₁)
//! Pₖ|ₙ = Pₖ|ₖ + Gₖ (Pₖ₊₁|ₙ − P⁻ₖ₊₁) Gₖᵀ
//! ```
//! The step from `k` to `k+1` uses the states' own time stamps, so irregular sampling and
//! coasting gaps are smoothed correctly. Control inputs are not replayed: smooth tracks that
//! were predicted without control (or accept that the smoother ignores `B u`).
//!
//! # References
//! Rauch, Tung, Striebel (1965); Bar-Shalom, Li, Kirubarajan (2001) §8.6; Särkkä (2008),
//! "Unscented Rauch–Tung–Striebel smoother", IEEE TAC 53(3).

use alloc::vec::Vec;

use crate::error::{EstimationError, Result};
use crate::filter::{sigma_points, weighted_moments};
use crate::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter};
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::motion::{LinearMotionModel, MotionModel};

/// One backward step given the filtered state, its one-step prediction, the cross-covariance
/// and the already-smoothed next state.
fn backward_step<const N: usize>(
    filtered: &Gaussian<N>,
    predicted_mean: &Vector<N>,
    predicted_cov: &Matrix<N>,
    cross_cov: &Matrix<N>,
    next_smoothed: &Gaussian<N>,
) -> Result<Gaussian<N>> {
    let chol = predicted_cov.cholesky().ok_or(EstimationError::NotPositiveDefinite {
        what: "predicted covariance (smoother)",
    })?;
    // G = C (P⁻)⁻¹  ⇔  Gᵀ = (P⁻)⁻¹ Cᵀ   (P⁻ symmetric)
    let gain = chol.solve(&cross_cov.transpose()).transpose();
    // x̂ₖ|ₙ = x̂ₖ|ₖ + G (x̂ₖ₊₁|ₙ − x⁻ₖ₊₁)
    let mean = filtered.mean() + gain * (next_smoothed.mean() - predicted_mean);
    // Pₖ|ₙ = Pₖ|ₖ + G (Pₖ₊₁|ₙ − P⁻ₖ₊₁) Gᵀ
    let covariance = filtered.covariance() + gain * (next_smoothed.covariance() - predicted_cov) * gain.transpose();
    Gaussian::from_step(mean, covariance, filtered.time_s(), "smoothed state")
}

/// Runs the backward pass with a per-step prediction function returning `(x⁻, P⁻, C)`.
fn smooth_with<const N: usize>(
    filtered: &[Gaussian<N>],
    mut predict: impl FnMut(&Gaussian<N>, f64) -> Result<(Vector<N>, Matrix<N>, Matrix<N>)>,
) -> Result<Vec<Gaussian<N>>> {
    let mut smoothed = filtered.to_vec();
    for k in (0..filtered.len().saturating_sub(1)).rev() {
        let dt_s = filtered[k].step_to(filtered[k + 1].time_s())?;
        let (xp, pp, c) = predict(&filtered[k], dt_s)?;
        smoothed[k] = backward_step(&filtered[k], &xp, &pp, &c, &smoothed[k + 1])?;
    }
    Ok(smoothed)
}

impl KalmanFilter {
    /// RTS-smooths a filtered track (oldest first) with a linear motion model.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if the states are not in time order;
    /// [`EstimationError::NotPositiveDefinite`] if a predicted covariance is singular.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::filter::KalmanFilter;
    /// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// let motion = ConstantVelocity::new(ProcessNoise::discrete(0.5, NoiseGain::kinematic()))?;
    /// let kf = KalmanFilter::default();
    /// let x0 = Gaussian::new(Vector::<2>::new(0.0, 1.0), Matrix::<2>::identity(), 0.0)?;
    /// let x1 = kf.predict(&x0, &motion, 1.0)?;
    /// let smoothed = kf.smooth(&[x0, x1], &motion)?;
    /// // Without measurements, smoothing a pure prediction changes nothing.
    /// assert!((smoothed[0].mean() - x0.mean()).norm() < 1e-12);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn smooth<const N: usize, M: LinearMotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        smooth_with(filtered, |state, dt_s| {
            let f = model.transition_matrix(dt_s);
            // C = P Fᵀ
            let c = state.covariance() * f.transpose();
            // x⁻ = F x̂,  P⁻ = F P Fᵀ + Q
            Ok((f * state.mean(), f * c + model.process_noise_matrix(dt_s), c))
        })
    }
}

impl ExtendedKalmanFilter {
    /// RTS-smooths a filtered track with a (possibly nonlinear) motion model linearised at each
    /// filtered state (the extended RTS smoother).
    ///
    /// # Errors
    /// As [`KalmanFilter::smooth`].
    pub fn smooth<const N: usize, M: MotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        smooth_with(filtered, |state, dt_s| {
            // F = ∂f/∂x at x̂ₖ|ₖ
            let f = model.transition_jacobian(state.mean(), dt_s);
            // C = P Fᵀ
            let c = state.covariance() * f.transpose();
            // x⁻ = f(x̂),  P⁻ = F P Fᵀ + Q
            let q = model.process_noise(state.mean(), dt_s);
            Ok((model.transition(state.mean(), dt_s), f * c + q, c))
        })
    }
}

impl UnscentedKalmanFilter {
    /// Unscented RTS smoother (Särkkä 2008): predictions and cross-covariances by the
    /// unscented transform of the filtered states.
    ///
    /// # Errors
    /// As [`KalmanFilter::smooth`], plus sigma-point factorisation failures.
    pub fn smooth<const N: usize, M: MotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        let weights = self.parameters.unscented_weights(N)?;
        smooth_with(filtered, |state, dt_s| {
            // χ = σ(x̂ₖ|ₖ, Pₖ|ₖ),  χᶠ = f(χ, dt)
            let points = sigma_points(state, weights.scale)?;
            let propagated: Vec<Vector<N>> = points.iter().map(|p| model.transition(p, dt_s)).collect();
            // x⁻ = Σ Wᵐ χᶠ,  P⁻ = Σ Wᶜ (χᶠ − x⁻)(…)ᵀ + Q
            let (xp, pp) = weighted_moments(&propagated, &weights);
            let pp = pp + model.process_noise(state.mean(), dt_s);
            // C = Σ Wᶜ (χ − x̂)(χᶠ − x⁻)ᵀ
            let mut c = Matrix::<N>::zeros();
            for (i, (p, pf)) in points.iter().zip(&propagated).enumerate() {
                c.ger(weights.covariance(i), &(p - state.mean()), &(pf - xp), 1.0);
            }
            Ok((xp, pp, c))
        })
    }
}
