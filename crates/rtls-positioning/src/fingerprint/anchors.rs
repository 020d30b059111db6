//! Anchor (access-point) positions estimated from the survey itself, for sites whose anchor
//! positions are unknown (Wi-Fi access points of a building, UJIIndoorLoc).

use super::database::FingerprintDatabase;
use crate::error::{PositioningError, Result};

impl FingerprintDatabase {
    /// Estimates the position of every anchor from the survey: the weighted centroid of the
    /// `strongest` reference points that hear it loudest, weighted by received power in
    /// milliwatts.
    ///
    /// For anchor `x` with heard set `L_x` sorted by decreasing `ρ_{l,x}`, keep the first
    /// `m = strongest` points, and
    ///
    /// `w_l = 10^{(ρ_{l,x} − ρ_max)/10}`, `Ŝ_x = Σ w_l P_l / Σ w_l`
    ///
    /// (`ρ_max` only rescales the weights, avoiding underflow). An anchor heard nowhere stays
    /// `None`. Known positions are not changed (see
    /// [`FingerprintDatabase::with_estimated_anchors`]). The estimate is biased towards the
    /// surveyed area and has the survey's resolution; it serves the coarse spatial step of
    /// L-WKNN, not ranging.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`strongest`) if `strongest` is 0.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, Survey};
    /// let db = FingerprintDatabase::from_survey(Survey {
    ///     reference_points_m: vec![[0.0, 0.0], [10.0, 0.0], [50.0, 0.0]],
    ///     anchor_count: 2,
    ///     readings_dbm: vec![vec![(0, -40.0)], vec![(0, -40.0)], vec![(0, -90.0)]],
    ///     ..Survey::default()
    /// })?;
    /// let estimated = db.estimate_anchor_positions(2)?;
    /// assert_eq!(estimated, vec![Some([5.0, 0.0]), None]); // anchor 1 is heard nowhere
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// J. Blumenthal et al., "Weighted centroid localization in Zigbee-based sensor networks",
    /// IEEE WISP 2007 (power-weighted centroid); seed 002 §1.2 step (2) needs the anchor
    /// positions.
    pub fn estimate_anchor_positions(&self, strongest: usize) -> Result<Vec<Option<[f64; 2]>>> {
        if strongest == 0 {
            return Err(PositioningError::InvalidParameter {
                name: "strongest",
                reason: "at least one reference point must locate each anchor",
            });
        }
        // per anchor: (ρ, l) of every reference point that hears it
        let mut heard_at: Vec<Vec<(f64, usize)>> = vec![Vec::new(); self.anchor_count()];
        for l in 0..self.reference_point_count() {
            for &(x, rssi_dbm) in self.row(l) {
                heard_at[x as usize].push((rssi_dbm, l));
            }
        }
        Ok(heard_at
            .into_iter()
            .map(|mut points| {
                if points.is_empty() {
                    return None;
                }
                points.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                points.truncate(strongest);
                let strongest_dbm = points[0].0;
                let (mut sum_w, mut sum_x, mut sum_y) = (0.0, 0.0, 0.0);
                for &(rssi_dbm, l) in &points {
                    // w_l = 10^{(ρ − ρ_max)/10}
                    let w = 10f64.powf((rssi_dbm - strongest_dbm) / 10.0);
                    let p = self.reference_points_m()[l];
                    sum_w += w;
                    sum_x += w * p[0];
                    sum_y += w * p[1];
                }
                // Ŝ = Σ w P / Σ w  (sum_w ≥ 1: the strongest point has w = 1)
                Some([sum_x / sum_w, sum_y / sum_w])
            })
            .collect())
    }

    /// The same database with every unknown anchor position replaced by its estimate from
    /// [`FingerprintDatabase::estimate_anchor_positions`] (known positions are kept).
    ///
    /// # Errors
    /// As [`FingerprintDatabase::estimate_anchor_positions`].
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::{FingerprintDatabase, Survey};
    /// let db = FingerprintDatabase::from_survey(Survey {
    ///     reference_points_m: vec![[0.0, 0.0], [10.0, 0.0]],
    ///     anchor_count: 1,
    ///     readings_dbm: vec![vec![(0, -40.0)], vec![(0, -70.0)]],
    ///     ..Survey::default()
    /// })?
    /// .with_estimated_anchors(1)?;
    /// assert_eq!(db.anchors_m(), &[Some([0.0, 0.0])]);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn with_estimated_anchors(mut self, strongest: usize) -> Result<Self> {
        let estimated = self.estimate_anchor_positions(strongest)?;
        for (known, estimate) in self.anchors_mut().iter_mut().zip(estimated) {
            if known.is_none() {
                *known = estimate;
            }
        }
        Ok(self)
    }
}
