//! Shared by the MQTT integration tests: a sink that records what it got and can be told to
//! delay or fail, an MQTT client driven by rumqttc whose events the test reads in order, and
//! an embedded broker on a free port.
#![allow(dead_code)] // each test binary uses a different part

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use rtls_server::auth::Tokens;
use rtls_server::mqtt::{BrokerConfig, BrokerStatsHandle, EmbeddedBroker};
use rtls_server::sink::{IngestError, IngestFuture, IngestOrder, MeasurementSink, Publication};
use rumqttc::mqttbytes::v4::Connect;
use rumqttc::{AsyncClient, ConnectionError, Event, MqttOptions, Packet};
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;
use tokio::sync::{broadcast, mpsc, oneshot};
use tokio::task::JoinHandle;
use tokio::time::Instant;

/// The write token of the test brokers.
pub const WRITE_TOKEN: &str = "w-token";
/// The read token of the test brokers.
pub const READ_TOKEN: &str = "r-token";

/// One JSON line of the measurement format: a range of `tag` at time `t_s`.
pub fn record_line(tag: &str, t_s: f64) -> String {
    format!(r#"{{"t":{t_s},"tag":"{tag}","kind":"range","anchor":"a1","range_m":2.5}}"#)
}

/// One call of the sink, recorded when its future resolved.
#[derive(Debug, Clone)]
pub struct SinkCall {
    /// The source the transport named.
    pub source: String,
    /// The payload as received.
    pub payload: Bytes,
    /// When the future resolved (the records were "durable" from then on).
    pub completed_at: Instant,
    /// What the future resolved to.
    pub result: Result<usize, IngestError>,
}

#[derive(Debug, Default)]
struct SinkState {
    delay: Duration,
    jitter_ms: u64,
    unavailable_remaining: usize,
    started: u64,
    in_flight: usize,
    max_in_flight: usize,
    calls: Vec<SinkCall>,
}

/// A sink that parses payloads like the real one (each non-empty line must be a JSON object
/// with `t`, `tag` and `kind`), takes `delay` (+ a deterministic jitter) to "store" them, can be
/// told to answer `Unavailable` a number of times, and records every call.
#[derive(Debug, Clone, Default)]
pub struct TestSink {
    state: Arc<Mutex<SinkState>>,
}

impl TestSink {
    /// A sink that stores at once.
    pub fn new() -> Self {
        Self::default()
    }

    /// Every call takes `delay` plus `(call number × 7) mod jitter_ms` milliseconds, so that
    /// later payloads may finish before earlier ones.
    pub fn with_delay(self, delay: Duration, jitter_ms: u64) -> Self {
        {
            let mut state = self.lock();
            state.delay = delay;
            state.jitter_ms = jitter_ms;
        }
        self
    }

    /// The next `count` calls answer `Unavailable`.
    pub fn fail_unavailable(&self, count: usize) {
        self.lock().unavailable_remaining = count;
    }

    /// The calls that have completed, in completion order.
    pub fn calls(&self) -> Vec<SinkCall> {
        self.lock().calls.clone()
    }

    /// The most payloads that were in the sink at the same time.
    pub fn max_in_flight(&self) -> usize {
        self.lock().max_in_flight
    }

    /// Waits until at least `count` calls have completed.
    pub async fn wait_for_calls(&self, count: usize, within: Duration) -> Vec<SinkCall> {
        let deadline = Instant::now() + within;
        loop {
            let calls = self.calls();
            if calls.len() >= count {
                return calls;
            }
            assert!(
                Instant::now() < deadline,
                "the sink completed {} calls within {within:?}, expected {count}",
                calls.len()
            );
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, SinkState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// What the real sink would answer: the number of records, or `Invalid` naming the line.
fn parse_records(payload: &[u8]) -> Result<usize, IngestError> {
    let text = std::str::from_utf8(payload).map_err(|e| IngestError::Invalid(format!("payload is not UTF-8: {e}")))?;
    let mut records = 0;
    for (index, line) in text.lines().enumerate().filter(|(_, line)| !line.trim().is_empty()) {
        let value: serde_json::Value = serde_json::from_str(line)
            .map_err(|e| IngestError::Invalid(format!("line {}: not JSON: {e}", index + 1)))?;
        for field in ["t", "tag", "kind"] {
            if value.get(field).is_none() {
                return Err(IngestError::Invalid(format!(
                    "line {}: missing field {field}",
                    index + 1
                )));
            }
        }
        records += 1;
    }
    Ok(records)
}

impl MeasurementSink for TestSink {
    fn ingest(&self, source: &str, payload: Bytes, _order: &mut IngestOrder) -> IngestFuture {
        let (delay, unavailable) = {
            let mut state = self.lock();
            let jitter = if state.jitter_ms == 0 {
                0
            } else {
                (state.started * 7) % state.jitter_ms
            };
            state.started += 1;
            state.in_flight += 1;
            state.max_in_flight = state.max_in_flight.max(state.in_flight);
            let unavailable = state.unavailable_remaining > 0;
            if unavailable {
                state.unavailable_remaining -= 1;
            }
            (state.delay + Duration::from_millis(jitter), unavailable)
        };
        let sink = self.clone();
        let source = source.to_owned();
        Box::pin(async move {
            tokio::time::sleep(delay).await;
            let result = if unavailable {
                Err(IngestError::Unavailable("test sink told to be unavailable".into()))
            } else {
                parse_records(&payload)
            };
            let mut state = sink.lock();
            state.in_flight -= 1;
            state.calls.push(SinkCall {
                source,
                payload,
                completed_at: Instant::now(),
                result: result.clone(),
            });
            result
        })
    }
}

/// An event of a test client's event loop, with the time the test saw it.
#[derive(Debug)]
pub enum ClientEvent {
    /// A packet in or out.
    Event(Event, Instant),
    /// The connection failed (rumqttc reconnects on the next poll, if told to go on).
    Error(ConnectionError, Instant),
}

/// A rumqttc client whose event loop runs in a task of its own; the test reads the events.
pub struct TestClient {
    /// The client handle (publish, subscribe, …).
    pub client: AsyncClient,
    events: mpsc::UnboundedReceiver<ClientEvent>,
    pump: JoinHandle<()>,
}

impl Drop for TestClient {
    fn drop(&mut self) {
        self.pump.abort();
    }
}

/// Options of a test client of the broker at `addr`: keep-alive 5 s, the given password.
pub fn client_options(addr: SocketAddr, client_id: &str, password: Option<&str>) -> MqttOptions {
    let mut options = MqttOptions::new(client_id, addr.ip().to_string(), addr.port());
    options.set_keep_alive(Duration::from_secs(5));
    if let Some(password) = password {
        options.set_credentials("test-user", password);
    }
    options
}

impl TestClient {
    /// Starts a client. With `reconnect`, the event loop is polled again 50 ms after an error
    /// (rumqttc then reconnects and resends unacknowledged publishes); without, it stops at the
    /// first error.
    pub fn start(options: MqttOptions, reconnect: bool) -> Self {
        let (client, mut eventloop) = AsyncClient::new(options, 16);
        let (tx, events) = mpsc::unbounded_channel();
        let pump = tokio::spawn(async move {
            loop {
                match eventloop.poll().await {
                    Ok(event) => {
                        if tx.send(ClientEvent::Event(event, Instant::now())).is_err() {
                            return;
                        }
                    }
                    Err(error) => {
                        // rumqttc 0.25 reads what arrived with the close (a PUBACK, say) into
                        // its event queue and returns the error first: those came before it.
                        for event in eventloop.state.events.drain(..) {
                            let _ = tx.send(ClientEvent::Event(event, Instant::now()));
                        }
                        if tx.send(ClientEvent::Error(error, Instant::now())).is_err() || !reconnect {
                            return;
                        }
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                }
            }
        });
        Self { client, events, pump }
    }

    /// The next event, or `None` when none came within `within`.
    pub async fn next_event(&mut self, within: Duration) -> Option<ClientEvent> {
        tokio::time::timeout(within, self.events.recv()).await.ok().flatten()
    }

    /// Skips events until an incoming packet satisfies `wanted`; panics on an error or after
    /// `within`.
    pub async fn expect_incoming(
        &mut self,
        within: Duration,
        what: &str,
        wanted: impl Fn(&Packet) -> bool,
    ) -> (Packet, Instant) {
        let deadline = Instant::now() + within;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.next_event(left).await {
                Some(ClientEvent::Event(Event::Incoming(packet), at)) if wanted(&packet) => return (packet, at),
                Some(ClientEvent::Event(..)) => {}
                Some(ClientEvent::Error(error, _)) => panic!("waiting for {what}: connection error {error:?}"),
                None => panic!("no {what} within {within:?}"),
            }
        }
    }

    /// Waits for the CONNACK of the first connection.
    pub async fn connected(&mut self) {
        self.expect_incoming(Duration::from_secs(2), "CONNACK", |p| matches!(p, Packet::ConnAck(_)))
            .await;
    }

    /// Skips events until an error; panics if an incoming packet satisfies `forbidden` first or
    /// no error comes within `within`. Returns the error and the events skipped.
    pub async fn expect_error(
        &mut self,
        within: Duration,
        forbidden: impl Fn(&Packet) -> bool,
    ) -> (ConnectionError, Vec<Event>) {
        let deadline = Instant::now() + within;
        let mut skipped = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.next_event(left).await {
                Some(ClientEvent::Error(error, _)) => return (error, skipped),
                Some(ClientEvent::Event(Event::Incoming(packet), _)) if forbidden(&packet) => {
                    panic!("got {packet:?} where the connection should have closed")
                }
                Some(ClientEvent::Event(event, _)) => skipped.push(event),
                None => panic!("the connection did not close within {within:?}"),
            }
        }
    }
}

/// A broker configuration with the test tokens and small limits.
pub fn test_config() -> BrokerConfig {
    let mut config = BrokerConfig::new(Tokens::new(WRITE_TOKEN, Some(READ_TOKEN.into())));
    config.max_packet_bytes = 64 * 1024;
    config.max_inflight_per_connection = 16;
    config.max_connections = 64;
    config
}

/// An embedded broker running on a free port of 127.0.0.1.
pub struct TestBroker {
    /// Where it listens.
    pub addr: SocketAddr,
    /// Its counters.
    pub stats: BrokerStatsHandle,
    /// Publications sent here reach its subscribers.
    pub publications: broadcast::Sender<Publication>,
    stop: Option<oneshot::Sender<()>>,
    task: Option<JoinHandle<()>>,
}

impl TestBroker {
    /// Binds and runs a broker with `config` in front of `sink`.
    pub async fn start(config: BrokerConfig, sink: TestSink) -> Self {
        let (publications, _) = broadcast::channel(64);
        let broker = EmbeddedBroker::bind(
            "127.0.0.1:0".parse().expect("address"),
            config,
            Arc::new(sink),
            publications.clone(),
        )
        .await
        .expect("the broker binds to a free port");
        let addr = broker.local_addr();
        let stats = broker.stats_handle();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(broker.run(async move {
            let _ = stopped.await;
        }));
        Self {
            addr,
            stats,
            publications,
            stop: Some(stop),
            task: Some(task),
        }
    }

    /// Tells the broker to stop and waits (at most `within`) until `run` returned.
    pub async fn shutdown(mut self, within: Duration) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(task) = self.task.take() {
            tokio::time::timeout(within, task)
                .await
                .expect("the broker stops in time")
                .expect("the broker task did not panic");
        }
    }
}

impl Drop for TestBroker {
    fn drop(&mut self) {
        if let Some(task) = &self.task {
            task.abort();
        }
    }
}

/// Reads from a raw connection until the server closes it; panics if it stays open `within`.
/// Returns what was read before the close.
pub async fn read_until_closed(stream: &mut TcpStream, within: Duration) -> Vec<u8> {
    let mut received = Vec::new();
    let deadline = Instant::now() + within;
    let mut chunk = [0u8; 256];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match tokio::time::timeout(left, stream.read(&mut chunk)).await {
            Ok(Ok(0) | Err(_)) => return received,
            Ok(Ok(n)) => received.extend_from_slice(&chunk[..n]),
            Err(_) => panic!("the server kept the connection open for {within:?} (read {received:?})"),
        }
    }
}

/// The bytes of a CONNECT with the write token and the given keep-alive.
pub fn raw_connect(client_id: &str, keep_alive_s: u16) -> BytesMut {
    let mut connect = Connect::new(client_id);
    connect.keep_alive = keep_alive_s;
    connect.set_login("raw", WRITE_TOKEN);
    let mut bytes = BytesMut::new();
    connect.write(&mut bytes).expect("encodable CONNECT");
    bytes
}

/// CONNACK "accepted, no session present".
pub const CONNACK_ACCEPTED: [u8; 4] = [0x20, 0x02, 0x00, 0x00];
