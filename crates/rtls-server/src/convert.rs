//! The engine's outputs in omlox terms, and ingested omlox locations as engine records.
//!
//! Choices, documented once:
//! - **Time**: the engine's `time_s` is taken as Unix seconds (the site clock) and written as
//!   ISO 8601 UTC with millisecond precision.
//! - **Ids**: omlox ids are UUIDs; ours are names. [`uuid_for`] derives a stable name-based UUID
//!   (RFC 4122 version 5, the `uuid` crate) from a namespace and a name, so the same zone or tag
//!   always gets the same id; the name goes in `foreign_id` / `provider_id`.
//! - **Frame**: everything is `crs: "local"` (site metres) unless a read asks for `EPSG:4326`.
//!   `course` is from true north, as omlox defines it: through the site's `[frame]` (the
//!   bearing of its `x` axis, [`true_course_deg`]); on a site without one, +y is taken as north.
//! - **Accuracy**: the 1-σ radius of the horizontal position covariance's major axis,
//!   `√λ_max` of the x–y block — conservative in every direction, and exactly σ for a circular
//!   error. Back on ingest, `accuracy = a` becomes the covariance `a² I`.

use rtls_engine::lifecycle::LifecycleEvent;
use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::FrameSettings;
use rtls_engine::tracker::{status_name, Event, TrackUpdate};
use rtls_engine::zones::{Shape, Zone as SiteZone, ZoneEvent, ZoneKind};
use serde_json::{json, Value};

use crate::omlox::crs::Crs;
use crate::omlox::time::{format_timestamp, parse_timestamp};
use crate::omlox::ws::Topic;
use crate::omlox::{Fence, FenceEvent, FenceEventType, Location, Point, Properties, ProviderType, Region};
use crate::{Result, ServerError};
use uuid::Uuid;

/// A stable name-based UUID (RFC 4122 version 5, SHA-1) for `name` within `namespace` (e.g.
/// `"fence"`, `"tag"`): omlox ids are UUIDs, ours are names.
///
/// # Examples
/// ```
/// use rtls_server::convert::uuid_for;
/// let id = uuid_for("fence", "stope-7");
/// assert_eq!(id, uuid_for("fence", "stope-7"));
/// assert_ne!(id, uuid_for("tag", "stope-7"));
/// assert_eq!((id.len(), &id[14..15]), (36, "5"));
/// ```
#[must_use]
pub fn uuid_for(namespace: &str, name: &str) -> String {
    // RFC 4122 name-based (SHA-1) UUIDs: the namespace's own UUID from "urn:rtls:<namespace>"
    let namespace = Uuid::new_v5(&Uuid::NAMESPACE_URL, format!("urn:rtls:{namespace}").as_bytes());
    Uuid::new_v5(&namespace, name.as_bytes()).to_string()
}

/// A GeoJSON geometry in site coordinates (m) as RFC 7946 wants it when the site is
/// georeferenced (`[frame] origin`): every position `[x, y(, z)]` becomes
/// `[longitude, latitude(, height)]` in WGS-84 degrees (and m above the ellipsoid); without a
/// frame the geometry is returned as it is (local metres). Works on any geometry's
/// `coordinates` nesting (Point, LineString, Polygon, …) and on a bare position array.
///
/// # Examples
/// ```
/// use rtls_server::convert::wgs84_geometry;
/// use serde_json::json;
/// let local = json!({ "type": "Point", "coordinates": [3.0, 4.0] });
/// assert_eq!(wgs84_geometry(None, &local), local);
/// let frame = rtls_engine::site::FrameSettings {
///     origin: rtls_engine::site::GeodeticOrigin { latitude_deg: 0.0, longitude_deg: 10.0, height_m: 0.0 },
///     x_axis_bearing_deg: 90.0,
/// };
/// let origin = wgs84_geometry(Some(&frame), &json!({ "type": "Point", "coordinates": [0.0, 0.0] }));
/// assert!((origin["coordinates"][0].as_f64().unwrap() - 10.0).abs() < 1e-9);
/// ```
#[must_use]
pub fn wgs84_geometry(frame: Option<&rtls_engine::site::FrameSettings>, geometry: &Value) -> Value {
    let Some(frame) = frame else {
        return geometry.clone();
    };
    fn convert(frame: &rtls_engine::site::FrameSettings, value: &Value) -> Value {
        match value {
            Value::Array(items) if items.first().is_some_and(Value::is_number) => {
                let at = |k: usize| items.get(k).and_then(Value::as_f64);
                match (at(0), at(1)) {
                    (Some(x), Some(y)) => {
                        let z = at(2);
                        match frame.wgs84_of([x, y, z.unwrap_or(0.0)]) {
                            Some([lon, lat, h]) if z.is_some() => json!([lon, lat, h]),
                            Some([lon, lat, _]) => json!([lon, lat]),
                            None => value.clone(),
                        }
                    }
                    _ => value.clone(),
                }
            }
            Value::Array(items) => Value::Array(items.iter().map(|v| convert(frame, v)).collect()),
            Value::Object(object) => Value::Object(
                object
                    .iter()
                    .map(|(k, v)| {
                        let v = if k == "coordinates" {
                            convert(frame, v)
                        } else {
                            v.clone()
                        };
                        (k.clone(), v)
                    })
                    .collect(),
            ),
            other => other.clone(),
        }
    }
    convert(frame, geometry)
}

/// An alarm's stable id: the name-based UUID of its event's JSON line, so the same alarm
/// regenerated by a replay after a restart keeps the id an acknowledgement refers to.
///
/// # Examples
/// ```
/// use rtls_server::convert::alarm_id;
/// let line = r#"{"type":"lifecycle","t":12.5,"tag":"miner-7","event":"lost"}"#;
/// assert_eq!(alarm_id(line), alarm_id(line));
/// assert_ne!(alarm_id(line), alarm_id(&line.replace("12.5", "13.0")));
/// ```
#[must_use]
pub fn alarm_id(event_json_line: &str) -> String {
    uuid_for("alarm", event_json_line)
}

/// The horizontal accuracy, m: `√λ_max` of the x–y block of a row-major `D × D` covariance.
///
/// # Examples
/// ```
/// use rtls_server::convert::accuracy_m;
/// // diag(4, 1): the major axis has σ = 2 m.
/// assert_eq!(accuracy_m(&[4.0, 0.0, 0.0, 1.0], 2), 2.0);
/// ```
#[must_use]
pub fn accuracy_m(covariance_m2: &[f64], dimensions: usize) -> f64 {
    let (a, b, d) = (covariance_m2[0], covariance_m2[1], covariance_m2[dimensions + 1]);
    // λ_max = (a + d)/2 + √(((a − d)/2)² + b²)
    let lambda_max = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt();
    lambda_max.max(0.0).sqrt()
}

/// Course, degrees clockwise from north (+y), in `[0, 360)`; `None` when not moving.
#[must_use]
pub fn course_deg(vx_mps: f64, vy_mps: f64) -> Option<f64> {
    if vx_mps == 0.0 && vy_mps == 0.0 {
        return None;
    }
    Some(vx_mps.atan2(vy_mps).to_degrees().rem_euclid(360.0))
}

/// A course measured clockwise from the site's +y axis (`course_deg`) as omlox's, clockwise
/// from true north: `c + (β − 90°)` modulo 360°, where `β` is the bearing of the site's `x`
/// axis (`[frame] x_axis_bearing_deg`; +y is then at `β − 90°`). Without a frame, +y is north.
///
/// # Examples
/// ```
/// use rtls_engine::site::{FrameSettings, GeodeticOrigin};
/// use rtls_server::convert::true_course_deg;
/// let origin = GeodeticOrigin { latitude_deg: 47.0, longitude_deg: 8.0, height_m: 0.0 };
/// // x east (bearing 90°): +y is north, nothing turns
/// let east = FrameSettings { origin, x_axis_bearing_deg: 90.0 };
/// assert_eq!(true_course_deg(30.0, Some(&east)), 30.0);
/// // x north (bearing 0°): moving along +x (site course 90°) is moving north
/// let north = FrameSettings { origin, x_axis_bearing_deg: 0.0 };
/// assert_eq!(true_course_deg(90.0, Some(&north)), 0.0);
/// assert_eq!(true_course_deg(90.0, None), 90.0);
/// ```
#[must_use]
pub fn true_course_deg(site_course_deg: f64, frame: Option<&FrameSettings>) -> f64 {
    match frame {
        Some(frame) => (site_course_deg + frame.x_axis_bearing_deg - 90.0).rem_euclid(360.0),
        None => site_course_deg,
    }
}

/// A track update as an omlox Location: `crs: "local"`, `provider_id` the tag, `source` the
/// omlox zone id of the site, accuracy and course as in the module docs, speed the horizontal
/// speed, and `properties` `rtls:predicted`, `rtls:status`, `rtls:source`, `rtls:covariance_m2`
/// (and `rtls:mode` under IMM; `rtls:revised: true` on an update that replaces one already
/// published — a late record re-filtered).
///
/// # Errors
/// [`ServerError::Unrepresentable`] when the time cannot be written as a timestamp.
pub fn location_from_update(update: &TrackUpdate, source: &str, provider_type: ProviderType) -> Result<Location> {
    let d = update.dimensions.clamp(2, 3);
    let [vx, vy, _] = update.velocity_mps;
    let mut properties = Properties::new();
    properties.insert("rtls:predicted".into(), json!(update.predicted));
    if update.revised {
        properties.insert("rtls:revised".into(), json!(true));
    }
    properties.insert("rtls:status".into(), json!(status_name(update.status)));
    properties.insert("rtls:source".into(), json!(update.source.name()));
    properties.insert(
        "rtls:covariance_m2".into(),
        json!(&update.position_covariance_m2[..d * d]),
    );
    if let Some(mode) = update.mode {
        properties.insert("rtls:mode".into(), json!(mode));
    }
    Ok(Location {
        position: Point {
            coordinates: update.position_m[..d].to_vec(),
        },
        source: source.into(),
        provider_type,
        provider_id: update.tag.to_string(),
        timestamp_generated: Some(format_timestamp(update.time_s, "timestamp_generated")?),
        timestamp_sent: None,
        crs: Some("local".into()),
        associated: None,
        accuracy: Some(accuracy_m(&update.position_covariance_m2, d)),
        floor: None,
        true_heading: None,
        magnetic_heading: None,
        heading_accuracy: None,
        elevation_ref: None,
        speed: Some(vx.hypot(vy)),
        course: course_deg(vx, vy),
        trackables: None,
        properties: Some(properties),
    })
}

fn kind_name(kind: ZoneKind) -> &'static str {
    match kind {
        ZoneKind::Hazard => "hazard",
        ZoneKind::Restricted => "restricted",
        ZoneKind::AreaOfInterest => "area-of-interest",
    }
}

/// The omlox fence id of the zone `zone_id`: the zone id itself when it is a UUID (a zone
/// created through the API is named by its fence's UUID), else a name-based UUID of it. Fences
/// and their events name a zone alike.
#[must_use]
pub fn fence_id(zone_id: &str) -> String {
    if Uuid::parse_str(zone_id).is_ok() {
        zone_id.to_string()
    } else {
        uuid_for("fence", zone_id)
    }
}

/// A site zone as an omlox Fence in local coordinates: a polygon becomes a closed GeoJSON
/// Polygon ring, a box its x–y rectangle; the height range becomes `extrusion` (and
/// `rtls:z_range_m`), the kind `rtls:kind`, the floor id `rtls:floor`.
#[must_use]
pub fn fence_from_zone(zone: &SiteZone) -> Fence {
    let mut properties = Properties::new();
    properties.insert("rtls:kind".into(), json!(kind_name(zone.kind)));
    let (ring, z_range) = match &zone.shape {
        Shape::Polygon {
            vertices_m,
            floor,
            z_range_m,
        } => {
            if let Some(floor) = floor {
                properties.insert("rtls:floor".into(), json!(floor));
            }
            let ring: Vec<Vec<f64>> = vertices_m.iter().map(|v| v.to_vec()).collect();
            (ring, *z_range_m)
        }
        Shape::Box { min_m, max_m } => (
            vec![
                vec![min_m[0], min_m[1]],
                vec![max_m[0], min_m[1]],
                vec![max_m[0], max_m[1]],
                vec![min_m[0], max_m[1]],
            ],
            Some([min_m[2], max_m[2]]),
        ),
    };
    let mut closed = ring;
    if let Some(first) = closed.first().cloned() {
        closed.push(first);
    }
    if let Some(range) = z_range {
        properties.insert("rtls:z_range_m".into(), json!(range));
    }
    Fence {
        id: fence_id(&zone.id),
        region: Region::Polygon {
            coordinates: vec![closed],
        },
        radius: None,
        extrusion: z_range.map(|[lo, hi]| hi - lo),
        floor: None,
        foreign_id: Some(zone.id.clone()),
        name: Some(zone.name.clone()),
        timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        crs: Some("local".into()),
        zone_id: None,
        elevation_ref: None,
        properties: Some(properties),
    }
}

/// A zone event in omlox terms: enter / exit are fence events; dwell has no omlox counterpart
/// and goes to the `rtls:events` extension topic.
#[derive(Debug, Clone, PartialEq)]
pub enum ZoneEventOut {
    /// `region_entry` / `region_exit` on `fence_events`.
    Fence(FenceEvent),
    /// Anything else: the topic and its payload.
    Extension(Topic, Value),
}

/// Converts a zone event. The fence id is [`fence_id`]`(zone)`, the provider the tag (the
/// partition adds the `trackables` the tag is assigned to);
/// the event id is derived from tag, zone, kind and time. An exit carries `entry_time` when
/// `entry_time_s` (the matching entry's time, s) is known.
///
/// # Errors
/// [`ServerError::Unrepresentable`] when a time cannot be written as a timestamp.
pub fn fence_event_from_zone_event(event: &ZoneEvent, entry_time_s: Option<f64>) -> Result<ZoneEventOut> {
    let (event_type, tag, zone, time_s) = match event {
        ZoneEvent::Enter { tag, zone, time_s } => (FenceEventType::RegionEntry, tag, zone, *time_s),
        ZoneEvent::Exit { tag, zone, time_s } => (FenceEventType::RegionExit, tag, zone, *time_s),
        ZoneEvent::Dwell { .. } => {
            return extension_message(&Event::Zone(event.clone()))
                .map(|(topic, payload)| ZoneEventOut::Extension(topic, payload))
        }
    };
    let (entry, exit) = match event_type {
        FenceEventType::RegionEntry => (Some(format_timestamp(time_s, "entry_time")?), None),
        FenceEventType::RegionExit => (
            entry_time_s.map(|t| format_timestamp(t, "entry_time")).transpose()?,
            Some(format_timestamp(time_s, "exit_time")?),
        ),
    };
    Ok(ZoneEventOut::Fence(FenceEvent {
        id: uuid_for("fence-event", &format!("{tag}\0{zone}\0{event_type:?}\0{time_s}")),
        fence_id: fence_id(zone),
        event_type,
        provider_id: Some(tag.clone()),
        trackable_id: None,
        trackables: None,
        foreign_id: Some(zone.clone()),
        entry_time: entry,
        exit_time: exit,
        properties: None,
    }))
}

/// Whether an event raises an alarm (stored flagged as one, counted in `rtls_alarms_total`):
/// a predicted hazard, a tag in a zone without coverage, a lost tag.
#[must_use]
pub fn is_alarm(event: &Event) -> bool {
    match event {
        Event::HazardPredicted { .. } | Event::NoCoverage { .. } => true,
        Event::Lifecycle { event, .. } => *event == LifecycleEvent::Lost,
        _ => false,
    }
}

/// Whether an event goes to `rtls:alarms`: the alarms, what ends them (hazard cleared, a lost
/// tag recovered) and model switches.
fn on_alarm_topic(event: &Event) -> bool {
    is_alarm(event)
        || match event {
            Event::HazardCleared { .. } | Event::ModelSwitch { .. } => true,
            Event::Lifecycle { event, .. } => *event == LifecycleEvent::Recovered,
            _ => false,
        }
}

/// An engine event as an extension-topic payload: the event's JSON line (its `type`, `t`,
/// `tag`, …) plus `timestamp` (ISO 8601). The alarms of [`is_alarm`], `hazard-cleared`,
/// `model-switch` and lifecycle `recovered` go to `rtls:alarms`, everything else to
/// `rtls:events`.
///
/// # Errors
/// [`ServerError::Unrepresentable`] when the time cannot be written as a timestamp.
pub fn extension_message(event: &Event) -> Result<(Topic, Value)> {
    let value: Value = serde_json::from_str(&event.to_json_line()).map_err(|e| ServerError::Unrepresentable {
        field: "event".into(),
        reason: format!("engine event is not JSON ({e})"),
    })?;
    extension_payload(event, value)
}

/// As [`extension_message`], for a caller that already holds the event's JSON (`value`, from
/// [`Event::to_json_line`]).
///
/// # Errors
/// As [`extension_message`].
pub fn extension_payload(event: &Event, mut value: Value) -> Result<(Topic, Value)> {
    let timestamp = format_timestamp(event.time_s(), "timestamp")?;
    if let Value::Object(object) = &mut value {
        object.insert("timestamp".into(), json!(timestamp));
    }
    let topic = if on_alarm_topic(event) {
        Topic::RtlsAlarms
    } else {
        Topic::RtlsEvents
    };
    Ok((topic, value))
}

/// A pushed Location in the site's local metres: as it is in `local` (or without `crs`); in
/// `EPSG:4326` its position `[longitude, latitude(, height)]` (degrees, m above the WGS-84
/// ellipsoid; the frame origin's height when absent) is taken to the site frame through the
/// site's `[frame]` georeference ([`FrameSettings::site_of_wgs84`]) and `crs` becomes `local`.
/// `accuracy` is a radius in metres in either CRS and stays as it is.
///
/// # Errors
/// [`ServerError::InvalidField`] (`crs`, with `index`) for another CRS, for `EPSG:4326` on a site
/// without a `[frame]`, and (`position`) for coordinates that are not a longitude and latitude.
pub fn location_in_site(location: &Location, index: usize, frame: Option<&FrameSettings>) -> Result<Location> {
    let err = |field: &str, reason: String| ServerError::InvalidField {
        index,
        field: field.into(),
        reason,
    };
    match Crs::parse(location.crs.as_deref()).map_err(|reason| err("crs", reason))? {
        Crs::Local => Ok(location.clone()),
        Crs::Wgs84 => {
            let frame = frame.ok_or_else(|| {
                err(
                    "crs",
                    "the site has no [frame] origin to place EPSG:4326 coordinates: send site coordinates with crs \"local\""
                        .into(),
                )
            })?;
            let coordinates = &location.position.coordinates;
            let (lon, lat) = match coordinates.as_slice() {
                [lon, lat] | [lon, lat, _] if lon.abs() <= 180.0 && lat.abs() <= 90.0 => (*lon, *lat),
                _ => {
                    return Err(err(
                        "position",
                        format!("{coordinates:?} is not [longitude, latitude(, height)] in degrees"),
                    ))
                }
            };
            let height_m = coordinates.get(2).copied().unwrap_or(frame.origin.height_m);
            let site = frame
                .site_of_wgs84([lon, lat, height_m])
                .ok_or_else(|| err("position", format!("{coordinates:?} has no place in the site frame")))?;
            let mut local = location.clone();
            local.position.coordinates = site[..coordinates.len()].to_vec();
            local.crs = Some("local".into());
            Ok(local)
        }
    }
}

/// An ingested Location as an engine record: `Measurement::Fix` with the position and the
/// covariance `accuracy² I` (`default_accuracy_m` when the location has none), the tag
/// `provider_id`, the time `timestamp_generated` (else `timestamp_sent`, else `received_s`).
///
/// # Errors
/// [`ServerError::InvalidField`] (with `index`) for a non-local `crs` (take the location to the
/// site frame first: [`location_in_site`]) or a non-positive accuracy.
pub fn record_from_location(
    location: &Location,
    index: usize,
    default_accuracy_m: f64,
    received_s: f64,
) -> Result<Record> {
    let err = |field: &str, reason: String| ServerError::InvalidField {
        index,
        field: field.into(),
        reason,
    };
    if let Some(crs) = location.crs.as_deref().filter(|c| *c != "local") {
        return Err(err(
            "crs",
            format!("`{crs}`: the location is to be taken to the site frame first"),
        ));
    }
    // none, or 0 (an exact position, or none stated: the vendor adapters read 0 so too), is the
    // server's default; the filter needs a variance > 0 to weigh a fix
    let accuracy = location.accuracy.filter(|a| *a != 0.0).unwrap_or(default_accuracy_m);
    if !(accuracy.is_finite() && accuracy > 0.0) {
        return Err(err(
            "accuracy",
            format!("must be > 0 m to weigh the fix, got {accuracy}"),
        ));
    }
    let time_s = match (&location.timestamp_generated, &location.timestamp_sent) {
        (Some(t), _) => parse_timestamp(t, "timestamp_generated"),
        (None, Some(t)) => parse_timestamp(t, "timestamp_sent"),
        (None, None) => Ok(received_s),
    }
    .map_err(|e| match e {
        ServerError::Unrepresentable { field, reason } => err(&field, reason),
        other => other,
    })?;
    let d = location.position.coordinates.len();
    let mut covariance_m2 = vec![0.0; d * d];
    for i in 0..d {
        covariance_m2[i * d + i] = accuracy * accuracy;
    }
    Ok(Record {
        time_s,
        tag: location.provider_id.clone(),
        measurement: Measurement::Fix {
            position_m: location.position.coordinates.clone(),
            covariance_m2,
        },
    })
}
