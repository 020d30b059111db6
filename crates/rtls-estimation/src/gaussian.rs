//! The Gaussian state of a track: mean, covariance and the time they refer to.

use nalgebra::{SMatrix, SVector};

use crate::error::{EstimationError, Result};
use crate::math::ensure_finite;

/// State vector of size `N` (units depend on the motion model, e.g. `[m, m/s, …]`).
pub type Vector<const N: usize> = SVector<f64, N>;
/// Square `N × N` matrix (covariances, transition matrices).
pub type Matrix<const N: usize> = SMatrix<f64, N, N>;

/// A Gaussian belief `N(mean, covariance)` about a state at time `time_s`.
///
/// This is a *value*: filters take a `&Gaussian` and return a new one, so one filter (an
/// immutable strategy) serves any number of tracks, each of which owns its state.
///
/// # Invariants
/// The mean and covariance are finite and the covariance is symmetric; constructors check
/// this, and every filter step re-establishes it (or returns an error).
///
/// # Units
/// `time_s` is in seconds on any monotonic clock the caller chooses; the mean's units are
/// those of the motion model (SI: metres, m/s, m/s², rad, rad/s).
///
/// # Example
/// ```
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// let x = Gaussian::new(Vector::<2>::new(0.0, 1.0), Matrix::<2>::identity(), 0.0)?;
/// assert_eq!(x.mean()[1], 1.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(try_from = "GaussianParts<N>")
)]
pub struct Gaussian<const N: usize> {
    mean: Vector<N>,
    covariance: Matrix<N>,
    time_s: f64,
}

/// A [`Gaussian`] as stored: it becomes one only through [`Gaussian::new`]'s checks.
#[cfg(feature = "serde")]
#[derive(serde::Deserialize)]
struct GaussianParts<const N: usize> {
    mean: Vector<N>,
    covariance: Matrix<N>,
    time_s: f64,
}

#[cfg(feature = "serde")]
impl<const N: usize> TryFrom<GaussianParts<N>> for Gaussian<N> {
    type Error = EstimationError;

    fn try_from(parts: GaussianParts<N>) -> Result<Self> {
        Self::new(parts.mean, parts.covariance, parts.time_s)
    }
}

impl<const N: usize> Gaussian<N> {
    /// Builds a state after checking that everything is finite and the covariance symmetric
    /// (to a relative tolerance of `1e-9`; the stored matrix is then exactly symmetrised).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞ in the mean, covariance or time;
    /// [`EstimationError::InvalidParameter`] for an asymmetric covariance or a negative variance.
    pub fn new(mean: Vector<N>, covariance: Matrix<N>, time_s: f64) -> Result<Self> {
        ensure_finite(&mean, "state mean")?;
        ensure_finite(&covariance, "state covariance")?;
        if !time_s.is_finite() {
            return Err(EstimationError::NonFinite { what: "state time" });
        }
        let scale = covariance.amax().max(f64::MIN_POSITIVE);
        for i in 0..N {
            if covariance[(i, i)] < 0.0 {
                return Err(EstimationError::InvalidParameter {
                    name: "covariance",
                    reason: "a diagonal entry (variance) is negative",
                });
            }
            for j in (i + 1)..N {
                if (covariance[(i, j)] - covariance[(j, i)]).abs() > 1e-9 * scale {
                    return Err(EstimationError::InvalidParameter {
                        name: "covariance",
                        reason: "the matrix is not symmetric",
                    });
                }
            }
        }
        let mut covariance = covariance;
        crate::math::symmetrize(&mut covariance);
        Ok(Self {
            mean,
            covariance,
            time_s,
        })
    }

    /// Builds a state whose finiteness and symmetry the caller (a filter) has established.
    #[inline]
    pub(crate) fn from_parts_unchecked(mean: Vector<N>, covariance: Matrix<N>, time_s: f64) -> Self {
        debug_assert!(mean.iter().all(|v| v.is_finite()));
        debug_assert!(covariance.iter().all(|v| v.is_finite()));
        Self {
            mean,
            covariance,
            time_s,
        }
    }

    /// Builds a state after a filter step: checks finiteness and symmetrises the covariance.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] naming `what` if any entry is NaN or infinite.
    #[inline]
    pub(crate) fn from_step(
        mean: Vector<N>,
        mut covariance: Matrix<N>,
        time_s: f64,
        what: &'static str,
    ) -> Result<Self> {
        ensure_finite(&mean, what)?;
        ensure_finite(&covariance, what)?;
        crate::math::symmetrize(&mut covariance);
        Ok(Self {
            mean,
            covariance,
            time_s,
        })
    }

    /// The mean (best estimate).
    #[inline]
    #[must_use]
    pub fn mean(&self) -> &Vector<N> {
        &self.mean
    }

    /// The covariance (uncertainty of the mean).
    #[inline]
    #[must_use]
    pub fn covariance(&self) -> &Matrix<N> {
        &self.covariance
    }

    /// The time the state refers to, in seconds.
    #[inline]
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The step `dt = to_time_s − time_s` to reach `to_time_s`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if `to_time_s` is earlier than the state;
    /// [`EstimationError::NonFinite`] if `to_time_s` is not finite.
    #[inline]
    pub fn step_to(&self, to_time_s: f64) -> Result<f64> {
        step_between(self.time_s, to_time_s)
    }

    /// Normalised estimation error squared `(x − x̂)ᵀ P⁻¹ (x − x̂)` of this estimate against the
    /// true state; `χ²(N)`-distributed for a consistent filter.
    ///
    /// # Errors
    /// [`EstimationError::NotPositiveDefinite`] if the covariance cannot be Cholesky-factorised.
    ///
    /// # References
    /// Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*
    /// (2001), §5.4.2, eq. (5.4.2-1).
    pub fn nees(&self, truth: &Vector<N>) -> Result<f64> {
        let chol = self.covariance.cholesky().ok_or(EstimationError::NotPositiveDefinite {
            what: "state covariance",
        })?;
        // e = x − x̂
        let error = truth - self.mean;
        // ε = eᵀ P⁻¹ e = |L⁻¹ e|²
        let whitened = chol
            .l()
            .solve_lower_triangular(&error)
            .ok_or(EstimationError::NotPositiveDefinite {
                what: "state covariance",
            })?;
        Ok(whitened.norm_squared())
    }
}

/// The step `dt = to_time_s − from_time_s` between two time stamps (s), refusing to go back.
///
/// # Errors
/// [`EstimationError::TimeWentBackwards`] if `to_time_s < from_time_s`;
/// [`EstimationError::NonFinite`] if `to_time_s` is not finite.
#[inline]
pub(crate) fn step_between(from_time_s: f64, to_time_s: f64) -> Result<f64> {
    if !to_time_s.is_finite() {
        return Err(EstimationError::NonFinite { what: "requested time" });
    }
    let dt_s = to_time_s - from_time_s;
    if dt_s < 0.0 {
        return Err(EstimationError::TimeWentBackwards {
            state_time_s: from_time_s,
            requested_time_s: to_time_s,
        });
    }
    Ok(dt_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_nan_and_asymmetry() {
        let mut p = Matrix::<2>::identity();
        assert!(Gaussian::new(Vector::<2>::new(f64::NAN, 0.0), p, 0.0).is_err());
        p[(0, 1)] = 0.5;
        assert_eq!(
            Gaussian::new(Vector::<2>::zeros(), p, 0.0),
            Err(EstimationError::InvalidParameter {
                name: "covariance",
                reason: "the matrix is not symmetric"
            })
        );
    }

    #[test]
    fn step_to_refuses_backwards_time() {
        let g = Gaussian::new(Vector::<1>::zeros(), Matrix::<1>::identity(), 5.0).unwrap();
        assert_eq!(g.step_to(7.5), Ok(2.5));
        assert!(matches!(g.step_to(4.0), Err(EstimationError::TimeWentBackwards { .. })));
    }

    #[test]
    fn nees_of_unit_gaussian_is_squared_distance() {
        let g = Gaussian::new(Vector::<2>::zeros(), Matrix::<2>::identity() * 4.0, 0.0).unwrap();
        let nees = g.nees(&Vector::<2>::new(2.0, 2.0)).unwrap();
        assert!((nees - 2.0).abs() < 1e-12);
    }
}
