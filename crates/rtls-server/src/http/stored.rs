//! Reading the stored omlox configuration (providers, trackables, zones: JSON by kind and id in
//! the store's configuration table). Kept apart from the handlers so that any of them — the
//! reads' frames (`read_frame`) too — can read it without importing a handler module.

use axum::http::StatusCode;
use serde::de::DeserializeOwned;

use super::{ApiError, ApiResult, AppState};

/// Every stored object of `kind`.
///
/// # Errors
/// The store's error; a 500 naming a stored object that does not parse.
pub(super) async fn list_stored<T: DeserializeOwned + Send + 'static>(
    state: &AppState,
    kind: &'static str,
) -> ApiResult<Vec<T>> {
    let rows = state.query(move |store| store.list_config(kind)).await?;
    rows.into_iter()
        .map(|(id, json)| {
            serde_json::from_str(&json).map_err(|e| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("stored {kind} `{id}` is corrupt: {e}"),
                )
            })
        })
        .collect()
}

/// The stored object of `kind` with `id`, if any.
///
/// # Errors
/// As [`list_stored`].
pub(super) async fn get_stored<T: DeserializeOwned + Send + 'static>(
    state: &AppState,
    kind: &'static str,
    id: &str,
) -> ApiResult<Option<T>> {
    let key = id.to_string();
    let json = state.query(move |store| store.get_config(kind, &key)).await?;
    json.map(|json| {
        serde_json::from_str(&json).map_err(|e| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("stored {kind} `{id}` is corrupt: {e}"),
            )
        })
    })
    .transpose()
}
