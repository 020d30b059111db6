//! One owned partition: take it over where its last owner stopped, warm its tracker up, then
//! store, acknowledge and track its records as they come.

use std::time::Duration;

use async_nats::jetstream::consumer::{pull, AckPolicy, DeliverPolicy};
use futures_util::{FutureExt, StreamExt};
use rtls_engine::record::parse_json_line;
use tokio::sync::watch;

use super::{checkpoints, cluster_error, message_origin, Cluster, ClusterError, INGEST_SUBJECT};
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
    // 2. the tracks' state: the newest checkpoint and the records after it up to the floor,
    //    or, without one, the records of the last `warmup_s` before the floor
    let floor = resume(&cluster, &pipeline, partition, &subject, floor).await?;
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
    let mut checkpointing = Checkpointing::new(&cluster, partition, floor.unwrap_or(0));
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
        if let Some(sequence) = messages.last().and_then(|m| m.info().ok()).map(|i| i.stream_sequence) {
            checkpointing.stored(sequence, &pipeline);
        }
    }
    // the next owner starts from the state this node stops at
    checkpointing.finish(&pipeline).await;
    Ok(())
}

/// The checkpoints of one owned partition: one every `checkpoint_s` while records come, at
/// most one at a time, and a last one when the partition stops here.
struct Checkpointing {
    cluster: Cluster,
    partition: usize,
    /// The last stream sequence stored, and the last one a checkpoint was asked for at.
    stored: u64,
    checkpointed: u64,
    next_due: tokio::time::Instant,
    /// The checkpoint being taken and written (aborted if this is dropped: a checkpoint asked
    /// for after the partition's reset would hold no tracks).
    in_flight: Option<AbortOnDrop>,
}

/// A task aborted when its handle is dropped.
struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

impl Checkpointing {
    fn new(cluster: &Cluster, partition: usize, resumed_after: u64) -> Self {
        Self {
            cluster: cluster.clone(),
            partition,
            stored: resumed_after,
            checkpointed: resumed_after,
            next_due: tokio::time::Instant::now() + period(cluster),
            in_flight: None,
        }
    }

    /// Records up to `sequence` are stored (and on their way to the partition): a checkpoint
    /// is taken if one is due and none is being taken.
    fn stored(&mut self, sequence: u64, pipeline: &Pipeline) {
        self.stored = self.stored.max(sequence);
        let idle = self.in_flight.as_ref().is_none_or(|task| task.0.is_finished());
        if self.cluster.settings.checkpoint_s > 0.0 && idle && tokio::time::Instant::now() >= self.next_due {
            self.next_due = tokio::time::Instant::now() + period(&self.cluster);
            self.checkpointed = self.stored;
            let (cluster, pipeline, partition, sequence) =
                (self.cluster.clone(), pipeline.clone(), self.partition, self.stored);
            self.in_flight = Some(AbortOnDrop(tokio::spawn(async move {
                take(&cluster, &pipeline, partition, sequence).await;
            })));
        }
    }

    /// Waits for the checkpoint being taken, then takes one of the last records stored if
    /// that one does not hold them.
    async fn finish(mut self, pipeline: &Pipeline) {
        if let Some(mut task) = self.in_flight.take() {
            let _ = (&mut task.0).await;
        }
        if self.cluster.settings.checkpoint_s > 0.0 && self.stored > self.checkpointed {
            take(&self.cluster, pipeline, self.partition, self.stored).await;
        }
    }
}

fn period(cluster: &Cluster) -> Duration {
    Duration::from_secs_f64(cluster.settings.checkpoint_s.max(0.1))
}

/// Takes partition `partition`'s state, which holds its records up to `sequence`, and stores
/// it; counted in `rtls_cluster_checkpoints_total{outcome}`, a failure logged.
async fn take(cluster: &Cluster, pipeline: &Pipeline, partition: usize, sequence: u64) {
    let written = async {
        let state = pipeline
            .checkpoint_partition(partition)
            .await
            .map_err(|reason| ClusterError(format!("taking the state: {reason}")))?;
        checkpoints::write(&cluster.checkpoints, partition, sequence, &state, &cluster.node).await?;
        Ok::<usize, ClusterError>(state.len())
    };
    let metrics = pipeline.metrics();
    let outcome = match written.await {
        Ok(bytes) => {
            metrics
                .cluster_checkpoint_bytes
                .set(i64::try_from(bytes).unwrap_or(i64::MAX));
            tracing::debug!(partition, sequence, bytes, "checkpoint written");
            "written"
        }
        Err(e) => {
            tracing::warn!(partition, sequence, error = %e, "checkpoint not written");
            "failed"
        }
    };
    metrics
        .cluster_checkpoints
        .get_or_create(&vec![("outcome".to_owned(), outcome.to_owned())])
        .inc();
}

/// Rebuilds the partition's tracks on this node before it consumes: from the newest
/// checkpoint (when there is one no older than `checkpoint_max_age_s`, of this site and
/// build) and the records after it up to the ack floor, or else from the records of the last
/// `warmup_s` up to the floor. Returns the sequence after which the new consumer starts: the
/// floor, or the checkpoint's sequence when an owner's acknowledgements were lost after it
/// (every record the checkpoint holds is stored).
///
/// # Errors
/// [`ClusterError`] when the stream cannot be read.
async fn resume(
    cluster: &Cluster,
    pipeline: &Pipeline,
    partition: usize,
    subject: &str,
    floor: Option<u64>,
) -> Result<Option<u64>, ClusterError> {
    let settings = &cluster.settings;
    let outcome = |what: &str| {
        pipeline
            .metrics()
            .cluster_resumes
            .get_or_create(&vec![("outcome".to_owned(), what.to_owned())])
            .inc();
    };
    let checkpoint = if settings.checkpoint_s > 0.0 {
        checkpoints::read(&cluster.checkpoints, partition)
            .await
            .unwrap_or_else(|e| {
                tracing::warn!(partition, error = %e, "no usable checkpoint; warming up instead");
                None
            })
    } else {
        None
    };
    let restored = match checkpoint {
        Some(checkpoint) => restore(pipeline, partition, checkpoint, settings.checkpoint_max_age_s).await,
        None => Restored::Not,
    };
    if restored == Restored::Refused {
        outcome("refused");
    }
    // after a checkpoint of sequence S: the records after S up to the floor (every record S
    // holds is stored, so the consumer starts after both); else the last `warmup_s` of them
    let (from, up_to, what) = match restored {
        Restored::At(sequence) => (
            WarmUpFrom::After(sequence),
            Some(floor.unwrap_or(0).max(sequence)),
            "restored",
        ),
        Restored::Not | Restored::Refused => (
            WarmUpFrom::RecentSeconds(settings.warmup_s),
            floor.filter(|&f| f > 0),
            "warmed-up",
        ),
    };
    if let Some(up_to) = up_to {
        warm_up(cluster, pipeline, partition, subject, from, up_to).await?;
        outcome(what);
    }
    Ok(if matches!(restored, Restored::At(_)) {
        up_to
    } else {
        floor
    })
}

/// What became of a partition's checkpoint at a takeover.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Restored {
    /// The tracks are its state, which holds the records up to this stream sequence.
    At(u64),
    /// There was none, or it was too old.
    Not,
    /// The partition did not take it (another site or release, or it did not decode).
    Refused,
}

/// Hands `checkpoint` to the partition unless it is older than `max_age_s`.
async fn restore(
    pipeline: &Pipeline,
    partition: usize,
    checkpoint: checkpoints::Checkpoint,
    max_age_s: f64,
) -> Restored {
    let age_s = (crate::pipeline::unix_ms() - checkpoint.taken_ms) as f64 / 1000.0;
    if age_s > max_age_s {
        tracing::info!(
            partition,
            age_s,
            "the checkpoint is too old to restore; warming up instead"
        );
        return Restored::Not;
    }
    match pipeline.restore_partition(partition, checkpoint.state).await {
        Ok(tracks) => {
            tracing::info!(partition, tracks, sequence = checkpoint.sequence, from = %checkpoint.node,
                age_s, "partition restored from its checkpoint");
            Restored::At(checkpoint.sequence)
        }
        Err(reason) => {
            tracing::warn!(partition, reason, "the checkpoint was not restored; warming up instead");
            Restored::Refused
        }
    }
}

/// Where a warm-up starts in the partition's stream.
enum WarmUpFrom {
    /// The records of the last `warmup_s` (no checkpoint).
    RecentSeconds(f64),
    /// The records after a checkpoint's sequence.
    After(u64),
}

/// Tracks the partition's records from `from` up to `floor` (inclusive) without publishing or
/// storing anything: the new owner's tracks continue where the old owner's were.
async fn warm_up(
    cluster: &Cluster,
    pipeline: &Pipeline,
    partition: usize,
    subject: &str,
    from: WarmUpFrom,
    floor: u64,
) -> Result<(), ClusterError> {
    let deliver_policy = match from {
        WarmUpFrom::RecentSeconds(seconds) if seconds <= 0.0 => return Ok(()),
        WarmUpFrom::RecentSeconds(seconds) => DeliverPolicy::ByStartTime {
            start_time: time::OffsetDateTime::now_utc() - time::Duration::seconds_f64(seconds),
        },
        WarmUpFrom::After(sequence) if sequence >= floor => return Ok(()),
        WarmUpFrom::After(sequence) => DeliverPolicy::ByStartSequence {
            start_sequence: sequence + 1,
        },
    };
    let reader = cluster
        .stream
        .create_consumer(pull::Config {
            filter_subject: subject.to_string(),
            ack_policy: AckPolicy::None,
            deliver_policy,
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
