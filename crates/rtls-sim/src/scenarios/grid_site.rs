//! A seed-002-style fingerprint site of any size: anchors on a square grid, reference points on
//! a finer grid, a log-distance radio and a receiver sensitivity below which an anchor is not
//! heard. [`GridSite::ujiindoorloc_size`] has UJIIndoorLoc's dimensions (520 anchors, ≈ 20 000
//! reference points), for benchmarking L-WKNN against global WKNN where the anchor positions
//! are exactly known.

use rand::Rng;
use rtls_positioning::fingerprint::{SignalDistance, SignalRepresentation, SignalSpace, Survey};

use crate::error::{finite2, positive, Result, SimError};
use crate::sensors::LogDistanceRadio;

/// A rectangular site `[0, width] × [0, height]` (m).
///
/// - anchors every `anchor_spacing_m`, the first half a spacing from the walls (seed 002:
///   20 m, 10 m from the walls);
/// - reference points every `reference_spacing_m`, from the corner `(0, 0)`;
/// - readings below `sensitivity_dbm` are absent (the anchor is not heard).
///
/// # Example
/// ```
/// let site = rtls_sim::GridSite::ujiindoorloc_size();
/// assert_eq!(site.anchors_m().len(), 520);
/// assert_eq!(site.reference_points_m().len(), 19_964); // UJIIndoorLoc: 19 937
/// ```
///
/// # References
/// Seed 002 §2 (grid site, log-distance radio); Torres-Sospedra et al., IPIN 2014 (the
/// UJIIndoorLoc dimensions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSite {
    /// Site width (m).
    pub width_m: f64,
    /// Site height (m).
    pub height_m: f64,
    /// Anchor grid spacing (m).
    pub anchor_spacing_m: f64,
    /// Reference-point grid spacing (m).
    pub reference_spacing_m: f64,
    /// Weakest reading the receiver reports (dBm).
    pub sensitivity_dbm: f64,
    /// The radio.
    pub radio: LogDistanceRadio,
}

impl GridSite {
    /// Seed 002's simulated field: 100 m × 100 m, 25 anchors on a 20 m grid (5 × 5, at 10, 30,
    /// …, 90 m), 121 reference points on a 10 m grid, `ρ = 0 − 40 log10(d)` dBm; every anchor is
    /// heard everywhere (sensitivity far below the weakest mean RSSI, −64 dBm at the far corner).
    ///
    /// # Example
    /// ```
    /// let site = rtls_sim::GridSite::seed_002();
    /// assert_eq!(site.anchors_m(), rtls_sim::SEED_002_ANCHORS.to_vec());
    /// assert_eq!(site.reference_points_m(), rtls_sim::seed_002_reference_points());
    /// ```
    ///
    /// # References
    /// Seed 002 §2 (simulation setup).
    #[must_use]
    pub fn seed_002() -> Self {
        Self {
            width_m: 100.0,
            height_m: 100.0,
            anchor_spacing_m: 20.0,
            reference_spacing_m: 10.0,
            sensitivity_dbm: -150.0,
            radio: LogDistanceRadio::default(),
        }
    }

    /// UJIIndoorLoc's size with seed 002's layout: 520 m × 400 m, anchors every 20 m
    /// (26 × 20 = 520), reference points every 3.25 m (161 × 124 = 19 964), seed 002's radio
    /// (`ρ_T = 0 dBm`, `η = 4`), sensitivity −85 dBm (anchors heard within 133 m, about 140 per
    /// place).
    #[must_use]
    pub fn ujiindoorloc_size() -> Self {
        Self {
            width_m: 520.0,
            height_m: 400.0,
            anchor_spacing_m: 20.0,
            reference_spacing_m: 3.25,
            sensitivity_dbm: -85.0,
            radio: LogDistanceRadio::default(),
        }
    }

    /// Seed 002's signal space (Euclidean on dBm) with "not heard" at this site's receiver
    /// sensitivity: an anchor heard just above it and missed just below it then differ by
    /// little, as they should. (A floor far below the sensitivity turns every such miss into a
    /// large distance: with −150 dBm the mean L-WKNN error on
    /// [`GridSite::ujiindoorloc_size`] rose from 2.3 m to 9.2 m, `docs/FINGERPRINTING.md`.)
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::SignalRepresentation;
    /// let site = rtls_sim::GridSite::ujiindoorloc_size();
    /// assert_eq!(site.signal_space().representation, SignalRepresentation::Positive { floor_dbm: -85.0 });
    /// ```
    #[must_use]
    pub fn signal_space(&self) -> SignalSpace {
        SignalSpace {
            representation: SignalRepresentation::Positive {
                floor_dbm: self.sensitivity_dbm,
            },
            distance: SignalDistance::Euclidean,
        }
    }

    /// Anchor positions (m), row by row.
    #[must_use]
    pub fn anchors_m(&self) -> Vec<[f64; 2]> {
        grid(
            self.width_m,
            self.height_m,
            self.anchor_spacing_m,
            0.5 * self.anchor_spacing_m,
        )
    }

    /// Reference point positions (m), row by row.
    #[must_use]
    pub fn reference_points_m(&self) -> Vec<[f64; 2]> {
        grid(self.width_m, self.height_m, self.reference_spacing_m, 0.0)
    }

    /// The offline survey: at every reference point, one reading per anchor with shadowing of
    /// variance `variance_db2` (dB²), kept if at or above the sensitivity.
    ///
    /// # Errors
    /// The radio's errors; [`SimError::InvalidParameter`] for non-positive spacings.
    pub fn survey(&self, variance_db2: f64, rng: &mut impl Rng) -> Result<Survey> {
        self.validate()?;
        let anchors_m = self.anchors_m();
        let reference_points_m = self.reference_points_m();
        let readings_dbm = reference_points_m
            .iter()
            .map(|&p| self.heard(&anchors_m, p, variance_db2, rng))
            .collect::<Result<Vec<_>>>()?;
        Ok(Survey {
            reference_points_m,
            floors: None,
            buildings: None,
            anchor_count: anchors_m.len(),
            anchors_m: Some(anchors_m.into_iter().map(Some).collect()),
            readings_dbm,
        })
    }

    /// An online query at `point_m`: one entry per anchor, `None` below the sensitivity.
    ///
    /// # Errors
    /// As [`GridSite::survey`]; [`SimError::NonFinite`] for a NaN/∞ point.
    pub fn query(&self, point_m: [f64; 2], variance_db2: f64, rng: &mut impl Rng) -> Result<Vec<Option<f64>>> {
        self.validate()?;
        let anchors_m = self.anchors_m();
        let mut query = vec![None; anchors_m.len()];
        for (anchor, rssi_dbm) in self.heard(&anchors_m, finite2(point_m, "point")?, variance_db2, rng)? {
            query[anchor] = Some(rssi_dbm);
        }
        Ok(query)
    }

    /// `(anchor, ρ)` of the anchors heard at `point_m`.
    fn heard(
        &self,
        anchors_m: &[[f64; 2]],
        point_m: [f64; 2],
        variance_db2: f64,
        rng: &mut impl Rng,
    ) -> Result<Vec<(usize, f64)>> {
        let readings = self.radio.measure(anchors_m, point_m, variance_db2, rng)?;
        Ok(readings
            .into_iter()
            .enumerate()
            .filter(|&(_, rssi_dbm)| rssi_dbm >= self.sensitivity_dbm)
            .collect())
    }

    /// Checks the fields (for a site whose public fields were set directly).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a non-positive size or spacing, a spacing that gives
    /// no point inside the site or over 10⁷ points; [`SimError::NonFinite`] for a NaN/∞ sensitivity.
    pub fn validate(&self) -> Result<()> {
        positive(self.width_m, "width_m", "the site must have a positive width")?;
        positive(self.height_m, "height_m", "the site must have a positive height")?;
        positive(
            self.anchor_spacing_m,
            "anchor_spacing_m",
            "the spacing must be positive",
        )?;
        positive(
            self.reference_spacing_m,
            "reference_spacing_m",
            "the spacing must be positive",
        )?;
        if self.sensitivity_dbm.is_finite() {
            Ok(())
        } else {
            Err(SimError::NonFinite {
                what: "sensitivity_dbm",
            })
        }
    }
}

/// Points `offset + k·spacing` within `[0, width] × [0, height]`, row by row.
fn grid(width_m: f64, height_m: f64, spacing_m: f64, offset_m: f64) -> Vec<[f64; 2]> {
    let count = |side: f64| ((side - offset_m) / spacing_m + 1e-9).floor() as usize + 1;
    let (columns, rows) = (count(width_m), count(height_m));
    (0..rows)
        .flat_map(|r| (0..columns).map(move |c| [offset_m + c as f64 * spacing_m, offset_m + r as f64 * spacing_m]))
        .filter(|p| p[0] <= width_m && p[1] <= height_m)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn seed_002_layout_is_reproduced_at_its_own_size() {
        let site = GridSite {
            width_m: 100.0,
            height_m: 100.0,
            anchor_spacing_m: 20.0,
            reference_spacing_m: 10.0,
            sensitivity_dbm: -200.0,
            radio: LogDistanceRadio::default(),
        };
        assert_eq!(site.anchors_m(), crate::SEED_002_ANCHORS.to_vec());
        assert_eq!(site.reference_points_m(), crate::seed_002_reference_points());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let survey = site.survey(1.0, &mut rng).unwrap();
        assert!(survey.readings_dbm.iter().all(|row| row.len() == 25));
    }

    #[test]
    fn readings_below_the_sensitivity_are_absent() {
        let site = GridSite::ujiindoorloc_size();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let query = site.query([260.0, 200.0], 0.0, &mut rng).unwrap();
        let anchors = site.anchors_m();
        for (a, reading) in anchors.iter().zip(&query) {
            let d = ((a[0] - 260.0f64).powi(2) + (a[1] - 200.0f64).powi(2)).sqrt();
            // heard ⇔ −40 lg d ≥ −85 ⇔ d ≤ 10^(85/40) = 133.4 m
            assert_eq!(reading.is_some(), d <= 10f64.powf(85.0 / 40.0), "anchor {a:?}, d = {d}");
        }
        assert!(site.query([f64::NAN, 0.0], 0.0, &mut rng).is_err());
        let bad = GridSite {
            reference_spacing_m: 0.0,
            ..site
        };
        assert!(bad.survey(1.0, &mut rng).is_err());
    }
}
