//! Credentials at run time (admin only): `POST /api/v1/tokens` issues a token with a role and
//! shows its secret once; `GET /api/v1/tokens` lists them (never a secret); `DELETE
//! /api/v1/tokens/{id}` revokes one at once, for HTTP and MQTT alike. The store keeps only each
//! token's SHA-256 (configuration kind `token`), and a restart loads them again. Every issue
//! and revocation goes to the audit log.

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

use super::{parse_json, ApiError, ApiResult, AppState};
use crate::auth::{Access, IssuedToken, Role};
use crate::pipeline::unix_ms;

/// The store's configuration kind of issued tokens.
pub const TOKEN_CONFIG: &str = "token";

/// Longest token name, characters.
const MAX_NAME_CHARS: usize = 64;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct IssueBody {
    name: String,
    role: Role,
}

/// `POST /api/v1/tokens` `{"name": "dispatcher-3", "role": "operator"}` (admin): 201 with
/// `{id, name, role, issued_ms, token}` — the secret, shown this once.
pub(super) async fn issue(State(state): State<AppState>, headers: HeaderMap, body: Bytes) -> ApiResult<Response> {
    let who = state.authorize(&headers, Access::Admin)?;
    let body: IssueBody = parse_json(&body)?;
    let name = body.name.trim().to_string();
    if name.is_empty() || name.chars().count() > MAX_NAME_CHARS || name.chars().any(char::is_control) {
        return Err(ApiError::field(
            "name",
            format!("1 to {MAX_NAME_CHARS} characters, no control characters"),
        ));
    }
    let (secret, record) = state.tokens.issue(&name, body.role, unix_ms());
    let stored =
        serde_json::to_string(&record).map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    let id = record.id.clone();
    if let Err(e) = state
        .query(move |store| store.put_config(TOKEN_CONFIG, &id, &stored))
        .await
    {
        // not stored: not issued
        state.tokens.revoke(&record.id);
        return Err(e);
    }
    state
        .audit(
            &who,
            "token-issued",
            &format!("{} ({}, {})", record.name, record.role.name(), record.id),
        )
        .await;
    let mut answer = listed(&record);
    answer["token"] = Value::String(secret);
    Ok((StatusCode::CREATED, Json(answer)).into_response())
}

/// `GET /api/v1/tokens` (admin): the issued tokens, oldest first, without secrets.
pub(super) async fn list(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Admin)?;
    let mut issued = state.tokens.issued();
    issued.sort_by_key(|t| t.issued_ms);
    Ok(Json(Value::Array(issued.iter().map(listed).collect())))
}

/// `DELETE /api/v1/tokens/{id}` (admin): 204 — the token stops working at once — or 404.
pub(super) async fn revoke(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> ApiResult<StatusCode> {
    let who = state.authorize(&headers, Access::Admin)?;
    let Some(token) = state.tokens.issued().into_iter().find(|t| t.id == id) else {
        return Err(ApiError::not_found(format!("no token {id}")));
    };
    state.tokens.revoke(&id);
    let key = id.clone();
    state
        .query(move |store| store.delete_config(TOKEN_CONFIG, &key))
        .await?;
    state
        .audit(
            &who,
            "token-revoked",
            &format!("{} ({}, {id})", token.name, token.role.name()),
        )
        .await;
    Ok(StatusCode::NO_CONTENT)
}

fn listed(token: &IssuedToken) -> Value {
    json!({
        "id": token.id,
        "name": token.name,
        "role": token.role,
        "issued_ms": token.issued_ms,
    })
}
