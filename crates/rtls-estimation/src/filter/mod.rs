//! Filters: the linear Kalman filter, the extended and the unscented Kalman filter, and a
//! structure-exploiting constant-velocity filter for position fixes.
//!
//! Every filter is an immutable strategy holding only its configuration: `predict` and
//! `update` take a [`Gaussian`](crate::Gaussian) state and return a new one, so one filter
//! value serves every track. Each update returns an [`Updated`] carrying the innovation `ν`,
//! its covariance `S`, the gain `K` and the NIS `νᵀ S⁻¹ ν`, so gating, manoeuvre detection
//! and consistency checks reuse them instead of recomputing.
//!
//! Predict-only steps (coasting through a coverage gap) are simply `predict` calls with no
//! `update`; the covariance grows with the process noise.

mod consider;
mod consider_scalar;
mod cv_axes;
mod ekf;
mod fixed_update;
mod gaussian_filter;
mod kf;
mod predict;
mod ukf;
mod update;

pub use consider::{carry_cross_covariance, consider_update, ConsiderUpdated};
pub use consider_scalar::consider_update_scalar;
pub use cv_axes::{CvAxis, DecoupledCvFilter, DecoupledCvState};
pub use ekf::ExtendedKalmanFilter;
pub use fixed_update::FixedUpdated;
pub use gaussian_filter::GaussianFilter;
pub use kf::KalmanFilter;
pub use ukf::{SigmaPointParameters, UnscentedKalmanFilter};
pub use update::{CovarianceUpdate, Gain, Updated};

pub(crate) use ukf::{sigma_points, weighted_moments};
