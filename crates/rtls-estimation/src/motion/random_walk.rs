//! Random walk: the state stays put up to a diffusion that grows linearly with time.

use super::LinearMotionModel;
use crate::error::{EstimationError, Result};
use crate::gaussian::Matrix;

/// Random-walk (Wiener process) model for any state size `N`: `x' = x + w`,
/// `w ~ N(0, q·dt·I)`, i.e. `F = I` and `Q = q·dt·I`.
///
/// Suits a tag that is parked or moves slowly and unpredictably, with position-only states
/// (`N = 2` or `3`), or a slowly drifting parameter such as a clock offset or path-loss bias.
///
/// # Units
/// `variance_rate` `q` in (state unit)²/s, e.g. m²/s for a position; `dt` in seconds.
///
/// # Example
/// ```
/// use rtls_estimation::motion::{LinearMotionModel, RandomWalk};
/// use rtls_estimation::Matrix;
/// let walk = RandomWalk::new(0.5)?;
/// assert_eq!(LinearMotionModel::<2>::transition_matrix(&walk, 3.0), Matrix::<2>::identity());
/// assert_eq!(LinearMotionModel::<2>::process_noise_matrix(&walk, 2.0), Matrix::<2>::identity());
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*
/// (2001), §6.2 (continuous kinematic models, zeroth order); seed 002 eq. (8) (position
/// variance accumulating per step with `A = I`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomWalk {
    variance_rate: f64,
}

impl RandomWalk {
    /// A random walk whose variance grows by `variance_rate` (units²/s) per second.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `variance_rate` is negative or not finite.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::RandomWalk;
    /// assert!(RandomWalk::new(0.0).is_ok());
    /// assert!(RandomWalk::new(-1.0).is_err());
    /// ```
    ///
    /// # References
    /// Bar-Shalom et al. (2001), §6.2.
    pub fn new(variance_rate: f64) -> Result<Self> {
        if !variance_rate.is_finite() || variance_rate < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "variance_rate",
                reason: "the random-walk variance rate must be finite and non-negative",
            });
        }
        Ok(Self { variance_rate })
    }

    /// The variance rate `q` in units²/s.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::RandomWalk;
    /// assert_eq!(RandomWalk::new(0.25)?.variance_rate(), 0.25);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn variance_rate(&self) -> f64 {
        self.variance_rate
    }
}

impl<const N: usize> LinearMotionModel<N> for RandomWalk {
    #[inline]
    fn transition_matrix(&self, _dt_s: f64) -> Matrix<N> {
        // F = I
        Matrix::<N>::identity()
    }

    #[inline]
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<N> {
        // Q = q·dt·I
        Matrix::<N>::from_diagonal_element(self.variance_rate * dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::super::MotionModel;
    use super::*;
    use crate::gaussian::Vector;

    #[test]
    fn identity_transition_and_linear_variance_growth() {
        let walk = RandomWalk::new(0.3).unwrap();
        let x = Vector::<3>::new(1.0, -2.0, 0.5);
        assert_eq!(walk.transition(&x, 10.0), x);
        let q: Matrix<3> = walk.process_noise_matrix(2.0);
        assert_eq!(q, Matrix::<3>::identity() * 0.6);
        // Variances add over consecutive steps: Q(dt1) + Q(dt2) = Q(dt1 + dt2).
        let q1: Matrix<3> = walk.process_noise_matrix(0.5);
        let q2: Matrix<3> = walk.process_noise_matrix(1.5);
        assert_eq!(q1 + q2, q);
        assert!(LinearMotionModel::<3>::control_matrix(&walk, 1.0).is_none());
    }

    #[test]
    fn rejects_invalid_variance_rate() {
        for bad in [-1e-12, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                RandomWalk::new(bad),
                Err(EstimationError::InvalidParameter {
                    name: "variance_rate",
                    ..
                })
            ));
        }
    }
}
