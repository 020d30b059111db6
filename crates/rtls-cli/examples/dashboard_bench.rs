//! The dashboard's browser benchmark (a benchmark, not a timed test): how fast headless chromium
//! draws the live map with many tags.
//!
//! ```sh
//! cargo run --release -p rtls-cli --example dashboard_bench -- [TAGS] [HZ] [SECONDS]
//! ```
//! (defaults 10 000 tags, 10 Hz, 10 s; chromium from `RTLS_CHROMIUM` or `/usr/bin/chromium`).
//!
//! 1. Starts `rtls serve` in-process on a 200 m × 100 m hall (55 readers, a data clock so the
//!    tags keep their state), posts four fixes for each of TAGS tags and waits until
//!    `/api/v1/tags` lists them all.
//! 2. Opens the dashboard and reports when the first frame with tags was drawn, counted from
//!    navigation start and from the page's load event ("first live frame").
//! 3. Streams TAGS updates at HZ into the page for SECONDS through the page's own WebSocket
//!    message handler (`rtls.handleMessage`), each tick one batched `rtls:positions` message
//!    (the columnar topic the dashboard subscribes to) as the server sends it: the JSON text is generated before the run (20 distinct ticks,
//!    cycled), so the measured main thread does what it does live — `JSON.parse`, the state
//!    update, the canvas redraw. It reports animation frames per second, map redraws per
//!    second, the tick rate achieved and updates applied per second.
//!
//! The server's own rate is not in this figure (100 k records/s is beyond one `rtls serve` on
//! two cores today; issue 20): it measures the screen.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use headless_chrome::Tab;
use rtls_server::auth::Tokens;
use rtls_server::config::{MqttMode, ServerConfig};
use rtls_server::serve::{serve, ServeOptions};
use serde_json::Value;

#[path = "../tests/devtools/mod.rs"]
mod devtools;

const READ: &str = "bench-read-token";
const WRITE: &str = "bench-write-token";

fn site_toml() -> String {
    let mut text = String::from("name = \"benchmark hall (200 m × 100 m)\"\n");
    for i in 0..11 {
        for j in 0..5 {
            text.push_str(&format!(
                "[[readers]]\nid = \"R{i}-{j}\"\nposition_m = [{}.0, {}.0, 4.0]\ntechnology = \"uwb\"\n",
                20 * i,
                25 * j
            ));
        }
    }
    text.push_str(
        "[[zones]]\nid = \"dock\"\nname = \"Dock\"\nkind = \"hazard\"\n\
         shape = { type = \"polygon\", vertices_m = [[0.0, 0.0], [40.0, 0.0], [40.0, 20.0], [0.0, 20.0]] }\n\
         [tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n",
    );
    text
}

/// A tag's position on the hall at tick `k` (m): spread on a grid, circling slowly.
fn position(tag: usize, tags: usize, k: usize) -> (f64, f64) {
    let columns = (tags as f64).sqrt().ceil() as usize;
    let (i, j) = (tag % columns, tag / columns);
    let angle = 0.1 * k as f64 + tag as f64;
    (
        5.0 + 190.0 * i as f64 / columns as f64 + angle.cos(),
        5.0 + 90.0 * j as f64 / columns as f64 + angle.sin(),
    )
}

fn eval(tab: &Tab, expression: &str) -> Result<Value> {
    devtools::eval(tab, expression).map_err(|e| anyhow::anyhow!(e))
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |k: usize, default: usize| args.get(k).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (tags, hz, seconds) = (number(0, 10_000), number(1, 10), number(2, 10));
    let chromium = std::env::var_os("RTLS_CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    if !chromium.exists() {
        bail!(
            "no chromium at {} (apt-get install chromium, or set RTLS_CHROMIUM)",
            chromium.display()
        );
    }

    // 1. the server, its tags
    let dir = std::env::temp_dir().join(format!("rtls-dashboard-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let text = site_toml();
    let site = rtls_engine::site::Site::from_toml_str(&text, "bench-site.toml")?;
    let mut config = ServerConfig::default();
    config.server.http = "127.0.0.1:0".parse()?;
    config.server.db = format!("sqlite:{}", dir.join("bench.db").display());
    config.mqtt.mode = MqttMode::Off;
    config.pipeline.live_clock = false;
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let (bound_tx, bound_rx) = std::sync::mpsc::channel();
    let (stop, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = runtime.spawn(serve(
        ServeOptions {
            config,
            site,
            site_text: text,
            tokens: Tokens::new(WRITE, Some(READ.into())),
            trackables: Vec::new(),
            floor_plans: rtls_server::http::plans::FloorPlans::default(),
            feed: None,
        },
        move |bound| {
            let _ = bound_tx.send(bound);
        },
        async move {
            let _ = stop_rx.await;
        },
    ));
    let http = bound_rx
        .recv_timeout(Duration::from_secs(30))
        .context("the server starts")?
        .http;
    let now_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)?
        .as_secs_f64();
    let client = reqwest::Client::new();
    runtime.block_on(async {
        // four fixes a tag, 1 s apart, in time order over all tags: the data clock releases a
        // record once later ones pass the re-ordering window, and refuses one that comes late
        let lines: Vec<String> = (0..4)
            .flat_map(|k| (0..tags).map(move |tag| (k, tag)))
            .map(|(k, tag)| {
                let (x, y) = position(tag, tags, 0);
                let t = now_s - 3.0 + f64::from(k);
                format!(
                    "{{\"t\":{t},\"tag\":\"bench-{tag}\",\"kind\":\"fix\",\"position_m\":[{x},{y}],\
                     \"covariance_m2\":[0.25,0,0,0.25]}}\n"
                )
            })
            .collect();
        for chunk in lines.chunks(5_000) {
            let body: String = chunk.concat();
            let reply = client
                .post(format!("http://{http}/api/v1/measurements"))
                .bearer_auth(WRITE)
                .body(body)
                .send()
                .await?;
            if !reply.status().is_success() {
                bail!("posting the tags: {}", reply.status());
            }
        }
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            let listed: Vec<Value> = client
                .get(format!("http://{http}/api/v1/tags"))
                .bearer_auth(READ)
                .send()
                .await?
                .json()
                .await?;
            if listed.len() == tags {
                return Ok(());
            }
            if Instant::now() > deadline {
                bail!("only {} of {tags} tags tracked after 120 s", listed.len());
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    })?;

    // 2. the page's first live frame
    let browser = devtools::launch(chromium).map_err(|e| anyhow::anyhow!(e))?;
    let tab = browser.new_tab()?;
    tab.navigate_to(&format!("http://{http}/?token={READ}"))?
        .wait_until_navigated()?;
    let deadline = Instant::now() + Duration::from_secs(60);
    let first = loop {
        let value = eval(
            &tab,
            &format!(
                "window.rtls && window.rtls.liveTags.size === {tags} && window.rtls.map.firstTagFrameMs !== null \
                 ? {{ first: window.rtls.map.firstTagFrameMs, \
                     load: performance.getEntriesByType('navigation')[0].loadEventEnd }} : null"
            ),
        )?;
        if !value.is_null() {
            break value;
        }
        if Instant::now() > deadline {
            bail!("the page did not draw {tags} tags within 60 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let first_ms = first["first"].as_f64().unwrap_or(f64::NAN);
    let load_ms = first["load"].as_f64().unwrap_or(f64::NAN);

    // 3. the stream: pre-generated batched messages, parsed and drawn by the page's own code
    let ticks: Vec<String> = (0..20)
        .map(|k| {
            // the server's `rtls:positions` columns (millimetres, as ws.rs rounds them)
            let mm = |v: f64| (v * 1000.0).round() / 1000.0;
            let points: Vec<(f64, f64)> = (0..tags).map(|tag| position(tag, tags, k)).collect();
            let payload = serde_json::json!({
                "tag": (0..tags).map(|tag| format!("bench-{tag}")).collect::<Vec<_>>(),
                "t": vec![now_s + k as f64 * 0.1; tags],
                "x": points.iter().map(|p| mm(p.0)).collect::<Vec<_>>(),
                "y": points.iter().map(|p| mm(p.1)).collect::<Vec<_>>(),
                "z": vec![Value::Null; tags],
                "cxx": vec![0.25; tags],
                "cxy": vec![0.0; tags],
                "cyy": vec![0.25; tags],
                "status": vec!["confirmed"; tags],
                "predicted": vec![0; tags],
            });
            serde_json::json!({ "event": "message", "topic": "rtls:positions", "subscription_id": 1, "payload": [payload] })
                .to_string()
        })
        .collect();
    eval(
        &tab,
        &format!("window.benchTicks = {}; true", serde_json::to_string(&ticks)?),
    )?;
    let result = eval(
        &tab,
        &format!(
            "new Promise(resolve => {{ \
               const hz = {hz}, seconds = {seconds}, t0 = performance.now(), frames0 = window.rtls.map.frames; \
               let rafs = 0, ticks = 0, updates = 0, parseMs = 0, handleMs = 0, drawMs = 0; \
               const map = window.rtls.map, draw = map.draw.bind(map); \
               map.draw = () => {{ const d0 = performance.now(); draw(); drawMs += performance.now() - d0; }}; \
               const raf = () => {{ rafs += 1; if (performance.now() - t0 < seconds * 1000) requestAnimationFrame(raf); }}; \
               requestAnimationFrame(raf); \
               const tick = () => {{ \
                 const p0 = performance.now(); \
                 const message = JSON.parse(window.benchTicks[ticks % window.benchTicks.length]); \
                 const p1 = performance.now(); \
                 window.rtls.handleMessage('rtls:positions', message); \
                 parseMs += p1 - p0; handleMs += performance.now() - p1; \
                 updates += message.payload[0].tag.length; ticks += 1; \
                 const elapsed = performance.now() - t0; \
                 if (elapsed < seconds * 1000) setTimeout(tick, Math.max(0, ticks * 1000 / hz - elapsed)); \
                 else setTimeout(() => {{ const s = (performance.now() - t0) / 1000; \
                   const redraws = window.rtls.map.frames - frames0; \
                   resolve({{ fps: rafs / s, redraws: redraws / s, \
                             tick_hz: ticks / s, updates_per_s: updates / s, seconds: s, \
                             parse_ms: parseMs / ticks, handle_ms: handleMs / ticks, draw_ms: drawMs / redraws }}); }}, 100); \
               }}; \
               tick(); \
             }})"
        ),
    )?;
    println!(
        "dashboard benchmark: {tags} tags, {hz} Hz offered for {seconds} s in headless chromium ({} cores)",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    println!(
        "first live frame: {first_ms:.0} ms after navigation start, {:.0} ms after the load event",
        first_ms - load_ms
    );
    println!(
        "stream: {:.1} animation frames/s, {:.1} map redraws/s, {:.2} ticks/s achieved of {hz}, {:.0} updates/s applied",
        result["fps"].as_f64().unwrap_or(f64::NAN),
        result["redraws"].as_f64().unwrap_or(f64::NAN),
        result["tick_hz"].as_f64().unwrap_or(f64::NAN),
        result["updates_per_s"].as_f64().unwrap_or(f64::NAN),
    );
    println!(
        "where the time went (main thread, per tick or redraw): JSON.parse {:.1} ms, state update {:.1} ms, \
         canvas redraw {:.1} ms",
        result["parse_ms"].as_f64().unwrap_or(f64::NAN),
        result["handle_ms"].as_f64().unwrap_or(f64::NAN),
        result["draw_ms"].as_f64().unwrap_or(f64::NAN),
    );
    let _ = stop.send(());
    runtime
        .block_on(async { tokio::time::timeout(Duration::from_secs(30), server).await })??
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
