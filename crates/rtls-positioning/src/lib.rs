//! # rtls-positioning
//!
//! Position fixes from raw RTLS measurements: the step between the reader layer (anchors that
//! measure ranges, range differences or signal strength) and the tracking filters of
//! `rtls-estimation`, which smooth fixes, bridge coverage gaps and predict.
//!
//! Every method returns a [`Fix2`] (or a [`Fix3`] in space): a position (m) and a covariance
//! (m²) that is the method's own estimate of its error; [`calibrate_fix_noise`] measures that
//! error at surveyed points instead, as seed 002 does for its Kalman filter.
//!
//! The crate is numeric only: no I/O, no async, no global state, no randomness. Every
//! numerical failure is a [`PositioningError`] (never a panic, never a NaN in an output).
//!
//! ## Layer
//! It owns the fix methods and their covariances and may import `rtls-estimation` only; the
//! engine, the simulators and the experiments build on it.
//!
//! ## What is here
//! - [`tdoa`] — time difference of arrival in the plane and in space: Chan & Ho's closed-form
//!   estimator ([`tdoa::chan`], two-step WLS for ≥ 4 stations in the plane and ≥ 5 in space,
//!   the exact quadratic for 3 / 4), its Taylor / Levenberg–Marquardt refinement to the
//!   maximum-likelihood fix ([`tdoa::taylor`], [`tdoa::chan_taylor`]) and seed 004's cyclic
//!   master station ([`tdoa::cyclic_reference`]).
//! - [`pathloss`] — path-loss laws ([`pathloss::LogDistance`] of seed 002, seed 001's UWB
//!   [`pathloss::Breakpoint`] law with its erratum), RSSI → range inversion (median or
//!   mean-unbiased) with the range standard deviation, and least-squares calibration of
//!   `ρ_T`, `η`, `σ_X` with standard errors (one model, per anchor, shared, shared exponent).
//! - [`multilateration`] — fixes from ranges (TOA, ultrasonic, RSSI-derived) in 2-D and 3-D:
//!   linear least squares by reference differencing (weighted, with covariance), the
//!   maximum-likelihood weighted Gauss–Newton / Levenberg–Marquardt fix with covariance
//!   `(JᵀWJ)⁻¹`, GDOP and a χ² consistency statistic ([`multilateration::gauss_newton`]),
//!   seed 001's joint TOA + RSS fix through any path-loss law ([`multilateration::toa_rss`]),
//!   seed 003's two-range fix with prior-based disambiguation ([`multilateration::two_range`])
//!   and GDOP/HDOP/VDOP for GDOP maps ([`multilateration::gdop`]).
//! - [`range_free`] — centroid and weighted centroid (RSSI or range weights) and DV-Hop over a
//!   multi-hop network ([`range_free::DvHop`]), seed 000's range-free baselines.
//! - [`fingerprint`] — RSSI fingerprinting: a surveyed [`fingerprint::FingerprintDatabase`]
//!   (absent readings explicit, floors and buildings, access-point positions estimated when
//!   unknown), signal spaces ([`fingerprint::SignalSpace`]: dBm / exponential / powed,
//!   Euclidean / Manhattan / Sørensen), global KNN and WKNN with building and floor votes
//!   ([`fingerprint::Knn`]) and seed 002's L-WKNN with a precomputed per-anchor spatial index
//!   ([`fingerprint::LocalWknn`]).
//! - [`gnss`] — GNSS pseudoranges: WGS-84 geodetic ↔ ECEF ↔ local ENU, the Earth-rotation
//!   (Sagnac) correction, elevation-dependent noise and the pseudorange point solver (position
//!   and receiver clock bias, an optional clock prior, joint covariance, DOP and RAIM-style
//!   fault exclusion).
//! - [`calibrate_fix_noise`] — the observation covariance `U` of any method from its errors
//!   at known points.
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
//! use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, LocalWknn, SignalSpace};
//! let db = FingerprintDatabase::new(
//!     vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]],
//!     vec![[0.0, 0.0], [10.0, 10.0]],
//!     vec![vec![-30.0, -70.0], vec![-55.0, -55.0], vec![-55.0, -55.0], vec![-70.0, -30.0]],
//! )?;
//! let index = FingerprintIndex::new(db, SignalSpace::default())?; // Euclidean on dBm
//! let locator = LocalWknn::default().build(&index)?;
//! let result = locator.locate(&[Some(-35.0), Some(-68.0)])?;
//! assert_eq!(result.neighbours[0].reference_point, 0);
//! # Ok::<(), rtls_positioning::PositioningError>(())
//! ```
//!
//! ## Example: a 3-D UWB fix that flags an NLOS range
//! ```
//! use nalgebra::Vector3;
//! use rtls_positioning::multilateration::{gauss_newton, GaussNewtonOptions, Initial};
//! let anchors = [[0.0, 0.0, 3.0], [20.0, 0.0, 2.5], [0.0, 15.0, 3.0], [20.0, 15.0, 0.5], [10.0, 7.0, 0.2]];
//! let truth = Vector3::new(6.0, 9.0, 1.5);
//! let mut ranges: Vec<f64> = anchors.iter().map(|a| (truth - Vector3::from(*a)).norm()).collect();
//! let variances = [0.01; 5]; // σ = 10 cm
//! let fix = gauss_newton(&anchors, &ranges, &variances, Initial::Linear, &GaussNewtonOptions::default())?;
//! assert!((fix.fix.position - truth).norm() < 1e-6 && fix.chi_square < 1e-9);
//! ranges[1] += 2.0; // a wall delays anchor 1's first path by 2 m
//! let fix = gauss_newton(&anchors, &ranges, &variances, Initial::Linear, &GaussNewtonOptions::default())?;
//! assert_eq!(fix.degrees_of_freedom, 2);
//! assert!(fix.chi_square > 9.21); // above the χ²(2) 99 % quantile: reject or down-weight
//! # Ok::<(), rtls_positioning::PositioningError>(())
//! ```
//!
//! ## References
//! The project seeds 000 (RSSI trilateration and DV-Hop baselines), 001 (joint TOA + RSS), 002
//! (L-WKNN), 003 (multi- and two-point range multilateration) and 004 (cellular TDOA with
//! Chan's estimator), see SPEC.md;
//! Y. T. Chan, K. C. Ho, "A simple and efficient estimator for hyperbolic location",
//! *IEEE Trans. Signal Processing* 42(8), 1994.

mod error;
pub mod fingerprint;
mod fix;
pub mod gnss;
pub(crate) mod linalg;
pub mod multilateration;
pub mod pathloss;
pub mod range_free;
pub mod tdoa;

pub use error::{PositioningError, Result};
pub use fix::{calibrate_fix_noise, Fix, Fix2, Fix3, PLAUSIBLE_EXTENT_FACTOR};
