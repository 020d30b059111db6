//! A connected client of the embedded broker: the session loop that stores measurement
//! payloads (acknowledging each only once stored), answers subscriptions and pings, and
//! delivers publications.

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use futures_util::stream::{FuturesOrdered, StreamExt};
use rumqttc::mqttbytes::v4::{
    ConnAck, ConnectReturnCode, Packet, PubAck, Publish, SubAck, Subscribe, SubscribeReasonCode, UnsubAck, Unsubscribe,
};
use rumqttc::mqttbytes::{matches, valid_filter, valid_topic, QoS};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::{broadcast, watch, Notify};
use tokio::time::{timeout, timeout_at, Instant};

use crate::auth::Access;
use crate::sink::{IngestError, IngestOrder, Publication};

use super::error_topic;
use super::frame::{self, Next};
use super::shared::Shared;
use super::stats::add;
use super::stream::{Reader, Writer};

/// How long a closing session (DISCONNECT, server shutdown) waits for the payloads it already
/// handed to the sink, to acknowledge them, before it closes anyway.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(5);

/// How long writing to a client may take before the connection is considered dead.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// How long a closing connection tries to write what is left in its output buffer.
pub(crate) const CLOSE_WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// The longest reader name a measurement topic (`rtls/v1/measurements/{reader}`) may carry, in
/// bytes.
pub(crate) const MAX_READER_NAME_BYTES: usize = 256;

/// A payload in the sink: what to do when its future resolves.
type PendingIngest = Pin<Box<dyn Future<Output = IngestDone> + Send>>;

/// A payload the sink has finished with.
struct IngestDone {
    /// The packet id to acknowledge (QoS 1), `None` for QoS 0.
    packet_id: Option<u16>,
    /// The topic it was published on.
    topic: String,
    /// The sink's answer.
    result: Result<usize, IngestError>,
}

/// Why a session ended.
#[derive(Debug, thiserror::Error)]
pub(crate) enum CloseReason {
    #[error("protocol violation: {0}")]
    Violation(String),
    #[error("the client closed the connection")]
    PeerClosed,
    #[error("no packet for {0:?} (1.5 × the client's keep-alive)")]
    KeepAliveExpired(Duration),
    #[error("the sink cannot take payloads now ({0}); unacknowledged payloads will be resent")]
    Unavailable(String),
    #[error("the sink refused a payload on {topic} as unauthorized: {reason}")]
    Refused { topic: String, reason: String },
    #[error("a new connection with the same client id took over")]
    TakenOver,
    #[error("i/o: {0}")]
    Io(std::io::Error),
    #[error("writing to the client took longer than {0:?}")]
    WriteTimeout(Duration),
    #[error("the client disconnected")]
    Disconnected,
    #[error("the server is shutting down")]
    Shutdown,
}

/// How the packet loop ended: at once, or after acknowledging what the sink still holds.
enum Ending {
    Close(CloseReason),
    Drain(CloseReason),
}

/// What woke the session loop.
enum Wake {
    Read(std::io::Result<usize>),
    Stored(IngestDone),
    Publication(Result<Publication, RecvError>),
    KeepAliveExpired,
    Stop,
    TakenOver,
}

/// The state of one connected client.
pub(crate) struct Session {
    shared: Arc<Shared>,
    client_id: String,
    access: Access,
    /// 1.5 × the keep-alive interval; `None` when the client asked for none.
    keep_alive_grace: Option<Duration>,
    reader: Reader,
    writer: Writer,
    /// Bytes read and not yet decoded.
    inbox: BytesMut,
    /// Packets encoded and not yet written.
    outbox: BytesMut,
    /// Topic filters subscribed to (all granted at QoS 0).
    filters: Vec<String>,
    /// Receives every publication while at least one filter is subscribed.
    publications: Option<broadcast::Receiver<Publication>>,
    /// Payloads in the sink, in arrival order (so acknowledgements keep that order).
    pending: FuturesOrdered<PendingIngest>,
    /// The order the connection's payloads are queued in: the order they arrived.
    order: IngestOrder,
    /// When the last packet arrived (or reading resumed after back-pressure).
    last_activity: Instant,
}

impl CloseReason {
    /// Whether the session ended the ordinary way (the client left, or the server stops).
    pub(crate) fn is_orderly(&self) -> bool {
        matches!(self, Self::Disconnected | Self::PeerClosed | Self::Shutdown)
    }
}

impl Session {
    /// A session for a client whose CONNECT was accepted, with its CONNACK queued.
    /// `keep_alive_s` is the client's keep-alive (0: none); `inbox` holds what arrived after
    /// the CONNECT.
    pub(crate) fn accept(
        shared: Arc<Shared>,
        client_id: String,
        access: Access,
        keep_alive_s: u16,
        (reader, writer): (Reader, Writer),
        inbox: BytesMut,
    ) -> Self {
        let mut session = Self {
            shared,
            client_id,
            access,
            keep_alive_grace: (keep_alive_s > 0).then(|| Duration::from_millis(u64::from(keep_alive_s) * 1500)),
            reader,
            writer,
            inbox,
            outbox: BytesMut::with_capacity(1024),
            filters: Vec::new(),
            publications: None,
            pending: FuturesOrdered::new(),
            order: IngestOrder::default(),
            last_activity: Instant::now(),
        };
        session.queue(&Packet::ConnAck(ConnAck::new(ConnectReturnCode::Success, false)));
        session
    }

    /// Runs the session to its end and closes the connection.
    pub(crate) async fn run(mut self, mut stop: watch::Receiver<bool>, taken_over: &Notify) -> CloseReason {
        let reason = match self.serve_packets(&mut stop, taken_over).await {
            Ending::Close(reason) => reason,
            Ending::Drain(reason) => self.drain(reason).await,
        };
        let _ = timeout(CLOSE_WRITE_TIMEOUT, async {
            let _ = self.writer.write_all(&self.outbox).await;
            let _ = self.writer.shutdown().await;
        })
        .await;
        reason
    }

    fn max_inflight(&self) -> usize {
        self.shared.config.max_inflight_per_connection
    }

    /// The session loop: decode and handle what has arrived, write what is queued, then wait
    /// for the next input, stored payload, publication, time-out or stop.
    async fn serve_packets(&mut self, stop: &mut watch::Receiver<bool>, taken_over: &Notify) -> Ending {
        loop {
            if let Some(ending) = self.process_buffered() {
                return ending;
            }
            if let Err(reason) = self.flush().await {
                return Ending::Close(reason);
            }
            let reading = self.pending.len() < self.max_inflight();
            let keep_alive_deadline = self.keep_alive_grace.map(|grace| self.last_activity + grace);
            let wake = tokio::select! {
                read = self.reader.read_buf(&mut self.inbox), if reading => Wake::Read(read),
                Some(done) = self.pending.next(), if !self.pending.is_empty() => Wake::Stored(done),
                received = next_publication(&mut self.publications) => Wake::Publication(received),
                () = tokio::time::sleep_until(keep_alive_deadline.unwrap_or_else(Instant::now)),
                    if reading && keep_alive_deadline.is_some() => Wake::KeepAliveExpired,
                _ = stop.changed() => Wake::Stop,
                () = taken_over.notified() => Wake::TakenOver,
            };
            let ending = match wake {
                Wake::Read(Ok(0)) => Some(Ending::Close(CloseReason::PeerClosed)),
                Wake::Read(Ok(_)) => None,
                Wake::Read(Err(error)) => Some(Ending::Close(CloseReason::Io(error))),
                Wake::Stored(done) => {
                    if !reading {
                        // Reading resumes now: the client could not be heard while paused.
                        self.last_activity = Instant::now();
                    }
                    self.finish_ingest(done).map(Ending::Close)
                }
                Wake::Publication(received) => {
                    self.deliver(received);
                    None
                }
                Wake::KeepAliveExpired => self
                    .keep_alive_grace
                    .map(|grace| Ending::Close(CloseReason::KeepAliveExpired(grace))),
                Wake::Stop => Some(Ending::Drain(CloseReason::Shutdown)),
                Wake::TakenOver => Some(Ending::Close(CloseReason::TakenOver)),
            };
            if let Some(ending) = ending {
                return ending;
            }
        }
    }

    /// Handles the packets already buffered, as long as the sink may take more payloads.
    fn process_buffered(&mut self) -> Option<Ending> {
        while self.pending.len() < self.max_inflight() {
            match frame::next_packet(&mut self.inbox, self.shared.config.max_packet_bytes) {
                Ok(Next::Incomplete { needed_bytes }) => {
                    self.inbox.reserve(needed_bytes);
                    return None;
                }
                Ok(Next::Packet(packet)) => {
                    self.last_activity = Instant::now();
                    if let Some(ending) = self.handle(packet) {
                        return Some(ending);
                    }
                }
                Err(error) => return Some(self.violation(error.to_string())),
            }
        }
        None
    }

    /// Handles one packet of a connected client.
    fn handle(&mut self, packet: Packet) -> Option<Ending> {
        match packet {
            Packet::Publish(publish) => self.accept_publish(publish),
            Packet::Subscribe(subscribe) => {
                self.subscribe(subscribe);
                None
            }
            Packet::Unsubscribe(unsubscribe) => {
                self.unsubscribe(unsubscribe);
                None
            }
            Packet::PingReq => {
                self.queue(&Packet::PingResp);
                None
            }
            Packet::Disconnect => Some(Ending::Drain(CloseReason::Disconnected)),
            other => Some(self.violation(format!("unexpected {} from a client", packet_name(&other)))),
        }
    }

    /// Counts a protocol violation and ends the session.
    fn violation(&self, reason: String) -> Ending {
        add(&self.shared.counters.protocol_violations, 1);
        Ending::Close(CloseReason::Violation(reason))
    }

    /// Hands a measurement PUBLISH to the sink, or ends the session if it is not allowed.
    fn accept_publish(&mut self, publish: Publish) -> Option<Ending> {
        let topic = &publish.topic;
        if publish.qos == QoS::ExactlyOnce {
            return Some(self.violation(format!("QoS 2 PUBLISH on {topic:?}: only QoS 0 and 1 are supported")));
        }
        if self.access != Access::Write {
            return Some(self.violation(format!(
                "PUBLISH on {topic:?} with a read-only token: publishing needs the write token"
            )));
        }
        let prefix = &self.shared.config.measurement_prefix;
        // MQTT 3.1.1 §1.5.3: no U+0000 in a topic name; ours name a reader, 256 bytes at most
        if topic.contains('\0') || topic.len() > prefix.len() + MAX_READER_NAME_BYTES {
            return Some(self.violation(format!(
                "PUBLISH on {:?}…: a topic must hold no NUL and name a reader in at most {MAX_READER_NAME_BYTES} bytes",
                topic.chars().take(64).collect::<String>()
            )));
        }
        let measurement = topic.starts_with(prefix.as_str()) && topic.len() > prefix.len();
        let adapter = crate::adapters::Vendor::from_topic(topic).is_some();
        if !valid_topic(topic) || !(measurement || adapter) {
            return Some(self.violation(format!(
                "PUBLISH on {topic:?}: clients may publish only to {prefix}{{reader}} or {}{{vendor}}/…",
                crate::adapters::MQTT_PREFIX
            )));
        }
        add(&self.shared.counters.publishes_received, 1);
        let ingest = self
            .shared
            .sink
            .ingest(&format!("mqtt:{topic}"), publish.payload, &mut self.order);
        let packet_id = (publish.qos == QoS::AtLeastOnce).then_some(publish.pkid);
        let topic = publish.topic;
        self.pending.push_back(Box::pin(async move {
            IngestDone {
                packet_id,
                topic,
                result: ingest.await,
            }
        }));
        None
    }

    /// Acknowledges a stored payload, or reports why it was not stored. Returns the reason to
    /// close the connection when the sink could not take the payload.
    fn finish_ingest(&mut self, done: IngestDone) -> Option<CloseReason> {
        let counters = &self.shared.counters;
        match done.result {
            Ok(records) => {
                add(&counters.records_stored, u64::try_from(records).unwrap_or(u64::MAX));
                self.acknowledge(done.packet_id);
                None
            }
            Err(IngestError::Invalid(reason)) => {
                add(&counters.publishes_invalid, 1);
                tracing::warn!(client_id = %self.client_id, topic = %done.topic, %reason,
                    "mqtt: invalid payload acknowledged and reported on the error topic");
                self.report_error(&done.topic, &reason);
                self.acknowledge(done.packet_id);
                None
            }
            Err(IngestError::Unavailable(reason)) => {
                add(&counters.publishes_unavailable, 1);
                Some(CloseReason::Unavailable(reason))
            }
            Err(IngestError::Unauthorized(reason)) => {
                add(&counters.publishes_unavailable, 1);
                Some(CloseReason::Refused {
                    topic: done.topic,
                    reason,
                })
            }
        }
    }

    /// Queues the PUBACK of a QoS 1 payload.
    fn acknowledge(&mut self, packet_id: Option<u16>) {
        if let Some(pkid) = packet_id {
            if self.queue(&Packet::PubAck(PubAck::new(pkid))) {
                add(&self.shared.counters.acks_sent, 1);
            }
        }
    }

    /// Sends `{"topic": …, "error": …}` on the client's error topic, if it subscribed to it.
    fn report_error(&mut self, topic: &str, reason: &str) {
        let error_topic = error_topic(&self.client_id);
        if !self.filters.iter().any(|filter| matches(&error_topic, filter)) {
            return;
        }
        let payload = serde_json::json!({ "topic": topic, "error": reason }).to_string();
        let publish = Publish::from_bytes(error_topic, QoS::AtMostOnce, Bytes::from(payload));
        if self.queue(&Packet::Publish(publish)) {
            add(&self.shared.counters.messages_delivered, 1);
        }
    }

    /// Grants the valid filters at QoS 0 and starts receiving publications.
    fn subscribe(&mut self, subscribe: Subscribe) {
        let mut codes = Vec::with_capacity(subscribe.filters.len());
        for filter in subscribe.filters {
            if valid_filter(&filter.path) && !filter.path.contains('\0') {
                if !self.filters.contains(&filter.path) {
                    self.filters.push(filter.path);
                }
                codes.push(SubscribeReasonCode::Success(QoS::AtMostOnce));
            } else {
                tracing::warn!(client_id = %self.client_id, filter = %filter.path, "mqtt: invalid topic filter refused");
                codes.push(SubscribeReasonCode::Failure);
            }
        }
        // Receive before the SUBACK leaves, so that every publication sent after the client
        // saw its SUBACK reaches it.
        if !self.filters.is_empty() && self.publications.is_none() {
            self.publications = Some(self.shared.publications.subscribe());
        }
        self.queue(&Packet::SubAck(SubAck::new(subscribe.pkid, codes)));
    }

    /// Removes filters; with none left, stops receiving publications.
    fn unsubscribe(&mut self, unsubscribe: Unsubscribe) {
        self.filters.retain(|filter| !unsubscribe.topics.contains(filter));
        if self.filters.is_empty() {
            self.publications = None;
        }
        self.queue(&Packet::UnsubAck(UnsubAck::new(unsubscribe.pkid)));
    }

    /// Forwards a publication if a filter matches it; counts what a lagging receiver missed.
    fn deliver(&mut self, received: Result<Publication, RecvError>) {
        match received {
            Ok(publication) => {
                if self.filters.iter().any(|filter| matches(&publication.topic, filter)) {
                    let publish = Publish::from_bytes(publication.topic, QoS::AtMostOnce, publication.payload);
                    if self.queue(&Packet::Publish(publish)) {
                        add(&self.shared.counters.messages_delivered, 1);
                    }
                }
            }
            Err(RecvError::Lagged(missed)) => {
                add(&self.shared.counters.messages_dropped, missed);
                tracing::warn!(client_id = %self.client_id, missed, "mqtt: subscriber too slow, publications dropped");
            }
            Err(RecvError::Closed) => self.publications = None,
        }
    }

    /// Encodes a packet into the output buffer; `false` (and a log line) if it cannot be
    /// encoded.
    fn queue(&mut self, packet: &Packet) -> bool {
        match frame::encode(packet, &mut self.outbox) {
            Ok(()) => true,
            Err(error) => {
                tracing::error!(client_id = %self.client_id, %error, packet = packet_name(packet), "mqtt: cannot encode");
                false
            }
        }
    }

    /// Writes the output buffer.
    async fn flush(&mut self) -> Result<(), CloseReason> {
        if self.outbox.is_empty() {
            return Ok(());
        }
        match timeout(WRITE_TIMEOUT, self.writer.write_all(&self.outbox)).await {
            Ok(Ok(())) => {
                self.outbox.clear();
                Ok(())
            }
            Ok(Err(error)) => Err(CloseReason::Io(error)),
            Err(_elapsed) => Err(CloseReason::WriteTimeout(WRITE_TIMEOUT)),
        }
    }

    /// Reads nothing more; waits (at most [`DRAIN_TIMEOUT`]) for the payloads in the sink and
    /// acknowledges them.
    async fn drain(&mut self, reason: CloseReason) -> CloseReason {
        let deadline = Instant::now() + DRAIN_TIMEOUT;
        while !self.pending.is_empty() {
            let Ok(Some(done)) = timeout_at(deadline, self.pending.next()).await else {
                tracing::warn!(client_id = %self.client_id, unacknowledged = self.pending.len(),
                    "mqtt: closing before the sink finished; the client will resend");
                break;
            };
            if let Some(close) = self.finish_ingest(done) {
                return close;
            }
            if let Err(close) = self.flush().await {
                return close;
            }
        }
        reason
    }
}

/// The next publication, or never when not subscribed.
async fn next_publication(receiver: &mut Option<broadcast::Receiver<Publication>>) -> Result<Publication, RecvError> {
    match receiver {
        Some(receiver) => receiver.recv().await,
        None => std::future::pending().await,
    }
}

/// The packet's name for log lines.
pub(crate) fn packet_name(packet: &Packet) -> &'static str {
    match packet {
        Packet::Connect(_) => "CONNECT",
        Packet::ConnAck(_) => "CONNACK",
        Packet::Publish(_) => "PUBLISH",
        Packet::PubAck(_) => "PUBACK",
        Packet::PubRec(_) => "PUBREC",
        Packet::PubRel(_) => "PUBREL",
        Packet::PubComp(_) => "PUBCOMP",
        Packet::Subscribe(_) => "SUBSCRIBE",
        Packet::SubAck(_) => "SUBACK",
        Packet::Unsubscribe(_) => "UNSUBSCRIBE",
        Packet::UnsubAck(_) => "UNSUBACK",
        Packet::PingReq => "PINGREQ",
        Packet::PingResp => "PINGRESP",
        Packet::Disconnect => "DISCONNECT",
    }
}
