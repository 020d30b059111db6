//! The SQLite back end (embedded, the default): one file, WAL journal.
//!
//! Writes run in `BEGIN IMMEDIATE` transactions with cached prepared statements; a batch of
//! records, states or events is one transaction, so one commit (and, with
//! [`SqliteSync::Full`], one fsync) per batch.

use std::path::{Path, PathBuf};

use rusqlite::{params, Connection, OptionalExtension, ToSql, TransactionBehavior};

use super::migrations::{self, AppliedMigration, Migration, MigrationTarget, SQLITE_MIGRATIONS};
use super::{EventQuery, EventRow, HistoryQuery, LocationRow, NewRecord, Pruned, Store, StoreError, StoredRecord};

#[path = "sqlite_blocks.rs"]
mod blocks;
#[path = "sqlite_lock.rs"]
mod lock;

use lock::wait_for_lock;

/// The write-ahead log's size (pages) at which the ingest log's connection checkpoints it
/// ([`Store::defer_wal_checkpoints`]): ten times SQLite's default, so the other connections,
/// at the default, checkpoint first whenever they write.
const DEFERRED_WAL_CHECKPOINT_PAGES: i64 = 10_000;

/// How many prepared statements a connection keeps (the event query alone has 8 shapes).
const STATEMENT_CACHE_CAPACITY: usize = 64;

/// When SQLite waits for the disk (`PRAGMA synchronous`; the journal is always WAL).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SqliteSync {
    /// `synchronous=FULL`: every commit is fsynced before it returns, so an acknowledged
    /// batch survives a process crash (SIGKILL) and a power loss or OS crash. The default.
    #[default]
    Full,
    /// `synchronous=NORMAL`: the WAL is fsynced only at checkpoints. Safe against process
    /// crashes (SIGKILL: committed data is in the OS's page cache and the database never
    /// corrupts), but a power loss or OS crash may lose the last commits — batches that were
    /// already acknowledged. Faster on slow disks.
    Normal,
}

impl SqliteSync {
    /// The value of `PRAGMA synchronous`.
    fn pragma_value(self) -> &'static str {
        match self {
            Self::Full => "FULL",
            Self::Normal => "NORMAL",
        }
    }
}

/// A [`Store`] in an SQLite database.
///
/// # Examples
/// ```
/// use rtls_server::store::{sqlite::SqliteStore, NewRecord, Store};
///
/// let mut store = SqliteStore::open_in_memory()?;
/// let record = NewRecord {
///     received_ms: 1_700_000_000_000,
///     source: "http".into(),
///     time_s: 12.5,
///     tag: "tag-1".into(),
///     json: r#"{"t":12.5,"tag":"tag-1"}"#.into(),
/// };
/// let ids = store.append_records(&[record])?;
/// assert_eq!(store.records_after(0, 10)?[0].id, ids[0]);
/// # Ok::<(), rtls_server::store::StoreError>(())
/// ```
#[derive(Debug)]
pub struct SqliteStore {
    connection: Connection,
    /// The database file (`None` in memory), for error messages.
    path: Option<PathBuf>,
}

/// A [`StoreError::Database`] maker for one operation.
fn database(operation: &'static str) -> impl Fn(rusqlite::Error) -> StoreError + Copy {
    move |error| StoreError::Database {
        backend: "sqlite",
        operation,
        reason: error.to_string(),
    }
}

/// A row count from SQLite (never negative) as `u64`.
fn count_from(value: i64) -> u64 {
    u64::try_from(value).unwrap_or(0)
}

/// A `LIMIT` value: SQLite takes an `i64`.
fn limit_from(limit: usize) -> i64 {
    i64::try_from(limit).unwrap_or(i64::MAX)
}

impl SqliteStore {
    /// Opens (creating if missing) the database file at `path`, switches it to the WAL
    /// journal, sets `synchronous` per `sync`, a busy handler that waits up to 5 s for another
    /// connection's lock (`sqlite_lock.rs`) and `foreign_keys=ON`, and applies the schema
    /// migrations this build knows.
    ///
    /// # Errors
    /// [`StoreError::Database`] when the file cannot be opened, or it does not take the WAL
    /// journal (e.g. on a network file system); [`StoreError::Migration`] when its schema is
    /// newer than this build knows or a migration fails.
    pub fn open(path: &Path, sync: SqliteSync) -> Result<Self, StoreError> {
        let connection = Connection::open(path).map_err(|error| StoreError::Database {
            backend: "sqlite",
            operation: "open",
            reason: format!("{}: {error}", path.display()),
        })?;
        Self::configure(connection, Some(path.to_path_buf()), sync)
    }

    /// Opens a private in-memory database (for tests; its journal cannot be WAL and
    /// everything is lost when the store is dropped).
    ///
    /// # Errors
    /// [`StoreError::Database`], [`StoreError::Migration`] as [`SqliteStore::open`].
    pub fn open_in_memory() -> Result<Self, StoreError> {
        let connection = Connection::open_in_memory().map_err(database("open in memory"))?;
        Self::configure(connection, None, SqliteSync::Full)
    }

    /// Sets the pragmas and applies the migrations.
    fn configure(mut connection: Connection, path: Option<PathBuf>, sync: SqliteSync) -> Result<Self, StoreError> {
        connection
            .busy_handler(Some(wait_for_lock))
            .map_err(database("set busy_handler"))?;
        let journal_mode: String = connection
            .query_row("PRAGMA journal_mode = WAL", [], |row| row.get(0))
            .map_err(database("set journal_mode=WAL"))?;
        if let Some(path) = &path {
            if !journal_mode.eq_ignore_ascii_case("wal") {
                return Err(StoreError::Database {
                    backend: "sqlite",
                    operation: "set journal_mode=WAL",
                    reason: format!(
                        "{}: the database stayed in {journal_mode:?} journal mode; WAL needs a local file \
                         system that supports shared memory",
                        path.display()
                    ),
                });
            }
        }
        connection
            .pragma_update(None, "synchronous", sync.pragma_value())
            .map_err(database("set synchronous"))?;
        connection
            .pragma_update(None, "foreign_keys", "ON")
            .map_err(database("set foreign_keys"))?;
        connection.set_prepared_statement_cache_capacity(STATEMENT_CACHE_CAPACITY);
        migrations::run(&mut connection, SQLITE_MIGRATIONS)?;
        Ok(Self { connection, path })
    }

    /// The database file (`None` in memory).
    #[must_use]
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The journal mode in effect (`wal` for a file, `memory` in memory).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    pub fn journal_mode(&self) -> Result<String, StoreError> {
        self.connection
            .query_row("PRAGMA journal_mode", [], |row| row.get(0))
            .map_err(database("read journal_mode"))
    }

    /// Closes the database, reporting a failure to do so (dropping the store closes it too,
    /// silently).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    pub fn close(self) -> Result<(), StoreError> {
        self.connection.close().map_err(|(_, error)| database("close")(error))
    }

    /// The raw connection (tests inspect pragmas and the migration history through it).
    #[cfg(test)]
    pub(crate) fn connection(&mut self) -> &mut Connection {
        &mut self.connection
    }
}

impl MigrationTarget for Connection {
    fn ensure_history_table(&mut self) -> Result<(), StoreError> {
        self.execute_batch(
            "CREATE TABLE IF NOT EXISTS schema_migrations (
                 version    INTEGER NOT NULL PRIMARY KEY,
                 name       TEXT    NOT NULL,
                 applied_ms INTEGER NOT NULL
             ) STRICT",
        )
        .map_err(database("create schema_migrations"))
    }

    fn applied_migrations(&mut self) -> Result<Vec<AppliedMigration>, StoreError> {
        let read = database("read schema_migrations");
        let mut statement = self
            .prepare("SELECT version, name, applied_ms FROM schema_migrations ORDER BY version")
            .map_err(read)?;
        let rows = statement
            .query_map([], |row| {
                Ok(AppliedMigration {
                    version: row.get(0)?,
                    name: row.get(1)?,
                    applied_ms: row.get(2)?,
                })
            })
            .map_err(read)?;
        rows.collect::<Result<_, _>>().map_err(read)
    }

    fn apply(&mut self, migration: &Migration, applied_ms: i64) -> Result<bool, String> {
        let transaction = self
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|error| error.to_string())?;
        let already: Option<i64> = transaction
            .query_row(
                "SELECT 1 FROM schema_migrations WHERE version = ?1",
                [migration.version],
                |row| row.get(0),
            )
            .optional()
            .map_err(|error| error.to_string())?;
        if already.is_some() {
            return Ok(false);
        }
        transaction
            .execute_batch(migration.sql)
            .map_err(|error| error.to_string())?;
        transaction
            .execute(
                "INSERT INTO schema_migrations (version, name, applied_ms) VALUES (?1, ?2, ?3)",
                params![migration.version, migration.name, applied_ms],
            )
            .map_err(|error| error.to_string())?;
        transaction.commit().map_err(|error| error.to_string())?;
        Ok(true)
    }
}

/// The event query's SQL for the filters present (each shape is a cached statement).
fn events_sql(by_tag: bool, by_kinds: bool, alarms_only: bool, newest_first: bool) -> String {
    let mut sql = String::from(
        "SELECT received_ms, time_s, kind, tag, zone, alarm, json FROM events \
         WHERE time_s >= :from_s AND time_s <= :to_s",
    );
    if by_tag {
        sql.push_str(" AND tag = :tag");
    }
    if by_kinds {
        sql.push_str(" AND kind IN (SELECT value FROM json_each(:kinds))");
    }
    if alarms_only {
        sql.push_str(" AND alarm = 1");
    }
    sql.push_str(if newest_first {
        " ORDER BY time_s DESC, id DESC LIMIT :limit"
    } else {
        " ORDER BY time_s, id LIMIT :limit"
    });
    sql
}

impl Store for SqliteStore {
    fn backend(&self) -> &'static str {
        "sqlite"
    }

    fn defer_wal_checkpoints(&mut self) -> Result<(), StoreError> {
        self.connection
            .pragma_update(None, "wal_autocheckpoint", DEFERRED_WAL_CHECKPOINT_PAGES)
            .map_err(database("set wal_autocheckpoint"))
    }

    fn append_records_then_commit(
        &mut self,
        records: &[NewRecord],
        inserted: &mut dyn FnMut(&[i64]),
    ) -> Result<Vec<i64>, StoreError> {
        let fail = database("append records");
        if records.is_empty() {
            return Ok(Vec::new());
        }
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        let mut ids = Vec::with_capacity(records.len());
        {
            let mut insert = transaction
                .prepare_cached(
                    "INSERT INTO records (received_ms, source, time_s, tag, json) VALUES (?1, ?2, ?3, ?4, ?5)",
                )
                .map_err(fail)?;
            for record in records {
                let id = insert
                    .insert(params![
                        record.received_ms,
                        record.source,
                        record.time_s,
                        record.tag,
                        record.json
                    ])
                    .map_err(fail)?;
                ids.push(id);
            }
        }
        inserted(&ids);
        transaction.commit().map_err(fail)?;
        Ok(ids)
    }

    fn last_record_id(&mut self) -> Result<i64, StoreError> {
        // `AUTOINCREMENT`'s sequence keeps the highest id ever committed, even once its row is
        // pruned; the rows and blocks are asked too, in case the sequence row was removed
        self.connection
            .prepare_cached(
                "SELECT max(coalesce((SELECT seq FROM sqlite_sequence WHERE name = 'records'), 0), \
                            coalesce((SELECT max(id) FROM records), 0), \
                            coalesce((SELECT max(last_id) FROM record_blocks), 0))",
            )
            .and_then(|mut statement| statement.query_row([], |row| row.get(0)))
            .map_err(database("read the last record id"))
    }

    fn append_records_with_ids(&mut self, ids: &[i64], records: &[NewRecord]) -> Result<(), StoreError> {
        let fail = database("append records");
        super::check_given_ids("sqlite", ids, records)?;
        if records.is_empty() {
            return Ok(());
        }
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        {
            let mut insert = transaction
                .prepare_cached(
                    "INSERT INTO records (id, received_ms, source, time_s, tag, json) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                )
                .map_err(fail)?;
            for (id, record) in ids.iter().zip(records) {
                insert
                    .execute(params![
                        id,
                        record.received_ms,
                        record.source,
                        record.time_s,
                        record.tag,
                        record.json
                    ])
                    .map_err(fail)?;
            }
        }
        transaction.commit().map_err(fail)
    }

    fn records_after(&mut self, after_id: i64, limit: usize) -> Result<Vec<StoredRecord>, StoreError> {
        blocks::records_after(&mut self.connection, after_id, limit)
    }

    fn record_count(&mut self) -> Result<u64, StoreError> {
        let fail = database("count records");
        let mut count = self
            .connection
            .prepare_cached(
                "SELECT (SELECT count(*) FROM records) + (SELECT coalesce(sum(count), 0) FROM record_blocks)",
            )
            .map_err(fail)?;
        count.query_row([], |row| row.get(0)).map(count_from).map_err(fail)
    }

    fn append_locations(&mut self, rows: &[LocationRow]) -> Result<(), StoreError> {
        let fail = database("append locations");
        if rows.is_empty() {
            return Ok(());
        }
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        {
            let mut insert = transaction
                .prepare_cached(
                    "INSERT INTO locations (received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json) \
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                )
                .map_err(fail)?;
            for row in rows {
                insert
                    .execute(params![
                        row.received_ms,
                        row.time_s,
                        row.tag,
                        row.x_m,
                        row.y_m,
                        row.z_m,
                        row.accuracy_m,
                        row.predicted,
                        row.json
                    ])
                    .map_err(fail)?;
            }
        }
        transaction.commit().map_err(fail)
    }

    fn append_events(&mut self, rows: &[EventRow]) -> Result<(), StoreError> {
        let fail = database("append events");
        if rows.is_empty() {
            return Ok(());
        }
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        {
            let mut insert = transaction
                .prepare_cached(
                    "INSERT INTO events (received_ms, time_s, kind, tag, zone, alarm, json) \
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                )
                .map_err(fail)?;
            for row in rows {
                insert
                    .execute(params![
                        row.received_ms,
                        row.time_s,
                        row.kind,
                        row.tag,
                        row.zone,
                        row.alarm,
                        row.json
                    ])
                    .map_err(fail)?;
            }
        }
        transaction.commit().map_err(fail)
    }

    fn history(&mut self, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError> {
        blocks::history(&mut self.connection, query)
    }

    fn events(&mut self, query: &EventQuery) -> Result<Vec<EventRow>, StoreError> {
        let fail = database("events query");
        let kinds_json = if query.kinds.is_empty() {
            None
        } else {
            Some(
                serde_json::to_string(&query.kinds).map_err(|error| StoreError::Database {
                    backend: "sqlite",
                    operation: "events query",
                    reason: format!("kinds as JSON: {error}"),
                })?,
            )
        };
        let limit = limit_from(query.limit);
        let mut parameters: Vec<(&str, &dyn ToSql)> = vec![(":from_s", &query.from_s), (":to_s", &query.to_s)];
        if let Some(tag) = &query.tag {
            parameters.push((":tag", tag));
        }
        if let Some(kinds) = &kinds_json {
            parameters.push((":kinds", kinds));
        }
        parameters.push((":limit", &limit));
        let sql = events_sql(
            query.tag.is_some(),
            kinds_json.is_some(),
            query.alarms_only,
            query.newest_first,
        );
        let mut select = self.connection.prepare_cached(&sql).map_err(fail)?;
        let rows = select
            .query_map(parameters.as_slice(), |row| {
                Ok(EventRow {
                    received_ms: row.get(0)?,
                    time_s: row.get(1)?,
                    kind: row.get(2)?,
                    tag: row.get(3)?,
                    zone: row.get(4)?,
                    alarm: row.get(5)?,
                    json: row.get(6)?,
                })
            })
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)
    }

    fn put_config(&mut self, kind: &str, id: &str, json: &str) -> Result<bool, StoreError> {
        let fail = database("put config");
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        let inserted = transaction
            .prepare_cached("INSERT INTO config (kind, id, json) VALUES (?1, ?2, ?3) ON CONFLICT (kind, id) DO NOTHING")
            .and_then(|mut insert| insert.execute(params![kind, id, json]))
            .map_err(fail)?;
        if inserted == 0 {
            transaction
                .prepare_cached("UPDATE config SET json = ?3 WHERE kind = ?1 AND id = ?2")
                .and_then(|mut update| update.execute(params![kind, id, json]))
                .map_err(fail)?;
        }
        transaction.commit().map_err(fail)?;
        Ok(inserted == 1)
    }

    fn get_config(&mut self, kind: &str, id: &str) -> Result<Option<String>, StoreError> {
        let fail = database("get config");
        let mut select = self
            .connection
            .prepare_cached("SELECT json FROM config WHERE kind = ?1 AND id = ?2")
            .map_err(fail)?;
        select
            .query_row(params![kind, id], |row| row.get(0))
            .optional()
            .map_err(fail)
    }

    fn list_config(&mut self, kind: &str) -> Result<Vec<(String, String)>, StoreError> {
        let fail = database("list config");
        let mut select = self
            .connection
            .prepare_cached("SELECT id, json FROM config WHERE kind = ?1 ORDER BY id")
            .map_err(fail)?;
        let rows = select
            .query_map([kind], |row| Ok((row.get(0)?, row.get(1)?)))
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)
    }

    fn delete_config(&mut self, kind: &str, id: &str) -> Result<bool, StoreError> {
        let fail = database("delete config");
        let mut delete = self
            .connection
            .prepare_cached("DELETE FROM config WHERE kind = ?1 AND id = ?2")
            .map_err(fail)?;
        delete
            .execute(params![kind, id])
            .map(|deleted| deleted > 0)
            .map_err(fail)
    }

    fn checkpoint(&mut self, name: &str) -> Result<Option<i64>, StoreError> {
        let fail = database("read checkpoint");
        let mut select = self
            .connection
            .prepare_cached("SELECT value FROM checkpoints WHERE name = ?1")
            .map_err(fail)?;
        select.query_row([name], |row| row.get(0)).optional().map_err(fail)
    }

    fn set_checkpoint(&mut self, name: &str, value: i64) -> Result<(), StoreError> {
        let fail = database("set checkpoint");
        let mut upsert = self
            .connection
            .prepare_cached(
                "INSERT INTO checkpoints (name, value) VALUES (?1, ?2) \
                 ON CONFLICT (name) DO UPDATE SET value = excluded.value",
            )
            .map_err(fail)?;
        upsert.execute(params![name, value]).map(|_| ()).map_err(fail)
    }

    fn prune_ingest_log(&mut self, before_ms: i64, through_id: i64) -> Result<u64, StoreError> {
        let fail = database("prune the ingest log");
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        let in_blocks: i64 = transaction
            .prepare_cached(
                "SELECT coalesce(sum(count), 0) FROM record_blocks WHERE received_ms < ?1 AND last_id <= ?2",
            )
            .and_then(|mut statement| statement.query_row(params![before_ms, through_id], |row| row.get(0)))
            .map_err(fail)?;
        let delete = |sql: &str| {
            transaction
                .prepare_cached(sql)
                .and_then(|mut statement| statement.execute(params![before_ms, through_id]))
                .map(|deleted| deleted as u64)
                .map_err(fail)
        };
        delete("DELETE FROM record_blocks WHERE received_ms < ?1 AND last_id <= ?2")?;
        let rows = delete("DELETE FROM records WHERE received_ms < ?1 AND id <= ?2")?;
        transaction.commit().map_err(fail)?;
        Ok(count_from(in_blocks) + rows)
    }

    fn compact_history(&mut self, before_ms: i64, max_rows: usize) -> Result<u64, StoreError> {
        blocks::compact_history(&mut self.connection, before_ms, max_rows)
    }

    fn compact_ingest_log(&mut self, before_ms: i64, through_id: i64, max_rows: usize) -> Result<u64, StoreError> {
        blocks::compact_ingest_log(&mut self.connection, before_ms, through_id, max_rows)
    }

    fn prune(&mut self, before_ms: i64) -> Result<Pruned, StoreError> {
        let fail = database("prune");
        let transaction = self
            .connection
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(fail)?;
        let delete = |sql: &str| {
            transaction
                .prepare_cached(sql)
                .and_then(|mut statement| statement.execute([before_ms]))
                .map(|deleted| deleted as u64)
                .map_err(fail)
        };
        let in_blocks = |sql: &str| {
            transaction
                .prepare_cached(sql)
                .and_then(|mut statement| statement.query_row([before_ms], |row| row.get::<_, i64>(0)))
                .map(count_from)
                .map_err(fail)
        };
        let records_in_blocks = in_blocks("SELECT coalesce(sum(count), 0) FROM record_blocks WHERE received_ms < ?1")?;
        let states_in_blocks = in_blocks("SELECT coalesce(sum(count), 0) FROM location_blocks WHERE received_ms < ?1")?;
        delete("DELETE FROM record_blocks WHERE received_ms < ?1")?;
        delete("DELETE FROM location_blocks WHERE received_ms < ?1")?;
        let pruned = Pruned {
            records: records_in_blocks + delete("DELETE FROM records WHERE received_ms < ?1")?,
            locations: states_in_blocks + delete("DELETE FROM locations WHERE received_ms < ?1")?,
            events: delete("DELETE FROM events WHERE received_ms < ?1")?,
        };
        transaction.commit().map_err(fail)?;
        Ok(pruned)
    }
}
