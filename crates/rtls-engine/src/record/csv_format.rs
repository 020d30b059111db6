//! CSV: a header row, then one record per row over a fixed set of columns.

use std::io::BufRead;

use super::{read_line, AnchorReading, Invalid, Line, Measurement, Record, MAX_LINE_BYTES};
use crate::error::{EngineError, Result};

/// The CSV columns, in the order [`to_csv_row`] writes them.
///
/// | column | used by | meaning |
/// | --- | --- | --- |
/// | `t` | all | time, s |
/// | `tag` | all | tag id |
/// | `kind` | all | `range`, `rssi`, `tdoa`, `rssi_vector`, `fix`, `accelerometer`, `odometry`, `velocity`, `yaw_rate`, `odometry_increment`, `imu`, `pseudorange` |
/// | `anchor` | range, rssi, tdoa, pseudorange (the satellite) | anchor (satellite) id |
/// | `reference` | tdoa | reference anchor id |
/// | `value` | range (m), rssi (dBm), tdoa (range difference, m), odometry (speed, m/s), yaw_rate (rad/s), odometry_increment (distance, m), pseudorange (m) | the scalar |
/// | `std` | range, tdoa, pseudorange (m), accelerometer, imu (m/s²), odometry (speed, m/s), yaw_rate (rad/s), odometry_increment (distance, m) | optional 1σ of `value` / `x,y,z` |
/// | `heading` | odometry (heading, optional), odometry_increment (change of heading, required) | rad |
/// | `heading_std` | odometry, odometry_increment | optional 1σ of `heading`, rad |
/// | `x`, `y`, `z` | fix (m), accelerometer, imu (m/s²), velocity (m/s), range (the anchor's position, m, optional), pseudorange (satellite ECEF, m, all three) | vector; `z` empty for 2-D |
/// | `covariance` | fix (m², required), velocity ((m/s)², optional) | `D × D` row-major, `;`-separated |
/// | `readings` | rssi_vector | `anchor=rssi_dbm;anchor=rssi_dbm;…` |
/// | `interval` | odometry_increment | the increment's interval, s |
/// | `rate` | imu | angular rate `z` or `x;y;z`, rad/s |
/// | `rate_std` | imu | optional 1σ of each rate, rad/s |
///
/// A file's header must contain `t`, `tag` and `kind`; the other columns may be left out (they
/// read as empty). Unknown and repeated column names are errors, and so is a non-empty cell in a
/// column the row's kind does not use.
pub const CSV_COLUMNS: [&str; 17] = [
    "t",
    "tag",
    "kind",
    "anchor",
    "reference",
    "value",
    "std",
    "heading",
    "heading_std",
    "x",
    "y",
    "z",
    "covariance",
    "readings",
    "interval",
    "rate",
    "rate_std",
];

const T: usize = 0;
const TAG: usize = 1;
const KIND: usize = 2;
const ANCHOR: usize = 3;
const REFERENCE: usize = 4;
const VALUE: usize = 5;
const STD: usize = 6;
const HEADING: usize = 7;
const HEADING_STD: usize = 8;
const X: usize = 9;
const Y: usize = 10;
const Z: usize = 11;
const COVARIANCE: usize = 12;
const READINGS: usize = 13;
const INTERVAL: usize = 14;
const RATE: usize = 15;
const RATE_STD: usize = 16;

/// Reads CSV records from any buffered reader, one `Result<Record>` per data row.
///
/// Blank lines and lines whose first non-blank character is `#` are skipped (and counted, so
/// that errors name the file's line); a line longer than [`MAX_LINE_BYTES`] or not UTF-8 is an
/// error for that line; cells are trimmed; quoting follows RFC 4180 within a line
/// (a record is one line: no field of a valid record contains a line break). Each bad row is
/// reported as an error and reading continues with the next row; a read error of the underlying
/// reader is reported once and ends the iteration.
///
/// # Examples
/// ```
/// use rtls_engine::record::{CsvRecords, Measurement};
///
/// let text = "t,tag,kind,anchor,value,std\n12.5,miner-017,range,R12,4.21,0.1\n13,miner-017,rssi,R12,-70,\n";
/// let records: Vec<_> = CsvRecords::new(text.as_bytes(), "input.csv").unwrap().collect::<Result<_, _>>().unwrap();
/// assert_eq!(records[1].measurement, Measurement::Rssi { anchor: "R12".into(), rssi_dbm: -70.0 });
/// ```
#[derive(Debug)]
pub struct CsvRecords<R> {
    reader: R,
    /// For each file column, its index in [`CSV_COLUMNS`].
    columns: Vec<usize>,
    file: String,
    line: usize,
    done: bool,
    skipping: bool,
    buffer: Vec<u8>,
}

/// What [`next_line`] found.
enum Next<'b> {
    End,
    Text(&'b [u8]),
    TooLong,
}

/// The next line that is not blank or a comment, at most [`MAX_LINE_BYTES`] long.
fn next_line<'b>(
    reader: &mut impl BufRead,
    buffer: &'b mut Vec<u8>,
    line: &mut usize,
    skipping: &mut bool,
) -> std::io::Result<Next<'b>> {
    loop {
        match read_line(reader, buffer, skipping)? {
            Line::End => return Ok(Next::End),
            Line::TooLong => {
                *line += 1;
                return Ok(Next::TooLong);
            }
            Line::Text => {
                *line += 1;
                let trimmed = buffer.trim_ascii();
                if !trimmed.is_empty() && !trimmed.starts_with(b"#") {
                    break;
                }
            }
        }
    }
    Ok(Next::Text(buffer.trim_ascii_end()))
}

/// The error of a line longer than [`MAX_LINE_BYTES`].
fn too_long() -> String {
    format!("line is longer than {MAX_LINE_BYTES} bytes; a record is one short line")
}

/// Splits one line into trimmed cells.
fn split(line: &[u8]) -> core::result::Result<csv::StringRecord, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .buffer_capacity(line.len().max(1))
        .from_reader(line);
    let mut cells = csv::StringRecord::new();
    match reader.read_record(&mut cells) {
        Ok(_) => Ok(cells),
        Err(error) => match error.kind() {
            csv::ErrorKind::Utf8 { .. } => Err("line is not valid UTF-8".into()),
            _ => Err(error.to_string()),
        },
    }
}

impl<R: BufRead> CsvRecords<R> {
    /// Reads the header row of `reader`; `file` names the source in errors.
    ///
    /// # Errors
    /// [`EngineError::Parse`] at the header's line for a missing header, an unknown or repeated
    /// column (named as the field), or a missing `t`, `tag` or `kind` column.
    pub fn new(mut reader: R, file: &str) -> Result<Self> {
        let error = |line: usize, field: &str, reason: String| EngineError::Parse {
            file: file.to_string(),
            line,
            field: field.to_string(),
            reason,
        };
        let (mut buffer, mut line, mut skipping) = (Vec::new(), 0, false);
        let header = match next_line(&mut reader, &mut buffer, &mut line, &mut skipping) {
            Ok(Next::Text(text)) => split(text).map_err(|reason| error(line, "-", reason))?,
            Ok(Next::TooLong) => return Err(error(line, "-", too_long())),
            Ok(Next::End) => {
                return Err(error(
                    line,
                    "-",
                    "no header row; expected column names such as t,tag,kind,…".into(),
                ))
            }
            Err(e) => return Err(error(line, "-", format!("read error: {e}"))),
        };
        let mut columns = Vec::with_capacity(header.len());
        for name in &header {
            let Some(index) = CSV_COLUMNS.iter().position(|c| *c == name) else {
                return Err(error(
                    line,
                    name,
                    format!("unknown column; known columns are {}", CSV_COLUMNS.join(",")),
                ));
            };
            if columns.contains(&index) {
                return Err(error(line, name, "column appears twice".into()));
            }
            columns.push(index);
        }
        for required in [T, TAG, KIND] {
            if !columns.contains(&required) {
                return Err(error(
                    line,
                    CSV_COLUMNS[required],
                    "column is missing; t, tag and kind are required".into(),
                ));
            }
        }
        Ok(Self {
            reader,
            columns,
            file: file.to_string(),
            line,
            done: false,
            skipping,
            buffer,
        })
    }
}

impl<R> CsvRecords<R> {
    /// The 1-based line of the row returned last (the header's line before the first row).
    #[must_use]
    pub fn line(&self) -> usize {
        self.line
    }
}

impl<R: BufRead> Iterator for CsvRecords<R> {
    type Item = Result<Record>;

    fn next(&mut self) -> Option<Result<Record>> {
        if self.done {
            return None;
        }
        let error = |line, reason| EngineError::Parse {
            file: self.file.clone(),
            line,
            field: "-".into(),
            reason,
        };
        let row = match next_line(&mut self.reader, &mut self.buffer, &mut self.line, &mut self.skipping) {
            Ok(Next::Text(text)) => split(text),
            Ok(Next::TooLong) => Err(too_long()),
            Ok(Next::End) => {
                self.done = true;
                return None;
            }
            Err(e) => {
                self.done = true;
                return Some(Err(EngineError::Read {
                    file: self.file.clone(),
                    line: self.line,
                    reason: e.to_string(),
                }));
            }
        };
        let row = match row {
            Ok(row) if row.len() == self.columns.len() => row,
            Ok(row) => {
                let reason = format!("row has {} cells but the header has {}", row.len(), self.columns.len());
                return Some(Err(error(self.line, reason)));
            }
            Err(reason) => return Some(Err(error(self.line, reason))),
        };
        let mut cells = Cells {
            values: [""; CSV_COLUMNS.len()],
            used: [false; CSV_COLUMNS.len()],
        };
        for (&column, value) in self.columns.iter().zip(row.iter()) {
            cells.values[column] = value;
        }
        Some(parse_row(&mut cells).map_err(|invalid| invalid.at(&self.file, self.line)))
    }
}

impl<'a> CsvRecords<&'a [u8]> {
    /// Reads from a string; `file` names the source in errors.
    ///
    /// # Errors
    /// As [`CsvRecords::new`].
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::CsvRecords;
    ///
    /// let records = CsvRecords::from_text("t,tag,kind,readings\n1,a,rssi_vector,R1=-70;R2=-81\n", "scan.csv").unwrap();
    /// assert_eq!(records.count(), 1);
    /// ```
    pub fn from_text(text: &'a str, file: &str) -> Result<Self> {
        Self::new(text.as_bytes(), file)
    }
}

/// One row's cells by [`CSV_COLUMNS`] index, and which ones the row's kind has read.
struct Cells<'r> {
    values: [&'r str; CSV_COLUMNS.len()],
    used: [bool; CSV_COLUMNS.len()],
}

impl Cells<'_> {
    fn text(&mut self, column: usize) -> Option<String> {
        self.used[column] = true;
        let value = self.values[column];
        (!value.is_empty()).then(|| value.to_string())
    }

    fn required_text(&mut self, column: usize, kind: &str) -> core::result::Result<String, Invalid> {
        self.text(column).ok_or_else(|| missing(column, kind))
    }

    fn number(&mut self, column: usize) -> core::result::Result<Option<f64>, Invalid> {
        self.used[column] = true;
        let value = self.values[column];
        if value.is_empty() {
            return Ok(None);
        }
        number(CSV_COLUMNS[column], value).map(Some)
    }

    fn required_number(&mut self, column: usize, kind: &str) -> core::result::Result<f64, Invalid> {
        self.number(column)?.ok_or_else(|| missing(column, kind))
    }

    /// `x, y` and an optional `z`.
    fn vector(&mut self, kind: &str) -> core::result::Result<Vec<f64>, Invalid> {
        let mut vector = vec![self.required_number(X, kind)?, self.required_number(Y, kind)?];
        vector.extend(self.number(Z)?);
        Ok(vector)
    }

    /// `x, y` and an optional `z`, or nothing when `x` and `y` are empty.
    fn optional_vector(&mut self, kind: &str) -> core::result::Result<Option<Vec<f64>>, Invalid> {
        if self.values[X].is_empty() && self.values[Y].is_empty() && self.values[Z].is_empty() {
            self.used[X] = true;
            self.used[Y] = true;
            self.used[Z] = true;
            return Ok(None);
        }
        self.vector(kind).map(Some)
    }

    /// A required `;`-separated list of numbers.
    fn list(&mut self, column: usize, kind: &str) -> core::result::Result<Vec<f64>, Invalid> {
        let text = self.required_text(column, kind)?;
        text.split(';').map(|n| number(CSV_COLUMNS[column], n.trim())).collect()
    }

    fn covariance(&mut self) -> core::result::Result<Option<Vec<f64>>, Invalid> {
        self.text(COVARIANCE)
            .map(|text| text.split(';').map(|n| number("covariance", n.trim())).collect())
            .transpose()
    }

    fn readings(&mut self, kind: &str) -> core::result::Result<Vec<AnchorReading>, Invalid> {
        let text = self.required_text(READINGS, kind)?;
        text.split(';')
            .map(|pair| {
                let (anchor, rssi) = pair.split_once('=').ok_or_else(|| {
                    Invalid::new(
                        "readings",
                        format!("`{pair}` is not `anchor=rssi_dbm`; separate readings with `;`"),
                    )
                })?;
                Ok(AnchorReading {
                    anchor: anchor.trim().to_string(),
                    rssi_dbm: number("readings", rssi.trim())?,
                })
            })
            .collect()
    }

    /// The first non-empty cell the kind did not read.
    fn unused(&self, kind: &str) -> core::result::Result<(), Invalid> {
        match (0..CSV_COLUMNS.len()).find(|&c| !self.used[c] && !self.values[c].is_empty()) {
            Some(column) => Err(Invalid::new(
                CSV_COLUMNS[column],
                format!("is not used by kind `{kind}`; leave it empty"),
            )),
            None => Ok(()),
        }
    }
}

fn missing(column: usize, kind: &str) -> Invalid {
    Invalid::new(CSV_COLUMNS[column], format!("is empty; kind `{kind}` requires it"))
}

fn number(column: &str, text: &str) -> core::result::Result<f64, Invalid> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(Invalid::new(column, format!("`{text}` is not a finite number"))),
        Err(_) => Err(Invalid::new(column, format!("`{text}` is not a number"))),
    }
}

fn parse_row(cells: &mut Cells<'_>) -> core::result::Result<Record, Invalid> {
    let time_s = cells.required_number(T, "any")?;
    let tag = cells.required_text(TAG, "any")?;
    let kind = cells.required_text(KIND, "any")?;
    let k = kind.as_str();
    let measurement = match k {
        "range" => Measurement::Range {
            anchor: cells.required_text(ANCHOR, k)?,
            range_m: cells.required_number(VALUE, k)?,
            std_m: cells.number(STD)?,
            anchor_position_m: cells.optional_vector(k)?,
        },
        "rssi" => Measurement::Rssi {
            anchor: cells.required_text(ANCHOR, k)?,
            rssi_dbm: cells.required_number(VALUE, k)?,
        },
        "tdoa" => Measurement::Tdoa {
            anchor: cells.required_text(ANCHOR, k)?,
            reference: cells.required_text(REFERENCE, k)?,
            range_difference_m: cells.required_number(VALUE, k)?,
            std_m: cells.number(STD)?,
        },
        "rssi_vector" => Measurement::RssiVector {
            readings: cells.readings(k)?,
        },
        "fix" => Measurement::Fix {
            position_m: cells.vector(k)?,
            covariance_m2: cells.covariance()?.ok_or_else(|| missing(COVARIANCE, k))?,
        },
        "accelerometer" => Measurement::Accelerometer {
            acceleration_mps2: cells.vector(k)?,
            std_mps2: cells.number(STD)?,
        },
        "odometry" => Measurement::Odometry {
            speed_mps: cells.required_number(VALUE, k)?,
            heading_rad: cells.number(HEADING)?,
            speed_std_mps: cells.number(STD)?,
            heading_std_rad: cells.number(HEADING_STD)?,
        },
        "velocity" => Measurement::Velocity {
            velocity_mps: cells.vector(k)?,
            covariance_m2ps2: cells.covariance()?,
        },
        "yaw_rate" => Measurement::YawRate {
            yaw_rate_radps: cells.required_number(VALUE, k)?,
            std_radps: cells.number(STD)?,
        },
        "odometry_increment" => Measurement::OdometryIncrement {
            distance_m: cells.required_number(VALUE, k)?,
            yaw_change_rad: cells.required_number(HEADING, k)?,
            interval_s: cells.required_number(INTERVAL, k)?,
            distance_std_m: cells.number(STD)?,
            yaw_change_std_rad: cells.number(HEADING_STD)?,
        },
        "imu" => Measurement::Imu {
            acceleration_mps2: cells.vector(k)?,
            angular_rate_radps: cells.list(RATE, k)?,
            std_mps2: cells.number(STD)?,
            std_radps: cells.number(RATE_STD)?,
        },
        "pseudorange" => Measurement::Pseudorange {
            satellite: cells.required_text(ANCHOR, k)?,
            satellite_position_m: [
                cells.required_number(X, k)?,
                cells.required_number(Y, k)?,
                cells.required_number(Z, k)?,
            ],
            pseudorange_m: cells.required_number(VALUE, k)?,
            std_m: cells.number(STD)?,
        },
        _ => {
            return Err(Invalid::new(
                "kind",
                format!(
                    "unknown kind `{kind}`; expected one of range, rssi, tdoa, rssi_vector, fix, accelerometer, \
                     odometry, velocity, yaw_rate, odometry_increment, imu, pseudorange"
                ),
            ));
        }
    };
    cells.unused(k)?;
    let record = Record {
        time_s,
        tag,
        measurement,
    };
    record
        .check()
        .map_err(|invalid| Invalid::new(csv_column(&invalid.field, k), invalid.reason))?;
    Ok(record)
}

/// The CSV column that holds a JSON key (`position_m[2]` → `z`, `readings[1].anchor` → `readings`).
fn csv_column(json_field: &str, kind: &str) -> &'static str {
    let (base, index) = match json_field.split_once('[') {
        Some((base, rest)) => (base, rest.split(']').next().and_then(|i| i.parse::<usize>().ok())),
        None => (json_field, None),
    };
    match base {
        "t" => "t",
        "tag" => "tag",
        "anchor" | "satellite" => "anchor",
        "reference" => "reference",
        "range_m" | "rssi_dbm" | "range_difference_m" | "speed_mps" | "yaw_rate_radps" | "distance_m"
        | "pseudorange_m" => "value",
        "std_m" | "std_mps2" | "speed_std_mps" | "distance_std_m" => "std",
        "heading_rad" | "yaw_change_rad" => "heading",
        "heading_std_rad" | "yaw_change_std_rad" => "heading_std",
        "interval_s" => "interval",
        "angular_rate_radps" => "rate",
        "std_radps" if kind == "imu" => "rate_std",
        "std_radps" => "std",
        "position_m" | "acceleration_mps2" | "velocity_mps" | "anchor_position_m" | "satellite_position_m" => {
            match index {
                Some(0) => "x",
                Some(1) => "y",
                Some(2) => "z",
                _ => "x,y,z",
            }
        }
        "covariance_m2" | "covariance_m2ps2" => "covariance",
        "readings" => "readings",
        _ => "-",
    }
}

/// Writes a record as one CSV row over [`CSV_COLUMNS`] (unused cells empty), for a
/// [`csv::Writer`] whose header is [`CSV_COLUMNS`]. A valid record round-trips through
/// [`CsvRecords`]; numbers are written in their shortest exact form.
///
/// # Examples
/// ```
/// use rtls_engine::record::{to_csv_row, Measurement, Record};
///
/// let record = Record {
///     time_s: 2.0,
///     tag: "cart-4".into(),
///     measurement: Measurement::Fix { position_m: vec![3.5, -1.0], covariance_m2: vec![0.04, 0.0, 0.0, 0.04] },
/// };
/// assert_eq!(to_csv_row(&record).join(","), "2,cart-4,fix,,,,,,,3.5,-1,,0.04;0;0;0.04,,,,");
/// ```
#[must_use]
pub fn to_csv_row(record: &Record) -> [String; CSV_COLUMNS.len()] {
    let mut row: [String; CSV_COLUMNS.len()] = Default::default();
    let number = |v: f64| v.to_string();
    let join = |values: &[f64]| values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(";");
    row[T] = number(record.time_s);
    row[TAG].clone_from(&record.tag);
    row[KIND] = record.measurement.kind().to_string();
    let vector = |row: &mut [String; CSV_COLUMNS.len()], values: &[f64]| {
        for (cell, value) in [X, Y, Z].into_iter().zip(values) {
            row[cell] = number(*value);
        }
    };
    match &record.measurement {
        Measurement::Range {
            anchor,
            range_m,
            std_m,
            anchor_position_m,
        } => {
            row[ANCHOR].clone_from(anchor);
            row[VALUE] = number(*range_m);
            row[STD] = std_m.map(number).unwrap_or_default();
            if let Some(position) = anchor_position_m {
                vector(&mut row, position);
            }
        }
        Measurement::Rssi { anchor, rssi_dbm } => {
            row[ANCHOR].clone_from(anchor);
            row[VALUE] = number(*rssi_dbm);
        }
        Measurement::Tdoa {
            anchor,
            reference,
            range_difference_m,
            std_m,
        } => {
            row[ANCHOR].clone_from(anchor);
            row[REFERENCE].clone_from(reference);
            row[VALUE] = number(*range_difference_m);
            row[STD] = std_m.map(number).unwrap_or_default();
        }
        Measurement::RssiVector { readings } => {
            row[READINGS] = readings
                .iter()
                .map(|r| format!("{}={}", r.anchor, r.rssi_dbm))
                .collect::<Vec<_>>()
                .join(";");
        }
        Measurement::Fix {
            position_m,
            covariance_m2,
        } => {
            vector(&mut row, position_m);
            row[COVARIANCE] = join(covariance_m2);
        }
        Measurement::Accelerometer {
            acceleration_mps2,
            std_mps2,
        } => {
            vector(&mut row, acceleration_mps2);
            row[STD] = std_mps2.map(number).unwrap_or_default();
        }
        Measurement::Odometry {
            speed_mps,
            heading_rad,
            speed_std_mps,
            heading_std_rad,
        } => {
            row[VALUE] = number(*speed_mps);
            row[HEADING] = heading_rad.map(number).unwrap_or_default();
            row[STD] = speed_std_mps.map(number).unwrap_or_default();
            row[HEADING_STD] = heading_std_rad.map(number).unwrap_or_default();
        }
        Measurement::Velocity {
            velocity_mps,
            covariance_m2ps2,
        } => {
            vector(&mut row, velocity_mps);
            row[COVARIANCE] = covariance_m2ps2.as_deref().map(join).unwrap_or_default();
        }
        Measurement::YawRate {
            yaw_rate_radps,
            std_radps,
        } => {
            row[VALUE] = number(*yaw_rate_radps);
            row[STD] = std_radps.map(number).unwrap_or_default();
        }
        Measurement::OdometryIncrement {
            distance_m,
            yaw_change_rad,
            interval_s,
            distance_std_m,
            yaw_change_std_rad,
        } => {
            row[VALUE] = number(*distance_m);
            row[HEADING] = number(*yaw_change_rad);
            row[INTERVAL] = number(*interval_s);
            row[STD] = distance_std_m.map(number).unwrap_or_default();
            row[HEADING_STD] = yaw_change_std_rad.map(number).unwrap_or_default();
        }
        Measurement::Imu {
            acceleration_mps2,
            angular_rate_radps,
            std_mps2,
            std_radps,
        } => {
            vector(&mut row, acceleration_mps2);
            row[RATE] = join(angular_rate_radps);
            row[STD] = std_mps2.map(number).unwrap_or_default();
            row[RATE_STD] = std_radps.map(number).unwrap_or_default();
        }
        Measurement::Pseudorange {
            satellite,
            satellite_position_m,
            pseudorange_m,
            std_m,
        } => {
            row[ANCHOR].clone_from(satellite);
            vector(&mut row, satellite_position_m);
            row[VALUE] = number(*pseudorange_m);
            row[STD] = std_m.map(number).unwrap_or_default();
        }
    }
    row
}

#[cfg(test)]
#[path = "csv_tests.rs"]
mod tests;
