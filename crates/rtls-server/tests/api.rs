//! The HTTP API through the router, without a port (`tower::ServiceExt::oneshot`): ingest,
//! auth, field-level errors, live locations, history exports, events, head counts, omlox CRUD,
//! fences, operations endpoints, and that every operation in /openapi.json is routed.

mod common;

use std::time::Duration;

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use common::{call, eventually, pushed_location, state, walk, READ, WRITE};
use serde_json::{json, Value};
use tower::ServiceExt;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ingest_is_authorised_validated_by_line_and_field_and_tracked() {
    let state = state("api-ingest");
    let app = rtls_server::http::router(state.clone());
    let body = walk("miner-1", 1000.0, 20.0);

    assert_eq!(
        call(&app, Method::POST, "/api/v1/measurements", None, &body)
            .await
            .status,
        StatusCode::UNAUTHORIZED
    );
    assert_eq!(
        call(&app, Method::POST, "/api/v1/measurements", Some(READ), &body)
            .await
            .status,
        StatusCode::FORBIDDEN
    );
    assert_eq!(
        call(&app, Method::POST, "/api/v1/measurements", Some("wrong-token"), &body)
            .await
            .status,
        StatusCode::FORBIDDEN
    );

    // line 2 names an anchor the site does not have; line 3 is not a record
    let bad = "{\"t\": 1, \"tag\": \"x\", \"kind\": \"range\", \"anchor\": \"A1\", \"range_m\": 3.0}\n\
               {\"t\": 2, \"tag\": \"x\", \"kind\": \"range\", \"anchor\": \"Z9\", \"range_m\": 3.0}\n";
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), bad).await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    let message = reply.json()["message"].as_str().unwrap().to_string();
    assert!(
        message.contains("request body:2") && message.contains("anchor") && message.contains("Z9"),
        "{message}"
    );
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        "{\"t\": 1, \"tag\": \"x\", \"kind\": \"fix\"}\n",
    )
    .await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    assert!(
        reply.json()["message"].as_str().unwrap().contains("request body:1"),
        "{}",
        reply.text()
    );
    // nothing of a refused payload is stored
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 0);

    // the first 14 s of the walk end inside the hazard zone (x ∈ [14, 18] m): counted there
    let lines: Vec<&str> = body.lines().collect();
    let (first, rest) = (lines[..29].join("\n"), lines[29..].join("\n"));
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &first).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    assert_eq!(reply.json()["accepted"], json!(29));
    let live = state.pipeline.live().clone();
    assert!(
        eventually(Duration::from_secs(10), || live.head_counts().get("forklift-lane")
            == Some(&1))
        .await,
        "{:?}",
        live.head_counts()
    );
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &rest).await;
    assert_eq!(reply.json()["accepted"], json!(12));
    assert_eq!(state.query(|s| s.record_count()).await.unwrap(), 41);

    // tracked to the walk's end (t = 1020 s, less the reorder window)
    assert!(
        eventually(Duration::from_secs(10), || live
            .tag("miner-1")
            .is_some_and(|t| t.time_s >= 1019.0))
        .await
    );
    let reply = call(&app, Method::GET, "/v2/providers/miner-1/location", Some(READ), "").await;
    assert_eq!(reply.status, StatusCode::OK);
    let location = reply.json();
    assert_eq!(location["provider_id"], "miner-1");
    assert_eq!(location["crs"], "local");
    // the reorder window holds the newest records (no live clock here): compare with the
    // walk's position at the reported time, x = 2 m + 1 m/s · (t − 1000 s)
    let x = location["position"]["coordinates"][0].as_f64().unwrap();
    let t = live.tag("miner-1").unwrap().time_s;
    assert!((x - (2.0 + t - 1000.0)).abs() < 0.5, "x = {x} at t = {t}");
    assert_eq!(
        call(&app, Method::GET, "/v2/providers/nobody/location", Some(READ), "")
            .await
            .status,
        StatusCode::NOT_FOUND
    );
    let all = call(&app, Method::GET, "/v2/providers/locations", Some(READ), "")
        .await
        .json();
    assert_eq!(all.as_array().unwrap().len(), 1);

    // the walk crossed the hazard zone: a stored entry and exit, in order
    let mut kinds = Vec::new();
    for _ in 0..200 {
        let reply = call(
            &app,
            Method::GET,
            "/api/v1/events?type=zone-enter,zone-exit&tag=miner-1",
            Some(READ),
            "",
        )
        .await;
        assert_eq!(reply.status, StatusCode::OK);
        kinds = reply
            .json()
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["type"].as_str().unwrap().to_string())
            .collect();
        if kinds.len() >= 2 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert_eq!(kinds, ["zone-enter", "zone-exit"]);
    let counts = call(&app, Method::GET, "/api/v1/zones/head-counts", Some(READ), "")
        .await
        .json();
    assert_eq!(counts, json!({ "forklift-lane": 0 }));
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn history_exports_json_csv_and_geojson_and_names_bad_parameters() {
    let state = state("api-history");
    let app = rtls_server::http::router(state.clone());
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &walk("miner-2", 2000.0, 10.0),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);
    let mut rows = Vec::new();
    for _ in 0..400 {
        rows = call(&app, Method::GET, "/api/v1/history?tag=miner-2", Some(READ), "")
            .await
            .json()
            .as_array()
            .unwrap()
            .clone();
        if rows.last().is_some_and(|r| r["t"].as_f64().unwrap() >= 2007.9) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert!(rows.len() >= 10, "{} states", rows.len());
    let times: Vec<f64> = rows.iter().map(|r| r["t"].as_f64().unwrap()).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "oldest first");

    // a time range, both bounds inclusive, as RFC 3339 and as Unix seconds
    let (from, to) = (times[2], times[times.len() - 3]);
    let in_range = times.iter().filter(|&&t| t >= from && t <= to).count();
    let uri = format!("/api/v1/history?tag=miner-2&from={from}&to={to}");
    assert_eq!(
        call(&app, Method::GET, &uri, Some(READ), "")
            .await
            .json()
            .as_array()
            .unwrap()
            .len(),
        in_range
    );
    let from_text = rtls_server::omlox::time::format_timestamp(from, "from").unwrap();
    let uri = format!("/api/v1/history?tag=miner-2&from={from_text}&to={to}&limit=3");
    assert_eq!(
        call(&app, Method::GET, &uri, Some(READ), "")
            .await
            .json()
            .as_array()
            .unwrap()
            .len(),
        3
    );

    let csv = call(
        &app,
        Method::GET,
        "/api/v1/history?tag=miner-2&format=csv",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(csv.content_type, "text/csv");
    let text = csv.text();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "t,timestamp,tag,x_m,y_m,z_m,accuracy_m,predicted");
    assert_eq!(lines.len(), rows.len() + 1);
    let first: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(first[2], "miner-2");
    assert!(
        (first[4].parse::<f64>().unwrap() - 10.0).abs() < 0.5,
        "y ≈ 10 m: {}",
        lines[1]
    );

    let geo = call(
        &app,
        Method::GET,
        "/api/v1/history?tag=miner-2&format=geojson",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(geo.content_type, "application/geo+json");
    let geo = geo.json();
    assert_eq!(geo["type"], "FeatureCollection");
    assert_eq!(geo["features"][0]["geometry"]["type"], "LineString");
    assert_eq!(
        geo["features"][0]["geometry"]["coordinates"].as_array().unwrap().len(),
        rows.len()
    );
    assert_eq!(geo["features"].as_array().unwrap().len(), rows.len() + 1);

    for (uri, field) in [
        ("/api/v1/history", "tag"),
        ("/api/v1/history?tag=miner-2&format=xml", "format"),
        ("/api/v1/history?tag=miner-2&from=yesterday", "from"),
        ("/api/v1/history?tag=miner-2&from=10&to=5", "to"),
        ("/api/v1/history?tag=miner-2&limit=0", "limit"),
    ] {
        let reply = call(&app, Method::GET, uri, Some(READ), "").await;
        assert_eq!(
            (reply.status, reply.json()["field"].as_str()),
            (StatusCode::BAD_REQUEST, Some(field)),
            "{uri}"
        );
    }
    assert_eq!(
        call(&app, Method::GET, "/api/v1/history?tag=miner-2", None, "")
            .await
            .status,
        StatusCode::UNAUTHORIZED
    );
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn omlox_location_ingest_and_trackables_name_the_bad_field() {
    let state = state("api-omlox");
    let app = rtls_server::http::router(state.clone());
    let now = 3000.0;
    let location = |tag: &str, x: f64, t: f64| pushed_location(tag, [x, 5.0], t);
    let bad = json!([location("forklift-9", 1.0, now), {"position": {"type": "Point", "coordinates": [1.0]},
        "source": "s", "provider_type": "uwb", "provider_id": "forklift-9"}]);
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/locations",
        Some(WRITE),
        &bad.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST);
    assert_eq!(reply.json()["field"], "[1].position.coordinates");
    let good: Vec<Value> = (0..8)
        .map(|k| location("forklift-9", 1.0 + f64::from(k), now + f64::from(k)))
        .collect();
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/locations",
        Some(READ),
        &Value::Array(good.clone()).to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::FORBIDDEN);
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/locations",
        Some(WRITE),
        &Value::Array(good).to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let live = state.pipeline.live().clone();
    let tracked = eventually(Duration::from_secs(10), || {
        live.tag("forklift-9").is_some_and(|t| t.time_s >= now + 4.9)
    })
    .await; // the newest two wait for later data (reorder window, epoch)
    assert!(
        tracked,
        "{:?} {}",
        live.tag("forklift-9"),
        state.pipeline.metrics().encode().unwrap()
    );
    // the pushed location comes back as pushed, with our estimate alongside
    let back = call(&app, Method::GET, "/v2/providers/forklift-9/location", Some(READ), "")
        .await
        .json();
    let t = rtls_server::omlox::time::parse_timestamp(back["timestamp_generated"].as_str().unwrap(), "t").unwrap();
    let k = (t - now).round();
    assert_eq!(back["source"], "other-rtls", "{back}");
    assert_eq!(back["accuracy"], 0.3, "{back}");
    assert_eq!(back["position"]["coordinates"], json!([1.0 + k, 5.0]), "{back}");
    let filtered = &back["properties"]["rtls:filtered"];
    assert!(
        filtered["position"]["coordinates"][0].is_number() && filtered["accuracy"].is_number(),
        "{back}"
    );
    assert_eq!(filtered["rtls:source"], "fix", "{back}");
    let mismatch = location("forklift-8", 1.0, now + 9.0).to_string();
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/forklift-9/location",
        Some(WRITE),
        &mismatch,
    )
    .await;
    assert_eq!(
        (reply.status, reply.json()["field"].as_str()),
        (StatusCode::BAD_REQUEST, Some("provider_id"))
    );

    // trackables: created with a generated UUID, read, replaced, listed, deleted
    let reply = call(
        &app,
        Method::POST,
        "/v2/trackables",
        Some(WRITE),
        r#"{"type": "omlox", "name": "Forklift 9", "location_providers": ["forklift-9"]}"#,
    )
    .await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let id = reply.json()["id"].as_str().unwrap().to_string();
    assert!(uuid::Uuid::parse_str(&id).is_ok());
    // the nil UUID means "the hub assigns it", as an absent id does
    let nil = json!({"id": "00000000-0000-0000-0000-000000000000", "type": "omlox", "name": "Cart 2"}).to_string();
    let reply = call(&app, Method::POST, "/v2/trackables", Some(WRITE), &nil).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let assigned = uuid::Uuid::parse_str(reply.json()["id"].as_str().unwrap()).unwrap();
    assert!(!assigned.is_nil() && assigned.to_string() != id);
    let reply = call(
        &app,
        Method::DELETE,
        &format!("/v2/trackables/{assigned}"),
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    let again = json!({"id": id, "type": "omlox"}).to_string();
    // omlox: POST "Creates a new trackable with a randomly generated id": an id in use is
    // replaced by a new one, and the trackable that had it stays
    let reply = call(&app, Method::POST, "/v2/trackables", Some(WRITE), &again).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let renewed = uuid::Uuid::parse_str(reply.json()["id"].as_str().unwrap()).unwrap();
    assert_ne!(
        renewed.to_string(),
        id,
        "a second create under a taken id gets a new one"
    );
    let first = call(&app, Method::GET, &format!("/v2/trackables/{id}"), Some(READ), "").await;
    assert_eq!(first.status, StatusCode::OK, "{}", first.text());
    let reply = call(
        &app,
        Method::DELETE,
        &format!("/v2/trackables/{renewed}"),
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/trackables/{id}/location"),
        Some(READ),
        "",
    )
    .await;
    assert_eq!(
        (reply.status, reply.json()["provider_id"].as_str()),
        (StatusCode::OK, Some("forklift-9"))
    );
    let reply = call(
        &app,
        Method::POST,
        "/v2/trackables",
        Some(WRITE),
        r#"{"type": "omlox", "location_providers": ["a", 7]}"#,
    )
    .await;
    assert_eq!(
        (reply.status, reply.json()["field"].as_str()),
        (StatusCode::BAD_REQUEST, Some("location_providers[1]"))
    );
    let reply = call(
        &app,
        Method::POST,
        "/v2/trackables",
        Some(WRITE),
        r#"{"type": "robot"}"#,
    )
    .await;
    assert_eq!(
        (reply.status, reply.json()["field"].as_str()),
        (StatusCode::BAD_REQUEST, Some("type"))
    );
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/trackables/{id}"),
        Some(WRITE),
        r#"{"id": "5d9e0f7a-0000-4000-8000-000000000000", "type": "virtual"}"#,
    )
    .await;
    assert_eq!(
        (reply.status, reply.json()["field"].as_str()),
        (StatusCode::BAD_REQUEST, Some("id"))
    );
    let renamed = json!({"id": id, "type": "virtual", "name": "Forklift nine"}).to_string();
    assert_eq!(
        call(
            &app,
            Method::PUT,
            &format!("/v2/trackables/{id}"),
            Some(WRITE),
            &renamed
        )
        .await
        .status,
        StatusCode::OK
    );
    assert_eq!(
        call(&app, Method::GET, &format!("/v2/trackables/{id}"), Some(READ), "")
            .await
            .json()["name"],
        "Forklift nine"
    );
    assert_eq!(
        call(&app, Method::GET, "/v2/trackables", Some(READ), "").await.json(),
        json!([id])
    );
    assert_eq!(
        call(&app, Method::DELETE, &format!("/v2/trackables/{id}"), Some(WRITE), "")
            .await
            .status,
        StatusCode::NO_CONTENT
    );
    assert_eq!(
        call(&app, Method::GET, &format!("/v2/trackables/{id}"), Some(READ), "")
            .await
            .status,
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        call(&app, Method::DELETE, &format!("/v2/trackables/{id}"), Some(WRITE), "")
            .await
            .status,
        StatusCode::NOT_FOUND
    );

    // providers: the tracked tag is listed without being configured
    assert_eq!(
        call(&app, Method::GET, "/v2/providers", Some(READ), "").await.json(),
        json!(["forklift-9"])
    );
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fences_zones_and_operations_endpoints() {
    let state = state("api-ops");
    let app = rtls_server::http::router(state.clone());
    let fences = call(&app, Method::GET, "/v2/fences/summary", Some(READ), "")
        .await
        .json();
    assert_eq!(fences.as_array().unwrap().len(), 1);
    assert_eq!(fences[0]["foreign_id"], "forklift-lane");
    assert_eq!(
        fences[0]["region"]["coordinates"][0].as_array().unwrap().len(),
        5,
        "closed ring"
    );
    let id = fences[0]["id"].as_str().unwrap();
    assert_eq!(
        call(&app, Method::GET, &format!("/v2/fences/{id}"), Some(READ), "")
            .await
            .json()["foreign_id"],
        "forklift-lane"
    );
    assert_eq!(
        call(&app, Method::GET, "/v2/fences/forklift-lane", Some(READ), "")
            .await
            .json()["id"],
        id
    );
    let no_region = call(&app, Method::POST, "/v2/fences", Some(WRITE), "{}").await;
    assert_eq!(no_region.status, StatusCode::BAD_REQUEST);
    assert!(
        no_region.json()["message"].as_str().unwrap().contains("region"),
        "{}",
        no_region.json()
    );
    let zones = call(&app, Method::GET, "/api/v1/zones.geojson", Some(READ), "")
        .await
        .json();
    assert_eq!(zones["features"][0]["properties"]["id"], "forklift-lane");
    assert_eq!(zones["features"][0]["properties"]["head_count"], 0);

    let health = call(&app, Method::GET, "/health", None, "").await;
    assert_eq!(
        (health.status, health.json()["status"].as_str()),
        (StatusCode::OK, Some("ok"))
    );
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &walk("m", 10.0, 1.0),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);
    let metrics = call(&app, Method::GET, "/metrics", None, "").await;
    assert!(metrics.content_type.starts_with("application/openmetrics-text"));
    let text = metrics.text();
    assert!(text.contains("rtls_ingest_records_total 3"), "{text}");
    assert!(
        text.contains("rtls_http_requests_total{route=\"/api/v1/measurements\",status=\"2xx\"} 1"),
        "{text}"
    );

    // every documented operation is routed (a handler answers: not axum's empty 404 / 405)
    let document = call(&app, Method::GET, "/openapi.json", None, "").await.json();
    let mut operations = 0;
    for (path, item) in document["paths"].as_object().unwrap() {
        for method in ["get", "put", "post", "delete"] {
            if item.get(method).is_none() || path == "/v2/ws/socket" {
                continue;
            }
            operations += 1;
            let uri = path
                .replace("{provider_id}", "p")
                .replace("{trackable_id}", "t")
                .replace("{zone_id}", "z")
                .replace("{fence_id}", "f")
                .replace("{path}", "dashboard/app.js")
                .replace("{alarm_id}", "a");
            let reply = call(&app, method.to_uppercase().parse().unwrap(), &uri, Some(WRITE), "").await;
            let unrouted = reply.status == StatusCode::METHOD_NOT_ALLOWED && reply.body.is_empty()
                || reply.status == StatusCode::NOT_FOUND && reply.body.is_empty();
            assert!(
                !unrouted,
                "{method} {path} is documented but not routed ({})",
                reply.status
            );
        }
    }
    assert!(operations >= 30, "{operations} operations");
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn geojson_is_wgs84_longitude_latitude_when_the_site_is_georeferenced_and_local_on_request() {
    let local_state = state("api-geo");
    let local_app = rtls_server::http::router(local_state.clone());
    // the same server, its site given a WGS-84 origin
    let mut geo_state = local_state.clone();
    let mut site = (*geo_state.site).clone();
    site.frame = Some(rtls_engine::site::FrameSettings {
        origin: rtls_engine::site::GeodeticOrigin {
            latitude_deg: 47.3769,
            longitude_deg: 8.5417,
            height_m: 455.0,
        },
        x_axis_bearing_deg: 90.0,
    });
    geo_state.site = std::sync::Arc::new(site);
    let geo_app = rtls_server::http::router(geo_state);

    let reply = call(
        &geo_app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &walk("miner-9", 3000.0, 4.0),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);
    // the walk tracked to its second-last fix, t = 3003.5 s (the last one waits in the 0.2 s
    // re-ordering window for a newer record): the two reads below see one state
    let tracked = eventually(Duration::from_secs(10), || {
        local_state
            .pipeline
            .live()
            .tag("miner-9")
            .is_some_and(|state| state.time_s >= 3003.5)
    })
    .await;
    assert!(tracked);

    let local = call(&local_app, Method::GET, "/api/v1/tracks.geojson", Some(READ), "")
        .await
        .json();
    let [x, y] = [0, 1].map(|k| local["features"][0]["geometry"]["coordinates"][k].as_f64().unwrap());
    assert!(
        (1.0..8.0).contains(&x) && (y - 10.0).abs() < 1.0,
        "site metres: {x}, {y}"
    );
    // RFC 7946: [longitude, latitude]; 10 m north of the origin is 9e-5° of latitude
    let geo = call(&geo_app, Method::GET, "/api/v1/tracks.geojson", Some(READ), "")
        .await
        .json();
    let [lon, lat] = [0, 1].map(|k| geo["features"][0]["geometry"]["coordinates"][k].as_f64().unwrap());
    assert!((lat - 47.3769 - y / 111_200.0).abs() < 2e-6, "latitude {lat}");
    assert!(
        (lon - 8.5417 - x / (111_320.0 * 47.3769_f64.to_radians().cos())).abs() < 2e-6,
        "longitude {lon}"
    );
    // crs=local keeps metres on a georeferenced site (the dashboard draws in them)
    let asked_local = call(
        &geo_app,
        Method::GET,
        "/api/v1/tracks.geojson?crs=local",
        Some(READ),
        "",
    )
    .await
    .json();
    assert_eq!(asked_local["features"][0]["geometry"], local["features"][0]["geometry"]);
    let zones = call(&geo_app, Method::GET, "/api/v1/zones.geojson", Some(READ), "")
        .await
        .json();
    let ring = zones["features"][0]["geometry"]["coordinates"][0]
        .as_array()
        .unwrap()
        .clone();
    assert!(
        ring.iter().all(|p| (p[1].as_f64().unwrap() - 47.3769).abs() < 1e-3),
        "{ring:?}"
    );
    // a site without a frame cannot answer in WGS-84, and an unknown crs is named
    let refused = call(
        &local_app,
        Method::GET,
        "/api/v1/zones.geojson?crs=EPSG:4326",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(refused.status, StatusCode::BAD_REQUEST);
    assert_eq!(refused.json()["field"], "crs");
    let unknown = call(
        &geo_app,
        Method::GET,
        "/api/v1/tracks.geojson?crs=EPSG:3857",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(unknown.status, StatusCode::BAD_REQUEST);
    local_state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fence_drawn_live_is_watched_by_the_running_trackers_renamed_deleted_and_stored() {
    let state = state("api-fence-edit");
    let app = rtls_server::http::router(state.clone());
    // a zone around the walk (y = 10 m, x from 2 m), with no restart
    let fence = r#"{"name": "Staging", "crs": "local", "region": {"type": "Polygon",
        "coordinates": [[[0, 5], [12, 5], [12, 15], [0, 15], [0, 5]]]},
        "properties": {"rtls:kind": "restricted"}}"#;
    let created = call(&app, Method::POST, "/v2/fences", Some(WRITE), fence).await;
    assert_eq!(created.status, StatusCode::CREATED);
    let created = created.json();
    let id = created["id"].as_str().unwrap().to_string();
    assert_eq!(created["name"], "Staging");
    assert_eq!(created["properties"]["rtls:kind"], "restricted");
    let listed = call(&app, Method::GET, "/v2/fences", Some(READ), "").await.json();
    assert_eq!(listed.as_array().unwrap().len(), 2, "{listed}");

    let reply = call(
        &app,
        Method::POST,
        "/api/v1/measurements",
        Some(WRITE),
        &walk("m-1", 100.0, 8.0),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);
    let counted = eventually(Duration::from_secs(10), || {
        state
            .pipeline
            .live()
            .occupants()
            .get(&id)
            .is_some_and(|tags| tags == &["m-1".to_string()])
    })
    .await;
    assert!(counted, "{:?}", state.pipeline.live().occupants());
    let counts = call(&app, Method::GET, "/api/v1/zones/head-counts", Some(READ), "")
        .await
        .json();
    assert_eq!(counts[&id], 1, "{counts}");

    // renamed and reshaped: the id and the tag inside stay
    let renamed = call(
        &app,
        Method::PUT,
        &format!("/v2/fences/{id}"),
        Some(WRITE),
        r#"{"name": "Staging area", "crs": "local", "region": {"type": "Point", "coordinates": [8, 10]}, "radius": 6}"#,
    )
    .await;
    assert_eq!(renamed.status, StatusCode::NO_CONTENT, "{}", renamed.text());
    let renamed = call(&app, Method::GET, &format!("/v2/fences/{id}"), Some(READ), "").await;
    assert_eq!(renamed.json()["name"], "Staging area");
    assert_eq!(state.pipeline.live().head_counts()[&id], 1);

    // bad fences name their field; a floor must be the site's
    let bad = call(
        &app,
        Method::POST,
        "/v2/fences",
        Some(WRITE),
        r#"{"crs": "local", "region": {"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 0]]]}}"#,
    )
    .await;
    assert_eq!(
        (bad.status, bad.json()["field"].as_str()),
        (StatusCode::BAD_REQUEST, Some("region.coordinates[0]")),
        "a ring of two corners"
    );
    let crossed = call(
        &app,
        Method::POST,
        "/v2/fences",
        Some(WRITE),
        r#"{"crs": "local", "region": {"type": "Polygon", "coordinates": [[[0, 0], [2, 2], [2, 0], [0, 2], [0, 0]]]}}"#,
    )
    .await;
    assert_eq!(crossed.json()["field"], "region", "{}", crossed.text());
    assert!(
        crossed.json()["message"].as_str().unwrap().starts_with("zone `"),
        "the zone's words, without the site file's position: {}",
        crossed.text()
    );
    let bad_kind = call(
        &app,
        Method::POST,
        "/v2/fences",
        Some(WRITE),
        r#"{"crs": "local", "region": {"type": "Point", "coordinates": [0, 0]}, "radius": 2, "properties": {"rtls:kind": "lava"}}"#,
    )
    .await;
    assert_eq!(bad_kind.json()["field"], "properties.rtls:kind");
    assert_eq!(
        call(&app, Method::POST, "/v2/fences", None, fence).await.status,
        StatusCode::UNAUTHORIZED
    );

    // the edited set is stored: a restart loads it
    // (read on a connection of its own, as `rtls serve` reads it at start)
    let stored =
        rtls_server::http::fences::stored_zones(common::open_sqlite(&common::db_path("api-fence-edit")).as_mut())
            .unwrap()
            .unwrap();
    assert_eq!(stored.len(), 2);
    assert!(stored.iter().any(|z| z.id == id && z.name == "Staging area"));

    let deleted = call(&app, Method::DELETE, &format!("/v2/fences/{id}"), Some(WRITE), "").await;
    assert_eq!(deleted.status, StatusCode::NO_CONTENT);
    assert!(!state.pipeline.live().head_counts().contains_key(&id));
    assert_eq!(
        call(&app, Method::GET, &format!("/v2/fences/{id}"), Some(READ), "")
            .await
            .status,
        StatusCode::NOT_FOUND
    );
    // back to the site file's zones
    let reset = call(&app, Method::DELETE, "/api/v1/zones/edits", Some(WRITE), "").await;
    assert_eq!(reset.status, StatusCode::NO_CONTENT);
    assert_eq!(state.pipeline.live().zones().len(), 1);
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cors_lets_the_configured_origins_call_the_api_and_no_other() {
    let state = state("api-cors");
    let plain = rtls_server::http::router(state.clone());
    let app = rtls_server::serve::with_cors(plain.clone(), &["https://ops.example.com".to_string()]);
    let preflight = |app: axum::Router, origin: &'static str| async move {
        app.oneshot(
            Request::builder()
                .method(Method::OPTIONS)
                .uri("/api/v1/tags")
                .header("origin", origin)
                .header("access-control-request-method", "GET")
                .header("access-control-request-headers", "authorization")
                .body(Body::empty())
                .unwrap(),
        )
        .await
        .unwrap()
    };
    let allowed = preflight(app.clone(), "https://ops.example.com").await;
    assert_eq!(
        allowed
            .headers()
            .get("access-control-allow-origin")
            .map(|v| v.to_str().unwrap()),
        Some("https://ops.example.com")
    );
    let headers = allowed.headers()["access-control-allow-headers"]
        .to_str()
        .unwrap()
        .to_lowercase();
    assert!(headers.contains("authorization"), "{headers}");
    let other = preflight(app.clone(), "https://evil.example.net").await;
    assert!(other.headers().get("access-control-allow-origin").is_none());
    // without cors_origins, no CORS headers at all
    let unconfigured = preflight(plain, "https://ops.example.com").await;
    assert!(unconfigured.headers().get("access-control-allow-origin").is_none());
    // a real request from the allowed origin carries the header too
    let get = app
        .oneshot(
            Request::builder()
                .uri("/api/v1/tags")
                .header("origin", "https://ops.example.com")
                .header("authorization", format!("Bearer {READ}"))
                .body(Body::empty())
                .unwrap(),
        )
        .await
        .unwrap();
    assert_eq!(get.status(), StatusCode::OK);
    assert_eq!(get.headers()["access-control-allow-origin"], "https://ops.example.com");
    state.pipeline.shutdown();
}
