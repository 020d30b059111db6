//! Outbound webhooks: alarms (and their acknowledgements) POSTed as JSON to HTTP(S) endpoints
//! configured in `[[webhooks]]` ([`crate::config::WebhookSection`], docs/SERVER.md).
//!
//! ```text
//!  hub (broadcast) ──▶ feeder: rtls:alarms messages whose type a webhook wants
//!                        │ try_send (full: dropped, counted, logged)
//!                        ▼
//!        [queue, 10 000] per webhook ──▶ worker task: POST, retry with back-off, next
//! ```
//!
//! - **What is sent.** Every message the WebSocket's `rtls:alarms` topic carries whose type
//!   ([`event_type`]: the event's `type`, or for a lifecycle event its `event`, `lost` /
//!   `recovered`) is in the webhook's `events` — by default [`DEFAULT_EVENT_TYPES`], every alarm
//!   and every acknowledgement. The body is that message's JSON, unchanged: the engine's event
//!   with `timestamp` and, for alarms and acknowledgements, `alarm_id`.
//! - **Headers.** `X-Rtls-Delivery` (a UUID, the same on every attempt of one event),
//!   `X-Rtls-Attempt` (1, 2, …), `X-Rtls-Event` (the type), and with a secret
//!   `X-Rtls-Signature: sha256=<hex HMAC-SHA256 of the body>` ([`signature`]).
//! - **Outcome.** 2xx: delivered. 408, 429, 5xx, a timeout or a connection error: retried after
//!   `initial_backoff_s`, doubling up to `max_backoff_s`, each wait 75–100 % of that (jitter), or
//!   after `Retry-After` seconds when the answer has them (capped at `max_backoff_s`), until
//!   `max_attempts`. Any other answer (4xx, 3xx: redirects are not followed): failed at once.
//! - **Order.** One worker per webhook sends one event at a time: an event is retried until
//!   delivered or given up before the next one is sent, so a webhook sees events in the order
//!   they were raised. A slow or failing webhook does not delay the others, the pipeline or the
//!   WebSocket; its queue holds [`QUEUE_CAPACITY`] events, beyond which new ones are dropped.
//! - **Nothing silent.** `rtls_webhook_deliveries_total{webhook, outcome}` counts `delivered`,
//!   `retried` (one per retry), `failed` (given up or refused) and `dropped` (for want of room
//!   or time: queue full, hub messages missed, queued or in flight when the shutdown grace ran
//!   out); each failure and drop is logged as a warning with the webhook's name, never its URL
//!   (which may hold a token).
//! - **Shutdown.** After the pipeline has drained, the workers get [`SHUTDOWN_GRACE`] to empty
//!   their queues; what is left then is dropped (counted, logged). Deliveries are not
//!   persisted: a restart does not resend them (the alarms are in `GET /api/v1/alarms`), and the
//!   replay after a crash may send an alarm again with its same `alarm_id`.

mod delivery;
#[cfg(test)]
mod tests;

use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use prometheus_client::metrics::counter::Counter;
use serde_json::Value;
use tokio::sync::broadcast::error::{RecvError, TryRecvError};
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

pub use delivery::{backoff, signature};

use crate::config::{ConfigError, WebhookSection};
use crate::metrics::{outcome_counter, Metrics};
use crate::omlox::ws::Topic;
use crate::pipeline::HubMessage;

/// Every event type a webhook may ask for in `events`: the `rtls:alarms` topic's.
pub const EVENT_TYPES: [&str; 8] = [
    "hazard-predicted",
    "zone-enter",
    "no-coverage",
    "lost",
    "alarm-acknowledged",
    "hazard-cleared",
    "recovered",
    "model-switch",
];

/// The types sent when `events` is not given: the alarms (each with an `alarm_id`) and their
/// acknowledgements.
pub const DEFAULT_EVENT_TYPES: [&str; 5] = [
    "hazard-predicted",
    "zone-enter",
    "no-coverage",
    "lost",
    "alarm-acknowledged",
];

/// Events waiting per webhook; beyond, new ones are dropped.
pub const QUEUE_CAPACITY: usize = 10_000;

/// How long the workers may go on delivering once the server stops.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

/// The name `events` knows an `rtls:alarms` message by: its `type` (`hazard-predicted`,
/// `alarm-acknowledged`, …), or for a `lifecycle` event its `event` (`lost`, `recovered`).
#[must_use]
pub fn event_type(event: &Value) -> Option<&str> {
    match event["type"].as_str()? {
        "lifecycle" => event["event"].as_str(),
        other => Some(other),
    }
}

/// A webhook, its configuration resolved (the secret read from the environment).
#[derive(Clone)]
pub struct Webhook {
    /// The name in metrics and logs.
    pub name: String,
    /// Where to POST.
    pub url: reqwest::Url,
    /// The event types sent.
    pub events: Vec<String>,
    /// The HMAC-SHA256 key, if bodies are signed.
    pub secret: Option<Vec<u8>>,
    /// One attempt's time limit.
    pub timeout: Duration,
    /// Attempts per event.
    pub max_attempts: u32,
    /// The first retry's wait.
    pub initial_backoff: Duration,
    /// The longest wait.
    pub max_backoff: Duration,
}

impl Webhook {
    /// The webhooks of a configuration, checked as [`crate::config::ServerConfig::validate`]
    /// does.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming `webhooks[i].key`.
    pub fn from_config(webhooks: &[WebhookSection]) -> Result<Vec<Self>, ConfigError> {
        crate::config::validate_webhooks(webhooks)?;
        webhooks
            .iter()
            .enumerate()
            .map(|(index, section)| {
                Ok(Self {
                    name: section.resolved_name(index)?,
                    url: section.parsed_url(index)?,
                    events: section.resolved_events(),
                    secret: section.resolved_secret(index)?.map(String::into_bytes),
                    timeout: Duration::from_secs_f64(section.timeout_s),
                    max_attempts: section.max_attempts,
                    initial_backoff: Duration::from_secs_f64(section.initial_backoff_s),
                    max_backoff: Duration::from_secs_f64(section.max_backoff_s),
                })
            })
            .collect()
    }
}

/// An event on its way to one webhook.
#[derive(Debug, Clone)]
struct Delivery {
    /// `X-Rtls-Delivery`.
    id: String,
    /// [`event_type`].
    event_type: String,
    /// The alarm's id, for logs.
    alarm_id: Option<String>,
    /// The JSON body (shared by the webhooks the event goes to).
    body: Bytes,
}

/// A webhook's `rtls_webhook_deliveries_total` counters.
#[derive(Clone)]
struct Counters {
    delivered: Counter,
    retried: Counter,
    failed: Counter,
    dropped: Counter,
}

impl Counters {
    /// Registers (at 0) the webhook's four series.
    fn new(metrics: &Metrics, webhook: &str) -> Self {
        let counter = |outcome: &str| outcome_counter(&metrics.webhook_deliveries, "webhook", webhook, outcome);
        Self {
            delivered: counter("delivered"),
            retried: counter("retried"),
            failed: counter("failed"),
            dropped: counter("dropped"),
        }
    }
}

/// The feeder's view of one webhook.
struct Route {
    name: String,
    events: Vec<String>,
    queue: mpsc::Sender<Delivery>,
    counters: Counters,
}

/// The running webhooks: one feeder task reading the hub, one worker task per webhook.
pub struct Dispatcher {
    stop: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
    grace: Duration,
}

impl Dispatcher {
    /// Starts delivering the `rtls:alarms` messages `hub` receives (subscribe before the
    /// pipeline produces what must be sent).
    ///
    /// # Errors
    /// A webhook's HTTP client cannot be built (its TLS setup failed).
    pub fn start(
        webhooks: Vec<Webhook>,
        hub: broadcast::Receiver<Arc<HubMessage>>,
        metrics: &Metrics,
    ) -> Result<Self, String> {
        Self::start_with(webhooks, hub, metrics, QUEUE_CAPACITY, SHUTDOWN_GRACE)
    }

    fn start_with(
        webhooks: Vec<Webhook>,
        hub: broadcast::Receiver<Arc<HubMessage>>,
        metrics: &Metrics,
        queue_capacity: usize,
        grace: Duration,
    ) -> Result<Self, String> {
        let (stop, stop_rx) = watch::channel(false);
        let mut routes = Vec::with_capacity(webhooks.len());
        let mut workers = Vec::with_capacity(webhooks.len());
        for webhook in webhooks {
            let counters = Counters::new(metrics, &webhook.name);
            let (queue, queued) = mpsc::channel(queue_capacity.max(1));
            routes.push(Route {
                name: webhook.name.clone(),
                events: webhook.events.clone(),
                queue,
                counters: counters.clone(),
            });
            let sender = delivery::Sender::new(webhook, counters)?;
            workers.push((sender, queued));
        }
        let mut tasks = vec![tokio::spawn(feed(hub, routes, stop_rx.clone()))];
        for (sender, queued) in workers {
            tracing::info!(webhook = %sender.webhook.name, events = ?sender.webhook.events, "webhook started");
            tasks.push(tokio::spawn(work(sender, queued, stop_rx.clone(), grace)));
        }
        Ok(Self { stop, tasks, grace })
    }

    /// Stops reading the hub, lets the workers deliver what is queued for at most the grace
    /// period (2 s), drops the rest (counted, logged) and waits for the tasks.
    pub async fn shutdown(self) {
        let _ = self.stop.send(true);
        let deadline = tokio::time::Instant::now() + self.grace + Duration::from_secs(1);
        for task in self.tasks {
            if tokio::time::timeout_at(deadline, task).await.is_err() {
                tracing::error!("a webhook task did not stop in time");
            }
        }
    }
}

/// Reads the hub until stopped; queues each `rtls:alarms` message for the webhooks that want
/// its type. On stop it queues what the hub already holds, then closes the queues.
async fn feed(mut hub: broadcast::Receiver<Arc<HubMessage>>, routes: Vec<Route>, mut stop: watch::Receiver<bool>) {
    loop {
        let received = tokio::select! {
            biased;
            _ = stop.wait_for(|stop| *stop) => break,
            received = hub.recv() => received,
        };
        match received {
            Ok(message) => route(&routes, &message),
            Err(RecvError::Lagged(missed)) => report_missed(&routes, missed),
            Err(RecvError::Closed) => return,
        }
    }
    loop {
        match hub.try_recv() {
            Ok(message) => route(&routes, &message),
            Err(TryRecvError::Lagged(missed)) => report_missed(&routes, missed),
            Err(_) => return,
        }
    }
}

fn route(routes: &[Route], message: &HubMessage) {
    let HubMessage::Extension {
        topic: Topic::RtlsAlarms,
        event,
    } = message
    else {
        return;
    };
    let Some(kind) = event_type(event) else {
        return;
    };
    let mut body: Option<Bytes> = None;
    for route in routes.iter().filter(|r| r.events.iter().any(|e| e == kind)) {
        let body = body
            .get_or_insert_with(|| Bytes::from(serde_json::to_vec(event).unwrap_or_default()))
            .clone();
        let delivery = Delivery {
            id: uuid::Uuid::new_v4().to_string(),
            event_type: kind.to_string(),
            alarm_id: event["alarm_id"].as_str().map(String::from),
            body,
        };
        if let Err(error) = route.queue.try_send(delivery) {
            let (reason, delivery) = match error {
                TrySendError::Full(d) => ("queue full", d),
                TrySendError::Closed(d) => ("worker stopped", d),
            };
            route.counters.dropped.inc();
            tracing::warn!(
                webhook = %route.name,
                delivery = %delivery.id,
                event = %delivery.event_type,
                alarm_id = delivery.alarm_id.as_deref().unwrap_or(""),
                queued = route.queue.max_capacity() - route.queue.capacity(),
                "webhook event dropped: {reason}"
            );
        }
    }
}

/// The feeder fell behind the hub (which carries every location too) and missed `missed`
/// messages: alarms among them were not queued. Counted as dropped for every webhook (an upper
/// bound: most hub messages are locations).
fn report_missed(routes: &[Route], missed: u64) {
    for route in routes {
        route.counters.dropped.inc_by(missed);
        tracing::warn!(
            webhook = %route.name,
            missed,
            "the webhook dispatcher fell behind the hub and missed {missed} messages; alarms among them were not sent"
        );
    }
}

/// A webhook's worker: delivers its queue in order until the queue closes (the feeder stopped)
/// and is empty, or until `grace` after the stop; what is left then is dropped.
async fn work(
    sender: delivery::Sender,
    mut queued: mpsc::Receiver<Delivery>,
    mut stop: watch::Receiver<bool>,
    grace: Duration,
) {
    let deadline = async move {
        let _ = stop.wait_for(|stop| *stop).await;
        tokio::time::sleep(grace).await;
    };
    tokio::pin!(deadline);
    let mut unsent = 0_u64;
    loop {
        let delivery = tokio::select! {
            biased;
            () = &mut deadline => break,
            delivery = queued.recv() => match delivery {
                Some(delivery) => delivery,
                None => break,
            },
        };
        tokio::select! {
            biased;
            () = &mut deadline => {
                unsent += 1;
                break;
            }
            () = sender.deliver(&delivery) => {}
        }
    }
    queued.close();
    while queued.try_recv().is_ok() {
        unsent += 1;
    }
    if unsent > 0 {
        sender.counters.dropped.inc_by(unsent);
        tracing::warn!(
            webhook = %sender.webhook.name,
            unsent,
            "webhook events dropped at shutdown: not delivered within {grace:?}"
        );
    }
}
