//! Constant-acceleration (nearly constant acceleration) model in 1, 2 or 3 axes.

use super::noise::ProcessNoise;
use super::LinearMotionModel;
use crate::error::Result;
use crate::gaussian::Matrix;

/// Constant-acceleration motion model over `D = N/3` independent axes, in seed 004's state
/// order `[x, vx, y, vy, (z, vz), ax, ay, (az)]`: for axis `i` the position is entry `2i`, the
/// velocity `2i + 1` and the acceleration `2D + i`, so the constant-velocity state is the first
/// `2D` entries.
///
/// Per axis, over a step `dt`:
/// ```text
/// p' = p + dt·v + dt²/2·a               [[1, dt, dt²/2],
/// v' =     v    + dt·a       F_axis =    [0,  1, dt   ],
/// a' =            a                      [0,  0, 1    ]]
/// ```
/// `F` and `Q` hold `F_axis` and `Q_axis` at the indices `(2i, 2i+1, 2D+i)`; `Q_axis` comes from
/// [`ProcessNoise`]: `G σ² Gᵀ` with `G = [g₀, g₁, g₂]ᵀ`, or for continuous white jerk
/// `q·[[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]`. `N` must be a
/// positive multiple of 3 (checked at compile time).
///
/// A state size that is not a multiple of 3 does not compile:
/// ```compile_fail
/// use rtls_estimation::motion::{ConstantAcceleration, LinearMotionModel, ProcessNoise};
/// let ca = ConstantAcceleration::new(ProcessNoise::continuous(1.0)).unwrap();
/// let _ = LinearMotionModel::<4>::process_noise_matrix(&ca, 1.0);
/// ```
///
/// # Units
/// Metres, m/s, m/s²; `dt` in seconds.
///
/// # Example
/// ```
/// use rtls_estimation::motion::{ConstantAcceleration, LinearMotionModel, NoiseGain, ProcessNoise};
/// use rtls_estimation::Vector;
/// let ca = ConstantAcceleration::new(ProcessNoise::discrete(0.1, NoiseGain::seed_004_ca()))?;
/// let f = LinearMotionModel::<6>::transition_matrix(&ca, 2.0);
/// // [x, vx, y, vy, ax, ay]: from rest with ax = 1 m/s², after 2 s x = 2 m, vx = 2 m/s.
/// let x = f * Vector::<6>::new(0.0, 0.0, 0.0, 0.0, 1.0, 0.0);
/// assert_eq!(x, Vector::<6>::new(2.0, 2.0, 0.0, 0.0, 1.0, 0.0));
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 eq. (10) (`Φᵐ`, `Gᵐ`, state order); Bar-Shalom, Li, Kirubarajan, *Estimation with
/// Applications to Tracking and Navigation* (2001), §6.2.3 and §6.3.3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantAcceleration {
    noise: ProcessNoise,
}

/// Number of axes `D = N/3` of an `N`-entry constant-acceleration state. Evaluated in a `const`
/// block, so an `N` that is not a positive multiple of 3 is a compile-time error.
const fn axis_count<const N: usize>() -> usize {
    assert!(
        N.is_multiple_of(3) && N > 0,
        "ConstantAcceleration needs a state size N = 3·axes > 0"
    );
    N / 3
}

/// Indices `(position, velocity, acceleration)` of `axis` in an `N = 3D` CA state.
#[inline]
const fn axis_indices(axis: usize, axes: usize) -> [usize; 3] {
    [2 * axis, 2 * axis + 1, 2 * axes + axis]
}

impl ConstantAcceleration {
    /// A constant-acceleration model with process noise `noise`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`](crate::EstimationError::InvalidParameter) if
    /// `noise` is invalid (see [`ProcessNoise::validate`]).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantAcceleration, ProcessNoise};
    /// assert!(ConstantAcceleration::new(ProcessNoise::continuous(0.01)).is_ok());
    /// assert!(ConstantAcceleration::new(ProcessNoise::continuous(-0.01)).is_err());
    /// ```
    ///
    /// # References
    /// Seed 004 eq. (10); Bar-Shalom et al. (2001), §6.3.3.
    pub fn new(noise: ProcessNoise) -> Result<Self> {
        noise.validate()?;
        Ok(Self { noise })
    }

    /// The process noise.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{ConstantAcceleration, ProcessNoise};
    /// let ca = ConstantAcceleration::new(ProcessNoise::continuous(0.01))?;
    /// assert_eq!(ca.noise(), ProcessNoise::continuous(0.01));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn noise(&self) -> ProcessNoise {
        self.noise
    }
}

impl<const N: usize> LinearMotionModel<N> for ConstantAcceleration {
    #[inline]
    fn transition_matrix(&self, dt_s: f64) -> Matrix<N> {
        let axes = const { axis_count::<N>() };
        let mut f = Matrix::<N>::identity();
        for axis in 0..axes {
            let [p, v, a] = axis_indices(axis, axes);
            // p' = p + dt·v + dt²/2·a
            f[(p, v)] = dt_s;
            f[(p, a)] = dt_s * dt_s / 2.0;
            // v' = v + dt·a
            f[(v, a)] = dt_s;
        }
        f
    }

    #[inline]
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<N> {
        let axes = const { axis_count::<N>() };
        // Q_axis = G σ² Gᵀ (discrete) or ∫ Φ L q Lᵀ Φᵀ (continuous white jerk)
        let block = self.noise.ca_axis_block(dt_s);
        // Q[idx_i, idx_j] = Q_axis[i, j] for each axis' (position, velocity, acceleration) indices
        let mut q = Matrix::<N>::zeros();
        for axis in 0..axes {
            let indices = axis_indices(axis, axes);
            for (i, &row) in indices.iter().enumerate() {
                for (j, &col) in indices.iter().enumerate() {
                    q[(row, col)] = block[i][j];
                }
            }
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::super::noise::test_support::{assert_matrix_close, assert_symmetric_psd, simpson_continuous_q};
    use super::super::noise::NoiseGain;
    use super::*;
    use crate::gaussian::Vector;

    fn model() -> ConstantAcceleration {
        ConstantAcceleration::new(ProcessNoise::discrete(0.3, NoiseGain::kinematic())).unwrap()
    }

    #[test]
    fn transition_matrix_matches_seed_004() {
        let t = 0.4;
        let f: Matrix<6> = model().transition_matrix(t);
        #[rustfmt::skip]
        let expected = Matrix::<6>::from_row_slice(&[
            1.0, t,   0.0, 0.0, t * t / 2.0, 0.0,
            0.0, 1.0, 0.0, 0.0, t,           0.0,
            0.0, 0.0, 1.0, t,   0.0,         t * t / 2.0,
            0.0, 0.0, 0.0, 1.0, 0.0,         t,
            0.0, 0.0, 0.0, 0.0, 1.0,         0.0,
            0.0, 0.0, 0.0, 0.0, 0.0,         1.0,
        ]);
        assert_eq!(f, expected);
        let f1: Matrix<3> = model().transition_matrix(2.0);
        assert_eq!(f1, Matrix::<3>::new(1.0, 2.0, 2.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0));
    }

    #[test]
    fn transition_of_3d_state_uses_the_layout() {
        let f: Matrix<9> = model().transition_matrix(1.0);
        // [x, vx, y, vy, z, vz, ax, ay, az] with only az = 2: z = 1, vz = 2.
        let mut x = Vector::<9>::zeros();
        x[8] = 2.0;
        let moved = f * x;
        let mut expected = Vector::<9>::zeros();
        expected[4] = 1.0;
        expected[5] = 2.0;
        expected[8] = 2.0;
        assert_eq!(moved, expected);
    }

    #[test]
    fn transition_composes_over_steps() {
        let ca = model();
        let (dt1, dt2) = (0.7, 1.3);
        let f12: Matrix<9> = ca.transition_matrix(dt1 + dt2);
        let f2: Matrix<9> = ca.transition_matrix(dt2);
        let f1: Matrix<9> = ca.transition_matrix(dt1);
        assert_matrix_close(&f12, &(f2 * f1), 1e-15);
    }

    #[test]
    fn discrete_noise_is_outer_product_in_layout() {
        let (sigma2, dt) = (0.3, 0.5);
        let q: Matrix<6> = model().process_noise_matrix(dt);
        let g = [dt * dt / 2.0, dt, 1.0];
        for axis in 0..2 {
            let idx = [2 * axis, 2 * axis + 1, 4 + axis];
            for i in 0..3 {
                for j in 0..3 {
                    let expected = sigma2 * g[i] * g[j];
                    assert!((q[(idx[i], idx[j])] - expected).abs() < 1e-15, "axis {axis} ({i}, {j})");
                }
            }
        }
        // Cross-axis terms are zero: x with ay, vx with y.
        assert_eq!(q[(0, 5)], 0.0);
        assert_eq!(q[(1, 2)], 0.0);
        assert_symmetric_psd(&q);
    }

    #[test]
    fn continuous_noise_equals_numerical_integral() {
        let spectral_density = 0.05;
        let ca = ConstantAcceleration::new(ProcessNoise::continuous(spectral_density)).unwrap();
        for dt in [0.1, 1.0, 2.5] {
            let q: Matrix<9> = ca.process_noise_matrix(dt);
            let transition = |tau: f64| -> Matrix<9> { ca.transition_matrix(tau) };
            let integral = simpson_continuous_q(transition, &[6, 7, 8], spectral_density, dt, 2000);
            assert_matrix_close(&q, &integral, 1e-9);
            assert_symmetric_psd(&q);
            assert!(q.cholesky().is_some());
        }
    }

    #[test]
    fn has_no_control_input_and_validates() {
        assert!(LinearMotionModel::<6>::control_matrix(&model(), 1.0).is_none());
        assert!(ConstantAcceleration::new(ProcessNoise::discrete(f64::NAN, NoiseGain::kinematic())).is_err());
        assert!(ConstantAcceleration::new(ProcessNoise::continuous(-1.0)).is_err());
    }
}
