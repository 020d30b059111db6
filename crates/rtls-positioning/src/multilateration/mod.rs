//! Multilateration: position fixes from ranges to anchors (UWB/radio TOA, ultrasonic time of
//! flight, RSSI-derived distances), in 2-D or 3-D.
//!
//! Anchors are `&[[f64; D]]` (m), fixes are [`crate::Fix<D>`] (`D = 2` or `3`). Every solver
//! validates its input the same way: too few anchors is
//! [`crate::PositioningError::Underdetermined`], collinear (2-D) / coplanar (3-D) anchors
//! [`crate::PositioningError::DegenerateGeometry`], two anchors at one position
//! [`crate::PositioningError::DuplicateAnchors`], NaN/∞ inputs
//! [`crate::PositioningError::NonFiniteEntry`] (naming the table, row and column), non-positive
//! variances [`crate::PositioningError::InvalidParameter`], length mismatches
//! [`crate::PositioningError::DimensionMismatch`]. Negative ranges (Wi-Fi FTM / RTT close to an
//! anchor) are noisy measurements like any other for [`gauss_newton`] and [`multilaterate`];
//! the closed forms that square ranges ([`linear_least_squares`],
//! [`weighted_linear_least_squares`], [`two_range`], [`toa_rss`]) refuse them with
//! [`crate::PositioningError::InvalidParameter`].
//!
//! - [`linear_least_squares`], [`weighted_linear_least_squares`] — closed form by
//!   reference differencing (seed 000's trilateration and seed 003's multi-point baselines);
//!   the weighted form has a first-order covariance.
//! - [`gauss_newton`] — the maximum-likelihood fix by weighted Gauss–Newton with
//!   Levenberg–Marquardt damping, with covariance `σ̂₀² (JᵀWJ)⁻¹`, GDOP and a χ² consistency
//!   statistic ([`GaussNewtonFix`]); started by the linear fix or a tracker's prediction.
//! - [`multilaterate`] — the fix a tracker's epoch uses: co-located anchors merged,
//!   Gauss–Newton from the guess or the linear fix, then from the weighted centroid, and the
//!   weighted centroid with an honest covariance as the last resort, the outcome named
//!   ([`FixMethod`]).
//! - [`horizontal_range`] — a slant range projected onto the tag's plane with its variance
//!   propagated (delta method, floored at the anchor's foot).
//! - [`toa_rss`] — seed 001's joint TOA + RSS fix through any
//!   [`crate::pathloss::PathLossModel`].
//! - [`two_range`] — seed 003's two-range fix: circle intersections, the ambiguity resolved by
//!   a prior's Mahalanobis distance.
//! - [`gdop`], [`dilution_of_precision`] — GDOP/HDOP/VDOP at a point, for GDOP maps.

mod dop;
mod gauss_newton;
mod linear;
mod projection;
mod robust;
mod solver;
mod toa_rss;
mod two_range;
pub(crate) mod validate;

pub use dop::{dilution_of_precision, gdop, Dop};
pub use gauss_newton::gauss_newton;
pub use linear::{linear_least_squares, weighted_linear_least_squares, ReferenceAnchor};
pub use projection::{horizontal_range, HorizontalRange};
pub use robust::{multilaterate, FixMethod, RangeFix, Start};
pub(crate) use solver::{levenberg_marquardt, variance_factor, Model, NormalEquations};
pub use solver::{GaussNewtonFix, GaussNewtonOptions, Initial};
pub use toa_rss::{toa_rss, RangeObservation, RssObservation};
pub use two_range::{two_range, CircleIntersection, TwoRangeSolution};
