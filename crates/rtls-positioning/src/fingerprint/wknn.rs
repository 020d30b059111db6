//! Weighted k-nearest neighbours over all reference points, and the neighbour-selection and
//! weighting kernel that L-WKNN shares.

use core::cmp::Ordering;

use nalgebra::{Matrix2, Vector2};

use super::{heard_anchors, FingerprintDatabase, FingerprintFix, Neighbour};
use crate::error::{PositioningError, Result};
use crate::fix::Fix2;

/// Signal-space distances at or below this (dB) count as an exact match.
pub(crate) const EXACT_MATCH_DB: f64 = 1e-12;

/// Plain WKNN over every reference point: the `n` reference points nearest in signal space,
/// averaged with weights `w_l ∝ 1/D_l`.
///
/// `D_l = √(Σ_{x heard} (ρ_x − ρ_{l,x})²)` (dB, see the [module docs](super)), keep the `n`
/// smallest (ties by reference-point index), `w_l = (1/D_l) / Σ_j (1/D_j)`,
/// `x̂ = Σ w_l P_l`. If the nearest distance is `≤ 1e-12` dB the query is an exact match: the
/// exactly matching reference point(s) get equal weight and all others 0, so an exact match
/// returns that reference point. With fewer than `n` reference points all are used.
///
/// **Erratum (seed 002 eq. 3):** the paper prints `w = D / ΣD`, which gives the *farther*
/// points more weight; WKNN weights by similarity, `w ∝ 1/D`, which is implemented.
///
/// # Units
/// RSSI in dBm, distances in dB, positions in m, covariance in m².
///
/// # Errors
/// [`PositioningError::InvalidParameter`] (`neighbours`) if `neighbours` is 0;
/// [`PositioningError::DimensionMismatch`] unless the query has one entry per anchor;
/// [`PositioningError::NonFiniteEntry`] (column = anchor) for a heard NaN/∞ value;
/// [`PositioningError::NoCommonAnchors`] if no anchor is heard;
/// [`PositioningError::NonFinite`] if a distance or the fix overflows.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, Wknn};
/// let db = FingerprintDatabase::new(
///     vec![[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]],
///     vec![[0.0, 0.0], [20.0, 0.0]],
///     vec![vec![-30.0, -60.0], vec![-45.0, -45.0], vec![-60.0, -30.0]],
/// )?;
/// // Only the first anchor is heard: D = (|−31 + 30|, |−31 + 45|, |−31 + 60|) = (1, 14, 29).
/// let result = Wknn { neighbours: 2 }.locate(&db, &[Some(-31.0), None])?;
/// // w ∝ (1/1, 1/14) → x̂ = 10 · (1/14) / (1 + 1/14) = 2/3 m
/// assert!((result.fix.position.x - 10.0 / 15.0).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, eqs. (1)–(3) with `N_k = N_s` (erratum: `w ∝ 1/D`); P. Bahl, V. Padmanabhan,
/// "RADAR: an in-building RF-based user location and tracking system", INFOCOM 2000 (k-NN in
/// signal space).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wknn {
    /// Number of neighbours `n` averaged (≥ 1).
    pub neighbours: usize,
}

impl Wknn {
    /// The WKNN fix of a measured RSSI vector (dBm, `None` = not heard) against `database`.
    ///
    /// # Errors
    /// As [`Wknn`].
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, Wknn};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0]],
    ///     vec![[0.0, 0.0], [10.0, 0.0]],
    ///     vec![vec![-30.0, -70.0], vec![-70.0, -30.0]],
    /// )?;
    /// // An exact match returns that reference point, with zero spread.
    /// let result = Wknn { neighbours: 2 }.locate(&db, &[Some(-70.0), Some(-30.0)])?;
    /// assert_eq!(result.fix.position.x, 10.0);
    /// assert_eq!(result.fix.covariance[(0, 0)], 0.0);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, eqs. (1)–(3).
    pub fn locate(&self, database: &FingerprintDatabase, measured_dbm: &[Option<f64>]) -> Result<FingerprintFix> {
        check_neighbours(self.neighbours)?;
        let heard = heard_anchors(database, measured_dbm)?;
        nearest_weighted(database, 0..database.reference_point_count(), &heard, self.neighbours)
    }
}

/// `n ≥ 1`.
pub(crate) fn check_neighbours(neighbours: usize) -> Result<()> {
    if neighbours == 0 {
        return Err(PositioningError::InvalidParameter {
            name: "neighbours",
            reason: "at least one neighbour must be averaged",
        });
    }
    Ok(())
}

/// `D_l = √(Σ_{x heard} (ρ_x − ρ_{l,x})²)` (dB).
#[inline]
fn signal_distance_db(row_dbm: &[f64], heard: &[(usize, f64)]) -> f64 {
    heard
        .iter()
        .map(|&(x, rho_dbm)| {
            let d = rho_dbm - row_dbm[x];
            d * d
        })
        .sum::<f64>()
        .sqrt()
}

/// Order by distance, then by reference-point index (a total order: the selected set and its
/// order do not depend on the candidate order).
#[inline]
fn by_distance_then_index(a: &Neighbour, b: &Neighbour) -> Ordering {
    a.distance_db
        .total_cmp(&b.distance_db)
        .then(a.reference_point.cmp(&b.reference_point))
}

/// Steps (3)–(4) of L-WKNN (and all of WKNN): distances to the `candidates` (distinct
/// reference-point indices), the `n` nearest, `1/D` weights, weighted mean and spread.
pub(crate) fn nearest_weighted(
    database: &FingerprintDatabase,
    candidates: impl IntoIterator<Item = usize>,
    heard: &[(usize, f64)],
    neighbours: usize,
) -> Result<FingerprintFix> {
    // D_l for every candidate
    let mut chosen: Vec<Neighbour> = candidates
        .into_iter()
        .map(|l| Neighbour {
            reference_point: l,
            distance_db: signal_distance_db(database.rssi_row(l), heard),
            weight: 0.0,
        })
        .collect();
    if chosen.is_empty() {
        return Err(PositioningError::NoCandidates);
    }
    if chosen.iter().any(|n| !n.distance_db.is_finite()) {
        return Err(PositioningError::NonFinite {
            what: "signal-space distance (rssi values too large)",
        });
    }
    // I(k) = the n smallest D_l
    if chosen.len() > neighbours {
        chosen.select_nth_unstable_by(neighbours - 1, by_distance_then_index);
        chosen.truncate(neighbours);
    }
    chosen.sort_unstable_by(by_distance_then_index);

    if chosen[0].distance_db <= EXACT_MATCH_DB {
        // exact match(es): equal weights, all others 0
        let exact = chosen.iter().filter(|n| n.distance_db <= EXACT_MATCH_DB).count();
        for n in chosen.iter_mut() {
            n.weight = if n.distance_db <= EXACT_MATCH_DB {
                1.0 / exact as f64
            } else {
                0.0
            };
        }
    } else {
        // w_l = (1/D_l) / Σ_j (1/D_j)
        let total: f64 = chosen.iter().map(|n| 1.0 / n.distance_db).sum();
        for n in chosen.iter_mut() {
            n.weight = (1.0 / n.distance_db) / total;
        }
    }

    let point = |n: &Neighbour| {
        let p = database.reference_points_m()[n.reference_point];
        Vector2::new(p[0], p[1])
    };
    // x̂ = Σ w_l P_l
    let position = chosen
        .iter()
        .fold(Vector2::zeros(), |acc: Vector2<f64>, n| acc + point(n) * n.weight);
    // P = Σ w_l (P_l − x̂)(P_l − x̂)ᵀ
    let covariance = chosen.iter().fold(Matrix2::zeros(), |acc: Matrix2<f64>, n| {
        let d = point(n) - position;
        acc + d * d.transpose() * n.weight
    });
    let fix = Fix2 { position, covariance }.checked()?;
    Ok(FingerprintFix {
        fix,
        neighbours: chosen,
    })
}
