//! The whole server on loopback: records published by a real MQTT client (rumqttc) reach a
//! WebSocket subscriber as omlox locations and fence events, and MQTT subscribers as track
//! publications — against the embedded broker, against Debian's mosquitto
//! (`RTLS_TEST_MOSQUITTO_URL`) and with PostgreSQL storage (`RTLS_TEST_POSTGRES_URL`); `.ci/run`
//! starts both. Without the variables those two tests print a notice and pass.

mod common;

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use rtls_server::config::{MqttMode, ServerConfig};
use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};
use serde_json::Value;
use tokio_tungstenite::tungstenite::Message;

use common::{walk, Running, READ, WRITE};

async fn start(mut config: ServerConfig) -> Running {
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.mqtt.listen = "127.0.0.1:0".parse().unwrap();
    config.pipeline.live_clock = false;
    common::serve_on_loopback(common::options(config)).await
}

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn subscribe(http: std::net::SocketAddr, requests: &[&str]) -> Socket {
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token={READ}"))
        .await
        .unwrap();
    for request in requests {
        socket.send(Message::Text((*request).into())).await.unwrap();
        let reply = next_json(&mut socket).await;
        assert_eq!(reply["event"], "subscribed", "{reply}");
    }
    socket
}

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

fn mqtt_client(address: &str, id: &str, token: Option<&str>) -> (AsyncClient, rumqttc::EventLoop) {
    let (host, port) = address.trim_start_matches("mqtt://").rsplit_once(':').unwrap();
    let mut options = MqttOptions::new(id, host, port.parse().unwrap());
    if let Some(token) = token {
        options.set_credentials("test", token);
    }
    options.set_max_packet_size(1 << 20, 1 << 20);
    AsyncClient::new(options, 64)
}

/// Publishes a walk through the hazard zone over MQTT and checks what the WebSocket and an
/// MQTT subscriber see.
async fn walk_reaches_websocket_and_mqtt(running: &Running, broker: &str, write_token: Option<&str>) {
    let mut socket = subscribe(
        running.bound.http,
        &[
            r#"{"event":"subscribe","topic":"location_updates","params":{"provider_id":"miner-7"}}"#,
            r#"{"event":"subscribe","topic":"fence_events"}"#,
        ],
    )
    .await;
    // an MQTT subscriber to the server's track publications
    let (subscriber, mut sub_loop) = mqtt_client(broker, "test-subscriber", write_token);
    subscriber.subscribe("rtls/v1/tracks/+", QoS::AtMostOnce).await.unwrap();
    let (track_tx, mut track_rx) = tokio::sync::mpsc::unbounded_channel();
    tokio::spawn(async move {
        while let Ok(event) = sub_loop.poll().await {
            if let Event::Incoming(Packet::Publish(publish)) = event {
                let _ = track_tx.send((publish.topic.clone(), publish.payload.to_vec()));
            }
        }
    });
    tokio::time::sleep(Duration::from_millis(300)).await;

    let (publisher, mut pub_loop) = mqtt_client(broker, "test-reader", write_token);
    let (ack_tx, mut ack_rx) = tokio::sync::mpsc::unbounded_channel();
    tokio::spawn(async move {
        while let Ok(event) = pub_loop.poll().await {
            if let Event::Incoming(Packet::PubAck(ack)) = event {
                let _ = ack_tx.send(ack.pkid);
            }
        }
    });
    // other tags' records too, which the location subscription filters out
    let payload = format!("{}{}", walk("miner-7", 5000.0, 20.0), walk("miner-8", 5000.0, 2.0));
    publisher
        .publish("rtls/v1/measurements/reader-1", QoS::AtLeastOnce, false, payload)
        .await
        .unwrap();
    tokio::time::timeout(Duration::from_secs(20), ack_rx.recv())
        .await
        .expect("PUBACK")
        .unwrap();

    let (mut last_x, mut fence_events, mut locations) = (0.0, Vec::new(), 0);
    // the newest records wait for later data (reorder window, epoch): x ≈ 20 m at the end
    while last_x < 19.5 || fence_events.len() < 2 {
        let message = next_json(&mut socket).await;
        assert_eq!(message["event"], "message", "{message}");
        for payload in message["payload"].as_array().unwrap() {
            match message["topic"].as_str().unwrap() {
                "location_updates" => {
                    assert_eq!(payload["provider_id"], "miner-7", "the filter holds");
                    last_x = payload["position"]["coordinates"][0].as_f64().unwrap();
                    locations += 1;
                }
                "fence_events" => fence_events.push(payload.clone()),
                other => panic!("unexpected topic {other}"),
            }
        }
    }
    assert!(locations >= 10, "{locations} locations");
    let kinds: Vec<&str> = fence_events.iter().map(|e| e["event_type"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["region_entry", "region_exit"]);
    assert_eq!(fence_events[0]["foreign_id"], "forklift-lane");
    assert!(fence_events[1]["entry_time"].is_string() && fence_events[1]["exit_time"].is_string());

    let (topic, payload) = tokio::time::timeout(Duration::from_secs(20), track_rx.recv())
        .await
        .expect("a track publication")
        .unwrap();
    assert!(
        topic == "rtls/v1/tracks/miner-7" || topic == "rtls/v1/tracks/miner-8",
        "{topic}"
    );
    let update: Value = serde_json::from_slice(&payload).unwrap();
    assert!(update["t"].as_f64().unwrap() >= 5000.0, "{update}");
}

async fn stop(running: Running) {
    running.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn embedded_broker_to_websocket_and_mqtt_subscribers() {
    let dir = common::temp_dir("live-embedded");
    let mut config = ServerConfig::default();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    let running = start(config).await;
    let broker = running.bound.mqtt.unwrap().to_string();
    walk_reaches_websocket_and_mqtt(&running, &broker, Some(WRITE)).await;

    // a client without the write token cannot publish: refused at CONNECT
    let (client, mut event_loop) = mqtt_client(&broker, "intruder", Some("not-the-token"));
    client
        .publish(
            "rtls/v1/measurements/x",
            QoS::AtLeastOnce,
            false,
            walk("intruder", 1.0, 1.0),
        )
        .await
        .unwrap();
    let refused = loop {
        match tokio::time::timeout(Duration::from_secs(10), event_loop.poll())
            .await
            .expect("an answer")
        {
            Ok(Event::Incoming(Packet::ConnAck(ack))) => break format!("{:?}", ack.code),
            Ok(_) => {}
            Err(e) => break e.to_string(),
        }
    };
    assert!(!refused.contains("Success"), "{refused}");

    // an unknown WebSocket topic is an omlox error 10001 / 10000
    let (mut socket, _) =
        tokio_tungstenite::connect_async(format!("ws://{}/v2/ws/socket?token={READ}", running.bound.http))
            .await
            .unwrap();
    socket
        .send(Message::Text(r#"{"event":"subscribe","topic":"weather"}"#.into()))
        .await
        .unwrap();
    let reply = next_json(&mut socket).await;
    assert_eq!(reply["event"], "error");
    assert!(matches!(reply["code"].as_u64(), Some(10000..=10005)), "{reply}");
    // a WebSocket without a token is refused
    assert!(
        tokio_tungstenite::connect_async(format!("ws://{}/v2/ws/socket", running.bound.http))
            .await
            .is_err()
    );
    stop(running).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn external_mosquitto_broker_to_websocket() {
    let Ok(url) = std::env::var("RTLS_TEST_MOSQUITTO_URL") else {
        eprintln!("skipped: RTLS_TEST_MOSQUITTO_URL not set (.ci/run starts mosquitto)");
        return;
    };
    let dir = common::temp_dir("live-mosquitto");
    let mut config = ServerConfig::default();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    config.mqtt.mode = MqttMode::External;
    config.mqtt.url = Some(format!("{url}?client_id=rtls-server-live-test"));
    let running = start(config).await;
    tokio::time::sleep(Duration::from_millis(500)).await; // the bridge subscribes
    walk_reaches_websocket_and_mqtt(&running, &url, None).await;
    stop(running).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgresql_storage_serves_history() {
    let Ok(url) = std::env::var("RTLS_TEST_POSTGRES_URL") else {
        eprintln!("skipped: RTLS_TEST_POSTGRES_URL not set (.ci/run starts PostgreSQL)");
        return;
    };
    // a database of its own, so the schema migrations run from scratch
    let database = format!("rtls_live_{}", std::process::id());
    let admin = url.clone();
    let name = database.clone();
    tokio::task::spawn_blocking(move || {
        let mut client = postgres::Client::connect(&admin, postgres::NoTls).unwrap();
        client
            .batch_execute(&format!("DROP DATABASE IF EXISTS {name}"))
            .unwrap();
        client.batch_execute(&format!("CREATE DATABASE {name}")).unwrap();
    })
    .await
    .unwrap();
    let (base, _) = url.rsplit_once('/').unwrap();
    let mut config = ServerConfig::default();
    config.server.db = format!("{base}/{database}");
    config.mqtt.mode = MqttMode::Off;
    let running = start(config).await;
    let client = reqwest::Client::new();
    let http = running.bound.http;
    let reply = client
        .post(format!("http://{http}/api/v1/measurements"))
        .bearer_auth(WRITE)
        .body(walk("miner-pg", 7000.0, 20.0))
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 200);
    let mut rows = Vec::new();
    for _ in 0..400 {
        let history: Value = client
            .get(format!("http://{http}/api/v1/history?tag=miner-pg"))
            .bearer_auth(READ)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        rows = history.as_array().unwrap().clone();
        if rows.last().is_some_and(|r| r["t"].as_f64().unwrap() >= 7017.9) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert!(rows.len() >= 20, "{} states in PostgreSQL", rows.len());
    // the output thread stores a batch's states before its events: poll for the events too
    let mut kinds: Vec<String> = Vec::new();
    for _ in 0..400 {
        let events: Value = client
            .get(format!(
                "http://{http}/api/v1/events?tag=miner-pg&type=zone-enter,zone-exit"
            ))
            .bearer_auth(READ)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        kinds = events
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["type"].as_str().unwrap().to_string())
            .collect();
        if kinds.len() >= 2 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert_eq!(kinds, ["zone-enter", "zone-exit"]);
    stop(running).await;
    tokio::task::spawn_blocking(move || {
        let mut client = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        // clean-up, not the test: FORCE cannot end a backend of another role (an autovacuum
        // worker on the fresh database refuses it for a moment), so try again for a while
        let drop = format!("DROP DATABASE IF EXISTS {database} WITH (FORCE)");
        for attempt in 1..=20 {
            match client.batch_execute(&drop) {
                Ok(()) => return,
                Err(e) if attempt == 20 => eprintln!("test database {database} left behind: {e}"),
                Err(_) => std::thread::sleep(std::time::Duration::from_millis(250)),
            }
        }
    })
    .await
    .unwrap();
}
