//! The output of every positioning method: a planar fix with its (estimated) covariance, and
//! the calibration of a method's fix noise from surveyed points.

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use crate::error::{PositioningError, Result};

/// A position fix in `D` dimensions: `position` (m) and `covariance` (m²). [`Fix2`] is the
/// planar fix, [`Fix3`] the spatial one.
///
/// The covariance is whatever the method can say about its own error, and is **an estimate**:
/// for Chan's TDOA estimator it is the first-order (small-noise) covariance, which equals the
/// Cramér–Rao bound evaluated at the fix; for fingerprinting it is the weighted spread of the
/// chosen neighbours, which says how much they disagree but is not calibrated. When feeding
/// fixes to a Kalman filter, prefer a covariance calibrated with [`calibrate_fix_noise`] unless
/// the method's own covariance has been validated for the deployment.
///
/// Fixes returned by this crate are always finite and their covariance is symmetric positive
/// semi-definite.
///
/// # Units
/// `position` in metres, `covariance` in m².
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use rtls_positioning::Fix2;
/// let fix = Fix2 { position: Vector2::new(3.0, 4.0), covariance: Matrix2::from_diagonal_element(2.0) };
/// assert_eq!(fix.drms_m(), 2.0); // √(2 + 2)
/// ```
///
/// # References
/// Seed 000 (fixes smoothed by a Kalman filter); seed 002 eq. (12) (the fix is the filter's
/// observation `z(k) = x̂(k)` with covariance `U`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix<const D: usize> {
    /// Estimated position (`(x, y)` or `(x, y, z)`) in m.
    pub position: SVector<f64, D>,
    /// Estimated covariance of `position` in m² (symmetric, positive semi-definite).
    pub covariance: SMatrix<f64, D, D>,
}

/// A planar fix `(x, y)`.
pub type Fix2 = Fix<2>;

/// A spatial fix `(x, y, z)`.
pub type Fix3 = Fix<3>;

impl<const D: usize> Fix<D> {
    /// Distance root mean square `DRMS = √(tr P)` (m): the expected radial error implied by the
    /// covariance (in 3-D this is the mean radial spherical error).
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_positioning::Fix2;
    /// let fix = Fix2 { position: Vector2::zeros(), covariance: Matrix2::new(9.0, 1.0, 1.0, 16.0) };
    /// assert_eq!(fix.drms_m(), 5.0);
    /// ```
    ///
    /// # References
    /// Standard navigation accuracy measure (e.g. Kaplan & Hegarty, *Understanding GPS*, §7).
    #[inline]
    #[must_use]
    pub fn drms_m(&self) -> f64 {
        // DRMS = √(σ_x² + σ_y² [+ σ_z²])
        self.covariance.trace().max(0.0).sqrt()
    }

    /// Checks that the position and covariance are finite (the crate's output invariant).
    pub(crate) fn checked(self) -> Result<Self> {
        if !self.position.iter().all(|v| v.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "position estimate",
            });
        }
        if !self.covariance.iter().all(|v| v.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "position covariance",
            });
        }
        Ok(self)
    }
}

/// A plausible fix lies within `PLAUSIBLE_EXTENT_FACTOR ×` the anchors' bounding-box diagonal
/// (plus the caller's reach) of their centroid.
pub const PLAUSIBLE_EXTENT_FACTOR: f64 = 4.0;

impl<const D: usize> Fix<D> {
    /// Refuses a fix no tracker should start from or be updated with: a non-finite position or
    /// covariance, a covariance that is not symmetric positive definite, or a position far
    /// outside the anchors that produced it.
    ///
    /// ```text
    /// c = (1/N) Σ a_i,   diag = ‖max_i a_i − min_i a_i‖       (bounding-box diagonal)
    /// limit = PLAUSIBLE_EXTENT_FACTOR · diag + reach_m
    /// plausible ⇔ ‖p − c‖ ≤ limit  and  P = Pᵀ ≻ 0 (Cholesky succeeds)
    /// ```
    /// `reach_m` is how far beyond the anchors the measurements themselves allow the tag to
    /// be: for ranges the largest range plus three standard deviations (the tag is within
    /// `r_i + 3σ_i` of each anchor), for range differences 0. A TDOA fix in the plane that
    /// ignores anchor heights, or Gauss–Newton converging to a far local minimum, gives
    /// positions thousands of kilometres away with a finite covariance; starting a track there
    /// gates out every later measurement.
    ///
    /// # Units
    /// Anchors and `reach_m` in m.
    ///
    /// # Errors
    /// [`PositioningError::Underdetermined`] without anchors; [`PositioningError::NonFinite`]
    /// for a NaN/∞ position, covariance, anchor or reach;
    /// [`PositioningError::NotPositiveDefinite`] (`what = "fix covariance"`) for an asymmetric
    /// or indefinite covariance; [`PositioningError::ImplausibleFix`] beyond the limit.
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_positioning::{Fix2, PositioningError};
    /// let anchors = [[0.0, 0.0], [20.0, 0.0], [0.0, 15.0]]; // diagonal 25 m
    /// let fix = Fix2 { position: Vector2::new(5.0, 5.0), covariance: Matrix2::identity() };
    /// assert!(fix.check_plausible(&anchors, 0.0).is_ok());
    /// let far = Fix2 { position: Vector2::new(1.8e7, 0.0), ..fix };
    /// assert!(matches!(far.check_plausible(&anchors, 0.0), Err(PositioningError::ImplausibleFix { .. })));
    /// # Ok::<(), PositioningError>(())
    /// ```
    ///
    /// # References
    /// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    /// Navigation*, 2001, §3.4 (validation before use) and §5.2 (a covariance must be
    /// positive definite).
    pub fn check_plausible(&self, anchors_m: &[[f64; D]], reach_m: f64) -> Result<()> {
        self.checked()?;
        if anchors_m.is_empty() {
            return Err(PositioningError::Underdetermined { anchors: 0, needed: 1 });
        }
        if !(anchors_m.iter().flatten().all(|v| v.is_finite()) && reach_m.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "anchor positions or reach of a fix check",
            });
        }
        let symmetric = (self.covariance - self.covariance.transpose()).amax() <= 1e-9 * self.covariance.amax();
        if !symmetric || self.covariance.cholesky().is_none() {
            return Err(PositioningError::NotPositiveDefinite { what: "fix covariance" });
        }
        let point = |a: &[f64; D]| SVector::<f64, D>::from(*a);
        // c = (1/N) Σ a_i
        let centroid = anchors_m
            .iter()
            .fold(SVector::<f64, D>::zeros(), |acc, a| acc + point(a))
            / anchors_m.len() as f64;
        // diag = ‖max a − min a‖
        let low = anchors_m.iter().fold(point(&anchors_m[0]), |acc, a| acc.inf(&point(a)));
        let high = anchors_m.iter().fold(point(&anchors_m[0]), |acc, a| acc.sup(&point(a)));
        let diagonal_m = (high - low).norm();
        // limit = k · diag + reach
        let limit_m = PLAUSIBLE_EXTENT_FACTOR * diagonal_m + reach_m.max(0.0);
        let distance_m = (self.position - centroid).norm();
        if distance_m.is_finite() && distance_m <= limit_m {
            Ok(())
        } else {
            Err(PositioningError::ImplausibleFix { distance_m, limit_m })
        }
    }
}

/// Sample covariance of fix errors measured at surveyed points: the observation covariance `U`
/// of a positioning method.
///
/// Seed 002 places the node at `S` known points, computes a fix at each, and takes the
/// variance of the error as the Kalman filter's observation noise `U`. With errors
/// `e_s = x̂_s − x_s` (m):
///
/// `ē = (1/S) Σ e_s`, `U = 1/(S − 1) Σ (e_s − ē)(e_s − ē)ᵀ`
///
/// (the unbiased sample covariance; the mean `ē` is the method's bias, which a variance
/// deliberately excludes).
///
/// # Units
/// Errors in m, result in m².
///
/// # Errors
/// [`PositioningError::TooFewSamples`] for fewer than two errors;
/// [`PositioningError::NonFiniteEntry`] (row = sample, column = axis) for a NaN/∞ error.
///
/// # Example
/// ```
/// use rtls_positioning::calibrate_fix_noise;
/// let errors = [[1.0, 0.0], [-1.0, 0.0], [0.0, 2.0], [0.0, -2.0]];
/// let u = calibrate_fix_noise(&errors)?;
/// assert!((u[(0, 0)] - 2.0 / 3.0).abs() < 1e-12);
/// assert!((u[(1, 1)] - 8.0 / 3.0).abs() < 1e-12);
/// assert_eq!(u[(0, 1)], 0.0);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, §1.3 (observation covariance `U`, reported `U = diag(1.5, 2)`).
pub fn calibrate_fix_noise(errors_m: &[[f64; 2]]) -> Result<Matrix2<f64>> {
    if errors_m.len() < 2 {
        return Err(PositioningError::TooFewSamples {
            found: errors_m.len(),
            needed: 2,
        });
    }
    for (row, e) in errors_m.iter().enumerate() {
        if let Some(column) = e.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: "fix errors (row = sample, column = axis)",
                row,
                column,
            });
        }
    }
    let count = errors_m.len() as f64;
    // ē = (1/S) Σ e_s
    let mean = errors_m
        .iter()
        .fold(Vector2::zeros(), |acc: Vector2<f64>, e| acc + Vector2::new(e[0], e[1]))
        / count;
    // U = 1/(S − 1) Σ (e_s − ē)(e_s − ē)ᵀ
    let scatter = errors_m.iter().fold(Matrix2::zeros(), |acc: Matrix2<f64>, e| {
        let d = Vector2::new(e[0], e[1]) - mean;
        acc + d * d.transpose()
    });
    let covariance = scatter / (count - 1.0);
    if covariance.iter().all(|v| v.is_finite()) {
        Ok(covariance)
    } else {
        Err(PositioningError::NonFinite {
            what: "fix error covariance",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calibration_is_the_unbiased_sample_covariance_and_ignores_the_bias() {
        // The same spread shifted by a bias (3, −1) gives the same U.
        let errors = [[1.0, 2.0], [3.0, -1.0], [-2.0, 0.5], [0.5, 0.5], [2.0, -3.0]];
        let shifted: Vec<[f64; 2]> = errors.iter().map(|e| [e[0] + 3.0, e[1] - 1.0]).collect();
        let u = calibrate_fix_noise(&errors).unwrap();
        let v = calibrate_fix_noise(&shifted).unwrap();
        assert!((u - v).abs().max() < 1e-12);
        // Hand computation: mean (0.9, −0.2).
        let mx = 0.9;
        let my = -0.2;
        let sxx: f64 = errors.iter().map(|e| (e[0] - mx) * (e[0] - mx)).sum::<f64>() / 4.0;
        let sxy: f64 = errors.iter().map(|e| (e[0] - mx) * (e[1] - my)).sum::<f64>() / 4.0;
        let syy: f64 = errors.iter().map(|e| (e[1] - my) * (e[1] - my)).sum::<f64>() / 4.0;
        assert!((u[(0, 0)] - sxx).abs() < 1e-12);
        assert!((u[(0, 1)] - sxy).abs() < 1e-12);
        assert!((u[(1, 0)] - sxy).abs() < 1e-12);
        assert!((u[(1, 1)] - syy).abs() < 1e-12);
    }

    #[test]
    fn calibration_error_paths() {
        assert_eq!(
            calibrate_fix_noise(&[]),
            Err(PositioningError::TooFewSamples { found: 0, needed: 2 })
        );
        assert_eq!(
            calibrate_fix_noise(&[[1.0, 1.0]]),
            Err(PositioningError::TooFewSamples { found: 1, needed: 2 })
        );
        assert!(matches!(
            calibrate_fix_noise(&[[1.0, 1.0], [0.0, 0.0], [2.0, f64::INFINITY]]),
            Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
        ));
        assert!(matches!(
            calibrate_fix_noise(&[[1e308, 0.0], [-1e308, 0.0]]),
            Err(PositioningError::NonFinite { .. })
        ));
    }

    #[test]
    fn checked_rejects_non_finite_fixes() {
        let good = Fix2 {
            position: Vector2::new(1.0, 2.0),
            covariance: Matrix2::identity(),
        };
        assert_eq!(good.checked(), Ok(good));
        let bad_position = Fix2 {
            position: Vector2::new(f64::NAN, 2.0),
            ..good
        };
        assert!(matches!(
            bad_position.checked(),
            Err(PositioningError::NonFinite {
                what: "position estimate"
            })
        ));
        let bad_covariance = Fix2 {
            covariance: Matrix2::new(1.0, f64::INFINITY, 0.0, 1.0),
            ..good
        };
        assert!(matches!(
            bad_covariance.checked(),
            Err(PositioningError::NonFinite {
                what: "position covariance"
            })
        ));
    }
}
