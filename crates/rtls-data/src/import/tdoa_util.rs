//! UWB TDOA static identification runs of the UTIL dataset pre-release (Zhao, Goudar, Qiao,
//! Schoellig, "UTIL: An Ultra-wideband Time-difference-of-arrival Indoor Localization
//! Dataset", IJRR 2024; no licence stated — research use with citation): two Loco Positioning
//! anchors `an1`, `an2` and one static tag per run, poses from Vicon.
//!
//! # Files (per run, under `static-dataset/`)
//! - `<name>_data.csv`: header, then `tdoa12, tdoa21, …` (m). `tdoa12` is written as a
//!   [`Measurement::Tdoa`] with `anchor = "an2"`, `reference = "an1"`, i.e.
//!   `‖p − an2‖ − ‖p − an1‖` — the sign is checked against the poses (notes, tests).
//!   `tdoa21` (the reverse difference, ≈ −`tdoa12`) and the signal-quality columns are not
//!   imported. Trailing rows with an empty `tdoa12` are padding: the authors' converter
//!   (`los_bagTocsv.py`, utiasDSL/util-uwb-dataset) zips two log streams of different length
//!   with `zip_longest`; they are counted in the notes.
//! - `<name>_pose.txt`: `an1_p,x,y,z`, `an2_p`, `tag_p` (m, Vicon frame, averaged over the run),
//!   `an1_quat`, `an2_quat`, `tag_quat` (x, y, z, w — the converter writes the ROS message
//!   fields in that order), NLOS runs add `obs_m1..4` (obstacle markers).
//!
//! # Time
//! The files carry no time stamps (the converter drops them), so sample `i` (0-based among the
//! data rows) gets `t = i / `[`NOMINAL_RATE_HZ`] — an assumed rate, said in the notes.
//!
//! # Observability
//! Two anchors give one hyperbola: a position is not observable from this data alone. The runs
//! measure TDOA errors (LOS distance / angle series, NLOS materials); the notes report the
//! error statistics against the Vicon poses.

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use rtls_engine::record::{Measurement, Record};

use super::util::{content_error, mean_std, median, parse_error, parse_finite, read_text};
use super::{create_dir, write_records, write_text, write_truth, ImportedRun, TruthRow};
use crate::Result;

/// Assumed sample rate of the TDOA rows, Hz (not documented; the Crazyflie's log rate).
pub(super) const NOMINAL_RATE_HZ: f64 = 100.0;

/// Tag id.
const TAG: &str = "tag";

/// The three positions of a pose file, m.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Poses {
    an1_m: [f64; 3],
    an2_m: [f64; 3],
    tag_m: [f64; 3],
}

fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl Poses {
    /// The true `‖tag − an2‖ − ‖tag − an1‖`, m.
    fn range_difference_m(&self) -> f64 {
        distance_m(self.tag_m, self.an2_m) - distance_m(self.tag_m, self.an1_m)
    }
}

/// Reads a `_pose.txt` file (`name,x,y,z` / `name,x,y,z,w` lines; only the positions are used).
///
/// # Errors
/// [`crate::DataError::Parse`] naming the line and field (`an1_p[2]`, `tag_quat[3]`, `name`)
/// for a non-numeric value, a wrong count or an unknown line name;
/// [`crate::DataError::Content`] when a position line is missing.
fn read_poses(path: &Path) -> Result<Poses> {
    let text = read_text(path)?;
    let (mut an1, mut an2, mut tag) = (None, None, None);
    for (index, raw) in text.lines().enumerate() {
        let line = index as u64 + 1;
        let fields: Vec<&str> = raw.trim().split(',').collect();
        let name = fields[0].trim();
        if name.is_empty() {
            continue;
        }
        let expected = match name {
            "an1_p" | "an2_p" | "tag_p" => 3,
            "an1_quat" | "an2_quat" | "tag_quat" => 4,
            n if n.starts_with("obs_m") => 3,
            other => return Err(parse_error(path, line, "name", format!("unknown pose line `{other}`"))),
        };
        if fields.len() != expected + 1 {
            return Err(parse_error(
                path,
                line,
                format!("{name}[{}]", (fields.len().max(1) - 1).min(expected)),
                format!("{} values, expected {expected}", fields.len() - 1),
            ));
        }
        let mut values = Vec::with_capacity(expected);
        for (k, cell) in fields[1..].iter().enumerate() {
            values.push(parse_finite(path, line, &format!("{name}[{k}]"), cell)?);
        }
        let position = [values[0], values[1], values[2]];
        match name {
            "an1_p" => an1 = Some(position),
            "an2_p" => an2 = Some(position),
            "tag_p" => tag = Some(position),
            _ => {}
        }
    }
    match (an1, an2, tag) {
        (Some(an1_m), Some(an2_m), Some(tag_m)) => Ok(Poses { an1_m, an2_m, tag_m }),
        _ => Err(content_error(path, "needs an1_p, an2_p and tag_p lines")),
    }
}

/// The `tdoa12` column of a `_data.csv` file: `(row index, value)` of the rows that have one,
/// the number of trailing rows without one, and the rows without one before the last value.
#[derive(Debug)]
struct TdoaColumn {
    samples: Vec<(usize, f64)>,
    rows: usize,
    trailing_empty: usize,
    inner_empty: Vec<u64>,
}

/// Reads `tdoa12` (found by its header name).
///
/// # Errors
/// [`crate::DataError::Parse`] naming the line and `tdoa12` for a non-numeric value, or line 1
/// when the header has no `tdoa12`.
fn read_tdoa(path: &Path) -> Result<TdoaColumn> {
    let text = read_text(path)?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    let column = header
        .split(',')
        .position(|h| h.trim() == "tdoa12")
        .ok_or_else(|| parse_error(path, 1, "tdoa12", "no `tdoa12` column in the header"))?;
    let mut out = TdoaColumn {
        samples: Vec::new(),
        rows: 0,
        trailing_empty: 0,
        inner_empty: Vec::new(),
    };
    let mut empty_run: Vec<u64> = Vec::new();
    for (index, raw) in lines.enumerate() {
        let line = index as u64 + 2;
        if raw.trim().is_empty() {
            continue;
        }
        let row = out.rows;
        out.rows += 1;
        let cell = raw.split(',').nth(column).unwrap_or("").trim();
        if cell.is_empty() {
            empty_run.push(line);
            continue;
        }
        out.inner_empty.append(&mut empty_run);
        out.samples.push((row, parse_finite(path, line, "tdoa12", cell)?));
    }
    out.trailing_empty = empty_run.len();
    Ok(out)
}

/// Run name from the data file's directory relative to `static-dataset/`
/// (`los/distTest/distT1` → `los-distTest-distT1`).
fn run_name(root: &Path, data_file: &Path) -> String {
    let dir = data_file.parent().unwrap_or(root);
    let relative = dir.strip_prefix(root).unwrap_or(dir);
    relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("-")
}

/// Every `*_data.csv` under `dir`, sorted by path.
fn data_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(current) = pending.pop() {
        let entries = std::fs::read_dir(&current).map_err(|source| crate::DataError::Io {
            file: current.clone(),
            source,
        })?;
        for entry in entries {
            let path = entry
                .map_err(|source| crate::DataError::Io {
                    file: current.clone(),
                    source,
                })?
                .path();
            if path.is_dir() {
                pending.push(path);
            } else if path
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with("_data.csv"))
            {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

fn site_toml(name: &str, poses: &Poses) -> String {
    let reader = |id: &str, p: [f64; 3]| {
        format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{:?}, {:?}, {:?}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = 0.035, bias_m = 0.0 }} }}\n\n",
            p[0], p[1], p[2]
        )
    };
    format!(
        "# UTIL UWB TDOA static identification run `{name}` (pre-release; Zhao et al., IJRR 2024), written by\n\
         # `rtls import`. Vicon frame, m. Two anchors give ONE hyperbola: a position is not observable from this\n\
         # data alone; this is a measurement-error dataset (error statistics in the import notes).\n\
         name = \"UTIL static TDOA: {name}\"\n\n\
         # Anchor positions from the run's _pose.txt. TDOA records are an2 relative to an1 and carry no std_m:\n\
         # range_std_m = 0.035 m per anchor gives sqrt(2)*0.035 = 0.05 m per difference, the LOS spread the\n\
         # dataset README reports (a nominal figure; the per-run spread is in the notes).\n\
         {}{}\
         [tracker]\n\
         pipeline = \"tightly-coupled\"\n\
         motion_model = \"cv\"\n\
         filter = \"ekf\"\n\
         # The tag does not move: a small white acceleration only absorbs model error.\n\
         acceleration_noise_std_mps2 = 0.05\n\
         gate_probability = 0.999\n\
         initiation = {{ confirm_updates = 3, within_s = 2.0 }}\n\
         coast_timeout_s = 2.0\n\
         delete_timeout_s = 60.0\n\
         # Records are written in order at the nominal 100 Hz.\n\
         reorder_window_s = 0.1\n\
         # Anchors (0.72-0.79 m) and tag (0.61-0.64 m) are at different heights and the poses are 3-D.\n\
         dimensions = 3\n\
         # One TDOA per sample: each is its own epoch.\n\
         epoch_s = 0.0\n",
        reader("an1", poses.an1_m),
        reader("an2", poses.an2_m),
    )
}

/// Imports one run.
fn import_run(root: &Path, data_file: &Path, out_dir: &Path) -> Result<ImportedRun> {
    let name = run_name(root, data_file);
    let file_name = data_file.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let pose_file = data_file.with_file_name(file_name.replace("_data.csv", "_pose.txt"));
    let poses = read_poses(&pose_file)?;
    let column = read_tdoa(data_file)?;
    if column.samples.is_empty() {
        return Err(content_error(data_file, "no tdoa12 values"));
    }
    let records: Vec<Record> = column
        .samples
        .iter()
        .map(|&(row, tdoa_m)| Record {
            time_s: row as f64 / NOMINAL_RATE_HZ,
            tag: TAG.to_string(),
            measurement: Measurement::Tdoa {
                anchor: "an2".to_string(),
                reference: "an1".to_string(),
                range_difference_m: tdoa_m,
                std_m: None,
            },
        })
        .collect();
    let truth: Vec<TruthRow> = records
        .iter()
        .map(|r| TruthRow {
            time_s: r.time_s,
            tag: TAG.to_string(),
            position_m: poses.tag_m.to_vec(),
        })
        .collect();
    let dir = out_dir.join(&name);
    create_dir(&dir)?;
    let files = vec![
        dir.join("site.toml"),
        dir.join("measurements.jsonl"),
        dir.join("truth.csv"),
    ];
    write_text(&files[0], &site_toml(&name, &poses))?;
    write_records(&files[1], &records)?;
    write_truth(&files[2], &truth)?;

    let true_difference_m = poses.range_difference_m();
    let errors: Vec<f64> = column.samples.iter().map(|&(_, v)| v - true_difference_m).collect();
    let flipped: Vec<f64> = column.samples.iter().map(|&(_, v)| v + true_difference_m).collect();
    let (mean, std) = mean_std(&errors).unwrap_or((errors[0], 0.0));
    let mut notes = vec![
        format!(
            "{} data rows → {} TDOA records (tdoa12 = ‖p − an2‖ − ‖p − an1‖); {} trailing rows without tdoa12 are \
             padding of the converter (its second log stream was longer), not missing samples{}",
            column.rows,
            records.len(),
            column.trailing_empty,
            if column.inner_empty.is_empty() {
                String::new()
            } else {
                format!(
                    "; {} rows without tdoa12 before the last value: lines {:?}",
                    column.inner_empty.len(),
                    column.inner_empty
                )
            }
        ),
        format!(
            "time stamps are NOT in the file: sample i (0-based among the data rows) is at i / {NOMINAL_RATE_HZ} Hz, \
             an assumed nominal rate ({:.2} s in all)",
            column.rows as f64 / NOMINAL_RATE_HZ
        ),
        format!(
            "TDOA error vs Vicon (true difference {true_difference_m:+.3} m, d(an1) {:.3} m, d(an2) {:.3} m): mean \
             {mean:+.3} m, std {std:.3} m, median {:+.3} m; with the opposite sign the median error would be {:+.3} m",
            distance_m(poses.tag_m, poses.an1_m),
            distance_m(poses.tag_m, poses.an2_m),
            median(&errors).unwrap_or(mean),
            median(&flipped).unwrap_or(mean),
        ),
        "two anchors give one hyperbola: a 2-D or 3-D position is not observable from this data alone (a \
         measurement-error dataset); truth = the static Vicon tag position at every sample time"
            .to_string(),
    ];
    notes.push("tdoa21 and the SNR / power / anchor-to-anchor columns are not imported".to_string());
    Ok(ImportedRun {
        name,
        files,
        records: records.len(),
        truth_rows: truth.len(),
        notes,
    })
}

/// Imports every static run (one per `_data.csv`) into `OUT/<run>/`.
pub(super) fn import(dataset_dir: &Path, out_dir: &Path) -> Result<Vec<ImportedRun>> {
    let root = dataset_dir.join("static-dataset");
    let files = data_files(&root)?;
    if files.is_empty() {
        return Err(content_error(&root, "no *_data.csv files"));
    }
    files.iter().map(|file| import_run(&root, file, out_dir)).collect()
}
