//! RSSI fingerprinting: weighted k-nearest neighbours over a surveyed fingerprint map, globally
//! ([`Wknn`]) or restricted to reference points near the strongest anchors ([`LocalWknn`],
//! seed 002's L-WKNN).
//!
//! A query is the measured RSSI vector `&[Option<f64>]` (dBm), one entry per database anchor;
//! `None` means the anchor was not heard. Signal-space distances use the heard anchors only:
//!
//! `D_l = √( Σ_{x heard} (ρ_x − ρ_{l,x})² )` (dB)
//!
//! Database values are always present, so every heard anchor is compared at every reference
//! point. An unheard anchor is simply left out rather than replaced by a floor value: a caller
//! who prefers "not heard = −100 dBm" passes `Some(-100.0)`. A query that hears nothing is
//! [`PositioningError::NoCommonAnchors`].

mod database;
mod local;
mod wknn;

pub use database::FingerprintDatabase;
pub use local::{LocalWknn, LocalWknnLocator};
pub use wknn::Wknn;

use crate::error::{PositioningError, Result};
use crate::fix::Fix2;

/// One neighbour chosen by (L-)WKNN: a reference point, its signal-space distance and its
/// weight in the fix.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::Neighbour;
/// let n = Neighbour { reference_point: 3, distance_db: 2.0, weight: 0.25 };
/// assert_eq!(n.reference_point, 3);
/// ```
///
/// # References
/// Seed 002, eqs. (1)–(3): matching set `I(k)`, distances `D_i^k`, weights `w_i^k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Row of the reference point in the database.
    pub reference_point: usize,
    /// Signal-space distance `D_l` (dB) over the heard anchors.
    pub distance_db: f64,
    /// Normalised weight `w_l` (the weights of one fix sum to 1).
    pub weight: f64,
}

/// A fingerprint fix and the neighbours it was averaged from.
///
/// `fix.covariance` is the weighted spread of the neighbours around the fix,
/// `Σ w_l (P_l − x̂)(P_l − x̂)ᵀ` (m²): it says how much the neighbours disagree, is zero when one
/// neighbour carries all the weight (an exact match, or `n = 1`), and is **not** calibrated.
/// For a tracking filter, use an observation covariance measured at surveyed points with
/// [`calibrate_fix_noise`](crate::calibrate_fix_noise), as seed 002 does.
///
/// `neighbours` are sorted by increasing signal-space distance (ties by reference-point index).
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, Wknn};
/// let db = FingerprintDatabase::new(
///     vec![[0.0, 0.0], [10.0, 0.0]],
///     vec![[0.0, 0.0], [10.0, 0.0]],
///     vec![vec![-30.0, -70.0], vec![-70.0, -30.0]],
/// )?;
/// let result = Wknn { neighbours: 2 }.locate(&db, &[Some(-40.0), Some(-60.0)])?;
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
}

/// The heard anchors of a validated query: `(anchor, ρ_x dBm)`, in anchor order.
pub(crate) fn heard_anchors(database: &FingerprintDatabase, measured_dbm: &[Option<f64>]) -> Result<Vec<(usize, f64)>> {
    if measured_dbm.len() != database.anchor_count() {
        return Err(PositioningError::DimensionMismatch {
            what: "measured rssi (one entry per database anchor)",
            expected: database.anchor_count(),
            found: measured_dbm.len(),
        });
    }
    let mut heard = Vec::with_capacity(measured_dbm.len());
    for (anchor, value) in measured_dbm.iter().enumerate() {
        if let Some(rssi_dbm) = *value {
            if !rssi_dbm.is_finite() {
                return Err(PositioningError::NonFiniteEntry {
                    what: "measured rssi (row 0, column = anchor)",
                    row: 0,
                    column: anchor,
                });
            }
            heard.push((anchor, rssi_dbm));
        }
    }
    if heard.is_empty() {
        return Err(PositioningError::NoCommonAnchors);
    }
    Ok(heard)
}

#[cfg(test)]
mod tests;
