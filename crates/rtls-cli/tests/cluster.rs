//! `rtls serve --cluster`: three `nats-server`s clustered with JetStream on loopback, a shared
//! PostgreSQL, three `rtls serve --cluster` nodes and a publisher at a steady rate counting
//! acknowledgements. Mid-stream one node is killed with SIGKILL, then one NATS server: the
//! dead node's partitions resume on the others within 5 s, every tag's track goes on with no
//! gap in its history longer than 5 s, and every acknowledged record is in the history.
//!
//! Needs `RTLS_TEST_NATS_SERVER` (the `nats-server` binary) and `RTLS_TEST_POSTGRES_URL`, which
//! `.ci/services/nats.sh` and `.ci/services/postgres.sh` print; without them it says so and
//! passes (as the other PostgreSQL tests do).

mod common;

use std::collections::{HashMap, HashSet};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::cluster::{metric, start_node, unix_s, Node, READ, WRITE};

const TAGS: usize = 20;
const RATE_HZ: f64 = 5.0;
const PARTITIONS: usize = 12;

/// (tag, t in µs) of every record the publisher got a 2xx for.
type Acked = Arc<Mutex<HashSet<(String, i64)>>>;

fn micros(t: f64) -> i64 {
    (t * 1e6).round() as i64
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cluster_loses_no_acknowledged_record_when_a_node_and_a_nats_server_die() {
    let Some((nats_binary, postgres_url)) = common::cluster::services() else {
        return;
    };
    let dir = common::temp_dir("cluster", "kill");
    std::fs::write(dir.join("site.toml"), common::cluster::SITE).unwrap();
    // a checkpoint a second, so the dead node's partitions have one however soon it dies
    std::fs::write(dir.join("server.toml"), "[cluster]\ncheckpoint_s = 1.0\n").unwrap();
    let schema = common::cluster::Schema::new(&postgres_url, "cluster");
    let db = schema.db.clone();

    let (mut nats, urls) = common::cluster::nats_cluster(&nats_binary, &dir);
    let mut nodes: Vec<Node> = (0..3).map(|i| start_node(&dir, i, &urls, &db)).collect();
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(15))
        .build()
        .unwrap();

    // every partition owned, a fair share each, before the records start
    common::cluster::wait_balanced(&client, &nodes, PARTITIONS).await;

    // the publisher: all tags every 1/RATE_HZ s, to the nodes that stay up, in turn
    let acked: Acked = Arc::default();
    let failed = Arc::new(Mutex::new(0usize));
    let publishing = Arc::new(std::sync::atomic::AtomicBool::new(true));
    let targets = [nodes[1].http.clone(), nodes[2].http.clone()];
    let publisher = {
        let (acked, failed, publishing, client) = (acked.clone(), failed.clone(), publishing.clone(), client.clone());
        tokio::spawn(async move {
            let mut round = 0usize;
            let mut in_flight = Vec::new();
            while publishing.load(std::sync::atomic::Ordering::Acquire) {
                let t = unix_s();
                let body: String = (0..TAGS)
                    .map(|i| {
                        format!(
                            "{{\"t\": {t}, \"tag\": \"tag-{i}\", \"kind\": \"fix\", \"position_m\": [{}, {}], \
                             \"covariance_m2\": [0.04, 0, 0, 0.04]}}\n",
                            i as f64 + 0.01 * round as f64,
                            5.0
                        )
                    })
                    .collect();
                // each payload on its own task: a slow acknowledgement does not hold the next
                // payload back, as a reader's clock does not wait either
                let target = targets[round % targets.len()].clone();
                let (acked, failed, client) = (acked.clone(), failed.clone(), client.clone());
                in_flight.push(tokio::spawn(async move {
                    let response = client
                        .post(format!("http://{target}/api/v1/measurements"))
                        .bearer_auth(WRITE)
                        .body(body)
                        .send()
                        .await;
                    match response {
                        Ok(r) if r.status().is_success() => {
                            let mut acked = acked.lock().unwrap();
                            acked.extend((0..TAGS).map(|i| (format!("tag-{i}"), micros(t))));
                        }
                        _ => *failed.lock().unwrap() += TAGS,
                    }
                }));
                round += 1;
                let spent = unix_s() - t;
                tokio::time::sleep(Duration::from_secs_f64((1.0 / RATE_HZ - spent).max(0.0))).await;
            }
            for request in in_flight {
                let _ = request.await;
            }
        })
    };

    tokio::time::sleep(Duration::from_secs(5)).await;
    let node_killed_at = unix_s();
    let _ = nodes[0].child.0.kill();
    let _ = nodes[0].child.0.wait();
    // the dead node's partitions resume on the others within 5 s
    let takeovers_before: f64 = {
        let mut sum = 0.0;
        for node in &nodes[1..] {
            sum += metric(&client, &node.http, "rtls_cluster_partitions_owned").await;
        }
        sum
    };
    let resumed = loop {
        let mut owned = 0.0;
        for node in &nodes[1..] {
            owned += metric(&client, &node.http, "rtls_cluster_partitions_owned").await;
        }
        if owned as usize == PARTITIONS {
            break unix_s() - node_killed_at;
        }
        assert!(
            unix_s() - node_killed_at < 15.0,
            "the dead node's partitions are not taken over: {owned} of {PARTITIONS} owned"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    // the dead node's partitions continued from its checkpoints, not from their priors (a
    // resume is counted once its warm-up after the checkpoint is done, after the ownership
    // above: polled for up to 10 s)
    let counted = Instant::now();
    let (restored, refused) = loop {
        let (mut restored, mut refused) = (0.0, 0.0);
        for node in &nodes[1..] {
            restored += metric(&client, &node.http, "rtls_cluster_resumes_total{outcome=\"restored\"}").await;
            refused += metric(&client, &node.http, "rtls_cluster_resumes_total{outcome=\"refused\"}").await;
        }
        if restored >= 1.0 || refused > 0.0 || counted.elapsed() > Duration::from_secs(10) {
            break (restored, refused);
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    tokio::time::sleep(Duration::from_secs(4)).await;
    let nats_killed_at = unix_s();
    let _ = nats[1].0.kill();
    let _ = nats[1].0.wait();
    tokio::time::sleep(Duration::from_secs(10)).await;
    publishing.store(false, std::sync::atomic::Ordering::Release);
    publisher.await.unwrap();
    let publishing_ended = unix_s();

    // every acknowledged record reaches the history (the owners store them before they
    // acknowledge them to the stream)
    let acked: HashSet<(String, i64)> = acked.lock().unwrap().clone();
    let failed = *failed.lock().unwrap();
    let stored_rows = |sql: &str| schema.query(sql);
    let waited = Instant::now();
    let (lost, rows) = loop {
        let rows = stored_rows(&format!("SELECT tag, time_s FROM {}.records", schema.name()));
        let stored: HashSet<(String, i64)> = rows
            .iter()
            .map(|r| (r.get::<_, String>(0), micros(r.get::<_, f64>(1))))
            .collect();
        let lost: Vec<_> = acked.difference(&stored).cloned().collect();
        if lost.is_empty() || waited.elapsed() > Duration::from_secs(30) {
            if !lost.is_empty() {
                let mut sample = lost.clone();
                sample.sort();
                eprintln!(
                    "lost (tag, µs), first of {}: {:?}; the nodes' logs: {}/node*.log",
                    lost.len(),
                    &sample[..sample.len().min(12)],
                    dir.display()
                );
            }
            break (lost.len(), rows.len());
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
    };

    // each tag's track history: the longest gap from the node's death to the end
    let locations = stored_rows(&format!(
        "SELECT tag, time_s FROM {}.locations WHERE time_s >= {} AND time_s <= {} ORDER BY tag, time_s",
        schema.name(),
        node_killed_at - 1.0,
        publishing_ended - 1.0
    ));
    let mut per_tag: HashMap<String, Vec<f64>> = HashMap::new();
    for row in &locations {
        per_tag.entry(row.get(0)).or_default().push(row.get(1));
    }
    // a gap is the node's when it starts before the NATS server died, else the NATS server's
    let (mut node_gap, mut nats_gap) = (0.0_f64, 0.0_f64);
    for times in per_tag.values() {
        for pair in times.windows(2) {
            let gap = pair[1] - pair[0];
            if pair[0] < nats_killed_at {
                node_gap = node_gap.max(gap);
            } else {
                nats_gap = nats_gap.max(gap);
            }
        }
    }

    // a surviving node serves every tag, whichever node tracks it
    let tags: serde_json::Value = client
        .get(format!("http://{}/api/v1/tags", nodes[2].http))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let served = tags.as_array().map_or(0, Vec::len);

    println!(
        "{}",
        serde_json::json!({
            "acknowledged": acked.len(), "refused": failed, "stored_rows": rows, "lost": lost,
            "duplicates": rows.saturating_sub(acked.len()),
            "partitions_resumed_after_s": resumed, "owned_just_after_kill": takeovers_before,
            "restored_from_checkpoints": restored, "checkpoints_refused": refused,
            "longest_track_gap_after_node_kill_s": node_gap, "longest_track_gap_after_nats_kill_s": nats_gap, "tags_with_history": per_tag.len(), "tags_served": served,
        })
    );
    assert!(
        acked.len() >= TAGS * 50,
        "too few records acknowledged: {}",
        acked.len()
    );
    assert_eq!(lost, 0, "acknowledged records missing from the history");
    assert!(resumed <= 5.0, "partitions resumed {resumed:.1} s after the node died");
    assert!(
        restored >= 1.0 && refused == 0.0,
        "takeovers restored from a checkpoint: {restored}, checkpoints refused: {refused}"
    );
    assert_eq!(per_tag.len(), TAGS, "tags with a history after the node died");
    assert!(
        node_gap <= 5.0,
        "a track's history has a {node_gap:.1} s gap after the node died"
    );
    // a stream or consumer whose leader was on the dead NATS server waits for JetStream's
    // election (a follower campaigns after 4–9 s without its leader: nats-server's
    // minElectionTimeoutDefault..maxElectionTimeoutDefault) before it takes records again
    assert!(
        nats_gap <= 12.0,
        "a track's history has a {nats_gap:.1} s gap after the NATS server died"
    );
    assert_eq!(served, TAGS, "tags served by a surviving node");

    // a graceful stop of the survivors; the servers go with the test
    for node in &mut nodes[1..] {
        let pid = node.child.0.id().to_string();
        let _ = Command::new("kill").args(["-TERM", &pid]).status();
    }
    for node in &mut nodes[1..] {
        let started = Instant::now();
        while node.child.0.try_wait().unwrap().is_none() {
            assert!(
                started.elapsed() < Duration::from_secs(30),
                "a node did not stop after SIGTERM"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    drop(nodes);
    drop(nats);
    drop(schema);
    let _ = std::fs::remove_dir_all(&dir);
}
