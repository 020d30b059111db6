-- rtls-server storage schema, version 1 (SQLite). Applied once by the migration runner
-- (src/store/migrations.rs) in a transaction of its own; never edit it after a release: add a
-- V2 instead. Times: time_s REAL seconds, received_ms INTEGER milliseconds since the Unix
-- epoch (server wall clock; retention prunes by it). AUTOINCREMENT: ids increase and are never
-- reused, even after the newest rows are pruned.

-- The ingest log: every accepted measurement record, the durability point of ingest.
CREATE TABLE records (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    received_ms INTEGER NOT NULL,
    source      TEXT    NOT NULL,
    time_s      REAL    NOT NULL,
    tag         TEXT    NOT NULL,
    json        TEXT    NOT NULL
) STRICT;
CREATE INDEX records_received_ms ON records (received_ms);

-- Track history: one row per reported track state.
CREATE TABLE locations (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    received_ms INTEGER NOT NULL,
    time_s      REAL    NOT NULL,
    tag         TEXT    NOT NULL,
    x_m         REAL    NOT NULL,
    y_m         REAL    NOT NULL,
    z_m         REAL,
    accuracy_m  REAL,
    predicted   INTEGER NOT NULL CHECK (predicted IN (0, 1)),
    json        TEXT    NOT NULL
) STRICT;
CREATE INDEX locations_tag_time_s ON locations (tag, time_s);
CREATE INDEX locations_received_ms ON locations (received_ms);

-- Events and alarms.
CREATE TABLE events (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    received_ms INTEGER NOT NULL,
    time_s      REAL    NOT NULL,
    kind        TEXT    NOT NULL,
    tag         TEXT,
    zone        TEXT,
    alarm       INTEGER NOT NULL CHECK (alarm IN (0, 1)),
    json        TEXT    NOT NULL
) STRICT;
CREATE INDEX events_time_s ON events (time_s);
CREATE INDEX events_tag_time_s ON events (tag, time_s);
CREATE INDEX events_received_ms ON events (received_ms);

-- Configuration objects (trackable, provider, zone, fence, site), kept until deleted.
CREATE TABLE config (
    kind TEXT NOT NULL,
    id   TEXT NOT NULL,
    json TEXT NOT NULL,
    PRIMARY KEY (kind, id)
) STRICT, WITHOUT ROWID;

-- Named counters (e.g. the last ingest-log id the tracker has processed).
CREATE TABLE checkpoints (
    name  TEXT    NOT NULL PRIMARY KEY,
    value INTEGER NOT NULL
) STRICT, WITHOUT ROWID;
