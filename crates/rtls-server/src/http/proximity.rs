//! omlox proximities: a provider heard by a proximity system (an RFID reader, an iBeacon)
//! becomes a location at that system's zone and goes through the same ingest path as
//! `PUT /v2/providers/locations` (stored in the ingest log, tracked as a fix).
//!
//! The proximity's `source` names an omlox zone by id or `foreign_id`; the location is placed
//! at the zone's `position` (EPSG:4326, placed in the site frame through the site's
//! georeference, `[x, y]` only) on the zone's `floor`. Its `accuracy` (horizontal 1-σ radius,
//! m) is the proximity's `accuracy` — the estimated distance to the emitter — when it is
//! above 0, else the zone's `radius`, else the server's default accuracy. `source`,
//! `provider_type`, `provider_id`, timestamps and `properties` are the proximity's.
//!
//! Once the locations are durable, the proximities themselves, as received, go to the
//! WebSocket's `proximity_updates` subscribers.

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};

use std::sync::Arc;

use super::hub::ingest_locations;
use super::zones::{all_zones, position_m, zone_by_source};
use super::{parse_json, same_as_path, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::omlox::{Location, Point, ProviderType, Proximity, Zone};
use crate::pipeline::HubMessage;

/// `PUT /v2/providers/proximities`: an array of `Proximity`; 204 when durable.
///
/// # Errors
/// 400 naming the field (`[i].source`, …) of a bad proximity: an unknown zone, a zone without
/// a position or a site without a georeference, a provider type other than `rfid`, `ibeacon`,
/// `virtual`, `unknown`, a negative accuracy, a bad timestamp.
pub(super) async fn put_proximities(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    state.authorize(&headers, Access::Write)?;
    let proximities: Vec<Proximity> = parse_json(&body)?;
    // the zones are read once for the whole batch
    let zones = all_zones(&state).await?;
    let locations = proximities
        .iter()
        .enumerate()
        .map(|(index, proximity)| location_of(&state, &zones, proximity, &format!("[{index}].")))
        .collect::<ApiResult<Vec<_>>>()?;
    let status = ingest_locations(&state, &locations).await?;
    publish(&state, proximities);
    Ok(status)
}

/// Sends accepted proximities to the `proximity_updates` subscribers.
fn publish(state: &AppState, proximities: Vec<Proximity>) {
    for proximity in proximities {
        state.pipeline.broadcast(HubMessage::Proximity(Arc::new(proximity)));
    }
}

/// `PUT /v2/providers/{provider_id}/proximity`: one `Proximity`, whose `provider_id` must
/// match the path; 204 when durable.
///
/// # Errors
/// As [`put_proximities`], fields named without an index.
pub(super) async fn put_proximity(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    state.authorize(&headers, Access::Write)?;
    let proximity: Proximity = parse_json(&body)?;
    same_as_path("provider_id", &proximity.provider_id, &provider_id)?;
    let zones = all_zones(&state).await?;
    let location = location_of(&state, &zones, &proximity, "")?;
    let status = ingest_locations(&state, &[location]).await.map_err(|mut e| {
        // a single location's fields are not indexed
        e.field = e.field.map(|f| f.trim_start_matches("[0].").to_string());
        e
    })?;
    publish(&state, vec![proximity]);
    Ok(status)
}

/// The location a proximity means (see the module documentation), its zone one of `zones`;
/// `prefix` goes before the field names of errors.
fn location_of(state: &AppState, zones: &[Zone], proximity: &Proximity, prefix: &str) -> ApiResult<Location> {
    let field = |name: &str, message: String| ApiError::field(format!("{prefix}{name}"), message);
    if !matches!(
        proximity.provider_type,
        ProviderType::Rfid | ProviderType::Ibeacon | ProviderType::Virtual | ProviderType::Unknown
    ) {
        return Err(field(
            "provider_type",
            format!(
                "`{}`: a proximity's provider is rfid, ibeacon, virtual or unknown",
                proximity.provider_type.name()
            ),
        ));
    }
    if proximity.provider_id.trim().is_empty() {
        return Err(field("provider_id", "must not be empty".into()));
    }
    if let Some(accuracy) = proximity.accuracy {
        if !(accuracy.is_finite() && accuracy >= 0.0) {
            return Err(field("accuracy", format!("a distance ≥ 0 m, got {accuracy}")));
        }
    }
    let zone = zone_by_source(zones, &proximity.source).ok_or_else(|| {
        field(
            "source",
            format!("no zone has the id or foreign_id `{}`", proximity.source),
        )
    })?;
    let [x, y] = position_m(state, zone).map_err(|e| field("source", e.message))?;
    let accuracy = proximity
        .accuracy
        .filter(|a| *a > 0.0)
        .or(zone.radius)
        .unwrap_or(state.default_accuracy_m);
    Ok(Location {
        position: Point {
            coordinates: vec![x, y],
        },
        source: proximity.source.clone(),
        provider_type: proximity.provider_type,
        provider_id: proximity.provider_id.clone(),
        timestamp_generated: proximity.timestamp_generated.clone(),
        timestamp_sent: proximity.timestamp_sent.clone(),
        crs: Some("local".into()),
        associated: None,
        accuracy: Some(accuracy),
        floor: zone.floor,
        true_heading: None,
        magnetic_heading: None,
        heading_accuracy: None,
        elevation_ref: None,
        speed: None,
        course: None,
        trackables: None,
        properties: proximity.properties.clone(),
    })
}
