//! The alarm console's API: recent alarms with their acknowledgement, and acknowledging one.
//!
//! Every alarm (predicted hazard, no coverage, lost tag) carries a stable `alarm_id`
//! ([`crate::convert::alarm_id`]) on the WebSocket (`rtls:alarms`), in MQTT and in the stored
//! events. An operator acknowledges it with the write token; the acknowledgement (who, when) is
//! stored, appended to the event history as `alarm-acknowledged`, and broadcast on
//! `rtls:alarms` so every open screen shows it.

use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, StatusCode};
use axum::Json;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use super::api::{parse_limit, parse_time};
use super::{parse_json, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::omlox::time::format_timestamp;
use crate::omlox::ws::Topic;
use crate::pipeline::{unix_ms, HubMessage};
use crate::store::{EventQuery, EventRow};

/// The configuration kind acknowledgements are stored under (`put_config`).
const ACK_KIND: &str = "alarm-ack";

/// The longest `by` accepted, characters.
const MAX_BY_CHARS: usize = 200;

/// An acknowledgement as stored and returned.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Acknowledgement {
    /// The alarm.
    pub alarm_id: String,
    /// Who acknowledged it (as the operator typed it).
    pub by: String,
    /// When, RFC 3339 (server clock).
    pub at: String,
}

/// Body of `POST /api/v1/alarms/{alarm_id}/acknowledge` (optional).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AcknowledgeBody {
    by: Option<String>,
}

/// Query of `GET /api/v1/alarms`.
#[derive(Debug, Deserialize)]
pub(super) struct AlarmParams {
    from: Option<String>,
    to: Option<String>,
    tag: Option<String>,
    limit: Option<usize>,
}

/// `GET /api/v1/alarms?from=…&to=…&tag=…&limit=…`: stored alarms, newest first, each the
/// event's JSON plus `acknowledged` (`{by, at}` or null).
pub(super) async fn list(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<AlarmParams>,
) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let limit = parse_limit(params.limit)?;
    let query = EventQuery {
        from_s: parse_time(params.from.as_deref(), "from", f64::MIN)?,
        to_s: parse_time(params.to.as_deref(), "to", f64::MAX)?,
        tag: params.tag.filter(|t| !t.is_empty()),
        alarms_only: true,
        limit,
        newest_first: true,
        ..EventQuery::default()
    };
    // each listed alarm's acknowledgement, looked up by its id (not every one ever stored)
    let alarms = state
        .query(move |store| {
            let mut alarms = Vec::new();
            for row in store.events(&query)? {
                let Ok(mut alarm) = serde_json::from_str::<Value>(&row.json) else {
                    continue;
                };
                let ack = match alarm["alarm_id"].as_str() {
                    Some(id) => store.get_config(ACK_KIND, id)?,
                    None => None,
                };
                let ack = ack
                    .and_then(|json| serde_json::from_str(&json).ok())
                    .unwrap_or(Value::Null);
                if let Some(object) = alarm.as_object_mut() {
                    object.insert("acknowledged".into(), ack);
                    alarms.push(alarm);
                }
            }
            Ok(alarms)
        })
        .await?;
    Ok(Json(Value::Array(alarms)))
}

/// `POST /api/v1/alarms/{alarm_id}/acknowledge` with an operator's (or admin's) token and optionally
/// `{"by": "operator name"}`: 200 with the acknowledgement (the first one, when it was
/// acknowledged before); 404 for an id that is not a known alarm.
pub(super) async fn acknowledge(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(alarm_id): Path<String>,
    body: Bytes,
) -> ApiResult<Json<Acknowledgement>> {
    let who = state.authorize(&headers, Access::Operate)?;
    let body: AcknowledgeBody = if body.iter().all(u8::is_ascii_whitespace) {
        AcknowledgeBody::default()
    } else {
        parse_json(&body)?
    };
    let by = body.by.map(|b| b.trim().to_string()).filter(|b| !b.is_empty());
    if by
        .as_ref()
        .is_some_and(|b| b.chars().count() > MAX_BY_CHARS || b.chars().any(char::is_control))
    {
        return Err(ApiError::field(
            "by",
            format!("at most {MAX_BY_CHARS} characters, no control characters"),
        ));
    }
    let alarm = match state.pipeline.live().recent_alarm(&alarm_id) {
        Some(alarm) => alarm,
        None => {
            let wanted = alarm_id.clone();
            // older than the live state keeps: the newest stored alarms, up to the row cap
            let query = EventQuery {
                from_s: f64::MIN,
                to_s: f64::MAX,
                alarms_only: true,
                limit: super::api::MAX_ROWS,
                newest_first: true,
                ..EventQuery::default()
            };
            state
                .query(move |store| {
                    Ok(store.events(&query)?.into_iter().find_map(|row| {
                        let alarm: Value = serde_json::from_str(&row.json).ok()?;
                        (alarm["alarm_id"].as_str() == Some(wanted.as_str())).then_some(alarm)
                    }))
                })
                .await?
                .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("no alarm {alarm_id}")))?
        }
    };
    let now_ms = unix_ms();
    let acknowledgement = Acknowledgement {
        alarm_id: alarm_id.clone(),
        by: by.unwrap_or_else(|| "operator".into()),
        at: format_timestamp(now_ms as f64 / 1000.0, "at")
            .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?,
    };
    let stored = serde_json::to_string(&acknowledgement)
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    let event = json!({
        "type": "alarm-acknowledged",
        "t": now_ms as f64 / 1000.0,
        "tag": alarm["tag"],
        "alarm_id": alarm_id,
        "alarm_type": alarm["type"],
        "by": acknowledgement.by,
        "timestamp": acknowledgement.at,
        // the credential that did it (the audit trail; `by` is what the operator typed)
        "credential": who.name,
        "role": who.role.name(),
    });
    let row = EventRow {
        received_ms: now_ms,
        time_s: now_ms as f64 / 1000.0,
        kind: "alarm-acknowledged".into(),
        tag: alarm["tag"].as_str().map(String::from),
        zone: alarm["zone"].as_str().map(String::from),
        alarm: false,
        json: event.to_string(),
    };
    let id = alarm_id.clone();
    let first = state
        .query(move |store| {
            // the first acknowledgement wins; a second one answers with it
            if let Some(existing) = store.get_config(ACK_KIND, &id)? {
                return Ok(Some(existing));
            }
            store.put_config(ACK_KIND, &id, &stored)?;
            store.append_events(&[row])?;
            Ok(None)
        })
        .await?;
    if let Some(existing) = first {
        return serde_json::from_str(&existing)
            .map(Json)
            .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()));
    }
    state.pipeline.broadcast(HubMessage::Extension {
        topic: Topic::RtlsAlarms,
        event,
    });
    Ok(Json(acknowledgement))
}
