//! Operations: `/health`, `/metrics` (Prometheus), `/openapi.json`.

use std::time::Duration;

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};

use super::{metrics, AppState};

/// The OpenAPI 3 description of this server's API (ours; the omlox paths follow the hub API).
pub const OPENAPI: &str = include_str!("../../openapi.json");

/// `GET /health`: 200 when the store answers a cheap query (the restart checkpoint) within
/// 2 s, else 503; with the live tag count.
pub(super) async fn health(State(state): State<AppState>) -> Response {
    let store = tokio::time::timeout(
        Duration::from_secs(2),
        state.query(|store| store.checkpoint(crate::pipeline::CHECKPOINT)),
    )
    .await;
    let (status, store_state, records) = match store {
        Ok(Ok(checkpoint)) => (StatusCode::OK, "ok".to_string(), Some(checkpoint.unwrap_or(0))),
        Ok(Err(e)) => (StatusCode::SERVICE_UNAVAILABLE, e.message, None),
        Err(_) => (
            StatusCode::SERVICE_UNAVAILABLE,
            "the store did not answer within 2 s".into(),
            None,
        ),
    };
    let body = json!({
        "status": if status == StatusCode::OK { "ok" } else { "degraded" },
        "store": store_state,
        "tracked_record_id": records,
        "tags": state.pipeline.live().tag_count(),
        "uptime_s": state.started.elapsed().as_secs_f64(),
    });
    (status, Json(body)).into_response()
}

/// `GET /metrics`: the OpenMetrics text exposition.
pub(super) async fn metrics_text(State(state): State<AppState>) -> Response {
    let metrics = metrics(&state);
    metrics
        .tags
        .set(i64::try_from(state.pipeline.live().tag_count()).unwrap_or(i64::MAX));
    match metrics.encode() {
        Ok(text) => (
            [(
                header::CONTENT_TYPE,
                "application/openmetrics-text; version=1.0.0; charset=utf-8",
            )],
            text,
        )
            .into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

/// `GET /openapi.json`.
pub(super) async fn openapi() -> Response {
    match serde_json::from_str::<Value>(OPENAPI) {
        Ok(document) => Json(document).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("openapi.json: {e}")).into_response(),
    }
}
