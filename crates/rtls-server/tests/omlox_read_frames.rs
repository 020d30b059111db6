//! The query parameters `crs`, `zone_id` and `geojson` of the omlox reads (locations, motions,
//! fences; `http::read_frame`), through the router: coordinates checked against
//! `FrameSettings::wgs84_of` and against the zone transform (`PUT /v2/zones/{id}/transform`),
//! GeoJSON shapes and media type, and the refusals.

mod common;

use axum::http::{Method, StatusCode};
use common::{assert_omlox_error, call, lon_lat, post_created, turned_zone, zone_of, Reply, FRAME, WRITE};
use rtls_server::convert::uuid_for;
use serde_json::{json, Value};

/// The test site's hazard zone, a box x ∈ [14, 18] m, y ∈ [0, 20] m, as a closed ring.
const LANE: [[f64; 2]; 5] = [[14.0, 0.0], [18.0, 0.0], [18.0, 20.0], [14.0, 20.0], [14.0, 0.0]];

fn xy(position: &Value) -> [f64; 2] {
    [0, 1].map(|k| position["coordinates"][k].as_f64().unwrap_or(f64::NAN))
}

fn assert_near(got: [f64; 2], want: [f64; 2], tolerance: f64, what: &str) {
    assert!(
        (got[0] - want[0]).abs() < tolerance && (got[1] - want[1]).abs() < tolerance,
        "{what}: {got:?} against {want:?}"
    );
}

async fn get(app: &axum::Router, uri: &str) -> Reply {
    call(app, Method::GET, uri, Some(WRITE), "").await
}

async fn get_json(app: &axum::Router, uri: &str) -> Value {
    let reply = get(app, uri).await;
    assert_eq!(reply.status, StatusCode::OK, "GET {uri}: {}", reply.text());
    reply.json()
}

/// A georeferenced site (`georeferenced`) or not, a walker tracked to its last fix
/// ([`common::walked_on_site`]), a trackable
/// on it, a fence around where it stops, and a stored zone with ground control points: the
/// router, the trackable's id, the fence's id and the zone's id.
async fn scene(name: &str, georeferenced: bool) -> (axum::Router, String, String, String) {
    let mut site = common::site();
    site.frame = georeferenced.then_some(FRAME);
    let (_, app) = common::walked_on_site(name, site).await;
    let trackable = json!({"type": "omlox", "name": "walker", "location_providers": ["walker"]});
    let trackable = post_created(&app, "/v2/trackables", &trackable).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    // the walk stops at (7.5, 10)
    let square = [[6.0, 8.0], [10.0, 8.0], [10.0, 12.0], [6.0, 12.0], [6.0, 8.0]];
    let fence = json!({"crs": "local", "name": "stop", "region": {"type": "Polygon", "coordinates": [square]}});
    let fence = post_created(&app, "/v2/fences", &fence).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let zone = post_created(&app, "/v2/zones", &turned_zone()).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    (app, trackable, fence, zone)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn crs_and_zone_id_project_locations_motions_and_fences() {
    let (app, trackable, fence, zone) = scene("read-frames-projection", true).await;
    let local = get_json(&app, "/v2/providers/walker/location").await;
    let site_xy = xy(&local["position"]);
    assert!(
        (site_xy[0] - 7.5).abs() < 0.1,
        "the walker stops near x = 7.5 m: {local}"
    );

    // EPSG:4326: through the site's [frame]
    for uri in [
        "/v2/providers/walker/location?crs=EPSG:4326".to_string(),
        format!("/v2/trackables/{trackable}/location?crs=EPSG:4326"),
    ] {
        let location = get_json(&app, &uri).await;
        assert_eq!(location["crs"], "EPSG:4326", "{uri}");
        assert_near(xy(&location["position"]), lon_lat(site_xy), 1e-9, &uri);
    }
    let locations = get_json(&app, &format!("/v2/trackables/{trackable}/locations?crs=EPSG:4326")).await;
    assert_near(
        xy(&locations[0]["position"]),
        lon_lat(site_xy),
        1e-9,
        "trackable locations",
    );
    let summary = get_json(&app, "/v2/fences/summary?crs=EPSG:4326").await;
    let lane = summary
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["foreign_id"] == "forklift-lane")
        .unwrap();
    assert_eq!(lane["crs"], "EPSG:4326");
    for (k, vertex) in LANE.iter().enumerate() {
        let got = xy(&json!({"coordinates": lane["region"]["coordinates"][0][k]}));
        assert_near(got, lon_lat(*vertex), 1e-9, "a fence vertex in WGS-84");
    }

    // zone_id: the zone's own [u, v], as its transform gives them, and as it was drawn
    let transform = json!({"position": {"type": "Point", "coordinates": lon_lat(site_xy)}, "crs": "EPSG:4326"});
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/zones/{zone}/transform"),
        Some(WRITE),
        &transform.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let transformed = xy(&reply.json()["position"]);
    assert_near(transformed, zone_of(site_xy), 1e-6, "the zone transform");
    let location = get_json(&app, &format!("/v2/trackables/{trackable}/location?zone_id={zone}")).await;
    assert_eq!(location["crs"], "local");
    assert_near(xy(&location["position"]), transformed, 1e-9, "a location in the zone");
    let motions = get_json(&app, &format!("/v2/trackables/motions?zone_id={zone}&crs=local")).await;
    assert_eq!(motions[0]["id"], trackable.as_str());
    assert_near(xy(&motions[0]["location"]["position"]), transformed, 1e-9, "motions");
    let inside = get_json(
        &app,
        &format!("/v2/fences/{fence}/locations?spatial_query=true&zone_id={zone}"),
    )
    .await;
    assert_near(xy(&inside[0]["position"]), transformed, 1e-9, "a fence's locations");
    let inside = get_json(
        &app,
        &format!("/v2/fences/{fence}/motions?spatial_query=true&crs=EPSG:4326"),
    )
    .await;
    assert_near(
        xy(&inside[0]["location"]["position"]),
        lon_lat(site_xy),
        1e-9,
        "a fence's motions",
    );
    let lane = get_json(&app, &format!("/v2/fences/forklift-lane?zone_id={zone}")).await;
    assert_eq!((&lane["crs"], &lane["zone_id"]), (&json!("local"), &json!(zone)));
    for (k, vertex) in LANE.iter().enumerate() {
        let got = xy(&json!({"coordinates": lane["region"]["coordinates"][0][k]}));
        assert_near(got, zone_of(*vertex), 1e-6, "a fence vertex in the zone");
    }
    // EPSG:4326 is one frame whichever zone: the zone is only checked to exist
    let both = get_json(&app, &format!("/v2/fences/forklift-lane?zone_id={zone}&crs=EPSG:4326")).await;
    assert_near(
        xy(&json!({"coordinates": both["region"]["coordinates"][0][0]})),
        lon_lat(LANE[0]),
        1e-9,
        "both",
    );

    // the site's own zone is the site's metres
    let site_zone = uuid_for("zone", "test floor");
    let own = get_json(&app, &format!("/v2/providers/walker/location?zone_id={site_zone}")).await;
    assert_eq!(own, local);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn geojson_answers_features_in_wgs84_unless_asked_otherwise() {
    let (app, trackable, fence, zone) = scene("read-frames-geojson", true).await;
    let local = get_json(&app, "/v2/providers/walker/location").await;
    let site_xy = xy(&local["position"]);

    // a list: a FeatureCollection of Points in WGS-84 (RFC 7946), no crs member
    let reply = get(&app, "/v2/providers/locations?geojson=true").await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    assert_eq!(reply.content_type, "application/geo+json");
    let collection = reply.json();
    assert_eq!(collection["type"], "FeatureCollection");
    assert!(collection.get("crs").is_none(), "{collection}");
    let feature = &collection["features"][0];
    assert_eq!(
        (&feature["type"], &feature["id"]),
        (&json!("Feature"), &json!("walker"))
    );
    assert_eq!(feature["geometry"]["type"], "Point");
    assert_near(xy(&feature["geometry"]), lon_lat(site_xy), 1e-9, "a Feature's Point");
    assert_eq!(feature["properties"]["provider_id"], "walker");
    assert_eq!(feature["properties"]["crs"], "EPSG:4326");
    assert_eq!(feature["properties"]["accuracy"], local["accuracy"]);
    assert!(feature["properties"].get("position").is_none());

    // one object asked for in local coordinates: a Feature that names its crs
    let motion = get_json(
        &app,
        &format!("/v2/trackables/{trackable}/motion?geojson=true&crs=local"),
    )
    .await;
    assert_eq!((&motion["type"], &motion["crs"]), (&json!("Feature"), &json!("local")));
    assert_eq!(motion["id"], trackable.as_str());
    assert_eq!(motion["geometry"], local["position"]);
    assert_eq!(motion["properties"]["name"], "walker");
    assert_eq!(motion["properties"]["location"]["provider_id"], "walker");

    // a fence in a zone's frame: its region, and the zone named
    let feature = get_json(&app, &format!("/v2/fences/{fence}?geojson=true&zone_id={zone}")).await;
    assert_eq!((&feature["crs"], &feature["zone_id"]), (&json!("local"), &json!(zone)));
    assert_eq!(feature["geometry"]["type"], "Polygon");
    let corner = xy(&json!({"coordinates": feature["geometry"]["coordinates"][0][0]}));
    assert_near(corner, zone_of([6.0, 8.0]), 1e-6, "a fence Feature in the zone");
    assert_eq!(feature["properties"]["name"], "stop");
    let fences = get_json(&app, "/v2/fences/summary?geojson=true").await;
    assert_eq!(fences["features"].as_array().map(Vec::len), Some(2), "{fences}");
    let lane = get_json(&app, "/v2/fences/forklift-lane?geojson=true").await;
    let corner = xy(&json!({"coordinates": lane["geometry"]["coordinates"][0][0]}));
    assert_near(corner, lon_lat(LANE[0]), 1e-9, "a fence Feature in WGS-84");

    // geojson=false is omlox JSON
    let plain = get(&app, "/v2/trackables/motions?geojson=false").await;
    assert_eq!(plain.content_type, "application/json");
    assert_eq!(plain.json()[0]["location"]["crs"], "local");
    let inside = get_json(
        &app,
        &format!("/v2/fences/{fence}/motions?spatial_query=true&geojson=true"),
    )
    .await;
    assert_eq!(inside["features"][0]["id"], trackable.as_str());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_or_frameless_zones_and_other_crs_are_refused() {
    let (app, trackable, _, _) = scene("read-frames-refusals", true).await;
    let proximity =
        json!({"type": "rfid", "position": {"type": "Point", "coordinates": [8.5417, 47.3769]}, "radius": 2.0});
    let proximity = post_created(&app, "/v2/zones", &proximity).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let incomplete = json!({"type": "uwb", "incomplete_configuration": true});
    let incomplete = post_created(&app, "/v2/zones", &incomplete).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let unknown = "ECADD57B-7E4A-4636-B105-6B1C11BB75BF";
    for (uri, status, field) in [
        (
            format!("/v2/trackables/motions?zone_id={unknown}"),
            StatusCode::NOT_FOUND,
            None,
        ),
        (
            format!("/v2/providers/walker/location?zone_id={unknown}&geojson=true"),
            StatusCode::NOT_FOUND,
            None,
        ),
        (
            format!("/v2/fences/summary?zone_id={proximity}"),
            StatusCode::BAD_REQUEST,
            Some("zone_id"),
        ),
        (
            format!("/v2/trackables/{trackable}/locations?zone_id={incomplete}"),
            StatusCode::BAD_REQUEST,
            Some("zone_id"),
        ),
        (
            "/v2/fences/summary?crs=EPSG:3857".to_string(),
            StatusCode::BAD_REQUEST,
            Some("crs"),
        ),
        (
            format!("/v2/trackables/{trackable}/motion?crs=local&zone_id={unknown}"),
            StatusCode::NOT_FOUND,
            None,
        ),
    ] {
        let reply = get(&app, &uri).await;
        assert_eq!(assert_omlox_error(&reply, status, &uri).as_deref(), field, "{uri}");
    }

    // a site without a [frame]: no WGS-84, and no way to a stored zone's ground control points
    let (plain, trackable, fence, _) = scene("read-frames-no-frame", false).await;
    let points = [
        [8.0, 47.0],
        [0.0, 0.0],
        [8.001, 47.0],
        [10.0, 0.0],
        [8.0, 47.001],
        [0.0, 10.0],
    ];
    let zone = post_created(
        &plain,
        "/v2/zones",
        &json!({"type": "uwb", "ground_control_points": points}),
    )
    .await;
    let zone = zone["id"].as_str().unwrap();
    for (uri, field) in [
        (format!("/v2/fences/{fence}?crs=EPSG:4326"), "crs"),
        (format!("/v2/trackables/{trackable}/motion?zone_id={zone}"), "zone_id"),
    ] {
        let reply = get(&plain, &uri).await;
        assert_eq!(
            assert_omlox_error(&reply, StatusCode::BAD_REQUEST, &uri).as_deref(),
            Some(field)
        );
    }
    // GeoJSON then stays in site metres, and says so
    let local = get_json(&plain, "/v2/providers/walker/location").await;
    let feature = get_json(&plain, "/v2/providers/walker/location?geojson=true").await;
    assert_eq!(
        (&feature["crs"], &feature["geometry"]),
        (&json!("local"), &local["position"])
    );
}

/// The first vertex of a fence's (Polygon) region.
fn first_vertex(fence: &Value) -> [f64; 2] {
    xy(&json!({"coordinates": fence["region"]["coordinates"][0][0]}))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fences_are_read_in_wgs84_by_default_or_in_the_site_zone_without_a_frame() {
    let (app, trackable, fence, _) = scene("read-frames-fence-default", true).await;
    let site_zone = uuid_for("zone", "test floor");
    // omlox getAllFences: "Returned fence objects use EPSG:4326 ("GPS") as the projection for
    // the region coordinates, unless another projection is requested"
    let summary = get_json(&app, "/v2/fences/summary").await;
    assert_eq!(summary, get_json(&app, "/v2/fences/summary?crs=EPSG:4326").await);
    let lane = get_json(&app, "/v2/fences/forklift-lane").await;
    assert_eq!(lane["crs"], "EPSG:4326");
    assert!(lane.get("zone_id").is_none(), "{lane}");
    for (k, vertex) in LANE.iter().enumerate() {
        let got = xy(&json!({"coordinates": lane["region"]["coordinates"][0][k]}));
        assert_near(got, lon_lat(*vertex), 1e-9, "a fence vertex in WGS-84 by default");
    }
    // the fences a provider or trackable is inside, in the same frame
    for uri in [
        "/v2/providers/walker/fences?spatial_query=true".to_string(),
        format!("/v2/trackables/{trackable}/fences?spatial_query=true"),
    ] {
        let inside = get_json(&app, &uri).await;
        let stop = inside.as_array().unwrap().iter().find(|f| f["id"] == fence.as_str());
        let stop = stop.unwrap_or_else(|| panic!("{uri}: the walker stops in `stop`: {inside}"));
        assert_eq!(stop["crs"], "EPSG:4326", "{uri}");
        assert_near(first_vertex(stop), lon_lat([6.0, 8.0]), 1e-9, &uri);
    }
    // local on request: site metres, named by the site's own zone
    let local = get_json(&app, "/v2/fences/forklift-lane?crs=local").await;
    assert_eq!((&local["crs"], &local["zone_id"]), (&json!("local"), &json!(site_zone)));
    assert_near(first_vertex(&local), LANE[0], 1e-12, "a fence vertex in site metres");

    // a site without a [frame] has no WGS-84 to give: local, with the zone the spec requires
    let (plain, _, fence, _) = scene("read-frames-fence-default-plain", false).await;
    for uri in [format!("/v2/fences/{fence}"), "/v2/fences/forklift-lane".to_string()] {
        let got = get_json(&plain, &uri).await;
        assert_eq!(
            (&got["crs"], &got["zone_id"]),
            (&json!("local"), &json!(site_zone)),
            "{uri}"
        );
    }
    let stop = get_json(&plain, &format!("/v2/fences/{fence}")).await;
    assert_near(first_vertex(&stop), [6.0, 8.0], 1e-12, "a fence in site metres");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fence_written_without_crs_is_in_wgs84() {
    let (app, _, _, _) = scene("read-frames-fence-write", true).await;
    let square = [[2.0, 2.0], [4.0, 2.0], [4.0, 4.0], [2.0, 4.0], [2.0, 2.0]];
    let degrees: Vec<[f64; 2]> = square.iter().map(|p| lon_lat(*p)).collect();
    // omlox Fence: "If crs is not present, 'EPSG:4326' ("GPS") MUST be assumed as the default."
    let fence = json!({"name": "gps", "region": {"type": "Polygon", "coordinates": [degrees]}});
    let created = post_created(&app, "/v2/fences", &fence).await;
    assert_eq!(
        created["crs"], "EPSG:4326",
        "answered in the CRS it was written in: {created}"
    );
    assert_near(first_vertex(&created), degrees[0], 1e-9, "the created fence");
    let id = created["id"].as_str().unwrap().to_string();
    let local = get_json(&app, &format!("/v2/fences/{id}?crs=local")).await;
    for (k, vertex) in square.iter().enumerate() {
        let got = xy(&json!({"coordinates": local["region"]["coordinates"][0][k]}));
        assert_near(got, *vertex, 1e-6, "a vertex written in degrees, in site metres");
    }
    // replaced in site metres (204, as the spec documents), read back in degrees
    let moved = json!({"name": "gps", "crs": "local", "region": {"type": "Polygon", "coordinates": [square.map(|[x, y]| [x + 1.0, y])]}});
    let reply = call(
        &app,
        Method::PUT,
        &format!("/v2/fences/{id}"),
        Some(WRITE),
        &moved.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let replaced = get_json(&app, &format!("/v2/fences/{id}")).await;
    assert_eq!(replaced["crs"], "EPSG:4326");
    assert_near(first_vertex(&replaced), lon_lat([3.0, 2.0]), 1e-9, "the replaced fence");

    // without a [frame] there is nothing to place degrees by: refused, naming crs
    let (plain, _, _, _) = scene("read-frames-fence-write-plain", false).await;
    let reply = call(&plain, Method::POST, "/v2/fences", Some(WRITE), &fence.to_string()).await;
    assert_eq!(
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "a fence without crs").as_deref(),
        Some("crs")
    );
    assert!(reply.text().contains("EPSG:4326"), "{}", reply.text());
}
