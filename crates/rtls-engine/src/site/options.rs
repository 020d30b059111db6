//! Optional sections of the site model: `[frame]`, `[tracker.imm]`, `[tracker.adaptive_noise]`,
//! `[tracker.gnss]`, `[scheduling]` and `[alarms]`.

use std::path::PathBuf;

use serde::Deserialize;

/// `[scheduling]`: seed 003's adaptive node scheduling. From each confirmed track's prediction
/// one cycle ahead, the tracker picks the nearest `task_nodes` readers of the predicted cell
/// (kept unless most of them change: seed 003's acceptance rule, with a handover into a
/// neighbouring cell that shares none of them) plus, within `edge_margin_m`
/// of a cell border, the neighbouring cell's monitors; a `schedule` event reports a track's
/// nodes whenever they change, for the readers to wake.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SchedulingSettings {
    /// The measurement cycle: how far ahead the prediction looks, s (> 0).
    pub cycle_s: f64,
    /// Task nodes per track and cycle (≥ 1; seed 003: 2 or 3).
    pub task_nodes: usize,
    /// Edge zone: within this distance of an inner cell border the neighbouring cell's nodes
    /// monitor too, m (≥ 0).
    pub edge_margin_m: f64,
    /// The cells, rectangles that do not overlap, each with its readers.
    pub cells: Vec<SchedulingCell>,
}

/// One cell of `[scheduling]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SchedulingCell {
    /// Lower-left corner `[x, y]`, m.
    pub min_m: [f64; 2],
    /// Upper-right corner `[x, y]`, m.
    pub max_m: [f64; 2],
    /// Ids of the readers that belong to the cell.
    pub readers: Vec<String>,
}

/// One motion mode of the IMM (`[tracker.imm] modes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImmModeKind {
    /// Constant velocity `[x, vx, y, vy(, z, vz)]`, white acceleration.
    Cv,
    /// Constant acceleration, white jerk.
    Ca,
    /// Coordinated turn with the turn rate as a state `[x, vx, y, vy, ω]` (2-D only).
    Ct,
}

impl ImmModeKind {
    /// The mode's name in updates and `model-switch` events: "CV", "CA", "CT".
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Cv => "CV",
            Self::Ca => "CA",
            Self::Ct => "CT",
        }
    }
}

/// The modes of an IMM, each at most once, in the order written (`modes = ["cv", "ct"]`). The
/// first is the mode a (re)started track is in.
///
/// # Example
/// ```
/// use rtls_engine::site::{ImmModeKind, ImmModeSet};
/// let set = ImmModeSet::new(&[ImmModeKind::Cv, ImmModeKind::Ct]).unwrap();
/// assert_eq!(set.modes(), [ImmModeKind::Cv, ImmModeKind::Ct]);
/// assert!(ImmModeSet::new(&[ImmModeKind::Cv, ImmModeKind::Cv]).is_err());
/// assert!(ImmModeSet::new(&[]).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(try_from = "Vec<ImmModeKind>")]
pub struct ImmModeSet {
    modes: [Option<ImmModeKind>; 3],
}

impl ImmModeSet {
    /// The set of `modes`, in that order.
    ///
    /// # Errors
    /// A reason when `modes` is empty or names a mode twice.
    pub fn new(modes: &[ImmModeKind]) -> core::result::Result<Self, String> {
        if modes.is_empty() {
            return Err("an IMM needs at least one mode (\"cv\", \"ca\", \"ct\")".to_string());
        }
        let mut set = [None; 3];
        for (i, mode) in modes.iter().enumerate() {
            if modes[..i].contains(mode) {
                return Err(format!("mode \"{}\" is listed twice", mode.name().to_lowercase()));
            }
            set[i] = Some(*mode);
        }
        Ok(Self { modes: set })
    }

    /// The modes, in order.
    #[must_use]
    pub fn modes(&self) -> Vec<ImmModeKind> {
        self.modes.iter().flatten().copied().collect()
    }
}

impl TryFrom<Vec<ImmModeKind>> for ImmModeSet {
    type Error = String;

    fn try_from(modes: Vec<ImmModeKind>) -> core::result::Result<Self, String> {
        Self::new(&modes)
    }
}

/// `[tracker.imm]`: the modes of `motion_model = "imm"` (Blom & Bar-Shalom 1988; seed 004's
/// manoeuvre problem). The CV mode uses `cv_acceleration_noise_std_mps2` (by default
/// `tracker.acceleration_noise_std_mps2`); the CA mode a white jerk; the coordinated turn (2-D
/// only) the CV noise plus a white turn acceleration.
/// Modes switch as a continuous-time Markov chain with the given mean sojourn times.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImmSettings {
    /// The modes, each at most once; the first is the mode a (re)started track is in.
    /// Absent: `["cv", "ca", "ct"]` in 2-D, `["cv", "ca"]` in 3-D (the coordinated turn is 2-D
    /// only).
    pub modes: Option<ImmModeSet>,
    /// CV mode (and the coordinated turn's translational noise): white-acceleration std, m/s²
    /// (> 0). Absent: `tracker.acceleration_noise_std_mps2` (see
    /// [`super::TrackerSettings::imm_cv_acceleration_noise_std_mps2`]).
    pub cv_acceleration_noise_std_mps2: Option<f64>,
    /// Mean time in the constant-velocity mode, s (> 0). Default 20.
    pub cv_sojourn_s: f64,
    /// Mean time in the constant-acceleration mode, s (> 0). Default 4.
    pub ca_sojourn_s: f64,
    /// Mean time in the coordinated-turn mode, s (> 0; 2-D only). Default 4.
    pub ct_sojourn_s: f64,
    /// CA mode: white-jerk spectral density `q = σ_j²`, σ_j in m/s³ (> 0). Default 1.
    pub ca_jerk_noise_std_mps3: f64,
    /// CT mode: white turn-acceleration spectral density, σ in rad/s² (> 0). Default 0.2.
    pub ct_turn_rate_noise_std_radps2: f64,
    /// A `model-switch` is reported when another mode becomes the most probable one with at
    /// least this probability (anti-flap), in (0, 1). Default 0.6.
    pub switch_probability: f64,
}

impl Default for ImmSettings {
    fn default() -> Self {
        Self {
            modes: None,
            cv_acceleration_noise_std_mps2: None,
            cv_sojourn_s: 20.0,
            ca_sojourn_s: 4.0,
            ct_sojourn_s: 4.0,
            ca_jerk_noise_std_mps3: 1.0,
            ct_turn_rate_noise_std_radps2: 0.2,
            switch_probability: 0.6,
        }
    }
}

/// `[tracker.adaptive_noise]`: innovation-based adaptive measurement noise
/// ([`rtls_estimation::adaptive`]). Each track keeps one noise scale `λ ≥ 1` per measurement
/// class (ranges, RSSI, TDOA, position fixes, fingerprint fixes, velocities) and updates with
/// `λR` instead of the stated `R`; `λ` follows the innovations (covariance matching), so a track
/// whose readers are noisier than the site says reports a covariance that still holds the
/// truth (95 % ellipses about 95 % of the time). It never goes below the stated noise.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdaptiveNoiseSettings {
    /// Whether the scales adapt; `false` keeps `λ = 1` (the stated noise). Default true.
    pub enabled: bool,
    /// The scale averages the innovations of its class over this window, s (> 0; a running
    /// mean over a track's first updates). Long enough that a manoeuvre of a few seconds is the
    /// motion model's to explain, short enough to follow a tag into a noisier area. Default 20.
    pub memory_s: f64,
    /// The largest scale, a multiple of the stated variance (≥ 1). Default 25 (σ × 5): larger
    /// scales let sparse, heavy-tailed fixes (Wi-Fi scans a minute apart) hand the track to the
    /// motion model.
    pub max_scale: f64,
    /// Correlation time of measurement errors, s (≥ 0; 0 treats every measurement as
    /// independent). A reader's readings (or a class of fixes) closer together than this are
    /// not independent information: each variance is inflated by `max(1, 2 τ_c / Δt)`, `Δt`
    /// after the same reader's previous reading of the tag, so a 100 Hz stream is not taken for
    /// 100 independent looks a second. Applies whether or not `enabled`. Default 0.25 (multipath
    /// and body shadowing change as a walking tag moves a few wavelengths). Not for RSSI: see
    /// `rssi_correlation_s`.
    pub correlation_s: f64,
    /// The correlation time of the errors of fixes made of received signal strength —
    /// fix-then-filter fixes solved from RSSI readings alone, fingerprint scans — s (≥ 0), used
    /// as `correlation_s` is. Their error is mostly shadowing by walls, furniture, the carrier's
    /// body and the antenna's orientation, which changes over metres, not wavelengths: indoor
    /// shadowing decorrelates over 1–3 m (Gudmundson's exponential model, M. Gudmundson,
    /// Electronics Letters 27(23), 1991), 1–3 s at walking pace. Default 2. On the BLE
    /// recording of docs/EVALUATION.md (9 tracks) 0.25 s left 74 % (path-loss fixes) and 82 %
    /// (fingerprints) of the truths inside the 95 % ellipses, 2 s gives 93 % and 92 % with the
    /// same RMSE. Single RSSI readings (tightly coupled) take `rssi_reading_correlation_s`.
    pub rssi_correlation_s: f64,
    /// The correlation time of single RSSI readings' errors (tightly coupled), s (≥ 0), used
    /// as `correlation_s` is. The same shadowing as `rssi_correlation_s`'s, counted per
    /// reading: at a scanner's ~2 readings per reader a second, `max(1, 2 τ_c / Δt)` with 1 s
    /// gives a track the information per second that 1-s epoch fixes carry at 2 s (each fix
    /// averages the epoch's two readings). Default 1. On the 9 BLE tracks of
    /// docs/EVALUATION.md (tightly coupled, defaults) 0.25 s (`correlation_s`, the value
    /// before) left 52–85 % of the truths inside the 95 % ellipses, 1 s 80–100 % on eight of
    /// them, mean RMSE 2.54 → 2.53 m over those eight (the ninth, 25 s long, starts 10 m off
    /// and lags more: 2.8 → 5.3 m).
    #[serde(default = "default_rssi_reading_correlation_s")]
    pub rssi_reading_correlation_s: f64,
    /// Whether each source's error correlation is also measured from its innovations (their
    /// lag-one correlation `ρ`, over `memory_s`) and its variances inflated by
    /// `(1 + ρ)/(1 − ρ)` when that is more than `correlation_s` gives (see
    /// [`rtls_estimation::adaptive::correlation`]): errors that persist for seconds — multipath
    /// that moves with the tag, an odometer heading's drift — are not counted as independent
    /// looks by a track whose motion model averages over them. Applies whether or not
    /// `enabled`. Default false: an innovation sequence is also correlated when the motion model
    /// lags a manoeuvre, and inflating the measurements then makes the lag worse (on simulated
    /// vehicles turning under a CV model, RMSE 0.37 → 0.44 m); on the recordings it raised
    /// coverage (BLE path loss 74.7 → 78.7 %, labyrinth with odometry) but cost BLE accuracy
    /// (2.95 → 3.22 m).
    pub correlation_from_innovations: bool,
}

/// `[tracker.range_bias]`: self-calibration of ranges. Each track estimates every anchor's
/// range offset (`r = d + b + v`: antenna delays of the anchor and of the tag, a cable, a
/// consistent NLOS excess) from its own innovations, removes it from the ranges and counts its
/// uncertainty in their noise (see [`rtls_estimation::bias`]). It acts on top of a reader's
/// `radio.range.bias_m`, which is removed first: a calibrated site starts near zero, an
/// uncalibrated one learns its offsets within seconds of a tag moving among its anchors. Both
/// pipelines: tightly coupled tracks learn from rounds of their readings, fix-then-filter tracks
/// from each epoch's residuals against its accepted fix (and solve their epochs with the
/// corrected ranges).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RangeBiasSettings {
    /// Whether the offsets are estimated; `false` takes ranges as the site states them. Default
    /// true.
    pub enabled: bool,
    /// Prior standard deviation of an anchor's remaining offset, m (> 0), for every reader that
    /// does not state its own (`radio.range.offset_std_m`). `None` (the default): each reader's
    /// technology's ([`crate::site::Technology::range_offset_prior_std_m`]: UWB 0.2, Wi-Fi 1.5,
    /// ultrasonic 0.05, BLE and RFID 0.5, cellular 10).
    pub prior_std_m: Option<f64>,
    /// Random walk of an offset, m/√s (≥ 0): temperature drift, the slow change of NLOS excess as a
    /// tag moves. Default 0.005 (0.1 m over about 7 minutes).
    pub random_walk_m_per_sqrt_s: f64,
    /// The largest offset learnt, m (> 0), for every reader. `None` (the default): five times
    /// the reader's prior standard deviation (1 m for UWB's 0.2 m).
    pub max_abs_m: Option<f64>,
    /// Whether a tightly coupled EKF takes each range with its offset's error considered
    /// (Schmidt–Kalman: the track keeps its state's cross-covariance with the offsets' errors,
    /// so an error shared by every range of an anchor is not averaged away); `false` adds the
    /// offset's variance to each range's noise as if it were fresh. Default true. The UKF and
    /// the IMM always take the second way.
    pub consider: bool,
}

impl Default for RangeBiasSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            prior_std_m: None,
            random_walk_m_per_sqrt_s: 0.005,
            max_abs_m: None,
            consider: true,
        }
    }
}

/// `[tracker.heading]`: the heading channel of tracks that send yaw rates, odometry without a
/// heading, odometry increments or body-frame IMU samples (see the tracker's `heading` module and
/// [`rtls_estimation::aided::HeadingModel`]). State: heading, gyro bias, odometer heading offset.
/// The defaults suit a MEMS gyro (a phone's, a robot's) and wheel odometry.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingSettings {
    /// A yaw rate's standard deviation when its record has none, rad/s (> 0). Default 0.005.
    pub gyro_noise_std_radps: f64,
    /// Prior standard deviation of the gyro's bias, rad/s (> 0). Default 0.01 (0.6°/s: an
    /// uncalibrated MEMS gyro).
    pub gyro_bias_std_radps: f64,
    /// Random walk of the gyro's bias, rad/s/√s (> 0). Default 1e-4.
    pub gyro_bias_random_walk_radps_per_sqrt_s: f64,
    /// Without a yaw rate the heading is a random walk of this density, rad/√s (> 0). Default
    /// 0.3 (a vehicle or walker can turn a right angle in a few seconds).
    pub heading_random_walk_rad_per_sqrt_s: f64,
    /// Random walk (drift) of an odometer heading's offset from the true heading, rad/√s (> 0).
    /// Default 0.005 (about 20° in an hour, seed 004's gyro drift).
    pub odometer_drift_rad_per_sqrt_s: f64,
    /// Prior standard deviation of an odometer heading's offset, rad (> 0). Default 0.05:
    /// odometry headings are in the site frame (`docs/FORMATS.md`), up to a few degrees.
    pub odometer_offset_std_rad: f64,
    /// Whether the track's course over ground is its heading (a vehicle, a robot, a sensor
    /// carried facing forward). Default true; false for a sensor whose axes are not the
    /// direction of travel (then headings come from odometry records only).
    pub course_is_heading: bool,
    /// The course is used as a heading reference from this speed on, m/s (> 0). Default 0.5.
    pub course_min_speed_mps: f64,
    /// Standard deviation of the heading about the course (side slip, crabbing, gait), rad
    /// (> 0). Default 0.05.
    pub course_heading_std_rad: f64,
    /// The longest correlation time of the heading's error in a velocity made from a speed, s
    /// (0 to 3600). The channel's heading error (an odometer's or an integrated gyro's drift)
    /// persists until a heading reference renews it — for `τ_ψ`, the interval between the
    /// channel's course references, this value before the first or when they stop — so the
    /// across-track part of the velocities it
    /// turns speeds into, `s² σ_ψ²`, is one error shared by many records, not a fresh one
    /// each: that part's variance is inflated by `max(1, 2 τ_ψ / Δt)`, `Δt` after the track's
    /// previous speed (Gelb 1974, §4.6). Default 0: every record's heading error is its own.
    /// On the labyrinth recording (UWB every 0.128 s + wheel odometry whose heading drifts 0.2–0.4
    /// rad) 10 takes the track from 25 % to 74 % of truths inside its 95 % ellipse and from
    /// 0.176 to 0.149 m; on a simulated fast vehicle with fixes 2 s apart it costs accuracy
    /// (0.47 → 0.59 m at 1 s) for no gain in consistency, so it is a setting, not a default.
    /// Used only where the heading's error is not considered (`consider_heading_error =
    /// false`, or under the IMM).
    pub heading_error_correlation_s: f64,
    /// Whether a speed's velocity takes the heading channel's error as one that persists
    /// (Schmidt–Kalman: the track keeps its error's cross-covariance with the channel's, so
    /// the shared error is not averaged away; [`crate::tracker`]'s consider module). Default
    /// true. False: the heading's variance is fresh noise of each velocity (with
    /// `heading_error_correlation_s` as the only allowance for its persistence). Under the IMM
    /// the speeds are always taken the second way.
    pub consider_heading_error: bool,
    /// Whether an IMU's horizontal specific force, rotated into the site frame by the heading,
    /// drives the prediction as a control input. Default false: an uncalibrated
    /// accelerometer's bias and tilt leak into velocity faster than the CV model's noise allows.
    pub imu_acceleration: bool,
}

impl Default for HeadingSettings {
    fn default() -> Self {
        Self {
            gyro_noise_std_radps: 0.005,
            gyro_bias_std_radps: 0.01,
            gyro_bias_random_walk_radps_per_sqrt_s: 1e-4,
            heading_random_walk_rad_per_sqrt_s: 0.3,
            odometer_drift_rad_per_sqrt_s: 0.005,
            odometer_offset_std_rad: 0.05,
            course_is_heading: true,
            course_min_speed_mps: 0.5,
            course_heading_std_rad: 0.05,
            heading_error_correlation_s: 0.0,
            consider_heading_error: true,
            imu_acceleration: false,
        }
    }
}

fn default_rssi_reading_correlation_s() -> f64 {
    1.0
}

impl Default for AdaptiveNoiseSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            memory_s: 20.0,
            max_scale: 25.0,
            correlation_s: 0.25,
            rssi_correlation_s: 2.0,
            rssi_reading_correlation_s: default_rssi_reading_correlation_s(),
            correlation_from_innovations: false,
        }
    }
}

/// `[alarms]`: predictive hazard alarms (seed 000): a tag's predicted path, with its
/// uncertainty, is checked against the hazard zones over a horizon.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlarmSettings {
    /// How far ahead the path is predicted, s (> 0). Default 10.
    #[serde(default = "default_horizon_s")]
    pub horizon_s: f64,
    /// Prediction step, s (> 0, ≤ horizon). Default 0.5.
    #[serde(default = "default_step_s")]
    pub step_s: f64,
    /// An alarm is raised when the predicted probability that the tag is inside the zone
    /// reaches this value within the horizon, in (0, 1). Default 0.5 (the predicted mean path
    /// enters); lower values warn earlier, counting the growing uncertainty.
    #[serde(default = "default_entry_probability")]
    pub entry_probability: f64,
}

fn default_horizon_s() -> f64 {
    10.0
}

fn default_step_s() -> f64 {
    0.5
}

fn default_entry_probability() -> f64 {
    0.5
}

impl Default for AlarmSettings {
    fn default() -> Self {
        Self {
            horizon_s: default_horizon_s(),
            step_s: default_step_s(),
            entry_probability: default_entry_probability(),
        }
    }
}

/// `[frame]`: where the site frame lies on the Earth. Site coordinates are then a local
/// frame about `origin` (`z` up along the ellipsoid normal, m; by default `x` east and `y`
/// north), which GNSS pseudoranges need to be solved in the site's coordinates and GeoJSON
/// outputs to be given in longitude and latitude.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameSettings {
    /// The site frame's origin.
    pub origin: GeodeticOrigin,
    /// The compass bearing of the site's `x` axis, degrees clockwise from north (0 ≤ β < 360;
    /// default 90: `x` east, `y` north). A plan drawn along a building's walls is rarely aligned
    /// with north; `y` is always 90° counter-clockwise from `x`.
    #[serde(default = "default_x_axis_bearing_deg")]
    pub x_axis_bearing_deg: f64,
}

fn default_x_axis_bearing_deg() -> f64 {
    90.0
}

/// A WGS-84 geodetic position: the origin of the site frame.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeodeticOrigin {
    /// Geodetic latitude, degrees (−90 to 90, north positive).
    pub latitude_deg: f64,
    /// Longitude, degrees (−180 to 180, east positive).
    pub longitude_deg: f64,
    /// Height above the WGS-84 ellipsoid (not above sea level), m (−11 000 to 100 000).
    pub height_m: f64,
}

impl FrameSettings {
    /// The site frame: origin and the bearing of its `x` axis
    /// ([`rtls_positioning::gnss::LocalFrame::with_x_axis_bearing`]).
    ///
    /// # Errors
    /// An invalid origin or bearing (the loader refuses those).
    pub fn local_frame(
        &self,
    ) -> std::result::Result<rtls_positioning::gnss::LocalFrame, rtls_positioning::PositioningError> {
        rtls_positioning::gnss::LocalFrame::with_x_axis_bearing(self.origin.geodetic(), self.x_axis_bearing_deg)
    }

    /// WGS-84 longitude, latitude (degrees) and ellipsoidal height (m) of a site position
    /// `[x, y, z]` (m; `z` 0 for a 2-D position): the offset from the origin taken to ECEF,
    /// `ecef = ecef₀ + R_siteᵀ [x, y, z]` (`R_site` turns ENU by the `x` axis' bearing), and
    /// back to geodetic — the RFC 7946 GeoJSON order. `None` when the origin is not a valid
    /// geodetic position (the loader refuses those).
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::{FrameSettings, GeodeticOrigin};
    /// let origin = GeodeticOrigin { latitude_deg: 47.3769, longitude_deg: 8.5417, height_m: 455.0 };
    /// let frame = FrameSettings { origin, x_axis_bearing_deg: 90.0 };
    /// let [lon, lat, h] = frame.wgs84_of([0.0, 111.2, 0.0]).unwrap();
    /// // 111.2 m north is about 0.001° of latitude; the longitude does not change
    /// assert!((lat - 47.3779).abs() < 2e-5 && (lon - 8.5417).abs() < 1e-9 && (h - 455.0).abs() < 0.01);
    /// // the plan's x axis pointing north (bearing 0): 111.2 m along x is the same point
    /// let turned = FrameSettings { origin, x_axis_bearing_deg: 0.0 };
    /// let [lon_x, lat_x, _] = turned.wgs84_of([111.2, 0.0, 0.0]).unwrap();
    /// assert!((lat_x - lat).abs() < 1e-9 && (lon_x - lon).abs() < 1e-9);
    /// ```
    #[must_use]
    pub fn wgs84_of(&self, position_m: [f64; 3]) -> Option<[f64; 3]> {
        let frame = self.local_frame().ok()?;
        let at = frame
            .geodetic_of_enu(&nalgebra::Vector3::new(position_m[0], position_m[1], position_m[2]))
            .ok()?;
        Some([at.longitude_deg, at.latitude_deg, at.height_m])
    }

    /// The site position `[x, y, z]` (m) of a WGS-84 longitude, latitude (degrees) and
    /// ellipsoidal height (m): the inverse of [`FrameSettings::wgs84_of`]. `None` for an
    /// invalid geodetic position or origin.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::site::{FrameSettings, GeodeticOrigin};
    /// let origin = GeodeticOrigin { latitude_deg: 47.3769, longitude_deg: 8.5417, height_m: 455.0 };
    /// let frame = FrameSettings { origin, x_axis_bearing_deg: 90.0 };
    /// let wgs84 = frame.wgs84_of([12.0, -7.0, 1.5]).unwrap();
    /// let [x, y, z] = frame.site_of_wgs84(wgs84).unwrap();
    /// assert!((x - 12.0).abs() < 1e-6 && (y + 7.0).abs() < 1e-6 && (z - 1.5).abs() < 1e-6);
    /// ```
    #[must_use]
    pub fn site_of_wgs84(&self, wgs84: [f64; 3]) -> Option<[f64; 3]> {
        let frame = self.local_frame().ok()?;
        let ecef = rtls_positioning::gnss::Geodetic {
            latitude_deg: wgs84[1],
            longitude_deg: wgs84[0],
            height_m: wgs84[2],
        }
        .to_ecef()
        .ok()?;
        let site = frame.enu_from_ecef(&ecef);
        Some([site.x, site.y, site.z])
    }
}

impl GeodeticOrigin {
    /// The origin as `rtls_positioning`'s geodetic position.
    #[must_use]
    pub fn geodetic(&self) -> rtls_positioning::gnss::Geodetic {
        rtls_positioning::gnss::Geodetic {
            latitude_deg: self.latitude_deg,
            longitude_deg: self.longitude_deg,
            height_m: self.height_m,
        }
    }
}

/// `[tracker.gnss]`: GNSS pseudoranges. A tag's pseudoranges of one epoch are solved together
/// into a fix and a receiver clock bias; each track keeps a two-state clock filter `[b, ḃ]`
/// (bias and drift, m and m/s) whose prediction is the solver's prior on the bias.
///
/// The clock model is the two-state random walk of Brown & Hwang: `ḃ` is a random walk of
/// spectral density `q_d` and `b` integrates it plus a white frequency noise of density `q_b`:
/// ```text
/// Q(Δt) = [[q_b Δt + q_d Δt³/3, q_d Δt²/2], [q_d Δt²/2, q_d Δt]]
/// ```
/// A TCXO's Allan-variance coefficients (`h₀ = 2·10⁻¹⁹ s`, `h₋₂ = 2·10⁻²⁰ s⁻¹`) give
/// `q_b = c² h₀/2 ≈ 0.009 m²/s` and `q_d = c² 2π² h₋₂ ≈ 0.036 m²/s³`; the defaults are about
/// ten and three times larger, for a smartphone's temperature swings.
///
/// # References
/// R. G. Brown, P. Y. C. Hwang, *Introduction to Random Signals and Applied Kalman Filtering*,
/// 4th ed., 2012, §9.3 (the clock model and its TCXO coefficients).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GnssSettings {
    /// A pseudorange's standard deviation at the zenith, for records without `std_m`:
    /// `σ = σ₀ / sin(max(el, min_elevation_deg))`, m (0.01 to 1000). Default 5 (a smartphone).
    pub pseudorange_std_m: f64,
    /// The elevation below which that `σ` stops growing, degrees (0.1 to 90). Default 5.
    pub min_elevation_deg: f64,
    /// Probability that an epoch's χ² residual test fails on fault-free pseudoranges (RAIM);
    /// a failing epoch excludes its worst satellite while redundancy remains (1e-9 to 0.5).
    /// Default 0.001.
    pub false_alarm_probability: f64,
    /// Clock bias white-frequency noise density `q_b`, m²/s (1e-9 to 1e6). Default 0.1.
    pub clock_bias_noise_m2ps: f64,
    /// Clock drift random-walk density `q_d`, m²/s³ (1e-9 to 1e6). Default 0.1.
    pub clock_drift_noise_m2ps3: f64,
    /// The drift's standard deviation when a track's clock starts, m/s (0.001 to 1e5).
    /// Default 600 (2 ppm).
    pub initial_clock_drift_std_mps: f64,
}

impl Default for GnssSettings {
    fn default() -> Self {
        Self {
            pseudorange_std_m: 5.0,
            min_elevation_deg: 5.0,
            false_alarm_probability: 1e-3,
            clock_bias_noise_m2ps: 0.1,
            clock_drift_noise_m2ps3: 0.1,
            initial_clock_drift_std_mps: 600.0,
        }
    }
}

/// `[[corridors]]`: one corridor tags move in (a drift, an aisle, a hallway), as its plan
/// centreline and half-width. See [`crate::corridors`] for the geometry.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Corridor {
    /// Unique id.
    pub id: String,
    /// The centreline, a polyline of at least two distinct consecutive points `[x, y]`, m.
    pub points_m: Vec<[f64; 2]>,
    /// The height `z` of a tag on the centreline at each point (a drift's walking line with its
    /// grade: floor height plus the height the tag is worn at), m; one per point, linear in
    /// between. With `tracker.dimensions = 3` the map constraint holds the estimate's height to
    /// it (`[tracker.map] vertical_std_m`). Optional; absent = no height constraint.
    #[serde(default)]
    pub heights_m: Option<Vec<f64>>,
    /// Half the corridor's width: from the centreline to the walls, m (> 0).
    pub half_width_m: f64,
}

/// `[tracker.map]`: the map constraint. After each epoch's updates the estimate's lateral
/// offset from its nearest corridor segment is observed as `0 ± lateral_std_m` (not within
/// `junction_radius_m` of a junction, where which way the tag went is for the measurements to
/// tell), and an estimate past a dead end is pulled back to it (Simon 2010's soft constraint
/// as a pseudo-measurement). Does nothing without `[[corridors]]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MapSettings {
    /// Whether the constraint is applied. Default true.
    pub enabled: bool,
    /// Standard deviation of a tag's lateral offset from the centreline, m (> 0). Absent: the
    /// corridor's `half_width_m / √3` (a tag anywhere across the corridor, uniformly).
    pub lateral_std_m: Option<f64>,
    /// Near a junction, within this distance, the lateral constraint is not applied, m (≥ 0).
    /// Absent: twice the widest corridor's half-width.
    pub junction_radius_m: Option<f64>,
    /// 3-D tracking, corridors with `heights_m`: standard deviation of a tag's height about
    /// the corridor's height at its place, m (> 0). Default 0.3 (a tag on a helmet, a belt or
    /// in a hand of walkers of different sizes).
    pub vertical_std_m: f64,
}

impl MapSettings {
    /// Default of [`MapSettings::vertical_std_m`], m.
    pub const DEFAULT_VERTICAL_STD_M: f64 = 0.3;
}

impl Default for MapSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            lateral_std_m: None,
            junction_radius_m: None,
            vertical_std_m: Self::DEFAULT_VERTICAL_STD_M,
        }
    }
}

/// A floor-plan image placed in site coordinates: the picture's lower-left and upper-right
/// corners (an image drawn north-up on a plan aligned with the site's axes; turn the site with
/// `[frame] x_axis_bearing_deg`, not the image).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FloorPlan {
    /// The image (PNG, JPEG, SVG, WebP or GIF), relative to the site file's folder.
    pub image: PathBuf,
    /// `[[x_min, y_min], [x_max, y_max]]`: where the image's lower-left and upper-right
    /// corners lie, m.
    pub bounds_m: [[f64; 2]; 2],
}

impl FloorPlan {
    /// The image's media type from its file extension, or `None` for a kind browsers do not
    /// draw.
    ///
    /// ```
    /// use rtls_engine::site::FloorPlan;
    /// let plan = FloorPlan { image: "level-1.PNG".into(), bounds_m: [[0.0, 0.0], [50.0, 30.0]] };
    /// assert_eq!(plan.media_type(), Some("image/png"));
    /// ```
    #[must_use]
    pub fn media_type(&self) -> Option<&'static str> {
        let extension = self.image.extension()?.to_str()?.to_ascii_lowercase();
        Some(match extension.as_str() {
            "png" => "image/png",
            "jpg" | "jpeg" => "image/jpeg",
            "svg" => "image/svg+xml",
            "webp" => "image/webp",
            "gif" => "image/gif",
            _ => return None,
        })
    }
}
