//! What the omlox OpenAPI run through schemathesis found (docs/SERVER.md, "omlox conformance"),
//! each pinned through the router: boolean query parameters are checked, a location body is
//! required, `properties` is an object (never `null`), fields the schema does not name are
//! ignored on providers and trackables, `locating_rules` is kept, and a location pushed in
//! EPSG:4326 is tracked in site metres through the site's georeference.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{assert_omlox_error, call, eventually, post_created, state, FRAME, WRITE};
use serde_json::json;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn boolean_parameters_bodies_and_properties_are_checked_and_extra_fields_ignored() {
    let app = rtls_server::http::router(state("conformance-checks"));
    for uri in [
        "/v2/providers/locations?geojson=null&geojson=null",
        "/v2/fences/summary?geojson=1",
        "/v2/trackables/motions?geojson=",
        "/v2/providers/AABB/fences?spatial_query=null",
    ] {
        let reply = call(&app, Method::GET, uri, Some(WRITE), "").await;
        let field = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, uri);
        assert!(
            matches!(field.as_deref(), Some("geojson" | "spatial_query")),
            "{uri}: {field:?}"
        );
    }
    let reply = call(
        &app,
        Method::GET,
        "/v2/providers/locations?geojson=false",
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK);

    // PUT of a provider's location without a body is no empty update
    let reply = call(&app, Method::PUT, "/v2/providers/AABB/location", Some(WRITE), "").await;
    assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "a location without a body");

    // refused, naming the field: `null` for an object or a number, a rule without its
    // priority, a position of four numbers, a geometry of another type, an id that is no UUID
    for (path, body, field) in [
        (
            "/v2/providers",
            json!({"id": "AABB", "type": "uwb", "properties": null}),
            "properties",
        ),
        (
            "/v2/providers",
            json!({"id": "CCDD", "type": "uwb", "exit_delay": null}),
            "exit_delay",
        ),
        (
            "/v2/trackables",
            json!({"type": "omlox", "locating_rules": [{"expression": "type = 'uwb'", "priority": {}}]}),
            "locating_rules",
        ),
        (
            "/v2/trackables",
            json!({"type": "omlox", "geometry": {"type": "Polygon", "coordinates": [[[0.0, 0.0, 0.0, 0.0]]]}}),
            "geometry",
        ),
        (
            "/v2/trackables",
            json!({"type": "omlox", "geometry": {"type": "AAA", "coordinates": [[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]]}}),
            "geometry",
        ),
        ("/v2/trackables", json!({"id": "", "type": "omlox"}), "id"),
        ("/v2/trackables", json!({"id": null, "type": "omlox"}), "id"),
    ] {
        let reply = call(&app, Method::POST, path, Some(WRITE), &body.to_string()).await;
        let named = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, &body.to_string());
        assert!(named.is_some_and(|f| f.starts_with(field)), "{body}: {}", reply.text());
    }
    // a field the schema does not name is ignored
    let provider = json!({"id": "AABB", "type": "uwb", "vendor_field": {"x": 1}, "properties": {"a": 1}});
    let reply = call(&app, Method::POST, "/v2/providers", Some(WRITE), &provider.to_string()).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    assert_eq!(reply.json()["properties"]["a"], 1);
    assert!(reply.json().get("vendor_field").is_none());

    // a trackable's locating rules are kept as given
    let rules = json!([{"expression": "type = 'uwb' AND accuracy < 5", "priority": 9}]);
    let trackable = json!({"id": "6b1b3e1c-3b0e-4f3a-9a53-1c1d7d3f2a10", "type": "omlox",
                           "locating_rules": rules, "unmodelled": true});
    post_created(&app, "/v2/trackables", &trackable).await;
    let reply = call(
        &app,
        Method::GET,
        "/v2/trackables/6b1b3e1c-3b0e-4f3a-9a53-1c1d7d3f2a10",
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(reply.json()["locating_rules"], rules);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_location_pushed_in_wgs84_is_tracked_in_site_metres() {
    let local_state = state("conformance-wgs84");
    let mut geo_state = local_state.clone();
    let mut site = (*geo_state.site).clone();
    site.frame = Some(FRAME);
    geo_state.site = std::sync::Arc::new(site);
    let geo_app = rtls_server::http::router(geo_state);
    let local_app = rtls_server::http::router(local_state.clone());

    let stamp = |t: f64| rtls_server::omlox::time::format_timestamp(t, "t").unwrap();
    let wgs84 = |t: f64| {
        let [lon, lat, _] = FRAME.wgs84_of([6.0, 4.0, 0.0]).unwrap();
        json!({"position": {"type": "Point", "coordinates": [lon, lat]}, "crs": "EPSG:4326",
               "source": "gnss", "provider_type": "gps", "provider_id": "truck-4",
               "timestamp_generated": stamp(t), "accuracy": 0.5})
    };
    let body = json!([wgs84(3000.0), wgs84(3001.0), wgs84(3002.0)]).to_string();
    // a site without a georeference cannot place it, and says so
    let reply = call(&local_app, Method::PUT, "/v2/providers/locations", Some(WRITE), &body).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "no frame").as_deref(),
        Some("[0].crs")
    );
    let reply = call(&geo_app, Method::PUT, "/v2/providers/locations", Some(WRITE), &body).await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let tracked = eventually(Duration::from_secs(10), || {
        local_state.pipeline.live().tag("truck-4").is_some()
    })
    .await;
    assert!(tracked, "the WGS-84 pushes are tracked");
    let location = call(
        &local_app,
        Method::GET,
        "/v2/providers/truck-4/location",
        Some(WRITE),
        "",
    )
    .await
    .json();
    let xy = &location["position"]["coordinates"];
    let (x, y) = (xy[0].as_f64().unwrap(), xy[1].as_f64().unwrap());
    assert!((x - 6.0).abs() < 1e-3 && (y - 4.0).abs() < 1e-3, "{location}");

    // a fence drawn in EPSG:4326 is watched in site metres
    let square = [[20.0, 20.0], [30.0, 20.0], [30.0, 30.0], [20.0, 30.0], [20.0, 20.0]];
    let ring: Vec<[f64; 2]> = square
        .iter()
        .map(|&[x, y]| {
            let [lon, lat, _] = FRAME.wgs84_of([x, y, 0.0]).unwrap();
            [lon, lat]
        })
        .collect();
    let fence = json!({"id": "00000000-0000-0000-0000-000000000000", "crs": "EPSG:4326",
                       "region": {"type": "Polygon", "coordinates": [ring]}, "name": "yard"});
    let reply = call(&local_app, Method::POST, "/v2/fences", Some(WRITE), &fence.to_string()).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "no frame").as_deref(),
        Some("crs")
    );
    let reply = call(&geo_app, Method::POST, "/v2/fences", Some(WRITE), &fence.to_string()).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    // answered in the CRS it was written in, and stored in site metres
    let created = reply.json();
    assert_eq!(created["crs"], "EPSG:4326", "{created}");
    let vertices = created["region"]["coordinates"][0].as_array().unwrap().clone();
    for (vertex, [lon, lat]) in vertices.iter().zip(&ring) {
        let (vx, vy) = (vertex[0].as_f64().unwrap(), vertex[1].as_f64().unwrap());
        assert!((vx - lon).abs() < 1e-9 && (vy - lat).abs() < 1e-9, "{created}");
    }
    let id = created["id"].as_str().unwrap();
    let local = call(
        &geo_app,
        Method::GET,
        &format!("/v2/fences/{id}?crs=local"),
        Some(WRITE),
        "",
    )
    .await;
    let local = local.json();
    let vertices = local["region"]["coordinates"][0].as_array().unwrap().clone();
    for (vertex, [x, y]) in vertices.iter().zip(square) {
        let (vx, vy) = (vertex[0].as_f64().unwrap(), vertex[1].as_f64().unwrap());
        assert!((vx - x).abs() < 1e-6 && (vy - y).abs() < 1e-6, "{local}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn course_is_from_true_north_and_motions_come_in_wgs84_on_request() {
    // the plan's x axis points north: a tag walking along +x walks north (course 0°)
    let mut site = common::site();
    site.frame = Some(rtls_engine::site::FrameSettings {
        x_axis_bearing_deg: 0.0,
        ..FRAME
    });
    let (state, app) = common::walked_on_site("conformance-course", site).await;
    let location = call(&app, Method::GET, "/v2/providers/walker/location", Some(WRITE), "")
        .await
        .json();
    let course = location["course"].as_f64().unwrap();
    // site course 90° (along +x), turned by the bearing 0° − 90°
    assert!(course.min(360.0 - course) < 5.0, "{location}");

    // a trackable's motion in WGS-84 on request, as the location reads
    let trackable = json!({"id": "00000000-0000-0000-0000-000000000000", "type": "omlox",
                           "location_providers": ["walker"]});
    let id = post_created(&app, "/v2/trackables", &trackable).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let motion = |crs: &'static str| {
        let (app, id) = (app.clone(), id.clone());
        async move {
            call(
                &app,
                Method::GET,
                &format!("/v2/trackables/{id}/motion?crs={crs}"),
                Some(WRITE),
                "",
            )
            .await
        }
    };
    let (local, wgs84) = (motion("local").await.json(), motion("EPSG:4326").await.json());
    let xy = [0, 1].map(|k| local["location"]["position"]["coordinates"][k].as_f64().unwrap());
    let frame = state.site.frame.unwrap();
    let [lon, lat, _] = frame.wgs84_of([xy[0], xy[1], 0.0]).unwrap();
    let got = [0, 1].map(|k| wgs84["location"]["position"]["coordinates"][k].as_f64().unwrap());
    assert_eq!(wgs84["location"]["crs"], "EPSG:4326", "{wgs84}");
    assert!(
        (got[0] - lon).abs() < 1e-9 && (got[1] - lat).abs() < 1e-9,
        "{wgs84} against {local}"
    );
    let all = call(
        &app,
        Method::GET,
        "/v2/trackables/motions?crs=EPSG:4326",
        Some(WRITE),
        "",
    )
    .await;
    assert_eq!(all.json()[0]["location"]["crs"], "EPSG:4326");
    let refused = motion("EPSG:3857").await;
    assert_eq!(
        assert_omlox_error(&refused, StatusCode::BAD_REQUEST, "another CRS").as_deref(),
        Some("crs")
    );
}
