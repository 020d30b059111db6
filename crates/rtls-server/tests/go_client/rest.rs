//! The Go client's REST half: `omlox.New(base, omlox.WithHTTPClient(token round-tripper))`.

use std::net::SocketAddr;

use reqwest::Method;
use serde_json::Value;

use super::wire::*;
use super::*;

// ---- the REST half: omlox.New(base, omlox.WithHTTPClient(token round-tripper)) ----

/// An answer as the client sees it (`sendRequestParseResponse`): `Ok(None)` for an empty body,
/// `Ok(Some(json))` for a body (still to be decoded into the response type), `Err` for a status
/// outside 200–399 (`isResponseError`) or a body that is not JSON.
pub type GoReply = Result<Option<Value>, String>;

/// The client's REST requests: `{base}` joined with the call's path (`url.JoinPath`), the
/// body JSON plus a newline, no header of the client's own; the caller's `http.Client`
/// adds the token (a round-tripper given with `WithHTTPClient`: the client has no auth option).
/// Go's transport sends `User-Agent: Go-http-client/1.1` (here too) and `Accept-Encoding: gzip`
/// (not here); reqwest adds `Accept: */*`, which means what Go's absent `Accept` means.
pub struct GoRest {
    pub http: reqwest::Client,
    pub base: String,
    pub token: &'static str,
}

impl GoRest {
    pub fn new(addr: SocketAddr, token: &'static str) -> Self {
        Self {
            http: reqwest::Client::builder().user_agent(GO_USER_AGENT).build().unwrap(),
            base: format!("http://{addr}/v2"),
            token,
        }
    }

    /// `newRequest` + `send` + `isResponseError` + `parseResponse` up to the JSON value.
    pub async fn call(&self, method: Method, path: &str, body: Option<String>) -> (u16, GoReply) {
        let mut request = self
            .http
            .request(method.clone(), format!("{}{path}", self.base))
            // the round-tripper's header: the hub's token
            .header("authorization", format!("Bearer {}", self.token));
        if let Some(body) = body {
            // json.NewEncoder(&buf).Encode(body): the JSON and a newline; no Content-Type
            request = request.body(format!("{body}\n"));
        }
        let response = tokio::time::timeout(WAIT, request.send())
            .await
            .unwrap_or_else(|_| panic!("{method} {path}: no answer in {WAIT:?}"))
            .unwrap();
        let status = response.status().as_u16();
        let text = response.text().await.unwrap();
        if !(200..=399).contains(&status) {
            return (status, Err(format!("{method} {path}: {status} {text}")));
        }
        if text.is_empty() {
            return (status, Ok(None));
        }
        let reply = serde_json::from_str(&text).map_err(|e| format!("{method} {path}: not JSON ({e}): {text}"));
        (status, reply.map(Some))
    }

    /// `sendStructuredRequestParseResponse[struct{}]`: success, and a body (if any) that
    /// `encoding/json` can put in a `struct{}` — an object or `null`.
    pub async fn call_no_result(&self, method: Method, path: &str, body: Option<String>) -> Result<u16, String> {
        let (status, reply) = self.call(method, path, body).await;
        match reply? {
            None | Some(Value::Object(_) | Value::Null) => Ok(status),
            Some(other) => Err(format!(
                "json: cannot unmarshal {other} into Go value of type struct {{}}"
            )),
        }
    }

    /// `TrackablesAPI.Create`: `POST /trackables` with the trackable.
    pub async fn create_trackable(&self, trackable: &GoTrackable<'_>) -> (u16, Result<Value, String>) {
        let (status, reply) = self.call(Method::POST, "/trackables", Some(trackable.to_json())).await;
        (
            status,
            reply.and_then(|v| v.ok_or_else(|| "no body: a nil *Trackable".to_string())),
        )
    }

    /// `TrackablesAPI.List`: `GET /trackables/summary` into `[]Trackable`.
    pub async fn list_trackables(&self) -> Result<Vec<DecodedTrackable>, String> {
        let list = self
            .call(Method::GET, "/trackables/summary", None)
            .await
            .1?
            .unwrap_or(Value::Null);
        match list {
            // parseResponseList: an empty body or null is an empty list
            Value::Null => Ok(Vec::new()),
            Value::Array(items) => items.iter().map(go_decode_trackable).collect(),
            other => Err(format!("json: cannot unmarshal {other} into []Trackable")),
        }
    }

    /// `TrackablesAPI.IDs`: `GET /trackables` into `[]uuid.UUID`.
    pub async fn trackable_ids(&self) -> Result<Vec<uuid::Uuid>, String> {
        let ids = self
            .call(Method::GET, "/trackables", None)
            .await
            .1?
            .unwrap_or(Value::Null);
        match ids {
            Value::Null => Ok(Vec::new()),
            Value::Array(items) => items.iter().map(|id| go_uuid(id, "[]")).collect(),
            other => Err(format!("json: cannot unmarshal {other} into []uuid.UUID")),
        }
    }

    /// `TrackablesAPI.Get`: `GET /trackables/{id}`.
    pub async fn get_trackable(&self, id: &uuid::Uuid) -> Result<DecodedTrackable, String> {
        let reply = self.call(Method::GET, &format!("/trackables/{id}"), None).await.1?;
        go_decode_trackable(&reply.ok_or("no body")?)
    }

    /// `TrackablesAPI.GetLocation`: `GET /trackables/{id}/location`.
    pub async fn trackable_location(&self, id: &uuid::Uuid) -> Result<DecodedLocation, String> {
        let reply = self
            .call(Method::GET, &format!("/trackables/{id}/location"), None)
            .await
            .1?;
        go_decode_location(&reply.ok_or("no body")?)
    }

    /// `TrackablesAPI.Delete`: `DELETE /trackables/{id}`.
    pub async fn delete_trackable(&self, id: &uuid::Uuid) -> Result<u16, String> {
        self.call_no_result(Method::DELETE, &format!("/trackables/{id}"), None)
            .await
    }

    /// `ProvidersAPI.Create`: `POST /providers` with the provider.
    pub async fn create_provider(&self, id: &str, name: &str) -> (u16, Result<String, String>) {
        let (status, reply) = self
            .call(Method::POST, "/providers", Some(go_provider_json(id, "uwb", name)))
            .await;
        (
            status,
            reply.and_then(|v| go_decode_provider(&v.ok_or("no body: a nil *LocationProvider")?)),
        )
    }

    /// `ProvidersAPI.UpdateLocation(location, location.ProviderID)`: `PUT
    /// /providers/{id}/location` with one location (as the client's CLI pushes each one).
    pub async fn update_location(&self, fix: &Fix) -> Result<u16, String> {
        self.call_no_result(
            Method::PUT,
            &format!("/providers/{}/location", fix.provider_id),
            Some(fix.to_json()),
        )
        .await
    }
}
