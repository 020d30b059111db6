//! A constant-velocity Kalman filter for position fixes that exploits the model's structure.
//!
//! With the CV model, a per-axis process noise and a position fix whose noise is diagonal
//! (`R = diag(σ²ₓ, σ²ᵧ, σ²_z)`, seed 000's `σ_v² I₃`), a covariance that starts block-diagonal
//! per axis stays block-diagonal forever: the `2D`-state filter is exactly `D` independent
//! 2-state filters, each with a scalar measurement. This turns the 6-state, 3-measurement
//! update (a 3 × 3 factorisation and 6 × 6 products) into three scalar divisions.
//! [`DecoupledCvState::to_gaussian`] converts to the general representation, and the tests
//! check the two paths agree.

use crate::error::{EstimationError, Result};
use crate::gaussian::{step_between, Gaussian, Matrix, Vector};
use crate::motion::ProcessNoise;

/// One axis of a decoupled constant-velocity state: position, velocity and their 2 × 2
/// covariance `[[pp, pv], [pv, vv]]`.
///
/// # Units
/// m, m/s, m², m²/s, m²/s².
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CvAxis {
    /// Position (m).
    pub position_m: f64,
    /// Velocity (m/s).
    pub velocity_mps: f64,
    /// Position variance (m²).
    pub var_position: f64,
    /// Position–velocity covariance (m²/s).
    pub cov_position_velocity: f64,
    /// Velocity variance (m²/s²).
    pub var_velocity: f64,
}

/// A `D`-axis constant-velocity state whose covariance is block-diagonal per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecoupledCvState<const D: usize> {
    axes: [CvAxis; D],
    time_s: f64,
}

impl<const D: usize> DecoupledCvState<D> {
    /// Builds a state from per-axis values.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞; [`EstimationError::InvalidParameter`] if an
    /// axis covariance is not positive semi-definite.
    pub fn new(axes: [CvAxis; D], time_s: f64) -> Result<Self> {
        if !time_s.is_finite() {
            return Err(EstimationError::NonFinite { what: "state time" });
        }
        for a in &axes {
            let values = [
                a.position_m,
                a.velocity_mps,
                a.var_position,
                a.cov_position_velocity,
                a.var_velocity,
            ];
            if values.iter().any(|v| !v.is_finite()) {
                return Err(EstimationError::NonFinite {
                    what: "decoupled CV axis",
                });
            }
            if a.var_position < 0.0
                || a.var_velocity < 0.0
                || a.cov_position_velocity * a.cov_position_velocity > a.var_position * a.var_velocity * (1.0 + 1e-12)
            {
                return Err(EstimationError::InvalidParameter {
                    name: "axes",
                    reason: "an axis covariance is not positive semi-definite",
                });
            }
        }
        Ok(Self { axes, time_s })
    }

    /// The per-axis states.
    #[must_use]
    pub fn axes(&self) -> &[CvAxis; D] {
        &self.axes
    }

    /// Time of the state (s).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The same state as a general [`Gaussian`] in the CV layout `[x, vx, y, vy, z, vz]`.
    /// `N` must equal `2 D` (checked at compile time).
    #[must_use]
    pub fn to_gaussian<const N: usize>(&self) -> Gaussian<N> {
        const { assert!(N == 2 * D, "N must be 2 D") };
        let mut mean = Vector::<N>::zeros();
        let mut cov = Matrix::<N>::zeros();
        for (i, a) in self.axes.iter().enumerate() {
            let (p, v) = (2 * i, 2 * i + 1);
            mean[p] = a.position_m;
            mean[v] = a.velocity_mps;
            cov[(p, p)] = a.var_position;
            cov[(p, v)] = a.cov_position_velocity;
            cov[(v, p)] = a.cov_position_velocity;
            cov[(v, v)] = a.var_velocity;
        }
        Gaussian::from_parts_unchecked(mean, cov, self.time_s)
    }
}

/// The decoupled constant-velocity filter: predict and position-fix update per axis.
///
/// Per axis, with `F = [[1, dt], [0, 1]]`, `Q` the process-noise block and `H = [1, 0]`:
/// ```text
/// predict:  p⁻ = p + v dt
///           P⁻ = F P Fᵀ + Q
/// update:   s = P⁻ₚₚ + r                    (innovation variance)
///           k = [P⁻ₚₚ, P⁻ₚᵥ]ᵀ / s           (gain)
///           [p, v] += k (z − p⁻)
///           P = (I − k H) P⁻ (I − k H)ᵀ + r k kᵀ   (Joseph form)
/// ```
///
/// # Example
/// ```
/// use rtls_estimation::filter::{CvAxis, DecoupledCvFilter, DecoupledCvState};
/// use rtls_estimation::motion::{NoiseGain, ProcessNoise};
///
/// // Seed 000: T = 1 s, σ_w² = 5, σ_v² = 5.
/// let filter = DecoupledCvFilter::new(ProcessNoise::discrete(5.0, NoiseGain::kinematic()))?;
/// let axis = CvAxis { var_position: 100.0, var_velocity: 10.0, ..CvAxis::default() };
/// let mut state = DecoupledCvState::new([axis; 3], 0.0)?;
/// for k in 1..=5 {
///     let t = k as f64;
///     state = filter.step(&state, t, &[1.2 * t, 0.9 * t, 0.0], &[5.0; 3])?;
/// }
/// assert!((state.axes()[0].position_m - 6.0).abs() < 2.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 000 eq. (5)–(9), (16)–(20) (ME-KF); Bar-Shalom, Li, Kirubarajan (2001) §6.3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecoupledCvFilter {
    noise: ProcessNoise,
}

impl DecoupledCvFilter {
    /// A filter with the given per-axis process noise.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite noise parameter.
    pub fn new(noise: ProcessNoise) -> Result<Self> {
        noise.validate()?;
        Ok(Self { noise })
    }

    /// Predicts every axis to `to_time_s`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`], [`EstimationError::NonFinite`].
    #[inline]
    pub fn predict<const D: usize>(&self, state: &DecoupledCvState<D>, to_time_s: f64) -> Result<DecoupledCvState<D>> {
        let dt = step_between(state.time_s, to_time_s)?;
        let [[q_pp, q_pv], [_, q_vv]] = self.noise.cv_axis_block(dt);
        let mut axes = state.axes;
        for a in &mut axes {
            // p⁻ = p + v dt
            a.position_m += a.velocity_mps * dt;
            // P⁻ = F P Fᵀ + Q, F = [[1, dt], [0, 1]]:
            //   pp⁻ = pp + 2 dt pv + dt² vv + q_pp
            //   pv⁻ = pv + dt vv + q_pv
            //   vv⁻ = vv + q_vv
            a.var_position += dt * (2.0 * a.cov_position_velocity + dt * a.var_velocity) + q_pp;
            a.cov_position_velocity += dt * a.var_velocity + q_pv;
            a.var_velocity += q_vv;
        }
        finite(DecoupledCvState {
            axes,
            time_s: to_time_s,
        })
    }

    /// Updates every axis with a position fix `position_m` whose per-axis noise variances are
    /// `variance_m2` (m²).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞ in the fix; [`EstimationError::InvalidParameter`]
    /// for a non-positive variance; [`EstimationError::InnovationNotPositiveDefinite`] if an
    /// innovation variance is not positive.
    #[inline]
    pub fn update<const D: usize>(
        &self,
        state: &DecoupledCvState<D>,
        position_m: &[f64; D],
        variance_m2: &[f64; D],
    ) -> Result<DecoupledCvState<D>> {
        let mut axes = state.axes;
        for ((a, &z), &r) in axes.iter_mut().zip(position_m).zip(variance_m2) {
            if !z.is_finite() {
                return Err(EstimationError::NonFinite { what: "position fix" });
            }
            if !(r > 0.0 && r.is_finite()) {
                return Err(EstimationError::InvalidParameter {
                    name: "variance_m2",
                    reason: "must be finite and positive",
                });
            }
            // s = H P⁻ Hᵀ + r = pp⁻ + r
            let s = a.var_position + r;
            if s.is_nan() || s <= 0.0 {
                return Err(EstimationError::InnovationNotPositiveDefinite);
            }
            // k = P⁻ Hᵀ / s
            let k_p = a.var_position / s;
            let k_v = a.cov_position_velocity / s;
            // ν = z − H x⁻
            let nu = z - a.position_m;
            // x = x⁻ + k ν
            a.position_m += k_p * nu;
            a.velocity_mps += k_v * nu;
            // Joseph form with A = I − k H = [[1 − k_p, 0], [−k_v, 1]]:
            //   pp = (1 − k_p)² pp⁻ + r k_p²
            //   pv = (1 − k_p)(pv⁻ − k_v pp⁻) + r k_p k_v
            //   vv = k_v² pp⁻ − 2 k_v pv⁻ + vv⁻ + r k_v²
            let one_minus = 1.0 - k_p;
            let (pp, pv, vv) = (a.var_position, a.cov_position_velocity, a.var_velocity);
            a.var_position = one_minus * one_minus * pp + r * k_p * k_p;
            a.cov_position_velocity = one_minus * (pv - k_v * pp) + r * k_p * k_v;
            a.var_velocity = k_v * k_v * pp - 2.0 * k_v * pv + vv + r * k_v * k_v;
        }
        finite(DecoupledCvState {
            axes,
            time_s: state.time_s,
        })
    }

    /// One predict + update: predicts to `to_time_s`, then fuses the fix.
    ///
    /// # Errors
    /// As [`DecoupledCvFilter::predict`] and [`DecoupledCvFilter::update`].
    #[inline]
    pub fn step<const D: usize>(
        &self,
        state: &DecoupledCvState<D>,
        to_time_s: f64,
        position_m: &[f64; D],
        variance_m2: &[f64; D],
    ) -> Result<DecoupledCvState<D>> {
        self.update(&self.predict(state, to_time_s)?, position_m, variance_m2)
    }
}

#[inline]
fn finite<const D: usize>(state: DecoupledCvState<D>) -> Result<DecoupledCvState<D>> {
    let ok = state.axes.iter().all(|a| {
        (a.position_m + a.velocity_mps + a.var_position + a.cov_position_velocity + a.var_velocity).is_finite()
    });
    if ok {
        Ok(state)
    } else {
        Err(EstimationError::NonFinite {
            what: "decoupled CV state",
        })
    }
}
