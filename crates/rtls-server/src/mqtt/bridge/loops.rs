//! The three loops of a running bridge, side by side in one task: polling the connection,
//! storing and acknowledging messages, forwarding publications.

use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use futures_util::stream::{FuturesOrdered, StreamExt};
use rumqttc::mqttbytes::v4::{Packet, Publish, SubscribeReasonCode};
use rumqttc::mqttbytes::{matches, QoS};
use rumqttc::{AsyncClient, Event, EventLoop, Outgoing};
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::{broadcast, mpsc, watch, Notify};
use tokio::time::{sleep, timeout, Instant};

use crate::sink::{IngestError, IngestOrder, MeasurementSink, Publication};

use super::{add, Counters, ExternalBroker};

/// How many payloads may be in the sink at once.
const MAX_PENDING_INGESTS: usize = 64;

/// First and largest delay between reconnection attempts.
const BACKOFF_MIN: Duration = Duration::from_millis(200);
const BACKOFF_MAX: Duration = Duration::from_secs(30);

/// How long shutdown waits for payloads in the sink and for the DISCONNECT to leave.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(5);

/// Runs `bridge` until `shutdown` resolves; see [`ExternalBroker::run`].
pub(super) async fn run(bridge: ExternalBroker, shutdown: impl Future<Output = ()> + Send) {
    let ExternalBroker {
        client,
        eventloop,
        sink,
        publications,
        measurement_filter,
        display_url,
        counters,
    } = bridge;
    let (stop_tx, stop_rx) = watch::channel(false);
    let (deliveries_tx, deliveries_rx) = mpsc::unbounded_channel();
    let reconnect = Notify::new();
    // The number of the current connection; deliveries carry the one they came on.
    let generation = AtomicU64::new(1);
    let connection = ConnectionLoop {
        eventloop,
        client: client.clone(),
        measurement_filter: measurement_filter.clone(),
        display_url: &display_url,
        deliveries: deliveries_tx,
        reconnect: &reconnect,
        generation: &generation,
        counters: &counters,
    };
    let ingest = IngestLoop {
        client: client.clone(),
        sink,
        measurement_filter,
        reconnect: &reconnect,
        generation: &generation,
        counters: &counters,
        order: IngestOrder::default(),
    };
    let signal = async move {
        shutdown.await;
        tracing::info!("mqtt: bridge stopping");
        let _ = stop_tx.send(true);
    };
    tokio::join!(
        connection.run(stop_rx.clone()),
        ingest.run(deliveries_rx, stop_rx.clone()),
        forward_publications(publications, client, stop_rx, &counters),
        signal,
    );
    tracing::info!(url = %display_url, "mqtt: bridge stopped");
}

/// One message from the broker, with the number of the connection it arrived on.
struct Delivery {
    generation: u64,
    publish: Publish,
}

/// Polls the rumqttc event loop: passes measurement messages on, resubscribes after every
/// CONNACK, reconnects on errors (with back-off) and on the ingest loop's request.
struct ConnectionLoop<'a> {
    eventloop: EventLoop,
    client: AsyncClient,
    measurement_filter: String,
    display_url: &'a str,
    deliveries: mpsc::UnboundedSender<Delivery>,
    reconnect: &'a Notify,
    generation: &'a AtomicU64,
    counters: &'a Counters,
}

impl ConnectionLoop<'_> {
    async fn run(mut self, mut stop: watch::Receiver<bool>) {
        let mut backoff = BACKOFF_MIN;
        // After the stop signal: until the DISCONNECT has left, at most this long.
        let mut stop_deadline: Option<Instant> = None;
        loop {
            // A poll is cancelled only when the connection is dropped next anyway (a cancelled
            // poll may leave a packet half written). The stop signal is therefore checked
            // between polls: after it, the ingest loop's DISCONNECT request wakes the poll.
            let polled = tokio::select! {
                polled = self.eventloop.poll() => polled,
                () = self.reconnect.notified() => {
                    tracing::warn!(url = %self.display_url, "mqtt: reconnecting so that the broker redelivers unacknowledged messages");
                    // Drops the connection; the next poll connects again.
                    self.eventloop.clean();
                    continue;
                }
                () = sleep_until_opt(stop_deadline) => return,
            };
            if stop_deadline.is_none() && *stop.borrow() {
                stop_deadline = Some(Instant::now() + 2 * SHUTDOWN_GRACE);
            }
            match polled {
                Ok(Event::Incoming(Packet::ConnAck(connack))) => {
                    backoff = BACKOFF_MIN;
                    let generation = self.generation.fetch_add(1, Ordering::SeqCst) + 1;
                    add(&self.counters.connections, 1);
                    tracing::info!(url = %self.display_url, session_present = connack.session_present, generation,
                        "mqtt: reconnected to the external broker");
                    // A broker that lost the session (restart without persistence) lost the
                    // subscription too; subscribing again is harmless otherwise.
                    let adapters = crate::mqtt::adapter_filter(&self.measurement_filter);
                    for filter in [self.measurement_filter.as_str(), adapters.as_str()] {
                        if let Err(error) = self.client.try_subscribe(filter, QoS::AtLeastOnce) {
                            tracing::error!(%error, "mqtt: cannot queue the measurement subscription");
                        }
                    }
                }
                Ok(Event::Incoming(Packet::Publish(publish))) => {
                    if stop_deadline.is_some() {
                        // Not acknowledged: the broker keeps it for the next run.
                        continue;
                    }
                    add(&self.counters.messages_received, 1);
                    let generation = self.generation.load(Ordering::SeqCst);
                    let _ = self.deliveries.send(Delivery { generation, publish });
                }
                Ok(Event::Incoming(Packet::SubAck(suback))) => {
                    if suback.return_codes.contains(&SubscribeReasonCode::Failure) {
                        tracing::error!(url = %self.display_url, filter = %self.measurement_filter,
                            "mqtt: the broker refused the measurement subscription (check its ACL)");
                    }
                }
                Ok(Event::Outgoing(Outgoing::Disconnect)) => return,
                Ok(_) => {}
                Err(error) => {
                    if stop_deadline.is_some() {
                        return;
                    }
                    add(&self.counters.connection_errors, 1);
                    // Packets read together with the failure wait in rumqttc's event queue and
                    // would come out after the next CONNACK, as if of the new connection. The
                    // broker redelivers unacknowledged messages of the persistent session, so
                    // they are dropped here instead of stored twice.
                    let stale = self.eventloop.state.events.len();
                    if stale > 0 {
                        self.eventloop.state.events.clear();
                        tracing::debug!(stale, "mqtt: dropped events read with the failed connection");
                    }
                    tracing::warn!(url = %self.display_url, %error, retry_in_ms = backoff.as_millis(),
                        "mqtt: connection to the external broker failed");
                    tokio::select! {
                        () = sleep(backoff) => {}
                        _ = stop.wait_for(|stopping| *stopping) => return,
                    }
                    backoff = (backoff * 2).min(BACKOFF_MAX);
                }
            }
        }
    }
}

/// Hands messages to the sink (up to [`MAX_PENDING_INGESTS`] at once) and acknowledges them in
/// arrival order once stored or refused as invalid. When the sink is unavailable, asks for a
/// new connection and leaves every message of the current one unacknowledged.
struct IngestLoop<'a> {
    client: AsyncClient,
    sink: Arc<dyn MeasurementSink>,
    measurement_filter: String,
    reconnect: &'a Notify,
    generation: &'a AtomicU64,
    counters: &'a Counters,
    /// The order the messages are queued in: the order they were delivered.
    order: IngestOrder,
}

/// A message in the sink.
type PendingIngest = std::pin::Pin<Box<dyn Future<Output = (Publish, Result<usize, IngestError>)> + Send>>;

impl IngestLoop<'_> {
    async fn run(mut self, mut deliveries: mpsc::UnboundedReceiver<Delivery>, mut stop: watch::Receiver<bool>) {
        let mut pending: FuturesOrdered<PendingIngest> = FuturesOrdered::new();
        // Messages of connections up to this number are left for the broker to redeliver.
        let mut abandoned_generation = 0u64;
        loop {
            tokio::select! {
                delivery = deliveries.recv(), if pending.len() < MAX_PENDING_INGESTS => {
                    let Some(delivery) = delivery else { break };
                    if delivery.generation <= abandoned_generation {
                        add(&self.counters.messages_redelivery_expected, 1);
                        continue;
                    }
                    if let Some(ingest) = self.start(delivery.publish).await {
                        pending.push_back(ingest);
                    }
                }
                Some((publish, result)) = pending.next(), if !pending.is_empty() => {
                    if !self.finish(&publish, result).await {
                        let abandoned = pending.len();
                        pending = FuturesOrdered::new();
                        abandoned_generation = self.generation.load(Ordering::SeqCst);
                        add(&self.counters.messages_redelivery_expected, u64::try_from(abandoned).unwrap_or(u64::MAX));
                        self.reconnect.notify_one();
                    }
                }
                _ = stop.changed() => break,
            }
        }
        // Shutdown: acknowledge what the sink still stores, then disconnect.
        let drained = timeout(SHUTDOWN_GRACE, async {
            while let Some((publish, result)) = pending.next().await {
                if !self.finish(&publish, result).await {
                    break;
                }
            }
        })
        .await;
        if drained.is_err() {
            tracing::warn!("mqtt: the sink did not finish in time; the broker will redeliver the rest");
        }
        if let Err(error) = self.client.disconnect().await {
            tracing::debug!(%error, "mqtt: cannot queue DISCONNECT");
        }
    }

    /// Starts storing a message; acknowledges at once (and returns `None`) a message outside
    /// the measurement filter, which a persistent session may still deliver from an older
    /// subscription.
    async fn start(&mut self, publish: Publish) -> Option<PendingIngest> {
        if !matches(&publish.topic, unshared(&self.measurement_filter))
            && !matches(&publish.topic, crate::mqtt::ADAPTER_FILTER)
        {
            tracing::warn!(topic = %publish.topic, filter = %self.measurement_filter,
                "mqtt: acknowledging and ignoring a message outside the measurement filter");
            self.acknowledge(&publish).await;
            return None;
        }
        let ingest = self.sink.ingest(
            &format!("mqtt:{}", publish.topic),
            publish.payload.clone(),
            &mut self.order,
        );
        Some(Box::pin(async move { (publish, ingest.await) }))
    }

    /// Acknowledges a stored (or invalid) message; `false` when the sink was unavailable and
    /// the connection must be replaced.
    async fn finish(&self, publish: &Publish, result: Result<usize, IngestError>) -> bool {
        match result {
            Ok(records) => {
                add(
                    &self.counters.records_stored,
                    u64::try_from(records).unwrap_or(u64::MAX),
                );
                self.acknowledge(publish).await;
                true
            }
            Err(IngestError::Invalid(reason)) => {
                add(&self.counters.messages_invalid, 1);
                tracing::warn!(topic = %publish.topic, %reason, "mqtt: invalid payload acknowledged and dropped");
                self.acknowledge(publish).await;
                true
            }
            Err(IngestError::Unavailable(reason) | IngestError::Unauthorized(reason)) => {
                add(&self.counters.messages_unavailable, 1);
                tracing::warn!(topic = %publish.topic, %reason,
                    "mqtt: the sink cannot take the message; leaving it to the broker to redeliver");
                false
            }
        }
    }

    async fn acknowledge(&self, publish: &Publish) {
        match self.client.ack(publish).await {
            Ok(()) => add(&self.counters.acks_sent, u64::from(publish.qos != QoS::AtMostOnce)),
            Err(error) => tracing::warn!(%error, "mqtt: cannot queue the acknowledgement"),
        }
    }
}

/// Publishes every publication to the broker at QoS 0 until stopped.
async fn forward_publications(
    mut publications: broadcast::Receiver<Publication>,
    client: AsyncClient,
    mut stop: watch::Receiver<bool>,
    counters: &Counters,
) {
    let forward = async {
        loop {
            match publications.recv().await {
                Ok(publication) => {
                    let topic = publication.topic;
                    match client
                        .publish_bytes(topic.as_str(), QoS::AtMostOnce, false, publication.payload)
                        .await
                    {
                        Ok(()) => add(&counters.publications_forwarded, 1),
                        Err(error) => {
                            add(&counters.publications_dropped, 1);
                            tracing::warn!(%topic, %error, "mqtt: cannot forward a publication");
                        }
                    }
                }
                Err(RecvError::Lagged(missed)) => {
                    add(&counters.publications_dropped, missed);
                    tracing::warn!(missed, "mqtt: the external broker is too slow, publications dropped");
                }
                Err(RecvError::Closed) => return,
            }
        }
    };
    tokio::select! {
        () = forward => {}
        _ = stop.changed() => {}
    }
}

/// Sleeps until `deadline`, or for ever without one.
async fn sleep_until_opt(deadline: Option<Instant>) {
    match deadline {
        Some(deadline) => tokio::time::sleep_until(deadline).await,
        None => std::future::pending().await,
    }
}

/// A filter without its shared-subscription prefix (`$share/<group>/<filter>` → `<filter>`):
/// the broker delivers the messages under their own topics.
fn unshared(filter: &str) -> &str {
    filter
        .strip_prefix("$share/")
        .and_then(|rest| rest.split_once('/'))
        .map_or(filter, |(_, filter)| filter)
}

#[cfg(test)]
mod tests {
    use super::unshared;

    #[test]
    fn a_shared_subscription_is_matched_by_the_filter_inside_it() {
        assert_eq!(unshared("$share/rtls/rtls/v1/measurements/#"), "rtls/v1/measurements/#");
        assert_eq!(unshared("rtls/v1/measurements/#"), "rtls/v1/measurements/#");
        assert_eq!(unshared("$share/only-a-group"), "$share/only-a-group");
    }
}
