//! omlox fences: the zones the trackers watch, read and edited live (the dashboard's zone
//! editor). The site file's `[[zones]]` are the seed; an edit (create, replace, delete) stores
//! the whole zone set in the database (configuration `zones/current`), which a restart loads
//! instead of the site's, and hands it to the running trackers (head counts, zone events and
//! predictive hazard alarms follow within a clock tick; tags inside an unchanged zone stay
//! inside). Deleting `zones/current` (`DELETE /api/v1/zones/edits`) returns to the site file.
//!
//! A fence is written in `EPSG:4326` (longitude, latitude in degrees; omlox's default, so also
//! a fence without `crs`) on a site with a `[frame]`, whose georeference takes it to site
//! metres, or in a zone's local frame (`crs: "local"` with the zone's `zone_id`: a stored
//! zone's ground control points, then the site's `[frame]`; the site's own zone, or no
//! `zone_id`, is the site's metres — `read_frame`'s `ReadFrame::of_written_fence`): a `Polygon` region
//! (closed ring) or a `Point` with `radius` (m, a 32-gon). The zone is used when the fence is
//! written: the fence is stored in site metres, and a later change of the zone's ground
//! control points does not move it. On a site without a `[frame]` a fence without `crs`
//! is refused (400 naming `crs`): its coordinates are degrees there is nothing to place by.
//! The reads give regions in EPSG:4326 by default where the site has a `[frame]`, else in
//! `local` with the site's zone as `zone_id`; in another frame on request, and as GeoJSON
//! (`read_frame`). A create answers in the CRS it was written in. `properties` may carry `rtls:kind`
//! (`hazard`, `restricted`, `area-of-interest`, default), and `rtls:floor` (a site floor id) or
//! `rtls:z_range_m`; without either the zone spans every height. The zone's id is the fence's
//! `foreign_id` when given, else its UUID.

use axum::body::Bytes;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use rtls_engine::site::Site;
use rtls_engine::zones::{AntiFlap, Shape, Zone as SiteZone, ZoneKind, ZoneMonitor};
use serde_json::Value;

use super::read_frame::ReadFrame;
use super::{parse_json, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::convert::fence_from_zone;
use crate::omlox::crs::Crs;
use crate::omlox::{Fence, Region};
use crate::store::Store;

/// Where the edited zone set is stored.
const ZONES_KIND: &str = "zones";
const ZONES_ID: &str = "current";

/// Vertices of the polygon a circular fence becomes.
const CIRCLE_VERTICES: usize = 32;

fn fences(state: &AppState) -> Vec<Fence> {
    state.pipeline.live().zones().iter().map(fence_from_zone).collect()
}

fn find<'a>(fences: &'a [Fence], fence_id: &str) -> Option<&'a Fence> {
    fences
        .iter()
        .find(|f| f.id == fence_id || f.foreign_id.as_deref() == Some(fence_id))
}

/// `GET /v2/fences`.
pub(super) async fn list(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Vec<String>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(fences(&state).into_iter().map(|f| f.id).collect()))
}

/// `GET /v2/fences/summary`: every fence, its region in the frame `crs` and `zone_id` ask for
/// — by default EPSG:4326 ("Returned fence objects use EPSG:4326 ("GPS") as the projection
/// for the region coordinates, unless another projection is requested") where the site has a
/// `[frame]`, else `local` with the site's zone as `zone_id` —, as GeoJSON with
/// `geojson=true` ([`ReadFrame::of_fences`]).
pub(super) async fn summary(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of_fences(&state, query.as_deref()).await?;
    let fences = fences(&state)
        .into_iter()
        .map(|f| read.fence(f))
        .collect::<ApiResult<Vec<_>>>()?;
    Ok(read.answer_all(&fences))
}

/// `GET /v2/fences/{fence_id}`: by UUID or by the zone's id (`foreign_id`); query and default
/// frame as on [`summary`].
pub(super) async fn get(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of_fences(&state, query.as_deref()).await?;
    let fence = find(&fences(&state), &fence_id)
        .cloned()
        .ok_or_else(|| ApiError::not_found(format!("fence `{fence_id}` not found")))?;
    Ok(read.answer(&read.fence(fence)?))
}

/// `POST /v2/fences`: 201 with the fence in the CRS it was written in (a UUID is assigned when
/// `id` is absent or the nil UUID); 400 naming the field of a bad fence or an id in use.
pub(super) async fn create(State(state): State<AppState>, headers: HeaderMap, body: Bytes) -> ApiResult<Response> {
    let who = state.authorize(&headers, Access::Operate)?;
    let mut value: Value = parse_json(&body)?;
    super::assign_id_if_unset(&mut value);
    let fence: Fence = parse_json(value.to_string().as_bytes())?;
    uuid::Uuid::parse_str(&fence.id)
        .map_err(|e| ApiError::field("id", format!("`{}` is not a UUID ({e})", fence.id)))?;
    let answer = ReadFrame::of_written_fence(&state, &fence).await?;
    let written = answer.clone();
    let site = std::sync::Arc::clone(&state.site);
    let live = std::sync::Arc::clone(state.pipeline.live());
    let created = state
        .query(move |store| {
            let mut zones = live.zones().to_vec();
            let zone = match put_fence(&mut zones, None, &fence, &site, &written) {
                Ok(zone) => zone,
                Err(e) => return Ok(Err(e)),
            };
            Ok(commit(store, &live, zones).map(|()| fence_from_zone(&zone)))
        })
        .await??;
    state.audit(&who, "fence-created", &created.id).await;
    Ok((StatusCode::CREATED, Json(answer.fence(created)?)).into_response())
}

/// `PUT /v2/fences/{fence_id}`: replaces a fence's geometry, name and properties (its zone id
/// stays); 204, the status the spec documents (as for trackables and zones).
pub(super) async fn replace(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Operate)?;
    let mut value: Value = parse_json(&body)?;
    if let Value::Object(object) = &mut value {
        // the path names the fence; a body without an id is fine
        object.entry("id").or_insert_with(|| Value::String(fence_id.clone()));
    }
    let fence: Fence = parse_json(value.to_string().as_bytes())?;
    let written = ReadFrame::of_written_fence(&state, &fence).await?;
    let site = std::sync::Arc::clone(&state.site);
    let live = std::sync::Arc::clone(state.pipeline.live());
    let replaced = state
        .query(move |store| {
            let mut zones = live.zones().to_vec();
            let Some(index) = zones.iter().position(|z| {
                let existing = fence_from_zone(z);
                existing.id == fence_id || existing.foreign_id.as_deref() == Some(fence_id.as_str())
            }) else {
                return Ok(Err(ApiError::not_found(format!("fence `{fence_id}` not found"))));
            };
            let zone = match put_fence(&mut zones, Some(index), &fence, &site, &written) {
                Ok(zone) => zone,
                Err(e) => return Ok(Err(e)),
            };
            Ok(commit(store, &live, zones).map(|()| fence_from_zone(&zone)))
        })
        .await??;
    state.audit(&who, "fence-replaced", &replaced.id).await;
    Ok(StatusCode::NO_CONTENT)
}

/// `DELETE /v2/fences/{fence_id}`: 204; its occupants leave it without an exit event.
pub(super) async fn delete(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Operate)?;
    let target = fence_id.clone();
    let live = std::sync::Arc::clone(state.pipeline.live());
    state
        .query(move |store| {
            let mut zones = live.zones().to_vec();
            let before = zones.len();
            zones.retain(|z| {
                let fence = fence_from_zone(z);
                fence.id != fence_id && fence.foreign_id.as_deref() != Some(fence_id.as_str())
            });
            if zones.len() == before {
                return Ok(Err(ApiError::not_found(format!("fence `{fence_id}` not found"))));
            }
            Ok(commit(store, &live, zones))
        })
        .await??;
    state.audit(&who, "fence-deleted", &target).await;
    Ok(StatusCode::NO_CONTENT)
}

/// `DELETE /v2/fences`: deletes every fence (the site file's seed included: the empty set is
/// stored and watched, also after a restart, until `DELETE /api/v1/zones/edits`); their
/// occupants leave them without an exit event; 204.
pub(super) async fn delete_all(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Operate)?;
    let live = std::sync::Arc::clone(state.pipeline.live());
    let deleted = state
        .query(move |store| {
            let deleted = live.zones().len();
            Ok(commit(store, &live, Vec::new()).map(|()| deleted))
        })
        .await??;
    state
        .audit(&who, "fences-deleted-all", &format!("{deleted} fences"))
        .await;
    Ok(StatusCode::NO_CONTENT)
}

/// Puts `fence` into `zones`: over the zone at `index` (its zone id stays), else as a new zone
/// (zone id the fence's `foreign_id`, else its id); the zone it became.
///
/// # Errors
/// 400 naming the field of a bad fence, or `id` when a new fence's id or zone id is taken.
fn put_fence(
    zones: &mut Vec<rtls_engine::zones::Zone>,
    index: Option<usize>,
    fence: &Fence,
    site: &rtls_engine::site::Site,
    written: &ReadFrame,
) -> ApiResult<rtls_engine::zones::Zone> {
    let zone_id = match index {
        Some(index) => zones[index].id.clone(),
        None => fence.foreign_id.clone().unwrap_or_else(|| fence.id.clone()),
    };
    let zone = zone_from_fence(fence, zone_id, site, written)?;
    match index {
        Some(index) => zones[index] = zone.clone(),
        None if zones
            .iter()
            .any(|z| z.id == zone.id || fence_from_zone(z).id == fence.id) =>
        {
            return Err(ApiError::field(
                "id",
                "a fence with this id or foreign_id exists; use PUT",
            ))
        }
        None => zones.push(zone.clone()),
    }
    Ok(zone)
}

/// Creates `fence` (its region in site metres, whatever its `crs` and `zone_id` say: the hub
/// made it), or replaces the fence with its id (its zone id stays), and hands the set to the
/// running trackers; the fence as watched, in the fence reads' default frame
/// ([`ReadFrame::fence_default`]).
///
/// # Errors
/// 400 naming the field of a bad fence; 503 when the store fails.
pub(super) async fn upsert(state: &AppState, who: &crate::auth::Principal, fence: Fence) -> ApiResult<Fence> {
    let written = ReadFrame::site_metres(state);
    let site = std::sync::Arc::clone(&state.site);
    let live = std::sync::Arc::clone(state.pipeline.live());
    let stored = state
        .query(move |store| {
            let mut zones = live.zones().to_vec();
            let index = zones.iter().position(|z| fence_from_zone(z).id == fence.id);
            let zone = match put_fence(&mut zones, index, &fence, &site, &written) {
                Ok(zone) => zone,
                Err(e) => return Ok(Err(e)),
            };
            Ok(commit(store, &live, zones).map(|()| fence_from_zone(&zone)))
        })
        .await??;
    state.audit(who, "fence-upserted", &stored.id).await;
    ReadFrame::fence_default(state).fence(stored)
}

/// `DELETE /api/v1/zones/edits`: forgets the edited zone set; the site file's zones are
/// watched again (at once, and after a restart). 204.
pub(super) async fn reset(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Operate)?;
    let site = std::sync::Arc::clone(&state.site);
    let live = std::sync::Arc::clone(state.pipeline.live());
    state
        .query(move |store| {
            store.delete_config(ZONES_KIND, ZONES_ID)?;
            live.set_zones(site.zones.clone());
            Ok(())
        })
        .await?;
    state.audit(&who, "zones-reset", "the site file's zones").await;
    Ok(StatusCode::NO_CONTENT)
}

/// Validates the whole set (ids unique, geometry), stores it, and hands it to the trackers.
fn commit(store: &mut dyn Store, live: &crate::pipeline::LiveState, zones: Vec<SiteZone>) -> Result<(), ApiError> {
    ZoneMonitor::new(
        zones.clone(),
        AntiFlap {
            tolerance_m: 0.0,
            delay_s: 0.0,
        },
    )
    .map_err(|e| ApiError::field("region", e.to_string()))?;
    let json =
        serde_json::to_string(&zones).map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    store
        .put_config(ZONES_KIND, ZONES_ID, &json)
        .map_err(|e| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, e.to_string()))?;
    live.set_zones(zones);
    Ok(())
}

/// The stored zone set, if the zones were edited (for `rtls serve` at start).
///
/// # Errors
/// The store's error, or a stored set that is not valid JSON zones.
pub fn stored_zones(store: &mut dyn Store) -> Result<Option<Vec<SiteZone>>, String> {
    let Some(json) = store.get_config(ZONES_KIND, ZONES_ID).map_err(|e| e.to_string())? else {
        return Ok(None);
    };
    let zones: Vec<SiteZone> = serde_json::from_str(&json)
        .map_err(|e| format!("the stored zone set (config zones/current) is corrupt: {e}"))?;
    ZoneMonitor::new(
        zones.clone(),
        AntiFlap {
            tolerance_m: 0.0,
            delay_s: 0.0,
        },
    )
    .map_err(|e| format!("the stored zone set (config zones/current) is invalid: {e}"))?;
    Ok(Some(zones))
}

/// A region given in EPSG:4326 (`[longitude, latitude(, height)]`, degrees) in site metres,
/// through the site's `[frame]` georeference; a Point's radius is metres in either CRS.
/// `stated` is whether the fence named its `crs` (else EPSG:4326 is omlox's default).
///
/// # Errors
/// A 400 naming `crs` on a site without a frame, or the position that is no longitude and
/// latitude.
fn region_in_site(region: &Region, site: &Site, stated: bool) -> ApiResult<Region> {
    let frame = site.frame.as_ref().ok_or_else(|| {
        let reason =
            "the site has no [frame] origin to place EPSG:4326 coordinates: send site metres with crs \"local\"";
        ApiError::field(
            "crs",
            if stated {
                reason.to_string()
            } else {
                format!("a fence without crs is in EPSG:4326 (omlox's default), and {reason}")
            },
        )
    })?;
    let to_site = |position: &[f64], field: String| -> ApiResult<Vec<f64>> {
        let [lon, lat] = position[..2] else {
            return Err(ApiError::field(field, "a position is [longitude, latitude]"));
        };
        let height_m = position.get(2).copied().unwrap_or(frame.origin.height_m);
        match frame.site_of_wgs84([lon, lat, height_m]) {
            Some(site_m) if lon.abs() <= 180.0 && lat.abs() <= 90.0 => Ok(site_m[..position.len()].to_vec()),
            _ => Err(ApiError::field(field, "a position is [longitude, latitude] in degrees")),
        }
    };
    region.try_map_positions(to_site)
}

/// A fence as a site zone with id `zone_id` (see the module documentation); a `local` region
/// is taken from the frame it was `written` in ([`ReadFrame::of_written_fence`]).
fn zone_from_fence(fence: &Fence, zone_id: String, site: &Site, written: &ReadFrame) -> ApiResult<SiteZone> {
    // omlox: "If crs is not present, 'EPSG:4326' ("GPS") MUST be assumed as the default."
    let crs = match fence.crs.as_deref() {
        None => Crs::Wgs84,
        stated => Crs::parse(stated).map_err(|reason| ApiError::field("crs", reason))?,
    };
    let region = match crs {
        Crs::Local => written.site_region(&fence.region)?,
        Crs::Wgs84 => region_in_site(&fence.region, site, fence.crs.is_some())?,
    };
    let vertices_m: Vec<[f64; 2]> = match &region {
        Region::Polygon { coordinates } => {
            let ring = coordinates
                .first()
                .ok_or_else(|| ApiError::field("region.coordinates", "a polygon needs a ring"))?;
            let mut vertices = Vec::with_capacity(ring.len());
            for (i, p) in ring.iter().enumerate() {
                match p.as_slice() {
                    [x, y, ..] if x.is_finite() && y.is_finite() => vertices.push([*x, *y]),
                    _ => {
                        return Err(ApiError::field(
                            format!("region.coordinates[0][{i}]"),
                            "a position is [x, y] in m, finite",
                        ))
                    }
                }
            }
            // GeoJSON rings repeat the first vertex at the end; zones do not
            if vertices.len() > 1 && vertices.first() == vertices.last() {
                vertices.pop();
            }
            if vertices.len() < 3 {
                // RFC 7946 §3.1.6: "A linear ring is a closed LineString with four or more positions."
                return Err(ApiError::field(
                    "region.coordinates[0]",
                    format!(
                        "a ring needs three corners (four positions, the first repeated last), got {} corners",
                        vertices.len()
                    ),
                ));
            }
            vertices
        }
        Region::Point { coordinates } => {
            let radius = fence
                .radius
                .filter(|r| r.is_finite() && *r > 0.0)
                .ok_or_else(|| ApiError::field("radius", "a Point fence needs a radius > 0 m"))?;
            let (Some(&x), Some(&y)) = (coordinates.first(), coordinates.get(1)) else {
                return Err(ApiError::field("region.coordinates", "a position is [x, y] in m"));
            };
            (0..CIRCLE_VERTICES)
                .map(|k| {
                    let angle = std::f64::consts::TAU * k as f64 / CIRCLE_VERTICES as f64;
                    [x + radius * angle.cos(), y + radius * angle.sin()]
                })
                .collect()
        }
    };
    if let Some(frame) = &site.frame {
        // fences are read in EPSG:4326 by default: every corner needs a place on the globe
        let placed = |&[x, y]: &[f64; 2]| {
            frame
                .wgs84_of([x, y, 0.0])
                .is_some_and(|p| p.iter().all(|v| v.is_finite()))
        };
        if let Some(i) = vertices_m.iter().position(|v| !placed(v)) {
            let field = match &fence.region {
                Region::Point { .. } => "region.coordinates".to_string(),
                Region::Polygon { .. } => format!("region.coordinates[0][{i}]"),
            };
            return Err(ApiError::field(
                field,
                format!(
                    "{:?} m (site metres) is no place on the globe through the site's [frame]",
                    vertices_m[i]
                ),
            ));
        }
    }
    let property = |key: &str| fence.properties.as_ref().and_then(|p| p.get(key)).cloned();
    let kind: ZoneKind = match property("rtls:kind") {
        None => ZoneKind::AreaOfInterest,
        Some(kind) => serde_json::from_value(kind.clone()).map_err(|_| {
            ApiError::field(
                "properties.rtls:kind",
                format!("{kind} is not one of \"hazard\", \"restricted\", \"area-of-interest\""),
            )
        })?,
    };
    let floor = match property("rtls:floor") {
        None => None,
        Some(Value::String(floor)) => Some(
            site.floors
                .iter()
                .find(|f| f.id == floor)
                .ok_or_else(|| ApiError::field("properties.rtls:floor", format!("the site has no floor `{floor}`")))?,
        ),
        Some(_) => return Err(ApiError::field("properties.rtls:floor", "a floor id (string)")),
    };
    let z_range_m = match (floor, property("rtls:z_range_m")) {
        (Some(floor), _) => Some(floor.z_range_m),
        (None, Some(range)) => Some(
            serde_json::from_value::<[f64; 2]>(range)
                .map_err(|_| ApiError::field("properties.rtls:z_range_m", "[z_min, z_max] in m"))?,
        ),
        (None, None) => None,
    };
    let zone = SiteZone {
        name: fence.name.clone().unwrap_or_else(|| zone_id.clone()),
        id: zone_id,
        kind,
        readers: Vec::new(),
        shape: Shape::Polygon {
            vertices_m,
            floor: floor.map(|f| f.id.clone()),
            z_range_m,
        },
    };
    zone.validate().map_err(|e| match e {
        // the zone's own words, without the site file's position it would have there
        rtls_engine::EngineError::Parse { reason, .. } => ApiError::field("region", reason),
        other => ApiError::field("region", other.to_string()),
    })?;
    Ok(zone)
}
