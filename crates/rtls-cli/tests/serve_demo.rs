//! `rtls serve --demo`, the README's first command: the simulated mine feeds the server over
//! its own MQTT broker, the miners are tracked and counted per drift, the WebSocket streams
//! their locations, and SIGTERM stops it cleanly.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_demo_mine_is_tracked_counted_and_streamed() {
    let dir = common::temp_dir("serve", "demo");
    let served = common::serve(
        &["--demo", "--demo-miners", "120"],
        &dir.join("demo.db"),
        "demo-test-write-token",
        "demo-test-read-token",
    );
    let bound = &served.bound;
    let http = bound["http"].as_str().unwrap().to_string();
    let client = reqwest::Client::new();
    let get = |path: &str| {
        client
            .get(format!("http://{http}{path}"))
            .bearer_auth("demo-test-read-token")
            .send()
    };

    // the miners get tracked: most of the 120 within 20 s (a few may be inside the collapse)
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut tags = 0;
    while Instant::now() < deadline {
        tags = get("/api/v1/tags")
            .await
            .unwrap()
            .json::<serde_json::Value>()
            .await
            .unwrap()
            .as_array()
            .unwrap()
            .len();
        if tags >= 110 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    assert!(tags >= 110, "{tags} of 120 miners tracked");
    // zone entries are confirmed after the anti-flap delay: most miners are counted in a drift
    let mut counts = serde_json::Value::Null;
    let mut in_drifts = 0;
    while Instant::now() < deadline + Duration::from_secs(20) {
        counts = get("/api/v1/zones/head-counts").await.unwrap().json().await.unwrap();
        in_drifts = counts
            .as_object()
            .unwrap()
            .iter()
            .filter(|(zone, _)| zone.starts_with("drift-"))
            .map(|(_, n)| n.as_u64().unwrap())
            .sum();
        if in_drifts >= 90 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    assert!(in_drifts >= 90, "head counts {counts}");
    let metrics = get("/metrics").await.unwrap().text().await.unwrap();
    assert!(metrics.contains("rtls_tracker_errors_total 0"), "{metrics}");
    assert!(!metrics.contains("rtls_ingest_records_total 0\n"), "{metrics}");

    // the WebSocket streams locations of the mine's miners
    use futures_util::{SinkExt, StreamExt};
    let (mut socket, _) =
        tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token=demo-test-read-token"))
            .await
            .unwrap();
    socket
        .send(tokio_tungstenite::tungstenite::Message::Text(
            r#"{"event":"subscribe","topic":"location_updates"}"#.into(),
        ))
        .await
        .unwrap();
    let mut miners = std::collections::HashSet::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while miners.len() < 20 && Instant::now() < deadline {
        let Ok(Some(Ok(tokio_tungstenite::tungstenite::Message::Text(text)))) =
            tokio::time::timeout(Duration::from_secs(5), socket.next()).await
        else {
            continue;
        };
        let message: serde_json::Value = serde_json::from_str(&text).unwrap();
        for location in message["payload"].as_array().into_iter().flatten() {
            miners.insert(location["provider_id"].as_str().unwrap().to_string());
        }
    }
    assert!(
        miners.len() >= 20 && miners.iter().all(|m| m.starts_with("miner-")),
        "{miners:?}"
    );

    let mut child = served.child;
    let pid = child.0.id().to_string();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.0.try_wait().unwrap() {
            break status;
        }
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "no exit 20 s after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}");
    std::fs::remove_dir_all(&dir).unwrap();
}
