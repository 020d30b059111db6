//! `[[nats_forward]]` against a real `nats-server` on loopback (`RTLS_TEST_NATS_SERVER`, the
//! binary; without it the tests print a notice and pass): a walk posted over REST arrives on
//! `rtls.positions.{tag}` as omlox Locations and its hazard alarm on
//! `rtls.events.hazard-predicted`; a NATS server that is down at the start blocks neither the
//! start nor the pipeline, and the forward delivers once it is up.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use rtls_server::config::{MqttMode, NatsForwardSection};
use serde_json::Value;

use common::{loopback_config, metric_value, poll_text, post_measurements, temp_dir, walk};

/// A `nats-server` child process, killed when dropped.
struct NatsServer {
    child: Child,
    url: String,
}

impl Drop for NatsServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The `nats-server` binary, or `None` after saying why.
fn binary() -> Option<String> {
    match std::env::var("RTLS_TEST_NATS_SERVER") {
        Ok(binary) if !binary.is_empty() => Some(binary),
        _ => {
            eprintln!("skipped: RTLS_TEST_NATS_SERVER (the nats-server binary) is needed (.ci/services)");
            None
        }
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Starts `nats-server` on 127.0.0.1:`port` and waits (≤ 10 s) until a client connects.
async fn nats_server(binary: &str, port: u16) -> (NatsServer, async_nats::Client) {
    let child = Command::new(binary)
        .args(["-a", "127.0.0.1", "-p", &port.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("nats-server starts");
    let server = NatsServer {
        child,
        url: format!("nats://127.0.0.1:{port}"),
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        match async_nats::connect(&server.url).await {
            Ok(client) => return (server, client),
            Err(e) if Instant::now() > deadline => panic!("nats-server on {port} did not come up: {e}"),
            Err(_) => tokio::time::sleep(Duration::from_millis(50)).await,
        }
    }
}

/// The next message of `subscriber` as JSON, within `timeout`.
async fn next_json(subscriber: &mut async_nats::Subscriber, timeout: Duration) -> Option<(String, Value)> {
    let message = tokio::time::timeout(timeout, subscriber.next()).await.ok()??;
    let json = serde_json::from_slice(&message.payload).expect("a JSON payload");
    Some((message.subject.to_string(), json))
}

/// A server (data clock, one partition, no MQTT) forwarding everything to `url` as `bus`.
async fn start(name: &str, url: &str) -> common::Running {
    let dir = temp_dir(name);
    let mut config = loopback_config(&dir, MqttMode::Off);
    config.pipeline.partitions = 1;
    config.pipeline.live_clock = false;
    config.nats_forward = vec![NatsForwardSection {
        url: url.to_string(),
        name: Some("bus".into()),
        ..NatsForwardSection::default()
    }];
    config.validate().unwrap();
    common::serve_on_loopback(common::options(config)).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn positions_and_alarms_reach_their_subjects() {
    let Some(binary) = binary() else { return };
    let (nats, client) = nats_server(&binary, free_port()).await;
    let mut positions = client.subscribe("rtls.positions.miner-7").await.unwrap();
    let mut alarms = client.subscribe("rtls.events.hazard-predicted").await.unwrap();
    client.flush().await.unwrap();
    let running = start("nats-forward", &nats.url).await;
    let http = running.bound.http;
    let web = reqwest::Client::new();

    // a tag walking at 1 m/s towards the hazard zone x ∈ [14, 18] m, through it and out
    let reply = post_measurements(&web, http, walk("miner-7", 5000.0, 20.0)).await;
    assert_eq!(reply.status(), 200);

    // its track updates, as the omlox Locations of the WebSocket's location_updates
    let (subject, location) = next_json(&mut positions, Duration::from_secs(20))
        .await
        .expect("a position on rtls.positions.miner-7");
    assert_eq!(subject, "rtls.positions.miner-7");
    assert_eq!(location["provider_id"], "miner-7", "{location}");
    assert_eq!(location["position"]["type"], "Point", "{location}");
    let x = location["position"]["coordinates"][0].as_f64().unwrap();
    assert!((1.5..=22.5).contains(&x), "{location}");

    // the hazard alarm, as the WebSocket's rtls:alarms (and a webhook) has it
    let (subject, alarm) = next_json(&mut alarms, Duration::from_secs(20))
        .await
        .expect("an alarm on rtls.events.hazard-predicted");
    assert_eq!(subject, "rtls.events.hazard-predicted");
    assert_eq!(
        (&alarm["type"], &alarm["tag"], &alarm["zone"]),
        (
            &Value::from("hazard-predicted"),
            &Value::from("miner-7"),
            &Value::from("forklift-lane")
        ),
        "{alarm}"
    );
    assert!(alarm["alarm_id"].is_string(), "{alarm}");

    // counted: published, nothing dropped
    let published = "rtls_nats_forward_total{forward=\"bus\",outcome=\"published\"}";
    let metrics = poll_text(&web, http, "/metrics", |m| metric_value(m, published) >= 2.0).await;
    assert!(metric_value(&metrics, published) >= 2.0, "{metrics}");
    assert_eq!(
        metric_value(&metrics, "rtls_nats_forward_total{forward=\"bus\",outcome=\"dropped\"}"),
        0.0
    );
    running.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_nats_server_that_is_down_blocks_nothing_and_is_reached_once_up() {
    let Some(binary) = binary() else { return };
    let port = free_port();
    // nothing listens on the port yet: the server starts and tracks all the same
    let running = start("nats-forward-down", &format!("nats://127.0.0.1:{port}")).await;
    let http = running.bound.http;
    let web = reqwest::Client::new();
    let reply = post_measurements(&web, http, walk("early", 5000.0, 3.0)).await;
    assert_eq!(reply.status(), 200);
    let tags = poll_text(&web, http, "/api/v1/tags", |t| t.contains("\"early\"")).await;
    assert!(
        tags.contains("\"early\""),
        "the pipeline tracks while NATS is down: {tags}"
    );

    // the NATS server comes up: the forward reconnects by itself and delivers later updates
    let (_nats, client) = nats_server(&binary, port).await;
    let mut positions = client.subscribe("rtls.positions.late").await.unwrap();
    client.flush().await.unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut received = None;
    let mut t0 = 6000.0;
    while received.is_none() && Instant::now() < deadline {
        // a few more updates every second, until the reconnected forward passes them on
        let reply = post_measurements(&web, http, walk("late", t0, 1.0)).await;
        assert_eq!(reply.status(), 200);
        t0 += 1.5;
        received = next_json(&mut positions, Duration::from_secs(1)).await;
    }
    let (subject, location) = received.expect("a position once NATS is up");
    assert_eq!(subject, "rtls.positions.late");
    assert_eq!(location["provider_id"], "late", "{location}");
    running.stop().await;
}
