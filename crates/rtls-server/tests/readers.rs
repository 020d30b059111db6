//! Reader health through the router (`GET /api/v1/readers`): what the tracks have learnt of
//! each reader's range offset.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{call, state, READ, WRITE};
use serde_json::Value;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn readers_report_the_range_offsets_the_tracks_learnt() {
    let state = state("api-range-offsets");
    let app = rtls_server::http::router(state.clone());
    // a tag wandering the floor for 60 s, four ranges per 0.25 s; A1's read 0.4 m long (an
    // uncalibrated antenna delay), the others exact up to a few centimetres
    let anchors = [
        ("A1", [0.0, 0.0, 2.5], 0.4),
        ("A2", [30.0, 0.0, 2.5], 0.0),
        ("A3", [30.0, 20.0, 2.5], 0.0),
        ("A4", [0.0, 20.0, 2.5], 0.0),
    ];
    let mut lines = String::new();
    for k in 0..240u32 {
        let t = 3000.0 + 0.25 * f64::from(k);
        let s = 0.25 * f64::from(k);
        let p = [5.0 + 0.3 * s, 10.0 + 6.0 * (0.15 * s).sin(), 0.0];
        for (i, (id, a, offset)) in anchors.iter().enumerate() {
            let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt();
            // deterministic ±4 cm
            let noise = 0.02 * (f64::from((k * 7 + i as u32 * 3) % 5) - 2.0);
            lines.push_str(&format!(
                "{{\"t\": {t}, \"tag\": \"w\", \"kind\": \"range\", \"anchor\": \"{id}\", \"range_m\": {}, \"std_m\": 0.05}}\n",
                d + offset + noise
            ));
        }
    }
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &lines).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let mut readers = Value::Null;
    for _ in 0..200 {
        readers = call(&app, Method::GET, "/api/v1/readers", Some(READ), "").await.json();
        let learnt = readers
            .as_array()
            .is_some_and(|rows| rows.iter().all(|r| r["range_offset"]["tags"] == 1));
        if learnt {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let offset = |id: &str| {
        readers
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["id"] == id)
            .and_then(|r| r["range_offset"]["mean_m"].as_f64())
            .unwrap_or_else(|| panic!("no offset for {id}: {readers:#}"))
    };
    eprintln!(
        "learnt offsets: A1 {:+.3} A2 {:+.3} A3 {:+.3} A4 {:+.3} m",
        offset("A1"),
        offset("A2"),
        offset("A3"),
        offset("A4")
    );
    assert!((offset("A1") - 0.4).abs() < 0.1, "{readers:#}");
    for id in ["A2", "A3", "A4"] {
        assert!(offset(id).abs() < 0.1, "{readers:#}");
    }
    state.pipeline.shutdown();
}
