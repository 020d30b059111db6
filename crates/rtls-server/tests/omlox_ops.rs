//! The omlox hub operations over the links between providers, trackables and fences (computed
//! from the live tracks and the fences the trackers watch), trackable motions, sensor data and
//! the DELETE-all operations — through the router (`tower::ServiceExt::oneshot`), with their
//! error cases as omlox `Error` objects. Zones and proximities are in `omlox_zones.rs`.

mod common;

use std::time::Duration;

use axum::http::{Method, StatusCode};
use common::{
    assert_omlox_error, call, call_json, eventually, eventually_some, post_created, pushed_location, state, walk, READ,
    WRITE,
};
use serde_json::{json, Value};

fn ids(array: &Value, key: &str) -> Vec<String> {
    array
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {array}"))
        .iter()
        .map(|item| item[key].as_str().unwrap_or_default().to_string())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fences_trackables_and_providers_link_through_the_live_tracks() {
    let state = state("ops-relations");
    let app = rtls_server::http::router(state.clone());
    // miner-7 walks along y = 10 m into the forklift lane (x ∈ [14, 18] m) at 1 m/s; miner-8
    // stops at x = 7 m, outside it
    let lines = walk("miner-7", 3000.0, 15.0) + &walk("miner-8", 3000.0, 5.0);
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &lines).await;
    assert_eq!(reply.status, StatusCode::OK, "{}", reply.text());
    let live = state.pipeline.live().clone();
    let inside = eventually(Duration::from_secs(10), || {
        live.tag("miner-7").is_some_and(|t| t.position_m[0] > 14.5)
            && live.tag("miner-8").is_some()
            && live.occupants()["forklift-lane"].contains(&"miner-7".to_string())
    })
    .await;
    assert!(inside, "{:?} {:?}", live.tag("miner-7"), live.occupants());

    let trackable = json!({"type": "omlox", "name": "Loader 7", "location_providers": ["miner-7", "ghost-1"],
                           "properties": {"colour": "red"}, "extrusion": 2.5});
    let loader = post_created(&app, "/v2/trackables", &trackable).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    let idle = json!({"type": "virtual", "name": "Idle", "location_providers": ["miner-8"]});
    let idle = post_created(&app, "/v2/trackables", &idle).await["id"]
        .as_str()
        .unwrap()
        .to_string();

    // a provider's and a trackable's fences: by the trackers' entries and by geometry alone
    for query in ["", "?spatial_query=true", "?spatial_query=false"] {
        let fences = call_json(&app, &format!("/v2/providers/miner-7/fences{query}")).await;
        assert_eq!(ids(&fences, "foreign_id"), ["forklift-lane"], "{query}");
        let fences = call_json(&app, &format!("/v2/trackables/{loader}/fences{query}")).await;
        assert_eq!(ids(&fences, "foreign_id"), ["forklift-lane"], "{query}");
        assert_eq!(
            call_json(&app, &format!("/v2/providers/miner-8/fences{query}")).await,
            json!([])
        );
        assert_eq!(
            call_json(&app, &format!("/v2/trackables/{idle}/fences{query}")).await,
            json!([])
        );
    }

    // a fence's locations, providers, trackables and motions, by zone id or fence UUID
    let fence_id = call_json(&app, "/v2/fences/forklift-lane").await["id"]
        .as_str()
        .unwrap()
        .to_string();
    for fence in ["forklift-lane", fence_id.as_str()] {
        let locations = call_json(&app, &format!("/v2/fences/{fence}/locations")).await;
        assert_eq!(ids(&locations, "provider_id"), ["miner-7"]);
        let providers = call_json(&app, &format!("/v2/fences/{fence}/providers?spatial_query=true")).await;
        assert_eq!(ids(&providers, "id"), ["miner-7"]);
        let trackables = call_json(&app, &format!("/v2/fences/{fence}/trackables")).await;
        assert_eq!(ids(&trackables, "id"), vec![loader.clone()]);
        let motions = call_json(&app, &format!("/v2/fences/{fence}/motions")).await;
        assert_eq!(ids(&motions, "id"), vec![loader.clone()]);
    }

    // a trackable's locations and providers; a provider's trackables
    let locations = call_json(&app, &format!("/v2/trackables/{loader}/locations")).await;
    assert_eq!(ids(&locations, "provider_id"), ["miner-7"], "ghost-1 has no location");
    let providers = call_json(&app, &format!("/v2/trackables/{loader}/providers")).await;
    assert_eq!(ids(&providers, "id"), ["miner-7", "ghost-1"]);
    assert_eq!(providers[1]["type"], "unknown");
    for provider in ["miner-7", "ghost-1"] {
        let trackables = call_json(&app, &format!("/v2/providers/{provider}/trackables")).await;
        assert_eq!(ids(&trackables, "id"), vec![loader.clone()], "{provider}");
    }

    // motions: the newest location with the track's speed (1 m/s) and course (east: 90°)
    let motion = call_json(&app, &format!("/v2/trackables/{loader}/motion")).await;
    assert_eq!(motion["id"], loader.as_str());
    assert_eq!(
        (&motion["name"], &motion["properties"], &motion["extrusion"]),
        (&json!("Loader 7"), &json!({"colour": "red"}), &json!(2.5))
    );
    assert_eq!(motion["location"]["provider_id"], "miner-7");
    let speed = motion["location"]["speed"].as_f64().unwrap();
    let course = motion["location"]["course"].as_f64().unwrap();
    assert!((speed - 1.0).abs() < 0.2 && (course - 90.0).abs() < 10.0, "{motion}");
    let motions = call_json(&app, "/v2/trackables/motions").await;
    let mut moving = ids(&motions, "id");
    moving.sort();
    let mut expected = vec![loader.clone(), idle.clone()];
    expected.sort();
    assert_eq!(moving, expected);
    let lonely = json!({"type": "omlox", "location_providers": ["never-seen"]}).to_string();
    let lonely = call(&app, Method::POST, "/v2/trackables", Some(WRITE), &lonely)
        .await
        .json()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let reply = call(
        &app,
        Method::GET,
        &format!("/v2/trackables/{lonely}/motion"),
        Some(READ),
        "",
    )
    .await;
    assert_omlox_error(
        &reply,
        StatusCode::NOT_FOUND,
        "a trackable without a location has no motion",
    );
    assert_eq!(
        call_json(&app, "/v2/trackables/motions")
            .await
            .as_array()
            .unwrap()
            .len(),
        2
    );

    // unknown ids: 404; a bad spatial_query: 400 naming it; no token: 401
    let unknown = "7c9e6679-7425-40de-944b-e07fc1f90ae7";
    for uri in [
        "/v2/fences/no-such-fence/locations".to_string(),
        "/v2/fences/no-such-fence/providers".into(),
        "/v2/fences/no-such-fence/trackables".into(),
        "/v2/fences/no-such-fence/motions".into(),
        format!("/v2/trackables/{unknown}/fences"),
        format!("/v2/trackables/{unknown}/locations"),
        format!("/v2/trackables/{unknown}/providers"),
        format!("/v2/trackables/{unknown}/motion"),
        "/v2/providers/nobody/fences".into(),
        "/v2/providers/nobody/trackables".into(),
    ] {
        let reply = call(&app, Method::GET, &uri, Some(READ), "").await;
        assert_omlox_error(&reply, StatusCode::NOT_FOUND, &uri);
    }
    let reply = call(
        &app,
        Method::GET,
        "/v2/providers/miner-7/fences?spatial_query=yes",
        Some(READ),
        "",
    )
    .await;
    let field = assert_omlox_error(&reply, StatusCode::BAD_REQUEST, "spatial_query=yes");
    assert_eq!(field.as_deref(), Some("spatial_query"));
    let reply = call(&app, Method::GET, "/v2/trackables/motions", None, "").await;
    assert_omlox_error(&reply, StatusCode::UNAUTHORIZED, "no token");

    // a deleted location takes its provider out of the fence until its next update
    let reply = call(&app, Method::DELETE, "/v2/providers/miner-7/location", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    // a stored provider without a location: there is none, as asked (idempotent); an unknown
    // provider is a 404
    let gate = json!({"id": "gate-9", "type": "uwb"}).to_string();
    let reply = call(&app, Method::POST, "/v2/providers", Some(WRITE), &gate).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let reply = call(&app, Method::DELETE, "/v2/providers/gate-9/location", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let reply = call(&app, Method::DELETE, "/v2/providers/nobody-9/location", Some(WRITE), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "nobody-9");
    for query in ["", "?spatial_query=true"] {
        let providers = call_json(&app, &format!("/v2/fences/forklift-lane/providers{query}")).await;
        assert_eq!(providers, json!([]), "{query}");
        assert_eq!(
            call_json(&app, &format!("/v2/trackables/{loader}/fences{query}")).await,
            json!([])
        );
    }
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sensor_data_is_stored_per_provider_and_gathered_per_trackable() {
    let state = state("ops-sensors");
    let app = rtls_server::http::router(state.clone());
    for provider in ["tag-a", "tag-b"] {
        let body = json!({"id": provider, "type": "uwb"}).to_string();
        let reply = call(&app, Method::POST, "/v2/providers", Some(WRITE), &body).await;
        assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    }
    let sensors = json!({"temperature_c": 21.5, "battery": [3.7, "ok"]});
    let reply = call(
        &app,
        Method::PUT,
        "/v2/providers/tag-a/sensors",
        Some(WRITE),
        &sensors.to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    assert_eq!(call_json(&app, "/v2/providers/tag-a/sensors").await, sensors);
    assert_eq!(call_json(&app, "/v2/providers/tag-a").await["sensors"], sensors);
    let reply = call(&app, Method::GET, "/v2/providers/tag-b/sensors", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "no sensor data yet");

    let trackable = json!({"type": "omlox", "location_providers": ["tag-b", "tag-a"]}).to_string();
    let reply = call(&app, Method::POST, "/v2/trackables", Some(WRITE), &trackable).await;
    let trackable = reply.json()["id"].as_str().unwrap().to_string();
    assert_eq!(
        call_json(&app, &format!("/v2/trackables/{trackable}/sensors")).await,
        json!([sensors])
    );
    let reply = call(&app, Method::PUT, "/v2/providers/tag-b/sensors", Some(WRITE), "42").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_eq!(
        call_json(&app, &format!("/v2/trackables/{trackable}/sensors")).await,
        json!([42, sensors])
    );

    // errors: unknown provider or trackable 404, a body that is not JSON or null 400, tokens
    let reply = call(&app, Method::PUT, "/v2/providers/nobody/sensors", Some(WRITE), "{}").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown provider");
    let reply = call(&app, Method::GET, "/v2/providers/nobody/sensors", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown provider");
    let reply = call(
        &app,
        Method::GET,
        "/v2/trackables/7c9e6679-7425-40de-944b-e07fc1f90ae7/sensors",
        Some(READ),
        "",
    )
    .await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "unknown trackable");
    for body in ["null", "{\"t\": ", ""] {
        let reply = call(&app, Method::PUT, "/v2/providers/tag-a/sensors", Some(WRITE), body).await;
        assert_omlox_error(&reply, StatusCode::BAD_REQUEST, body);
    }
    assert_eq!(
        call_json(&app, "/v2/providers/tag-a/sensors").await,
        sensors,
        "unchanged"
    );
    let reply = call(&app, Method::PUT, "/v2/providers/tag-a/sensors", Some(READ), "{}").await;
    assert_omlox_error(&reply, StatusCode::FORBIDDEN, "a read token");
    let reply = call(&app, Method::PUT, "/v2/providers/tag-a/sensors", None, "{}").await;
    assert_omlox_error(&reply, StatusCode::UNAUTHORIZED, "no token");
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn delete_all_operations_empty_their_collections_and_the_watched_fences() {
    let state = state("ops-delete-all");
    let app = rtls_server::http::router(state.clone());
    let lines = walk("miner-1", 3000.0, 3.0) + &walk("miner-2", 3000.0, 3.0);
    let reply = call(&app, Method::POST, "/api/v1/measurements", Some(WRITE), &lines).await;
    assert_eq!(reply.status, StatusCode::OK);
    let live = state.pipeline.live().clone();
    let tracked = eventually(Duration::from_secs(10), || {
        live.tag("miner-1").is_some() && live.tag("miner-2").is_some()
    })
    .await;
    assert!(tracked);
    let body = json!({"id": "stored-tag", "type": "uwb"}).to_string();
    assert_eq!(
        call(&app, Method::POST, "/v2/providers", Some(WRITE), &body)
            .await
            .status,
        StatusCode::CREATED
    );
    for name in ["a", "b"] {
        let body = json!({"type": "omlox", "name": name}).to_string();
        assert_eq!(
            call(&app, Method::POST, "/v2/trackables", Some(WRITE), &body)
                .await
                .status,
            StatusCode::CREATED
        );
    }

    // every DELETE-all needs a token that may change things
    for uri in [
        "/v2/trackables",
        "/v2/providers",
        "/v2/providers/locations",
        "/v2/fences",
        "/v2/providers/miner-1/location",
    ] {
        assert_omlox_error(
            &call(&app, Method::DELETE, uri, None, "").await,
            StatusCode::UNAUTHORIZED,
            uri,
        );
        assert_omlox_error(
            &call(&app, Method::DELETE, uri, Some(READ), "").await,
            StatusCode::FORBIDDEN,
            uri,
        );
    }
    assert_eq!(call_json(&app, "/v2/trackables").await.as_array().unwrap().len(), 2);

    let reply = call(&app, Method::DELETE, "/v2/trackables", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_eq!(call_json(&app, "/v2/trackables").await, json!([]));

    // a tracked tag deleted as a provider: not listed again until its next update
    let reply = call(&app, Method::DELETE, "/v2/providers/miner-2", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    let providers = call_json(&app, "/v2/providers").await;
    assert!(
        !providers.as_array().unwrap().contains(&json!("miner-2")),
        "{providers}"
    );
    let reply = call(&app, Method::GET, "/v2/providers/miner-2/location", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "a deleted provider's location");

    // one provider's location, then all
    let reply = call(&app, Method::DELETE, "/v2/providers/miner-1/location", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    let reply = call(&app, Method::GET, "/v2/providers/miner-1/location", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "deleted location");
    let reply = call(&app, Method::DELETE, "/v2/providers/miner-1/location", Some(WRITE), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "deleted twice");
    assert!(ids(&call_json(&app, "/v2/providers/locations").await, "provider_id").is_empty());
    let reply = call(&app, Method::DELETE, "/v2/providers/locations", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_eq!(call_json(&app, "/v2/providers/locations").await, json!([]));
    assert_eq!(call_json(&app, "/v2/providers").await, json!(["stored-tag"]));

    let reply = call(&app, Method::DELETE, "/v2/providers", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    assert_eq!(call_json(&app, "/v2/providers").await, json!([]));
    let reply = call(&app, Method::GET, "/v2/providers/stored-tag", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "deleted provider");

    // fences: none listed, none watched by the trackers, the empty set stored
    assert_eq!(call_json(&app, "/v2/fences").await.as_array().unwrap().len(), 1);
    let reply = call(&app, Method::DELETE, "/v2/fences", Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    assert_eq!(call_json(&app, "/v2/fences").await, json!([]));
    assert!(live.zones().is_empty());
    assert!(live.head_counts().is_empty());
    let mut store = common::open_sqlite(&common::db_path("ops-delete-all"));
    let stored = rtls_server::http::fences::stored_zones(store.as_mut()).unwrap();
    assert_eq!(stored.map(|zones| zones.len()), Some(0), "a restart watches no fence");
    let reply = call(&app, Method::GET, "/v2/fences/forklift-lane", Some(READ), "").await;
    assert_omlox_error(&reply, StatusCode::NOT_FOUND, "deleted fence");
    state.pipeline.shutdown();
}

/// A provider whose pushed locations move 285 m at once (the tag was carried, or another
/// system relocated it) is followed after the site's confirmation evidence
/// (`initiation.confirm_updates` agreeing locations), not after the tracker's rejection rate
/// has re-initialised it; the jump is a `jumped` lifecycle event.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pushed_location_that_jumps_285_m_is_followed_after_the_confirmation_evidence() {
    let state = state("ops-jump");
    let app = rtls_server::http::router(state.clone());
    let now = 3000.0;
    let location = |x: f64, y: f64, t: f64| pushed_location("cart-3", [x, y], t);
    let confirm = state.site.tracker.initiation.confirm_updates.max(2);
    // 10 pushes at 1 Hz along y = 5 m, then `confirm` + 2 at y = 290 m
    let pushes: Vec<Value> = (0..10)
        .map(|k| location(2.0 + f64::from(k) * 0.5, 5.0, now + f64::from(k)))
        .chain((10..12 + confirm).map(|k| location(2.0 + f64::from(k) * 0.5, 290.0, now + f64::from(k))))
        .collect();
    for push in pushes {
        let body = Value::Array(vec![push]).to_string();
        let reply = call(&app, Method::PUT, "/v2/providers/locations", Some(WRITE), &body).await;
        assert_eq!(reply.status, StatusCode::NO_CONTENT, "{}", reply.text());
    }
    let live = state.pipeline.live().clone();
    // the jump is confirmed by the push at 10 + confirm − 1 s
    let jump_s = now + 10.0 + f64::from(confirm) - 1.0;
    let followed = eventually(Duration::from_secs(10), || {
        live.tag("cart-3")
            .is_some_and(|t| t.time_s >= jump_s && (t.position_m[1] - 290.0).abs() < 2.0)
    })
    .await;
    assert!(followed, "{:?}", live.tag("cart-3"));
    // the event is stored by the output thread, after the live state
    let events = eventually_some(Duration::from_secs(10), || async {
        let events = call_json(&app, "/api/v1/events?type=lifecycle&tag=cart-3").await;
        events
            .as_array()
            .is_some_and(|all| all.iter().any(|e| e["event"] == "jumped"))
            .then_some(events)
    })
    .await
    .expect("a jumped event is stored");
    let jumped: Vec<&Value> = events
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["event"] == "jumped")
        .collect();
    assert_eq!(jumped.len(), 1, "{events}");
    assert!((jumped[0]["t"].as_f64().unwrap() - jump_s).abs() < 1e-6, "{events}");
    state.pipeline.shutdown();
}
