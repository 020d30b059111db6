//! Persistent storage: the ingest log, track history, events and alarms, and the hub's
//! configuration (trackables, providers, zones, fences, the site).
//!
//! [`Store`] is synchronous: the server runs it on a storage thread of its own, so no async
//! task ever waits on a disk. Two back ends implement it: SQLite (embedded, the default, WAL
//! journal) and PostgreSQL (`--db postgres://…`). Both apply the same versioned schema
//! migrations when opened.

use thiserror::Error;

/// A measurement record as stored in the ingest log.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredRecord {
    /// The log's id, increasing in the order records were accepted.
    pub id: i64,
    /// Server wall-clock time of acceptance (ms since the Unix epoch).
    pub received_ms: i64,
    /// Who sent it (`http`, `mqtt:rtls/v1/measurements/reader-7`, `omlox`).
    pub source: String,
    /// The record's own time stamp (s).
    pub time_s: f64,
    /// The record's tag (`*` for anonymous records).
    pub tag: String,
    /// The record as one JSON line of the measurement format (docs/FORMATS.md).
    pub json: String,
}

/// A record to append to the ingest log.
#[derive(Debug, Clone, PartialEq)]
pub struct NewRecord {
    /// Server wall-clock time of acceptance (ms since the Unix epoch).
    pub received_ms: i64,
    /// Who sent it.
    pub source: String,
    /// The record's own time stamp (s).
    pub time_s: f64,
    /// The record's tag.
    pub tag: String,
    /// The record as one JSON line.
    pub json: String,
}

/// One reported track state.
#[derive(Debug, Clone, PartialEq)]
pub struct LocationRow {
    /// Server wall-clock time it was stored (ms since the Unix epoch); retention uses this.
    pub received_ms: i64,
    /// The state's time (s).
    pub time_s: f64,
    /// The tag.
    pub tag: String,
    /// Position (m).
    pub x_m: f64,
    /// Position (m).
    pub y_m: f64,
    /// Height (m); `None` for 2-D tracks.
    pub z_m: Option<f64>,
    /// √(largest eigenvalue of the position covariance) (m).
    pub accuracy_m: Option<f64>,
    /// Whether the state is a prediction without a measurement (coasting).
    pub predicted: bool,
    /// The full `TrackUpdate` JSON line.
    pub json: String,
}

/// One event (zone entry/exit/dwell, lifecycle, hazard alarms, model switches, …).
#[derive(Debug, Clone, PartialEq)]
pub struct EventRow {
    /// Server wall-clock time it was stored (ms since the Unix epoch); retention uses this.
    pub received_ms: i64,
    /// The event's time (s).
    pub time_s: f64,
    /// The event's `type` (`zone-enter`, `hazard-predicted`, …, docs/FORMATS.md).
    pub kind: String,
    /// The tag it concerns, if any.
    pub tag: Option<String>,
    /// The zone it concerns, if any.
    pub zone: Option<String>,
    /// Whether it is an alarm (hazard predicted, no coverage, a lost tag).
    pub alarm: bool,
    /// The event's JSON line.
    pub json: String,
}

/// A history query: one tag's (or every tag's) states in `[from_s, to_s]`, oldest first.
#[derive(Debug, Clone, PartialEq)]
pub struct HistoryQuery {
    /// The tag; `None`: every tag (a replay of the whole site).
    pub tag: Option<String>,
    /// Start of the range (s, inclusive).
    pub from_s: f64,
    /// End of the range (s, inclusive).
    pub to_s: f64,
    /// At most this many rows.
    pub limit: usize,
}

/// An event query: events in `[from_s, to_s]`, oldest first (or newest first).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EventQuery {
    /// Start of the range (s, inclusive).
    pub from_s: f64,
    /// End of the range (s, inclusive).
    pub to_s: f64,
    /// Only this tag's events.
    pub tag: Option<String>,
    /// Only these kinds (empty: all).
    pub kinds: Vec<String>,
    /// Only alarms.
    pub alarms_only: bool,
    /// At most this many rows.
    pub limit: usize,
    /// Newest first: the limit keeps the latest rows (an alarm console), not the earliest.
    pub newest_first: bool,
}

/// What [`Store::prune`] deleted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Pruned {
    /// Ingest-log records.
    pub records: u64,
    /// Track states.
    pub locations: u64,
    /// Events.
    pub events: u64,
}

/// A storage failure, naming the back end and what failed.
#[derive(Debug, Error)]
pub enum StoreError {
    /// The database URL is not understood.
    #[error("database URL {url:?}: {reason}")]
    Url {
        /// The URL given.
        url: String,
        /// What is wrong and what is accepted.
        reason: String,
    },
    /// A schema migration failed.
    #[error("schema migration {version} ({name}): {reason}")]
    Migration {
        /// The migration's version.
        version: u32,
        /// Its name.
        name: String,
        /// The database's error.
        reason: String,
    },
    /// The database refused an operation.
    #[error("{backend} {operation}: {reason}")]
    Database {
        /// `sqlite` or `postgres`.
        backend: &'static str,
        /// What was being done (`append records`, `history query`, …).
        operation: &'static str,
        /// The database's error.
        reason: String,
    },
}

/// The storage interface (synchronous; the server calls it from its storage thread).
pub trait Store: Send {
    /// `sqlite` or `postgres`.
    fn backend(&self) -> &'static str;
    /// Keeps this connection's commits short: it is the ingest log's, whose commits stand
    /// between a record and its acknowledgement. SQLite: the connection checkpoints the
    /// write-ahead log only once it holds 10 000 pages (about 40 MB), leaving the routine
    /// checkpoints (every 1 000 pages) to the output thread's connection, whose commits
    /// nobody waits for. Other back ends: nothing to do.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn defer_wal_checkpoints(&mut self) -> Result<(), StoreError> {
        Ok(())
    }
    /// Appends records to the ingest log in one transaction; when this returns `Ok` they are
    /// durable (committed). Returns their ids, in order.
    ///
    /// # Errors
    /// [`StoreError::Database`]; then none of the records is stored.
    fn append_records(&mut self, records: &[NewRecord]) -> Result<Vec<i64>, StoreError> {
        self.append_records_then_commit(records, &mut |_| {})
    }
    /// Appends records as [`Store::append_records`] does, calling `inserted` with their ids
    /// (in order) once they are inserted and before the commit that makes them durable, so
    /// the caller can work on them while the commit waits for the disk (a cluster's nodes,
    /// which share the store and take their ids from it). `inserted` must not
    /// block: the transaction holds the database's write lock meanwhile (SQLite). When this
    /// then fails, the records are not stored although `inserted` saw them, and their ids may
    /// be handed out again (SQLite rolls its id sequence back).
    ///
    /// # Errors
    /// [`StoreError::Database`]; then none of the records is stored.
    fn append_records_then_commit(
        &mut self,
        records: &[NewRecord],
        inserted: &mut dyn FnMut(&[i64]),
    ) -> Result<Vec<i64>, StoreError>;
    /// The highest ingest-log id given out so far (0 for a log that never held a record): no
    /// record in the log, in a packed block or not, has a higher id, nor did the back end's
    /// own id sequence give one out. The ingest log counts on from it
    /// ([`Store::append_records_with_ids`]).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn last_record_id(&mut self) -> Result<i64, StoreError>;
    /// Appends records under ids the caller chose, in one transaction; when this returns `Ok`
    /// they are durable. The ids must increase and be above every id the log holds
    /// ([`Store::last_record_id`]): the log's single writer (the ingest-log thread of a
    /// one-node server) counts them in memory, so it can hand records to the trackers before
    /// they are stored. Ids [`Store::append_records`] gives out later are above them.
    ///
    /// # Errors
    /// [`StoreError::Database`] when the ids and records differ in number, the ids do not
    /// increase, one is in the log already, or the database fails; then none of the records
    /// is stored.
    fn append_records_with_ids(&mut self, ids: &[i64], records: &[NewRecord]) -> Result<(), StoreError>;
    /// Up to `limit` records with id > `after_id`, in id order (replay after a restart).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn records_after(&mut self, after_id: i64, limit: usize) -> Result<Vec<StoredRecord>, StoreError>;
    /// The number of records in the ingest log.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn record_count(&mut self) -> Result<u64, StoreError>;
    /// Appends track states in one transaction.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn append_locations(&mut self, rows: &[LocationRow]) -> Result<(), StoreError>;
    /// Appends events in one transaction.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn append_events(&mut self, rows: &[EventRow]) -> Result<(), StoreError>;
    /// One tag's track states in a time range, oldest first.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn history(&mut self, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError>;
    /// Events in a time range, oldest first.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn events(&mut self, query: &EventQuery) -> Result<Vec<EventRow>, StoreError>;
    /// Creates or replaces a configuration object (`kind`: `trackable`, `provider`, `zone`,
    /// `fence`, `site`); returns whether it was created.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn put_config(&mut self, kind: &str, id: &str, json: &str) -> Result<bool, StoreError>;
    /// A configuration object.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn get_config(&mut self, kind: &str, id: &str) -> Result<Option<String>, StoreError>;
    /// All objects of a kind as `(id, json)`, ordered by id.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn list_config(&mut self, kind: &str) -> Result<Vec<(String, String)>, StoreError>;
    /// Deletes one object; returns whether it existed.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn delete_config(&mut self, kind: &str, id: &str) -> Result<bool, StoreError>;
    /// A named counter (e.g. the last ingest-log id the tracker has processed).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn checkpoint(&mut self, name: &str) -> Result<Option<i64>, StoreError>;
    /// Sets a named counter.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn set_checkpoint(&mut self, name: &str, value: i64) -> Result<(), StoreError>;
    /// Deletes records, states and events stored before `before_ms` (retention).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn prune(&mut self, before_ms: i64) -> Result<Pruned, StoreError>;
    /// Deletes ingest-log records stored before `before_ms` whose id is at most `through_id`
    /// (the checkpoint: their outputs are stored, so a restart does not replay them); returns
    /// how many (the raw-record retention, shorter than the history's).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn prune_ingest_log(&mut self, before_ms: i64, through_id: i64) -> Result<u64, StoreError>;
    /// Packs up to `max_rows` track states stored before `before_ms` into compressed blocks,
    /// one per tag, and deletes their rows, in one transaction; returns how many it packed
    /// (0: none is left). Queries read them as before, to the precision the block format
    /// keeps (module `history_blocks`: 1 µs, 1 mm, 1 mm/s, σ to 0.1 mm).
    ///
    /// # Errors
    /// [`StoreError::Database`]; then nothing is changed.
    fn compact_history(&mut self, before_ms: i64, max_rows: usize) -> Result<u64, StoreError>;
    /// Packs up to `max_rows` ingest-log records stored before `before_ms` whose id is at most
    /// `through_id` (the output checkpoint) into compressed blocks and deletes their rows, in
    /// one transaction; returns how many it packed. They read back exactly.
    ///
    /// # Errors
    /// [`StoreError::Database`]; then nothing is changed.
    fn compact_ingest_log(&mut self, before_ms: i64, through_id: i64, max_rows: usize) -> Result<u64, StoreError>;
}

/// Checks the ids given to [`Store::append_records_with_ids`]: one per record, increasing.
///
/// # Errors
/// [`StoreError::Database`] naming `backend` and what is wrong.
fn check_given_ids(backend: &'static str, ids: &[i64], records: &[NewRecord]) -> Result<(), StoreError> {
    let refused = |reason: String| StoreError::Database {
        backend,
        operation: "append records",
        reason,
    };
    if ids.len() != records.len() {
        return Err(refused(format!("{} ids for {} records", ids.len(), records.len())));
    }
    match ids.windows(2).find(|pair| pair[0] >= pair[1]) {
        Some(pair) => Err(refused(format!(
            "the ids do not increase: {} then {}",
            pair[0], pair[1]
        ))),
        None => Ok(()),
    }
}

mod history_blocks;
mod log_blocks;
mod migrations;
mod packing;
pub mod postgres;
pub mod sqlite;
#[cfg(test)]
mod tests;

pub use self::postgres::PostgresStore;
pub use self::sqlite::{SqliteStore, SqliteSync};

/// The database URL forms [`open`] accepts, for error messages.
const ACCEPTED_URLS: &str = "accepted: sqlite:PATH, sqlite://PATH, a file path (SQLite), \
                             postgres://USER:PASSWORD@HOST:PORT/DATABASE or postgresql://…";

/// Opens the store a database URL names, applying the schema migrations:
///
/// - `sqlite:PATH`, `sqlite://PATH` or a bare file path: an SQLite file (created if missing),
///   WAL journal, `synchronous` per `sqlite_sync`; the path `:memory:` (`sqlite::memory:`) is
///   a private in-memory database;
/// - `postgres://…` or `postgresql://…`: a PostgreSQL database (`sqlite_sync` is ignored).
///
/// # Errors
/// [`StoreError::Url`] for anything else (another scheme, an empty path), naming the URL (its
/// password masked) and the accepted forms; otherwise the errors of [`SqliteStore::open`] and
/// [`PostgresStore::connect`].
///
/// # Examples
/// ```
/// use rtls_server::store::{open, SqliteSync, StoreError};
///
/// let store = open("sqlite::memory:", SqliteSync::Full)?;
/// assert_eq!(store.backend(), "sqlite");
/// assert!(matches!(open("mysql://db.example/rtls", SqliteSync::Full), Err(StoreError::Url { .. })));
/// # Ok::<(), StoreError>(())
/// ```
pub fn open(url: &str, sqlite_sync: SqliteSync) -> Result<Box<dyn Store>, StoreError> {
    match parse_url(url)? {
        DatabaseUrl::Postgres => Ok(Box::new(PostgresStore::connect(url)?)),
        DatabaseUrl::Sqlite(":memory:") => Ok(Box::new(SqliteStore::open_in_memory()?)),
        DatabaseUrl::Sqlite(path) => Ok(Box::new(SqliteStore::open(std::path::Path::new(path), sqlite_sync)?)),
    }
}

/// What a database URL names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DatabaseUrl<'a> {
    /// An SQLite file (or `:memory:`).
    Sqlite(&'a str),
    /// A PostgreSQL database (the URL goes to the client as it is).
    Postgres,
}

/// Classifies a database URL (see [`open`]).
fn parse_url(url: &str) -> Result<DatabaseUrl<'_>, StoreError> {
    let rejected = |reason: String| StoreError::Url {
        url: crate::config::redact_password(url),
        reason,
    };
    if url.is_empty() {
        return Err(rejected(format!("empty; {ACCEPTED_URLS}")));
    }
    if url.starts_with("postgres://") || url.starts_with("postgresql://") {
        return Ok(DatabaseUrl::Postgres);
    }
    if let Some(path) = url.strip_prefix("sqlite://").or_else(|| url.strip_prefix("sqlite:")) {
        if path.is_empty() {
            return Err(rejected(format!("no file path after the scheme; {ACCEPTED_URLS}")));
        }
        return Ok(DatabaseUrl::Sqlite(path));
    }
    // A scheme is a letter followed by letters, digits, `+`, `-` or `.`, then `:`; one letter
    // is a Windows drive (`C:\rtls.db`), a path.
    if let Some((scheme, _)) = url.split_once(':') {
        let mut characters = scheme.chars();
        let is_scheme = characters.next().is_some_and(|first| first.is_ascii_alphabetic())
            && scheme.len() > 1
            && characters.all(|character| character.is_ascii_alphanumeric() || "+-.".contains(character));
        if is_scheme {
            return Err(rejected(format!("unsupported scheme {scheme:?}; {ACCEPTED_URLS}")));
        }
    }
    Ok(DatabaseUrl::Sqlite(url))
}
