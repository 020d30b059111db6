//! The control-room dashboard: its static files (embedded in the binary) at `/` and `/ui/…`,
//! and the JSON it draws the site from (`/api/v1/site`), reader health (`/api/v1/readers`) and
//! who is inside each zone (`/api/v1/zones/occupants`).
//!
//! The page itself holds no data, so it is served without a token; it asks for the read token
//! (and, to acknowledge alarms, the write token) and sends it with every API call, as any client
//! must. Assets are `include_bytes!` of `crates/rtls-server/assets/` — a handful of files, so a
//! static table (no embedding crate); the vendored browser libraries and how to refresh them are
//! in `assets/vendor/README.md`.

use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};

use super::{ApiError, ApiResult, AppState};
use crate::auth::Access;
use crate::pipeline::unix_ms;

/// One embedded file: its path under `/ui/`, content type and bytes.
struct Asset {
    path: &'static str,
    content_type: &'static str,
    bytes: &'static [u8],
}

macro_rules! asset {
    ($path:literal, $content_type:literal) => {
        Asset {
            path: $path,
            content_type: $content_type,
            bytes: include_bytes!(concat!("../../assets/", $path)),
        }
    };
}

/// Every file the dashboard loads.
const ASSETS: &[Asset] = &[
    asset!("dashboard/index.html", "text/html; charset=utf-8"),
    asset!("dashboard/app.js", "text/javascript; charset=utf-8"),
    asset!("dashboard/map.js", "text/javascript; charset=utf-8"),
    asset!("dashboard/panels.js", "text/javascript; charset=utf-8"),
    asset!("dashboard/app.css", "text/css; charset=utf-8"),
    asset!("vendor/leaflet/leaflet.js", "text/javascript; charset=utf-8"),
    asset!("vendor/leaflet/leaflet.css", "text/css; charset=utf-8"),
    asset!("vendor/leaflet/LICENSE", "text/plain; charset=utf-8"),
    asset!("vendor/leaflet/VERSION", "text/plain; charset=utf-8"),
];

fn serve_asset(path: &str) -> Response {
    match ASSETS.iter().find(|asset| asset.path == path) {
        Some(asset) => (
            [
                (header::CONTENT_TYPE, asset.content_type),
                // the files change with the binary only; revalidate so an upgrade shows at once
                (header::CACHE_CONTROL, "no-cache"),
                (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            ],
            asset.bytes,
        )
            .into_response(),
        None => ApiError::new(StatusCode::NOT_FOUND, format!("no file /ui/{path}")).into_response(),
    }
}

/// `GET /`: the dashboard.
pub(super) async fn index() -> Response {
    serve_asset("dashboard/index.html")
}

/// `GET /ui/{*path}`: the dashboard's scripts, styles and vendored libraries.
pub(super) async fn ui_file(Path(path): Path<String>) -> Response {
    serve_asset(&path)
}

/// `GET /api/v1/site`: what the map is drawn from — the site's name, frame origin, readers,
/// floors, corridors and the bounding box of all of them (m). Zones come from
/// `/api/v1/zones.geojson`.
pub(super) async fn site(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let site = &state.site;
    let mut bounds = Bounds::default();
    let readers: Vec<Value> = site
        .readers
        .iter()
        .map(|r| {
            bounds.add(&r.position_m);
            json!({ "id": r.id, "position_m": r.position_m, "working": r.working })
        })
        .collect();
    let corridors: Vec<Value> = site
        .corridors
        .iter()
        .map(|c| {
            c.points_m.iter().for_each(|p| bounds.add(p));
            json!({ "id": c.id, "points_m": c.points_m, "half_width_m": c.half_width_m })
        })
        .collect();
    for zone in &site.zones {
        match &zone.shape {
            rtls_engine::zones::Shape::Polygon { vertices_m, .. } => vertices_m.iter().for_each(|v| bounds.add(v)),
            rtls_engine::zones::Shape::Box { min_m, max_m } => {
                bounds.add(min_m);
                bounds.add(max_m);
            }
        }
    }
    let floors: Vec<Value> = site
        .floors
        .iter()
        .map(|f| {
            let plan = state
                .floor_plans
                .get(&f.id)
                .and(f.plan.as_ref())
                .map(|plan| json!({ "url": super::plans::plan_url(&f.id), "bounds_m": plan.bounds_m }));
            json!({ "id": f.id, "z_range_m": f.z_range_m, "plan": plan })
        })
        .collect();
    let origin = site.frame.map(|f| {
        json!({
            "latitude_deg": f.origin.latitude_deg,
            "longitude_deg": f.origin.longitude_deg,
            "height_m": f.origin.height_m,
            "x_axis_bearing_deg": f.x_axis_bearing_deg,
        })
    });
    Ok(Json(json!({
        "name": site.name,
        "origin": origin,
        "bounds_m": bounds.finish(),
        "readers": readers,
        "floors": floors,
        "corridors": corridors,
    })))
}

/// `GET /api/v1/readers`: each reader's health — last heard, records per second, and whether
/// it has gone silent ([`crate::pipeline::ReaderHealth`]).
pub(super) async fn readers(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let health = state.pipeline.readers().health(unix_ms());
    serde_json::to_value(health)
        .map(Json)
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))
}

/// `GET /api/v1/zones/occupants`: the tags inside each zone now (confirmed entries), sorted.
pub(super) async fn occupants(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    Ok(Json(json!(state.pipeline.live().occupants())))
}

/// The x–y bounding box of what the site lists, m.
#[derive(Debug, Default)]
struct Bounds {
    min: Option<[f64; 2]>,
    max: Option<[f64; 2]>,
}

impl Bounds {
    fn add(&mut self, point: &[f64]) {
        let (Some(&x), Some(&y)) = (point.first(), point.get(1)) else {
            return;
        };
        let min = self.min.get_or_insert([x, y]);
        *min = [min[0].min(x), min[1].min(y)];
        let max = self.max.get_or_insert([x, y]);
        *max = [max[0].max(x), max[1].max(y)];
    }

    fn finish(self) -> Value {
        match (self.min, self.max) {
            (Some(min), Some(max)) => json!({ "min": min, "max": max }),
            _ => Value::Null,
        }
    }
}
