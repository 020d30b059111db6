//! The HTTP and WebSocket surface: omlox hub API under `/v2`, our own API under `/api/v1`,
//! operations endpoints (`/health`, `/metrics`, `/openapi.json`).
//!
//! Auth: `Authorization: Bearer <token>` (the WebSocket also takes `?token=`, since browsers
//! cannot set headers on it). Writes need the write token; reads the read token when one is
//! configured. Errors are omlox `Error` objects `{type, code, message}` plus `field` — the
//! offending field's path — when one field is at fault.

mod adapters;
mod alarms;
mod api;
mod dashboard;
pub mod fences;
mod hub;
pub mod listener;
mod muster;
mod ops;
pub mod plans;
pub mod positions;
mod proximity;
mod query_flags;
pub mod rate;
mod read_frame;
mod relations;
mod sensors;
mod stored;
pub mod tokens;
pub mod trackable_sync;
mod v2;
mod ws;
mod zone_frame;
mod zone_store;
mod zones;

use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{HeaderMap, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::{delete, get, post};
use axum::{Json, Router};
use rtls_engine::site::Site;
use serde::de::DeserializeOwned;
use serde_json::{json, Value};

use crate::auth::{Access, Principal, Role, Tokens};
use crate::metrics::Metrics;
use crate::pipeline::Pipeline;
use crate::sink::IngestError;
use crate::store::{Store, StoreError};

/// The configuration kind omlox trackables are stored under.
pub const TRACKABLE_CONFIG: &str = "trackable";

/// What the handlers share.
#[derive(Clone)]
pub struct AppState {
    /// The ingest pipeline and live state.
    pub pipeline: Pipeline,
    /// The store connection for queries and configuration (used on blocking threads).
    pub queries: Arc<Mutex<QueryStore>>,
    /// The access tokens.
    pub tokens: Arc<Tokens>,
    /// The site being tracked.
    pub site: Arc<Site>,
    /// The omlox ingest's accuracy for locations without one (m).
    pub default_accuracy_m: f64,
    /// When the server started.
    pub started: Instant,
    /// The site's floor-plan images.
    pub floor_plans: Arc<plans::FloorPlans>,
}

/// The query connection: closed on a thread of its own when dropped, because the PostgreSQL
/// client blocks on a runtime of its own to close, which must not happen on an async task.
pub struct QueryStore(Option<Box<dyn Store>>);

impl QueryStore {
    /// Wraps a store.
    #[must_use]
    pub fn new(store: Box<dyn Store>) -> Self {
        Self(Some(store))
    }

    /// The store.
    fn get(&mut self) -> ApiResult<&mut (dyn Store + 'static)> {
        self.0
            .as_deref_mut()
            .ok_or_else(|| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the query connection is closed"))
    }

    /// Deletes rows stored before `before_ms` (retention).
    ///
    /// # Errors
    /// The store's error, or a closed connection.
    pub fn prune(&mut self, before_ms: i64) -> Result<crate::store::Pruned, String> {
        self.get()
            .map_err(|e| e.message)?
            .prune(before_ms)
            .map_err(|e| e.to_string())
    }

    /// Deletes ingest-log records stored before `before_ms` that are behind the output
    /// checkpoint (raw-record retention); returns how many.
    ///
    /// # Errors
    /// The store's error, or a closed connection.
    pub fn prune_ingest_log(&mut self, before_ms: i64) -> Result<u64, String> {
        let store = self.get().map_err(|e| e.message)?;
        let Some(through_id) = store
            .checkpoint(crate::pipeline::CHECKPOINT)
            .map_err(|e| e.to_string())?
        else {
            return Ok(0);
        };
        store.prune_ingest_log(before_ms, through_id).map_err(|e| e.to_string())
    }
}

impl QueryStore {
    /// Packs up to `max_rows` track states and up to `max_rows` tracked raw records stored
    /// before `before_ms` into compressed blocks; returns how many of each.
    ///
    /// # Errors
    /// The store's error, or a closed connection.
    pub fn compact(&mut self, before_ms: i64, max_rows: usize) -> Result<(u64, u64), String> {
        let store = self.get().map_err(|e| e.message)?;
        let states = store.compact_history(before_ms, max_rows).map_err(|e| e.to_string())?;
        let records = match store
            .checkpoint(crate::pipeline::CHECKPOINT)
            .map_err(|e| e.to_string())?
        {
            Some(through_id) => store
                .compact_ingest_log(before_ms, through_id, max_rows)
                .map_err(|e| e.to_string())?,
            None => 0,
        };
        Ok((states, records))
    }
}

impl Drop for QueryStore {
    fn drop(&mut self) {
        if let Some(store) = self.0.take() {
            let closing = std::thread::Builder::new()
                .name("rtls-store-close".into())
                .spawn(move || drop(store));
            if let Err(e) = closing {
                tracing::warn!(error = %e, "could not close the query connection on its own thread");
            }
        }
    }
}

/// An API error: the HTTP status, a message and, when one field is at fault, its path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiError {
    /// The status.
    pub status: StatusCode,
    /// What is wrong.
    pub message: String,
    /// The offending field (`[3].position.coordinates`, `name`), if one.
    pub field: Option<String>,
}

impl ApiError {
    /// An error without a field.
    #[must_use]
    pub fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
            field: None,
        }
    }

    /// A 400 naming a field.
    #[must_use]
    pub fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            status: StatusCode::BAD_REQUEST,
            message: message.into(),
            field: Some(field.into()),
        }
    }

    /// A 404.
    #[must_use]
    pub fn not_found(what: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, what)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let kind = self.status.canonical_reason().unwrap_or("error").to_lowercase();
        let mut body = json!({ "type": kind, "code": self.status.as_u16(), "message": self.message });
        if let Some(field) = self.field {
            body["field"] = json!(field);
        }
        (self.status, Json(body)).into_response()
    }
}

impl From<IngestError> for ApiError {
    fn from(error: IngestError) -> Self {
        match error {
            IngestError::Invalid(message) => Self::new(StatusCode::BAD_REQUEST, message),
            IngestError::Unauthorized(message) => Self::new(StatusCode::FORBIDDEN, message),
            IngestError::Unavailable(message) => Self::new(StatusCode::SERVICE_UNAVAILABLE, message),
        }
    }
}

impl From<StoreError> for ApiError {
    fn from(error: StoreError) -> Self {
        tracing::error!(error = %error, "store query failed");
        Self::new(StatusCode::SERVICE_UNAVAILABLE, error.to_string())
    }
}

/// The result of a handler.
pub type ApiResult<T> = Result<T, ApiError>;

impl AppState {
    /// Checks the request's bearer token against `needed`; who presented it.
    ///
    /// # Errors
    /// 401 without a token, 403 with a token that does not allow `needed`.
    pub fn authorize(&self, headers: &HeaderMap, needed: Access) -> ApiResult<Principal> {
        self.authorize_token(bearer(headers), needed)
    }

    /// Checks a presented token against `needed`; who presented it.
    ///
    /// # Errors
    /// As [`AppState::authorize`].
    pub fn authorize_token(&self, presented: Option<&str>, needed: Access) -> ApiResult<Principal> {
        let principal = self.tokens.principal(presented);
        if let Some(principal) = principal.filter(|p| p.role.allows(needed)) {
            return Ok(principal);
        }
        let what = match needed {
            Access::None | Access::Read => "reading",
            Access::Operate => "operating (acknowledging alarms, editing zones)",
            Access::Write => "writing",
            Access::Admin => "managing tokens",
        };
        Err(match presented {
            None => ApiError::new(StatusCode::UNAUTHORIZED, format!("{what} needs a bearer token")),
            Some(_) => ApiError::new(StatusCode::FORBIDDEN, format!("the token does not allow {what}")),
        })
    }

    /// Records a change in the audit log: an `audit` event — `action`, `target`, who (`by`:
    /// the credential's name, `role`) — stored with the events (`GET
    /// /api/v1/events?type=audit`) and published on `rtls:events`.
    ///
    /// The change is made when this is called, so a store failure does not fail the request
    /// (a 503 would make the client retry a change that happened): the event is still
    /// published, logged at error level and counted in `rtls_audit_store_failures_total`.
    pub async fn audit(&self, who: &Principal, action: &str, target: &str) {
        let now_ms = crate::pipeline::unix_ms();
        let time_s = now_ms as f64 / 1000.0;
        let event = serde_json::json!({
            "type": "audit",
            "t": time_s,
            "action": action,
            "target": target,
            "by": who.name,
            "role": who.role.name(),
        });
        tracing::info!(action, target, by = %who.name, role = who.role.name(), "audit");
        let row = crate::store::EventRow {
            received_ms: now_ms,
            time_s,
            kind: "audit".into(),
            tag: None,
            zone: None,
            alarm: false,
            json: event.to_string(),
        };
        if let Err(error) = self.query(move |store| store.append_events(&[row])).await {
            self.pipeline.metrics().audit_store_failures.inc();
            tracing::error!(action, target, by = %who.name, error = %error.message,
                "audit event not stored (the change is made)");
        }
        self.pipeline.broadcast(crate::pipeline::HubMessage::Extension {
            topic: crate::omlox::ws::Topic::RtlsEvents,
            event,
        });
    }

    /// Runs `query` on the query connection on a blocking thread.
    ///
    /// # Errors
    /// The query's [`StoreError`] as a 503.
    pub async fn query<T: Send + 'static>(
        &self,
        query: impl FnOnce(&mut dyn Store) -> Result<T, StoreError> + Send + 'static,
    ) -> ApiResult<T> {
        let queries = Arc::clone(&self.queries);
        tokio::task::spawn_blocking(move || {
            let mut store = queries
                .lock()
                .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the query connection failed"))?;
            query(store.get()?).map_err(ApiError::from)
        })
        .await
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, format!("query task failed: {e}")))?
    }
}

/// Gives a JSON object about to be created a fresh UUIDv4 `id` when it has none: absent, or the
/// nil UUID (`00000000-0000-0000-0000-000000000000`, which omlox clients send for "the hub
/// assigns it"). Any other id is kept and checked by the caller: `null` and `""` are not
/// UUIDs (the schema's `string`, format `uuid`) and are refused there.
pub(crate) fn assign_id_if_unset(value: &mut Value) {
    if let Value::Object(object) = value {
        let unset = match object.get("id") {
            None => true,
            Some(Value::String(id)) => uuid::Uuid::parse_str(id).is_ok_and(|u| u.is_nil()),
            Some(_) => false,
        };
        if unset {
            object.insert("id".into(), Value::String(uuid::Uuid::new_v4().to_string()));
        }
    }
}

/// Checks that the id a body names (`field`) is the path's: a 400 naming `field` otherwise.
///
/// # Errors
/// A 400 with `field` when `in_body` differs from `in_path`.
pub(super) fn same_as_path(field: &str, in_body: &str, in_path: &str) -> ApiResult<()> {
    if in_body == in_path {
        return Ok(());
    }
    Err(ApiError::field(
        field,
        format!("`{in_body}` does not match the path's `{in_path}`"),
    ))
}

/// Parses a JSON body into `T`, naming the offending field's path on failure.
///
/// # Errors
/// A 400 with `field` (e.g. `location_providers[1]`) and serde's message.
pub fn parse_json<T: DeserializeOwned>(body: &[u8]) -> ApiResult<T> {
    let mut deserializer = serde_json::Deserializer::from_slice(body);
    let value = serde_path_to_error::deserialize(&mut deserializer).map_err(|error| {
        let path = error.path().to_string();
        let message = error.into_inner().to_string();
        if path == "." {
            ApiError::new(StatusCode::BAD_REQUEST, format!("request body: {message}"))
        } else {
            ApiError::field(path, message)
        }
    })?;
    // one JSON value and nothing after it but whitespace (`5garbage` is not JSON)
    deserializer
        .end()
        .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, format!("request body: {e}")))?;
    Ok(value)
}

/// The largest request body accepted (bytes).
pub const MAX_BODY_BYTES: usize = 16 * 1024 * 1024;

/// The router with every route, for a server or for tests without a port
/// (`tower::ServiceExt::oneshot`).
pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/", get(dashboard::index))
        .route("/ui/{*path}", get(dashboard::ui_file))
        .route("/api/v1/site", get(dashboard::site))
        .route("/api/v1/readers", get(dashboard::readers))
        .route("/api/v1/zones/occupants", get(dashboard::occupants))
        .route("/api/v1/muster", get(muster::muster))
        .route("/api/v1/site/floors/{floor_id}/plan", get(plans::floor_plan))
        .route("/api/v1/alarms", get(alarms::list))
        .route("/api/v1/alarms/{alarm_id}/acknowledge", post(alarms::acknowledge))
        .route("/health", get(ops::health))
        .route("/metrics", get(ops::metrics_text))
        .route("/openapi.json", get(ops::openapi))
        .route("/api/v1/quarantine", get(ops::quarantine))
        .route("/api/v1/tokens", get(tokens::list).post(tokens::issue))
        .route("/api/v1/tokens/{token_id}", delete(tokens::revoke))
        .route("/api/v1/measurements", post(api::ingest_measurements))
        .route("/api/v1/adapters/{vendor}", post(adapters::ingest))
        .route("/api/v1/tags", get(api::tags))
        .route("/api/v1/positions", get(positions::positions))
        .route("/api/v1/tracks.geojson", get(api::tracks_geojson))
        .route("/api/v1/history", get(api::history))
        .route("/api/v1/events", get(api::events))
        .route("/api/v1/zones/head-counts", get(api::head_counts))
        .route("/api/v1/zones.geojson", get(api::zones_geojson))
        .route("/api/v1/zones/edits", delete(fences::reset))
        .route("/v2/ws/socket", get(ws::socket))
        .merge(v2::routes())
        .fallback(unknown_route)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES))
        .layer(axum::middleware::from_fn(query_flags::check_boolean_parameters))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            authorize_writes_first,
        ))
        .layer(axum::middleware::from_fn(limit_headers))
        .layer(axum::middleware::from_fn_with_state(state.clone(), count_requests))
        .with_state(state)
}

/// The request line's target and headers together, at most (bytes): a request over it is
/// answered 431 before any handler runs.
pub const MAX_HEADER_BYTES: usize = 16 * 1024;

/// Refuses a request whose target and headers exceed [`MAX_HEADER_BYTES`] (431).
async fn limit_headers(request: Request, next: Next) -> Response {
    let header_bytes: usize = request
        .headers()
        .iter()
        .map(|(name, value)| name.as_str().len() + value.len() + 4)
        .sum::<usize>()
        + request.uri().path_and_query().map_or(0, |target| target.as_str().len());
    if header_bytes > MAX_HEADER_BYTES {
        return ApiError::new(
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            format!("the request's target and headers take {header_bytes} bytes; at most {MAX_HEADER_BYTES}"),
        )
        .into_response();
    }
    next.run(request).await
}

/// Every request that changes something (any method but GET, HEAD and OPTIONS) needs a
/// credential that may change something (not a viewer's), checked here before its body is read: an unauthenticated client cannot make
/// the server buffer a body (up to the body limit) just to be refused. The handlers check
/// again, with their own access.
async fn authorize_writes_first(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let reads = matches!(
        *request.method(),
        axum::http::Method::GET | axum::http::Method::HEAD | axum::http::Method::OPTIONS
    ) || is_zone_transform(request.uri().path());
    if !reads {
        // a credential that may change something (the handler checks what exactly)
        let may_change = state
            .tokens
            .principal(bearer(request.headers()))
            .is_some_and(|p| p.role != Role::Viewer);
        if !may_change {
            let refused = match bearer(request.headers()) {
                None => ApiError::new(StatusCode::UNAUTHORIZED, "changing something needs a bearer token"),
                Some(_) => ApiError::new(StatusCode::FORBIDDEN, "the token does not allow changing anything"),
            };
            return refused.into_response();
        }
    }
    next.run(request).await
}

/// Whether a path is `PUT /v2/zones/{zone_id}/transform`'s: a computation that changes
/// nothing, so a viewer's token may send it (its body is small).
fn is_zone_transform(path: &str) -> bool {
    path.strip_prefix("/v2/zones/")
        .and_then(|rest| rest.strip_suffix("/transform"))
        .is_some_and(|zone_id| !zone_id.is_empty() && !zone_id.contains('/'))
}

/// The first value of the query parameter `name` in a raw query string (percent-decoded).
pub(crate) fn query_value(query: Option<&str>, name: &str) -> Option<String> {
    url::form_urlencoded::parse(query?.as_bytes())
        .find(|(key, _)| key == name)
        .map(|(_, value)| value.into_owned())
}

/// Counts requests by route and status class, and logs failures.
async fn count_requests(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<axum::extract::MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = request.method().clone();
    let response = next.run(request).await;
    let status = response.status();
    let class = format!("{}xx", status.as_u16() / 100);
    state
        .pipeline
        .metrics()
        .http_requests
        .get_or_create(&vec![("route".into(), route.clone()), ("status".into(), class)])
        .inc();
    if status.is_server_error() {
        tracing::warn!(%method, %route, status = status.as_u16(), "request failed");
    }
    response
}

/// Shared state for the handlers' metrics access.
fn metrics(state: &AppState) -> &Metrics {
    state.pipeline.metrics()
}

/// An unknown path: 404 with an omlox `Error` object.
async fn unknown_route(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no route {}", uri.path()))
}

/// A known path with a method it does not take: 405 with an omlox `Error` object.
async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        format!("{} does not take {method}", uri.path()),
    )
}

/// The bearer token of a request, if any.
fn bearer(headers: &HeaderMap) -> Option<&str> {
    headers
        .get(axum::http::header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_absent_or_nil_id_is_assigned_and_any_other_kept() {
        for body in [json!({}), json!({"id": "00000000-0000-0000-0000-000000000000"})] {
            let mut value = body.clone();
            assign_id_if_unset(&mut value);
            let id = uuid::Uuid::parse_str(value["id"].as_str().unwrap()).unwrap();
            assert!(!id.is_nil(), "{body}");
        }
        for id in [
            json!("forklift-9"),
            json!("7c9e6679-7425-40de-944b-e07fc1f90ae7"),
            json!(7),
            json!(null),
            json!(""),
        ] {
            let mut value = json!({ "id": id.clone() });
            assign_id_if_unset(&mut value);
            assert_eq!(value["id"], id);
        }
    }
}
