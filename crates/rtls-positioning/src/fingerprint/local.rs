//! Seed 002's local WKNN (L-WKNN): WKNN restricted to reference points near the strongest
//! anchors, with the spatial part precomputed per anchor.

use super::index::FingerprintIndex;
use super::knn::{nearest_weighted, Knn};
use super::FingerprintFix;
use crate::error::{PositioningError, Result};

/// L-WKNN parameters: `N_k` strongest anchors, search radius (m), and the neighbour step.
///
/// Online, per query:
/// 1. keep the `N_k` strongest heard anchors of the measured vector whose position is known
///    or estimated (ties by anchor index; all of them if fewer than `N_k`);
/// 2. candidates = reference points within `radius_m` of any of those anchors
///    (`‖P_l − S_x‖ ≤ radius_m`);
/// 3. the `n` candidates nearest in signal space, and their building/floor vote ([`Knn`]);
/// 4. their weighted mean position (`1/D` weights, erratum included).
///
/// Step 2 uses a spatial index built once per database by [`LocalWknn::build`]: for every
/// anchor, the sorted list of reference points within the radius (a fixed-radius
/// neighbourhood index). A query merges `N_k` precomputed lists and touches only its
/// candidates, which is what makes L-WKNN fast on a large site. With `N_k ≥` the number of
/// anchors and a radius covering the site, L-WKNN equals [`Knn`] exactly. Anchors without a
/// position are never selected; estimate their positions from the survey with
/// [`super::FingerprintDatabase::with_estimated_anchors`].
///
/// [`Default`] gives the paper's simulation values `N_k = 4`, `radius = 20 m`, `n = 4` (WKNN).
///
/// # Units
/// `radius_m` in metres.
///
/// # Errors
/// See [`LocalWknn::build`] and [`LocalWknnLocator::locate`].
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::LocalWknn;
/// let paper = LocalWknn::default();
/// assert_eq!((paper.strongest_anchors, paper.radius_m, paper.knn.neighbours), (4, 20.0, 4));
/// ```
///
/// # References
/// Seed 002, §1.2 steps (1)–(4) and §2 (`N_k = 4`, radius 20 m, `n = 4`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalWknn {
    /// `N_k`: how many of the strongest heard anchors select the candidates (≥ 1).
    pub strongest_anchors: usize,
    /// Search radius around each selected anchor (m, > 0; `f64::INFINITY` allowed).
    pub radius_m: f64,
    /// The neighbour step over the candidates (`n`, weights, floor handling).
    pub knn: Knn,
}

impl Default for LocalWknn {
    /// Seed 002's simulation: `N_k = 4`, radius 20 m, `n = 4`.
    fn default() -> Self {
        Self {
            strongest_anchors: 4,
            radius_m: 20.0,
            knn: Knn::wknn(4),
        }
    }
}

impl LocalWknn {
    /// Validates the parameters and builds the per-anchor spatial index for `index`: for every
    /// anchor `x` with a position, the reference points `l` with `‖P_l − S_x‖ ≤ radius_m`, in
    /// increasing `l`. Cost `O(N · N_s)`, once.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] if `strongest_anchors` or `knn.neighbours` is 0,
    /// `knn`'s weighting power is not positive, or `radius_m` is NaN or not positive;
    /// [`PositioningError::DegenerateGeometry`] if no anchor has a position.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalSpace};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     vec![[0.0, 0.0], [50.0, 0.0]],
    ///     vec![vec![-30.0, -80.0], vec![-50.0, -75.0], vec![-80.0, -30.0]],
    /// )?;
    /// let index = FingerprintIndex::new(db, SignalSpace::default())?;
    /// let locator = LocalWknn { strongest_anchors: 1, radius_m: 20.0, knn: Knn::wknn(2) }.build(&index)?;
    /// assert_eq!(locator.nearby_reference_points(0), Some(&[0, 1][..]));
    /// assert_eq!(locator.nearby_reference_points(1), Some(&[2][..]));
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 step (2).
    pub fn build<'i>(&self, index: &'i FingerprintIndex) -> Result<LocalWknnLocator<'i>> {
        if self.strongest_anchors == 0 {
            return Err(PositioningError::InvalidParameter {
                name: "strongest_anchors",
                reason: "at least one anchor must select the candidates",
            });
        }
        if self.radius_m.is_nan() || self.radius_m <= 0.0 {
            return Err(PositioningError::InvalidParameter {
                name: "radius_m",
                reason: "the search radius must be positive (infinity covers the whole site)",
            });
        }
        self.knn.validate()?;
        let database = index.database();
        if database.anchors_m().iter().all(Option::is_none) {
            return Err(PositioningError::DegenerateGeometry {
                reason: "no anchor has a position, so L-WKNN cannot select nearby reference points; \
                         estimate them with FingerprintDatabase::with_estimated_anchors",
            });
        }
        let radius_squared_m2 = self.radius_m * self.radius_m;
        let nearby = database
            .anchors_m()
            .iter()
            .map(|anchor| {
                anchor.map(|anchor| {
                    database
                        .reference_points_m()
                        .iter()
                        .enumerate()
                        .filter(|(_, p)| {
                            // ‖P_l − S_x‖² ≤ radius²
                            let (dx, dy) = (p[0] - anchor[0], p[1] - anchor[1]);
                            dx * dx + dy * dy <= radius_squared_m2
                        })
                        .map(|(l, _)| l as u32)
                        .collect()
                })
            })
            .collect();
        Ok(LocalWknnLocator {
            parameters: *self,
            index,
            nearby,
        })
    }
}

/// An L-WKNN locator bound to one [`FingerprintIndex`], holding the per-anchor spatial index
/// built by [`LocalWknn::build`].
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, LocalWknn, SignalSpace};
/// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-30.0]])?;
/// let index = FingerprintIndex::new(db, SignalSpace::default())?;
/// let locator = LocalWknn::default().build(&index)?;
/// assert_eq!(locator.parameters().knn.neighbours, 4);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, §1.2.
#[derive(Debug, Clone)]
pub struct LocalWknnLocator<'i> {
    parameters: LocalWknn,
    index: &'i FingerprintIndex,
    /// Per anchor with a position, the reference points within the radius (increasing).
    nearby: Vec<Option<Vec<u32>>>,
}

impl<'i> LocalWknnLocator<'i> {
    /// The L-WKNN fix of a measured RSSI vector (dBm, one entry per anchor, `None` = not
    /// heard): steps (1)–(4) of [`LocalWknn`].
    ///
    /// # Errors
    /// The query errors of [`Knn`] (size, NaN, below floor, nothing heard, no match);
    /// [`PositioningError::NoCandidates`] if no reference point lies within the radius of the
    /// selected anchors (or no heard anchor has a position).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalSpace};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     vec![[0.0, 0.0], [50.0, 0.0]],
    ///     vec![vec![-30.0, -80.0], vec![-50.0, -75.0], vec![-80.0, -30.0]],
    /// )?;
    /// let index = FingerprintIndex::new(db, SignalSpace::default())?;
    /// let locator = LocalWknn { strongest_anchors: 1, radius_m: 20.0, knn: Knn::wknn(2) }.build(&index)?;
    /// // Anchor 0 is the strongest: only reference points 0 and 1 are candidates.
    /// let result = locator.locate(&[Some(-40.0), Some(-78.0)])?;
    /// let chosen: Vec<usize> = result.neighbours.iter().map(|n| n.reference_point).collect();
    /// assert_eq!(chosen, [0, 1]);
    /// assert!(result.fix.position.x > 0.0 && result.fix.position.x < 10.0);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 steps (1)–(4) (erratum: `w ∝ 1/D`).
    pub fn locate(&self, measured_dbm: &[Option<f64>]) -> Result<FingerprintFix> {
        let query = self.index.represent_query(measured_dbm)?;
        let candidates = self.candidates(&query);
        // (3)–(4) the neighbour step over the candidates
        nearest_weighted(
            self.index,
            candidates.into_iter().map(|l| l as usize),
            &query,
            &self.parameters.knn,
        )
    }

    /// How many reference points steps (1)–(2) select for a query: the work L-WKNN does
    /// instead of comparing all `N`.
    ///
    /// # Errors
    /// The query errors of [`LocalWknnLocator::locate`].
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalSpace};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     vec![[0.0, 0.0], [50.0, 0.0]],
    ///     vec![vec![-30.0, -80.0], vec![-50.0, -75.0], vec![-80.0, -30.0]],
    /// )?;
    /// let index = FingerprintIndex::new(db, SignalSpace::default())?;
    /// let locator = LocalWknn { strongest_anchors: 1, radius_m: 20.0, knn: Knn::wknn(2) }.build(&index)?;
    /// assert_eq!(locator.candidate_count(&[Some(-40.0), Some(-78.0)])?, 2);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn candidate_count(&self, measured_dbm: &[Option<f64>]) -> Result<usize> {
        let query = self.index.represent_query(measured_dbm)?;
        Ok(self.candidates(&query).len())
    }

    /// Steps (1)–(2): the sorted candidate reference points of a represented query.
    fn candidates(&self, query: &[(u32, f64)]) -> Vec<u32> {
        // (1) the N_k strongest heard anchors with a position (ties by anchor index); ψ is
        // increasing in ρ in every representation, so the strongest reading has the largest ψ
        let mut strongest: Vec<(u32, f64)> = query
            .iter()
            .copied()
            .filter(|&(x, _)| self.nearby[x as usize].is_some())
            .collect();
        strongest.sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        strongest.truncate(self.parameters.strongest_anchors);
        // (2) candidates = ∪ reference points within the radius of those anchors
        let lists: Vec<&[u32]> = strongest
            .iter()
            .filter_map(|&(x, _)| self.nearby[x as usize].as_deref())
            .collect();
        merge_sorted_unique(&lists)
    }

    /// The reference points within the radius of `anchor` (increasing index); `None` if
    /// `anchor` is out of range or has no position.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, LocalWknn, SignalSpace};
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[100.0, 0.0]], vec![vec![-30.0]])?;
    /// let index = FingerprintIndex::new(db, SignalSpace::default())?;
    /// let locator = LocalWknn::default().build(&index)?;
    /// assert_eq!(locator.nearby_reference_points(0), Some(&[][..])); // 100 m > 20 m
    /// assert_eq!(locator.nearby_reference_points(1), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 step (2).
    #[must_use]
    pub fn nearby_reference_points(&self, anchor: usize) -> Option<&[u32]> {
        self.nearby.get(anchor)?.as_deref()
    }

    /// The parameters the locator was built with.
    #[inline]
    #[must_use]
    pub fn parameters(&self) -> &LocalWknn {
        &self.parameters
    }

    /// The index the locator was built for.
    #[inline]
    #[must_use]
    pub fn index(&self) -> &'i FingerprintIndex {
        self.index
    }
}

/// The union of sorted, duplicate-free lists, sorted and duplicate-free: a k-way merge that
/// repeatedly takes the smallest head (`k = N_k` is small).
fn merge_sorted_unique(lists: &[&[u32]]) -> Vec<u32> {
    let mut heads = vec![0usize; lists.len()];
    let mut merged = Vec::with_capacity(lists.iter().map(|l| l.len()).max().unwrap_or(0));
    loop {
        // smallest head value
        let Some(next) = lists
            .iter()
            .zip(&heads)
            .filter_map(|(list, &h)| list.get(h).copied())
            .min()
        else {
            return merged;
        };
        merged.push(next);
        // advance every list whose head equals it
        for (list, h) in lists.iter().zip(heads.iter_mut()) {
            if list.get(*h) == Some(&next) {
                *h += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_is_the_sorted_union() {
        assert_eq!(
            merge_sorted_unique(&[&[1, 4, 9], &[2, 4, 10], &[], &[0, 9]]),
            vec![0, 1, 2, 4, 9, 10]
        );
        assert!(merge_sorted_unique(&[]).is_empty());
    }
}
