//! Chi-square distribution, Mahalanobis validation gates and NIS/NEES consistency intervals.
//!
//! Under a correct linear-Gaussian model, the normalised innovation squared (NIS)
//! `d² = νᵀ S⁻¹ ν` of an `m`-dimensional measurement is χ²(m)-distributed, and so is the
//! normalised estimation error squared (NEES) `(x − x̂)ᵀ P⁻¹ (x − x̂)` of an `n`-dimensional
//! state with `m = n`. This module provides what is needed to use that fact:
//!
//! - [`chi_square_cdf`] and [`chi_square_quantile`] — the distribution function and its inverse,
//!   accurate to about `1e-12` relative, for any real number of degrees of freedom;
//! - [`ChiSquareGate`] — the validation gate `d² ≤ χ²_P(m)` used for outlier rejection and
//!   data association;
//! - [`average_consistency_interval`] — the two-sided acceptance interval for an average of
//!   χ² statistics (average NEES over Monte Carlo runs, time-averaged NIS).
//!
//! Everything is pure arithmetic on `f64` and works without `std`. Invalid input and numerical
//! failure are reported as [`EstimationError`](crate::EstimationError); no function here panics or returns NaN.
//!
//! # References
//! - W. H. Press, S. A. Teukolsky, W. T. Vetterling, B. P. Flannery, *Numerical Recipes*,
//!   3rd ed., Cambridge University Press, 2007, §6.2 (incomplete gamma function).
//! - Y. Bar-Shalom, X.-R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley, 2001, §2.4 and §5.4.

mod chi_square;
mod consistency;
mod gamma;

pub use chi_square::{chi_square_cdf, chi_square_quantile};
pub use consistency::{average_consistency_interval, ChiSquareGate, ConsistencyInterval};

#[cfg(test)]
mod test_support {
    use crate::math::abs;

    /// Asserts `|actual − expected| ≤ tolerance · |expected|`.
    pub(crate) fn assert_relative(actual: f64, expected: f64, tolerance: f64, what: &str) {
        let error = abs(actual - expected) / abs(expected);
        assert!(
            error <= tolerance,
            "{what}: got {actual:e}, expected {expected:e}, relative error {error:e}"
        );
    }
}
