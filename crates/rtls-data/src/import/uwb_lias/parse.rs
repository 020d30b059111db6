//! Readers of the LIAS files: the UWB range log, the motion-capture log and the static poses of
//! `Static/README.md`. Every malformed value is a [`crate::DataError::Parse`] naming the file,
//! the 1-based line and the field.

use std::path::Path;

use super::{ANCHORS, PAIRS, TAGS};
use crate::import::util::{parse_error, parse_finite, read_text};
use crate::Result;

/// Seconds per day.
const DAY_S: i64 = 86_400;

/// A wall-clock time stamp `YYYY-MM-DD H:MM:SS.fff`, split into its civil day and the exact
/// time of day as an integer count of `10^-digits` s (so no precision is lost before the single
/// final division).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Clock {
    /// Days since 1970-01-01 of the date.
    day: i64,
    /// Time of day in units of `10^-digits` s.
    ticks: i64,
    /// Decimal digits of the fraction.
    digits: u32,
}

impl Clock {
    /// Seconds since midnight of `origin_day` (the run's first date), exactly rounded.
    pub(super) fn seconds_since_midnight_of(self, origin_day: i64) -> f64 {
        let scale = 10_i64.pow(self.digits);
        let total = (self.day - origin_day) * DAY_S * scale + self.ticks;
        // one correctly rounded division of two exactly representable integers
        total as f64 / scale as f64
    }

    /// The civil day (days since 1970-01-01).
    pub(super) fn day(self) -> i64 {
        self.day
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (month + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Parses `YYYY-MM-DD H:MM:SS[.fff]`.
///
/// # Errors
/// [`crate::DataError::Parse`] naming `file`, `line` and `field` when the text is not such a
/// time stamp (or a component is out of range).
pub(super) fn parse_clock(file: &Path, line: u64, field: &str, text: &str) -> Result<Clock> {
    let text = text.trim();
    let bad = || {
        parse_error(
            file,
            line,
            field,
            format!("`{text}` is not a time stamp `YYYY-MM-DD H:MM:SS.fff`"),
        )
    };
    let (date, time) = text.split_once(' ').ok_or_else(bad)?;
    let mut date_parts = date.split('-').map(|p| p.parse::<i64>().ok());
    let (Some(Some(year)), Some(Some(month)), Some(Some(day)), None) = (
        date_parts.next(),
        date_parts.next(),
        date_parts.next(),
        date_parts.next(),
    ) else {
        return Err(bad());
    };
    let mut time_parts = time.trim().split(':');
    let (Some(hours), Some(minutes), Some(seconds), None) = (
        time_parts.next(),
        time_parts.next(),
        time_parts.next(),
        time_parts.next(),
    ) else {
        return Err(bad());
    };
    let (whole, fraction) = seconds.split_once('.').unwrap_or((seconds, ""));
    let digits = u32::try_from(fraction.len()).map_err(|_| bad())?;
    let number = |s: &str| -> Option<i64> {
        (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
            .then(|| s.parse().ok())
            .flatten()
    };
    let (Some(h), Some(m), Some(s)) = (number(hours), number(minutes), number(whole)) else {
        return Err(bad());
    };
    let f = if fraction.is_empty() {
        0
    } else {
        number(fraction).ok_or_else(bad)?
    };
    if !(1..=12).contains(&month) || !(1..=31).contains(&day) || h > 23 || m > 59 || s > 60 || digits > 9 {
        return Err(bad());
    }
    let scale = 10_i64.pow(digits);
    Ok(Clock {
        day: days_from_civil(year, month, day),
        ticks: (h * 3600 + m * 60 + s) * scale + f,
        digits,
    })
}

/// Name of the range column of `pair` (`a3-t1`), as in the dataset's README.
pub(super) fn pair_column(pair: usize) -> String {
    format!("a{}-t{}", pair / TAGS.len(), pair % TAGS.len())
}

/// One row of a UWB log: a time stamp and the 24 ranges (anchor-major, tag-minor).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct UwbRow {
    /// 1-based line in the file.
    pub line: u64,
    /// Wall-clock time stamp.
    pub clock: Clock,
    /// Ranges, m, in column order `a0-t0, a0-t1, a0-t2, a1-t0, …`; `None` for an empty cell.
    pub ranges_m: [Option<f64>; PAIRS],
    /// Non-empty fields after column 25 (not ranges; ignored, and reported by the importer).
    pub extra_values: usize,
}

/// Reads a UWB log (no header; time then 24 ranges). Columns after the 25th are not ranges:
/// `UWB_static_exp_8_14_pos2_deg_0.csv` has 9 more, empty except on 3 rows (`0`, `652.8`);
/// they are ignored and counted in [`UwbRow::extra_values`]. Blank lines are skipped.
///
/// # Errors
/// [`crate::DataError::Io`] if unreadable; [`crate::DataError::Parse`] naming the line and the
/// column (`time`, `a3-t1`) for a bad time stamp, a non-numeric or negative range, or fewer
/// than 25 fields.
pub(super) fn read_uwb(path: &Path) -> Result<Vec<UwbRow>> {
    let text = read_text(path)?;
    let mut rows = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let line = index as u64 + 1;
        if raw.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = raw.split(',').collect();
        if fields.len() < 1 + PAIRS {
            let missing = pair_column(fields.len().saturating_sub(1));
            return Err(parse_error(
                path,
                line,
                missing,
                format!(
                    "missing: the row has {} fields, expected 25 (time + 24 ranges)",
                    fields.len()
                ),
            ));
        }
        let extra_values = fields[1 + PAIRS..].iter().filter(|f| !f.trim().is_empty()).count();
        let clock = parse_clock(path, line, "time", fields[0])?;
        let mut ranges_m = [None; PAIRS];
        for (pair, cell) in fields[1..=PAIRS].iter().enumerate() {
            if cell.trim().is_empty() {
                continue;
            }
            let column = pair_column(pair);
            let range_m = parse_finite(path, line, &column, cell)?;
            if range_m < 0.0 {
                return Err(parse_error(path, line, column, format!("negative range {range_m} m")));
            }
            ranges_m[pair] = Some(range_m);
        }
        rows.push(UwbRow {
            line,
            clock,
            ranges_m,
            extra_values,
        });
    }
    Ok(rows)
}

/// One motion-capture sample.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MocapRow {
    /// 1-based line in the file.
    pub line: u64,
    /// Wall-clock time stamp.
    pub clock: Clock,
    /// Rigid-body centroid `[x, y, z]`, m.
    pub centroid_m: [f64; 3],
    /// The four orientation columns 5–8 as stored (see [`MocapRow::yaw_rad`]).
    pub rotation: [f64; 4],
}

impl MocapRow {
    /// Planar yaw, rad: `2·atan2(col7, col6)` (1-based columns), i.e. column 6 behaves as `q_w`
    /// and column 7 as `q_z`. The README's `(q_w, q_x, q_y, q_z)` order does not fit the
    /// ranges (the importer's notes and tests show the residual spread for both).
    pub(super) fn yaw_rad(&self) -> f64 {
        2.0 * self.rotation[2].atan2(self.rotation[1])
    }
}

/// Rotates `v` by the quaternion the README documents, `(q_w, q_x, q_y, q_z)` = columns 5–8
/// (`rotation[0..4]`). Only used to show that this order does not fit the ranges.
pub(super) fn rotate_documented_order(rotation: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let [w, x, y, z] = rotation;
    // R(q) of a unit quaternion, row by row
    [
        (1.0 - 2.0 * (y * y + z * z)) * v[0] + 2.0 * (x * y - w * z) * v[1] + 2.0 * (x * z + w * y) * v[2],
        2.0 * (x * y + w * z) * v[0] + (1.0 - 2.0 * (x * x + z * z)) * v[1] + 2.0 * (y * z - w * x) * v[2],
        2.0 * (x * z - w * y) * v[0] + 2.0 * (y * z + w * x) * v[1] + (1.0 - 2.0 * (x * x + y * y)) * v[2],
    ]
}

/// Column names of the motion-capture file, for error messages.
const MOCAP_FIELDS: [&str; 8] = [
    "time",
    "x",
    "y",
    "z",
    "rotation[0]",
    "rotation[1]",
    "rotation[2]",
    "rotation[3]",
];

/// Reads a motion-capture log (header `time,x,y,z,rotation,,,` then 8 fields per row). Blank
/// lines are skipped.
///
/// # Errors
/// [`crate::DataError::Io`] if unreadable; [`crate::DataError::Parse`] naming the line and the
/// field for a missing header, a row with other than 8 fields, a bad time stamp or number.
pub(super) fn read_mocap(path: &Path) -> Result<Vec<MocapRow>> {
    let text = read_text(path)?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header.trim_start().starts_with("time") => {}
        _ => return Err(parse_error(path, 1, "time", "missing header `time,x,y,z,rotation,,,`")),
    }
    let mut rows = Vec::new();
    for (index, raw) in lines {
        let line = index as u64 + 1;
        if raw.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = raw.split(',').collect();
        if fields.len() != MOCAP_FIELDS.len() {
            let field = MOCAP_FIELDS.get(fields.len()).copied().unwrap_or("rotation[3]");
            return Err(parse_error(
                path,
                line,
                field,
                format!(
                    "the row has {} fields, expected 8 (time, x, y, z, 4 rotation columns)",
                    fields.len()
                ),
            ));
        }
        let clock = parse_clock(path, line, "time", fields[0])?;
        let mut numbers = [0.0; 7];
        for (k, value) in numbers.iter_mut().enumerate() {
            *value = parse_finite(path, line, MOCAP_FIELDS[k + 1], fields[k + 1])?;
        }
        rows.push(MocapRow {
            line,
            clock,
            centroid_m: [numbers[0], numbers[1], numbers[2]],
            rotation: [numbers[3], numbers[4], numbers[5], numbers[6]],
        });
    }
    Ok(rows)
}

/// The surveyed pose of one static run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StaticPose {
    /// Pose number (1–5).
    pub pose: usize,
    /// Yaw, rad.
    pub yaw_rad: f64,
    /// Rigid-body centroid `[x, y]`, m.
    pub centroid_m: [f64; 2],
}

/// Largest |yaw| accepted as the `deg_0` orientation, degrees.
const DEG0_TOLERANCE_DEG: f64 = 10.0;

/// Reads the `deg_0` pose of Pose 1–5 of the 2022/8/14 session from `Static/README.md`: the
/// first data row of each pose in the "Different Poses" table of the `### 2022/8/14` section
/// (the 8/20 session uses another room and is not staged).
///
/// # Errors
/// [`crate::DataError::Io`] if unreadable; [`crate::DataError::Parse`] naming the line and
/// column (`Yaw(°)`, `X`, `Y`) for a non-numeric cell or a first yaw that is not ≈ 0°;
/// [`crate::DataError::Content`] when a pose is missing.
pub(super) fn read_static_poses(path: &Path, poses: usize) -> Result<Vec<StaticPose>> {
    let text = read_text(path)?;
    let mut in_session = false;
    let mut current: Option<usize> = None;
    let mut found: Vec<StaticPose> = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let line = index as u64 + 1;
        let trimmed = raw.trim();
        if let Some(heading) = trimmed.strip_prefix("### ") {
            in_session = heading.trim() == "2022/8/14";
            current = None;
            continue;
        }
        if !in_session || !trimmed.starts_with('|') {
            continue;
        }
        let cells: Vec<&str> = trimmed.trim_matches('|').split('|').map(str::trim).collect();
        if cells.len() != 4 {
            continue;
        }
        if let Some(number) = cells[0].strip_prefix("Pose ") {
            current = number.trim().parse().ok();
        }
        let Some(pose) = current else { continue };
        if cells[1].is_empty() || found.iter().any(|p| p.pose == pose) {
            continue;
        }
        let yaw_deg = parse_finite(path, line, "Yaw(°)", cells[1])?;
        let x = parse_finite(path, line, "X", cells[2])?;
        let y = parse_finite(path, line, "Y", cells[3])?;
        if yaw_deg.abs() > DEG0_TOLERANCE_DEG {
            return Err(parse_error(
                path,
                line,
                "Yaw(°)",
                format!("first orientation of Pose {pose} is {yaw_deg}°, expected ≈ 0° (the staged files are deg_0)"),
            ));
        }
        found.push(StaticPose {
            pose,
            yaw_rad: yaw_deg.to_radians(),
            centroid_m: [x, y],
        });
    }
    (1..=poses)
        .map(|pose| {
            found.iter().find(|p| p.pose == pose).copied().ok_or_else(|| {
                crate::import::util::content_error(
                    path,
                    format!("no deg_0 pose for Pose {pose} in the 2022/8/14 table"),
                )
            })
        })
        .collect()
}

/// Anchor index of a pair (anchor-major column order).
pub(super) fn pair_anchor(pair: usize) -> usize {
    pair / TAGS.len()
}

/// Tag index of a pair.
pub(super) fn pair_tag(pair: usize) -> usize {
    pair % TAGS.len()
}

const _: () = assert!(ANCHORS.len() * TAGS.len() == PAIRS);
