//! Helpers shared by the experiments: errors pooled over Monte Carlo runs, RMSE over time,
//! CDF series, and matrix conversions for the PCRB.

use nalgebra::{DMatrix, SMatrix};

use crate::error::{Result, SimError};
use crate::report::{Series, SeriesStyle};
use rtls_sim::metrics::{average_over_runs, empirical_cdf, euclidean_errors};

/// Squared Euclidean errors `‖x̂_k − x_k‖²` per epoch (from [`euclidean_errors`]).
///
/// # Errors
/// As [`euclidean_errors`].
pub fn squared_errors(truth_m: &[[f64; 2]], estimates_m: &[[f64; 2]]) -> Result<Vec<f64>> {
    Ok(euclidean_errors(truth_m, estimates_m)?
        .into_iter()
        .map(|e| e * e)
        .collect())
}

/// RMSE at each epoch over the runs: `√((1/M) Σ_m e²_{m,k})` (the papers' "RMSE over time").
///
/// # Errors
/// As [`average_over_runs`].
pub fn rmse_over_time(squared_errors_per_run: &[Vec<f64>]) -> Result<Vec<f64>> {
    Ok(average_over_runs(squared_errors_per_run)?
        .into_iter()
        .map(f64::sqrt)
        .collect())
}

/// RMSE pooled over every run and epoch: `√((1/MK) Σ_m Σ_k e²_{m,k})`.
///
/// # Errors
/// [`SimError::EmptyInput`] for no errors.
pub fn pooled_rmse(squared_errors_per_run: &[Vec<f64>]) -> Result<f64> {
    let count: usize = squared_errors_per_run.iter().map(Vec::len).sum();
    if count == 0 {
        return Err(SimError::EmptyInput { what: "errors" });
    }
    let sum: f64 = squared_errors_per_run.iter().flatten().sum();
    Ok((sum / count as f64).sqrt())
}

/// At most `max_points` points of `points`, evenly spaced, always keeping the last.
#[must_use]
pub fn decimate(points: Vec<[f64; 2]>, max_points: usize) -> Vec<[f64; 2]> {
    if points.len() <= max_points || max_points < 2 {
        return points;
    }
    let step = (points.len() - 1) as f64 / (max_points - 1) as f64;
    (0..max_points)
        .map(|i| points[((i as f64 * step).round() as usize).min(points.len() - 1)])
        .collect()
}

/// The empirical CDF of `errors_m` as a line series (at most 400 points).
///
/// # Errors
/// As [`empirical_cdf`].
pub fn cdf_series(label: &str, errors_m: &[f64]) -> Result<Series> {
    let points = empirical_cdf(errors_m)?.into_iter().map(|(e, p)| [e, p]).collect();
    Ok(Series::new(label, SeriesStyle::Line, decimate(points, 400)))
}

/// A fixed-size matrix as a dynamic one (for the PCRB recursion).
#[must_use]
pub fn dynamic<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_column_slice(R, C, m.as_slice())
}

/// `value` formatted with `decimals` decimals, for notes.
#[must_use]
pub fn fmt(value: f64, decimals: usize) -> String {
    format!("{value:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooled_and_per_epoch_rmse() {
        let runs = vec![vec![1.0, 4.0], vec![9.0, 16.0]];
        assert_eq!(rmse_over_time(&runs).unwrap(), vec![5f64.sqrt(), 10f64.sqrt()]);
        assert!((pooled_rmse(&runs).unwrap() - 7.5f64.sqrt()).abs() < 1e-12);
        assert!(pooled_rmse(&[]).is_err());
        assert_eq!(squared_errors(&[[0.0, 0.0]], &[[3.0, 4.0]]).unwrap(), vec![25.0]);
        assert!(squared_errors(&[[0.0, 0.0]], &[[f64::NAN, 4.0]]).is_err());
        let d = decimate((0..1000).map(|i| [i as f64, 0.0]).collect(), 10);
        assert_eq!((d.len(), d[9][0]), (10, 999.0));
    }
}
