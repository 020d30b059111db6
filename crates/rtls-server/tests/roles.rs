//! Roles and the audit log (issue 22 item 3): tokens issued at run time with a role, what each
//! role may do on every kind of route, revocation without a restart, only hashes at rest, issued
//! tokens surviving a restart, and an audit entry for each change with the credential that made
//! it; over MQTT, integrators and admins publish, operators and viewers only read, and a
//! revoked token is refused at CONNECT.

mod common;

use axum::http::{Method, StatusCode};
use common::{call, state, walk, READ, WRITE};
use rtls_server::config::MqttMode;
use serde_json::{json, Value};

const FENCE: &str = r#"{"region": {"type": "Polygon", "coordinates": [[[1, 1], [3, 1], [3, 3], [1, 3], [1, 1]]]}, "crs": "local", "name": "bay"}"#;

async fn issue(app: &axum::Router, name: &str, role: &str) -> (String, String) {
    let reply = call(
        app,
        Method::POST,
        "/api/v1/tokens",
        Some(WRITE),
        &json!({"name": name, "role": role}).to_string(),
    )
    .await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let body = reply.json();
    (
        body["token"].as_str().unwrap().to_string(),
        body["id"].as_str().unwrap().to_string(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_role_does_its_own_work_and_every_change_is_audited() {
    let state = state("roles-matrix");
    let app = rtls_server::http::router(state.clone());
    let (viewer, _) = issue(&app, "wall-screen", "viewer").await;
    let (operator, operator_id) = issue(&app, "dispatcher-3", "operator").await;
    let (integrator, _) = issue(&app, "gateway-north", "integrator").await;
    let trackable = r#"{"id": "2f0cbd70-6f1e-4bb0-9a3a-9d3c3e1a3a11", "name": "forklift", "type": "omlox"}"#;
    let records = walk("miner-1", 1000.0, 2.0);
    // (method, path, body, [viewer, operator, integrator, admin] expected statuses)
    let cases: Vec<(Method, &str, &str, [StatusCode; 4])> = vec![
        (Method::GET, "/api/v1/tags", "", [StatusCode::OK; 4]),
        (
            Method::POST,
            "/api/v1/measurements",
            &records,
            [
                StatusCode::FORBIDDEN,
                StatusCode::FORBIDDEN,
                StatusCode::OK,
                StatusCode::OK,
            ],
        ),
        (
            Method::POST,
            "/api/v1/alarms/no-such-alarm/acknowledge",
            "",
            [
                StatusCode::FORBIDDEN,
                StatusCode::NOT_FOUND,
                StatusCode::FORBIDDEN,
                StatusCode::NOT_FOUND,
            ],
        ),
        (
            Method::GET,
            "/api/v1/tokens",
            "",
            [
                StatusCode::FORBIDDEN,
                StatusCode::FORBIDDEN,
                StatusCode::FORBIDDEN,
                StatusCode::OK,
            ],
        ),
    ];
    let tokens = [viewer.as_str(), operator.as_str(), integrator.as_str(), WRITE];
    for (method, path, body, expected) in &cases {
        for (token, want) in tokens.iter().zip(expected) {
            let reply = call(&app, method.clone(), path, Some(token), body).await;
            assert_eq!(reply.status, *want, "{method} {path} with {token}: {}", reply.text());
        }
    }
    // zones: operators (and admins) only
    for token in [viewer.as_str(), integrator.as_str()] {
        let reply = call(&app, Method::POST, "/v2/fences", Some(token), FENCE).await;
        assert_eq!(reply.status, StatusCode::FORBIDDEN, "{}", reply.text());
    }
    let reply = call(&app, Method::POST, "/v2/fences", Some(&operator), FENCE).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());
    let fence_id = reply.json()["id"].as_str().unwrap().to_string();
    // trackables: integrators (and admins) only
    for token in [viewer.as_str(), operator.as_str()] {
        let reply = call(&app, Method::POST, "/v2/trackables", Some(token), trackable).await;
        assert_eq!(reply.status, StatusCode::FORBIDDEN, "{}", reply.text());
    }
    let reply = call(&app, Method::POST, "/v2/trackables", Some(&integrator), trackable).await;
    assert_eq!(reply.status, StatusCode::CREATED, "{}", reply.text());

    // revoked: refused at once, nothing restarted
    let revoke_path = format!("/api/v1/tokens/{operator_id}");
    let reply = call(&app, Method::DELETE, &revoke_path, Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NO_CONTENT);
    let reply = call(&app, Method::GET, "/api/v1/tags", Some(&operator), "").await;
    assert_eq!(reply.status, StatusCode::FORBIDDEN, "a revoked token reads nothing");
    let reply = call(&app, Method::DELETE, &revoke_path, Some(WRITE), "").await;
    assert_eq!(reply.status, StatusCode::NOT_FOUND, "revoked once");

    // the list shows no secret; the store keeps only hashes
    let listed = call(&app, Method::GET, "/api/v1/tokens", Some(WRITE), "").await.json();
    let listed = listed.as_array().unwrap();
    assert_eq!(listed.len(), 2, "{listed:?}");
    assert!(listed
        .iter()
        .all(|t| t.get("token").is_none() && t.get("sha256").is_none()));
    let stored = format!("{:?}", state.tokens.issued());
    assert!(
        !stored.contains(&viewer) && !stored.contains(&integrator),
        "secrets are not kept"
    );

    // the audit log: who changed what
    let audit = call(&app, Method::GET, "/api/v1/events?type=audit", Some(READ), "")
        .await
        .json();
    let entries: Vec<(String, String, String)> = audit
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["action"].as_str().unwrap().to_string(),
                e["by"].as_str().unwrap().to_string(),
                e["target"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let has = |action: &str, by: &str, target: &str| {
        entries
            .iter()
            .any(|(a, b, t)| a == action && b == by && t.contains(target))
    };
    assert!(has("token-issued", "write-token", "dispatcher-3"), "{entries:?}");
    assert!(has("fence-created", "dispatcher-3", &fence_id), "{entries:?}");
    assert!(has("trackable-created", "gateway-north", "2f0cbd70"), "{entries:?}");
    assert!(has("token-revoked", "write-token", "dispatcher-3"), "{entries:?}");
    // a bad role or name is refused with the field
    let reply = call(
        &app,
        Method::POST,
        "/api/v1/tokens",
        Some(WRITE),
        r#"{"name": "x", "role": "superuser"}"#,
    )
    .await;
    assert_eq!(reply.status, StatusCode::BAD_REQUEST, "{}", reply.text());
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn issued_tokens_survive_a_restart_and_reads_can_be_closed() {
    let dir = common::temp_dir("roles-restart");
    let config = common::loopback_config(&dir, MqttMode::Off);
    let client = reqwest::Client::new();
    let running = common::serve_on_loopback(common::options(config.clone())).await;
    let http = running.bound.http;
    let (token, _) = issue_over_http(&client, http, "wall-screen", "viewer").await;
    running.stop().await;

    // the same database, no read token, reads closed: only credentials read
    let mut options = common::options(config);
    options.tokens = rtls_server::auth::Tokens::new(WRITE, None).with_open_reads(false);
    let running = common::serve_on_loopback(options).await;
    let http = running.bound.http;
    let status = |token: Option<String>| {
        let client = client.clone();
        async move {
            let mut request = client.get(format!("http://{http}/api/v1/tags"));
            if let Some(token) = token {
                request = request.bearer_auth(token);
            }
            request.send().await.unwrap().status()
        }
    };
    assert_eq!(
        status(Some(token)).await,
        StatusCode::OK,
        "the issued token survived the restart"
    );
    assert_eq!(status(None).await, StatusCode::UNAUTHORIZED, "reads need a credential");
    running.stop().await;
}

/// Issues a token named `name` with `role` through a running server: its secret and id.
async fn issue_over_http(
    client: &reqwest::Client,
    http: std::net::SocketAddr,
    name: &str,
    role: &str,
) -> (String, String) {
    let body: Value = client
        .post(format!("http://{http}/api/v1/tokens"))
        .bearer_auth(WRITE)
        .json(&json!({"name": name, "role": role}))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    (
        body["token"].as_str().unwrap().to_string(),
        body["id"].as_str().unwrap().to_string(),
    )
}

/// Connects to the broker at `mqtt` with `password`, publishes one record at QoS 1 and says
/// what came back: `Ok(true)` PUBACK, `Ok(false)` the connection closed, `Err` refused at
/// CONNECT.
async fn mqtt_publish(mqtt: std::net::SocketAddr, client_id: &str, password: &str) -> Result<bool, String> {
    use rumqttc::{AsyncClient, ConnectionError, Event, MqttOptions, Packet, QoS};
    let mut options = MqttOptions::new(client_id, mqtt.ip().to_string(), mqtt.port());
    options.set_credentials("role-test", password);
    let (client, mut events) = AsyncClient::new(options, 8);
    let line = format!(
        r#"{{"t": {:.3}, "tag": "mqtt-role", "kind": "fix", "position_m": [5.0, 5.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#,
        rtls_server::pipeline::unix_s()
    );
    client
        .publish("rtls/v1/measurements/role-test", QoS::AtLeastOnce, false, line)
        .await
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    while std::time::Instant::now() < deadline {
        match tokio::time::timeout(std::time::Duration::from_secs(5), events.poll()).await {
            Ok(Ok(Event::Incoming(Packet::PubAck(_)))) => return Ok(true),
            Ok(Ok(_)) => {}
            Ok(Err(ConnectionError::ConnectionRefused(code))) => return Err(format!("{code:?}")),
            Ok(Err(_)) | Err(_) => return Ok(false),
        }
    }
    Ok(false)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_mqtt_integrators_publish_others_only_read_and_revoked_tokens_are_refused() {
    let dir = common::temp_dir("roles-mqtt");
    let config = common::loopback_config(&dir, MqttMode::Embedded);
    let running = common::serve_on_loopback(common::options(config)).await;
    let (http, mqtt) = (running.bound.http, running.bound.mqtt.unwrap());
    let client = reqwest::Client::new();
    let (integrator, integrator_id) = issue_over_http(&client, http, "gateway-north", "integrator").await;
    let (operator, _) = issue_over_http(&client, http, "dispatcher-3", "operator").await;
    assert_eq!(
        mqtt_publish(mqtt, "gw-north", &integrator).await,
        Ok(true),
        "an integrator publishes"
    );
    assert_eq!(
        mqtt_publish(mqtt, "gw-admin", WRITE).await,
        Ok(true),
        "an admin publishes"
    );
    assert_eq!(
        mqtt_publish(mqtt, "dispatch", &operator).await,
        Ok(false),
        "an operator's publish closes its connection"
    );
    assert_eq!(mqtt_publish(mqtt, "wall", READ).await, Ok(false), "so does a viewer's");
    let revoked = client
        .delete(format!("http://{http}/api/v1/tokens/{integrator_id}"))
        .bearer_auth(WRITE)
        .send()
        .await
        .unwrap();
    assert_eq!(revoked.status(), StatusCode::NO_CONTENT);
    assert_eq!(
        mqtt_publish(mqtt, "gw-north-2", &integrator).await,
        Err("BadUserNamePassword".to_string()),
        "a revoked token is refused at CONNECT"
    );
    running.stop().await;
}
