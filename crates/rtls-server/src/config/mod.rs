//! The server's configuration file (TOML) and its defaults.
//!
//! ```toml
//! [server]
//! http = "127.0.0.1:8080"        # HTTP and WebSocket
//! site = "site.toml"             # the site file (readers, zones, tracker settings)
//! db = "sqlite:rtls.db"          # or "postgres://user:password@host/db[?sslmode=require&sslrootcert=CA.pem]"
//! retention_days = 92            # history, events and the ingest log (mine rules: ≥ 3 months)
//! raw_retention_days = 1         # raw records in the ingest log (once their outputs are stored)
//! compact_after_s = 300          # older track states and tracked records: packed into compressed blocks
//! history_interval_s = 0.0       # a tag's stored track states at least this far apart (0: every one)
//! log_format = "text"            # or "json"
//! default_accuracy_m = 1.0       # omlox locations without `accuracy`
//! sqlite_sync = "full"           # or "normal": safe against a crash, not a power loss
//! max_connections = 4096         # open HTTP connections at most (WebSockets included)
//! max_connections_per_ip = 256   # of one IP address at most
//! idle_timeout_s = 120.0         # a connection moving no byte this long is closed
//! max_requests_per_s_per_ip = 500   # HTTP requests per second of one address (bursts 2×); 0: none
//!
//! [auth]
//! write_token = "…"              # or the environment variable RTLS_WRITE_TOKEN
//! read_token = "…"               # or RTLS_READ_TOKEN; without one, rtls serve generates one and prints it
//! open_reads = false             # true (and no read token): reads need no credential
//!
//! [mqtt]
//! mode = "embedded"              # "embedded", "external" or "off"
//! listen = "127.0.0.1:1883"      # the embedded broker
//! url = "mqtt://broker:1883?client_id=rtls-server"   # the external broker
//! max_connections = 1024         # embedded broker: sessions at most …
//! max_read_connections = 512     # … of which read-only (subscribers) at most
//! max_connections_per_ip = 128   # connections of one IP address at most
//! max_pending_connects = 256     # sockets waiting for their CONNECT at most
//!
//! [pipeline]
//! partitions = 2                 # tag partitions (worker threads); default: the CPU count
//! live_clock = true              # advance tracks with the wall clock (records in Unix time)
//! clock_lag_s = "auto"           # how far the live clock runs behind the wall: measured, or seconds
//! max_record_age_s = 86400.0     # with live_clock: older records are refused at ingest
//! max_record_lead_s = 60.0       # with live_clock: records this far ahead of the clock are refused
//!
//! [tls]                          # HTTPS / WSS and MQTTS (plain HTTP and MQTT without it)
//! cert = "tls/server.crt"        # PEM chain, with key
//! key = "tls/server.key"         # PEM private key
//! self_signed = false            # true: generate one for localhost (a demo) if the files are absent
//! reload_s = 10.0                # a renewed certificate is picked up within this
//!
//! [adapters.generic]             # optional: a gateway's JSON by field paths (docs/SERVER.md, Vendor adapters)
//! tag = "tagId"                  # paths of keys separated by dots; a number indexes an array
//! time = "ts"                    # time_unit = "s" (default), "ms" or "rfc3339"
//! x = "pos.x"                    # y, z (optional) likewise; position_unit = "m" (default), "cm" or "mm"
//! y = "pos.y"                    # accuracy = "…" (optional radius, position_unit); items = "…" (array path)
//!
//! [adapters.zebra]               # optional: a Zebra Dart hub's ASCII lines (docs/SERVER.md, Vendor adapters)
//! unit = "m"                     # the hub's coordinates: "m" (default) or "ft"
//! range_sigma_m = 0.3            # a locate's σ = its GDOP × this (without GDOP: server.default_accuracy_m)
//! o_packet_accuracy_m = 10.0     # σ of an O packet (a 1-D estimate between two receivers)
//! hub = "10.0.0.5:5117"          # optional: connect to the hub's Dart output and read it (also --zebra-hub)
//! idle_timeout_s = 300.0         # a hub connection silent this long is opened again
//!
//! [[webhooks]]                   # zero or more: alarms POSTed as JSON (docs/SERVER.md, Webhooks)
//! url = "https://ops.example.com/rtls/alarms"   # http:// or https://
//! name = "ops"                   # the `webhook` label of metrics and logs; default: the URL's host[:port]
//! events = ["hazard-predicted", "zone-enter", "no-coverage", "lost", "alarm-acknowledged"]  # the default;
//!                                # also "hazard-cleared", "recovered", "model-switch"
//! secret = "…"                   # or secret_env = "RTLS_WEBHOOK_SECRET": signs each body,
//!                                # X-Rtls-Signature: sha256=<hex HMAC-SHA256>
//! timeout_s = 5.0                # per attempt (connect, send, answer)
//! max_attempts = 8               # then the delivery is given up (counted `failed`)
//! initial_backoff_s = 1.0        # first retry after this, doubling each retry …
//! max_backoff_s = 60.0           # … up to this; each wait is 75–100 % of it (jitter)
//!
//! [udp]                          # optional: best-effort UDP ingest, one payload per datagram (docs/SERVER.md, UDP ingest)
//! listen = "127.0.0.1:9000"      # our measurement JSON lines (the body of POST /api/v1/measurements)
//! [udp.adapters]                 # a vendor's messages through its adapter, one port per vendor
//! quuppa = "127.0.0.1:9001"      # also pozyx, sewio, zebra, openrtls, generic (which needs [adapters.generic])
//!
//! [[nats_forward]]               # zero or more: positions and events published to NATS (docs/SERVER.md)
//! url = "nats://127.0.0.1:4222"  # nats:// or tls://; user:password@ for a user; several: comma-separated
//! name = "bus"                   # the `forward` label of metrics and logs; default: the URL's host[:port]
//! subject_prefix = "rtls"        # subjects {prefix}.positions.{tag}, {prefix}.events.{type}
//! topics = ["positions", "alarms", "events"]   # the default: every topic
//! token_env = "RTLS_NATS_TOKEN"  # optional: the server's token from this environment variable
//! ```

use std::net::SocketAddr;
use std::path::PathBuf;

use serde::Deserialize;

pub mod cluster;
mod nats_forward;
mod udp;
mod webhooks;

pub(crate) use nats_forward::validate_nats_forwards;
pub use nats_forward::{ForwardTopic, NatsForwardSection};
pub use udp::{UdpAdapters, UdpSection};
pub(crate) use webhooks::validate_webhooks;
pub use webhooks::WebhookSection;

/// A configuration error, naming the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("config file {path}: {reason}")]
    Read {
        /// The path.
        path: String,
        /// The OS error.
        reason: String,
    },
    /// The file does not parse or has a bad value (toml names the line, column and key).
    #[error("config file {path}: {reason}")]
    Parse {
        /// The path.
        path: String,
        /// What is wrong, where.
        reason: String,
    },
    /// A value is out of range.
    #[error("config {field}: {reason}")]
    Invalid {
        /// The field (`server.retention_days`).
        field: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
}

/// Where MQTT measurements come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum MqttMode {
    /// The server's own broker.
    #[default]
    Embedded,
    /// An external broker (`mqtt.url`).
    External,
    /// No MQTT.
    Off,
}

/// The whole configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ServerConfig {
    /// `[server]`.
    pub server: ServerSection,
    /// `[auth]`.
    pub auth: AuthSection,
    /// `[mqtt]`.
    pub mqtt: MqttSection,
    /// `[pipeline]`.
    pub pipeline: PipelineSection,
    /// `[[webhooks]]`: where alarms are POSTed ([`crate::webhooks`]).
    pub webhooks: Vec<WebhookSection>,
    /// `[tls]`: HTTPS / WSS and MQTTS.
    pub tls: TlsSection,
    /// `[cluster]`: `rtls serve` as one node of a cluster on NATS JetStream.
    pub cluster: cluster::ClusterSection,
    /// `[adapters]`: settings of the vendor adapters ([`crate::adapters`]).
    pub adapters: AdaptersSection,
    /// `[udp]`: best-effort UDP ingest listeners ([`crate::udp`]); none by default.
    pub udp: UdpSection,
    /// `[[nats_forward]]`: NATS servers positions and events are published to
    /// ([`crate::nats_forward`]).
    pub nats_forward: Vec<NatsForwardSection>,
}

/// `[adapters]`: settings of the vendor adapters.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptersSection {
    /// `[adapters.generic]`: the field names of a generic gateway's JSON
    /// ([`crate::adapters::GenericAdapter`]); without it `generic` payloads are refused.
    pub generic: Option<crate::adapters::GenericAdapter>,
    /// `[adapters.zebra]`: the unit and accuracies of a Zebra Dart hub's lines, and the hub to
    /// connect to ([`crate::adapters::ZebraAdapter`]); without it metres, the default
    /// accuracies and no hub connection.
    pub zebra: crate::adapters::ZebraAdapter,
}

/// `[tls]`: with a certificate, the HTTP listener serves HTTPS (and WSS) only and the embedded
/// MQTT broker MQTTS only.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TlsSection {
    /// The certificate chain (PEM); with `key`.
    pub cert: Option<PathBuf>,
    /// The private key (PEM); with `cert`.
    pub key: Option<PathBuf>,
    /// Generate a self-signed certificate for localhost and the listen addresses (a demo, a
    /// test bench) at `cert` / `key`, or `rtls-self-signed.crt` / `.key` in the working
    /// directory; an existing pair is reused.
    pub self_signed: bool,
    /// How often the files are checked for a change (s, > 0): a renewed certificate is served
    /// from the next connection on, without a restart.
    pub reload_s: f64,
}

impl Default for TlsSection {
    fn default() -> Self {
        Self {
            cert: None,
            key: None,
            self_signed: false,
            reload_s: 10.0,
        }
    }
}

impl TlsSection {
    /// The certificate and key files TLS uses, or `None` when TLS is off.
    #[must_use]
    pub fn files(&self) -> Option<(PathBuf, PathBuf)> {
        match (&self.cert, &self.key) {
            (Some(cert), Some(key)) => Some((cert.clone(), key.clone())),
            _ if self.self_signed => Some((
                PathBuf::from("rtls-self-signed.crt"),
                PathBuf::from("rtls-self-signed.key"),
            )),
            _ => None,
        }
    }
}

/// `[server]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServerSection {
    /// HTTP listen address.
    pub http: SocketAddr,
    /// The site file.
    pub site: Option<PathBuf>,
    /// The database URL.
    pub db: String,
    /// Days of history, events and ingest log kept.
    pub retention_days: f64,
    /// Days of raw records kept in the ingest log (> 0): older ones whose outputs are stored
    /// are deleted hourly. The ingest log is most of the database (docs/SERVER.md, sizing);
    /// the tracks and events it produced are kept for `retention_days`.
    pub raw_retention_days: f64,
    /// Track states and tracked raw records older than this (s, 1–86 400) are packed into
    /// compressed blocks (about 15× smaller; states keep 1 mm, 1 mm/s, σ to 0.1 mm), every
    /// this often. Queries read blocks and rows alike.
    pub compact_after_s: f64,
    /// A tag's stored track states are at least this far apart (s, 0–3 600; 0, the default:
    /// every state is stored). Live outputs (WebSocket, MQTT), zones and alarms still see every
    /// state; a change of status (coasting, lost), a switch between measured and predicted, and
    /// a revision of the newest stored state are stored whatever the interval. A 10 Hz site
    /// stores a tenth of the rows at 1 s (docs/SERVER.md, sizing).
    pub history_interval_s: f64,
    /// `text` or `json` logs.
    pub log_format: String,
    /// Accuracy of omlox locations without one (m).
    pub default_accuracy_m: f64,
    /// SQLite's `synchronous`: `full` (every commit is fsynced: safe against power loss) or
    /// `normal` (safe against a process crash, e.g. SIGKILL; the last commits may be lost on
    /// power loss).
    pub sqlite_sync: String,
    /// Origins whose web pages may call the API from a browser (CORS), e.g.
    /// `["https://ops.example.com"]`; `["*"]` for any origin; empty (the default): none — the
    /// dashboard served by this server needs no CORS.
    pub cors_origins: Vec<String>,
    /// Open HTTP connections at most (WebSockets included); more are closed at accept.
    pub max_connections: usize,
    /// Open HTTP connections of one IP address at most.
    pub max_connections_per_ip: usize,
    /// An HTTP connection that moves no byte for this long is closed (s, > 0).
    pub idle_timeout_s: f64,
    /// HTTP requests per second from one IP address at most, bursts of twice that (0: no
    /// limit); more are answered 429 with `Retry-After`.
    pub max_requests_per_s_per_ip: u32,
}

impl Default for ServerSection {
    fn default() -> Self {
        Self {
            http: SocketAddr::from(([127, 0, 0, 1], 8080)),
            site: None,
            db: "sqlite:rtls.db".into(),
            retention_days: 92.0,
            raw_retention_days: 1.0,
            compact_after_s: 300.0,
            history_interval_s: 0.0,
            log_format: "text".into(),
            default_accuracy_m: 1.0,
            sqlite_sync: "full".into(),
            cors_origins: Vec::new(),
            max_connections: 4096,
            max_connections_per_ip: 256,
            idle_timeout_s: 120.0,
            max_requests_per_s_per_ip: 500,
        }
    }
}

/// `[auth]`.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct AuthSection {
    /// The write token.
    pub write_token: Option<String>,
    /// The read token.
    pub read_token: Option<String>,
    /// Without a read token, whether reads need no credential (false: `rtls serve` generates a
    /// read token and prints it).
    pub open_reads: bool,
}

/// `[mqtt]`.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MqttSection {
    /// Embedded, external or off.
    pub mode: MqttMode,
    /// The embedded broker's listen address.
    pub listen: SocketAddr,
    /// The external broker's URL.
    pub url: Option<String>,
    /// The embedded broker's sessions at most.
    pub max_connections: usize,
    /// Of them, read-only (subscriber) sessions at most (capped at `max_connections`); the
    /// rest stays free for writers.
    pub max_read_connections: usize,
    /// Connections one IP address may hold at most.
    pub max_connections_per_ip: usize,
    /// Connections waiting for their CONNECT at most (idle sockets hold no session slot).
    pub max_pending_connects: usize,
}

impl Default for MqttSection {
    fn default() -> Self {
        Self {
            mode: MqttMode::Embedded,
            listen: SocketAddr::from(([127, 0, 0, 1], 1883)),
            url: None,
            max_connections: crate::mqtt::BrokerConfig::DEFAULT_MAX_CONNECTIONS,
            max_read_connections: crate::mqtt::BrokerConfig::DEFAULT_MAX_READ_CONNECTIONS,
            max_connections_per_ip: crate::mqtt::BrokerConfig::DEFAULT_MAX_CONNECTIONS_PER_IP,
            max_pending_connects: crate::mqtt::BrokerConfig::DEFAULT_MAX_PENDING_CONNECTS,
        }
    }
}

/// `[pipeline]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineSection {
    /// Tag partitions (0: the CPU count).
    pub partitions: usize,
    /// Advance tracks with the wall clock.
    pub live_clock: bool,
    /// How far behind the wall clock: seconds, or `"auto"` (measured from the records'
    /// delivery delays, [`crate::pipeline::clock_lag`]).
    pub clock_lag_s: crate::pipeline::clock_lag::ClockLag,
    /// With `live_clock`: records more than this behind the server clock are refused at ingest
    /// (s, > 0; a relative clock, a long-buffered replay).
    pub max_record_age_s: f64,
    /// With `live_clock`: records more than this ahead of the server clock are refused at
    /// ingest (s, > 0; a reader whose clock is wrong).
    pub max_record_lead_s: f64,
}

impl Default for PipelineSection {
    fn default() -> Self {
        Self {
            partitions: 0,
            live_clock: true,
            clock_lag_s: crate::pipeline::clock_lag::ClockLag::Auto,
            max_record_age_s: 86_400.0,
            max_record_lead_s: 60.0,
        }
    }
}

impl ServerConfig {
    /// Reads a configuration file.
    ///
    /// # Errors
    /// [`ConfigError::Read`], [`ConfigError::Parse`] (with toml's line, column and key), or
    /// [`ConfigError::Invalid`] from [`ServerConfig::validate`].
    pub fn from_file(path: &std::path::Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        let config: Self = toml::from_str(&text).map_err(|e| ConfigError::Parse {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Checks the values' ranges.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let invalid = |field: &str, reason: String| ConfigError::Invalid {
            field: field.into(),
            reason,
        };
        self.cluster.validate().map_err(|reason| invalid("cluster", reason))?;
        if let Some(generic) = &self.adapters.generic {
            generic
                .validate()
                .map_err(|reason| invalid("adapters.generic", reason))?;
        }
        self.adapters
            .zebra
            .validate()
            .map_err(|reason| invalid("adapters.zebra", reason))?;
        if self.cluster.enabled() && !self.server.db.starts_with("postgres") {
            return Err(invalid(
                "server.db",
                "a cluster's nodes share one PostgreSQL database (postgres://…); SQLite is one process's".into(),
            ));
        }
        let s = &self.server;
        if !(s.retention_days.is_finite() && s.retention_days > 0.0) {
            return Err(invalid(
                "server.retention_days",
                format!("must be > 0 days, got {}", s.retention_days),
            ));
        }
        if !(s.raw_retention_days.is_finite() && s.raw_retention_days > 0.0) {
            return Err(invalid(
                "server.raw_retention_days",
                format!("must be > 0 days, got {}", s.raw_retention_days),
            ));
        }
        if !(s.compact_after_s.is_finite() && (1.0..=86_400.0).contains(&s.compact_after_s)) {
            return Err(invalid(
                "server.compact_after_s",
                format!("must be 1–86400 s, got {}", s.compact_after_s),
            ));
        }
        if !(s.history_interval_s.is_finite() && (0.0..=3_600.0).contains(&s.history_interval_s)) {
            return Err(invalid(
                "server.history_interval_s",
                format!("must be 0–3600 s, got {}", s.history_interval_s),
            ));
        }
        if !matches!(s.log_format.as_str(), "text" | "json") {
            return Err(invalid(
                "server.log_format",
                format!("`{}` is not text or json", s.log_format),
            ));
        }
        if !matches!(s.sqlite_sync.as_str(), "full" | "normal") {
            return Err(invalid(
                "server.sqlite_sync",
                format!("`{}` is not full or normal", s.sqlite_sync),
            ));
        }
        if !(s.default_accuracy_m.is_finite() && s.default_accuracy_m > 0.0) {
            return Err(invalid(
                "server.default_accuracy_m",
                format!("must be > 0 m, got {}", s.default_accuracy_m),
            ));
        }
        for (field, value) in [
            ("server.max_connections", s.max_connections),
            ("server.max_connections_per_ip", s.max_connections_per_ip),
        ] {
            if value == 0 {
                return Err(invalid(field, "must be at least 1".into()));
            }
        }
        if !(s.idle_timeout_s.is_finite() && s.idle_timeout_s > 0.0) {
            return Err(invalid(
                "server.idle_timeout_s",
                format!("must be a finite number > 0 s, got {}", s.idle_timeout_s),
            ));
        }
        for (k, origin) in s.cors_origins.iter().enumerate() {
            let scheme_ok = origin.starts_with("http://") || origin.starts_with("https://");
            if origin != "*"
                && (!scheme_ok || origin.ends_with('/') || origin.parse::<axum::http::HeaderValue>().is_err())
            {
                return Err(invalid(
                    &format!("server.cors_origins[{k}]"),
                    format!("`{origin}` is not \"*\" or an origin like https://ops.example.com (scheme, host, port; no path)"),
                ));
            }
        }
        let m = &self.mqtt;
        for (field, value) in [
            ("mqtt.max_connections", m.max_connections),
            ("mqtt.max_read_connections", m.max_read_connections),
            ("mqtt.max_connections_per_ip", m.max_connections_per_ip),
            ("mqtt.max_pending_connects", m.max_pending_connects),
        ] {
            if value == 0 {
                return Err(invalid(field, "must be at least 1".into()));
            }
        }
        if self.mqtt.mode == MqttMode::External && self.mqtt.url.is_none() {
            return Err(invalid("mqtt.url", "required when mqtt.mode = \"external\"".into()));
        }
        let p = &self.pipeline;
        if let crate::pipeline::clock_lag::ClockLag::Fixed(lag_s) = p.clock_lag_s {
            if !(lag_s.is_finite() && lag_s >= 0.0) {
                return Err(invalid(
                    "pipeline.clock_lag_s",
                    format!("must be ≥ 0 s or \"auto\", got {lag_s}"),
                ));
            }
        }
        for (field, value) in [
            ("pipeline.max_record_age_s", p.max_record_age_s),
            ("pipeline.max_record_lead_s", p.max_record_lead_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(field, format!("must be a finite number > 0 s, got {value}")));
            }
        }
        for (field, token) in [
            ("auth.write_token", &self.auth.write_token),
            ("auth.read_token", &self.auth.read_token),
        ] {
            if token.as_deref().is_some_and(|t| t.len() < 8) {
                return Err(invalid(field, "must be at least 8 characters".into()));
            }
        }
        let t = &self.tls;
        if t.cert.is_some() != t.key.is_some() {
            return Err(invalid("tls.cert", "tls.cert and tls.key go together".into()));
        }
        if !(t.reload_s.is_finite() && t.reload_s > 0.0) {
            return Err(invalid(
                "tls.reload_s",
                format!("must be a finite number > 0 s, got {}", t.reload_s),
            ));
        }
        validate_webhooks(&self.webhooks)?;
        self.udp.validate(self.adapters.generic.is_some())?;
        validate_nats_forwards(&self.nats_forward)?;
        Ok(())
    }
}

/// `url` (database, MQTT broker) with the password of its `user:password@` part replaced by
/// `***`, for log lines and error messages.
pub(crate) fn redact_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    let authority_end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    let (authority, path) = rest.split_at(authority_end);
    match authority.rsplit_once('@') {
        Some((user_info, host)) => match user_info.split_once(':') {
            Some((user, _password)) => format!("{scheme}://{user}:***@{host}{path}"),
            None => url.to_owned(),
        },
        None => url.to_owned(),
    }
}

#[cfg(test)]
mod tests;
