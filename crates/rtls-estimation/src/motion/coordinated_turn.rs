//! Coordinated-turn models in the plane: a known turn rate (linear), or the turn rate as a
//! fifth state (nonlinear).

use super::noise::ProcessNoise;
use super::{LinearMotionModel, MotionModel};
use crate::error::{EstimationError, Result};
use crate::gaussian::{Matrix, Vector};
use crate::math::{abs, sin_cos};

/// Below this `|ωT|` the turn coefficients use their Taylor series, so `ω = 0` is exactly CV.
const SERIES_THRESHOLD: f64 = 1e-6;
/// Below this `|ωT|` the ω-derivatives of the coefficients use their Taylor series: the closed
/// forms `(T cos ωT − sin(ωT)/ω)/ω` cancel catastrophically for small `ωT` (relative error
/// ≈ 3e-16/(ωT)², i.e. 3e-12 at the threshold), while the series below is exact to rounding.
const DERIVATIVE_SERIES_THRESHOLD: f64 = 1e-2;

/// The trigonometric coefficients of the coordinated-turn transition for `x = ωT`.
#[derive(Debug, Clone, Copy)]
struct TurnCoefficients {
    /// `sin ωT`.
    sin: f64,
    /// `cos ωT`.
    cos: f64,
    /// `sin(ωT)/ω` (s), → `T` as `ω → 0`.
    sin_over_rate: f64,
    /// `(1 − cos ωT)/ω` (s), → `0` as `ω → 0`.
    one_minus_cos_over_rate: f64,
}

impl TurnCoefficients {
    #[inline]
    fn new(rate_rad_s: f64, dt_s: f64) -> Self {
        // x = ωT
        let x = rate_rad_s * dt_s;
        // (sin x/2, cos x/2): one trigonometric call gives everything below
        let (half_sin, half_cos) = sin_cos(0.5 * x);
        // sin x = 2 sin(x/2) cos(x/2)
        let sin = 2.0 * half_sin * half_cos;
        // 1 − cos x = 2 sin²(x/2), free of cancellation for small x
        let one_minus_cos = 2.0 * half_sin * half_sin;
        let cos = 1.0 - one_minus_cos;
        let (sin_over_rate, one_minus_cos_over_rate) = if abs(x) < SERIES_THRESHOLD {
            let x2 = x * x;
            // sin(ωT)/ω = T (1 − x²/6 + …)
            // (1 − cos ωT)/ω = T x/2 (1 − x²/12 + …)
            (dt_s * (1.0 - x2 / 6.0), dt_s * 0.5 * x * (1.0 - x2 / 12.0))
        } else {
            (sin / rate_rad_s, one_minus_cos / rate_rad_s)
        };
        Self {
            sin,
            cos,
            sin_over_rate,
            one_minus_cos_over_rate,
        }
    }

    /// `(∂/∂ω [sin(ωT)/ω], ∂/∂ω [(1 − cos ωT)/ω])`, both in s².
    #[inline]
    fn rate_derivatives(&self, rate_rad_s: f64, dt_s: f64) -> (f64, f64) {
        // x = ωT
        let x = rate_rad_s * dt_s;
        if abs(x) < DERIVATIVE_SERIES_THRESHOLD {
            let x2 = x * x;
            let dt2 = dt_s * dt_s;
            // ∂/∂ω [sin(ωT)/ω] = T² (−x/3 + x³/30 − x⁵/840 + x⁷/45360 − …)
            let d_sin = dt2 * x * (-1.0 / 3.0 + x2 * (1.0 / 30.0 + x2 * (-1.0 / 840.0 + x2 / 45360.0)));
            // ∂/∂ω [(1 − cos ωT)/ω] = T² (1/2 − x²/8 + x⁴/144 − x⁶/5760 + …)
            let d_one_minus_cos = dt2 * (0.5 + x2 * (-1.0 / 8.0 + x2 * (1.0 / 144.0 - x2 / 5760.0)));
            (d_sin, d_one_minus_cos)
        } else {
            // ∂/∂ω [sin(ωT)/ω] = (T cos ωT − sin(ωT)/ω)/ω
            let d_sin = (dt_s * self.cos - self.sin_over_rate) / rate_rad_s;
            // ∂/∂ω [(1 − cos ωT)/ω] = (T sin ωT − (1 − cos ωT)/ω)/ω
            let d_one_minus_cos = (dt_s * self.sin - self.one_minus_cos_over_rate) / rate_rad_s;
            (d_sin, d_one_minus_cos)
        }
    }

    /// Writes the 4 × 4 turn transition into the top-left block of `f`.
    #[inline]
    fn write_transition<const N: usize>(&self, f: &mut Matrix<N>) {
        let (s, c) = (self.sin, self.cos);
        let (a, b) = (self.sin_over_rate, self.one_minus_cos_over_rate);
        // x' = x + sin(ωT)/ω vx − (1 − cos ωT)/ω vy
        f[(0, 0)] = 1.0;
        f[(0, 1)] = a;
        f[(0, 3)] = -b;
        // vx' = cos ωT vx − sin ωT vy
        f[(1, 1)] = c;
        f[(1, 3)] = -s;
        // y' = y + (1 − cos ωT)/ω vx + sin(ωT)/ω vy
        f[(2, 1)] = b;
        f[(2, 2)] = 1.0;
        f[(2, 3)] = a;
        // vy' = sin ωT vx + cos ωT vy
        f[(3, 1)] = s;
        f[(3, 3)] = c;
    }
}

/// Coordinated turn at a known, constant turn rate `ω` in the plane; state `[x, vx, y, vy]`.
///
/// Over a step `T` the velocity rotates by `ωT` (speed is preserved) and the position follows
/// the arc:
/// ```text
/// x'  = x + sin(ωT)/ω · vx − (1 − cos ωT)/ω · vy
/// vx' =     cos ωT    · vx − sin ωT        · vy
/// y'  = y + (1 − cos ωT)/ω · vx + sin(ωT)/ω · vy
/// vy' =     sin ωT    · vx + cos ωT        · vy
/// ```
/// For `|ωT| < 1e-6` the Taylor limits are used, so `ω = 0` gives exactly the
/// constant-velocity matrix. `Q = blockdiag(Q_x, Q_y)` with the constant-velocity blocks of
/// [`ProcessNoise`].
///
/// # Units
/// Metres, m/s, seconds; `ω` in rad/s, positive counter-clockwise (from `x` towards `y`).
///
/// # Example
/// ```
/// use rtls_estimation::motion::{CoordinatedTurn, LinearMotionModel, NoiseGain, ProcessNoise};
/// use rtls_estimation::Vector;
/// let ct = CoordinatedTurn::new(1.0, ProcessNoise::discrete(0.1, NoiseGain::kinematic()))?;
/// // A quarter turn at 1 m/s, 1 rad/s: heading x → heading y, on a circle of radius 1 m.
/// let x = ct.transition_matrix(core::f64::consts::FRAC_PI_2) * Vector::<4>::new(0.0, 1.0, 0.0, 0.0);
/// assert!((x - Vector::<4>::new(1.0, 0.0, 1.0, 1.0)).amax() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*
/// (2001), §11.7.1 (coordinated turn with known rate); seed 000 eq. (5)–(6) for the noise blocks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoordinatedTurn {
    turn_rate_rad_s: f64,
    noise: ProcessNoise,
}

impl CoordinatedTurn {
    /// A coordinated turn at `turn_rate_rad_s` (rad/s, counter-clockwise positive).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if the turn rate is not finite or `noise` is
    /// invalid (see [`ProcessNoise::validate`]).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurn, ProcessNoise};
    /// assert!(CoordinatedTurn::new(-0.2, ProcessNoise::continuous(0.5)).is_ok());
    /// assert!(CoordinatedTurn::new(f64::NAN, ProcessNoise::continuous(0.5)).is_err());
    /// ```
    ///
    /// # References
    /// Bar-Shalom et al. (2001), §11.7.1.
    pub fn new(turn_rate_rad_s: f64, noise: ProcessNoise) -> Result<Self> {
        if !turn_rate_rad_s.is_finite() {
            return Err(EstimationError::InvalidParameter {
                name: "turn_rate_rad_s",
                reason: "the turn rate must be finite (use 0 for straight motion)",
            });
        }
        noise.validate()?;
        Ok(Self { turn_rate_rad_s, noise })
    }

    /// The turn rate `ω` in rad/s (counter-clockwise positive).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurn, ProcessNoise};
    /// let ct = CoordinatedTurn::new(0.3, ProcessNoise::continuous(0.5))?;
    /// assert_eq!(ct.turn_rate_rad_s(), 0.3);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn turn_rate_rad_s(&self) -> f64 {
        self.turn_rate_rad_s
    }

    /// The process noise (constant-velocity blocks on `x` and `y`).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurn, ProcessNoise};
    /// let ct = CoordinatedTurn::new(0.3, ProcessNoise::continuous(0.5))?;
    /// assert_eq!(ct.noise(), ProcessNoise::continuous(0.5));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn noise(&self) -> ProcessNoise {
        self.noise
    }
}

impl LinearMotionModel<4> for CoordinatedTurn {
    #[inline]
    fn transition_matrix(&self, dt_s: f64) -> Matrix<4> {
        let mut f = Matrix::<4>::zeros();
        TurnCoefficients::new(self.turn_rate_rad_s, dt_s).write_transition(&mut f);
        f
    }

    #[inline]
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<4> {
        let mut q = Matrix::<4>::zeros();
        self.noise.write_cv_blocks(dt_s, 2, &mut q);
        q
    }
}

/// Coordinated turn with the turn rate as a state: `[x, vx, y, vy, ω]`, nonlinear.
///
/// The transition is [`CoordinatedTurn`]'s with `ω` read from the state, and `ω' = ω`. The
/// Jacobian `F = ∂f/∂x` is analytic; with `a = sin(ωT)/ω`, `b = (1 − cos ωT)/ω`, its last
/// column is
/// ```text
/// ∂x'/∂ω  = ∂a/∂ω · vx − ∂b/∂ω · vy        ∂a/∂ω = (T cos ωT − a)/ω  → −ωT³/3
/// ∂vx'/∂ω = −T sin ωT · vx − T cos ωT · vy   ∂b/∂ω = (T sin ωT − b)/ω  → T²/2
/// ∂y'/∂ω  = ∂b/∂ω · vx + ∂a/∂ω · vy
/// ∂vy'/∂ω = T cos ωT · vx − T sin ωT · vy
/// ∂ω'/∂ω  = 1
/// ```
/// where the small-`ωT` limits (`|ωT| < 1e-2`) use Taylor series, so there is no division by
/// a vanishing `ω`. `Q = blockdiag(Q_x, Q_y, σ_ω̇² T²)`: constant-velocity blocks of
/// [`ProcessNoise`] and a white turn-rate acceleration entering with gain `T`.
///
/// # Units
/// Metres, m/s, seconds; `ω` in rad/s (counter-clockwise positive); `turn_rate_variance`
/// `σ_ω̇²` in (rad/s²)², so that `σ_ω̇² T²` is in (rad/s)².
///
/// # Example
/// ```
/// use rtls_estimation::motion::{CoordinatedTurnWithRate, MotionModel, ProcessNoise};
/// use rtls_estimation::Vector;
/// let ct = CoordinatedTurnWithRate::new(ProcessNoise::continuous(0.5), 0.01)?;
/// let x = Vector::<5>::new(0.0, 1.0, 0.0, 0.0, 1.0);
/// let next = ct.transition(&x, core::f64::consts::FRAC_PI_2);
/// assert!((next - Vector::<5>::new(1.0, 0.0, 1.0, 1.0, 1.0)).amax() < 1e-12);
/// let jacobian = ct.transition_jacobian(&x, 0.1);
/// assert_eq!(jacobian[(4, 4)], 1.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*
/// (2001), §11.7 (coordinated turn with the turn rate augmented to the state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoordinatedTurnWithRate {
    noise: ProcessNoise,
    turn_rate_variance: f64,
}

impl CoordinatedTurnWithRate {
    /// A coordinated turn with an estimated rate; `turn_rate_variance` is the variance
    /// `σ_ω̇²` of the white turn-rate acceleration, in (rad/s²)².
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `turn_rate_variance` is negative or not finite,
    /// or `noise` is invalid (see [`ProcessNoise::validate`]).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurnWithRate, ProcessNoise};
    /// assert!(CoordinatedTurnWithRate::new(ProcessNoise::continuous(0.5), 1e-3).is_ok());
    /// assert!(CoordinatedTurnWithRate::new(ProcessNoise::continuous(0.5), -1e-3).is_err());
    /// ```
    ///
    /// # References
    /// Bar-Shalom et al. (2001), §11.7.
    pub fn new(noise: ProcessNoise, turn_rate_variance: f64) -> Result<Self> {
        if !turn_rate_variance.is_finite() || turn_rate_variance < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "turn_rate_variance",
                reason: "the turn-rate noise variance must be finite and non-negative",
            });
        }
        noise.validate()?;
        Ok(Self {
            noise,
            turn_rate_variance,
        })
    }

    /// The process noise on the planar position/velocity.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurnWithRate, ProcessNoise};
    /// let ct = CoordinatedTurnWithRate::new(ProcessNoise::continuous(0.5), 1e-3)?;
    /// assert_eq!(ct.noise(), ProcessNoise::continuous(0.5));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn noise(&self) -> ProcessNoise {
        self.noise
    }

    /// The turn-rate acceleration variance `σ_ω̇²` in (rad/s²)².
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{CoordinatedTurnWithRate, ProcessNoise};
    /// let ct = CoordinatedTurnWithRate::new(ProcessNoise::continuous(0.5), 1e-3)?;
    /// assert_eq!(ct.turn_rate_variance(), 1e-3);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn turn_rate_variance(&self) -> f64 {
        self.turn_rate_variance
    }
}

impl MotionModel<5> for CoordinatedTurnWithRate {
    #[inline]
    fn transition(&self, x: &Vector<5>, dt_s: f64) -> Vector<5> {
        let (vx, vy, rate) = (x[1], x[3], x[4]);
        let k = TurnCoefficients::new(rate, dt_s);
        let (s, c) = (k.sin, k.cos);
        let (a, b) = (k.sin_over_rate, k.one_minus_cos_over_rate);
        Vector::<5>::new(
            // x' = x + sin(ωT)/ω vx − (1 − cos ωT)/ω vy
            x[0] + a * vx - b * vy,
            // vx' = cos ωT vx − sin ωT vy
            c * vx - s * vy,
            // y' = y + (1 − cos ωT)/ω vx + sin(ωT)/ω vy
            x[2] + b * vx + a * vy,
            // vy' = sin ωT vx + cos ωT vy
            s * vx + c * vy,
            // ω' = ω
            rate,
        )
    }

    #[inline]
    fn transition_jacobian(&self, x: &Vector<5>, dt_s: f64) -> Matrix<5> {
        let (vx, vy, rate) = (x[1], x[3], x[4]);
        let k = TurnCoefficients::new(rate, dt_s);
        // ∂f/∂[x, vx, y, vy] is the known-rate transition
        let mut f = Matrix::<5>::zeros();
        k.write_transition(&mut f);
        // ∂a/∂ω, ∂b/∂ω with a = sin(ωT)/ω, b = (1 − cos ωT)/ω
        let (da, db) = k.rate_derivatives(rate, dt_s);
        let (s, c) = (k.sin, k.cos);
        // ∂x'/∂ω = ∂a/∂ω vx − ∂b/∂ω vy
        f[(0, 4)] = da * vx - db * vy;
        // ∂vx'/∂ω = −T sin ωT vx − T cos ωT vy
        f[(1, 4)] = -dt_s * (s * vx + c * vy);
        // ∂y'/∂ω = ∂b/∂ω vx + ∂a/∂ω vy
        f[(2, 4)] = db * vx + da * vy;
        // ∂vy'/∂ω = T cos ωT vx − T sin ωT vy
        f[(3, 4)] = dt_s * (c * vx - s * vy);
        // ∂ω'/∂ω = 1
        f[(4, 4)] = 1.0;
        f
    }

    #[inline]
    fn process_noise(&self, _x: &Vector<5>, dt_s: f64) -> Matrix<5> {
        let mut q = Matrix::<5>::zeros();
        // Q_xy = blockdiag(Q_x, Q_y)
        self.noise.write_cv_blocks(dt_s, 2, &mut q);
        // Q_ω = T σ_ω̇² T
        q[(4, 4)] = dt_s * self.turn_rate_variance * dt_s;
        q
    }
}

#[cfg(test)]
mod tests {
    use super::super::constant_velocity::ConstantVelocity;
    use super::super::noise::test_support::{assert_matrix_close, assert_symmetric_psd, close};
    use super::super::noise::NoiseGain;
    use super::*;
    use core::f64::consts::PI;

    fn noise() -> ProcessNoise {
        ProcessNoise::discrete(0.4, NoiseGain::kinematic())
    }

    fn ct(rate: f64) -> CoordinatedTurn {
        CoordinatedTurn::new(rate, noise()).unwrap()
    }

    fn cv_transition(dt: f64) -> Matrix<4> {
        ConstantVelocity::new(noise()).unwrap().transition_matrix(dt)
    }

    #[test]
    fn zero_rate_is_exactly_constant_velocity() {
        for dt in [0.0, 0.1, 1.0, 7.5] {
            assert_eq!(ct(0.0).transition_matrix(dt), cv_transition(dt));
            assert_eq!(ct(-0.0).transition_matrix(dt), cv_transition(dt));
        }
    }

    #[test]
    fn tiny_rate_is_continuous_with_constant_velocity() {
        let rate = 1e-7;
        // Short steps: within 1e-9 of the constant-velocity matrix.
        for dt in [1e-3, 5e-3] {
            assert_matrix_close(&ct(rate).transition_matrix(dt), &cv_transition(dt), 1e-9);
        }
        // Any step: within 1e-9 of the Taylor expansion in x = ωT (series branch for
        // |x| < 1e-6, closed form above), and off CV by O(ωT) only.
        for dt in [0.1, 1.0, 5.0, 20.0, 100.0] {
            let f = ct(rate).transition_matrix(dt);
            let x = rate * dt;
            let (s, c) = (x - x * x * x / 6.0, 1.0 - x * x / 2.0);
            let (a, b) = (dt * (1.0 - x * x / 6.0), dt * x / 2.0 * (1.0 - x * x / 12.0));
            #[rustfmt::skip]
            let taylor = Matrix::<4>::from_row_slice(&[
                1.0, a,   0.0, -b,
                0.0, c,   0.0, -s,
                0.0, b,   1.0, a,
                0.0, s,   0.0, c,
            ]);
            assert_matrix_close(&f, &taylor, 1e-9);
            assert!(f[(2, 1)] > 0.0 && f[(3, 1)] > 0.0, "the turn is kept: {f}");
            let deviation = (f - cv_transition(dt)).amax();
            assert!(deviation <= x * (1.0 + dt), "|F − F_cv| = {deviation} at dt = {dt}");
        }
    }

    #[test]
    fn matches_direct_trigonometric_formulas() {
        for (rate, dt) in [(0.9, 0.5), (-2.0, 1.3), (3e-6, 1.0), (0.02, 0.4), (1.5, 2.0)] {
            let f = ct(rate).transition_matrix(dt);
            let (s, c) = sin_cos(rate * dt);
            #[rustfmt::skip]
            let expected = Matrix::<4>::from_row_slice(&[
                1.0, s / rate,         0.0, -(1.0 - c) / rate,
                0.0, c,                0.0, -s,
                0.0, (1.0 - c) / rate, 1.0, s / rate,
                0.0, s,                0.0, c,
            ]);
            // The direct (1 − cos)/ω loses ~1e-16/ω to cancellation; compare accordingly.
            assert_matrix_close(&f, &expected, 1e-10);
        }
    }

    #[test]
    fn velocity_rotation_is_orthogonal_and_preserves_speed() {
        for (rate, dt) in [(0.7, 0.3), (-1.9, 2.2), (4.0, 10.0)] {
            let f = ct(rate).transition_matrix(dt);
            let rotation = nalgebra::Matrix2::new(f[(1, 1)], f[(1, 3)], f[(3, 1)], f[(3, 3)]);
            let residual = rotation.transpose() * rotation - nalgebra::Matrix2::identity();
            assert!(residual.amax() < 1e-15, "RᵀR − I = {residual}");
            assert!(close(rotation.determinant(), 1.0, 1e-15));
            let x = Vector::<4>::new(3.0, -1.2, 2.0, 0.5);
            let next = f * x;
            assert!(close(
                next[1] * next[1] + next[3] * next[3],
                1.2 * 1.2 + 0.5 * 0.5,
                1e-14
            ));
        }
    }

    #[test]
    fn full_turn_returns_to_start_and_steps_compose() {
        let rate = 0.5;
        let x = Vector::<4>::new(1.0, 2.0, -3.0, 0.5);
        let full = ct(rate).transition_matrix(2.0 * PI / rate) * x;
        assert!((full - x).amax() < 1e-12, "{full}");
        let half = ct(rate).transition_matrix(PI / rate) * x;
        // Half a turn: velocity reversed, displaced by the diameter 2|v|/ω perpendicular to v.
        assert!(close(half[1], -2.0, 1e-12) && close(half[3], -0.5, 1e-12));
        assert!(close(half[0], 1.0 - 2.0 * 0.5 / rate, 1e-12) && close(half[2], -3.0 + 2.0 * 2.0 / rate, 1e-12));
        let (dt1, dt2) = (0.4, 1.1);
        let model = ct(-1.3);
        assert_matrix_close(
            &model.transition_matrix(dt1 + dt2),
            &(model.transition_matrix(dt2) * model.transition_matrix(dt1)),
            1e-14,
        );
    }

    #[test]
    fn process_noise_is_the_constant_velocity_one() {
        let cv: Matrix<4> = ConstantVelocity::new(noise()).unwrap().process_noise_matrix(0.8);
        let q = ct(0.6).process_noise_matrix(0.8);
        assert_eq!(q, cv);
        assert!(q[(0, 0)] > 0.0);
        assert_symmetric_psd(&q);
    }

    fn with_rate() -> CoordinatedTurnWithRate {
        CoordinatedTurnWithRate::new(noise(), 0.02).unwrap()
    }

    #[test]
    fn with_rate_transition_equals_known_rate_transition() {
        for (rate, dt) in [(0.0, 1.0), (1e-9, 0.5), (0.35, 0.5), (-2.5, 1.5)] {
            let x = Vector::<5>::new(4.0, -1.0, 2.5, 3.0, rate);
            let next = with_rate().transition(&x, dt);
            let planar = ct(rate).transition_matrix(dt) * Vector::<4>::new(4.0, -1.0, 2.5, 3.0);
            for i in 0..4 {
                assert_eq!(next[i], planar[i], "entry {i} at ω = {rate}");
            }
            assert_eq!(next[4], rate);
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let model = with_rate();
        let step = 1e-6;
        for rate in [0.0, 1e-9, -1e-9, 4e-3, -9.99e-3, 1.01e-2, 0.3, -1.7] {
            for dt in [0.1, 1.0, 2.0] {
                let x = Vector::<5>::new(1.5, -2.0, 0.5, 3.0, rate);
                let jacobian = model.transition_jacobian(&x, dt);
                for j in 0..5 {
                    let mut plus = x;
                    let mut minus = x;
                    plus[j] += step;
                    minus[j] -= step;
                    let column = (model.transition(&plus, dt) - model.transition(&minus, dt)) / (2.0 * step);
                    for i in 0..5 {
                        assert!(
                            (jacobian[(i, j)] - column[i]).abs() < 1e-6,
                            "∂f{i}/∂x{j} at ω = {rate}, dt = {dt}: {} vs {}",
                            jacobian[(i, j)],
                            column[i]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn jacobian_rate_column_has_the_straight_line_limit() {
        // At ω = 0: ∂x'/∂ω = −T²/2 vy, ∂vx'/∂ω = −T vy, ∂y'/∂ω = T²/2 vx, ∂vy'/∂ω = T vx.
        let (vx, vy, dt) = (2.0, -3.0, 0.5);
        let jacobian = with_rate().transition_jacobian(&Vector::<5>::new(0.0, vx, 0.0, vy, 0.0), dt);
        assert_eq!(jacobian[(0, 4)], -dt * dt / 2.0 * vy);
        assert_eq!(jacobian[(1, 4)], -dt * vy);
        assert_eq!(jacobian[(2, 4)], dt * dt / 2.0 * vx);
        assert_eq!(jacobian[(3, 4)], dt * vx);
    }

    #[test]
    fn rate_derivative_series_meets_closed_form_at_threshold() {
        let dt = 1.0;
        for rate in [DERIVATIVE_SERIES_THRESHOLD * 0.999, DERIVATIVE_SERIES_THRESHOLD * 1.001] {
            let k = TurnCoefficients::new(rate, dt);
            let (da, db) = k.rate_derivatives(rate, dt);
            let x = rate * dt;
            let (s, c) = sin_cos(x);
            // Series with two more terms, evaluated independently.
            let x2 = x * x;
            let da_ref = dt * dt * (-x / 3.0 + x * x2 / 30.0 - x * x2 * x2 / 840.0);
            let db_ref = dt * dt * (0.5 - x2 / 8.0 + x2 * x2 / 144.0);
            assert!(close(da, da_ref, 1e-10), "{da} vs {da_ref}");
            assert!(close(db, db_ref, 1e-12), "{db} vs {db_ref}");
            // And the closed forms.
            assert!(close(da, (dt * c - s / rate) / rate, 1e-9));
            assert!(close(db, (dt * s - (1.0 - c) / rate) / rate, 1e-9));
        }
    }

    #[test]
    fn with_rate_process_noise() {
        let dt = 0.5;
        let q = with_rate().process_noise(&Vector::<5>::zeros(), dt);
        let planar = ct(0.0).process_noise_matrix(dt);
        for i in 0..4 {
            for j in 0..4 {
                assert_eq!(q[(i, j)], planar[(i, j)]);
            }
            assert_eq!(q[(i, 4)], 0.0);
        }
        assert!(close(q[(4, 4)], 0.02 * dt * dt, 1e-15));
        assert_symmetric_psd(&q);
        assert!(with_rate().control_gain(dt).is_none());
    }

    #[test]
    fn constructors_validate() {
        assert!(CoordinatedTurn::new(f64::INFINITY, noise()).is_err());
        assert!(CoordinatedTurn::new(0.1, ProcessNoise::continuous(-1.0)).is_err());
        assert_eq!(
            CoordinatedTurnWithRate::new(noise(), f64::NAN),
            Err(EstimationError::InvalidParameter {
                name: "turn_rate_variance",
                reason: "the turn-rate noise variance must be finite and non-negative",
            })
        );
        assert!(CoordinatedTurnWithRate::new(noise(), -0.1).is_err());
        assert!(CoordinatedTurnWithRate::new(ProcessNoise::discrete(f64::NAN, NoiseGain::kinematic()), 0.1).is_err());
    }
}
