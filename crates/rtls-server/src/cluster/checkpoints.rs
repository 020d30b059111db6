//! Partition checkpoints: an owner stores each partition's encoded tracker state every
//! `checkpoint_s` in the key-value bucket `rtls_checkpoints`, with the stream sequence it
//! holds; a new owner restores the newest one and tracks only the records after it.
//!
//! A checkpoint of sequence `S` holds exactly the partition's records of stream sequence ≤ `S`,
//! each of them stored in PostgreSQL before it was taken (the consumer asks for it after the
//! store answered, through the pipeline's ingest queue, which hands it to the partition after
//! those records).
//!
//! Layout: a NATS message stays below its server's `max_payload` (1 MiB by default), so the
//! state is split into chunks `p<n>.c<k>` of at most 512 KiB, each prefixed with the
//! checkpoint's random id, and the entry `p<n>` — written last — says how many chunks of
//! which id make it up. A reader that finds a chunk of another id (an owner was writing while
//! it read) has no checkpoint, and the partition warms up from its records instead.

use async_nats::jetstream::kv;
use bytes::Bytes;
use serde::{Deserialize, Serialize};

use super::{cluster_error, ClusterError};

/// The checkpoints' bucket.
pub const CHECKPOINTS: &str = "rtls_checkpoints";
/// The state's bytes per chunk, at most (the chunk adds its 8-byte id).
const CHUNK_BYTES: usize = 512 * 1024;

/// The entry `p<n>`: what makes up partition n's newest checkpoint.
#[derive(Debug, Serialize, Deserialize)]
struct Entry {
    /// The last stream sequence whose record the state holds.
    sequence: u64,
    /// The chunks' id (random per checkpoint).
    id: u64,
    chunks: usize,
    bytes: usize,
    /// When it was taken, ms since the Unix epoch, and by which node.
    taken_ms: i64,
    node: String,
}

/// A partition's newest checkpoint, read back.
#[derive(Debug)]
pub struct Checkpoint {
    /// The last stream sequence whose record the state holds.
    pub sequence: u64,
    /// The encoded state.
    pub state: Vec<u8>,
    /// When it was taken, ms since the Unix epoch.
    pub taken_ms: i64,
    /// The node that took it.
    pub node: String,
}

fn entry_key(partition: usize) -> String {
    format!("p{partition}")
}

fn chunk_key(partition: usize, chunk: usize) -> String {
    format!("p{partition}.c{chunk}")
}

/// Stores partition `partition`'s state `state`, which holds its records up to stream
/// sequence `sequence`: the chunks first, then the entry naming them.
///
/// # Errors
/// [`ClusterError`] when a write failed (the previous checkpoint's entry stays, though its
/// chunks may be overwritten: a reader then finds the ids disagree and has none).
pub async fn write(
    bucket: &kv::Store,
    partition: usize,
    sequence: u64,
    state: &[u8],
    node: &str,
) -> Result<(), ClusterError> {
    let id = uuid::Uuid::new_v4().as_u64_pair().0;
    let chunks: Vec<&[u8]> = state.chunks(CHUNK_BYTES).collect();
    for (k, chunk) in chunks.iter().enumerate() {
        let mut payload = Vec::with_capacity(8 + chunk.len());
        payload.extend_from_slice(&id.to_be_bytes());
        payload.extend_from_slice(chunk);
        bucket
            .put(chunk_key(partition, k), Bytes::from(payload))
            .await
            .map_err(|e| cluster_error(&format!("writing chunk {k} of partition {partition}'s checkpoint"), e))?;
    }
    let entry = Entry {
        sequence,
        id,
        chunks: chunks.len(),
        bytes: state.len(),
        taken_ms: crate::pipeline::unix_ms(),
        node: node.to_string(),
    };
    let entry = serde_json::to_vec(&entry).map_err(|e| cluster_error("encoding a checkpoint entry", e))?;
    bucket
        .put(entry_key(partition), Bytes::from(entry))
        .await
        .map_err(|e| cluster_error(&format!("writing partition {partition}'s checkpoint entry"), e))?;
    Ok(())
}

/// Partition `partition`'s newest checkpoint; `None` when there is none.
///
/// # Errors
/// [`ClusterError`] when the bucket cannot be read, or the checkpoint is incomplete or was
/// overwritten while it was read.
pub async fn read(bucket: &kv::Store, partition: usize) -> Result<Option<Checkpoint>, ClusterError> {
    let Some(entry) = bucket
        .get(entry_key(partition))
        .await
        .map_err(|e| cluster_error(&format!("reading partition {partition}'s checkpoint entry"), e))?
    else {
        return Ok(None);
    };
    let entry: Entry = serde_json::from_slice(&entry)
        .map_err(|e| cluster_error(&format!("partition {partition}'s checkpoint entry"), e))?;
    let mut state = Vec::with_capacity(entry.bytes);
    for k in 0..entry.chunks {
        let chunk = bucket
            .get(chunk_key(partition, k))
            .await
            .map_err(|e| cluster_error(&format!("reading chunk {k} of partition {partition}'s checkpoint"), e))?
            .ok_or_else(|| ClusterError(format!("chunk {k} of partition {partition}'s checkpoint is missing")))?;
        let (id, data) = chunk.split_at(8.min(chunk.len()));
        if id != entry.id.to_be_bytes() {
            return Err(ClusterError(format!(
                "chunk {k} of partition {partition}'s checkpoint belongs to another checkpoint \
                 (it was being written while it was read)"
            )));
        }
        state.extend_from_slice(data);
    }
    if state.len() != entry.bytes {
        return Err(ClusterError(format!(
            "partition {partition}'s checkpoint has {} bytes where its entry says {}",
            state.len(),
            entry.bytes
        )));
    }
    Ok(Some(Checkpoint {
        sequence: entry.sequence,
        state,
        taken_ms: entry.taken_ms,
        node: entry.node,
    }))
}
