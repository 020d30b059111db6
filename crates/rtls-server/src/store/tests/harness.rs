//! What the storage tests share: unique temporary SQLite files, PostgreSQL schemas of their
//! own, and rows to store.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use super::super::{EventRow, LocationRow, NewRecord, PostgresStore, SqliteStore, SqliteSync};

/// The variable naming the PostgreSQL database the tests may use.
const POSTGRES_URL_VARIABLE: &str = "RTLS_TEST_POSTGRES_URL";

/// A name no other test (or test process) uses: `{prefix}_{pid}_{counter}_{nanoseconds}`.
fn unique_name(prefix: &str) -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |since| since.subsec_nanos());
    format!(
        "{prefix}_{}_{}_{nanos}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// An SQLite file in the temporary directory, deleted (with its WAL and shared-memory files)
/// when dropped.
pub(crate) struct TempDb {
    pub path: PathBuf,
}

impl TempDb {
    pub fn new(test: &str) -> Self {
        Self {
            path: std::env::temp_dir().join(format!("{}.db", unique_name(&format!("rtls_store_{test}")))),
        }
    }

    pub fn open(&self) -> SqliteStore {
        SqliteStore::open(&self.path, SqliteSync::Full).expect("open the SQLite file")
    }

    /// The path of the file SQLite keeps beside the database (`-wal`, `-shm`).
    pub fn sibling(&self, suffix: &str) -> PathBuf {
        let mut name = self.path.clone().into_os_string();
        name.push(suffix);
        PathBuf::from(name)
    }
}

impl Drop for TempDb {
    fn drop(&mut self) {
        for path in [self.path.clone(), self.sibling("-wal"), self.sibling("-shm")] {
            let _ = std::fs::remove_file(Path::new(&path));
        }
    }
}

/// A PostgreSQL schema of its own for one test, dropped (with everything in it) when dropped.
pub(crate) struct PgSchema {
    pub url: String,
    pub schema: String,
}

impl PgSchema {
    /// `None` (after printing why) when `RTLS_TEST_POSTGRES_URL` is not set.
    pub fn new() -> Option<Self> {
        match std::env::var(POSTGRES_URL_VARIABLE) {
            Ok(url) if !url.is_empty() => Some(Self {
                url,
                schema: unique_name("rtls_test"),
            }),
            _ => {
                eprintln!("skipped: {POSTGRES_URL_VARIABLE} not set");
                None
            }
        }
    }

    pub fn open(&self) -> PostgresStore {
        PostgresStore::connect_in_schema(&self.url, &self.schema).expect("connect to PostgreSQL")
    }
}

impl Drop for PgSchema {
    fn drop(&mut self) {
        let dropped = ::postgres::Client::connect(&self.url, ::postgres::NoTls)
            .and_then(|mut client| client.batch_execute(&format!("DROP SCHEMA IF EXISTS \"{}\" CASCADE", self.schema)));
        if let Err(error) = dropped {
            eprintln!("could not drop the test schema {}: {error}", self.schema);
        }
    }
}

pub(crate) fn record(received_ms: i64, time_s: f64, tag: &str, label: &str) -> NewRecord {
    NewRecord {
        received_ms,
        source: format!("mqtt:rtls/v1/measurements/{label}"),
        time_s,
        tag: tag.to_owned(),
        json: format!(r#"{{"t":{time_s},"tag":"{tag}","label":"{label}"}}"#),
    }
}

pub(crate) fn location(received_ms: i64, time_s: f64, tag: &str) -> LocationRow {
    LocationRow {
        received_ms,
        time_s,
        tag: tag.to_owned(),
        x_m: time_s * 2.0 + 0.125,
        y_m: -time_s,
        // Every other state is 2-D, every third has no accuracy, every fourth is predicted.
        z_m: ((time_s as i64) % 2 == 0).then_some(1.5),
        accuracy_m: ((time_s as i64) % 3 != 0).then_some(0.25 * time_s),
        predicted: (time_s as i64) % 4 == 0,
        json: format!(r#"{{"t":{time_s},"tag":"{tag}","received":{received_ms}}}"#),
    }
}

/// A state as the pipeline stores it (an engine track line), with numbers on the compacted
/// blocks' grid (µs, mm, mm/s, σ in 0.1 mm, ρ in 10⁻⁴), so it reads back exactly after
/// compaction.
pub(crate) fn track_state(received_ms: i64, time_s: f64, tag: &str) -> LocationRow {
    use rtls_engine::lifecycle::TrackStatus;
    use rtls_engine::tracker::{TrackUpdate, UpdateSource};
    let predicted = (time_s as i64) % 4 == 0;
    let update = TrackUpdate {
        time_s,
        tag: tag.into(),
        dimensions: 2,
        position_m: [time_s * 2.0 + 0.125, 0.5 - time_s, 0.0],
        velocity_mps: [0.5, -0.25, 0.0],
        // σ = 0.5 m on both axes, ρ = 0.5
        position_covariance_m2: [0.25, 0.125, 0.125, 0.25, 0.0, 0.0, 0.0, 0.0, 0.0],
        predicted,
        status: if predicted {
            TrackStatus::Coasting
        } else {
            TrackStatus::Confirmed
        },
        source: UpdateSource::Fix,
        mode: None,
        revised: false,
        smoothed: false,
    };
    LocationRow {
        received_ms,
        time_s,
        tag: tag.to_owned(),
        x_m: update.position_m[0],
        y_m: update.position_m[1],
        z_m: None,
        accuracy_m: Some(0.75),
        predicted,
        json: update.to_json_line(),
    }
}

pub(crate) fn event(received_ms: i64, time_s: f64, kind: &str, tag: Option<&str>, alarm: bool) -> EventRow {
    EventRow {
        received_ms,
        time_s,
        kind: kind.to_owned(),
        tag: tag.map(str::to_owned),
        zone: kind.starts_with("zone").then(|| "stope-3".to_owned()),
        alarm,
        json: format!(r#"{{"t":{time_s},"type":"{kind}"}}"#),
    }
}
