//! The bridge to an external MQTT broker (`rtls serve --mqtt-url mqtt://host:1883`): a rumqttc
//! client that takes measurement payloads from the broker into the sink, acknowledging each one
//! only once stored, and forwards the server's publications to the broker.
//!
//! The client keeps a persistent session (clean session off) and acknowledges manually, so a
//! QoS 1 message the server has not stored stays with the broker: when the sink is unavailable
//! the bridge drops its connection without acknowledging, and the broker delivers the message
//! again on the next connection. Three loops run side by side in [`ExternalBroker::run`]: one
//! polls the connection (and reconnects with back-off), one hands messages to the sink and
//! acknowledges them in arrival order, one forwards publications at QoS 0.

use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use rumqttc::mqttbytes::v4::Packet;
use rumqttc::mqttbytes::{valid_filter, QoS};
use rumqttc::{AsyncClient, ConnectionError, Event, EventLoop, MqttOptions, OptionError, TlsConfiguration, Transport};
use tokio::sync::broadcast;
use tokio::time::timeout;

use crate::sink::{MeasurementSink, Publication};

mod loops;
mod tls;

/// The client id used when the URL names none (`?client_id=…`). The broker keeps the bridge's
/// session under this id: two servers on one broker need different ids.
pub const DEFAULT_CLIENT_ID: &str = "rtls-server";

/// Largest packet the bridge sends or accepts unless the URL says otherwise
/// (`max_incoming_packet_size_bytes`, `max_outgoing_packet_size_bytes`): 1 MiB. (rumqttc's own
/// default of 10 KiB is smaller than a batch of records.)
const MAX_PACKET_BYTES: usize = 1 << 20;

/// Capacity of the request channel between the bridge's loops and the rumqttc event loop.
const REQUEST_CHANNEL_CAPACITY: usize = 1024;

/// How long [`ExternalBroker::connect`] waits for the first CONNACK.
const FIRST_CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// Why the bridge could not start.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// The URL is not an MQTT URL the bridge understands (`mqtt://`, `tcp://`, `mqtts://` or
    /// `ssl://`, host, port, `?client_id=…`, the TLS options `ca_file`, `client_cert_file`,
    /// `client_key_file` and rumqttc's other options).
    #[error("mqtt url {url}: {reason}")]
    InvalidUrl {
        /// The URL, with any password replaced by `***`.
        url: String,
        /// What is wrong.
        reason: String,
    },
    /// The TLS configuration the URL asks for cannot be built (a CA or certificate file cannot
    /// be read or holds nothing usable).
    #[error("mqtt url {url}: TLS: {reason}")]
    Tls {
        /// The URL, with any password replaced by `***`.
        url: String,
        /// What is wrong.
        reason: String,
    },
    /// The measurement filter is not a valid MQTT topic filter.
    #[error("mqtt measurement filter {filter:?} is not a valid topic filter")]
    InvalidFilter {
        /// The filter given.
        filter: String,
    },
    /// The first connection to the broker failed.
    #[error("mqtt: cannot connect to {url}: {source} (is the broker running, and are the credentials right?)")]
    Connect {
        /// The URL, with any password replaced by `***`.
        url: String,
        /// rumqttc's error.
        source: ConnectionError,
    },
    /// The first connection did not complete in time.
    #[error("mqtt: no CONNACK from {url} within {timeout:?}")]
    ConnectTimeout {
        /// The URL, with any password replaced by `***`.
        url: String,
        /// How long the bridge waited.
        timeout: Duration,
    },
}

/// A snapshot of the bridge's counters (totals since it connected).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Connections established (CONNACK received), the first one included.
    pub connections: u64,
    /// Connection errors (each followed by a reconnection attempt).
    pub connection_errors: u64,
    /// Measurement messages received from the broker.
    pub messages_received: u64,
    /// Records the sink stored from them.
    pub records_stored: u64,
    /// Messages acknowledged to the broker (stored, or refused as invalid).
    pub acks_sent: u64,
    /// Messages the sink refused as invalid (acknowledged all the same).
    pub messages_invalid: u64,
    /// Messages the sink could not take (not acknowledged; the bridge reconnected).
    pub messages_unavailable: u64,
    /// Messages received on a connection that was being replaced, left to the broker to send
    /// again.
    pub messages_redelivery_expected: u64,
    /// Publications forwarded to the broker.
    pub publications_forwarded: u64,
    /// Publications dropped: missed while the forwarder lagged, or refused by the client.
    pub publications_dropped: u64,
}

/// The live counters behind [`BridgeStats`].
#[derive(Debug, Default)]
struct Counters {
    connections: AtomicU64,
    connection_errors: AtomicU64,
    messages_received: AtomicU64,
    records_stored: AtomicU64,
    acks_sent: AtomicU64,
    messages_invalid: AtomicU64,
    messages_unavailable: AtomicU64,
    messages_redelivery_expected: AtomicU64,
    publications_forwarded: AtomicU64,
    publications_dropped: AtomicU64,
}

fn add(counter: &AtomicU64, amount: u64) {
    counter.fetch_add(amount, Ordering::Relaxed);
}

/// A cheap, cloneable handle on the bridge's counters that outlives [`ExternalBroker::run`].
#[derive(Debug, Clone)]
pub struct BridgeStatsHandle(Arc<Counters>);

impl BridgeStatsHandle {
    /// The counters now.
    #[must_use]
    pub fn snapshot(&self) -> BridgeStats {
        let c = &self.0;
        let get = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        BridgeStats {
            connections: get(&c.connections),
            connection_errors: get(&c.connection_errors),
            messages_received: get(&c.messages_received),
            records_stored: get(&c.records_stored),
            acks_sent: get(&c.acks_sent),
            messages_invalid: get(&c.messages_invalid),
            messages_unavailable: get(&c.messages_unavailable),
            messages_redelivery_expected: get(&c.messages_redelivery_expected),
            publications_forwarded: get(&c.publications_forwarded),
            publications_dropped: get(&c.publications_dropped),
        }
    }
}

/// A connected bridge to an external broker, ready to [`run`](Self::run).
pub struct ExternalBroker {
    client: AsyncClient,
    eventloop: EventLoop,
    sink: Arc<dyn MeasurementSink>,
    publications: broadcast::Receiver<Publication>,
    measurement_filter: String,
    /// The URL for log lines, password hidden.
    display_url: String,
    counters: Arc<Counters>,
}

impl std::fmt::Debug for ExternalBroker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExternalBroker")
            .field("url", &self.display_url)
            .field("measurement_filter", &self.measurement_filter)
            .finish_non_exhaustive()
    }
}

impl ExternalBroker {
    /// Parses `url` (rumqttc's URL form, e.g.
    /// `mqtt://user:password@broker:1883?client_id=rtls-site-1`; the client id defaults to
    /// [`DEFAULT_CLIENT_ID`]; `mqtts://broker?ca_file=ca.pem` for TLS, see the `tls` module), connects with a persistent session and manual acknowledgements,
    /// and subscribes to `measurement_filter` (normally
    /// [`MEASUREMENT_FILTER`](super::MEASUREMENT_FILTER)) and to its
    /// [`adapter_filter`](super::adapter_filter) (vendor feeds) at QoS 1. Both go to `sink`; whatever is sent on `publications` will be published to the broker.
    ///
    /// # Errors
    /// [`BridgeError::InvalidUrl`], [`BridgeError::Tls`], [`BridgeError::InvalidFilter`], or
    /// [`BridgeError::Connect`] / [`BridgeError::ConnectTimeout`] when the broker cannot be
    /// reached or refuses the connection: a server started with a wrong URL fails at once.
    pub async fn connect(
        url: &str,
        sink: Arc<dyn MeasurementSink>,
        publications: broadcast::Sender<Publication>,
        measurement_filter: &str,
    ) -> Result<Self, BridgeError> {
        let display_url = crate::config::redact_password(url);
        if !valid_filter(measurement_filter) {
            return Err(BridgeError::InvalidFilter {
                filter: measurement_filter.to_owned(),
            });
        }
        let (plain_url, broker_tls) = tls::split(url).map_err(|reason| BridgeError::InvalidUrl {
            url: display_url.clone(),
            reason,
        })?;
        let mut options = parse_options(&plain_url).map_err(|error| BridgeError::InvalidUrl {
            url: display_url.clone(),
            reason: error.to_string(),
        })?;
        if let tls::BrokerTls::On {
            ca_file,
            client_identity,
        } = &broker_tls
        {
            let identity = client_identity
                .as_ref()
                .map(|(cert, key)| (cert.as_path(), key.as_path()));
            let config = tls::client_config(ca_file.as_deref(), identity).map_err(|reason| BridgeError::Tls {
                url: display_url.clone(),
                reason,
            })?;
            options.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(Arc::new(config))));
        }
        options.set_clean_session(false).set_manual_acks(true);
        if !url.contains("max_incoming_packet_size_bytes=") {
            options.set_max_packet_size(MAX_PACKET_BYTES, MAX_PACKET_BYTES);
        }
        if !url.contains("request_channel_capacity_num=") {
            options.set_request_channel_capacity(REQUEST_CHANNEL_CAPACITY);
        }
        let capacity = options.request_channel_capacity();
        let (client, mut eventloop) = AsyncClient::new(options, capacity);
        match timeout(FIRST_CONNECT_TIMEOUT, eventloop.poll()).await {
            Ok(Ok(Event::Incoming(Packet::ConnAck(connack)))) => {
                tracing::info!(url = %display_url, session_present = connack.session_present, "mqtt: connected to the external broker");
            }
            Ok(Ok(other)) => {
                // The first event of a new connection is always its CONNACK.
                tracing::warn!(url = %display_url, event = ?other, "mqtt: unexpected first event");
            }
            Ok(Err(source)) => {
                return Err(BridgeError::Connect {
                    url: display_url,
                    source,
                })
            }
            Err(_elapsed) => {
                return Err(BridgeError::ConnectTimeout {
                    url: display_url,
                    timeout: FIRST_CONNECT_TIMEOUT,
                })
            }
        }
        let counters = Arc::new(Counters::default());
        add(&counters.connections, 1);
        for filter in [measurement_filter.to_owned(), super::adapter_filter(measurement_filter)] {
            if let Err(error) = client.try_subscribe(filter, QoS::AtLeastOnce) {
                tracing::error!(url = %display_url, %error, "mqtt: cannot queue the measurement subscription");
            }
        }
        Ok(Self {
            client,
            eventloop,
            sink,
            publications: publications.subscribe(),
            measurement_filter: measurement_filter.to_owned(),
            display_url,
            counters,
        })
    }

    /// A handle on the bridge's counters.
    #[must_use]
    pub fn stats_handle(&self) -> BridgeStatsHandle {
        BridgeStatsHandle(Arc::clone(&self.counters))
    }

    /// Runs the bridge until `shutdown` resolves: stores and acknowledges measurement
    /// messages, forwards publications, and reconnects (with back-off from 0.2 s to 30 s)
    /// whenever the connection fails. On shutdown it stops taking messages, acknowledges what
    /// the sink still stores (for at most 5 s) and disconnects.
    pub async fn run(self, shutdown: impl Future<Output = ()> + Send) {
        loops::run(self, shutdown).await;
    }
}

/// rumqttc's options from `url`, with [`DEFAULT_CLIENT_ID`] when it names no client id.
fn parse_options(url: &str) -> Result<MqttOptions, OptionError> {
    match MqttOptions::parse_url(url) {
        Err(OptionError::ClientId) => {
            let separator = if url.contains('?') { '&' } else { '?' };
            MqttOptions::parse_url(format!("{url}{separator}client_id={DEFAULT_CLIENT_ID}"))
        }
        parsed => parsed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_client_id_defaults_and_credentials_come_from_the_url() {
        let options = parse_options("mqtt://127.0.0.1:18830").expect("valid url");
        assert_eq!(options.client_id(), DEFAULT_CLIENT_ID);
        assert_eq!(options.broker_address(), ("127.0.0.1".to_owned(), 18830));
        assert_eq!(options.credentials(), None);

        let options = parse_options("mqtt://u:p@broker?keep_alive_secs=7").expect("valid url");
        assert_eq!(options.client_id(), DEFAULT_CLIENT_ID);
        assert_eq!(options.broker_address(), ("broker".to_owned(), 1883));
        assert_eq!(options.keep_alive(), Duration::from_secs(7));
        let login = options.credentials().expect("credentials from the url");
        assert_eq!((login.username.as_str(), login.password.as_str()), ("u", "p"));

        let options = parse_options("tcp://broker:1884?client_id=site-2").expect("valid url");
        assert_eq!(options.client_id(), "site-2");

        assert!(matches!(parse_options("http://broker"), Err(OptionError::Scheme)));
        assert!(matches!(
            parse_options("mqtt://broker?colour=blue"),
            Err(OptionError::Unknown(option)) if option == "colour"
        ));
    }
}
