//! The survey map as CSV: writing the cell and reader tables, and reading them back.

use std::collections::HashMap;
use std::io::Write;

use super::map::{CellEntry, Degradation, ReaderEntry, Summary, SurveyMap};
use super::{ResidualKind, SurveySettings};
use crate::error::{EngineError, Result};

/// The columns of the cell table, in order: the cell's bounds (m), the reader, the kind
/// (`range` / `rssi`), the residual count `n`, the mean distance to the reader (m), the bias
/// and the standard deviation (in the kind's unit: m or dB; `std` empty when `n < 2`), the
/// robust z scores of the bias and the spread (empty when not scored), `flagged` (`true` /
/// `false`) and the `reason` ([`Degradation::name`]: `bias`, `spread`, `bias+spread`, or
/// empty).
pub const CELL_COLUMNS: [&str; 14] = [
    "x_min_m",
    "x_max_m",
    "y_min_m",
    "y_max_m",
    "reader",
    "kind",
    "n",
    "distance_m",
    "bias",
    "std",
    "z",
    "spread_z",
    "flagged",
    "reason",
];

/// The columns of the reader table, in order: as [`CELL_COLUMNS`] without the bounds, with
/// `flagged_cells` (how many of the reader's cells are flagged) before `flagged`; the reason
/// may include `cells`.
pub const READER_COLUMNS: [&str; 11] = [
    "reader",
    "kind",
    "n",
    "distance_m",
    "bias",
    "std",
    "z",
    "spread_z",
    "flagged_cells",
    "flagged",
    "reason",
];

/// An optional number as a cell: empty for `None`, else the shortest form that reads back to
/// the same `f64`.
fn optional(value: Option<f64>) -> String {
    value.map_or_else(String::new, |v| v.to_string())
}

/// The statistics columns (`n` to `spread_z`) of an entry.
fn statistics_cells(summary: &Summary) -> [String; 6] {
    [
        summary.count.to_string(),
        summary.distance_m.to_string(),
        summary.bias.to_string(),
        optional(summary.std),
        optional(summary.z),
        optional(summary.spread_z),
    ]
}

/// The `flagged` and `reason` columns.
fn flag_cells(degraded: Degradation) -> [String; 2] {
    [degraded.any().to_string(), degraded.name()]
}

impl SurveyMap {
    /// Writes the cell table ([`CELL_COLUMNS`]): a header, then one row per (cell, reader,
    /// kind) entry, RFC 4180 quoting where an id needs it. Numbers are written in the shortest
    /// form that reads back to the same `f64`, so [`SurveyMap::from_csv`] restores the map
    /// exactly.
    ///
    /// # Errors
    /// Those of `writer`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::survey::{Residual, ResidualKind, SurveyMap, SurveySettings};
    /// let residual = |value| Residual { time_s: 0.0, tag: "w".into(), reader: "R1".into(),
    ///                                   kind: ResidualKind::Rssi, position_m: [12.0, 3.0, 0.0],
    ///                                   distance_m: 12.5, value };
    /// let map = SurveyMap::build(&[residual(-5.0), residual(-7.0)], &SurveySettings::default())?;
    /// let mut csv = Vec::new();
    /// map.write_cells_csv(&mut csv).unwrap();
    /// let text = String::from_utf8(csv).unwrap();
    /// assert_eq!(text.lines().nth(1), Some("10,20,0,10,R1,rssi,2,12.5,-6,1.4142135623730951,,,false,"));
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn write_cells_csv(&self, writer: impl Write) -> std::io::Result<()> {
        let mut csv = csv::Writer::from_writer(writer);
        csv.write_record(CELL_COLUMNS)?;
        for entry in self.cells() {
            let bounds = self.settings().cell_bounds_m(entry.cell).map(|v| v.to_string());
            let [x_min, x_max, y_min, y_max] = bounds;
            let mut row = vec![
                x_min,
                x_max,
                y_min,
                y_max,
                entry.reader.clone(),
                entry.kind.name().to_string(),
            ];
            row.extend(statistics_cells(&entry.summary));
            row.extend(flag_cells(entry.summary.degraded));
            csv.write_record(&row)?;
        }
        csv.flush()
    }

    /// Writes the reader table ([`READER_COLUMNS`]) as [`SurveyMap::write_cells_csv`] does the
    /// cell table.
    ///
    /// # Errors
    /// Those of `writer`.
    pub fn write_readers_csv(&self, writer: impl Write) -> std::io::Result<()> {
        let mut csv = csv::Writer::from_writer(writer);
        csv.write_record(READER_COLUMNS)?;
        for entry in self.readers() {
            let mut row = vec![entry.reader.clone(), entry.kind.name().to_string()];
            row.extend(statistics_cells(&entry.summary));
            row.push(entry.flagged_cells.to_string());
            row.extend(flag_cells(entry.summary.degraded));
            csv.write_record(&row)?;
        }
        csv.flush()
    }

    /// Reads a map back from its cell and reader tables (as written by
    /// [`SurveyMap::write_cells_csv`] and [`SurveyMap::write_readers_csv`]), for use as a
    /// correction table. The scores and flags are taken from the files, not recomputed;
    /// `settings` gives the grid (the cell bounds must be cells of it) and `min_count` for
    /// [`SurveyMap::correction`]. Cells are trimmed; blank lines are skipped.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for settings out of range; [`EngineError::Parse`]
    /// naming the file, the 1-based line and the column for: a header other than
    /// [`CELL_COLUMNS`] / [`READER_COLUMNS`], a row with the wrong number of cells, malformed
    /// CSV, a number that does not parse or is not finite, bounds that are not a cell of the
    /// grid, an empty reader id, an unknown kind, `n` not an integer ≥ 1, a negative `std`, a
    /// `flagged` other than `true` / `false`, an unknown `reason` or one that contradicts
    /// `flagged`, and an entry that repeats an earlier line's.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::survey::{ResidualKind, SurveyMap, SurveySettings};
    /// let cells = "x_min_m,x_max_m,y_min_m,y_max_m,reader,kind,n,distance_m,bias,std,z,spread_z,flagged,reason\n\
    ///              10,20,0,10,R1,rssi,60,14.2,-9.5,3,-6.1,0.2,true,bias\n";
    /// let readers = "reader,kind,n,distance_m,bias,std,z,spread_z,flagged_cells,flagged,reason\n\
    ///                R1,rssi,300,21.7,-4.5,3.5,-4.2,0.1,1,true,bias+cells\n";
    /// let settings = SurveySettings::default();
    /// let map = SurveyMap::from_csv(cells, "cells.csv", readers, "readers.csv", &settings)?;
    /// assert_eq!(map.correction("R1", ResidualKind::Rssi, [15.0, 5.0]).unwrap().bias, -9.5);
    /// // no cell entry there: the reader's (flagged for its bias too)
    /// assert_eq!(map.correction("R1", ResidualKind::Rssi, [55.0, 5.0]).unwrap().bias, -4.5);
    ///
    /// let bad = cells.replace("-9.5", "minus nine");
    /// let error = SurveyMap::from_csv(&bad, "cells.csv", readers, "readers.csv", &settings).unwrap_err();
    /// assert!(error.to_string().starts_with("cells.csv:2: field `bias`"));
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn from_csv(
        cells_text: &str,
        cells_file: &str,
        readers_text: &str,
        readers_file: &str,
        settings: &SurveySettings,
    ) -> Result<Self> {
        settings.validate()?;
        let mut cells = Vec::new();
        let mut seen: HashMap<([i64; 2], String, ResidualKind), usize> = HashMap::new();
        for row in rows(cells_text, cells_file, &CELL_COLUMNS)? {
            let mut bounds = [0.0; 4];
            for (k, bound) in bounds.iter_mut().enumerate() {
                *bound = row.number(k)?;
            }
            let c = settings.cell_size_m;
            let cell = settings.cell_of([bounds[0] + 0.5 * c, bounds[2] + 0.5 * c]);
            let expected = settings.cell_bounds_m(cell);
            for k in 0..4 {
                if (bounds[k] - expected[k]).abs() > 1e-9 * c.max(expected[k].abs()) {
                    return Err(row.error(
                        k,
                        format!(
                            "{}: the bounds are not a cell of the grid (cell_size_m = {c}, origin_m = [{}, {}]); \
                             read the file with the grid it was written with",
                            bounds[k], settings.origin_m[0], settings.origin_m[1]
                        ),
                    ));
                }
            }
            let (reader, kind, summary) = row.entry(4, None)?;
            if let Some(first) = seen.insert((cell, reader.clone(), kind), row.line) {
                return Err(row.error(4, format!("cell, reader and kind repeat line {first}")));
            }
            cells.push(CellEntry {
                cell,
                reader,
                kind,
                summary,
            });
        }
        let mut readers = Vec::new();
        let mut seen: HashMap<(String, ResidualKind), usize> = HashMap::new();
        for row in rows(readers_text, readers_file, &READER_COLUMNS)? {
            let flagged_cells = row.count(8, 0)?;
            let (reader, kind, summary) = row.entry(0, Some(flagged_cells))?;
            if let Some(first) = seen.insert((reader.clone(), kind), row.line) {
                return Err(row.error(0, format!("reader and kind repeat line {first}")));
            }
            readers.push(ReaderEntry {
                reader,
                kind,
                summary,
                flagged_cells,
            });
        }
        Ok(Self::assemble(*settings, cells, readers))
    }
}

/// One data row of a table: its cells, line and the names of its columns.
struct Row<'a> {
    cells: csv::StringRecord,
    line: usize,
    file: &'a str,
    columns: &'a [&'a str],
}

impl Row<'_> {
    fn error(&self, column: usize, reason: String) -> EngineError {
        EngineError::Parse {
            file: self.file.to_string(),
            line: self.line,
            field: self.columns[column].to_string(),
            reason,
        }
    }

    fn text(&self, column: usize) -> &str {
        self.cells.get(column).unwrap_or("")
    }

    fn number(&self, column: usize) -> Result<f64> {
        let text = self.text(column);
        match text.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            Ok(value) => Err(self.error(column, format!("{value} is not a finite number"))),
            Err(_) => Err(self.error(column, format!("`{text}` is not a number"))),
        }
    }

    fn optional_number(&self, column: usize) -> Result<Option<f64>> {
        if self.text(column).is_empty() {
            Ok(None)
        } else {
            self.number(column).map(Some)
        }
    }

    /// An integer ≥ `least` in `column`.
    fn count(&self, column: usize, least: usize) -> Result<usize> {
        match self.text(column).parse::<usize>() {
            Ok(count) if count >= least => Ok(count),
            _ => Err(self.error(column, format!("`{}` is not an integer ≥ {least}", self.text(column)))),
        }
    }

    /// The reader, kind and summary in the columns from `first` (`reader`) on: `reader, kind,
    /// n, distance_m, bias, std, z, spread_z`, then (readers) `flagged_cells`, then `flagged,
    /// reason`. `flagged_cells` is `None` for a cell row.
    fn entry(&self, first: usize, flagged_cells: Option<usize>) -> Result<(String, ResidualKind, Summary)> {
        let [reader, kind, n, distance, bias, std, z, spread_z] = core::array::from_fn(|k| first + k);
        let flagged = first + 8 + usize::from(flagged_cells.is_some());
        let reason = flagged + 1;
        let id = self.text(reader);
        if id.is_empty() {
            return Err(self.error(reader, "is empty; every row names a reader".into()));
        }
        let kind_name = self.text(kind);
        let kind_value = ResidualKind::from_name(kind_name)
            .ok_or_else(|| self.error(kind, format!("`{kind_name}` is not a kind; expected `range` or `rssi`")))?;
        let count = self.count(n, 1)?;
        let distance_m = self.number(distance)?;
        if distance_m < 0.0 {
            return Err(self.error(distance, format!("{distance_m} is negative; must be ≥ 0")));
        }
        let std_value = self.optional_number(std)?;
        if std_value.is_some_and(|s| s < 0.0) {
            return Err(self.error(std, format!("{} is negative; must be ≥ 0", self.text(std))));
        }
        let flagged_value = match self.text(flagged) {
            "true" => true,
            "false" => false,
            other => return Err(self.error(flagged, format!("`{other}` is not `true` or `false`"))),
        };
        let reason_name = self.text(reason);
        let expected = if flagged_cells.is_some() {
            "`bias`, `spread`, `cells` joined by `+` in this order, or empty"
        } else {
            "`bias`, `spread`, `bias+spread` or empty"
        };
        let degraded = Degradation::from_name(reason_name)
            .filter(|d| flagged_cells.is_some() || !d.cells)
            .ok_or_else(|| self.error(reason, format!("`{reason_name}` is not a reason; expected {expected}")))?;
        if degraded.any() != flagged_value {
            return Err(self.error(
                flagged,
                format!(
                    "is {flagged_value} but the reason is `{reason_name}`; a flagged entry has a reason, others none"
                ),
            ));
        }
        if let Some(cells) = flagged_cells {
            if degraded.cells != (cells > 0) {
                return Err(self.error(
                    reason,
                    format!("`{reason_name}` does not match flagged_cells = {cells}; `cells` is a reason exactly when some are flagged"),
                ));
            }
        }
        let summary = Summary {
            count,
            distance_m,
            bias: self.number(bias)?,
            std: std_value,
            z: self.optional_number(z)?,
            spread_z: self.optional_number(spread_z)?,
            degraded,
        };
        Ok((id.to_string(), kind_value, summary))
    }
}

/// The data rows of a table whose header must be `columns`.
fn rows<'a>(text: &str, file: &'a str, columns: &'a [&'a str]) -> Result<Vec<Row<'a>>> {
    let parse_error = |line: usize, field: &str, reason: String| EngineError::Parse {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut rows = Vec::new();
    let mut header_seen = false;
    for result in reader.records() {
        let cells = result.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            parse_error(line, "-", format!("malformed CSV: {e}"))
        })?;
        let line = cells.position().map_or(0, |p| p.line() as usize);
        if !header_seen {
            header_seen = true;
            if cells.iter().ne(columns.iter().copied()) {
                let at = (0..columns.len().max(cells.len()))
                    .find(|&k| cells.get(k) != columns.get(k).copied())
                    .unwrap_or(0);
                return Err(parse_error(
                    line,
                    cells.get(at).unwrap_or("-"),
                    format!("the header must be {}", columns.join(",")),
                ));
            }
            continue;
        }
        if cells.len() != columns.len() {
            return Err(parse_error(
                line,
                "-",
                format!("row has {} cells but the header has {}", cells.len(), columns.len()),
            ));
        }
        rows.push(Row {
            cells,
            line,
            file,
            columns,
        });
    }
    if !header_seen {
        return Err(parse_error(
            0,
            "-",
            format!("no header row; expected {}", columns.join(",")),
        ));
    }
    Ok(rows)
}
