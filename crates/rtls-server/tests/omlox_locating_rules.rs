//! A trackable's `locating_rules` decide which of its providers' locations it takes: a cart
//! with a UWB tag (accuracy 0.3 m) and a BLE beacon (provider type `ibeacon`, accuracy 3 m)
//! and the rules `type = 'uwb' AND accuracy < 1` (priority 10) and `type = 'ibeacon'`
//! (priority 1) — its REST location and motion through the router, its WebSocket motions and
//! fence events on the whole server on loopback; and rules that do not parse are refused.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{assert_omlox_error, call, call_json, eventually, post_created, pushed_location, state, READ, WRITE};
use futures_util::{SinkExt, StreamExt};
use rtls_server::config::MqttMode;
use rtls_server::omlox::time::parse_timestamp;
use rtls_server::omlox::Trackable;
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::Message;

const UWB: &str = "cart-uwb";
const BLE: &str = "cart-ble";

/// The UWB tag's push at `t`: along y = 5 m, `accuracy` m.
fn uwb_at(t: f64, accuracy: f64) -> Value {
    let mut location = pushed_location(UWB, [2.0 + (t - 3000.0) * 0.5, 5.0], t);
    location["accuracy"] = json!(accuracy);
    location
}

/// The beacon's push at `t`: along y = 20 m, 3 m accuracy.
fn ble_at(t: f64) -> Value {
    let mut location = pushed_location(BLE, [2.0 + (t - 3000.0) * 0.5, 20.0], t);
    location["provider_type"] = json!("ibeacon");
    location["accuracy"] = json!(3.0);
    location
}

fn cart_with(rules: &Value) -> Value {
    json!({"type": "omlox", "name": "Cart", "location_providers": [UWB, BLE], "locating_rules": rules})
}

async fn push(app: &axum::Router, locations: &[Value]) {
    let body = Value::Array(locations.to_vec()).to_string();
    let reply = call(app, Method::PUT, "/v2/providers/locations", Some(WRITE), &body).await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
}

/// Waits until the tag's latest location is its push at `t` or later, and the beacon's at
/// `t + 0.5` or later.
async fn settled(state: &rtls_server::http::AppState, t: f64) {
    let live = state.pipeline.live().clone();
    let both = eventually(Duration::from_secs(10), || {
        live.tag(UWB).is_some_and(|s| s.time_s >= t) && live.tag(BLE).is_some_and(|s| s.time_s >= t + 0.5)
    })
    .await;
    assert!(both, "{:?} {:?}", live.tag(UWB), live.tag(BLE));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_cart_follows_its_uwb_tag_while_it_qualifies_and_its_beacon_when_only_that_does() {
    let state = state("locating-rules");
    let app = rtls_server::http::router(state.clone());
    let rules = json!([
        {"expression": "type = 'uwb' AND accuracy < 1", "priority": 10},
        {"expression": "type = 'ibeacon'", "priority": 1}
    ]);
    let cart = post_created(&app, "/v2/trackables", &cart_with(&rules)).await;
    assert_eq!(cart["locating_rules"], rules, "kept as given");
    let id = cart["id"].as_str().unwrap().to_string();
    // and one without rules on the same providers: it takes the newest of them
    let plain = json!({"type": "omlox", "location_providers": [UWB, BLE]});
    let plain = post_created(&app, "/v2/trackables", &plain).await["id"]
        .as_str()
        .unwrap()
        .to_string();

    // both push at 1 Hz, the beacon 0.5 s after the tag: the beacon's is always the newest
    for k in 0..8 {
        let t = 3000.0 + f64::from(k);
        push(&app, &[uwb_at(t, 0.3), ble_at(t + 0.5)]).await;
    }
    // (on the data clock the newest push of each partition waits for a later one)
    settled(&state, 3006.0).await;
    let location = call_json(&app, &format!("/v2/trackables/{id}/location")).await;
    assert_eq!(location["provider_id"], UWB, "{location}");
    assert_eq!(location["provider_type"], "uwb");
    assert_eq!(location["position"]["coordinates"][1], 5.0, "{location}");
    let motion = call_json(&app, &format!("/v2/trackables/{id}/motion")).await;
    assert_eq!(motion["location"]["provider_id"], UWB, "{motion}");
    // without rules, the newest: the beacon's
    let location = call_json(&app, &format!("/v2/trackables/{plain}/location")).await;
    assert_eq!(location["provider_id"], BLE, "{location}");

    // the tag's accuracy degrades to 5 m: it matches no rule, and only the beacon qualifies
    for k in 8..12 {
        let t = 3000.0 + f64::from(k);
        push(&app, &[uwb_at(t, 5.0), ble_at(t + 0.5)]).await;
    }
    settled(&state, 3010.0).await;
    let location = call_json(&app, &format!("/v2/trackables/{id}/location")).await;
    assert_eq!(location["provider_id"], BLE, "{location}");
    assert_eq!(location["position"]["coordinates"][1], 20.0, "{location}");
    let motions = call_json(&app, "/v2/trackables/motions").await;
    let mine = motions
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["id"] == id.as_str())
        .unwrap_or_else(|| panic!("{motions}"));
    assert_eq!(mine["location"]["provider_id"], BLE, "{mine}");

    // it recovers: the tag is taken again, though the beacon's location is newer
    for k in 12..14 {
        let t = 3000.0 + f64::from(k);
        push(&app, &[uwb_at(t, 0.3), ble_at(t + 0.5)]).await;
    }
    settled(&state, 3012.0).await;
    let location = call_json(&app, &format!("/v2/trackables/{id}/location")).await;
    assert_eq!(location["provider_id"], UWB, "{location}");

    // rules nothing matches: no location (404), though both providers have one
    let mut none = cart_with(&json!([{"expression": "type = 'gps'", "priority": 1}]));
    none["id"] = json!(id);
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/trackables/{id}"),
        Some(WRITE),
        &none.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/trackables/{id}/location"),
        Some(READ),
        "",
    )
    .await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "no location matches a rule");
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rule_that_does_not_parse_is_refused_naming_the_rule_and_the_position() {
    let state = state("locating-rules-refused");
    let app = rtls_server::http::router(state.clone());
    let rules = json!([
        {"expression": "type = 'uwb'", "priority": 2},
        {"expression": "type = 'uwb' AND", "priority": 1}
    ]);
    let reply = call(
        &app,
        Method::POST,
        "/v2/trackables",
        Some(WRITE),
        &cart_with(&rules).to_string(),
    )
    .await;
    let field = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "a rule ending in AND");
    assert_eq!(field.as_deref(), Some("locating_rules[1].expression"));
    let message = reply.json()["message"].as_str().unwrap().to_string();
    assert!(
        message.contains("`type = 'uwb' AND`") && message.contains("at character 17"),
        "{message}"
    );
    assert_eq!(call_json(&app, "/v2/trackables").await, json!([]), "nothing created");

    // a replacement too; the stored trackable stays as it was
    let good = json!([{"expression": "accuracy < 1", "priority": 1}]);
    let stored = post_created(&app, "/v2/trackables", &cart_with(&good)).await;
    let id = stored["id"].as_str().unwrap();
    for (expression, says) in [
        ("accuracy <", "at character 11"),
        ("colour = 'red'", "unknown property `colour`"),
        ("type = 'ble'", "is not a provider type"),
    ] {
        let mut bad = cart_with(&json!([{"expression": expression, "priority": 1}]));
        bad["id"] = json!(id);
        let reply = call(
            &app,
            Method::PUT,
            &format!("/v2/trackables/{id}"),
            Some(WRITE),
            &bad.to_string(),
        )
        .await;
        let field = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, expression);
        assert_eq!(field.as_deref(), Some("locating_rules[0].expression"));
        assert!(
            reply.json()["message"].as_str().unwrap().contains(says),
            "{}",
            reply.text()
        );
    }
    assert_eq!(call_json(&app, &format!("/v2/trackables/{id}")).await, stored);
    state.pipeline.shutdown();
}

/// The cart registered at the start of the loopback server.
const CART: &str = "0c1a2b3c-0000-4000-8000-0000000000c1";

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn next_json(socket: &mut Socket) -> Value {
    loop {
        let message = tokio::time::timeout(Duration::from_secs(20), socket.next())
            .await
            .expect("a message within 20 s");
        if let Some(Ok(Message::Text(text))) = message {
            return serde_json::from_str(&text).unwrap();
        }
    }
}

/// The time of a location's `timestamp_generated`, s.
fn time_of(location: &Value) -> f64 {
    parse_timestamp(location["timestamp_generated"].as_str().unwrap(), "t").unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_carts_motions_and_fence_events_follow_the_provider_its_rules_take() {
    let dir = common::temp_dir("locating-rules-ws");
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.pipeline.live_clock = false;
    config.pipeline.partitions = 2;
    let rules = json!([
        {"expression": "type = 'uwb' AND accuracy < 1", "priority": 10},
        {"expression": "type = 'ibeacon'", "priority": 1}
    ]);
    let mut cart = cart_with(&rules);
    cart["id"] = json!(CART);
    let cart: Trackable = serde_json::from_value(cart).unwrap();
    let running = common::serve_on_loopback(rtls_server::serve::ServeOptions {
        trackables: vec![cart],
        ..common::options(config)
    })
    .await;
    let http = running.bound.http;
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token={READ}"))
        .await
        .unwrap();
    for topic in ["trackable_motions", "fence_events"] {
        let request = json!({"event": "subscribe", "topic": topic});
        socket.send(Message::Text(request.to_string().into())).await.unwrap();
        assert_eq!(next_json(&mut socket).await["event"], "subscribed");
    }
    // the tag walks along y = 5 m from x = 2 m, outside the forklift lane (x ∈ [14, 18] m);
    // the beacon stands in the lane at x = 16 m
    let client = reqwest::Client::new();
    let push = |k: u32, accuracy: f64| {
        let t = 3000.0 + f64::from(k);
        let mut beacon = ble_at(t + 0.5);
        beacon["position"]["coordinates"] = json!([16.0, 10.0]);
        let body = Value::Array(vec![uwb_at(t, accuracy), beacon]).to_string();
        let client = client.clone();
        async move {
            let reply = client
                .put(format!("http://{http}/v2/providers/locations"))
                .bearer_auth(WRITE)
                .body(body)
                .send()
                .await
                .unwrap();
            assert_eq!(reply.status(), reqwest::StatusCode::NO_CONTENT);
        }
    };
    // 8 s of good UWB fixes, then 8 s of 5 m ones
    for k in 0..8 {
        push(k, 0.3).await;
    }
    for k in 8..16 {
        push(k, 5.0).await;
    }
    let (mut motions, mut beacon_entered, mut cart_entered) = (Vec::new(), None, None);
    while cart_entered.is_none() || motions.last().is_none_or(|(_, t)| *t < 3014.0) {
        let message = next_json(&mut socket).await;
        assert_eq!(message["event"], "message", "{message}");
        for payload in message["payload"].as_array().unwrap() {
            match message["topic"].as_str().unwrap() {
                "trackable_motions" if payload["id"] == CART => {
                    let location = &payload["location"];
                    motions.push((location["provider_id"].as_str().unwrap().to_string(), time_of(location)));
                }
                "fence_events" if payload["provider_id"] == BLE && payload["event_type"] == "region_entry" => {
                    assert_eq!(payload["trackables"], json!([CART]), "{payload}");
                    beacon_entered = Some(payload["entry_time"].clone());
                }
                "fence_events" if payload["trackable_id"] == CART => {
                    assert_eq!(payload["event_type"], "region_entry", "{payload}");
                    cart_entered = Some(parse_timestamp(payload["entry_time"].as_str().unwrap(), "t").unwrap());
                }
                _ => {}
            }
        }
    }
    // the tag's good fixes move the cart; from its first 5 m fix (3008 s) only the beacon does.
    // The tag and the beacon are tracked on different partitions, which publish concurrently:
    // until the tag's first fix has reached the hub the beacon is the only candidate, so the
    // cart may take it for that first instant (3000.5 s)
    let settled = motions.iter().skip_while(|(p, _)| p == BLE);
    let (good, degraded): (Vec<_>, Vec<_>) = settled.partition(|(_, t)| *t < 3008.0);
    assert!(good.len() >= 6, "{motions:?}");
    assert!(good.iter().all(|(p, _)| p == UWB), "{motions:?}");
    assert!(degraded.len() >= 5, "{motions:?}");
    assert!(degraded.iter().all(|(p, _)| p == BLE), "{motions:?}");
    // the beacon entered the lane while the cart followed the tag outside it: the cart entered
    // only when its rules took the beacon
    let beacon_entered = beacon_entered.expect("the beacon's own entry");
    let cart_entered = cart_entered.unwrap();
    assert!(
        (3008.0..3009.0).contains(&cart_entered),
        "the cart entered at {cart_entered}, the beacon at {beacon_entered}"
    );
    running.stop().await;
}
