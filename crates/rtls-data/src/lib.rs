//! # rtls-data
//!
//! Readers for the recorded RTLS datasets the project evaluates on, and the evaluations
//! themselves. This is an I/O layer above the numeric crates: it parses files into the types of
//! `rtls-positioning` (and later `rtls-estimation`), and every malformed input is a
//! [`DataError`] naming the file, the line and the field.
//!
//! ## Layer
//! It owns the readers and importers of recorded datasets and their evaluations, and may import
//! `rtls-positioning` and `rtls-engine` (the importers write sites and records); it does not
//! import the simulator, the paper experiments or the server.
//!
//! ## Datasets
//! - [`ujiindoorloc`] — UJIIndoorLoc, the multi-building, multi-floor Wi-Fi fingerprint
//!   database of Universitat Jaume I (Torres-Sospedra et al., IPIN 2014; CC BY 4.0), and
//!   [`ujiindoorloc::evaluate`], the building/floor hit rates and 2-D error of a fingerprint
//!   method on its validation set.
//!
//! The datasets live outside the repository (`../shared/data` next to the checkout, see each
//! folder's README.txt for source and licence); [`data_dir`] finds them.
//!
//! ## Example
//! ```no_run
//! use rtls_data::{data_dir, ujiindoorloc};
//! let training = ujiindoorloc::load(&data_dir().join(ujiindoorloc::TRAINING))?;
//! println!("{} training fingerprints", training.len());
//! # Ok::<(), rtls_data::DataError>(())
//! ```

pub mod import;
pub mod ujiindoorloc;

use std::path::{Path, PathBuf};

/// Environment variable that overrides [`data_dir`].
pub const DATA_DIR_VARIABLE: &str = "RTLS_DATA_DIR";

/// The directory holding the recorded datasets: `$RTLS_DATA_DIR` if set, else `shared/data`
/// beside the repository checkout (`<checkout>/../shared/data`, where this project's machines
/// keep them).
///
/// # Example
/// ```
/// let dir = rtls_data::data_dir();
/// assert!(dir.ends_with("data"));
/// ```
#[must_use]
pub fn data_dir() -> PathBuf {
    match std::env::var_os(DATA_DIR_VARIABLE) {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    }
}

/// Why a dataset could not be read. Every variant names the file; parse errors name the
/// 1-based line and the column (field) too.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DataError {
    /// The file could not be opened or read.
    #[error("{file}: {source} (set {DATA_DIR_VARIABLE} to the directory holding the datasets)")]
    Io {
        /// The file.
        file: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A record or field is malformed.
    #[error("{file}:{line}: field `{field}`: {reason}")]
    Parse {
        /// The file.
        file: PathBuf,
        /// 1-based line number (the header is line 1).
        line: u64,
        /// The column name from the header (or its position if there is no header).
        field: String,
        /// What is wrong, with the offending value.
        reason: String,
    },
    /// The file parsed but its content cannot be used (e.g. it has no records).
    #[error("{file}: {reason}")]
    Content {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A positioning method rejected the data.
    #[error("positioning: {0}")]
    Positioning(#[from] rtls_positioning::PositioningError),
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, DataError>;
