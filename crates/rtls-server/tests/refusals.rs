//! Every refusal is visible (issue 21): a record the tracker cannot use is counted by kind in
//! `/metrics` (and is an event with its reason); unknown routes, wrong methods and omlox
//! operations this hub does not provide answer with an omlox `Error` object, not an empty body
//! or another route's answer.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{call, metric_value, state, READ, WRITE};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_range_the_site_cannot_weigh_is_counted_and_explained() {
    let state = state("refusals-metric");
    let app = rtls_server::http::router(state.clone());
    // the test site's readers state no range noise, and the record states none either
    // (the tag's later fix moves its clock past the range, which is then judged)
    let body = concat!(
        r#"{"t": 1000.0, "tag": "miner-1", "kind": "range", "anchor": "A1", "range_m": 4.2}"#,
        "\n",
        r#"{"t": 1002.0, "tag": "miner-1", "kind": "fix", "position_m": [5.0, 5.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}"#
    );
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), body).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let series = "rtls_records_unused_total{event=\"rejected\",kind=\"range\"}";
    let mut counted = 0.0;
    for _ in 0..100 {
        let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
        counted = metric_value(&metrics, series);
        if counted > 0.0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(counted, 1.0, "the refused record raised the metric");
    // the event is stored by the output thread, after the partition counted it
    let mut events = serde_json::Value::Null;
    for _ in 0..100 {
        events = call(&app, Method::GET, "/api/v1/events?type=rejected", Some(READ), "")
            .await
            .json();
        if events.as_array().is_some_and(|e| !e.is_empty()) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let reason = events[0]["reason"].as_str().unwrap_or_default().to_string();
    assert!(reason.contains("std"), "the event says why: {events}");
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_routes_wrong_methods_and_bad_bodies_answer_omlox_errors() {
    let state = state("refusals-routes");
    let app = rtls_server::http::router(state.clone());
    for (method, path, status) in [
        (Method::GET, "/v2/no-such-thing", StatusCode::NOT_FOUND),
        (Method::PATCH, "/v2/trackables", StatusCode::METHOD_NOT_ALLOWED),
        // routed to its own handler, not taken for a provider id
        (Method::PUT, "/v2/providers/proximities", StatusCode::BAD_REQUEST),
    ] {
        let reply = call(&app, method.clone(), path, Some(WRITE), "").await;
        assert_eq!(reply.status, status, "{method} {path}: {}", reply.text());
        let error = reply.json();
        assert_eq!(error["code"], status.as_u16(), "{error}");
        assert!(error["type"].is_string() && error["message"].is_string(), "{error}");
    }
    state.pipeline.shutdown();
}
