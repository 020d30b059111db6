//! The radio map CSV text: parsing against a site, and writing.

use std::fmt::Write as _;

use crate::error::{EngineError, Result};
use crate::site::{Site, MAX_RADIO_MAP_ROWS};

/// The position columns every header starts with.
const POSITION_COLUMNS: [&str; 2] = ["x_m", "y_m"];

/// The optional floor column (third when present).
const FLOOR_COLUMN: &str = "floor";

/// File name used in the errors of [`radio_map_csv`] (nothing has been written yet).
const WRITING: &str = "radio map (being written)";

/// One reference point of a radio map, as [`radio_map_csv`] writes it.
///
/// # Units
/// `position_m` in m (site frame, `x, y`); `rssi_dbm` in dBm, one entry per reader column,
/// `None` where the reader was not heard.
///
/// # Examples
/// ```
/// use rtls_engine::radio_map::RadioMapRow;
/// let row = RadioMapRow { position_m: [0.25, 0.75], floor: None, rssi_dbm: vec![Some(-61.5), None] };
/// assert_eq!(row.rssi_dbm.len(), 2);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct RadioMapRow {
    /// Reference point `[x, y]`, m.
    pub position_m: [f64; 2],
    /// Floor label; give every row a floor or none.
    pub floor: Option<i32>,
    /// Mean RSSI per reader column, dBm; `None` = not heard.
    pub rssi_dbm: Vec<Option<f64>>,
}

/// Writes a radio map CSV (format in the [module docs](super)): the header
/// `x_m,y_m[,floor],<reader ids>`, then one row per reference point, empty cells for readers
/// not heard. The floor column is written when the rows have floors. Numbers are written in
/// the shortest form that reads back to the same `f64`, so a written map parses back exactly.
///
/// # Errors
/// [`EngineError::Parse`] (file `radio map (being written)`, line = the line the row would
/// have had, field = the column) for: no reader columns; no rows; a reader id that is empty, has outer
/// white space, contains `,`, `"` or a line break, is repeated, or is `x_m`, `y_m` or `floor`;
/// a row whose RSSI list does not have one entry per reader, with a non-finite number, without
/// any heard reader, or with a floor when another row has none (or the reverse).
///
/// # Examples
/// ```
/// use rtls_engine::radio_map::{radio_map_csv, RadioMapRow};
/// let readers = vec!["AP-1".to_string(), "AP-2".to_string()];
/// let rows = [RadioMapRow { position_m: [0.25, 0.75], floor: Some(1), rssi_dbm: vec![Some(-61.5), None] }];
/// assert_eq!(radio_map_csv(&readers, &rows)?, "x_m,y_m,floor,AP-1,AP-2\n0.25,0.75,1,-61.5,\n");
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
pub fn radio_map_csv(reader_ids: &[String], rows: &[RadioMapRow]) -> Result<String> {
    let error = |line: usize, field: &str, reason: String| EngineError::Parse {
        file: WRITING.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    if reader_ids.is_empty() {
        return Err(error(1, "-", "a radio map needs at least one reader column".into()));
    }
    for (k, id) in reader_ids.iter().enumerate() {
        let bad = id.is_empty()
            || id.trim() != id
            || id.contains([',', '"', '\n', '\r'])
            || POSITION_COLUMNS.contains(&id.as_str())
            || id == FLOOR_COLUMN;
        if bad {
            return Err(error(
                1,
                id,
                format!(
                    "reader column {} has the id `{id}`; ids must be non-empty, without outer white space, \
                     `,`, `\"` or line breaks, and not `x_m`, `y_m` or `floor`",
                    k + 1
                ),
            ));
        }
        if reader_ids[..k].contains(id) {
            return Err(error(1, id, format!("reader `{id}` is listed twice")));
        }
    }
    if rows.is_empty() {
        return Err(error(2, "-", "a radio map needs at least one reference point".into()));
    }
    let with_floor = rows.first().is_some_and(|row| row.floor.is_some());
    let mut text = String::new();
    text.push_str(&POSITION_COLUMNS.join(","));
    if with_floor {
        text.push(',');
        text.push_str(FLOOR_COLUMN);
    }
    for id in reader_ids {
        text.push(',');
        text.push_str(id);
    }
    text.push('\n');
    for (k, row) in rows.iter().enumerate() {
        let line = k + 2;
        if row.rssi_dbm.len() != reader_ids.len() {
            return Err(error(
                line,
                "rssi_dbm",
                format!(
                    "has {} entries; one per reader ({}) is needed",
                    row.rssi_dbm.len(),
                    reader_ids.len()
                ),
            ));
        }
        for (axis, &v) in POSITION_COLUMNS.iter().zip(&row.position_m) {
            if !v.is_finite() {
                return Err(error(line, axis, format!("{v} is not a finite number")));
            }
        }
        if row.floor.is_some() != with_floor {
            return Err(error(
                line,
                FLOOR_COLUMN,
                "some rows have a floor and others not; give every row a floor or none".into(),
            ));
        }
        if row.rssi_dbm.iter().all(Option::is_none) {
            return Err(error(
                line,
                "rssi_dbm",
                "no reader is heard; a reference point needs at least one reading".into(),
            ));
        }
        // writing to a String cannot fail
        let _ = write!(text, "{},{}", row.position_m[0], row.position_m[1]);
        if let Some(floor) = row.floor {
            let _ = write!(text, ",{floor}");
        }
        for (id, value) in reader_ids.iter().zip(&row.rssi_dbm) {
            text.push(',');
            if let Some(v) = value {
                if !v.is_finite() {
                    return Err(error(line, id, format!("{v} is not a finite rssi")));
                }
                let _ = write!(text, "{v}");
            }
        }
        text.push('\n');
    }
    Ok(text)
}

/// A parsed radio map, before indexing.
#[derive(Debug)]
pub(super) struct Parsed {
    pub reader_ids: Vec<String>,
    pub positions_m: Vec<[f64; 2]>,
    pub floors: Option<Vec<i32>>,
    /// Heard readers per reference point, `(column, dBm)`.
    pub readings_dbm: Vec<Vec<(usize, f64)>>,
    /// 1-based line of each reference point.
    pub lines: Vec<usize>,
}

/// Parses the text (see [`super::RadioMap::from_csv_str`] for the checks).
pub(super) fn parse(text: &str, file: &str, site: &Site) -> Result<Parsed> {
    let error = |line: usize, field: &str, reason: String| EngineError::Parse {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    // (1-based line, cells) of every line that is not blank or a comment
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, line)| (k + 1, line.trim()))
        .filter(|(_, line)| !line.is_empty() && !line.starts_with('#'))
        .map(|(k, line)| (k, line.split(',').map(str::trim).collect::<Vec<_>>()));
    let Some((header_line, header)) = lines.next() else {
        return Err(error(
            0,
            "-",
            "no header; expected `x_m,y_m[,floor],<reader id>,…`".into(),
        ));
    };
    for (k, expected) in POSITION_COLUMNS.iter().enumerate() {
        let found = header.get(k).copied().unwrap_or("");
        if found != *expected {
            return Err(error(
                header_line,
                found,
                format!(
                    "column {} is `{found}`, expected `{expected}` (the header starts `x_m,y_m`)",
                    k + 1
                ),
            ));
        }
    }
    let with_floor = header.get(2) == Some(&FLOOR_COLUMN);
    let first_reader = if with_floor { 3 } else { 2 };
    let reader_ids =
        reader_columns(&header, first_reader, site).map_err(|(field, reason)| error(header_line, &field, reason))?;

    let mut parsed = Parsed {
        reader_ids,
        positions_m: Vec::new(),
        floors: with_floor.then(Vec::new),
        readings_dbm: Vec::new(),
        lines: Vec::new(),
    };
    for (line, cells) in lines {
        if parsed.positions_m.len() == MAX_RADIO_MAP_ROWS {
            return Err(error(
                line,
                "-",
                format!("more than {MAX_RADIO_MAP_ROWS} reference points; a radio map may have at most that many rows"),
            ));
        }
        if cells.len() != header.len() {
            return Err(error(
                line,
                "-",
                format!("{} cells, but the header has {} columns", cells.len(), header.len()),
            ));
        }
        let number = |k: usize| -> Result<f64> {
            match cells[k].parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(error(line, header[k], format!("`{}` is not a finite number", cells[k]))),
            }
        };
        parsed.positions_m.push([number(0)?, number(1)?]);
        if let Some(floors) = parsed.floors.as_mut() {
            let floor = cells[2].parse::<i32>().map_err(|_| {
                error(
                    line,
                    FLOOR_COLUMN,
                    format!("`{}` is not an integer floor label", cells[2]),
                )
            })?;
            floors.push(floor);
        }
        let mut heard = Vec::new();
        for (k, cell) in cells.iter().enumerate().skip(first_reader) {
            if !cell.is_empty() {
                heard.push((k - first_reader, number(k)?));
            }
        }
        if heard.is_empty() {
            return Err(error(
                line,
                "-",
                "no reader is heard at this reference point (every rssi cell is empty); \
                 a reference point needs at least one reading"
                    .into(),
            ));
        }
        parsed.readings_dbm.push(heard);
        parsed.lines.push(line);
    }
    if parsed.positions_m.is_empty() {
        return Err(error(header_line, "-", "no reference points after the header".into()));
    }
    Ok(parsed)
}

/// The reader ids of header columns `first..`, checked against the site; an error is the
/// field to name (the offending header cell, `-` when it is empty, the missing reader id when
/// the header is short) and the reason.
fn reader_columns(header: &[&str], first: usize, site: &Site) -> core::result::Result<Vec<String>, (String, String)> {
    let ids: Vec<String> = header[first.min(header.len())..]
        .iter()
        .map(|s| (*s).to_string())
        .collect();
    if ids.is_empty() {
        return Err((
            "-".to_string(),
            format!("no reader columns; expected reader ids after column {first}"),
        ));
    }
    let expected = site
        .fingerprints
        .as_ref()
        .map(|db| db.readers.as_slice())
        .unwrap_or(&[]);
    for (j, id) in ids.iter().enumerate() {
        let place = format!("column {}", first + j + 1);
        let column = if id.is_empty() { "-".to_string() } else { id.clone() };
        if id.is_empty() {
            return Err((column, format!("{place} is empty; reader columns need a reader id")));
        }
        if POSITION_COLUMNS.contains(&id.as_str()) || id == FLOOR_COLUMN {
            return Err((
                column,
                format!("{place}: `{id}` is reserved for the position and floor columns"),
            ));
        }
        if ids[..j].contains(id) {
            return Err((column, format!("{place}: reader `{id}` is listed twice")));
        }
        if let Some(wanted) = expected.get(j) {
            if wanted != id {
                return Err((
                    column,
                    format!(
                        "{place} is reader `{id}` but the site's [fingerprints].readers[{j}] is `{wanted}`; \
                         the reader columns must list [fingerprints].readers in order"
                    ),
                ));
            }
        } else if !expected.is_empty() {
            return Err((
                column,
                format!(
                    "{place}: reader `{id}` is beyond the {} readers of the site's [fingerprints].readers",
                    expected.len()
                ),
            ));
        }
        if site.reader(id).is_none() {
            return Err((column, format!("{place}: `{id}` is not a reader of the site")));
        }
    }
    if let Some(missing) = expected.get(ids.len()) {
        return Err((
            missing.clone(),
            format!(
                "the header ends after {} reader columns, but the site's [fingerprints].readers[{}] is `{missing}`",
                ids.len(),
                ids.len()
            ),
        ));
    }
    Ok(ids)
}
