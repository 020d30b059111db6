//! What the end-of-epoch constraints know ([`Constraints`]: the corridor map, the listening
//! readers, zones without coverage, the speed limit — shared by every track) and a track's open
//! epoch ([`Hearing`]); the `constraints` module applies them.

use super::anchors::{AnchorReading, Anchors};
use super::models::{AnchorLaw, AnchorMeasurement};
use crate::corridors::CorridorMap;
use crate::site::Site;
use crate::zones::Zone;

/// Smallest variance of a silence pseudo-measurement, dB² (a reader stated with no shadowing).
pub(super) const MIN_SILENCE_VARIANCE_DB2: f64 = 0.25;

/// The end-of-epoch knowledge shared by every track.
#[derive(Debug, Clone)]
pub(crate) struct Constraints {
    /// The corridors (empty: no map constraint, every reader in line of sight).
    pub(super) map: CorridorMap,
    /// `σ_lat` when set; else each corridor's `half_width / √3`.
    pub(super) lateral_std_m: Option<f64>,
    /// `r_J`, m.
    pub(super) junction_radius_m: f64,
    /// `σ_z` of a tag's height about its corridor's, m (3-D tracking).
    pub(super) vertical_std_m: f64,
    /// Whether the map constraint is applied.
    pub(super) map_enabled: bool,
    /// Anchors used as negative information: `(index, S dBm, its RSSI model with R = σ_X²)`,
    /// built once (no allocation per epoch).
    pub(super) listeners: Vec<(usize, f64, AnchorMeasurement)>,
    /// `v_max`, m/s.
    pub(super) max_speed_mps: Option<f64>,
    /// Zones without coverage, which shield the radio.
    pub(super) shadows: Vec<Zone>,
}

impl Constraints {
    /// The constraints `site` asks for, or `None` when it asks for none. `shadows` are the
    /// site's zones without coverage (the tracker's alarm zones of that kind).
    pub(crate) fn new(site: &Site, anchors: &Anchors, shadows: Vec<Zone>) -> Option<Self> {
        let settings = &site.tracker;
        let map = CorridorMap::new(&site.corridors);
        let map_enabled = settings.map.enabled && !map.is_empty();
        let tag_height_m = settings.tag_height_m.unwrap_or(0.0);
        let listeners: Vec<(usize, f64, AnchorMeasurement)> = if settings.negative_information {
            anchors
                .iter()
                .enumerate()
                .filter(|(_, a)| a.working)
                .filter_map(|(i, a)| {
                    let ([p0, d0, n, shadowing_db], sensitivity_dbm) = (a.path_loss?, a.sensitivity_dbm?);
                    let law = AnchorLaw::LogDistance {
                        reference_power_dbm: p0,
                        reference_distance_m: d0,
                        exponent: n,
                    };
                    let variance = (shadowing_db * shadowing_db).max(MIN_SILENCE_VARIANCE_DB2);
                    let model = AnchorMeasurement::new(a.position_m, tag_height_m, law, variance);
                    Some((i, sensitivity_dbm, model))
                })
                .collect()
        } else {
            Vec::new()
        };
        if !map_enabled && listeners.is_empty() && settings.max_speed_mps.is_none() {
            return None;
        }
        let widest_m = site.corridors.iter().map(|c| c.half_width_m).fold(0.0, f64::max);
        Some(Self {
            map,
            lateral_std_m: settings.map.lateral_std_m,
            junction_radius_m: settings.map.junction_radius_m.unwrap_or(2.0 * widest_m),
            vertical_std_m: settings.map.vertical_std_m,
            map_enabled,
            listeners,
            max_speed_mps: settings.max_speed_mps,
            shadows,
        })
    }

    /// Whether a reader at `reader_m` is expected to hear a tag at `tag_m`: in line of sight
    /// through the corridors and with no zone without coverage in between.
    pub(super) fn audible(&self, tag_m: [f64; 3], reader_m: [f64; 3]) -> bool {
        if !self.map.line_of_sight([tag_m[0], tag_m[1]], [reader_m[0], reader_m[1]]) {
            return false;
        }
        if self.shadows.is_empty() {
            return true;
        }
        // samples every 0.5 m along the line, ends included
        let length_m = (0..3).map(|k| (reader_m[k] - tag_m[k]).powi(2)).sum::<f64>().sqrt();
        let steps = (length_m / SHADOW_STEP_M).ceil().clamp(1.0, 1e5) as usize;
        !(0..=steps).any(|k| {
            let t = k as f64 / steps as f64;
            let p = [0, 1, 2].map(|a| tag_m[a] + t * (reader_m[a] - tag_m[a]));
            self.shadows.iter().any(|z| z.contains(p))
        })
    }
}

/// Spacing of the samples of a line tested against zones without coverage, m.
pub(super) const SHADOW_STEP_M: f64 = 0.5;

/// A track's open epoch: when it opened and which readers heard the tag in it.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct Hearing {
    pub(super) open_since_s: Option<f64>,
    pub(super) heard: Vec<usize>,
    /// The epoch's anchor readings (a track found in the wrong corridor restarts at their fix).
    pub(super) readings: Vec<AnchorReading>,
}

impl Hearing {
    /// A record at `time_s`, with its anchor reading when it came from a reader.
    pub(super) fn heard(&mut self, time_s: f64, reading: Option<AnchorReading>) {
        self.open_since_s.get_or_insert(time_s);
        if let Some(reading) = reading {
            let anchor = reading.anchor();
            if !self.heard.contains(&anchor) {
                self.heard.push(anchor);
            }
            self.readings.push(reading);
        }
    }

    /// An update applied at `time_s` (opens the epoch if none is open).
    pub(super) fn updated(&mut self, time_s: f64) {
        self.open_since_s.get_or_insert(time_s);
    }
}
