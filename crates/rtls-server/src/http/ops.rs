//! Operations: `/health`, `/metrics` (Prometheus), `/openapi.json`, `/api/v1/quarantine`.

use std::time::Duration;

use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};

use super::{metrics, Access, ApiError, ApiResult, AppState};

/// The OpenAPI 3 description of this server's API (ours; the omlox paths follow the hub API).
pub const OPENAPI: &str = include_str!("../../openapi.json");

/// `GET /health`: 200 when the store answers a cheap query (the restart checkpoint) within
/// 2 s and no tag partition is stalled (`[pipeline]`'s stall time, 10 s), else 503 saying
/// which; with the live tag count and each partition's seconds since it last came round.
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
    let partitions = state.pipeline.partition_health();
    let status = if partitions.iter().any(|p| p.stalled) {
        StatusCode::SERVICE_UNAVAILABLE
    } else {
        status
    };
    let cluster = state.pipeline.cluster_status().map(|(node, owned)| {
        json!({
            "node": node,
            "owned_partitions": owned,
        })
    });
    let body = json!({
        "status": if status == StatusCode::OK { "ok" } else { "degraded" },
        "cluster": cluster,
        "store": store_state,
        "partitions": partitions.iter().enumerate().map(|(index, p)| json!({
            "partition": index,
            "silent_s": (p.silent_s * 10.0).round() / 10.0,
            "stalled": p.stalled,
        })).collect::<Vec<_>>(),
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

/// `GET /api/v1/quarantine`: the records a partition's tracker failed on (an error or a panic),
/// oldest first — `record_id`, `partition`, `tag`, `reason`, `quarantined_ms` and the `record`
/// itself — kept apart and skipped by the replay after a restart.
pub(super) async fn quarantine(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let rows = state
        .query(|store| store.list_config(crate::pipeline::QUARANTINE))
        .await?;
    let entries: Vec<Value> = rows
        .into_iter()
        .map(|(id, json)| {
            serde_json::from_str(&json).map_err(|e| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("quarantined record `{id}` is corrupt: {e}"),
                )
            })
        })
        .collect::<ApiResult<_>>()?;
    Ok(Json(json!({ "quarantined": entries })))
}
