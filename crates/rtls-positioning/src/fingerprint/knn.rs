//! k-nearest neighbours in signal space over all reference points (KNN, WKNN), with building
//! and floor classification, and the selection kernel L-WKNN shares.

use core::cmp::Ordering;

use nalgebra::{Matrix2, Vector2};

use super::index::FingerprintIndex;
use super::signal::SparseFingerprint;
use super::{FingerprintFix, Neighbour};
use crate::error::{PositioningError, Result};
use crate::fix::Fix2;

/// Signal-space distances at or below this count as an exact match.
pub(crate) const EXACT_MATCH: f64 = 1e-12;

/// How the chosen neighbours are weighted.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::Weighting;
/// assert_eq!(Weighting::default(), Weighting::InverseDistance { power: 1.0 });
/// ```
///
/// # References
/// Seed 002 eq. (3) (erratum: `w ∝ 1/D`, see [`Knn`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Weighting {
    /// KNN: `w_l = 1/n`.
    Uniform,
    /// WKNN: `w_l ∝ 1 / D_l^p` (`p > 0`; an exact match takes all the weight).
    InverseDistance {
        /// Exponent `p` (1 in seed 002).
        power: f64,
    },
}

impl Default for Weighting {
    fn default() -> Self {
        Self::InverseDistance { power: 1.0 }
    }
}

/// k-nearest-neighbour fingerprinting over every reference point: the `n` reference points
/// nearest in signal space, their building and floor by weighted vote, and their weighted mean
/// position.
///
/// Per query `q` (represented in the index's [`super::SignalSpace`]):
/// 1. `D_l = D(q, ψ_l)` for every reference point; keep the `n` smallest (ties by index);
/// 2. weights: `w_l = 1/n` (KNN) or `w_l = D_l^{−p} / Σ_j D_j^{−p}` (WKNN); if the nearest
///    distance is `≤ 1e-12` the exactly matching points share the weight equally;
/// 3. if the survey labels buildings: `b̂ = argmax_b Σ_{l: b_l = b} w_l`; if it labels floors:
///    `f̂ = argmax_f Σ_{l: b_l = b̂, f_l = f} w_l` (ties to the smaller label);
/// 4. with `same_floor_only`, neighbours of another building/floor get weight 0 and the rest
///    are renormalised (a neighbour on the floor above is a different place);
/// 5. `x̂ = Σ w_l P_l`, covariance `Σ w_l (P_l − x̂)(P_l − x̂)ᵀ` (the neighbours' spread).
///
/// **Erratum (seed 002 eq. 3):** the paper prints `w = D / ΣD`, which gives the *farther*
/// points more weight; WKNN weights by similarity, `w ∝ 1/D`, which is implemented.
///
/// # Units
/// Positions in m, covariance in m²; distances in the signal space's units.
///
/// # Errors
/// [`PositioningError::InvalidParameter`] (`neighbours`, `power`);
/// the query errors of [`FingerprintIndex`] (size, NaN, below floor, nothing heard);
/// [`PositioningError::NoFingerprintMatch`] if no reference point hears any anchor the query
/// hears; [`PositioningError::NonFinite`] if a distance or the fix overflows.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, SignalSpace};
/// let db = FingerprintDatabase::new(
///     vec![[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]],
///     vec![[0.0, 0.0], [20.0, 0.0]],
///     vec![vec![-30.0, -60.0], vec![-45.0, -45.0], vec![-60.0, -30.0]],
/// )?;
/// let index = FingerprintIndex::new(db, SignalSpace::default())?;
/// // D = (√2, √(14² + 14²)·… ) — the query is nearest the first point
/// let result = Knn::wknn(2).locate(&index, &[Some(-31.0), Some(-59.0)])?;
/// assert_eq!(result.neighbours[0].reference_point, 0);
/// assert!(result.fix.position.x < 5.0);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, eqs. (1)–(3) with `N_k = N_s`; P. Bahl, V. Padmanabhan, "RADAR", INFOCOM 2000
/// (k-NN in signal space); Torres-Sospedra et al., "UJIIndoorLoc", IPIN 2014 (building and
/// floor hit rates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Knn {
    /// Number of neighbours `n` (≥ 1).
    pub neighbours: usize,
    /// Neighbour weights.
    pub weighting: Weighting,
    /// Average only the neighbours on the voted building and floor (no effect without labels).
    pub same_floor_only: bool,
}

impl Knn {
    /// Plain KNN (`w = 1/n`), averaging on the voted floor.
    #[must_use]
    pub const fn unweighted(neighbours: usize) -> Self {
        Self {
            neighbours,
            weighting: Weighting::Uniform,
            same_floor_only: true,
        }
    }

    /// WKNN with `w ∝ 1/D`, averaging on the voted floor.
    #[must_use]
    pub const fn wknn(neighbours: usize) -> Self {
        Self {
            neighbours,
            weighting: Weighting::InverseDistance { power: 1.0 },
            same_floor_only: true,
        }
    }

    /// The fix of a measured RSSI vector (dBm, one entry per anchor, `None` = not heard)
    /// against every reference point of `index`.
    ///
    /// # Errors
    /// As [`Knn`].
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
    /// // An exact match returns that reference point, with zero spread.
    /// let result = Knn::wknn(2).locate(&index, &[Some(-70.0), Some(-30.0)])?;
    /// assert_eq!(result.fix.position.x, 10.0);
    /// assert_eq!(result.fix.covariance[(0, 0)], 0.0);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn locate(&self, index: &FingerprintIndex, measured_dbm: &[Option<f64>]) -> Result<FingerprintFix> {
        self.validate()?;
        let query = index.represent_query(measured_dbm)?;
        nearest_weighted(index, 0..index.database().reference_point_count(), &query, self)
    }

    /// Checks `neighbours ≥ 1` and a positive finite weighting power.
    pub(crate) fn validate(&self) -> Result<()> {
        if self.neighbours == 0 {
            return Err(PositioningError::InvalidParameter {
                name: "neighbours",
                reason: "at least one neighbour must be averaged",
            });
        }
        if let Weighting::InverseDistance { power } = self.weighting {
            if !(power.is_finite() && power > 0.0) {
                return Err(PositioningError::InvalidParameter {
                    name: "power",
                    reason: "the inverse-distance power must be positive and finite",
                });
            }
        }
        Ok(())
    }
}

/// Order by distance, then by reference-point index (a total order: the selected set and its
/// order do not depend on the candidate order).
#[inline]
fn by_distance_then_index(a: &Neighbour, b: &Neighbour) -> Ordering {
    a.distance
        .total_cmp(&b.distance)
        .then(a.reference_point.cmp(&b.reference_point))
}

/// Steps 1–5 of [`Knn`] over `candidates` (distinct reference-point indices).
pub(crate) fn nearest_weighted(
    index: &FingerprintIndex,
    candidates: impl IntoIterator<Item = usize>,
    query: &SparseFingerprint,
    knn: &Knn,
) -> Result<FingerprintFix> {
    // (1) D_l for every candidate that shares a heard anchor with the query
    let mut any_candidate = false;
    let mut chosen: Vec<Neighbour> = candidates
        .into_iter()
        .filter_map(|l| {
            any_candidate = true;
            let (distance, shared) = index.distance(query, l);
            shared.then_some(Neighbour {
                reference_point: l,
                distance,
                weight: 0.0,
            })
        })
        .collect();
    if !any_candidate {
        return Err(PositioningError::NoCandidates);
    }
    if chosen.is_empty() {
        return Err(PositioningError::NoFingerprintMatch);
    }
    if chosen.iter().any(|n| !n.distance.is_finite()) {
        return Err(PositioningError::NonFinite {
            what: "signal-space distance (rssi values too large)",
        });
    }
    // I(k) = the n smallest D_l
    if chosen.len() > knn.neighbours {
        chosen.select_nth_unstable_by(knn.neighbours - 1, by_distance_then_index);
        chosen.truncate(knn.neighbours);
    }
    chosen.sort_unstable_by(by_distance_then_index);

    // (2) weights
    assign_weights(&mut chosen, knn.weighting);
    // (3) building and floor by weighted vote
    let database = index.database();
    let (has_floors, has_buildings) = database.has_labels();
    let building = has_buildings
        .then(|| weighted_vote(chosen.iter().map(|n| (database.building(n.reference_point), n.weight))))
        .flatten();
    let floor = has_floors
        .then(|| {
            weighted_vote(
                chosen
                    .iter()
                    .filter(|n| database.building(n.reference_point) == building)
                    .map(|n| (database.floor(n.reference_point), n.weight)),
            )
        })
        .flatten();
    // (4) keep the voted building and floor
    if knn.same_floor_only && (has_floors || has_buildings) {
        let mut kept = 0.0;
        for n in chosen.iter_mut() {
            let same = database.building(n.reference_point) == building && database.floor(n.reference_point) == floor;
            if !same {
                n.weight = 0.0;
            }
            kept += n.weight;
        }
        // the voted floor has positive weight, so kept > 0
        for n in chosen.iter_mut() {
            n.weight /= kept;
        }
    }

    // (5) x̂ = Σ w_l P_l, P = Σ w_l (P_l − x̂)(P_l − x̂)ᵀ
    let point = |n: &Neighbour| {
        let p = database.reference_points_m()[n.reference_point];
        Vector2::new(p[0], p[1])
    };
    let position = chosen
        .iter()
        .fold(Vector2::zeros(), |acc: Vector2<f64>, n| acc + point(n) * n.weight);
    let covariance = chosen.iter().fold(Matrix2::zeros(), |acc: Matrix2<f64>, n| {
        let d = point(n) - position;
        acc + d * d.transpose() * n.weight
    });
    let fix = Fix2 { position, covariance }.checked()?;
    Ok(FingerprintFix {
        fix,
        neighbours: chosen,
        building,
        floor,
    })
}

/// Normalised weights of the sorted neighbours.
fn assign_weights(chosen: &mut [Neighbour], weighting: Weighting) {
    let exact = chosen.iter().filter(|n| n.distance <= EXACT_MATCH).count();
    match weighting {
        Weighting::Uniform => {
            // w_l = 1/n
            let w = 1.0 / chosen.len() as f64;
            chosen.iter_mut().for_each(|n| n.weight = w);
        }
        Weighting::InverseDistance { .. } if exact > 0 => {
            // exact match(es): equal weights, all others 0
            for n in chosen.iter_mut() {
                n.weight = if n.distance <= EXACT_MATCH {
                    1.0 / exact as f64
                } else {
                    0.0
                };
            }
        }
        Weighting::InverseDistance { power } => {
            // w_l = D_l^{−p} / Σ_j D_j^{−p}, computed relative to the nearest D_1 to avoid
            // overflow: (D_1/D_l)^p / Σ_j (D_1/D_j)^p
            let nearest = chosen[0].distance;
            let total: f64 = chosen.iter().map(|n| (nearest / n.distance).powf(power)).sum();
            for n in chosen.iter_mut() {
                n.weight = (nearest / n.distance).powf(power) / total;
            }
        }
    }
}

/// `argmax_label Σ w` over `(label, w)` pairs; ties go to the smaller label; `None` if there
/// are no labelled pairs.
fn weighted_vote<L: Copy + Ord>(votes: impl Iterator<Item = (Option<L>, f64)>) -> Option<L> {
    let mut tally: Vec<(L, f64)> = Vec::new();
    for (label, weight) in votes {
        let Some(label) = label else { continue };
        match tally.iter_mut().find(|(l, _)| *l == label) {
            Some((_, total)) => *total += weight,
            None => tally.push((label, weight)),
        }
    }
    tally
        .into_iter()
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
        .map(|(label, _)| label)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_vote_takes_the_heaviest_label_and_breaks_ties_low() {
        assert_eq!(
            weighted_vote([(Some(2), 0.3), (Some(1), 0.2), (Some(1), 0.2)].into_iter()),
            Some(1)
        );
        assert_eq!(weighted_vote([(Some(3), 0.5), (Some(1), 0.5)].into_iter()), Some(1));
        assert_eq!(weighted_vote([(None::<i32>, 1.0)].into_iter()), None);
    }

    #[test]
    fn inverse_distance_weights_are_normalised_and_power_sharpens_them() {
        let mut n: Vec<Neighbour> = [1.0, 2.0, 4.0]
            .iter()
            .enumerate()
            .map(|(l, &d)| Neighbour {
                reference_point: l,
                distance: d,
                weight: 0.0,
            })
            .collect();
        assign_weights(&mut n, Weighting::InverseDistance { power: 1.0 });
        // 1 : 1/2 : 1/4 → 4/7, 2/7, 1/7
        assert!((n[0].weight - 4.0 / 7.0).abs() < 1e-15);
        assert!((n[2].weight - 1.0 / 7.0).abs() < 1e-15);
        assign_weights(&mut n, Weighting::InverseDistance { power: 2.0 });
        // 1 : 1/4 : 1/16 → 16/21, 4/21, 1/21
        assert!((n[0].weight - 16.0 / 21.0).abs() < 1e-15);
        assign_weights(&mut n, Weighting::Uniform);
        assert!(n.iter().all(|n| (n.weight - 1.0 / 3.0).abs() < 1e-15));
    }
}
