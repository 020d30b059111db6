//! MQTT for `rtls serve`: readers publish measurement records, subscribers receive tracks and
//! events.
//!
//! Two transports share one topic scheme:
//!
//! - [`EmbeddedBroker`] (the default): our own small MQTT 3.1.1 server, built on rumqttc's
//!   packet codec (`rumqttc::mqttbytes::v4`). It exists because of one guarantee a general
//!   broker does not give: **a QoS 1 PUBACK is sent only after the records are durable** (the
//!   [`MeasurementSink`](crate::sink::MeasurementSink)'s future resolved `Ok`).
//! - [`ExternalBroker`] (`--mqtt-url`): a client of an existing broker (tested against
//!   mosquitto) that subscribes to the measurement topics with a persistent session and manual
//!   acknowledgements, so the same guarantee holds end to end: the bridge acknowledges a
//!   message to the broker only after the sink stored it.
//!
//! # Topics
//!
//! | topic | direction | payload |
//! | --- | --- | --- |
//! | `rtls/v1/measurements/{reader}` | reader → server | JSON Lines of the measurement record format (`docs/FORMATS.md`), one or more records per message |
//! | `rtls/v1/adapters/{vendor}/…` | a vendor's engine (or a bridge from its broker) → server | one message of the vendor's feed, read by its adapter ([`crate::adapters`]: `pozyx`, `quuppa`, `sewio`, `zebra`, `openrtls`, `generic`) |
//! | `rtls/v1/tracks/{tag}`, `rtls/v1/events/{type}`, … | server → subscribers | the JSON of each [`Publication`](crate::sink::Publication) the server emits |
//! | `rtls/v1/errors/{client_id}` | embedded broker → that client only | `{"topic": …, "error": …}` for a payload the sink refused as invalid |
//!
//! The sink hears each payload with the source `mqtt:{topic}` (e.g.
//! `mqtt:rtls/v1/measurements/reader-7`).
//!
//! # Quality of service
//!
//! - **Readers → server, QoS 1** (at least once): the PUBACK means "stored". PUBACKs of one
//!   connection leave in the order its PUBLISH packets arrived, although up to
//!   [`BrokerConfig::max_inflight_per_connection`] payloads of a connection are being stored at
//!   once. A payload the sink refuses as invalid is acknowledged all the same (sending it again
//!   would fail again) and reported on the client's error topic. When the sink is unavailable
//!   (storage failure, shutting down) the PUBLISH is not acknowledged and the connection is
//!   closed; the client sends it again after reconnecting. Duplicates are therefore possible
//!   (a resend of a payload whose PUBACK was lost), losses are not.
//! - **Readers → server, QoS 0**: stored as well, but the reader hears of no failure except the
//!   closing of its connection when the sink is unavailable.
//! - **QoS 2** is not supported: a QoS 2 PUBLISH closes the connection. (Exactly-once would need
//!   a deduplication store; records carry their own time stamps, and the tracker tolerates a
//!   repeated record far better than a lost one.)
//! - **Server → subscribers, QoS 0**: every subscription is granted QoS 0. Tracks and events are
//!   a live feed superseded by the next message; history is served by the REST API. A subscriber
//!   too slow to keep up loses messages (counted as dropped) and never slows ingest down.
//!
//! # Sessions
//!
//! The embedded broker keeps no session state across connections: every CONNECT gets
//! `session_present = false`, whatever its clean-session flag says, and subscriptions end with
//! the connection. This is safe for QoS 1 ingest because the client — not the broker — holds
//! every PUBLISH it has not seen acknowledged and sends it again on its next connection
//! (MQTT 3.1.1 §4.4), and the server acknowledges only stored records. A second connection with
//! the same client id and the same credential takes over: the first one is closed (MQTT 3.1.1
//! §3.1.4); one with another credential (another token, or none, reusing a reader's id) is
//! refused with CONNACK "identifier rejected". Last-will
//! messages are accepted and ignored: the broker relays no client-to-client messages.
//!
//! # Authentication
//!
//! The CONNECT password is the access token ([`Tokens`](crate::auth::Tokens)); the user name is
//! free (readers may put their name there, it is only logged). An integrator's or admin's token
//! (the write token is an admin) allows publishing measurements and subscribing; a viewer's or
//! operator's (the read token is a viewer; no token when reads are open) allows subscribing
//! only, and a PUBLISH on such a connection closes it. A token revoked through the API is
//! refused at the next CONNECT. A wrong
//! password is refused with CONNACK "bad user name or password" (also when reads need no
//! token: a wrong credential is never admitted as a reader), a missing one with "not
//! authorized". Use TLS in front of the broker (a terminating proxy) where the network is not
//! trusted: MQTT sends the password in clear.
//!
//! # Limits
//!
//! [`BrokerConfig`] bounds the size of one packet, the payloads of one connection being stored
//! at once (while that many are pending the broker reads no further packets from the
//! connection: TCP back-pressure throttles the reader), the connections of one IP address,
//! the handshakes waiting for CONNECT (idle sockets take no session slot; beyond the limit a
//! new socket is closed at once), and the sessions — of which read-only ones may take only
//! [`BrokerConfig::max_read_connections`], so that subscribers cannot lock readers out (a
//! session over a limit gets CONNACK "server unavailable"). A client must send its CONNECT within
//! [`CONNECT_TIMEOUT`] of opening the connection and then a packet at least every
//! 1.5 × its keep-alive interval (keep-alive 0 disables this). A malformed or oversize packet,
//! or one the protocol forbids at that point, closes that connection and no other.

mod bridge;
mod broker;
mod config;
mod connection;
mod frame;
mod session;
mod shared;
mod stats;
mod stream;

pub use bridge::{BridgeError, BridgeStats, BridgeStatsHandle, ExternalBroker, DEFAULT_CLIENT_ID};
pub use broker::EmbeddedBroker;
pub use config::{BrokerConfig, BrokerError};
pub use stats::{BrokerStats, BrokerStatsHandle};

use std::time::Duration;

/// The prefix of the topics readers publish measurement records to
/// (`rtls/v1/measurements/{reader}`).
pub const MEASUREMENT_PREFIX: &str = "rtls/v1/measurements/";

/// The topic filter of every measurement topic, for subscribing on an external broker.
pub const MEASUREMENT_FILTER: &str = "rtls/v1/measurements/#";

/// The topic filter of every vendor adapter topic (`rtls/v1/adapters/{vendor}/…`,
/// [`crate::adapters`]), for subscribing on an external broker.
pub const ADAPTER_FILTER: &str = "rtls/v1/adapters/#";

/// The adapter filter beside a measurement filter: shared in the same group when the
/// measurement filter is a shared subscription (`$share/{group}/…`, a cluster's nodes).
///
/// # Examples
/// ```
/// use rtls_server::mqtt::adapter_filter;
/// assert_eq!(adapter_filter("rtls/v1/measurements/#"), "rtls/v1/adapters/#");
/// assert_eq!(adapter_filter("$share/rtls/rtls/v1/measurements/#"), "$share/rtls/rtls/v1/adapters/#");
/// ```
#[must_use]
pub fn adapter_filter(measurement_filter: &str) -> String {
    match measurement_filter
        .strip_prefix("$share/")
        .and_then(|rest| rest.split_once('/'))
    {
        Some((group, _)) => format!("$share/{group}/{ADAPTER_FILTER}"),
        None => ADAPTER_FILTER.to_string(),
    }
}

/// The prefix of the per-client error topics (`rtls/v1/errors/{client_id}`).
pub const ERROR_PREFIX: &str = "rtls/v1/errors/";

/// How long the embedded broker waits for a new connection's CONNECT packet.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// The topic on which the embedded broker reports the payloads of `client_id` that the sink
/// refused as invalid.
///
/// # Examples
/// ```
/// assert_eq!(rtls_server::mqtt::error_topic("reader-7"), "rtls/v1/errors/reader-7");
/// ```
#[must_use]
pub fn error_topic(client_id: &str) -> String {
    format!("{ERROR_PREFIX}{client_id}")
}
