//! Positions and events forwarded to NATS servers configured in `[[nats_forward]]`
//! ([`crate::config::NatsForwardSection`], docs/SERVER.md).
//!
//! ```text
//!  hub (broadcast) ──▶ feeder: locations, rtls:alarms, rtls:events a forward wants
//!                        │ try_send (full: dropped, counted, logged)
//!                        ▼
//!        [queue, 10 000] per forward ──▶ worker task: publish on the forward's client
//! ```
//!
//! - **Subjects.** `{subject_prefix}.positions.{tag}` carries each track update as the omlox
//!   `Location` the WebSocket's `location_updates` sends; `{subject_prefix}.events.{type}`
//!   each `rtls:alarms` and `rtls:events` message as the WebSocket (and a webhook) sends it,
//!   `type` being the event's `type` (as in MQTT's `rtls/v1/events/{type}`). A character a
//!   subject token cannot hold (`.`, `*`, `>`, white space) is written `_` ([`token`]).
//! - **Delivery.** Core NATS publish: at most once, no acknowledgement, nothing stored — the
//!   forward is for live consumers; history is in the REST API. The client (async-nats)
//!   connects in the background and reconnects on its own with back-off, so a NATS server that
//!   is down delays neither the start nor the pipeline: messages wait in the forward's queue
//!   (and the client's buffer) and are dropped, counted, when it is full.
//! - **Nothing silent.** `rtls_nats_forward_total{forward, outcome}` counts `published`
//!   (handed to the client) and `dropped` (queue full, hub messages the feeder missed — an
//!   upper bound —, a publish error, or left at shutdown). Drops and connection changes are
//!   logged as warnings — drops at most every 10 s per forward with the count since
//!   ([`crate::log_limit`]) — with the forward's name, never its URL (which may hold a
//!   password).
//! - **Shutdown.** After the pipeline has drained, the workers get [`SHUTDOWN_GRACE`] to
//!   publish what is queued and flush the client; what is left then is dropped (counted,
//!   logged).

use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use prometheus_client::metrics::counter::Counter;
use tokio::sync::broadcast::error::{RecvError, TryRecvError};
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

use crate::config::{ConfigError, ForwardTopic, NatsForwardSection};
use crate::log_limit::LogLimiter;
use crate::metrics::{outcome_counter, Metrics};
use crate::omlox::ws::Topic;
use crate::pipeline::HubMessage;

/// Messages waiting per forward; beyond, new ones are dropped.
pub const QUEUE_CAPACITY: usize = 10_000;

/// How long the workers may go on publishing once the server stops.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

/// A forward, its configuration resolved (the token read from the environment).
#[derive(Clone)]
pub struct NatsForward {
    /// The name in metrics and logs.
    pub name: String,
    /// The servers (`nats://…`, `tls://…`; credentials possibly inside: never logged).
    pub servers: Vec<String>,
    /// The subjects' first tokens.
    pub subject_prefix: String,
    /// What is sent.
    pub topics: Vec<ForwardTopic>,
    /// The NATS server's authentication token, if any.
    pub token: Option<String>,
}

impl NatsForward {
    /// The forwards of a configuration, checked as [`crate::config::ServerConfig::validate`]
    /// does.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming `nats_forward[i].key`.
    pub fn from_config(forwards: &[NatsForwardSection]) -> Result<Vec<Self>, ConfigError> {
        crate::config::validate_nats_forwards(forwards)?;
        forwards
            .iter()
            .enumerate()
            .map(|(index, section)| {
                Ok(Self {
                    name: section.resolved_name(index)?,
                    servers: section.url.split(',').map(|s| s.trim().to_string()).collect(),
                    subject_prefix: section.subject_prefix.clone(),
                    topics: section.topics.clone(),
                    token: section.resolved_token(index)?,
                })
            })
            .collect()
    }
}

/// `text` as one subject token: `.`, `*`, `>` and white space become `_`; empty is `_`.
///
/// # Examples
/// ```
/// use rtls_server::nats_forward::token;
/// assert_eq!(token("miner-7"), "miner-7");
/// assert_eq!(token("site.a *>"), "site_a___");
/// assert_eq!(token(""), "_");
/// ```
#[must_use]
pub fn token(text: &str) -> String {
    if text.is_empty() {
        return "_".into();
    }
    text.chars()
        .map(|c| {
            if c.is_whitespace() || matches!(c, '.' | '*' | '>') {
                '_'
            } else {
                c
            }
        })
        .collect()
}

/// A hub message as what a forward sends: its topic, the subject after the prefix and the
/// JSON payload; `None` for what no forward sends (fence events, collisions, proximities).
fn outgoing(message: &HubMessage) -> Option<(ForwardTopic, String, Bytes)> {
    match message {
        HubMessage::Location { tag, location, .. } => Some((
            ForwardTopic::Positions,
            format!("positions.{}", token(tag)),
            Bytes::from(serde_json::to_vec(&**location).ok()?),
        )),
        HubMessage::Extension { topic, event } => {
            let forward_topic = match topic {
                Topic::RtlsAlarms => ForwardTopic::Alarms,
                Topic::RtlsEvents => ForwardTopic::Events,
                _ => return None,
            };
            let kind = event["type"].as_str().unwrap_or("unknown");
            Some((
                forward_topic,
                format!("events.{}", token(kind)),
                Bytes::from(serde_json::to_vec(event).ok()?),
            ))
        }
        _ => None,
    }
}

/// A forward's `rtls_nats_forward_total` counters.
#[derive(Clone)]
struct Counters {
    published: Counter,
    dropped: Counter,
}

impl Counters {
    /// Registers (at 0) the forward's two series.
    fn new(metrics: &Metrics, forward: &str) -> Self {
        let counter = |outcome: &str| outcome_counter(&metrics.nats_forward, "forward", forward, outcome);
        Self {
            published: counter("published"),
            dropped: counter("dropped"),
        }
    }
}

/// The feeder's view of one forward.
struct Route {
    name: String,
    prefix: String,
    topics: Vec<ForwardTopic>,
    queue: mpsc::Sender<(String, Bytes)>,
    counters: Counters,
    drops: LogLimiter,
}

impl Route {
    /// `count` messages dropped for `reason`: counted, logged at most every 10 s.
    fn dropped(&mut self, count: u64, reason: &str) {
        self.counters.dropped.inc_by(count);
        if let Some(since) = self.drops.occurred_many(count) {
            tracing::warn!(forward = %self.name, dropped = since, reason,
                "NATS forward: messages dropped (the count is since the last such line; rtls_nats_forward_total counts every one)");
        }
    }
}

/// The running forwards: one feeder task reading the hub, one worker task per forward.
pub struct Forwarder {
    stop: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
    grace: Duration,
}

impl Forwarder {
    /// Connects each forward's client (in the background: a server that is down is retried
    /// with back-off) and starts forwarding what `hub` receives (subscribe before the pipeline
    /// produces what must be sent).
    ///
    /// # Errors
    /// A client cannot be set up (an address async-nats does not take).
    pub async fn start(
        forwards: Vec<NatsForward>,
        hub: broadcast::Receiver<Arc<HubMessage>>,
        metrics: &Metrics,
    ) -> Result<Self, String> {
        let (stop, stop_rx) = watch::channel(false);
        let mut routes = Vec::with_capacity(forwards.len());
        let mut tasks = Vec::with_capacity(forwards.len() + 1);
        for forward in forwards {
            let counters = Counters::new(metrics, &forward.name);
            let client = connect(&forward).await?;
            let (queue, queued) = mpsc::channel(QUEUE_CAPACITY);
            tracing::info!(forward = %forward.name, topics = ?forward.topics, prefix = %forward.subject_prefix, "NATS forward started");
            tasks.push(tokio::spawn(work(
                forward.name.clone(),
                client,
                queued,
                counters.clone(),
                stop_rx.clone(),
                SHUTDOWN_GRACE,
            )));
            routes.push(Route {
                name: forward.name,
                prefix: forward.subject_prefix,
                topics: forward.topics,
                queue,
                counters,
                drops: LogLimiter::default(),
            });
        }
        tasks.insert(0, tokio::spawn(feed(hub, routes, stop_rx)));
        Ok(Self {
            stop,
            tasks,
            grace: SHUTDOWN_GRACE,
        })
    }

    /// Stops reading the hub, lets the workers publish what is queued and flush for at most
    /// the grace period (2 s), drops the rest (counted, logged) and waits for the tasks.
    pub async fn shutdown(self) {
        let _ = self.stop.send(true);
        let deadline = tokio::time::Instant::now() + self.grace + Duration::from_secs(1);
        for task in self.tasks {
            if tokio::time::timeout_at(deadline, task).await.is_err() {
                tracing::error!("a NATS forward task did not stop in time");
            }
        }
    }
}

/// A forward's client: connecting and reconnecting in the background, connection changes
/// logged by the forward's name.
async fn connect(forward: &NatsForward) -> Result<async_nats::Client, String> {
    let name = forward.name.clone();
    let mut options = async_nats::ConnectOptions::new()
        .name(format!("rtls-server forward {}", forward.name))
        .retry_on_initial_connect()
        .event_callback(move |event| {
            let name = name.clone();
            async move {
                match event {
                    async_nats::Event::Connected => tracing::info!(forward = %name, "NATS forward connected"),
                    async_nats::Event::Disconnected => {
                        tracing::warn!(forward = %name, "NATS forward disconnected; reconnecting with back-off");
                    }
                    other => tracing::warn!(forward = %name, event = %other, "NATS forward"),
                }
            }
        });
    if let Some(token) = &forward.token {
        options = options.token(token.clone());
    }
    options
        .connect(forward.servers.as_slice())
        .await
        .map_err(|e| format!("nats_forward `{}`: {e}", forward.name))
}

/// Reads the hub until stopped; queues each message for the forwards that want its topic. On
/// stop it queues what the hub already holds, then closes the queues.
async fn feed(mut hub: broadcast::Receiver<Arc<HubMessage>>, mut routes: Vec<Route>, mut stop: watch::Receiver<bool>) {
    loop {
        let received = tokio::select! {
            biased;
            _ = stop.wait_for(|stop| *stop) => break,
            received = hub.recv() => received,
        };
        match received {
            Ok(message) => route(&mut routes, &message),
            Err(RecvError::Lagged(missed)) => report_missed(&mut routes, missed),
            Err(RecvError::Closed) => return,
        }
    }
    loop {
        match hub.try_recv() {
            Ok(message) => route(&mut routes, &message),
            Err(TryRecvError::Lagged(missed)) => report_missed(&mut routes, missed),
            Err(_) => return,
        }
    }
}

fn route(routes: &mut [Route], message: &HubMessage) {
    if !routes.iter().any(|r| r.topics.iter().any(|t| wants(*t, message))) {
        return;
    }
    let Some((topic, subject, payload)) = outgoing(message) else {
        return;
    };
    for route in routes.iter_mut().filter(|r| r.topics.contains(&topic)) {
        let subject = format!("{}.{subject}", route.prefix);
        if let Err(error) = route.queue.try_send((subject, payload.clone())) {
            let reason = match error {
                TrySendError::Full(_) => "queue full (the NATS server is slow or unreachable)",
                TrySendError::Closed(_) => "worker stopped",
            };
            route.dropped(1, reason);
        }
    }
}

/// Whether `message` is of `topic` (checked before its payload is written).
fn wants(topic: ForwardTopic, message: &HubMessage) -> bool {
    match (topic, message) {
        (ForwardTopic::Positions, HubMessage::Location { .. }) => true,
        (ForwardTopic::Alarms, HubMessage::Extension { topic, .. }) => *topic == Topic::RtlsAlarms,
        (ForwardTopic::Events, HubMessage::Extension { topic, .. }) => *topic == Topic::RtlsEvents,
        _ => false,
    }
}

/// The feeder fell behind the hub and missed `missed` messages: counted as dropped for every
/// forward (an upper bound: a forward may not have wanted them all).
fn report_missed(routes: &mut [Route], missed: u64) {
    for route in routes {
        route.dropped(missed, "the forwarder fell behind the hub");
    }
}

/// A forward's worker: publishes its queue in order until the queue closes (the feeder
/// stopped) and is empty, or until `grace` after the stop; then flushes the client within
/// what is left of the grace. What is left is dropped.
async fn work(
    name: String,
    client: async_nats::Client,
    mut queued: mpsc::Receiver<(String, Bytes)>,
    counters: Counters,
    mut stop: watch::Receiver<bool>,
    grace: Duration,
) {
    let deadline = async move {
        let _ = stop.wait_for(|stop| *stop).await;
        tokio::time::sleep(grace).await;
    };
    tokio::pin!(deadline);
    let mut failures = LogLimiter::default();
    let mut unsent = 0_u64;
    let mut expired = false;
    loop {
        let (subject, payload) = tokio::select! {
            biased;
            () = &mut deadline => {
                expired = true;
                break;
            }
            message = queued.recv() => match message {
                Some(message) => message,
                None => break,
            },
        };
        tokio::select! {
            biased;
            () = &mut deadline => {
                unsent += 1;
                expired = true;
                break;
            }
            published = client.publish(subject, payload) => match published {
                Ok(()) => {
                    counters.published.inc();
                }
                Err(e) => {
                    counters.dropped.inc();
                    if let Some(count) = failures.occurred() {
                        tracing::warn!(forward = %name, error = %e, count, "NATS forward: publish failed (the count is since the last such line)");
                    }
                }
            },
        }
    }
    queued.close();
    while queued.try_recv().is_ok() {
        unsent += 1;
    }
    if unsent > 0 {
        counters.dropped.inc_by(unsent);
        tracing::warn!(forward = %name, unsent, "NATS forward: messages dropped at shutdown: not published within {grace:?}");
    }
    // what the client holds goes out now, if the server is there
    if expired {
        tracing::warn!(forward = %name, "NATS forward: the client's buffer was not flushed: no time left");
        return;
    }
    tokio::select! {
        biased;
        () = &mut deadline => tracing::warn!(forward = %name, "NATS forward: the client's buffer was not flushed within the grace"),
        flushed = client.flush() => if let Err(e) = flushed {
            tracing::warn!(forward = %name, error = %e, "NATS forward: flush failed at shutdown");
        },
    }
}
