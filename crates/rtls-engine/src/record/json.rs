//! JSON Lines: one record object per line.

use std::fmt;
use std::io::BufRead;

use serde::de::{self, DeserializeSeed, MapAccess, Visitor};
use serde::Serialize;

use super::{read_line, AnchorReading, Invalid, Line, Measurement, Record, MAX_LINE_BYTES};
use crate::error::{EngineError, Result};

/// The flat wire form of a record: every key of every kind, each optional. Declares the keys
/// once and generates the struct, the list of keys and the key-by-key reader (which remembers the
/// key being read, so that an error names it).
macro_rules! wire {
    ($($name:ident: $ty:ty),* $(,)?) => {
        #[derive(Debug, Default, Serialize)]
        struct Wire {
            $(#[serde(skip_serializing_if = "Option::is_none")] $name: Option<$ty>,)*
        }

        const KEYS: &[&str] = &[$(stringify!($name)),*];

        impl Wire {
            /// The keys that are set, in declaration order.
            fn present_keys(&self) -> Vec<&'static str> {
                let mut keys = Vec::new();
                $(if self.$name.is_some() {
                    keys.push(stringify!($name));
                })*
                keys
            }
        }

        impl<'de> Visitor<'de> for WireSeed<'_> {
            type Value = Wire;

            fn expecting(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
                formatter.write_str("a record object such as {\"t\": 1.0, \"tag\": \"a\", \"kind\": \"rssi\", …}")
            }

            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> core::result::Result<Wire, A::Error> {
                let mut wire = Wire::default();
                while let Some(key) = map.next_key::<String>()? {
                    self.key.clone_from(&key);
                    match key.as_str() {
                        $(stringify!($name) => {
                            if wire.$name.is_some() {
                                return Err(de::Error::duplicate_field(stringify!($name)));
                            }
                            wire.$name = Some(map.next_value()?);
                        })*
                        _ => return Err(de::Error::unknown_field(&key, KEYS)),
                    }
                }
                self.key.clear();
                Ok(wire)
            }
        }
    };
}

wire! {
    t: f64,
    tag: String,
    kind: String,
    anchor: String,
    reference: String,
    range_m: f64,
    range_difference_m: f64,
    rssi_dbm: f64,
    std_m: f64,
    readings: Vec<AnchorReading>,
    position_m: Vec<f64>,
    covariance_m2: Vec<f64>,
    acceleration_mps2: Vec<f64>,
    std_mps2: f64,
    speed_mps: f64,
    heading_rad: f64,
    speed_std_mps: f64,
    heading_std_rad: f64,
    velocity_mps: Vec<f64>,
    covariance_m2ps2: Vec<f64>,
    anchor_position_m: Vec<f64>,
    yaw_rate_radps: f64,
    std_radps: f64,
    distance_m: f64,
    yaw_change_rad: f64,
    interval_s: f64,
    distance_std_m: f64,
    yaw_change_std_rad: f64,
    angular_rate_radps: Vec<f64>,
    satellite: String,
    satellite_position_m: Vec<f64>,
    pseudorange_m: f64,
}

/// Reads a [`Wire`] and leaves in `key` the key being read when an error occurred.
struct WireSeed<'a> {
    key: &'a mut String,
}

impl<'de> DeserializeSeed<'de> for WireSeed<'_> {
    type Value = Wire;

    fn deserialize<D: de::Deserializer<'de>>(self, deserializer: D) -> core::result::Result<Wire, D::Error> {
        deserializer.deserialize_map(self)
    }
}

/// The kinds, as written in the `kind` field.
const KINDS: [&str; 12] = [
    "range",
    "rssi",
    "tdoa",
    "rssi_vector",
    "fix",
    "accelerometer",
    "odometry",
    "velocity",
    "yaw_rate",
    "odometry_increment",
    "imu",
    "pseudorange",
];

/// An ECEF position: exactly three components.
fn ecef(values: Vec<f64>) -> core::result::Result<[f64; 3], Invalid> {
    <[f64; 3]>::try_from(values.as_slice()).map_err(|_| {
        Invalid::new(
            "satellite_position_m",
            format!(
                "has {} components; must have 3 (x, y, z in WGS-84 ECEF, m)",
                values.len()
            ),
        )
    })
}

/// Takes a required key out of the wire form.
fn required<T>(value: &mut Option<T>, key: &str, kind: &str) -> core::result::Result<T, Invalid> {
    value
        .take()
        .ok_or_else(|| Invalid::new(key, format!("is missing; kind `{kind}` requires it")))
}

impl Wire {
    fn into_record(mut self) -> core::result::Result<Record, Invalid> {
        let time_s = required(&mut self.t, "t", "any")?;
        let tag = required(&mut self.tag, "tag", "any")?;
        let kind = required(&mut self.kind, "kind", "any")?;
        let k = kind.as_str();
        let measurement = match k {
            "range" => Measurement::Range {
                anchor: required(&mut self.anchor, "anchor", k)?,
                range_m: required(&mut self.range_m, "range_m", k)?,
                std_m: self.std_m.take(),
                anchor_position_m: self.anchor_position_m.take(),
            },
            "rssi" => Measurement::Rssi {
                anchor: required(&mut self.anchor, "anchor", k)?,
                rssi_dbm: required(&mut self.rssi_dbm, "rssi_dbm", k)?,
            },
            "tdoa" => Measurement::Tdoa {
                anchor: required(&mut self.anchor, "anchor", k)?,
                reference: required(&mut self.reference, "reference", k)?,
                range_difference_m: required(&mut self.range_difference_m, "range_difference_m", k)?,
                std_m: self.std_m.take(),
            },
            "rssi_vector" => Measurement::RssiVector {
                readings: required(&mut self.readings, "readings", k)?,
            },
            "fix" => Measurement::Fix {
                position_m: required(&mut self.position_m, "position_m", k)?,
                covariance_m2: required(&mut self.covariance_m2, "covariance_m2", k)?,
            },
            "accelerometer" => Measurement::Accelerometer {
                acceleration_mps2: required(&mut self.acceleration_mps2, "acceleration_mps2", k)?,
                std_mps2: self.std_mps2.take(),
            },
            "odometry" => Measurement::Odometry {
                speed_mps: required(&mut self.speed_mps, "speed_mps", k)?,
                heading_rad: self.heading_rad.take(),
                speed_std_mps: self.speed_std_mps.take(),
                heading_std_rad: self.heading_std_rad.take(),
            },
            "velocity" => Measurement::Velocity {
                velocity_mps: required(&mut self.velocity_mps, "velocity_mps", k)?,
                covariance_m2ps2: self.covariance_m2ps2.take(),
            },
            "yaw_rate" => Measurement::YawRate {
                yaw_rate_radps: required(&mut self.yaw_rate_radps, "yaw_rate_radps", k)?,
                std_radps: self.std_radps.take(),
            },
            "odometry_increment" => Measurement::OdometryIncrement {
                distance_m: required(&mut self.distance_m, "distance_m", k)?,
                yaw_change_rad: required(&mut self.yaw_change_rad, "yaw_change_rad", k)?,
                interval_s: required(&mut self.interval_s, "interval_s", k)?,
                distance_std_m: self.distance_std_m.take(),
                yaw_change_std_rad: self.yaw_change_std_rad.take(),
            },
            "imu" => Measurement::Imu {
                acceleration_mps2: required(&mut self.acceleration_mps2, "acceleration_mps2", k)?,
                angular_rate_radps: required(&mut self.angular_rate_radps, "angular_rate_radps", k)?,
                std_mps2: self.std_mps2.take(),
                std_radps: self.std_radps.take(),
            },
            "pseudorange" => Measurement::Pseudorange {
                satellite: required(&mut self.satellite, "satellite", k)?,
                satellite_position_m: ecef(required(&mut self.satellite_position_m, "satellite_position_m", k)?)?,
                pseudorange_m: required(&mut self.pseudorange_m, "pseudorange_m", k)?,
                std_m: self.std_m.take(),
            },
            _ => {
                return Err(Invalid::new(
                    "kind",
                    format!("unknown kind `{kind}`; expected one of {}", KINDS.join(", ")),
                ));
            }
        };
        // Whatever is left over belongs to another kind.
        if let Some(key) = self.present_keys().first() {
            return Err(Invalid::new(*key, format!("is not used by kind `{kind}`")));
        }
        Ok(Record {
            time_s,
            tag,
            measurement,
        })
    }

    fn from_record(record: &Record) -> Self {
        let mut wire = Wire {
            t: Some(record.time_s),
            tag: Some(record.tag.clone()),
            kind: Some(record.measurement.kind().to_string()),
            ..Wire::default()
        };
        match &record.measurement {
            Measurement::Range {
                anchor,
                range_m,
                std_m,
                anchor_position_m,
            } => {
                wire.anchor = Some(anchor.clone());
                wire.range_m = Some(*range_m);
                wire.std_m = *std_m;
                wire.anchor_position_m.clone_from(anchor_position_m);
            }
            Measurement::Rssi { anchor, rssi_dbm } => {
                wire.anchor = Some(anchor.clone());
                wire.rssi_dbm = Some(*rssi_dbm);
            }
            Measurement::Tdoa {
                anchor,
                reference,
                range_difference_m,
                std_m,
            } => {
                wire.anchor = Some(anchor.clone());
                wire.reference = Some(reference.clone());
                wire.range_difference_m = Some(*range_difference_m);
                wire.std_m = *std_m;
            }
            Measurement::RssiVector { readings } => wire.readings = Some(readings.clone()),
            Measurement::Fix {
                position_m,
                covariance_m2,
            } => {
                wire.position_m = Some(position_m.clone());
                wire.covariance_m2 = Some(covariance_m2.clone());
            }
            Measurement::Accelerometer {
                acceleration_mps2,
                std_mps2,
            } => {
                wire.acceleration_mps2 = Some(acceleration_mps2.clone());
                wire.std_mps2 = *std_mps2;
            }
            Measurement::Odometry {
                speed_mps,
                heading_rad,
                speed_std_mps,
                heading_std_rad,
            } => {
                wire.speed_mps = Some(*speed_mps);
                wire.heading_rad = *heading_rad;
                wire.speed_std_mps = *speed_std_mps;
                wire.heading_std_rad = *heading_std_rad;
            }
            Measurement::Velocity {
                velocity_mps,
                covariance_m2ps2,
            } => {
                wire.velocity_mps = Some(velocity_mps.clone());
                wire.covariance_m2ps2.clone_from(covariance_m2ps2);
            }
            Measurement::YawRate {
                yaw_rate_radps,
                std_radps,
            } => {
                wire.yaw_rate_radps = Some(*yaw_rate_radps);
                wire.std_radps = *std_radps;
            }
            Measurement::OdometryIncrement {
                distance_m,
                yaw_change_rad,
                interval_s,
                distance_std_m,
                yaw_change_std_rad,
            } => {
                wire.distance_m = Some(*distance_m);
                wire.yaw_change_rad = Some(*yaw_change_rad);
                wire.interval_s = Some(*interval_s);
                wire.distance_std_m = *distance_std_m;
                wire.yaw_change_std_rad = *yaw_change_std_rad;
            }
            Measurement::Imu {
                acceleration_mps2,
                angular_rate_radps,
                std_mps2,
                std_radps,
            } => {
                wire.acceleration_mps2 = Some(acceleration_mps2.clone());
                wire.angular_rate_radps = Some(angular_rate_radps.clone());
                wire.std_mps2 = *std_mps2;
                wire.std_radps = *std_radps;
            }
            Measurement::Pseudorange {
                satellite,
                satellite_position_m,
                pseudorange_m,
                std_m,
            } => {
                wire.satellite = Some(satellite.clone());
                wire.satellite_position_m = Some(satellite_position_m.to_vec());
                wire.pseudorange_m = Some(*pseudorange_m);
                wire.std_m = *std_m;
            }
        }
        wire
    }
}

/// Parses one JSON Lines record and validates it ([`Record::validate`]).
///
/// The object's keys are `t` (s), `tag`, `kind` and the kind's own keys (see `docs/FORMATS.md`);
/// unknown keys, keys of another kind and duplicate keys are errors. Blank and `#` lines are not
/// records: skip them before calling this, or read with [`JsonLines`], which does.
///
/// # Errors
/// [`EngineError::Parse`] with `file` and `line` as given and the JSON key at fault as the field
/// (`-` when the line is not a JSON object at all); the reason is serde_json's message or the
/// rule that was broken.
///
/// # Examples
/// ```
/// use rtls_engine::record::{parse_json_line, Measurement};
///
/// let text = r#"{"t": 12.5, "tag": "miner-017", "kind": "range", "anchor": "R12", "range_m": 4.21, "std_m": 0.1}"#;
/// let record = parse_json_line(text, "input.jsonl", 1).unwrap();
/// assert_eq!(record.measurement, Measurement::Range { anchor: "R12".into(), range_m: 4.21, std_m: Some(0.1), anchor_position_m: None });
///
/// let error = parse_json_line(r#"{"t": 1, "tag": "a", "kind": "rssi", "rssi": -70}"#, "input.jsonl", 2).unwrap_err();
/// assert!(error.to_string().starts_with("input.jsonl:2: field `rssi`: unknown field"));
/// ```
pub fn parse_json_line(text: &str, file: &str, line: usize) -> Result<Record> {
    let mut key = String::new();
    let mut deserializer = serde_json::Deserializer::from_str(text);
    let parsed = WireSeed { key: &mut key }
        .deserialize(&mut deserializer)
        .and_then(|wire| {
            deserializer.end()?;
            Ok(wire)
        });
    let wire = parsed.map_err(|error| {
        let field = if key.is_empty() { "-".to_string() } else { key.clone() };
        EngineError::Parse {
            file: file.to_string(),
            line,
            field,
            reason: error.to_string(),
        }
    })?;
    let record = wire.into_record().map_err(|invalid| invalid.at(file, line))?;
    record.validate(file, line)?;
    Ok(record)
}

/// Writes a record as one JSON Lines object (no trailing newline): `t`, `tag`, `kind`, then the
/// kind's keys; optional values that are `None` are left out.
///
/// A valid record ([`Record::validate`]) round-trips exactly through [`parse_json_line`]
/// (numbers are written in their shortest exact form). Non-finite numbers have no JSON form and
/// are written as `null`, which the parser rejects.
///
/// # Examples
/// ```
/// use rtls_engine::record::{parse_json_line, to_json_line, Measurement, Record};
///
/// let record = Record {
///     time_s: 0.1,
///     tag: "t1".into(),
///     measurement: Measurement::Rssi { anchor: "R1".into(), rssi_dbm: -71.5 },
/// };
/// let line = to_json_line(&record);
/// assert_eq!(line, r#"{"t":0.1,"tag":"t1","kind":"rssi","anchor":"R1","rssi_dbm":-71.5}"#);
/// assert_eq!(parse_json_line(&line, "-", 1).unwrap(), record);
/// ```
#[must_use]
pub fn to_json_line(record: &Record) -> String {
    // A struct of strings, numbers and vectors always serialises.
    serde_json::to_string(&Wire::from_record(record)).unwrap_or_default()
}

/// Reads JSON Lines records from any buffered reader, one `Result<Record>` per record line.
///
/// Blank lines and lines whose first non-blank character is `#` are skipped. Each bad line is
/// reported as an error (and reading continues with the next line), so a caller can stop at the
/// first error or count and report them. A line that is not UTF-8 is an error for that line; a
/// read error of the underlying reader is reported once and ends the iteration.
///
/// # Examples
/// ```
/// use rtls_engine::record::JsonLines;
///
/// let text = "# two records\n{\"t\": 1, \"tag\": \"a\", \"kind\": \"rssi\", \"anchor\": \"R1\", \"rssi_dbm\": -70}\n\n\
///             {\"t\": 2, \"tag\": \"a\", \"kind\": \"range\", \"anchor\": \"R1\"}\n";
/// let results: Vec<_> = JsonLines::new(text.as_bytes(), "input.jsonl").collect();
/// assert_eq!(results.len(), 2);
/// assert!(results[0].is_ok());
/// assert!(results[1].as_ref().unwrap_err().to_string().starts_with("input.jsonl:4: field `range_m`"));
/// ```
#[derive(Debug)]
pub struct JsonLines<R> {
    reader: R,
    file: String,
    line: usize,
    done: bool,
    skipping: bool,
    buffer: Vec<u8>,
}

impl<R: BufRead> JsonLines<R> {
    /// Reads from `reader`; `file` names the source in errors.
    #[must_use]
    pub fn new(reader: R, file: &str) -> Self {
        Self {
            reader,
            file: file.to_string(),
            line: 0,
            done: false,
            skipping: false,
            buffer: Vec::new(),
        }
    }

    /// The 1-based line of the record returned last (0 before the first).
    #[must_use]
    pub fn line(&self) -> usize {
        self.line
    }
}

impl<R: BufRead> Iterator for JsonLines<R> {
    type Item = Result<Record>;

    fn next(&mut self) -> Option<Result<Record>> {
        while !self.done {
            match read_line(&mut self.reader, &mut self.buffer, &mut self.skipping) {
                Ok(Line::End) => self.done = true,
                Ok(Line::TooLong) => {
                    self.line += 1;
                    let reason = format!("line is longer than {MAX_LINE_BYTES} bytes; a record is one short line");
                    return Some(Err(self.error(&reason)));
                }
                Ok(Line::Text) => {
                    self.line += 1;
                    let text = match std::str::from_utf8(&self.buffer) {
                        Ok(text) => text,
                        Err(error) => {
                            let reason = format!(
                                "line is not valid UTF-8 (byte {} of the line); is the input a text file?",
                                error.valid_up_to() + 1
                            );
                            return Some(Err(self.error(&reason)));
                        }
                    };
                    let trimmed = text.trim();
                    if trimmed.is_empty() || trimmed.starts_with('#') {
                        continue;
                    }
                    return Some(parse_json_line(trimmed, &self.file, self.line));
                }
                Err(error) => {
                    self.done = true;
                    return Some(Err(EngineError::Read {
                        file: self.file.clone(),
                        line: self.line,
                        reason: error.to_string(),
                    }));
                }
            }
        }
        None
    }
}

impl<R> JsonLines<R> {
    fn error(&self, reason: &str) -> EngineError {
        EngineError::Parse {
            file: self.file.clone(),
            line: self.line,
            field: "-".into(),
            reason: reason.into(),
        }
    }
}

#[cfg(test)]
#[path = "json_tests.rs"]
mod tests;
