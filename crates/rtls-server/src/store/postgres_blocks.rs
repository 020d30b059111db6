//! PostgreSQL: the compacted blocks of the history and the ingest log (their formats:
//! [`super::super::history_blocks`], [`super::super::log_blocks`]) — packing rows into them and
//! reading them back with the rows.

use ::postgres::fallible_iterator::FallibleIterator;
use ::postgres::types::ToSql;

use super::super::history_blocks::{self, HistoryCollector};
use super::super::log_blocks::{self, RecordCollector};
use super::super::{HistoryQuery, LocationRow, StoreError, StoredRecord};
use super::{database, limit_from, location_from, PostgresStore};

/// A corrupt block, as a store error naming it.
fn corrupt(operation: &'static str, what: String) -> StoreError {
    StoreError::Database {
        backend: "postgres",
        operation,
        reason: what,
    }
}

fn stored_record(row: &::postgres::Row) -> Result<StoredRecord, ::postgres::Error> {
    Ok(StoredRecord {
        id: row.try_get(0)?,
        received_ms: row.try_get(1)?,
        source: row.try_get(2)?,
        time_s: row.try_get(3)?,
        tag: row.try_get(4)?,
        json: row.try_get(5)?,
    })
}

impl PostgresStore {
    /// [`super::super::Store::compact_history`].
    pub(super) fn compact_history_blocks(&mut self, before_ms: i64, max_rows: usize) -> Result<u64, StoreError> {
        const OPERATION: &str = "compact the history";
        let fail = database(OPERATION);
        let select = self.statement(
            "SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json, id FROM locations \
             WHERE received_ms < $1 ORDER BY id LIMIT $2",
            OPERATION,
        )?;
        let insert = self.statement(
            "INSERT INTO location_blocks (tag, from_s, to_s, received_ms, count, payload) \
             VALUES ($1, $2, $3, $4, $5, $6)",
            OPERATION,
        )?;
        // exactly the rows read: older than the cut, up to the last id read
        let delete = self.statement("DELETE FROM locations WHERE received_ms < $1 AND id <= $2", OPERATION)?;
        let mut transaction = self.client.transaction().map_err(fail)?;
        let rows = transaction
            .query(&select, &[&before_ms, &limit_from(max_rows)])
            .map_err(fail)?;
        // the state's columns as `location_from` reads them, then its id
        let rows: Vec<(i64, LocationRow)> = rows
            .iter()
            .map(|row| Ok((row.try_get(9)?, location_from(row)?)))
            .collect::<Result<_, ::postgres::Error>>()
            .map_err(fail)?;
        let packed = rows.len() as u64;
        let Some(last_id) = rows.iter().map(|(id, _)| *id).max() else {
            return Ok(0);
        };
        for block in history_blocks::pack(rows.into_iter().map(|(_, row)| row).collect()) {
            transaction
                .execute(
                    &insert,
                    &[
                        &block.tag,
                        &block.from_s,
                        &block.to_s,
                        &block.received_ms,
                        &block.count,
                        &block.payload,
                    ],
                )
                .map_err(fail)?;
        }
        transaction.execute(&delete, &[&before_ms, &last_id]).map_err(fail)?;
        transaction.commit().map_err(fail)?;
        Ok(packed)
    }

    /// [`super::super::Store::compact_ingest_log`].
    pub(super) fn compact_ingest_log_blocks(
        &mut self,
        before_ms: i64,
        through_id: i64,
        max_rows: usize,
    ) -> Result<u64, StoreError> {
        const OPERATION: &str = "compact the ingest log";
        let fail = database(OPERATION);
        let select = self.statement(
            "SELECT id, received_ms, source, time_s, tag, json FROM records \
             WHERE received_ms < $1 AND id <= $2 ORDER BY id LIMIT $3",
            OPERATION,
        )?;
        let insert = self.statement(
            "INSERT INTO record_blocks (first_id, last_id, received_ms, count, payload) VALUES ($1, $2, $3, $4, $5)",
            OPERATION,
        )?;
        // exactly the rows read: older than the cut, up to the last id read (≤ the checkpoint)
        let delete = self.statement("DELETE FROM records WHERE received_ms < $1 AND id <= $2", OPERATION)?;
        let mut transaction = self.client.transaction().map_err(fail)?;
        let records: Vec<StoredRecord> = transaction
            .query(&select, &[&before_ms, &through_id, &limit_from(max_rows)])
            .map_err(fail)?
            .iter()
            .map(stored_record)
            .collect::<Result<_, _>>()
            .map_err(fail)?;
        if records.is_empty() {
            return Ok(0);
        }
        for block in log_blocks::pack(&records) {
            transaction
                .execute(
                    &insert,
                    &[
                        &block.first_id,
                        &block.last_id,
                        &block.received_ms,
                        &block.count,
                        &block.payload,
                    ],
                )
                .map_err(fail)?;
        }
        let last_id = records.last().map_or(0, |record| record.id);
        transaction.execute(&delete, &[&before_ms, &last_id]).map_err(fail)?;
        transaction.commit().map_err(fail)?;
        Ok(records.len() as u64)
    }

    /// [`super::super::Store::history`]: the rows, then the blocks that can hold earlier states.
    pub(super) fn history_with_blocks(&mut self, query: &HistoryQuery) -> Result<Vec<LocationRow>, StoreError> {
        const OPERATION: &str = "history query";
        let fail = database(OPERATION);
        let limit = limit_from(query.limit);
        let rows = match &query.tag {
            Some(tag) => self.query(
                "SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json FROM locations \
                 WHERE tag = $1 AND time_s >= $2 AND time_s <= $3 ORDER BY time_s, id LIMIT $4",
                &[tag, &query.from_s, &query.to_s, &limit],
                OPERATION,
            )?,
            None => self.query(
                "SELECT received_ms, time_s, tag, x_m, y_m, z_m, accuracy_m, predicted, json FROM locations \
                 WHERE time_s >= $1 AND time_s <= $2 ORDER BY time_s, id LIMIT $3",
                &[&query.from_s, &query.to_s, &limit],
                OPERATION,
            )?,
        };
        let rows = rows.iter().map(location_from).collect::<Result<_, _>>().map_err(fail)?;
        let mut collector = HistoryCollector::new(query, rows);
        let earliest_s = collector.earliest_block_start_s();
        let (sql, parameters): (&str, Vec<&(dyn ToSql + Sync)>) = match &query.tag {
            Some(tag) => (
                "SELECT id, tag, from_s, payload FROM location_blocks \
                 WHERE tag = $1 AND from_s >= $2 AND from_s <= $3 AND to_s >= $4 ORDER BY from_s, id",
                vec![tag, &earliest_s, &query.to_s, &query.from_s],
            ),
            None => (
                "SELECT id, tag, from_s, payload FROM location_blocks \
                 WHERE from_s >= $1 AND from_s <= $2 AND to_s >= $3 ORDER BY from_s, id",
                vec![&earliest_s, &query.to_s, &query.from_s],
            ),
        };
        let statement = self.statement(sql, OPERATION)?;
        // streamed: the blocks after the first `limit` states are never fetched
        let mut blocks = self.client.query_raw(&statement, parameters).map_err(fail)?;
        while let Some(block) = blocks.next().map_err(fail)? {
            let from_s: f64 = block.try_get(2).map_err(fail)?;
            if !collector.wants_block_from(from_s) {
                break;
            }
            let id: i64 = block.try_get(0).map_err(fail)?;
            let tag: String = block.try_get(1).map_err(fail)?;
            let payload: &[u8] = block.try_get(3).map_err(fail)?;
            collector
                .add_block(&tag, payload)
                .map_err(|e| corrupt(OPERATION, format!("location block {id} (tag {tag}): {e}")))?;
        }
        Ok(collector.finish())
    }

    /// [`super::super::Store::records_after`]: the rows, then the blocks that can hold earlier
    /// ids.
    pub(super) fn records_after_with_blocks(
        &mut self,
        after_id: i64,
        limit: usize,
    ) -> Result<Vec<StoredRecord>, StoreError> {
        const OPERATION: &str = "read records";
        let fail = database(OPERATION);
        let rows = self
            .query(
                "SELECT id, received_ms, source, time_s, tag, json FROM records WHERE id > $1 ORDER BY id LIMIT $2",
                &[&after_id, &limit_from(limit)],
                OPERATION,
            )?
            .iter()
            .map(stored_record)
            .collect::<Result<_, _>>()
            .map_err(fail)?;
        let mut collector = RecordCollector::new(after_id, limit, rows);
        let statement = self.statement(
            "SELECT first_id, payload FROM record_blocks WHERE last_id > $1 ORDER BY first_id",
            OPERATION,
        )?;
        let parameters: [&(dyn ToSql + Sync); 1] = [&after_id];
        let mut blocks = self.client.query_raw(&statement, parameters).map_err(fail)?;
        while let Some(block) = blocks.next().map_err(fail)? {
            let first_id: i64 = block.try_get(0).map_err(fail)?;
            if !collector.wants_block_from(first_id) {
                break;
            }
            let payload: &[u8] = block.try_get(1).map_err(fail)?;
            collector
                .add_block(payload)
                .map_err(|e| corrupt(OPERATION, format!("record block {first_id}: {e}")))?;
        }
        Ok(collector.finish())
    }
}
