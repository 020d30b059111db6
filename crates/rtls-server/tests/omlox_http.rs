//! An integrator's omlox session against `rtls serve` on a loopback port (real HTTP): a zone is
//! made into a fence the running trackers watch, a trackable walks into it and is found
//! inside it with its motion, the fences are deleted — and after a restart the stored zone is
//! still there and the deleted fences stay deleted.

mod common;

use std::time::Duration;

use common::{walk, READ, WRITE};
use rtls_server::config::{MqttMode, ServerConfig};
use serde_json::{json, Value};

async fn start(db: &std::path::Path) -> common::Running {
    let mut config = ServerConfig::default();
    config.server.db = format!("sqlite:{}", db.display());
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.mqtt.mode = MqttMode::Off;
    config.pipeline.live_clock = false;
    common::serve_on_loopback(common::options(config)).await
}

async fn send(request: reqwest::RequestBuilder) -> (u16, Value) {
    let reply = request.send().await.unwrap();
    let status = reply.status().as_u16();
    let text = reply.text().await.unwrap();
    (status, serde_json::from_str(&text).unwrap_or(Value::Null))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_zone_made_into_a_fence_is_watched_live_and_the_changes_survive_a_restart() {
    let db = common::temp_dir("omlox-http").join("rtls.db");
    let running = start(&db).await;
    let base = format!("http://{}/v2", running.bound.http);
    let client = reqwest::Client::new();

    // a zone whose ground control points outline x ∈ [4, 9] m, y ∈ [8, 12] m (the site has no
    // georeference: their [x, y] are site metres)
    let points = [[4.0, 8.0], [9.0, 8.0], [9.0, 12.0], [4.0, 12.0]]
        .iter()
        .enumerate()
        .flat_map(|(k, xy)| [json!([8.0 + 1e-4 * k as f64, 47.0 + 1e-4 * (k % 3) as f64]), json!(xy)])
        .collect::<Vec<_>>();
    let zone = json!({"type": "uwb", "name": "Bay 1", "ground_control_points": points});
    let (status, zone) = send(client.post(format!("{base}/zones")).bearer_auth(WRITE).json(&zone)).await;
    assert_eq!(status, 201, "{zone}");
    let zone_id = zone["id"].as_str().unwrap().to_string();
    let (status, fence) = send(
        client
            .get(format!("{base}/zones/{zone_id}/createfence"))
            .bearer_auth(WRITE),
    )
    .await;
    assert_eq!(status, 200, "{fence}");
    let fence_id = fence["id"].as_str().unwrap().to_string();

    let trackable = json!({"type": "omlox", "name": "Cart 5", "location_providers": ["miner-5"]});
    let (status, trackable) = send(
        client
            .post(format!("{base}/trackables"))
            .bearer_auth(WRITE)
            .json(&trackable),
    )
    .await;
    assert_eq!(status, 201, "{trackable}");
    let trackable_id = trackable["id"].as_str().unwrap().to_string();
    // miner-5 walks along y = 10 m from x = 2 m to x = 8 m at 1 m/s: into the new fence
    let reply = client
        .post(format!("http://{}/api/v1/measurements", running.bound.http))
        .bearer_auth(WRITE)
        .body(walk("miner-5", 3000.0, 6.0))
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 200);

    // the running trackers' entries (not geometry alone) put the trackable inside the fence
    let mut inside = Value::Null;
    for _ in 0..250 {
        let (_, trackables) = send(
            client
                .get(format!("{base}/fences/{fence_id}/trackables"))
                .bearer_auth(READ),
        )
        .await;
        inside = trackables;
        if inside.as_array().is_some_and(|a| !a.is_empty()) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(40)).await;
    }
    assert_eq!(inside[0]["id"], trackable_id.as_str(), "{inside}");
    let (status, fences) = send(
        client
            .get(format!("{base}/trackables/{trackable_id}/fences"))
            .bearer_auth(READ),
    )
    .await;
    assert_eq!(
        (status, fences[0]["id"].as_str()),
        (200, Some(fence_id.as_str())),
        "{fences}"
    );
    let (status, motion) = send(
        client
            .get(format!("{base}/trackables/{trackable_id}/motion"))
            .bearer_auth(READ),
    )
    .await;
    assert_eq!(status, 200, "{motion}");
    let speed = motion["location"]["speed"].as_f64().unwrap();
    assert!((speed - 1.0).abs() < 0.25, "{motion}");

    // all fences deleted: gone from the trackers' view too
    let (status, _) = send(client.delete(format!("{base}/fences")).bearer_auth(WRITE)).await;
    assert_eq!(status, 204);
    let (status, error) = send(
        client
            .get(format!("{base}/fences/{fence_id}/trackables"))
            .bearer_auth(READ),
    )
    .await;
    assert_eq!((status, error["code"].as_u64()), (404, Some(404)), "{error}");
    running.stop().await;

    // a restart: the stored zone is back, the empty fence set too
    let running = start(&db).await;
    let base = format!("http://{}/v2", running.bound.http);
    let (status, zones) = send(client.get(format!("{base}/zones")).bearer_auth(READ)).await;
    assert_eq!(status, 200);
    assert!(zones.as_array().unwrap().contains(&json!(zone_id)), "{zones}");
    let (_, fences) = send(client.get(format!("{base}/fences")).bearer_auth(READ)).await;
    assert_eq!(fences, json!([]));
    running.stop().await;
}
