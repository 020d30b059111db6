//! One owned partition: take it over where its last owner stopped, warm its tracker up, then
//! store, acknowledge and track its records as they come.

use std::time::Duration;

use async_nats::jetstream::consumer::{pull, AckPolicy, DeliverPolicy};
use futures_util::{FutureExt, StreamExt};
use rtls_engine::record::parse_json_line;
use tokio::sync::watch;

use super::{cluster_error, message_origin, Cluster, ClusterError, INGEST_SUBJECT};
use crate::pipeline::Pipeline;
use crate::sink::IngestError;

/// Messages stored and tracked together at most (and pulled from the stream at once).
const BATCH_MESSAGES: usize = 256;
/// How long one warm-up fetch waits for messages.
const FETCH_WAIT: Duration = Duration::from_millis(100);
/// The pull's heartbeat: a silent server is noticed after two of them.
const HEARTBEAT: Duration = Duration::from_secs(1);
/// How long the stream waits for an acknowledgement before it redelivers (a live owner
/// acknowledges within milliseconds; a dead owner's consumer is replaced at takeover).
const ACK_WAIT: Duration = Duration::from_secs(10);
/// How long a failed store is retried before the message is left to the stream.
const STORE_RETRY: Duration = Duration::from_millis(200);

/// The prefix of a partition's durable consumers' names (`rtls-p<n>-<node>-<ms>`, one per
/// takeover).
#[must_use]
pub fn consumer_name(partition: usize) -> String {
    format!("rtls-p{partition}")
}

/// The partition's consumers left by earlier owners, with their ack floors (stream sequence).
async fn previous_consumers(
    stream: &async_nats::jetstream::stream::Stream,
    partition: usize,
) -> Result<Vec<(String, u64)>, ClusterError> {
    let prefix = format!("{}-", consumer_name(partition));
    // a listing that fails is not an empty one: that would redeliver the partition's history
    let mut names = Vec::new();
    let mut listing = stream.consumer_names();
    while let Some(name) = listing.next().await {
        let name = name.map_err(|e| cluster_error("listing the stream's consumers", e))?;
        if name.starts_with(&prefix) {
            names.push(name);
        }
    }
    let mut previous = Vec::with_capacity(names.len());
    for name in names {
        let info = stream
            .consumer_info(&name)
            .await
            .map_err(|e| cluster_error(&format!("reading the consumer {name}"), e))?;
        previous.push((name, info.ack_floor.stream_sequence));
    }
    Ok(previous)
}

/// Runs partition `partition` on this node until `stop` is set (or the stream fails): the
/// takeover, then the live records. Every record is acknowledged to the stream only after the
/// store has it.
///
/// # Errors
/// [`ClusterError`] when the stream cannot be read; the owner gives the lease up then.
pub async fn run(
    cluster: Cluster,
    pipeline: Pipeline,
    partition: usize,
    mut stop: watch::Receiver<bool>,
) -> Result<(), ClusterError> {
    let subject = format!("{INGEST_SUBJECT}.{partition}");
    let stream = cluster.stream.clone();
    // 1. where the last owners stopped: every record at or below the highest ack floor of
    //    the partition's consumers is stored
    let previous = previous_consumers(&stream, partition).await?;
    let floor = previous.iter().map(|(_, floor)| *floor).max();
    // 2. the tracks' state from the records before the floor
    if let Some(floor) = floor.filter(|&f| f > 0) {
        warm_up(&cluster, &pipeline, partition, &subject, floor).await?;
    }
    // 3. a consumer of this takeover's own, delivering from the floor on at once: the old
    //    one's unacknowledged messages would wait for ACK_WAIT on a dead owner, and a stale
    //    owner's late acknowledgements must not land on the new consumer
    for (old, _) in &previous {
        stream
            .delete_consumer(old)
            .await
            .map_err(|e| cluster_error(&format!("deleting the consumer {old}"), e))?;
    }
    let name = format!(
        "{}-{}-{}",
        consumer_name(partition),
        cluster.node,
        crate::pipeline::unix_ms()
    );
    let deliver_policy = match floor {
        Some(floor) => DeliverPolicy::ByStartSequence {
            start_sequence: floor + 1,
        },
        None => DeliverPolicy::All,
    };
    let consumer = stream
        .create_consumer(pull::Config {
            durable_name: Some(name.clone()),
            filter_subject: subject.clone(),
            // each message acknowledged once stored: a message lost on its way to this node is
            // redelivered, never acknowledged by a later one
            ack_policy: AckPolicy::Explicit,
            ack_wait: ACK_WAIT,
            deliver_policy,
            ..Default::default()
        })
        .await
        .map_err(|e| cluster_error(&format!("the consumer {name}"), e))?;
    tracing::info!(
        partition,
        from_sequence = floor.map_or(1, |f| f + 1),
        "partition taken over"
    );
    // a continuous pull: messages come as they are published, not when a fetch expires
    let mut deliveries = consumer
        .stream()
        .max_messages_per_batch(BATCH_MESSAGES)
        .heartbeat(HEARTBEAT)
        .messages()
        .await
        .map_err(|e| cluster_error(&format!("reading from {name}"), e))?;
    while !*stop.borrow() {
        // the first message waits; those already delivered join it
        let first = tokio::select! {
            next = deliveries.next() => next,
            _ = stop.changed() => break,
        };
        let mut messages = Vec::new();
        match first {
            Some(Ok(message)) => messages.push(message),
            Some(Err(e)) => {
                // missed heartbeats while NATS elects a leader: the pull is renewed
                tracing::warn!(partition, error = %e, "reading from the ingest stream failed; going on");
                continue;
            }
            None => return Err(ClusterError(format!("the consumer {name} ended"))),
        }
        while messages.len() < BATCH_MESSAGES {
            match deliveries.next().now_or_never() {
                Some(Some(Ok(message))) => messages.push(message),
                _ => break,
            }
        }
        let payloads: Vec<(String, i64, String)> = messages
            .iter()
            .map(|m| {
                let (source, received_ms) = message_origin(m.headers.as_ref());
                (source, received_ms, String::from_utf8_lossy(&m.payload).into_owned())
            })
            .collect();
        // stored before acknowledged; a store failure is retried, never skipped
        loop {
            match pipeline.take_from_stream(&payloads).await {
                Ok(_) => break,
                Err(IngestError::Unavailable(reason)) if !*stop.borrow() => {
                    tracing::warn!(partition, reason, "storing the stream's records failed; retrying");
                    tokio::select! {
                        () = tokio::time::sleep(STORE_RETRY) => {}
                        _ = stop.changed() => {}
                    }
                }
                Err(e) => {
                    // stopping: the records stay unacknowledged for the next owner
                    tracing::warn!(partition, error = %e, "records left to the next owner");
                    return Ok(());
                }
            }
        }
        for message in &messages {
            message
                .ack()
                .await
                .map_err(|e| cluster_error(&format!("acknowledging on {name}"), e))?;
        }
    }
    Ok(())
}

/// Tracks the partition's records of the last `warmup_s` up to `floor` (inclusive) without
/// publishing or storing anything: the new owner's tracks start where the old owner's were.
async fn warm_up(
    cluster: &Cluster,
    pipeline: &Pipeline,
    partition: usize,
    subject: &str,
    floor: u64,
) -> Result<(), ClusterError> {
    if cluster.settings.warmup_s <= 0.0 {
        return Ok(());
    }
    let start = time::OffsetDateTime::now_utc() - time::Duration::seconds_f64(cluster.settings.warmup_s);
    let reader = cluster
        .stream
        .create_consumer(pull::Config {
            filter_subject: subject.to_string(),
            ack_policy: AckPolicy::None,
            deliver_policy: DeliverPolicy::ByStartTime { start_time: start },
            inactive_threshold: Duration::from_secs(30),
            ..Default::default()
        })
        .await
        .map_err(|e| cluster_error("the warm-up reader", e))?;
    let mut records = Vec::new();
    let mut done = false;
    while !done {
        let mut batch = reader
            .fetch()
            .max_messages(BATCH_MESSAGES * 4)
            .expires(FETCH_WAIT)
            .messages()
            .await
            .map_err(|e| cluster_error("the warm-up reader", e))?;
        let mut seen = 0usize;
        while let Some(message) = batch.next().await {
            let Ok(message) = message else { break };
            seen += 1;
            let sequence = message.info().map_or(u64::MAX, |info| info.stream_sequence);
            if sequence > floor {
                done = true;
                break;
            }
            let text = String::from_utf8_lossy(&message.payload);
            records.extend(
                text.lines()
                    .filter(|line| !line.trim().is_empty())
                    .filter_map(|line| parse_json_line(line, "ingest stream", 0).ok()),
            );
            if sequence == floor {
                done = true;
                break;
            }
        }
        done |= seen == 0;
    }
    let name = reader.cached_info().name.clone();
    let _ = cluster.stream.delete_consumer(&name).await;
    let count = records.len();
    let pipeline = pipeline.clone();
    tokio::task::spawn_blocking(move || pipeline.warm_up_partition(partition, records))
        .await
        .map_err(|e| cluster_error("the warm-up", e))?;
    tracing::info!(
        partition,
        records = count,
        up_to_sequence = floor,
        "warm-up records sent"
    );
    Ok(())
}
