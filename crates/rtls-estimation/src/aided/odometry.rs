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
/// Seed 004 §1 (odometry-based dead reckoning, its ref. [4]).
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
