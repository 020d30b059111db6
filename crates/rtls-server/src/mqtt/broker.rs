//! The embedded MQTT 3.1.1 broker: binding, the accept loop and shutdown. Its configuration is
//! in [`super::config`], its counters in [`super::stats`], what its connection tasks share in
//! [`super::shared`]; what happens on one connection is in [`super::connection`] and
//! [`super::session`].

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{broadcast, watch};
use tokio::task::JoinSet;
use tokio_rustls::TlsAcceptor;

use crate::sink::{MeasurementSink, Publication};

use super::config::{BrokerConfig, BrokerError};
use super::connection;
use super::shared::{ClientRegistry, Limits, Shared};
use super::stats::{add, BrokerStats, BrokerStatsHandle};
use super::stream;
use super::CONNECT_TIMEOUT;

/// The embedded MQTT 3.1.1 broker, bound to its address and ready to [`run`](Self::run).
///
/// # Examples
/// ```no_run
/// # async fn example(sink: std::sync::Arc<dyn rtls_server::sink::MeasurementSink>) -> Result<(), rtls_server::mqtt::BrokerError> {
/// use rtls_server::auth::Tokens;
/// use rtls_server::mqtt::{BrokerConfig, EmbeddedBroker};
///
/// let (publications, _) = tokio::sync::broadcast::channel(1024);
/// let config = BrokerConfig::new(Tokens::new("secret", None));
/// let broker = EmbeddedBroker::bind("127.0.0.1:1883".parse().unwrap(), config, sink, publications).await?;
/// println!("mqtt on {}", broker.local_addr());
/// broker.run(async { let _ = tokio::signal::ctrl_c().await; }).await;
/// # Ok(()) }
/// ```
pub struct EmbeddedBroker {
    listener: TcpListener,
    local_addr: SocketAddr,
    shared: Arc<Shared>,
    tls: Option<TlsAcceptor>,
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
                sink,
                publications,
                counters: Arc::default(),
                clients: ClientRegistry::default(),
                limits: Limits::new(&config),
                config,
            }),
            tls: None,
        })
    }

    /// Serves MQTT over TLS (MQTTS) only: each connection's TLS handshake, in its own task,
    /// must end within [`CONNECT_TIMEOUT`](super::CONNECT_TIMEOUT) like its CONNECT.
    #[must_use]
    pub fn with_tls(mut self, acceptor: TlsAcceptor) -> Self {
        self.tls = Some(acceptor);
        self
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
            tls,
        } = self;
        tracing::info!(%local_addr, "mqtt: embedded broker listening");
        let (stop_tx, stop_rx) = watch::channel(false);
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
                        spawn_connection(&mut tasks, stream, peer, connection_no, &shared, tls.as_ref(), &stop_rx);
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

/// Starts the task of one accepted connection — its handshake, then its session — when its IP
/// address is under [`BrokerConfig::max_connections_per_ip`] and a handshake slot is free
/// ([`BrokerConfig::max_pending_connects`]); else it is refused (CONNACK "server unavailable")
/// or, with every handshake slot taken, closed at once.
fn spawn_connection(
    tasks: &mut JoinSet<()>,
    stream: TcpStream,
    peer: SocketAddr,
    connection_no: u64,
    shared: &Arc<Shared>,
    tls: Option<&TlsAcceptor>,
    stop: &watch::Receiver<bool>,
) {
    let shared = Arc::clone(shared);
    let Some(ip_slot) = shared
        .limits
        .per_ip
        .take(peer.ip(), shared.config.max_connections_per_ip)
    else {
        tracing::warn!(%peer, limit = shared.config.max_connections_per_ip, "mqtt: connection limit of this address reached, refusing");
        add(&shared.counters.connections_refused, 1);
        if tls.is_none() {
            let halves = stream::plain_halves(stream);
            tasks.spawn(connection::refuse_unavailable(halves, peer, shared, REFUSAL_TIMEOUT));
        }
        return;
    };
    let Ok(handshake) = Arc::clone(&shared.limits.pending).try_acquire_owned() else {
        tracing::warn!(%peer, limit = shared.config.max_pending_connects, "mqtt: too many connections waiting for CONNECT, closing");
        add(&shared.counters.connections_refused, 1);
        drop(stream);
        return;
    };
    let stop = stop.clone();
    let tls = tls.cloned();
    tasks.spawn(async move {
        let halves = match tls {
            None => stream::plain_halves(stream),
            Some(acceptor) => match tokio::time::timeout(CONNECT_TIMEOUT, acceptor.accept(stream)).await {
                Ok(Ok(tls_stream)) => stream::halves(tls_stream),
                Ok(Err(error)) => {
                    add(&shared.counters.protocol_violations, 1);
                    tracing::warn!(%peer, %error, "mqtt: TLS handshake failed");
                    return;
                }
                Err(_) => {
                    tracing::warn!(%peer, "mqtt: no TLS handshake in time, closing");
                    return;
                }
            },
        };
        connection::serve(halves, peer, connection_no, shared, stop, handshake).await;
        drop(ip_slot);
    });
}

/// Logs a connection task that panicked (a bug: sessions handle every input as a value).
fn log_task_end(finished: Result<(), tokio::task::JoinError>) {
    if let Err(error) = finished {
        tracing::error!(%error, "mqtt: a connection task failed");
    }
}
