//! Schema conformance against the omlox OpenAPI file, round trips, ingest errors, conversions.

use std::sync::Arc;

use rtls_engine::lifecycle::TrackStatus;
use rtls_engine::record::Measurement;
use rtls_engine::tracker::{Event, TrackUpdate, UpdateSource};
use rtls_engine::zones::{Shape, Zone as SiteZone, ZoneEvent, ZoneKind};
use serde_json::{json, Value};

use crate::convert::{
    accuracy_m, course_deg, extension_message, fence_event_from_zone_event, fence_from_zone, location_from_update,
    location_in_site, record_from_location, uuid_for, ZoneEventOut,
};
use crate::omlox::ingest::parse_locations;
use crate::omlox::time::{format_timestamp, parse_timestamp};
use crate::omlox::ws::{Topic, WsErrorCode, WsMessage};
use crate::omlox::{LocationProvider, ProviderType, Trackable, TrackableType, Zone, ZoneType};

const SPEC: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/reference/omlox_Hub_API_2.0.0.json"
);

/// The omlox OpenAPI document, kept beside the checkout (not in the repository, by its
/// licence); like the recorded datasets, the schema checks are skipped, with a notice, on a
/// machine without it — the tests' own assertions still run.
fn spec() -> Option<Value> {
    match std::fs::read_to_string(SPEC) {
        Ok(text) => Some(serde_json::from_str(&text).unwrap()),
        Err(e) => {
            eprintln!("omlox schema checks skipped: {SPEC} is missing ({e})");
            None
        }
    }
}

/// Validates `instance` against `#/components/schemas/{name}` (draft 4, refs resolved in the
/// whole OpenAPI document); `patch` may edit the component first (spec defects, see callers).
fn assert_valid(name: &str, instance: &Value, patch: impl FnOnce(&mut Value)) {
    let Some(mut document) = spec() else {
        return;
    };
    patch(&mut document["components"]["schemas"][name]);
    document["$ref"] = json!(format!("#/components/schemas/{name}"));
    let validator = jsonschema::draft4::new(&document).unwrap();
    let errors: Vec<String> = validator
        .iter_errors(instance)
        .map(|e| format!("{} at {}", e, e.instance_path))
        .collect();
    assert!(errors.is_empty(), "{name} {instance}: {errors:?}");
}

fn update() -> TrackUpdate {
    TrackUpdate {
        time_s: 1_567_461_744.355,
        tag: Arc::from("miner-017"),
        dimensions: 2,
        position_m: [3.0, 4.0, 0.0],
        velocity_mps: [1.0, -1.0, 0.0],
        position_covariance_m2: [3.0, 1.0, 1.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        predicted: true,
        status: TrackStatus::Coasting,
        source: UpdateSource::Prediction,
        mode: Some("CV"),
        revised: false,
        smoothed: false,
    }
}

fn site_zone() -> SiteZone {
    SiteZone {
        id: "stope-7".into(),
        name: "Collapsed stope".into(),
        kind: ZoneKind::Hazard,
        readers: vec![],
        shape: Shape::Box {
            min_m: [0.0, 0.0, 0.0],
            max_m: [10.0, 4.0, 3.0],
        },
    }
}

#[test]
fn a_schema_that_is_violated_is_reported() {
    // The validator harness itself can fail: a Location without provider_id.
    let Some(mut document) = spec() else {
        return;
    };
    document["$ref"] = json!("#/components/schemas/Location");
    let validator = jsonschema::draft4::new(&document).unwrap();
    let bad = json!({"position": {"type": "Point", "coordinates": [1, 2]}, "source": "s", "provider_type": "uwb"});
    assert!(!validator.is_valid(&bad));
    let bad_enum = json!({"position": {"type": "Point", "coordinates": [1, 2]}, "source": "s", "provider_type": "ble", "provider_id": "x"});
    assert!(!validator.is_valid(&bad_enum));
}

#[test]
fn location_from_update_matches_schema_and_hand_values() {
    let location = location_from_update(&update(), "site-a", ProviderType::Uwb).unwrap();
    let value = serde_json::to_value(&location).unwrap();
    assert_valid("Location", &value, |_| {});
    // cov [[3,1],[1,3]]: λ = 4, 2 → accuracy 2 m.
    assert_eq!(location.accuracy, Some(2.0));
    // v = (1, −1): speed √2, course 135° (south-east, clockwise from +y).
    assert!((location.speed.unwrap() - 2f64.sqrt()).abs() < 1e-12);
    assert!((location.course.unwrap() - 135.0).abs() < 1e-12);
    assert_eq!(
        location.timestamp_generated.as_deref(),
        Some("2019-09-02T22:02:24.355Z")
    );
    assert_eq!(value["crs"], "local");
    assert_eq!(value["position"]["coordinates"], json!([3.0, 4.0]));
    assert_eq!(value["properties"]["rtls:predicted"], true);
    assert_eq!(value["properties"]["rtls:status"], "coasting");
    assert_eq!(value["properties"]["rtls:mode"], "CV");
    // only a revision says so (a late record re-filtered)
    assert!(value["properties"].get("rtls:revised").is_none());
    let revised = TrackUpdate {
        revised: true,
        smoothed: false,
        ..update()
    };
    let revised = serde_json::to_value(location_from_update(&revised, "site-a", ProviderType::Uwb).unwrap()).unwrap();
    assert_eq!(revised["properties"]["rtls:revised"], true);
    assert_valid("Location", &revised, |_| {});
    // Round trip.
    let back: crate::omlox::Location = serde_json::from_value(value).unwrap();
    assert_eq!(back, location);
}

#[test]
fn accuracy_and_course_against_hand_values() {
    assert_eq!(accuracy_m(&[4.0, 0.0, 0.0, 0.0, 9.0, 0.0, 0.0, 0.0, 1.0], 3), 3.0);
    assert_eq!(course_deg(0.0, 1.0), Some(0.0));
    assert_eq!(course_deg(1.0, 0.0), Some(90.0));
    assert_eq!(course_deg(0.0, -2.0), Some(180.0));
    assert_eq!(course_deg(-1.0, 0.0), Some(270.0));
    assert_eq!(course_deg(0.0, 0.0), None);
}

#[test]
fn timestamps_round_trip_and_reject_garbage() {
    assert_eq!(format_timestamp(0.0, "t").unwrap(), "1970-01-01T00:00:00.000Z");
    // 2000-02-29 (leap day) 12:00:00 = 951 825 600 s.
    assert_eq!(
        format_timestamp(951_825_600.0, "t").unwrap(),
        "2000-02-29T12:00:00.000Z"
    );
    assert_eq!(parse_timestamp("2000-02-29T12:00:00Z", "t").unwrap(), 951_825_600.0);
    assert_eq!(parse_timestamp("1969-12-31T23:59:59.250Z", "t").unwrap(), -0.75);
    let error = parse_timestamp("2019-09-02 22:02", "timestamp_sent").unwrap_err();
    assert!(
        error.to_string().starts_with("timestamp_sent: `2019-09-02 22:02`"),
        "{error}"
    );
    assert!(format_timestamp(f64::NAN, "t").is_err());
}

#[test]
fn fences_from_site_zones_match_schema() {
    let fence = fence_from_zone(&site_zone());
    let value = serde_json::to_value(&fence).unwrap();
    assert_valid("Fence", &value, |_| {});
    assert_eq!(
        value["region"],
        json!({"type": "Polygon", "coordinates": [[[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0], [0.0, 0.0]]]})
    );
    assert_eq!(fence.extrusion, Some(3.0));
    assert_eq!(fence.crs.as_deref(), Some("local"));
    assert_eq!(fence.id, uuid_for("fence", "stope-7"));
    let back: crate::omlox::Fence = serde_json::from_value(value).unwrap();
    assert_eq!(back, fence);
    // A point fence.
    let point =
        json!({"id": uuid_for("fence", "p"), "region": {"type": "Point", "coordinates": [1.0, 2.0]}, "radius": 2.5});
    let parsed: crate::omlox::Fence = serde_json::from_value(point.clone()).unwrap();
    assert_eq!(serde_json::to_value(&parsed).unwrap(), point);
    assert_valid("Fence", &point, |_| {});
}

#[test]
fn fence_events_from_zone_events() {
    let enter = ZoneEvent::Enter {
        tag: "t1".into(),
        zone: "stope-7".into(),
        time_s: 10.0,
    };
    let ZoneEventOut::Fence(entry) = fence_event_from_zone_event(&enter, None).unwrap() else {
        panic!("enter must be a fence event")
    };
    let value = serde_json::to_value(&entry).unwrap();
    assert_valid("FenceEvent", &value, |_| {});
    assert_eq!(value["event_type"], "region_entry");
    assert_eq!(value["entry_time"], "1970-01-01T00:00:10.000Z");
    assert_eq!(entry.fence_id, fence_from_zone(&site_zone()).id);
    let exit = ZoneEvent::Exit {
        tag: "t1".into(),
        zone: "stope-7".into(),
        time_s: 12.5,
    };
    let ZoneEventOut::Fence(exit) = fence_event_from_zone_event(&exit, Some(10.0)).unwrap() else {
        panic!("exit must be a fence event")
    };
    let value = serde_json::to_value(&exit).unwrap();
    assert_valid("FenceEvent", &value, |_| {});
    assert_eq!(value["event_type"], "region_exit");
    assert_eq!(value["exit_time"], "1970-01-01T00:00:12.500Z");
    assert_eq!(value["entry_time"], "1970-01-01T00:00:10.000Z");
    let dwell = ZoneEvent::Dwell {
        tag: "t1".into(),
        zone: "z".into(),
        time_s: 1.0,
        dwell_s: 60.0,
    };
    let ZoneEventOut::Extension(topic, payload) = fence_event_from_zone_event(&dwell, None).unwrap() else {
        panic!("dwell has no omlox counterpart")
    };
    assert_eq!(
        (topic, payload["type"].as_str()),
        (Topic::RtlsEvents, Some("zone-dwell"))
    );
}

#[test]
fn extension_topics_for_engine_events() {
    let hazard = Event::HazardPredicted {
        tag: "m7".into(),
        zone: "collapse".into(),
        time_s: 2.0,
        time_to_entry_s: 3.5,
        probability: 0.9,
    };
    let (topic, payload) = extension_message(&hazard).unwrap();
    assert_eq!(topic, Topic::RtlsAlarms);
    assert_eq!(payload["time_to_entry_s"], 3.5);
    assert_eq!(payload["timestamp"], "1970-01-01T00:00:02.000Z");
    let lost = Event::Lifecycle {
        tag: "m7".into(),
        time_s: 2.0,
        event: rtls_engine::lifecycle::LifecycleEvent::Lost,
        position_m: [1.0, 2.0, 0.0],
    };
    assert_eq!(extension_message(&lost).unwrap().0, Topic::RtlsAlarms);
    let switch = Event::ModelSwitch {
        tag: "m7".into(),
        time_s: 2.0,
        from: "CV",
        to: "CT",
        probability: 0.8,
    };
    assert_eq!(extension_message(&switch).unwrap().0, Topic::RtlsAlarms);
    let late = Event::Late {
        tag: "m7".into(),
        time_s: 2.0,
        kind: "range",
        lateness_s: 0.4,
    };
    assert_eq!(extension_message(&late).unwrap().0, Topic::RtlsEvents);
    let message = WsMessage::message(topic, 4, vec![payload]);
    let text = serde_json::to_string(&message).unwrap();
    assert!(text.contains("\"topic\":\"rtls:alarms\""), "{text}");
}

#[test]
fn websocket_messages_match_schema() {
    let request: WsMessage =
        serde_json::from_str(r#"{"event":"subscribe","topic":"fence_events","params":{"provider_id":"t1"}}"#).unwrap();
    assert_valid(
        "WebsocketSubscriptionRequest",
        &serde_json::to_value(&request).unwrap(),
        |_| {},
    );
    let subscribed = WsMessage::subscribed(Topic::LocationUpdates, 7);
    assert_valid(
        "WebsocketSubscriptionResponse",
        &serde_json::to_value(&subscribed).unwrap(),
        |_| {},
    );
    // Spec defect: WebsocketMessage.payload items are typed "string" although the text says
    // they are omlox objects; validate with the item type lifted.
    let location = location_from_update(&update(), "site-a", ProviderType::Uwb).unwrap();
    let message = WsMessage::message(Topic::LocationUpdates, 7, vec![serde_json::to_value(location).unwrap()]);
    assert_valid("WebsocketMessage", &serde_json::to_value(&message).unwrap(), |schema| {
        schema["properties"]["payload"]["items"] = json!({});
    });
    // Spec defect: WebsocketError.code is a number whose enum lists strings ("10000 - Unknown
    // event"); we send the number, validated with the enum lifted.
    let error = WsMessage::error(WsErrorCode::UnknownTopic, "`foo`");
    let value = serde_json::to_value(&error).unwrap();
    assert_eq!(value["code"], 10001);
    assert_eq!(value["description"], "Unknown topic: `foo`");
    assert_valid("WebsocketError", &value, |schema| {
        schema["properties"]["code"] = json!({"type": "number"});
    });
    let codes: Vec<u32> = [
        WsErrorCode::UnknownEvent,
        WsErrorCode::UnknownTopic,
        WsErrorCode::SubscriptionFailed,
        WsErrorCode::UnsubscribeFailed,
        WsErrorCode::NotAuthorized,
        WsErrorCode::InvalidData,
    ]
    .iter()
    .map(|c| c.code())
    .collect();
    assert_eq!(codes, (10000..=10005).collect::<Vec<_>>());
    assert!(serde_json::from_str::<WsMessage>(r#"{"event":"subscribe","topic":"nope"}"#).is_err());
}

#[test]
fn trackables_providers_and_zones_match_schema() {
    let trackable = Trackable {
        id: uuid_for("tag", "miner-017"),
        kind: TrackableType::Omlox,
        name: Some("Miner 17".into()),
        geometry: None,
        extrusion: None,
        location_providers: Some(vec!["miner-017".into()]),
        fence_timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        radius: Some(0.5),
        properties: None,
        locating_rules: None,
    };
    assert_valid("Trackable", &serde_json::to_value(&trackable).unwrap(), |_| {});
    let provider = LocationProvider {
        id: "AABBCCDDEEFF0022".into(),
        kind: ProviderType::Uwb,
        name: Some("tag".into()),
        sensors: None,
        fence_timeout: Some(5.0),
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        properties: None,
    };
    assert_valid("LocationProvider", &serde_json::to_value(&provider).unwrap(), |_| {});
    let zone = Zone {
        id: uuid_for("zone", "mine"),
        kind: ZoneType::Uwb,
        foreign_id: Some("mine".into()),
        position: None,
        radius: None,
        ground_control_points: None,
        incomplete_configuration: Some(true),
        measurement_timestamp: None,
        site: None,
        building: None,
        floor: Some(0.0),
        name: Some("mine".into()),
        description: None,
        address: None,
        properties: None,
        wgs84_height: None,
    };
    let value = serde_json::to_value(&zone).unwrap();
    assert_valid("Zone", &value, |_| {});
    assert_eq!(serde_json::from_value::<Zone>(value).unwrap(), zone);
}

fn good(provider_id: &str) -> Value {
    json!({"position": {"type": "Point", "coordinates": [1.0, 2.0]}, "source": "s",
           "provider_type": "uwb", "provider_id": provider_id,
           "timestamp_generated": "1970-01-01T00:00:05.000Z", "accuracy": 0.5})
}

#[test]
fn ingest_errors_name_index_and_field() {
    let cases: Vec<(Value, &str)> = vec![
        (
            json!({"position": {"type": "Point", "coordinates": [1.0, "x"]}}),
            "[1].position.coordinates[1]: expected a finite number",
        ),
        (
            json!({"provider_type": "ble"}),
            "[1].provider_type: expected one of uwb, gps",
        ),
        (json!({"accuracy": -1.0}), "[1].accuracy: must be ≥ 0"),
        (
            json!({"timestamp_generated": "yesterday"}),
            "[1].timestamp_generated: `yesterday` is not an ISO 8601",
        ),
        (json!({"trackables": ["a", 3]}), "[1].trackables[1]: expected a string"),
        (
            json!({"position": {"type": "Polygon", "coordinates": [1.0, 2.0]}}),
            "[1].position.type: expected \"Point\"",
        ),
    ];
    for (change, expected) in cases {
        let mut bad = good("t2");
        for (k, v) in change.as_object().unwrap() {
            bad[k] = v.clone();
        }
        let body = json!([good("t1"), bad]).to_string();
        let message = parse_locations(&body).unwrap_err().to_string();
        assert!(message.starts_with(expected), "{message} vs {expected}");
    }
    // a member the schema does not name is ignored (the spec's Location does not close its
    // object), beside the position's too
    let mut extra = good("t2");
    extra["colour"] = json!("red");
    extra["position"]["crs_hint"] = json!("site");
    let parsed = parse_locations(&json!([good("t1"), extra]).to_string()).unwrap();
    assert_eq!(parsed[1].provider_id, "t2");
    let mut missing = good("t2");
    missing.as_object_mut().unwrap().remove("source");
    let message = parse_locations(&json!([good("t1"), good("t3"), missing]).to_string())
        .unwrap_err()
        .to_string();
    assert_eq!(message, "[2].source: required field is missing");
    assert_eq!(
        parse_locations("{}").unwrap_err().to_string(),
        "request body: expected a JSON array of Location objects"
    );
    assert_eq!(
        parse_locations(&json!([good("a"), good("b")]).to_string())
            .unwrap()
            .len(),
        2
    );
}

#[test]
fn a_wgs84_location_is_taken_to_the_site_frame_through_its_georeference() {
    let frame = rtls_engine::site::FrameSettings {
        origin: rtls_engine::site::GeodeticOrigin {
            latitude_deg: 47.3769,
            longitude_deg: 8.5417,
            height_m: 455.0,
        },
        x_axis_bearing_deg: 90.0,
    };
    let mut location = parse_locations(&json!([good("t1")]).to_string()).unwrap().remove(0);
    // site (12, -7) in WGS-84, as a provider with a GNSS receiver would send it
    let [lon, lat, _] = frame.wgs84_of([12.0, -7.0, 0.0]).unwrap();
    location.position.coordinates = vec![lon, lat];
    location.crs = Some("EPSG:4326".into());
    let local = location_in_site(&location, 0, Some(&frame)).unwrap();
    assert_eq!(local.crs.as_deref(), Some("local"));
    let [x, y] = local.position.coordinates[..] else {
        panic!("{local:?}")
    };
    assert!((x - 12.0).abs() < 1e-6 && (y + 7.0).abs() < 1e-6, "{x} {y}");
    assert_eq!(local.accuracy, location.accuracy);
    // a local location is left as it is
    let mut site_metres = location.clone();
    site_metres.crs = None;
    assert_eq!(location_in_site(&site_metres, 0, Some(&frame)).unwrap(), site_metres);
    // no georeference, another CRS, coordinates that are no longitude and latitude
    let message = location_in_site(&location, 2, None).unwrap_err().to_string();
    assert!(message.starts_with("[2].crs: the site has no [frame]"), "{message}");
    let mut other = location.clone();
    other.crs = Some("EPSG:25832".into());
    let message = location_in_site(&other, 0, Some(&frame)).unwrap_err().to_string();
    assert!(message.contains("not one of local, EPSG:4326"), "{message}");
    let mut off_earth = location.clone();
    off_earth.position.coordinates = vec![8.5, 95.0];
    let message = location_in_site(&off_earth, 0, Some(&frame)).unwrap_err().to_string();
    assert!(message.starts_with("[0].position:"), "{message}");
}

#[test]
fn ingested_location_becomes_a_fix_record() {
    let locations = parse_locations(&json!([good("t1")]).to_string()).unwrap();
    let record = record_from_location(&locations[0], 0, 1.0, 99.0).unwrap();
    assert_eq!((record.time_s, record.tag.as_str()), (5.0, "t1"));
    assert_eq!(
        record.measurement,
        Measurement::Fix {
            position_m: vec![1.0, 2.0],
            covariance_m2: vec![0.25, 0.0, 0.0, 0.25]
        }
    );
    let mut geographic = locations[0].clone();
    geographic.crs = Some("EPSG:4326".into());
    let message = record_from_location(&geographic, 3, 1.0, 0.0).unwrap_err().to_string();
    assert!(
        message.starts_with("[3].crs: `EPSG:4326`: the location is to be taken to the site frame first"),
        "{message}"
    );
    let mut untimed = locations[0].clone();
    untimed.timestamp_generated = None;
    untimed.accuracy = None;
    let record = record_from_location(&untimed, 0, 2.0, 99.0).unwrap();
    assert_eq!(record.time_s, 99.0);
    assert_eq!(
        record.measurement,
        Measurement::Fix {
            position_m: vec![1.0, 2.0],
            covariance_m2: vec![4.0, 0.0, 0.0, 4.0]
        }
    );
    // an accuracy of 0 m is a valid Location's: the default, as when none is given
    untimed.accuracy = Some(0.0);
    let record = record_from_location(&untimed, 0, 2.0, 99.0).unwrap();
    assert!(matches!(record.measurement, Measurement::Fix { ref covariance_m2, .. } if covariance_m2[0] == 4.0));
    untimed.accuracy = Some(-1.0);
    assert!(
        record_from_location(&untimed, 0, 2.0, 99.0).is_err(),
        "a negative accuracy is none"
    );
}

#[test]
fn motions_and_collision_events_match_schema() {
    let location = location_from_update(&update(), "site", ProviderType::Uwb).unwrap();
    let trackable = crate::pipeline::trackables::implicit_trackable("miner-017");
    let motion = crate::omlox::TrackableMotion::of(&trackable, location);
    assert_eq!(
        (motion.id.as_str(), motion.location.provider_id.as_str()),
        ("miner-017", "miner-017")
    );
    assert_valid("TrackableMotion", &serde_json::to_value(&motion).unwrap(), |_| {});

    use crate::omlox::collision::{Body, CollisionDetector, CollisionSettings};
    use crate::omlox::CollisionType;
    let body = |id: &str, t: f64, x: f64| Body {
        id: id.into(),
        provider_id: id.into(),
        time_s: 1_567_461_744.0 + t,
        coordinates: vec![x, 0.0],
        floor: 0.0,
        radius_m: 1.0,
        sigma_m: 0.2,
        exit_tolerance_m: 0.0,
        tolerance_timeout_s: None,
    };
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    detector.update(body("a", 0.0, 0.0));
    let mut transitions = detector.update(body("b", 0.1, 1.5));
    transitions.extend(detector.update(body("a", 0.2, 0.0)));
    transitions.extend(detector.update(body("b", 0.3, 9.0)));
    let kinds: Vec<CollisionType> = transitions.iter().map(|t| t.kind).collect();
    assert_eq!(
        kinds,
        [
            CollisionType::CollisionStart,
            CollisionType::Colliding,
            CollisionType::CollisionEnd
        ]
    );
    for transition in &transitions {
        let event = crate::pipeline::collision_news::collision_event(transition).unwrap();
        let value = serde_json::to_value(&event).unwrap();
        assert_valid("CollisionEvent", &value, |_| {});
        assert_eq!(value["start_time"], "2019-09-02T22:02:24.100Z");
        assert_eq!(value["collisions"][0]["id"], transition.trigger.id.as_str());
        // the same transition has the same event id (a replay repeats it)
        assert_eq!(
            event.id,
            crate::pipeline::collision_news::collision_event(transition).unwrap().id
        );
    }
    let end = serde_json::to_value(crate::pipeline::collision_news::collision_event(&transitions[2]).unwrap()).unwrap();
    assert_eq!(end["end_time"], "2019-09-02T22:02:24.300Z");
    assert!(end.get("collision_area").is_none() && end.get("collision_time").is_none());
}
