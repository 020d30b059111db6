//! The omlox WebSocket topics about trackables and proximities — `trackable_motions`,
//! `collision_events`, `proximity_updates` — on the whole server on loopback
//! (tokio-tungstenite client): records and proximities in, the topics' messages checked.

mod common;

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use rtls_server::config::MqttMode;
use rtls_server::omlox::collision::K_SIGMA_95;
use rtls_server::omlox::{Trackable, TrackableType};
use rtls_server::serve::ServeOptions;
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::Message;

use common::{post_measurements, temp_dir, walk, Running, FRAME, READ, WRITE};

/// The configured forklift: a trackable with a 1 m radius moved by the tag `forklift-tag`.
const FORKLIFT: &str = "6f1c2d3e-0000-4000-8000-00000000f0f1";

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The server on loopback on a data clock with `partitions` tag partitions, the test site
/// georeferenced at [`FRAME`], the forklift registered at start.
async fn start(name: &str, partitions: usize) -> Running {
    let dir = temp_dir(name);
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.pipeline.live_clock = false;
    config.pipeline.partitions = partitions;
    let mut site = common::site();
    site.frame = Some(FRAME);
    let forklift = Trackable {
        id: FORKLIFT.into(),
        kind: TrackableType::Virtual,
        name: Some("Forklift 1".into()),
        geometry: None,
        extrusion: Some(2.2),
        location_providers: Some(vec!["forklift-tag".into()]),
        fence_timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        radius: Some(1.0),
        properties: Some(json!({"fleet": "north"}).as_object().unwrap().clone()),
        locating_rules: None,
    };
    common::serve_on_loopback(ServeOptions {
        site,
        trackables: vec![forklift],
        ..common::options(config)
    })
    .await
}

/// Opens a socket and subscribes to `requests`; gives the socket and the subscription ids.
async fn subscribe(http: std::net::SocketAddr, requests: &[Value]) -> (Socket, Vec<u64>) {
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token={READ}"))
        .await
        .unwrap();
    let mut ids = Vec::new();
    for request in requests {
        socket.send(Message::Text(request.to_string().into())).await.unwrap();
        let reply = next_json(&mut socket).await;
        assert_eq!(reply["event"], "subscribed", "{request} → {reply}");
        assert_eq!(reply["topic"], request["topic"], "{reply}");
        ids.push(reply["subscription_id"].as_u64().unwrap());
    }
    (socket, ids)
}

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

/// The next `message`'s topic, subscription id and payload objects.
async fn next_message(socket: &mut Socket) -> (String, u64, Vec<Value>) {
    let message = next_json(socket).await;
    assert_eq!(message["event"], "message", "{message}");
    (
        message["topic"].as_str().unwrap().to_string(),
        message["subscription_id"].as_u64().unwrap(),
        message["payload"].as_array().unwrap().clone(),
    )
}

/// Record lines in time order (a partition's records older than its data clock are late).
fn by_time(lines: &str) -> String {
    let mut lines: Vec<(f64, &str)> = lines
        .lines()
        .map(|line| {
            (
                serde_json::from_str::<Value>(line).unwrap()["t"].as_f64().unwrap(),
                line,
            )
        })
        .collect();
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    lines.into_iter().map(|(_, line)| format!("{line}\n")).collect()
}

fn x_of(location: &Value) -> f64 {
    location["position"]["coordinates"][0].as_f64().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trackable_motions_follow_every_track_update_of_a_trackable() {
    let running = start("ws-motions", 2).await;
    let http = running.bound.http;
    let (mut socket, ids) = subscribe(
        http,
        &[
            json!({"event": "subscribe", "topic": "trackable_motions", "params": {"trackable_id": FORKLIFT}}),
            json!({"event": "subscribe", "topic": "trackable_motions"}),
        ],
    )
    .await;
    let (forklift_only, all) = (ids[0], ids[1]);
    // the forklift's tag drives along y = 10 m from x = 2 m at 1 m/s; miner-8 (no stored
    // trackable: its own implicit one) walks for 3 s
    let lines = by_time(&(walk("forklift-tag", 5000.0, 12.0) + &walk("miner-8", 5000.0, 3.0)));
    let client = reqwest::Client::new();
    assert!(post_measurements(&client, http, lines).await.status().is_success());

    let (mut filtered, mut forklift_all, mut miner) = (Vec::new(), 0, 0);
    while filtered.last().is_none_or(|x| *x < 11.0) || miner == 0 {
        let (topic, subscription, payload) = next_message(&mut socket).await;
        assert_eq!(topic, "trackable_motions");
        for motion in payload {
            let location = &motion["location"];
            match (subscription, motion["id"].as_str().unwrap()) {
                (s, FORKLIFT) => {
                    // the trackable's name, extrusion and properties with its tag's location
                    assert_eq!(motion["name"], "Forklift 1", "{motion}");
                    assert_eq!(motion["extrusion"], 2.2);
                    assert_eq!(motion["properties"]["fleet"], "north");
                    assert_eq!(location["provider_id"], "forklift-tag");
                    assert!((location["position"]["coordinates"][1].as_f64().unwrap() - 10.0).abs() < 0.3);
                    if s == forklift_only {
                        filtered.push(x_of(location));
                    } else {
                        forklift_all += 1;
                    }
                }
                (s, "miner-8") => {
                    assert_eq!(s, all, "the trackable_id filter holds: {motion}");
                    assert_eq!(location["provider_id"], "miner-8");
                    miner += 1;
                }
                (_, other) => panic!("unexpected trackable {other}: {motion}"),
            }
        }
    }
    // one motion per track update, in order, following the drive
    assert!(filtered.len() >= 15, "{filtered:?}");
    assert!(filtered.windows(2).all(|w| w[1] >= w[0] - 0.05), "{filtered:?}");
    assert!(forklift_all > 0);
    running.stop().await;
}

/// The two objects' ids, and each one's judged radius (the distance of its region polygon's
/// first vertex from its position).
fn sides(event: &Value) -> Vec<(String, f64)> {
    event["collisions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let p = &c["position"]["coordinates"];
            let v = &c["geometry"]["coordinates"][0][0];
            let r = (v[0].as_f64().unwrap() - p[0].as_f64().unwrap())
                .hypot(v[1].as_f64().unwrap() - p[1].as_f64().unwrap());
            (c["id"].as_str().unwrap().to_string(), r)
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn collisions_start_once_and_end_once_judged_with_the_tracks_uncertainty() {
    // one partition: the hub carries the updates of all tags in time order, as a live feed
    // does (a burst replayed through two partitions may run one tag's whole drive before the
    // other's first update, and collisions are judged against each one's newest update)
    let running = start("ws-collisions", 1).await;
    let http = running.bound.http;
    // the same events in site metres and, through the site's frame, in longitude/latitude
    let (mut socket, ids) = subscribe(
        http,
        &[
            json!({"event": "subscribe", "topic": "collision_events", "params": {"trackable_id": FORKLIFT}}),
            json!({"event": "subscribe", "topic": "collision_events",
                   "params": {"trackable_id": FORKLIFT, "crs": "EPSG:4326"}}),
        ],
    )
    .await;
    let (in_site, in_wgs84) = (ids[0], ids[1]);
    // the forklift drives past miner-3, who stands 0.5 m off its path at x = 10 m; miner-9
    // stands far away
    let mut lines = walk("forklift-tag", 5000.0, 18.0);
    for k in 0..=36 {
        let t = 5000.0 + 0.5 * f64::from(k);
        for (tag, x, y) in [("miner-3", 10.0, 10.5), ("miner-9", 25.0, 2.0)] {
            lines.push_str(&format!(
                "{{\"t\": {t}, \"tag\": \"{tag}\", \"kind\": \"fix\", \"position_m\": [{x}, {y}], \"covariance_m2\": [0.04, 0.0, 0.0, 0.04]}}\n"
            ));
        }
    }
    let client = reqwest::Client::new();
    assert!(post_measurements(&client, http, by_time(&lines))
        .await
        .status()
        .is_success());

    // [site metres, longitude/latitude]
    let mut received: [Vec<Value>; 2] = [Vec::new(), Vec::new()];
    let take = |received: &mut [Vec<Value>; 2], subscription: u64, payload: Vec<Value>| {
        let which = usize::from(subscription == in_wgs84);
        assert!(subscription == in_site || subscription == in_wgs84);
        received[which].extend(payload);
    };
    let ended = |events: &[Value]| events.iter().any(|e| e["collision_type"] == "collision_end");
    while !(ended(&received[0]) && ended(&received[1])) {
        let (topic, subscription, payload) = next_message(&mut socket).await;
        assert_eq!(topic, "collision_events");
        take(&mut received, subscription, payload);
    }
    // the rest of the drive: nothing more about this pair
    let _ = tokio::time::timeout(Duration::from_millis(500), async {
        loop {
            let (_, subscription, payload) = next_message(&mut socket).await;
            take(&mut received, subscription, payload);
        }
    })
    .await;
    let [events, projected] = received;
    // params.crs: every position of every event through the site's frame, nothing else changed
    assert_eq!(projected.len(), events.len());
    let wgs84 = |p: &Value| {
        let c: Vec<f64> = p.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        FRAME.wgs84_of([c[0], c[1], c.get(2).copied().unwrap_or(0.0)]).unwrap()
    };
    let near = |got: &Value, want: [f64; 3]| {
        (got[0].as_f64().unwrap() - want[0]).abs() < 1e-9 && (got[1].as_f64().unwrap() - want[1]).abs() < 1e-9
    };
    for (site, lon_lat) in events.iter().zip(&projected) {
        assert_eq!(site["id"], lon_lat["id"]);
        assert_eq!(site["center_distance"], lon_lat["center_distance"]);
        if let Some(area) = site.get("collision_area") {
            let want = wgs84(&area["coordinates"]);
            assert!(near(&lon_lat["collision_area"]["coordinates"], want), "{lon_lat}");
        }
        for (a, b) in site["collisions"]
            .as_array()
            .unwrap()
            .iter()
            .zip(lon_lat["collisions"].as_array().unwrap())
        {
            assert!(
                near(&b["position"]["coordinates"], wgs84(&a["position"]["coordinates"])),
                "{b}"
            );
            let vertex = &a["geometry"]["coordinates"][0][0];
            assert!(near(&b["geometry"]["coordinates"][0][0], wgs84(vertex)), "{b}");
        }
    }
    let kinds: Vec<&str> = events.iter().map(|e| e["collision_type"].as_str().unwrap()).collect();
    assert_eq!(kinds.first(), Some(&"collision_start"), "{kinds:?}");
    assert_eq!(
        kinds.iter().filter(|k| **k == "collision_start").count(),
        1,
        "{kinds:?}"
    );
    assert_eq!(kinds.iter().filter(|k| **k == "collision_end").count(), 1, "{kinds:?}");
    assert_eq!(kinds.last(), Some(&"collision_end"), "{kinds:?}");
    assert!(kinds.iter().filter(|k| **k == "colliding").count() >= 2, "{kinds:?}");
    for event in &events {
        let ids: Vec<String> = sides(event).into_iter().map(|(id, _)| id).collect();
        assert!(
            ids.contains(&FORKLIFT.to_string()) && ids.contains(&"miner-3".to_string()),
            "{event}"
        );
        assert_eq!(event["start_time"], events[0]["start_time"], "{event}");
        assert!(event["id"].is_string());
    }
    let (start, end) = (&events[0], events.last().unwrap());
    // the regions: the forklift's 1 m radius plus k·σ, the miner's k·σ alone
    let radius = |event: &Value, id: &str| sides(event).into_iter().find(|(i, _)| i == id).unwrap().1;
    let (forklift_r, miner_r) = (radius(start, FORKLIFT), radius(start, "miner-3"));
    assert!(forklift_r > 1.0 && forklift_r < 1.0 + K_SIGMA_95 * 0.3, "{start}");
    assert!(miner_r > 0.0 && miner_r < K_SIGMA_95 * 0.3, "{start}");
    // they collide where the regions overlap, not where the declared radii alone would
    let distance = |event: &Value| event["center_distance"].as_f64().unwrap();
    assert!(distance(start) < forklift_r + miner_r, "{start}");
    assert!(distance(start) > 1.0, "the uncertainty widened the regions: {start}");
    assert!(distance(end) >= radius(end, FORKLIFT) + radius(end, "miner-3"), "{end}");
    assert!(start["collision_area"]["coordinates"].is_array());
    assert!(
        end["end_time"].is_string() && end.get("collision_area").is_none(),
        "{end}"
    );
    // the forklift meets the miner before x = 10 m and leaves him after
    let forklift_x = |event: &Value| {
        let side = event["collisions"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["id"] == FORKLIFT)
            .unwrap()
            .clone();
        side["position"]["coordinates"][0].as_f64().unwrap()
    };
    assert!((7.0..10.0).contains(&forklift_x(start)), "{start}");
    assert!((10.0..13.0).contains(&forklift_x(end)), "{end}");
    running.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn proximity_updates_carry_the_proximities_providers_push() {
    let running = start("ws-proximities", 2).await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    let [lon, lat, _] = FRAME.wgs84_of([20.0, 10.0, 0.0]).unwrap();
    let gate = json!({"type": "rfid", "foreign_id": "gate-3", "radius": 1.5,
                      "position": {"type": "Point", "coordinates": [lon, lat]}});
    let reply = client
        .post(format!("http://{http}/v2/zones"))
        .bearer_auth(WRITE)
        .json(&gate)
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), 201);
    let (mut socket, ids) = subscribe(
        http,
        &[
            json!({"event": "subscribe", "topic": "proximity_updates", "params": {"provider_id": "rfid-77"}}),
            json!({"event": "subscribe", "topic": "location_updates", "params": {"provider_id": "rfid-77"}}),
        ],
    )
    .await;
    let stamp = |t: f64| rtls_server::omlox::time::format_timestamp(t, "t").unwrap();
    let proximity = |provider: &str, source: &str, t: f64| {
        json!({"source": source, "provider_type": "rfid", "provider_id": provider,
               "timestamp_generated": stamp(t), "accuracy": 0.4, "properties": {"rssi": -51}})
    };
    let put = |body: Value| {
        let client = client.clone();
        async move {
            client
                .put(format!("http://{http}/v2/providers/proximities"))
                .bearer_auth(WRITE)
                .json(&body)
                .send()
                .await
                .unwrap()
                .status()
        }
    };
    // a refused batch publishes nothing
    assert_eq!(put(json!([proximity("rfid-77", "gate-9", 6000.0)])).await, 400);
    assert_eq!(
        put(json!([
            proximity("rfid-78", "gate-3", 6000.0),
            proximity("rfid-77", "gate-3", 6000.5)
        ]))
        .await,
        204
    );
    let mut proximities = Vec::new();
    while proximities.is_empty() {
        let (topic, subscription, payload) = next_message(&mut socket).await;
        match topic.as_str() {
            "proximity_updates" => {
                assert_eq!(subscription, ids[0]);
                proximities.extend(payload);
            }
            // the proximity is tracked too: its location at the gate, routed by its topic
            "location_updates" => assert_eq!(subscription, ids[1]),
            other => panic!("unexpected topic {other}"),
        }
    }
    // the Proximity as pushed: the filter holds, the fields and properties are kept
    assert_eq!(proximities.len(), 1, "{proximities:?}");
    assert_eq!(proximities[0], proximity("rfid-77", "gate-3", 6000.5));
    running.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn location_updates_come_in_wgs84_when_a_subscription_asks_for_it() {
    let running = start("ws-crs", 1).await;
    let http = running.bound.http;
    let (mut socket, ids) = subscribe(
        http,
        &[
            json!({"event": "subscribe", "topic": "location_updates", "params": {"provider_id": "miner-9", "crs": "EPSG:4326"}}),
            json!({"event": "subscribe", "topic": "location_updates", "params": {"provider_id": "miner-9"}}),
            json!({"event": "subscribe", "topic": "trackable_motions", "params": {"provider_id": "miner-9", "crs": "EPSG:4326"}}),
            json!({"event": "subscribe", "topic": "location_updates:geojson", "params": {"provider_id": "miner-9"}}),
        ],
    )
    .await;
    let (wgs84, local, motions, features) = (ids[0], ids[1], ids[2], ids[3]);
    // another CRS is refused with omlox's subscription-failed error
    socket
        .send(Message::Text(
            json!({"event": "subscribe", "topic": "location_updates", "params": {"crs": "EPSG:3857"}})
                .to_string()
                .into(),
        ))
        .await
        .unwrap();
    let refusal = next_json(&mut socket).await;
    assert_eq!(
        (refusal["event"].as_str(), refusal["code"].as_u64()),
        (Some("error"), Some(10002)),
        "{refusal}"
    );

    let client = reqwest::Client::new();
    assert!(post_measurements(&client, http, walk("miner-9", 5000.0, 4.0))
        .await
        .status()
        .is_success());
    // the same updates, once per subscription: match them by their time
    let (mut in_degrees, mut in_metres) = (std::collections::HashMap::new(), std::collections::HashMap::new());
    let (mut motions_in_degrees, mut as_features) =
        (std::collections::HashMap::new(), std::collections::HashMap::new());
    let matched = |of: &std::collections::HashMap<String, Value>, metres: &std::collections::HashMap<String, Value>| {
        of.keys().filter(|t| metres.contains_key(*t)).count()
    };
    while matched(&in_degrees, &in_metres) < 3
        || matched(&motions_in_degrees, &in_metres) < 3
        || matched(&as_features, &in_degrees) < 3
    {
        let (_, id, payload) = next_message(&mut socket).await;
        for object in payload {
            if id == features {
                let stamp = object["properties"]["timestamp_generated"]
                    .as_str()
                    .unwrap()
                    .to_string();
                as_features.insert(stamp, object);
                continue;
            }
            // a motion carries its trackable's location
            let location = if id == motions {
                object["location"].clone()
            } else {
                object
            };
            let stamp = location["timestamp_generated"].as_str().unwrap().to_string();
            if id == wgs84 {
                in_degrees.insert(stamp, location);
            } else if id == local {
                in_metres.insert(stamp, location);
            } else if id == motions {
                motions_in_degrees.insert(stamp, location);
            }
        }
    }
    for (stamp, degrees) in in_degrees.iter().chain(&motions_in_degrees) {
        let Some(metres) = in_metres.get(stamp) else { continue };
        let xy = [0, 1].map(|k| metres["position"]["coordinates"][k].as_f64().unwrap());
        let [lon, lat, _] = FRAME.wgs84_of([xy[0], xy[1], 0.0]).unwrap();
        assert_eq!(degrees["crs"], "EPSG:4326", "{degrees}");
        let got = [0, 1].map(|k| degrees["position"]["coordinates"][k].as_f64().unwrap());
        assert!(
            (got[0] - lon).abs() < 1e-9 && (got[1] - lat).abs() < 1e-9,
            "{degrees} against {metres}"
        );
        assert_eq!(degrees["accuracy"], metres["accuracy"]);
    }
    // location_updates:geojson: the REST reads' Feature of the location in WGS-84 (RFC 7946)
    for (stamp, feature) in &as_features {
        let Some(degrees) = in_degrees.get(stamp) else { continue };
        assert_eq!(
            (&feature["type"], &feature["id"], &feature["geometry"]),
            (&json!("Feature"), &json!("miner-9"), &degrees["position"]),
            "{feature}"
        );
        let mut properties = degrees.as_object().unwrap().clone();
        properties.remove("position");
        assert_eq!(feature["properties"], Value::Object(properties), "{feature}");
    }
    running.stop().await;
}
