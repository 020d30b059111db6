//! A faithful harness of a third-party omlox client, run as a scripted session against the
//! whole server on loopback (issue 21: "a third-party omlox client … passing a scripted
//! session: create trackables, push locations, subscribe, receive every pushed location and
//! fence event").
//!
//! The client is the Go library `wavecomtech/omlox-client-go` (MIT), studied at commit
//! `34053748938b64888636554bd45c281597f88cde` (2025-12-12, "fix nix package vendor hash
//! (#22)"), with the dependencies its `go.mod` pins where they decide what goes over the wire:
//! `nhooyr.io/websocket` v1.8.10, `github.com/mailru/easyjson` v0.7.7 (the generated
//! encoders and decoders), `github.com/tidwall/geojson` v1.4.3, `github.com/google/uuid`
//! v1.3.0. No Go toolchain is involved: this file makes the client's requests in Rust — the
//! same methods, paths, headers and bodies, field for field in its encoders' order and
//! `omitempty` rules — and judges every answer by the client's own decoding rules. Files of the
//! client read for it:
//! - `client.go` (`newRequest`: the base address joined with the path, no headers of its own —
//!   no `Content-Type`, no `Accept`, no auth; `sendStructuredRequestParseResponse`: the body is
//!   `json.NewEncoder(…).Encode`, so JSON plus a newline; `parseResponse[List]`: an empty body
//!   is no value, anything else must decode into the response type);
//! - `client_configuration.go` (`WithHTTPClient`: the only way to add a token, a round-tripper
//!   that the WebSocket dial uses too);
//! - `error.go` (`isResponseError`: 200–399 is success);
//! - `trackable_requests.go`, `provider_requests.go` (the calls and their paths);
//! - `trackable.go`, `provider.go`, `location.go`, `point.go`, `polygon.go`, `duration.go`,
//!   `rules.go`, `omlox_easyjson.go` (the models: `id` a `uuid.UUID`, `type` enums that refuse
//!   unknown names, the `Duration` timeouts and a `LocatingRule`'s `priority` read as integers
//!   — `jlexer.Int` is `strconv.ParseInt`, which refuses `5000.0` — timestamps as RFC 3339,
//!   positions and geometries through `geojson.Parse`);
//! - `client_websockets.go`, `client_subscription.go`, `websockets.go` (`Connect` dials
//!   `{base}/ws/socket`; `subscribe` sends `{"event":"subscribe","topic":…}`, waits for the
//!   next `subscribed` or a subscription `error`, then files the subscription under id **0**
//!   whatever id the hub assigned — "BUG: deephub doesn't return the sid in subsequent
//!   messages"; `readLoop` decodes each text frame with `encoding/json` into the wrapper and
//!   drops what does not decode; `routeMessage` hands a `message` to `subs[subscription_id]`
//!   and drops it when there is none; `ReceiveAs` drops payload objects that do not decode;
//!   `pingLoop` pings every 9 s and gives up after 10 s without the pong);
//! - `cmd/omlox-cli/{root.go, create_trackables.go, update_providers_location.go, sub.go}`
//!   (how its own CLI uses the library: one `UpdateLocation` per location, one subscription
//!   per connection);
//! - nhooyr.io/websocket v1.8.10 `read.go` (a message over 32 768 bytes closes the connection
//!   with 1009 — the client never raises the limit) and `dial.go` (the handshake answer may
//!   not name a subprotocol or an extension the client did not ask for).
//!
//! The session: two trackables and their providers created the client's way (the nil UUID as
//! a new trackable's id), listed and read back; a fence created by plain REST (the client has
//! no fence call); two client connections, each subscribed to one topic as the client
//! subscribes (`location_updates`, `fence_events`) and pinged as `pingLoop` pings; a walk of
//! 20 locations per provider pushed with the client's one-location call while the sockets are
//! read; every pushed location must come back on `location_updates`, decodable by the client,
//! at its pushed position with its provider's fields, and both providers' `region_entry` and
//! `region_exit` of the fence on `fence_events`, in frames the client's reader takes; then
//! `GetLocation`, and `Create`, `List`, `Delete` of a trackable with the client's integer
//! fields; last a load probe (not a client call): 150 tags pushed at once in bulk while the
//! client listens.
//!
//! What the client would trip on is collected and asserted absent. The run that added this
//! file found four such things in the hub, fixed since: (1) the client's own routing delivered
//! none of the hub's messages, because the hub numbered a connection's subscriptions from 1 and
//! the client looks every message up under 0 — a connection's subscriptions are now numbered
//! from 0; (2) a fence event's `fence_id` was not the id the fence was created with (its
//! `foreign_id` was); (3) a trackable's `fence_timeout`, `tolerance_timeout`, `exit_delay` and a
//! locating rule's `priority`, sent as integers, came back as `5000.0`, `-1.0`, `1000.0`, `1.0`,
//! which the client's decoder refuses; (4) the load probe's locations came in
//! `location_updates` frames of 70–105 kB, over the 32 768 bytes after which the client's
//! WebSocket library closes the connection — frames now stay below 32 KiB.

mod common;

use std::collections::HashSet;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use reqwest::Method;
use rtls_server::config::MqttMode;
use serde_json::Value;

use common::{temp_dir, READ, WRITE};

mod go_client;

use go_client::rest::*;
use go_client::socket::*;
use go_client::wire::*;
use go_client::*;

// ---- the session ----

/// Now, ns since the epoch.
fn now_ns() -> i128 {
    i128::try_from(SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_nanos()).unwrap()
}

/// EUI-64 provider ids, upper case with colons, as the client's model asks of UWB tags.
const TAG_A: &str = "0A:1B:2C:3D:4E:5F:60:71";
const TAG_B: &str = "0A:1B:2C:3D:4E:5F:60:72";

/// The fence, site metres: x ∈ [4.5, 8.5] m across the walk (y = 10 m and 8 m).
const FENCE_X: [f64; 2] = [4.5, 8.5];

/// The walk: each provider from x = 1 m east at 1.2 m/s, one location every 0.5 s of data time
/// starting half a second from now (the hub's live clock runs 2 s behind the wall clock, so
/// none of them is late), to x = 12.4 m: through the fence and out, short of the site's hazard
/// zone at x = 14 m. The time of each has nanoseconds, as a Go `time.Now()` has.
fn walk(start_ns: i128) -> Vec<Fix> {
    let mut fixes = Vec::new();
    for k in 0..FIXES {
        for (provider_id, y) in [(TAG_A, 10.0), (TAG_B, 8.0)] {
            let step = i32::try_from(k).unwrap();
            let ns = start_ns + 500_000_000 * i128::from(step);
            fixes.push(Fix {
                provider_id,
                position: [1.0 + 0.6 * f64::from(step), y],
                timestamp_generated: go_time(ns),
                unix_ms: i64::try_from((ns + 500_000) / 1_000_000).unwrap(),
                accuracy: 0.3,
            });
        }
    }
    fixes
}

/// A timestamp as ms since the epoch (rounded as the hub rounds).
fn unix_ms(time: time::OffsetDateTime) -> i64 {
    i64::try_from((time.unix_timestamp_nanos() + 500_000).div_euclid(1_000_000)).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_go_omlox_client_session_creates_pushes_subscribes_and_receives_everything() {
    println!("omlox-client-go {CLIENT_COMMIT}: scripted session");
    let dir = temp_dir("omlox-go-client");
    let config = common::loopback_config(&dir, MqttMode::Off);
    let running = common::serve_on_loopback(common::options(config)).await;
    let http = running.bound.http;
    let writer = GoRest::new(http, WRITE);
    let mut incompatible: Vec<String> = Vec::new();

    // 1. providers and trackables, created as the client creates them
    for (tag, name) in [(TAG_A, "tag A"), (TAG_B, "tag B")] {
        let (status, created) = writer.create_provider(tag, name).await;
        assert_eq!(created.as_deref(), Ok(tag), "ProvidersAPI.Create {tag}: {status}");
    }
    let forklift = GoTrackable {
        id: NIL_UUID,
        kind: "omlox",
        name: "Forklift 7",
        location_providers: &[TAG_A],
        radius: 1.5,
        properties: Some(r#"{"fleet":"north","driver":"J. Doe"}"#),
        ..GoTrackable::default()
    };
    let cart = GoTrackable {
        id: NIL_UUID,
        kind: "virtual",
        name: "Cart 3",
        location_providers: &[TAG_B],
        extrusion: 1.2,
        exit_tolerance: 0.5,
        ..GoTrackable::default()
    };
    let mut ids = Vec::new();
    for trackable in [&forklift, &cart] {
        let (status, created) = writer.create_trackable(trackable).await;
        let created = created.unwrap_or_else(|e| panic!("TrackablesAPI.Create {}: {e}", trackable.name));
        assert_eq!(status, 201, "{created}");
        let decoded = go_decode_trackable(&created)
            .unwrap_or_else(|e| panic!("the client cannot decode its created trackable: {e}: {created}"));
        assert!(
            !decoded.id.is_nil(),
            "a nil id is answered with an assigned one: {created}"
        );
        assert_eq!(decoded.id.get_version_num(), 4, "{created}");
        assert_eq!(decoded.name, trackable.name);
        assert_eq!(decoded.location_providers, trackable.location_providers);
        assert_eq!(created["type"], trackable.kind);
        ids.push(decoded.id);
    }
    assert_ne!(ids[0], ids[1], "distinct ids");

    // 2. listed and read back as the client lists and reads them
    let listed = writer.list_trackables().await.expect("TrackablesAPI.List");
    let listed_ids: HashSet<uuid::Uuid> = listed.iter().map(|t| t.id).collect();
    assert_eq!(listed_ids, ids.iter().copied().collect(), "{listed:?}");
    let all_ids = writer.trackable_ids().await.expect("TrackablesAPI.IDs");
    assert_eq!(all_ids.iter().copied().collect::<HashSet<_>>(), listed_ids);
    for (id, trackable) in ids.iter().zip([&forklift, &cart]) {
        let got = writer.get_trackable(id).await.expect("TrackablesAPI.Get");
        assert_eq!((got.id, got.name.as_str()), (*id, trackable.name));
        assert_eq!(got.location_providers, trackable.location_providers);
    }

    // 3. a fence across the walk: plain REST (the client has no fence call), through the same
    //    http.Client, so again without Content-Type
    let fence_body = format!(
        "{{\"id\":\"{NIL_UUID}\",\"name\":\"go client fence\",\"crs\":\"local\",\"region\":{{\"type\":\"Polygon\",\"coordinates\":[[[{x0},5],[{x1},5],[{x1},15],[{x0},15],[{x0},5]]]}}}}",
        x0 = FENCE_X[0],
        x1 = FENCE_X[1]
    );
    let (status, fence) = writer.call(Method::POST, "/fences", Some(fence_body)).await;
    let fence = fence.expect("POST /v2/fences").expect("the fence");
    assert_eq!(status, 201, "{fence}");
    let fence_id = fence["id"].as_str().unwrap().to_string();
    assert!(!uuid::Uuid::parse_str(&fence_id).unwrap().is_nil(), "{fence}");
    // the trackers take a zone edit within a clock tick (250 ms)
    tokio::time::sleep(Duration::from_millis(600)).await;

    // 4. two client connections, one subscription each (one per connection is all the client's
    //    id-0 filing can hold; its CLI subscribes once per process), with the read token
    let mut locations_socket = GoSocket::connect(http, READ).await;
    let location_sid = locations_socket.subscribe("location_updates").await.expect("Subscribe");
    let mut fences_socket = GoSocket::connect(http, READ).await;
    let fence_sid = fences_socket.subscribe("fence_events").await.expect("Subscribe");
    println!(
        "subscribed: location_updates → hub id {location_sid}, fence_events → hub id {fence_sid} (both filed under 0)"
    );
    locations_socket.ping().await;
    fences_socket.ping().await;

    // 5. the walk, pushed location by location with the client's call while the sockets are
    //    read (as the client's reader goroutine reads them)
    // half a second from now, with a sub-millisecond part of its own (nanoseconds as a Go
    // time.Now() has them, kept away from the hub's millisecond rounding boundary)
    let fixes = walk((now_ns() / 1_000_000 + 500) * 1_000_000 + 123_457);
    let pusher = {
        let fixes = fixes.clone();
        let writer = GoRest::new(http, WRITE);
        tokio::spawn(async move {
            let started = Instant::now();
            for fix in &fixes {
                let status = writer
                    .update_location(fix)
                    .await
                    .unwrap_or_else(|e| panic!("ProvidersAPI.UpdateLocation {}: {e}", fix.to_json()));
                assert_eq!(status, 204);
            }
            started.elapsed()
        })
    };

    // 6. every pushed location back on location_updates, and the fence's entries and exits
    let mut wanted: Vec<&Fix> = fixes.iter().collect();
    let mut revisions: Vec<String> = Vec::new();
    let mut ids_seen: HashSet<(String, i64)> = HashSet::new();
    let mut fence_events: Vec<Value> = Vec::new();
    let (mut updates, mut undecodable_locations, mut strings_kept) = (0usize, Vec::new(), 0usize);
    let (mut by_client, mut by_hub_id, mut messages) = (0usize, 0usize, 0usize);
    let trackable_ids = [ids[0].to_string(), ids[1].to_string()];
    let fence_done = |events: &[Value]| {
        let by = |key: &str, of: &str| {
            ["region_entry", "region_exit"]
                .iter()
                .all(|kind| events.iter().any(|e| e[key] == of && e["event_type"] == *kind))
        };
        [TAG_A, TAG_B].iter().all(|tag| by("provider_id", tag)) && trackable_ids.iter().all(|id| by("trackable_id", id))
    };
    let deadline = tokio::time::Instant::now() + WAIT;
    while !(wanted.is_empty() && fence_done(&fence_events)) {
        let routed = tokio::select! {
            routed = locations_socket.next_message(deadline) => routed,
            routed = fences_socket.next_message(deadline) => routed,
        };
        let Some(routed) = routed else { break };
        messages += 1;
        ids_seen.insert((routed.topic.clone(), routed.subscription_id));
        by_client += usize::from(routed.by_client.is_some());
        by_hub_id += usize::from(routed.by_hub_id.is_some());
        // the messages are taken as routed by the hub's id (see the module doc)
        assert_eq!(routed.by_hub_id.as_deref(), Some(routed.topic.as_str()), "{routed:?}");
        match routed.topic.as_str() {
            "location_updates" => {
                for object in &routed.payload {
                    updates += 1;
                    let location = match go_decode_location(object) {
                        Ok(location) => location,
                        Err(e) => {
                            undecodable_locations.push(format!("{e}: {object}"));
                            continue;
                        }
                    };
                    let Some(time) = location.timestamp_generated else {
                        continue;
                    };
                    // the hub writes milliseconds: the fix of that provider within 1 ms
                    let Some(index) = wanted
                        .iter()
                        .position(|f| f.provider_id == location.provider_id && (unix_ms(time) - f.unix_ms).abs() <= 1)
                    else {
                        continue;
                    };
                    let fix = wanted[index];
                    // the pushed fix itself: the provider's position and fields
                    let position = &location.position;
                    if (position[0] - fix.position[0]).abs() > 1e-9 || (position[1] - fix.position[1]).abs() > 1e-9 {
                        // an update of the track at that time that is not the fix as pushed
                        revisions.push(object.to_string());
                        continue;
                    }
                    assert_eq!(location.source, SOURCE, "{object}");
                    assert_eq!(location.provider_type, "uwb", "{object}");
                    assert_eq!(location.accuracy, Some(fix.accuracy), "{object}");
                    let properties = location.properties.as_ref().expect("properties kept");
                    assert_eq!(properties["battery"], 87, "{object}");
                    assert_eq!(properties["firmware"], "2.1.0", "{object}");
                    assert!(properties["rtls:filtered"].is_object(), "{object}");
                    strings_kept += usize::from(object["timestamp_generated"] == fix.timestamp_generated.as_str());
                    // if the hub lists the provider's trackables, they are the one it moves
                    let trackable = if fix.provider_id == TAG_A { ids[0] } else { ids[1] };
                    assert!(
                        location.trackables.is_empty() || location.trackables == [trackable],
                        "{object}"
                    );
                    wanted.swap_remove(index);
                }
            }
            "fence_events" => {
                // the client has no FenceEvent model: a caller reads ReceiveRaw's payload
                for event in routed.payload {
                    if event["fence_id"] == fence_id.as_str() || event["foreign_id"] == fence_id.as_str() {
                        fence_events.push(event);
                    }
                }
            }
            other => panic!("a message on {other}, which nobody subscribed to"),
        }
    }
    let push_time = tokio::time::timeout(WAIT, pusher)
        .await
        .expect("the pushes end")
        .unwrap();
    println!(
        "pushed {} locations in {push_time:.2?}; read {messages} messages ({by_hub_id} routed by the hub's \
         id, {by_client} by the client's), {updates} location updates, {} fence events of the fence; \
         largest frame {} / {} bytes",
        fixes.len(),
        fence_events.len(),
        locations_socket.largest_frame,
        fences_socket.largest_frame
    );
    assert!(
        wanted.is_empty(),
        "pushed locations that did not come back on location_updates: {:?}; updates at their \
         times at another position: {revisions:#?}",
        wanted
            .iter()
            .map(|f| (f.provider_id, &f.timestamp_generated))
            .collect::<Vec<_>>()
    );
    assert!(
        undecodable_locations.is_empty(),
        "payload objects ReceiveAs[Location] would drop: {undecodable_locations:#?}"
    );
    for tag in [TAG_A, TAG_B] {
        let kinds: Vec<&str> = fence_events
            .iter()
            .filter(|e| e["provider_id"] == tag)
            .map(|e| e["event_type"].as_str().unwrap())
            .collect();
        assert_eq!(kinds, ["region_entry", "region_exit"], "{tag}: {fence_events:#?}");
        // omlox: a fence event names the trackables its provider is assigned to
        let trackable = if tag == TAG_A { ids[0] } else { ids[1] }.to_string();
        assert!(
            fence_events
                .iter()
                .filter(|e| e["provider_id"] == tag)
                .all(|e| e["trackables"] == serde_json::json!([trackable])),
            "{tag} is {trackable}'s provider: {fence_events:#?}"
        );
        // and the trackable's own entry and exit (omlox: `trackable_id`, no `provider_id`)
        let kinds: Vec<&str> = fence_events
            .iter()
            .filter(|e| e["trackable_id"] == trackable.as_str())
            .inspect(|e| assert!(e.get("provider_id").is_none(), "{e}"))
            .map(|e| e["event_type"].as_str().unwrap())
            .collect();
        assert_eq!(kinds, ["region_entry", "region_exit"], "{trackable}: {fence_events:#?}");
    }
    for socket in [&locations_socket, &fences_socket] {
        assert!(
            socket.undecodable.is_empty(),
            "frames readLoop would skip: {:#?}",
            socket.undecodable
        );
        assert!(
            socket.largest_frame <= GO_READ_LIMIT,
            "a {} byte frame: nhooyr would close the client's connection (1009)",
            socket.largest_frame
        );
    }
    println!(
        "timestamp_generated strings echoed unchanged: {strings_kept} of {}; (topic, subscription_id) \
         of the messages: {ids_seen:?}",
        fixes.len()
    );

    // after the walk: the trackable's location as the client reads it
    let location = writer
        .trackable_location(&ids[0])
        .await
        .expect("TrackablesAPI.GetLocation decodes");
    assert_eq!(location.provider_id, TAG_A);

    // a load probe (not one of the client's calls): a vendor's RTLS pushes 150 tags at once
    // with the bulk call while the client listens; the hub sends what waits for a subscription
    // in one frame, and nhooyr closes the client's connection on a frame over 32 768 bytes
    let (tags, bulk_start) = (150usize, now_ns() / 1_000_000 * 1_000_000 + 500_000_000);
    let mut bulk = Vec::new();
    for step in 0..3i32 {
        for tag in 0..tags {
            let (column, row) = (u32::try_from(tag % 10).unwrap(), u32::try_from(tag / 10).unwrap());
            bulk.push(format!(
                "{{\"position\":{{\"type\":\"Point\",\"coordinates\":[{},{}]}},\"source\":\"{SOURCE}\",\"provider_type\":\"uwb\",\"provider_id\":\"bulk-{tag:03}\",\"timestamp_generated\":\"{}\",\"accuracy\":0.3}}",
                20.0 + f64::from(column) + 0.1 * f64::from(step),
                1.0 + f64::from(row),
                go_time(bulk_start + 500_000_000 * i128::from(step))
            ));
        }
    }
    locations_socket.largest_frame = 0;
    let (status, _) = writer
        .call(
            Method::PUT,
            "/providers/locations",
            Some(format!("[{}]", bulk.join(","))),
        )
        .await;
    assert_eq!(status, 204, "PUT /v2/providers/locations");
    let mut bulk_seen: HashSet<String> = HashSet::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(6);
    while bulk_seen.len() < tags {
        let Some(routed) = locations_socket.next_message(deadline).await else {
            break;
        };
        for object in &routed.payload {
            let location = go_decode_location(object).unwrap_or_else(|e| panic!("{e}: {object}"));
            if location.provider_id.starts_with("bulk-") {
                bulk_seen.insert(location.provider_id);
            }
        }
    }
    println!(
        "load probe: {} of {tags} bulk tags seen; largest location_updates frame {} bytes",
        bulk_seen.len(),
        locations_socket.largest_frame
    );
    if locations_socket.largest_frame > GO_READ_LIMIT {
        incompatible.push(format!(
            "a location_updates frame of {} bytes after one PUT /v2/providers/locations of {tags} tags: \
             over nhooyr's default read limit ({GO_READ_LIMIT} bytes), which the client never raises, so \
             the client's connection is closed with 1009 and its subscriptions end",
            locations_socket.largest_frame
        ));
    }

    // what the client trips on (each would break it; see the module doc)
    if by_client < messages {
        incompatible.push(format!(
            "routeMessage delivers {by_client} of {messages} messages: the hub's subscription ids are \
             {location_sid} (location_updates) and {fence_sid} (fence_events), the client files every \
             subscription under 0 and looks each message up by its subscription_id"
        ));
    }
    let mismatched: Vec<&Value> = fence_events
        .iter()
        .filter(|e| e["fence_id"] != fence_id.as_str())
        .collect();
    if !mismatched.is_empty() {
        incompatible.push(format!(
            "{} fence events of fence {fence_id} carry fence_id {} (its foreign_id is the fence's id)",
            mismatched.len(),
            mismatched[0]["fence_id"]
        ));
    }
    // a trackable with the client's integer-typed fields: timeouts and a locating rule
    let timed = GoTrackable {
        id: NIL_UUID,
        kind: "omlox",
        name: "Timed tug",
        location_providers: &["0A:1B:2C:3D:4E:5F:60:73"],
        fence_timeout_ms: Some(5000),
        tolerance_timeout_ms: Some(-1),
        exit_delay_ms: Some(1000),
        locating_rules: &[("accuracy < 1", 1)],
        ..GoTrackable::default()
    };
    let (status, created) = writer.create_trackable(&timed).await;
    let created = created.expect("POST /v2/trackables with timeouts");
    assert_eq!(status, 201, "{created}");
    if let Err(e) = go_decode_trackable(&created) {
        incompatible.push(format!(
            "TrackablesAPI.Create with fence_timeout/tolerance_timeout/exit_delay/locating_rules: \
             the trackable is created (201) but the client's decoder refuses the answer ({e}); \
             sent {}, answered {created}",
            timed.to_json()
        ));
    }
    if let Err(e) = writer.list_trackables().await {
        incompatible.push(format!("TrackablesAPI.List fails while that trackable exists: {e}"));
    }
    let timed_id = uuid::Uuid::parse_str(created["id"].as_str().unwrap()).unwrap();
    assert_eq!(
        writer.delete_trackable(&timed_id).await,
        Ok(204),
        "TrackablesAPI.Delete"
    );
    assert_eq!(writer.list_trackables().await.expect("TrackablesAPI.List").len(), 2);

    assert!(
        incompatible.is_empty(),
        "what the Go client trips on:\n{}",
        incompatible.join("\n")
    );
    running.stop().await;
}

/// The harness's own encoders and decoders against the client's test vector (the location of
/// `websocket_test.go`) and Go's formatting and parsing rules.
#[test]
fn the_harness_writes_what_the_client_writes() {
    assert_eq!(go_time(1_567_461_744_355_000_000), "2019-09-02T22:02:24.355Z");
    assert_eq!(go_time(1_567_461_744_000_000_000), "2019-09-02T22:02:24Z");
    assert_eq!(go_time(1_567_461_744_000_000_123), "2019-09-02T22:02:24.000000123Z");
    let new = GoTrackable {
        id: NIL_UUID,
        kind: "omlox",
        ..GoTrackable::default()
    };
    assert_eq!(new.to_json(), format!("{{\"id\":\"{NIL_UUID}\",\"type\":\"omlox\"}}"));
    let fix = Fix {
        provider_id: "77:4f:34:69:27:40",
        position: [5.0, 4.0],
        timestamp_generated: "2019-09-02T22:02:24.355Z".into(),
        unix_ms: 1_567_461_744_355,
        accuracy: 0.3,
    };
    let json = fix.to_json();
    assert!(
        json.starts_with(r#"{"position":{"type":"Point","coordinates":[5,4]},"source":"#),
        "{json}"
    );
    let decoded = go_decode_location(&serde_json::from_str(&json).unwrap()).unwrap();
    assert_eq!(decoded.position, vec![5.0, 4.0]);
    // the client's decoder refuses what strconv.ParseInt refuses
    assert!(go_int(&serde_json::json!(5000.0), "t").is_err());
    assert_eq!(go_int(&serde_json::json!(-1), "t"), Ok(-1));
    // the wrapper: members in any case, an unknown event refused
    let wrapper = go_decode_wrapper(r#"{"Event":"message","TOPIC":"location_updates","payload":[{}]}"#).unwrap();
    assert_eq!((wrapper.event.as_str(), wrapper.subscription_id), ("message", 0));
    assert!(go_decode_wrapper(r#"{"event":"hello"}"#).is_err());
    assert!(go_decode_wrapper(r#"{"event":"message","subscription_id":1.0}"#).is_err());
}
