//! A fingerprint database represented in one signal space, ready for queries.

use super::database::FingerprintDatabase;
use super::signal::{sparse_distance, SignalSpace, SparseFingerprint};
use crate::error::{PositioningError, Result};

/// A [`FingerprintDatabase`] with every reading represented once in a [`SignalSpace`]; the
/// object every matcher ([`super::Knn`], [`super::LocalWknn`]) queries.
///
/// Represented rows are stored sparsely (only heard anchors, `ψ > 0` or not), so a distance
/// costs one merge of the query's heard anchors with the row's: `O(|H_q| + |H_l|)`.
///
/// # Errors
/// See [`FingerprintIndex::new`].
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, SignalSpace};
/// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-40.0]])?;
/// let index = FingerprintIndex::new(db, SignalSpace::default())?;
/// assert_eq!(index.database().reference_point_count(), 1);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Torres-Sospedra et al. (2015) (representations and distances); seed 002 §1.2.
#[derive(Debug, Clone)]
pub struct FingerprintIndex {
    database: FingerprintDatabase,
    space: SignalSpace,
    /// `(anchor, ψ_{l,x})`, same layout as the database's compressed rows.
    represented: Vec<(u32, f64)>,
}

impl FingerprintIndex {
    /// Represents every reading of `database` in `space`.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] for invalid representation parameters;
    /// [`PositioningError::RssiBelowFloor`] naming the first reading below the floor
    /// (row = reference point, column = anchor); [`PositioningError::NonFinite`] if a
    /// representation overflows.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::{fingerprint::{FingerprintDatabase, FingerprintIndex, SignalSpace}, PositioningError};
    /// let db = FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![-110.0]])?;
    /// let wifi = FingerprintIndex::new(db, SignalSpace::powed_sorensen()); // floor −104 dBm
    /// assert!(matches!(wifi, Err(PositioningError::RssiBelowFloor { row: 0, column: 0, .. })));
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn new(database: FingerprintDatabase, space: SignalSpace) -> Result<Self> {
        space.representation.validate()?;
        let (row_start, readings) = database.compressed_rows();
        let mut represented = Vec::with_capacity(readings.len());
        for row in 0..row_start.len() - 1 {
            for &(anchor, rssi_dbm) in &readings[row_start[row]..row_start[row + 1]] {
                let psi = represent(
                    &space,
                    rssi_dbm,
                    "fingerprint rssi (row = reference point, column = anchor)",
                    row,
                    anchor as usize,
                )?;
                represented.push((anchor, psi));
            }
        }
        Ok(Self {
            database,
            space,
            represented,
        })
    }

    /// The database.
    #[inline]
    #[must_use]
    pub fn database(&self) -> &FingerprintDatabase {
        &self.database
    }

    /// The signal space.
    #[inline]
    #[must_use]
    pub fn space(&self) -> &SignalSpace {
        &self.space
    }

    /// Represents a query (`measured_dbm[x]` = RSSI of anchor `x`, `None` = not heard) as the
    /// sparse list of heard anchors.
    ///
    /// # Errors
    /// [`PositioningError::DimensionMismatch`] unless there is one entry per anchor;
    /// [`PositioningError::NonFiniteEntry`] (row 0, column = anchor) for a NaN/∞ reading;
    /// [`PositioningError::RssiBelowFloor`] (row 0, column = anchor);
    /// [`PositioningError::NoCommonAnchors`] if nothing is heard.
    pub(crate) fn represent_query(&self, measured_dbm: &[Option<f64>]) -> Result<Vec<(u32, f64)>> {
        if measured_dbm.len() != self.database.anchor_count() {
            return Err(PositioningError::DimensionMismatch {
                what: "measured rssi (one entry per database anchor)",
                expected: self.database.anchor_count(),
                found: measured_dbm.len(),
            });
        }
        let mut heard = Vec::new();
        for (anchor, reading) in measured_dbm.iter().enumerate() {
            if let Some(rssi_dbm) = *reading {
                let psi = represent(
                    &self.space,
                    rssi_dbm,
                    "measured rssi (row 0, column = anchor)",
                    0,
                    anchor,
                )?;
                heard.push((anchor as u32, psi));
            }
        }
        if heard.is_empty() {
            return Err(PositioningError::NoCommonAnchors);
        }
        Ok(heard)
    }

    /// The represented fingerprint of reference point `l` (heard anchors, increasing anchor),
    /// usable as a query.
    #[inline]
    pub(crate) fn represented_row(&self, reference_point: usize) -> &SparseFingerprint {
        let (row_start, _) = self.database.compressed_rows();
        &self.represented[row_start[reference_point]..row_start[reference_point + 1]]
    }

    /// Signal-space distance from a represented query to reference point `l`, and whether
    /// they share a heard anchor.
    #[inline]
    pub(crate) fn distance(&self, query: &SparseFingerprint, reference_point: usize) -> (f64, bool) {
        sparse_distance(self.space.distance, query, self.represented_row(reference_point))
    }
}

/// `ψ(ρ)` with the error naming the table, row and column.
fn represent(space: &SignalSpace, rssi_dbm: f64, what: &'static str, row: usize, column: usize) -> Result<f64> {
    if !rssi_dbm.is_finite() {
        return Err(PositioningError::NonFiniteEntry { what, row, column });
    }
    let floor_dbm = space.representation.floor_dbm();
    if rssi_dbm < floor_dbm {
        return Err(PositioningError::RssiBelowFloor {
            what,
            row,
            column,
            rssi_dbm,
            floor_dbm,
        });
    }
    space.representation.value_above_floor(rssi_dbm)
}
