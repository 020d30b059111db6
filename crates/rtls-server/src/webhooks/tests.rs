//! The dispatcher against a local receiver: filtering, retries, `Retry-After`, giving up,
//! drops (queue full, hub lag, shutdown) — without a server. The whole path, from a tracked
//! alarm to a signed POST, is in `tests/webhooks.rs`.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use serde_json::{json, Value};
use tokio::sync::broadcast;

use super::delivery::{classify, parse_retry_after, Verdict};
use super::*;

/// What the receiver saw of one request.
#[derive(Debug, Clone)]
struct Seen {
    at: Instant,
    delivery: String,
    attempt: u32,
    body: Value,
}

type Answer = Arc<dyn Fn(&Seen) -> Response + Send + Sync>;

/// A receiver on 127.0.0.1:0 answering each request with `answer`; returns its URL and what
/// it saw.
async fn receiver(answer: Answer) -> (reqwest::Url, Arc<Mutex<Vec<Seen>>>) {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&seen);
    let app = axum::Router::new().route(
        "/hook",
        axum::routing::post(move |headers: HeaderMap, body: axum::body::Bytes| {
            let (log, answer) = (Arc::clone(&log), Arc::clone(&answer));
            async move {
                let header = |name: &str| {
                    headers
                        .get(name)
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("")
                        .to_string()
                };
                let request = Seen {
                    at: Instant::now(),
                    delivery: header("x-rtls-delivery"),
                    attempt: header("x-rtls-attempt").parse().unwrap_or(0),
                    body: serde_json::from_slice(&body).unwrap_or(Value::Null),
                };
                log.lock().unwrap().push(request.clone());
                answer(&request)
            }
        }),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await });
    (format!("http://{address}/hook").parse().unwrap(), seen)
}

fn webhook(url: reqwest::Url, events: &[&str]) -> Webhook {
    Webhook {
        name: "test".into(),
        url,
        events: events.iter().map(|e| (*e).to_string()).collect(),
        secret: None,
        timeout: Duration::from_secs(5),
        max_attempts: 3,
        initial_backoff: Duration::from_millis(10),
        max_backoff: Duration::from_millis(50),
    }
}

fn alarm(kind: &str, id: usize) -> HubMessage {
    let event = if kind == "lost" || kind == "recovered" {
        json!({"type": "lifecycle", "event": kind, "t": id, "tag": "m1", "alarm_id": format!("a-{id}")})
    } else {
        json!({"type": kind, "t": id, "tag": "m1", "zone": "pit", "alarm_id": format!("a-{id}")})
    };
    HubMessage::Extension {
        topic: Topic::RtlsAlarms,
        event,
    }
}

fn count(metrics: &Metrics, outcome: &str) -> u64 {
    metrics
        .webhook_deliveries
        .get_or_create(&vec![
            ("webhook".into(), "test".into()),
            ("outcome".into(), outcome.into()),
        ])
        .get()
}

/// Polls `condition` every 10 ms for up to 10 s.
async fn eventually(mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    condition()
}

#[test]
fn the_backoff_doubles_up_to_the_cap_and_the_jitter_only_shortens_it() {
    let (initial, max) = (Duration::from_secs(1), Duration::from_secs(60));
    let waits: Vec<f64> = (1..=8)
        .map(|retry| backoff(retry, initial, max, None, 1.0).as_secs_f64())
        .collect();
    assert_eq!(waits, [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 60.0, 60.0]);
    assert_eq!(backoff(3, initial, max, None, 0.0), Duration::from_secs(3));
    assert_eq!(backoff(1000, initial, max, None, 0.5).as_secs_f64(), 52.5);
    // Retry-After wins, capped, without jitter
    assert_eq!(
        backoff(1, initial, max, Some(Duration::from_secs(7)), 0.0),
        Duration::from_secs(7)
    );
    assert_eq!(backoff(1, initial, max, Some(Duration::from_secs(3600)), 0.0), max);
    for _ in 0..100 {
        let j = super::delivery::jitter();
        assert!((0.0..1.0).contains(&j), "{j}");
    }
}

#[test]
fn answers_are_delivered_retried_or_refused() {
    let retry_after = axum::http::HeaderValue::from_static("3");
    let verdict = |status: u16, after: Option<&axum::http::HeaderValue>| {
        classify(StatusCode::from_u16(status).unwrap(), after, "")
    };
    for status in [200, 201, 202, 204] {
        assert_eq!(verdict(status, None), Verdict::Delivered, "{status}");
    }
    for status in [408, 429, 500, 502, 503, 504] {
        assert!(
            matches!(verdict(status, None), Verdict::Retry { after: None, .. }),
            "{status}"
        );
    }
    assert!(matches!(
        verdict(429, Some(&retry_after)),
        Verdict::Retry { after: Some(d), .. } if d == Duration::from_secs(3)
    ));
    for status in [301, 302, 400, 401, 403, 404, 410, 422] {
        assert!(
            matches!(verdict(status, Some(&retry_after)), Verdict::Failed(_)),
            "{status}"
        );
    }
    let date = axum::http::HeaderValue::from_static("Wed, 21 Oct 2026 07:28:00 GMT");
    assert_eq!(parse_retry_after(&date), None);
}

#[test]
fn lost_and_recovered_are_named_by_their_lifecycle_event() {
    let HubMessage::Extension { event, .. } = alarm("lost", 1) else {
        unreachable!()
    };
    assert_eq!(event_type(&event), Some("lost"));
    assert_eq!(
        event_type(&json!({"type": "hazard-predicted"})),
        Some("hazard-predicted")
    );
    assert_eq!(event_type(&json!({"type": "lifecycle"})), None);
    for kind in DEFAULT_EVENT_TYPES {
        assert!(EVENT_TYPES.contains(&kind));
    }
}

#[tokio::test]
async fn only_the_types_in_events_on_the_alarm_topic_are_sent() {
    let (url, seen) = receiver(Arc::new(|_| StatusCode::OK.into_response())).await;
    let (hub, _) = broadcast::channel(64);
    let metrics = Metrics::new();
    let dispatcher = Dispatcher::start(vec![webhook(url, &["lost"])], hub.subscribe(), &metrics).unwrap();
    for message in [
        alarm("hazard-predicted", 1),
        alarm("recovered", 2),
        alarm("lost", 3),
        HubMessage::Extension {
            topic: Topic::RtlsEvents,
            event: json!({"type": "lifecycle", "event": "lost", "tag": "m1"}),
        },
        HubMessage::Location {
            tag: "m1".into(),
            time_s: 0.0,
            location: Arc::new(
                serde_json::from_value(json!({
                    "position": {"type": "Point", "coordinates": [1.0, 2.0]},
                    "source": "test", "provider_type": "uwb", "provider_id": "m1"
                }))
                .unwrap(),
            ),
        },
    ] {
        hub.send(Arc::new(message)).unwrap();
    }
    assert!(eventually(|| count(&metrics, "delivered") == 1).await);
    dispatcher.shutdown().await;
    let seen = seen.lock().unwrap();
    assert_eq!(seen.len(), 1, "{seen:?}");
    assert_eq!(seen[0].body["alarm_id"], "a-3");
    assert_eq!(count(&metrics, "dropped"), 0);
}

#[tokio::test]
async fn retry_after_is_honoured_up_to_max_backoff_and_the_last_attempt_gives_up() {
    // 429 with Retry-After: 30 s, capped at max_backoff = 0.3 s; then always 503
    let (url, seen) = receiver(Arc::new(|request: &Seen| {
        if request.attempt == 1 {
            (StatusCode::TOO_MANY_REQUESTS, [("retry-after", "30")]).into_response()
        } else {
            StatusCode::SERVICE_UNAVAILABLE.into_response()
        }
    }))
    .await;
    let (hub, _) = broadcast::channel(64);
    let metrics = Metrics::new();
    let mut hook = webhook(url, &["hazard-predicted"]);
    hook.max_backoff = Duration::from_millis(300);
    let dispatcher = Dispatcher::start(vec![hook], hub.subscribe(), &metrics).unwrap();
    hub.send(Arc::new(alarm("hazard-predicted", 1))).unwrap();
    assert!(eventually(|| count(&metrics, "failed") == 1).await);
    dispatcher.shutdown().await;
    let seen = seen.lock().unwrap();
    let attempts: Vec<u32> = seen.iter().map(|s| s.attempt).collect();
    assert_eq!(attempts, [1, 2, 3], "max_attempts = 3");
    assert!(seen.iter().all(|s| s.delivery == seen[0].delivery));
    let waited = seen[1].at - seen[0].at;
    // the back-off alone would be ≤ 10 ms
    assert!(waited >= Duration::from_millis(300), "{waited:?}");
    assert!(waited < Duration::from_secs(10), "Retry-After capped: {waited:?}");
    assert_eq!((count(&metrics, "retried"), count(&metrics, "delivered")), (2, 0));
}

/// A receiver that never answers, a queue of 2: of 5 events 3 are dropped at once (queue full),
/// and at shutdown the one in flight and the one queued are dropped after the grace period.
#[tokio::test]
async fn a_full_queue_and_the_shutdown_drop_events_and_count_them() {
    // connections wait in the listen backlog: the request is sent, never answered
    let hang = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let hang_url: reqwest::Url = format!("http://{}/hook", hang.local_addr().unwrap()).parse().unwrap();
    let (hub, _) = broadcast::channel(64);
    let metrics = Metrics::new();
    let mut hook = webhook(hang_url, &["hazard-predicted"]);
    hook.timeout = Duration::from_secs(30);
    let dispatcher =
        Dispatcher::start_with(vec![hook], hub.subscribe(), &metrics, 2, Duration::from_millis(200)).unwrap();
    // the tasks have not run yet (one thread): the feeder finds all five at once
    for id in 0..5 {
        hub.send(Arc::new(alarm("hazard-predicted", id))).unwrap();
    }
    assert!(eventually(|| count(&metrics, "dropped") == 3).await);
    let started = Instant::now();
    dispatcher.shutdown().await;
    assert!(started.elapsed() < Duration::from_secs(2), "{:?}", started.elapsed());
    assert_eq!(count(&metrics, "dropped"), 5);
    assert_eq!((count(&metrics, "delivered"), count(&metrics, "failed")), (0, 0));
    drop(hang);
}

/// Hub messages the feeder missed (it fell behind a ring buffer of 16) are counted as dropped.
#[tokio::test]
async fn messages_missed_on_the_hub_are_counted_as_dropped() {
    let (url, seen) = receiver(Arc::new(|_| StatusCode::NO_CONTENT.into_response())).await;
    let (hub, _) = broadcast::channel(16);
    let metrics = Metrics::new();
    let dispatcher = Dispatcher::start(vec![webhook(url, &["no-coverage"])], hub.subscribe(), &metrics).unwrap();
    for id in 0..40 {
        hub.send(Arc::new(alarm("no-coverage", id))).unwrap();
    }
    assert!(eventually(|| count(&metrics, "delivered") == 16).await);
    dispatcher.shutdown().await;
    assert_eq!(count(&metrics, "dropped"), 24);
    // in order: the 16 newest, oldest first
    let ids: Vec<String> = seen
        .lock()
        .unwrap()
        .iter()
        .map(|s| s.body["alarm_id"].as_str().unwrap().to_string())
        .collect();
    let expected: Vec<String> = (24..40).map(|id| format!("a-{id}")).collect();
    assert_eq!(ids, expected);
}
