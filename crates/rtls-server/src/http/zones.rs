//! omlox zones: the positioning systems and their frames (not geofences: those are fences).
//!
//! The site itself is one zone, derived from the site file (id [`uuid_for`]`("zone", name)`,
//! `foreign_id` the site's name): it is read-only here — replacing or deleting it answers 400.
//! Other zones are created, replaced and deleted through the API and stored in the database
//! (configuration kind `zone`), like providers and trackables. A zone is validated as the
//! spec says: a proximity zone (`rfid`, `ibeacon`) has a `position` (EPSG:4326) and no
//! `ground_control_points`; any other zone has at least three ground control points — unless
//! `incomplete_configuration` is `true`.
//!
//! Zones do not change what the trackers watch: `GET /v2/zones/{id}/createfence` turns a
//! zone's geometry into a fence, which from then on is a fence like any other (applied live to
//! the trackers, edited and deleted through `/v2/fences`). Proximities (`proximity.rs`) place a
//! provider at its proximity zone's position at the time they arrive.

use axum::body::Bytes;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::Response;
use axum::Json;
use serde_json::Value;

use super::hub::{create, delete, delete_all, replace, IdInUse};
use super::stored::{get_stored, list_stored};
use super::zone_frame::{fence_ring_m, ZoneFrame};
use super::zone_store::{is_proximity, site_zone, zone, ZONE};
use super::{parse_json, query_value, same_as_path, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::convert::uuid_for;
use crate::omlox::crs::Crs;
use crate::omlox::time::parse_timestamp;
use crate::omlox::{Fence, Point, Region, SimpleTransform, Zone};

/// Every zone: the site's first, then the stored ones by id.
pub(super) async fn all_zones(state: &AppState) -> ApiResult<Vec<Zone>> {
    let mut zones = vec![site_zone(state)];
    let mut stored: Vec<Zone> = list_stored(state, ZONE).await?;
    stored.sort_by(|a, b| a.id.cmp(&b.id));
    zones.extend(stored);
    Ok(zones)
}

/// The zone of `zones` whose id (any letter case) or `foreign_id` is `source` (a proximity's
/// source).
pub(super) fn zone_by_source<'a>(zones: &'a [Zone], source: &str) -> Option<&'a Zone> {
    zones
        .iter()
        .find(|z| z.id.eq_ignore_ascii_case(source) || z.foreign_id.as_deref() == Some(source))
}

/// A 400 naming `zone_id` for a change to the site's own zone.
fn site_zone_is_read_only(zone_id: &str) -> ApiError {
    ApiError::field(
        "zone_id",
        format!("zone `{zone_id}` is the site's own (from the site file) and cannot be changed here"),
    )
}

/// `GET /v2/zones`: ids, optionally only those with `foreign_id`.
pub(super) async fn list(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<String>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(filtered(&state, query).await?.into_iter().map(|z| z.id).collect()))
}

/// `GET /v2/zones/summary`: zones, optionally only those with `foreign_id`.
pub(super) async fn summary(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Zone>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(filtered(&state, query).await?))
}

async fn filtered(state: &AppState, query: Option<String>) -> ApiResult<Vec<Zone>> {
    let foreign_id = query_value(query.as_deref(), "foreign_id");
    let mut zones = all_zones(state).await?;
    if let Some(foreign_id) = foreign_id {
        zones.retain(|z| z.foreign_id.as_deref() == Some(foreign_id.as_str()));
    }
    Ok(zones)
}

/// `GET /v2/zones/{zone_id}`: 404 when unknown.
pub(super) async fn get(
    State(state): State<AppState>,
    Path(zone_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Zone>> {
    state.authorize(&headers, Access::Read)?;
    zone(&state, &zone_id).await.map(Json)
}

/// `POST /v2/zones`: 201 with the stored zone. A UUID is assigned when `id` is absent, the
/// nil UUID (as for trackables and fences) or in use (omlox: "The provided id will be replaced
/// by a generated uuid" — here only then); 400 naming the field of an invalid zone.
pub(super) async fn create_zone(State(state): State<AppState>, headers: HeaderMap, body: Bytes) -> ApiResult<Response> {
    let who = state.authorize(&headers, Access::Write)?;
    let mut value: Value = parse_json(&body)?;
    super::assign_id_if_unset(&mut value);
    let zone: Zone = parse_json(value.to_string().as_bytes())?;
    validate(&zone)?;
    let mut zone = zone;
    if zone.id.eq_ignore_ascii_case(&site_zone(&state).id) {
        // the site's own zone has this id: a new one, as for any id in use
        zone.id = uuid::Uuid::new_v4().to_string();
    }
    create(&state, &who, ZONE, zone.id.clone(), &zone, IdInUse::Generate).await
}

/// `PUT /v2/zones/{zone_id}`: replaces a stored zone (a body without `id` takes the path's);
/// 204; 404 when unknown, 400 for the site's own zone or an invalid zone.
pub(super) async fn replace_zone(
    State(state): State<AppState>,
    Path(zone_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let mut value: Value = parse_json(&body)?;
    if let Value::Object(object) = &mut value {
        object.entry("id").or_insert_with(|| Value::String(zone_id.clone()));
    }
    let zone: Zone = parse_json(value.to_string().as_bytes())?;
    same_as_path("id", &zone.id, &zone_id)?;
    if zone_id == site_zone(&state).id {
        return Err(site_zone_is_read_only(&zone_id));
    }
    if get_stored::<Zone>(&state, ZONE, &zone_id).await?.is_none() {
        return Err(ApiError::not_found(format!("zone `{zone_id}` not found")));
    }
    validate(&zone)?;
    replace(&state, &who, ZONE, zone_id, &zone).await
}

/// `DELETE /v2/zones/{zone_id}`: 204; 404 when unknown, 400 for the site's own zone. Fences
/// made from it stay.
pub(super) async fn delete_zone(
    State(state): State<AppState>,
    Path(zone_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    if zone_id == site_zone(&state).id {
        return Err(site_zone_is_read_only(&zone_id));
    }
    delete(&state, &who, ZONE, zone_id).await
}

/// `DELETE /v2/zones`: deletes every stored zone (the site's own stays: it is the site file's);
/// 204.
pub(super) async fn delete_all_zones(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    delete_all(&state, &who, ZONE).await
}

/// `GET /v2/zones/{zone_id}/createfence`: makes a fence of the zone's area and watches it like
/// any fence (stored, applied live to the trackers); 200 with the fence, in the fence reads'
/// default frame (EPSG:4326 where the site has a `[frame]`).
///
/// The fence's id is derived from the zone's ([`uuid_for`]`("zone-fence", zone id)`), so
/// calling it again replaces that fence with the zone's current geometry instead of adding
/// one. A proximity zone gives a circle of its `radius` about its `position`; another zone the
/// polygon of its ground control points (their WGS-84 corners in the site frame when the site
/// is georeferenced, else their `[x, y]`, taken as site metres). Since it changes the fences it
/// needs the access `POST /v2/fences` needs (operate), though it is a GET.
///
/// # Errors
/// 404 for an unknown zone; 400 when the zone has no area (no ground control points, or a
/// proximity zone without position or radius, or a position the site cannot place).
pub(super) async fn create_fence(
    State(state): State<AppState>,
    Path(zone_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Fence>> {
    let who = state.authorize(&headers, Access::Operate)?;
    let zone = zone(&state, &zone_id).await?;
    let (region, radius) = if is_proximity(zone.kind) {
        let centre = position_m(&state, &zone)?;
        let radius = zone
            .radius
            .ok_or_else(|| ApiError::field("radius", format!("zone `{zone_id}` has no radius to make a fence")))?;
        (
            Region::Point {
                coordinates: centre.to_vec(),
            },
            Some(radius),
        )
    } else {
        let ring = fence_ring_m(&zone, state.site.frame.as_ref())?;
        (
            Region::Polygon {
                coordinates: vec![ring],
            },
            None,
        )
    };
    let fence = Fence {
        id: uuid_for("zone-fence", &zone.id),
        region,
        radius,
        extrusion: None,
        floor: None,
        foreign_id: None,
        name: Some(zone.name.clone().unwrap_or_else(|| format!("zone {}", zone.id))),
        timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        // the ring is in site metres (`local` without a zone_id), as `upsert` takes it
        crs: Some("local".into()),
        zone_id: None,
        elevation_ref: None,
        properties: None,
    };
    super::fences::upsert(&state, &who, fence).await.map(Json)
}

/// `PUT /v2/zones/{zone_id}/transform`: a position in the zone's local frame (`crs` absent or
/// `local`, m) as EPSG:4326 `[longitude, latitude(, height)]`, or back; 200 with the result
/// (`source` the zone's id, `crs` the other one). Changes nothing, so the read access is enough.
///
/// The site's own zone uses the site's georeference (`[frame]`). A stored zone uses its ground
/// control points: a least-squares affine map between its `[x, y]` and east/north metres
/// about their mean longitude and latitude (exact for three points; a third coordinate is
/// passed through unchanged).
///
/// # Errors
/// 404 for an unknown zone; 400 for a bad body, a `crs` other than `local` / `EPSG:4326`, or a
/// zone that has no frame (no ground control points, or an ungeoreferenced site).
pub(super) async fn transform(
    State(state): State<AppState>,
    Path(zone_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<SimpleTransform>> {
    state.authorize(&headers, Access::Read)?;
    let request: SimpleTransform = parse_json(&body)?;
    let zone = zone(&state, &zone_id).await?;
    // the transform goes from the position's CRS to the other one
    let to_wgs84 = Crs::parse(request.crs.as_deref()).map_err(|reason| ApiError::field("crs", reason))? == Crs::Local;
    let coordinates = &request.position.coordinates;
    if !(2..=3).contains(&coordinates.len()) || coordinates.iter().any(|c| !c.is_finite()) {
        return Err(ApiError::field(
            "position.coordinates",
            "a position is 2 or 3 finite numbers",
        ));
    }
    let frame = if zone.id == site_zone(&state).id {
        ZoneFrame::of_site(state.site.frame.as_ref(), &zone.id)?
    } else {
        ZoneFrame::of_zone(&zone)?
    };
    let transformed = if to_wgs84 {
        frame.wgs84_of(coordinates)
    } else {
        frame.local_of(coordinates)
    }
    .ok_or_else(|| ApiError::field("position.coordinates", "the position cannot be transformed"))?;
    Ok(Json(SimpleTransform {
        position: Point {
            coordinates: transformed,
        },
        source: Some(zone.id),
        crs: Some(if to_wgs84 { "EPSG:4326" } else { "local" }.into()),
    }))
}

/// A zone's `position` in site metres `[x, y]`, through the site's georeference.
///
/// # Errors
/// 400 when the zone has no position or the site no `[frame]`.
pub(super) fn position_m(state: &AppState, zone: &Zone) -> ApiResult<[f64; 2]> {
    let position = zone
        .position
        .as_ref()
        .ok_or_else(|| ApiError::field("position", format!("zone `{}` has no position", zone.id)))?;
    let frame = state.site.frame.as_ref().ok_or_else(|| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            format!(
                "zone `{}`'s position is in EPSG:4326 and the site has no georeference ([frame]) to place it",
                zone.id
            ),
        )
    })?;
    let at = |k: usize| position.coordinates.get(k).copied();
    let [lon, lat] = [at(0), at(1)].map(|c| c.unwrap_or(f64::NAN));
    frame
        .site_of_wgs84([lon, lat, at(2).unwrap_or(frame.origin.height_m)])
        .map(|[x, y, _]| [x, y])
        .ok_or_else(|| ApiError::field("position", format!("zone `{}`'s position is not a place", zone.id)))
}

/// Checks a zone as the spec describes it (see the module documentation).
fn validate(zone: &Zone) -> ApiResult<()> {
    uuid::Uuid::parse_str(&zone.id).map_err(|e| ApiError::field("id", format!("`{}` is not a UUID ({e})", zone.id)))?;
    if let Some(position) = &zone.position {
        let c = &position.coordinates;
        let valid = (2..=3).contains(&c.len())
            && c.iter().all(|v| v.is_finite())
            && (-180.0..=180.0).contains(&c[0])
            && (-90.0..=90.0).contains(&c[1]);
        if !valid {
            return Err(ApiError::field(
                "position.coordinates",
                "[longitude, latitude(, height)] in degrees (EPSG:4326)",
            ));
        }
    }
    // omlox Zone.radius: "The radius MUST be ignored for non-proximity based position
    // providers" (kept as given, unchecked, on those)
    if let Some(radius) = zone.radius.filter(|_| is_proximity(zone.kind)) {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(ApiError::field("radius", "must be > 0 m"));
        }
    }
    if let Some(points) = &zone.ground_control_points {
        if is_proximity(zone.kind) {
            return Err(ApiError::field(
                "ground_control_points",
                "a proximity zone (rfid, ibeacon) must not have ground control points",
            ));
        }
        if points.len() % 2 != 0 {
            return Err(ApiError::field(
                "ground_control_points",
                "pairs of [longitude, latitude] and [x, y]: an even number of positions",
            ));
        }
        for (i, point) in points.iter().enumerate() {
            if point.len() != 2 || point.iter().any(|v| !v.is_finite()) {
                return Err(ApiError::field(
                    format!("ground_control_points[{i}]"),
                    "a position is two finite numbers",
                ));
            }
        }
    }
    if let Some(stamp) = &zone.measurement_timestamp {
        parse_timestamp(stamp, "measurement_timestamp")
            .map_err(|e| ApiError::field("measurement_timestamp", e.to_string()))?;
    }
    if zone.incomplete_configuration != Some(true) {
        if is_proximity(zone.kind) && zone.position.is_none() {
            return Err(ApiError::field(
                "position",
                "a proximity zone needs its position (or incomplete_configuration: true)",
            ));
        }
        if !is_proximity(zone.kind) && zone.ground_control_points.as_ref().is_none_or(|p| p.len() < 6) {
            return Err(ApiError::field(
                "ground_control_points",
                "a zone needs at least three ground control points (or incomplete_configuration: true)",
            ));
        }
    }
    Ok(())
}
