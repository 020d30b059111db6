//! Mahalanobis validation gates and consistency intervals for averaged χ² statistics.

use super::chi_square::{check_probability, chi_square_quantile};
use crate::error::{EstimationError, Result};

/// Mahalanobis validation gate: accepts a measurement when its normalised innovation squared
/// lies below the chi-square quantile of the gate probability.
///
/// For an innovation `ν = z − ẑ` of dimension `m` with covariance `S = H P Hᵀ + R`,
///
/// ```text
/// d² = νᵀ S⁻¹ ν  ~  χ²(m)      under the model,
/// ```
///
/// so the gate `d² ≤ γ` with `γ = χ²_P(m)` keeps a correctly modelled measurement with
/// probability `P` (the gate probability `P_G`) and rejects the rest as outliers or as
/// belonging to another target. Typical gate probabilities are 0.95–0.999.
///
/// # Example
/// ```
/// use rtls_estimation::stats::ChiSquareGate;
/// let gate = ChiSquareGate::new(0.99)?;
/// // 2-D position fix: γ = χ²_0.99(2) ≈ 9.21.
/// assert!((gate.threshold(2)? - 9.21034037197618).abs() < 1e-10);
/// assert!(gate.accepts(4.0, 2)?);
/// assert!(!gate.accepts(12.0, 2)?);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
///   Navigation*, Wiley, 2001, §2.4.
/// - S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House,
///   1999, §6.3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiSquareGate {
    probability: f64,
}

impl ChiSquareGate {
    /// Builds a gate of probability `P_G = probability` (e.g. `0.99`).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] unless `0 < probability < 1`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::stats::ChiSquareGate;
    /// let gate = ChiSquareGate::new(0.95)?;
    /// assert_eq!(gate.probability(), 0.95);
    /// assert!(ChiSquareGate::new(1.0).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    ///   Navigation*, Wiley, 2001, §2.4.
    pub fn new(probability: f64) -> Result<Self> {
        check_probability(probability, "probability")?;
        Ok(Self { probability })
    }

    /// The gate probability `P_G`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::stats::ChiSquareGate;
    /// assert_eq!(ChiSquareGate::new(0.99)?.probability(), 0.99);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// - S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, 1999, §6.3.
    #[inline]
    pub fn probability(&self) -> f64 {
        self.probability
    }

    /// Gate threshold `γ = χ²_{P_G}(m)` for an `m = dof`-dimensional innovation.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `dof == 0` (or, not expected, if the quantile
    /// iteration fails).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::stats::ChiSquareGate;
    /// let gate = ChiSquareGate::new(0.95)?;
    /// assert!((gate.threshold(1)? - 3.841458820694124).abs() < 1e-10);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    ///   Navigation*, Wiley, 2001, §2.4.
    pub fn threshold(&self, dof: usize) -> Result<f64> {
        if dof == 0 {
            return Err(EstimationError::InvalidParameter {
                name: "dof",
                reason: "the innovation dimension must be at least 1",
            });
        }
        chi_square_quantile(self.probability, dof as f64)
    }

    /// Whether a measurement with normalised innovation squared `nis = νᵀ S⁻¹ ν` of dimension
    /// `dof` passes the gate: `nis ≤ χ²_{P_G}(dof)`.
    ///
    /// A slightly negative `nis` (rounding) is accepted.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] if `nis` is NaN or infinite;
    /// [`EstimationError::InvalidParameter`] if `dof == 0`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::stats::ChiSquareGate;
    /// let gate = ChiSquareGate::new(0.95)?;
    /// assert!(gate.accepts(3.8, 1)?);
    /// assert!(!gate.accepts(3.9, 1)?);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// - S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, 1999, §6.3.
    pub fn accepts(&self, nis: f64, dof: usize) -> Result<bool> {
        if !nis.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "normalised innovation squared",
            });
        }
        Ok(nis <= self.threshold(dof)?)
    }
}

/// Two-sided acceptance interval `[lower, upper]` for an average of chi-square statistics,
/// as returned by [`average_consistency_interval`].
///
/// # Example
/// ```
/// use rtls_estimation::stats::ConsistencyInterval;
/// let interval = ConsistencyInterval { lower: 3.25, upper: 4.82 };
/// assert!(interval.contains(4.0));
/// assert!(!interval.contains(5.0));
/// ```
///
/// # References
/// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
///   Navigation*, Wiley, 2001, §5.4.2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConsistencyInterval {
    /// Lower end `r₁` of the interval.
    pub lower: f64,
    /// Upper end `r₂` of the interval.
    pub upper: f64,
}

impl ConsistencyInterval {
    /// Whether `lower ≤ value ≤ upper` (false for NaN).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::stats::average_consistency_interval;
    /// let interval = average_consistency_interval(4, 50, 0.95)?;
    /// assert!(interval.contains(4.0));
    /// assert!(!interval.contains(f64::NAN));
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    ///   Navigation*, Wiley, 2001, §5.4.2.
    #[inline]
    pub fn contains(&self, value: f64) -> bool {
        self.lower <= value && value <= self.upper
    }
}

/// Two-sided `confidence` interval for the average of `samples` independent χ²(`dim`)
/// statistics — the average NEES over `M` Monte Carlo runs, or the time-averaged NIS.
///
/// With `ε̄ = (1/M) Σᵢ εᵢ`, `εᵢ ~ χ²(n)` independent, `M·ε̄ ~ χ²(M·n)`, so a consistent
/// estimator has `ε̄` inside
///
/// ```text
/// [r₁, r₂] = [ χ²_{(1−c)/2}(M·n) / M ,  χ²_{(1+c)/2}(M·n) / M ]
/// ```
///
/// with probability `c` (Bar-Shalom et al. 2001, eq. 5.4.2-6). Here `n = dim`, `M = samples`,
/// `c = confidence`. The interval shrinks around `n` as `M` grows.
///
/// # Errors
/// [`EstimationError::InvalidParameter`] if `dim == 0`, `samples == 0`, `confidence` is not
/// strictly between 0 and 1, or `dim · samples` exceeds `10¹⁰`.
///
/// # Example
/// ```
/// use rtls_estimation::stats::average_consistency_interval;
/// // Average NEES of a 4-state filter over 50 Monte Carlo runs, 95 % two-sided.
/// let interval = average_consistency_interval(4, 50, 0.95)?;
/// assert!((interval.lower - 3.2545596500369256).abs() < 1e-10);
/// assert!((interval.upper - 4.821157910126218).abs() < 1e-10);
/// assert!(interval.contains(4.0));
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
///   Navigation*, Wiley, 2001, §5.4.2, eq. 5.4.2-6.
pub fn average_consistency_interval(dim: usize, samples: usize, confidence: f64) -> Result<ConsistencyInterval> {
    if dim == 0 {
        return Err(EstimationError::InvalidParameter {
            name: "dim",
            reason: "the dimension of the chi-square statistic must be at least 1",
        });
    }
    if samples == 0 {
        return Err(EstimationError::InvalidParameter {
            name: "samples",
            reason: "at least one sample (Monte Carlo run or time step) is needed",
        });
    }
    check_probability(confidence, "confidence")?;
    let m = samples as f64;
    let total_dof = m * dim as f64;
    // Tail probabilities (1 − c)/2 and (1 + c)/2 of the two-sided interval.
    let alpha_lower = 0.5 * (1.0 - confidence);
    let alpha_upper = 0.5 * (1.0 + confidence);
    let lower = chi_square_quantile(alpha_lower, total_dof)? / m;
    let upper = chi_square_quantile(alpha_upper, total_dof)? / m;
    Ok(ConsistencyInterval { lower, upper })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::test_support::assert_relative;

    #[test]
    fn gate_at_95_percent_one_dof() {
        let gate = ChiSquareGate::new(0.95).unwrap();
        assert_relative(gate.threshold(1).unwrap(), 3.841458820694124, 1e-10, "gate threshold");
        assert!(gate.accepts(3.8, 1).unwrap());
        assert!(!gate.accepts(3.9, 1).unwrap());
        assert!(gate.accepts(0.0, 1).unwrap());
        assert!(gate.accepts(3.9, 2).unwrap());
    }

    #[test]
    fn consistency_interval_matches_scipy() {
        // chi2.ppf(0.025, 200) / 50 and chi2.ppf(0.975, 200) / 50.
        let interval = average_consistency_interval(4, 50, 0.95).unwrap();
        assert_relative(interval.lower, 3.2545596500369256, 1e-10, "lower end");
        assert_relative(interval.upper, 4.821157910126218, 1e-10, "upper end");
        assert!(interval.contains(4.0));
        assert!(!interval.contains(3.2));
        assert!(!interval.contains(4.9));
        assert!(!interval.contains(f64::NAN));
    }
}
