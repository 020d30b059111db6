//! Back-end-specific tests: SQLite durability, WAL and `synchronous`; schema migrations on
//! both back ends (idempotent, newer schema refused, failed migration rolled back); database
//! URLs.

use rusqlite::Connection;

use super::super::migrations::{
    self, AppliedMigration, Migration, MigrationTarget, POSTGRES_MIGRATIONS, SQLITE_MIGRATIONS,
};
use super::super::{
    open, parse_url, DatabaseUrl, EventQuery, HistoryQuery, PostgresStore, SqliteStore, SqliteSync, Store, StoreError,
};
use super::harness::{event, location, record, PgSchema, TempDb};

fn sqlite_history(connection: &mut Connection) -> Vec<AppliedMigration> {
    connection.applied_migrations().expect("read schema_migrations")
}

#[test]
fn sqlite_file_keeps_everything_across_close_and_reopen() {
    let file = TempDb::new("reopen");
    let mut store = file.open();
    let ids = store
        .append_records(&[record(1_000, 1.0, "t", "a"), record(1_001, 2.0, "t", "b")])
        .unwrap();
    store.append_locations(&[location(1_000, 1.0, "t")]).unwrap();
    store
        .append_events(&[event(1_000, 1.0, "zone-enter", Some("t"), false)])
        .unwrap();
    store.put_config("zone", "z1", r#"{"id":"z1"}"#).unwrap();
    store.set_checkpoint("tracker", ids[1]).unwrap();
    store.close().unwrap();

    let mut reopened = file.open();
    let stored = reopened.records_after(0, 10).unwrap();
    assert_eq!(stored.iter().map(|r| r.id).collect::<Vec<_>>(), ids);
    assert_eq!(stored[1].json, record(1_001, 2.0, "t", "b").json);
    let history = reopened
        .history(&HistoryQuery {
            tag: Some("t".into()),
            from_s: 0.0,
            to_s: 5.0,
            limit: 5,
        })
        .unwrap();
    assert_eq!(history, [location(1_000, 1.0, "t")]);
    let events = reopened
        .events(&EventQuery {
            from_s: 0.0,
            to_s: 5.0,
            limit: 5,
            ..Default::default()
        })
        .unwrap();
    assert_eq!(events, [event(1_000, 1.0, "zone-enter", Some("t"), false)]);
    assert_eq!(
        reopened.get_config("zone", "z1").unwrap().as_deref(),
        Some(r#"{"id":"z1"}"#)
    );
    assert_eq!(reopened.checkpoint("tracker").unwrap(), Some(ids[1]));
    let next = reopened.append_records(&[record(2_000, 3.0, "t", "c")]).unwrap();
    assert!(next[0] > ids[1], "ids continue after reopening");
}

#[test]
fn sqlite_hands_inserted_records_over_before_other_connections_see_them() {
    let file = TempDb::new("handover");
    let mut writer = file.open();
    let mut reader = file.open();
    let mut count_meanwhile = None;
    writer
        .append_records_then_commit(&[record(1_000, 1.0, "tag-1", "a")], &mut |_| {
            count_meanwhile = Some(reader.record_count().expect("count"));
        })
        .expect("append");
    assert_eq!(count_meanwhile, Some(0), "not committed yet while handed over");
    assert_eq!(reader.record_count().expect("count"), 1);
}

#[test]
fn sqlite_file_uses_the_wal_journal() {
    let file = TempDb::new("wal");
    let mut store = file.open();
    assert_eq!(store.journal_mode().unwrap(), "wal");
    store.append_records(&[record(1_000, 1.0, "t", "a")]).unwrap();
    assert!(
        file.sibling("-wal").exists(),
        "the write-ahead log file exists while the database is open"
    );
    // WAL is a property of the file: another connection sees it too.
    let other = Connection::open(&file.path).unwrap();
    let mode: String = other.query_row("PRAGMA journal_mode", [], |row| row.get(0)).unwrap();
    assert_eq!(mode, "wal");

    let memory = SqliteStore::open_in_memory().unwrap();
    assert_eq!(memory.journal_mode().unwrap(), "memory");
    assert_eq!(memory.path(), None);
    assert_eq!(store.path(), Some(file.path.as_path()));
}

#[test]
fn sqlite_synchronous_follows_the_option_and_foreign_keys_are_on() {
    for (sync, expected) in [(SqliteSync::Full, 2), (SqliteSync::Normal, 1)] {
        let file = TempDb::new("sync");
        let mut store = SqliteStore::open(&file.path, sync).unwrap();
        let synchronous: i64 = store
            .connection()
            .query_row("PRAGMA synchronous", [], |row| row.get(0))
            .unwrap();
        assert_eq!(synchronous, expected, "{sync:?}");
        let foreign_keys: i64 = store
            .connection()
            .query_row("PRAGMA foreign_keys", [], |row| row.get(0))
            .unwrap();
        assert_eq!(foreign_keys, 1);
    }
    assert_eq!(SqliteSync::default(), SqliteSync::Full);
}

#[test]
fn sqlite_unopenable_file_is_a_database_error_naming_the_path() {
    let file = TempDb::new("missing_dir");
    let path = file.path.join("no").join("such.db");
    let error = SqliteStore::open(&path, SqliteSync::Full).unwrap_err();
    assert!(
        matches!(
            error,
            StoreError::Database {
                backend: "sqlite",
                operation: "open",
                ..
            }
        ),
        "{error:?}"
    );
    assert!(error.to_string().contains(&path.display().to_string()), "{error}");
}

#[test]
fn sqlite_migrations_are_applied_once() {
    let file = TempDb::new("migrations");
    let mut store = file.open();
    let first = sqlite_history(store.connection());
    let versions: Vec<u32> = first.iter().map(|row| row.version).collect();
    let known: Vec<u32> = SQLITE_MIGRATIONS.iter().map(|migration| migration.version).collect();
    assert_eq!(versions, known);
    assert!(first.iter().all(|row| row.applied_ms > 1_600_000_000_000), "{first:?}");
    store.append_records(&[record(1_000, 1.0, "t", "a")]).unwrap();
    drop(store);

    let mut reopened = file.open();
    assert_eq!(
        sqlite_history(reopened.connection()),
        first,
        "reopening applies nothing"
    );
    assert!(migrations::run(reopened.connection(), SQLITE_MIGRATIONS)
        .unwrap()
        .is_empty());
    assert_eq!(reopened.record_count().unwrap(), 1, "the data is untouched");
}

#[test]
fn sqlite_newer_schema_is_refused() {
    let file = TempDb::new("newer");
    drop(file.open());
    let future = SQLITE_MIGRATIONS.last().map_or(0, |migration| migration.version) + 1;
    let connection = Connection::open(&file.path).unwrap();
    connection
        .execute(
            "INSERT INTO schema_migrations (version, name, applied_ms) VALUES (?1, 'from the future', 0)",
            [future],
        )
        .unwrap();
    drop(connection);

    let error = SqliteStore::open(&file.path, SqliteSync::Full).unwrap_err();
    match &error {
        StoreError::Migration { version, name, reason } => {
            assert_eq!((*version, name.as_str()), (future, "from the future"));
            assert!(reason.contains("newer than this build"), "{reason}");
        }
        other => panic!("expected a migration error, got {other:?}"),
    }
}

/// V1 and V2 of a toy schema; V2 fails halfway unless `fixed`.
fn toy_migrations(fixed: bool) -> [Migration; 2] {
    [
        Migration {
            version: 1,
            name: "first",
            sql: "CREATE TABLE first (x INTEGER);",
        },
        Migration {
            version: 2,
            name: "second",
            sql: if fixed {
                "CREATE TABLE second (y INTEGER); INSERT INTO first VALUES (2);"
            } else {
                "CREATE TABLE second (y INTEGER); INSERT INTO no_such_table VALUES (2);"
            },
        },
    ]
}

fn table_exists(connection: &Connection, table: &str) -> bool {
    connection
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
            [table],
            |row| row.get::<_, i64>(0),
        )
        .unwrap()
        == 1
}

#[test]
fn failed_migration_is_rolled_back_and_not_recorded() {
    let mut connection = Connection::open_in_memory().unwrap();
    let error = migrations::run(&mut connection, &toy_migrations(false)).unwrap_err();
    match &error {
        StoreError::Migration { version, name, reason } => {
            assert_eq!((*version, name.as_str()), (2, "second"));
            assert!(reason.contains("no_such_table"), "{reason}");
        }
        other => panic!("expected a migration error, got {other:?}"),
    }
    assert!(table_exists(&connection, "first"), "V1 stays applied");
    assert!(
        !table_exists(&connection, "second"),
        "V2's first statement was rolled back"
    );
    let versions: Vec<u32> = sqlite_history(&mut connection).iter().map(|row| row.version).collect();
    assert_eq!(versions, [1]);

    assert_eq!(migrations::run(&mut connection, &toy_migrations(true)).unwrap(), [2]);
    assert!(table_exists(&connection, "second"));
    assert!(migrations::run(&mut connection, &toy_migrations(true))
        .unwrap()
        .is_empty());
}

#[test]
fn history_that_disagrees_with_this_build_is_refused() {
    // A different migration under a known version.
    let mut connection = Connection::open_in_memory().unwrap();
    migrations::run(&mut connection, &toy_migrations(true)[..1]).unwrap();
    let renamed = [Migration {
        version: 1,
        name: "other",
        sql: "CREATE TABLE other (z INTEGER);",
    }];
    let error = migrations::run(&mut connection, &renamed).unwrap_err();
    assert!(
        matches!(&error, StoreError::Migration { version: 1, name, reason } if name == "first" && reason.contains("different build")),
        "{error:?}"
    );
    assert!(!table_exists(&connection, "other"));

    // A gap: V2 recorded, V1 not.
    let mut gapped = Connection::open_in_memory().unwrap();
    migrations::run(&mut gapped, &toy_migrations(true)[..0]).unwrap();
    gapped
        .execute_batch("INSERT INTO schema_migrations VALUES (2, 'second', 0)")
        .unwrap();
    let error = migrations::run(&mut gapped, &toy_migrations(true)).unwrap_err();
    assert!(matches!(&error, StoreError::Migration { version: 1, .. }), "{error:?}");
    assert!(!table_exists(&gapped, "first"));
}

#[test]
fn postgres_migrations_are_applied_once_and_newer_schema_is_refused() {
    let Some(schema) = PgSchema::new() else { return };
    let mut store = schema.open();
    let first = store.client_mut().applied_migrations().unwrap();
    let versions: Vec<u32> = first.iter().map(|row| row.version).collect();
    let known: Vec<u32> = POSTGRES_MIGRATIONS.iter().map(|migration| migration.version).collect();
    assert_eq!(versions, known);
    store.set_checkpoint("tracker", 3).unwrap();
    store.close().unwrap();

    let mut reopened = schema.open();
    assert_eq!(
        reopened.client_mut().applied_migrations().unwrap(),
        first,
        "reopening applies nothing"
    );
    assert!(migrations::run(reopened.client_mut(), POSTGRES_MIGRATIONS)
        .unwrap()
        .is_empty());
    assert_eq!(reopened.checkpoint("tracker").unwrap(), Some(3));

    let future = i32::try_from(known.last().copied().unwrap_or(0) + 1).unwrap();
    reopened
        .client_mut()
        .execute(
            "INSERT INTO schema_migrations (version, name, applied_ms) VALUES ($1, 'from the future', 0)",
            &[&future],
        )
        .unwrap();
    drop(reopened);
    let error = PostgresStore::connect_in_schema(&schema.url, &schema.schema).unwrap_err();
    assert!(
        matches!(&error, StoreError::Migration { version, name, reason }
            if i64::from(*version) == i64::from(future) && name == "from the future" && reason.contains("newer")),
        "{error:?}"
    );
}

#[test]
fn postgres_unreachable_server_is_a_database_error_without_the_password() {
    let url = "postgres://rtls:secret@127.0.0.1:1/rtls_test?connect_timeout=5";
    let error = PostgresStore::connect(url).unwrap_err();
    assert!(
        matches!(
            error,
            StoreError::Database {
                backend: "postgres",
                operation: "connect",
                ..
            }
        ),
        "{error:?}"
    );
    let message = error.to_string();
    assert!(
        message.contains("postgres://rtls:***@127.0.0.1:1/rtls_test"),
        "{message}"
    );
    assert!(!message.contains("secret"), "{message}");
}

#[test]
fn urls_name_the_back_end() {
    assert_eq!(
        parse_url("sqlite:/var/lib/rtls/rtls.db").unwrap(),
        DatabaseUrl::Sqlite("/var/lib/rtls/rtls.db")
    );
    assert_eq!(
        parse_url("sqlite:///var/lib/rtls/rtls.db").unwrap(),
        DatabaseUrl::Sqlite("/var/lib/rtls/rtls.db")
    );
    assert_eq!(
        parse_url("sqlite://data/rtls.db").unwrap(),
        DatabaseUrl::Sqlite("data/rtls.db")
    );
    assert_eq!(parse_url("sqlite:rtls.db").unwrap(), DatabaseUrl::Sqlite("rtls.db"));
    assert_eq!(parse_url("data/rtls.db").unwrap(), DatabaseUrl::Sqlite("data/rtls.db"));
    assert_eq!(parse_url("/tmp/a:b.db").unwrap(), DatabaseUrl::Sqlite("/tmp/a:b.db"));
    assert_eq!(
        parse_url(r"C:\rtls\rtls.db").unwrap(),
        DatabaseUrl::Sqlite(r"C:\rtls\rtls.db")
    );
    assert_eq!(parse_url("sqlite::memory:").unwrap(), DatabaseUrl::Sqlite(":memory:"));
    assert_eq!(parse_url("postgres://rtls@db/rtls").unwrap(), DatabaseUrl::Postgres);
    assert_eq!(parse_url("postgresql://rtls@db/rtls").unwrap(), DatabaseUrl::Postgres);
}

#[test]
fn bad_urls_are_refused_naming_the_url_and_the_accepted_forms() {
    for url in [
        "mysql://db.example/rtls",
        "http://localhost/rtls.db",
        "sqlite:",
        "sqlite://",
        "",
        "redis:rtls",
    ] {
        let error = open(url, SqliteSync::Full).map(|store| store.backend()).unwrap_err();
        match &error {
            StoreError::Url { url: named, reason } => {
                assert_eq!(named, url);
                assert!(
                    reason.contains("sqlite:PATH") && reason.contains("postgres://"),
                    "{reason}"
                );
            }
            other => panic!("{url:?}: expected a URL error, got {other:?}"),
        }
        assert!(error.to_string().contains(&format!("{url:?}")), "{error}");
    }
    let error = open("mysql://rtls:secret@db.example:3306/rtls", SqliteSync::Full)
        .map(|_| ())
        .unwrap_err();
    let message = error.to_string();
    assert!(
        message.contains("mysql://rtls:***@db.example:3306/rtls") && !message.contains("secret"),
        "{message}"
    );
    // A PostgreSQL URL the client cannot parse is a URL error too.
    let error = PostgresStore::connect("postgres://rtls@db.example:notaport/rtls").unwrap_err();
    assert!(matches!(error, StoreError::Url { .. }), "{error:?}");
}

#[test]
fn open_reaches_the_same_sqlite_file_through_every_url_form() {
    let file = TempDb::new("open_forms");
    let path = file.path.display().to_string();
    let mut first = open(&format!("sqlite:{path}"), SqliteSync::Normal).unwrap();
    assert_eq!(first.backend(), "sqlite");
    first.set_checkpoint("written", 1).unwrap();
    drop(first);
    for url in [format!("sqlite://{path}"), path.clone()] {
        let mut store = open(&url, SqliteSync::Full).unwrap();
        assert_eq!(store.checkpoint("written").unwrap(), Some(1), "{url}");
    }
    let mut memory = open("sqlite::memory:", SqliteSync::Full).unwrap();
    assert_eq!(
        memory.checkpoint("written").unwrap(),
        None,
        "in memory is a database of its own"
    );
    assert!(!std::path::Path::new(":memory:").exists());
}

#[test]
fn open_connects_to_postgres_urls() {
    let Some(schema) = PgSchema::new() else { return };
    // `open` hands the URL to the client as it is; the URL's `options` select the test's own
    // schema (created by `schema.open()`) so nothing lands in the shared default schema.
    drop(schema.open());
    let url = format!(
        "{}{}options=-c%20search_path%3D{}",
        schema.url,
        if schema.url.contains('?') { '&' } else { '?' },
        schema.schema
    );
    let mut store = open(&url, SqliteSync::Full).unwrap();
    assert_eq!(store.backend(), "postgres");
    store.set_checkpoint("via-open", 9).unwrap();
    assert_eq!(
        schema.open().checkpoint("via-open").unwrap(),
        Some(9),
        "it wrote into the test's schema"
    );
}
