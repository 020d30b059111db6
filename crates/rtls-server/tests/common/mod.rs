//! Shared by the server's integration tests: a small site, a state on a fresh SQLite file,
//! records of a tag walking through a hazard zone.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use rtls_engine::site::Site;
use rtls_server::auth::Tokens;
use rtls_server::http::{AppState, QueryStore};
use rtls_server::metrics::Metrics;
use rtls_server::pipeline::{Pipeline, PipelineConfig};
use rtls_server::store::{self, SqliteSync, Store};
use serde_json::Value;
use tower::ServiceExt;

/// A georeferenced site frame (Zürich), for the tests of WGS-84 conversions.
pub const FRAME: rtls_engine::site::FrameSettings = rtls_engine::site::FrameSettings {
    origin: rtls_engine::site::GeodeticOrigin {
        latitude_deg: 47.3769,
        longitude_deg: 8.5417,
        height_m: 455.0,
    },
    x_axis_bearing_deg: 90.0,
};

pub const WRITE: &str = "write-token-0123";
pub const READ: &str = "read-token-4567";

/// Four UWB anchors on a 30 × 20 m floor and a hazard zone x ∈ [14, 18] m.
pub const SITE: &str = r#"
name = "test floor"
[[readers]]
id = "A1"
position_m = [0.0, 0.0, 2.5]
technology = "uwb"
[[readers]]
id = "A2"
position_m = [30.0, 0.0, 2.5]
technology = "uwb"
[[readers]]
id = "A3"
position_m = [30.0, 20.0, 2.5]
technology = "uwb"
[[readers]]
id = "A4"
position_m = [0.0, 20.0, 2.5]
technology = "uwb"
[[zones]]
id = "forklift-lane"
name = "Forklift lane"
kind = "hazard"
shape = { type = "box", min_m = [14.0, 0.0, -10.0], max_m = [18.0, 20.0, 10.0] }
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "ekf"
gate_probability = 0.999
acceleration_noise_std_mps2 = 0.5
initiation = { confirm_updates = 2, within_s = 5.0 }
coast_timeout_s = 10.0
delete_timeout_s = 300.0
reorder_window_s = 0.2
dimensions = 2
"#;

pub fn site() -> Site {
    Site::from_toml_str(SITE, "test-site.toml").expect("test site")
}

/// A fresh directory under the system's temp dir.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtls-server-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// The SQLite file of [`state`]`(name)`, to open a second connection on it.
pub fn db_path(name: &str) -> PathBuf {
    std::env::temp_dir()
        .join(format!("rtls-server-{name}-{}", std::process::id()))
        .join("rtls.db")
}

pub fn open_sqlite(path: &std::path::Path) -> Box<dyn Store> {
    store::open(&format!("sqlite:{}", path.display()), SqliteSync::Normal).expect("sqlite")
}

/// A state over a fresh SQLite file, with the test site, a data clock (no wall clock).
pub fn state(name: &str) -> AppState {
    temp_dir(name);
    state_on(
        name,
        PipelineConfig {
            partitions: 2,
            live_clock: false,
            ..PipelineConfig::default()
        },
    )
}

/// A state with the test site and `config` over the SQLite file of `name` as it is (a fresh
/// one unless an earlier state of `name` wrote it: a restart).
pub fn state_on(name: &str, config: PipelineConfig) -> AppState {
    state_on_site(name, site(), config)
}

/// As [`state_on`], on `site`.
pub fn state_on_site(name: &str, site: Site, config: PipelineConfig) -> AppState {
    std::fs::create_dir_all(db_path(name).parent().expect("dir")).expect("temp dir");
    let path = db_path(name);
    let pipeline = Pipeline::start(
        &site,
        open_sqlite(&path),
        open_sqlite(&path),
        config,
        Arc::new(Metrics::new()),
    )
    .expect("pipeline");
    AppState {
        pipeline,
        queries: Arc::new(Mutex::new(QueryStore::new(open_sqlite(&path)))),
        tokens: Arc::new(Tokens::new(WRITE, Some(READ.into()))),
        site: Arc::new(site),
        default_accuracy_m: 0.5,
        started: Instant::now(),
        floor_plans: Arc::default(),
    }
}

/// JSON lines: `tag` walks along y = 10 m from x = 2 m at 1 m/s, one fix per 0.5 s, from
/// `t0_s` for `seconds` s (it crosses the hazard zone x ∈ [14, 18] m between 12 and 16 s).
pub fn walk(tag: &str, t0_s: f64, seconds: f64) -> String {
    let mut lines = String::new();
    let mut k = 0;
    loop {
        let t = 0.5 * f64::from(k);
        if t > seconds {
            break;
        }
        lines.push_str(&format!(
            "{{\"t\": {}, \"tag\": \"{tag}\", \"kind\": \"fix\", \"position_m\": [{}, 10.0], \"covariance_m2\": [0.04, 0.0, 0.0, 0.04]}}\n",
            t0_s + t,
            2.0 + t
        ));
        k += 1;
    }
    lines
}

/// A router on `site` (clock from the records, 2 partitions) over which
/// `walk("walker", 3000.0, 6.0)` was tracked to the last fix the trackers take, 3005.5 s at
/// x = 7.5 m (the reorder window holds back the one at 3006 s, since no later record comes), so
/// the walker's location stays put from then on: the state and the router.
pub async fn walked_on_site(name: &str, site: Site) -> (AppState, axum::Router) {
    let config = PipelineConfig {
        partitions: 2,
        live_clock: false,
        ..PipelineConfig::default()
    };
    let state = state_on_site(name, site, config);
    let app = rtls_server::http::router(state.clone());
    let walked = walk("walker", 3000.0, 6.0);
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &walked).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let live = || state.pipeline.live().tag("walker").map(|t| t.time_s);
    let done = eventually(Duration::from_secs(10), || live().is_some_and(|t| t >= 3005.5)).await;
    assert!(done, "the walk is tracked to its last fix: {:?}", live());
    (state, app)
}

/// Polls `condition` every 20 ms for up to `timeout`.
pub async fn eventually(timeout: Duration, mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    condition()
}

/// `rtls serve` running in this test's runtime on loopback ports.
pub struct Running {
    /// Where it listens.
    pub bound: rtls_server::serve::Bound,
    stop: tokio::sync::oneshot::Sender<()>,
    task: tokio::task::JoinHandle<Result<(), rtls_server::serve::ServeError>>,
}

/// Options for [`serve_on_loopback`]: `config` (its addresses should be `127.0.0.1:0`), the
/// test site, the test tokens, no trackables, floor plans or feed.
pub fn options(config: rtls_server::config::ServerConfig) -> rtls_server::serve::ServeOptions {
    rtls_server::serve::ServeOptions {
        config,
        site: site(),
        site_text: SITE.into(),
        tokens: Tokens::new(WRITE, Some(READ.into())),
        trackables: Vec::new(),
        floor_plans: rtls_server::http::plans::FloorPlans::default(),
        feed: None,
    }
}

/// Starts `rtls serve` with `options` and waits (≤ 20 s) until it listens.
pub async fn serve_on_loopback(options: rtls_server::serve::ServeOptions) -> Running {
    let (bound_tx, bound_rx) = tokio::sync::oneshot::channel();
    let (stop, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(rtls_server::serve::serve(
        options,
        move |b| {
            let _ = bound_tx.send(b);
        },
        async move {
            let _ = stop_rx.await;
        },
    ));
    let bound = tokio::time::timeout(Duration::from_secs(20), bound_rx)
        .await
        .expect("server starts")
        .unwrap();
    Running { bound, stop, task }
}

impl Running {
    /// Stops the server gracefully (≤ 30 s) and returns how long the stop took.
    pub async fn stop(self) -> Duration {
        let started = Instant::now();
        self.stop.send(()).unwrap();
        tokio::time::timeout(Duration::from_secs(30), self.task)
            .await
            .expect("graceful stop")
            .unwrap()
            .unwrap();
        started.elapsed()
    }
}

/// POSTs measurement lines to `/api/v1/measurements` with the write token.
pub async fn post_measurements(
    client: &reqwest::Client,
    http: std::net::SocketAddr,
    lines: String,
) -> reqwest::Response {
    client
        .post(format!("http://{http}/api/v1/measurements"))
        .bearer_auth(WRITE)
        .body(lines)
        .send()
        .await
        .unwrap()
}

/// The value of one series (`name` or `name{labels}`) in a `/metrics` text; 0 when absent.
pub fn metric_value(metrics: &str, series: &str) -> f64 {
    metrics
        .lines()
        .find_map(|line| line.strip_prefix(series)?.strip_prefix(' '))
        .and_then(|value| value.trim().parse().ok())
        .unwrap_or(0.0)
}

/// A response read in full.
pub struct Reply {
    pub status: StatusCode,
    pub content_type: String,
    pub body: Vec<u8>,
}

impl Reply {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", self.text()))
    }
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// `POST path` of `body` with the write token through the router: asserts 201 Created and
/// gives the created object.
pub async fn post_created(app: &axum::Router, path: &str, body: &Value) -> Value {
    let reply = call(app, Method::POST, path, Some(WRITE), &body.to_string()).await;
    assert_eq!(reply.status, StatusCode::CREATED, "POST {path}: {}", reply.text());
    reply.json()
}

/// An omlox Location as another system pushes it: `provider`'s position `[x, y]` (site
/// metres) at `t` (Unix s), source `other-rtls`, accuracy 0.3 m.
pub fn pushed_location(provider: &str, [x, y]: [f64; 2], t: f64) -> Value {
    let stamp = rtls_server::omlox::time::format_timestamp(t, "t").unwrap();
    serde_json::json!({"position": {"type": "Point", "coordinates": [x, y]}, "source": "other-rtls",
                       "provider_type": "uwb", "provider_id": provider, "timestamp_generated": stamp,
                       "accuracy": 0.3})
}

/// Polls the async `condition` every 100 ms until it gives `Some` or `timeout` passes.
pub async fn eventually_some<T, F>(timeout: Duration, mut condition: impl FnMut() -> F) -> Option<T>
where
    F: std::future::Future<Output = Option<T>>,
{
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(found) = condition().await {
            return Some(found);
        }
        if Instant::now() >= deadline {
            return None;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// One request through the router, without a port (`tower::ServiceExt::oneshot`).
pub async fn call(app: &axum::Router, method: Method, uri: &str, token: Option<&str>, body: &str) -> Reply {
    let mut request = Request::builder().method(method).uri(uri);
    if let Some(token) = token {
        request = request.header("authorization", format!("Bearer {token}"));
    }
    let response = app
        .clone()
        .oneshot(request.body(Body::from(body.to_string())).unwrap())
        .await
        .unwrap();
    let status = response.status();
    let content_type = response
        .headers()
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let body = axum::body::to_bytes(response.into_body(), usize::MAX)
        .await
        .unwrap()
        .to_vec();
    Reply {
        status,
        content_type,
        body,
    }
}

/// `GET uri` through the router with the read token: asserts 200 and gives the JSON.
pub async fn call_json(app: &axum::Router, uri: &str) -> Value {
    let reply = call(app, Method::GET, uri, Some(READ), "").await;
    assert_eq!(reply.status, StatusCode::OK, "GET {uri}: {}", reply.text());
    reply.json()
}

/// Asserts an omlox `Error` object (`type`, `code`, `message`) with `status`; gives its
/// `field`, if any.
pub fn assert_omlox_error(reply: &Reply, status: StatusCode, what: &str) -> Option<String> {
    assert_eq!(reply.status, status, "{what}: {}", reply.text());
    let error = reply.json();
    assert_eq!(error["code"], status.as_u16(), "{what}: {error}");
    assert!(
        error["type"].is_string() && error["message"].is_string(),
        "{what}: {error}"
    );
    error["field"].as_str().map(str::to_string)
}

/// `GET path` with the read token, as JSON.
pub async fn get_json(client: &reqwest::Client, http: std::net::SocketAddr, path: &str) -> Value {
    let reply = client
        .get(format!("http://{http}{path}"))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap();
    reply.json().await.unwrap()
}

/// `GET path` with the read token, as text, every 100 ms until `done` holds of it or 20 s
/// have passed; the last answer.
pub async fn poll_text(
    client: &reqwest::Client,
    http: std::net::SocketAddr,
    path: &str,
    done: impl Fn(&str) -> bool,
) -> String {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    loop {
        let text = client
            .get(format!("http://{http}{path}"))
            .bearer_auth(READ)
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        if done(&text) || std::time::Instant::now() > deadline {
            return text;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// `GET path` with the read token, as text.
pub async fn get_text(client: &reqwest::Client, http: std::net::SocketAddr, path: &str) -> String {
    poll_text(client, http, path, |_| true).await
}

/// A server configuration on loopback ports of its own (`127.0.0.1:0`), SQLite in `dir`, MQTT
/// as `mqtt`; everything else the default.
pub fn loopback_config(
    dir: &std::path::Path,
    mqtt: rtls_server::config::MqttMode,
) -> rtls_server::config::ServerConfig {
    let mut config = rtls_server::config::ServerConfig::default();
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    config.mqtt.mode = mqtt;
    config.mqtt.listen = "127.0.0.1:0".parse().unwrap();
    config
}

/// The stored zone of the frame tests, turned 90° from the site's frame and shifted: its
/// `[u, v]` of site metres `[x, y]`.
pub fn zone_of(site: [f64; 2]) -> [f64; 2] {
    [2.0 - site[1], site[0] - 5.0]
}

/// Site metres of a turned-zone position (the inverse of [`zone_of`]).
pub fn site_of(zone: [f64; 2]) -> [f64; 2] {
    [5.0 + zone[1], 2.0 - zone[0]]
}

/// `[longitude, latitude]` of site metres through [`FRAME`].
pub fn lon_lat(site: [f64; 2]) -> [f64; 2] {
    let [lon, lat, _] = FRAME.wgs84_of([site[0], site[1], 0.0]).unwrap();
    [lon, lat]
}

/// The turned zone's body: four ground control points of its `[u, v]` and their WGS-84
/// places.
pub fn turned_zone() -> Value {
    let points: Vec<[f64; 2]> = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]]
        .into_iter()
        .flat_map(|uv| [lon_lat(site_of(uv)), uv])
        .collect();
    serde_json::json!({"type": "uwb", "name": "turned", "ground_control_points": points})
}
