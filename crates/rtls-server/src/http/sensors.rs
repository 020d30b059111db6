//! omlox sensor data: what a provider's sensors report, application-defined JSON (any value
//! but `null`), kept as the provider's `sensors` field in its stored configuration — so it is
//! also in `GET /v2/providers/{id}` and survives a restart. A tracked tag that has no stored
//! provider gets one (type `unknown`) when its sensor data is first written.

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::Json;
use serde_json::Value;

use super::hub::{known_provider_or_404, replace, stored_trackable, PROVIDER};
use super::stored::get_stored;
use super::{parse_json, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::omlox::LocationProvider;

/// `PUT /v2/providers/{provider_id}/sensors`: replaces the provider's sensor data; 204.
///
/// # Errors
/// 404 for a provider neither stored nor tracked; 400 for a body that is not JSON or `null`.
pub(super) async fn put_sensors(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Write)?;
    let sensors: Value = parse_json(&body)?;
    if sensors.is_null() {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "request body: sensor data is a JSON value other than null",
        ));
    }
    let mut provider = known_provider_or_404(&state, &provider_id).await?;
    provider.sensors = Some(sensors);
    replace(&state, &who, PROVIDER, provider_id, &provider).await
}

/// `GET /v2/providers/{provider_id}/sensors`: the provider's sensor data as written.
///
/// # Errors
/// 404 for a provider neither stored nor tracked, or one without sensor data.
pub(super) async fn get_sensors(
    State(state): State<AppState>,
    Path(provider_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let provider = known_provider_or_404(&state, &provider_id).await?;
    provider
        .sensors
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("provider `{provider_id}` has no sensor data")))
}

/// `GET /v2/trackables/{trackable_id}/sensors`: the sensor data of each of its providers that
/// has some, an array in the order of `location_providers` (empty when none has).
///
/// # Errors
/// 404 for an unknown trackable.
pub(super) async fn trackable_sensors(
    State(state): State<AppState>,
    Path(trackable_id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<Value>>> {
    state.authorize(&headers, Access::Read)?;
    let trackable = stored_trackable(&state, &trackable_id).await?;
    let mut sensors = Vec::new();
    for provider_id in trackable.location_providers.unwrap_or_default() {
        let provider: Option<LocationProvider> = get_stored(&state, PROVIDER, &provider_id).await?;
        sensors.extend(provider.and_then(|p| p.sensors));
    }
    Ok(Json(sensors))
}
