//! SQLite: the compacted blocks of the history and the ingest log (their formats:
//! [`super::super::history_blocks`], [`super::super::log_blocks`]) — packing rows into them and
//! reading them back with the rows.

use rusqlite::{params, Connection, TransactionBehavior};

use super::super::history_blocks::{self, HistoryCollector};
use super::super::log_blocks::{self, RecordCollector};
use super::super::{HistoryQuery, LocationRow, StoreError, StoredRecord};
use super::{database, limit_from};

/// A corrupt block, as a store error naming it.
fn corrupt(operation: &'static str, what: String) -> StoreError {
    StoreError::Database {
        backend: "sqlite",
        operation,
        reason: what,
    }
}

fn location_row(row: &rusqlite::Row<'_>, first: usize) -> rusqlite::Result<LocationRow> {
    Ok(LocationRow {
        received_ms: row.get(first)?,
        time_s: row.get(first + 1)?,
        tag: row.get(first + 2)?,
        x_m: row.get(first + 3)?,
        y_m: row.get(first + 4)?,
        z_m: row.get(first + 5)?,
        accuracy_m: row.get(first + 6)?,
        predicted: row.get(first + 7)?,
        json: row.get(first + 8)?,
    })
}

/// [`super::super::Store::compact_history`].
pub(super) fn compact_history(connection: &mut Connection, before_ms: i64, max_rows: usize) -> Result<u64, StoreError> {
    const OPERATION: &str = "compact the history";
    let fail = database(OPERATION);
    // Read and packed outside the write transaction, which then only inserts and deletes: the
    // pipeline's commits wait for that alone. Rows are never updated, and only this
    // connection deletes them, so what was read is still there.
    // The oldest rows by id: the same set is then deleted by one range statement.
    let rows: Vec<(i64, LocationRow)> = {
        let mut select = connection
            .prepare_cached(
                "SELECT id, received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json FROM locations \
                 WHERE received_ms < ?1 ORDER BY id LIMIT ?2",
            )
            .map_err(fail)?;
        let rows = select
            .query_map(params![before_ms, limit_from(max_rows)], |row| {
                Ok((row.get(0)?, location_row(row, 1)?))
            })
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)?
    };
    let packed = rows.len() as u64;
    let Some(last_id) = rows.iter().map(|(id, _)| *id).max() else {
        return Ok(0);
    };
    let blocks = history_blocks::pack(rows.into_iter().map(|(_, row)| row).collect());
    let transaction = connection
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(fail)?;
    {
        let mut insert = transaction
            .prepare_cached(
                "INSERT INTO location_blocks (tag, from_s, to_s, received_ms, count, payload) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            )
            .map_err(fail)?;
        for block in blocks {
            insert
                .execute(params![
                    block.tag,
                    block.from_s,
                    block.to_s,
                    block.received_ms,
                    block.count,
                    block.payload
                ])
                .map_err(fail)?;
        }
    }
    // exactly the rows read: older than the cut, up to the last id read
    transaction
        .prepare_cached("DELETE FROM locations WHERE received_ms < ?1 AND id <= ?2")
        .and_then(|mut delete| delete.execute(params![before_ms, last_id]))
        .map_err(fail)?;
    transaction.commit().map_err(fail)?;
    Ok(packed)
}

/// [`super::super::Store::compact_ingest_log`].
pub(super) fn compact_ingest_log(
    connection: &mut Connection,
    before_ms: i64,
    through_id: i64,
    max_rows: usize,
) -> Result<u64, StoreError> {
    const OPERATION: &str = "compact the ingest log";
    let fail = database(OPERATION);
    // read and packed outside the write transaction, as the history's
    let records: Vec<StoredRecord> = {
        let mut select = connection
            .prepare_cached(
                "SELECT id, received_ms, source, time_s, tag, json FROM records \
                 WHERE received_ms < ?1 AND id <= ?2 ORDER BY id LIMIT ?3",
            )
            .map_err(fail)?;
        let rows = select
            .query_map(params![before_ms, through_id, limit_from(max_rows)], stored_record)
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)?
    };
    if records.is_empty() {
        return Ok(0);
    }
    let blocks = log_blocks::pack(&records);
    let transaction = connection
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(fail)?;
    {
        let mut insert = transaction
            .prepare_cached(
                "INSERT INTO record_blocks (first_id, last_id, received_ms, count, payload) VALUES (?1, ?2, ?3, ?4, ?5)",
            )
            .map_err(fail)?;
        for block in blocks {
            insert
                .execute(params![
                    block.first_id,
                    block.last_id,
                    block.received_ms,
                    block.count,
                    block.payload
                ])
                .map_err(fail)?;
        }
    }
    // exactly the rows read: older than the cut, up to the last id read (≤ the checkpoint)
    let last_id = records.last().map_or(0, |record| record.id);
    transaction
        .prepare_cached("DELETE FROM records WHERE received_ms < ?1 AND id <= ?2")
        .and_then(|mut delete| delete.execute(params![before_ms, last_id]))
        .map_err(fail)?;
    transaction.commit().map_err(fail)?;
    Ok(records.len() as u64)
}

fn stored_record(row: &rusqlite::Row<'_>) -> rusqlite::Result<StoredRecord> {
    Ok(StoredRecord {
        id: row.get(0)?,
        received_ms: row.get(1)?,
        source: row.get(2)?,
        time_s: row.get(3)?,
        tag: row.get(4)?,
        json: row.get(5)?,
    })
}

/// [`super::super::Store::history`]: the rows, then the blocks that can hold earlier states.
pub(super) fn history(connection: &mut Connection, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError> {
    const OPERATION: &str = "history query";
    let fail = database(OPERATION);
    // one statement per shape, so each uses its index (tag, time_s) or (time_s)
    let sql = if query.tag.is_some() {
        "SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json FROM locations \
         WHERE tag = ?1 AND time_s >= ?2 AND time_s <= ?3 ORDER BY time_s, id LIMIT ?4"
    } else {
        "SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json FROM locations \
         WHERE ?1 IS NULL AND time_s >= ?2 AND time_s <= ?3 ORDER BY time_s, id LIMIT ?4"
    };
    let rows: Vec<LocationRow> = {
        let mut select = connection.prepare_cached(sql).map_err(fail)?;
        let rows = select
            .query_map(
                params![query.tag, query.from_s, query.to_s, limit_from(query.limit)],
                |row| location_row(row, 0),
            )
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)?
    };
    let mut collector = HistoryCollector::new(query, rows);
    let sql = if query.tag.is_some() {
        "SELECT id, tag, from_s, payload FROM location_blocks \
         WHERE tag = ?1 AND from_s >= ?2 AND from_s <= ?3 AND to_s >= ?4 ORDER BY from_s, id"
    } else {
        "SELECT id, tag, from_s, payload FROM location_blocks \
         WHERE ?1 IS NULL AND from_s >= ?2 AND from_s <= ?3 AND to_s >= ?4 ORDER BY from_s, id"
    };
    let mut select = connection.prepare_cached(sql).map_err(fail)?;
    let mut blocks = select
        .query(params![
            query.tag,
            collector.earliest_block_start_s(),
            query.to_s,
            query.from_s
        ])
        .map_err(fail)?;
    while let Some(block) = blocks.next().map_err(fail)? {
        let from_s: f64 = block.get(2).map_err(fail)?;
        if !collector.wants_block_from(from_s) {
            break;
        }
        let (id, tag): (i64, String) = (block.get(0).map_err(fail)?, block.get(1).map_err(fail)?);
        let payload: Vec<u8> = block.get(3).map_err(fail)?;
        collector
            .add_block(&tag, &payload)
            .map_err(|e| corrupt(OPERATION, format!("location block {id} (tag {tag}): {e}")))?;
    }
    Ok(collector.finish())
}

/// [`super::super::Store::records_after`]: the rows, then the blocks that can hold earlier ids.
pub(super) fn records_after(
    connection: &mut Connection,
    after_id: i64,
    limit: usize,
) -> Result<Vec<StoredRecord>, StoreError> {
    const OPERATION: &str = "read records";
    let fail = database(OPERATION);
    let rows: Vec<StoredRecord> = {
        let mut select = connection
            .prepare_cached(
                "SELECT id, received_ms, source, time_s, tag, json FROM records WHERE id > ?1 ORDER BY id LIMIT ?2",
            )
            .map_err(fail)?;
        let rows = select
            .query_map(params![after_id, limit_from(limit)], stored_record)
            .map_err(fail)?;
        rows.collect::<Result<_, _>>().map_err(fail)?
    };
    let mut collector = RecordCollector::new(after_id, limit, rows);
    let mut select = connection
        .prepare_cached("SELECT first_id, payload FROM record_blocks WHERE last_id > ?1 ORDER BY first_id")
        .map_err(fail)?;
    let mut blocks = select.query([after_id]).map_err(fail)?;
    while let Some(block) = blocks.next().map_err(fail)? {
        let first_id: i64 = block.get(0).map_err(fail)?;
        if !collector.wants_block_from(first_id) {
            break;
        }
        let payload: Vec<u8> = block.get(1).map_err(fail)?;
        collector
            .add_block(&payload)
            .map_err(|e| corrupt(OPERATION, format!("record block {first_id}: {e}")))?;
    }
    Ok(collector.finish())
}
