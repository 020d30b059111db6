//! Constant-velocity (nearly constant velocity, white-noise acceleration) model in 1, 2 or 3 axes.

use nalgebra::{Const, Dyn};

use super::noise::ProcessNoise;
use super::{ControlGain, LinearMotionModel};
use crate::error::Result;
use crate::gaussian::Matrix;

/// Constant-velocity motion model over `D = N/2` independent axes, state
/// `[x, vx, y, vy, z, vz]` truncated to `N = 2D` entries, optionally driven by a known
/// acceleration.
///
/// Per axis, over a step `dt`:
/// ```text
/// p' = p + dt·v + dt²/2·u + w_p        F_axis = [[1, dt],      B_axis = [dt²/2,
/// v' = v        + dt·u    + w_v                  [0,  1]]                dt   ]
/// ```
/// `F = blockdiag(F_axis)`, `Q = blockdiag(Q_axis)` with `Q_axis` from
/// [`ProcessNoise`] (`G σ² Gᵀ`, or `q·[[dt³/3, dt²/2], [dt²/2, dt]]` for continuous white
/// acceleration), and, with [`ConstantVelocity::with_acceleration_input`], `B` is `N × D` with
/// `B_axis` in the axis' column. `N` must be even and positive (checked at compile time).
///
/// An odd state size does not compile:
/// ```compile_fail
/// use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, ProcessNoise};
/// let cv = ConstantVelocity::new(ProcessNoise::continuous(1.0)).unwrap();
/// let _ = LinearMotionModel::<3>::transition_matrix(&cv, 1.0);
/// ```
///
/// # Units
/// Positions in metres, velocities in m/s, `dt` in seconds, control `u` in m/s² per axis.
///
/// # Example
/// ```
/// use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, NoiseGain, ProcessNoise};
/// use rtls_estimation::Vector;
/// let cv = ConstantVelocity::new(ProcessNoise::discrete(5.0, NoiseGain::kinematic()))?;
/// let f = LinearMotionModel::<4>::transition_matrix(&cv, 0.5);
/// let moved = f * Vector::<4>::new(0.0, 2.0, 1.0, -1.0);
/// assert_eq!(moved, Vector::<4>::new(1.0, 2.0, 0.5, -1.0));
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 000 eq. (4)–(6) (3-D `A` and `C`); seed 001 (`F`, `G`); seed 004 eq. (8); seed 003
/// eq. (1)–(4) (force/mass input); seed 002 eq. (10) (accelerometer input); Bar-Shalom, Li,
/// Kirubarajan, *Estimation with Applications to Tracking and Navigation* (2001), §6.2.2 and
/// §6.3.2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocity {
    noise: ProcessNoise,
    acceleration_input: bool,
}

impl ConstantVelocity {
    /// A constant-velocity model with process noise `noise` and no control input.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`](crate::EstimationError::InvalidParameter) if
    /// `noise` is invalid (see [`ProcessNoise::validate`]).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
    /// assert!(ConstantVelocity::new(ProcessNoise::continuous(0.5)).is_ok());
    /// assert!(ConstantVelocity::new(ProcessNoise::continuous(f64::NAN)).is_err());
    /// ```
    ///
    /// # References
    /// Seed 000 eq. (5)–(6); Bar-Shalom et al. (2001), §6.3.2.
    pub fn new(noise: ProcessNoise) -> Result<Self> {
        noise.validate()?;
        Ok(Self {
            noise,
            acceleration_input: false,
        })
    }

    /// The same model driven by a known acceleration `u` (m/s², one component per axis):
    /// `B_axis = [dt²/2, dt]ᵀ`, e.g. `u = F/m` from a commanded force, or an accelerometer
    /// reading in the navigation frame.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, ProcessNoise};
    /// let cv = ConstantVelocity::new(ProcessNoise::continuous(0.1))?.with_acceleration_input();
    /// let b = LinearMotionModel::<4>::control_matrix(&cv, 2.0).expect("has a control input");
    /// assert_eq!((b.nrows(), b.ncols()), (4, 2));
    /// assert_eq!((b[(0, 0)], b[(1, 0)]), (2.0, 2.0));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 003 eq. (1)–(4) (`u/m` through `∫ e^{Aτ} B dτ`); seed 002 eq. (10)
    /// (`v Δt + Δt²/2 · a`).
    #[inline]
    #[must_use]
    pub fn with_acceleration_input(self) -> Self {
        Self {
            acceleration_input: true,
            ..self
        }
    }

    /// The process noise.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
    /// let cv = ConstantVelocity::new(ProcessNoise::continuous(0.5))?;
    /// assert_eq!(cv.noise(), ProcessNoise::continuous(0.5));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn noise(&self) -> ProcessNoise {
        self.noise
    }

    /// Whether the model takes a known acceleration as control input.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
    /// let cv = ConstantVelocity::new(ProcessNoise::continuous(0.5))?;
    /// assert!(!cv.has_acceleration_input());
    /// assert!(cv.with_acceleration_input().has_acceleration_input());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn has_acceleration_input(&self) -> bool {
        self.acceleration_input
    }
}

/// Number of axes `D = N/2` of an `N`-entry constant-velocity state. Evaluated in a `const`
/// block, so an odd or zero `N` is a compile-time error.
const fn axis_count<const N: usize>() -> usize {
    assert!(
        N.is_multiple_of(2) && N > 0,
        "ConstantVelocity needs an even state size N = 2·axes > 0"
    );
    N / 2
}

impl<const N: usize> LinearMotionModel<N> for ConstantVelocity {
    #[inline]
    fn transition_matrix(&self, dt_s: f64) -> Matrix<N> {
        let axes = const { axis_count::<N>() };
        let mut f = Matrix::<N>::identity();
        for axis in 0..axes {
            let (p, v) = (2 * axis, 2 * axis + 1);
            // p' = p + dt·v
            f[(p, v)] = dt_s;
        }
        f
    }

    #[inline]
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<N> {
        let axes = const { axis_count::<N>() };
        // Q = blockdiag(Q_axis), Q_axis = G σ² Gᵀ (discrete) or ∫ Φ L q Lᵀ Φᵀ (continuous)
        let mut q = Matrix::<N>::zeros();
        self.noise.write_cv_blocks(dt_s, axes, &mut q);
        q
    }

    #[inline]
    fn control_matrix(&self, dt_s: f64) -> Option<ControlGain<N>> {
        let axes = const { axis_count::<N>() };
        if !self.acceleration_input {
            return None;
        }
        let mut b = ControlGain::<N>::zeros_generic(Const::<N>, Dyn(axes));
        for axis in 0..axes {
            // B_axis = [dt²/2, dt]ᵀ in column `axis`
            b[(2 * axis, axis)] = dt_s * dt_s / 2.0;
            b[(2 * axis + 1, axis)] = dt_s;
        }
        Some(b)
    }
}

#[cfg(test)]
mod tests {
    use super::super::noise::test_support::{assert_matrix_close, assert_symmetric_psd, simpson_continuous_q};
    use super::super::noise::NoiseGain;
    use super::*;
    use crate::gaussian::Vector;

    fn discrete(variance: f64) -> ConstantVelocity {
        ConstantVelocity::new(ProcessNoise::discrete(variance, NoiseGain::kinematic())).unwrap()
    }

    #[test]
    fn transition_matrix_is_the_closed_form() {
        let dt = 0.25;
        let f: Matrix<6> = discrete(1.0).transition_matrix(dt);
        // Seed 000's A for 3 axes.
        #[rustfmt::skip]
        let expected = Matrix::<6>::from_row_slice(&[
            1.0, dt,  0.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 1.0, dt,  0.0, 0.0,
            0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
            0.0, 0.0, 0.0, 0.0, 1.0, dt,
            0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ]);
        assert_eq!(f, expected);
        let f1: Matrix<2> = discrete(1.0).transition_matrix(3.0);
        assert_eq!(f1, Matrix::<2>::new(1.0, 3.0, 0.0, 1.0));
    }

    #[test]
    fn transition_composes_over_steps() {
        let cv = discrete(1.0);
        let (dt1, dt2) = (0.3, 1.7);
        let f12: Matrix<4> = cv.transition_matrix(dt1 + dt2);
        let f2: Matrix<4> = cv.transition_matrix(dt2);
        let f1: Matrix<4> = cv.transition_matrix(dt1);
        assert_matrix_close(&f12, &(f2 * f1), 1e-15);
    }

    #[test]
    fn discrete_kinematic_noise_is_textbook_per_axis() {
        let (sigma2, dt) = (5.0, 0.4);
        let q: Matrix<6> = discrete(sigma2).process_noise_matrix(dt);
        let (dt2, dt3, dt4) = (dt * dt, dt * dt * dt, dt * dt * dt * dt);
        let block = [[dt4 / 4.0, dt3 / 2.0], [dt3 / 2.0, dt2]];
        let mut expected = Matrix::<6>::zeros();
        for axis in 0..3 {
            for i in 0..2 {
                for j in 0..2 {
                    expected[(2 * axis + i, 2 * axis + j)] = sigma2 * block[i][j];
                }
            }
        }
        assert_matrix_close(&q, &expected, 1e-15);
        assert_symmetric_psd(&q);
        // Axes are independent.
        assert_eq!(q[(0, 2)], 0.0);
        assert_eq!(q[(1, 3)], 0.0);
    }

    #[test]
    fn seed_004_gain_gives_its_q() {
        let (sigma2, dt) = (2.0, 0.5);
        let cv = ConstantVelocity::new(ProcessNoise::discrete(sigma2, NoiseGain::seed_004_cv())).unwrap();
        let q: Matrix<4> = cv.process_noise_matrix(dt);
        // G = [T/2, 1]ᵀ → Q = σ² [[T²/4, T/2], [T/2, 1]]
        let expected = Matrix::<4>::from_row_slice(&[
            0.125, 0.5, 0.0, 0.0, //
            0.5, 2.0, 0.0, 0.0, //
            0.0, 0.0, 0.125, 0.5, //
            0.0, 0.0, 0.5, 2.0,
        ]);
        assert_matrix_close(&q, &expected, 1e-15);
    }

    #[test]
    fn continuous_noise_equals_numerical_integral() {
        let spectral_density = 0.7;
        let cv = ConstantVelocity::new(ProcessNoise::continuous(spectral_density)).unwrap();
        for dt in [0.05, 1.0, 3.3] {
            let q: Matrix<6> = cv.process_noise_matrix(dt);
            let transition = |tau: f64| -> Matrix<6> { cv.transition_matrix(tau) };
            let integral = simpson_continuous_q(transition, &[1, 3, 5], spectral_density, dt, 2000);
            assert_matrix_close(&q, &integral, 1e-9);
            assert!(q[(0, 0)] > 0.0 && q[(0, 1)] > 0.0);
            assert_symmetric_psd(&q);
            // Continuous-noise Q is positive definite for dt > 0.
            assert!(q.cholesky().is_some());
        }
    }

    #[test]
    fn control_matrix_shape_and_values() {
        let cv = discrete(1.0);
        assert!(LinearMotionModel::<4>::control_matrix(&cv, 1.0).is_none());
        let cv = cv.with_acceleration_input();
        let dt = 0.2;
        let b: ControlGain<6> = cv.control_matrix(dt).unwrap();
        assert_eq!((b.nrows(), b.ncols()), (6, 3));
        for row in 0..6 {
            for col in 0..3 {
                let expected = match (row, col) {
                    (r, c) if r == 2 * c => dt * dt / 2.0,
                    (r, c) if r == 2 * c + 1 => dt,
                    _ => 0.0,
                };
                assert_eq!(b[(row, col)], expected, "B[({row}, {col})]");
            }
        }
        // Constant acceleration a = 2 m/s² along y from rest, 1 s: y = a t²/2, vy = a t.
        let b: ControlGain<4> = cv.control_matrix(1.0).unwrap();
        let u = nalgebra::DVector::from_vec(vec![0.0, 2.0]);
        let f: Matrix<4> = cv.transition_matrix(1.0);
        let x = f * Vector::<4>::zeros() + b * u;
        assert_eq!(x, Vector::<4>::new(0.0, 0.0, 1.0, 2.0));
    }

    #[test]
    fn new_rejects_invalid_noise() {
        assert!(ConstantVelocity::new(ProcessNoise::discrete(-1.0, NoiseGain::kinematic())).is_err());
        assert!(ConstantVelocity::new(ProcessNoise::continuous(f64::NAN)).is_err());
    }
}
