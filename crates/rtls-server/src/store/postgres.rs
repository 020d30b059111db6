//! The PostgreSQL back end (`--db postgres://…`), through the synchronous `postgres` client
//! without TLS (run it on a trusted network or through a local socket/tunnel).
//!
//! A batch is one statement: the rows travel as one array per column and are inserted with
//! `INSERT … SELECT … FROM UNNEST(…)`, a single round trip whatever the batch size, through
//! statements prepared once per connection.

use std::collections::HashMap;

use ::postgres::types::ToSql;
use ::postgres::{Client, Config, NoTls, Row, Statement};

use super::migrations::{self, AppliedMigration, Migration, MigrationTarget, POSTGRES_MIGRATIONS};
use super::{EventQuery, EventRow, HistoryQuery, LocationRow, NewRecord, Pruned, Store, StoreError, StoredRecord};
use crate::config::redact_password;

#[path = "postgres_blocks.rs"]
mod blocks;
#[path = "postgres_tls.rs"]
mod tls;

/// The advisory lock that serialises migrations of concurrent processes (an arbitrary key:
/// "rtls" in ASCII).
const MIGRATION_LOCK_KEY: i64 = 0x7274_6c73;

/// A [`Store`] in a PostgreSQL database.
///
/// Ids come from sequences, or for the ingest log of a one-node server from the server
/// ([`Store::append_records_with_ids`], which moves the sequence past them): they increase and
/// are never reused. With one writer (the server's ingest-log thread) they are also committed
/// in increasing order, which [`Store::records_after`] relies on.
pub struct PostgresStore {
    client: Client,
    /// Statements prepared on this connection, by SQL text.
    statements: HashMap<String, Statement>,
}

impl std::fmt::Debug for PostgresStore {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter
            .debug_struct("PostgresStore")
            .field("closed", &self.client.is_closed())
            .field("prepared_statements", &self.statements.len())
            .finish()
    }
}

/// A [`StoreError::Database`] maker for one operation.
fn database(operation: &'static str) -> impl Fn(::postgres::Error) -> StoreError + Copy {
    move |error| StoreError::Database {
        backend: "postgres",
        operation,
        reason: error.to_string(),
    }
}

/// A row count from PostgreSQL (never negative) as `u64`.
fn count_from(value: i64) -> u64 {
    u64::try_from(value).unwrap_or(0)
}

/// A `LIMIT` value: PostgreSQL takes a `BIGINT`.
fn limit_from(limit: usize) -> i64 {
    i64::try_from(limit).unwrap_or(i64::MAX)
}

/// `name` as a quoted SQL identifier.
fn quote_identifier(name: &str) -> String {
    format!("\"{}\"", name.replace('"', "\"\""))
}

impl PostgresStore {
    /// Connects to `url` (`postgres://user:password@host:port/database`, or any form the
    /// `postgres` crate accepts; TLS with `?sslmode=require&sslrootcert=CA.pem`, see
    /// `store/postgres_tls.rs`) and applies the schema migrations this build knows, in the
    /// connection's default schema (normally `public`).
    ///
    /// # Errors
    /// [`StoreError::Url`] when the URL does not parse; [`StoreError::Database`] when the
    /// server cannot be reached or refuses the login; [`StoreError::Migration`] when the
    /// schema is newer than this build knows or a migration fails.
    pub fn connect(url: &str) -> Result<Self, StoreError> {
        let client = Self::client(url)?;
        Self::migrated(client)
    }

    /// As [`PostgresStore::connect`], but first creates `schema` if it does not exist and makes
    /// it the connection's `search_path`, so the store's tables live there (tests run in
    /// parallel, each in a schema of its own).
    ///
    /// # Errors
    /// As [`PostgresStore::connect`]; [`StoreError::Database`] when the schema cannot be
    /// created or selected (e.g. the role lacks the `CREATE` privilege on the database).
    pub fn connect_in_schema(url: &str, schema: &str) -> Result<Self, StoreError> {
        if schema.is_empty() {
            return Err(StoreError::Database {
                backend: "postgres",
                operation: "create schema",
                reason: "the schema name is empty".to_owned(),
            });
        }
        let mut client = Self::client(url)?;
        let quoted = quote_identifier(schema);
        client
            .batch_execute(&format!(
                "CREATE SCHEMA IF NOT EXISTS {quoted}; SET search_path TO {quoted}"
            ))
            .map_err(|error| StoreError::Database {
                backend: "postgres",
                operation: "create schema",
                reason: format!("{schema:?}: {error}"),
            })?;
        Self::migrated(client)
    }

    /// Parses `url` and connects, over TLS when its `sslmode` asks for it ([`tls::split`]).
    fn client(url: &str) -> Result<Client, StoreError> {
        let url_error = |reason: String| StoreError::Url {
            url: redact_password(url),
            reason,
        };
        let (rest, wanted) = tls::split(url).map_err(url_error)?;
        let mut config: Config = rest
            .parse()
            .map_err(|error: ::postgres::Error| url_error(format!("not a PostgreSQL connection URL: {error}")))?;
        let connect_error = |error: ::postgres::Error| {
            // the causes too: "error performing TLS handshake" alone does not say which
            let mut reason = error.to_string();
            let mut cause = std::error::Error::source(&error);
            while let Some(inner) = cause {
                reason.push_str(&format!(": {inner}"));
                cause = inner.source();
            }
            StoreError::Database {
                backend: "postgres",
                operation: "connect",
                reason: format!("{}: {reason}", redact_password(url)),
            }
        };
        match wanted {
            tls::PgTls::Off => config.connect(NoTls).map_err(connect_error),
            tls::PgTls::Verified(ca_file) => {
                let connector = tls::connector(&ca_file).map_err(url_error)?;
                config
                    .ssl_mode(::postgres::config::SslMode::Require)
                    .connect(connector)
                    .map_err(connect_error)
            }
        }
    }

    /// Applies the migrations on `client`.
    fn migrated(mut client: Client) -> Result<Self, StoreError> {
        migrations::run(&mut client, POSTGRES_MIGRATIONS)?;
        Ok(Self {
            client,
            statements: HashMap::new(),
        })
    }

    /// Closes the connection, reporting a failure to do so (dropping the store closes it too,
    /// silently).
    ///
    /// # Errors
    /// [`StoreError::Database`].
    pub fn close(self) -> Result<(), StoreError> {
        self.client.close().map_err(database("close"))
    }

    /// The prepared statement for `sql`, preparing it on first use.
    fn statement(&mut self, sql: &str, operation: &'static str) -> Result<Statement, StoreError> {
        if let Some(statement) = self.statements.get(sql) {
            return Ok(statement.clone());
        }
        let statement = self.client.prepare(sql).map_err(database(operation))?;
        self.statements.insert(sql.to_owned(), statement.clone());
        Ok(statement)
    }

    /// Runs a cached query.
    fn query(
        &mut self,
        sql: &str,
        parameters: &[&(dyn ToSql + Sync)],
        operation: &'static str,
    ) -> Result<Vec<Row>, StoreError> {
        let statement = self.statement(sql, operation)?;
        self.client.query(&statement, parameters).map_err(database(operation))
    }

    /// Inserts records into the ingest log (in the caller's transaction); their ids, in order.
    fn insert_records(&mut self, records: &[NewRecord]) -> Result<Vec<i64>, StoreError> {
        const OPERATION: &str = "append records";
        let received_ms: Vec<i64> = records.iter().map(|record| record.received_ms).collect();
        let sources: Vec<&str> = records.iter().map(|record| record.source.as_str()).collect();
        let times_s: Vec<f64> = records.iter().map(|record| record.time_s).collect();
        let tags: Vec<&str> = records.iter().map(|record| record.tag.as_str()).collect();
        let jsons: Vec<&str> = records.iter().map(|record| record.json.as_str()).collect();
        // Rows are inserted in array order (ORDER BY ordinal), so the sequence hands out
        // increasing ids in that order; RETURNING's order is unspecified, hence the sort.
        let rows = self.query(
            "INSERT INTO records (received_ms, source, time_s, tag, json) \
             SELECT received_ms, source, time_s, tag, json \
             FROM UNNEST($1::BIGINT[], $2::TEXT[], $3::DOUBLE PRECISION[], $4::TEXT[], $5::TEXT[]) \
                  WITH ORDINALITY AS batch (received_ms, source, time_s, tag, json, ordinal) \
             ORDER BY ordinal RETURNING id",
            &[&received_ms, &sources, &times_s, &tags, &jsons],
            OPERATION,
        )?;
        let mut ids = rows
            .iter()
            .map(|row| row.try_get::<_, i64>(0))
            .collect::<Result<Vec<_>, _>>()
            .map_err(database(OPERATION))?;
        ids.sort_unstable();
        if ids.len() != records.len() {
            return Err(StoreError::Database {
                backend: "postgres",
                operation: OPERATION,
                reason: format!("the insert returned {} ids for {} records", ids.len(), records.len()),
            });
        }
        Ok(ids)
    }

    /// Runs a cached statement; returns the number of rows it changed.
    fn execute(
        &mut self,
        sql: &str,
        parameters: &[&(dyn ToSql + Sync)],
        operation: &'static str,
    ) -> Result<u64, StoreError> {
        let statement = self.statement(sql, operation)?;
        self.client.execute(&statement, parameters).map_err(database(operation))
    }

    /// The raw client (tests inspect the migration history through it).
    #[cfg(test)]
    pub(crate) fn client_mut(&mut self) -> &mut Client {
        &mut self.client
    }
}

impl MigrationTarget for Client {
    fn ensure_history_table(&mut self) -> Result<(), StoreError> {
        let fail = database("create schema_migrations");
        let mut transaction = self.transaction().map_err(fail)?;
        transaction
            .execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK_KEY])
            .map_err(fail)?;
        transaction
            .batch_execute(
                "CREATE TABLE IF NOT EXISTS schema_migrations (
                     version    INTEGER NOT NULL PRIMARY KEY,
                     name       TEXT    NOT NULL,
                     applied_ms BIGINT  NOT NULL
                 )",
            )
            .map_err(fail)?;
        transaction.commit().map_err(fail)
    }

    fn applied_migrations(&mut self) -> Result<Vec<AppliedMigration>, StoreError> {
        let fail = database("read schema_migrations");
        let rows = self
            .query(
                "SELECT version, name, applied_ms FROM schema_migrations ORDER BY version",
                &[],
            )
            .map_err(fail)?;
        rows.iter()
            .map(|row| {
                let version: i32 = row.try_get(0).map_err(fail)?;
                Ok(AppliedMigration {
                    version: u32::try_from(version).map_err(|_| StoreError::Database {
                        backend: "postgres",
                        operation: "read schema_migrations",
                        reason: format!("negative migration version {version}"),
                    })?,
                    name: row.try_get(1).map_err(fail)?,
                    applied_ms: row.try_get(2).map_err(fail)?,
                })
            })
            .collect()
    }

    fn apply(&mut self, migration: &Migration, applied_ms: i64) -> Result<bool, String> {
        let version = i32::try_from(migration.version).map_err(|error| error.to_string())?;
        let mut transaction = self.transaction().map_err(|error| error.to_string())?;
        transaction
            .execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK_KEY])
            .map_err(|error| error.to_string())?;
        let already = transaction
            .query_opt("SELECT 1 FROM schema_migrations WHERE version = $1", &[&version])
            .map_err(|error| error.to_string())?;
        if already.is_some() {
            return Ok(false);
        }
        transaction
            .batch_execute(migration.sql)
            .map_err(|error| error.to_string())?;
        transaction
            .execute(
                "INSERT INTO schema_migrations (version, name, applied_ms) VALUES ($1, $2, $3)",
                &[&version, &migration.name, &applied_ms],
            )
            .map_err(|error| error.to_string())?;
        transaction.commit().map_err(|error| error.to_string())?;
        Ok(true)
    }
}

/// The event query's SQL for the filters present, with its parameters numbered in the order
/// `from_s, to_s, [tag], [kinds], limit` (each shape is a cached statement).
fn events_sql(by_tag: bool, by_kinds: bool, alarms_only: bool, newest_first: bool) -> String {
    let mut sql = String::from(
        "SELECT received_ms, time_s, kind, tag, zone, alarm, json FROM events WHERE time_s >= $1 AND time_s <= $2",
    );
    let mut next = 3;
    if by_tag {
        sql.push_str(&format!(" AND tag = ${next}"));
        next += 1;
    }
    if by_kinds {
        sql.push_str(&format!(" AND kind = ANY(${next}::TEXT[])"));
        next += 1;
    }
    if alarms_only {
        sql.push_str(" AND alarm");
    }
    let order = if newest_first {
        "time_s DESC, id DESC"
    } else {
        "time_s, id"
    };
    sql.push_str(&format!(" ORDER BY {order} LIMIT ${next}"));
    sql
}

/// A history row.
fn location_from(row: &Row) -> Result<LocationRow, ::postgres::Error> {
    Ok(LocationRow {
        received_ms: row.try_get(0)?,
        time_s: row.try_get(1)?,
        tag: row.try_get(2)?,
        x_m: row.try_get(3)?,
        y_m: row.try_get(4)?,
        z_m: row.try_get(5)?,
        accuracy_m: row.try_get(6)?,
        predicted: row.try_get(7)?,
        json: row.try_get(8)?,
    })
}

/// An event row.
fn event_from(row: &Row) -> Result<EventRow, ::postgres::Error> {
    Ok(EventRow {
        received_ms: row.try_get(0)?,
        time_s: row.try_get(1)?,
        kind: row.try_get(2)?,
        tag: row.try_get(3)?,
        zone: row.try_get(4)?,
        alarm: row.try_get(5)?,
        json: row.try_get(6)?,
    })
}

impl Store for PostgresStore {
    fn backend(&self) -> &'static str {
        "postgres"
    }

    fn append_records_then_commit(
        &mut self,
        records: &[NewRecord],
        inserted: &mut dyn FnMut(&[i64]),
    ) -> Result<Vec<i64>, StoreError> {
        const OPERATION: &str = "append records";
        if records.is_empty() {
            inserted(&[]);
            return Ok(Vec::new());
        }
        self.client.batch_execute("BEGIN").map_err(database(OPERATION))?;
        let ids = match self.insert_records(records) {
            Ok(ids) => ids,
            Err(error) => {
                // the transaction is aborted; a failing ROLLBACK leaves the same error to report
                let _ = self.client.batch_execute("ROLLBACK");
                return Err(error);
            }
        };
        inserted(&ids);
        self.client.batch_execute("COMMIT").map_err(database(OPERATION))?;
        Ok(ids)
    }

    fn last_record_id(&mut self) -> Result<i64, StoreError> {
        const OPERATION: &str = "read the last record id";
        // the sequence's last value (NULL before its first use) covers ids whose rows are
        // pruned; the rows and blocks cover ids given explicitly
        let rows = self.query(
            "SELECT greatest(\
                 coalesce(pg_sequence_last_value(pg_get_serial_sequence('records', 'id')::regclass), 0), \
                 coalesce((SELECT max(id) FROM records), 0), \
                 coalesce((SELECT max(last_id) FROM record_blocks), 0))::BIGINT",
            &[],
            OPERATION,
        )?;
        rows.first()
            .map_or(Ok(0), |row| row.try_get::<_, i64>(0))
            .map_err(database(OPERATION))
    }

    fn append_records_with_ids(&mut self, ids: &[i64], records: &[NewRecord]) -> Result<(), StoreError> {
        const OPERATION: &str = "append records";
        super::check_given_ids("postgres", ids, records)?;
        let Some(&last_id) = ids.last() else {
            return Ok(());
        };
        let received_ms: Vec<i64> = records.iter().map(|record| record.received_ms).collect();
        let sources: Vec<&str> = records.iter().map(|record| record.source.as_str()).collect();
        let times_s: Vec<f64> = records.iter().map(|record| record.time_s).collect();
        let tags: Vec<&str> = records.iter().map(|record| record.tag.as_str()).collect();
        let jsons: Vec<&str> = records.iter().map(|record| record.json.as_str()).collect();
        self.client.batch_execute("BEGIN").map_err(database(OPERATION))?;
        let inserted = self
            .execute(
                "INSERT INTO records (id, received_ms, source, time_s, tag, json) \
                 SELECT * FROM UNNEST($1::BIGINT[], $2::BIGINT[], $3::TEXT[], $4::DOUBLE PRECISION[], \
                                      $5::TEXT[], $6::TEXT[])",
                &[&ids, &received_ms, &sources, &times_s, &tags, &jsons],
                OPERATION,
            )
            // the sequence moves past the given ids, so the ids it gives out later (a cluster
            // on this database) do not collide with them; a sequence is not transactional, so
            // after a failed commit it stays moved: a gap
            .and_then(|_| {
                self.query(
                    "SELECT setval(pg_get_serial_sequence('records', 'id'), \
                         greatest(nextval(pg_get_serial_sequence('records', 'id')), $1::BIGINT))",
                    &[&last_id],
                    OPERATION,
                )
            });
        if let Err(error) = inserted {
            // the transaction is aborted; a failing ROLLBACK leaves the same error to report
            let _ = self.client.batch_execute("ROLLBACK");
            return Err(error);
        }
        self.client.batch_execute("COMMIT").map_err(database(OPERATION))
    }

    fn records_after(&mut self, after_id: i64, limit: usize) -> Result<Vec<StoredRecord>, StoreError> {
        self.records_after_with_blocks(after_id, limit)
    }

    fn record_count(&mut self) -> Result<u64, StoreError> {
        const OPERATION: &str = "count records";
        let rows = self.query(
            "SELECT (SELECT count(*) FROM records) + (SELECT coalesce(sum(count), 0)::BIGINT FROM record_blocks)",
            &[],
            OPERATION,
        )?;
        match rows.first() {
            Some(row) => row.try_get::<_, i64>(0).map(count_from).map_err(database(OPERATION)),
            None => Ok(0),
        }
    }

    fn append_locations(&mut self, rows: &[LocationRow]) -> Result<(), StoreError> {
        if rows.is_empty() {
            return Ok(());
        }
        let received_ms: Vec<i64> = rows.iter().map(|row| row.received_ms).collect();
        let times_s: Vec<f64> = rows.iter().map(|row| row.time_s).collect();
        let tags: Vec<&str> = rows.iter().map(|row| row.tag.as_str()).collect();
        let xs_m: Vec<f64> = rows.iter().map(|row| row.x_m).collect();
        let ys_m: Vec<f64> = rows.iter().map(|row| row.y_m).collect();
        let zs_m: Vec<Option<f64>> = rows.iter().map(|row| row.z_m).collect();
        let accuracies_m: Vec<Option<f64>> = rows.iter().map(|row| row.accuracy_m).collect();
        let predicted: Vec<bool> = rows.iter().map(|row| row.predicted).collect();
        let jsons: Vec<&str> = rows.iter().map(|row| row.json.as_str()).collect();
        self.execute(
            "INSERT INTO locations (received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json) \
             SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json \
             FROM UNNEST($1::BIGINT[], $2::DOUBLE PRECISION[], $3::TEXT[], $4::DOUBLE PRECISION[], \
                         $5::DOUBLE PRECISION[], $6::DOUBLE PRECISION[], $7::DOUBLE PRECISION[], $8::BOOLEAN[], \
                         $9::TEXT[]) \
                  WITH ORDINALITY AS batch (received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json, \
                                            ordinal) \
             ORDER BY ordinal",
            &[
                &received_ms,
                &times_s,
                &tags,
                &xs_m,
                &ys_m,
                &zs_m,
                &accuracies_m,
                &predicted,
                &jsons,
            ],
            "append locations",
        )
        .map(|_| ())
    }

    fn append_events(&mut self, rows: &[EventRow]) -> Result<(), StoreError> {
        if rows.is_empty() {
            return Ok(());
        }
        let received_ms: Vec<i64> = rows.iter().map(|row| row.received_ms).collect();
        let times_s: Vec<f64> = rows.iter().map(|row| row.time_s).collect();
        let kinds: Vec<&str> = rows.iter().map(|row| row.kind.as_str()).collect();
        let tags: Vec<Option<&str>> = rows.iter().map(|row| row.tag.as_deref()).collect();
        let zones: Vec<Option<&str>> = rows.iter().map(|row| row.zone.as_deref()).collect();
        let alarms: Vec<bool> = rows.iter().map(|row| row.alarm).collect();
        let jsons: Vec<&str> = rows.iter().map(|row| row.json.as_str()).collect();
        self.execute(
            "INSERT INTO events (received_ms, time_s, kind, tag, zone, alarm, json) \
             SELECT received_ms, time_s, kind, tag, zone, alarm, json \
             FROM UNNEST($1::BIGINT[], $2::DOUBLE PRECISION[], $3::TEXT[], $4::TEXT[], $5::TEXT[], $6::BOOLEAN[], \
                         $7::TEXT[]) \
                  WITH ORDINALITY AS batch (received_ms, time_s, kind, tag, zone, alarm, json, ordinal) \
             ORDER BY ordinal",
            &[&received_ms, &times_s, &kinds, &tags, &zones, &alarms, &jsons],
            "append events",
        )
        .map(|_| ())
    }

    fn history(&mut self, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError> {
        self.history_with_blocks(query)
    }

    fn events(&mut self, query: &EventQuery) -> Result<Vec<EventRow>, StoreError> {
        const OPERATION: &str = "events query";
        let limit = limit_from(query.limit);
        let mut parameters: Vec<&(dyn ToSql + Sync)> = vec![&query.from_s, &query.to_s];
        if let Some(tag) = &query.tag {
            parameters.push(tag);
        }
        if !query.kinds.is_empty() {
            parameters.push(&query.kinds);
        }
        parameters.push(&limit);
        let sql = events_sql(
            query.tag.is_some(),
            !query.kinds.is_empty(),
            query.alarms_only,
            query.newest_first,
        );
        let rows = self.query(&sql, &parameters, OPERATION)?;
        rows.iter()
            .map(event_from)
            .collect::<Result<_, _>>()
            .map_err(database(OPERATION))
    }

    fn put_config(&mut self, kind: &str, id: &str, json: &str) -> Result<bool, StoreError> {
        const OPERATION: &str = "put config";
        let fail = database(OPERATION);
        let insert = self.statement(
            "INSERT INTO config (kind, id, json) VALUES ($1, $2, $3) ON CONFLICT (kind, id) DO NOTHING",
            OPERATION,
        )?;
        let update = self.statement("UPDATE config SET json = $3 WHERE kind = $1 AND id = $2", OPERATION)?;
        let mut transaction = self.client.transaction().map_err(fail)?;
        let inserted = transaction.execute(&insert, &[&kind, &id, &json]).map_err(fail)?;
        if inserted == 0 {
            transaction.execute(&update, &[&kind, &id, &json]).map_err(fail)?;
        }
        transaction.commit().map_err(fail)?;
        Ok(inserted == 1)
    }

    fn get_config(&mut self, kind: &str, id: &str) -> Result<Option<String>, StoreError> {
        const OPERATION: &str = "get config";
        let rows = self.query(
            "SELECT json FROM config WHERE kind = $1 AND id = $2",
            &[&kind, &id],
            OPERATION,
        )?;
        rows.first()
            .map(|row| row.try_get(0))
            .transpose()
            .map_err(database(OPERATION))
    }

    fn list_config(&mut self, kind: &str) -> Result<Vec<(String, String)>, StoreError> {
        const OPERATION: &str = "list config";
        let rows = self.query(
            "SELECT id, json FROM config WHERE kind = $1 ORDER BY id",
            &[&kind],
            OPERATION,
        )?;
        rows.iter()
            .map(|row| Ok((row.try_get(0)?, row.try_get(1)?)))
            .collect::<Result<_, _>>()
            .map_err(database(OPERATION))
    }

    fn delete_config(&mut self, kind: &str, id: &str) -> Result<bool, StoreError> {
        self.execute(
            "DELETE FROM config WHERE kind = $1 AND id = $2",
            &[&kind, &id],
            "delete config",
        )
        .map(|deleted| deleted > 0)
    }

    fn checkpoint(&mut self, name: &str) -> Result<Option<i64>, StoreError> {
        const OPERATION: &str = "read checkpoint";
        let rows = self.query("SELECT value FROM checkpoints WHERE name = $1", &[&name], OPERATION)?;
        rows.first()
            .map(|row| row.try_get(0))
            .transpose()
            .map_err(database(OPERATION))
    }

    fn set_checkpoint(&mut self, name: &str, value: i64) -> Result<(), StoreError> {
        self.execute(
            "INSERT INTO checkpoints (name, value) VALUES ($1, $2) ON CONFLICT (name) DO UPDATE SET value = EXCLUDED.value",
            &[&name, &value],
            "set checkpoint",
        )
        .map(|_| ())
    }

    fn prune_ingest_log(&mut self, before_ms: i64, through_id: i64) -> Result<u64, StoreError> {
        const OPERATION: &str = "prune the ingest log";
        let fail = database(OPERATION);
        let statements = [
            self.statement(
                "SELECT coalesce(sum(count), 0)::BIGINT FROM record_blocks WHERE received_ms < $1 AND last_id <= $2",
                OPERATION,
            )?,
            self.statement(
                "DELETE FROM record_blocks WHERE received_ms < $1 AND last_id <= $2",
                OPERATION,
            )?,
            self.statement("DELETE FROM records WHERE received_ms < $1 AND id <= $2", OPERATION)?,
        ];
        let mut transaction = self.client.transaction().map_err(fail)?;
        let in_blocks: i64 = transaction
            .query_one(&statements[0], &[&before_ms, &through_id])
            .and_then(|row| row.try_get(0))
            .map_err(fail)?;
        transaction
            .execute(&statements[1], &[&before_ms, &through_id])
            .map_err(fail)?;
        let rows = transaction
            .execute(&statements[2], &[&before_ms, &through_id])
            .map_err(fail)?;
        transaction.commit().map_err(fail)?;
        Ok(count_from(in_blocks) + rows)
    }

    fn compact_history(&mut self, before_ms: i64, max_rows: usize) -> Result<u64, StoreError> {
        self.compact_history_blocks(before_ms, max_rows)
    }

    fn compact_ingest_log(&mut self, before_ms: i64, through_id: i64, max_rows: usize) -> Result<u64, StoreError> {
        self.compact_ingest_log_blocks(before_ms, through_id, max_rows)
    }

    fn prune(&mut self, before_ms: i64) -> Result<Pruned, StoreError> {
        const OPERATION: &str = "prune";
        let fail = database(OPERATION);
        let statements = [
            self.statement("DELETE FROM records WHERE received_ms < $1", OPERATION)?,
            self.statement("DELETE FROM locations WHERE received_ms < $1", OPERATION)?,
            self.statement("DELETE FROM events WHERE received_ms < $1", OPERATION)?,
        ];
        // blocks: their rows' counts, as what they packed
        let block_statements = [
            self.statement(
                "WITH gone AS (DELETE FROM record_blocks WHERE received_ms < $1 RETURNING count) \
                 SELECT coalesce(sum(count), 0)::BIGINT FROM gone",
                OPERATION,
            )?,
            self.statement(
                "WITH gone AS (DELETE FROM location_blocks WHERE received_ms < $1 RETURNING count) \
                 SELECT coalesce(sum(count), 0)::BIGINT FROM gone",
                OPERATION,
            )?,
        ];
        let mut transaction = self.client.transaction().map_err(fail)?;
        let mut deleted = [0_u64; 3];
        for (count, statement) in deleted.iter_mut().zip(&block_statements) {
            let packed: i64 = transaction
                .query_one(statement, &[&before_ms])
                .and_then(|row| row.try_get(0))
                .map_err(fail)?;
            *count = count_from(packed);
        }
        for (count, statement) in deleted.iter_mut().zip(&statements) {
            *count += transaction.execute(statement, &[&before_ms]).map_err(fail)?;
        }
        transaction.commit().map_err(fail)?;
        Ok(Pruned {
            records: deleted[0],
            locations: deleted[1],
            events: deleted[2],
        })
    }
}
