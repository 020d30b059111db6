//! Accuracy metrics of position estimates: Euclidean errors, their summary statistics,
//! percentiles and the empirical CDF, and per-axis RMSE.
//!
//! Percentiles use linear interpolation between order statistics (Hyndman & Fan type 7, the
//! default of NumPy, R and Excel's `PERCENTILE.INC`): for sorted values `x₀ ≤ … ≤ x_{n−1}` and
//! `p ∈ [0, 100]`, `h = (n − 1) p/100`, `Q(p) = x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋₊₁ − x_⌊h⌋)`.

mod tracking;

pub use tracking::{average_over_runs, empty_location_percentage, error_rate, mean_axis_error_rates};

use crate::error::{finite, Result, SimError};

/// Summary statistics of a set of non-negative position errors (m).
///
/// With errors `e₁ … e_n`:
/// `mean = (1/n) Σ eᵢ`, `rmse = √((1/n) Σ eᵢ²)`, `std = √((1/n) Σ (eᵢ − mean)²)` (population
/// form, so `rmse² = mean² + std²` exactly), percentiles by linear interpolation (module docs).
///
/// # Units
/// Everything in m (the unit of the errors).
///
/// # Example
/// ```
/// let s = rtls_sim::ErrorSummary::from_errors(&[1.0, 2.0, 3.0, 4.0, 10.0])?;
/// assert_eq!((s.count, s.mean_m, s.median_m, s.max_m), (5, 4.0, 3.0, 10.0));
/// assert!((s.p90_m - 7.6).abs() < 1e-12); // h = 3.6: 4 + 0.6 · (10 − 4)
/// assert!((s.rmse_m - 26f64.sqrt()).abs() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2, eq. (13) (mean error; erratum: the paper prints `√|X − X'|`, we use the
/// Euclidean distance `‖X − X'‖`), Fig. 3 (CDF, 90 % of errors < 3 m), Table 2 (mean and
/// standard deviation); R. J. Hyndman, Y. Fan, "Sample quantiles in statistical packages",
/// *The American Statistician* 50(4), 1996 (type 7).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSummary {
    /// Number of errors `n`.
    pub count: usize,
    /// Mean error `(1/n) Σ eᵢ`, m.
    pub mean_m: f64,
    /// Root-mean-square error `√((1/n) Σ eᵢ²)`, m.
    pub rmse_m: f64,
    /// Population standard deviation `√((1/n) Σ (eᵢ − mean)²)`, m.
    pub std_m: f64,
    /// Median (50th percentile), m.
    pub median_m: f64,
    /// 90th percentile, m.
    pub p90_m: f64,
    /// 95th percentile, m.
    pub p95_m: f64,
    /// Largest error, m.
    pub max_m: f64,
}

impl ErrorSummary {
    /// Summarises the errors `errors_m` (m, each finite and `≥ 0`).
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for no errors; [`SimError::NonFinite`] for a NaN/∞ error;
    /// [`SimError::InvalidParameter`] (`errors_m`) for a negative error.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::{ErrorSummary, SimError};
    /// let s = ErrorSummary::from_errors(&[3.0, 4.0])?;
    /// assert_eq!((s.mean_m, s.std_m, s.median_m), (3.5, 0.5, 3.5));
    /// assert!(matches!(ErrorSummary::from_errors(&[]), Err(SimError::EmptyInput { .. })));
    /// assert!(matches!(ErrorSummary::from_errors(&[1.0, f64::NAN]), Err(SimError::NonFinite { .. })));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §2 (mean error, CDF percentiles, standard deviation).
    pub fn from_errors(errors_m: &[f64]) -> Result<Self> {
        let sorted = sorted_errors(errors_m)?;
        let n = sorted.len() as f64;
        // mean = (1/n) Σ eᵢ
        let mean_m = sorted.iter().sum::<f64>() / n;
        // rmse = √((1/n) Σ eᵢ²)
        let rmse_m = (sorted.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        // std = √((1/n) Σ (eᵢ − mean)²)
        let std_m = (sorted.iter().map(|e| (e - mean_m) * (e - mean_m)).sum::<f64>() / n).sqrt();
        Ok(Self {
            count: sorted.len(),
            mean_m,
            rmse_m,
            std_m,
            median_m: percentile_of_sorted(&sorted, 50.0),
            p90_m: percentile_of_sorted(&sorted, 90.0),
            p95_m: percentile_of_sorted(&sorted, 95.0),
            max_m: sorted[sorted.len() - 1],
        })
    }

    /// Summarises the Euclidean errors of `estimates_m` against `truth_m`
    /// ([`euclidean_errors`] then [`ErrorSummary::from_errors`]).
    ///
    /// # Errors
    /// As [`euclidean_errors`].
    ///
    /// # Example
    /// ```
    /// let s = rtls_sim::ErrorSummary::from_positions(&[[0.0, 0.0], [1.0, 1.0]], &[[3.0, 4.0], [1.0, 1.0]])?;
    /// assert_eq!((s.mean_m, s.max_m), (2.5, 5.0));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §2, eq. (13) (Euclidean, per the SPEC erratum).
    pub fn from_positions(truth_m: &[[f64; 2]], estimates_m: &[[f64; 2]]) -> Result<Self> {
        Self::from_errors(&euclidean_errors(truth_m, estimates_m)?)
    }
}

/// Euclidean position errors `eᵢ = ‖x̂ᵢ − xᵢ‖` (m), pairing `truth_m[i]` with `estimates_m[i]`.
///
/// # Errors
/// [`SimError::EmptyInput`] for no positions; [`SimError::LengthMismatch`] if the slices differ
/// in length; [`SimError::NonFinite`] for a NaN/∞ coordinate.
///
/// # Example
/// ```
/// use rtls_sim::{euclidean_errors, SimError};
/// assert_eq!(euclidean_errors(&[[0.0, 0.0], [1.0, 1.0]], &[[3.0, 4.0], [1.0, 2.0]])?, vec![5.0, 1.0]);
/// assert!(matches!(
///     euclidean_errors(&[[0.0, 0.0]], &[[0.0, 0.0], [1.0, 1.0]]),
///     Err(SimError::LengthMismatch { expected: 1, found: 2, .. })
/// ));
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2, eq. (13), with the Euclidean distance (SPEC erratum: the paper prints
/// `√|X − X'|`).
pub fn euclidean_errors(truth_m: &[[f64; 2]], estimates_m: &[[f64; 2]]) -> Result<Vec<f64>> {
    check_pairs(truth_m, estimates_m)?;
    truth_m
        .iter()
        .zip(estimates_m)
        // eᵢ = ‖x̂ᵢ − xᵢ‖
        .map(|(x, x_hat)| finite((x_hat[0] - x[0]).hypot(x_hat[1] - x[1]), "positions"))
        .collect()
}

/// Per-axis root-mean-square error `[√((1/n) Σ (x̂ᵢ − xᵢ)²), √((1/n) Σ (ŷᵢ − yᵢ)²)]` (m).
///
/// The two squared components add up to the squared position RMSE.
///
/// # Errors
/// As [`euclidean_errors`].
///
/// # Example
/// ```
/// let rmse = rtls_sim::axis_rmse(&[[0.0, 0.0], [0.0, 0.0]], &[[3.0, 0.0], [-3.0, 4.0]])?;
/// assert_eq!(rmse[0], 3.0);
/// assert!((rmse[1] - 8f64.sqrt()).abs() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 001 §3 (RMSE per axis); seed 000 §4 (per-axis errors).
pub fn axis_rmse(truth_m: &[[f64; 2]], estimates_m: &[[f64; 2]]) -> Result<[f64; 2]> {
    check_pairs(truth_m, estimates_m)?;
    let n = truth_m.len() as f64;
    let mut sum_sq = [0.0, 0.0];
    for (x, x_hat) in truth_m.iter().zip(estimates_m) {
        for axis in 0..2 {
            // Σ (x̂ᵢ − xᵢ)²
            let d = x_hat[axis] - x[axis];
            sum_sq[axis] += d * d;
        }
    }
    // √(Σ/n)
    Ok([
        finite((sum_sq[0] / n).sqrt(), "positions")?,
        finite((sum_sq[1] / n).sqrt(), "positions")?,
    ])
}

/// The empirical CDF of the errors: one point `(e, F(e))` per distinct value in increasing
/// order, with `F(e) = #{eᵢ ≤ e}/n` (the height after the step at `e`).
///
/// # Errors
/// As [`ErrorSummary::from_errors`].
///
/// # Example
/// ```
/// let cdf = rtls_sim::empirical_cdf(&[2.0, 1.0, 2.0, 4.0])?;
/// assert_eq!(cdf, vec![(1.0, 0.25), (2.0, 0.75), (4.0, 1.0)]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2, Fig. 3 and 4 (CDF of the error distance).
pub fn empirical_cdf(errors_m: &[f64]) -> Result<Vec<(f64, f64)>> {
    let sorted = sorted_errors(errors_m)?;
    let n = sorted.len() as f64;
    let mut cdf: Vec<(f64, f64)> = Vec::with_capacity(sorted.len());
    for (i, &e) in sorted.iter().enumerate() {
        // F(e) = #{eᵢ ≤ e} / n (ties collapse to their last, highest point)
        let height = (i + 1) as f64 / n;
        match cdf.last_mut() {
            Some(last) if last.0 == e => last.1 = height,
            _ => cdf.push((e, height)),
        }
    }
    Ok(cdf)
}

/// The `percent`-th percentile (`0 ≤ percent ≤ 100`) of `values`, by linear interpolation
/// between order statistics: `h = (n − 1) p/100`, `Q = x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋₊₁ − x_⌊h⌋)`.
///
/// # Errors
/// [`SimError::EmptyInput`] for no values; [`SimError::NonFinite`] for a NaN/∞ value or
/// percent; [`SimError::InvalidParameter`] (`percent`) outside `[0, 100]`.
///
/// # Example
/// ```
/// let v = [10.0, 0.0, 30.0, 20.0];
/// assert_eq!(rtls_sim::percentile(&v, 50.0)?, 15.0); // h = 1.5
/// assert_eq!(rtls_sim::percentile(&v, 100.0)?, 30.0);
/// assert!((rtls_sim::percentile(&v, 90.0)? - 27.0).abs() < 1e-12); // h = 2.7
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Hyndman & Fan (1996), definition 7; seed 002 §2 ("90 % of errors < 3 m").
pub fn percentile(values: &[f64], percent: f64) -> Result<f64> {
    let percent = finite(percent, "percent")?;
    if !(0.0..=100.0).contains(&percent) {
        return Err(SimError::InvalidParameter {
            name: "percent",
            reason: "a percentile must lie in [0, 100]",
        });
    }
    if values.is_empty() {
        return Err(SimError::EmptyInput { what: "values" });
    }
    let mut sorted = values.to_vec();
    for &v in &sorted {
        finite(v, "values")?;
    }
    sorted.sort_by(f64::total_cmp);
    Ok(percentile_of_sorted(&sorted, percent))
}

/// Type-7 percentile of non-empty, sorted, finite values.
fn percentile_of_sorted(sorted: &[f64], percent: f64) -> f64 {
    // h = (n − 1) p / 100
    let h = (sorted.len() - 1) as f64 * percent / 100.0;
    let lower = h.floor() as usize;
    let upper = (lower + 1).min(sorted.len() - 1);
    // Q = x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋₊₁ − x_⌊h⌋)
    sorted[lower] + (h - h.floor()) * (sorted[upper] - sorted[lower])
}

/// Validates errors (non-empty, finite, ≥ 0) and returns them sorted.
fn sorted_errors(errors_m: &[f64]) -> Result<Vec<f64>> {
    if errors_m.is_empty() {
        return Err(SimError::EmptyInput { what: "errors" });
    }
    for &e in errors_m {
        finite(e, "errors")?;
        if e < 0.0 {
            return Err(SimError::InvalidParameter {
                name: "errors_m",
                reason: "a position error is a distance and cannot be negative",
            });
        }
    }
    let mut sorted = errors_m.to_vec();
    sorted.sort_by(f64::total_cmp);
    Ok(sorted)
}

/// Checks that truth and estimates are non-empty, equally long and finite.
fn check_pairs(truth_m: &[[f64; 2]], estimates_m: &[[f64; 2]]) -> Result<()> {
    if truth_m.is_empty() {
        return Err(SimError::EmptyInput {
            what: "truth positions",
        });
    }
    if estimates_m.len() != truth_m.len() {
        return Err(SimError::LengthMismatch {
            what: "estimates vs truth positions",
            expected: truth_m.len(),
            found: estimates_m.len(),
        });
    }
    for p in truth_m.iter().chain(estimates_m) {
        finite(p[0], "positions")?;
        finite(p[1], "positions")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn summary_matches_hand_computation() {
        // unsorted on purpose
        let s = ErrorSummary::from_errors(&[10.0, 2.0, 4.0, 1.0, 3.0]).unwrap();
        assert_eq!(s.count, 5);
        assert!(close(s.mean_m, 4.0)); // 20 / 5
        assert!(close(s.rmse_m, 26f64.sqrt())); // √(130/5)
        assert!(close(s.std_m, 10f64.sqrt())); // √((9 + 4 + 1 + 0 + 36)/5)
        assert!(close(s.median_m, 3.0)); // h = 2
        assert!(close(s.p90_m, 7.6)); // h = 3.6: 4 + 0.6 · 6
        assert!(close(s.p95_m, 8.8)); // h = 3.8: 4 + 0.8 · 6
        assert_eq!(s.max_m, 10.0);
    }

    #[test]
    fn single_error() {
        let s = ErrorSummary::from_errors(&[2.5]).unwrap();
        assert_eq!(
            (s.mean_m, s.rmse_m, s.std_m, s.median_m, s.p95_m, s.max_m),
            (2.5, 2.5, 0.0, 2.5, 2.5, 2.5)
        );
    }

    #[test]
    fn percentiles_match_hand_computation() {
        let v = [7.0, 1.0, 3.0, 5.0]; // sorted 1, 3, 5, 7
        for (p, expected) in [
            (0.0, 1.0),
            (25.0, 2.5),
            (50.0, 4.0),
            (62.5, 4.75),
            (90.0, 6.4),
            (100.0, 7.0),
        ] {
            // h = 3p/100: 25 → 0.75, 62.5 → 1.875, 90 → 2.7
            assert!(
                close(percentile(&v, p).unwrap(), expected),
                "p{p}: {}",
                percentile(&v, p).unwrap()
            );
        }
        assert_eq!(percentile(&[-3.0], 37.0).unwrap(), -3.0);
    }

    #[test]
    fn cdf_steps_collapse_ties() {
        let cdf = empirical_cdf(&[3.0, 1.0, 3.0, 3.0, 0.0]).unwrap();
        assert_eq!(cdf, vec![(0.0, 0.2), (1.0, 0.4), (3.0, 1.0)]);
    }

    #[test]
    fn euclidean_and_axis_errors() {
        let truth = [[0.0, 0.0], [10.0, 10.0], [-5.0, 2.0]];
        let est = [[3.0, 4.0], [10.0, 9.0], [-5.0, 2.0]];
        assert_eq!(euclidean_errors(&truth, &est).unwrap(), vec![5.0, 1.0, 0.0]);
        let rmse = axis_rmse(&truth, &est).unwrap();
        assert!(close(rmse[0], 3.0f64.sqrt()) && close(rmse[1], (17.0f64 / 3.0).sqrt()));
        let total = ErrorSummary::from_positions(&truth, &est).unwrap().rmse_m;
        assert!(close(rmse[0].powi(2) + rmse[1].powi(2), total * total));
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(matches!(
            ErrorSummary::from_errors(&[]),
            Err(SimError::EmptyInput { .. })
        ));
        assert!(matches!(
            ErrorSummary::from_errors(&[1.0, f64::NAN]),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            ErrorSummary::from_errors(&[f64::INFINITY]),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            ErrorSummary::from_errors(&[1.0, -0.1]),
            Err(SimError::InvalidParameter { .. })
        ));
        assert!(matches!(empirical_cdf(&[]), Err(SimError::EmptyInput { .. })));
        assert!(matches!(empirical_cdf(&[f64::NAN]), Err(SimError::NonFinite { .. })));
        assert!(matches!(percentile(&[], 50.0), Err(SimError::EmptyInput { .. })));
        assert!(matches!(
            percentile(&[1.0], 100.1),
            Err(SimError::InvalidParameter { name: "percent", .. })
        ));
        assert!(matches!(
            percentile(&[1.0], -1.0),
            Err(SimError::InvalidParameter { .. })
        ));
        assert!(matches!(percentile(&[1.0], f64::NAN), Err(SimError::NonFinite { .. })));
        assert!(matches!(
            percentile(&[1.0, f64::NAN], 50.0),
            Err(SimError::NonFinite { .. })
        ));
        let one = [[0.0, 0.0]];
        let two = [[0.0, 0.0], [1.0, 1.0]];
        assert!(matches!(
            euclidean_errors(&two, &one),
            Err(SimError::LengthMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
        assert!(matches!(axis_rmse(&one, &two), Err(SimError::LengthMismatch { .. })));
        assert!(matches!(euclidean_errors(&[], &[]), Err(SimError::EmptyInput { .. })));
        assert!(matches!(
            euclidean_errors(&one, &[[f64::NAN, 0.0]]),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            ErrorSummary::from_positions(&one, &two),
            Err(SimError::LengthMismatch { .. })
        ));
    }

    proptest! {
        #[test]
        fn summary_invariants(errors in prop::collection::vec(0.0..100.0f64, 1..200)) {
            let s = ErrorSummary::from_errors(&errors).unwrap();
            // rmse² = mean² + std² (population std)
            prop_assert!((s.rmse_m.powi(2) - (s.mean_m.powi(2) + s.std_m.powi(2))).abs() < 1e-9 * s.rmse_m.powi(2).max(1.0));
            let min = errors.iter().copied().fold(f64::INFINITY, f64::min);
            prop_assert!(min <= s.median_m && s.median_m <= s.p90_m && s.p90_m <= s.p95_m && s.p95_m <= s.max_m);
            prop_assert!(s.mean_m <= s.rmse_m + 1e-12);
            // the CDF ends at 1 and the fraction at or below p90 is at least 90 %
            let cdf = empirical_cdf(&errors).unwrap();
            prop_assert!(close(cdf[cdf.len() - 1].1, 1.0));
            let below = errors.iter().filter(|e| **e <= s.p90_m).count() as f64 / errors.len() as f64;
            prop_assert!(below >= 0.9 - 1.0 / errors.len() as f64);
        }
    }
}
