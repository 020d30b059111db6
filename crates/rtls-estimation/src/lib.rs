//! # rtls-estimation
//!
//! Gaussian state estimation for real-time location systems: motion and measurement models,
//! the linear, extended and unscented Kalman filters, the Rauch–Tung–Striebel smoother,
//! Mahalanobis gating and the NIS/NEES consistency statistics.
//!
//! The crate has no I/O and no async runtime; without its default `std` feature it is
//! `no_std` + `alloc`.
//!
//! ## Layer
//! The bottom of the workspace: it owns state estimation (models, filters, smoothers, gating,
//! consistency) and imports no other rtls crate.
//!
//! ## Vocabulary
//! - [`Gaussian`] — a state value (mean, covariance, time stamp) owned by a track.
//! - [`motion`] — immutable transition strategies (`F`, `Q`, optional control `B`).
//! - [`measurement`] — immutable measurement strategies (`h`, `H`, `R`, residual).
//! - [`filter`] — KF, EKF, UKF: pure functions of (state, model, data) → new state, each
//!   update carrying its innovation, innovation covariance, gain and NIS.
//! - [`manoeuvre`] — seed 004's variable-dimension KF (CV ↔ CA) with manoeuvre detection.
//! - [`imm`] — interacting multiple models across CV, CA and coordinated-turn models of
//!   different state size, each run by a KF, EKF or UKF.
//! - [`adaptive`] — innovation-based adaptive measurement noise (a consistent covariance
//!   when the stated noise is too small).
//! - [`bias`] — a reader's measurement bias estimated alongside a track (self-calibration).
//! - [`aided`] — accelerometer-aided (seed 002) and odometry-aided (seed 004) tracking.
//! - [`smoother`] — RTS smoothing of a filtered sequence.
//! - [`stats`] — chi-square quantiles, gates and consistency intervals.
//!
//! ## Example: track a walker with position fixes
//! ```
//! use rtls_estimation::filter::KalmanFilter;
//! use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
//! use rtls_estimation::motion::{ConstantVelocity, ProcessNoise, NoiseGain};
//! use rtls_estimation::{Gaussian, Matrix, Vector};
//! use nalgebra::DVector;
//!
//! // Seed 000's ME-KF: CV model, T = 1 s, σ_w² = 5, σ_v² = 5 (here in 2-D).
//! let motion = ConstantVelocity::new(ProcessNoise::discrete(5.0, NoiseGain::kinematic()))?;
//! let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 5.0)?)?;
//! let kf = KalmanFilter::default();
//! let mut state = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::identity() * 100.0, 0.0)?;
//! for k in 1..=10 {
//!     let t = k as f64;
//!     let prior = kf.predict(&state, &motion, t)?;
//!     let fix = DVector::from_vec(vec![1.2 * t, 0.9 * t]);
//!     state = kf.update(&prior, &fixes, &fix)?.state;
//! }
//! assert!((state.mean()[1] - 1.2).abs() < 0.3);
//! # Ok::<(), rtls_estimation::EstimationError>(())
//! ```
#![cfg_attr(not(feature = "std"), no_std)]

extern crate alloc;

pub mod adaptive;
pub mod aided;
pub mod bias;
mod error;
pub mod filter;
mod gaussian;
pub mod imm;
pub mod manoeuvre;
pub(crate) mod math;
pub mod measurement;
pub mod motion;
pub mod smoother;
pub mod stats;

pub use error::{EstimationError, Result};
pub use gaussian::{Gaussian, Matrix, Vector};
pub use math::wrap_angle;
