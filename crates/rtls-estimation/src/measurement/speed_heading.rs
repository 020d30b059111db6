//! Odometry: speed and heading from on-board sensors (odometer, gyro/compass).

use nalgebra::{DMatrix, DVector};

use super::range::check_noise_dim;
use super::{MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;
use crate::math::{atan2, sin_cos, sqrt, wrap_angle};

/// Below this speed (m/s) the heading is undefined.
const MIN_SPEED_MPS: f64 = 1e-9;

/// State indices of the x and y velocities.
const VELOCITY_INDICES: [usize; 2] = [1, 3];

/// Speed and heading of a planar track: `z = [s, ψ] + v` with
/// `s = √(vx² + vy²)` and `ψ = atan2(vy, vx)` (the angle from the +x axis, counter-clockwise).
///
/// The velocities are state indices 1 and 3 (`[x, vx, y, vy, …]`, `N ≥ 4`). The Jacobian is
///
/// ```text
/// ∂s/∂vx = vx/s      ∂s/∂vy = vy/s
/// ∂ψ/∂vx = −vy/s²    ∂ψ/∂vy = vx/s²
/// ```
/// and 0 in every other column. The residual wraps the heading difference into `(−π, π]`, and
/// the weighted mean of sigma points uses the circular mean `atan2(Σ w sin ψ, Σ w cos ψ)` for
/// the heading, so headings near ±π average correctly.
///
/// # Units
/// `s` in m/s, `ψ` in rad (a compass bearing `β`, clockwise from north, is `ψ = π/2 − β`);
/// `R` in (m/s)² and rad².
///
/// # Errors
/// [`MeasurementModel::predict`] and [`MeasurementModel::jacobian`] return
/// [`EstimationError::SingularMeasurement`] (model `"speed_heading"`) when the speed is below
/// `1e-9` m/s (a standing target has no heading: skip the odometry update then), and
/// [`EstimationError::DimensionMismatch`] for `N < 4`.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{MeasurementModel, NoiseCovariance, SpeedHeading};
/// use rtls_estimation::Vector;
/// // Seed 004: speed error 1 m/s, heading error ≈ 0.1 rad.
/// let odometry = SpeedHeading::new(NoiseCovariance::diagonal(&[1.0, 0.01])?)?;
/// let z = odometry.predict(&Vector::<4>::new(0.0, 3.0, 0.0, 4.0))?;
/// assert!((z[0] - 5.0).abs() < 1e-12);
/// assert!((z[1] - 4f64.atan2(3.0)).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004, §1: the local sensors give the target's speed and direction of motion, which the
/// paper converts to `(zvx, zvy)` for `H = I₄` (eq. (9)); this model uses them raw instead.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedHeading {
    noise: NoiseCovariance,
}

impl SpeedHeading {
    /// Speed and heading with noise covariance `noise` (2 × 2: speed in (m/s)², heading in
    /// rad²).
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `noise.dim() ≠ 2`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{NoiseCovariance, SpeedHeading};
    /// assert!(SpeedHeading::new(NoiseCovariance::diagonal(&[1.0, 0.01])?).is_ok());
    /// assert!(SpeedHeading::new(NoiseCovariance::isotropic(3, 1.0)?).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn new(noise: NoiseCovariance) -> Result<Self> {
        check_noise_dim(&noise, 2)?;
        Ok(Self { noise })
    }

    /// The measurement noise covariance.
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }
}

/// The velocity `(vx, vy)` and speed `s = √(vx² + vy²)`, or an error when `s` is too small to
/// define a heading or the state has no planar velocity.
fn velocity_and_speed<const N: usize>(x: &Vector<N>) -> Result<(f64, f64, f64)> {
    if N < 4 {
        return Err(EstimationError::DimensionMismatch {
            what: "state size (speed and heading need [x, vx, y, vy, …])",
            expected: 4,
            found: N,
        });
    }
    let (vx, vy) = (x[VELOCITY_INDICES[0]], x[VELOCITY_INDICES[1]]);
    // s = √(vx² + vy²)
    let speed_mps = sqrt(vx * vx + vy * vy);
    if speed_mps.is_nan() || speed_mps < MIN_SPEED_MPS {
        return Err(EstimationError::SingularMeasurement {
            model: "speed_heading",
            reason: "the speed is below 1e-9 m/s, so the heading is undefined; \
                     skip the odometry update while the target stands still",
        });
    }
    Ok((vx, vy, speed_mps))
}

impl<const N: usize> MeasurementModel<N> for SpeedHeading {
    #[inline]
    fn dim(&self) -> usize {
        2
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        let (vx, vy, speed_mps) = velocity_and_speed(x)?;
        // ψ = atan2(vy, vx)
        let heading_rad = atan2(vy, vx);
        Ok(DVector::from_column_slice(&[speed_mps, heading_rad]))
    }

    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        let (vx, vy, speed_mps) = velocity_and_speed(x)?;
        let speed2 = speed_mps * speed_mps;
        let [ix, iy] = VELOCITY_INDICES;
        let mut h = MeasurementJacobian::<N>::zeros(2);
        // ∂s/∂v = vᵀ / s
        h[(0, ix)] = vx / speed_mps;
        h[(0, iy)] = vy / speed_mps;
        // ∂ψ/∂v = [−vy, vx] / s²
        h[(1, ix)] = -vy / speed2;
        h[(1, iy)] = vx / speed2;
        Ok(h)
    }

    #[inline]
    fn noise_covariance(&self) -> &DMatrix<f64> {
        self.noise.matrix()
    }

    fn residual(&self, z: &DVector<f64>, predicted: &DVector<f64>) -> DVector<f64> {
        debug_assert!(
            z.len() == 2 && predicted.len() == 2,
            "speed and heading have two components"
        );
        // ν = [s − ŝ, wrap(ψ − ψ̂)]
        DVector::from_column_slice(&[z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
    }

    fn weighted_mean(&self, points: &DMatrix<f64>, weights: &[f64]) -> DVector<f64> {
        debug_assert_eq!(points.nrows(), 2, "speed and heading have two components");
        let (mut speed, mut sin_sum, mut cos_sum) = (0.0, 0.0, 0.0);
        for (point, &w) in points.column_iter().zip(weights) {
            // s̄ = Σ wᵢ sᵢ
            speed += w * point[0];
            let (sin, cos) = sin_cos(point[1]);
            sin_sum += w * sin;
            cos_sum += w * cos;
        }
        // ψ̄ = atan2(Σ wᵢ sin ψᵢ, Σ wᵢ cos ψᵢ)
        DVector::from_column_slice(&[speed, atan2(sin_sum, cos_sum)])
    }
}

#[cfg(test)]
mod tests {
    use alloc::vec;
    use core::f64::consts::{FRAC_PI_2, PI, TAU};

    use super::super::range::testing::{assert_jacobian_matches_finite_differences, random_states};
    use super::*;

    fn model() -> SpeedHeading {
        SpeedHeading::new(NoiseCovariance::diagonal(&[1.0, 0.01]).unwrap()).unwrap()
    }

    #[test]
    fn speed_and_heading_follow_the_axes_convention() {
        let m = model();
        let z = m.predict(&Vector::<4>::new(7.0, 0.0, -2.0, 2.0)).unwrap();
        assert!((z[0] - 2.0).abs() < 1e-12);
        assert!((z[1] - FRAC_PI_2).abs() < 1e-12); // moving along +y
        let z = m.predict(&Vector::<4>::new(0.0, -1.0, 0.0, 0.0)).unwrap();
        assert!((z[1] - PI).abs() < 1e-12); // along −x
        let z = m
            .predict(&Vector::<6>::from_column_slice(&[0.0, 1.0, 0.0, -1.0, 5.0, 5.0]))
            .unwrap();
        assert!((z[0] - crate::math::sqrt(2.0)).abs() < 1e-12);
        assert!((z[1] + PI / 4.0).abs() < 1e-12);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = model();
        for x in random_states::<4>(51, 30, 5.0) {
            assert_jacobian_matches_finite_differences(&m, &x);
        }
        for x in random_states::<6>(52, 10, 5.0) {
            assert_jacobian_matches_finite_differences(&m, &x);
        }
        // Across the ±π cut: heading ≈ π, vy slightly positive.
        let x = Vector::<4>::new(0.0, -2.0, 0.0, 1e-3);
        assert_jacobian_matches_finite_differences(&m, &x);
        let h = m.jacobian(&Vector::<4>::new(9.0, 3.0, 9.0, 4.0)).unwrap();
        assert!((h[(0, 1)] - 0.6).abs() < 1e-12);
        assert!((h[(1, 1)] + 4.0 / 25.0).abs() < 1e-12);
        assert_eq!(h[(0, 0)], 0.0);
        assert_eq!(h[(1, 2)], 0.0);
    }

    #[test]
    fn standing_still_is_an_error_not_nan() {
        let m = model();
        let x = Vector::<4>::new(1.0, 0.0, 2.0, 0.0);
        assert!(matches!(
            m.predict(&x),
            Err(EstimationError::SingularMeasurement {
                model: "speed_heading",
                ..
            })
        ));
        assert!(matches!(
            m.jacobian(&x),
            Err(EstimationError::SingularMeasurement {
                model: "speed_heading",
                ..
            })
        ));
        assert!(m.jacobian(&Vector::<4>::new(0.0, 1e-10, 0.0, 0.0)).is_err());
        assert!(matches!(
            MeasurementModel::<2>::predict(&m, &Vector::<2>::new(1.0, 1.0)),
            Err(EstimationError::DimensionMismatch {
                expected: 4,
                found: 2,
                ..
            })
        ));
    }

    #[test]
    fn residual_wraps_the_heading() {
        let m = model();
        let z = DVector::from_vec(vec![2.0, 3.1]);
        let predicted = DVector::from_vec(vec![1.5, -3.1]);
        let y = MeasurementModel::<4>::residual(&m, &z, &predicted);
        assert!((y[0] - 0.5).abs() < 1e-15);
        // 6.2 − 2π ≈ −0.0832
        assert!((y[1] - (6.2 - TAU)).abs() < 1e-12);
        assert!((y[1] + 0.083_185).abs() < 1e-6);
        let y = MeasurementModel::<4>::residual(&m, &predicted, &z);
        assert!((y[1] - (TAU - 6.2)).abs() < 1e-12);
    }

    #[test]
    fn circular_mean_of_headings_near_pi() {
        let m = model();
        // Two headings 0.04 rad either side of π: the arithmetic mean would be ≈ 0.
        let points = DMatrix::from_row_slice(2, 2, &[1.0, 3.0, PI - 0.04, -PI + 0.04]);
        let mean = MeasurementModel::<4>::weighted_mean(&m, &points, &[0.5, 0.5]);
        assert!((mean[0] - 2.0).abs() < 1e-15);
        assert!(wrap_angle(mean[1] - PI).abs() < 1e-12);
        // Unequal and negative weights (as unscented weights can be) still follow the circle.
        let points = DMatrix::from_row_slice(2, 3, &[1.0, 1.0, 1.0, 3.1, -3.1, 3.0]);
        let weights = [-0.5, 0.75, 0.75];
        let mean = MeasurementModel::<4>::weighted_mean(&m, &points, &weights);
        let (s, c) = weights.iter().zip([3.1, -3.1, 3.0]).fold((0.0, 0.0), |(s, c), (w, a)| {
            let (sa, ca) = sin_cos(a);
            (s + w * sa, c + w * ca)
        });
        assert!((mean[1] - atan2(s, c)).abs() < 1e-15);
        assert!(mean[1].abs() > 3.0);
        assert!((mean[0] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn noise_must_be_two_by_two() {
        assert_eq!(
            SpeedHeading::new(NoiseCovariance::isotropic(1, 1.0).unwrap()),
            Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: 2,
                found: 1
            })
        );
    }
}
