//! Webhooks end to end: the whole server on loopback, a tag walked towards a hazard zone over
//! HTTP ingest, and the tracker's real `hazard-predicted` alarm — then its acknowledgement —
//! POSTed to local receivers: retried after 503s with a growing back-off, one delivery id,
//! signed; refused with 400 and not retried; types not in `events` not sent; counted in
//! `/metrics`; and the stop waits for a hanging webhook no longer than its grace period.

mod common;

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::http::{HeaderMap, StatusCode};
use hmac::{KeyInit, Mac};
use rtls_server::config::{MqttMode, ServerConfig, WebhookSection};
use serde_json::Value;

use common::{walk, Running, READ, WRITE};

const SECRET: &str = "webhook-test-secret";

/// One request a receiver got.
#[derive(Debug, Clone)]
struct Seen {
    path: String,
    at: Instant,
    delivery: String,
    attempt: String,
    event: String,
    signature: Option<String>,
    content_type: String,
    body: Vec<u8>,
}

impl Seen {
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body).expect("a JSON body")
    }
}

/// Receivers on 127.0.0.1:0: `/flaky` answers 503 to the first two requests of each delivery
/// id (counted here, not from the headers), then 200; `/reject` answers 400.
async fn receivers() -> (std::net::SocketAddr, Arc<Mutex<Vec<Seen>>>) {
    let seen: Arc<Mutex<Vec<Seen>>> = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&seen);
    let handler = move |uri: axum::http::Uri, headers: HeaderMap, body: axum::body::Bytes| {
        let log = Arc::clone(&log);
        async move {
            let header = |name: &str| headers.get(name).and_then(|v| v.to_str().ok()).map(String::from);
            let request = Seen {
                path: uri.path().to_string(),
                at: Instant::now(),
                delivery: header("x-rtls-delivery").unwrap_or_default(),
                attempt: header("x-rtls-attempt").unwrap_or_default(),
                event: header("x-rtls-event").unwrap_or_default(),
                signature: header("x-rtls-signature"),
                content_type: header("content-type").unwrap_or_default(),
                body: body.to_vec(),
            };
            let mut log = log.lock().unwrap();
            let earlier = log
                .iter()
                .filter(|s| s.path == request.path && s.delivery == request.delivery)
                .count();
            let status = match (request.path.as_str(), earlier) {
                ("/flaky", 0 | 1) => StatusCode::SERVICE_UNAVAILABLE,
                ("/flaky", _) => StatusCode::OK,
                _ => StatusCode::BAD_REQUEST,
            };
            log.push(request);
            status
        }
    };
    let app = axum::Router::new()
        .route("/flaky", axum::routing::post(handler.clone()))
        .route("/reject", axum::routing::post(handler));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await });
    (address, seen)
}

async fn start(name: &str, webhooks: Vec<WebhookSection>) -> Running {
    let dir = common::temp_dir(name);
    let mut config = ServerConfig::default();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.mqtt.mode = MqttMode::Off;
    config.pipeline.partitions = 1;
    config.pipeline.live_clock = false;
    config.webhooks = webhooks;
    config.validate().unwrap();
    common::serve_on_loopback(common::options(config)).await
}

/// Stops the server; returns how long the stop took.
async fn stop(running: Running) -> Duration {
    running.stop().await
}

/// Polls `condition` every 20 ms for up to 20 s.
async fn eventually(mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + Duration::from_secs(20);
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    condition()
}

async fn get_json(client: &reqwest::Client, url: String) -> Value {
    client
        .get(url)
        .bearer_auth(READ)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

/// The value of `rtls_webhook_deliveries_total{webhook, outcome}` in `/metrics`.
fn deliveries(metrics: &str, webhook: &str, outcome: &str) -> u64 {
    let series = format!("rtls_webhook_deliveries_total{{webhook=\"{webhook}\",outcome=\"{outcome}\"}} ");
    metrics
        .lines()
        .find_map(|line| line.strip_prefix(&series))
        .unwrap_or_else(|| panic!("no {series} in\n{metrics}"))
        .trim()
        .parse()
        .unwrap()
}

/// Each delivery's requests, in arrival order, by delivery id (in order of first arrival).
fn by_delivery(seen: &[Seen], path: &str) -> Vec<(String, Vec<Seen>)> {
    let mut groups: Vec<(String, Vec<Seen>)> = Vec::new();
    for request in seen.iter().filter(|s| s.path == path) {
        match groups.iter_mut().find(|(id, _)| *id == request.delivery) {
            Some((_, requests)) => requests.push(request.clone()),
            None => groups.push((request.delivery.clone(), vec![request.clone()])),
        }
    }
    groups
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tracked_alarm_and_its_acknowledgement_reach_the_webhooks() {
    let (receiver, seen) = receivers().await;
    let flaky = WebhookSection {
        url: format!("http://{receiver}/flaky"),
        name: Some("flaky".into()),
        events: Some(vec!["hazard-predicted".into(), "alarm-acknowledged".into()]),
        secret: Some(SECRET.into()),
        initial_backoff_s: 0.2,
        max_backoff_s: 5.0,
        ..WebhookSection::default()
    };
    let rejecting = WebhookSection {
        url: format!("http://{receiver}/reject"),
        name: Some("rejecting".into()),
        events: Some(vec!["hazard-predicted".into()]),
        initial_backoff_s: 0.05,
        ..WebhookSection::default()
    };
    let running = start("webhooks-e2e", vec![flaky, rejecting]).await;
    let http = running.bound.http;
    let client = reqwest::Client::new();

    // a tag walking at 1 m/s towards the hazard zone x ∈ [14, 18] m, through it and out
    let reply = client
        .post(format!("http://{http}/api/v1/measurements"))
        .bearer_auth(WRITE)
        .body(walk("miner-7", 5000.0, 20.0))
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 200);

    // the hazard alarm: two 503s, then delivered on the third attempt
    let delivered = |seen: &Arc<Mutex<Vec<Seen>>>, event: &str| {
        by_delivery(&seen.lock().unwrap(), "/flaky")
            .into_iter()
            .find(|(_, requests)| requests[0].event == event && requests.len() >= 3)
    };
    assert!(
        eventually(|| delivered(&seen, "hazard-predicted").is_some()).await,
        "no hazard-predicted delivered: {:?}",
        seen.lock().unwrap()
    );
    let (id, attempts) = delivered(&seen, "hazard-predicted").unwrap();
    assert_eq!(attempts.len(), 3, "delivered on the third attempt, not sent again");
    assert!(uuid::Uuid::parse_str(&id).is_ok(), "{id}");
    let numbers: Vec<&str> = attempts.iter().map(|a| a.attempt.as_str()).collect();
    assert_eq!(numbers, ["1", "2", "3"]);
    assert!(
        attempts.iter().all(|a| a.body == attempts[0].body),
        "the same body each time"
    );
    assert!(attempts.iter().all(|a| a.content_type == "application/json"));
    // the body is the alarm as stored, with its alarm_id
    let body = attempts[0].json();
    assert_eq!(
        (&body["type"], &body["tag"], &body["zone"]),
        (
            &Value::from("hazard-predicted"),
            &Value::from("miner-7"),
            &Value::from("forklift-lane")
        ),
        "{body}"
    );
    assert!(body["time_to_entry_s"].as_f64().unwrap() > 0.0, "{body}");
    let alarm_id = body["alarm_id"].as_str().expect("an alarm_id").to_string();
    let mut stored = Value::Null;
    for _ in 0..1000 {
        let alarms = get_json(&client, format!("http://{http}/api/v1/alarms?tag=miner-7")).await;
        if let Some(alarm) = alarms
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["alarm_id"] == alarm_id.as_str())
        {
            stored = alarm.clone();
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(
        (&stored["type"], &stored["t"]),
        (&body["type"], &body["t"]),
        "{alarm_id} stored"
    );
    // signed with the secret: HMAC-SHA256 of the exact body
    let mut mac = hmac::Hmac::<sha2::Sha256>::new_from_slice(SECRET.as_bytes()).unwrap();
    mac.update(&attempts[0].body);
    let signature = attempts[0].signature.as_deref().expect("X-Rtls-Signature");
    let hex = signature.strip_prefix("sha256=").expect("sha256=<hex>");
    let bytes: Vec<u8> = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
        .collect();
    mac.verify_slice(&bytes).expect("the signature verifies");
    // waits of 75–100 % of 0.2 s, then of 0.4 s: the back-off grew (timers never fire early)
    let (first_wait, second_wait) = (attempts[1].at - attempts[0].at, attempts[2].at - attempts[1].at);
    assert!(first_wait >= Duration::from_millis(150), "{first_wait:?}");
    assert!(second_wait >= Duration::from_millis(300), "{second_wait:?}");
    assert!(second_wait > first_wait, "{first_wait:?} then {second_wait:?}");

    // the operator acknowledges: the acknowledgement follows, the same way
    let reply = client
        .post(format!("http://{http}/api/v1/alarms/{alarm_id}/acknowledge"))
        .bearer_auth(WRITE)
        .json(&serde_json::json!({"by": "shift lead"}))
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 200);
    assert!(eventually(|| delivered(&seen, "alarm-acknowledged").is_some()).await);
    let (_, ack) = delivered(&seen, "alarm-acknowledged").unwrap();
    let ack_body = ack[0].json();
    assert_eq!(ack_body["type"], "alarm-acknowledged");
    assert_eq!(ack_body["alarm_id"], alarm_id.as_str());
    assert_eq!(ack_body["by"], "shift lead");
    assert!(ack[0].signature.is_some());

    // the walk also cleared the alarm, which neither webhook asked for
    let cleared = get_json(
        &client,
        format!("http://{http}/api/v1/events?tag=miner-7&type=hazard-cleared"),
    )
    .await;
    assert!(!cleared.as_array().unwrap().is_empty(), "the walk clears the alarm");

    // the counters, once every delivery made so far has its outcome
    let mut metrics = String::new();
    for _ in 0..1000 {
        metrics = client
            .get(format!("http://{http}/metrics"))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        let seen = seen.lock().unwrap().clone();
        if deliveries(&metrics, "flaky", "delivered") == by_delivery(&seen, "/flaky").len() as u64
            && deliveries(&metrics, "rejecting", "failed") == by_delivery(&seen, "/reject").len() as u64
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    stop(running).await;

    let seen = seen.lock().unwrap().clone();
    let flaky_deliveries = by_delivery(&seen, "/flaky");
    let rejected = by_delivery(&seen, "/reject");
    let hazards = flaky_deliveries
        .iter()
        .filter(|(_, r)| r[0].event == "hazard-predicted")
        .count();
    assert!(hazards >= 1);
    // only the types asked for
    assert!(flaky_deliveries
        .iter()
        .all(|(_, r)| matches!(r[0].event.as_str(), "hazard-predicted" | "alarm-acknowledged")));
    assert!(seen.iter().all(|s| s.event == s.json()["type"].as_str().unwrap()));
    assert!(rejected.iter().all(|(_, r)| r[0].event == "hazard-predicted"));
    // in order: each delivery's attempts are contiguous (retried before the next is sent)
    let flaky_order: Vec<&str> = seen
        .iter()
        .filter(|s| s.path == "/flaky")
        .map(|s| s.delivery.as_str())
        .collect();
    let mut runs = flaky_order.clone();
    runs.dedup();
    assert_eq!(runs.len(), flaky_deliveries.len(), "interleaved: {flaky_order:?}");
    // a 400 is not retried; the rejecting webhook got the hazard alarms, once each, unsigned
    assert_eq!(rejected.len(), hazards);
    assert!(rejected.iter().all(|(_, r)| r.len() == 1 && r[0].attempt == "1"));
    assert!(rejected.iter().all(|(_, r)| r[0].signature.is_none()));
    // counted
    let acknowledged = flaky_deliveries.len() - hazards;
    assert_eq!(acknowledged, 1);
    assert_eq!(
        deliveries(&metrics, "flaky", "delivered"),
        flaky_deliveries.len() as u64
    );
    assert_eq!(
        deliveries(&metrics, "flaky", "retried"),
        2 * flaky_deliveries.len() as u64
    );
    assert_eq!(deliveries(&metrics, "flaky", "failed"), 0);
    assert_eq!(deliveries(&metrics, "rejecting", "failed"), hazards as u64);
    assert_eq!(deliveries(&metrics, "rejecting", "retried"), 0);
    assert_eq!(deliveries(&metrics, "rejecting", "dropped"), 0);
}

/// A webhook that never answers does not hold the server: the stop gives it 2 s, then goes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_stop_waits_for_a_hanging_webhook_two_seconds_at_most() {
    // connections wait in the listen backlog: requests are sent, never answered
    let hang = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let hanging = WebhookSection {
        url: format!("http://{}/hook", hang.local_addr().unwrap()),
        timeout_s: 60.0,
        ..WebhookSection::default()
    };
    let running = start("webhooks-stop", vec![hanging]).await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    let reply = client
        .post(format!("http://{http}/api/v1/measurements"))
        .bearer_auth(WRITE)
        .body(walk("miner-9", 8000.0, 20.0))
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 200);
    let alarms = || async {
        get_json(&client, format!("http://{http}/api/v1/alarms?tag=miner-9"))
            .await
            .as_array()
            .map_or(0, Vec::len)
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    while alarms().await == 0 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(alarms().await > 0, "an alarm to deliver");
    let took = stop(running).await;
    assert!(took >= Duration::from_secs(2), "the grace period was given: {took:?}");
    assert!(took < Duration::from_secs(10), "{took:?}");
    drop(hang);
}
