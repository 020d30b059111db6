//! What the importer tests share: the dataset folder (or a skip message), a temporary output
//! directory, and reading a written measurement file back through the engine's parser.

use std::path::{Path, PathBuf};

use rtls_engine::record::{parse_json_line, Record};

/// `../shared/data/<folder>` if it is there; otherwise prints that the test is skipped.
pub(crate) fn dataset(folder: &str) -> Option<PathBuf> {
    let dir = crate::data_dir().join(folder);
    if dir.exists() {
        Some(dir)
    } else {
        eprintln!("skipped: {} not found", dir.display());
        None
    }
}

/// A fresh temporary directory, removed when dropped (kept when `RTLS_KEEP_IMPORT` is set,
/// for inspection).
pub(crate) struct TempDir(pub(crate) PathBuf);

impl TempDir {
    /// `<temp>/rtls-data-<importer>-<pid>-<name>`, emptied and created.
    pub(crate) fn new(importer: &str, name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("rtls-data-{importer}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::env::var_os("RTLS_KEEP_IMPORT").is_none() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Every line of a written measurement file, parsed and validated (panics naming the line).
pub(crate) fn read_records(path: &Path) -> Vec<Record> {
    let name = path.display().to_string();
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, line)| {
            let record = parse_json_line(line, &name, i + 1).unwrap();
            record.validate(&name, i + 1).unwrap();
            record
        })
        .collect()
}
