//! The cluster's benchmark (ignored by `cargo test`; docs/CLUSTER.md, "Sizing"): acknowledged
//! records/s at the maximum rate and ingest → WebSocket latency, with 1, 2 and 3 nodes on a
//! three-server JetStream cluster (R3) and a shared PostgreSQL, all on this machine's loopback.
//!
//! ```sh
//! cargo test --release -p rtls-cli --test cluster_bench -- --ignored --nocapture
//! ```
//!
//! Node count 0 is the baseline: one `rtls serve` without `--cluster` on the same PostgreSQL
//! (its ingest log there). Two runs per node count: at the maximum rate (four HTTP publishers, each with 4 payloads of
//! 250 fixes in flight, sending to the nodes in turn, 1 000 tags) and at a mine's load (6 000
//! records/s offered: the same 16 lanes each sending a payload of 25 fixes every 66.7 ms). A
//! WebSocket client on the first node subscribes to `location_updates`; latency is the receive
//! time minus the location's `timestamp_generated`, which is the record's send time. 3 s of
//! warm-up are not measured; then 15 s are. One JSON line per run.

mod common;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::cluster::{self, unix_s};
use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::Message;

const PUBLISHERS: usize = 4;
const IN_FLIGHT: usize = 4;
const BATCH: usize = 250;
/// A payload at the offered rate (a reader's scan of 25 tags).
const PACED_BATCH: usize = 25;
/// The offered rate of the paced runs (records/s): a mine of 600 tags at 10 Hz (here 1 000 tags at 6 Hz).
const PACED_RPS: f64 = 6_000.0;
const TAGS_PER_PUBLISHER: usize = 250;
const PARTITIONS: usize = 12;
const WARMUP: Duration = Duration::from_secs(3);
const MEASURED: Duration = Duration::from_secs(15);

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// One run with `nodes_count` nodes, at the maximum rate or at `offered_rps`.
async fn run(nodes_count: usize, offered_rps: Option<f64>, nats_binary: &str, postgres_url: &str) -> serde_json::Value {
    let dir = common::temp_dir("cluster-bench", &format!("n{nodes_count}"));
    std::fs::write(dir.join("site.toml"), cluster::SITE).unwrap();
    let schema = cluster::Schema::new(postgres_url, &format!("bench{nodes_count}"));
    // 0 nodes: the baseline, one rtls serve without a cluster on the same PostgreSQL
    let (nats, urls) = if nodes_count == 0 {
        (Vec::new(), Vec::new())
    } else {
        cluster::nats_cluster(nats_binary, &dir)
    };
    let nodes: Vec<cluster::Node> = (0..nodes_count.max(1))
        .map(|i| cluster::start_node(&dir, i, &urls, &schema.db))
        .collect();
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap();
    if nodes_count > 0 {
        cluster::wait_balanced(&client, &nodes, PARTITIONS).await;
    }

    let (mut socket, _) =
        tokio_tungstenite::connect_async(format!("ws://{}/v2/ws/socket?token={}", nodes[0].http, cluster::READ))
            .await
            .expect("WebSocket");
    socket
        .send(Message::Text(
            r#"{"event":"subscribe","topic":"location_updates"}"#.into(),
        ))
        .await
        .unwrap();
    let measuring = Arc::new(AtomicBool::new(false));
    let latencies = Arc::new(Mutex::new(Vec::<f64>::new()));
    let ws = {
        let (measuring, latencies) = (measuring.clone(), latencies.clone());
        tokio::spawn(async move {
            while let Some(Ok(message)) = socket.next().await {
                let Message::Text(text) = message else { continue };
                let received = unix_s();
                let value: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
                for location in value["payload"].as_array().into_iter().flatten() {
                    let Some(stamp) = location["timestamp_generated"].as_str() else {
                        continue;
                    };
                    let Ok(t) = rtls_server::omlox::time::parse_timestamp(stamp, "t") else {
                        continue;
                    };
                    if measuring.load(Ordering::Relaxed) {
                        latencies.lock().unwrap().push(received - t);
                    }
                }
            }
        })
    };

    let acked = Arc::new(AtomicU64::new(0));
    let running = Arc::new(AtomicBool::new(true));
    let targets: Arc<Vec<String>> = Arc::new(nodes.iter().map(|n| n.http.clone()).collect());
    let mut senders = Vec::new();
    for publisher in 0..PUBLISHERS {
        for lane in 0..IN_FLIGHT {
            let (acked, running, targets, client) = (acked.clone(), running.clone(), targets.clone(), client.clone());
            let (batch, pause) = match offered_rps {
                Some(rate) => (
                    PACED_BATCH,
                    Some(Duration::from_secs_f64(
                        (PACED_BATCH * PUBLISHERS * IN_FLIGHT) as f64 / rate,
                    )),
                ),
                None => (BATCH, None),
            };
            senders.push(tokio::spawn(async move {
                let mut round = lane;
                let mut next = tokio::time::Instant::now();
                while running.load(Ordering::Relaxed) {
                    if let Some(pause) = pause {
                        tokio::time::sleep_until(next).await;
                        next += pause;
                    }
                    let t = unix_s();
                    let body: String = (0..batch)
                        .map(|i| {
                            let tag = publisher * TAGS_PER_PUBLISHER + (round * batch + i) % TAGS_PER_PUBLISHER;
                            format!(
                                "{{\"t\": {t}, \"tag\": \"tag-{tag}\", \"kind\": \"fix\", \"position_m\": [{}, 5.0], \
                                 \"covariance_m2\": [0.04, 0, 0, 0.04]}}\n",
                                (tag % 30) as f64
                            )
                        })
                        .collect();
                    let target = &targets[round % targets.len()];
                    let response = client
                        .post(format!("http://{target}/api/v1/measurements"))
                        .bearer_auth(cluster::WRITE)
                        .body(body)
                        .send()
                        .await;
                    if matches!(&response, Ok(r) if r.status().is_success()) {
                        acked.fetch_add(batch as u64, Ordering::Relaxed);
                    }
                    round += IN_FLIGHT;
                }
            }));
        }
    }
    tokio::time::sleep(WARMUP).await;
    let acked_before = acked.load(Ordering::Relaxed);
    measuring.store(true, Ordering::Relaxed);
    tokio::time::sleep(MEASURED).await;
    measuring.store(false, Ordering::Relaxed);
    let acked_during = acked.load(Ordering::Relaxed) - acked_before;
    running.store(false, Ordering::Relaxed);
    for sender in senders {
        let _ = sender.await;
    }
    ws.abort();
    let mut latencies = latencies.lock().unwrap().clone();
    latencies.sort_by(f64::total_cmp);
    let sustained = acked_during as f64 / MEASURED.as_secs_f64();
    drop(nodes);
    drop(nats);
    drop(schema);
    let _ = std::fs::remove_dir_all(&dir);
    serde_json::json!({
        "nodes": nodes_count,
        "offered_rps": offered_rps,
        "sustained_rps": sustained.round(),
        "rps_per_node": (sustained / nodes_count.max(1) as f64).round(),
        "p50_ms": (percentile(&latencies, 0.5) * 1e3 * 10.0).round() / 10.0,
        "p99_ms": (percentile(&latencies, 0.99) * 1e3 * 10.0).round() / 10.0,
        "location_updates_measured": latencies.len(),
        "cores": std::thread::available_parallelism().map_or(0, |n| n.get()),
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a benchmark: cargo test --release -p rtls-cli --test cluster_bench -- --ignored --nocapture"]
async fn acknowledged_records_per_second_with_one_two_and_three_nodes() {
    let Some((nats, postgres)) = cluster::services() else {
        return;
    };
    for nodes in 0..=3 {
        for offered in [None, Some(PACED_RPS)] {
            println!("{}", run(nodes, offered, &nats, &postgres).await);
        }
    }
}
