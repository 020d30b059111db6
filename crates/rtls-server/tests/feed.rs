//! A live feed (`rtls_server::feed`) on a running server, with a tiny local record source in
//! place of the binary's simulated mine: its records reach the trackers over the embedded MQTT
//! broker with the write token, and through the pipeline's sink when MQTT is off; the source is
//! asked for records up to the wall clock.

mod common;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use rtls_engine::record::{parse_json_line, Record};
use rtls_server::config::{MqttMode, ServerConfig};
use rtls_server::feed::{self, FeedIdentity};
use rtls_server::pipeline::unix_s;
use rtls_server::serve::{Bound, Feed, ServeOptions};
use serde_json::Value;

use common::{walk, READ, WRITE};

/// A source that returns a 20 s walk through the test floor on its first call and nothing
/// after, noting the times it was asked for.
fn walk_source(asked: Arc<Mutex<Vec<f64>>>) -> impl FnMut(f64) -> Vec<Record> + Send + 'static {
    let mut records: Vec<Record> = walk("feed-tag", 5000.0, 20.0)
        .lines()
        .enumerate()
        .map(|(i, line)| parse_json_line(line, "walk", i + 1).unwrap())
        .collect();
    move |up_to_s| {
        asked.lock().unwrap().push(up_to_s);
        std::mem::take(&mut records)
    }
}

/// Serves the test site with the walk as its feed; returns the final position of `feed-tag`
/// and the times the source was asked for.
async fn run(mqtt: MqttMode) -> (Bound, f64, Vec<f64>) {
    let dir = common::temp_dir(&format!("feed-{mqtt:?}"));
    let mut config = ServerConfig::default();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.mqtt.listen = "127.0.0.1:0".parse().unwrap();
    config.mqtt.mode = mqtt;
    config.pipeline.live_clock = false;
    let asked = Arc::new(Mutex::new(Vec::new()));
    let source = walk_source(Arc::clone(&asked));
    let start: Feed = Box::new(move |pipeline, bound, stop| {
        let identity = FeedIdentity {
            name: "test-feed".into(),
            client_id: "rtls-test-feed".into(),
            topic: "rtls/v1/measurements/test-feed".into(),
            write_token: WRITE.into(),
        };
        feed::start(identity, source, pipeline, bound, stop)
    });
    let running = common::serve_on_loopback(ServeOptions {
        feed: Some(start),
        ..common::options(config)
    })
    .await;
    let bound = running.bound.clone();
    let client = reqwest::Client::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let mut last_x = 0.0;
    while std::time::Instant::now() < deadline {
        let tags: Value = client
            .get(format!("http://{}/api/v1/tags", bound.http))
            .bearer_auth(READ)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if let Some(tag) = tags.as_array().unwrap().iter().find(|t| t["tag"] == "feed-tag") {
            last_x = tag["position_m"][0].as_f64().unwrap();
            // the walk ends at x ≈ 20 m
            if last_x > 19.0 {
                break;
            }
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    running.stop().await;
    let asked = asked.lock().unwrap().clone();
    (bound, last_x, asked)
}

/// The source is asked up to the wall clock, never ahead of it, ten times a second.
fn assert_asked_up_to_the_clock(asked: &[f64]) {
    assert!(!asked.is_empty(), "the source was asked for records");
    let now = unix_s();
    for pair in asked.windows(2) {
        assert!(pair[1] > pair[0], "times move forward: {asked:?}");
        assert!(
            pair[1] - pair[0] < 0.5,
            "asked every 100 ms, not every second: {asked:?}"
        );
    }
    for &t in asked {
        assert!(t <= now && t > now - 120.0, "asked up to {t}, now {now}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_feed_publishes_over_the_embedded_broker() {
    let (bound, last_x, asked) = run(MqttMode::Embedded).await;
    assert!(bound.mqtt.is_some());
    assert!(last_x > 19.0, "feed-tag tracked to x = {last_x} m");
    assert_asked_up_to_the_clock(&asked);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_feed_without_mqtt_goes_through_the_sink() {
    let (bound, last_x, asked) = run(MqttMode::Off).await;
    assert!(bound.mqtt.is_none());
    assert!(last_x > 19.0, "feed-tag tracked to x = {last_x} m");
    assert_asked_up_to_the_clock(&asked);
}
