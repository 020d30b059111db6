//! Versioned schema migrations, applied when a store is opened.
//!
//! Each back end has an ordered list of [`Migration`]s (SQL files under
//! `crates/rtls-server/migrations/{sqlite,postgres}/`, embedded in the binary). [`run`] records
//! every migration it applies in `schema_migrations(version, name, applied_ms)` and applies
//! each one, together with its row there, in a transaction of its own, so a failure leaves the
//! database at the previous version. Opening an up-to-date database applies nothing. A database
//! that records a version this build does not know (written by a newer rtls) is refused before
//! anything is changed, as is one whose history disagrees with this build's (a different
//! migration under the same version, or a gap).
//!
//! Why not the `refinery` crate: its 0.9 line (the last that accepts rusqlite 0.37; 0.10 needs
//! Rust 1.92) pulls OpenSSL (`native-tls`) in with its `postgres` driver, commits a migration
//! and its history row in separate transactions, and `expect`s on the history table's
//! contents. This runner is small and has none of those problems.

use std::time::{SystemTime, UNIX_EPOCH};

use super::StoreError;

/// One schema migration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Migration {
    /// Its version: 1, 2, 3, … in the order they are applied.
    pub version: u32,
    /// A short name, recorded with the version.
    pub name: &'static str,
    /// The SQL, one or more statements.
    pub sql: &'static str,
}

/// The SQLite schema's migrations, oldest first.
pub(crate) const SQLITE_MIGRATIONS: &[Migration] = &[
    Migration {
        version: 1,
        name: "initial",
        sql: include_str!("../../migrations/sqlite/V1__initial.sql"),
    },
    Migration {
        version: 2,
        name: "locations_by_time",
        sql: include_str!("../../migrations/sqlite/V2__locations_by_time.sql"),
    },
    Migration {
        version: 3,
        name: "compacted_blocks",
        sql: include_str!("../../migrations/sqlite/V3__compacted_blocks.sql"),
    },
];

/// The PostgreSQL schema's migrations, oldest first.
pub(crate) const POSTGRES_MIGRATIONS: &[Migration] = &[
    Migration {
        version: 1,
        name: "initial",
        sql: include_str!("../../migrations/postgres/V1__initial.sql"),
    },
    Migration {
        version: 2,
        name: "locations_by_time",
        sql: include_str!("../../migrations/postgres/V2__locations_by_time.sql"),
    },
    Migration {
        version: 3,
        name: "compacted_blocks",
        sql: include_str!("../../migrations/postgres/V3__compacted_blocks.sql"),
    },
];

/// A row of `schema_migrations`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct AppliedMigration {
    /// The migration's version.
    pub version: u32,
    /// Its name.
    pub name: String,
    /// When it was applied (ms since the Unix epoch).
    pub applied_ms: i64,
}

/// What the runner needs from a database connection.
pub(crate) trait MigrationTarget {
    /// Creates `schema_migrations` if it does not exist.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn ensure_history_table(&mut self) -> Result<(), StoreError>;

    /// The rows of `schema_migrations`, by version.
    ///
    /// # Errors
    /// [`StoreError::Database`].
    fn applied_migrations(&mut self) -> Result<Vec<AppliedMigration>, StoreError>;

    /// In one transaction: runs `migration.sql` and records it with `applied_ms`, unless its
    /// version is already recorded (another process applied it meanwhile). Returns whether it
    /// was applied.
    ///
    /// # Errors
    /// The database's error message; then nothing of the migration is kept.
    fn apply(&mut self, migration: &Migration, applied_ms: i64) -> Result<bool, String>;
}

/// Brings the database's schema up to the newest of `migrations` (sorted by version).
/// Returns the versions it applied (empty when the schema was up to date).
///
/// # Errors
/// [`StoreError::Migration`] when the database's schema is newer than `migrations` know, when
/// its history disagrees with them, or when a migration fails (then the earlier ones stay
/// applied and recorded); [`StoreError::Database`] when the history table cannot be read.
pub(crate) fn run(target: &mut impl MigrationTarget, migrations: &[Migration]) -> Result<Vec<u32>, StoreError> {
    target.ensure_history_table()?;
    let applied = target.applied_migrations()?;
    let newest_known = migrations.last().map_or(0, |migration| migration.version);

    if let Some(newest_applied) = applied.iter().max_by_key(|row| row.version) {
        if newest_applied.version > newest_known {
            return Err(StoreError::Migration {
                version: newest_applied.version,
                name: newest_applied.name.clone(),
                reason: format!(
                    "the database's schema is at version {}, newer than this build of rtls knows (up to \
                     version {newest_known}); run a newer rtls or use another database",
                    newest_applied.version
                ),
            });
        }
    }
    for row in &applied {
        let known = migrations.iter().find(|migration| migration.version == row.version);
        if let Some(known) = known.filter(|known| known.name != row.name) {
            return Err(StoreError::Migration {
                version: row.version,
                name: row.name.clone(),
                reason: format!(
                    "the database records migration {} as {:?} but this build's migration {} is {:?}: it \
                     was migrated by a different build of rtls",
                    row.version, row.name, known.version, known.name
                ),
            });
        }
    }
    let newest_applied = applied.iter().map(|row| row.version).max().unwrap_or(0);

    let mut applied_now = Vec::new();
    for migration in migrations {
        if applied.iter().any(|row| row.version == migration.version) {
            continue;
        }
        if migration.version < newest_applied {
            return Err(StoreError::Migration {
                version: migration.version,
                name: migration.name.to_owned(),
                reason: format!(
                    "not applied although the later version {newest_applied} is: the database's history \
                     has a gap, so it was not migrated by this build of rtls"
                ),
            });
        }
        let was_applied = target
            .apply(migration, now_ms())
            .map_err(|reason| StoreError::Migration {
                version: migration.version,
                name: migration.name.to_owned(),
                reason,
            })?;
        if was_applied {
            applied_now.push(migration.version);
        }
    }
    Ok(applied_now)
}

/// Wall-clock time (ms since the Unix epoch); 0 if the clock is set before 1970.
fn now_ms() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |since_epoch| {
        i64::try_from(since_epoch.as_millis()).unwrap_or(i64::MAX)
    })
}
