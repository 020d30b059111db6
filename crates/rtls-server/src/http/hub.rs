//! The omlox hub API under `/v2`: trackables and providers (stored configuration), location
//! ingest and latest locations, and the stored-configuration helpers the other omlox modules
//! share (zones are in `zones.rs`, fences in `fences.rs`, the links between them in
//! `relations.rs`, proximities in `proximity.rs`, sensor data in `sensors.rs`).

use axum::body::Bytes;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use serde_json::Value;

use super::read_frame::ReadFrame;
use super::stored::{get_stored, list_stored};
use super::trackable_sync::refresh_trackables;
use super::{parse_json, same_as_path, ApiError, ApiResult, AppState};
use crate::auth::{Access, Principal};
use crate::convert::{location_in_site, record_from_location};
use crate::omlox::ingest::parse_locations;
use crate::omlox::locating_rules::RuleSet;
use crate::omlox::{Location, LocationProvider, Trackable};
use crate::pipeline::trackable_location::trackable_location;
use crate::pipeline::unix_s;
use crate::sink::IngestError;
use crate::ServerError;

/// Stored configuration kinds.
use super::TRACKABLE_CONFIG as TRACKABLE;
pub(super) const PROVIDER: &str = "provider";

// ---- location ingest (PUT /v2/providers/locations, PUT /v2/providers/{id}/location) ----

/// `PUT /v2/providers/locations`: an array of omlox `Location`s, stored and tracked as fixes;
/// 204 when durable.
pub(super) async fn put_locations(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    state.authorize(&headers, Access::Write)?;
    let text = utf8(&body)?;
    let locations = parse_locations(text).map_err(server_error)?;
    ingest_locations(&state, &locations).await
}

/// `PUT /v2/providers/{provider_id}/location`: one `Location` whose `provider_id` must match
/// the path.
pub(super) async fn put_provider_location(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    state.authorize(&headers, Access::Write)?;
    let text = utf8(&body)?;
    if text.trim().is_empty() {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "request body: a Location is required",
        ));
    }
    let locations = parse_locations(&format!("[{text}]")).map_err(server_error)?;
    for location in &locations {
        same_as_path("provider_id", &location.provider_id, &provider_id)?;
    }
    ingest_locations(&state, &locations).await
}

pub(super) async fn ingest_locations(state: &AppState, locations: &[Location]) -> ApiResult<StatusCode> {
    let received_s = unix_s();
    // EPSG:4326 positions in site metres: what is tracked, stored and pushed on
    let locations = locations
        .iter()
        .enumerate()
        .map(|(index, location)| location_in_site(location, index, state.site.frame.as_ref()))
        .collect::<Result<Vec<_>, _>>()
        .map_err(server_error)?;
    let records = locations
        .iter()
        .enumerate()
        .map(|(index, location)| record_from_location(location, index, state.default_accuracy_m, received_s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(server_error)?;
    // before the records: their track updates keep what the provider said
    for (location, record) in locations.iter().zip(&records) {
        state.pipeline.note_pushed(crate::pushed::PushedLocation {
            location: location.clone(),
            time_s: record.time_s,
        });
    }
    state
        .pipeline
        .submit_records(LOCATIONS, records)
        .await
        .map_err(|e| naming_the_timestamp(e, &locations))?;
    Ok(StatusCode::NO_CONTENT)
}

/// How the ingest names omlox locations in its refusals (`{LOCATIONS}:{i + 1}: field …`).
const LOCATIONS: &str = "omlox locations";

/// An ingest refusal as an omlox Error: one of a location's time (outside the server's record
/// window) names the timestamp it came from, `[i].timestamp_generated` (else
/// `[i].timestamp_sent`); any other as it is.
fn naming_the_timestamp(error: IngestError, locations: &[Location]) -> ApiError {
    if let IngestError::Invalid(message) = &error {
        let refusal = message
            .strip_prefix(LOCATIONS)
            .and_then(|rest| rest.strip_prefix(':'))
            .and_then(|rest| rest.split_once(": field `t`: "))
            .and_then(|(line, reason)| Some((line.parse::<usize>().ok()?.checked_sub(1)?, reason)));
        if let Some((index, reason)) = refusal {
            let field = match locations.get(index) {
                Some(location) if location.timestamp_generated.is_none() => "timestamp_sent",
                _ => "timestamp_generated",
            };
            return ApiError::field(format!("[{index}].{field}"), reason);
        }
    }
    error.into()
}

/// The body as text, or a 400 naming the first bad byte.
pub(super) fn utf8(body: &[u8]) -> ApiResult<&str> {
    std::str::from_utf8(body).map_err(|e| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("request body: not UTF-8 at byte {}", e.valid_up_to()),
        )
    })
}

/// A conversion error as a 400, with its field path when it has one.
pub(super) fn server_error(error: ServerError) -> ApiError {
    match error {
        ServerError::InvalidField { index, field, reason } => ApiError::field(format!("[{index}].{field}"), reason),
        other => ApiError::new(StatusCode::BAD_REQUEST, other.to_string()),
    }
}

/// `GET /v2/providers/locations`: every tag's latest location (`crs`, `zone_id` and `geojson`
/// as [`ReadFrame`] reads them).
pub(super) async fn get_locations(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let tags = state.pipeline.live().tags();
    let locations = read.locations(tags.into_values().map(|t| Location::clone(&t.location)))?;
    Ok(read.answer_all(&locations))
}

/// `GET /v2/providers/{provider_id}/location`: a tag's latest location (query as on
/// [`get_locations`]).
pub(super) async fn get_provider_location(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let read = ReadFrame::of(&state, query.as_deref()).await?;
    let location = state
        .pipeline
        .live()
        .tag(&provider_id)
        .map(|t| Location::clone(&t.location))
        .ok_or_else(|| ApiError::not_found(format!("provider `{provider_id}` has no location")))?;
    Ok(read.answer(&read.location(location)?))
}

// ---- providers (stored; every tracked tag is also listed) ----

/// `GET /v2/providers`: ids of the stored providers and of every tracked tag.
pub(super) async fn list_providers(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Vec<String>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(providers(&state).await?.into_iter().map(|p| p.id).collect()))
}

/// `GET /v2/providers/summary`.
pub(super) async fn provider_summary(
    State(state): State<AppState>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<LocationProvider>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(providers(&state).await?))
}

/// Stored providers, then tracked tags that have none, by id.
pub(super) async fn providers(state: &AppState) -> ApiResult<Vec<LocationProvider>> {
    let mut stored: Vec<LocationProvider> = list_stored(state, PROVIDER).await?;
    let known: std::collections::HashSet<String> = stored.iter().map(|p| p.id.clone()).collect();
    for tag in state.pipeline.live().tags().into_keys().filter(|t| !known.contains(t)) {
        stored.push(implicit_provider(&tag));
    }
    stored.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(stored)
}

pub(super) fn implicit_provider(tag: &str) -> LocationProvider {
    LocationProvider {
        id: tag.to_string(),
        kind: crate::omlox::ProviderType::Unknown,
        name: Some(tag.to_string()),
        sensors: None,
        fence_timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        properties: None,
    }
}

/// `POST /v2/providers`: 201 with the stored provider; 400 naming `id` when a provider has
/// it (the id is the device's, "e.g. a MAC address of a UWB tag": a second provider under it
/// would be the same device).
pub(super) async fn create_provider(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Response> {
    let who = state.authorize(&headers, Access::Write)?;
    let provider: LocationProvider = parse_json(&body)?;
    if provider.id.trim().is_empty() {
        return Err(ApiError::field("id", "must not be empty"));
    }
    create(&state, &who, PROVIDER, provider.id.clone(), &provider, IdInUse::Refuse).await
}

/// `GET /v2/providers/{provider_id}`.
pub(super) async fn get_provider(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<LocationProvider>> {
    state.authorize(&headers, Access::Read)?;
    known_provider_or_404(&state, &provider_id).await.map(Json)
}

/// `PUT /v2/providers/{provider_id}`: replaces (or creates) it; 204.
pub(super) async fn put_provider(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let provider: LocationProvider = parse_json(&body)?;
    same_as_path("id", &provider.id, &provider_id)?;
    replace(&state, &who, PROVIDER, provider_id, &provider).await
}

/// `DELETE /v2/providers/{provider_id}`: 204, or 404.
pub(super) async fn delete_provider(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    // a tracked tag is listed as a provider by its live location: deleting the provider
    // forgets that too (until the tag's next update), so GET no longer returns it
    let live = state.pipeline.live();
    let tracked = live.tag(&provider_id).is_some();
    live.remove_tag(&provider_id);
    match delete(&state, &who, PROVIDER, provider_id.clone()).await {
        Err(not_stored) if tracked && not_stored.status == StatusCode::NOT_FOUND => {
            state.audit(&who, "location-deleted", &provider_id).await;
            Ok(StatusCode::NO_CONTENT)
        }
        outcome => outcome,
    }
}

// ---- trackables (stored) ----

/// `GET /v2/trackables`: ids.
pub(super) async fn list_trackables(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Vec<String>>> {
    state.authorize(&headers, Access::Read)?;
    let trackables: Vec<Trackable> = list_stored(&state, TRACKABLE).await?;
    Ok(Json(trackables.into_iter().map(|t| t.id).collect()))
}

/// `GET /v2/trackables/summary`.
pub(super) async fn trackable_summary(
    State(state): State<AppState>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Trackable>>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(list_stored(&state, TRACKABLE).await?))
}

/// `POST /v2/trackables`: a UUID is generated when `id` is absent, the nil UUID or in use
/// (omlox: "Creates a new trackable with a randomly generated id"); 201 with the trackable.
pub(super) async fn create_trackable(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Response> {
    let who = state.authorize(&headers, Access::Write)?;
    let mut value: Value = parse_json(&body)?;
    super::assign_id_if_unset(&mut value);
    let trackable: Trackable = parse_json(value.to_string().as_bytes())?;
    check_uuid(&trackable.id)?;
    check_rules(&trackable)?;
    let created = create(
        &state,
        &who,
        TRACKABLE,
        trackable.id.clone(),
        &trackable,
        IdInUse::Generate,
    )
    .await?;
    refresh_trackables(&state).await;
    Ok(created)
}

fn check_uuid(id: &str) -> ApiResult<()> {
    uuid::Uuid::parse_str(id)
        .map(|_| ())
        .map_err(|e| ApiError::field("id", format!("`{id}` is not a UUID ({e})")))
}

/// `GET /v2/trackables/{trackable_id}`.
pub(super) async fn get_trackable(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Trackable>> {
    state.authorize(&headers, Access::Read)?;
    stored_trackable(&state, &trackable_id).await.map(Json)
}

/// `PUT /v2/trackables/{trackable_id}`: replaces it; 200 with the trackable (as omlox
/// specifies for trackables).
pub(super) async fn put_trackable(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<Trackable>> {
    let who = state.authorize(&headers, Access::Write)?;
    let trackable: Trackable = parse_json(&body)?;
    same_as_path("id", &trackable.id, &trackable_id)?;
    check_uuid(&trackable.id)?;
    check_rules(&trackable)?;
    replace(&state, &who, TRACKABLE, trackable_id, &trackable).await?;
    refresh_trackables(&state).await;
    Ok(Json(trackable))
}

/// `DELETE /v2/trackables/{trackable_id}`.
pub(super) async fn delete_trackable(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let deleted = delete(&state, &who, TRACKABLE, trackable_id).await?;
    refresh_trackables(&state).await;
    Ok(deleted)
}

/// `GET /v2/trackables/{trackable_id}/location`: its location ([`newest_location`]; query as
/// on [`get_locations`]).
pub(super) async fn get_trackable_location(
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
    Ok(read.answer(&read.location(location)?))
}

/// A trackable's location: the newest of its providers' latest locations it takes — all of
/// them without `locating_rules`, the one they select with them
/// ([`crate::pipeline::trackable_location`]).
pub(super) fn newest_location(state: &AppState, trackable: &Trackable) -> Option<Location> {
    trackable_location(trackable, state.pipeline.live()).map(|location| Location::clone(&location))
}

/// A trackable's `locating_rules` must parse: a 400 naming the rule
/// (`locating_rules[i].expression`) and the position of its fault.
fn check_rules(trackable: &Trackable) -> ApiResult<()> {
    RuleSet::compile(trackable.locating_rules.as_deref().unwrap_or_default())
        .map(|_| ())
        .map_err(|e| ApiError::field(format!("locating_rules[{}].expression", e.index), e.to_string()))
}

/// A stored trackable, or a 404 naming it.
pub(super) async fn stored_trackable(state: &AppState, trackable_id: &str) -> ApiResult<Trackable> {
    get_stored(state, TRACKABLE, trackable_id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("trackable `{trackable_id}` not found")))
}

/// A provider: the stored one, else the implicit one of a tracked tag; `None` when neither.
pub(super) async fn known_provider(state: &AppState, provider_id: &str) -> ApiResult<Option<LocationProvider>> {
    Ok(
        match get_stored::<LocationProvider>(state, PROVIDER, provider_id).await? {
            Some(provider) => Some(provider),
            None => state
                .pipeline
                .live()
                .tag(provider_id)
                .map(|_| implicit_provider(provider_id)),
        },
    )
}

/// A provider as [`known_provider`], or a 404.
pub(super) async fn known_provider_or_404(state: &AppState, provider_id: &str) -> ApiResult<LocationProvider> {
    known_provider(state, provider_id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("provider `{provider_id}` not found")))
}

// ---- deleting everything of a kind, and latest locations ----

/// `DELETE /v2/trackables`: deletes every stored trackable; 204.
pub(super) async fn delete_all_trackables(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let deleted = delete_all(&state, &who, TRACKABLE).await?;
    refresh_trackables(&state).await;
    Ok(deleted)
}

/// `DELETE /v2/providers`: deletes every stored provider and forgets every tag's latest
/// location, so that `GET /v2/providers` is empty until a tag is tracked again (its tracks
/// themselves go on: the next update lists the tag again); 204.
pub(super) async fn delete_all_providers(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    forget_locations(&state);
    delete_all(&state, &who, PROVIDER).await
}

/// `DELETE /v2/providers/locations`: forgets every tag's latest location (listed again at its
/// track's next update); stored providers stay; 204.
pub(super) async fn delete_locations(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let forgotten = forget_locations(&state);
    state
        .audit(&who, "locations-deleted", &format!("{forgotten} latest locations"))
        .await;
    Ok(StatusCode::NO_CONTENT)
}

/// `DELETE /v2/providers/{provider_id}/location`: forgets a tag's latest location (it comes
/// back at its track's next update); 204, also for a stored provider without a location (there
/// is none afterwards, as asked: a DELETE is idempotent), 404 for an unknown provider.
pub(super) async fn delete_provider_location(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let live = state.pipeline.live();
    if live.tag(&provider_id).is_none() {
        known_provider_or_404(&state, &provider_id).await?;
        return Ok(StatusCode::NO_CONTENT);
    }
    live.remove_tag(&provider_id);
    state.audit(&who, "location-deleted", &provider_id).await;
    Ok(StatusCode::NO_CONTENT)
}

/// Forgets every tag's latest location; how many.
fn forget_locations(state: &AppState) -> usize {
    let live = state.pipeline.live();
    let tags: Vec<String> = live.tags().into_keys().collect();
    for tag in &tags {
        live.remove_tag(tag);
    }
    tags.len()
}

// ---- stored configuration helpers ----

/// What a create does when the object's id is in use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum IdInUse {
    /// A 400 naming `id` (providers: the id is the device's own, e.g. its MAC address).
    Refuse,
    /// A new object under a generated UUIDv4: omlox's POST /trackables "Creates a new
    /// trackable with a randomly generated id", POST /zones "The provided id will be replaced
    /// by a generated uuid" — here only when the given one is taken.
    Generate,
}

/// Stores `object` (whose `id` is `id`) as a new `kind`; 201 with it as stored.
///
/// # Errors
/// A 400 naming `id` when it is in use and `in_use` is [`IdInUse::Refuse`]; 503 when the store
/// fails.
pub(super) async fn create<T: Serialize>(
    state: &AppState,
    who: &Principal,
    kind: &'static str,
    id: String,
    object: &T,
    in_use: IdInUse,
) -> ApiResult<Response> {
    let mut body =
        serde_json::to_value(object).map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    // one call under the query connection's lock: no other request can create it in between
    let stored = state
        .query(move |store| {
            let mut key = id;
            while store.get_config(kind, &key)?.is_some() {
                if in_use == IdInUse::Refuse {
                    return Ok(Err(key));
                }
                key = uuid::Uuid::new_v4().to_string();
            }
            body["id"] = Value::String(key.clone());
            store.put_config(kind, &key, &body.to_string())?;
            Ok(Ok((key, body)))
        })
        .await?;
    let (id, body) =
        stored.map_err(|id| ApiError::field("id", format!("a {kind} `{id}` exists; use PUT to replace it")))?;
    state.audit(who, &format!("{kind}-created"), &id).await;
    Ok((StatusCode::CREATED, Json(body)).into_response())
}

pub(super) async fn replace<T: Serialize>(
    state: &AppState,
    who: &Principal,
    kind: &'static str,
    id: String,
    object: &T,
) -> ApiResult<StatusCode> {
    let json =
        serde_json::to_string(object).map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    let key = id.clone();
    state.query(move |store| store.put_config(kind, &key, &json)).await?;
    state.audit(who, &format!("{kind}-replaced"), &id).await;
    Ok(StatusCode::NO_CONTENT)
}

/// Deletes every stored object of `kind` in one call under the query connection's lock; 204.
pub(super) async fn delete_all(state: &AppState, who: &Principal, kind: &'static str) -> ApiResult<StatusCode> {
    let deleted = state
        .query(move |store| {
            let ids: Vec<String> = store.list_config(kind)?.into_iter().map(|(id, _)| id).collect();
            for id in &ids {
                store.delete_config(kind, id)?;
            }
            Ok(ids.len())
        })
        .await?;
    state
        .audit(who, &format!("{kind}-deleted-all"), &format!("{deleted} {kind}s"))
        .await;
    Ok(StatusCode::NO_CONTENT)
}

pub(super) async fn delete(state: &AppState, who: &Principal, kind: &'static str, id: String) -> ApiResult<StatusCode> {
    let key = id.clone();
    if state.query(move |store| store.delete_config(kind, &key)).await? {
        state.audit(who, &format!("{kind}-deleted"), &id).await;
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(ApiError::not_found(format!("{kind} `{id}` not found")))
    }
}
