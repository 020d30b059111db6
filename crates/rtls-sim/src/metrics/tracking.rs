//! Tracking metrics of the seed papers beyond plain Euclidean error: seed 000's per-axis error
//! rate and percentage of empty locations (PEL), and the filter-consistency statistics NEES
//! and NIS averaged over Monte Carlo runs.

use crate::error::{finite, Result, SimError};

/// Seed 000's error rate of one coordinate: `Err = |D − N| / N`, with `N` the true coordinate
/// and `D` the located one; an empty location (no fix) is `None` and counts as 100 %.
///
/// The rate is relative to the coordinate's distance from the site origin, so it is not
/// translation invariant: the same 0.5 m error is 50 % at 1 m from the mine entrance and 2 %
/// at 25 m. We report it because seed 000 does, beside errors in metres.
///
/// # Errors
/// [`SimError::InvalidParameter`] (`truth`) for `N = 0`, where the rate is undefined;
/// [`SimError::NonFinite`] for NaN/∞.
///
/// # Example
/// ```
/// use rtls_sim::metrics::error_rate;
/// assert!((error_rate(2.0, Some(2.3))? - 0.15).abs() < 1e-12);
/// assert_eq!(error_rate(2.0, None)?, 1.0); // empty location
/// assert!(error_rate(0.0, Some(0.1)).is_err());
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 §5.2 (`Err = |D − N| / N`; empty locations plotted as 100 %).
pub fn error_rate(truth: f64, located: Option<f64>) -> Result<f64> {
    finite(truth, "true coordinate")?;
    if truth == 0.0 {
        return Err(SimError::InvalidParameter {
            name: "truth",
            reason: "the error rate |D − N|/N is undefined for a true coordinate N = 0",
        });
    }
    match located {
        // empty location: 100 %
        None => Ok(1.0),
        // Err = |D − N| / |N|
        Some(d) => Ok((finite(d, "located coordinate")? - truth).abs() / truth.abs()),
    }
}

/// Mean error rate per axis over epochs with a location (empty locations excluded, as seed 000
/// does when it quotes its averages), for `D`-dimensional points.
///
/// Epochs whose true coordinate is 0 on an axis are skipped on that axis.
///
/// # Errors
/// [`SimError::LengthMismatch`] for different lengths; [`SimError::EmptyInput`] if an axis has no
/// usable epoch; [`SimError::NonFinite`] for NaN/∞.
///
/// # Example
/// ```
/// use rtls_sim::metrics::mean_axis_error_rates;
/// let truth = [[1.0, 2.0], [2.0, 4.0], [4.0, 8.0]];
/// let located = [Some([1.1, 2.0]), None, Some([4.0, 9.0])];
/// let rates = mean_axis_error_rates(&truth, &located)?;
/// assert!((rates[0] - 0.05).abs() < 1e-12 && (rates[1] - 0.0625).abs() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn mean_axis_error_rates<const D: usize>(truth: &[[f64; D]], located: &[Option<[f64; D]>]) -> Result<[f64; D]> {
    if truth.len() != located.len() {
        return Err(SimError::LengthMismatch {
            what: "located points vs truth",
            expected: truth.len(),
            found: located.len(),
        });
    }
    let mut rates = [0.0; D];
    for (axis, rate) in rates.iter_mut().enumerate() {
        let mut sum = 0.0;
        let mut count = 0usize;
        for (n, d) in truth.iter().zip(located) {
            let Some(d) = d else { continue };
            if n[axis] == 0.0 {
                continue;
            }
            sum += error_rate(n[axis], Some(d[axis]))?;
            count += 1;
        }
        if count == 0 {
            return Err(SimError::EmptyInput {
                what: "epochs with a location and a non-zero true coordinate",
            });
        }
        *rate = sum / count as f64;
    }
    Ok(rates)
}

/// Seed 000's percentage of empty locations: the share of epochs at which a method gave no
/// position (the tag was outside every reader's range), in percent.
///
/// # Errors
/// [`SimError::EmptyInput`] for no epochs.
///
/// # Example
/// ```
/// let fixes = [Some(1.0), None, Some(2.0), Some(3.0)];
/// assert_eq!(rtls_sim::metrics::empty_location_percentage(&fixes)?, 25.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 §5.3, Table 2 (PEL 6.7 % for RSSI and DV-Hop, 0 for ME-KF).
pub fn empty_location_percentage<T>(located: &[Option<T>]) -> Result<f64> {
    if located.is_empty() {
        return Err(SimError::EmptyInput { what: "epochs" });
    }
    let empty = located.iter().filter(|l| l.is_none()).count();
    Ok(100.0 * empty as f64 / located.len() as f64)
}

/// Average of a consistency statistic (NEES or NIS) over Monte Carlo runs at each epoch:
/// `ε̄_k = (1/M) Σ_m ε_k^(m)`; the filter is consistent if `M ε̄_k` lies in the χ² interval
/// with `M · dim` degrees of freedom (`rtls_estimation::stats::average_consistency_interval`).
///
/// # Errors
/// [`SimError::EmptyInput`] for no runs; [`SimError::LengthMismatch`] for runs of different
/// lengths; [`SimError::NonFinite`] for NaN/∞.
///
/// # Example
/// ```
/// let runs = vec![vec![1.0, 3.0], vec![3.0, 5.0]];
/// assert_eq!(rtls_sim::metrics::average_over_runs(&runs)?, vec![2.0, 4.0]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
/// Navigation*, Wiley 2001, §5.4.2 (average NEES and NIS tests).
pub fn average_over_runs(statistic: &[Vec<f64>]) -> Result<Vec<f64>> {
    let first = statistic.first().ok_or(SimError::EmptyInput { what: "runs" })?;
    let mut mean = vec![0.0; first.len()];
    for run in statistic {
        if run.len() != mean.len() {
            return Err(SimError::LengthMismatch {
                what: "epochs per run",
                expected: mean.len(),
                found: run.len(),
            });
        }
        for (sum, &value) in mean.iter_mut().zip(run) {
            *sum += finite(value, "consistency statistic")?;
        }
    }
    let m = statistic.len() as f64;
    mean.iter_mut().for_each(|v| *v /= m);
    Ok(mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_rate_is_relative_and_signless() {
        assert!((error_rate(-2.0, Some(-2.5)).unwrap() - 0.25).abs() < 1e-12);
        assert!(error_rate(1.0, Some(f64::NAN)).is_err());
        assert!(mean_axis_error_rates(&[[0.0]], &[Some([1.0])]).is_err());
        assert!(mean_axis_error_rates(&[[1.0]], &[]).is_err());
        assert!(empty_location_percentage::<f64>(&[]).is_err());
        assert!(average_over_runs(&[vec![1.0], vec![]]).is_err());
    }
}
