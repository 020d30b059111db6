//! Covariance consistency: the NEES of each scored position and its summary ([`Consistency`]).

use rtls_estimation::stats::chi_square_quantile;

use super::statistics::percentile;
use super::Consistency;
use crate::error::Result;

/// Probability mass of the `d`-dimensional "1 σ" region, as for one dimension: `P(|x| ≤ σ)`.
const ONE_SIGMA_PROBABILITY: f64 = 0.682_689_492_137_086;

/// The NEES `ε = eᵀ P⁻¹ e` of a position error `e` (first `d` axes) against the reported
/// row-major covariance `covariance_m2` (`D × D`, `D ≥ d`; its top-left `d × d` block is used).
///
/// `None` when the block is not positive definite (a Cholesky factor `P = L Lᵀ` does not exist).
pub(super) fn nees(error_m: &[f64; 3], covariance_m2: &[f64], d: usize) -> Option<f64> {
    let size = if covariance_m2.len() == 9 { 3 } else { 2 };
    if d > size {
        return None;
    }
    let block = nalgebra::DMatrix::from_fn(d, d, |i, j| covariance_m2[i * size + j]);
    // P = L Lᵀ; ε = |L⁻¹ e|²
    let cholesky = block.cholesky()?;
    let whitened = cholesky
        .l()
        .solve_lower_triangular(&nalgebra::DVector::from_column_slice(&error_m[..d]))?;
    let value = whitened.norm_squared();
    value.is_finite().then_some(value)
}

impl Consistency {
    /// Summarises NEES values of `d`-dimensional errors; `not_positive_definite` counts the
    /// samples that had a covariance that could not be used.
    ///
    /// # Errors
    /// Only for `d` outside 1–3 (from the χ² quantile).
    pub(super) fn from_nees(values: &[f64], d: usize, not_positive_definite: usize) -> Result<Option<Self>> {
        if values.is_empty() {
            return Ok(None);
        }
        let gate_95 = chi_square_quantile(0.95, d as f64)?;
        let gate_68 = chi_square_quantile(ONE_SIGMA_PROBABILITY, d as f64)?;
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len() as f64;
        let share_inside = |gate: f64| sorted.partition_point(|&v| v <= gate) as f64 / n;
        Ok(Some(Self {
            count: sorted.len(),
            dimensions: d,
            // ε̄ = Σ εᵢ / n
            mean_nees: sorted.iter().sum::<f64>() / n,
            median_nees: percentile(&sorted, 0.5),
            inside_95: share_inside(gate_95),
            inside_68: share_inside(gate_68),
            not_positive_definite,
            // k² = ε₉₅ / χ²_d(0.95)
            covariance_scale_95: percentile(&sorted, 0.95) / gate_95,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nees_whitens_by_the_covariance_block() {
        // P = diag(4, 1): ε = 2²/4 + 1²/1 = 2
        let value = nees(&[2.0, 1.0, 9.0], &[4.0, 0.0, 0.0, 1.0], 2).unwrap();
        assert!((value - 2.0).abs() < 1e-12);
        // the 2-D block of a 3-D covariance
        let value = nees(&[2.0, 1.0, 9.0], &[4.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1e-9], 2).unwrap();
        assert!((value - 2.0).abs() < 1e-12);
        // correlated: P = [[2, 1], [1, 2]], e = (1, 1): ε = eᵀP⁻¹e = 2/3
        let value = nees(&[1.0, 1.0, 0.0], &[2.0, 1.0, 1.0, 2.0], 2).unwrap();
        assert!((value - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(nees(&[1.0, 1.0, 0.0], &[1.0, 2.0, 2.0, 1.0], 2), None);
        assert_eq!(nees(&[1.0, 1.0, 1.0], &[1.0, 0.0, 0.0, 1.0], 3), None);
    }

    #[test]
    fn gaussian_errors_with_their_own_covariance_are_consistent() {
        // e ~ N(0, I₂) on a deterministic low-discrepancy grid of the χ²(2) CDF: ε = −2 ln(1 − u)
        let values: Vec<f64> = (0..10_000)
            .map(|i| -2.0 * (1.0 - (i as f64 + 0.5) / 10_000.0).ln())
            .collect();
        let summary = Consistency::from_nees(&values, 2, 0).unwrap().unwrap();
        assert!((summary.mean_nees - 2.0).abs() < 0.01, "{summary:?}");
        assert!((summary.inside_95 - 0.95).abs() < 0.001, "{summary:?}");
        assert!((summary.inside_68 - ONE_SIGMA_PROBABILITY).abs() < 0.001, "{summary:?}");
        assert!((summary.median_nees - 2.0 * 2f64.ln()).abs() < 0.01, "{summary:?}");
        assert!((summary.covariance_scale_95 - 1.0).abs() < 0.01, "{summary:?}");
        // covariances 4 × too small: ε 4 × too large, and k² says so
        let overconfident: Vec<f64> = values.iter().map(|v| 4.0 * v).collect();
        let summary = Consistency::from_nees(&overconfident, 2, 0).unwrap().unwrap();
        assert!((summary.covariance_scale_95 - 4.0).abs() < 0.04, "{summary:?}");
        assert_eq!(Consistency::from_nees(&[], 2, 3).unwrap(), None);
    }
}
