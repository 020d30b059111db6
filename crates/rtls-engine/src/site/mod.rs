//! The site model (TOML): readers/anchors, floors, zones, an optional fingerprint database
//! reference, tracker settings and zone-event settings.
//!
//! `examples/site.toml` documents every key with its unit; `examples/mine-site.toml` is a small
//! seed-000 deployment (tunnel readers, a hazard zone around a broken reader). Load a site with
//! [`Site::from_toml_str`]: unknown keys are rejected everywhere, and every problem is an
//! [`EngineError::Parse`] naming the file, the line and the key path (e.g.
//! `readers[3].position_m`).
//!
//! # References
//! - Seed 000 (ME-KF): the three-layer architecture, the manager layer's settings.
//! - Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001: gates (§2.6), M-of-N track initiation and deletion.

mod advice;
mod consistency;
mod keys;
mod limits;
mod load;
mod options;
pub mod platform;
mod ranges;
mod readers;

pub use consistency::ConsistencySettings;
pub use limits::{read_text_file, MAX_RADIO_MAP_BYTES, MAX_RADIO_MAP_ROWS, MAX_SITE_BYTES, MAX_ZONE_VERTICES};
pub use options::{
    AdaptiveNoiseSettings, AlarmSettings, Corridor, FloorPlan, FrameSettings, GeodeticOrigin, GnssSettings,
    HeadingSettings, ImmModeKind, ImmModeSet, ImmSettings, MapSettings, RangeBiasSettings, SchedulingCell,
    SchedulingSettings,
};
pub use platform::Platform;
pub use readers::{PathLoss, Radio, RangeErrors, Reader, Technology};

use std::path::PathBuf;

use serde::Deserialize;

use crate::error::{EngineError, Result};
use crate::zones::{AntiFlap, Zone, ZoneMonitor};

/// A whole site, as loaded from TOML by [`Site::from_toml_str`].
///
/// # Examples
/// ```
/// use rtls_engine::site::Site;
/// let site = Site::from_toml_str(
///     r#"
///     [[readers]]
///     id = "R1"
///     position_m = [0.0, 0.0, 2.5]
///     technology = "uwb"
///
///     [tracker]
///     pipeline = "fix-then-filter"
///     motion_model = "cv"
///     filter = "kf"
///     acceleration_noise_std_mps2 = 1.0
///     gate_probability = 0.99
///     initiation = { confirm_updates = 3, within_s = 5.0 }
///     coast_timeout_s = 10.0
///     delete_timeout_s = 60.0
///     reorder_window_s = 0.5
///     "#,
///     "site.toml",
/// )
/// .unwrap();
/// assert!(site.reader("R1").unwrap().working);
/// assert!(site.reader("R2").is_none());
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Human-readable site name.
    #[serde(default)]
    pub name: Option<String>,
    /// Where the site frame lies on the Earth (`[frame]`): needed for GNSS pseudoranges.
    #[serde(default)]
    pub frame: Option<FrameSettings>,
    /// Fixed readers, anchors, base stations and access points.
    #[serde(default)]
    pub readers: Vec<Reader>,
    /// Floors (levels), referenced by polygon zones.
    #[serde(default)]
    pub floors: Vec<Floor>,
    /// The corridors tags move in (drifts, aisles): the tracker keeps its estimates inside them
    /// ([`TrackerSettings::map`]) and, with negative information, treats rock between a
    /// reader and a tag as blocking the radio.
    #[serde(default)]
    pub corridors: Vec<Corridor>,
    /// Zones; after loading, a polygon's `floor` has been resolved into its `z_range_m`.
    #[serde(default)]
    pub zones: Vec<Zone>,
    /// Zone-event settings (anti-flap and dwell); no hysteresis, no delay and no dwell reports
    /// when the section is absent.
    #[serde(default)]
    pub zone_events: ZoneEventSettings,
    /// A fingerprint database to load (only referenced here, not loaded).
    #[serde(default)]
    pub fingerprints: Option<FingerprintDatabase>,
    /// How tags are tracked (every key has a default).
    #[serde(default)]
    pub tracker: TrackerSettings,
    /// Anonymous detections (records with tag `"*"`: ranges or fixes that carry no identity,
    /// like seed 003's ultrasonic echoes) are tracked by the multi-target association of
    /// [`crate::association`] with these settings; without the section they are rejected.
    #[serde(default)]
    pub anonymous: Option<crate::association::AnonymousTrackerSettings>,
    /// Seed 003's adaptive node scheduling: the cells of the sensor network and how many task
    /// nodes measure each track; the tracker then reports every track's next-cycle nodes.
    #[serde(default)]
    pub scheduling: Option<SchedulingSettings>,
    /// Predictive hazard alarms (defaults when the section is absent).
    #[serde(default)]
    pub alarms: AlarmSettings,
    /// The check-in/check-out rule of a muster board: who is on site (`[muster]`).
    #[serde(default)]
    pub muster: Option<crate::zones::MusterSettings>,
}

/// A floor (level) and its height range.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Floor {
    /// Unique id, referenced by polygon zones.
    pub id: String,
    /// Height range `[z_min, z_max]`, m.
    pub z_range_m: [f64; 2],
    /// A floor-plan image the dashboard draws under the map.
    #[serde(default)]
    pub plan: Option<FloorPlan>,
}

/// File format of a fingerprint database.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FingerprintFormat {
    /// The UJIIndoorLoc CSV layout (520 WAP columns, 100 = not heard).
    Ujiindoorloc,
    /// CSV: `x_m,y_m[,floor]` then one RSSI column per reader, dBm, empty when not heard
    /// ([`crate::radio_map::RadioMap::from_csv_str`], docs/FORMATS.md). The format `rtls track`
    /// loads.
    Csv,
    /// JSON Lines: `{"position_m": [x, y, z], "rssi_dbm": [...]}` in `readers` order.
    JsonLines,
}

/// A reference to a fingerprint (radio map) database; the site only names it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerprintDatabase {
    /// Path of the database file, relative to the site file's directory.
    pub path: PathBuf,
    /// Its format.
    pub format: FingerprintFormat,
    /// Reader ids in the order of the RSSI columns (empty when the format fixes the order).
    #[serde(default)]
    pub readers: Vec<String>,
    /// WKNN: the number of nearest reference points averaged, `k` (1 to 100). Default 3
    /// ([`crate::radio_map::RadioMap::DEFAULT_NEIGHBOURS`]).
    #[serde(default = "default_neighbours")]
    pub neighbours: usize,
    /// The noise floor `ρ_min` of the powed signal space, dBm (−150 to −30): weaker readings
    /// count as not heard, and a map cell below it is an error. Default −104.
    #[serde(default = "default_noise_floor_dbm")]
    pub noise_floor_dbm: f64,
    /// The standard deviation floor of a fingerprint fix, m (0.001 to 10 000), in place of the
    /// one calibrated on the map by leave-one-out cross-validation
    /// ([`crate::radio_map::RadioMap::locate`]): the fix covariance is the neighbours' spread
    /// plus `min_std_m²` on the diagonal. Absent (the default): calibrated.
    #[serde(default)]
    pub min_std_m: Option<f64>,
}

fn default_neighbours() -> usize {
    FingerprintDatabase::DEFAULT_NEIGHBOURS
}

impl FingerprintDatabase {
    /// `k` when `neighbours` is absent.
    pub const DEFAULT_NEIGHBOURS: usize = 3;
}

fn default_noise_floor_dbm() -> f64 {
    -104.0
}

/// Where positions come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pipeline {
    /// A positioning solver turns each epoch's measurements into a fix; the filter smooths the
    /// fixes (seed 000's ME-KF).
    FixThenFilter,
    /// Raw ranges / RSSI / TDOA update the filter directly (seeds 001, 004); needs `ekf` or `ukf`.
    TightlyCoupled,
}

/// Motion model of the track state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionModelKind {
    /// Constant velocity with white-noise acceleration (seed 000).
    Cv,
    /// Constant acceleration.
    Ca,
    /// Random walk (position only).
    RandomWalk,
    /// Coordinated turn with the turn rate as a state, `[x, vx, y, vy, ω]` (2-D only): the
    /// velocity turns at `ω`, which changes by a white turn acceleration
    /// (`tracker.turn_rate_noise_std_radps2`); a straight track is `ω = 0`.
    Ct,
    /// Interacting multiple models switching between motion modes (by default a quiet constant
    /// velocity, a constant acceleration and, in 2-D, a coordinated turn with the turn rate as a
    /// state; `[tracker.imm] modes` chooses the set); settings in `[tracker.imm]`. The tracker reports the most probable model and a `model-switch` event
    /// when it changes.
    Imm,
}

/// Filter kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FilterKind {
    /// Linear Kalman filter (position fixes only).
    Kf,
    /// Extended Kalman filter.
    Ekf,
    /// Unscented Kalman filter (seed 001).
    Ukf,
}

/// M-of-N track confirmation: a tentative track is confirmed after `confirm_updates` updates
/// within `within_s`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Initiation {
    /// Updates needed (M, ≥ 1).
    pub confirm_updates: u32,
    /// Window in which they must arrive, s (> 0).
    pub within_s: f64,
}

/// `[tracker]`: how tags are tracked.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerSettings {
    /// What carries the tags: `walker`, `vehicle` or `robot`; fills the keys left out with that
    /// platform's defaults ([`platform`]). Absent: the generic defaults.
    #[serde(default)]
    pub platform: Option<Platform>,
    /// Fix-then-filter or tightly coupled. Default tightly coupled; fix-then-filter when every
    /// reader is `ble` (`platform::pipeline_for_readers`).
    #[serde(default = "platform::default_pipeline")]
    pub pipeline: Pipeline,
    /// Motion model. Default `cv` (`imm` for a vehicle).
    #[serde(default = "platform::default_motion_model")]
    pub motion_model: MotionModelKind,
    /// Filter kind. Default `ekf`.
    #[serde(default = "platform::default_filter")]
    pub filter: FilterKind,
    /// Process noise: white acceleration (CV, random walk: velocity) std, m/s² (> 0). Default 1
    /// (walker 1, vehicle 2, robot 0.5).
    #[serde(default = "platform::default_acceleration_noise_std_mps2")]
    pub acceleration_noise_std_mps2: f64,
    /// Process noise of a prediction driven by an accelerometer sample (the sample is the
    /// control input): the white acceleration the accelerometer misses (misalignment, bias,
    /// vibration), m/s² (≥ 0). The sample's own `std_mps2` is added as discrete white noise held
    /// over the step, `Γ ε² Γᵀ` with `Γ = [Δt²/2, Δt]ᵀ`. Absent:
    /// `acceleration_noise_std_mps2` (an accelerometer of unknown quality).
    /// Single-model CV tracks only (the IMM's CV mode keeps its own noise).
    #[serde(default)]
    pub aided_acceleration_noise_std_mps2: Option<f64>,
    /// Probability that a correct measurement falls inside the χ² validation gate, in (0, 1).
    /// Default 0.999.
    #[serde(default = "platform::default_gate_probability")]
    pub gate_probability: f64,
    /// Track confirmation rule. Default 3 updates within 5 s.
    #[serde(default = "platform::default_initiation")]
    pub initiation: Initiation,
    /// After this long without a measurement a track coasts no more and is reported lost, s
    /// (> 0). Default 5.
    #[serde(default = "platform::default_coast_timeout_s")]
    pub coast_timeout_s: f64,
    /// After this long without a measurement a track is deleted, s (≥ `coast_timeout_s`).
    /// Default 60.
    #[serde(default = "platform::default_delete_timeout_s")]
    pub delete_timeout_s: f64,
    /// Records up to this much older than the newest are re-ordered; older ones are reported
    /// late, s (≥ 0). Default 0.5.
    #[serde(default = "platform::default_reorder_window_s")]
    pub reorder_window_s: f64,
    /// A record older than its tag's newest input by up to this much (beyond the re-ordering
    /// window) is not dropped: the track rewinds to a stored state before it and re-filters
    /// what followed, and the updates it revises are flagged `revised`; older records are
    /// reported late, s (0 = off: records beyond the window are reported late). Lets a live
    /// server run with `reorder_window_s = 0`, publishing each update as it is produced.
    /// Default 0.
    #[serde(default)]
    pub rewind_horizon_s: f64,
    /// Tracked dimensions: 2 (x, y) or 3 (x, y, z). Default 2.
    #[serde(default = "default_dimensions")]
    pub dimensions: u8,
    /// Fix-then-filter: a tag's anchor measurements within this window from the first one are
    /// solved together as one fix, s (≥ 0; 0 = equal time stamps only). Absent: automatic
    /// epochs (`tracker::epoch::epoch_due`): readings with equal time stamps are one epoch, and
    /// a tag whose readers report one at a time (Wi-Fi RTT, TDMA UWB) has its readings
    /// collected until a reader of the epoch reports again, at most
    /// [`AUTO_EPOCH_MAX_S`](crate::tracker::AUTO_EPOCH_MAX_S) after the first.
    #[serde(default)]
    pub epoch_s: Option<f64>,
    /// 2-D tracking with anchors at other heights: the tag's height, m. Slant ranges `r` to an
    /// anchor at height `z_a` are projected to the plane, `√(r² − (z_a − h)²)`, and RSS laws use
    /// the 3-D distance. Absent: anchors and tag are taken to be coplanar.
    #[serde(default)]
    pub tag_height_m: Option<f64>,
    /// While a track coasts, its prediction is output this often, s (> 0). Default 1.
    #[serde(default = "default_output_interval_s")]
    pub output_interval_s: f64,
    /// Velocity standard deviation of a new track, m/s (> 0). Default 2.
    #[serde(default = "default_initial_speed_std_mps")]
    pub initial_speed_std_mps: f64,
    /// `motion_model = "ct"`: std of the white turn acceleration that changes the turn rate,
    /// rad/s² (> 0). Default 0.2 (the IMM's CT mode has its own,
    /// `[tracker.imm] ct_turn_rate_noise_std_radps2`).
    #[serde(default = "default_turn_rate_noise_std_radps2")]
    pub turn_rate_noise_std_radps2: f64,
    /// Turn-rate standard deviation of a new track's coordinated turn (`motion_model = "ct"`
    /// and the IMM's CT mode), rad/s (> 0); its mean is 0 (straight). Default 1 (any turn a
    /// person or vehicle makes); a walker turns at well under 0.5 rad/s.
    #[serde(default = "default_initial_turn_rate_std_radps")]
    pub initial_turn_rate_std_radps: f64,
    /// A record more than this far ahead of the newest record is refused as a bad time stamp
    /// (a `rejected` event), not coasted through; [`crate::record::JUMP_CONFIRMATIONS`] records
    /// in a row on the new time base are taken as a real gap (see
    /// [`crate::record::TimeGate`]), s (1 s to 1 year). Default 86 400 (one day).
    #[serde(default = "default_max_time_jump_s")]
    pub max_time_jump_s: f64,
    /// The interacting multiple models of `motion_model = "imm"`.
    #[serde(default)]
    pub imm: ImmSettings,
    /// Innovation-based adaptive measurement noise (on by default).
    #[serde(default)]
    pub adaptive_noise: AdaptiveNoiseSettings,
    /// Self-calibration of ranges: each anchor's offset estimated by each track (on by default).
    #[serde(default)]
    pub range_bias: RangeBiasSettings,
    /// The test of each track's consistency from its corrections, and the covariance inflation
    /// when it fails (on by default).
    #[serde(default)]
    pub consistency: ConsistencySettings,
    /// The heading channel (yaw rates, odometry without heading, IMU samples).
    #[serde(default)]
    pub heading: HeadingSettings,
    /// GNSS pseudoranges: default noise, fault exclusion and the receiver clock's process.
    #[serde(default)]
    pub gnss: GnssSettings,
    /// The map constraint: how firmly estimates are held to the site's `[[corridors]]`.
    #[serde(default)]
    pub map: MapSettings,
    /// Negative information (seed 000): a working reader with a `sensitivity_dbm` that did not
    /// hear a tag although, from the estimate, it should have, moves the estimate away from
    /// it. Default true (it needs readers with a sensitivity to do anything).
    #[serde(default = "readers::yes")]
    pub negative_information: bool,
    /// The largest speed a tag can have, m/s (> 0): a faster estimated velocity is scaled down
    /// to it (a walker cannot run at 6 m/s through a drift). Absent: no limit.
    #[serde(default)]
    pub max_speed_mps: Option<f64>,
}

fn default_dimensions() -> u8 {
    2
}

fn default_output_interval_s() -> f64 {
    1.0
}

fn default_initial_speed_std_mps() -> f64 {
    2.0
}

fn default_turn_rate_noise_std_radps2() -> f64 {
    0.2
}

fn default_initial_turn_rate_std_radps() -> f64 {
    1.0
}

fn default_max_time_jump_s() -> f64 {
    86_400.0
}

impl TrackerSettings {
    /// The IMM's CV-mode white-acceleration std, m/s²: `[tracker.imm]
    /// cv_acceleration_noise_std_mps2`, or `acceleration_noise_std_mps2` when it is absent.
    ///
    /// # Example
    /// ```
    /// let site = rtls_engine::site::Site::from_toml_str(
    ///     include_str!("../../../../examples/site.toml"),
    ///     "examples/site.toml",
    /// )?;
    /// let expected = site.tracker.imm.cv_acceleration_noise_std_mps2.unwrap_or(site.tracker.acceleration_noise_std_mps2);
    /// assert_eq!(site.tracker.imm_cv_acceleration_noise_std_mps2(), expected);
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    #[must_use]
    pub fn imm_cv_acceleration_noise_std_mps2(&self) -> f64 {
        self.imm
            .cv_acceleration_noise_std_mps2
            .unwrap_or(self.acceleration_noise_std_mps2)
    }

    /// The track lifecycle these settings describe (`initiation`, `coast_timeout_s`,
    /// `delete_timeout_s`).
    ///
    /// # Example
    /// ```
    /// let site = rtls_engine::site::Site::from_toml_str(
    ///     include_str!("../../../../examples/mine-site.toml"),
    ///     "examples/mine-site.toml",
    /// )?;
    /// let lifecycle = site.tracker.lifecycle();
    /// assert!(lifecycle.validate().is_ok());
    /// assert_eq!(lifecycle.coast_timeout_s, site.tracker.coast_timeout_s);
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    #[must_use]
    pub fn lifecycle(&self) -> crate::lifecycle::LifecycleSettings {
        crate::lifecycle::LifecycleSettings {
            confirm_updates: self.initiation.confirm_updates,
            confirm_window_s: self.initiation.within_s,
            coast_timeout_s: self.coast_timeout_s,
            delete_timeout_s: self.delete_timeout_s,
        }
    }
}

/// `[zone_events]`: anti-flap and dwell settings of the zone monitor.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZoneEventSettings {
    /// Hysteresis half-width around zone borders, m (≥ 0).
    pub tolerance_m: f64,
    /// How long a change must persist before it is reported, s (≥ 0).
    pub delay_s: f64,
    /// Dwell report interval, s (> 0); none when absent.
    #[serde(default)]
    pub dwell_interval_s: Option<f64>,
}

impl Default for ZoneEventSettings {
    fn default() -> Self {
        Self {
            tolerance_m: 0.0,
            delay_s: 0.0,
            dwell_interval_s: None,
        }
    }
}

impl Site {
    /// Parses and validates a site file. `file_name` is only used in error messages.
    ///
    /// Checks: TOML syntax, types and unknown keys; unique, non-empty reader, floor and zone
    /// ids; reader positions with 2 or 3 finite coordinates; radio parameters in range; zone
    /// geometry ([`Zone::validate`]); reader and floor ids referenced by zones and the
    /// fingerprint database exist; a polygon has at most one of `floor` and `z_range_m`;
    /// tracker settings in range and consistent (a tightly coupled pipeline needs an EKF or
    /// UKF; `delete_timeout_s ≥ coast_timeout_s`). Polygon floors are resolved into
    /// `z_range_m`.
    ///
    /// # Errors
    /// [`EngineError::Parse`] with the file, the 1-based line (0 when unknown, e.g. inside an
    /// inline array of tables), the key path (`readers[3].position_m`) and the reason.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::{site::Site, EngineError};
    /// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/site.toml")).unwrap();
    /// let site = Site::from_toml_str(&text, "site.toml").unwrap();
    /// assert!(!site.zones.is_empty());
    /// let broken = text.replace("technology = \"uwb\"", "technology = \"carrier-pigeon\"");
    /// assert!(matches!(Site::from_toml_str(&broken, "site.toml"), Err(EngineError::Parse { .. })));
    /// ```
    pub fn from_toml_str(text: &str, file_name: &str) -> Result<Self> {
        load::load(text, file_name)
    }

    /// The reader with id `id`.
    ///
    /// # Examples
    /// See [`Site`].
    #[must_use]
    pub fn reader(&self, id: &str) -> Option<&Reader> {
        self.readers.iter().find(|r| r.id == id)
    }

    /// The floor with id `id`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::Site;
    /// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/site.toml")).unwrap();
    /// let site = Site::from_toml_str(&text, "site.toml").unwrap();
    /// assert!(site.floor("ground").is_some());
    /// ```
    #[must_use]
    pub fn floor(&self, id: &str) -> Option<&Floor> {
        self.floors.iter().find(|f| f.id == id)
    }

    /// The zone with id `id`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::Site;
    /// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/mine-site.toml")).unwrap();
    /// let site = Site::from_toml_str(&text, "mine-site.toml").unwrap();
    /// assert!(site.zone("collapse-r4").is_some());
    /// ```
    #[must_use]
    pub fn zone(&self, id: &str) -> Option<&Zone> {
        self.zones.iter().find(|z| z.id == id)
    }

    /// A [`ZoneMonitor`] of this site's zones with its `[zone_events]` settings.
    ///
    /// # Errors
    /// None for a site loaded by [`Site::from_toml_str`] (everything was checked); otherwise
    /// those of [`ZoneMonitor::new`] and [`ZoneMonitor::with_dwell_interval_s`].
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::Site;
    /// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/mine-site.toml")).unwrap();
    /// let site = Site::from_toml_str(&text, "mine-site.toml").unwrap();
    /// let monitor = site.zone_monitor().unwrap();
    /// assert_eq!(monitor.zones().len(), site.zones.len());
    /// ```
    pub fn zone_monitor(&self) -> Result<ZoneMonitor> {
        let settings = self.zone_events;
        let monitor = ZoneMonitor::new(
            self.zones.clone(),
            AntiFlap {
                tolerance_m: settings.tolerance_m,
                delay_s: settings.delay_s,
            },
        )?;
        match settings.dwell_interval_s {
            Some(interval_s) => monitor.with_dwell_interval_s(interval_s),
            None => Ok(monitor),
        }
    }
}

/// A validation error at a key path of the file.
fn invalid(file: &str, text: &str, path: &str, reason: impl Into<String>) -> EngineError {
    EngineError::Parse {
        file: file.to_string(),
        line: keys::line_of(text, path),
        field: path.to_string(),
        reason: reason.into(),
    }
}

#[cfg(test)]
mod example_tests;
#[cfg(test)]
mod tests;
