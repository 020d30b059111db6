-- rtls-server storage schema, version 1 (PostgreSQL). Applied once by the migration runner
-- (src/store/migrations.rs) in a transaction of its own; never edit it after a release: add a
-- V2 instead. Times: time_s DOUBLE PRECISION seconds, received_ms BIGINT milliseconds since
-- the Unix epoch (server wall clock; retention prunes by it). BIGSERIAL ids come from a
-- sequence: they increase and are never reused.

-- The ingest log: every accepted measurement record, the durability point of ingest.
CREATE TABLE records (
    id          BIGSERIAL        PRIMARY KEY,
    received_ms BIGINT           NOT NULL,
    source      TEXT             NOT NULL,
    time_s      DOUBLE PRECISION NOT NULL,
    tag         TEXT             NOT NULL,
    json        TEXT             NOT NULL
);
CREATE INDEX records_received_ms ON records (received_ms);

-- Track history: one row per reported track state.
CREATE TABLE locations (
    id          BIGSERIAL        PRIMARY KEY,
    received_ms BIGINT           NOT NULL,
    time_s      DOUBLE PRECISION NOT NULL,
    tag         TEXT             NOT NULL,
    x_m         DOUBLE PRECISION NOT NULL,
    y_m         DOUBLE PRECISION NOT NULL,
    z_m         DOUBLE PRECISION,
    accuracy_m  DOUBLE PRECISION,
    predicted   BOOLEAN          NOT NULL,
    json        TEXT             NOT NULL
);
CREATE INDEX locations_tag_time_s ON locations (tag, time_s);
CREATE INDEX locations_received_ms ON locations (received_ms);

-- Events and alarms.
CREATE TABLE events (
    id          BIGSERIAL        PRIMARY KEY,
    received_ms BIGINT           NOT NULL,
    time_s      DOUBLE PRECISION NOT NULL,
    kind        TEXT             NOT NULL,
    tag         TEXT,
    zone        TEXT,
    alarm       BOOLEAN          NOT NULL,
    json        TEXT             NOT NULL
);
CREATE INDEX events_time_s ON events (time_s);
CREATE INDEX events_tag_time_s ON events (tag, time_s);
CREATE INDEX events_received_ms ON events (received_ms);

-- Configuration objects (trackable, provider, zone, fence, site), kept until deleted.
-- COLLATE "C": ids list in byte order, as in SQLite, whatever the database's locale.
CREATE TABLE config (
    kind TEXT COLLATE "C" NOT NULL,
    id   TEXT COLLATE "C" NOT NULL,
    json TEXT NOT NULL,
    PRIMARY KEY (kind, id)
);

-- Named counters (e.g. the last ingest-log id the tracker has processed).
CREATE TABLE checkpoints (
    name  TEXT   NOT NULL PRIMARY KEY,
    value BIGINT NOT NULL
);
