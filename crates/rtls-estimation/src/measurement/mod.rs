//! Measurement models: what a sensor reports as a function of the state.
//!
//! Measurement vectors are dynamically sized ([`DVector`]) because the set of anchors that
//! answer changes from one epoch to the next; a model value is cheap to build for each epoch
//! (e.g. [`Ranges`] over the anchors that answered). Every model gives its analytic Jacobian.

use nalgebra::{Const, DMatrix, DVector, Dyn, OMatrix};

use crate::error::Result;
use crate::gaussian::Vector;

mod fixed_selection;
mod noise_covariance;
mod path_loss;
mod position;
mod range;
mod rss;
mod speed_heading;
mod stacked;
mod tdoa;

pub use fixed_selection::FixedSelection;
pub use noise_covariance::NoiseCovariance;
pub use path_loss::{BreakpointForm, BreakpointPathLoss, LogDistancePathLoss, PathLoss};
pub use position::ComponentSelection;
pub use range::Ranges;
pub use rss::RssPathLoss;
pub use speed_heading::SpeedHeading;
pub use stacked::Stacked;
pub use tdoa::Tdoa;

/// Measurement Jacobian `H = ∂h/∂x`: one row per measurement component, `N` columns.
pub type MeasurementJacobian<const N: usize> = OMatrix<f64, Dyn, Const<N>>;

/// A (possibly nonlinear) measurement model `z = h(x) + v`, `v ~ N(0, R)`.
///
/// # Units
/// Each model documents the units of its components (m for ranges, dBm or dB for RSS, rad for
/// angles, m/s for speeds).
pub trait MeasurementModel<const N: usize> {
    /// Number of measurement components `m`.
    fn dim(&self) -> usize;
    /// Predicted measurement `h(x)` (length `m`).
    ///
    /// # Errors
    /// [`crate::EstimationError::SingularMeasurement`] where `h` is undefined at `x`.
    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>>;
    /// Jacobian `H = ∂h/∂x` at `x` (`m × N`).
    ///
    /// # Errors
    /// [`crate::EstimationError::SingularMeasurement`] where `H` is undefined at `x` (e.g. a
    /// range Jacobian at the anchor itself).
    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>>;
    /// Measurement noise covariance `R` (`m × m`, symmetric positive definite).
    fn noise_covariance(&self) -> &DMatrix<f64>;
    /// Residual `z − ẑ`; models with angle components override it to wrap angles into `(−π, π]`.
    fn residual(&self, z: &DVector<f64>, predicted: &DVector<f64>) -> DVector<f64> {
        z - predicted
    }
    /// Residuals `Zᵢ − ẑ` of every column of `points` (`m × k`) against `mean`, as an `m × k`
    /// matrix (the UKF's measurement deviations). The default applies [`Self::residual`] to
    /// each column, so angle-wrapping models are handled; models whose residual is a plain
    /// subtraction override it with [`subtract_from_columns`], which allocates once.
    fn residuals(&self, points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
        let mut deviations = DMatrix::zeros(points.nrows(), points.ncols());
        for (i, column) in points.column_iter().enumerate() {
            deviations.set_column(i, &self.residual(&column.into_owned(), mean));
        }
        deviations
    }
    /// Weighted mean `Σ wᵢ zᵢ` of measurement sigma points (columns of `points`, `m × k`);
    /// models with angle components override it with a circular mean.
    fn weighted_mean(&self, points: &DMatrix<f64>, weights: &[f64]) -> DVector<f64> {
        let mut mean = DVector::zeros(points.nrows());
        for (column, &w) in points.column_iter().zip(weights) {
            mean.axpy(w, &column, 1.0);
        }
        mean
    }
}

/// `Zᵢ − ẑ` for every column `Zᵢ` of `points`: the residuals of a model without angles.
#[must_use]
pub fn subtract_from_columns(points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
    let mut deviations = points.clone();
    for mut column in deviations.column_iter_mut() {
        // Zᵢ − ẑ
        column -= mean;
    }
    deviations
}

/// A linear measurement model `z = H x + v` with constant `H`.
///
/// Linear models are also [`MeasurementModel`]s (`h(x) = H x`, Jacobian `H`).
pub trait LinearMeasurementModel<const N: usize>: MeasurementModel<N> {
    /// The measurement matrix `H` (`m × N`).
    fn matrix(&self) -> &MeasurementJacobian<N>;
}
