//! The offline fingerprint database: reference points (with optional floor and building),
//! anchors (with known, estimated or unknown positions) and the surveyed RSSI readings, stored
//! sparsely with absent readings explicit.

use crate::error::{PositioningError, Result};

/// A site survey, the input of [`FingerprintDatabase::from_survey`].
///
/// `readings_dbm[l]` lists the anchors heard at reference point `l` as `(anchor, ρ dBm)`, in any
/// order; **an anchor that is not listed was not heard there**. Nothing stands in for a missing
/// reading (no −100 or +100 sentinel): how absence is compared is the signal space's business
/// ([`super::SignalRepresentation`]).
///
/// # Units
/// Positions in metres, RSSI in dBm; floors and buildings are labels.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, Survey};
/// let survey = Survey {
///     reference_points_m: vec![[0.0, 0.0], [10.0, 0.0]],
///     floors: Some(vec![0, 1]),
///     buildings: None,
///     anchor_count: 3,
///     anchors_m: None, // unknown: estimate them with `estimate_anchor_positions`
///     readings_dbm: vec![vec![(0, -40.0), (2, -80.0)], vec![(1, -45.0)]],
/// };
/// let db = FingerprintDatabase::from_survey(survey)?;
/// assert_eq!(db.readings_dbm(0), Some(&[(0, -40.0), (2, -80.0)][..]));
/// assert_eq!(db.floor(1), Some(1));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002 §1.2 (offline phase); Torres-Sospedra et al., "UJIIndoorLoc", IPIN 2014 (building
/// and floor labels, absent access points).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Survey {
    /// Reference point positions `P_l` (m).
    pub reference_points_m: Vec<[f64; 2]>,
    /// Floor of each reference point, if the site has floors.
    pub floors: Option<Vec<i32>>,
    /// Building of each reference point, if the site has several.
    pub buildings: Option<Vec<u32>>,
    /// Number of anchors `N_s` (columns).
    pub anchor_count: usize,
    /// Anchor positions `S_x` (m); `None` = all unknown, `Some(v)` with `v[x] = None` = anchor
    /// `x` unknown.
    pub anchors_m: Option<Vec<Option<[f64; 2]>>>,
    /// Heard anchors per reference point, `(anchor, ρ dBm)`.
    pub readings_dbm: Vec<Vec<(usize, f64)>>,
}

/// An RSSI fingerprint map surveyed offline: reference points `P_l` (m) with optional floor and
/// building labels, anchors `S_x` whose positions may be known, estimated or unknown, and at
/// each reference point the mean RSSI `ρ_{l,x}` (dBm) of the anchors heard there.
///
/// Readings are stored sparsely (compressed rows, anchors in increasing order), so a
/// Wi-Fi survey with hundreds of access points, of which each place hears a few dozen, costs
/// memory in proportion to what was heard.
///
/// # Units
/// Positions in metres, RSSI in dBm.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::FingerprintDatabase;
/// let db = FingerprintDatabase::new(
///     vec![[0.0, 0.0], [10.0, 0.0]],
///     vec![[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]],
///     vec![vec![-30.0, -70.0, -65.0], vec![-70.0, -30.0, -65.0]],
/// )?;
/// assert_eq!(db.reference_point_count(), 2);
/// assert_eq!(db.readings_dbm(1), Some(&[(0, -70.0), (1, -30.0), (2, -65.0)][..]));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, §1.2: `N` reference points `P_l`, `N_s` anchors `S_i`, fingerprint `ρ_l` = mean
/// RSSI vector at `P_l`.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerprintDatabase {
    reference_points_m: Vec<[f64; 2]>,
    floors: Option<Vec<i32>>,
    buildings: Option<Vec<u32>>,
    anchors_m: Vec<Option<[f64; 2]>>,
    /// Row `l` is `readings[row_start[l]..row_start[l + 1]]`.
    row_start: Vec<usize>,
    /// `(anchor, ρ_{l,x} dBm)`, increasing anchor within a row.
    readings: Vec<(u32, f64)>,
}

impl FingerprintDatabase {
    /// Builds a database from a complete survey: every anchor heard at every reference point
    /// (seed 002's simulation), anchor positions known.
    ///
    /// # Errors
    /// As [`FingerprintDatabase::from_survey`], and [`PositioningError::RowLength`] naming the
    /// first RSSI row without one value per anchor.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::{fingerprint::FingerprintDatabase, PositioningError};
    /// let bad = FingerprintDatabase::new(
    ///     vec![[0.0, 0.0], [10.0, 0.0]],
    ///     vec![[0.0, 0.0], [10.0, 0.0]],
    ///     vec![vec![-30.0, -70.0], vec![-70.0, f64::NAN]],
    /// );
    /// assert!(matches!(bad, Err(PositioningError::NonFiniteEntry { row: 1, column: 1, .. })));
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 (offline phase).
    pub fn new(reference_points_m: Vec<[f64; 2]>, anchors_m: Vec<[f64; 2]>, rssi_dbm: Vec<Vec<f64>>) -> Result<Self> {
        let anchor_count = anchors_m.len();
        if reference_points_m.is_empty() || anchor_count == 0 {
            return Err(PositioningError::EmptyDatabase);
        }
        let mut readings_dbm = Vec::with_capacity(rssi_dbm.len());
        for (row, values) in rssi_dbm.iter().enumerate() {
            if values.len() != anchor_count {
                return Err(PositioningError::RowLength {
                    what: "fingerprint rssi (one value per anchor)",
                    row,
                    expected: anchor_count,
                    found: values.len(),
                });
            }
            readings_dbm.push(values.iter().copied().enumerate().collect());
        }
        Self::from_survey(Survey {
            reference_points_m,
            floors: None,
            buildings: None,
            anchor_count,
            anchors_m: Some(anchors_m.into_iter().map(Some).collect()),
            readings_dbm,
        })
    }

    /// Builds and validates a database from a [`Survey`] (absent readings, labels, unknown
    /// anchors allowed).
    ///
    /// # Errors
    /// - [`PositioningError::EmptyDatabase`] with no reference points or no anchors;
    /// - [`PositioningError::DimensionMismatch`] unless there is one reading row (and one floor,
    ///   one building label) per reference point and one anchor position per anchor;
    /// - [`PositioningError::NonFiniteEntry`] naming the first NaN/∞ reference-point coordinate
    ///   (row = reference point, column = axis), anchor coordinate (row = anchor, column = axis)
    ///   or RSSI (row = reference point, column = anchor);
    /// - [`PositioningError::AnchorOutOfRange`] for a reading of an anchor index `≥ anchor_count`;
    /// - [`PositioningError::DuplicateReading`] for an anchor listed twice in one row.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::{fingerprint::{FingerprintDatabase, Survey}, PositioningError};
    /// let survey = Survey {
    ///     reference_points_m: vec![[0.0, 0.0]],
    ///     anchor_count: 2,
    ///     readings_dbm: vec![vec![(0, -40.0), (0, -41.0)]], // anchor 0 twice
    ///     ..Survey::default()
    /// };
    /// assert!(matches!(
    ///     FingerprintDatabase::from_survey(survey),
    ///     Err(PositioningError::DuplicateReading { row: 0, column: 0 })
    /// ));
    /// ```
    ///
    /// # References
    /// Seed 002, §1.2 (offline phase).
    pub fn from_survey(survey: Survey) -> Result<Self> {
        let Survey {
            reference_points_m,
            floors,
            buildings,
            anchor_count,
            anchors_m,
            readings_dbm,
        } = survey;
        let points = reference_points_m.len();
        if points == 0 || anchor_count == 0 {
            return Err(PositioningError::EmptyDatabase);
        }
        first_non_finite(
            &reference_points_m,
            "reference point positions (row = reference point, column = axis)",
        )?;
        let anchors_m = anchors_m.unwrap_or_else(|| vec![None; anchor_count]);
        check_length("anchor positions (one per anchor)", anchor_count, anchors_m.len())?;
        check_anchor_positions(&anchors_m)?;
        check_length("fingerprint rows (one per reference point)", points, readings_dbm.len())?;
        if let Some(floors) = &floors {
            check_length("floor labels (one per reference point)", points, floors.len())?;
        }
        if let Some(buildings) = &buildings {
            check_length("building labels (one per reference point)", points, buildings.len())?;
        }
        let mut row_start = Vec::with_capacity(points + 1);
        let mut readings = Vec::with_capacity(readings_dbm.iter().map(Vec::len).sum());
        row_start.push(0);
        for (row, heard) in readings_dbm.into_iter().enumerate() {
            let start = readings.len();
            for (anchor, rssi_dbm) in heard {
                if anchor >= anchor_count {
                    return Err(PositioningError::AnchorOutOfRange {
                        row,
                        anchor,
                        anchors: anchor_count,
                    });
                }
                if !rssi_dbm.is_finite() {
                    return Err(PositioningError::NonFiniteEntry {
                        what: "fingerprint rssi (row = reference point, column = anchor)",
                        row,
                        column: anchor,
                    });
                }
                readings.push((anchor as u32, rssi_dbm));
            }
            let row_readings = &mut readings[start..];
            row_readings.sort_unstable_by_key(|&(anchor, _)| anchor);
            if let Some(pair) = row_readings.windows(2).find(|pair| pair[0].0 == pair[1].0) {
                return Err(PositioningError::DuplicateReading {
                    row,
                    column: pair[0].0 as usize,
                });
            }
            row_start.push(readings.len());
        }
        Ok(Self {
            reference_points_m,
            floors,
            buildings,
            anchors_m,
            row_start,
            readings,
        })
    }

    /// Reference point positions `P_l` (m), in row order.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[1.0, 2.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.reference_points_m(), &[[1.0, 2.0]]);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn reference_points_m(&self) -> &[[f64; 2]] {
        &self.reference_points_m
    }

    /// Anchor positions `S_x` (m), in column order; `None` where unknown.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[1.0, 2.0]], vec![[0.0, 5.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.anchors_m(), &[Some([0.0, 5.0])]);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn anchors_m(&self) -> &[Option<[f64; 2]>] {
        &self.anchors_m
    }

    /// Number of reference points `N` (rows); never 0.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.reference_point_count(), 1);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn reference_point_count(&self) -> usize {
        self.reference_points_m.len()
    }

    /// Number of anchors `N_s` (columns); never 0.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0], [9.0, 0.0]], vec![vec![-40.0, -60.0]])?;
    /// assert_eq!(db.anchor_count(), 2);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn anchor_count(&self) -> usize {
        self.anchors_m.len()
    }

    /// The anchors heard at reference point `l`, `(anchor, ρ_{l,x} dBm)` in increasing anchor
    /// order, or `None` if `l` is out of range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.readings_dbm(0), Some(&[(0, -40.0)][..]));
    /// assert_eq!(db.readings_dbm(1), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn readings_dbm(&self, reference_point: usize) -> Option<&[(u32, f64)]> {
        let start = *self.row_start.get(reference_point)?;
        let end = *self.row_start.get(reference_point + 1)?;
        Some(&self.readings[start..end])
    }

    /// Floor label of reference point `l`, if the survey has floors and `l` is in range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.floor(0), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn floor(&self, reference_point: usize) -> Option<i32> {
        self.floors.as_ref()?.get(reference_point).copied()
    }

    /// Building label of reference point `l`, if the survey has buildings and `l` is in range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.building(0), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn building(&self, reference_point: usize) -> Option<u32> {
        self.buildings.as_ref()?.get(reference_point).copied()
    }

    /// Whether the survey labels floors / buildings.
    #[inline]
    #[must_use]
    pub(crate) fn has_labels(&self) -> (bool, bool) {
        (self.floors.is_some(), self.buildings.is_some())
    }

    /// Anchor positions for in-crate updates (estimation).
    #[inline]
    pub(crate) fn anchors_mut(&mut self) -> &mut [Option<[f64; 2]>] {
        &mut self.anchors_m
    }

    /// Row `l` for an in-range index (internal).
    #[inline]
    pub(crate) fn row(&self, reference_point: usize) -> &[(u32, f64)] {
        &self.readings[self.row_start[reference_point]..self.row_start[reference_point + 1]]
    }

    /// All readings in row order, with the row boundaries (internal).
    #[inline]
    pub(crate) fn compressed_rows(&self) -> (&[usize], &[(u32, f64)]) {
        (&self.row_start, &self.readings)
    }
}

fn check_length(what: &'static str, expected: usize, found: usize) -> Result<()> {
    if expected == found {
        Ok(())
    } else {
        Err(PositioningError::DimensionMismatch { what, expected, found })
    }
}

fn check_anchor_positions(anchors_m: &[Option<[f64; 2]>]) -> Result<()> {
    // rows are anchor indices: unknown anchors keep their place
    for (row, position) in anchors_m.iter().enumerate() {
        if let Some(column) = position.and_then(|p| p.iter().position(|v| !v.is_finite())) {
            return Err(PositioningError::NonFiniteEntry {
                what: "anchor positions (row = anchor, column = axis)",
                row,
                column,
            });
        }
    }
    Ok(())
}

/// The first NaN/∞ coordinate of a point list, as [`PositioningError::NonFiniteEntry`].
fn first_non_finite(points: &[[f64; 2]], what: &'static str) -> Result<()> {
    for (row, p) in points.iter().enumerate() {
        if let Some(column) = p.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry { what, row, column });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference points, anchors, rssi rows.
    type Complete = (Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<Vec<f64>>);

    fn two_by_two() -> Complete {
        (
            vec![[0.0, 0.0], [10.0, 0.0]],
            vec![[0.0, 0.0], [10.0, 0.0]],
            vec![vec![-30.0, -70.0], vec![-70.0, -30.0]],
        )
    }

    #[test]
    fn rows_are_stored_sparsely_in_anchor_order() {
        let db = FingerprintDatabase::from_survey(Survey {
            reference_points_m: vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],
            anchor_count: 4,
            readings_dbm: vec![vec![(3, -50.0), (1, -40.0)], vec![], vec![(0, -60.0)]],
            ..Survey::default()
        })
        .unwrap();
        assert_eq!(db.row(0), &[(1, -40.0), (3, -50.0)]);
        assert_eq!(db.row(1), &[]);
        assert_eq!(db.row(2), &[(0, -60.0)]);
        assert_eq!(db.readings_dbm(3), None);
        assert_eq!(db.anchors_m(), &[None; 4]);
        assert_eq!(db.has_labels(), (false, false));
    }

    #[test]
    fn constructor_names_the_offending_row_and_column() {
        let (p, a, rssi) = two_by_two();
        assert_eq!(
            FingerprintDatabase::new(vec![], a.clone(), vec![]),
            Err(PositioningError::EmptyDatabase)
        );
        assert_eq!(
            FingerprintDatabase::new(p.clone(), vec![], rssi.clone()),
            Err(PositioningError::EmptyDatabase)
        );
        assert!(matches!(
            FingerprintDatabase::new(p.clone(), a.clone(), rssi[..1].to_vec()),
            Err(PositioningError::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
        assert!(matches!(
            FingerprintDatabase::new(p.clone(), a.clone(), vec![rssi[0].clone(), vec![-50.0]]),
            Err(PositioningError::RowLength {
                row: 1,
                expected: 2,
                found: 1,
                ..
            })
        ));
        let mut bad = rssi.clone();
        bad[0][1] = f64::NEG_INFINITY;
        assert!(matches!(
            FingerprintDatabase::new(p.clone(), a.clone(), bad),
            Err(PositioningError::NonFiniteEntry { row: 0, column: 1, what }) if what.starts_with("fingerprint rssi")
        ));
        let mut bad_points = p.clone();
        bad_points[1][0] = f64::NAN;
        assert!(matches!(
            FingerprintDatabase::new(bad_points, a.clone(), rssi.clone()),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 0, what }) if what.starts_with("reference point")
        ));
        let mut bad_anchors = a;
        bad_anchors[1][1] = f64::INFINITY;
        assert!(matches!(
            FingerprintDatabase::new(p.clone(), bad_anchors, rssi.clone()),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 1, what }) if what.starts_with("anchor")
        ));
        let survey = Survey {
            reference_points_m: p,
            anchor_count: 2,
            readings_dbm: vec![vec![(0, -40.0)], vec![(2, -40.0)]],
            ..Survey::default()
        };
        assert_eq!(
            FingerprintDatabase::from_survey(survey.clone()),
            Err(PositioningError::AnchorOutOfRange {
                row: 1,
                anchor: 2,
                anchors: 2
            })
        );
        let labels = Survey {
            readings_dbm: vec![vec![], vec![]],
            floors: Some(vec![0]),
            ..survey.clone()
        };
        assert!(matches!(
            FingerprintDatabase::from_survey(labels),
            Err(PositioningError::DimensionMismatch { what, expected: 2, found: 1 }) if what.starts_with("floor")
        ));
        let anchors = Survey {
            readings_dbm: vec![vec![], vec![]],
            anchors_m: Some(vec![None]),
            ..survey
        };
        assert!(matches!(
            FingerprintDatabase::from_survey(anchors),
            Err(PositioningError::DimensionMismatch { what, expected: 2, found: 1 }) if what.starts_with("anchor")
        ));
    }

    #[test]
    fn anchor_estimates_are_power_weighted_centroids_of_the_loudest_points() {
        let db = FingerprintDatabase::from_survey(Survey {
            reference_points_m: vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [30.0, 30.0]],
            anchor_count: 2,
            anchors_m: Some(vec![None, Some([7.0, 7.0])]),
            readings_dbm: vec![
                vec![(0, -40.0), (1, -50.0)],
                vec![(0, -50.0)],
                vec![(0, -50.0)],
                vec![(0, -90.0)],
            ],
            ..Survey::default()
        })
        .unwrap();
        // top 3: weights 1, 0.1, 0.1 → (1, 1) / 1.2
        let estimated = db.estimate_anchor_positions(3).unwrap();
        let s = estimated[0].unwrap();
        assert!((s[0] - 1.0 / 1.2).abs() < 1e-12 && (s[1] - 1.0 / 1.2).abs() < 1e-12);
        // anchor 1 is heard only at point 0
        assert_eq!(estimated[1], Some([0.0, 0.0]));
        // known positions are kept
        let db = db.with_estimated_anchors(3).unwrap();
        assert_eq!(db.anchors_m()[1], Some([7.0, 7.0]));
        assert!(db.anchors_m()[0].is_some());
        assert!(db.estimate_anchor_positions(0).is_err());
    }
}
