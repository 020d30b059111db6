//! Adapters for RTLS vendors' own position feeds: each turns one message of a vendor's
//! published format (JSON, or Zebra Dart's ASCII lines) into our `fix` records (`rtls_engine::record`), so an installation
//! that already runs a vendor's positioning engine can feed its positions to the tracker
//! without a converter of its own.
//!
//! | vendor | [`Vendor`] | message | units in | reference |
//! | --- | --- | --- | --- | --- |
//! | Pozyx (Enterprise / Creator) | `pozyx` | the MQTT `tags` stream: an array of tag updates | mm, Unix s | <https://docs.pozyx.io/enterprise/MQTT-data-structure.1224015817.html> |
//! | Quuppa (QPE) | `quuppa` | `DefaultLocation` tag data (`/qpe/getTagData`, output targets): one tag object, an array of them, or a `{"tags": [...]}` response | m, Unix ms | <https://www.quuppa.com/documentation/QSP/topics/QSP_udp_logging_api.html> |
//! | Sewio (RTLS Studio) | `sewio` | a feed with `datastreams` `posX`/`posY`/`posZ`/`clr`: a WebSocket message `{"body": feed, "resource": …}`, a REST feed or a REST `{"results": [feed, …]}` | m, UTC `YYYY-MM-DD hh:mm:ss.sss` | <http://rtlsstudio.com/studio/index.php/websockets-connector/> |
//! | OpenRTLS | `openrtls` | the master's JSON location (LS) output, UDP port 8787 (API 16040600): one message (or an array) with `id`, `timestamp`, `coordinates` `{x, y, z, …}` | m (not stated: see the module), Unix s | <https://wiki.openrtls.com/index.php?title=Software:JsonCommands> |
//! | Zebra Dart UWB (hub) | `zebra` | the hub's Dart-format ASCII output (TCP port 5117): lines `R`/`T`/`O` (locates), `P`/`N`/`D`/`I` (refused), settings in `[adapters.zebra]` ([`ZebraAdapter`]) | m or ft (`[adapters.zebra] unit`), Unix s | Zebra, "Dart RTLS User Guide" D2119 Rev F, ch. 11 "System output", pp. 83–88 |
//!
//! A gateway of none of these vendors can be read by the generic adapter (`generic`,
//! [`GenericAdapter`]) once its field names are configured in `[adapters.generic]`.
//!
//! Each adapter's module names the published example messages its tests use. The Zebra hub
//! can also be read directly: `rtls serve` connects to its output port and reads its lines
//! ([`crate::zebra_hub`]). Of Zebra's formats only the Dart one is read: the guide names the
//! Z-SLMF format of port 5118 but does not describe it.
//!
//! # Units
//! Positions become metres in the vendor's own frame (the site's frame must be the vendor's:
//! no transform is applied), times Unix seconds. A vendor's accuracy radius `r` (m) — Quuppa's
//! `locationRadius`, Sewio's `clr` — becomes the covariance `r² I` of the fix (`r` taken as the
//! standard deviation of each coordinate); where the vendor gives none (Pozyx) or gives 0, the
//! server's `default_accuracy_m` is used instead. Zebra's hub gives a GDOP instead of a
//! radius: its module says how that becomes σ.
//!
//! # Refusals
//! A well-formed message that carries no position — Pozyx `"success": false`, a Quuppa
//! `locationType` other than `position`, a Sewio battery or zone update, a Sewio anchor, a
//! Zebra presence, non-locate, diagnostic or information packet — is not an error and is not
//! dropped silently: it is returned as a [`Refusal`] whose `reason` the ingest path counts in
//! `rtls_ingest_refused_total{reason}` and reports to the sender.
//! A malformed message is an [`AdapterError`] naming the field. In Zebra's line-based output a
//! malformed line costs that line only: beside usable lines it is a [`Refusal`] with reason
//! `format`.
//!
//! # Examples
//! ```
//! use rtls_server::adapters::{parse, Vendor};
//! // from the Sewio RTLS Studio WebSockets connector documentation
//! let message = r#"{"body":{"id":"18","datastreams":[{"id":"posX","current_value":" 6.34","at":"2016-10-18 14:16:56.365"},{"id":"posY","current_value":" 2.27","at":"2016-10-18 14:16:56.365"},{"id":"clr","current_value":" 0.10","at":"2016-10-18 14:16:56.365"}]},"resource":"\/feeds\/18"}"#;
//! let parsed = parse(Vendor::Sewio, message.as_bytes(), 1.0).unwrap();
//! assert_eq!(parsed.records[0].tag, "18");
//! assert!(parsed.refusals.is_empty());
//! ```

mod generic;
mod openrtls;
mod pozyx;
mod quuppa;
mod sewio;
mod zebra;

pub use generic::{GenericAdapter, LengthUnit, TimeUnit};
pub use zebra::{ZebraAdapter, ZebraUnit};

use rtls_engine::record::{Measurement, Record};
use serde_json::Value;

/// The prefix of the MQTT topics vendor feeds are published to (`rtls/v1/adapters/{vendor}/…`).
pub const MQTT_PREFIX: &str = "rtls/v1/adapters/";

/// A vendor whose feed the server reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Vendor {
    /// Pozyx Enterprise / Creator: the MQTT `tags` stream.
    Pozyx,
    /// Quuppa Positioning Engine: `DefaultLocation` tag data.
    Quuppa,
    /// Sewio RTLS Studio: WebSocket / REST feeds.
    Sewio,
    /// Zebra Dart UWB: the hub's Dart-format ASCII lines (settings in `[adapters.zebra]`,
    /// [`ZebraAdapter`]).
    Zebra,
    /// OpenRTLS: the master's JSON location output.
    OpenRtls,
    /// A gateway whose field names are configured (`[adapters.generic]`, [`GenericAdapter`]).
    Generic,
}

impl Vendor {
    /// Every vendor, in the order of the documentation.
    pub const ALL: [Vendor; 6] = [
        Vendor::Pozyx,
        Vendor::Quuppa,
        Vendor::Sewio,
        Vendor::Zebra,
        Vendor::OpenRtls,
        Vendor::Generic,
    ];

    /// The vendor's name in routes and topics (`pozyx`, `quuppa`, `sewio`, `zebra`, `openrtls`,
    /// `generic`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Vendor::Pozyx => "pozyx",
            Vendor::Quuppa => "quuppa",
            Vendor::Sewio => "sewio",
            Vendor::Zebra => "zebra",
            Vendor::OpenRtls => "openrtls",
            Vendor::Generic => "generic",
        }
    }

    /// The vendor named `name` (as [`Vendor::name`]), if any.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::adapters::Vendor;
    /// assert_eq!(Vendor::from_name("quuppa"), Some(Vendor::Quuppa));
    /// assert_eq!(Vendor::from_name("zebra"), Some(Vendor::Zebra));
    /// assert_eq!(Vendor::from_name("acme"), None);
    /// ```
    #[must_use]
    pub fn from_name(name: &str) -> Option<Vendor> {
        Vendor::ALL.into_iter().find(|v| v.name() == name)
    }

    /// The vendor of an MQTT topic `rtls/v1/adapters/{vendor}[/…]`, if it is one.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::adapters::Vendor;
    /// assert_eq!(Vendor::from_topic("rtls/v1/adapters/pozyx/tags"), Some(Vendor::Pozyx));
    /// assert_eq!(Vendor::from_topic("rtls/v1/measurements/r1"), None);
    /// ```
    #[must_use]
    pub fn from_topic(topic: &str) -> Option<Vendor> {
        let rest = topic.strip_prefix(MQTT_PREFIX)?;
        Vendor::from_name(rest.split('/').next().unwrap_or(rest))
    }
}

/// A malformed vendor message: the field (with its index in the message, e.g. `[0].tagId`)
/// and what is wrong with it. Nothing of the message is used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AdapterError {
    /// The payload is not JSON (a JSON vendor's).
    #[error("not valid JSON ({0}): send the vendor's message unchanged")]
    Json(String),
    /// The generic adapter was asked for but the server's configuration has no
    /// `[adapters.generic]`.
    #[error("the generic adapter is not configured: add [adapters.generic] (tag, time, x, y paths) to the server's configuration")]
    NotConfigured,
    /// A field is missing or has the wrong type or value.
    #[error("{field}: {reason}")]
    Field {
        /// The field's path, e.g. `[0].data.coordinates.x`, or line and field, e.g.
        /// `line 2 <X>`.
        field: String,
        /// What is wrong, and what was expected.
        reason: String,
    },
}

impl AdapterError {
    fn field(field: impl Into<String>, reason: impl Into<String>) -> Self {
        AdapterError::Field {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// A well-formed vendor message that carries no position.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Refusal {
    /// The message's path in the payload (`[1]`, `tags[0]`, `body`, `line 3`).
    pub at: String,
    /// The tag, when the message names one.
    pub tag: Option<String>,
    /// The counter's label: `no_position`, `anchor`, or `format` (a malformed line among
    /// usable ones in a line-based payload: Zebra's).
    pub reason: &'static str,
    /// Why, in words.
    pub detail: String,
}

/// The records of a vendor payload and its messages without a position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Parsed {
    /// One `fix` record per message with a position, in payload order.
    pub records: Vec<Record>,
    /// The messages without a position (and a line-based payload's malformed lines).
    pub refusals: Vec<Refusal>,
}

/// Parses one payload of `vendor`'s feed into fix records (see the [module](self) for units and
/// refusals); `default_accuracy_m` (σ, m) weighs fixes whose message gives no accuracy. The
/// generic adapter needs its settings: [`GenericAdapter::parse`]; Zebra's are taken at their
/// defaults (metres): [`ZebraAdapter::parse`] with others.
///
/// # Errors
/// [`AdapterError::Json`] when a JSON vendor's payload is not JSON, [`AdapterError::Field`]
/// naming the first malformed field (a missing tag id, a non-numeric coordinate, a time stamp
/// that is not one), [`AdapterError::NotConfigured`] for [`Vendor::Generic`].
///
/// # Examples
/// ```
/// use rtls_server::adapters::{parse, Vendor};
/// let error = parse(Vendor::Pozyx, br#"[{"timestamp": 1.0, "success": true}]"#, 1.0).unwrap_err();
/// assert_eq!(error.to_string(), "[0].tagId: required field is missing");
/// ```
pub fn parse(vendor: Vendor, payload: &[u8], default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
    let json = |parse: fn(&Value, f64) -> Result<Parsed, AdapterError>| {
        let value: Value = serde_json::from_slice(payload).map_err(|e| AdapterError::Json(e.to_string()))?;
        parse(&value, default_accuracy_m)
    };
    match vendor {
        Vendor::Pozyx => json(pozyx::parse),
        Vendor::Quuppa => json(quuppa::parse),
        Vendor::Sewio => json(sewio::parse),
        Vendor::OpenRtls => json(openrtls::parse),
        Vendor::Zebra => ZebraAdapter::default().parse(payload, default_accuracy_m),
        Vendor::Generic => Err(AdapterError::NotConfigured),
    }
}

/// A `fix` record with the covariance `σ² I` (σ = `accuracy_m`).
fn fix(time_s: f64, tag: String, position_m: Vec<f64>, accuracy_m: f64) -> Record {
    let d = position_m.len();
    let mut covariance_m2 = vec![0.0; d * d];
    for i in 0..d {
        // R = σ² I
        covariance_m2[i * d + i] = accuracy_m * accuracy_m;
    }
    Record {
        time_s,
        tag,
        measurement: Measurement::Fix {
            position_m,
            covariance_m2,
        },
    }
}

/// A finite number at `field`, or an error naming it.
fn number(value: &Value, field: &str) -> Result<f64, AdapterError> {
    value
        .as_f64()
        .filter(|x| x.is_finite())
        .ok_or_else(|| AdapterError::field(field, format!("expected a finite number, got {value}")))
}

/// A tag id: a non-empty string (or an integer, written in decimal), or an error naming it.
/// The messages of a payload that is one JSON object or an array of them.
///
/// # Errors
/// An [`AdapterError`] on `-` for anything else, saying `expected {what}`.
fn objects<'a>(value: &'a Value, what: &str) -> Result<Vec<&'a Value>, AdapterError> {
    match value {
        Value::Array(items) => Ok(items.iter().collect()),
        Value::Object(_) => Ok(vec![value]),
        other => Err(AdapterError::field("-", format!("expected {what}, got {other}"))),
    }
}

/// A record's fix, `(position_m, covariance_m2)`, for the adapters' tests.
#[cfg(test)]
fn fix_of(record: &Record) -> (&[f64], &[f64]) {
    match &record.measurement {
        Measurement::Fix {
            position_m,
            covariance_m2,
        } => (position_m, covariance_m2),
        other => panic!("expected a fix, got {other:?}"),
    }
}

fn tag_id(value: Option<&Value>, field: &str) -> Result<String, AdapterError> {
    match value {
        None | Some(Value::Null) => Err(AdapterError::field(field, "required field is missing")),
        Some(Value::String(s)) if !s.trim().is_empty() => Ok(s.trim().to_string()),
        Some(Value::Number(n)) if n.is_u64() || n.is_i64() => Ok(n.to_string()),
        Some(other) => Err(AdapterError::field(
            field,
            format!("expected a non-empty tag id, got {other}"),
        )),
    }
}

/// The accuracy radius `radius_m` when it weighs a fix (> 0 and finite), else the default.
fn accuracy_or(radius_m: Option<f64>, default_accuracy_m: f64) -> f64 {
    radius_m
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(default_accuracy_m)
}
