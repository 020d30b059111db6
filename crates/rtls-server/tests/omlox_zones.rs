//! The omlox zone operations (create, replace, delete, transform, createfence) and proximities
//! through the router (`tower::ServiceExt::oneshot`), with their error cases as omlox `Error`
//! objects.

mod common;

use std::sync::Arc;
use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{assert_omlox_error, call, call_json, eventually, state, FRAME, READ, WRITE};
use rtls_server::http::AppState;
use serde_json::{json, Value};

/// `state` with the site georeferenced at [`FRAME`].
fn georeferenced(mut state: AppState) -> AppState {
    let mut site = (*state.site).clone();
    site.frame = Some(FRAME);
    state.site = Arc::new(site);
    state
}

/// A UWB zone whose ground control points are a 6 × 12 m rectangle at x ∈ [20, 26] m,
/// y ∈ [4, 16] m of the site (their WGS-84 corners through [`FRAME`]).
fn rectangle_zone() -> Value {
    let mut points = Vec::new();
    for [x, y] in [[20.0, 4.0], [26.0, 4.0], [26.0, 16.0], [20.0, 16.0]] {
        let [lon, lat, _] = FRAME.wgs84_of([x, y, 0.0]).unwrap();
        points.push(json!([lon, lat]));
        points.push(json!([x, y]));
    }
    json!({"id": "00000000-0000-0000-0000-000000000000", "type": "uwb", "name": "Bay 3",
           "foreign_id": "bay-3", "ground_control_points": points, "description": "loading bay"})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zones_are_created_replaced_transformed_made_into_fences_and_deleted() {
    let state = georeferenced(state("zones-crud"));
    let app = rtls_server::http::router(state.clone());
    let site_zone = call_json(&app, "/v2/zones").await[0].as_str().unwrap().to_string();

    // invalid zones name their field
    for (zone, field) in [
        (json!({"type": "uwb"}), "ground_control_points"),
        (
            json!({"type": "rfid", "position": {"type": "Point", "coordinates": [8.5, 47.3]},
                "ground_control_points": [[8.5, 47.3], [0, 0]]}),
            "ground_control_points",
        ),
        (json!({"type": "ibeacon"}), "position"),
        (
            json!({"type": "rfid", "position": {"type": "Point", "coordinates": [200.0, 47.3]}}),
            "position.coordinates",
        ),
        (
            json!({"type": "rfid", "incomplete_configuration": true, "radius": -1.0}),
            "radius",
        ),
        (
            json!({"type": "uwb", "incomplete_configuration": true, "id": "not-a-uuid"}),
            "id",
        ),
        (json!({"type": "tachyon", "incomplete_configuration": true}), "type"),
        (
            json!({"type": "uwb", "incomplete_configuration": true, "measurement_timestamp": "yesterday"}),
            "measurement_timestamp",
        ),
    ] {
        let reply = call(&app, Method::POST, "/v2/zones", Some(WRITE), &zone.to_string()).await;
        let named = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, &zone.to_string());
        assert_eq!(named.as_deref(), Some(field), "{zone}");
    }
    let reply = call(
        &app,
        Method::POST,
        "/v2/zones",
        Some(READ),
        &rectangle_zone().to_string(),
    )
    .await;
    assert_omlox_error(&reply, StatusCode::FORBIDDEN, "a read token");

    // create (the nil id means "assign one"), read, list, filter by foreign id
    let reply = call(
        &app,
        Method::POST,
        "/v2/zones",
        Some(WRITE),
        &rectangle_zone().to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let zone = reply.json();
    let id = zone["id"].as_str().unwrap().to_string();
    assert!(!uuid::Uuid::parse_str(&id).unwrap().is_nil());
    assert_eq!(call_json(&app, &format!("/v2/zones/{id}")).await, zone);
    assert_eq!(call_json(&app, "/v2/zones").await, json!([site_zone, id]));
    assert_eq!(call_json(&app, "/v2/zones?foreign_id=bay-3").await, json!([id]));
    assert_eq!(
        call_json(&app, "/v2/zones/summary?foreign_id=bay-3").await,
        json!([zone])
    );
    // omlox POST /zones: "The provided id will be replaced by a generated uuid" — here when it
    // is in use (the site's own zone's too); the zone that had it stays
    for taken in [id.as_str(), site_zone.as_str()] {
        let again = json!({"id": taken, "type": "uwb", "incomplete_configuration": true}).to_string();
        let reply = call(&app, Method::POST, "/v2/zones", Some(WRITE), &again).await;
        assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
        let renewed = reply.json()["id"].as_str().unwrap().to_string();
        assert!(renewed != taken && uuid::Uuid::parse_str(&renewed).is_ok(), "{renewed}");
        let reply = call(&app, Method::DELETE, &format!("/v2/zones/{renewed}"), Some(WRITE), "").await;
        assert_eq!(reply.status, StatusCode::NO_CONTENT);
    }
    assert_eq!(call_json(&app, &format!("/v2/zones/{id}")).await, zone);

    // replace: 204 and read back; unknown 404, the site's own 400, a mismatched id 400
    let mut renamed = zone.clone();
    renamed["name"] = json!("Bay 3 (north)");
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}"),
        Some(WRITE),
        &renamed.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    assert_eq!(
        call_json(&app, &format!("/v2/zones/{id}")).await["name"],
        "Bay 3 (north)"
    );
    let unknown = "7c9e6679-7425-40de-944b-e07fc1f90ae7";
    let body = json!({"type": "uwb", "incomplete_configuration": true}).to_string();
    let reply = call(&app, Method::PUT, &format!("/v2/zones/{unknown}"), Some(WRITE), &body).await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown zone");
    let reply = call(&app, Method::PUT, &format!("/v2/zones/{site_zone}"), Some(WRITE), &body).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "the site's zone").as_deref(),
        Some("zone_id")
    );
    let mismatched = json!({"id": unknown, "type": "uwb", "incomplete_configuration": true});
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}"),
        Some(WRITE),
        &mismatched.to_string(),
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "mismatch").as_deref(),
        Some("id")
    );
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}"),
        Some(WRITE),
        "{\"type\": ",
    )
    .await;
    assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "bad JSON");

    // transform with the ground control points, and back; the site's zone with its frame
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}/transform"),
        Some(READ),
        &json!({"position": {"type": "Point", "coordinates": [23.0, 10.0, 1.5]}}).to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let geo = reply.json();
    assert_eq!((&geo["crs"], &geo["source"]), (&json!("EPSG:4326"), &json!(id)));
    let [lon, lat, _] = FRAME.wgs84_of([23.0, 10.0, 0.0]).unwrap();
    let got = &geo["position"]["coordinates"];
    assert!(
        (got[0].as_f64().unwrap() - lon).abs() < 1e-7 && (got[1].as_f64().unwrap() - lat).abs() < 1e-7,
        "{geo}"
    );
    assert_eq!(got[2], 1.5);
    for zone_id in [id.as_str(), site_zone.as_str()] {
        let body = json!({"position": {"type": "Point", "coordinates": [lon, lat]}, "crs": "EPSG:4326"});
        let back = call(
            &app,
            Method::PUT,
            &format!("/v2/zones/{zone_id}/transform"),
            Some(READ),
            &body.to_string(),
        )
        .await;
        assert_eq!(back.status, StatusCode::OK, "{}", back.text());
        let local = back.json();
        assert_eq!(local["crs"], "local");
        let [x, y] = [0, 1].map(|k| local["position"]["coordinates"][k].as_f64().unwrap());
        assert!((x - 23.0).abs() < 0.01 && (y - 10.0).abs() < 0.01, "{zone_id}: {local}");
    }
    let bad_crs = json!({"position": {"type": "Point", "coordinates": [1.0, 2.0]}, "crs": "EPSG:3857"});
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}/transform"),
        Some(READ),
        &bad_crs.to_string(),
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "crs").as_deref(),
        Some("crs")
    );
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{id}/transform"),
        Some(READ),
        "{}",
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "no position").as_deref(),
        None
    );
    let point = json!({"position": {"type": "Point", "coordinates": [1.0, 2.0]}}).to_string();
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{unknown}/transform"),
        Some(READ),
        &point,
    )
    .await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown zone");
    let reply = call(&app, Method::PUT, &format!("/v2/zones/{id}/transform"), None, &point).await;
    assert_omlox_error(&reply, StatusCode::UNAUTHORIZED, "no token");

    // createfence: a fence the trackers watch, made again in place
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/zones/{id}/createfence"),
        Some(READ),
        "",
    )
    .await;
    assert_omlox_error(&reply, StatusCode::FORBIDDEN, "creating a fence needs operate");
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/zones/{id}/createfence"),
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let fence = reply.json();
    let fence_id = fence["id"].as_str().unwrap().to_string();
    // in the fence reads' default: EPSG:4326 on this georeferenced site
    assert_eq!(
        (&fence["name"], &fence["crs"]),
        (&json!("Bay 3 (north)"), &json!("EPSG:4326"))
    );
    assert_eq!(call_json(&app, &format!("/v2/fences/{fence_id}")).await, fence);
    let local = call_json(&app, &format!("/v2/fences/{fence_id}?crs=local")).await;
    let ring = local["region"]["coordinates"][0].as_array().unwrap();
    assert_eq!(ring.len(), 5, "{local}");
    let [x, y] = [0, 1].map(|k| ring[2][k].as_f64().unwrap());
    assert!((x - 26.0).abs() < 1e-3 && (y - 16.0).abs() < 1e-3, "{local}");
    let live = state.pipeline.live();
    assert!(live.zones().iter().any(|z| z.id == fence_id), "the trackers watch it");
    assert!(live
        .zones()
        .iter()
        .any(|z| z.contains([23.0, 10.0, 0.0]) && z.id == fence_id));
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/zones/{id}/createfence"),
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.json()["id"], fence_id.as_str());
    assert_eq!(
        call_json(&app, "/v2/fences").await.as_array().unwrap().len(),
        2,
        "replaced, not added"
    );
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/zones/{unknown}/createfence"),
        Some(WRITE),
        "",
    )
    .await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown zone");
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/zones/{site_zone}/createfence"),
        Some(WRITE),
        "",
    )
    .await;
    assert_omlox_error(
        &reply,
        StatusCode::BAD_REQUEST,
        "the site's zone has no ground control points",
    );

    // delete one (its fence stays), the site's own is refused, then all
    let reply = call(&app, Method::DELETE, &format!("/v2/zones/{id}"), Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_omlox_error(
        &call(&app, Method::GET, &format!("/v2/zones/{id}"), Some(READ), "").await,
        StatusCode::NOT_FOUND,
        "deleted zone",
    );
    assert_omlox_error(
        &call(&app, Method::DELETE, &format!("/v2/zones/{id}"), Some(WRITE), "").await,
        StatusCode::NOT_FOUND,
        "deleted twice",
    );
    assert_omlox_error(
        &call(&app, Method::DELETE, &format!("/v2/zones/{site_zone}"), Some(WRITE), "").await,
        StatusCode::BAD_REQUEST,
        "the site's zone",
    );
    assert_eq!(
        call_json(&app, &format!("/v2/fences/{fence_id}")).await["id"],
        fence_id.as_str()
    );
    for name in ["a", "b"] {
        let zone = json!({"type": "wifi", "name": name, "incomplete_configuration": true}).to_string();
        assert_eq!(
            call(&app, Method::POST, "/v2/zones", Some(WRITE), &zone).await.status,
            StatusCode::CREATED
        );
    }
    assert_eq!(call_json(&app, "/v2/zones").await.as_array().unwrap().len(), 3);
    assert_omlox_error(
        &call(&app, Method::DELETE, "/v2/zones", None, "").await,
        StatusCode::UNAUTHORIZED,
        "no token",
    );
    let reply = call(&app, Method::DELETE, "/v2/zones", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_eq!(call_json(&app, "/v2/zones").await, json!([site_zone]));
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn proximities_place_a_provider_at_its_reader_and_are_tracked() {
    let plain = state("zones-proximity");
    let state = georeferenced(plain.clone());
    let app = rtls_server::http::router(state.clone());
    let [lon, lat, _] = FRAME.wgs84_of([20.0, 10.0, 0.0]).unwrap();
    let gate = json!({"type": "rfid", "foreign_id": "gate-3", "radius": 1.5, "floor": 0,
                      "position": {"type": "Point", "coordinates": [lon, lat]}});
    let reply = call(&app, Method::POST, "/v2/zones", Some(WRITE), &gate.to_string()).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let gate_id = reply.json()["id"].as_str().unwrap().to_string();
    let stamp = |t: f64| rtls_server::omlox::time::format_timestamp(t, "t").unwrap();
    let proximity = |source: &str, t: f64| {
        json!({"source": source, "provider_type": "rfid", "provider_id": "rfid-77",
               "timestamp_generated": stamp(t), "accuracy": 0.4, "properties": {"rssi": -51}})
    };

    // bulk (by foreign id) and one (by zone id, any letter case)
    let bulk: Vec<Value> = (0..6).map(|k| proximity("gate-3", 3000.0 + f64::from(k))).collect();
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/proximities",
        Some(WRITE),
        &Value::Array(bulk).to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let one = proximity(&gate_id.to_uppercase(), 3006.0).to_string();
    let reply = call(&app, Method::PUT, "/v2/providers/rfid-77/proximity", Some(WRITE), &one).await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let live = state.pipeline.live().clone();
    let placed = eventually(Duration::from_secs(10), || {
        live.tag("rfid-77").is_some_and(|t| t.time_s >= 3004.9)
    })
    .await;
    assert!(placed, "{:?}", live.tag("rfid-77"));
    let location = call_json(&app, "/v2/providers/rfid-77/location").await;
    let [x, y] = [0, 1].map(|k| location["position"]["coordinates"][k].as_f64().unwrap());
    assert!(
        (x - 20.0).abs() < 0.05 && (y - 10.0).abs() < 0.05,
        "at the gate: {location}"
    );

    // the same location in WGS-84 through the site's frame (`?crs=EPSG:4326`), one and all
    let [lon, lat, _] = FRAME.wgs84_of([x, y, 0.0]).unwrap();
    let in_degrees = call_json(&app, "/v2/providers/rfid-77/location?crs=EPSG:4326").await;
    assert_eq!(in_degrees["crs"], "EPSG:4326", "{in_degrees}");
    let [got_lon, got_lat] = [0, 1].map(|k| in_degrees["position"]["coordinates"][k].as_f64().unwrap());
    assert!(
        (got_lon - lon).abs() < 1e-9 && (got_lat - lat).abs() < 1e-9,
        "{in_degrees} against ({lon}, {lat})"
    );
    assert_eq!(in_degrees["accuracy"], location["accuracy"], "accuracy stays in metres");
    let all = call_json(&app, "/v2/providers/locations?crs=EPSG:4326").await;
    let listed = all
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["provider_id"] == "rfid-77")
        .expect("rfid-77 listed");
    assert_eq!(listed["position"], in_degrees["position"]);
    assert_eq!(
        call_json(&app, "/v2/providers/rfid-77/location?crs=local").await["position"],
        location["position"]
    );
    let reply = call(
        &app,
        Method::GET,
        "/v2/providers/locations?crs=EPSG:3857",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "EPSG:3857").as_deref(),
        Some("crs")
    );
    let reply = call(
        &rtls_server::http::router(plain.clone()),
        Method::GET,
        "/v2/providers/rfid-77/location?crs=EPSG:4326",
        Some(READ),
        "",
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "no [frame]").as_deref(),
        Some("crs")
    );

    // refused: unknown source, a technology that is not proximity-based, a negative distance,
    // a mismatched provider, a bad body, a site without a georeference, no token
    let mut uwb = proximity("gate-3", 3007.0);
    uwb["provider_type"] = json!("uwb");
    let mut negative = proximity("gate-3", 3007.0);
    negative["accuracy"] = json!(-1.0);
    for (body, field) in [
        (json!([proximity("gate-9", 3007.0)]), "[0].source"),
        (json!([proximity("gate-3", 3007.0), uwb]), "[1].provider_type"),
        (json!([negative]), "[0].accuracy"),
        (json!([{"source": "gate-3", "provider_type": "rfid"}]), "[0]"),
    ] {
        let reply = call(
            &app,
            Method::PUT,
            "/v2/providers/proximities",
            Some(WRITE),
            &body.to_string(),
        )
        .await;
        let named = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, &body.to_string());
        assert_eq!(named.as_deref(), Some(field), "{body}");
    }
    let reply = call(&app, Method::PUT, "/v2/providers/rfid-78/proximity", Some(WRITE), &one).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "mismatch").as_deref(),
        Some("provider_id")
    );
    let reply = call(&app, Method::PUT, "/v2/providers/rfid-77/proximity", Some(WRITE), "[").await;
    assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "bad JSON");
    let plain_app = rtls_server::http::router(plain);
    let reply = call(
        &plain_app,
        Method::PUT,
        "/v2/providers/rfid-77/proximity",
        Some(WRITE),
        &one,
    )
    .await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "no [frame]").as_deref(),
        Some("source")
    );
    let reply = call(&app, Method::PUT, "/v2/providers/rfid-77/proximity", None, &one).await;
    assert_omlox_error(&reply, StatusCode::UNAUTHORIZED, "no token");
    let reply = call(&app, Method::PUT, "/v2/providers/proximities", Some(READ), "[]").await;
    assert_omlox_error(&reply, StatusCode::FORBIDDEN, "a read token");
    state.pipeline.shutdown();
}
