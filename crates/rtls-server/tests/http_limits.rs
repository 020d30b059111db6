//! The HTTP listener's limits (issue 22): connections per IP address and in all, idle sockets
//! closed, oversized headers refused — with real sockets, the attacker on another loopback
//! address than the user.

mod common;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::http::{Method, StatusCode};
use axum::routing::get;
use axum::Router;
use common::{call, state, READ};
use rtls_server::http::listener::{GuardedListener, HttpLimits};
use rtls_server::metrics::Metrics;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpSocket, TcpStream};

/// A tiny app behind a [`GuardedListener`] with `limits`, on a free port of 127.0.0.1.
async fn serve(limits: HttpLimits) -> (SocketAddr, Arc<Metrics>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let metrics = Arc::new(Metrics::new());
    let guarded = GuardedListener::new(listener, limits, None, Arc::clone(&metrics));
    let app = Router::new().route("/", get(|| async { "ok" }));
    tokio::spawn(async move {
        let _ = axum::serve(guarded, app).await;
    });
    (addr, metrics)
}

async fn connect_from(source: &str, addr: SocketAddr) -> TcpStream {
    let socket = TcpSocket::new_v4().expect("socket");
    socket
        .bind(format!("{source}:0").parse().unwrap())
        .expect("bind source");
    socket.connect(addr).await.expect("connect")
}

/// Sends `GET /` (keep-alive) and reads the answer's status line.
async fn get_root(stream: &mut TcpStream) -> String {
    stream
        .write_all(b"GET / HTTP/1.1\r\nhost: test\r\n\r\n")
        .await
        .expect("request");
    let mut buffer = vec![0u8; 1024];
    let n = tokio::time::timeout(Duration::from_secs(2), stream.read(&mut buffer))
        .await
        .expect("an answer in time")
        .expect("read");
    String::from_utf8_lossy(&buffer[..n])
        .lines()
        .next()
        .unwrap_or("")
        .to_string()
}

/// Whether the server closes `stream` within `within` (a read returns 0 or fails).
async fn closed_within(stream: &mut TcpStream, within: Duration) -> bool {
    let mut buffer = [0u8; 256];
    loop {
        match tokio::time::timeout(within, stream.read(&mut buffer)).await {
            Ok(Ok(0) | Err(_)) => return true,
            Ok(Ok(_)) => continue,
            Err(_) => return false,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_address_cannot_hold_more_than_its_connections_and_others_still_get_in() {
    let (addr, metrics) = serve(HttpLimits {
        max_connections: 100,
        max_connections_per_ip: 3,
        idle: Duration::from_secs(60),
    })
    .await;
    let mut held = Vec::new();
    for _ in 0..3 {
        let mut stream = connect_from("127.0.0.2", addr).await;
        assert_eq!(get_root(&mut stream).await, "HTTP/1.1 200 OK");
        held.push(stream);
    }
    let mut fourth = connect_from("127.0.0.2", addr).await;
    assert!(
        closed_within(&mut fourth, Duration::from_secs(2)).await,
        "the fourth connection of one address is closed"
    );
    let mut user = connect_from("127.0.0.1", addr).await;
    assert_eq!(get_root(&mut user).await, "HTTP/1.1 200 OK", "another address gets in");
    drop(held);
    // the address's slots come back when its connections close
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut again = connect_from("127.0.0.2", addr).await;
    assert_eq!(get_root(&mut again).await, "HTTP/1.1 200 OK");
    let text = metrics.encode().expect("metrics");
    assert!(
        text.contains("rtls_http_connections_refused_total{reason=\"per_ip\"} 1"),
        "{text}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_connections_are_closed_and_busy_ones_are_not() {
    let (addr, _) = serve(HttpLimits {
        max_connections: 100,
        max_connections_per_ip: 100,
        idle: Duration::from_millis(400),
    })
    .await;
    // a socket that never sends a request
    let mut silent = TcpStream::connect(addr).await.expect("connect");
    let opened = Instant::now();
    assert!(
        closed_within(&mut silent, Duration::from_secs(3)).await,
        "a silent socket is closed"
    );
    assert!(
        opened.elapsed() >= Duration::from_millis(350),
        "not before its idle time"
    );
    // a keep-alive socket used now and then stays open, and is closed once left idle
    let mut busy = TcpStream::connect(addr).await.expect("connect");
    for _ in 0..4 {
        assert_eq!(get_root(&mut busy).await, "HTTP/1.1 200 OK");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    assert!(
        closed_within(&mut busy, Duration::from_secs(3)).await,
        "then closed when idle"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_headers_are_refused_with_431() {
    let state = state("http-limits-headers");
    let app = rtls_server::http::router(state.clone());
    let request = axum::http::Request::builder()
        .method(Method::GET)
        .uri("/api/v1/tags")
        .header("authorization", format!("Bearer {READ}"))
        .header("x-padding", "a".repeat(20_000))
        .body(axum::body::Body::empty())
        .unwrap();
    let response = tower::ServiceExt::oneshot(app.clone(), request).await.unwrap();
    assert_eq!(response.status(), StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE);
    assert_eq!(
        call(&app, Method::GET, "/api/v1/tags", Some(READ), "").await.status,
        StatusCode::OK
    );
    state.pipeline.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_over_its_request_rate_gets_429_and_others_do_not() {
    let dir = common::temp_dir("http-limits-rate");
    let mut config = common::loopback_config(&dir, rtls_server::config::MqttMode::Off);
    config.server.max_requests_per_s_per_ip = 5;
    let running = common::serve_on_loopback(common::options(config)).await;
    let http = running.bound.http;
    let from = |source: &str| {
        reqwest::Client::builder()
            .local_address(Some(source.parse().unwrap()))
            .build()
            .unwrap()
    };
    let (greedy, polite) = (from("127.0.0.2"), from("127.0.0.1"));
    let mut limited = 0;
    let mut retry_after = None;
    for _ in 0..40 {
        let reply = greedy.get(format!("http://{http}/health")).send().await.unwrap();
        if reply.status() == StatusCode::TOO_MANY_REQUESTS {
            limited += 1;
            retry_after = reply
                .headers()
                .get("retry-after")
                .map(|v| v.to_str().unwrap().to_string());
        }
    }
    assert!(
        limited >= 20,
        "40 requests at once over 5/s (bursts of 10): {limited} limited"
    );
    assert!(retry_after.is_some_and(|s| s.parse::<u64>().is_ok_and(|s| s >= 1)));
    let reply = polite.get(format!("http://{http}/health")).send().await.unwrap();
    assert_eq!(reply.status(), StatusCode::OK, "another address is not limited");
    let metrics = common::get_text(&polite, http, "/metrics").await;
    assert_eq!(
        common::metric_value(&metrics, "rtls_http_requests_limited_total"),
        f64::from(limited)
    );
    running.stop().await;
}
