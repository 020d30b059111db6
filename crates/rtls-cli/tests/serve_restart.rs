//! Restart safety of `rtls serve`: records are sent over HTTP and MQTT (QoS 1) while the
//! server is killed with SIGKILL; every record the server acknowledged (HTTP 2xx, PUBACK) is
//! in the database afterwards, and the restarted server replays and serves them. Then a
//! SIGTERM stops it gracefully.

mod common;

use std::collections::{HashMap, HashSet};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rtls_server::store::{self, SqliteSync};
use rumqttc::{AsyncClient, Event, MqttOptions, Outgoing, Packet, QoS};

const TOKEN: &str = "restart-test-write-token";

const SITE: &str = r#"
name = "restart test"
[[readers]]
id = "A1"
position_m = [0.0, 0.0, 2.5]
technology = "uwb"
[[readers]]
id = "A2"
position_m = [30.0, 0.0, 2.5]
technology = "uwb"
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "ekf"
gate_probability = 0.999
acceleration_noise_std_mps2 = 0.5
coast_timeout_s = 10.0
delete_timeout_s = 300.0
initiation = { confirm_updates = 2, within_s = 5.0 }
reorder_window_s = 0.2
dimensions = 2
"#;

struct Server {
    child: common::KillOnDrop,
    http: String,
    mqtt: String,
}

fn start(dir: &std::path::Path) -> Server {
    let site = dir.join("site.toml");
    std::fs::write(&site, SITE).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_rtls"))
        .args([
            "serve",
            "--site",
            site.to_str().unwrap(),
            "--http",
            "127.0.0.1:0",
            "--mqtt-listen",
            "127.0.0.1:0",
            "--data-clock",
            // each writer's time stamps advance at its own pace (the MQTT writer's ~6× faster
            // than the HTTP ones'), not with a shared clock as real readers' do: a partition
            // holding two of them would report the slower tag's records late. Four partitions
            // put the three tags on three threads (FNV-1a: http-1 → 3, http-2 → 2, mqtt-1 → 1).
            "--partitions",
            "4",
        ])
        .arg("--db")
        .arg(format!("sqlite:{}", dir.join("rtls.db").display()))
        .env("RTLS_WRITE_TOKEN", TOKEN)
        .env("RTLS_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("rtls serve starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let bound: serde_json::Value =
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("announce line {line:?}: {e}"));
    Server {
        child: common::KillOnDrop(child),
        http: bound["http"].as_str().unwrap().to_string(),
        mqtt: bound["mqtt"].as_str().unwrap().to_string(),
    }
}

/// A record line with a unique (tag, t) key.
fn record(tag: &str, k: usize) -> String {
    format!(
        "{{\"t\": {}, \"tag\": \"{tag}\", \"kind\": \"fix\", \"position_m\": [{}, 5.0], \"covariance_m2\": [0.04, 0, 0, 0.04]}}\n",
        1000.0 + 0.1 * k as f64,
        (k % 300) as f64 * 0.1
    )
}

type Keys = Arc<Mutex<HashSet<(String, u64)>>>;

fn key(tag: &str, k: usize) -> (String, u64) {
    (tag.to_string(), (1000.0 + 0.1 * k as f64).to_bits())
}

/// Posts batches of 50 records until the server dies; records the acknowledged keys.
async fn http_writer(http: String, tag: &'static str, acked: Keys) {
    let client = reqwest::Client::new();
    let mut k = 0;
    loop {
        let batch: String = (k..k + 50).map(|i| record(tag, i)).collect();
        let sent = client
            .post(format!("http://{http}/api/v1/measurements"))
            .bearer_auth(TOKEN)
            .body(batch)
            .send()
            .await;
        match sent {
            Ok(response) if response.status().is_success() => {
                acked.lock().unwrap().extend((k..k + 50).map(|i| key(tag, i)));
            }
            _ => return,
        }
        k += 50;
    }
}

/// Publishes batches of 20 records at QoS 1 until the connection dies; a batch counts as
/// acknowledged when its PUBACK arrives.
async fn mqtt_writer(mqtt: String, tag: &'static str, acked: Keys) {
    let (host, port) = mqtt.rsplit_once(':').unwrap();
    let mut options = MqttOptions::new("restart-test", host, port.parse().unwrap());
    options.set_credentials("test", TOKEN);
    options.set_inflight(20);
    let (client, mut event_loop) = AsyncClient::new(options, 100);
    let publisher = tokio::spawn(async move {
        for batch in 0.. {
            let payload: String = (batch * 20..batch * 20 + 20).map(|i| record(tag, i)).collect();
            if client
                .publish("rtls/v1/measurements/r1", QoS::AtLeastOnce, false, payload)
                .await
                .is_err()
            {
                return;
            }
        }
    });
    // the event loop reports each publish's packet id in request order, then its PUBACK
    let mut next_batch = 0usize;
    let mut in_flight: HashMap<u16, usize> = HashMap::new();
    loop {
        match event_loop.poll().await {
            Ok(Event::Outgoing(Outgoing::Publish(pkid))) => {
                in_flight.insert(pkid, next_batch);
                next_batch += 1;
            }
            Ok(Event::Incoming(Packet::PubAck(ack))) => {
                if let Some(batch) = in_flight.remove(&ack.pkid) {
                    acked
                        .lock()
                        .unwrap()
                        .extend((batch * 20..batch * 20 + 20).map(|i| key(tag, i)));
                }
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    publisher.abort();
}

fn stored_keys(dir: &std::path::Path) -> HashSet<(String, u64)> {
    let mut store = store::open(&format!("sqlite:{}", dir.join("rtls.db").display()), SqliteSync::Normal).unwrap();
    let mut keys = HashSet::new();
    let mut after = 0;
    loop {
        let page = store.records_after(after, 10_000).unwrap();
        let Some(last) = page.last() else { break };
        after = last.id;
        for stored in page {
            keys.insert((stored.tag.clone(), stored.time_s.to_bits()));
        }
    }
    keys
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_acknowledged_record_is_lost_when_the_server_is_killed_during_ingest() {
    let dir = common::temp_dir("serve", "restart");
    let mut server = start(&dir);
    let acked: Keys = Arc::default();
    let writers = vec![
        tokio::spawn(http_writer(server.http.clone(), "http-1", Arc::clone(&acked))),
        tokio::spawn(http_writer(server.http.clone(), "http-2", Arc::clone(&acked))),
        tokio::spawn(mqtt_writer(server.mqtt.clone(), "mqtt-1", Arc::clone(&acked))),
    ];
    // let ingest run, then kill the server mid-stream
    let deadline = Instant::now() + Duration::from_secs(20);
    while acked.lock().unwrap().len() < 3000 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    server.child.0.kill().unwrap(); // SIGKILL
    server.child.0.wait().unwrap();
    for writer in writers {
        tokio::time::timeout(Duration::from_secs(30), writer)
            .await
            .expect("writers stop")
            .unwrap();
    }
    let acked = acked.lock().unwrap().clone();
    let from_mqtt = acked.iter().filter(|(tag, _)| tag == "mqtt-1").count();
    println!(
        "acknowledged before SIGKILL: {} records ({from_mqtt} over MQTT)",
        acked.len()
    );
    assert!(
        acked.len() >= 3000 && from_mqtt > 0,
        "ingest ran: {} acked, {from_mqtt} over MQTT",
        acked.len()
    );

    let stored = stored_keys(&dir);
    let lost: Vec<_> = acked.difference(&stored).collect();
    println!(
        "stored: {} records; acknowledged but lost: {}",
        stored.len(),
        lost.len()
    );
    assert!(
        lost.is_empty(),
        "{} acknowledged records lost, e.g. {:?}",
        lost.len(),
        lost.first()
    );

    // the restarted server replays the log: the tags are tracked again, health is ok
    let mut server = start(&dir);
    let client = reqwest::Client::new();
    let mut tags = serde_json::Value::Null;
    for _ in 0..250 {
        tags = client
            .get(format!("http://{}/api/v1/tags", server.http))
            .bearer_auth(TOKEN)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if tags.as_array().is_some_and(|t| t.len() == 3) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(40)).await;
    }
    let names: HashSet<&str> = tags
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["tag"].as_str().unwrap())
        .collect();
    assert_eq!(names, HashSet::from(["http-1", "http-2", "mqtt-1"]));

    // SIGTERM: a graceful stop with exit status 0
    let pid = server.child.0.id().to_string();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    let started = Instant::now();
    let status = loop {
        if let Some(status) = server.child.0.try_wait().unwrap() {
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
