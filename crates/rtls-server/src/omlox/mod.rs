//! Serde types for the omlox™ hub API 2.0.0 objects, named and shaped as in the OpenAPI
//! components (`#/components/schemas/…`): required fields are plain, optional ones are
//! `Option` and left out when `None`.
//!
//! - [`Location`], and [`Point`], [`Polygon`], [`Region`] — positions and geometries (GeoJSON, in
//!   `geometry.rs`).
//! - [`Trackable`], [`LocationProvider`], [`Zone`], [`Fence`], [`FenceEvent`],
//!   [`TrackableMotion`], [`Proximity`], [`SimpleTransform`], [`CollisionEvent`] and its
//!   [`Collision`]s.
//! - [`ws`] — WebSocket messages, topics and error codes.
//! - [`geojson`] — locations, motions and fences as GeoJSON Features (`?geojson=true`).
//! - [`collision`] — collisions between trackables judged from their tracks' uncertainty.
//! - [`crs`] — the `crs` values the hub takes: `local` and `EPSG:4326`.
//! - [`time`] — ISO 8601 UTC timestamps ↔ seconds since the Unix epoch.
//! - [`ingest`] — field-level validation of the `PUT /v2/providers/locations` body.
//! - [`locating_rules`] — a trackable's `locating_rules`: their expression language and which
//!   of its providers' locations they select.

pub mod collision;
pub mod crs;
pub mod geojson;
mod geometry;
pub mod ingest;
pub mod locating_rules;
pub mod time;
pub mod ws;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

pub use geometry::{Point, Polygon, Region};

/// Free-form application properties (`properties` in every omlox object): the spec requires
/// them to be preserved, not interpreted. Our own keys start with `rtls:`.
pub type Properties = Map<String, Value>;

/// The technology behind a location (`provider_type` of a Location, `type` of a
/// LocationProvider).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProviderType {
    /// Ultra-wideband.
    Uwb,
    /// Satellite positioning.
    Gps,
    /// Wi-Fi.
    Wifi,
    /// RFID.
    Rfid,
    /// iBeacon / BLE.
    Ibeacon,
    /// A virtual provider (e.g. an application-made id, or a fused track).
    Virtual,
    /// Unknown.
    Unknown,
}

impl ProviderType {
    /// All values, in the order of the spec's enum.
    pub const ALL: [Self; 7] = [
        Self::Uwb,
        Self::Gps,
        Self::Wifi,
        Self::Rfid,
        Self::Ibeacon,
        Self::Virtual,
        Self::Unknown,
    ];

    /// The name in JSON (`"uwb"`, …).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Uwb => "uwb",
            Self::Gps => "gps",
            Self::Wifi => "wifi",
            Self::Rfid => "rfid",
            Self::Ibeacon => "ibeacon",
            Self::Virtual => "virtual",
            Self::Unknown => "unknown",
        }
    }
}

/// A location update (`#/components/schemas/Location`).
///
/// # Units
/// Coordinates in the `crs` (absent = `local`, metres), `accuracy` m (horizontal), `speed` m/s,
/// `course` degrees clockwise from north, timestamps ISO 8601 UTC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Location {
    /// The position.
    pub position: Point,
    /// The RTLS (zone id or foreign id) that produced the location, or a self-localising
    /// device's id.
    pub source: String,
    /// The provider technology.
    pub provider_type: ProviderType,
    /// The location provider's id (e.g. a tag's MAC address).
    pub provider_id: String,
    /// When the location was computed (ISO 8601 UTC).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub timestamp_generated: Option<String>,
    /// When the location was sent (ISO 8601 UTC).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub timestamp_sent: Option<String>,
    /// `local` or an EPSG id such as `EPSG:4326`; absent means `local`.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
    /// Whether a Wi-Fi client is associated.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub associated: Option<bool>,
    /// Horizontal accuracy, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<f64>,
    /// Logical floor (0 = ground; fractional for mezzanines).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub floor: Option<f64>,
    /// True heading, degrees (negative = unavailable).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub true_heading: Option<f64>,
    /// Magnetic heading, degrees (negative = unavailable).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub magnetic_heading: Option<f64>,
    /// Heading accuracy, degrees.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub heading_accuracy: Option<f64>,
    /// `floor` (default) or `wgs84`: what the z coordinate is relative to.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub elevation_ref: Option<String>,
    /// Speed, m/s.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// Course, degrees clockwise from north (0 = north, 90 = east).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub course: Option<f64>,
    /// Ids of the trackables the provider is assigned to.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub trackables: Option<Vec<String>>,
    /// Application properties.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

/// Whether a trackable knows its providers (`omlox`) or is a logical asset (`virtual`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TrackableType {
    /// Self-assigns its location providers.
    Omlox,
    /// A logical asset to which providers are assigned.
    Virtual,
}

/// A tracked object (`#/components/schemas/Trackable`). Fields the schema does not name are
/// ignored, as the spec allows; `locating_rules` is kept as given, and evaluated
/// ([`locating_rules`]): its expressions must parse when the trackable is written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trackable {
    /// UUID.
    pub id: String,
    /// Kind of trackable.
    #[serde(rename = "type")]
    pub kind: TrackableType,
    /// Name.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Outline (local to the trackable).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub geometry: Option<Polygon>,
    /// Extrusion of the geometry, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub extrusion: Option<f64>,
    /// Assigned location provider ids.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub location_providers: Option<Vec<String>>,
    /// Location expiry before a fence exit, ms (-1 = infinite).
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub fence_timeout: Option<f64>,
    /// Collision release distance, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub exit_tolerance: Option<f64>,
    /// Collision release timeout, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub tolerance_timeout: Option<f64>,
    /// Exit delay, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub exit_delay: Option<f64>,
    /// Radius around the trackable, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Application properties (an object; `null` is refused).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
    /// The rule set choosing among the providers' locations (`#/components/schemas/RuleSet`),
    /// kept and returned as given, evaluated as [`locating_rules`] says.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub locating_rules: Option<Vec<LocatingRule>>,
}

/// One rule of a trackable's rule set (`#/components/schemas/LocatingRule`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocatingRule {
    /// The conditions, e.g. `type = 'uwb' AND accuracy < 5`.
    pub expression: String,
    /// The higher, the more preferred.
    #[serde(serialize_with = "whole_as_integer")]
    pub priority: f64,
}

/// A number written as an integer when it is one (`5000`, not `5000.0`): the timeouts (ms) and
/// priorities omlox clients read as integers (the Go client's decoder refuses `5000.0`).
fn whole_as_integer<S: serde::Serializer>(value: &f64, serializer: S) -> std::result::Result<S::Ok, S::Error> {
    // |v| < 2⁵³: every such whole f64 is exactly an i64
    if value.fract() == 0.0 && value.abs() < 9_007_199_254_740_992.0 {
        serializer.serialize_i64(*value as i64)
    } else {
        serializer.serialize_f64(*value)
    }
}

/// [`whole_as_integer`] of an optional number (skipped when absent by the field's attribute).
fn integral_if_whole<S: serde::Serializer>(value: &Option<f64>, serializer: S) -> std::result::Result<S::Ok, S::Error> {
    match value {
        Some(value) => whole_as_integer(value, serializer),
        None => serializer.serialize_none(),
    }
}

/// An optional field that, when present, must not be `null`: the schema types it (a number,
/// an object, a rule set) and does not make it nullable.
fn not_null<'de, D, T>(deserializer: D) -> std::result::Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    match Option::<T>::deserialize(deserializer)? {
        Some(value) => Ok(Some(value)),
        None => Err(serde::de::Error::custom("must not be null")),
    }
}

/// A location provider (`#/components/schemas/LocationProvider`): a tag, a phone, a GPS unit.
/// Fields the schema does not name are ignored, as the spec allows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocationProvider {
    /// Provider id (EUI-64 upper-case hex where applicable).
    pub id: String,
    /// Technology.
    #[serde(rename = "type")]
    pub kind: ProviderType,
    /// Name.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Application-defined sensor data.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub sensors: Option<Value>,
    /// Location expiry before a fence exit, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub fence_timeout: Option<f64>,
    /// Release distance, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub exit_tolerance: Option<f64>,
    /// Release timeout, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub tolerance_timeout: Option<f64>,
    /// Exit delay, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub exit_delay: Option<f64>,
    /// Application properties (an object; `null` is refused).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

/// The positioning technology of an omlox [`Zone`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ZoneType {
    /// Ultra-wideband.
    Uwb,
    /// Wi-Fi.
    Wifi,
    /// RFID.
    Rfid,
    /// iBeacon.
    Ibeacon,
}

/// An omlox zone (`#/components/schemas/Zone`): the area and local frame of one positioning
/// system — not a geofence (that is a [`Fence`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Zone {
    /// UUID.
    pub id: String,
    /// Positioning technology.
    #[serde(rename = "type")]
    pub kind: ZoneType,
    /// Foreign id (e.g. our site name).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub foreign_id: Option<String>,
    /// Position in EPSG:4326.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub position: Option<Point>,
    /// Proximity radius, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Pairs of `[longitude, latitude]`, `[x, y]` mapping the local frame to WGS84.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub ground_control_points: Option<Vec<Vec<f64>>>,
    /// `true` while the configuration (e.g. ground control points) is incomplete.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub incomplete_configuration: Option<bool>,
    /// When the geographic coordinates were measured (ISO 8601).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub measurement_timestamp: Option<String>,
    /// Site.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub site: Option<String>,
    /// Building.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub building: Option<String>,
    /// Floor (0 = ground).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub floor: Option<f64>,
    /// Name.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// What the zone is for.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Address.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub address: Option<String>,
    /// Application properties.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
    /// WGS84 height, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub wgs84_height: Option<f64>,
}

/// A geofence (`#/components/schemas/Fence`). Without `crs` the spec assumes EPSG:4326, so
/// fences in site coordinates must carry `crs: "local"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fence {
    /// UUID.
    pub id: String,
    /// The region.
    pub region: Region,
    /// Radius around a Point region, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Extrusion (height) of the region, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub extrusion: Option<f64>,
    /// Floor (0 = ground).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub floor: Option<f64>,
    /// Foreign id (our zone id).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub foreign_id: Option<String>,
    /// Name.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Location expiry, ms (-1 = infinite).
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub timeout: Option<f64>,
    /// Exit distance tolerance, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub exit_tolerance: Option<f64>,
    /// Tolerance timeout, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub tolerance_timeout: Option<f64>,
    /// Exit delay, ms.
    #[serde(
        default,
        deserialize_with = "not_null",
        serialize_with = "integral_if_whole",
        skip_serializing_if = "Option::is_none"
    )]
    pub exit_delay: Option<f64>,
    /// `local` or an EPSG id; absent means EPSG:4326.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
    /// The omlox zone whose local frame a `local` fence uses.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub zone_id: Option<String>,
    /// `floor` or `wgs84`.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub elevation_ref: Option<String>,
    /// Application properties.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

/// The two fence event kinds of the spec (predictive alarms go to the `rtls:alarms` topic).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FenceEventType {
    /// The provider or trackable entered the fence.
    RegionEntry,
    /// It left the fence.
    RegionExit,
}

/// A fence entry or exit (`#/components/schemas/FenceEvent`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FenceEvent {
    /// UUID of this event.
    pub id: String,
    /// UUID of the fence.
    pub fence_id: String,
    /// Entry or exit.
    pub event_type: FenceEventType,
    /// The provider that triggered it (absent when a trackable did).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provider_id: Option<String>,
    /// The trackable that triggered it (absent when a provider did).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trackable_id: Option<String>,
    /// Trackables the provider is assigned to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trackables: Option<Vec<String>>,
    /// Foreign id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub foreign_id: Option<String>,
    /// When the location was first inside the fence (ISO 8601 UTC).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub entry_time: Option<String>,
    /// When the exit was triggered (ISO 8601 UTC).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exit_time: Option<String>,
    /// Properties copied from the fence.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

/// A trackable's position and shape (`#/components/schemas/TrackableMotion`): its newest
/// location (with our track's `speed`, m/s, and `course`, degrees clockwise from north) and
/// its geometry, name and properties copied from the [`Trackable`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackableMotion {
    /// The trackable's UUID.
    pub id: String,
    /// The trackable's newest location.
    pub location: Location,
    /// The trackable's name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Extrusion of the geometry, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extrusion: Option<f64>,
    /// The trackable's outline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<Polygon>,
    /// The trackable's properties.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

impl TrackableMotion {
    /// The motion of `trackable` at `location` (one of its providers' locations): the
    /// trackable's id, name, extrusion, geometry and properties with that location — what
    /// `GET /v2/trackables/motions` answers and the `trackable_motions` topic sends.
    #[must_use]
    pub fn of(trackable: &Trackable, location: Location) -> Self {
        Self {
            id: trackable.id.clone(),
            location,
            name: trackable.name.clone(),
            extrusion: trackable.extrusion,
            geometry: trackable.geometry.clone(),
            properties: trackable.properties.clone(),
        }
    }
}

/// What a [`CollisionEvent`] says about a pair of trackables (`collision_type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CollisionType {
    /// The two started colliding (sent once per collision).
    CollisionStart,
    /// They still collide after a position update of one of them.
    Colliding,
    /// They separated (sent once per collision).
    CollisionEnd,
}

/// What collides (`#/components/schemas/Collision`): one of the two objects of a
/// [`CollisionEvent`].
///
/// # Units
/// `position` in the site frame (`crs: local`), m; `geometry` likewise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Collision {
    /// The trackable's id.
    pub id: String,
    /// Always `trackable`.
    pub object_type: String,
    /// The position the collision was judged at (the trackable's newest location).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<Point>,
    /// The region judged to collide: a polygon about `position` (see [`collision`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<Polygon>,
    /// Logical floor (absent = 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor: Option<f64>,
}

/// A collision between two trackables started, goes on, or ended
/// (`#/components/schemas/CollisionEvent`).
///
/// # Units
/// Timestamps ISO 8601 UTC with milliseconds; `center_distance` m; `collision_area` in the
/// site frame, m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionEvent {
    /// UUID of this event.
    pub id: String,
    /// Start, continuing, or end.
    pub collision_type: CollisionType,
    /// When the two first collided.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_time: Option<String>,
    /// When they were released (on `collision_end`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_time: Option<String>,
    /// When this continuing event was triggered (on `colliding`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collision_time: Option<String>,
    /// The two objects, the one whose update triggered the event first.
    pub collisions: Vec<Collision>,
    /// Where the two regions overlap (the middle of the overlap on the line between the
    /// centres); absent on `collision_end`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collision_area: Option<Point>,
    /// Centre-to-centre distance, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center_distance: Option<f64>,
}

/// A provider seen by a proximity system (`#/components/schemas/Proximity`): an RFID reader
/// or iBeacon, named by `source` (an omlox zone's id or foreign id), heard the provider.
///
/// # Units
/// `accuracy` m (the estimated distance to the emitter), timestamps ISO 8601 UTC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Proximity {
    /// The proximity system's zone id or foreign id.
    pub source: String,
    /// `rfid`, `ibeacon`, `virtual` or `unknown`.
    pub provider_type: ProviderType,
    /// The provider's id (e.g. an RFID tag's UID).
    pub provider_id: String,
    /// When the proximity was detected (ISO 8601 UTC).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub timestamp_generated: Option<String>,
    /// When it was sent (ISO 8601 UTC).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub timestamp_sent: Option<String>,
    /// Estimated distance to the emitter, m.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<f64>,
    /// Application properties.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub properties: Option<Properties>,
}

/// A position to transform with a zone (`#/components/schemas/SimpleTransform`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimpleTransform {
    /// The position: `[x, y(, z)]` m (`local`) or `[longitude, latitude(, height)]` (`EPSG:4326`).
    pub position: Point,
    /// The zone used for the transformation (set in the answer).
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// `local` (the default) or `EPSG:4326`.
    #[serde(default, deserialize_with = "not_null", skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
}
