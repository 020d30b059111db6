//! Locations that providers push (`PUT /v2/providers/locations`, `…/{id}/location`) keep
//! what the provider said — `source`, `provider_type`, `accuracy`, `properties`, and the
//! position and times of the pushed fix — with our filtered estimate alongside, in
//! `properties["rtls:filtered"]`.
//!
//! The track's update of the pushed fix's own time is returned as the pushed location plus
//! `rtls:filtered` ({`position`, `accuracy`, `speed`, `course` and the `rtls:*` properties of our
//! estimate}); the track's other updates (coasting, predictions between pushes) are ours, with
//! the provider's `source`, `provider_type` and properties.

use serde_json::json;

use crate::omlox::Location;

/// The latest location a provider pushed, and its time (s, as the record it became).
#[derive(Debug, Clone, PartialEq)]
pub struct PushedLocation {
    /// As pushed.
    pub location: Location,
    /// Its time: `timestamp_generated`, else `timestamp_sent`, else when it was received (s).
    pub time_s: f64,
}

/// Two times within this are the same fix's (s).
const SAME_TIME_S: f64 = 1e-6;

/// Whether two times are the same fix's.
#[must_use]
pub fn same_time(a_s: f64, b_s: f64) -> bool {
    (a_s - b_s).abs() <= SAME_TIME_S
}

/// The location to publish for a track update (`ours`, at `update_time_s`) of a provider that
/// pushes its own locations.
///
/// # Examples
/// ```
/// use rtls_server::omlox::Location;
/// use rtls_server::pushed::{with_pushed, PushedLocation};
/// let location = |x: f64, source: &str| -> Location {
///     serde_json::from_value(serde_json::json!({
///         "position": {"type": "Point", "coordinates": [x, 2.0]}, "source": source,
///         "provider_type": "uwb", "provider_id": "t1", "accuracy": 0.3,
///         "properties": {"battery": 80}
///     }))
///     .unwrap()
/// };
/// let pushed = PushedLocation { location: location(1.0, "vendor-hub"), time_s: 10.0 };
/// let merged = with_pushed(location(1.1, "rtls"), &pushed, 10.0);
/// assert_eq!(merged.position.coordinates, vec![1.0, 2.0]);
/// assert_eq!(merged.source, "vendor-hub");
/// let properties = merged.properties.unwrap();
/// assert_eq!(properties["battery"], 80);
/// assert_eq!(properties["rtls:filtered"]["position"]["coordinates"][0], 1.1);
/// ```
#[must_use]
pub fn with_pushed(ours: Location, pushed: &PushedLocation, update_time_s: f64) -> Location {
    let mut provider_properties = pushed.location.properties.clone().unwrap_or_default();
    if same_time(update_time_s, pushed.time_s) {
        // the pushed fix itself, with our estimate of that instant alongside
        let mut filtered = json!({
            "position": ours.position,
            "accuracy": ours.accuracy,
            "speed": ours.speed,
            "course": ours.course,
        });
        if let (Some(object), Some(properties)) = (filtered.as_object_mut(), &ours.properties) {
            object.extend(properties.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
        provider_properties.insert("rtls:filtered".into(), filtered);
        let mut location = pushed.location.clone();
        location.properties = Some(provider_properties);
        return location;
    }
    // between pushes: our estimate, as the provider's
    let mut location = ours;
    let mut properties = location.properties.take().unwrap_or_default();
    for (key, value) in provider_properties {
        properties.entry(key).or_insert(value);
    }
    location.source.clone_from(&pushed.location.source);
    location.provider_type = pushed.location.provider_type;
    location.properties = Some(properties);
    location
}
