//! Unit tests of the survey's CSV tables: the round trip and errors that name the file, the
//! line and the field.

use super::tests::{population, residuals_in};
use super::*;

/// A map with flagged cells and readers, a reader id that needs quoting, and a 1-residual cell.
fn map_for_csv(settings: &SurveySettings) -> SurveyMap {
    let mut all = population(&[([0, 1], -6.0, 2.0), ([-3, -2], 0.5, 1.0)]);
    for r in &mut all[..50] {
        r.reader = "R, \"north\"".into();
    }
    all.extend(residuals_in([7, 7], "R", ResidualKind::Rssi, 1.0, 0.0, 1));
    for k in 0..6 {
        all.extend(residuals_in([k, 3], "U", ResidualKind::Range, 0.1 * k as f64, 0.05, 60));
    }
    SurveyMap::build(&all, settings).unwrap()
}

fn csv_texts(map: &SurveyMap) -> (String, String) {
    let (mut cells, mut readers) = (Vec::new(), Vec::new());
    map.write_cells_csv(&mut cells).unwrap();
    map.write_readers_csv(&mut readers).unwrap();
    (String::from_utf8(cells).unwrap(), String::from_utf8(readers).unwrap())
}

#[test]
fn the_csv_tables_read_back_to_the_same_map() {
    let settings = SurveySettings {
        origin_m: [0.25, -3.5],
        ..SurveySettings::default()
    };
    let map = map_for_csv(&settings);
    let (cells, readers) = csv_texts(&map);
    assert_eq!(cells.lines().next().unwrap(), CELL_COLUMNS.join(","));
    assert_eq!(readers.lines().next().unwrap(), READER_COLUMNS.join(","));
    assert!(cells.contains("\"R, \"\"north\"\"\""), "{cells}");
    let back = SurveyMap::from_csv(&cells, "cells.csv", &readers, "readers.csv", &settings).unwrap();
    assert_eq!(back.cells(), map.cells());
    assert_eq!(back.readers(), map.readers());
    assert_eq!(back, map);
    assert!(!map.flagged_cells().is_empty());
    let p = [5.3, 12.0];
    assert_eq!(
        back.correction("R", ResidualKind::Rssi, p),
        map.correction("R", ResidualKind::Rssi, p)
    );
    // blank lines are skipped
    let spaced = cells.replacen('\n', "\n\n", 2);
    assert_eq!(
        SurveyMap::from_csv(&spaced, "cells.csv", &readers, "readers.csv", &settings).unwrap(),
        map
    );
}

/// The error of reading the tables after setting `column` of data row `row` (1-based, a row
/// without quoted cells) of `table` to `value`.
fn csv_error(table: &str, row: usize, column: &str, value: &str) -> String {
    let settings = SurveySettings::default();
    let (mut cells, mut readers) = csv_texts(&map_for_csv(&settings));
    let (text, columns) = if table == "cells" {
        (&mut cells, &CELL_COLUMNS[..])
    } else {
        (&mut readers, &READER_COLUMNS[..])
    };
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells_of_row: Vec<&str> = lines[row].split(',').collect();
    assert_eq!(cells_of_row.len(), columns.len(), "{}", lines[row]);
    let k = columns.iter().position(|c| *c == column).unwrap();
    cells_of_row[k] = value;
    lines[row] = cells_of_row.join(",");
    *text = lines.join("\n");
    SurveyMap::from_csv(&cells, "cells.csv", &readers, "readers.csv", &settings)
        .unwrap_err()
        .to_string()
}

#[test]
fn csv_errors_name_the_file_the_line_and_the_field() {
    // data row 1 of the cell table: cell (-3, -2) of R, unflagged; row 3: cell (0, 1) of R,
    // flagged for its bias. Reader rows: 1 = R (flagged through a cell), 3 = U (ranges).
    let cases = [
        (
            "cells",
            1,
            "bias",
            "0.5e",
            "cells.csv:2: field `bias`: `0.5e` is not a number",
        ),
        (
            "cells",
            1,
            "bias",
            "inf",
            "cells.csv:2: field `bias`: inf is not a finite number",
        ),
        (
            "cells",
            1,
            "x_min_m",
            "-31",
            "cells.csv:2: field `x_min_m`: -31: the bounds are not a cell of the grid",
        ),
        (
            "cells",
            1,
            "y_max_m",
            "-11",
            "cells.csv:2: field `y_max_m`: -11: the bounds are not a cell of the grid",
        ),
        (
            "cells",
            1,
            "n",
            "0",
            "cells.csv:2: field `n`: `0` is not an integer ≥ 1",
        ),
        (
            "cells",
            1,
            "n",
            "2.5",
            "cells.csv:2: field `n`: `2.5` is not an integer ≥ 1",
        ),
        (
            "cells",
            1,
            "kind",
            "tdoa",
            "cells.csv:2: field `kind`: `tdoa` is not a kind",
        ),
        ("cells", 1, "reader", "", "cells.csv:2: field `reader`: is empty"),
        ("cells", 1, "std", "-1", "cells.csv:2: field `std`: -1 is negative"),
        (
            "cells",
            1,
            "distance_m",
            "-12",
            "cells.csv:2: field `distance_m`: -12 is negative",
        ),
        ("cells", 1, "z", "x", "cells.csv:2: field `z`: `x` is not a number"),
        (
            "cells",
            1,
            "flagged",
            "yes",
            "cells.csv:2: field `flagged`: `yes` is not `true` or `false`",
        ),
        (
            "cells",
            1,
            "flagged",
            "true",
            "cells.csv:2: field `flagged`: is true but the reason is ``",
        ),
        (
            "cells",
            3,
            "reason",
            "cells",
            "cells.csv:4: field `reason`: `cells` is not a reason",
        ),
        (
            "cells",
            1,
            "x_min_m",
            "x_low",
            "cells.csv:2: field `x_min_m`: `x_low` is not a number",
        ),
        (
            "cells",
            0,
            "x_min_m",
            "x_low",
            "cells.csv:1: field `x_low`: the header must be x_min_m,x_max_m",
        ),
        (
            "readers",
            1,
            "flagged_cells",
            "0",
            "readers.csv:2: field `reason`: `cells` does not match flagged_cells = 0",
        ),
        (
            "readers",
            1,
            "flagged_cells",
            "x",
            "readers.csv:2: field `flagged_cells`: `x` is not an integer ≥ 0",
        ),
        (
            "readers",
            3,
            "flagged_cells",
            "2",
            "readers.csv:4: field `reason`: `` does not match flagged_cells = 2",
        ),
    ];
    for (table, row, column, value, expected) in cases {
        let message = csv_error(table, row, column, value);
        assert!(
            message.starts_with(expected),
            "{table} row {row} {column} = `{value}`: {message}"
        );
    }
    let settings = SurveySettings::default();
    let (cells, readers) = csv_texts(&map_for_csv(&settings));
    let read = |cells: &str, readers: &str| {
        SurveyMap::from_csv(cells, "cells.csv", readers, "readers.csv", &settings)
            .unwrap_err()
            .to_string()
    };
    // a repeated row names the first
    let first = cells.lines().nth(1).unwrap();
    let doubled = format!("{cells}{first}\n");
    let last = doubled.lines().count();
    let error = read(&doubled, &readers);
    assert!(
        error.starts_with(&format!(
            "cells.csv:{last}: field `reader`: cell, reader and kind repeat line 2"
        )),
        "{error}"
    );
    let first = readers.lines().nth(1).unwrap();
    let error = read(&cells, &format!("{readers}{first}\n"));
    assert!(
        error.starts_with("readers.csv:5: field `reader`: reader and kind repeat line 2"),
        "{error}"
    );
    // a short row, a missing header
    let short = cells.replacen(",false,\n", "\n", 1);
    assert!(read(&short, &readers).starts_with("cells.csv:2: field `-`: row has 12 cells but the header has 14"));
    assert!(read("", &readers).starts_with("cells.csv:0: field `-`: no header row"));
}
