//! The unscented Kalman filter with scaled (Merwe) sigma points.

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::predict::control_effect;
use super::update::{check_measurement, solve_gain, Gain, GainSolution, Updated};
use crate::error::{EstimationError, Result};
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::measurement::MeasurementModel;
use crate::motion::MotionModel;

/// Parameters of the scaled unscented transform.
///
/// ```text
/// λ = α² (n + κ) − n
/// W₀ᵐ = λ / (n + λ)      W₀ᶜ = λ / (n + λ) + 1 − α² + β      Wᵢᵐ = Wᵢᶜ = 1 / (2 (n + λ))
/// ```
/// `α` sets the spread of the points around the mean (small α: close to the mean), `β = 2`
/// is optimal for Gaussian priors, `κ` is a secondary scaling (usually `0` or `3 − n`).
///
/// # References
/// Van der Merwe (2004), *Sigma-point Kalman filters*, PhD thesis, §3.2; seed 001 §1
/// (α = 0.01, β = 2, κ = 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaPointParameters {
    /// Spread `α` (> 0).
    pub alpha: f64,
    /// Prior-distribution parameter `β` (2 for Gaussians).
    pub beta: f64,
    /// Secondary scaling `κ`.
    pub kappa: f64,
}

impl SigmaPointParameters {
    /// Seed 001's parameters: `α = 0.01`, `β = 2`, `κ = 0`.
    #[must_use]
    pub fn seed_001() -> Self {
        Self {
            alpha: 0.01,
            beta: 2.0,
            kappa: 0.0,
        }
    }

    /// Validated parameters.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] unless `α > 0` and all are finite.
    pub fn new(alpha: f64, beta: f64, kappa: f64) -> Result<Self> {
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "alpha",
                reason: "must be finite and positive",
            });
        }
        if !beta.is_finite() || !kappa.is_finite() {
            return Err(EstimationError::InvalidParameter {
                name: "beta/kappa",
                reason: "must be finite",
            });
        }
        Ok(Self { alpha, beta, kappa })
    }

    /// Weights for an `n`-dimensional state: `(n + λ, mean weights, covariance weights)`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `n + λ ≤ 0` (κ too negative for this `n`).
    pub fn weights(&self, n: usize) -> Result<(f64, Vec<f64>, Vec<f64>)> {
        let w = self.unscented_weights(n)?;
        let wm = (0..=2 * n).map(|i| w.mean(i)).collect();
        let wc = (0..=2 * n).map(|i| w.covariance(i)).collect();
        Ok((w.scale, wm, wc))
    }

    /// The weights as four scalars (no allocation), for the filters' hot paths.
    pub(crate) fn unscented_weights(&self, n: usize) -> Result<UnscentedWeights> {
        let n_f = n as f64;
        // λ = α² (n + κ) − n
        let lambda = self.alpha * self.alpha * (n_f + self.kappa) - n_f;
        let scale = n_f + lambda;
        if scale.is_nan() || scale <= 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "kappa",
                reason: "n + λ must be positive",
            });
        }
        Ok(UnscentedWeights {
            scale,
            // W₀ᵐ = λ / (n + λ)
            mean_0: lambda / scale,
            // W₀ᶜ = λ / (n + λ) + 1 − α² + β
            covariance_0: lambda / scale + 1.0 - self.alpha * self.alpha + self.beta,
            // Wᵢ = 1 / (2 (n + λ))
            other: 0.5 / scale,
        })
    }
}

/// Unscented-transform weights: `n + λ`, `W₀ᵐ`, `W₀ᶜ` and the common `Wᵢ` (i ≥ 1).
#[derive(Debug, Clone, Copy)]
pub(crate) struct UnscentedWeights {
    pub(crate) scale: f64,
    mean_0: f64,
    covariance_0: f64,
    other: f64,
}

impl UnscentedWeights {
    /// `Wᵢᵐ`.
    #[inline]
    pub(crate) fn mean(&self, i: usize) -> f64 {
        if i == 0 {
            self.mean_0
        } else {
            self.other
        }
    }

    /// `Wᵢᶜ`.
    #[inline]
    pub(crate) fn covariance(&self, i: usize) -> f64 {
        if i == 0 {
            self.covariance_0
        } else {
            self.other
        }
    }
}

impl Default for SigmaPointParameters {
    /// `α = 1`, `β = 2`, `κ = 0`: points at `±√n σ`, a robust default for tracking.
    fn default() -> Self {
        Self {
            alpha: 1.0,
            beta: 2.0,
            kappa: 0.0,
        }
    }
}

/// Sigma points `χ₀ = x`, `χᵢ = x + (√((n+λ)P))ᵢ`, `χₙ₊ᵢ = x − (√((n+λ)P))ᵢ` (columns of the
/// lower Cholesky factor).
pub(crate) fn sigma_points<const N: usize>(state: &Gaussian<N>, scale: f64) -> Result<Vec<Vector<N>>> {
    // L Lᵀ = (n + λ) P
    let l = (state.covariance() * scale)
        .cholesky()
        .ok_or(EstimationError::NotPositiveDefinite {
            what: "state covariance (sigma points)",
        })?
        .unpack();
    let x = state.mean();
    let mut points = Vec::with_capacity(2 * N + 1);
    points.push(*x);
    for i in 0..N {
        points.push(x + l.column(i));
    }
    for i in 0..N {
        points.push(x - l.column(i));
    }
    Ok(points)
}

/// `x̄ = Σ Wᵐ χ`, `P = Σ Wᶜ (χ − x̄)(χ − x̄)ᵀ`.
pub(crate) fn weighted_moments<const N: usize>(
    points: &[Vector<N>],
    weights: &UnscentedWeights,
) -> (Vector<N>, Matrix<N>) {
    // x̄ = Σ Wᵢᵐ χᵢ
    let mut mean = Vector::<N>::zeros();
    for (i, p) in points.iter().enumerate() {
        mean.axpy(weights.mean(i), p, 1.0);
    }
    // P = Σ Wᵢᶜ (χᵢ − x̄)(χᵢ − x̄)ᵀ
    let mut cov = Matrix::<N>::zeros();
    for (i, p) in points.iter().enumerate() {
        let d = p - mean;
        cov.ger(weights.covariance(i), &d, &d, 1.0);
    }
    (mean, cov)
}

/// The unscented Kalman filter.
///
/// ```text
/// predict: χ = σ(x̂, P)                    χᶠ = f(χ, dt) + B u
///          x⁻ = Σ Wᵐ χᶠ                   P⁻ = Σ Wᶜ (χᶠ − x⁻)(χᶠ − x⁻)ᵀ + Q
/// update:  χ = σ(x⁻, P⁻)  (redrawn)       Z = h(χ)
///          ẑ = Σ Wᵐ Z                     S = Σ Wᶜ (Z − ẑ)(Z − ẑ)ᵀ + R
///          Pxz = Σ Wᶜ (χ − x⁻)(Z − ẑ)ᵀ    K = Pxz S⁻¹
///          x̂ = x⁻ + K (z − ẑ)             P = P⁻ − K S Kᵀ  (computed as P⁻ − Pxz Kᵀ)
/// ```
/// Sigma points are redrawn from the predicted mean and covariance before the update (so the
/// process noise `Q` is reflected in the measurement sigma points), as FilterPy 2.0 does.
///
/// # Errors
/// [`EstimationError::NotPositiveDefinite`] if a covariance cannot be factorised for sigma
/// points, and the errors of [`crate::filter::ExtendedKalmanFilter`].
///
/// # Example
/// Seed 001: ranges to base stations at (2, 2) and (20, 40).
/// ```
/// use rtls_estimation::filter::{SigmaPointParameters, UnscentedKalmanFilter};
/// use rtls_estimation::measurement::{NoiseCovariance, Ranges};
/// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// use nalgebra::DVector;
///
/// let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::seed_001());
/// let motion = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic()))?;
/// let toa = Ranges::planar(&[[2.0, 2.0], [20.0, 40.0]], NoiseCovariance::isotropic(2, 0.09)?)?;
/// let x0 = Gaussian::new(Vector::<4>::new(2.0, 0.1, 10.0, 0.5), Matrix::<4>::identity(), 0.0)?;
/// let prior = ukf.predict(&x0, &motion, 1.0)?;
/// let updated = ukf.update(&prior, &toa, &DVector::from_vec(vec![8.6, 29.6]))?;
/// assert!(updated.state.covariance()[(0, 0)] < prior.covariance()[(0, 0)]);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Julier & Uhlmann (2004); Van der Merwe (2004) Alg. 3.1; seed 001 §1 (UKF equations).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UnscentedKalmanFilter {
    /// Sigma-point parameters.
    pub parameters: SigmaPointParameters,
}

impl UnscentedKalmanFilter {
    /// A filter with the given sigma-point parameters.
    #[must_use]
    pub fn new(parameters: SigmaPointParameters) -> Self {
        Self { parameters }
    }

    /// Predicts `state` to `to_time_s` through the unscented transform of `f`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`], [`EstimationError::NotPositiveDefinite`],
    /// [`EstimationError::NonFinite`], [`EstimationError::InvalidParameter`] (weights).
    pub fn predict<const N: usize, M: MotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        self.predict_inner(state, model, None, to_time_s)
    }

    /// Predicts with a control input: `χᶠ = f(χ, dt) + B u`.
    ///
    /// # Errors
    /// As [`UnscentedKalmanFilter::predict`], plus [`EstimationError::NoControlInput`] and
    /// [`EstimationError::DimensionMismatch`] for the control.
    pub fn predict_with_control<const N: usize, M: MotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        control: &DVector<f64>,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        self.predict_inner(state, model, Some(control), to_time_s)
    }

    fn predict_inner<const N: usize, M: MotionModel<N>>(
        &self,
        state: &Gaussian<N>,
        model: &M,
        control: Option<&DVector<f64>>,
        to_time_s: f64,
    ) -> Result<Gaussian<N>> {
        let dt_s = state.step_to(to_time_s)?;
        let weights = self.parameters.unscented_weights(N)?;
        let offset = match control {
            Some(u) => {
                let b = model.control_gain(dt_s).ok_or(EstimationError::NoControlInput)?;
                control_effect(&b, u)?
            }
            None => Vector::<N>::zeros(),
        };
        // χᶠᵢ = f(χᵢ, dt) + B u
        let mut points = sigma_points(state, weights.scale)?;
        for p in &mut points {
            *p = model.transition(p, dt_s) + offset;
        }
        // x⁻ = Σ Wᵐ χᶠ,  P⁻ = Σ Wᶜ (χᶠ − x⁻)(χᶠ − x⁻)ᵀ
        let (mean, cov) = weighted_moments(&points, &weights);
        // P⁻ += Q
        let covariance = cov + model.process_noise(state.mean(), dt_s);
        Gaussian::from_step(mean, covariance, to_time_s, "predicted state")
    }

    /// Updates a predicted state with measurement `z` through the unscented transform of `h`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`], [`EstimationError::NonFinite`],
    /// [`EstimationError::NotPositiveDefinite`], [`EstimationError::SingularMeasurement`],
    /// [`EstimationError::InnovationNotPositiveDefinite`].
    pub fn update<const N: usize, H: MeasurementModel<N>>(
        &self,
        prior: &Gaussian<N>,
        model: &H,
        z: &DVector<f64>,
    ) -> Result<Updated<N>> {
        let m = model.dim();
        check_measurement(z, m)?;
        let r = model.noise_covariance();
        if r.nrows() != m || r.ncols() != m {
            return Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: m,
                found: r.nrows(),
            });
        }
        let weights = self.parameters.unscented_weights(N)?;
        // χ = σ(x⁻, P⁻), redrawn after the prediction
        let points = sigma_points(prior, weights.scale)?;
        // Zᵢ = h(χᵢ)
        let mut z_points = DMatrix::<f64>::zeros(m, points.len());
        for (i, p) in points.iter().enumerate() {
            let zi = model.predict(p)?;
            if zi.len() != m {
                return Err(EstimationError::DimensionMismatch {
                    what: "predicted measurement",
                    expected: m,
                    found: zi.len(),
                });
            }
            z_points.set_column(i, &zi);
        }
        // ẑ = Σ Wᵐ Zᵢ
        let wm: Vec<f64> = (0..points.len()).map(|i| weights.mean(i)).collect();
        let z_mean = model.weighted_mean(&z_points, &wm);
        // ΔZ = [Zᵢ − ẑ]  (through the model's residual, so angles wrap)
        let dz = model.residuals(&z_points, &z_mean);
        let mut s = r.clone();
        let mut pxz = Gain::<N>::zeros(m);
        for (i, p) in points.iter().enumerate() {
            let w = weights.covariance(i);
            let dz_i = dz.column(i);
            // S += Wᶜᵢ (Zᵢ − ẑ)(Zᵢ − ẑ)ᵀ      (S starts at R)
            s.ger(w, &dz_i, &dz_i, 1.0);
            // Pxz += Wᶜᵢ (χᵢ − x⁻)(Zᵢ − ẑ)ᵀ
            pxz.ger(w, &(p - prior.mean()), &dz_i, 1.0);
        }
        // ν = z − ẑ
        let innovation = model.residual(z, &z_mean);
        // K = Pxz S⁻¹,  NIS = νᵀ S⁻¹ ν
        let GainSolution {
            gain,
            gain_t,
            nis,
            log_det,
        } = solve_gain(&s, &pxz, &innovation)?;
        // x̂ = x⁻ + K ν
        let mean = prior.mean() + &gain * &innovation;
        // P = P⁻ − K S Kᵀ = P⁻ − Pxz Kᵀ   (K S = Pxz)
        let covariance = prior.covariance() - &pxz * &gain_t;
        let state = Gaussian::from_step(mean, covariance, prior.time_s(), "posterior state")?;
        Ok(Updated {
            state,
            innovation,
            innovation_covariance: s,
            gain,
            nis,
            log_det_innovation_covariance: log_det,
        })
    }
}
