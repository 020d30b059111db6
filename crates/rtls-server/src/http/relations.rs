//! The omlox links between providers, trackables and fences, and trackable motions — computed
//! at each request from the live state (every tag's latest location) and the fences the
//! trackers watch now.
//!
//! "Inside a fence" is, by default, what the trackers consider inside: the confirmed entries
//! of the zone monitors (an entry event was sent and no exit since; this follows the zones'
//! anti-flap settings). With `?spatial_query=true` it is the geometry alone: the tag's latest
//! location lies in the fence's region (and height range). A provider is a tag (its id is the
//! tag's); a trackable is inside a fence when one of the providers whose locations it takes is
//! ([`crate::pipeline::trackable_location`]: every one of its `location_providers` without
//! `locating_rules`, the one they select with them).

use std::collections::{BTreeSet, HashMap};

use axum::extract::{Path, RawQuery, State};
use axum::http::HeaderMap;
use axum::response::Response;
use axum::Json;

use super::hub::{
    implicit_provider, known_provider, known_provider_or_404, newest_location, stored_trackable, PROVIDER,
};
use super::read_frame::ReadFrame;
use super::stored::list_stored;
use super::{query_value, ApiError, ApiResult, AppState, TRACKABLE_CONFIG};
use crate::auth::Access;
use crate::convert::fence_from_zone;
use crate::omlox::locating_rules::RuleSet;
use crate::omlox::{Fence, Location, LocationProvider, Trackable, TrackableMotion};
use crate::pipeline::trackable_location::taken;

/// `spatial_query` of a query string: `true` / `false` (default `false`).
fn spatial_query(query: Option<&str>) -> ApiResult<bool> {
    match query_value(query, "spatial_query").as_deref() {
        None | Some("false") => Ok(false),
        Some("true") => Ok(true),
        Some(other) => Err(ApiError::field(
            "spatial_query",
            format!("`{other}` is not true or false"),
        )),
    }
}

/// The fence with this id (or `foreign_id`) and the tags inside it (see the module
/// documentation), or a 404. Only that fence's occupants are gathered.
fn fence_with_tags(state: &AppState, fence_id: &str, spatial: bool) -> ApiResult<(Fence, BTreeSet<String>)> {
    let live = state.pipeline.live();
    let zones = live.zones();
    let (zone, fence) = zones
        .iter()
        .map(|zone| (zone, fence_from_zone(zone)))
        .find(|(_, f)| f.id == fence_id || f.foreign_id.as_deref() == Some(fence_id))
        .ok_or_else(|| ApiError::not_found(format!("fence `{fence_id}` not found")))?;
    let mut tags = BTreeSet::new();
    if spatial {
        live.for_each_tag(|tag, tag_state| {
            if zone.contains(tag_state.position_m) {
                tags.insert(tag.to_string());
            }
        });
    } else {
        // a tag whose latest location was deleted is not listed until its next update
        let inside = live.occupants().remove(&zone.id).unwrap_or_default();
        tags.extend(inside.into_iter().filter(|tag| live.has_tag(tag)));
    }
    Ok((fence, tags))
}

/// The fences one of `tags` is inside, in the fence list's order and the fence reads' default
/// frame; only those tags' states are read.
///
/// # Errors
/// A region the frame cannot take ([`ReadFrame::fence`]).
fn fences_of(state: &AppState, tags: &[String], spatial: bool) -> ApiResult<Vec<Fence>> {
    let live = state.pipeline.live();
    // a tag whose latest location was deleted is inside nothing until its next update
    let located: Vec<(&String, [f64; 3])> = tags
        .iter()
        .filter_map(|tag| live.tag(tag).map(|s| (tag, s.position_m)))
        .collect();
    if located.is_empty() {
        return Ok(Vec::new());
    }
    let read = ReadFrame::fence_default(state);
    let occupants = (!spatial).then(|| live.occupants());
    live.zones()
        .iter()
        .filter(|zone| match &occupants {
            None => located.iter().any(|(_, position_m)| zone.contains(*position_m)),
            Some(occupants) => occupants
                .get(&zone.id)
                .is_some_and(|inside| located.iter().any(|(tag, _)| inside.contains(*tag))),
        })
        .map(|zone| read.fence(fence_from_zone(zone)))
        .collect()
}

/// The motions of those of `trackables` that have a location, each location in `read`'s frame.
///
/// # Errors
/// A location the frame cannot take ([`ReadFrame::location`]).
fn motions(state: &AppState, trackables: &[Trackable], read: &ReadFrame) -> ApiResult<Vec<TrackableMotion>> {
    trackables
        .iter()
        .filter_map(|t| Some(read.motion(t, newest_location(state, t)?)))
        .collect()
}

/// The stored trackables with one of `tags` among their providers.
async fn trackables_with(state: &AppState, tags: &BTreeSet<String>) -> ApiResult<Vec<Trackable>> {
    let trackables: Vec<Trackable> = list_stored(state, TRACKABLE_CONFIG).await?;
    Ok(trackables
        .into_iter()
        .filter(|t| t.location_providers.iter().flatten().any(|p| tags.contains(p)))
        .collect())
}

/// The providers whose latest locations `trackable` takes ([`taken`]).
fn taken_providers(state: &AppState, trackable: &Trackable) -> Vec<String> {
    taken(trackable, &RuleSet::of_stored(trackable), state.pipeline.live())
        .into_iter()
        .map(|latest| latest.provider)
        .collect()
}

/// The stored trackables that take the location of one of `tags` (inside a fence).
async fn trackables_taking(state: &AppState, tags: &BTreeSet<String>) -> ApiResult<Vec<Trackable>> {
    Ok(trackables_with(state, tags)
        .await?
        .into_iter()
        .filter(|t| taken_providers(state, t).iter().any(|p| tags.contains(p)))
        .collect())
}

/// Providers by id: the stored one, else the implicit one of the tag.
async fn providers_by_id(state: &AppState, ids: impl IntoIterator<Item = String>) -> ApiResult<Vec<LocationProvider>> {
    let mut stored: HashMap<String, LocationProvider> = list_stored::<LocationProvider>(state, PROVIDER)
        .await?
        .into_iter()
        .map(|p| (p.id.clone(), p))
        .collect();
    Ok(ids
        .into_iter()
        .map(|id| stored.remove(&id).unwrap_or_else(|| implicit_provider(&id)))
        .collect())
}

// ---- providers ----

/// `GET /v2/providers/{provider_id}/fences`: the fences the provider is inside, in the fence
/// reads' default frame ([`ReadFrame::fence_default`]: EPSG:4326 where the site has a
/// `[frame]`); 404 for an unknown provider (neither stored nor tracked).
pub(super) async fn provider_fences(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Fence>>> {
    state.authorize(&headers, Access::Read)?;
    let spatial = spatial_query(query.as_deref())?;
    known_provider_or_404(&state, &provider_id).await?;
    fences_of(&state, &[provider_id], spatial).map(Json)
}

/// `GET /v2/providers/{provider_id}/trackables`: the stored trackables the provider is
/// assigned to; 404 when the provider is neither stored, tracked nor assigned.
pub(super) async fn provider_trackables(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Trackable>>> {
    state.authorize(&headers, Access::Read)?;
    let trackables = trackables_with(&state, &BTreeSet::from([provider_id.clone()])).await?;
    if trackables.is_empty() && known_provider(&state, &provider_id).await?.is_none() {
        return Err(ApiError::not_found(format!("provider `{provider_id}` not found")));
    }
    Ok(Json(trackables))
}

// ---- trackables ----

/// `GET /v2/trackables/{trackable_id}/fences`: the fences one of the providers whose locations
/// it takes is inside, in the fence reads' default frame (as [`provider_fences`]); 404 for an
/// unknown trackable.
pub(super) async fn trackable_fences(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Fence>>> {
    state.authorize(&headers, Access::Read)?;
    let spatial = spatial_query(query.as_deref())?;
    let trackable = stored_trackable(&state, &trackable_id).await?;
    let providers = taken_providers(&state, &trackable);
    fences_of(&state, &providers, spatial).map(Json)
}

/// `GET /v2/trackables/{trackable_id}/locations`: the latest location of each of its
/// providers that has one, in the order of `location_providers`; 404 for an unknown trackable.
/// `crs`, `zone_id` and `geojson` as [`ReadFrame`] reads them.
pub(super) async fn trackable_locations(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let trackable = stored_trackable(&state, &trackable_id).await?;
    let live = state.pipeline.live();
    let latest = trackable
        .location_providers
        .iter()
        .flatten()
        .filter_map(|p| live.tag(p));
    let locations = read.locations(latest.map(|t| Location::clone(&t.location)))?;
    Ok(read.answer_all(&locations))
}

/// `GET /v2/trackables/{trackable_id}/providers`: its `location_providers` as objects (the
/// stored provider, else an implicit one of type `unknown`); 404 for an unknown trackable.
pub(super) async fn trackable_providers(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<LocationProvider>>> {
    state.authorize(&headers, Access::Read)?;
    let trackable = stored_trackable(&state, &trackable_id).await?;
    Ok(Json(
        providers_by_id(&state, trackable.location_providers.unwrap_or_default()).await?,
    ))
}

/// `GET /v2/trackables/{trackable_id}/motion`: its motion — its location ([`newest_location`]:
/// the newest of its providers', or the one its `locating_rules` select; with our track's
/// `speed`, m/s, and `course`, degrees from north) and its name, geometry, extrusion and
/// properties; 404 for an unknown trackable or one without a location.
/// `crs`, `zone_id` and `geojson` as [`ReadFrame`] reads them (the location's frame).
pub(super) async fn trackable_motion(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let trackable = stored_trackable(&state, &trackable_id).await?;
    let location = newest_location(&state, &trackable)
        .ok_or_else(|| ApiError::not_found(format!("trackable `{trackable_id}` has no location")))?;
    Ok(read.answer(&read.motion(&trackable, location)?))
}

/// `GET /v2/trackables/motions`: the motion of every stored trackable that has a location
/// (query as on [`trackable_motion`]).
pub(super) async fn trackable_motions(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let trackables: Vec<Trackable> = list_stored(&state, TRACKABLE_CONFIG).await?;
    Ok(read.answer_all(&motions(&state, &trackables, &read)?))
}

// ---- fences ----

/// `GET /v2/fences/{fence_id}/locations`: the latest locations of the providers inside the
/// fence; 404 for an unknown fence. `crs`, `zone_id` and `geojson` as [`ReadFrame`] reads them.
pub(super) async fn fence_locations(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let (_, tags) = fence_with_tags(&state, &fence_id, spatial_query(query.as_deref())?)?;
    let live = state.pipeline.live();
    let inside = tags.iter().filter_map(|t| live.tag(t));
    let locations = read.locations(inside.map(|t| Location::clone(&t.location)))?;
    Ok(read.answer_all(&locations))
}

/// `GET /v2/fences/{fence_id}/providers`: the providers inside the fence; 404 for an unknown
/// fence.
pub(super) async fn fence_providers(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<LocationProvider>>> {
    state.authorize(&headers, Access::Read)?;
    let (_, tags) = fence_with_tags(&state, &fence_id, spatial_query(query.as_deref())?)?;
    Ok(Json(providers_by_id(&state, tags).await?))
}

/// `GET /v2/fences/{fence_id}/trackables`: the stored trackables one of whose taken providers
/// (module documentation) is inside the fence; 404 for an unknown fence.
pub(super) async fn fence_trackables(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Trackable>>> {
    state.authorize(&headers, Access::Read)?;
    let (_, tags) = fence_with_tags(&state, &fence_id, spatial_query(query.as_deref())?)?;
    Ok(Json(trackables_taking(&state, &tags).await?))
}

/// `GET /v2/fences/{fence_id}/motions`: the motions of the trackables inside the fence; 404
/// for an unknown fence. `crs`, `zone_id` and `geojson` as [`ReadFrame`] reads them.
pub(super) async fn fence_motions(
    State(state): State<AppState>,
    Path(fence_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let (_, tags) = fence_with_tags(&state, &fence_id, spatial_query(query.as_deref())?)?;
    let trackables = trackables_taking(&state, &tags).await?;
    Ok(read.answer_all(&motions(&state, &trackables, &read)?))
}
