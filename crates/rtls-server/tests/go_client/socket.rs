//! The Go client's WebSocket half: `Client.Connect`, `Subscribe`, `readLoop`, `routeMessage`,
//! `pingLoop`.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

use super::wire::*;
use super::*;

// ---- the WebSocket half: Client.Connect, Subscribe, readLoop, routeMessage, pingLoop ----

pub type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A subscription as the client files it.
#[derive(Debug, Clone)]
pub struct GoSubscription {
    pub topic: String,
    /// The id the hub's `subscribed` gave, which the client reads and then drops.
    pub hub_id: i64,
}

/// The WebSocket wrapper as `readLoop` decodes it (`encoding/json` into the unexported
/// `wrapperObject`, which embeds `WebsocketError` and `WrapperObject`: member names matched
/// without regard to case; a frame that does not decode is skipped).
#[derive(Debug)]
pub struct GoWrapper {
    pub event: String,
    pub topic: String,
    /// 0 when absent.
    pub subscription_id: i64,
    pub payload: Vec<Value>,
    pub code: i64,
}

pub const EVENTS: [&str; 6] = [
    "message",
    "subscribe",
    "subscribed",
    "unsubscribe",
    "unsubscribed",
    "error",
];

pub fn go_decode_wrapper(text: &str) -> Result<GoWrapper, String> {
    let value: Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    let object = value.as_object().ok_or("not an object")?;
    let member = |name: &str| {
        object
            .iter()
            .filter(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v)
            .next_back()
            .filter(|v| !v.is_null())
    };
    // Event.UnmarshalJSON: a string naming one of the six events
    let event = member("event")
        .map_or("", |v| v.as_str().unwrap_or("\u{0}"))
        .to_string();
    if !EVENTS.contains(&event.as_str()) {
        return Err(format!("unsuported websocket event type: {}", value["event"]));
    }
    let topic = member("topic").map_or(Ok(""), |v| go_string(v, "topic"))?.to_string();
    let subscription_id = member("subscription_id").map_or(Ok(0), |v| go_int(v, "subscription_id"))?;
    let code = member("code").map_or(Ok(0), |v| go_int(v, "code"))?;
    if let Some(description) = member("description") {
        go_string(description, "description")?;
    }
    let payload = match member("payload") {
        None => Vec::new(),
        Some(Value::Array(items)) => items.clone(),
        Some(other) => return Err(format!("payload: not an array: {other}")),
    };
    // Parameters is a map[string]string
    if let Some(params) = member("params") {
        let params = params.as_object().ok_or("params: not an object")?;
        for (name, value) in params {
            if !(value.is_string() || value.is_null()) {
                return Err(format!("params.{name}: not a string: {value}"));
            }
        }
    }
    Ok(GoWrapper {
        event,
        topic,
        subscription_id,
        payload,
        code,
    })
}

/// A `message` as the client's reader handles it.
#[derive(Debug)]
pub struct Routed {
    pub topic: String,
    /// As the hub wrote it (0 when absent).
    pub subscription_id: i64,
    /// The subscription `routeMessage` hands it to (`subs[subscription_id]`), if any.
    pub by_client: Option<String>,
    /// The subscription the hub meant (the id its `subscribed` gave).
    pub by_hub_id: Option<String>,
    pub payload: Vec<Value>,
}

/// One `omlox.Client` connected to the hub's WebSocket.
pub struct GoSocket {
    pub socket: Socket,
    /// `Client.subs`: every subscription is filed under 0 (`sid: 0` in `subscribe`), so a
    /// second one replaces the first.
    pub subs: HashMap<i64, GoSubscription>,
    /// Text frames read while waiting for something else (a pong), still to be handled.
    pub backlog: Vec<String>,
    /// The largest text frame read (nhooyr closes the connection beyond [`GO_READ_LIMIT`]).
    pub largest_frame: usize,
    /// Frames `readLoop` would have skipped (they do not decode as a wrapper).
    pub undecodable: Vec<String>,
}

impl GoSocket {
    /// `Client.Connect`: dials `{base}/ws/socket` (`ws` for `http`) through the caller's
    /// `http.Client`, so with the round-tripper's token header; no subprotocol, no compression
    /// (nhooyr v1.8.10's default), and the answer must name neither (`verifyServerResponse`).
    pub async fn connect(addr: SocketAddr, token: &str) -> Self {
        let mut request = format!("ws://{addr}/v2/ws/socket").into_client_request().unwrap();
        let headers = request.headers_mut();
        headers.insert("authorization", format!("Bearer {token}").parse().unwrap());
        headers.insert("user-agent", GO_USER_AGENT.parse().unwrap());
        let (socket, response) = tokio::time::timeout(WAIT, tokio_tungstenite::connect_async(request))
            .await
            .expect("the WebSocket handshake in time")
            .unwrap();
        assert_eq!(response.status().as_u16(), 101);
        for refused in ["sec-websocket-protocol", "sec-websocket-extensions"] {
            assert!(
                response.headers().get(refused).is_none(),
                "nhooyr's dial refuses an answer with {refused}: {:?}",
                response.headers()
            );
        }
        Self {
            socket,
            subs: HashMap::new(),
            backlog: Vec::new(),
            largest_frame: 0,
            undecodable: Vec::new(),
        }
    }

    /// The next text frame (pings are answered by tungstenite as nhooyr answers them).
    pub async fn next_text(&mut self, deadline: tokio::time::Instant) -> Option<String> {
        if !self.backlog.is_empty() {
            return Some(self.backlog.remove(0));
        }
        loop {
            let frame = tokio::time::timeout_at(deadline, self.socket.next()).await.ok()??;
            match frame.expect("the WebSocket stays open") {
                Message::Text(text) => {
                    self.largest_frame = self.largest_frame.max(text.len());
                    return Some(text.to_string());
                }
                Message::Close(close) => panic!("the hub closed the WebSocket: {close:?}"),
                // binary frames are skipped (readLoop: "assumed that messages can only be text")
                _ => {}
            }
        }
    }

    /// `Client.Subscribe(ctx, topic)` without parameters: writes `{"event":"subscribe",
    /// "topic":…}` (easyjson drops the empty `subscription_id`, `payload` and `params`), waits
    /// for the next `subscribed` (or an `error` of code 10001, 10002, 10004 or 10005), and
    /// files the subscription under id 0. Gives the id the hub assigned.
    pub async fn subscribe(&mut self, topic: &str) -> Result<i64, String> {
        let request = format!("{{\"event\":\"subscribe\",\"topic\":{}}}", go_str(topic));
        self.socket.send(Message::Text(request.into())).await.unwrap();
        let deadline = tokio::time::Instant::now() + WAIT;
        loop {
            let text = self
                .next_text(deadline)
                .await
                .ok_or_else(|| format!("no `subscribed` for {topic} in {WAIT:?}"))?;
            let Ok(wrapper) = go_decode_wrapper(&text) else {
                self.undecodable.push(text);
                continue;
            };
            match wrapper.event.as_str() {
                "subscribed" => {
                    // sid: 0 — "BUG: deephub doesn't return the sid in subsequent messages"
                    self.subs.insert(
                        0,
                        GoSubscription {
                            topic: topic.to_string(),
                            hub_id: wrapper.subscription_id,
                        },
                    );
                    return Ok(wrapper.subscription_id);
                }
                "error" if [10001, 10002, 10004, 10005].contains(&wrapper.code) => {
                    return Err(format!("subscription refused: {text}"));
                }
                // anything else before the confirmation is routed (and here: not expected)
                _ => self.backlog.push(text),
            }
        }
    }

    /// One round of `pingLoop` (every 9 s there; once here): `Conn.Ping` sends the ping
    /// counter as payload and waits up to `pongWait` (10 s) for the pong with it.
    pub async fn ping(&mut self) {
        self.socket.send(Message::Ping(b"1".to_vec().into())).await.unwrap();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
        loop {
            let frame = tokio::time::timeout_at(deadline, self.socket.next())
                .await
                .expect("the pong within pongWait (10 s): pingLoop would end the client")
                .expect("the WebSocket stays open")
                .unwrap();
            match frame {
                Message::Pong(payload) => {
                    assert_eq!(&payload[..], b"1", "the pong echoes the ping's payload");
                    return;
                }
                Message::Text(text) => {
                    self.largest_frame = self.largest_frame.max(text.len());
                    self.backlog.push(text.to_string());
                }
                _ => {}
            }
        }
    }

    /// The next `message` as `readLoop` → `handleMessage` → `routeMessage` handle it; `None`
    /// when nothing comes before `deadline`.
    pub async fn next_message(&mut self, deadline: tokio::time::Instant) -> Option<Routed> {
        loop {
            let text = self.next_text(deadline).await?;
            let wrapper = match go_decode_wrapper(&text) {
                Ok(wrapper) => wrapper,
                Err(e) => {
                    self.undecodable.push(format!("{e}: {text}"));
                    continue;
                }
            };
            if wrapper.event != "message" {
                // subscribed / error / unsubscribed: none expected once subscribed
                self.undecodable.push(format!("unexpected {}: {text}", wrapper.event));
                continue;
            }
            let by_client = self.subs.get(&wrapper.subscription_id).map(|s| s.topic.clone());
            let by_hub_id = self
                .subs
                .values()
                .find(|s| s.hub_id == wrapper.subscription_id)
                .map(|s| s.topic.clone());
            return Some(Routed {
                topic: wrapper.topic,
                subscription_id: wrapper.subscription_id,
                by_client,
                by_hub_id,
                payload: wrapper.payload,
            });
        }
    }
}
