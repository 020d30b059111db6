//! Radio-environment survey: where obstacles degrade the radio links (seed 000's obstacle
//! analysis), learned from the measurements and the tracks they produced.
//!
//! Seed 000 observes that equipment near readers attenuates the signal and biases the fixes,
//! and that analysing the positioning data reveals where the obstacles are. The survey does
//! this in three steps:
//!
//! 1. **Residuals** ([`residuals`]): every range or RSSI measurement of a tag is compared with
//!    the value the site's model expects at the tag's *tracked* position at that time (the
//!    track's non-predicted updates, interpolated linearly in time):
//!    - range: `e = (r − b) − ‖p − a‖`, with `b` the reader's configured `radio.range.bias_m`
//!      (0 when absent) — positive for a non-line-of-sight excess path;
//!    - RSSI: `e = ρ − (P₀ − 10 n log₁₀(d / d₀))`, `d = ‖p − a‖`, with the reader's
//!      `radio.path_loss` law — negative for extra attenuation.
//!
//!    `p` is the tag's position (`x, y` from the track; `z` from the track in 3-D, else
//!    `tracker.tag_height_m`, else 0) and `a` the reader's, so `d` is the slant distance. RSSI
//!    vectors (fingerprint scans) give one RSSI residual per reading; TDOA and the other kinds
//!    give none. Nothing is dropped silently: each measurement without a residual is counted
//!    in [`Unmatched`] under its reason.
//! 2. **Map** ([`SurveyMap::build`]): residuals are accumulated (Welford, [`RunningStats`]) per
//!    (area cell, reader, kind) — cells are squares of `cell_size_m` on the `x, y` plane,
//!    indexed by the *tracked* position — and per (reader, kind): count `n`, mean (the bias)
//!    and standard deviation (the spread).
//! 3. **Flags**: an entry is compared with its population by a robust z score (Iglewicz &
//!    Hoaglin's modified z score, with a floor on the scale):
//!
//!    ```text
//!    m = median(bᵢ),  σ̂ = max(1.4826 · median(|bᵢ − m|), δ / z*),  z = (b − m) / σ̂
//!    ```
//!
//!    with `z*` = `z_threshold` and `δ` the minimum effect (`min_rssi_effect_db` or
//!    `min_range_effect_m`). Let `s = −1` for RSSI (attenuation lowers it) and `s = +1` for
//!    ranges (an excess path lengthens them). An entry is **degraded by its bias** when
//!    `n ≥ min_count`, `s·z ≥ z*` and `s·(b − m) ≥ δ`; the floor on `σ̂` makes the second
//!    condition imply the first when the population is tight (MAD ≈ 0), so neither a tiny
//!    MAD nor a tiny effect alone flags anything. With `flag_spread`, it is also **degraded by
//!    its spread** by the same rule applied to the standard deviations, upwards for both kinds
//!    (off by default: on RSSI, the cells where the tracker's position is wrong, e.g. off a
//!    tunnel's centre line, have abnormal spreads too; the spread z score is reported either
//!    way). The bias is relative to the population's median: a site-wide offset (a wrong `P₀`)
//!    is a calibration error, not an obstacle.
//!
//!    **Populations.** The entries of one kind and level with at least `min_count` residuals;
//!    cell entries are further split into bands of `distance_band_m` of their mean distance to
//!    their reader. A receiver's detection threshold lets only the stronger readings through
//!    far from a reader, so the residual bias of unobstructed cells grows with distance (in
//!    `tests/obstacles.rs`: median +0.4 dB within 20 m, +3.5 dB at 40–60 m); in one population
//!    the far cells would raise the median above that of the near cells, where obstacles'
//!    shadows are. A population of fewer than [`MIN_POPULATION`] entries is not scored
//!    (`z = None`, nothing flagged). A **reader** is also flagged (reason `cells`) when any of
//!    its cells is: an obstacle on one side of a reader shadows only some of its links, and its
//!    bias over all of them is diluted.
//!
//! The map exports CSV ([`SurveyMap::write_cells_csv`], [`SurveyMap::write_readers_csv`]),
//! reads it back ([`SurveyMap::from_csv`]) and serves as a bias-correction table:
//! [`SurveyMap::correction`] gives the learned bias of a reader at a position — its cell's
//! when that entry is flagged for its bias, else the reader's when that is, else none — and
//! [`SurveyMap::correct_record`] subtracts it from a record, given the tag's last known
//! position. Only flagged entries correct by default (`correct_unflagged` to use every entry
//! with `min_count` residuals): in `tests/obstacles.rs`, correcting with every entry made
//! the tracks worse (RMSE 3.63 → 4.28 m away from the obstacles), because cells where the
//! tracker's cross-track error put the tags learn that error and the correction confirms it,
//! while the flagged entries alone took the RMSE in the shadows from 7.18 to 6.04 m.
//!
//! # Units
//! Times in s, positions, distances, cell sizes and range residuals in m, RSSI residuals in
//! dB. A bias or a spread is in the unit of its kind ([`ResidualKind::unit`]).
//!
//! # Caveats
//! The track the residuals are computed against was itself estimated from the biased
//! measurements, so it is pulled towards agreeing with them and the learned biases understate
//! the true ones (in `tests/obstacles.rs`, about −6 dB learned for 8–12 dB of extra loss;
//! less when the tracker's gate rejects the worst readings). The detection threshold also
//! raises the mean of the weak readings that are heard, including attenuated ones.
//!
//! # Example
//! ```
//! use rtls_engine::evaluation::parse_track_lines;
//! use rtls_engine::record::{Measurement, Record};
//! use rtls_engine::site::Site;
//! use rtls_engine::survey::{residuals, ResidualKind, SurveyMap, SurveySettings};
//!
//! let site = Site::from_toml_str(r#"
//!     [[readers]]
//!     id = "R1"
//!     position_m = [0.0, 0.0]
//!     technology = "ble"
//!     radio = { path_loss = { reference_power_dbm = -40.0, exponent = 2.0, shadowing_std_db = 3.0, reference_distance_m = 1.0 } }
//!
//!     [tracker]
//!     pipeline = "tightly-coupled"
//!     motion_model = "cv"
//!     filter = "ekf"
//!     acceleration_noise_std_mps2 = 0.5
//!     gate_probability = 0.999
//!     initiation = { confirm_updates = 3, within_s = 5.0 }
//!     coast_timeout_s = 5.0
//!     delete_timeout_s = 60.0
//!     reorder_window_s = 0.0
//! "#, "site.toml")?;
//! // the tag is tracked from (5, 0) at t = 0 to (15, 0) at t = 1
//! let tracks = parse_track_lines(
//!     "{\"t\": 0, \"tag\": \"w\", \"x\": 5, \"y\": 0}\n{\"t\": 1, \"tag\": \"w\", \"x\": 15, \"y\": 0}\n",
//!     "tracks.jsonl",
//! )?;
//! // at t = 0.5 it is at (10, 0): the law expects −40 − 20 log₁₀ 10 = −60 dBm; −66 was heard
//! // (twice, so that the map has a spread)
//! let record = Record { time_s: 0.5, tag: "w".into(),
//!                       measurement: Measurement::Rssi { anchor: "R1".into(), rssi_dbm: -66.0 } };
//! // (one entry is no population to flag against: let unflagged entries correct too)
//! let settings = SurveySettings { min_count: 2, skip_initial_s: 0.0, correct_unflagged: true, ..SurveySettings::default() };
//! let found = residuals(&site, &[record.clone(), record.clone()], &tracks, &settings)?;
//! assert_eq!(found.unmatched.total(), 0);
//! assert!((found.residuals[0].value + 6.0).abs() < 1e-12);
//!
//! // the map learns −6 dB for R1 in the cell [10, 20) × [0, 10) and corrects the record
//! let map = SurveyMap::build(&found.residuals, &settings)?;
//! let correction = map.correction("R1", ResidualKind::Rssi, [12.0, 3.0]).unwrap();
//! assert!((correction.bias + 6.0).abs() < 1e-12);
//! let corrected = map.correct_record(&record, [12.0, 3.0]);
//! let Measurement::Rssi { rssi_dbm, .. } = corrected.measurement else { unreachable!() };
//! assert!((rssi_dbm + 60.0).abs() < 1e-12);
//! # Ok::<(), rtls_engine::EngineError>(())
//! ```
//!
//! # References
//! - Seed 000 (`SPEC.md`), capability 4: equipment near readers attenuates the signal; the
//!   positioning data reveal where the obstacles are.
//! - B. Iglewicz, D. C. Hoaglin, *How to Detect and Handle Outliers*, ASQC 1993 (the modified
//!   z score `0.6745 (x − median) / MAD` and its threshold 3.5).
//! - B. P. Welford, *Technometrics* 4(3), 1962 (running variance).
//! - T. S. Rappaport, *Wireless Communications*, 2nd ed., §4.9 (log-distance path loss).

mod csv_io;
#[cfg(test)]
mod csv_tests;
mod map;
mod residuals;
mod stats;
#[cfg(test)]
mod tests;

pub use csv_io::{CELL_COLUMNS, READER_COLUMNS};
pub use map::{CellEntry, Correction, CorrectionSource, Degradation, ReaderEntry, Summary, SurveyMap};
pub use residuals::{residuals, samples_from_updates};
pub use stats::RunningStats;

use crate::error::{EngineError, Result};

/// A population needs at least this many entries (with `min_count` residuals each) for its
/// median and MAD to mean anything; smaller populations are not scored.
pub const MIN_POPULATION: usize = 5;

/// The `file` that [`residuals`] names in errors about a record: its 1-based position in the
/// slice is given as the line.
pub const RECORDS_SOURCE: &str = "records";

/// What a residual measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ResidualKind {
    /// A time-of-flight range, m.
    Range,
    /// A received signal strength, dB.
    Rssi,
}

impl ResidualKind {
    /// Both kinds, in the order of their indices.
    pub const ALL: [Self; 2] = [Self::Range, Self::Rssi];

    /// The name written in the `kind` column (`"range"`, `"rssi"`, as in the record formats).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Range => "range",
            Self::Rssi => "rssi",
        }
    }

    /// The unit of its residuals, biases and spreads (`"m"`, `"dB"`).
    #[must_use]
    pub fn unit(self) -> &'static str {
        match self {
            Self::Range => "m",
            Self::Rssi => "dB",
        }
    }

    /// The direction in which an obstacle moves the residual: `+1` for ranges (an excess
    /// path), `−1` for RSSI (attenuation).
    #[must_use]
    pub fn degradation_sign(self) -> f64 {
        match self {
            Self::Range => 1.0,
            Self::Rssi => -1.0,
        }
    }

    /// The kind named `name` (`"range"` or `"rssi"`).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    pub(crate) fn index(self) -> usize {
        match self {
            Self::Range => 0,
            Self::Rssi => 1,
        }
    }
}

/// One measurement compared with the site's model at the tag's tracked position.
#[derive(Debug, Clone, PartialEq)]
pub struct Residual {
    /// Time of the measurement, s.
    pub time_s: f64,
    /// Tag id.
    pub tag: String,
    /// Reader id.
    pub reader: String,
    /// Range or RSSI.
    pub kind: ResidualKind,
    /// The tag's tracked position `[x, y, z]` at `time_s`, m (interpolated).
    pub position_m: [f64; 3],
    /// Slant distance from the reader to `position_m`, m.
    pub distance_m: f64,
    /// Measured minus expected: m for ranges, dB for RSSI.
    pub value: f64,
}

/// Measurements that gave no residual, by reason (an RSSI vector counts once per reading).
/// Each is counted once, under the first reason in field order that applies.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Unmatched {
    /// Records that measure no reader: fixes, accelerometer, odometry, velocity.
    pub not_anchor_measurement: usize,
    /// TDOA measurements (not surveyed: a range difference cannot be attributed to one
    /// reader).
    pub tdoa: usize,
    /// The reader is not in the site.
    pub unknown_reader: usize,
    /// The reader is marked broken (`working = false`).
    pub broken_reader: usize,
    /// An RSSI measurement of a reader without `radio.path_loss`.
    pub no_path_loss: usize,
    /// The tag has no non-predicted track update.
    pub no_track: usize,
    /// In the tag's first `skip_initial_s` of track (the filter is still converging).
    pub initial_skipped: usize,
    /// Before the tag's first or after its last non-predicted update.
    pub outside_track: usize,
    /// Between two non-predicted updates more than `max_gap_s` apart.
    pub track_gap: usize,
}

impl Unmatched {
    /// All measurements without a residual.
    #[must_use]
    pub fn total(&self) -> usize {
        self.reasons().iter().map(|(_, n)| n).sum()
    }

    /// `(reason, count)` for every reason, in field order, with the field names as reasons.
    #[must_use]
    pub fn reasons(&self) -> [(&'static str, usize); 9] {
        [
            ("not_anchor_measurement", self.not_anchor_measurement),
            ("tdoa", self.tdoa),
            ("unknown_reader", self.unknown_reader),
            ("broken_reader", self.broken_reader),
            ("no_path_loss", self.no_path_loss),
            ("no_track", self.no_track),
            ("initial_skipped", self.initial_skipped),
            ("outside_track", self.outside_track),
            ("track_gap", self.track_gap),
        ]
    }
}

/// The residuals [`residuals`] found and the measurements it could not use.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Residuals {
    /// One per usable measurement, in record order.
    pub residuals: Vec<Residual>,
    /// The others, by reason.
    pub unmatched: Unmatched,
}

/// How the survey matches, accumulates and flags.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurveySettings {
    /// Side of the square area cells, m (> 0). Default 10.
    pub cell_size_m: f64,
    /// A corner of the cell grid `[x, y]`, m (finite): cell `(i, j)` is
    /// `[x₀ + i c, x₀ + (i + 1) c) × [y₀ + j c, y₀ + (j + 1) c)`. Default `[0, 0]`.
    pub origin_m: [f64; 2],
    /// Longest interval between the two non-predicted track updates that bracket a measurement,
    /// s (≥ 0); a measurement in a longer gap is not matched (interpolating would invent the
    /// position). Default 2.
    pub max_gap_s: f64,
    /// Measurements in each tag's first `skip_initial_s` of track are not matched, s (≥ 0,
    /// finite). Default 5.
    pub skip_initial_s: f64,
    /// Residuals an entry needs to be scored, flagged or used as a correction (≥ 2).
    /// Default 50.
    pub min_count: usize,
    /// Robust z threshold `z*` (> 0). Default 3.5 (Iglewicz & Hoaglin).
    pub z_threshold: f64,
    /// Minimum RSSI effect `δ`, dB (> 0): how far below the population's median a bias (or
    /// above it a spread) must be to flag. Default 3 (half the power).
    pub min_rssi_effect_db: f64,
    /// Minimum range effect `δ`, m (> 0): how far above the population's median a bias or a
    /// spread must be to flag. Default 0.3.
    pub min_range_effect_m: f64,
    /// Width of the distance bands that split the cell entries into populations, m (> 0): an
    /// entry is compared with the entries whose mean distance to their reader falls in the
    /// same band. `None`: one population of all cell entries. Default 10.
    pub distance_band_m: Option<f64>,
    /// Whether an abnormal spread flags an entry (its `spread_z` is reported either way).
    /// Default `false`.
    pub flag_spread: bool,
    /// Whether [`SurveyMap::correction`] also returns the bias of entries that are not flagged
    /// for their bias (with at least `min_count` residuals). Default `false`: only flagged
    /// entries correct.
    pub correct_unflagged: bool,
}

impl Default for SurveySettings {
    fn default() -> Self {
        Self {
            cell_size_m: 10.0,
            origin_m: [0.0, 0.0],
            max_gap_s: 2.0,
            skip_initial_s: 5.0,
            min_count: 50,
            z_threshold: 3.5,
            min_rssi_effect_db: 3.0,
            min_range_effect_m: 0.3,
            distance_band_m: Some(10.0),
            flag_spread: false,
            correct_unflagged: false,
        }
    }
}

impl SurveySettings {
    /// Checks every setting's range.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming the first setting out of range.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::survey::SurveySettings;
    /// assert!(SurveySettings::default().validate().is_ok());
    /// let bad = SurveySettings { cell_size_m: 0.0, ..SurveySettings::default() };
    /// assert!(bad.validate().unwrap_err().to_string().contains("cell_size_m"));
    /// ```
    pub fn validate(&self) -> Result<()> {
        let invalid = |name, reason| Err(EngineError::InvalidParameter { name, reason });
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.cell_size_m) {
            return invalid("cell_size_m", "must be a finite number of metres > 0");
        }
        if !self.origin_m.iter().all(|v| v.is_finite()) {
            return invalid("origin_m", "must be finite");
        }
        if self.max_gap_s.is_nan() || self.max_gap_s < 0.0 {
            return invalid("max_gap_s", "must be ≥ 0 s (infinity: no limit)");
        }
        if !(self.skip_initial_s.is_finite() && self.skip_initial_s >= 0.0) {
            return invalid("skip_initial_s", "must be a finite number of seconds ≥ 0");
        }
        if self.min_count < 2 {
            return invalid("min_count", "must be ≥ 2 (a spread needs two residuals)");
        }
        if !positive(self.z_threshold) {
            return invalid("z_threshold", "must be finite and > 0");
        }
        if !positive(self.min_rssi_effect_db) {
            return invalid("min_rssi_effect_db", "must be a finite number of dB > 0");
        }
        if !positive(self.min_range_effect_m) {
            return invalid("min_range_effect_m", "must be a finite number of metres > 0");
        }
        if self.distance_band_m.is_some_and(|w| !positive(w)) {
            return invalid("distance_band_m", "must be a finite number of metres > 0 (or none)");
        }
        Ok(())
    }

    /// The minimum effect `δ` of a kind (dB for RSSI, m for ranges).
    #[must_use]
    pub fn min_effect(&self, kind: ResidualKind) -> f64 {
        match kind {
            ResidualKind::Range => self.min_range_effect_m,
            ResidualKind::Rssi => self.min_rssi_effect_db,
        }
    }

    /// The cell `[i, j]` containing `position_m` (`x, y`, m): `i = ⌊(x − x₀) / c⌋`,
    /// `j = ⌊(y − y₀) / c⌋`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::survey::SurveySettings;
    /// let settings = SurveySettings::default(); // 10 m cells from (0, 0)
    /// assert_eq!(settings.cell_of([25.0, -0.5]), [2, -1]);
    /// assert_eq!(settings.cell_bounds_m([2, -1]), [20.0, 30.0, -10.0, 0.0]);
    /// ```
    #[must_use]
    pub fn cell_of(&self, position_m: [f64; 2]) -> [i64; 2] {
        // `as` saturates for values beyond the i64 range
        [
            ((position_m[0] - self.origin_m[0]) / self.cell_size_m).floor() as i64,
            ((position_m[1] - self.origin_m[1]) / self.cell_size_m).floor() as i64,
        ]
    }

    /// The bounds `[x_min, x_max, y_min, y_max]` of cell `[i, j]`, m.
    #[must_use]
    pub fn cell_bounds_m(&self, cell: [i64; 2]) -> [f64; 4] {
        let c = self.cell_size_m;
        let (x, y) = (
            self.origin_m[0] + cell[0] as f64 * c,
            self.origin_m[1] + cell[1] as f64 * c,
        );
        [x, x + c, y, y + c]
    }
}
