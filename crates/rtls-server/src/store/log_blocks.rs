//! The compacted ingest log: consecutive records packed into one compressed block.
//!
//! Records are appended as rows of `records` (the durability point of ingest). The compaction
//! pass ([`super::Store::compact_ingest_log`]) packs the rows older than
//! `server.compact_after_s` whose outputs are stored (id ≤ the output checkpoint) into
//! `record_blocks` of at most [`MAX_BLOCK_RECORDS`] and deletes the rows, in one transaction.
//! Nothing of a record changes: its id, server time, source, time, tag and JSON line come back
//! exactly.
//!
//! # Block format (version 1)
//! A format byte, then DEFLATE of: the record count, a string table (sources and tags), then
//! per record `Δid` (against the previous record; the first against 0), `Δreceived_ms`, the
//! time (f64), the source's and tag's string indexes and the JSON line.

use std::collections::HashMap;

use super::packing::{deflate, inflate, put_bytes, put_f64, put_signed, put_strings, put_varint, string_at, Reader};
use super::StoredRecord;

/// A block holds at most this many records.
pub(crate) const MAX_BLOCK_RECORDS: usize = 8192;
/// The payload's format byte.
const FORMAT: u8 = 1;

/// One block of `record_blocks`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RecordBlock {
    /// The first record's id.
    pub first_id: i64,
    /// The last record's id.
    pub last_id: i64,
    /// The newest record's server time (ms): retention deletes the block after it.
    pub received_ms: i64,
    /// Its number of records.
    pub count: i64,
    /// Format byte + DEFLATE stream.
    pub payload: Vec<u8>,
}

/// Packs records (in id order) into blocks of at most [`MAX_BLOCK_RECORDS`].
pub(crate) fn pack(records: &[StoredRecord]) -> Vec<RecordBlock> {
    records.chunks(MAX_BLOCK_RECORDS).map(encode_block).collect()
}

fn encode_block(records: &[StoredRecord]) -> RecordBlock {
    // the string table: each source and tag once, numbered in order of appearance
    let mut strings: Vec<&str> = Vec::new();
    let mut numbers: HashMap<&str, u64> = HashMap::new();
    for record in records {
        for text in [record.source.as_str(), record.tag.as_str()] {
            numbers.entry(text).or_insert_with(|| {
                strings.push(text);
                strings.len() as u64 - 1
            });
        }
    }
    let index = |text: &str| numbers.get(text).copied().unwrap_or(0);
    let mut fields = Vec::with_capacity(records.iter().map(|r| r.json.len() + 16).sum());
    put_varint(&mut fields, records.len() as u64);
    put_strings(&mut fields, &strings);
    let (mut previous_id, mut previous_ms) = (0i64, 0i64);
    for record in records {
        put_signed(&mut fields, record.id - previous_id);
        put_signed(&mut fields, record.received_ms - previous_ms);
        put_f64(&mut fields, record.time_s);
        put_varint(&mut fields, index(&record.source));
        put_varint(&mut fields, index(&record.tag));
        put_bytes(&mut fields, record.json.as_bytes());
        (previous_id, previous_ms) = (record.id, record.received_ms);
    }
    RecordBlock {
        first_id: records.first().map_or(0, |r| r.id),
        last_id: records.last().map_or(0, |r| r.id),
        received_ms: records.iter().map(|r| r.received_ms).max().unwrap_or(0),
        count: records.len() as i64,
        payload: deflate(FORMAT, &fields),
    }
}

/// Unpacks a block's records, in id order.
///
/// # Errors
/// A message naming what is corrupt.
pub(crate) fn decode_block(payload: &[u8]) -> Result<Vec<StoredRecord>, String> {
    let (format, fields) = inflate(payload)?;
    if format != FORMAT {
        return Err(format!("record block format {format} is not known to this build (1)"));
    }
    let mut reader = Reader::new(&fields);
    let count = usize::try_from(reader.varint()?).map_err(|_| "record count too large")?;
    if count > MAX_BLOCK_RECORDS * 16 {
        return Err(format!("{count} records in one block"));
    }
    let strings = reader.strings()?;
    let string = |reader: &mut Reader<'_>| -> Result<String, String> {
        string_at(&strings, reader.varint()?).map(str::to_owned)
    };
    let (mut id, mut received_ms) = (0i64, 0i64);
    let mut records = Vec::with_capacity(count);
    for _ in 0..count {
        id += reader.signed()?;
        received_ms += reader.signed()?;
        let time_s = reader.f64()?;
        let source = string(&mut reader)?;
        let tag = string(&mut reader)?;
        let json = reader.text()?.to_owned();
        records.push(StoredRecord {
            id,
            received_ms,
            source,
            time_s,
            tag,
            json,
        });
    }
    if !reader.is_empty() {
        return Err("bytes left after the last record".into());
    }
    Ok(records)
}

/// Merges a replay's records (the first `limit` after an id, in id order) from the row table
/// and from blocks read in order of their first id.
pub(crate) struct RecordCollector {
    after_id: i64,
    limit: usize,
    records: Vec<StoredRecord>,
    /// The `limit`-th smallest id when last sorted: no later block can enter once its first
    /// id is past it (it only falls as records are added, so a stale one reads more, never less).
    bound_id: Option<i64>,
}

impl RecordCollector {
    /// Starts with the rows of `records` after `after_id` (the first `limit` by id).
    pub(crate) fn new(after_id: i64, limit: usize, rows: Vec<StoredRecord>) -> Self {
        Self {
            after_id,
            limit,
            records: rows,
            bound_id: None,
        }
    }

    /// Whether a block whose first id is `first_id` (blocks come in order of it) can still
    /// enter the first `limit` records; `false`: stop reading blocks.
    pub(crate) fn wants_block_from(&mut self, first_id: i64) -> bool {
        if self.limit == 0 {
            return false;
        }
        // sorted when the limit is first reached, then only when twice as many are held
        let full = self.records.len() >= self.limit;
        if (full && self.bound_id.is_none()) || self.records.len() >= 2 * self.limit {
            self.sort_and_truncate();
            self.bound_id = self.records.last().map(|last| last.id);
        }
        self.bound_id.is_none_or(|bound| bound > first_id)
    }

    /// Adds a block's records after the id.
    ///
    /// # Errors
    /// The block does not decode.
    pub(crate) fn add_block(&mut self, payload: &[u8]) -> Result<(), String> {
        let after_id = self.after_id;
        self.records
            .extend(decode_block(payload)?.into_iter().filter(|record| record.id > after_id));
        Ok(())
    }

    fn sort_and_truncate(&mut self) {
        self.records.sort_by_key(|record| record.id);
        self.records.truncate(self.limit);
    }

    /// The first `limit` records after the id, in id order.
    pub(crate) fn finish(mut self) -> Vec<StoredRecord> {
        self.sort_and_truncate();
        self.records
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records(n: usize) -> Vec<StoredRecord> {
        (0..n)
            .map(|k| {
                let time_s = 1_795_697_830.853_307_2 + (k / 4) as f64;
                let tag = format!("miner-{:03}", k % 17);
                StoredRecord {
                    id: 1000 + 2 * k as i64,
                    received_ms: 1_795_697_831_000 + 250 * k as i64,
                    source: format!("mqtt:rtls/v1/measurements/gw-{}", k % 2),
                    time_s,
                    json: format!(
                        r#"{{"t":{time_s},"tag":"{tag}","kind":"rssi","anchor":"X-{:02}","rssi_dbm":{}}}"#,
                        k % 9,
                        -70.0 - (k as f64 * 0.731).sin() * 9.123_456_789
                    ),
                    tag,
                }
            })
            .collect()
    }

    #[test]
    fn records_come_back_exactly_and_smaller() {
        let originals = records(MAX_BLOCK_RECORDS + 5);
        let blocks = pack(&originals);
        assert_eq!(blocks.len(), 2);
        assert_eq!(
            (blocks[0].first_id, blocks[1].last_id),
            (1000, originals.last().unwrap().id)
        );
        assert_eq!(blocks[0].count as usize, MAX_BLOCK_RECORDS);
        let mut read = Vec::new();
        for block in &blocks {
            read.extend(decode_block(&block.payload).unwrap());
        }
        assert_eq!(read, originals);
        let json: usize = originals.iter().map(|r| r.json.len()).sum();
        let packed: usize = blocks.iter().map(|b| b.payload.len()).sum();
        assert!(packed * 3 < json, "{packed} bytes packed for {json} bytes of JSON");
    }

    #[test]
    fn the_collector_merges_rows_and_blocks_by_id_and_stops_early() {
        let all = records(40);
        // ids 1000, 1002, …: the first 30 in two blocks, one of them (1010) still a row
        let mut packed: Vec<StoredRecord> = all[..30].to_vec();
        let row = packed.remove(5);
        let blocks = [pack(&packed[..15]).remove(0), pack(&packed[15..]).remove(0)];
        let mut rows = vec![row];
        rows.extend_from_slice(&all[30..]);
        let mut collector = RecordCollector::new(1003, 6, rows);
        assert!(collector.wants_block_from(blocks[0].first_id));
        collector.add_block(&blocks[0].payload).unwrap();
        assert!(
            !collector.wants_block_from(blocks[1].first_id),
            "six records before it are in hand"
        );
        let ids: Vec<i64> = collector.finish().iter().map(|r| r.id).collect();
        assert_eq!(ids, [1004, 1006, 1008, 1010, 1012, 1014]);
    }

    #[test]
    fn a_corrupt_or_foreign_block_is_an_error() {
        let block = &pack(&records(50))[0];
        assert!(decode_block(&block.payload[..block.payload.len() - 3]).is_err());
        let mut foreign = block.payload.clone();
        foreign[0] = 2;
        assert!(decode_block(&foreign).unwrap_err().contains("format 2"));
    }
}
