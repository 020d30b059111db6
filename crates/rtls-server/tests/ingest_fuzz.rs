//! A bounded fuzz of the ingest paths (issue 22): mutated and hostile measurement payloads over
//! HTTP and over MQTT (QoS 1) into a running `rtls serve` (embedded broker, SQLite, the wall
//! clock driving the trackers). It must answer every payload — HTTP with 200 or 4xx, never 5xx;
//! MQTT with a PUBACK each — within seconds, stay healthy (no stalled partition), go on
//! tracking a valid walk afterwards, and stop within seconds. Seeded: a failure repeats.

mod common;

use std::time::{Duration, Instant};

use common::{metric_value, WRITE};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtls_server::config::MqttMode;
use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};

/// Payloads per transport.
const HTTP_CASES: usize = 1_500;
const MQTT_CASES: usize = 800;

fn now_s() -> f64 {
    rtls_server::pipeline::unix_s()
}

/// A valid record line of a random kind at about `t`.
fn valid_line(rng: &mut ChaCha8Rng, t: f64) -> String {
    let tag = format!("fz-{}", rng.gen_range(0..20));
    match rng.gen_range(0..3) {
        0 => format!(
            r#"{{"t": {t:.3}, "tag": "{tag}", "kind": "fix", "position_m": [{:.2}, {:.2}], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#,
            rng.gen_range(0.0..30.0),
            rng.gen_range(0.0..20.0)
        ),
        1 => format!(
            r#"{{"t": {t:.3}, "tag": "{tag}", "kind": "range", "anchor": "A{}", "range_m": {:.2}, "std_m": 0.1}}"#,
            rng.gen_range(1..5),
            rng.gen_range(0.5..30.0)
        ),
        _ => format!(
            r#"{{"t": {t:.3}, "tag": "{tag}", "kind": "velocity", "velocity_mps": [0.5, 0.0], "covariance_m2ps2": [0.04, 0.0, 0.0, 0.04]}}"#
        ),
    }
}

/// Hostile values spliced into a record.
const NASTY: [&str; 16] = [
    "NaN",
    "1e308",
    "-1e308",
    "1e16",
    "1.7e18",
    "-0",
    "\"\"",
    "null",
    "[]",
    "{}",
    "\"\\u0000\"",
    "[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]",
    "true",
    "99999999999999999999999999999",
    "\"\u{1F600}\"",
    "0.000000000000000000001",
];

/// One payload: valid lines, mutated ones, or garbage.
fn payload(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let t = now_s() - rng.gen_range(0.0..1.5);
    let mut line = valid_line(rng, t).into_bytes();
    match rng.gen_range(0..12) {
        // several valid lines (the control: these must be taken)
        0 | 1 => (0..rng.gen_range(1..50))
            .map(|_| valid_line(rng, t))
            .collect::<Vec<_>>()
            .join("\n")
            .into_bytes(),
        // flipped bytes
        2 | 3 => {
            for _ in 0..rng.gen_range(1..4) {
                let at = rng.gen_range(0..line.len());
                line[at] = rng.gen();
            }
            line
        }
        // cut short
        4 => {
            line.truncate(rng.gen_range(0..line.len()));
            line
        }
        // a number replaced by a hostile value
        5 | 6 => {
            let text = String::from_utf8(line).unwrap();
            let numbers: Vec<usize> = text
                .char_indices()
                .filter(|(i, c)| c.is_ascii_digit() && text[..*i].ends_with(": "))
                .map(|(i, _)| i)
                .collect();
            let at = numbers[rng.gen_range(0..numbers.len())];
            let end = text[at..].find([',', ']', '}']).map_or(text.len(), |e| at + e);
            format!(
                "{}{}{}",
                &text[..at],
                NASTY[rng.gen_range(0..NASTY.len())],
                &text[end..]
            )
            .into_bytes()
        }
        // a huge tag, a deep nest, random bytes, an empty body, CR LF line ends
        7 => format!(
            r#"{{"t": {t}, "tag": "{}", "kind": "fix", "position_m": [1, 2], "covariance_m2": [1, 0, 0, 1]}}"#,
            "x".repeat(rng.gen_range(1_000..20_000))
        )
        .into_bytes(),
        8 => format!("{}{}", "[".repeat(5_000), "]".repeat(5_000)).into_bytes(),
        9 => (0..rng.gen_range(0..2_000)).map(|_| rng.gen()).collect(),
        10 => Vec::new(),
        _ => {
            let mut lines = valid_line(rng, t);
            lines.push_str("\r\n");
            lines.push_str(&valid_line(rng, t));
            lines.into_bytes()
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mutated_payloads_over_http_and_mqtt_never_crash_stall_or_lose_the_server() {
    let dir = common::temp_dir("ingest-fuzz");
    let config = common::loopback_config(&dir, MqttMode::Embedded);
    let running = common::serve_on_loopback(common::options(config)).await;
    let http = running.bound.http;
    let mqtt = running.bound.mqtt.expect("the embedded broker");
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(22);

    // HTTP
    let mut statuses = std::collections::BTreeMap::<u16, usize>::new();
    let mut slowest = Duration::ZERO;
    for case in 0..HTTP_CASES {
        let body = payload(&mut rng);
        let started = Instant::now();
        let reply = client
            .post(format!("http://{http}/api/v1/measurements"))
            .bearer_auth(WRITE)
            .body(body.clone())
            .send()
            .await
            .unwrap_or_else(|e| panic!("case {case}: no answer: {e}; body {:?}", String::from_utf8_lossy(&body)));
        slowest = slowest.max(started.elapsed());
        let status = reply.status();
        assert!(
            status.is_success() || status.is_client_error(),
            "case {case}: {status} for {:?}: {}",
            String::from_utf8_lossy(&body),
            reply.text().await.unwrap_or_default()
        );
        *statuses.entry(status.as_u16()).or_default() += 1;
    }
    eprintln!("HTTP answers by status: {statuses:?}; the slowest took {slowest:?}");
    assert!(slowest < Duration::from_secs(5), "the slowest answer took {slowest:?}");
    assert!(
        statuses.get(&200).copied().unwrap_or(0) >= HTTP_CASES / 10,
        "{statuses:?}"
    );
    assert!(
        statuses.get(&400).copied().unwrap_or(0) >= HTTP_CASES / 4,
        "{statuses:?}"
    );

    // MQTT, QoS 1: every payload acknowledged (the invalid ones are explained on the error topic)
    let mut options = MqttOptions::new("fuzz-gateway", mqtt.ip().to_string(), mqtt.port());
    options.set_credentials("fuzz", WRITE);
    options.set_max_packet_size(1 << 20, 1 << 20);
    let (mqtt_client, mut events) = AsyncClient::new(options, 64);
    let publisher = tokio::spawn(async move {
        for _ in 0..MQTT_CASES {
            let body = payload(&mut rng);
            mqtt_client
                .publish("rtls/v1/measurements/fuzz", QoS::AtLeastOnce, false, body)
                .await
                .expect("queued");
        }
        mqtt_client
    });
    let mut acknowledged = 0;
    let deadline = Instant::now() + Duration::from_secs(60);
    while acknowledged < MQTT_CASES {
        let left = deadline.saturating_duration_since(Instant::now());
        match tokio::time::timeout(left, events.poll()).await {
            Ok(Ok(Event::Incoming(Packet::PubAck(_)))) => acknowledged += 1,
            Ok(Ok(_)) => {}
            Ok(Err(e)) => panic!("the MQTT connection failed after {acknowledged} PUBACKs: {e}"),
            Err(_) => panic!("only {acknowledged} of {MQTT_CASES} payloads acknowledged within 60 s"),
        }
    }
    let _client = publisher.await.unwrap();

    // still healthy, still tracking
    let health = client.get(format!("http://{http}/health")).send().await.unwrap();
    assert!(health.status().is_success(), "{}", health.text().await.unwrap());
    let walk_t = now_s() - 1.0;
    let walk: String = (0..6)
        .map(|k| {
            format!(
                "{{\"t\": {:.3}, \"tag\": \"after-fuzz\", \"kind\": \"fix\", \"position_m\": [{}, 5.0], \"covariance_m2\": [0.04, 0.0, 0.0, 0.04]}}\n",
                walk_t + 0.2 * f64::from(k),
                5.0 + 0.2 * f64::from(k)
            )
        })
        .collect();
    let reply = common::post_measurements(&client, http, walk).await;
    assert!(reply.status().is_success());
    let tags = common::poll_text(&client, http, "/api/v1/tags", |tags| tags.contains("after-fuzz")).await;
    let tracked = tags.contains("after-fuzz");
    assert!(tracked, "a valid walk is tracked after the fuzz");
    let metrics = common::get_text(&client, http, "/metrics").await;
    assert_eq!(
        metric_value(&metrics, "rtls_records_quarantined_total"),
        0.0,
        "no tracker failure"
    );
    let stop = running.stop().await;
    assert!(stop < Duration::from_secs(10), "stopped in {stop:?}");
}
