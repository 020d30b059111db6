//! # rtls-positioning
//!
//! Position fixes from raw RTLS measurements: the step between the reader layer (anchors that
//! measure ranges, range differences or signal strength) and the tracking filters of
//! `rtls-estimation`, which smooth fixes, bridge coverage gaps and predict.
//!
//! Every method returns a [`Fix2`]: a planar position (m) and a covariance (m²) that is the
//! method's own estimate of its error; [`calibrate_fix_noise`] measures that error at
//! surveyed points instead, as seed 002 does for its Kalman filter.
//!
//! The crate is numeric only: no I/O, no async, no global state, no randomness. Every
//! numerical failure is a [`PositioningError`] (never a panic, never a NaN in an output).
//!
//! ## What is here
//! - [`tdoa`] — time difference of arrival: Chan & Ho's closed-form estimator
//!   ([`tdoa::chan`], two-step WLS for ≥ 4 stations, the exact quadratic for 3) and seed 004's
//!   cyclic master station ([`tdoa::cyclic_reference`]).
//! - [`fingerprint`] — RSSI fingerprinting: a surveyed [`fingerprint::FingerprintDatabase`],
//!   global WKNN ([`fingerprint::Wknn`]) and seed 002's L-WKNN with a precomputed per-anchor
//!   spatial index ([`fingerprint::LocalWknn`]).
//! - [`calibrate_fix_noise`] — the observation covariance `U` of any method from its errors
//!   at known points.
//!
//! ## Planned
//! Multilateration from ranges (linear least squares, weighted Gauss–Newton /
//! Levenberg–Marquardt with covariance), TOA + RSS, Taylor-series TDOA refinement, path-loss
//! models and their calibration, centroid and DV-Hop (seed 000's baselines), GDOP maps.
//!
//! ## Example: a cellular TDOA fix with a rotating master station (seed 004)
//! ```
//! use nalgebra::Vector2;
//! use rtls_positioning::tdoa::{chan, cyclic_reference, differenced_range_covariance, range_differences_at};
//! let stations = [[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]];
//! let truth = Vector2::new(1200.0, 800.0);
//! for epoch in 0..4 {
//!     let master = cyclic_reference(epoch, stations.len())?;
//!     let r = range_differences_at(&stations, master, &truth)?;
//!     let q = differenced_range_covariance(&[900.0; 4], master)?; // σ = 30 m per TOA
//!     let fix = chan(&stations, master, &r, &q)?.fix;
//!     assert!((fix.position - truth).norm() < 1e-6);
//! }
//! # Ok::<(), rtls_positioning::PositioningError>(())
//! ```
//!
//! ## Example: L-WKNN on a fingerprint map (seed 002)
//! ```
//! use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
//! let db = FingerprintDatabase::new(
//!     vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]],
//!     vec![[0.0, 0.0], [10.0, 10.0]],
//!     vec![vec![-30.0, -70.0], vec![-55.0, -55.0], vec![-55.0, -55.0], vec![-70.0, -30.0]],
//! )?;
//! let locator = LocalWknn::default().build(&db)?;
//! let result = locator.locate(&[Some(-35.0), Some(-68.0)])?;
//! assert_eq!(result.neighbours[0].reference_point, 0);
//! # Ok::<(), rtls_positioning::PositioningError>(())
//! ```
//!
//! ## References
//! The project seeds 002 (L-WKNN) and 004 (cellular TDOA with Chan's estimator), see SPEC.md;
//! Y. T. Chan, K. C. Ho, "A simple and efficient estimator for hyperbolic location",
//! *IEEE Trans. Signal Processing* 42(8), 1994.

mod error;
pub mod fingerprint;
mod fix;
pub(crate) mod linalg;
pub mod tdoa;

pub use error::{PositioningError, Result};
pub use fix::{calibrate_fix_noise, Fix2};
