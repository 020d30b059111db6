//! Ground truth CSV: `t,tag,x,y,z`.

use std::collections::BTreeMap;

use super::TruthSample;
use crate::error::{EngineError, Result};

/// The columns of a ground-truth file, in the order the importers write them.
const COLUMNS: [&str; 5] = ["t", "tag", "x", "y", "z"];

fn parse_error(file: &str, line: usize, field: &str, reason: String) -> EngineError {
    EngineError::Parse {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    }
}

/// Parses a ground-truth CSV file: a header naming the columns `t` (s), `tag`, `x`, `y` (m) and
/// optionally `z` (m; an empty cell is a 2-D row), in any order, then one sample per row.
///
/// Blank lines (empty or spaces only) and lines starting with `#` are skipped; cells are trimmed. Rows need not be
/// sorted by time. A tag may have several rows at the same time only if they give the same
/// position.
///
/// # Errors
/// [`EngineError::Parse`] naming `file`, the 1-based line and the column for: a missing header,
/// an unknown or repeated column, a missing `t`/`tag`/`x`/`y` column, a row with the wrong
/// number of cells, an empty tag, a value that is not a finite number, two rows of a tag at the
/// same time with different positions (the later line, naming the earlier one), or a file with
/// no rows.
///
/// # Examples
/// ```
/// use rtls_engine::evaluation::parse_truth_csv;
///
/// let truth = parse_truth_csv("t,tag,x,y,z\n0.5,robot-1,1.5,2,\n0.5,robot-2,0,0,1.2\n", "truth.csv")?;
/// assert_eq!(truth[0].position_m, [1.5, 2.0, 0.0]);
/// assert!(!truth[0].has_z && truth[1].has_z);
///
/// let error = parse_truth_csv("t,tag,x,y,z\n0.5,robot-1,north,2,\n", "truth.csv").unwrap_err();
/// assert!(error.to_string().starts_with("truth.csv:2: field `x`"));
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
pub fn parse_truth_csv(text: &str, file: &str) -> Result<Vec<TruthSample>> {
    // (1-based line, cells) of every line that is not blank or a comment
    let mut rows = text.lines().enumerate().filter_map(|(index, line)| {
        let trimmed = line.trim();
        (!trimmed.is_empty() && !trimmed.starts_with('#')).then(|| (index + 1, split(trimmed)))
    });

    // Header: for each file column, its index in COLUMNS.
    let Some((header_line, header)) = rows.next() else {
        return Err(parse_error(file, 0, "-", "no header row; expected t,tag,x,y,z".into()));
    };
    let header = header.map_err(|reason| parse_error(file, header_line, "-", reason))?;
    let mut columns = Vec::with_capacity(header.len());
    for name in &header {
        let Some(index) = COLUMNS.iter().position(|c| c == name) else {
            return Err(parse_error(
                file,
                header_line,
                name,
                format!(
                    "unknown column; a ground-truth file has the columns {}",
                    COLUMNS.join(",")
                ),
            ));
        };
        if columns.contains(&index) {
            return Err(parse_error(file, header_line, name, "column appears twice".into()));
        }
        columns.push(index);
    }
    for required in &COLUMNS[..4] {
        if !header.iter().any(|name| name == required) {
            return Err(parse_error(
                file,
                header_line,
                required,
                "column is missing; t, tag, x and y are required (z is optional)".into(),
            ));
        }
    }

    let mut samples = Vec::new();
    for (line, record) in rows {
        let record = record.map_err(|reason| parse_error(file, line, "-", reason))?;
        if record.len() != columns.len() {
            return Err(parse_error(
                file,
                line,
                "-",
                format!(
                    "{} cells, the header has {} ({})",
                    record.len(),
                    columns.len(),
                    header.join(",")
                ),
            ));
        }
        let mut cells = [""; 5];
        for (cell, &index) in record.iter().map(String::as_str).zip(&columns) {
            cells[index] = cell;
        }
        let number = |index: usize| -> Result<f64> {
            let cell = cells[index];
            match cell.parse::<f64>() {
                Ok(value) if value.is_finite() => Ok(value),
                _ => Err(parse_error(
                    file,
                    line,
                    COLUMNS[index],
                    format!("`{cell}` is not a finite number"),
                )),
            }
        };
        let time_s = number(0)?;
        let tag = cells[1];
        if tag.is_empty() {
            return Err(parse_error(
                file,
                line,
                "tag",
                "is empty; every row needs a tag id".into(),
            ));
        }
        let (x, y) = (number(2)?, number(3)?);
        let (z, has_z) = if cells[4].is_empty() {
            (0.0, false)
        } else {
            (number(4)?, true)
        };
        samples.push(TruthSample {
            time_s,
            tag: tag.to_string(),
            position_m: [x, y, z],
            has_z,
            line,
        });
    }
    if samples.is_empty() {
        return Err(parse_error(
            file,
            header_line,
            "-",
            "no ground-truth rows after the header".into(),
        ));
    }
    check_same_time_same_position(&samples, file)?;
    Ok(samples)
}

/// Splits one line into trimmed cells (RFC 4180 quoting within the line).
fn split(line: &str) -> core::result::Result<Vec<String>, String> {
    if !line.contains('"') {
        return Ok(line.split(',').map(|cell| cell.trim().to_string()).collect());
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .from_reader(line.as_bytes());
    let mut cells = csv::StringRecord::new();
    match reader.read_record(&mut cells) {
        Ok(_) => Ok(cells.iter().map(str::to_string).collect()),
        Err(error) => Err(format!("not readable as CSV: {error}")),
    }
}

/// Errors when a tag has two samples at the same time with different positions, naming the later
/// sample's line (and the earlier one's) and the first coordinate that differs.
pub(super) fn check_same_time_same_position(samples: &[TruthSample], file: &str) -> Result<()> {
    let mut by_tag: BTreeMap<&str, Vec<&TruthSample>> = BTreeMap::new();
    for sample in samples {
        by_tag.entry(&sample.tag).or_default().push(sample);
    }
    for (tag, mut tagged) in by_tag {
        tagged.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.line.cmp(&b.line)));
        for pair in tagged.windows(2) {
            let (first, second) = (pair[0], pair[1]);
            if first.time_s != second.time_s {
                continue;
            }
            let field = if first.position_m[0] != second.position_m[0] {
                "x"
            } else if first.position_m[1] != second.position_m[1] {
                "y"
            } else if first.has_z != second.has_z || (first.has_z && first.position_m[2] != second.position_m[2]) {
                "z"
            } else {
                continue;
            };
            return Err(parse_error(
                file,
                second.line,
                field,
                format!(
                    "tag `{tag}` is also at t = {} s on line {} with a different position; \
                     keep one of the two rows",
                    first.time_s, first.line
                ),
            ));
        }
    }
    Ok(())
}
