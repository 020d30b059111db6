//! What the control room's screen reads, over a served server on loopback: the columnar
//! `rtls:positions` WebSocket topic, the alarm for entering a hazard zone, the muster board's
//! check-in/check-out rule and a floor-plan image.

mod common;

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use rtls_engine::site::Site;
use rtls_server::config::MqttMode;
use rtls_server::http::plans::FloorPlans;
use rtls_server::serve::ServeOptions;
use serde_json::Value;
use tokio_tungstenite::tungstenite::Message;

use common::{get_json, poll_text, temp_dir, walk, READ, SITE, WRITE};

/// The test floor with a portal (x ∈ [0, 4] m) as the muster's entry zone and a floor plan.
fn site_text() -> String {
    format!(
        "{SITE}\n\
         [[floors]]\nid = \"ground\"\nz_range_m = [-10.0, 10.0]\n\
         plan = {{ image = \"plan.png\", bounds_m = [[0.0, 0.0], [30.0, 20.0]] }}\n\
         [[zones]]\nid = \"portal\"\nname = \"Portal\"\nkind = \"area-of-interest\"\n\
         shape = {{ type = \"box\", min_m = [0.0, 0.0, -10.0], max_m = [4.0, 20.0, 10.0] }}\n\
         [muster]\nentry_zone = \"portal\"\n"
    )
}

/// The eight bytes every PNG starts with, and a little more: enough for the server, which
/// does not decode images.
const PNG: &[u8] = b"\x89PNG\r\n\x1a\n0000IHDR";

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn next_json(socket: &mut Socket) -> Value {
    loop {
        let message = tokio::time::timeout(Duration::from_secs(20), socket.next())
            .await
            .expect("a message within 20 s");
        if let Some(Ok(Message::Text(text))) = message {
            return serde_json::from_str(&text).unwrap();
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn positions_alarms_muster_and_floor_plan_as_the_screen_reads_them() {
    let dir = temp_dir("control-room");
    std::fs::write(dir.join("plan.png"), PNG).unwrap();
    let text = site_text();
    let site = Site::from_toml_str(&text, "control-room.toml").unwrap();
    let floor_plans = FloorPlans::load(&site, &dir).unwrap();
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.pipeline.live_clock = false;
    // one partition: every tag's records advance the same data clock, so silent tags get lost
    config.pipeline.partitions = 1;
    let running = common::serve_on_loopback(ServeOptions {
        site,
        site_text: text,
        floor_plans,
        ..common::options(config)
    })
    .await;
    let http = running.bound.http;

    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token={READ}"))
        .await
        .unwrap();
    for topic in ["rtls:positions", "rtls:alarms"] {
        let request = format!(r#"{{"event":"subscribe","topic":"{topic}"}}"#);
        socket.send(Message::Text(request.into())).await.unwrap();
        assert_eq!(next_json(&mut socket).await["event"], "subscribed");
    }

    // three people at the portal at t = 100 s: `in` walks through the forklift lane (x 14–18 m
    // at 12–16 s) to x = 22 m; `gate` stays in the portal and goes quiet after 1 s (it left);
    // `stop` walks to x = 8 m and goes quiet after 6 s (missing on site)
    let mut lines: Vec<(f64, String)> = [("in", 20.0), ("gate", 1.0), ("stop", 6.0)]
        .iter()
        .flat_map(|(tag, seconds)| {
            walk(tag, 100.0, *seconds)
                .lines()
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .map(|line| {
            let t = serde_json::from_str::<Value>(&line).unwrap()["t"].as_f64().unwrap();
            (t, line)
        })
        .collect();
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    let body: String = lines.into_iter().map(|(_, line)| line + "\n").collect();
    let client = reqwest::Client::new();
    let reply = client
        .post(format!("http://{http}/api/v1/measurements"))
        .bearer_auth(WRITE)
        .body(body)
        .send()
        .await
        .unwrap();
    assert!(reply.status().is_success(), "{}", reply.status());

    // the columns: equal lengths, millimetres, the x–y covariance
    let (mut positions_of_in, mut entered) = (Vec::new(), None);
    while positions_of_in.len() < 3 || entered.is_none() {
        let message = next_json(&mut socket).await;
        match message["topic"].as_str() {
            Some("rtls:positions") => {
                let columns = &message["payload"][0];
                let n = columns["tag"].as_array().unwrap().len();
                for field in ["t", "x", "y", "z", "cxx", "cxy", "cyy", "status", "predicted"] {
                    assert_eq!(columns[field].as_array().map(Vec::len), Some(n), "{field}: {columns}");
                }
                for i in 0..n {
                    if columns["tag"][i] == "in" {
                        let x = columns["x"][i].as_f64().unwrap();
                        assert_eq!((x * 1000.0).round() / 1000.0, x, "millimetres: {x}");
                        assert!(columns["cxx"][i].as_f64().unwrap() > 0.0, "{columns}");
                        assert!(columns["z"][i].is_null(), "2-D tracks have no z");
                        positions_of_in.push(x);
                    }
                }
            }
            Some("rtls:alarms") => {
                for alarm in message["payload"].as_array().unwrap() {
                    // (`stop` may enter too: its coasting prediction walks on at 1 m/s)
                    if alarm["type"] == "zone-enter" && alarm["tag"] == "in" {
                        entered = Some(alarm.clone());
                    }
                }
            }
            _ => {}
        }
    }
    assert!(positions_of_in.windows(2).any(|w| w[1] > w[0]), "{positions_of_in:?}");
    let entered = entered.unwrap();
    assert_eq!(
        (
            entered["tag"].as_str(),
            entered["zone"].as_str(),
            entered["zone_kind"].as_str()
        ),
        (Some("in"), Some("forklift-lane"), Some("hazard")),
        "{entered}"
    );
    assert!(entered["alarm_id"].is_string(), "{entered}");
    // entering the portal (an area of interest) is no alarm
    let stored: Value = get_json(&client, http, "/api/v1/alarms").await;
    let zone_alarms: Vec<&Value> = stored
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["type"] == "zone-enter")
        .collect();
    assert!(
        zone_alarms.iter().all(|a| a["zone"] == "forklift-lane"),
        "{zone_alarms:?}"
    );

    // the muster board: in on site, stop missing, gate checked out at the portal
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let board = loop {
        let board: Value = get_json(&client, http, "/api/v1/muster").await;
        if board["counts"]["missing"] == 1 && board["counts"]["off-site"] == 1 {
            break board;
        }
        assert!(std::time::Instant::now() < deadline, "{board}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(board["configured"], true);
    assert_eq!(board["entry_zone"], "portal");
    assert_eq!(board["on_site_total"], 2, "{board}");
    let listed: Vec<(&str, &str)> = board["tags"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (t["tag"].as_str().unwrap(), t["status"].as_str().unwrap()))
        .collect();
    assert_eq!(listed, [("stop", "missing"), ("in", "on-site")], "{board}");

    // a lost tag's frozen position is stored once, not every output interval until deletion
    // (gate was lost near t = 111 s; the data clock ran on to 120 s)
    // (the output thread stores rows after the live state shows them: wait for the first)
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let (gate, lost_rows) = loop {
        let gate: Value = get_json(&client, http, "/api/v1/history?tag=gate").await;
        let lost_rows = gate
            .as_array()
            .unwrap()
            .iter()
            .filter(|state| state["status"] == "lost")
            .count();
        if lost_rows > 0 || std::time::Instant::now() > deadline {
            break (gate, lost_rows);
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(lost_rows, 1, "{gate}");

    // the columnar snapshot lists what /api/v1/tags lists, with the same positions
    let (snapshot, tags) = (
        get_json(&client, http, "/api/v1/positions").await,
        get_json(&client, http, "/api/v1/tags").await,
    );
    let listed: Vec<(String, f64)> = tags
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["tag"].as_str().unwrap().to_string(),
                t["position_m"][0].as_f64().unwrap(),
            )
        })
        .collect();
    let columns: Vec<(String, f64)> = (0..snapshot["tag"].as_array().unwrap().len())
        .map(|i| {
            (
                snapshot["tag"][i].as_str().unwrap().to_string(),
                snapshot["x"][i].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(columns.len(), 3, "{snapshot}");
    for (tag, x) in &listed {
        let column = columns
            .iter()
            .find(|(t, _)| t == tag)
            .unwrap_or_else(|| panic!("{tag} in {snapshot}"));
        assert!((column.1 - x).abs() <= 0.0005, "{tag}: {} vs {x}", column.1);
    }

    // the floor plan: listed with the site, served with its media type to readers only
    let site_view: Value = get_json(&client, http, "/api/v1/site").await;
    let plan = &site_view["floors"][0]["plan"];
    assert_eq!(
        plan["bounds_m"],
        serde_json::json!([[0.0, 0.0], [30.0, 20.0]]),
        "{site_view}"
    );
    let url = plan["url"].as_str().unwrap();
    let image = client
        .get(format!("http://{http}{url}"))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap();
    assert_eq!(image.headers()["content-type"], "image/png");
    assert_eq!(image.bytes().await.unwrap().as_ref(), PNG);
    let anonymous = client.get(format!("http://{http}{url}")).send().await.unwrap();
    assert_eq!(anonymous.status(), reqwest::StatusCode::UNAUTHORIZED);
    let none = client
        .get(format!("http://{http}/api/v1/site/floors/attic/plan"))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap();
    assert_eq!(none.status(), reqwest::StatusCode::NOT_FOUND);

    running.stop().await;
}

/// A record that arrives after later ones of its tag (a second request, 3 s of data late) with
/// the site rewinding: it is re-filtered, and the updates it revises are stored and counted as
/// revisions.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_record_is_refiltered_and_its_revisions_flagged() {
    let dir = temp_dir("late-record");
    let text = SITE.replace(
        "reorder_window_s = 0.2",
        "reorder_window_s = 0.0\nrewind_horizon_s = 5.0",
    );
    let site = Site::from_toml_str(&text, "late-record.toml").unwrap();
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.pipeline.live_clock = false;
    let running = common::serve_on_loopback(ServeOptions {
        site,
        site_text: text,
        ..common::options(config)
    })
    .await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    // a walk at 2 Hz for 6 s; its fix at t = 103 s is held back and sent after the rest
    let (late, in_time): (Vec<&str>, Vec<&str>) = walk("late", 100.0, 6.0)
        .leak()
        .lines()
        .partition(|line| serde_json::from_str::<Value>(line).unwrap()["t"].as_f64() == Some(103.0));
    assert_eq!(late.len(), 1);
    for body in [in_time.join("\n"), late.join("\n")] {
        let reply = common::post_measurements(&client, http, body).await;
        assert!(reply.status().is_success(), "{}", reply.status());
    }
    let revised_count = |metrics: &str| common::metric_value(metrics, "rtls_track_updates_revised_total");
    let metrics = poll_text(&client, http, "/metrics", |m| revised_count(m) > 0.0).await;
    // the updates from 103 s to the walk's end (103.5–106 s) are revised
    assert!(revised_count(&metrics) >= 1.0, "revisions counted: {metrics}");
    // stored by the output thread, after publication
    let history = poll_text(
        &client,
        http,
        "/api/v1/history?tag=late&from=0&to=200&format=json",
        |h| h.contains("\"revised\""),
    )
    .await;
    assert!(history.contains("\"revised\""), "a stored revision: {history}");
    let events = get_json(&client, http, "/api/v1/events?type=late").await;
    assert_eq!(
        events.as_array().map(Vec::len),
        Some(0),
        "nothing reported late: {events}"
    );
    running.stop().await;
}

/// Compaction in `rtls serve`: with `compact_after_s = 1` the states and the tracked records
/// are packed into blocks (counted by `rtls_store_compacted_total`), and the history still
/// answers with every state, its keys and its position (to the block's 1 mm).
#[tokio::test]
async fn old_states_and_records_are_compacted_and_still_read() {
    let dir = temp_dir("compaction");
    let site = Site::from_toml_str(SITE, "compaction.toml").unwrap();
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.server.compact_after_s = 1.0;
    config.pipeline.live_clock = false;
    let running = common::serve_on_loopback(ServeOptions {
        site,
        site_text: SITE.into(),
        ..common::options(config)
    })
    .await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    let reply = common::post_measurements(&client, http, walk("packed", 100.0, 5.0)).await;
    assert!(reply.status().is_success(), "{}", reply.status());
    let history_path = "/api/v1/history?tag=packed&from=0&to=200&format=json";
    let states_before = poll_text(&client, http, history_path, |h| h.matches("\"t\"").count() >= 10).await;
    let stored = states_before.matches("\"t\"").count();
    assert!(stored >= 10, "the walk's states are stored: {states_before}");
    let compacted = |metrics: &str, kind: &str| {
        common::metric_value(metrics, &format!("rtls_store_compacted_total{{kind=\"{kind}\"}}"))
    };
    // the walk's 11 records and every stored state, a pass or two after they are 1 s old
    let metrics = poll_text(&client, http, "/metrics", |m| {
        compacted(m, "states") >= stored as f64 && compacted(m, "records") >= 11.0
    })
    .await;
    assert!(
        compacted(&metrics, "states") >= stored as f64 && compacted(&metrics, "records") >= 11.0,
        "packed: {metrics}"
    );
    let history = get_json(&client, http, history_path).await;
    let states = history.as_array().expect("an array of states");
    assert!(states.len() >= stored, "every state still read: {history}");
    let on_the_mm_grid = |state: &&Value| {
        let x = state["x"].as_f64().unwrap_or(f64::NAN);
        x == (x * 1000.0).round() / 1000.0
    };
    assert!(
        states.iter().filter(on_the_mm_grid).count() >= stored,
        "the packed states are read from their blocks (positions to the mm): {history}"
    );
    for state in states {
        for key in ["cov", "predicted", "source", "status", "t", "tag", "vx", "vy", "x", "y"] {
            assert!(state.get(key).is_some(), "{key} in {state}");
        }
        // the walk is at x = 2 + (t − 100) m, y = 10 m
        let t = state["t"].as_f64().unwrap();
        let x = state["x"].as_f64().unwrap();
        assert!(
            (x - (2.0 + t - 100.0)).abs() < 0.5 && (state["y"].as_f64().unwrap() - 10.0).abs() < 0.5,
            "{state}"
        );
    }
    running.stop().await;
}
