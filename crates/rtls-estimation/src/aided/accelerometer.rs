//! Accelerometer-aided tracking of seed 002: the first- and second-order dead-reckoning models
//! with the accumulating `Q(k)` recursion exactly as printed, and the textbook alternative.

use nalgebra::{Const, Dyn, Matrix2, Vector2};

use crate::error::{EstimationError, Result};
use crate::gaussian::Matrix;
use crate::motion::{ControlGain, LinearMotionModel};

/// One accelerometer sample: the acceleration over the last interval and the variance of its
/// error, per axis.
///
/// # Units
/// `acceleration_mps2` in m/s²; `variance_m2ps4` (ε²) in (m/s²)².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerSample {
    /// `a(k)`, `[ax, ay]` (m/s²).
    pub acceleration_mps2: [f64; 2],
    /// `ε²`, the error variance of each axis ((m/s²)²).
    pub variance_m2ps4: [f64; 2],
}

impl AccelerometerSample {
    /// A sample with its error variances.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞; [`EstimationError::InvalidParameter`] for a
    /// negative variance.
    pub fn new(acceleration_mps2: [f64; 2], variance_m2ps4: [f64; 2]) -> Result<Self> {
        if acceleration_mps2.iter().chain(&variance_m2ps4).any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "accelerometer sample",
            });
        }
        if variance_m2ps4.iter().any(|v| *v < 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "variance_m2ps4",
                reason: "an accelerometer error variance cannot be negative",
            });
        }
        Ok(Self {
            acceleration_mps2,
            variance_m2ps4,
        })
    }

    fn acceleration(&self) -> Vector2<f64> {
        Vector2::new(self.acceleration_mps2[0], self.acceleration_mps2[1])
    }

    fn variance(&self) -> Matrix2<f64> {
        Matrix2::new(self.variance_m2ps4[0], 0.0, 0.0, self.variance_m2ps4[1])
    }
}

/// Which of seed 002's models: velocity constant (first order) or acceleration constant
/// (second order) within a sampling interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModelOrder {
    /// `B(k) = v(k) Δt`, `Q(k) = Q(k−1) + Qv(k−1) Δt²` (seed 002 eq. (7)–(8)).
    First,
    /// `B(k) = v(k−1) Δt + a(k) Δt²/2`, `Q(k) = Q(k−1) + Qv(k−1) Δt² + Δt⁴/4 diag(ε²)`
    /// (eq. (10)–(11)).
    Second,
}

/// The dead-reckoning quantities seed 002 carries between steps: the integrated velocity
/// `v(k)`, the position noise `Q(k)` and the velocity noise `Qv(k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeadReckoning {
    /// `v(k)` (m/s).
    pub velocity_mps: Vector2<f64>,
    /// `Q(k)` (m²).
    pub position_noise_m2: Matrix2<f64>,
    /// `Qv(k)` ((m/s)²).
    pub velocity_noise_m2ps2: Matrix2<f64>,
}

impl DeadReckoning {
    /// Seed 002's start: the node is at rest, `v(0) = 0`, `Q(0) = 0`, `Qv(0) = 0`.
    #[must_use]
    pub fn at_rest() -> Self {
        Self {
            velocity_mps: Vector2::zeros(),
            position_noise_m2: Matrix2::zeros(),
            velocity_noise_m2ps2: Matrix2::zeros(),
        }
    }
}

/// The position step of seed 002's model: `x(k) = A x(k−1) + B(k) + V(k)`, `A = I`,
/// `V(k) ~ N(0, Q(k))`, as a [`LinearMotionModel`] on the position `[x, y]` with control
/// input `u = B(k)` (gain `I`). Build it with [`PrintedAccelerometerModel::advance`] and run it
/// with [`crate::filter::KalmanFilter::predict_with_control`] and [`PositionStep::control`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionStep {
    control_m: Vector2<f64>,
    process_noise_m2: Matrix2<f64>,
}

impl PositionStep {
    /// `B(k)` as a control vector (m).
    #[must_use]
    pub fn control(&self) -> nalgebra::DVector<f64> {
        nalgebra::DVector::from_column_slice(self.control_m.as_slice())
    }

    /// `Q(k)` (m²).
    #[must_use]
    pub fn process_noise(&self) -> Matrix2<f64> {
        self.process_noise_m2
    }
}

impl LinearMotionModel<2> for PositionStep {
    fn transition_matrix(&self, _dt_s: f64) -> Matrix<2> {
        // A = I
        Matrix::<2>::identity()
    }
    fn process_noise_matrix(&self, _dt_s: f64) -> Matrix<2> {
        // Q(k), accumulated by the dead-reckoning recursion
        self.process_noise_m2
    }
    fn control_matrix(&self, _dt_s: f64) -> Option<ControlGain<2>> {
        // x(k) = x(k−1) + B(k): unit gain on the control B(k)
        Some(ControlGain::<2>::identity_generic(Const::<2>, Dyn(2)))
    }
}

/// Seed 002's accelerometer-driven position model, **exactly as printed** (reproduces the
/// paper; see the caveat below).
///
/// ```text
/// v(k)  = v(k−1) + a(k) Δt                                        eq. (6), both orders
/// Qv(k) = Qv(k−1) + Δt² diag(ε²)                                  eq. (9)
/// first order:   B(k) = v(k) Δt,                   Q(k) = Q(k−1) + Qv(k−1) Δt²              eq. (7)–(8)
/// second order:  B(k) = v(k−1) Δt + a(k) Δt²/2,    Q(k) = Q(k−1) + Qv(k−1) Δt² + Δt⁴/4 diag(ε²)  eq. (10)–(11)
/// x(k) = x(k−1) + B(k) + V(k),   V(k) ~ N(0, Q(k));   z(k) = x(k) + n(k),  n ~ N(0, U)
/// ```
/// with `v(0) = 0`, `Q(0) = Qv(0) = 0`.
///
/// **Caveat (why the textbook form exists).** `Q(k)` is the covariance of the *whole*
/// dead-reckoned position since `k = 0`, yet the KF adds it as the noise of *one* step, and the
/// velocity `v(k)` is never corrected by the fixes. The filter therefore grows less confident
/// in its prediction every step and its velocity drifts with the integrated accelerometer
/// error. [`TextbookAccelerometerModel`] estimates the velocity from the fixes too and adds
/// only one step's accelerometer noise.
///
/// # Units
/// m, m/s, m/s², s.
///
/// # Example
/// ```
/// use rtls_estimation::aided::{AccelerometerSample, DeadReckoning, ModelOrder, PrintedAccelerometerModel};
/// let second = PrintedAccelerometerModel::new(ModelOrder::Second);
/// let a = AccelerometerSample::new([1.0, 0.0], [1e-4, 1e-4])?;
/// let (step, dr) = second.advance(&DeadReckoning::at_rest(), &a, 1.0)?;
/// assert_eq!(step.control()[0], 0.5);          // B = v(0)Δt + aΔt²/2
/// assert_eq!(dr.velocity_mps[0], 1.0);         // v(1) = v(0) + aΔt
/// assert_eq!(step.process_noise()[(0, 0)], 0.25e-4); // Δt⁴/4 ε²
/// let first = PrintedAccelerometerModel::new(ModelOrder::First);
/// let (step1, _) = first.advance(&DeadReckoning::at_rest(), &a, 1.0)?;
/// assert_eq!(step1.control()[0], 1.0);         // B = v(1)Δt
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 002 §1.2, eq. (4)–(12).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PrintedAccelerometerModel {
    order: ModelOrder,
}

impl PrintedAccelerometerModel {
    /// The first- or second-order model.
    #[must_use]
    pub fn new(order: ModelOrder) -> Self {
        Self { order }
    }

    /// The order.
    #[must_use]
    pub fn order(&self) -> ModelOrder {
        self.order
    }

    /// One step of the recursion with sample `a(k)` over `dt_s`: the position step to predict
    /// with, and the dead-reckoning quantities at `k`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `dt_s` is negative or not finite.
    pub fn advance(
        &self,
        previous: &DeadReckoning,
        sample: &AccelerometerSample,
        dt_s: f64,
    ) -> Result<(PositionStep, DeadReckoning)> {
        if !dt_s.is_finite() || dt_s < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "dt_s",
                reason: "the sampling interval must be finite and non-negative",
            });
        }
        let a = sample.acceleration();
        let eps2 = sample.variance();
        let dt2 = dt_s * dt_s;
        // v(k) = v(k−1) + a(k) Δt
        let velocity = previous.velocity_mps + a * dt_s;
        // Qv(k) = Qv(k−1) + Δt² diag(ε²)
        let velocity_noise = previous.velocity_noise_m2ps2 + eps2 * dt2;
        let (control, position_noise) = match self.order {
            ModelOrder::First => (
                // B(k) = v(k) Δt
                velocity * dt_s,
                // Q(k) = Q(k−1) + Qv(k−1) Δt²
                previous.position_noise_m2 + previous.velocity_noise_m2ps2 * dt2,
            ),
            ModelOrder::Second => (
                // B(k) = v(k−1) Δt + a(k) Δt²/2
                previous.velocity_mps * dt_s + a * (dt2 / 2.0),
                // Q(k) = Q(k−1) + Qv(k−1) Δt² + Δt⁴/4 diag(ε²)
                previous.position_noise_m2 + previous.velocity_noise_m2ps2 * dt2 + eps2 * (dt2 * dt2 / 4.0),
            ),
        };
        Ok((
            PositionStep {
                control_m: control,
                process_noise_m2: position_noise,
            },
            DeadReckoning {
                velocity_mps: velocity,
                position_noise_m2: position_noise,
                velocity_noise_m2ps2: velocity_noise,
            },
        ))
    }
}

/// The textbook accelerometer-aided model: state `[x, vx, y, vy]`, the accelerometer as a
/// control input, its noise propagated into `Q`.
///
/// ```text
/// x(k) = F x(k−1) + B a(k) + B w,   w ~ N(0, diag(ε²))
/// F = blockdiag([[1, Δt], [0, 1]]),  B = blockdiag([Δt²/2, Δt]ᵀ)
/// Q = B diag(ε²) Bᵀ + Q_extra
/// ```
/// Build one per sample with [`TextbookAccelerometerModel::for_sample`] (ε² may change every
/// sample, e.g. when it is proportional to the reading) and predict with
/// [`crate::filter::KalmanFilter::predict_with_control`], `u = a(k)`. `Q_extra` (white
/// acceleration of variance `extra_variance_m2ps4` through the same `B`) covers what the
/// accelerometer misses (misalignment, bias); seed 002's comparison uses 0.
///
/// # Example
/// ```
/// use rtls_estimation::aided::{AccelerometerSample, TextbookAccelerometerModel};
/// use rtls_estimation::motion::LinearMotionModel;
/// let sample = AccelerometerSample::new([0.2, 0.0], [1e-4, 4e-4])?;
/// let model = TextbookAccelerometerModel::new(0.0)?.for_sample(&sample);
/// let q = model.process_noise_matrix(1.0);
/// assert!((q[(1, 1)] - 1e-4).abs() < 1e-18);   // Δt² ε_x²
/// assert!((q[(2, 2)] - 1e-4).abs() < 1e-18);   // Δt⁴/4 ε_y²
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan (2001), §6.3.2 (`Γ = [T²/2, T]ᵀ`); seed 002 §1.2 for the
/// accelerometer-as-input idea.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextbookAccelerometerModel {
    extra_variance_m2ps4: f64,
    variance_m2ps4: [f64; 2],
}

impl TextbookAccelerometerModel {
    /// A model template with extra white-acceleration variance `extra_variance_m2ps4`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite variance.
    pub fn new(extra_variance_m2ps4: f64) -> Result<Self> {
        if !extra_variance_m2ps4.is_finite() || extra_variance_m2ps4 < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "extra_variance_m2ps4",
                reason: "must be finite and non-negative",
            });
        }
        Ok(Self {
            extra_variance_m2ps4,
            variance_m2ps4: [0.0; 2],
        })
    }

    /// The model for one sample (its ε² enters `Q`).
    #[must_use]
    pub fn for_sample(&self, sample: &AccelerometerSample) -> Self {
        Self {
            variance_m2ps4: sample.variance_m2ps4,
            ..*self
        }
    }
}

impl LinearMotionModel<4> for TextbookAccelerometerModel {
    fn transition_matrix(&self, dt_s: f64) -> Matrix<4> {
        let mut f = Matrix::<4>::identity();
        // p' = p + Δt v
        f[(0, 1)] = dt_s;
        f[(2, 3)] = dt_s;
        f
    }
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<4> {
        // B = [Δt²/2, Δt]ᵀ per axis;  Q_axis = B (εᵢ² + q_extra) Bᵀ
        let g = [dt_s * dt_s / 2.0, dt_s];
        let mut q = Matrix::<4>::zeros();
        for axis in 0..2 {
            let variance = self.variance_m2ps4[axis] + self.extra_variance_m2ps4;
            for (i, gi) in g.iter().enumerate() {
                for (j, gj) in g.iter().enumerate() {
                    q[(2 * axis + i, 2 * axis + j)] = gi * variance * gj;
                }
            }
        }
        q
    }
    fn control_matrix(&self, dt_s: f64) -> Option<ControlGain<4>> {
        let mut b = ControlGain::<4>::zeros_generic(Const::<4>, Dyn(2));
        for axis in 0..2 {
            // B_axis = [Δt²/2, Δt]ᵀ
            b[(2 * axis, axis)] = dt_s * dt_s / 2.0;
            b[(2 * axis + 1, axis)] = dt_s;
        }
        Some(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two steps of both recursions by hand with Δt = 2, ε² = (1e-2, 4e-2).
    #[test]
    fn printed_recursions_match_hand_computation() {
        let dt = 2.0;
        let s1 = AccelerometerSample::new([0.5, -1.0], [1e-2, 4e-2]).unwrap();
        let s2 = AccelerometerSample::new([0.0, 1.0], [1e-2, 4e-2]).unwrap();
        for order in [ModelOrder::First, ModelOrder::Second] {
            let model = PrintedAccelerometerModel::new(order);
            let (b1, dr1) = model.advance(&DeadReckoning::at_rest(), &s1, dt).unwrap();
            let (b2, dr2) = model.advance(&dr1, &s2, dt).unwrap();
            // v(1) = (1, −2), v(2) = (1, 0)
            assert_eq!(dr1.velocity_mps, Vector2::new(1.0, -2.0));
            assert_eq!(dr2.velocity_mps, Vector2::new(1.0, 0.0));
            // Qv(1) = 4 ε², Qv(2) = 8 ε²
            assert!((dr2.velocity_noise_m2ps2[(1, 1)] - 8.0 * 4e-2).abs() < 1e-15);
            match order {
                ModelOrder::First => {
                    // B(1) = v(1)Δt = (2, −4); B(2) = v(2)Δt = (2, 0)
                    assert_eq!(b1.control().as_slice(), &[2.0, -4.0]);
                    assert_eq!(b2.control().as_slice(), &[2.0, 0.0]);
                    // Q(1) = 0 + Qv(0)Δt² = 0; Q(2) = Q(1) + Qv(1)Δt² = 4·4ε² = 16 ε²
                    assert_eq!(b1.process_noise()[(0, 0)], 0.0);
                    assert!((b2.process_noise()[(0, 0)] - 16.0 * 1e-2).abs() < 1e-15);
                }
                ModelOrder::Second => {
                    // B(1) = 0 + aΔt²/2 = (1, −2); B(2) = v(1)Δt + a(2)Δt²/2 = (2, −4 + 2)
                    assert_eq!(b1.control().as_slice(), &[1.0, -2.0]);
                    assert_eq!(b2.control().as_slice(), &[2.0, -2.0]);
                    // Q(1) = Δt⁴/4 ε² = 4ε²; Q(2) = 4ε² + 4ε²·4 + 4ε² = 24 ε²
                    assert!((b1.process_noise()[(1, 1)] - 4.0 * 4e-2).abs() < 1e-15);
                    assert!((b2.process_noise()[(1, 1)] - 24.0 * 4e-2).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn bad_samples_are_errors() {
        assert!(AccelerometerSample::new([f64::NAN, 0.0], [0.0, 0.0]).is_err());
        assert!(AccelerometerSample::new([0.0, 0.0], [-1.0, 0.0]).is_err());
        let sample = AccelerometerSample::new([0.0, 0.0], [0.0, 0.0]).unwrap();
        let model = PrintedAccelerometerModel::new(ModelOrder::First);
        assert!(model.advance(&DeadReckoning::at_rest(), &sample, -1.0).is_err());
        assert!(TextbookAccelerometerModel::new(f64::INFINITY).is_err());
    }
}
