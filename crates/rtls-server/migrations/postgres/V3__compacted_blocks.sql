-- Compacted history and ingest log (src/store/history_blocks.rs, src/store/log_blocks.rs):
-- rows older than `server.compact_after_s` are packed into DEFLATE-compressed blocks and
-- deleted from `locations` / `records` in the same transaction. Queries read both.

-- One tag's consecutive track states (at most an hour, 4 096 states).
CREATE TABLE location_blocks (
    id          BIGSERIAL        PRIMARY KEY,
    tag         TEXT             NOT NULL,
    from_s      DOUBLE PRECISION NOT NULL,
    to_s        DOUBLE PRECISION NOT NULL,
    received_ms BIGINT           NOT NULL,
    count       BIGINT           NOT NULL,
    payload     BYTEA            NOT NULL
);
-- already compressed: TOAST stores it out of line without trying to compress it again
ALTER TABLE location_blocks ALTER COLUMN payload SET STORAGE EXTERNAL;
CREATE INDEX location_blocks_tag_from_s ON location_blocks (tag, from_s);
CREATE INDEX location_blocks_from_s ON location_blocks (from_s);
CREATE INDEX location_blocks_received_ms ON location_blocks (received_ms);

-- Consecutive ingest-log records behind the output checkpoint (ids first_id..=last_id, with
-- the ids of records still in `records` possibly between them).
CREATE TABLE record_blocks (
    first_id    BIGINT PRIMARY KEY,
    last_id     BIGINT NOT NULL,
    received_ms BIGINT NOT NULL,
    count       BIGINT NOT NULL,
    payload     BYTEA  NOT NULL
);
ALTER TABLE record_blocks ALTER COLUMN payload SET STORAGE EXTERNAL;
CREATE INDEX record_blocks_last_id ON record_blocks (last_id);
CREATE INDEX record_blocks_received_ms ON record_blocks (received_ms);

-- The row tables now hold only the last minutes: compaction reads them oldest first by id and
-- retention scans them, so an index by server time costs every insert and serves nothing.
DROP INDEX locations_received_ms;
DROP INDEX records_received_ms;
