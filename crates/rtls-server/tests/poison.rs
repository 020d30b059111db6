//! Poison-proof ingest (issue 22): records whose time cannot be the present are refused at
//! ingest with the reason; a record that makes its partition's tracker fail — an error or a
//! panic — is quarantined (stored apart, counted, listed by the API, published as an event)
//! while the partition tracks the rest, and a restart's replay skips it; a stalled partition
//! turns `/health` to 503; a write without the token is refused before its body is read.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{call, eventually, metric_value, open_sqlite, state, state_on, walk, READ, WRITE};
use rtls_engine::record::Record;
use rtls_engine::tracker::{Output, Tracker};
use rtls_server::pipeline::{unix_s, PipelineConfig, CHECKPOINT};

fn fix(t: f64, tag: &str) -> String {
    format!(
        "{{\"t\": {t}, \"tag\": \"{tag}\", \"kind\": \"fix\", \"position_m\": [5.0, 10.0], \"covariance_m2\": [0.04, 0.0, 0.0, 0.04]}}\n"
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_outside_the_clock_window_or_in_other_units_are_refused_with_the_reason() {
    common::temp_dir("poison-window");
    let state = state_on(
        "poison-window",
        PipelineConfig {
            partitions: 2,
            ..PipelineConfig::default()
        },
    );
    let app = rtls_server::http::router(state.clone());
    let now = unix_s();
    for (t, expected) in [
        (now + 3_600.0, "ahead of the server clock"),
        (now - 7.0 * 86_400.0, "behind the server clock"),
        (12.5, "relative clock"),
        (now * 1e3, "milliseconds"),
        (now * 1e6, "microseconds"),
        (now * 1e9, "nanoseconds"),
    ] {
        let body = format!("{}{}", fix(now, "good-1"), fix(t, "bad-clock"));
        let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &body).await;
        assert_eq!(reply.status, StatusCode::BAD_REQUEST, "t = {t}: {}", reply.text());
        let message = reply.text();
        assert!(message.contains(expected), "t = {t}: {message}");
        assert!(message.contains(":2:"), "names the line: {message}");
    }
    // the window's records refused by reason; nothing of those payloads was stored
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"time_window\"}"),
        3.0
    );
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"format\"}"),
        3.0
    );
    assert_eq!(metric_value(&metrics, "rtls_ingest_records_total"), 0.0);
    // and the server goes on taking good records
    let lines: String = (0..10).map(|k| fix(now - 1.0 + 0.1 * f64::from(k), "good-1")).collect();
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &lines).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    assert!(
        eventually(Duration::from_secs(10), || state.pipeline.live().tag_count() == 1).await,
        "the good tag is tracked"
    );
    state.pipeline.shutdown();
}

/// [`Tracker::push`], except that a record of tag `poison` panics (a bug it would expose) and
/// one of tag `refused` fails with an error.
fn failing_step(tracker: &mut Tracker, record: Record, out: &mut Output) -> rtls_engine::Result<()> {
    match record.tag.as_str() {
        "poison" => panic!("poisoned by record at t = {}", record.time_s),
        "refused" => Err(rtls_engine::EngineError::InvalidParameter {
            name: "record",
            reason: "the test refuses it",
        }),
        _ => tracker.push(record, out),
    }
}

fn failing_config() -> PipelineConfig {
    PipelineConfig {
        partitions: 2,
        live_clock: false,
        track_step: failing_step,
        ..PipelineConfig::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_record_that_fails_its_partition_is_quarantined_and_the_replay_skips_it() {
    let name = "poison-quarantine";
    common::temp_dir(name);
    let state = state_on(name, failing_config());
    let app = rtls_server::http::router(state.clone());
    // the poison in the middle of a walk, in one payload; the erroring record in another
    let walk_lines = walk("miner-1", 1000.0, 10.0);
    let mut lines: Vec<&str> = walk_lines.lines().collect();
    let poison = fix(1004.0, "poison");
    lines.insert(8, poison.trim_end());
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &lines.join("\n"),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &fix(1011.0, "refused"),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    // the walk after the poison is tracked (its partition went on)
    let tracked_to_end = eventually(Duration::from_secs(10), || {
        state.pipeline.live().tag("miner-1").is_some_and(|t| t.time_s >= 1009.0)
    })
    .await;
    assert!(tracked_to_end, "miner-1 tracked to the end of its walk");
    let mut listed = false;
    for _ in 0..100 {
        let list = call(&app, Method::GET, "/api/v1/quarantine", Some(READ), "")
            .await
            .json();
        if list["quarantined"].as_array().is_some_and(|a| a.len() == 2) {
            listed = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(listed, "both records stored apart");
    let list = call(&app, Method::GET, "/api/v1/quarantine", Some(READ), "")
        .await
        .json();
    let entries = list["quarantined"].as_array().expect("array");
    assert_eq!(entries.len(), 2, "{list}");
    assert_eq!(entries[0]["tag"], "poison");
    assert!(
        entries[0]["reason"]
            .as_str()
            .unwrap()
            .starts_with("the tracker panicked: poisoned by record at t = 1004"),
        "{list}"
    );
    assert_eq!(entries[0]["record"]["tag"], "poison", "the record itself: {list}");
    assert_eq!(entries[0]["record"]["t"], 1004.0);
    assert_eq!(entries[1]["tag"], "refused");
    assert!(entries[1]["reason"].as_str().unwrap().contains("the test refuses it"));
    assert!(entries[0]["record_id"].as_i64().unwrap() < entries[1]["record_id"].as_i64().unwrap());
    assert_eq!(
        call(&app, Method::GET, "/api/v1/quarantine", None, "").await.status,
        StatusCode::UNAUTHORIZED,
        "a read credential is needed"
    );
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    assert_eq!(metric_value(&metrics, "rtls_records_quarantined_total"), 2.0);
    let health = call(&app, Method::GET, "/health", None, "").await;
    assert_eq!(health.status, StatusCode::OK, "{}", health.text());
    assert_eq!(health.json()["partitions"].as_array().unwrap().len(), 2);
    let mut has_event = false;
    for _ in 0..100 {
        let events = call(
            &app,
            Method::GET,
            "/api/v1/events?tag=poison&type=record-quarantined",
            Some(READ),
            "",
        )
        .await
        .json();
        if events.as_array().is_some_and(|a| a.len() == 1) {
            assert_eq!(events[0]["reason"], entries[0]["reason"]);
            has_event = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(has_event, "a record-quarantined event is stored");
    state.pipeline.shutdown();

    // a restart that replays the whole ingest log (checkpoint reset) skips both records
    open_sqlite(&common::db_path(name))
        .set_checkpoint(CHECKPOINT, 0)
        .expect("reset the checkpoint");
    let restarted = state_on(name, failing_config());
    let replayed = eventually(Duration::from_secs(10), || {
        restarted
            .pipeline
            .live()
            .tag("miner-1")
            .is_some_and(|t| t.time_s >= 1009.0)
    })
    .await;
    assert!(replayed, "the replay tracks the walk again");
    let app = rtls_server::http::router(restarted.clone());
    // every record replayed: the checkpoint reaches the last one tracked (the walk's last,
    // just before the erroring record, which is the log's last and is skipped)
    let last_id = entries[1]["record_id"].as_i64().unwrap() - 1;
    let mut caught_up = false;
    for _ in 0..100 {
        let health = call(&app, Method::GET, "/health", None, "").await.json();
        if health["tracked_record_id"].as_i64().is_some_and(|id| id >= last_id) {
            caught_up = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(caught_up, "the replay reached the last record");
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    assert_eq!(
        metric_value(&metrics, "rtls_records_quarantined_total"),
        0.0,
        "the replay did not feed the quarantined records again"
    );
    restarted.pipeline.shutdown();
}

/// Sleeps 1.5 s on a record of tag `slow` (a partition stuck in a long computation).
fn slow_step(tracker: &mut Tracker, record: Record, out: &mut Output) -> rtls_engine::Result<()> {
    if record.tag == "slow" {
        std::thread::sleep(Duration::from_millis(1500));
    }
    tracker.push(record, out)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_partition_turns_health_to_503_until_it_comes_round() {
    let state = {
        common::temp_dir("poison-stall");
        state_on(
            "poison-stall",
            PipelineConfig {
                partitions: 2,
                live_clock: false,
                track_step: slow_step,
                stall_after_s: 0.5,
                ..PipelineConfig::default()
            },
        )
    };
    let app = rtls_server::http::router(state.clone());
    assert_eq!(
        call(&app, Method::GET, "/health", None, "").await.status,
        StatusCode::OK
    );
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &fix(10.0, "slow"),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);
    let mut saw_stall = false;
    for _ in 0..50 {
        let health = call(&app, Method::GET, "/health", None, "").await;
        if health.status == StatusCode::SERVICE_UNAVAILABLE {
            let body = health.json();
            assert_eq!(body["status"], "degraded");
            let stalled: Vec<_> = body["partitions"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|p| p["stalled"] == true)
                .collect();
            assert_eq!(stalled.len(), 1, "{body}");
            saw_stall = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(saw_stall, "health reported the stalled partition");
    let recovered = {
        let mut ok = false;
        for _ in 0..60 {
            if call(&app, Method::GET, "/health", None, "").await.status == StatusCode::OK {
                ok = true;
                break;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        ok
    };
    assert!(recovered, "health is 200 again once the partition comes round");
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_default_state_has_partitions_that_are_not_stalled() {
    let state = state("poison-default");
    let app = rtls_server::http::router(state.clone());
    let health = call(&app, Method::GET, "/health", None, "").await.json();
    assert!(health["partitions"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["stalled"] == false && p["silent_s"].as_f64().unwrap() < 1.0));
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_write_without_the_token_is_refused_before_its_body_is_read() {
    use axum::body::Body;
    use axum::http::Request;
    use futures_util::stream::{self, StreamExt};
    use tower::ServiceExt;

    let state = state("poison-body");
    let app = rtls_server::http::router(state.clone());
    for token in [None, Some(READ), Some("guess-the-token")] {
        // a body whose first megabyte arrives and whose end never does
        let endless =
            stream::iter([Ok::<_, std::io::Error>(bytes::Bytes::from(vec![b' '; 1 << 20]))]).chain(stream::pending());
        let mut request = Request::builder().method(Method::POST).uri("/api/v1/measurements");
        if let Some(token) = token {
            request = request.header("authorization", format!("Bearer {token}"));
        }
        let response = tokio::time::timeout(
            Duration::from_secs(2),
            app.clone().oneshot(request.body(Body::from_stream(endless)).unwrap()),
        )
        .await
        .expect("answered without waiting for the body")
        .unwrap();
        let expected = if token.is_none() {
            StatusCode::UNAUTHORIZED
        } else {
            StatusCode::FORBIDDEN
        };
        assert_eq!(response.status(), expected, "token {token:?}");
    }
    state.pipeline.shutdown();
}
