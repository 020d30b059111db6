//! A heading channel with bias states: yaw rate (gyro or wheel odometry) integrated into the
//! heading, the gyro's bias and an odometer heading's offset estimated against absolute
//! headings and the course over ground.
//!
//! State `x = [ψ, b_g, δ]ᵀ`: the true heading `ψ` (rad, counter-clockwise from the site's x
//! axis), the gyro's yaw-rate bias `b_g` (rad/s) and the offset `δ` (rad) of an odometer's
//! heading from the true one (its drift, seed 004). It is an error-state channel in the sense of
//! Groves (2013) §14.1: the rate sensor drives the prediction, the heading references correct it
//! and calibrate the sensor's errors.
//!
//! ```text
//! prediction over Δt with a measured yaw rate ω (held from the previous sample):
//!   ψ ← ψ + (ω − b_g) Δt,   F = [[1, −Δt, 0], [0, 1, 0], [0, 0, 1]]
//!   Q = [[σ_ω² Δt² + q_b Δt³/3, −q_b Δt²/2, 0], [−q_b Δt²/2, q_b Δt, 0], [0, 0, q_δ Δt]]
//! without a rate sensor: ψ a random walk, Q_ψψ = q_ψ Δt
//! heading reference (compass, the course over ground):  z = ψ + v,       H = [1, 0, 0]
//! odometer heading:                                      z = ψ + δ + v,   H = [1, 0, 1]
//! ```
//! Innovations are wrapped to `(−π, π]`; `ψ` and `δ` are kept wrapped.
//!
//! # References
//! Groves, *Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems*, 2nd
//! ed. (2013), §14.1 (error-state integration), §16.2 (heading and odometer calibration);
//! seed 004 §3 (heading drift); Bar-Shalom, Li & Kirubarajan (2001) §5.2 (the Kalman filter).

use nalgebra::{Matrix3, RowVector3, Vector3};

use crate::error::{EstimationError, Result};
use crate::math::wrap_angle;
use crate::Gaussian;

/// The heading channel's noise model: an immutable strategy shared by every track.
///
/// State `[ψ, b_g, δ]`: heading (rad), gyro bias (rad/s), odometer heading offset (rad).
/// ```text
/// with a yaw rate ω held over Δt:  ψ ← ψ + (ω − b_g) Δt,  F = [[1, −Δt, 0], [0, 1, 0], [0, 0, 1]]
///   Q = [[σ_ω² Δt² + q_b Δt³/3, −q_b Δt²/2, 0], [−q_b Δt²/2, q_b Δt, 0], [0, 0, q_δ Δt]]
/// without one:                     Q = diag(q_ψ Δt, q_b Δt, q_δ Δt)
/// heading reference  z = ψ + v (H = [1, 0, 0]);  odometer heading  z = ψ + δ + v (H = [1, 0, 1])
/// ```
///
/// # Units
/// Rates in rad/s; random-walk densities in rad/√s (`q = σ²`, variance per second) or
/// rad/s/√s for the bias.
///
/// # Example
/// ```
/// use rtls_estimation::aided::HeadingModel;
/// // a MEMS gyro (bias up to 0.6°/s), a vehicle turning at up to ~0.3 rad/s without a gyro
/// let model = HeadingModel::new(0.01, 1e-4, 0.3, 0.005, 0.05)?;
/// // aligned east (ψ = 0 ± 0.1 rad), then 1 s at a measured 0.1 rad/s
/// let state = model.start(0.0, 0.0, 0.01)?;
/// let state = model.propagate(&state, 1.0, Some((0.1, 1e-4)))?;
/// assert!((state.heading_rad() - 0.1).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingModel {
    /// `σ_b0`: prior std of the gyro bias, rad/s.
    gyro_bias_std_radps: f64,
    /// `√q_b`: bias random walk, rad/s/√s.
    gyro_bias_random_walk: f64,
    /// `√q_ψ`: heading random walk when no rate is measured, rad/√s.
    heading_random_walk: f64,
    /// `√q_δ`: odometer heading offset random walk (its drift), rad/√s.
    odometer_drift: f64,
    /// `σ_δ0`: prior std of the odometer heading offset, rad.
    odometer_offset_std_rad: f64,
}

/// The state of a [`HeadingModel`]: `[ψ, b_g, δ]` with its covariance and time.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HeadingState {
    state: Gaussian<3>,
}

fn positive(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(EstimationError::InvalidParameter {
            name,
            reason: "must be positive and finite",
        })
    }
}

impl HeadingModel {
    /// A model from the gyro bias's prior std (rad/s) and random walk (rad/s/√s), the
    /// heading's random walk without a rate sensor (rad/√s), and the odometer heading offset's
    /// drift (rad/√s) and prior std (rad).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a parameter that is not positive and finite.
    pub fn new(
        gyro_bias_std_radps: f64,
        gyro_bias_random_walk: f64,
        heading_random_walk: f64,
        odometer_drift: f64,
        odometer_offset_std_rad: f64,
    ) -> Result<Self> {
        Ok(Self {
            gyro_bias_std_radps: positive("gyro_bias_std_radps", gyro_bias_std_radps)?,
            gyro_bias_random_walk: positive("gyro_bias_random_walk", gyro_bias_random_walk)?,
            heading_random_walk: positive("heading_random_walk", heading_random_walk)?,
            odometer_drift: positive("odometer_drift", odometer_drift)?,
            odometer_offset_std_rad: positive("odometer_offset_std_rad", odometer_offset_std_rad)?,
        })
    }

    /// Starts the channel at `time_s` from a heading `heading_rad` with variance
    /// `heading_variance_rad2` (> 0); the biases start at zero with their priors.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞; [`EstimationError::InvalidParameter`] for a
    /// variance that is not positive.
    pub fn start(&self, time_s: f64, heading_rad: f64, heading_variance_rad2: f64) -> Result<HeadingState> {
        if !heading_rad.is_finite() {
            return Err(EstimationError::NonFinite { what: "heading" });
        }
        positive("heading_variance_rad2", heading_variance_rad2)?;
        // x₀ = [ψ, 0, 0],  P₀ = diag(σ_ψ², σ_b0², σ_δ0²)
        let mean = Vector3::new(wrap_angle(heading_rad), 0.0, 0.0);
        let covariance = Matrix3::from_diagonal(&Vector3::new(
            heading_variance_rad2,
            self.gyro_bias_std_radps * self.gyro_bias_std_radps,
            self.odometer_offset_std_rad * self.odometer_offset_std_rad,
        ));
        Ok(HeadingState {
            state: Gaussian::new(mean, covariance, time_s)?,
        })
    }

    /// Predicts to `time_s`, integrating the yaw rate `(ω, σ_ω²)` (rad/s, (rad/s)²) held since
    /// the state's time, or as a random walk without one (equations in the module documentation, also in [`HeadingModel`]).
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] for an earlier time; [`EstimationError::NonFinite`]
    /// for a NaN/∞ rate or result.
    pub fn propagate(&self, state: &HeadingState, time_s: f64, yaw_rate: Option<(f64, f64)>) -> Result<HeadingState> {
        let dt = state.state.step_to(time_s)?;
        let x = state.state.mean();
        let p = state.state.covariance();
        let q_b = self.gyro_bias_random_walk * self.gyro_bias_random_walk;
        // Q_δδ = q_δ Δt
        let q_delta = self.odometer_drift * self.odometer_drift * dt;
        let (mean, f, q) = match yaw_rate {
            Some((rate, variance)) => {
                if !(rate.is_finite() && variance.is_finite() && variance >= 0.0) {
                    return Err(EstimationError::NonFinite { what: "yaw rate" });
                }
                // ψ ← ψ + (ω − b_g) Δt
                let mean = Vector3::new(wrap_angle(x[0] + (rate - x[1]) * dt), x[1], x[2]);
                let f = Self::transition(dt, true);
                // Q_ψψ = σ_ω² Δt² + q_b Δt³/3, Q_ψb = −q_b Δt²/2, Q_bb = q_b Δt
                let q = Matrix3::new(
                    variance * dt * dt + q_b * dt * dt * dt / 3.0,
                    -q_b * dt * dt / 2.0,
                    0.0,
                    -q_b * dt * dt / 2.0,
                    q_b * dt,
                    0.0,
                    0.0,
                    0.0,
                    q_delta,
                );
                (mean, f, q)
            }
            None => {
                // ψ a random walk: Q_ψψ = q_ψ Δt; the bias, unobserved, still wanders
                let q_psi = self.heading_random_walk * self.heading_random_walk * dt;
                let q = Matrix3::from_diagonal(&Vector3::new(q_psi, q_b * dt, q_delta));
                (*x, Self::transition(dt, false), q)
            }
        };
        // P ← F P Fᵀ + Q
        let covariance = f * p * f.transpose() + q;
        Ok(HeadingState {
            state: Gaussian::from_step(mean, covariance, time_s, "heading state")?,
        })
    }

    /// The state transition `F` of a prediction over `dt_s` (s): with a yaw rate held
    /// (`rate_held`), `F = [[1, −Δt, 0], [0, 1, 0], [0, 0, 1]]` (the bias's error enters the
    /// heading's); without one, `I`. Other filters whose errors are correlated with this
    /// channel's carry their cross-covariance with it, `X ← X Fᵀ`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::aided::HeadingModel;
    /// let f = HeadingModel::transition(0.5, true);
    /// assert_eq!(f[(0, 1)], -0.5);
    /// ```
    #[must_use]
    pub fn transition(dt_s: f64, rate_held: bool) -> Matrix3<f64> {
        if rate_held {
            // F = [[1, −Δt, 0], [0, 1, 0], [0, 0, 1]]
            Matrix3::new(1.0, -dt_s, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
        } else {
            Matrix3::identity()
        }
    }

    /// Updates with a heading reference `z = ψ + v` (compass, course over ground), variance
    /// `variance_rad2` (> 0); `None` when the wrapped innovation is outside `gate_sigmas`
    /// standard deviations of `S` (the reference and the state disagree: the state is kept).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞; [`EstimationError::InvalidParameter`] for a
    /// variance that is not positive.
    pub fn observe_heading(
        &self,
        state: &HeadingState,
        heading_rad: f64,
        variance_rad2: f64,
        gate_sigmas: f64,
    ) -> Result<Option<HeadingState>> {
        update(
            state,
            RowVector3::new(1.0, 0.0, 0.0),
            heading_rad,
            variance_rad2,
            gate_sigmas,
        )
    }

    /// Adds `variance_rad2` (≥ 0) to the odometer offset's variance, `P_δδ ← P_δδ + q`: the
    /// drift an odometer states itself, as the growth of its heading's standard deviation from
    /// one record to the next (its heading error is accumulated, so that growth is the offset
    /// moving, not a fresh error of each record).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite variance.
    pub fn drift_odometer_offset(&self, state: &HeadingState, variance_rad2: f64) -> Result<HeadingState> {
        if !(variance_rad2.is_finite() && variance_rad2 >= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "variance_rad2",
                reason: "must be a finite variance ≥ 0",
            });
        }
        let mut covariance = *state.state.covariance();
        // P_δδ ← P_δδ + q
        covariance[(2, 2)] += variance_rad2;
        Ok(HeadingState {
            state: Gaussian::from_step(*state.state.mean(), covariance, state.state.time_s(), "heading state")?,
        })
    }

    /// Updates with an odometer heading `z = ψ + δ + v`, variance `variance_rad2` (> 0); `None`
    /// when outside the gate (as [`HeadingModel::observe_heading`]).
    ///
    /// # Errors
    /// As [`HeadingModel::observe_heading`].
    pub fn observe_odometer_heading(
        &self,
        state: &HeadingState,
        heading_rad: f64,
        variance_rad2: f64,
        gate_sigmas: f64,
    ) -> Result<Option<HeadingState>> {
        update(
            state,
            RowVector3::new(1.0, 0.0, 1.0),
            heading_rad,
            variance_rad2,
            gate_sigmas,
        )
    }
}

/// One scalar angle update `z = H x + v` with a wrapped innovation.
fn update(
    state: &HeadingState,
    h: RowVector3<f64>,
    z: f64,
    variance_rad2: f64,
    gate_sigmas: f64,
) -> Result<Option<HeadingState>> {
    if !z.is_finite() {
        return Err(EstimationError::NonFinite { what: "heading" });
    }
    positive("variance_rad2", variance_rad2)?;
    let x = state.state.mean();
    let p = state.state.covariance();
    // y = wrap(z − H x)
    let y = wrap_angle(z - (h * x)[0]);
    // S = H P Hᵀ + R
    let s = (h * p * h.transpose())[0] + variance_rad2;
    if y * y > gate_sigmas * gate_sigmas * s {
        return Ok(None);
    }
    // K = P Hᵀ / S
    let k = p * h.transpose() / s;
    // x ← x + K y  (angles wrapped)
    let mut mean = x + k * y;
    mean[0] = wrap_angle(mean[0]);
    mean[2] = wrap_angle(mean[2]);
    // P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ  (Joseph form: stays positive definite)
    let i_kh = Matrix3::identity() - k * h;
    let covariance = i_kh * p * i_kh.transpose() + k * variance_rad2 * k.transpose();
    Ok(Some(HeadingState {
        state: Gaussian::from_step(mean, covariance, state.state.time_s(), "heading state")?,
    }))
}

impl HeadingState {
    /// `ψ̂`, rad in `(−π, π]`.
    #[must_use]
    pub fn heading_rad(&self) -> f64 {
        self.state.mean()[0]
    }

    /// `var(ψ̂)`, rad².
    #[must_use]
    pub fn heading_variance_rad2(&self) -> f64 {
        self.state.covariance()[(0, 0)]
    }

    /// `(b̂_g, var(b̂_g))`, rad/s and (rad/s)².
    #[must_use]
    pub fn gyro_bias(&self) -> (f64, f64) {
        (self.state.mean()[1], self.state.covariance()[(1, 1)])
    }

    /// `(δ̂, var(δ̂))`, the odometer heading's offset, rad and rad².
    #[must_use]
    pub fn odometer_offset(&self) -> (f64, f64) {
        (self.state.mean()[2], self.state.covariance()[(2, 2)])
    }

    /// The state's time, s.
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.state.time_s()
    }

    /// The whole state `[ψ, b_g, δ]` with its covariance.
    #[must_use]
    pub fn gaussian(&self) -> &Gaussian<3> {
        &self.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> HeadingModel {
        HeadingModel::new(0.02, 1e-5, 0.3, 0.002, 0.05).unwrap()
    }

    /// A deterministic pseudo-random normal (Box–Muller on a linear congruential stream).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn sample(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (core::f64::consts::TAU * v).cos()
        }
    }

    #[test]
    fn propagation_matches_the_closed_form_covariance() {
        // one step from P₀ = diag(a, b, c): P_ψψ = a + Δt² b + σ_ω² Δt² + q_b Δt³/3
        let m = model();
        let s = m.start(0.0, 0.3, 0.01).unwrap();
        let s = m.propagate(&s, 2.0, Some((0.1, 1e-4))).unwrap();
        let (b0, qb) = (0.02f64 * 0.02, 1e-10);
        let expected = 0.01 + 4.0 * b0 + 1e-4 * 4.0 + qb * 8.0 / 3.0;
        assert!((s.heading_variance_rad2() - expected).abs() < 1e-15);
        assert!((s.heading_rad() - 0.5).abs() < 1e-15);
        // cross-covariance ψ–b: −Δt σ_b0² − q_b Δt²/2
        let p = s.gaussian().covariance();
        assert!((p[(0, 1)] - (-2.0 * b0 - qb * 2.0)).abs() < 1e-15);
    }

    #[test]
    fn a_gyro_bias_is_learned_from_heading_references() {
        // true bias 0.01 rad/s; gyro at 10 Hz, compass (σ 2°) at 1 Hz, heading turning at 0.05 rad/s
        let m = model();
        let mut noise = Normal(7);
        let (bias, sigma_gyro, sigma_ref) = (0.01, 0.005, 2f64.to_radians());
        let mut s = m.start(0.0, 0.0, sigma_ref * sigma_ref).unwrap();
        let mut rate = 0.05 + bias;
        for k in 1..=3000 {
            let t = k as f64 * 0.1;
            s = m.propagate(&s, t, Some((rate, sigma_gyro * sigma_gyro))).unwrap();
            rate = 0.05 + bias + sigma_gyro * noise.sample();
            if k % 10 == 0 {
                let truth = 0.05 * t;
                let z = truth + sigma_ref * noise.sample();
                s = m
                    .observe_heading(&s, z, sigma_ref * sigma_ref, 5.0)
                    .unwrap()
                    .unwrap_or(s);
            }
        }
        let (b, var) = s.gyro_bias();
        assert!(
            (b - bias).abs() < 4.0 * var.sqrt() && var.sqrt() < 0.002,
            "b̂ {b} ± {}",
            var.sqrt()
        );
        let error = wrap_angle(s.heading_rad() - 0.05 * 300.0);
        assert!(
            error.abs() < 4.0 * s.heading_variance_rad2().sqrt(),
            "heading error {error}"
        );
    }

    #[test]
    fn an_odometer_offset_is_separated_from_the_heading_by_a_course_reference() {
        // the odometer reads ψ + 0.2 rad; course references say ψ
        let m = model();
        let mut s = m.start(0.0, 0.2, 0.04).unwrap();
        for k in 1..=200 {
            let t = k as f64 * 0.5;
            s = m.propagate(&s, t, Some((0.0, 1e-6))).unwrap();
            s = m.observe_odometer_heading(&s, 0.2, 1e-4, 5.0).unwrap().unwrap_or(s);
            if k % 2 == 0 {
                s = m.observe_heading(&s, 0.0, 0.01, 5.0).unwrap().unwrap_or(s);
            }
        }
        let (delta, var) = s.odometer_offset();
        assert!((delta - 0.2).abs() < 3.0 * var.sqrt() + 1e-3, "δ̂ {delta}");
        assert!(s.heading_rad().abs() < 0.03, "ψ̂ {}", s.heading_rad());
    }

    #[test]
    fn innovations_wrap_across_pi() {
        let m = model();
        let s = m.start(0.0, 3.1, 0.01).unwrap();
        // −3.1 is 0.083 rad away across ±π, not 6.2
        let s = m
            .observe_heading(&s, -3.1, 0.01, 3.0)
            .unwrap()
            .expect("inside the gate");
        assert!(s.heading_rad().abs() > 3.1, "ψ̂ {}", s.heading_rad());
    }

    #[test]
    fn an_outlier_is_gated_and_bad_input_is_an_error() {
        let m = model();
        let s = m.start(0.0, 0.0, 1e-4).unwrap();
        assert!(m.observe_heading(&s, 1.0, 1e-4, 3.0).unwrap().is_none());
        assert!(m.observe_heading(&s, f64::NAN, 1e-4, 3.0).is_err());
        assert!(m.observe_heading(&s, 0.0, 0.0, 3.0).is_err());
        assert!(m.propagate(&s, -1.0, None).is_err());
        assert!(m.propagate(&s, 1.0, Some((f64::INFINITY, 0.0))).is_err());
        assert!(HeadingModel::new(0.0, 1.0, 1.0, 1.0, 1.0).is_err());
    }

    #[test]
    fn without_a_rate_the_heading_variance_grows_as_a_random_walk() {
        let m = model();
        let s = m.start(0.0, 0.0, 0.01).unwrap();
        let s = m.propagate(&s, 4.0, None).unwrap();
        assert!((s.heading_variance_rad2() - (0.01 + 0.09 * 4.0)).abs() < 1e-12);
    }
}
