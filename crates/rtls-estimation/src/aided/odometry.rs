//! Odometry (speed + heading) fusion of seed 004: error model, velocity measurement and
//! dead-reckoning control input.

use nalgebra::{Const, DVector, Dyn, Matrix2, Matrix4, Vector2};

use crate::error::{EstimationError, Result};
use crate::gaussian::Matrix;
use crate::manoeuvre::LinearObservation;
use crate::measurement::{MeasurementJacobian, NoiseCovariance};
use crate::motion::{ControlGain, LinearMotionModel};

/// One odometry reading: speed from the odometer, heading from the gyro/compass.
///
/// # Units
/// `speed_mps` in m/s; `heading_rad` in rad, counter-clockwise from +x.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryReading {
    /// Speed (m/s).
    pub speed_mps: f64,
    /// Heading (rad).
    pub heading_rad: f64,
}

/// The error model of an odometer + heading sensor: white speed error, white heading error and
/// a heading drift whose sign is unknown, so it enters as an uncertainty growing linearly with
/// the time since the heading was last referenced.
///
/// ```text
/// σ_θ²(t) = σ_θ² + (ḋ t)²                     heading variance t seconds after a reference
/// v = s [cos θ, sin θ]ᵀ                        velocity from speed and heading
/// J = [[cos θ, −s sin θ], [sin θ, s cos θ]]    ∂v/∂(s, θ)
/// R_v = J diag(σ_s², σ_θ²(t)) Jᵀ               with s² → s² + σ_s² in the cross-track term
/// ```
/// The cross-track variance uses `E[ŝ²] = s² + σ_s²` instead of `ŝ²` (the exact second moment
/// of `ŝ δθ`), which also keeps `R_v` positive definite when the vehicle stands still.
///
/// # Units
/// m/s, rad, rad/s, s.
///
/// # Example
/// ```
/// use rtls_estimation::aided::{OdometryErrorModel, OdometryReading};
/// let model = OdometryErrorModel::seed_004();
/// let reading = OdometryReading { speed_mps: 10.0, heading_rad: 0.0 };
/// let (v, r) = model.velocity(&reading, 3600.0)?;
/// assert!((v[0] - 10.0).abs() < 1e-12);
/// assert!((r[(0, 0)] - 1.0).abs() < 1e-12);    // along track: σ_s² = 1 (m/s)²
/// // cross track after one hour: (s² + σ_s²)(σ_θ² + (20°)²) ≈ 101 · 0.122 ≈ 12.4 (m/s)²
/// assert!(r[(1, 1)] > 12.0 && r[(1, 1)] < 13.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 §3 (heading drift 20°/h, speed error 1 m/s, velocity observation `(zvx, zvy)` in
/// eq. (9)); Bar-Shalom, Li, Kirubarajan (2001), §1.4.13 (first-order propagation of
/// covariance through a nonlinear map).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryErrorModel {
    speed_std_mps: f64,
    heading_std_rad: f64,
    heading_drift_rad_per_s: f64,
}

impl OdometryErrorModel {
    /// An error model.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite parameter, or a zero
    /// speed error (the velocity covariance would be singular along track).
    pub fn new(speed_std_mps: f64, heading_std_rad: f64, heading_drift_rad_per_s: f64) -> Result<Self> {
        if !(speed_std_mps.is_finite() && speed_std_mps > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "speed_std_mps",
                reason: "must be positive and finite",
            });
        }
        if !(heading_std_rad.is_finite() && heading_std_rad >= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "heading_std_rad",
                reason: "must be finite and non-negative",
            });
        }
        if !(heading_drift_rad_per_s.is_finite() && heading_drift_rad_per_s >= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "heading_drift_rad_per_s",
                reason: "must be finite and non-negative",
            });
        }
        Ok(Self {
            speed_std_mps,
            heading_std_rad,
            heading_drift_rad_per_s,
        })
    }

    /// Seed 004's sensors: speed error 1 m/s, heading drift 20°/h, and (not given in the paper;
    /// our choice) a white heading error of 0.5°.
    #[must_use]
    pub fn seed_004() -> Self {
        Self {
            speed_std_mps: 1.0,
            heading_std_rad: 0.5_f64.to_radians(),
            heading_drift_rad_per_s: 20.0_f64.to_radians() / 3600.0,
        }
    }

    /// The white heading error `σ_θ` (rad).
    #[must_use]
    pub fn heading_std_rad(&self) -> f64 {
        self.heading_std_rad
    }

    /// The velocity and covariance of a reading whose heading has already been corrected for
    /// drift, with the correction's variance `bias_variance_rad2` in place of `(ḋ t)²`:
    /// `σ_θ² = σ_θ² + var(b̂)` (see [`HeadingBiasEstimator`]).
    ///
    /// # Errors
    /// As [`OdometryErrorModel::velocity`].
    pub fn corrected_velocity(
        &self,
        reading: &OdometryReading,
        bias_rad: f64,
        bias_variance_rad2: f64,
    ) -> Result<(Vector2<f64>, Matrix2<f64>)> {
        if !bias_rad.is_finite() || !bias_variance_rad2.is_finite() || bias_variance_rad2 < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "bias_variance_rad2",
                reason: "the heading bias and its variance must be finite, the variance non-negative",
            });
        }
        let corrected = OdometryReading {
            speed_mps: reading.speed_mps,
            heading_rad: reading.heading_rad - bias_rad,
        };
        let unbiased = Self {
            heading_std_rad: crate::math::sqrt(self.heading_std_rad * self.heading_std_rad + bias_variance_rad2),
            heading_drift_rad_per_s: 0.0,
            ..*self
        };
        unbiased.velocity(&corrected, 0.0)
    }

    /// `σ_θ²(t) = σ_θ² + (ḋ t)²`, `elapsed_s` after the last heading reference.
    #[must_use]
    pub fn heading_variance(&self, elapsed_s: f64) -> f64 {
        let drift = self.heading_drift_rad_per_s * elapsed_s;
        self.heading_std_rad * self.heading_std_rad + drift * drift
    }

    /// The velocity `[vx, vy]` (m/s) and its covariance `R_v` ((m/s)²) of a reading taken
    /// `elapsed_s` after the last heading reference.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞ in the reading;
    /// [`EstimationError::InvalidParameter`] for a negative `elapsed_s`.
    pub fn velocity(&self, reading: &OdometryReading, elapsed_s: f64) -> Result<(Vector2<f64>, Matrix2<f64>)> {
        if !reading.speed_mps.is_finite() || !reading.heading_rad.is_finite() || !elapsed_s.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "odometry reading",
            });
        }
        if elapsed_s < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "elapsed_s",
                reason: "time since the heading reference cannot be negative",
            });
        }
        let s = reading.speed_mps;
        let (sin, cos) = crate::math::sin_cos(reading.heading_rad);
        // v = s [cos θ, sin θ]ᵀ
        let v = Vector2::new(s * cos, s * sin);
        // along-track σ_s², cross-track (s² + σ_s²) σ_θ²(t)
        let along = self.speed_std_mps * self.speed_std_mps;
        let cross = (s * s + along) * self.heading_variance(elapsed_s);
        // R_v = U diag(along, cross) Uᵀ,  U = [[cos θ, −sin θ], [sin θ, cos θ]]
        let u = Matrix2::new(cos, -sin, sin, cos);
        let r = u * Matrix2::new(along, 0.0, 0.0, cross) * u.transpose();
        Ok((v, r))
    }
}

/// Online estimate of the heading sensor's drift `b(t) = b₀ + ḃ t` from a heading reference
/// that does not use the odometer (the course of a track filtered from position fixes alone).
///
/// A two-state Kalman filter on `[b, ḃ]` (constant drift rate, a small random walk on it):
/// ```text
/// y = wrap(θ_odo − atan2(v̂_y, v̂_x))                 observed bias
/// R_y = σ_θ² + σ²_course,  σ²_course ≈ (v̂ᵀ⊥ P_v v̂⊥)/‖v̂‖⁴   course variance of the reference
/// update only when ‖v̂‖ ≥ min_speed_mps (the course of a slow track is meaningless)
/// and (y − b̂)² ≤ 3² (P_bb + R_y) (a reference lagging in a turn is not a bias)
/// ```
/// The corrected heading `θ_odo − b̂` then has variance `σ_θ² + var(b̂)`
/// ([`OdometryErrorModel::corrected_velocity`]) instead of a variance that grows with time, so a
/// fused filter neither trusts drifted headings nor discards the odometer after an hour.
///
/// # Example
/// ```
/// use rtls_estimation::aided::HeadingBiasEstimator;
/// use nalgebra::{Matrix2, Vector2};
/// // seed 004's gyro drifts by 20°/h; prior on the rate: 40°/h
/// let drift = 20f64.to_radians() / 3600.0;
/// let mut estimator = HeadingBiasEstimator::new(2.0 * drift, 1e-14, 2.0)?.start(0.0)?;
/// // heading east at 10 m/s: the odometer's heading is the course plus the drift
/// for k in 1..=600 {
///     let t = k as f64;
///     estimator = estimator.update(t, drift * t, &Vector2::new(10.0, 0.0), &(Matrix2::identity() * 0.01), 1e-4)?;
/// }
/// let (bias, variance) = estimator.bias();
/// assert!((bias - drift * 600.0).abs() < 0.2f64.to_radians() && variance < 1e-5);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 §3 (heading drift 20°/h degrades the fused track late in the run); Groves,
/// *Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems* (2013), §16.2
/// (heading and odometer calibration from position fixes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingBiasEstimator {
    drift_rate_std_rad_per_s: f64,
    drift_rate_random_walk: f64,
    min_speed_mps: f64,
}

/// The state of a [`HeadingBiasEstimator`]: `[b, ḃ]` with covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingBias {
    state: crate::Gaussian<2>,
    filter: HeadingBiasEstimator,
}

impl HeadingBiasEstimator {
    /// An estimator with prior drift-rate standard deviation `drift_rate_std_rad_per_s` (the
    /// gyro's specified drift, e.g. 20°/h), drift-rate random-walk variance rate
    /// `drift_rate_random_walk` ((rad/s)²/s), updating only while the reference speed is at
    /// least `min_speed_mps`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite parameter.
    pub fn new(drift_rate_std_rad_per_s: f64, drift_rate_random_walk: f64, min_speed_mps: f64) -> Result<Self> {
        if !(drift_rate_std_rad_per_s.is_finite() && drift_rate_std_rad_per_s > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "drift_rate_std_rad_per_s",
                reason: "must be positive and finite",
            });
        }
        if !(drift_rate_random_walk.is_finite() && drift_rate_random_walk >= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "drift_rate_random_walk",
                reason: "must be finite and non-negative",
            });
        }
        if !(min_speed_mps.is_finite() && min_speed_mps > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "min_speed_mps",
                reason: "must be positive and finite",
            });
        }
        Ok(Self {
            drift_rate_std_rad_per_s,
            drift_rate_random_walk,
            min_speed_mps,
        })
    }

    /// Starts at `time_s` with the heading aligned (`b = 0`, var 0) and the drift rate's prior.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a NaN/∞ time.
    pub fn start(&self, time_s: f64) -> Result<HeadingBias> {
        let rate_std = self.drift_rate_std_rad_per_s;
        Ok(HeadingBias {
            state: crate::Gaussian::new(
                crate::Vector::<2>::zeros(),
                crate::Matrix::<2>::new(0.0, 0.0, 0.0, rate_std * rate_std),
                time_s,
            )?,
            filter: *self,
        })
    }
}

impl HeadingBias {
    /// `(b̂, var(b̂))` (rad, rad²) at the state's time.
    #[must_use]
    pub fn bias(&self) -> (f64, f64) {
        (self.state.mean()[0], self.state.covariance()[(0, 0)])
    }

    /// `(b̂, var(b̂))` predicted to `time_s` without a new reference.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] for an earlier time.
    pub fn bias_at(&self, time_s: f64) -> Result<(f64, f64)> {
        let predicted = crate::filter::KalmanFilter::default().predict(&self.state, &self.model()?, time_s)?;
        Ok((predicted.mean()[0], predicted.covariance()[(0, 0)]))
    }

    fn model(&self) -> Result<crate::motion::ConstantVelocity> {
        crate::motion::ConstantVelocity::new(crate::motion::ProcessNoise::continuous(
            self.filter.drift_rate_random_walk,
        ))
    }

    /// Predicts to `time_s` and, if the reference track moves fast enough, updates with the
    /// odometer heading `heading_rad` against the reference velocity `velocity_mps`
    /// (covariance `velocity_covariance`), heading noise variance `heading_variance_rad2`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`]; [`EstimationError::NonFinite`] for NaN/∞ input.
    pub fn update(
        &self,
        time_s: f64,
        heading_rad: f64,
        velocity_mps: &Vector2<f64>,
        velocity_covariance: &Matrix2<f64>,
        heading_variance_rad2: f64,
    ) -> Result<Self> {
        let kf = crate::filter::KalmanFilter::default();
        let prior = kf.predict(&self.state, &self.model()?, time_s)?;
        let speed = velocity_mps.norm();
        if !heading_rad.is_finite() || !speed.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "heading bias reference",
            });
        }
        if speed < self.filter.min_speed_mps {
            return Ok(Self { state: prior, ..*self });
        }
        // y = wrap(θ_odo − atan2(v_y, v_x))
        let course = crate::math::atan2(velocity_mps[1], velocity_mps[0]);
        let y = crate::math::wrap_angle(heading_rad - course);
        // σ²_course = v⊥ᵀ P_v v⊥ / ‖v‖⁴,  v⊥ = (−v_y, v_x)
        let perpendicular = Vector2::new(-velocity_mps[1], velocity_mps[0]);
        let course_variance =
            perpendicular.dot(&(velocity_covariance * perpendicular)) / (speed * speed * speed * speed);
        let r_y = heading_variance_rad2 + course_variance;
        // gate: (y − b̂)² / (P_bb + R_y) ≤ 3²; a reference track lagging in a turn would teach a
        // false bias, so such epochs are skipped
        let residual = crate::math::wrap_angle(y - prior.mean()[0]);
        if residual * residual > GATE_SIGMAS * GATE_SIGMAS * (prior.covariance()[(0, 0)] + r_y) {
            return Ok(Self { state: prior, ..*self });
        }
        let noise = NoiseCovariance::isotropic(1, r_y)?;
        let observe_bias = crate::measurement::ComponentSelection::<2>::new(&[0], noise)?;
        let updated = kf.update(&prior, &observe_bias, &DVector::from_element(1, y))?;
        Ok(Self {
            state: updated.state,
            ..*self
        })
    }
}

/// Gate of [`HeadingBias::update`], in standard deviations.
const GATE_SIGMAS: f64 = 3.0;

/// Seed 004's fused observation `Z = [zx, zvx, zy, zvy]ᵀ` with `H = I₄` (eq. (9)): a position
/// fix (e.g. from TDOA) with covariance `R_p` and an odometry velocity with covariance `R_v`,
/// independent, so `R = ` the interleaved block-diagonal of `R_p` and `R_v`.
///
/// # Errors
/// [`EstimationError::InvalidParameter`] if `R` is not positive definite;
/// [`EstimationError::NonFinite`] for NaN/∞.
///
/// # Example
/// ```
/// use rtls_estimation::aided::position_velocity_observation;
/// use nalgebra::{Matrix2, Vector2};
/// let obs = position_velocity_observation(
///     5.0,
///     &Vector2::new(100.0, 200.0), &(Matrix2::identity() * 900.0),
///     &Vector2::new(10.0, 0.0), &Matrix2::new(1.0, 0.0, 0.0, 0.5),
/// )?;
/// assert_eq!(obs.z().as_slice(), &[100.0, 10.0, 200.0, 0.0]);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 eq. (9).
pub fn position_velocity_observation(
    time_s: f64,
    position_m: &Vector2<f64>,
    position_covariance_m2: &Matrix2<f64>,
    velocity_mps: &Vector2<f64>,
    velocity_covariance_m2ps2: &Matrix2<f64>,
) -> Result<LinearObservation> {
    // Z = [zx, zvx, zy, zvy]
    let z = DVector::from_vec(alloc::vec![
        position_m[0],
        velocity_mps[0],
        position_m[1],
        velocity_mps[1]
    ]);
    // R: position entries (0, 2), velocity entries (1, 3)
    let mut r = Matrix4::<f64>::zeros();
    for (i, ii) in [0usize, 2].iter().enumerate() {
        for (j, jj) in [0usize, 2].iter().enumerate() {
            r[(*ii, *jj)] = position_covariance_m2[(i, j)];
            r[(ii + 1, jj + 1)] = velocity_covariance_m2ps2[(i, j)];
        }
    }
    let noise = NoiseCovariance::full(nalgebra::DMatrix::from_column_slice(4, 4, r.as_slice()))?;
    // H = I₄
    let h = MeasurementJacobian::<4>::identity_generic(Dyn(4), Const::<4>);
    LinearObservation::new(time_s, z, h, &noise)
}

/// Odometry as a control input: dead reckoning of the position `[x, y]` with the odometry
/// velocity, as a [`LinearMotionModel`] for
/// [`crate::filter::KalmanFilter::predict_with_control`] with `u = v_odo`:
/// ```text
/// x(k) = x(k−1) + Δt v_odo + w,    Q = Δt² R_v + q Δt I
/// ```
/// `q` (m²/s) is a small random-walk rate for wheel slip and what the odometer misses.
/// Build one per reading with [`OdometryDeadReckoning::new`].
///
/// # Example
/// ```
/// use rtls_estimation::aided::OdometryDeadReckoning;
/// use rtls_estimation::motion::LinearMotionModel;
/// use nalgebra::Matrix2;
/// let model = OdometryDeadReckoning::new(Matrix2::identity(), 0.1)?;
/// assert_eq!(model.process_noise_matrix(2.0)[(0, 0)], 4.0 + 0.2);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 §1 (odometry-based dead reckoning, its ref. 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryDeadReckoning {
    velocity_covariance_m2ps2: Matrix2<f64>,
    random_walk_m2ps: f64,
}

impl OdometryDeadReckoning {
    /// A dead-reckoning step model for a velocity with covariance `velocity_covariance_m2ps2`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite random-walk rate;
    /// [`EstimationError::NonFinite`] for a non-finite covariance.
    pub fn new(velocity_covariance_m2ps2: Matrix2<f64>, random_walk_m2ps: f64) -> Result<Self> {
        crate::math::ensure_finite(&velocity_covariance_m2ps2, "odometry velocity covariance")?;
        if !random_walk_m2ps.is_finite() || random_walk_m2ps < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "random_walk_m2ps",
                reason: "must be finite and non-negative",
            });
        }
        Ok(Self {
            velocity_covariance_m2ps2,
            random_walk_m2ps,
        })
    }
}

impl LinearMotionModel<2> for OdometryDeadReckoning {
    fn transition_matrix(&self, _dt_s: f64) -> Matrix<2> {
        Matrix::<2>::identity()
    }
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<2> {
        // Q = Δt² R_v + q Δt I
        self.velocity_covariance_m2ps2 * (dt_s * dt_s) + Matrix::<2>::identity() * (self.random_walk_m2ps * dt_s)
    }
    fn control_matrix(&self, dt_s: f64) -> Option<ControlGain<2>> {
        // B = Δt I
        Some(ControlGain::<2>::identity_generic(Const::<2>, Dyn(2)) * dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R_v against a Monte Carlo of the speed/heading errors (first-order propagation is
    /// accurate when σ_θ is small).
    #[test]
    fn velocity_covariance_matches_sampled_errors() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let model = OdometryErrorModel::new(0.5, 0.02, 0.0).unwrap();
        let truth = OdometryReading {
            speed_mps: 8.0,
            heading_rad: 0.7,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let speed = Normal::new(0.0, 0.5).unwrap();
        let heading = Normal::new(0.0, 0.02).unwrap();
        let n = 100_000;
        let (v_true, r) = model.velocity(&truth, 0.0).unwrap();
        let mut sum = Matrix2::zeros();
        for _ in 0..n {
            let s = truth.speed_mps + speed.sample(&mut rng);
            let th = truth.heading_rad + heading.sample(&mut rng);
            let d = Vector2::new(s * th.cos(), s * th.sin()) - v_true;
            sum += d * d.transpose();
        }
        let empirical = sum / n as f64;
        for i in 0..2 {
            for j in 0..2 {
                assert!(
                    (empirical[(i, j)] - r[(i, j)]).abs() < 0.03 * r.trace(),
                    "R_v[{i},{j}] {} vs sampled {}",
                    r[(i, j)],
                    empirical[(i, j)]
                );
            }
        }
    }

    #[test]
    fn standing_still_keeps_the_covariance_positive_definite() {
        let model = OdometryErrorModel::seed_004();
        let (_, r) = model
            .velocity(
                &OdometryReading {
                    speed_mps: 0.0,
                    heading_rad: 1.0,
                },
                0.0,
            )
            .unwrap();
        assert!(r.cholesky().is_some());
    }

    #[test]
    fn bad_parameters_are_errors() {
        assert!(OdometryErrorModel::new(0.0, 0.1, 0.0).is_err());
        assert!(OdometryErrorModel::new(1.0, -0.1, 0.0).is_err());
        assert!(OdometryErrorModel::new(1.0, 0.1, f64::NAN).is_err());
        let model = OdometryErrorModel::seed_004();
        let nan = OdometryReading {
            speed_mps: f64::NAN,
            heading_rad: 0.0,
        };
        assert!(model.velocity(&nan, 0.0).is_err());
        let ok = OdometryReading {
            speed_mps: 1.0,
            heading_rad: 0.0,
        };
        assert!(model.velocity(&ok, -1.0).is_err());
        assert!(OdometryDeadReckoning::new(Matrix2::identity(), -1.0).is_err());
    }
}
