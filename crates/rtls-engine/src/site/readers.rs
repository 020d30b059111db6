//! The site's readers (anchors, base stations, access points) and their radio parameters.

use serde::Deserialize;

/// Radio technology of a reader.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Technology {
    /// Ultra-wideband (ranges, TDOA).
    Uwb,
    /// Bluetooth Low Energy (RSSI).
    Ble,
    /// Wi-Fi (RSSI, fingerprints, round-trip time).
    Wifi,
    /// Active or passive RFID (RSSI, presence).
    Rfid,
    /// Cellular base station (RSSI, TDOA).
    Cellular,
    /// Ultrasonic time-of-flight ranges.
    Ultrasonic,
}

impl Technology {
    /// The prior standard deviation of an uncalibrated reader's range offset, m, when neither
    /// the reader (`radio.range.offset_std_m`) nor the site (`tracker.range_bias.prior_std_m`)
    /// states one: UWB two-way ranging 0.2 (antenna delays leave ranges 0.1–0.3 m long); Wi-Fi
    /// round-trip time 1.5 (fine-time-measurement offsets of 0.5–3 m per responder and phone
    /// model); ultrasonic 0.05 (a transducer's delay of tens of µs at 343 m/s); BLE and RFID
    /// ranges (phase or channel sounding) 0.5; cellular 10 (a base station's timing offset).
    #[must_use]
    pub fn range_offset_prior_std_m(self) -> f64 {
        match self {
            Self::Uwb => 0.2,
            Self::Wifi => 1.5,
            Self::Ultrasonic => 0.05,
            Self::Ble | Self::Rfid => 0.5,
            Self::Cellular => 10.0,
        }
    }
}

/// One fixed reader / anchor.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reader {
    /// Unique id, as used by measurement records.
    pub id: String,
    /// Position `[x, y]` or `[x, y, z]`, m (site frame).
    pub position_m: Vec<f64>,
    /// Radio technology.
    pub technology: Technology,
    /// `false` for a broken reader: its measurements are ignored and its coverage is a hole
    /// (seed 000's hazard example). Default `true`.
    #[serde(default = "yes")]
    pub working: bool,
    /// Radio parameters, when known.
    #[serde(default)]
    pub radio: Option<Radio>,
}

pub(super) fn yes() -> bool {
    true
}

impl Reader {
    /// The position as `[x, y, z]`, m; a 2-D reader (`[x, y]`) is placed at `z = 0`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::{Reader, Technology};
    /// let reader = Reader {
    ///     id: "A".into(),
    ///     position_m: vec![1.0, 2.0],
    ///     technology: Technology::Ble,
    ///     working: true,
    ///     radio: None,
    /// };
    /// assert_eq!(reader.position_xyz_m(), [1.0, 2.0, 0.0]);
    /// ```
    #[must_use]
    pub fn position_xyz_m(&self) -> [f64; 3] {
        let at = |k: usize| self.position_m.get(k).copied().unwrap_or(0.0);
        [at(0), at(1), at(2)]
    }
}

/// A reader's radio parameters (both parts optional).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Radio {
    /// Log-distance path-loss model for RSSI.
    #[serde(default)]
    pub path_loss: Option<PathLoss>,
    /// Range error model for time-of-flight ranges.
    #[serde(default)]
    pub range: Option<RangeErrors>,
    /// The weakest RSSI the reader reports, dBm. With it and a `path_loss`, a working reader
    /// that does not hear a tag it should have heard is evidence that the tag is farther away
    /// (`tracker.negative_information`; seed 000).
    #[serde(default)]
    pub sensitivity_dbm: Option<f64>,
}

/// Log-distance path loss: `P(d) = reference_power_dbm − 10·exponent·log10(d / d₀) + X`,
/// `X ~ N(0, shadowing_std_db²)`.
///
/// # References
/// T. S. Rappaport, *Wireless Communications*, 2nd ed., §4.9 (log-distance path loss).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathLoss {
    /// Received power at the reference distance, dBm.
    pub reference_power_dbm: f64,
    /// Path-loss exponent (> 0; 2 in free space, 1.6–6 indoors and underground).
    pub exponent: f64,
    /// Log-normal shadowing, dB (1σ, ≥ 0).
    pub shadowing_std_db: f64,
    /// Reference distance `d₀`, m (> 0).
    pub reference_distance_m: f64,
}

/// Range measurement errors: `r = scale · d + bias_m + N(0, range_std_m²)`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeErrors {
    /// Range noise, m (1σ, > 0).
    pub range_std_m: f64,
    /// Constant range bias, m (subtracted before use).
    pub bias_m: f64,
    /// Range scale (0.5 to 2; default 1): a pair whose antenna, cable or clock calibration
    /// is off by a fraction reads every distance that fraction long or short. A range is used
    /// as `(r − bias_m) / scale`, with its noise divided by `scale`. Ranges only: a TDOA
    /// difference is taken as it comes. `rtls tune --truth` fits it.
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// The standard deviation of this reader's range offset that remains after `bias_m`, m
    /// (> 0): the prior of the offset a track learns (`[tracker.range_bias]`). `None` (the
    /// default): `tracker.range_bias.prior_std_m`, or the reader's technology's default
    /// ([`Technology::range_offset_prior_std_m`]). `rtls tune --truth` writes it from the
    /// spread of the calibrated offset over the calibration recording.
    #[serde(default)]
    pub offset_std_m: Option<f64>,
}

fn unit_scale() -> f64 {
    1.0
}
