//! UJIIndoorLoc: the Wi-Fi fingerprint database of Universitat Jaume I (3 buildings, 4–5
//! floors, 520 access points; 19 937 training and 1 111 validation fingerprints).
//!
//! Format (CSV with a header): `WAP001 … WAP520` RSSI (dBm, integers in [−104, 0]; the value
//! 100 means "not detected"), `LONGITUDE`, `LATITUDE` (m, EPSG:3857 Web Mercator), `FLOOR`,
//! `BUILDINGID`, `SPACEID`, `RELATIVEPOSITION`, `USERID`, `PHONEID`, `TIMESTAMP` (Unix s).
//! The validation set was recorded four months after the training set, by other users and
//! phones.
//!
//! The reader turns the dataset's `100` into an absent reading at the file boundary; nothing
//! downstream sees the sentinel.
//!
//! **Units of the error.** EPSG:3857 "metres" are stretched by `1/cos(latitude)`; at the
//! campus (39.99° N) one of them is 0.766 ground metres. Errors are reported in the dataset's
//! coordinates, as every published UJIIndoorLoc result is, so they compare directly with the
//! literature; multiply by 0.766 for ground distance.
//!
//! # References
//! J. Torres-Sospedra, R. Montoliu, A. Martínez-Usó, J. P. Avariento, T. J. Arnau, M.
//! Benedito-Bordonau, J. Huerta, "UJIIndoorLoc: A new multi-building and multi-floor database
//! for WLAN fingerprint-based indoor localization problems", IPIN 2014 (dataset; CC BY 4.0,
//! UCI Machine Learning Repository).

mod evaluation;

pub use evaluation::{evaluate, locate_all, neighbour_agreement, score, Evaluation, Outcomes};

use std::path::Path;

use rtls_positioning::fingerprint::Survey;

use crate::{DataError, Result};

/// The training file, relative to [`crate::data_dir`].
pub const TRAINING: &str = "ujiindoorloc/UJIndoorLoc/trainingData.csv";

/// The validation file, relative to [`crate::data_dir`].
pub const VALIDATION: &str = "ujiindoorloc/UJIndoorLoc/validationData.csv";

/// Number of access points (RSSI columns).
pub const ACCESS_POINTS: usize = 520;

/// The dataset's "not detected" value (converted to an absent reading by [`load`]).
const NOT_DETECTED: f64 = 100.0;

/// Weakest and strongest valid reading (dBm).
const RSSI_RANGE_DBM: (f64, f64) = (-104.0, 0.0);

/// The columns after the RSSI block, in file order.
const LABEL_COLUMNS: [&str; 9] = [
    "LONGITUDE",
    "LATITUDE",
    "FLOOR",
    "BUILDINGID",
    "SPACEID",
    "RELATIVEPOSITION",
    "USERID",
    "PHONEID",
    "TIMESTAMP",
];

/// One UJIIndoorLoc record: the heard access points and the labels.
#[derive(Debug, Clone, PartialEq)]
pub struct Fingerprint {
    /// Heard access points `(index 0..520, RSSI dBm)`, increasing index.
    pub readings_dbm: Vec<(usize, f64)>,
    /// `(LONGITUDE, LATITUDE)` in EPSG:3857 metres.
    pub position_m: [f64; 2],
    /// `FLOOR` (0–4).
    pub floor: i32,
    /// `BUILDINGID` (0–2).
    pub building: u32,
    /// `SPACEID`.
    pub space_id: u32,
    /// `RELATIVEPOSITION` (1 inside, 2 in front of the door).
    pub relative_position: u32,
    /// `USERID` (0 = unknown, in the validation set).
    pub user_id: u32,
    /// `PHONEID`.
    pub phone_id: u32,
    /// `TIMESTAMP` (Unix s).
    pub timestamp_s: i64,
}

impl Fingerprint {
    /// The query vector of this record: one entry per access point, `None` where not heard.
    ///
    /// # Example
    /// ```
    /// use rtls_data::ujiindoorloc::Fingerprint;
    /// let f = Fingerprint {
    ///     readings_dbm: vec![(2, -70.0)],
    ///     position_m: [0.0, 0.0], floor: 0, building: 0, space_id: 0,
    ///     relative_position: 1, user_id: 0, phone_id: 0, timestamp_s: 0,
    /// };
    /// let q = f.query();
    /// assert_eq!((q.len(), q[2], q[0]), (520, Some(-70.0), None));
    /// ```
    #[must_use]
    pub fn query(&self) -> Vec<Option<f64>> {
        let mut query = vec![None; ACCESS_POINTS];
        for &(ap, rssi_dbm) in &self.readings_dbm {
            query[ap] = Some(rssi_dbm);
        }
        query
    }
}

/// Reads a UJIIndoorLoc CSV file (training or validation).
///
/// # Errors
/// [`DataError::Io`] if the file cannot be read; [`DataError::Parse`] naming the line and
/// column of the first malformed header name, missing field, non-numeric value, RSSI outside
/// [−104, 0] dBm (other than 100), or label out of range; [`DataError::Content`] for a file
/// without records.
///
/// # Example
/// ```no_run
/// use rtls_data::{data_dir, ujiindoorloc};
/// let validation = ujiindoorloc::load(&data_dir().join(ujiindoorloc::VALIDATION))?;
/// assert_eq!(validation.len(), 1111);
/// # Ok::<(), rtls_data::DataError>(())
/// ```
pub fn load(path: &Path) -> Result<Vec<Fingerprint>> {
    let file = std::fs::File::open(path).map_err(|source| DataError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    read(std::io::BufReader::new(file), path)
}

/// Parses UJIIndoorLoc CSV from any reader; `path` names the source in errors.
///
/// # Errors
/// As [`load`].
///
/// # Example
/// ```
/// use std::path::Path;
/// let mut header: Vec<String> = (1..=520).map(|k| format!("WAP{k:03}")).collect();
/// header.extend(["LONGITUDE", "LATITUDE", "FLOOR", "BUILDINGID", "SPACEID",
///     "RELATIVEPOSITION", "USERID", "PHONEID", "TIMESTAMP"].map(String::from));
/// let mut row = vec!["100".to_string(); 520];
/// row[4] = "-101".into(); // WAP005 heard at −101 dBm; the other 519 not detected
/// row.extend(["-7500.0", "4864900.0", "1", "0", "12", "2", "3", "13", "1371713733"].map(String::from));
/// let csv = format!("{}\n{}\n", header.join(","), row.join(","));
/// let records = rtls_data::ujiindoorloc::read(csv.as_bytes(), Path::new("x.csv"))?;
/// assert_eq!(records[0].readings_dbm, vec![(4, -101.0)]);
/// assert_eq!((records[0].floor, records[0].building), (1, 0));
/// # Ok::<(), rtls_data::DataError>(())
/// ```
pub fn read(reader: impl std::io::Read, path: &Path) -> Result<Vec<Fingerprint>> {
    let mut csv = csv::ReaderBuilder::new().has_headers(true).from_reader(reader);
    let header = csv.headers().map_err(|e| csv_error(path, &e))?.clone();
    check_header(&header, path)?;
    let mut records = Vec::new();
    let mut record = csv::StringRecord::new();
    loop {
        match csv.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(path, &e)),
        }
        let line = record.position().map_or(0, csv::Position::line);
        records.push(parse_record(&record, &header, path, line)?);
    }
    if records.is_empty() {
        return Err(DataError::Content {
            file: path.to_path_buf(),
            reason: "no records after the header".into(),
        });
    }
    Ok(records)
}

/// The training records as a fingerprint survey: every record is a reference point (with its
/// floor and building), access-point positions unknown.
///
/// Records are not averaged per location: on UJIIndoorLoc the individual records, taken by
/// several users and phones, match the validation set better than their means (see
/// `docs/FINGERPRINTING.md`).
///
/// # Example
/// ```
/// use rtls_data::ujiindoorloc::{survey, Fingerprint};
/// let f = Fingerprint {
///     readings_dbm: vec![(2, -70.0)], position_m: [1.0, 2.0], floor: 3, building: 1,
///     space_id: 0, relative_position: 1, user_id: 0, phone_id: 0, timestamp_s: 0,
/// };
/// let s = survey(&[f]);
/// assert_eq!((s.anchor_count, s.floors, s.buildings), (520, Some(vec![3]), Some(vec![1])));
/// ```
#[must_use]
pub fn survey(training: &[Fingerprint]) -> Survey {
    Survey {
        reference_points_m: training.iter().map(|f| f.position_m).collect(),
        floors: Some(training.iter().map(|f| f.floor).collect()),
        buildings: Some(training.iter().map(|f| f.building).collect()),
        anchor_count: ACCESS_POINTS,
        anchors_m: None,
        readings_dbm: training.iter().map(|f| f.readings_dbm.clone()).collect(),
    }
}

fn check_header(header: &csv::StringRecord, path: &Path) -> Result<()> {
    let expected = (1..=ACCESS_POINTS)
        .map(|k| format!("WAP{k:03}"))
        .chain(LABEL_COLUMNS.iter().map(|s| (*s).to_string()));
    let mut found = 0;
    for (column, expected) in expected.enumerate() {
        let name = header.get(column).unwrap_or("");
        if name.trim() != expected {
            return Err(DataError::Parse {
                file: path.to_path_buf(),
                line: 1,
                field: format!("column {}", column + 1),
                reason: format!("header is `{name}`, expected `{expected}`"),
            });
        }
        found += 1;
    }
    if header.len() != found {
        return Err(DataError::Parse {
            file: path.to_path_buf(),
            line: 1,
            field: format!("column {}", found + 1),
            reason: format!("{} columns, expected {found}", header.len()),
        });
    }
    Ok(())
}

fn parse_record(record: &csv::StringRecord, header: &csv::StringRecord, path: &Path, line: u64) -> Result<Fingerprint> {
    let error = |column: usize, reason: String| DataError::Parse {
        file: path.to_path_buf(),
        line,
        field: header.get(column).unwrap_or("?").to_string(),
        reason,
    };
    if record.len() != header.len() {
        return Err(error(
            record.len().min(header.len() - 1),
            format!("{} fields, expected {}", record.len(), header.len()),
        ));
    }
    let number = |column: usize| -> Result<f64> {
        let text = record[column].trim();
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(error(column, format!("`{text}` is not a finite number"))),
        }
    };
    let label = |column: usize, max: f64| -> Result<f64> {
        let v = number(column)?;
        if v.fract() == 0.0 && (0.0..=max).contains(&v) {
            Ok(v)
        } else {
            Err(error(column, format!("{v} is not an integer in [0, {max}]")))
        }
    };
    let mut readings_dbm = Vec::new();
    for ap in 0..ACCESS_POINTS {
        let rssi_dbm = number(ap)?;
        if rssi_dbm == NOT_DETECTED {
            continue;
        }
        if !(RSSI_RANGE_DBM.0..=RSSI_RANGE_DBM.1).contains(&rssi_dbm) {
            return Err(error(
                ap,
                format!("rssi {rssi_dbm} dBm is outside [-104, 0] and is not 100 (not detected)"),
            ));
        }
        readings_dbm.push((ap, rssi_dbm));
    }
    let c = ACCESS_POINTS;
    Ok(Fingerprint {
        readings_dbm,
        position_m: [number(c)?, number(c + 1)?],
        floor: label(c + 2, 9.0)? as i32,
        building: label(c + 3, 9.0)? as u32,
        space_id: label(c + 4, f64::from(u32::MAX))? as u32,
        relative_position: label(c + 5, 2.0)? as u32,
        user_id: label(c + 6, f64::from(u32::MAX))? as u32,
        phone_id: label(c + 7, f64::from(u32::MAX))? as u32,
        timestamp_s: label(c + 8, 1e12)? as i64,
    })
}

fn csv_error(path: &Path, error: &csv::Error) -> DataError {
    let line = error.position().map_or(0, csv::Position::line);
    DataError::Parse {
        file: path.to_path_buf(),
        line,
        field: "record".into(),
        reason: error.to_string(),
    }
}

#[cfg(test)]
mod tests;
