//! `zone_id` on the omlox writes and subscriptions: a fence written in a zone's local frame
//! (`crs: "local"`, `zone_id`) is placed through the zone's ground control points and read
//! back as written, its events come where the zone puts it, and a WebSocket subscription with
//! `params.zone_id` gets its locations in that zone's frame; unknown zones are refused.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{
    assert_omlox_error, call, lon_lat, post_created, post_measurements, turned_zone, zone_of, Reply, FRAME, READ, WRITE,
};
use futures_util::{SinkExt, StreamExt};
use rtls_server::config::MqttMode;
use rtls_server::serve::ServeOptions;
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::Message;

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

fn xy(position: &Value) -> [f64; 2] {
    [0, 1].map(|k| position[k].as_f64().unwrap_or(f64::NAN))
}

fn assert_near(got: [f64; 2], want: [f64; 2], tolerance: f64, what: &str) {
    assert!(
        (got[0] - want[0]).abs() < tolerance && (got[1] - want[1]).abs() < tolerance,
        "{what}: {got:?} against {want:?}"
    );
}

/// The square x ∈ [6, 10] m, y ∈ [8, 12] m of the site (the walk along y = 10 m crosses it),
/// as a closed ring in the zone's `[u, v]`.
fn square_in_zone() -> Vec<[f64; 2]> {
    [[6.0, 8.0], [10.0, 8.0], [10.0, 12.0], [6.0, 12.0], [6.0, 8.0]]
        .into_iter()
        .map(zone_of)
        .collect()
}

fn ring_of(fence: &Value) -> Vec<[f64; 2]> {
    fence["region"]["coordinates"][0]
        .as_array()
        .unwrap()
        .iter()
        .map(xy)
        .collect()
}

async fn get(app: &axum::Router, uri: &str) -> Reply {
    call(app, Method::GET, uri, Some(WRITE), "").await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_local_fence_with_a_zone_id_is_placed_through_the_zone_and_read_back_as_written() {
    let mut site = common::site();
    site.frame = Some(FRAME);
    // the walker stops at (7.5, 10) site metres
    let (_, app) = common::walked_on_site("zone-fence-round-trip", site).await;
    let zone = post_created(&app, "/v2/zones", &turned_zone()).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let written = square_in_zone();
    let body = json!({"crs": "local", "zone_id": zone, "name": "stop",
                      "region": {"type": "Polygon", "coordinates": [written]}});
    let created = post_created(&app, "/v2/fences", &body).await;
    // answered in the frame it was written in
    assert_eq!(
        (&created["crs"], &created["zone_id"]),
        (&json!("local"), &json!(zone)),
        "{created}"
    );
    for (got, want) in ring_of(&created).into_iter().zip(&written) {
        assert_near(got, *want, 1e-6, "the created fence");
    }
    let id = created["id"].as_str().unwrap().to_string();
    // read in the zone's frame: what was written
    let reply = get(&app, &format!("/v2/fences/{id}?zone_id={zone}")).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let read = reply.json();
    assert_eq!((&read["crs"], &read["zone_id"]), (&json!("local"), &json!(zone)));
    for (got, want) in ring_of(&read).into_iter().zip(&written) {
        assert_near(got, *want, 1e-6, "the fence read in the zone");
    }
    // in the site's metres and in WGS-84 (the default): where the zone puts it
    let site_zone = rtls_server::convert::uuid_for("zone", common::site().name.as_deref().unwrap_or("rtls"));
    let in_site = get(&app, &format!("/v2/fences/{id}?zone_id={site_zone}")).await.json();
    let square = [[6.0, 8.0], [10.0, 8.0], [10.0, 12.0], [6.0, 12.0]];
    for (got, want) in ring_of(&in_site).into_iter().zip(square) {
        assert_near(got, want, 1e-6, "the fence in site metres");
    }
    let default = get(&app, &format!("/v2/fences/{id}")).await.json();
    assert_eq!(default["crs"], "EPSG:4326");
    for (got, want) in ring_of(&default).into_iter().zip(square) {
        assert_near(got, lon_lat(want), 1e-9, "the fence in WGS-84");
    }
    // the walker, stopped at (7.5, 10), is inside it
    let inside = get(&app, &format!("/v2/fences/{id}/providers?spatial_query=true")).await;
    assert!(inside.text().contains("walker"), "{}", inside.text());

    // PUT in the zone's frame: moved 1 m along the zone's u (the site's −y), read back so
    let moved: Vec<[f64; 2]> = written.iter().map(|[u, v]| [u + 1.0, *v]).collect();
    let body = json!({"crs": "local", "zone_id": zone, "name": "stop",
                      "region": {"type": "Polygon", "coordinates": [moved]}});
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/fences/{id}"),
        Some(WRITE),
        &body.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let read = get(&app, &format!("/v2/fences/{id}?zone_id={zone}")).await.json();
    for (got, want) in ring_of(&read).into_iter().zip(&moved) {
        assert_near(got, *want, 1e-6, "the replaced fence in the zone");
    }
    let in_site = get(&app, &format!("/v2/fences/{id}?crs=local")).await.json();
    assert_near(
        ring_of(&in_site)[0],
        [6.0, 7.0],
        1e-6,
        "the replaced fence in site metres",
    );

    // a Point fence: its centre through the zone, its radius metres
    let centre = zone_of([7.5, 10.0]);
    let body = json!({"crs": "local", "zone_id": zone, "radius": 1.0,
                      "region": {"type": "Point", "coordinates": centre}});
    let circle = post_created(&app, "/v2/fences", &body).await;
    let circle_id = circle["id"].as_str().unwrap();
    let in_site = get(&app, &format!("/v2/fences/{circle_id}?crs=local")).await.json();
    let ring = ring_of(&in_site);
    let n = (ring.len() - 1) as f64;
    let mean = [0, 1].map(|k| ring[..ring.len() - 1].iter().map(|p| p[k]).sum::<f64>() / n);
    assert_near(mean, [7.5, 10.0], 1e-6, "the circle's centre in site metres");

    // without zone_id, `local` stays the site's metres (the same numbers, elsewhere)
    let body = json!({"crs": "local", "region": {"type": "Polygon", "coordinates": [written]}});
    let plain = post_created(&app, "/v2/fences", &body).await;
    assert_near(ring_of(&plain)[0], written[0], 1e-12, "a local fence without zone_id");
    let plain_id = plain["id"].as_str().unwrap();
    let inside = get(&app, &format!("/v2/fences/{plain_id}/providers?spatial_query=true")).await;
    assert!(!inside.text().contains("walker"), "{}", inside.text());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fence_in_an_unknown_or_frameless_zone_is_refused_naming_zone_id() {
    let mut site = common::site();
    site.frame = Some(FRAME);
    let (_, app) = common::walked_on_site("zone-fence-refused", site).await;
    let ring = square_in_zone();
    let fence = |zone_id: &str| {
        json!({"crs": "local", "zone_id": zone_id, "region": {"type": "Polygon", "coordinates": [ring]}}).to_string()
    };
    let unknown = "0b8e5c0a-1111-4222-8333-444455556666";
    let reply = call(&app, Method::POST, "/v2/fences", Some(WRITE), &fence(unknown)).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "an unknown zone").as_deref(),
        Some("zone_id")
    );
    assert!(reply.text().contains(unknown), "{}", reply.text());
    // a proximity zone has no local frame, nor has a zone without ground control points
    let reader =
        json!({"type": "rfid", "position": {"type": "Point", "coordinates": lon_lat([1.0, 1.0])}, "radius": 2.0});
    let reader = post_created(&app, "/v2/zones", &reader).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let sketch = json!({"type": "uwb", "incomplete_configuration": true});
    let sketch = post_created(&app, "/v2/zones", &sketch).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    for zone in [&reader, &sketch] {
        let reply = call(&app, Method::POST, "/v2/fences", Some(WRITE), &fence(zone)).await;
        assert_eq!(
            assert_omlox_error(&reply, StatusCode::BAD_REQUEST, zone).as_deref(),
            Some("zone_id")
        );
    }
    // a PUT likewise, and the fence stays as it was
    let created = post_created(
        &app,
        "/v2/fences",
        &json!({"crs": "local", "region": {"type": "Polygon", "coordinates": [ring]}}),
    )
    .await;
    let id = created["id"].as_str().unwrap();
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/fences/{id}"),
        Some(WRITE),
        &fence(unknown),
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "PUT in an unknown zone").as_deref(),
        Some("zone_id")
    );
    let read = get(&app, &format!("/v2/fences/{id}?crs=local")).await.json();
    assert_near(ring_of(&read)[0], ring[0], 1e-12, "unchanged");
    // beside EPSG:4326 a zone_id is not read: WGS-84 is one frame whichever zone
    let wgs84: Vec<[f64; 2]> = [[6.0, 8.0], [10.0, 8.0], [10.0, 12.0], [6.0, 12.0], [6.0, 8.0]]
        .into_iter()
        .map(lon_lat)
        .collect();
    let body = json!({"zone_id": unknown, "region": {"type": "Polygon", "coordinates": [wgs84]}});
    post_created(&app, "/v2/fences", &body).await;
}

/// The server on loopback on a data clock, the test site georeferenced at [`FRAME`].
async fn start(name: &str) -> common::Running {
    let dir = common::temp_dir(name);
    let mut config = common::loopback_config(&dir, MqttMode::Off);
    config.pipeline.live_clock = false;
    config.pipeline.partitions = 1;
    let mut site = common::site();
    site.frame = Some(FRAME);
    common::serve_on_loopback(ServeOptions {
        site,
        ..common::options(config)
    })
    .await
}

async fn post(client: &reqwest::Client, http: std::net::SocketAddr, path: &str, body: &Value) -> Value {
    let reply = client
        .post(format!("http://{http}{path}"))
        .bearer_auth(WRITE)
        .json(body)
        .send()
        .await
        .unwrap();
    assert_eq!(reply.status(), StatusCode::CREATED, "POST {path}");
    reply.json().await.unwrap()
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

async fn request(socket: &mut Socket, request: Value) -> Value {
    socket.send(Message::Text(request.to_string().into())).await.unwrap();
    next_json(socket).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zone_id_on_a_subscription_projects_its_locations_and_fence_events_follow_the_zone() {
    let running = start("ws-zone-id").await;
    let http = running.bound.http;
    let client = reqwest::Client::new();
    let zone = post(&client, http, "/v2/zones", &turned_zone()).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    // the square x ∈ [6, 10], y ∈ [8, 12] written in the zone's frame, and a decoy: the same
    // numbers as site metres (x ∈ [−10, −6], y ∈ [1, 5]: never walked)
    let ring = square_in_zone();
    let in_zone = post(
        &client,
        http,
        "/v2/fences",
        &json!({"crs": "local", "zone_id": zone, "region": {"type": "Polygon", "coordinates": [ring]}}),
    )
    .await;
    let decoy = post(
        &client,
        http,
        "/v2/fences",
        &json!({"crs": "local", "region": {"type": "Polygon", "coordinates": [ring]}}),
    )
    .await;

    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{http}/v2/ws/socket?token={READ}"))
        .await
        .unwrap();
    let mut ids = Vec::new();
    for params in [
        json!({"provider_id": "miner-3", "zone_id": zone}),
        json!({"provider_id": "miner-3"}),
        json!({"provider_id": "miner-3", "crs": "local", "zone_id": zone}),
    ] {
        let reply = request(
            &mut socket,
            json!({"event": "subscribe", "topic": "location_updates", "params": params}),
        )
        .await;
        assert_eq!(reply["event"], "subscribed", "{reply}");
        ids.push(reply["subscription_id"].as_u64().unwrap());
    }
    // the GeoJSON topic in the zone's frame, named by the foreign members
    let reply = request(
        &mut socket,
        json!({"event": "subscribe", "topic": "location_updates:geojson",
               "params": {"provider_id": "miner-3", "zone_id": zone}}),
    )
    .await;
    assert_eq!(reply["event"], "subscribed", "{reply}");
    let geojson = reply["subscription_id"].as_u64().unwrap();
    let mut features = Vec::new();
    let reply = request(&mut socket, json!({"event": "subscribe", "topic": "fence_events"})).await;
    let events = reply["subscription_id"].as_u64().unwrap();
    // refusals: an unknown zone, a zone without a frame, zone_id where no location is carried
    let unknown = "0b8e5c0a-1111-4222-8333-444455556666";
    let sketch = post(
        &client,
        http,
        "/v2/zones",
        &json!({"type": "uwb", "incomplete_configuration": true}),
    )
    .await;
    for (topic, zone_id) in [
        ("location_updates", unknown),
        ("trackable_motions", sketch["id"].as_str().unwrap()),
        ("fence_events", zone.as_str()),
    ] {
        let reply = request(
            &mut socket,
            json!({"event": "subscribe", "topic": topic, "params": {"zone_id": zone_id}}),
        )
        .await;
        assert_eq!(
            (reply["event"].as_str(), reply["code"].as_u64()),
            (Some("error"), Some(10002)),
            "{reply}"
        );
        assert!(reply["description"].as_str().unwrap().contains("zone_id"), "{reply}");
    }

    // walk along y = 10 m from x = 2 to 14 m: in and out of the square
    assert!(post_measurements(&client, http, common::walk("miner-3", 7000.0, 12.0))
        .await
        .status()
        .is_success());
    let (mut in_zone_frame, mut in_site, mut both) = (Vec::new(), Vec::new(), Vec::new());
    let mut kinds = Vec::new();
    while kinds.len() < 2 || in_site.len() < 5 || in_zone_frame.len() < 5 || features.len() < 5 {
        let message = next_json(&mut socket).await;
        assert_eq!(message["event"], "message", "{message}");
        let id = message["subscription_id"].as_u64().unwrap();
        for object in message["payload"].as_array().unwrap() {
            if id == events {
                assert_ne!(object["fence_id"], decoy["id"], "the decoy is never walked: {object}");
                assert_eq!(object["fence_id"], in_zone["id"], "{object}");
                kinds.push(object["event_type"].as_str().unwrap().to_string());
            } else if id == geojson {
                features.push(object.clone());
            } else if id == ids[0] {
                in_zone_frame.push(object.clone());
            } else if id == ids[1] {
                in_site.push(object.clone());
            } else {
                both.push(object.clone());
            }
        }
    }
    assert_eq!(kinds, ["region_entry", "region_exit"]);
    // the same updates, in the zone's [u, v]
    let mut matched = 0;
    for local in &in_zone_frame {
        assert_eq!(local["crs"], "local", "{local}");
        let Some(site) = in_site
            .iter()
            .find(|s| s["timestamp_generated"] == local["timestamp_generated"])
        else {
            continue;
        };
        let site_xy = xy(&site["position"]["coordinates"]);
        assert_near(
            xy(&local["position"]["coordinates"]),
            zone_of(site_xy),
            1e-6,
            "a location in the zone",
        );
        assert_eq!(local["accuracy"], site["accuracy"]);
        matched += 1;
    }
    assert!(matched >= 3, "{matched} matched");
    // each Feature's point is its Location's in the zone's frame
    let mut features_matched = 0;
    for feature in &features {
        assert_eq!(
            (&feature["crs"], &feature["zone_id"]),
            (&json!("local"), &json!(zone)),
            "{feature}"
        );
        let Some(local) = in_zone_frame
            .iter()
            .find(|l| l["timestamp_generated"] == feature["properties"]["timestamp_generated"])
        else {
            continue;
        };
        assert_eq!(
            feature["geometry"]["coordinates"], local["position"]["coordinates"],
            "{feature}"
        );
        features_matched += 1;
    }
    assert!(features_matched >= 3, "{features_matched} features matched");
    for object in &both {
        if let Some(twin) = in_zone_frame
            .iter()
            .find(|l| l["timestamp_generated"] == object["timestamp_generated"])
        {
            assert_eq!(object["position"], twin["position"]);
        }
    }
    running.stop().await;
}
