//! Quarantine: a record that makes its partition's tracker fail (an error, or a panic — a bug
//! the record exposes) costs that record only. The partition logs it, counts it
//! (`rtls_records_quarantined_total`), publishes a `record-quarantined` event and moves on; the
//! output thread stores it apart (the store's `quarantine` entries, read by
//! `GET /api/v1/quarantine`), and a restart's replay of the ingest log skips it, so the record
//! cannot fail the server again.

use std::collections::HashSet;
use std::panic::{catch_unwind, AssertUnwindSafe};

use serde_json::{json, Value};

use crate::store::{Store, StoreError};

/// The store's configuration kind the quarantined records are kept under (id: the record's
/// ingest-log id).
pub const QUARANTINE: &str = "quarantine";

/// Quarantined records stored per server run at most; beyond, they are logged and counted
/// only (a bug that fails every record must not fill the disk twice).
pub(super) const MAX_STORED_PER_RUN: usize = 10_000;

/// A record its partition could not track.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Quarantined {
    /// The record's ingest-log id.
    pub record_id: i64,
    pub partition: usize,
    pub tag: String,
    /// Why: the tracker's error, or its panic's message.
    pub reason: String,
    /// When it was quarantined (ms since the Unix epoch).
    pub quarantined_ms: i64,
}

/// Runs one tracking step, turning its error or its panic into the reason the record is
/// quarantined.
///
/// # Errors
/// The step's error message, or `the tracker panicked: <message>`.
pub(super) fn guarded<E: std::fmt::Display>(step: impl FnOnce() -> Result<(), E>) -> Result<(), String> {
    match catch_unwind(AssertUnwindSafe(step)) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(error)) => Err(error.to_string()),
        Err(panic) => {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".into());
            Err(format!("the tracker panicked: {message}"))
        }
    }
}

/// The store key of a record id: zero-padded, so the entries list in id order.
fn key(record_id: i64) -> String {
    format!("{record_id:020}")
}

/// Stores `items` with their records' JSON read back from the ingest log (`null` if it is no
/// longer there).
///
/// # Errors
/// The store's error; the items not yet stored are not.
pub(super) fn store(store: &mut dyn Store, items: &[Quarantined]) -> Result<(), StoreError> {
    for item in items {
        let record = store
            .records_after(item.record_id - 1, 1)?
            .into_iter()
            .find(|r| r.id == item.record_id)
            .and_then(|r| serde_json::from_str::<Value>(&r.json).ok())
            .unwrap_or(Value::Null);
        let entry = json!({
            "record_id": item.record_id,
            "partition": item.partition,
            "tag": item.tag,
            "reason": item.reason,
            "quarantined_ms": item.quarantined_ms,
            "record": record,
        });
        store.put_config(QUARANTINE, &key(item.record_id), &entry.to_string())?;
    }
    Ok(())
}

/// The ingest-log ids of every quarantined record (the replay skips them).
///
/// # Errors
/// The store's error.
pub(super) fn quarantined_ids(store: &mut dyn Store) -> Result<HashSet<i64>, StoreError> {
    Ok(store
        .list_config(QUARANTINE)?
        .into_iter()
        .filter_map(|(id, _)| id.parse().ok())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::guarded;

    #[test]
    fn a_panic_or_an_error_becomes_the_reason_and_success_passes() {
        assert_eq!(guarded(|| Ok::<(), String>(())), Ok(()));
        assert_eq!(guarded(|| Err::<(), _>("bad state")), Err("bad state".to_string()));
        let reason = guarded(|| -> Result<(), String> { panic!("index out of bounds: {}", 7) }).unwrap_err();
        assert_eq!(reason, "the tracker panicked: index out of bounds: 7");
        let reason = guarded(|| -> Result<(), String> { panic!("static") }).unwrap_err();
        assert_eq!(reason, "the tracker panicked: static");
    }
}
