//! RSSI fingerprinting: k-nearest neighbours in signal space over a surveyed fingerprint map,
//! globally ([`Knn`]: KNN and WKNN) or restricted to reference points near the strongest
//! anchors ([`LocalWknn`], seed 002's L-WKNN), with building and floor classification.
//!
//! The pieces:
//! - [`FingerprintDatabase`] (from a [`Survey`]): reference points with optional floor and
//!   building labels, anchors with known, estimated ([`FingerprintDatabase::with_estimated_anchors`])
//!   or unknown positions, and the heard readings only: an absent reading is absent, not a
//!   magic RSSI;
//! - [`SignalSpace`]: how readings are represented ([`SignalRepresentation`]; "not heard" is
//!   `ψ = 0` in all of them) and compared ([`SignalDistance`]);
//! - [`FingerprintIndex`]: the database represented once in a signal space, which the matchers
//!   query;
//! - [`LeaveOneOut`] ([`Knn::leave_one_out`]): the matcher's errors on its own map, each
//!   reference point located by the others, and the fix-noise floor that makes the reported
//!   95 % ellipses hold 95 % of them.
//!
//! A query is the measured RSSI vector `&[Option<f64>]` (dBm), one entry per database anchor;
//! `None` means the anchor was not heard. A query that hears nothing is
//! [`PositioningError::NoCommonAnchors`]; one that shares no heard anchor with any candidate
//! reference point is [`PositioningError::NoFingerprintMatch`].
//!
//! # Example: multi-floor Wi-Fi with unknown access-point positions
//! ```
//! use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalSpace, Survey};
//! let survey = Survey {
//!     reference_points_m: vec![[0.0, 0.0], [10.0, 0.0], [0.0, 0.0], [10.0, 0.0]],
//!     floors: Some(vec![0, 0, 1, 1]),
//!     buildings: None,
//!     anchor_count: 3,
//!     anchors_m: None,
//!     readings_dbm: vec![
//!         vec![(0, -40.0), (1, -70.0)],
//!         vec![(0, -70.0), (1, -45.0)],
//!         vec![(2, -42.0), (0, -85.0)],
//!         vec![(2, -60.0), (1, -88.0)],
//!     ],
//! };
//! let db = FingerprintDatabase::from_survey(survey)?.with_estimated_anchors(3)?;
//! let index = FingerprintIndex::new(db, SignalSpace::powed_sorensen())?;
//! let query = [Some(-84.0), None, Some(-44.0)];
//! let global = Knn::wknn(2).locate(&index, &query)?;
//! assert_eq!(global.floor, Some(1));
//! let local = LocalWknn { strongest_anchors: 1, radius_m: 15.0, knn: Knn::wknn(2) }.build(&index)?;
//! assert_eq!(local.locate(&query)?.fix.position, global.fix.position);
//! # Ok::<(), rtls_positioning::PositioningError>(())
//! ```

mod anchors;
mod cross_validation;
mod database;
mod index;
mod knn;
mod local;
mod signal;

pub use cross_validation::{LeaveOneOut, LeaveOneOutSample, MIN_DISTINCT_POSITIONS, MIN_LOCATED};
pub use database::{FingerprintDatabase, Survey};
pub use index::FingerprintIndex;
pub use knn::{Knn, Weighting};
pub use local::{LocalWknn, LocalWknnLocator};
pub use signal::{SignalDistance, SignalRepresentation, SignalSpace};

#[cfg(doc)]
use crate::error::PositioningError;
use crate::fix::Fix2;

/// One neighbour chosen by (L-)WKNN or KNN: a reference point, its signal-space distance and its
/// weight in the fix.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::Neighbour;
/// let n = Neighbour { reference_point: 3, distance: 2.0, weight: 0.25 };
/// assert_eq!(n.reference_point, 3);
/// ```
///
/// # References
/// Seed 002, eqs. (1)–(3): matching set `I(k)`, distances `D_i^k`, weights `w_i^k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Row of the reference point in the database.
    pub reference_point: usize,
    /// Signal-space distance `D_l`, in the units of the index's [`SignalSpace`] (dB for
    /// Euclidean on the `Positive` representation).
    pub distance: f64,
    /// Normalised weight `w_l` (the weights of one fix sum to 1).
    pub weight: f64,
}

/// A fingerprint fix and the neighbours it was averaged from.
///
/// `fix.covariance` is the weighted spread of the neighbours around the fix,
/// `Σ w_l (P_l − x̂)(P_l − x̂)ᵀ` (m²): it says how much the neighbours disagree, is zero when one
/// neighbour carries all the weight (an exact match, or `n = 1`), and is **not** calibrated.
/// For a tracking filter, use an observation covariance measured at surveyed points with
/// [`calibrate_fix_noise`](crate::calibrate_fix_noise), as seed 002 does, or add to it the
/// floor calibrated on the map itself ([`Knn::leave_one_out`],
/// [`LeaveOneOut::floor_variance_m2`]).
///
/// `neighbours` are sorted by increasing signal-space distance (ties by reference-point index);
/// a neighbour on another floor than the voted one has weight 0 when
/// [`Knn::same_floor_only`] is set. `building` and `floor` are the weighted votes of the
/// neighbours (`None` when the survey has no such labels).
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, SignalSpace};
/// let db = FingerprintDatabase::new(
///     vec![[0.0, 0.0], [10.0, 0.0]],
///     vec![[0.0, 0.0], [10.0, 0.0]],
///     vec![vec![-30.0, -70.0], vec![-70.0, -30.0]],
/// )?;
/// let index = FingerprintIndex::new(db, SignalSpace::default())?;
/// let result = Knn::wknn(2).locate(&index, &[Some(-40.0), Some(-60.0)])?;
/// assert_eq!(result.neighbours[0].reference_point, 0);
/// assert!(result.fix.position.x < 5.0);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, eq. (2) (the fix) and §1.3 (the observation covariance `U`).
#[derive(Debug, Clone, PartialEq)]
pub struct FingerprintFix {
    /// Position (m) and neighbour spread (m²).
    pub fix: Fix2,
    /// The chosen neighbours, nearest first.
    pub neighbours: Vec<Neighbour>,
    /// Voted building, if the survey labels buildings.
    pub building: Option<u32>,
    /// Voted floor, if the survey labels floors.
    pub floor: Option<i32>,
}

#[cfg(test)]
mod tests;
