//! Measurement records: what a reader or a tag reports, as it arrives at the manager layer.
//!
//! A [`Record`] is a time stamp, a tag id and one [`Measurement`] (range, RSSI, TDOA, RSSI vector,
//! position fix, accelerometer sample, odometry speed + heading, velocity, yaw rate, odometry
//! increment, body-frame IMU sample, GNSS pseudorange). Records travel as
//! JSON Lines ([`parse_json_line`], [`JsonLines`], [`to_json_line`]) or CSV ([`CsvRecords`],
//! [`to_csv_row`], [`CSV_COLUMNS`]); `docs/FORMATS.md` documents both with a JSON Schema.
//! Records that arrive out of order are put back in order by a [`Reorderer`], which reports late
//! ones instead of dropping them.
//!
//! Every parser validates what it reads ([`Record::validate`]): plausible times (finite, within
//! ±[`MAX_ABS_TIME_S`]), finite numbers, non-negative speeds and standard deviations, symmetric positive semi-definite covariances of the right
//! size, non-empty ids. Errors are [`EngineError::Parse`] naming the file, line and field.
//!
//! # References
//! Seed 000 (`SPEC.md`, architecture): the reader layer produces raw measurements of tags; the
//! manager layer cleans, orders and tracks them.

mod csv_format;
mod json;
mod reorder;
mod time;

pub use csv_format::{to_csv_row, CsvRecords, CSV_COLUMNS};
pub use json::{parse_json_line, to_json_line, JsonLines};
pub use reorder::{Emitted, Reorderer};
pub use time::{implausible_time, TimeGate, JUMP_CONFIRMATIONS, MAX_ABS_TIME_S};

/// The longest interval of an [`Measurement::OdometryIncrement`], s (1 minute): longer ones are
/// not increments but gaps.
pub const MAX_INCREMENT_INTERVAL_S: f64 = 60.0;
/// The smallest distance of a satellite from the Earth's centre a `pseudorange` record may give,
/// m (just below the Earth's polar radius, 6 356 752 m).
pub const MIN_SATELLITE_RADIUS_M: f64 = 6.3e6;

/// The largest distance of a satellite from the Earth's centre a `pseudorange` record may give,
/// m (above every navigation satellite orbit: GEO and IGSO at 42 164 km).
pub const MAX_SATELLITE_RADIUS_M: f64 = 5.0e7;

/// The longest record line the readers accept, bytes (1 MiB): a longer line is an error for
/// that line (and is skipped without being held in memory), so a binary or endless input
/// cannot exhaust memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

use serde::{Deserialize, Serialize};

use crate::error::{EngineError, Result};

/// What [`read_line`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Line {
    /// The end of the input.
    End,
    /// A line (with its `\n`, if any) is in the buffer.
    Text,
    /// The line is longer than [`MAX_LINE_BYTES`]; the buffer is empty and the rest of the line
    /// is skipped by the next call.
    TooLong,
}

/// Reads one line into `buffer`, holding at most [`MAX_LINE_BYTES`]. `skipping` carries over
/// between calls: after [`Line::TooLong`] the next call first drops the rest of that line.
pub(crate) fn read_line(
    reader: &mut impl std::io::BufRead,
    buffer: &mut Vec<u8>,
    skipping: &mut bool,
) -> std::io::Result<Line> {
    buffer.clear();
    loop {
        let available = match reader.fill_buf() {
            Ok(available) => available,
            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(error) => return Err(error),
        };
        if available.is_empty() {
            *skipping = false;
            return Ok(if buffer.is_empty() { Line::End } else { Line::Text });
        }
        let (length, complete) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        if *skipping {
            reader.consume(length);
            if complete {
                *skipping = false;
            }
            continue;
        }
        if buffer.len() + length > MAX_LINE_BYTES {
            buffer.clear();
            reader.consume(length);
            *skipping = !complete;
            return Ok(Line::TooLong);
        }
        buffer.extend_from_slice(&available[..length]);
        reader.consume(length);
        if complete {
            return Ok(Line::Text);
        }
    }
}

/// One measurement of one tag at one time.
///
/// # Units
/// `time_s` in seconds on the site's clock (any origin, e.g. Unix time).
///
/// # Examples
/// ```
/// use rtls_engine::record::{Measurement, Record};
///
/// let record = Record {
///     time_s: 12.5,
///     tag: "miner-017".into(),
///     measurement: Measurement::Range { anchor: "R12".into(), range_m: 4.21, std_m: Some(0.1), anchor_position_m: None },
/// };
/// assert!(record.validate("input.jsonl", 1).is_ok());
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Record {
    /// Time of the measurement, s.
    pub time_s: f64,
    /// The tag's id (non-empty).
    pub tag: String,
    /// What was measured.
    pub measurement: Measurement,
}

/// One RSSI reading of a fingerprint scan: an anchor that was heard and its signal strength.
///
/// Anchors that were not heard are not listed (absence is never a sentinel value).
///
/// # Examples
/// ```
/// use rtls_engine::record::AnchorReading;
///
/// let reading = AnchorReading { anchor: "AP-3".into(), rssi_dbm: -71.0 };
/// assert_eq!(reading.anchor, "AP-3");
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnchorReading {
    /// The anchor's id (as in the site model).
    pub anchor: String,
    /// Received signal strength, dBm.
    pub rssi_dbm: f64,
}

/// The measurement a [`Record`] carries: one variant per kind.
///
/// Anchors are string ids; the site model maps them to positions. Optional standard deviations
/// are `None` when the sender does not know them (the tracker then uses the site's defaults).
/// Vectors have 2 or 3 components (`x, y` or `x, y, z`); covariances are `D × D` row-major with
/// `D` the vector's dimension.
///
/// # Examples
/// ```
/// use rtls_engine::record::Measurement;
///
/// let fix = Measurement::Fix { position_m: vec![1.0, 2.0], covariance_m2: vec![0.25, 0.0, 0.0, 0.25] };
/// assert_eq!(fix.kind(), "fix");
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Measurement {
    /// Distance to an anchor (UWB time of arrival, ultrasonic time of flight).
    Range {
        /// The anchor's id.
        anchor: String,
        /// Measured distance, m (finite; may be negative: Wi-Fi FTM/RTT reports negative
        /// ranges for devices close to the responder).
        range_m: f64,
        /// Its standard deviation, m (≥ 0).
        std_m: Option<f64>,
        /// The anchor's position at the time of the range `[x, y]` or `[x, y, z]` (site frame,
        /// m), for an anchor that moves (on a vehicle, a drone, another tag); absent: the
        /// reader's position in the site. A 2-component position keeps the reader's height.
        anchor_position_m: Option<Vec<f64>>,
    },
    /// Received signal strength at (or from) an anchor.
    Rssi {
        /// The anchor's id.
        anchor: String,
        /// Received signal strength, dBm.
        rssi_dbm: f64,
    },
    /// Time difference of arrival as a range difference: `‖p − anchor‖ − ‖p − reference‖`.
    Tdoa {
        /// The anchor's id.
        anchor: String,
        /// The reference anchor's id (different from `anchor`).
        reference: String,
        /// Range difference, m (speed of light × time difference).
        range_difference_m: f64,
        /// Its standard deviation, m (≥ 0).
        std_m: Option<f64>,
    },
    /// A fingerprint scan: the anchors heard and their RSSI (at least one, no duplicates).
    RssiVector {
        /// The readings, one per heard anchor.
        readings: Vec<AnchorReading>,
    },
    /// A position fix computed elsewhere (multilateration, fingerprinting, GNSS, …).
    Fix {
        /// Position `[x, y]` or `[x, y, z]`, m.
        position_m: Vec<f64>,
        /// Its covariance, `D × D` row-major, m².
        covariance_m2: Vec<f64>,
    },
    /// An accelerometer sample in the site frame.
    Accelerometer {
        /// Acceleration `[x, y]` or `[x, y, z]`, m/s².
        acceleration_mps2: Vec<f64>,
        /// Per-axis standard deviation, m/s² (≥ 0).
        std_mps2: Option<f64>,
    },
    /// Odometry: speed over ground and heading (seed 004).
    Odometry {
        /// Speed, m/s (≥ 0; the direction is the heading).
        speed_mps: f64,
        /// Heading, rad, counter-clockwise from the site's x axis; absent: the track's heading
        /// channel supplies it (yaw rates integrated, aligned with the course over ground).
        heading_rad: Option<f64>,
        /// Speed standard deviation, m/s (≥ 0).
        speed_std_mps: Option<f64>,
        /// Heading standard deviation, rad (≥ 0).
        heading_std_rad: Option<f64>,
    },
    /// A yaw rate: a gyro's rate about the vertical, or a vehicle's from its wheels or CAN bus.
    /// It drives the track's heading channel (with the gyro's bias as a state).
    YawRate {
        /// Rate of turn, rad/s, counter-clockwise positive.
        yaw_rate_radps: f64,
        /// Its standard deviation, rad/s (≥ 0).
        std_radps: Option<f64>,
    },
    /// An odometry increment over the interval ending at the record's time: distance
    /// travelled and change of heading (wheel encoders).
    OdometryIncrement {
        /// Distance travelled, m (≥ 0).
        distance_m: f64,
        /// Change of heading, rad, counter-clockwise positive.
        yaw_change_rad: f64,
        /// The interval, s (> 0).
        interval_s: f64,
        /// Distance standard deviation, m (≥ 0).
        distance_std_m: Option<f64>,
        /// Heading change standard deviation, rad (≥ 0).
        yaw_change_std_rad: Option<f64>,
    },
    /// A body-frame inertial sample: specific force and angular rate in the sensor's axes
    /// (x forward, y left, z up when mounted level).
    Imu {
        /// Specific force `[x, y]` or `[x, y, z]`, m/s² (with `z`, gravity included: at rest
        /// it reads `[0, 0, 9.81]` when level).
        acceleration_mps2: Vec<f64>,
        /// Angular rate `[z]` (about the vertical, sensor level) or `[x, y, z]`, rad/s.
        angular_rate_radps: Vec<f64>,
        /// Per-axis specific-force standard deviation, m/s² (≥ 0).
        std_mps2: Option<f64>,
        /// Per-axis angular-rate standard deviation, rad/s (≥ 0).
        std_radps: Option<f64>,
    },
    /// A velocity measurement in the site frame.
    Velocity {
        /// Velocity `[x, y]` or `[x, y, z]`, m/s.
        velocity_mps: Vec<f64>,
        /// Its covariance, `D × D` row-major, (m/s)².
        covariance_m2ps2: Option<Vec<f64>>,
    },
    /// A GNSS pseudorange: `ρ = ‖s − p‖ + c δt + v`, the distance to a satellite plus the
    /// receiver's unknown clock offset (`c δt`, common to every satellite of an epoch).
    Pseudorange {
        /// The satellite's id (e.g. `G05`, `E11`).
        satellite: String,
        /// The satellite's position in WGS-84 ECEF at the signal's transmit time, m; its
        /// distance from the Earth's centre lies in
        /// [[`MIN_SATELLITE_RADIUS_M`], [`MAX_SATELLITE_RADIUS_M`]]. The tracker applies the
        /// Earth-rotation (Sagnac) correction itself.
        satellite_position_m: [f64; 3],
        /// The pseudorange, m, already corrected by the sender for the satellite clock
        /// (including the relativistic term), the ionosphere and the troposphere.
        pseudorange_m: f64,
        /// Its standard deviation, m (≥ 0); absent: the site's elevation-dependent default.
        std_m: Option<f64>,
    },
}

impl Measurement {
    /// The kind's name as written in the `kind` field of both formats (`"range"`, `"rssi"`,
    /// `"tdoa"`, `"rssi_vector"`, `"fix"`, `"accelerometer"`, `"odometry"`, `"velocity"`,
    /// `"yaw_rate"`, `"odometry_increment"`, `"imu"`, `"pseudorange"`).
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::Measurement;
    ///
    /// let rssi = Measurement::Rssi { anchor: "R1".into(), rssi_dbm: -70.0 };
    /// assert_eq!(rssi.kind(), "rssi");
    /// ```
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Range { .. } => "range",
            Self::Rssi { .. } => "rssi",
            Self::Tdoa { .. } => "tdoa",
            Self::RssiVector { .. } => "rssi_vector",
            Self::Fix { .. } => "fix",
            Self::Accelerometer { .. } => "accelerometer",
            Self::Odometry { .. } => "odometry",
            Self::Velocity { .. } => "velocity",
            Self::YawRate { .. } => "yaw_rate",
            Self::OdometryIncrement { .. } => "odometry_increment",
            Self::Imu { .. } => "imu",
            Self::Pseudorange { .. } => "pseudorange",
        }
    }
}

/// A field-level validation failure, before the file and line are attached.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Invalid {
    /// The JSON key at fault, with an index for vector elements (`position_m[2]`).
    pub field: String,
    /// What is wrong and what is allowed.
    pub reason: String,
}

impl Invalid {
    pub(crate) fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            reason: reason.into(),
        }
    }

    pub(crate) fn at(self, file: &str, line: usize) -> EngineError {
        EngineError::Parse {
            file: file.to_string(),
            line,
            field: self.field,
            reason: self.reason,
        }
    }
}

type Checked = core::result::Result<(), Invalid>;

impl Record {
    /// Checks every value: a plausible time ([`implausible_time`]: finite, within
    /// ±[`MAX_ABS_TIME_S`] s), finite numbers (a range may be negative), non-negative speeds and
    /// standard deviations, vectors
    /// of 2 or 3 components, covariances of matching size that are symmetric and positive
    /// semi-definite, non-empty ids without leading or trailing white space, control characters,
    /// `;` or `=` (so that every id can be written in CSV), TDOA anchor ≠ reference, RSSI vectors
    /// non-empty without duplicate anchors, satellites between [`MIN_SATELLITE_RADIUS_M`] and
    /// [`MAX_SATELLITE_RADIUS_M`] from the Earth's centre.
    ///
    /// `file` and `line` name the record's source in the error.
    ///
    /// # Errors
    /// [`EngineError::Parse`] naming `file`, `line` and the field (JSON key, with the element's
    /// index for vectors, e.g. `covariance_m2[1]`) of the first bad value.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::{Measurement, Record};
    ///
    /// let record = Record {
    ///     time_s: 3.0,
    ///     tag: "robot-2".into(),
    ///     measurement: Measurement::Range { anchor: "U1".into(), range_m: 1.0, std_m: Some(-0.1), anchor_position_m: None },
    /// };
    /// let error = record.validate("log.jsonl", 7).unwrap_err();
    /// assert!(error.to_string().starts_with("log.jsonl:7: field `std_m`"));
    /// ```
    pub fn validate(&self, file: &str, line: usize) -> Result<()> {
        self.check().map_err(|invalid| invalid.at(file, line))
    }

    pub(crate) fn check(&self) -> Checked {
        if let Some(reason) = implausible_time(self.time_s) {
            return Err(Invalid::new("t", reason));
        }
        id("tag", &self.tag)?;
        match &self.measurement {
            Measurement::Range {
                anchor,
                range_m,
                std_m,
                anchor_position_m,
            } => {
                id("anchor", anchor)?;
                finite("range_m", *range_m)?;
                if let Some(position) = anchor_position_m {
                    vector("anchor_position_m", position)?;
                }
                optional_std("std_m", *std_m)
            }
            Measurement::Rssi { anchor, rssi_dbm } => {
                id("anchor", anchor)?;
                finite("rssi_dbm", *rssi_dbm)
            }
            Measurement::Tdoa {
                anchor,
                reference,
                range_difference_m,
                std_m,
            } => {
                id("anchor", anchor)?;
                id("reference", reference)?;
                if anchor == reference {
                    return Err(Invalid::new(
                        "reference",
                        format!("equals the anchor `{anchor}`; a TDOA needs two different anchors"),
                    ));
                }
                finite("range_difference_m", *range_difference_m)?;
                optional_std("std_m", *std_m)
            }
            Measurement::RssiVector { readings } => check_readings(readings),
            Measurement::Fix {
                position_m,
                covariance_m2,
            } => {
                let dimension = vector("position_m", position_m)?;
                covariance("covariance_m2", covariance_m2, dimension)
            }
            Measurement::Accelerometer {
                acceleration_mps2,
                std_mps2,
            } => {
                vector("acceleration_mps2", acceleration_mps2)?;
                optional_std("std_mps2", *std_mps2)
            }
            Measurement::Odometry {
                speed_mps,
                heading_rad,
                speed_std_mps,
                heading_std_rad,
            } => {
                non_negative("speed_mps", *speed_mps)?;
                if let Some(heading_rad) = heading_rad {
                    finite("heading_rad", *heading_rad)?;
                }
                optional_std("speed_std_mps", *speed_std_mps)?;
                optional_std("heading_std_rad", *heading_std_rad)
            }
            Measurement::YawRate {
                yaw_rate_radps,
                std_radps,
            } => {
                finite("yaw_rate_radps", *yaw_rate_radps)?;
                optional_std("std_radps", *std_radps)
            }
            Measurement::OdometryIncrement {
                distance_m,
                yaw_change_rad,
                interval_s,
                distance_std_m,
                yaw_change_std_rad,
            } => {
                non_negative("distance_m", *distance_m)?;
                finite("yaw_change_rad", *yaw_change_rad)?;
                non_negative("interval_s", *interval_s)?;
                if *interval_s == 0.0 || *interval_s > MAX_INCREMENT_INTERVAL_S {
                    return Err(Invalid::new(
                        "interval_s",
                        format!("{interval_s} s; an increment's interval must be in (0, {MAX_INCREMENT_INTERVAL_S}] s"),
                    ));
                }
                optional_std("distance_std_m", *distance_std_m)?;
                optional_std("yaw_change_std_rad", *yaw_change_std_rad)
            }
            Measurement::Imu {
                acceleration_mps2,
                angular_rate_radps,
                std_mps2,
                std_radps,
            } => {
                vector("acceleration_mps2", acceleration_mps2)?;
                if !matches!(angular_rate_radps.len(), 1 | 3) {
                    return Err(Invalid::new(
                        "angular_rate_radps",
                        format!(
                            "has {} components; must have 1 (z, sensor level) or 3 (x, y, z)",
                            angular_rate_radps.len()
                        ),
                    ));
                }
                for (i, &w) in angular_rate_radps.iter().enumerate() {
                    finite(&format!("angular_rate_radps[{i}]"), w)?;
                }
                optional_std("std_mps2", *std_mps2)?;
                optional_std("std_radps", *std_radps)
            }
            Measurement::Velocity {
                velocity_mps,
                covariance_m2ps2,
            } => {
                let dimension = vector("velocity_mps", velocity_mps)?;
                match covariance_m2ps2 {
                    Some(c) => covariance("covariance_m2ps2", c, dimension),
                    None => Ok(()),
                }
            }
            Measurement::Pseudorange {
                satellite,
                satellite_position_m,
                pseudorange_m,
                std_m,
            } => {
                id("satellite", satellite)?;
                satellite_position("satellite_position_m", satellite_position_m)?;
                finite("pseudorange_m", *pseudorange_m)?;
                optional_std("std_m", *std_m)
            }
        }
    }
}

fn finite(field: &str, value: f64) -> Checked {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Invalid::new(field, format!("{value} is not a finite number")))
    }
}

fn non_negative(field: &str, value: f64) -> Checked {
    finite(field, value)?;
    if value < 0.0 {
        return Err(Invalid::new(field, format!("{value} is negative; must be ≥ 0")));
    }
    Ok(())
}

fn optional_std(field: &str, value: Option<f64>) -> Checked {
    value.map_or(Ok(()), |v| non_negative(field, v))
}

/// Ids: non-empty, no leading or trailing white space (CSV trims cells), no control characters,
/// no `;` or `=` (the CSV RSSI-vector separators).
pub(crate) fn id(field: &str, value: &str) -> Checked {
    if value.is_empty() {
        return Err(Invalid::new(field, "is empty; ids must be non-empty"));
    }
    if value.trim() != value {
        return Err(Invalid::new(
            field,
            format!("`{value}` starts or ends with white space; ids may not"),
        ));
    }
    if let Some(c) = value.chars().find(|&c| c.is_control() || c == ';' || c == '=') {
        return Err(Invalid::new(
            field,
            format!("`{value}` contains {c:?}; ids may not contain control characters, `;` or `=`"),
        ));
    }
    Ok(())
}

fn check_readings(readings: &[AnchorReading]) -> Checked {
    if readings.is_empty() {
        return Err(Invalid::new(
            "readings",
            "is empty; list at least one heard anchor (omit the record if none was heard)",
        ));
    }
    // a set, not a scan of the earlier readings: a long line must not cost quadratic time
    let mut seen = std::collections::HashSet::with_capacity(readings.len());
    for (i, reading) in readings.iter().enumerate() {
        id(&format!("readings[{i}].anchor"), &reading.anchor)?;
        finite(&format!("readings[{i}].rssi_dbm"), reading.rssi_dbm)?;
        if !seen.insert(reading.anchor.as_str()) {
            return Err(Invalid::new(
                format!("readings[{i}].anchor"),
                format!("anchor `{}` is listed twice", reading.anchor),
            ));
        }
    }
    Ok(())
}

/// A satellite's ECEF position: finite, between [`MIN_SATELLITE_RADIUS_M`] and
/// [`MAX_SATELLITE_RADIUS_M`] from the Earth's centre (catches km for m, or a local position).
fn satellite_position(field: &str, values: &[f64; 3]) -> Checked {
    for (i, &v) in values.iter().enumerate() {
        finite(&format!("{field}[{i}]"), v)?;
    }
    let radius = values.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(MIN_SATELLITE_RADIUS_M..=MAX_SATELLITE_RADIUS_M).contains(&radius) {
        return Err(Invalid::new(
            field,
            format!(
                "is {radius:.0} m from the Earth's centre; a satellite's WGS-84 ECEF position (m) lies between \
                 {MIN_SATELLITE_RADIUS_M:e} and {MAX_SATELLITE_RADIUS_M:e} m"
            ),
        ));
    }
    Ok(())
}

/// A 2- or 3-component vector of finite numbers; returns its dimension.
fn vector(field: &str, values: &[f64]) -> core::result::Result<usize, Invalid> {
    if !(2..=3).contains(&values.len()) {
        return Err(Invalid::new(
            field,
            format!("has {} components; must have 2 (x, y) or 3 (x, y, z)", values.len()),
        ));
    }
    for (i, &v) in values.iter().enumerate() {
        finite(&format!("{field}[{i}]"), v)?;
    }
    Ok(values.len())
}

/// A `dimension × dimension` row-major covariance: finite, symmetric and positive semi-definite
/// (both to a relative tolerance of 1e-9 of its largest entry).
fn covariance(field: &str, values: &[f64], dimension: usize) -> Checked {
    let expected = dimension * dimension;
    if values.len() != expected {
        return Err(Invalid::new(
            field,
            format!(
                "has {} numbers; a {dimension}-D vector needs {expected} ({dimension} × {dimension}, row-major)",
                values.len()
            ),
        ));
    }
    for (i, &v) in values.iter().enumerate() {
        finite(&format!("{field}[{i}]"), v)?;
    }
    let scale = values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let tolerance = 1e-9 * scale;
    for row in 0..dimension {
        for column in row + 1..dimension {
            let (upper, lower) = (values[row * dimension + column], values[column * dimension + row]);
            if (upper - lower).abs() > tolerance {
                return Err(Invalid::new(
                    field,
                    format!("is not symmetric: entry ({row}, {column}) = {upper} but ({column}, {row}) = {lower}"),
                ));
            }
        }
    }
    let matrix = nalgebra::DMatrix::from_row_slice(dimension, dimension, values);
    let smallest = matrix.symmetric_eigenvalues().min();
    if smallest < -tolerance {
        return Err(Invalid::new(
            field,
            format!(
                "is not positive semi-definite (smallest eigenvalue {smallest}); variances must dominate covariances"
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
