//! The offline fingerprint database: reference points, anchors and the mean RSSI map.

use crate::error::{PositioningError, Result};

/// An RSSI fingerprint map surveyed offline: reference points `P_l` (m), anchors `S_x` (m),
/// and at each reference point the mean RSSI `ρ_{l,x}` (dBm) of every anchor.
///
/// Every database value is present (a reference point that does not hear an anchor should be
/// surveyed with the receiver's floor value, e.g. −100 dBm); absence is only allowed in
/// queries (see [`super::Wknn`]). The RSSI map is stored row-major, one contiguous row per
/// reference point, so a signal-space distance reads one slice.
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
/// assert_eq!(db.fingerprint_dbm(1), Some(&[-70.0, -30.0, -65.0][..]));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002, §1.2: `N` reference points `P_l`, `N_s` anchors `S_i`, fingerprint `ρ_l` = mean
/// RSSI vector at `P_l`.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerprintDatabase {
    reference_points_m: Vec<[f64; 2]>,
    anchors_m: Vec<[f64; 2]>,
    /// `ρ_{l,x}` at `l · N_s + x`.
    rssi_dbm: Vec<f64>,
}

impl FingerprintDatabase {
    /// Builds and validates a database from reference points, anchors and one RSSI row per
    /// reference point (one value per anchor, dBm).
    ///
    /// # Errors
    /// - [`PositioningError::EmptyDatabase`] with no reference points or no anchors;
    /// - [`PositioningError::DimensionMismatch`] unless there is one RSSI row per reference
    ///   point;
    /// - [`PositioningError::RowLength`] naming the first row without one value per anchor;
    /// - [`PositioningError::NonFiniteEntry`] naming the first NaN/∞ reference-point
    ///   coordinate (row = reference point, column = axis), anchor coordinate (row = anchor,
    ///   column = axis) or RSSI (row = reference point, column = anchor).
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
        if reference_points_m.is_empty() || anchors_m.is_empty() {
            return Err(PositioningError::EmptyDatabase);
        }
        first_non_finite(
            &reference_points_m,
            "reference point positions (row = reference point, column = axis)",
        )?;
        first_non_finite(&anchors_m, "anchor positions (row = anchor, column = axis)")?;
        if rssi_dbm.len() != reference_points_m.len() {
            return Err(PositioningError::DimensionMismatch {
                what: "fingerprint rssi rows (one per reference point)",
                expected: reference_points_m.len(),
                found: rssi_dbm.len(),
            });
        }
        let anchors = anchors_m.len();
        let mut flat = Vec::with_capacity(reference_points_m.len() * anchors);
        for (row, values) in rssi_dbm.iter().enumerate() {
            if values.len() != anchors {
                return Err(PositioningError::RowLength {
                    what: "fingerprint rssi (one value per anchor)",
                    row,
                    expected: anchors,
                    found: values.len(),
                });
            }
            if let Some(column) = values.iter().position(|v| !v.is_finite()) {
                return Err(PositioningError::NonFiniteEntry {
                    what: "fingerprint rssi (row = reference point, column = anchor)",
                    row,
                    column,
                });
            }
            flat.extend_from_slice(values);
        }
        Ok(Self {
            reference_points_m,
            anchors_m,
            rssi_dbm: flat,
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

    /// Anchor positions `S_x` (m), in column order.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[1.0, 2.0]], vec![[0.0, 5.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.anchors_m(), &[[0.0, 5.0]]);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn anchors_m(&self) -> &[[f64; 2]] {
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

    /// The fingerprint `ρ_l` (dBm, one value per anchor) of reference point `l`, or `None` if
    /// `l` is out of range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::FingerprintDatabase;
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
    /// assert_eq!(db.fingerprint_dbm(0), Some(&[-40.0][..]));
    /// assert_eq!(db.fingerprint_dbm(1), None);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[inline]
    #[must_use]
    pub fn fingerprint_dbm(&self, reference_point: usize) -> Option<&[f64]> {
        let n = self.anchors_m.len();
        self.rssi_dbm.get(reference_point * n..(reference_point + 1) * n)
    }

    /// `ρ_{l,x}` for in-range indices (internal; callers index within bounds).
    #[inline]
    pub(crate) fn rssi_row(&self, reference_point: usize) -> &[f64] {
        let n = self.anchors_m.len();
        &self.rssi_dbm[reference_point * n..(reference_point + 1) * n]
    }
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
    type Survey = (Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<Vec<f64>>);

    fn two_by_two() -> Survey {
        (
            vec![[0.0, 0.0], [10.0, 0.0]],
            vec![[0.0, 0.0], [10.0, 0.0]],
            vec![vec![-30.0, -70.0], vec![-70.0, -30.0]],
        )
    }

    #[test]
    fn rows_are_stored_per_reference_point() {
        let (p, a, rssi) = two_by_two();
        let db = FingerprintDatabase::new(p, a, rssi).unwrap();
        assert_eq!(db.rssi_row(0), &[-30.0, -70.0]);
        assert_eq!(db.rssi_row(1), &[-70.0, -30.0]);
        assert_eq!(db.fingerprint_dbm(2), None);
        assert_eq!(db.anchor_count(), 2);
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
        bad_anchors[0][1] = f64::INFINITY;
        assert!(matches!(
            FingerprintDatabase::new(p, bad_anchors, rssi),
            Err(PositioningError::NonFiniteEntry { row: 0, column: 1, what }) if what.starts_with("anchor")
        ));
    }
}
