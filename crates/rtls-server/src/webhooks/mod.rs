//! Outbound webhooks: alarms (and their acknowledgements) POSTed as JSON to HTTP(S) endpoints
//! configured in `[[webhooks]]` ([`crate::config::WebhookSection`]). So far the event types a
//! webhook may ask for; the dispatcher follows.

use serde_json::Value;

/// Every event type a webhook may ask for in `events`: the `rtls:alarms` topic's.
pub const EVENT_TYPES: [&str; 7] = [
    "hazard-predicted",
    "no-coverage",
    "lost",
    "alarm-acknowledged",
    "hazard-cleared",
    "recovered",
    "model-switch",
];

/// The types sent when `events` is not given: the alarms (each with an `alarm_id`) and their
/// acknowledgements.
pub const DEFAULT_EVENT_TYPES: [&str; 4] = ["hazard-predicted", "no-coverage", "lost", "alarm-acknowledged"];

/// The name `events` knows an `rtls:alarms` message by: its `type` (`hazard-predicted`,
/// `alarm-acknowledged`, …), or for a `lifecycle` event its `event` (`lost`, `recovered`).
#[must_use]
pub fn event_type(event: &Value) -> Option<&str> {
    match event["type"].as_str()? {
        "lifecycle" => event["event"].as_str(),
        other => Some(other),
    }
}
