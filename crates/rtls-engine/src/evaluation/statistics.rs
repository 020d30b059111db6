//! Error statistics: RMSE, mean, type-7 percentiles, maximum.

use super::ErrorStatistics;
use crate::error::{EngineError, Result};

impl ErrorStatistics {
    /// Summarises position errors, m (in any order).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] when `errors_m` is empty or holds a negative or
    /// non-finite value.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::evaluation::ErrorStatistics;
    ///
    /// let stats = ErrorStatistics::from_errors(&[3.0, 1.0, 2.0, 10.0, 4.0])?;
    /// assert_eq!(stats.median_m, 3.0);
    /// assert!((stats.p90_m - 7.6).abs() < 1e-12); // h = 0.9·4 = 3.6: 4 + 0.6·(10 − 4)
    /// assert_eq!(stats.max_m, 10.0);
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn from_errors(errors_m: &[f64]) -> Result<Self> {
        if errors_m.is_empty() {
            return Err(EngineError::InvalidParameter {
                name: "errors_m",
                reason: "is empty; statistics need at least one error",
            });
        }
        if errors_m.iter().any(|e| !(e.is_finite() && *e >= 0.0)) {
            return Err(EngineError::InvalidParameter {
                name: "errors_m",
                reason: "holds a negative or non-finite value; errors are distances in m",
            });
        }
        let mut sorted = errors_m.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len() as f64;
        // RMSE = √(Σ eᵢ² / n)
        let rmse_m = (sorted.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let mean_m = sorted.iter().sum::<f64>() / n;
        Ok(Self {
            count: sorted.len(),
            rmse_m,
            mean_m,
            median_m: percentile(&sorted, 0.5),
            p90_m: percentile(&sorted, 0.9),
            p95_m: percentile(&sorted, 0.95),
            max_m: sorted[sorted.len() - 1],
        })
    }
}

/// The `p`-quantile (`0 ≤ p ≤ 1`) of non-empty ascending `sorted` values, interpolating linearly
/// between order statistics (Hyndman & Fan type 7): `h = (n − 1)·p`, `x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋₊₁ − x_⌊h⌋)`.
pub(super) fn percentile(sorted: &[f64], p: f64) -> f64 {
    debug_assert!(!sorted.is_empty() && (0.0..=1.0).contains(&p));
    let h = (sorted.len() - 1) as f64 * p;
    let lower = h.floor() as usize;
    let fraction = h - h.floor();
    match sorted.get(lower + 1) {
        Some(next) => sorted[lower] + fraction * (next - sorted[lower]),
        None => sorted[lower],
    }
}
