//! `rtls import`: converts each recorded dataset in `../shared/data` into the engine's files —
//! a site model (`site.toml`), a measurement file (`measurements.jsonl`, the record format of
//! `docs/FORMATS.md`) and a ground-truth file (`truth.csv`) per run.
//!
//! # Output layout
//! `OUT/<run>/site.toml`, `OUT/<run>/measurements.jsonl`, `OUT/<run>/truth.csv` (plus any extra
//! files a dataset needs, e.g. a radio map), one directory per run of the dataset.
//!
//! # Ground-truth format (`truth.csv`)
//! CSV with the header `t,tag,x,y,z`: time in s (the measurement file's clock), tag id, position
//! in m in the site frame; `z` is empty for 2-D truth.

mod ble_tetam;
mod labyrinth;
mod tdoa_util;
#[cfg(test)]
mod test_support;
mod ujiindoorloc;
mod util;
mod uwb_lias;

use std::io::Write;
use std::path::{Path, PathBuf};

use rtls_engine::record::{to_json_line, Record};

use crate::{DataError, Result};

/// Which recorded dataset a directory holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dataset {
    /// UWB two-way ranging with motion capture (LIAS CUHK-SZ, planar rigid body).
    UwbLias,
    /// UWB ranges + wheel odometry in a labyrinth (TU Chemnitz libRSF).
    UwbOdometryLabyrinth,
    /// UWB TDOA static identification runs (UTIL pre-release).
    TdoaUtil,
    /// BLE RSSI tracks with camera ground truth (Danis et al., tetam area).
    BleTetam,
    /// UJIIndoorLoc Wi-Fi fingerprints.
    UjiIndoorLoc,
}

impl Dataset {
    /// Recognises a dataset directory by the files it holds.
    ///
    /// # Errors
    /// [`DataError::Content`] when the directory matches none of the known datasets.
    pub fn detect(dataset_dir: &Path) -> Result<Self> {
        let has = |relative: &str| dataset_dir.join(relative).exists();
        if has("Dynamic/UWB_dynamic_exp_fast.csv") {
            Ok(Self::UwbLias)
        } else if has("Indoor_UWB_Input.txt") {
            Ok(Self::UwbOdometryLabyrinth)
        } else if has("static-dataset") {
            Ok(Self::TdoaUtil)
        } else if has("trk") && has("cnf") {
            Ok(Self::BleTetam)
        } else if has("UJIndoorLoc/trainingData.csv") {
            Ok(Self::UjiIndoorLoc)
        } else {
            Err(DataError::Content {
                file: dataset_dir.to_path_buf(),
                reason: "not a known dataset directory (expected one of the folders of ../shared/data: \
                         uwb_lias_cuhksz_planar_rbl, uwb_odometry_labyrinth_tuc, tdoa_util_static_prerelease, \
                         ble_rssi_tracking_danis_tetam, ujiindoorloc)"
                    .into(),
            })
        }
    }

    /// Short name used in summaries.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::UwbLias => "uwb-lias",
            Self::UwbOdometryLabyrinth => "uwb-odometry-labyrinth",
            Self::TdoaUtil => "tdoa-util",
            Self::BleTetam => "ble-tetam",
            Self::UjiIndoorLoc => "ujiindoorloc",
        }
    }
}

/// One imported run: its directory and what was written.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedRun {
    /// Run name (the sub-directory of the output directory).
    pub name: String,
    /// Files written, in the order written.
    pub files: Vec<PathBuf>,
    /// Measurement records written.
    pub records: usize,
    /// Ground-truth rows written.
    pub truth_rows: usize,
    /// Choices and corrections made while importing (calibrations, skipped rows and why).
    pub notes: Vec<String>,
}

/// What an import wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportSummary {
    /// The dataset recognised.
    pub dataset: Dataset,
    /// The runs, in output order.
    pub runs: Vec<ImportedRun>,
}

/// Imports the dataset in `dataset_dir` into `out_dir` (created if needed).
///
/// # Errors
/// [`DataError`] naming the file (and line and field) of unreadable or malformed input, or an
/// output file that could not be written.
pub fn import_dataset(dataset_dir: &Path, out_dir: &Path) -> Result<ImportSummary> {
    let dataset = Dataset::detect(dataset_dir)?;
    let runs = match dataset {
        Dataset::UwbLias => uwb_lias::import(dataset_dir, out_dir)?,
        Dataset::UwbOdometryLabyrinth => labyrinth::import(dataset_dir, out_dir)?,
        Dataset::TdoaUtil => tdoa_util::import(dataset_dir, out_dir)?,
        Dataset::BleTetam => ble_tetam::import(dataset_dir, out_dir)?,
        Dataset::UjiIndoorLoc => ujiindoorloc::import(dataset_dir, out_dir)?,
    };
    Ok(ImportSummary { dataset, runs })
}

/// One ground-truth sample.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Time, s (the measurement file's clock).
    pub time_s: f64,
    /// Tag id.
    pub tag: String,
    /// Position `[x, y]` or `[x, y, z]`, m.
    pub position_m: Vec<f64>,
}

fn io_error(file: &Path, source: std::io::Error) -> DataError {
    DataError::Io {
        file: file.to_path_buf(),
        source,
    }
}

/// Creates `dir` and its parents.
pub(crate) fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| io_error(dir, source))
}

/// Writes `text` to `path`.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| io_error(path, source))
}

/// Writes records as JSON Lines (one record per line).
pub(crate) fn write_records(path: &Path, records: &[Record]) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|source| io_error(path, source))?;
    let mut out = std::io::BufWriter::new(file);
    for record in records {
        writeln!(out, "{}", to_json_line(record)).map_err(|source| io_error(path, source))?;
    }
    out.flush().map_err(|source| io_error(path, source))
}

/// Writes ground truth as `t,tag,x,y,z` CSV (`z` empty for 2-D rows).
pub(crate) fn write_truth(path: &Path, rows: &[TruthRow]) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|source| io_error(path, source))?;
    let mut out = std::io::BufWriter::new(file);
    writeln!(out, "t,tag,x,y,z").map_err(|source| io_error(path, source))?;
    for row in rows {
        let z = row.position_m.get(2).map(|z| format!("{z}")).unwrap_or_default();
        writeln!(
            out,
            "{},{},{},{},{}",
            row.time_s, row.tag, row.position_m[0], row.position_m[1], z
        )
        .map_err(|source| io_error(path, source))?;
    }
    out.flush().map_err(|source| io_error(path, source))
}
