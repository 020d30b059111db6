//! Reading the tetam dataset: the sensors of `cnf/tetam.dev` and the merged track files
//! `trk/<name>_all_sensors.mbd`.

use std::path::{Path, PathBuf};

use crate::{DataError, Result};

/// Valid RSSI range of a Bluetooth controller report, dBm (Bluetooth Core Specification 5.x,
/// Vol. 4 Part E §7.7.65.2, LE Advertising Report: "Range: −127 to +20"). A value outside it is
/// not a measurement (the dataset has +42 and +29 dBm in `straight_05`); such rows are skipped
/// and counted.
pub(super) const RSSI_RANGE_DBM: (f64, f64) = (-127.0, 20.0);

/// One fixed sensor (receiver).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sensor {
    /// MAC address as written in the track files.
    pub mac: String,
    /// Alias (`sensor10`, …): the reader id.
    pub alias: String,
    /// Position `[x, y, z]`, m.
    pub position_m: [f64; 3],
}

/// One RSSI row of a track with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sample {
    /// Unix time, s.
    pub time_s: f64,
    /// Index into the sensor list.
    pub sensor: usize,
    /// Beacon MAC (the tag id).
    pub beacon: String,
    /// RSSI, dBm.
    pub rssi_dbm: f64,
    /// True beacon position `[x, y, z]`, m.
    pub position_m: [f64; 3],
}

/// One track file, parsed.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Track {
    /// Track name (`straight_01`, …): the run name.
    pub name: String,
    /// The file read.
    pub file: PathBuf,
    /// Rows with a valid RSSI, sorted by time (stable: ties keep file order).
    pub samples: Vec<Sample>,
    /// Data rows in the file.
    pub rows: usize,
    /// `(line, rssi)` of rows skipped for an RSSI outside [`RSSI_RANGE_DBM`].
    pub implausible_rssi: Vec<(u64, f64)>,
    /// Rows whose time stamp is earlier than a previous row's (put in order by the sort).
    pub out_of_order: usize,
}

/// Track names of the dataset, in output order (the `trk/*_all_sensors.mbd` files, sorted).
///
/// # Errors
/// [`DataError::Io`] if `trk/` cannot be listed; [`DataError::Content`] if it holds no track.
pub(super) fn track_names(dataset_dir: &Path) -> Result<Vec<String>> {
    let dir = dataset_dir.join("trk");
    let entries = std::fs::read_dir(&dir).map_err(|source| DataError::Io {
        file: dir.clone(),
        source,
    })?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|source| DataError::Io {
            file: dir.clone(),
            source,
        })?;
        if let Some(name) = entry
            .file_name()
            .to_str()
            .and_then(|f| f.strip_suffix("_all_sensors.mbd"))
        {
            names.push(name.to_string());
        }
    }
    names.sort();
    if names.is_empty() {
        return Err(DataError::Content {
            file: dir,
            reason: "no `<name>_all_sensors.mbd` track files".into(),
        });
    }
    Ok(names)
}

/// Reads the sensors (the `Dongles:` line) of `cnf/tetam.dev`, sorted by alias.
///
/// The line is a Python dict `{"<mac>": [[x, y, z], <colour>, "<alias>"], …}`.
///
/// # Errors
/// [`DataError::Io`]; [`DataError::Parse`] naming the line and the entry (`Dongles.<mac>`) of
/// a malformed entry, a missing `Dongles:` line, repeated MACs or aliases.
pub(super) fn read_sensors(path: &Path) -> Result<Vec<Sensor>> {
    let text = crate::import::util::read_text(path)?;
    parse_sensors(&text, path)
}

/// [`read_sensors`] on text.
pub(super) fn parse_sensors(text: &str, path: &Path) -> Result<Vec<Sensor>> {
    let error = |line: u64, field: &str, reason: String| DataError::Parse {
        file: path.to_path_buf(),
        line,
        field: field.to_string(),
        reason,
    };
    let Some((index, dict)) = text
        .lines()
        .enumerate()
        .find_map(|(k, line)| line.trim().strip_prefix("Dongles:").map(|rest| (k, rest)))
    else {
        return Err(error(0, "Dongles", "no `Dongles:` line (the sensor list)".into()));
    };
    let line = index as u64 + 1;
    let value = python_literal(dict).map_err(|reason| error(line, "Dongles", reason))?;
    let Value::Dict(entries) = value else {
        return Err(error(line, "Dongles", "is not a dict {\"<mac>\": [...], …}".into()));
    };
    let mut sensors = Vec::with_capacity(entries.len());
    for (mac, entry) in entries {
        let field = format!("Dongles.{mac}");
        let malformed = || error(line, &field, "expected [[x, y, z], colour, \"alias\"]".into());
        let Value::List(parts) = entry else {
            return Err(malformed());
        };
        let (Some(Value::List(xyz)), Some(Value::Str(alias))) = (parts.first(), parts.get(2)) else {
            return Err(malformed());
        };
        let coordinates: Vec<f64> = xyz
            .iter()
            .filter_map(|v| match v {
                Value::Num(x) if x.is_finite() => Some(*x),
                _ => None,
            })
            .collect();
        let [x, y, z] = coordinates[..] else {
            return Err(error(
                line,
                &field,
                "the position is not 3 finite numbers [x, y, z]".into(),
            ));
        };
        if sensors.iter().any(|s: &Sensor| s.mac == mac || s.alias == *alias) {
            return Err(error(
                line,
                &field,
                format!("mac `{mac}` or alias `{alias}` is listed twice"),
            ));
        }
        sensors.push(Sensor {
            mac,
            alias: alias.clone(),
            position_m: [x, y, z],
        });
    }
    if sensors.is_empty() {
        return Err(error(line, "Dongles", "no sensors listed".into()));
    }
    sensors.sort_by(|a, b| a.alias.cmp(&b.alias));
    Ok(sensors)
}

/// Reads `trk/<name>_all_sensors.mbd`.
///
/// Line format (no header): `timestamp,sensor MAC,beacon MAC,RSSI,x,y,z,` then the 3 × 3
/// orientation matrix (9 numbers, not used). Rows with an RSSI outside [`RSSI_RANGE_DBM`] are
/// skipped and listed; the rest are sorted by time.
///
/// # Errors
/// [`DataError::Io`]; [`DataError::Parse`] naming the 1-based line and the field (`timestamp`,
/// `sensor_mac`, `beacon_mac`, `rssi_dbm`, `x`, `y`, `z`, or `-` for the field count) of a row
/// that does not have 16 fields, a non-finite number, an unknown sensor or an empty beacon MAC;
/// [`DataError::Content`] for a file without valid rows.
pub(super) fn read_track(dataset_dir: &Path, name: &str, sensors: &[Sensor]) -> Result<Track> {
    let file = dataset_dir.join("trk").join(format!("{name}_all_sensors.mbd"));
    let text = crate::import::util::read_text(&file)?;
    parse_track(&text, name, &file, sensors)
}

/// [`read_track`] on text.
pub(super) fn parse_track(text: &str, name: &str, file: &Path, sensors: &[Sensor]) -> Result<Track> {
    const FIELDS: usize = 16;
    let mut track = Track {
        name: name.to_string(),
        file: file.to_path_buf(),
        samples: Vec::new(),
        rows: 0,
        implausible_rssi: Vec::new(),
        out_of_order: 0,
    };
    let mut latest_s = f64::NEG_INFINITY;
    for (k, line) in text.lines().enumerate() {
        let line_no = k as u64 + 1;
        if line.trim().is_empty() {
            continue;
        }
        track.rows += 1;
        let error = |field: &str, reason: String| DataError::Parse {
            file: file.to_path_buf(),
            line: line_no,
            field: field.to_string(),
            reason,
        };
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != FIELDS {
            return Err(error("-", format!("{} fields, expected {FIELDS}", cells.len())));
        }
        let number = |k: usize, field: &str| -> Result<f64> {
            match cells[k].parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(error(field, format!("`{}` is not a finite number", cells[k]))),
            }
        };
        let time_s = number(0, "timestamp")?;
        let sensor = sensors
            .iter()
            .position(|s| s.mac == cells[1])
            .ok_or_else(|| error("sensor_mac", format!("`{}` is not a sensor of cnf/tetam.dev", cells[1])))?;
        if cells[2].is_empty() {
            return Err(error("beacon_mac", "is empty".into()));
        }
        let rssi_dbm = number(3, "rssi_dbm")?;
        let position_m = [number(4, "x")?, number(5, "y")?, number(6, "z")?];
        if time_s < latest_s {
            track.out_of_order += 1;
        }
        latest_s = latest_s.max(time_s);
        if !(RSSI_RANGE_DBM.0..=RSSI_RANGE_DBM.1).contains(&rssi_dbm) {
            track.implausible_rssi.push((line_no, rssi_dbm));
            continue;
        }
        track.samples.push(Sample {
            time_s,
            sensor,
            beacon: cells[2].to_string(),
            rssi_dbm,
            position_m,
        });
    }
    if track.samples.is_empty() {
        return Err(DataError::Content {
            file: file.to_path_buf(),
            reason: "no valid rssi rows".into(),
        });
    }
    // stable: equal time stamps keep their file order
    track.samples.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    Ok(track)
}

/// A Python literal of the subset `tetam.dev` uses.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Str(String),
    Num(f64),
    List(Vec<Value>),
    Dict(Vec<(String, Value)>),
}

/// Parses one Python literal (dicts with string keys, lists, strings without escapes,
/// numbers); the error says what was expected where (character offset).
fn python_literal(text: &str) -> core::result::Result<Value, String> {
    let mut parser = LiteralParser {
        bytes: text.as_bytes(),
        at: 0,
    };
    let value = parser.value()?;
    parser.skip_blank();
    if parser.at != parser.bytes.len() {
        return Err(format!("unexpected text after the literal at character {}", parser.at));
    }
    Ok(value)
}

struct LiteralParser<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl LiteralParser<'_> {
    fn skip_blank(&mut self) {
        while self.bytes.get(self.at).is_some_and(u8::is_ascii_whitespace) {
            self.at += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.skip_blank();
        self.bytes.get(self.at).copied()
    }

    fn expect(&mut self, c: u8) -> core::result::Result<(), String> {
        if self.peek() == Some(c) {
            self.at += 1;
            Ok(())
        } else {
            Err(format!("expected `{}` at character {}", c as char, self.at))
        }
    }

    fn value(&mut self) -> core::result::Result<Value, String> {
        match self.peek() {
            Some(b'{') => self.dict(),
            Some(b'[') => self.list(),
            Some(b'"') => self.string().map(Value::Str),
            Some(_) => self.number(),
            None => Err("unexpected end of the literal".into()),
        }
    }

    /// Comma-separated items up to `close`, a trailing comma allowed.
    fn items<T>(
        &mut self,
        close: u8,
        mut item: impl FnMut(&mut Self) -> core::result::Result<T, String>,
    ) -> core::result::Result<Vec<T>, String> {
        let mut items = Vec::new();
        loop {
            if self.peek() == Some(close) {
                self.at += 1;
                return Ok(items);
            }
            items.push(item(self)?);
            if self.peek() == Some(b',') {
                self.at += 1;
            } else {
                self.expect(close)?;
                return Ok(items);
            }
        }
    }

    fn dict(&mut self) -> core::result::Result<Value, String> {
        self.expect(b'{')?;
        self.items(b'}', |p| {
            let key = p.string()?;
            p.expect(b':')?;
            Ok((key, p.value()?))
        })
        .map(Value::Dict)
    }

    fn list(&mut self) -> core::result::Result<Value, String> {
        self.expect(b'[')?;
        self.items(b']', Self::value).map(Value::List)
    }

    fn string(&mut self) -> core::result::Result<String, String> {
        self.expect(b'"')?;
        let start = self.at;
        while let Some(&c) = self.bytes.get(self.at) {
            if c == b'"' {
                let text = String::from_utf8_lossy(&self.bytes[start..self.at]).into_owned();
                self.at += 1;
                return Ok(text);
            }
            self.at += 1;
        }
        Err(format!("unterminated string starting at character {start}"))
    }

    fn number(&mut self) -> core::result::Result<Value, String> {
        let start = self.at;
        while self
            .bytes
            .get(self.at)
            .is_some_and(|c| c.is_ascii_digit() || matches!(c, b'-' | b'+' | b'.' | b'e' | b'E'))
        {
            self.at += 1;
        }
        let text = String::from_utf8_lossy(&self.bytes[start..self.at]);
        text.parse::<f64>()
            .map(Value::Num)
            .map_err(|_| format!("expected a value at character {start}, found `{text}`"))
    }
}
