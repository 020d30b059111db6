//! Seed 002's local WKNN (L-WKNN): WKNN restricted to reference points near the strongest
//! anchors, with the spatial part precomputed per anchor.

use super::wknn::{check_neighbours, nearest_weighted};
use super::{heard_anchors, FingerprintDatabase, FingerprintFix};
use crate::error::{PositioningError, Result};

/// L-WKNN parameters: `N_k` strongest anchors, search radius (m), `n` neighbours.
///
/// Online, per query:
/// 1. keep the `N_k` strongest heard anchors of the measured vector (ties by anchor index;
///    all heard anchors if fewer than `N_k` are heard);
/// 2. candidates = reference points within `radius_m` of any of those anchors
///    (`‖P_l − S_x‖ ≤ radius_m`);
/// 3. signal-space distance `D_l` to each candidate, keep the `n` nearest;
/// 4. `1/D`-weighted average of their positions (as [`super::Wknn`], erratum included).
///
/// Step 2 uses an index built once per database by [`LocalWknn::build`]: for every anchor,
/// the reference points within the radius. A query then touches only its candidates, which
/// is what makes L-WKNN fast on a large site. With `N_k ≥` the number of anchors and a radius
/// covering the site, L-WKNN equals [`super::Wknn`] exactly.
///
/// [`Default`] gives the paper's simulation values `N_k = 4`, `radius = 20 m`, `n = 4`.
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
/// assert_eq!((paper.strongest_anchors, paper.radius_m, paper.neighbours), (4, 20.0, 4));
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
    /// `n`: neighbours averaged (≥ 1).
    pub neighbours: usize,
}

impl Default for LocalWknn {
    /// Seed 002's simulation: `N_k = 4`, radius 20 m, `n = 4`.
    fn default() -> Self {
        Self {
            strongest_anchors: 4,
            radius_m: 20.0,
            neighbours: 4,
        }
    }
}

impl LocalWknn {
    /// Validates the parameters and builds the per-anchor spatial index for `database`:
    /// for every anchor `x`, the reference points `l` with `‖P_l − S_x‖ ≤ radius_m`, in
    /// increasing `l`. Cost `O(N · N_s)`, once.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] if `strongest_anchors` or `neighbours` is 0, or
    /// `radius_m` is NaN or not positive.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     vec![[0.0, 0.0], [50.0, 0.0]],
    ///     vec![vec![-30.0, -80.0], vec![-50.0, -75.0], vec![-80.0, -30.0]],
    /// )?;
    /// let locator = LocalWknn { strongest_anchors: 1, radius_m: 20.0, neighbours: 2 }.build(&db)?;
    /// assert_eq!(locator.nearby_reference_points(0), Some(&[0, 1][..]));
    /// assert_eq!(locator.nearby_reference_points(1), Some(&[2][..]));
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 step (2).
    pub fn build<'db>(&self, database: &'db FingerprintDatabase) -> Result<LocalWknnLocator<'db>> {
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
        check_neighbours(self.neighbours)?;
        let radius_squared_m2 = self.radius_m * self.radius_m;
        let nearby = database
            .anchors_m()
            .iter()
            .map(|anchor| {
                database
                    .reference_points_m()
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| {
                        // ‖P_l − S_x‖² ≤ radius²
                        let (dx, dy) = (p[0] - anchor[0], p[1] - anchor[1]);
                        dx * dx + dy * dy <= radius_squared_m2
                    })
                    .map(|(l, _)| l)
                    .collect()
            })
            .collect();
        Ok(LocalWknnLocator {
            parameters: *self,
            database,
            nearby,
        })
    }
}

/// An L-WKNN locator bound to one database, holding the per-anchor spatial index built by
/// [`LocalWknn::build`].
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
/// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-30.0]])?;
/// let locator = LocalWknn::default().build(&db)?;
/// assert_eq!(locator.parameters().neighbours, 4);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, §1.2.
#[derive(Debug, Clone)]
pub struct LocalWknnLocator<'db> {
    parameters: LocalWknn,
    database: &'db FingerprintDatabase,
    /// Per anchor, the reference points within the radius (increasing index).
    nearby: Vec<Vec<usize>>,
}

impl<'db> LocalWknnLocator<'db> {
    /// The L-WKNN fix of a measured RSSI vector (dBm, one entry per anchor, `None` = not
    /// heard): steps (1)–(4) of [`LocalWknn`].
    ///
    /// # Errors
    /// [`PositioningError::DimensionMismatch`] unless the query has one entry per anchor;
    /// [`PositioningError::NonFiniteEntry`] (column = anchor) for a heard NaN/∞ value;
    /// [`PositioningError::NoCommonAnchors`] if no anchor is heard;
    /// [`PositioningError::NoCandidates`] if no reference point lies within the radius of the
    /// selected anchors; [`PositioningError::NonFinite`] if a distance or the fix overflows.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
    /// let db = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     vec![[0.0, 0.0], [50.0, 0.0]],
    ///     vec![vec![-30.0, -80.0], vec![-50.0, -75.0], vec![-80.0, -30.0]],
    /// )?;
    /// let locator = LocalWknn { strongest_anchors: 1, radius_m: 20.0, neighbours: 2 }.build(&db)?;
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
        let heard = heard_anchors(self.database, measured_dbm)?;
        // (1) the N_k strongest heard anchors (ties by anchor index)
        let mut strongest = heard.clone();
        strongest.sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        strongest.truncate(self.parameters.strongest_anchors);
        // (2) candidates = ∪ reference points within the radius of those anchors
        let mut candidates: Vec<usize> = strongest
            .iter()
            .flat_map(|&(x, _)| self.nearby[x].iter().copied())
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        // (3)–(4) the n nearest in signal space over the heard anchors, 1/D weights
        nearest_weighted(self.database, candidates, &heard, self.parameters.neighbours)
    }

    /// The reference points within the radius of `anchor` (increasing index), or `None` if
    /// `anchor` is out of range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[100.0, 0.0]], vec![vec![-30.0]])?;
    /// let locator = LocalWknn::default().build(&db)?;
    /// assert_eq!(locator.nearby_reference_points(0), Some(&[][..])); // 100 m > 20 m
    /// assert_eq!(locator.nearby_reference_points(1), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 step (2).
    #[must_use]
    pub fn nearby_reference_points(&self, anchor: usize) -> Option<&[usize]> {
        self.nearby.get(anchor).map(Vec::as_slice)
    }

    /// The parameters the locator was built with.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-30.0]])?;
    /// let params = LocalWknn { strongest_anchors: 2, radius_m: 40.0, neighbours: 8 };
    /// assert_eq!(params.build(&db)?.parameters(), &params);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn parameters(&self) -> &LocalWknn {
        &self.parameters
    }

    /// The database the locator was built for.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, LocalWknn};
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-30.0]])?;
    /// assert_eq!(LocalWknn::default().build(&db)?.database().anchor_count(), 1);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn database(&self) -> &'db FingerprintDatabase {
        self.database
    }
}
