//! WebSocket messages of `/v2/ws/socket`: `{event, topic, subscription_id, payload, params}`.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::Properties;

/// What a WebSocket message is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WsEvent {
    /// Client → hub: subscribe to a topic.
    Subscribe,
    /// Hub → client: the subscription exists, with its id.
    Subscribed,
    /// Client → hub: end a subscription.
    Unsubscribe,
    /// Hub → client: the subscription ended.
    Unsubscribed,
    /// Hub → client (or client → hub for ingest): data on a topic.
    Message,
    /// Hub → client: something failed; see [`WsMessage::code`].
    Error,
}

/// A topic: the spec's, their GeoJSON variants, and our extensions (prefixed `rtls:`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Topic {
    /// Location objects.
    #[serde(rename = "location_updates")]
    LocationUpdates,
    /// Locations as GeoJSON features.
    #[serde(rename = "location_updates:geojson")]
    LocationUpdatesGeojson,
    /// Fence events.
    #[serde(rename = "fence_events")]
    FenceEvents,
    /// Fence events as GeoJSON features.
    #[serde(rename = "fence_events:geojson")]
    FenceEventsGeojson,
    /// Trackable motions.
    #[serde(rename = "trackable_motions")]
    TrackableMotions,
    /// Collision events.
    #[serde(rename = "collision_events")]
    CollisionEvents,
    /// Proximity updates.
    #[serde(rename = "proximity_updates")]
    ProximityUpdates,
    /// Extension: predictive hazard alarms (raised / cleared), no-coverage, lost and recovered
    /// tags, motion-model switches — what a control room must see.
    #[serde(rename = "rtls:alarms")]
    RtlsAlarms,
    /// Extension: every other engine event (zone dwell, lifecycle, schedule, late, rejected).
    #[serde(rename = "rtls:events")]
    RtlsEvents,
    /// Extension: the location updates of `location_updates` in a compact, columnar form for
    /// maps with thousands of tags — one object per WebSocket message with one array per field
    /// (`tag`, `t`, `x`, `y`, `z`, `cxx`, `cxy`, `cyy`, `status`, `predicted`); see
    /// docs/SERVER.md.
    #[serde(rename = "rtls:positions")]
    RtlsPositions,
}

impl Topic {
    /// Whether the topic is in the omlox spec (not one of our `rtls:` extensions).
    #[must_use]
    pub fn is_standard(self) -> bool {
        !matches!(self, Self::RtlsAlarms | Self::RtlsEvents)
    }
}

/// The WebSocket error codes of the spec (`WebsocketError.code`), as numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WsErrorCode {
    /// 10000 — unknown event.
    UnknownEvent = 10000,
    /// 10001 — unknown topic.
    UnknownTopic = 10001,
    /// 10002 — subscription failed.
    SubscriptionFailed = 10002,
    /// 10003 — unsubscribe failed.
    UnsubscribeFailed = 10003,
    /// 10004 — not authorised.
    NotAuthorized = 10004,
    /// 10005 — invalid data.
    InvalidData = 10005,
}

impl WsErrorCode {
    /// The numeric code.
    #[must_use]
    pub fn code(self) -> u32 {
        self as u32
    }

    /// The spec's text after the number (`"Unknown event"`, …).
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Self::UnknownEvent => "Unknown event",
            Self::UnknownTopic => "Unknown topic",
            Self::SubscriptionFailed => "Subscription failed",
            Self::UnsubscribeFailed => "Unsubscribe failed",
            Self::NotAuthorized => "Not authorized",
            Self::InvalidData => "Invalid data",
        }
    }
}

/// One WebSocket message. Which fields are set depends on `event`: see the constructors.
///
/// # Examples
/// ```
/// use rtls_server::omlox::ws::{Topic, WsMessage};
/// let text = r#"{"event":"subscribe","topic":"location_updates"}"#;
/// let message: WsMessage = serde_json::from_str(text).unwrap();
/// assert_eq!(message.topic, Some(Topic::LocationUpdates));
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WsMessage {
    /// What the message is.
    pub event: WsEvent,
    /// The topic (absent on errors about the message itself).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub topic: Option<Topic>,
    /// The hub-assigned subscription id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subscription_id: Option<u64>,
    /// omlox objects of the topic's one type (Location for `location_updates`, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Vec<Value>>,
    /// Subscription parameters (filters such as `provider_id`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<Properties>,
    /// Error code (10000–10005) on `error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub code: Option<u32>,
    /// Error description on `error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
}

impl WsMessage {
    /// A `message` carrying `payload` on `topic` for subscription `subscription_id`.
    #[must_use]
    pub fn message(topic: Topic, subscription_id: u64, payload: Vec<Value>) -> Self {
        Self {
            event: WsEvent::Message,
            topic: Some(topic),
            subscription_id: Some(subscription_id),
            payload: Some(payload),
            params: None,
            code: None,
            description: None,
        }
    }

    /// The `subscribed` answer.
    #[must_use]
    pub fn subscribed(topic: Topic, subscription_id: u64) -> Self {
        Self {
            event: WsEvent::Subscribed,
            topic: Some(topic),
            subscription_id: Some(subscription_id),
            payload: None,
            params: None,
            code: None,
            description: None,
        }
    }

    /// An `error` with the spec's code and a description (`detail` appended when not empty).
    #[must_use]
    pub fn error(code: WsErrorCode, detail: &str) -> Self {
        let description = if detail.is_empty() {
            code.description().to_string()
        } else {
            format!("{}: {detail}", code.description())
        };
        Self {
            event: WsEvent::Error,
            topic: None,
            subscription_id: None,
            payload: None,
            params: None,
            code: Some(code.code()),
            description: Some(description),
        }
    }
}
