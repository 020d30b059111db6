//! The embedded MQTT 3.1.1 broker: configuration, statistics, the accept loop and shutdown.
//! What happens on one connection is in [`super::session`].

use std::collections::HashMap;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use rumqttc::mqttbytes::valid_topic;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{broadcast, watch, Notify, Semaphore};
use tokio::task::JoinSet;

use crate::auth::Tokens;
use crate::sink::{MeasurementSink, Publication};

use super::connection;

/// What the embedded broker allows; see the module documentation of [`crate::mqtt`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerConfig {
    /// The access tokens: the CONNECT password is compared with them.
    pub tokens: Tokens,
    /// The topic prefix under which PUBLISH packets are measurement payloads, normally
    /// [`MEASUREMENT_PREFIX`](super::MEASUREMENT_PREFIX) (`rtls/v1/measurements/`). Must end
    /// with `/`; the topic must have at least one character after it.
    pub measurement_prefix: String,
    /// The largest packet accepted, in bytes, counted without its 2–5-byte fixed header (the
    /// MQTT "remaining length"). A larger packet closes its connection.
    pub max_packet_bytes: usize,
    /// How many payloads of one connection may be in the sink at once. While that many are
    /// pending, the broker reads nothing more from the connection.
    pub max_inflight_per_connection: usize,
    /// How many client connections may be open at once; one more is refused with CONNACK
    /// "server unavailable".
    pub max_connections: usize,
}

impl BrokerConfig {
    /// Default for [`BrokerConfig::max_packet_bytes`]: 1 MiB.
    pub const DEFAULT_MAX_PACKET_BYTES: usize = 1 << 20;
    /// Default for [`BrokerConfig::max_inflight_per_connection`].
    pub const DEFAULT_MAX_INFLIGHT_PER_CONNECTION: usize = 32;
    /// Default for [`BrokerConfig::max_connections`].
    pub const DEFAULT_MAX_CONNECTIONS: usize = 1024;

    /// The default configuration with the given tokens: measurements under
    /// [`MEASUREMENT_PREFIX`](super::MEASUREMENT_PREFIX) and the `DEFAULT_*` limits.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::auth::Tokens;
    /// use rtls_server::mqtt::BrokerConfig;
    ///
    /// let config = BrokerConfig::new(Tokens { write: "w".into(), read: None });
    /// assert_eq!(config.measurement_prefix, "rtls/v1/measurements/");
    /// ```
    #[must_use]
    pub fn new(tokens: Tokens) -> Self {
        Self {
            tokens,
            measurement_prefix: super::MEASUREMENT_PREFIX.to_owned(),
            max_packet_bytes: Self::DEFAULT_MAX_PACKET_BYTES,
            max_inflight_per_connection: Self::DEFAULT_MAX_INFLIGHT_PER_CONNECTION,
            max_connections: Self::DEFAULT_MAX_CONNECTIONS,
        }
    }

    /// Checks the fields that have to make sense before the broker starts.
    fn validate(&self) -> Result<(), BrokerError> {
        let invalid = |field: &'static str, reason: &str| {
            Err(BrokerError::Config {
                field,
                reason: reason.to_owned(),
            })
        };
        if !self.measurement_prefix.ends_with('/') || !valid_topic(&self.measurement_prefix) {
            return invalid(
                "measurement_prefix",
                "must be a topic ending with '/' and without wildcards, e.g. \"rtls/v1/measurements/\"",
            );
        }
        if self.max_packet_bytes < 64 {
            return invalid("max_packet_bytes", "must be at least 64 bytes");
        }
        if self.max_inflight_per_connection == 0 {
            return invalid("max_inflight_per_connection", "must be at least 1");
        }
        if self.max_connections == 0 {
            return invalid("max_connections", "must be at least 1");
        }
        Ok(())
    }
}

/// Why the embedded broker could not start.
#[derive(Debug, thiserror::Error)]
pub enum BrokerError {
    /// The listening socket could not be opened (address in use, no permission).
    #[error("mqtt: cannot listen on {addr}: {source} (is another broker running there?)")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A configuration field is out of range.
    #[error("mqtt broker configuration: {field} {reason}")]
    Config {
        /// The field of [`BrokerConfig`].
        field: &'static str,
        /// What is wrong and what is allowed.
        reason: String,
    },
}

/// A snapshot of the embedded broker's counters (totals since it started, except
/// `connections_open`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BrokerStats {
    /// TCP connections accepted.
    pub connections_accepted: u64,
    /// MQTT sessions open now (CONNECT accepted, not yet closed).
    pub connections_open: u64,
    /// Connections refused at CONNECT: wrong token, protocol version, client id, or the
    /// connection limit.
    pub connections_refused: u64,
    /// Connections closed for a protocol violation: malformed or oversize packet, forbidden
    /// PUBLISH (read-only token, topic outside the prefix, QoS 2), unexpected packet.
    pub protocol_violations: u64,
    /// Measurement PUBLISH packets handed to the sink.
    pub publishes_received: u64,
    /// Records the sink stored from them.
    pub records_stored: u64,
    /// PUBACKs sent.
    pub acks_sent: u64,
    /// Payloads the sink refused as invalid (acknowledged and reported on the error topic).
    pub publishes_invalid: u64,
    /// Payloads the sink could not take (not acknowledged; the connection was closed).
    pub publishes_unavailable: u64,
    /// Publications written to subscribers.
    pub messages_delivered: u64,
    /// Publications a lagging subscriber missed.
    pub messages_dropped: u64,
}

/// The live counters behind [`BrokerStats`].
#[derive(Debug, Default)]
pub(crate) struct Counters {
    pub(crate) connections_accepted: AtomicU64,
    pub(crate) connections_open: AtomicU64,
    pub(crate) connections_refused: AtomicU64,
    pub(crate) protocol_violations: AtomicU64,
    pub(crate) publishes_received: AtomicU64,
    pub(crate) records_stored: AtomicU64,
    pub(crate) acks_sent: AtomicU64,
    pub(crate) publishes_invalid: AtomicU64,
    pub(crate) publishes_unavailable: AtomicU64,
    pub(crate) messages_delivered: AtomicU64,
    pub(crate) messages_dropped: AtomicU64,
}

/// Adds `amount` to a counter.
pub(crate) fn add(counter: &AtomicU64, amount: u64) {
    counter.fetch_add(amount, Ordering::Relaxed);
}

/// A cheap, cloneable handle on the embedded broker's counters that outlives
/// [`EmbeddedBroker::run`]'s consumption of the broker (e.g. for a metrics endpoint).
#[derive(Debug, Clone)]
pub struct BrokerStatsHandle(Arc<Counters>);

impl BrokerStatsHandle {
    /// The counters now.
    #[must_use]
    pub fn snapshot(&self) -> BrokerStats {
        let c = &self.0;
        let get = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        BrokerStats {
            connections_accepted: get(&c.connections_accepted),
            connections_open: get(&c.connections_open),
            connections_refused: get(&c.connections_refused),
            protocol_violations: get(&c.protocol_violations),
            publishes_received: get(&c.publishes_received),
            records_stored: get(&c.records_stored),
            acks_sent: get(&c.acks_sent),
            publishes_invalid: get(&c.publishes_invalid),
            publishes_unavailable: get(&c.publishes_unavailable),
            messages_delivered: get(&c.messages_delivered),
            messages_dropped: get(&c.messages_dropped),
        }
    }
}

/// The sessions by client id, so that a new CONNECT with an id in use closes the older session
/// (MQTT 3.1.1 §3.1.4).
#[derive(Debug, Default)]
pub(crate) struct ClientRegistry {
    sessions: Mutex<HashMap<String, (u64, Arc<Notify>)>>,
}

impl ClientRegistry {
    /// Registers session `connection_no` as `client_id`, tells the session it replaces (if any)
    /// to close, and returns the signal by which this session will be told.
    pub(crate) fn register(&self, client_id: &str, connection_no: u64) -> Arc<Notify> {
        let taken_over = Arc::new(Notify::new());
        let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((_, previous)) = sessions.insert(client_id.to_owned(), (connection_no, Arc::clone(&taken_over))) {
            previous.notify_one();
        }
        taken_over
    }

    /// Removes `client_id` unless a newer session registered it since.
    pub(crate) fn unregister(&self, client_id: &str, connection_no: u64) {
        let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
        if sessions.get(client_id).is_some_and(|(no, _)| *no == connection_no) {
            sessions.remove(client_id);
        }
    }
}

/// What every connection task shares.
pub(crate) struct Shared {
    pub(crate) config: BrokerConfig,
    pub(crate) sink: Arc<dyn MeasurementSink>,
    pub(crate) publications: broadcast::Sender<Publication>,
    pub(crate) counters: Arc<Counters>,
    pub(crate) clients: ClientRegistry,
}

/// The embedded MQTT 3.1.1 broker, bound to its address and ready to [`run`](Self::run).
///
/// # Examples
/// ```no_run
/// # async fn example(sink: std::sync::Arc<dyn rtls_server::sink::MeasurementSink>) -> Result<(), rtls_server::mqtt::BrokerError> {
/// use rtls_server::auth::Tokens;
/// use rtls_server::mqtt::{BrokerConfig, EmbeddedBroker};
///
/// let (publications, _) = tokio::sync::broadcast::channel(1024);
/// let config = BrokerConfig::new(Tokens { write: "secret".into(), read: None });
/// let broker = EmbeddedBroker::bind("127.0.0.1:1883".parse().unwrap(), config, sink, publications).await?;
/// println!("mqtt on {}", broker.local_addr());
/// broker.run(async { let _ = tokio::signal::ctrl_c().await; }).await;
/// # Ok(()) }
/// ```
pub struct EmbeddedBroker {
    listener: TcpListener,
    local_addr: SocketAddr,
    shared: Arc<Shared>,
}

impl std::fmt::Debug for EmbeddedBroker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbeddedBroker")
            .field("local_addr", &self.local_addr)
            .field("config", &self.shared.config)
            .finish_non_exhaustive()
    }
}

/// How long a connection over the limit has to send its CONNECT before it is closed without
/// CONNACK.
const REFUSAL_TIMEOUT: Duration = Duration::from_secs(2);

/// How long to wait before accepting again after `accept` failed (e.g. out of file
/// descriptors), so that the loop does not spin.
const ACCEPT_RETRY_DELAY: Duration = Duration::from_millis(100);

impl EmbeddedBroker {
    /// Validates `config` and listens on `addr` (port 0: any free port, see
    /// [`local_addr`](Self::local_addr)). Measurement payloads go to `sink`; subscribers
    /// receive what is sent on `publications`.
    ///
    /// # Errors
    /// [`BrokerError::Config`] for a configuration out of range, [`BrokerError::Bind`] when the
    /// socket cannot be opened.
    pub async fn bind(
        addr: SocketAddr,
        config: BrokerConfig,
        sink: Arc<dyn MeasurementSink>,
        publications: broadcast::Sender<Publication>,
    ) -> Result<Self, BrokerError> {
        config.validate()?;
        let listener = TcpListener::bind(addr)
            .await
            .map_err(|source| BrokerError::Bind { addr, source })?;
        let local_addr = listener
            .local_addr()
            .map_err(|source| BrokerError::Bind { addr, source })?;
        Ok(Self {
            listener,
            local_addr,
            shared: Arc::new(Shared {
                config,
                sink,
                publications,
                counters: Arc::default(),
                clients: ClientRegistry::default(),
            }),
        })
    }

    /// The address the broker listens on.
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// A handle on the broker's counters.
    #[must_use]
    pub fn stats_handle(&self) -> BrokerStatsHandle {
        BrokerStatsHandle(Arc::clone(&self.shared.counters))
    }

    /// The broker's counters now.
    #[must_use]
    pub fn stats(&self) -> BrokerStats {
        self.stats_handle().snapshot()
    }

    /// Accepts and serves connections until `shutdown` resolves. Then it stops accepting, lets
    /// every session finish storing and acknowledging the payloads it has received (for at most
    /// 5 s each), closes the connections and returns.
    pub async fn run(self, shutdown: impl Future<Output = ()> + Send) {
        let Self {
            listener,
            local_addr,
            shared,
        } = self;
        tracing::info!(%local_addr, "mqtt: embedded broker listening");
        let (stop_tx, stop_rx) = watch::channel(false);
        let permits = Arc::new(Semaphore::new(shared.config.max_connections));
        let mut tasks = JoinSet::new();
        let mut connection_no = 0u64;
        tokio::pin!(shutdown);
        loop {
            tokio::select! {
                () = &mut shutdown => break,
                accepted = listener.accept() => match accepted {
                    Ok((stream, peer)) => {
                        connection_no += 1;
                        add(&shared.counters.connections_accepted, 1);
                        let _ = stream.set_nodelay(true);
                        spawn_connection(&mut tasks, &permits, stream, peer, connection_no, &shared, &stop_rx);
                    }
                    Err(error) => {
                        tracing::warn!(%error, "mqtt: accept failed");
                        tokio::time::sleep(ACCEPT_RETRY_DELAY).await;
                    }
                },
                Some(finished) = tasks.join_next(), if !tasks.is_empty() => log_task_end(finished),
            }
        }
        drop(listener);
        tracing::info!(sessions = tasks.len(), "mqtt: embedded broker stopping");
        let _ = stop_tx.send(true);
        while let Some(finished) = tasks.join_next().await {
            log_task_end(finished);
        }
        tracing::info!("mqtt: embedded broker stopped");
    }
}

/// Starts the task of one accepted connection: a session when a connection permit is free,
/// else a refusal with CONNACK "server unavailable".
fn spawn_connection(
    tasks: &mut JoinSet<()>,
    permits: &Arc<Semaphore>,
    stream: TcpStream,
    peer: SocketAddr,
    connection_no: u64,
    shared: &Arc<Shared>,
    stop: &watch::Receiver<bool>,
) {
    let shared = Arc::clone(shared);
    match Arc::clone(permits).try_acquire_owned() {
        Ok(permit) => {
            let stop = stop.clone();
            tasks.spawn(async move {
                connection::serve(stream, peer, connection_no, shared, stop).await;
                drop(permit);
            });
        }
        Err(_) => {
            tracing::warn!(%peer, limit = shared.config.max_connections, "mqtt: connection limit reached, refusing");
            add(&shared.counters.connections_refused, 1);
            tasks.spawn(connection::refuse_unavailable(stream, peer, shared, REFUSAL_TIMEOUT));
        }
    }
}

/// Logs a connection task that panicked (a bug: sessions handle every input as a value).
fn log_task_end(finished: Result<(), tokio::task::JoinError>) {
    if let Err(error) = finished {
        tracing::error!(%error, "mqtt: a connection task failed");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Tokens {
        Tokens {
            write: "w".into(),
            read: None,
        }
    }

    #[test]
    fn the_default_configuration_is_valid_and_bad_fields_are_named() {
        assert!(BrokerConfig::new(tokens()).validate().is_ok());
        type Spoil = fn(&mut BrokerConfig);
        let cases: [(Spoil, &str); 5] = [
            (
                |c| c.measurement_prefix = "rtls/v1/measurements".into(),
                "measurement_prefix",
            ),
            (
                |c| c.measurement_prefix = "rtls/+/measurements/".into(),
                "measurement_prefix",
            ),
            (|c| c.max_packet_bytes = 10, "max_packet_bytes"),
            (|c| c.max_inflight_per_connection = 0, "max_inflight_per_connection"),
            (|c| c.max_connections = 0, "max_connections"),
        ];
        for (spoil, expected_field) in cases {
            let mut config = BrokerConfig::new(tokens());
            spoil(&mut config);
            match config.validate() {
                Err(BrokerError::Config { field, .. }) => assert_eq!(field, expected_field),
                other => panic!("expected a Config error on {expected_field}, got {other:?}"),
            }
        }
    }

    #[test]
    fn a_second_session_with_the_same_client_id_takes_over() {
        let registry = ClientRegistry::default();
        let first = registry.register("reader-1", 1);
        let other = registry.register("reader-2", 2);
        let second = registry.register("reader-1", 3);
        // The first session was told; a notified() future now completes at once.
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("runtime");
        runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(100), first.notified())
                .await
                .expect("the first session is told to close");
            assert!(tokio::time::timeout(Duration::from_millis(20), other.notified())
                .await
                .is_err());
            assert!(tokio::time::timeout(Duration::from_millis(20), second.notified())
                .await
                .is_err());
        });
        // The first session's unregister must not remove the second one's entry.
        registry.unregister("reader-1", 1);
        let third = registry.register("reader-1", 4);
        runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(100), second.notified())
                .await
                .expect("the second session is still registered and is told");
        });
        drop(third);
    }
}
