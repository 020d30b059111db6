//! The vendor adapters through the router (`POST /api/v1/adapters/{vendor}`), with the
//! vendors' published example messages (sources in `src/adapters/`): auth, refusals counted by
//! reason, field-level errors, and the fixes stored and tracked. Zebra's hub read over TCP:
//! tests/zebra_hub.rs.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use bytes::Bytes;
use common::{call, eventually, metric_value, state, READ, WRITE};
use rtls_server::sink::{IngestOrder, MeasurementSink};
use serde_json::json;

/// Sewio RTLS Studio's WebSockets connector documentation: tag 18's position.
const SEWIO_POSITION: &str = r#"{"body":{"id":"18","datastreams":[{"id":"posX","current_value":" 6.34","at":"2016-10-18 14:16:56.365"},{"id":"posY","current_value":" 2.27","at":"2016-10-18 14:16:56.365"},{"id":"clr","current_value":" 0.10","at":"2016-10-18 14:16:56.365"}]},"resource":"\/feeds\/18"}"#;
/// The same page: tag 1's battery update (no position).
const SEWIO_BATTERY: &str = r#"{"body":{"id":"1","datastreams":[{"id":"battery_level","current_value":"77%","at":"2016-10-18 15:27:38.606"},{"id":"firmware_version","current_value":"3.115","at":"2016-10-18 15:27:38.606"}]},"resource":"\/feeds\/1"}"#;
/// The Zebra Dart RTLS User Guide's example output (page 85), one packet per line.
const ZEBRA_EXAMPLE: &str = include_str!("../src/adapters/zebra_dart_example.txt");
/// The Quuppa push sample (DefaultLocation format).
const QUUPPA: &str = r##"{"tagId": "d10000001111", "tagName": null, "color": "#FF0000", "tagGroupName": null, "locationType": "position", "locationMovementStatus": "stationary", "locationRadius": 0.09, "location": [-1.09, 0.38, 1.0], "locationTS": 1641888440139, "locationCoordSysId": "3e7c4371-42be-4019-b7c0-ec2012d448ad", "locationCoordSysName": "CoordSys001"}"##;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vendor_messages_are_authorised_parsed_counted_and_tracked() {
    let state = state("api-adapters");
    let app = rtls_server::http::router(state.clone());
    let route = "/api/v1/adapters/sewio";

    assert_eq!(
        call(&app, Method::POST, route, None, SEWIO_POSITION).await.status,
        StatusCode::UNAUTHORIZED
    );
    assert_eq!(
        call(&app, Method::POST, route, Some(READ), SEWIO_POSITION).await.status,
        StatusCode::FORBIDDEN
    );
    let reply = call(&app, Method::POST, "/api/v1/adapters/acme", Some(WRITE), SEWIO_POSITION).await;
    assert_eq!(reply.status, StatusCode::NOT_FOUND);
    assert!(
        reply.text().contains("pozyx, quuppa, sewio, zebra, openrtls, generic"),
        "{}",
        reply.text()
    );

    // the generic adapter without [adapters.generic] says what to configure
    let reply = call(&app, Method::POST, "/api/v1/adapters/generic", Some(WRITE), QUUPPA).await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    assert!(reply.text().contains("[adapters.generic]"), "{}", reply.text());

    // a malformed message names the field; nothing is stored
    let bad = QUUPPA.replace("-1.09", "\"west\"");
    let reply = call(&app, Method::POST, "/api/v1/adapters/quuppa", Some(WRITE), &bad).await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    let message = reply.json()["message"].as_str().unwrap().to_string();
    assert!(
        message.contains("[0].location[0]: expected a finite number"),
        "{message}"
    );
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 0);

    // a battery update is refused with its reason, not dropped silently
    let reply = call(&app, Method::POST, route, Some(WRITE), SEWIO_BATTERY).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    assert_eq!(reply.json()["accepted"], json!(0));
    assert_eq!(reply.json()["refused"][0]["reason"], json!("no_position"));
    assert_eq!(reply.json()["refused"][0]["tag"], json!("1"));

    // tag 18's position, and the same message 0.5 s later: a confirmed track at (6.34, 2.27)
    for message in [SEWIO_POSITION.to_string(), SEWIO_POSITION.replace("56.365", "56.865")] {
        let reply = call(&app, Method::POST, route, Some(WRITE), &message).await;
        assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
        assert_eq!(reply.json(), json!({ "accepted": 1, "refused": [] }));
    }
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 2);
    let live = state.pipeline.live().clone();
    assert!(
        eventually(Duration::from_secs(10), || live.tag("18").is_some()).await,
        "tag 18 was not tracked"
    );
    let tag = live.tag("18").unwrap();
    assert!(
        (tag.position_m[0] - 6.34).abs() < 0.05 && (tag.position_m[1] - 2.27).abs() < 0.05,
        "{:?}",
        tag.position_m
    );
    assert!((tag.time_s - 1_476_800_216.865).abs() < 0.6, "{}", tag.time_s);

    // over MQTT the sink reads a vendor topic with its adapter: a Quuppa fix, stored
    let sink: &dyn MeasurementSink = &state.pipeline;
    let stored = sink
        .ingest(
            "mqtt:rtls/v1/adapters/quuppa/qpe-1",
            Bytes::from_static(QUUPPA.as_bytes()),
            &mut IngestOrder::default(),
        )
        .await;
    assert_eq!(stored, Ok(1));
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 3);
    let presence = QUUPPA.replace(r#""locationType": "position""#, r#""locationType": "presence""#);
    let stored = sink
        .ingest(
            "mqtt:rtls/v1/adapters/quuppa/qpe-1",
            Bytes::from(presence),
            &mut IngestOrder::default(),
        )
        .await;
    assert_eq!(stored, Ok(0));

    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"no_position\"}"),
        2.0
    );
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"format\"}"),
        2.0
    );
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zebra_lines_are_fixes_refusals_counted_and_a_bad_line_costs_only_itself() {
    let state = state("api-adapters-zebra");
    let app = rtls_server::http::router(state.clone());
    let route = "/api/v1/adapters/zebra";

    // the guide's example (metres, the default unit): 7 locates stored, 11 N packets and a P
    // packet refused with their line and reason
    let reply = call(&app, Method::POST, route, Some(WRITE), ZEBRA_EXAMPLE).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let answer = reply.json();
    assert_eq!(answer["accepted"], json!(7));
    let refused = answer["refused"].as_array().unwrap();
    assert_eq!(refused.len(), 12);
    assert!(refused.iter().all(|r| r["reason"] == "no_position"), "{answer}");
    let presence = refused.iter().find(|r| r["at"] == "line 17").unwrap();
    assert_eq!(presence["tag"], json!("00210F51"));
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 7);

    // a malformed line among good ones: listed as `format`, the others stored
    let lines = "R,00210E2C,24.45,15.25,2.59,5,1433877486.442,4,*,G0.9\nT,0021F7B1,29.53,north,1.52,12,1433877486.430,4,*,G0.73\n";
    let reply = call(&app, Method::POST, route, Some(WRITE), lines).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    assert_eq!(reply.json()["accepted"], json!(1));
    assert_eq!(
        reply.json()["refused"],
        json!([{"at": "line 2", "tag": "0021F7B1", "reason": "format",
                "detail": "line 2 <Y>: expected a number (m), got \"north\""}])
    );
    // a payload of malformed lines only: 400 naming the field, nothing stored
    let reply = call(&app, Method::POST, route, Some(WRITE), "T,0021F7B1,29.53\n").await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    let message = reply.json()["message"].as_str().unwrap().to_string();
    assert!(message.contains("line 1 <Y>: required field is missing"), "{message}");
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 8);

    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"no_position\"}"),
        12.0
    );
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"format\"}"),
        2.0
    );
    state.pipeline.shutdown();
}
