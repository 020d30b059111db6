//! Our own API under `/api/v1`: measurement ingest, live tags, history and events with CSV and
//! GeoJSON export, head counts, zones as GeoJSON.

use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

use super::{metrics, ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::convert::{fence_from_zone, wgs84_geometry};
use crate::omlox::crs::Crs;
use crate::omlox::time::{format_timestamp, parse_timestamp};
use crate::store::{EventQuery, HistoryQuery, LocationRow};

/// Rows a history or event query returns at most (and by default).
pub const MAX_ROWS: usize = 100_000;

/// `POST /api/v1/measurements`: JSON lines of the measurement format (docs/FORMATS.md);
/// 200 `{"accepted": n}` once stored, 400 naming the line and field of the first bad record.
pub(super) async fn ingest_measurements(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Write)?;
    match state.pipeline.submit_lines("request body", &body).await {
        Ok(accepted) => Ok(Json(json!({ "accepted": accepted }))),
        Err(error) => Err(refused_over_http(&state, error)),
    }
}

/// An ingest error as the HTTP answer; a refused payload (a client error) is counted in
/// `rtls_ingest_rejected_total{transport="http"}`.
pub(super) fn refused_over_http(state: &AppState, error: crate::sink::IngestError) -> ApiError {
    if matches!(error, crate::sink::IngestError::Invalid(_)) {
        metrics(state)
            .ingest_rejected
            .get_or_create(&vec![("transport".into(), "http".into())])
            .inc();
    }
    error.into()
}

/// `GET /api/v1/tags`: every tag's latest state, with its omlox `Location` (covariance in its
/// `properties`).
pub(super) async fn tags(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let tags: Vec<Value> = state
        .pipeline
        .live()
        .tags()
        .into_iter()
        .map(|(tag, s)| {
            json!({ "tag": tag, "t": s.time_s, "position_m": s.position_m, "status": s.status, "location": *s.location })
        })
        .collect();
    Ok(Json(Value::Array(tags)))
}

/// `GET /api/v1/tracks.geojson?crs=…`: every tag's latest position as a GeoJSON
/// FeatureCollection of Points (WGS-84 when the site is georeferenced, else site metres; see
/// [`GeoParams`]).
pub(super) async fn tracks_geojson(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<GeoParams>,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let frame = export_frame(&state, params.crs.as_deref())?;
    let features: Vec<Value> = state
        .pipeline
        .live()
        .tags()
        .into_iter()
        .map(|(tag, s)| {
            json!({
                "type": "Feature",
                "geometry": { "type": "Point", "coordinates": s.position_m },
                "properties": { "tag": tag, "t": s.time_s, "status": s.status },
            })
        })
        .collect();
    Ok(geojson(
        json!({ "type": "FeatureCollection", "features": features }),
        frame,
    ))
}

/// `GET /api/v1/zones.geojson?crs=…`: the site's zones as a FeatureCollection of Polygons
/// (frames as [`GeoParams`]).
pub(super) async fn zones_geojson(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<GeoParams>,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let frame = export_frame(&state, params.crs.as_deref())?;
    let counts = state.pipeline.live().head_counts();
    let zones = state.pipeline.live().zones();
    let features: Vec<Value> = zones
        .iter()
        .map(|zone| {
            let fence = fence_from_zone(zone);
            let mut properties = json!({ "id": zone.id, "name": zone.name, "head_count": counts.get(&zone.id) });
            if let (Value::Object(target), Some(extra)) = (&mut properties, fence.properties) {
                target.extend(extra);
            }
            json!({ "type": "Feature", "geometry": fence.region, "properties": properties })
        })
        .collect();
    Ok(geojson(
        json!({ "type": "FeatureCollection", "features": features }),
        frame,
    ))
}

/// `GET /api/v1/zones/head-counts`: tags inside each zone now.
pub(super) async fn head_counts(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(json!(state.pipeline.live().head_counts())))
}

/// Query of the GeoJSON exports: `crs=local` (site metres) or `crs=EPSG:4326` (`wgs84`).
#[derive(Debug, Default, Deserialize)]
pub(super) struct GeoParams {
    crs: Option<String>,
}

/// The frame a GeoJSON export is written in: WGS-84 (RFC 7946) by default when the site has a
/// `[frame] origin`, local metres otherwise or with `crs=local`.
fn export_frame<'a>(state: &'a AppState, crs: Option<&str>) -> ApiResult<Option<&'a rtls_engine::site::FrameSettings>> {
    if crs.is_none() {
        return Ok(state.site.frame.as_ref());
    }
    match Crs::parse(crs).map_err(|reason| ApiError::field("crs", reason))? {
        Crs::Local => Ok(None),
        Crs::Wgs84 => state
            .site
            .frame
            .as_ref()
            .map(Some)
            .ok_or_else(|| ApiError::field("crs", "the site has no [frame] origin, so only crs=local is available")),
    }
}

/// A FeatureCollection as `application/geo+json`, each feature's geometry in `frame`'s WGS-84
/// when given (RFC 7946: longitude, latitude), else in site metres.
fn geojson(mut body: Value, frame: Option<&rtls_engine::site::FrameSettings>) -> Response {
    if frame.is_some() {
        if let Some(features) = body["features"].as_array_mut() {
            for feature in features {
                feature["geometry"] = wgs84_geometry(frame, &feature["geometry"]);
            }
        }
    }
    ([(header::CONTENT_TYPE, "application/geo+json")], body.to_string()).into_response()
}

/// Query of `GET /api/v1/history`.
#[derive(Debug, Deserialize)]
pub(super) struct HistoryParams {
    tag: Option<String>,
    from: Option<String>,
    to: Option<String>,
    format: Option<String>,
    limit: Option<usize>,
    crs: Option<String>,
}

/// A time parameter: Unix seconds or an RFC 3339 time stamp.
pub(super) fn parse_time(value: Option<&str>, field: &str, default: f64) -> ApiResult<f64> {
    let Some(text) = value else { return Ok(default) };
    if let Ok(seconds) = text.parse::<f64>() {
        if seconds.is_finite() {
            return Ok(seconds);
        }
    }
    parse_timestamp(text, field).map_err(|_| {
        ApiError::field(
            field,
            format!("`{text}` is neither Unix seconds nor an RFC 3339 time stamp"),
        )
    })
}

pub(super) fn parse_limit(limit: Option<usize>) -> ApiResult<usize> {
    match limit {
        None => Ok(MAX_ROWS),
        Some(0) => Err(ApiError::field("limit", "must be at least 1")),
        Some(n) if n > MAX_ROWS => Err(ApiError::field("limit", format!("at most {MAX_ROWS}"))),
        Some(n) => Ok(n),
    }
}

/// `GET /api/v1/history?tag=…&from=…&to=…&format=json|csv|geojson&limit=…`: one tag's track
/// states in a time range, oldest first; without `tag` (then `from` and `to` are required) every
/// tag's, for a replay. `from`/`to` are Unix seconds or RFC 3339.
pub(super) async fn history(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<HistoryParams>,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let tag = params.tag.filter(|t| !t.is_empty());
    if tag.is_none() && (params.from.is_none() || params.to.is_none()) {
        return Err(ApiError::field(
            "tag",
            "required unless both `from` and `to` are given (a replay of every tag in a range)",
        ));
    }
    let from_s = parse_time(params.from.as_deref(), "from", f64::MIN)?;
    let to_s = parse_time(params.to.as_deref(), "to", f64::MAX)?;
    if from_s > to_s {
        return Err(ApiError::field("to", "must not be before `from`"));
    }
    let limit = parse_limit(params.limit)?;
    let format = params.format.unwrap_or_else(|| "json".into());
    if !matches!(format.as_str(), "json" | "csv" | "geojson") {
        return Err(ApiError::field(
            "format",
            format!("`{format}` is not one of json, csv, geojson"),
        ));
    }
    let query = HistoryQuery {
        tag: tag.clone(),
        from_s,
        to_s,
        limit,
    };
    let rows = state.query(move |store| store.history(&query)).await?;
    Ok(match format.as_str() {
        "csv" => ([(header::CONTENT_TYPE, "text/csv")], history_csv(&rows)?).into_response(),
        "geojson" => geojson(history_geojson(&rows), export_frame(&state, params.crs.as_deref())?),
        _ => {
            let states: Vec<Value> = rows.iter().filter_map(|r| serde_json::from_str(&r.json).ok()).collect();
            Json(Value::Array(states)).into_response()
        }
    })
}

/// History as CSV (the `csv` crate quotes as RFC 4180 needs):
/// `t,timestamp,tag,x_m,y_m,z_m,accuracy_m,predicted`.
fn history_csv(rows: &[LocationRow]) -> ApiResult<String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let failed = |e: csv::Error| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, format!("writing CSV: {e}"));
    writer
        .write_record(["t", "timestamp", "tag", "x_m", "y_m", "z_m", "accuracy_m", "predicted"])
        .map_err(failed)?;
    let optional = |v: Option<f64>| v.map_or_else(String::new, |v| v.to_string());
    for row in rows {
        writer
            .write_record([
                row.time_s.to_string(),
                format_timestamp(row.time_s, "t").unwrap_or_default(),
                row.tag.clone(),
                row.x_m.to_string(),
                row.y_m.to_string(),
                optional(row.z_m),
                optional(row.accuracy_m),
                row.predicted.to_string(),
            ])
            .map_err(failed)?;
    }
    let bytes = writer.into_inner().map_err(|e| failed(e.into_error().into()))?;
    String::from_utf8(bytes).map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))
}

/// History as GeoJSON: per tag, a LineString of its path, then one Point per state.
fn history_geojson(rows: &[LocationRow]) -> Value {
    let coordinates = |r: &LocationRow| match r.z_m {
        Some(z) => json!([r.x_m, r.y_m, z]),
        None => json!([r.x_m, r.y_m]),
    };
    let mut paths: std::collections::BTreeMap<&str, Vec<&LocationRow>> = std::collections::BTreeMap::new();
    for row in rows {
        paths.entry(row.tag.as_str()).or_default().push(row);
    }
    let mut features: Vec<Value> = paths
        .iter()
        .map(|(tag, path)| {
            json!({
                "type": "Feature",
                "geometry": { "type": "LineString", "coordinates": path.iter().map(|r| coordinates(r)).collect::<Vec<_>>() },
                "properties": { "tag": tag, "from": path.first().map(|r| r.time_s), "to": path.last().map(|r| r.time_s) },
            })
        })
        .collect();
    features.extend(rows.iter().map(|r| {
        json!({
            "type": "Feature",
            "geometry": { "type": "Point", "coordinates": coordinates(r) },
            "properties": { "tag": r.tag, "t": r.time_s, "accuracy_m": r.accuracy_m, "predicted": r.predicted },
        })
    }));
    json!({ "type": "FeatureCollection", "features": features })
}

/// Query of `GET /api/v1/events`.
#[derive(Debug, Deserialize)]
pub(super) struct EventParams {
    from: Option<String>,
    to: Option<String>,
    tag: Option<String>,
    #[serde(rename = "type")]
    kinds: Option<String>,
    alarms: Option<bool>,
    limit: Option<usize>,
}

/// `GET /api/v1/events?from=…&to=…&tag=…&type=a,b&alarms=true&limit=…`: stored events and
/// alarms, oldest first.
pub(super) async fn events(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<EventParams>,
) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let query = EventQuery {
        from_s: parse_time(params.from.as_deref(), "from", f64::MIN)?,
        to_s: parse_time(params.to.as_deref(), "to", f64::MAX)?,
        tag: params.tag.filter(|t| !t.is_empty()),
        kinds: params
            .kinds
            .map(|k| {
                k.split(',')
                    .map(str::trim)
                    .filter(|k| !k.is_empty())
                    .map(String::from)
                    .collect()
            })
            .unwrap_or_default(),
        alarms_only: params.alarms.unwrap_or(false),
        limit: parse_limit(params.limit)?,
        newest_first: false,
    };
    let rows = state.query(move |store| store.events(&query)).await?;
    let events: Vec<Value> = rows.iter().filter_map(|r| serde_json::from_str(&r.json).ok()).collect();
    Ok(Json(Value::Array(events)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_csv_quotes_a_tag_with_a_comma_or_quote_and_reads_back() {
        let row = |tag: &str| LocationRow {
            received_ms: 0,
            time_s: 12.5,
            tag: tag.into(),
            x_m: 1.0,
            y_m: 2.0,
            z_m: None,
            accuracy_m: Some(0.3),
            predicted: true,
            json: String::new(),
        };
        let text = history_csv(&[row("crew 4, \"north\""), row("plain")]).unwrap();
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let tags: Vec<String> = reader.records().map(|r| r.unwrap()[2].to_string()).collect();
        assert_eq!(tags, ["crew 4, \"north\"", "plain"]);
        assert!(
            text.lines().nth(1).unwrap().contains("\"crew 4, \"\"north\"\"\""),
            "{text}"
        );
        assert!(text.lines().nth(2).unwrap().ends_with(",1,2,,0.3,true"), "{text}");
    }
}
