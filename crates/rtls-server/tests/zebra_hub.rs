//! A Zebra Dart hub read over TCP (`[adapters.zebra] hub`, `rtls serve --zebra-hub`) on
//! loopback: a fake hub — a listener here — writes the guide's example output; its lines are
//! counted by outcome, the refused packets by reason, a malformed line costs only itself; the
//! hub goes away and comes back and the server reconnects and reads on; the tags are tracked.

mod common;

use std::net::SocketAddr;
use std::time::Duration;

use common::{eventually_some, get_json, loopback_config, metric_value, poll_text, temp_dir};
use rtls_server::adapters::ZebraUnit;
use rtls_server::config::MqttMode;
use serde_json::Value;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};

/// The Zebra Dart RTLS User Guide's example output (page 85), one packet per line.
const EXAMPLE: &str = include_str!("../src/adapters/zebra_dart_example.txt");

fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// `line` with its `<timestamp>` (the 7th field) replaced by `t` (the live clock refuses the
/// guide's 2015 times).
fn at_time(line: &str, t: f64) -> String {
    let mut fields: Vec<String> = line.split(',').map(str::to_string).collect();
    fields[6] = format!("{t:.3}");
    fields.join(",")
}

/// The server's connection to the fake hub (≤ 20 s).
async fn accepted(hub: &TcpListener) -> TcpStream {
    let (stream, _) = tokio::time::timeout(Duration::from_secs(20), hub.accept())
        .await
        .expect("the server connects to the hub")
        .unwrap();
    stream
}

/// The tag's entry in `GET /api/v1/tags`, once it is there (≤ 20 s).
async fn tracked(client: &reqwest::Client, http: SocketAddr, tag: &str) -> Option<Value> {
    eventually_some(Duration::from_secs(20), || async {
        let tags = get_json(client, http, "/api/v1/tags").await;
        tags.as_array()?.iter().find(|t| t["tag"] == tag).cloned()
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hub_lines_are_counted_tracked_and_read_again_after_a_reconnect() {
    let hub = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let hub_at = hub.local_addr().unwrap();
    let dir = temp_dir("zebra-hub");
    let mut config = loopback_config(&dir, MqttMode::Off);
    config.adapters.zebra.hub = Some(hub_at.to_string());
    config.adapters.zebra.unit = ZebraUnit::Ft;
    config.validate().unwrap();
    let running = common::serve_on_loopback(common::options(config)).await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    let series = |outcome: &str| format!("rtls_zebra_hub_lines_total{{hub=\"{hub_at}\",outcome=\"{outcome}\"}}");
    let connected = format!("rtls_zebra_hub_connected{{hub=\"{hub_at}\"}}");

    // the guide's 19 lines, their times now, and a malformed one in the middle, written in
    // two pieces that split a line: 7 locates stored, 12 packets refused as no_position
    let mut connection = accepted(&hub).await;
    let t0 = now_s() - 1.0;
    let mut lines: Vec<String> = EXAMPLE
        .lines()
        .enumerate()
        .map(|(k, line)| at_time(line, t0 + 0.01 * k as f64))
        .collect();
    lines.insert(5, "T,0021F7B1,29.53,18.38,1.52,12,soon,4,*,G0.73".to_string());
    let stream = lines.join("\r\n") + "\r\n";
    let (first, second) = stream.split_at(stream.len() / 2);
    connection.write_all(first.as_bytes()).await.unwrap();
    connection.flush().await.unwrap();
    tokio::time::sleep(Duration::from_millis(50)).await;
    connection.write_all(second.as_bytes()).await.unwrap();
    let metrics = poll_text(&client, http, "/metrics", |m| {
        metric_value(m, &series("accepted")) + metric_value(m, &series("refused")) >= 20.0
    })
    .await;
    assert_eq!(metric_value(&metrics, &series("accepted")), 19.0, "{metrics}");
    assert_eq!(metric_value(&metrics, &series("refused")), 1.0);
    assert_eq!(metric_value(&metrics, &series("dropped")), 0.0);
    assert_eq!(metric_value(&metrics, &connected), 1.0);
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"no_position\"}"),
        12.0
    );
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"format\"}"),
        1.0
    );

    // the hub goes away (connection and listener) and comes back 1.5 s later on its port:
    // the server's first retry is refused, a later one connects
    drop(connection);
    drop(hub);
    let metrics = poll_text(&client, http, "/metrics", |m| metric_value(m, &connected) == 0.0).await;
    assert_eq!(
        metric_value(&metrics, &connected),
        0.0,
        "the gauge follows the connection"
    );
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let hub = TcpListener::bind(hub_at).await.expect("the hub's port again");
    let mut connection = accepted(&hub).await;
    // tag 00201C40's locate again, half a second on: read on the new connection, and tracked
    let again = EXAMPLE.lines().find(|l| l.starts_with("T,00201C40")).unwrap();
    let line = at_time(again, t0 + 0.01 * 14.0 + 0.5) + "\n";
    connection.write_all(line.as_bytes()).await.unwrap();
    let metrics = poll_text(&client, http, "/metrics", |m| {
        metric_value(m, &series("accepted")) >= 20.0
    })
    .await;
    assert_eq!(metric_value(&metrics, &series("accepted")), 20.0, "{metrics}");
    assert_eq!(metric_value(&metrics, &connected), 1.0);

    let tag = tracked(&client, http, "00201C40").await.expect("00201C40 is tracked");
    let position = &tag["position_m"];
    // 25.85 ft, 15.67 ft
    assert!(
        (position[0].as_f64().unwrap() - 7.879).abs() < 0.05 && (position[1].as_f64().unwrap() - 4.776).abs() < 0.05,
        "{tag}"
    );

    // the client stops with the server, its connection open
    running.stop().await;
    drop(connection);
}
