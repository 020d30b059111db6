//! The omlox WebSocket `/v2/ws/socket`: subscribe to `location_updates`(`:geojson`),
//! `fence_events`(`:geojson`; geometries in WGS-84 longitude/latitude when the site has a
//! `[frame] origin`, as RFC 7946 wants, else site metres), `trackable_motions` (a
//! `TrackableMotion` per track update of a trackable: [`crate::pipeline::trackables`]),
//! `collision_events` (`CollisionEvent`s: [`crate::omlox::collision`]), `proximity_updates`
//! (the `Proximity` objects providers push) and the extension topics `rtls:alarms` (predictive
//! hazard alarms, lost tags, no coverage, model switches) and `rtls:events` (everything else).
//!
//! Client: `{"event":"subscribe","topic":"location_updates","params":{"provider_id":"tag-7"}}`
//! → `{"event":"subscribed","topic":…,"subscription_id":0}`, then
//! `{"event":"message","topic":…,"subscription_id":0,"payload":[…]}` for every update.
//! A connection's subscriptions are numbered from 0: a client that files its one subscription
//! under 0 whatever the hub answers (the Go omlox client does) gets its messages.
//! `params.provider_id` (or `tag`) filters by tag (on `collision_events`: either tag whose
//! update placed one of the two trackables); `params.trackable_id` filters `trackable_motions`
//! and `collision_events` (either of the two) by trackable. `params.crs` and `params.zone_id`
//! on `location_updates`, `location_updates:geojson`, `trackable_motions` and
//! `collision_events` project positions as `?crs=` and `?zone_id=` do on the REST reads
//! (`zone_id` projects into the zone's local frame; it does not filter): a Location's
//! position, the GeoJSON Feature's geometry (with the foreign members `crs` and `zone_id` when
//! local, as `geojson=true` reads have them; without params it is WGS-84 when the site has a
//! frame), a collision's `collision_area` and each collision's `position` and `geometry`.
//! A location or collision the subscription's frame cannot project is not sent (counted in
//! `rtls_websocket_unprojected`). A client that falls more than the broadcast capacity behind
//! misses messages (counted in `rtls_websocket_dropped`).
//!
//! Batching: every message waiting in the broadcast queue when the socket is ready is sent
//! together, one `message` per subscription whose `payload` holds all of them in order (up to
//! [`MAX_BATCH`]): a screen with ten thousand tags gets one frame per output tick, not one per
//! tag. A frame stays below [`MAX_FRAME_BYTES`] (a larger batch goes in several `message`s):
//! WebSocket libraries close the connection on larger messages by default (32 KiB in Go's
//! `nhooyr.io/websocket`).

use std::collections::HashMap;
use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;
use serde_json::{json, Value};
use tokio::sync::broadcast::error::{RecvError, TryRecvError};

/// At most this many hub messages go into one WebSocket send.
pub const MAX_BATCH: usize = 4096;

/// A `message` frame's size at most, bytes (one payload object larger than that goes alone).
pub const MAX_FRAME_BYTES: usize = 32 * 1024 - 512;

use super::positions::PositionColumns;
use super::read_frame::ReadFrame;
use super::{metrics, ApiResult, AppState};
use crate::auth::Access;
use crate::convert::{fence_from_zone, wgs84_geometry};
use crate::omlox::crs::Crs;
use crate::omlox::geojson::ToFeature;
use crate::omlox::ws::{Topic, WsErrorCode, WsEvent, WsMessage};
use crate::omlox::{CollisionEvent, Location, Proximity, TrackableMotion};
use crate::pipeline::trackable_location::moved_by;
use crate::pipeline::trackables::TrackableIndex;
use crate::pipeline::{CollisionListener, HubMessage, LiveState};

/// Query of the upgrade request.
#[derive(Debug, Deserialize)]
pub(super) struct SocketParams {
    token: Option<String>,
}

/// `GET /v2/ws/socket` (upgrade).
pub(super) async fn socket(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(params): Query<SocketParams>,
    upgrade: WebSocketUpgrade,
) -> ApiResult<Response> {
    if params.token.is_some() {
        state.authorize_token(params.token.as_deref(), Access::Read)?;
    } else {
        state.authorize(&headers, Access::Read)?;
    }
    Ok(upgrade.on_upgrade(move |socket| serve(socket, state)))
}

/// How often the server pings a WebSocket client.
const PING_PERIOD: std::time::Duration = std::time::Duration::from_secs(30);

/// One subscription.
struct Subscription {
    topic: Topic,
    /// Only this tag's messages.
    tag: Option<String>,
    /// Only this trackable's messages (`trackable_motions`, `collision_events`).
    trackable: Option<String>,
    /// `params.crs` / `params.zone_id` on the topics that carry positions
    /// ([`carries_locations`]): the frame positions go to (`None`: as published — site metres,
    /// or on `location_updates:geojson` WGS-84 when the site has a frame).
    frame: Option<ReadFrame>,
    /// On `collision_events`: the collision thread publishes while this is held.
    _collisions: Option<CollisionListener>,
}

async fn serve(mut socket: WebSocket, state: AppState) {
    let metrics = metrics(&state);
    metrics.websocket_clients.inc();
    let mut hub = state.pipeline.subscribe();
    // the zones when the socket opened (a zone edit reaches sockets opened after it)
    let fences: HashMap<String, Value> = state
        .pipeline
        .live()
        .zones()
        .iter()
        .map(fence_from_zone)
        .filter_map(|f| {
            let region = serde_json::to_value(&f.region).ok()?;
            Some((f.id.clone(), wgs84_geometry(state.site.frame.as_ref(), &region)))
        })
        .collect();
    let mut subscriptions: HashMap<u64, Subscription> = HashMap::new();
    let mut next_id = 0u64;
    // a ping every PING_PERIOD keeps a quiet subscription open through the listener's idle
    // timeout, and finds dead peers
    let mut ping = tokio::time::interval_at(tokio::time::Instant::now() + PING_PERIOD, PING_PERIOD);
    loop {
        tokio::select! {
            _ = ping.tick() => {
                if socket.send(Message::Ping(axum::body::Bytes::new())).await.is_err() {
                    break;
                }
            }
            incoming = socket.recv() => {
                let Some(Ok(message)) = incoming else { break };
                let text = match message {
                    Message::Text(text) => text.to_string(),
                    Message::Close(_) => break,
                    _ => continue,
                };
                let reply = handle(&text, &mut subscriptions, &mut next_id, &state).await;
                if send(&mut socket, &reply).await.is_err() {
                    break;
                }
            }
            published = hub.recv() => {
                let mut batch = match published {
                    Ok(message) => vec![message],
                    Err(RecvError::Lagged(missed)) => {
                        metrics.websocket_dropped.inc_by(missed);
                        continue;
                    }
                    Err(RecvError::Closed) => break,
                };
                // what else is already waiting goes in the same frames
                while batch.len() < MAX_BATCH {
                    match hub.try_recv() {
                        Ok(message) => batch.push(message),
                        Err(TryRecvError::Lagged(missed)) => {
                            metrics.websocket_dropped.inc_by(missed);
                        }
                        Err(_) => break,
                    }
                }
                let trackables = state.pipeline.live().trackables();
                let context = Context {
                    fences: &fences,
                    frame: state.site.frame.as_ref(),
                    trackables: &trackables,
                    live: state.pipeline.live(),
                    unprojected: &metrics.websocket_unprojected,
                };
                if deliver(&mut socket, &batch, &subscriptions, &context).await.is_err() {
                    break;
                }
            }
        }
    }
    metrics.websocket_clients.dec();
}

async fn send(socket: &mut WebSocket, message: &impl serde::Serialize) -> Result<(), axum::Error> {
    let text =
        serde_json::to_string(message).unwrap_or_else(|e| format!("{{\"event\":\"error\",\"description\":\"{e}\"}}"));
    socket.send(Message::Text(text.into())).await
}

/// Answers one client message.
async fn handle(
    text: &str,
    subscriptions: &mut HashMap<u64, Subscription>,
    next_id: &mut u64,
    state: &AppState,
) -> WsMessage {
    // read the event and the topic first, so an unknown one gets its own omlox error code
    let value: Value = match serde_json::from_str(text) {
        Ok(value) => value,
        Err(e) => return WsMessage::error(WsErrorCode::InvalidData, &e.to_string()),
    };
    if serde_json::from_value::<WsEvent>(value["event"].clone()).is_err() {
        return WsMessage::error(WsErrorCode::UnknownEvent, &format!("event {}", value["event"]));
    }
    if !value["topic"].is_null() && serde_json::from_value::<Topic>(value["topic"].clone()).is_err() {
        return WsMessage::error(WsErrorCode::UnknownTopic, &format!("topic {}", value["topic"]));
    }
    let request: WsMessage = match serde_json::from_value(value) {
        Ok(request) => request,
        Err(e) => return WsMessage::error(WsErrorCode::InvalidData, &e.to_string()),
    };
    match request.event {
        WsEvent::Subscribe => {
            let Some(topic) = request.topic else {
                return WsMessage::error(WsErrorCode::SubscriptionFailed, "`topic` is required");
            };
            let param = |name: &str| {
                request
                    .params
                    .as_ref()
                    .and_then(|p| p.get(name))
                    .and_then(Value::as_str)
                    .map(String::from)
            };
            let tag = param("provider_id").or_else(|| param("tag"));
            let trackable = param("trackable_id");
            let frame =
                match subscription_frame(topic, param("crs").as_deref(), param("zone_id").as_deref(), state).await {
                    Ok(frame) => frame,
                    Err(reason) => return WsMessage::error(WsErrorCode::SubscriptionFailed, &reason),
                };
            let id = *next_id;
            *next_id += 1;
            subscriptions.insert(
                id,
                Subscription {
                    topic,
                    tag,
                    trackable,
                    frame,
                    _collisions: (topic == Topic::CollisionEvents)
                        .then(|| state.pipeline.live().listen_for_collisions()),
                },
            );
            WsMessage::subscribed(topic, id)
        }
        WsEvent::Unsubscribe => match request
            .subscription_id
            .and_then(|id| subscriptions.remove(&id).map(|s| (id, s)))
        {
            Some((id, subscription)) => WsMessage {
                event: WsEvent::Unsubscribed,
                ..WsMessage::subscribed(subscription.topic, id)
            },
            None => WsMessage::error(WsErrorCode::UnsubscribeFailed, "no such subscription_id"),
        },
        _ => WsMessage::error(WsErrorCode::UnknownEvent, "clients send subscribe or unsubscribe"),
    }
}

/// The frame a subscription's `params.crs` and `params.zone_id` ask for ("crs and geojson
/// params as defined for the location and fence API"; `zone_id` "the zone id to be used to
/// project coordinates"): on the topics that carry positions ([`carries_locations`]) the REST
/// location reads' frame ([`ReadFrame::of_params`]), `None` for site metres (on
/// `location_updates:geojson` only without params: its default is WGS-84 when the site has a
/// frame, so an explicit `crs: "local"` keeps its frame); on other topics only
/// `crs: "local"` (their payloads carry no position to project).
///
/// # Errors
/// The reason, for error 10002: a CRS other than `local` / `EPSG:4326`, EPSG:4326 on a site
/// without a `[frame]`, an unknown zone or one without a local frame, or `crs` / `zone_id` on
/// a topic they do not apply to.
async fn subscription_frame(
    topic: Topic,
    crs: Option<&str>,
    zone_id: Option<&str>,
    state: &AppState,
) -> Result<Option<ReadFrame>, String> {
    if !carries_locations(topic) {
        return match (Crs::parse(crs), zone_id) {
            (Ok(Crs::Local), None) => Ok(None),
            (_, Some(zone_id)) => Err(format!(
                "zone_id `{zone_id}`: only on location_updates(:geojson), trackable_motions and collision_events"
            )),
            _ => Err(format!(
                "crs `{}`: only local, or EPSG:4326 on location_updates(:geojson), trackable_motions and \
                 collision_events",
                crs.unwrap_or_default()
            )),
        };
    }
    if crs.is_none() && zone_id.is_none() {
        return Ok(None);
    }
    match ReadFrame::of_params(state, crs, zone_id).await {
        Ok(frame) if frame.is_site_metres() && topic != Topic::LocationUpdatesGeojson => Ok(None),
        Ok(frame) => Ok(Some(frame)),
        Err(e) => Err(match e.field {
            Some(field) => format!("{field}: {}", e.message),
            // the one lookup that answers 404 is the zone's
            None if e.status == axum::http::StatusCode::NOT_FOUND => format!("zone_id: {}", e.message),
            None => e.message,
        }),
    }
}

/// What the payloads of a batch are built with.
struct Context<'a> {
    /// Fence geometries by fence id (for `fence_events:geojson`).
    fences: &'a HashMap<String, Value>,
    /// The site's georeference.
    frame: Option<&'a rtls_engine::site::FrameSettings>,
    /// The stored trackables by provider (for `trackable_motions`).
    trackables: &'a TrackableIndex,
    /// The providers' latest locations (a trackable with `locating_rules` chooses among them).
    live: &'a LiveState,
    /// Locations a subscription's frame could not project, so not sent
    /// (`rtls_websocket_unprojected`).
    unprojected: &'a prometheus_client::metrics::counter::Counter,
}

/// Sends hub messages to every matching subscription: one WebSocket message per subscription
/// with the payloads of all of them, in order.
async fn deliver(
    socket: &mut WebSocket,
    batch: &[Arc<HubMessage>],
    subscriptions: &HashMap<u64, Subscription>,
    context: &Context<'_>,
) -> Result<(), axum::Error> {
    for (&id, subscription) in subscriptions {
        let payloads: Vec<Payload<'_>> = match subscription.topic {
            Topic::RtlsPositions => compact_positions(batch, subscription)
                .into_iter()
                .map(Payload::Built)
                .collect(),
            Topic::TrackableMotions => motions(batch, subscription, context)
                .map(|motion| Payload::Motion(Box::new(motion)))
                .collect(),
            _ => batch
                .iter()
                .filter_map(|message| payload(message, subscription, context))
                .collect(),
        };
        if payloads.is_empty() {
            continue;
        }
        for frame in frames(subscription.topic, id, &payloads) {
            socket.send(Message::Text(frame.into())).await?;
        }
    }
    Ok(())
}

/// The `message` frames of one subscription's payloads, in order, each below
/// [`MAX_FRAME_BYTES`] (a payload object larger than that alone in its frame), written as
/// [`Delivery`] writes one.
fn frames(topic: Topic, subscription_id: u64, payloads: &[Payload<'_>]) -> Vec<String> {
    let envelope = Delivery {
        event: WsEvent::Message,
        topic,
        subscription_id,
        payload: Vec::new(),
    };
    // `{…,"payload":[]}` → the head up to `[` and the tail `]}`
    let empty = serde_json::to_string(&envelope).unwrap_or_default();
    let head = &empty[..empty.len() - 2];
    let mut frames = Vec::new();
    let mut frame = String::from(head);
    let mut items = 0usize;
    for payload in payloads {
        let Ok(item) = serde_json::to_string(payload) else {
            continue;
        };
        if items > 0 && frame.len() + 1 + item.len() + 2 > MAX_FRAME_BYTES {
            frame.push_str("]}");
            frames.push(std::mem::replace(&mut frame, String::from(head)));
            items = 0;
        }
        if items > 0 {
            frame.push(',');
        }
        frame.push_str(&item);
        items += 1;
    }
    if items > 0 {
        frame.push_str("]}");
        frames.push(frame);
    }
    frames
}

/// One object of a `message`'s payload: the hub message's own (shared by every connection and
/// written from there, not copied) or one built for this subscription.
#[derive(serde::Serialize)]
#[serde(untagged)]
enum Payload<'a> {
    Location(&'a Location),
    Shared(&'a Value),
    Built(Value),
    Motion(Box<TrackableMotion>),
    Collision(&'a CollisionEvent),
    Proximity(&'a Proximity),
}

/// A `message` to a subscription, written as [`WsMessage::message`] is (same keys, same order).
#[derive(serde::Serialize)]
struct Delivery<'a> {
    event: WsEvent,
    topic: Topic,
    subscription_id: u64,
    payload: Vec<Payload<'a>>,
}

/// A hub message's payload for one subscription, if it wants it.
fn payload<'a>(
    message: &'a Arc<HubMessage>,
    subscription: &Subscription,
    context: &Context<'_>,
) -> Option<Payload<'a>> {
    let (fences, frame) = (context.fences, context.frame);
    let payload = match (message.as_ref(), subscription.topic) {
        (HubMessage::Location { tag, location, .. }, Topic::LocationUpdates) if wanted(subscription, tag) => {
            let Some(projection) = &subscription.frame else {
                return Some(Payload::Location(location));
            };
            // a position the frame cannot take is not sent (its coordinates would be in no
            // frame), and counted
            let Ok(projected) = projection.location(Location::clone(location)) else {
                context.unprojected.inc();
                return None;
            };
            serde_json::to_value(projected).ok()?
        }
        (HubMessage::Location { tag, location, .. }, Topic::LocationUpdatesGeojson) if wanted(subscription, tag) => {
            match &subscription.frame {
                // the Feature of the REST reads' geojson=true, in WGS-84 when the site has a frame
                None => super::read_frame::in_frame(Location::clone(location), frame).to_feature(),
                Some(projection) => {
                    let Ok(feature) = projection.location_feature(Location::clone(location)) else {
                        context.unprojected.inc();
                        return None;
                    };
                    feature
                }
            }
        }
        (HubMessage::FenceEvent { tag, event }, Topic::FenceEvents) if wanted(subscription, tag) => {
            return Some(Payload::Shared(event));
        }
        (HubMessage::FenceEvent { tag, event }, Topic::FenceEventsGeojson) if wanted(subscription, tag) => {
            let geometry = event["fence_id"].as_str().and_then(|id| fences.get(id)).cloned();
            json!({ "type": "Feature", "geometry": geometry, "properties": event })
        }
        (HubMessage::Collision(news), Topic::CollisionEvents)
            if news.tags().iter().any(|tag| wanted(subscription, tag))
                && subscription
                    .trackable
                    .as_deref()
                    .is_none_or(|t| news.trackables().contains(&t)) =>
        {
            let event = news.event()?;
            let Some(projection) = &subscription.frame else {
                return Some(Payload::Collision(event));
            };
            let Ok(projected) = projection.collision(event) else {
                context.unprojected.inc();
                return None;
            };
            serde_json::to_value(projected).ok()?
        }
        (HubMessage::Proximity(proximity), Topic::ProximityUpdates) if wanted(subscription, &proximity.provider_id) => {
            return Some(Payload::Proximity(proximity));
        }
        (HubMessage::Extension { topic, event }, wanted_topic)
            if *topic == wanted_topic
                && subscription
                    .tag
                    .as_deref()
                    .is_none_or(|t| event["tag"].as_str() == Some(t)) =>
        {
            return Some(Payload::Shared(event));
        }
        _ => return None,
    };
    Some(Payload::Built(payload))
}

/// The batch's location updates as one columnar object (`rtls:positions`,
/// [`super::positions::PositionColumns`]); `None` without updates.
fn compact_positions(batch: &[Arc<HubMessage>], subscription: &Subscription) -> Option<Value> {
    let mut columns = PositionColumns::default();
    for message in batch {
        if let HubMessage::Location { tag, time_s, location } = message.as_ref() {
            if wanted(subscription, tag) {
                columns.push(tag, *time_s, location);
            }
        }
    }
    columns.finish()
}

/// The batch's track updates as the motions of the trackables they move
/// ([`moved_by`]: every trackable of the tag without `locating_rules`, with them only those
/// whose location the update now is), filtered by tag and trackable.
fn motions<'a>(
    batch: &'a [Arc<HubMessage>],
    subscription: &'a Subscription,
    context: &'a Context<'_>,
) -> impl Iterator<Item = TrackableMotion> + 'a {
    batch.iter().flat_map(move |message| {
        let mut out = Vec::new();
        if let HubMessage::Location { tag, time_s, location } = message.as_ref() {
            if wanted(subscription, tag) {
                for moved in moved_by(context.trackables, context.live, tag, *time_s, location) {
                    let trackable = &moved.trackable;
                    if moved.moves && subscription.trackable.as_deref().is_none_or(|t| t == trackable.id) {
                        let location = match &subscription.frame {
                            Some(projection) => match projection.location(Location::clone(location)) {
                                Ok(location) => location,
                                // a position the frame cannot take is not sent, and counted
                                Err(_) => {
                                    context.unprojected.inc();
                                    continue;
                                }
                            },
                            None => Location::clone(location),
                        };
                        out.push(TrackableMotion::of(trackable, location));
                    }
                }
            }
        }
        out
    })
}

/// The topics whose payloads carry an omlox `Location` (`params.crs` applies to them).
/// Whether `topic`'s payloads carry positions a subscription's `crs` / `zone_id` project.
fn carries_locations(topic: Topic) -> bool {
    matches!(
        topic,
        Topic::LocationUpdates | Topic::LocationUpdatesGeojson | Topic::TrackableMotions | Topic::CollisionEvents
    )
}

fn wanted(subscription: &Subscription, tag: &str) -> bool {
    subscription.tag.as_deref().is_none_or(|t| t == tag)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_large_batch_goes_in_frames_below_the_limit_in_order() {
        let payloads: Vec<Payload<'_>> = (0..400)
            .map(|i| Payload::Built(json!({"provider_id": format!("tag-{i:03}"), "pad": "x".repeat(200)})))
            .collect();
        let split = frames(Topic::LocationUpdates, 0, &payloads);
        assert!(split.len() > 2, "{} frames", split.len());
        let mut ids = Vec::new();
        for frame in &split {
            assert!(frame.len() <= MAX_FRAME_BYTES, "{} bytes", frame.len());
            let message: Value = serde_json::from_str(frame).unwrap();
            assert_eq!(message["event"], "message");
            assert_eq!(message["topic"], "location_updates");
            assert_eq!(message["subscription_id"], 0);
            ids.extend(
                message["payload"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| p["provider_id"].as_str().unwrap().to_string()),
            );
        }
        let expected: Vec<String> = (0..400).map(|i| format!("tag-{i:03}")).collect();
        assert_eq!(ids, expected);
        // one object over the limit goes alone, and a small batch is one frame
        let big = [Payload::Built(json!({"pad": "x".repeat(MAX_FRAME_BYTES)}))];
        assert_eq!(frames(Topic::LocationUpdates, 3, &big).len(), 1);
        assert_eq!(frames(Topic::FenceEvents, 1, &payloads[..2]).len(), 1);
    }
}
