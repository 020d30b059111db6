//! The embedded broker's configuration and the errors that keep it from starting.

use std::net::SocketAddr;

use rumqttc::mqttbytes::valid_topic;

use crate::auth::Tokens;

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
    /// How many client sessions may be open at once; one more is refused with CONNACK
    /// "server unavailable".
    pub max_connections: usize,
    /// How many of them may be read-only (subscribers with the read token, or none when reads
    /// are open): the rest stays free for writers, so subscribers cannot lock readers out.
    /// Above `max_connections` it is `max_connections`.
    pub max_read_connections: usize,
    /// How many connections (sessions and handshakes) one IP address may hold; one more is
    /// refused.
    pub max_connections_per_ip: usize,
    /// How many connections may be waiting for their CONNECT at once (each for at most
    /// [`CONNECT_TIMEOUT`](super::CONNECT_TIMEOUT)); one more is closed at once. Idle sockets
    /// hold no session slot.
    pub max_pending_connects: usize,
}

impl BrokerConfig {
    /// Default for [`BrokerConfig::max_packet_bytes`]: 1 MiB.
    pub const DEFAULT_MAX_PACKET_BYTES: usize = 1 << 20;
    /// Default for [`BrokerConfig::max_inflight_per_connection`].
    pub const DEFAULT_MAX_INFLIGHT_PER_CONNECTION: usize = 32;
    /// Default for [`BrokerConfig::max_connections`].
    pub const DEFAULT_MAX_CONNECTIONS: usize = 1024;
    /// Default for [`BrokerConfig::max_read_connections`]: half the sessions.
    pub const DEFAULT_MAX_READ_CONNECTIONS: usize = 512;
    /// Default for [`BrokerConfig::max_connections_per_ip`].
    pub const DEFAULT_MAX_CONNECTIONS_PER_IP: usize = 128;
    /// Default for [`BrokerConfig::max_pending_connects`].
    pub const DEFAULT_MAX_PENDING_CONNECTS: usize = 256;

    /// The default configuration with the given tokens: measurements under
    /// [`MEASUREMENT_PREFIX`](super::MEASUREMENT_PREFIX) and the `DEFAULT_*` limits.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::auth::Tokens;
    /// use rtls_server::mqtt::BrokerConfig;
    ///
    /// let config = BrokerConfig::new(Tokens::new("w", None));
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
            max_read_connections: Self::DEFAULT_MAX_READ_CONNECTIONS,
            max_connections_per_ip: Self::DEFAULT_MAX_CONNECTIONS_PER_IP,
            max_pending_connects: Self::DEFAULT_MAX_PENDING_CONNECTS,
        }
    }

    /// Checks the fields that have to make sense before the broker starts.
    pub(super) fn validate(&self) -> Result<(), BrokerError> {
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
        if self.max_read_connections == 0 {
            return invalid("max_read_connections", "must be at least 1");
        }
        if self.max_connections_per_ip == 0 {
            return invalid("max_connections_per_ip", "must be at least 1");
        }
        if self.max_pending_connects == 0 {
            return invalid("max_pending_connects", "must be at least 1");
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

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Tokens {
        Tokens::new("w", None)
    }

    #[test]
    fn the_default_configuration_is_valid_and_bad_fields_are_named() {
        assert!(BrokerConfig::new(tokens()).validate().is_ok());
        type Spoil = fn(&mut BrokerConfig);
        let cases: [(Spoil, &str); 8] = [
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
            (|c| c.max_read_connections = 0, "max_read_connections"),
            (|c| c.max_connections_per_ip = 0, "max_connections_per_ip"),
            (|c| c.max_pending_connects = 0, "max_pending_connects"),
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
}
