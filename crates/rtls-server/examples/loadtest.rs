//! A bounded load test of `rtls serve` on loopback: an in-process server (embedded MQTT broker,
//! SQLite in a temp dir, 2-D fix-then-filter site), publishers sending one fix per tag per
//! period over MQTT QoS 1 (each PUBACK only after the records are committed), and a WebSocket
//! client subscribed to `location_updates`. Prints one JSON line at its end:
//! `{"offered_rps", "sustained_rps", "p50_ms", "p99_ms", "sent", "acknowledged", "lost",
//! "rss_mb_start", "rss_mb_end", …}` — the sustained acknowledged records/s, the
//! ingest-to-WebSocket latency percentiles (receive time − the record's time stamp, which is
//! its send time), records sent and acknowledged (`lost`: sent, never acknowledged) and this
//! process's resident memory (server and load generator) when the measured run starts and
//! ends.
//!
//! ```text
//! cargo run --release -p rtls-server --example loadtest -- --tags 600 --rate-hz 10 --seconds 30
//! cargo run --release -p rtls-server --example loadtest -- --tags 600 --rate-hz 0 --seconds 30   # max rate
//! ```
//! `--rate-hz 0` sends as fast as the acknowledgements allow (each publisher keeps 64 batches
//! in flight).
//!
//! Against a running `rtls serve` (the soak, `scripts/soak.sh`): `--mqtt HOST:PORT --http
//! HOST:PORT` connect to it instead of starting one (`--token` its write token, `--read-token`
//! its read token for the WebSocket), `--server-pid PID` reads the server's resident memory
//! instead of this process's, `--report-s S` prints a JSON line on stderr every `S` seconds
//! (that window's acknowledged records/s, latency percentiles and resident memory; the final
//! line lists them as `windows`), and `--write-site PATH` writes the site the in-process server
//! uses (for `rtls serve --site PATH`) and exits. `--slow-publisher-s S` has the first of the
//! four publishers send each batch `S` seconds after stamping it (a gateway with a slower
//! backhaul); the final line then also gives the server's track updates, those revised and
//! the records reported late (from its `/metrics`).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use hdrhistogram::Histogram;
use rtls_engine::site::Site;
use rtls_server::auth::Tokens;
use rtls_server::config::ServerConfig;
use rtls_server::serve::{serve, Bound, ServeOptions};
use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};
use tokio_tungstenite::tungstenite::Message;

const TOKEN: &str = "loadtest-write-token";
const PUBLISHERS: usize = 4;

const SITE: &str = r#"
name = "load test"
[[readers]]
id = "A1"
position_m = [0.0, 0.0, 2.5]
technology = "uwb"
[[zones]]
id = "east"
name = "East half"
kind = "area-of-interest"
shape = { type = "box", min_m = [50.0, 0.0, -10.0], max_m = [100.0, 100.0, 10.0] }
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "ekf"
gate_probability = 0.999
acceleration_noise_std_mps2 = 0.5
coast_timeout_s = 10.0
delete_timeout_s = 300.0
initiation = { confirm_updates = 2, within_s = 5.0 }
reorder_window_s = 0.0
rewind_horizon_s = 2.0
output_interval_s = 0.5
dimensions = 2
"#;

/// A WebSocket `message`: only what the latency needs.
#[derive(serde::Deserialize)]
struct Frame<'a> {
    #[serde(borrow, default)]
    payload: Vec<Stamp<'a>>,
}

/// A payload's time stamp (a `Location`'s `timestamp_generated`).
#[derive(serde::Deserialize)]
struct Stamp<'a> {
    #[serde(borrow, default)]
    timestamp_generated: Option<std::borrow::Cow<'a, str>>,
}

struct Args {
    tags: usize,
    rate_hz: f64,
    seconds: f64,
    /// An external server's broker and HTTP addresses (both or neither).
    external: Option<(SocketAddr, SocketAddr)>,
    token: String,
    read_token: Option<String>,
    server_pid: Option<u32>,
    report_s: Option<f64>,
    write_site: Option<std::path::PathBuf>,
    /// How long after stamping the first publisher sends each batch, s (a sender with a slower
    /// backhaul than the others).
    slow_publisher_s: f64,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        tags: 600,
        rate_hz: 10.0,
        seconds: 20.0,
        external: None,
        token: TOKEN.into(),
        read_token: None,
        server_pid: None,
        report_s: None,
        write_site: None,
        slow_publisher_s: 0.0,
    };
    let (mut mqtt, mut http) = (None, None);
    let argv: Vec<String> = std::env::args().skip(1).collect();
    for pair in argv.chunks(2) {
        let value = pair.get(1).map_or("", String::as_str);
        let bad = |what: &str| format!("{} {value:?}: expected {what}", pair[0]);
        match pair[0].as_str() {
            "--tags" => {
                args.tags = value
                    .parse()
                    .ok()
                    .filter(|&n| n > 0)
                    .ok_or_else(|| bad("a tag count ≥ 1"))?
            }
            "--rate-hz" => {
                args.rate_hz = value
                    .parse()
                    .ok()
                    .filter(|r: &f64| r.is_finite() && *r >= 0.0)
                    .ok_or_else(|| bad("a rate ≥ 0 Hz (0: maximum rate)"))?;
            }
            "--seconds" => {
                args.seconds = value
                    .parse()
                    .ok()
                    .filter(|s: &f64| s.is_finite() && *s > 0.0)
                    .ok_or_else(|| bad("a duration > 0 s"))?;
            }
            "--mqtt" => mqtt = Some(value.parse().map_err(|_| bad("HOST:PORT"))?),
            "--http" => http = Some(value.parse().map_err(|_| bad("HOST:PORT"))?),
            "--token" => args.token = value.to_string(),
            "--read-token" => args.read_token = Some(value.to_string()),
            "--server-pid" => args.server_pid = Some(value.parse().map_err(|_| bad("a process id"))?),
            "--report-s" => {
                args.report_s = Some(
                    value
                        .parse()
                        .ok()
                        .filter(|s: &f64| s.is_finite() && *s >= 1.0)
                        .ok_or_else(|| bad("a period ≥ 1 s"))?,
                )
            }
            "--write-site" => args.write_site = Some(value.into()),
            "--slow-publisher-s" => {
                args.slow_publisher_s = value
                    .parse()
                    .ok()
                    .filter(|s: &f64| (0.0..=60.0).contains(s))
                    .ok_or_else(|| bad("a delay of 0 to 60 s"))?;
            }
            other => {
                return Err(format!(
                    "unknown argument {other}; use --tags N, --rate-hz HZ, --seconds S, --mqtt HOST:PORT \
                     --http HOST:PORT [--token T] [--read-token T] [--server-pid PID], --report-s S, \
                     --write-site PATH, --slow-publisher-s S"
                ))
            }
        }
    }
    args.external = match (mqtt, http) {
        (Some(mqtt), Some(http)) => Some((mqtt, http)),
        (None, None) => None,
        _ => return Err("--mqtt and --http go together (an external server)".into()),
    };
    Ok(args)
}

fn unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// Latencies (ms) in an HDR histogram: 3 significant digits from 1 µs to an hour.
fn latency_histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 3_600_000_000, 3).expect("histogram bounds")
}

/// The `p` quantile of `histogram` in ms (one decimal), `None` when empty.
fn quantile_ms(histogram: &Histogram<u64>, p: f64) -> Option<f64> {
    (!histogram.is_empty()).then(|| (histogram.value_at_quantile(p) as f64 / 100.0).round() / 10.0)
}

/// The latencies measured: the whole run's and the current report window's.
struct Latencies {
    total: Histogram<u64>,
    window: Histogram<u64>,
}

impl Latencies {
    fn record(&mut self, latency_s: f64) {
        // µs, at least 1 (a clock a hair behind the sender's)
        let us = (latency_s * 1e6).round().clamp(1.0, 3_600_000_000.0) as u64;
        self.total.saturating_record(us);
        self.window.saturating_record(us);
    }
}

/// An in-process server's task.
type ServerTask = tokio::task::JoinHandle<Result<(), rtls_server::serve::ServeError>>;

/// The server started in this process, or the addresses of one already running.
struct Target {
    mqtt: SocketAddr,
    http: SocketAddr,
    /// The in-process server's task and its stop signal.
    own: Option<(ServerTask, tokio::sync::oneshot::Sender<()>)>,
    dir: Option<std::path::PathBuf>,
}

async fn start_target(args: &Args) -> Target {
    if let Some((mqtt, http)) = args.external {
        return Target {
            mqtt,
            http,
            own: None,
            dir: None,
        };
    }
    let dir = std::env::temp_dir().join(format!("rtls-loadtest-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut config = ServerConfig::default();
    config.server.http = "127.0.0.1:0".parse().unwrap();
    config.mqtt.listen = "127.0.0.1:0".parse().unwrap();
    config.server.db = format!("sqlite:{}", dir.join("rtls.db").display());
    let site = Site::from_toml_str(SITE, "loadtest-site.toml").unwrap();
    let options = ServeOptions {
        config,
        site,
        site_text: SITE.into(),
        tokens: Tokens::new(TOKEN, None),
        trackables: Vec::new(),
        floor_plans: rtls_server::http::plans::FloorPlans::default(),
        feed: None,
    };
    let (bound_tx, bound_rx) = tokio::sync::oneshot::channel::<Bound>();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(serve(
        options,
        move |bound| {
            let _ = bound_tx.send(bound);
        },
        async move {
            let _ = stop_rx.await;
        },
    ));
    let bound = bound_rx.await.expect("server started");
    Target {
        mqtt: bound.mqtt.expect("embedded broker"),
        http: bound.http,
        own: Some((server, stop_tx)),
        dir: Some(dir),
    }
}

#[tokio::main]
async fn main() {
    let args = match parse_args() {
        Ok(args) => args,
        Err(message) => {
            eprintln!("error: {message}");
            std::process::exit(2);
        }
    };
    if let Some(path) = &args.write_site {
        std::fs::write(path, SITE).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
        return;
    }
    let target = start_target(&args).await;
    let resident = || resident_mb(args.server_pid);

    // the WebSocket client: latency of every location update
    let query = args
        .read_token
        .as_ref()
        .map_or(String::new(), |t| format!("?token={t}"));
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{}/v2/ws/socket{query}", target.http))
        .await
        .unwrap();
    futures_util::SinkExt::send(
        &mut socket,
        Message::Text(r#"{"event":"subscribe","topic":"location_updates"}"#.into()),
    )
    .await
    .unwrap();
    let latencies = Arc::new(Mutex::new(Latencies {
        total: latency_histogram(),
        window: latency_histogram(),
    }));
    let measuring = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let ws_task = {
        let latencies = Arc::clone(&latencies);
        let measuring = Arc::clone(&measuring);
        tokio::spawn(async move {
            while let Some(Ok(message)) = socket.next().await {
                let Message::Text(text) = message else { continue };
                let received = unix_s();
                // only the time stamps are read (a typed, borrowing parse: the client's own cost
                // is kept out of the latency it measures, as far as it can be)
                let frame: Frame<'_> = serde_json::from_str(&text).unwrap();
                for location in &frame.payload {
                    let Some(stamp) = location.timestamp_generated.as_deref() else {
                        continue;
                    };
                    let t = rtls_server::omlox::time::parse_timestamp(stamp, "t").unwrap();
                    if measuring.load(Ordering::Relaxed) {
                        latencies.lock().unwrap().record(received - t);
                    }
                }
            }
        })
    };

    // publishers: tags split among them; one batch = one fix per tag of the publisher
    let acked = Arc::new(AtomicU64::new(0));
    let sent = Arc::new(AtomicU64::new(0));
    let started = Instant::now();
    let warmup = Duration::from_secs(2);
    let run = Duration::from_secs_f64(args.seconds);
    let mut publishers = Vec::new();
    for p in 0..PUBLISHERS {
        let tags: Vec<usize> = (0..args.tags).filter(|t| t % PUBLISHERS == p).collect();
        let (acked, sent) = (Arc::clone(&acked), Arc::clone(&sent));
        let (rate_hz, slow_publisher_s) = (args.rate_hz, args.slow_publisher_s);
        let (mqtt, token) = (target.mqtt, args.token.clone());
        publishers.push(tokio::spawn(async move {
            let mut options = MqttOptions::new(format!("loadtest-{p}"), mqtt.ip().to_string(), mqtt.port());
            options.set_credentials("load", token);
            options.set_inflight(64);
            options.set_max_packet_size(1 << 20, 1 << 20);
            let (client, mut event_loop) = AsyncClient::new(options, 128);
            let per_batch = tags.len() as u64;
            let acks = tokio::spawn(async move {
                while let Ok(event) = event_loop.poll().await {
                    if let Event::Incoming(Packet::PubAck(_)) = event {
                        acked.fetch_add(per_batch, Ordering::Relaxed);
                    }
                }
            });
            let period = (rate_hz > 0.0).then(|| Duration::from_secs_f64(1.0 / rate_hz));
            let mut next = Instant::now();
            while started.elapsed() < warmup + run {
                let t = unix_s();
                let mut payload = String::with_capacity(tags.len() * 120);
                for &tag in &tags {
                    // each tag walks a circle of 20 m radius at ~1 m/s
                    let phase = t / 20.0 + tag as f64;
                    let (x, y) = (50.0 + 20.0 * phase.cos(), 50.0 + 20.0 * phase.sin());
                    payload.push_str(&format!(
                        "{{\"t\": {t:.4}, \"tag\": \"tag-{tag:04}\", \"kind\": \"fix\", \"position_m\": [{x:.3}, {y:.3}], \"covariance_m2\": [0.09, 0, 0, 0.09]}}\n"
                    ));
                }
                if p == 0 && slow_publisher_s > 0.0 {
                    // a slower backhaul: the batch leaves slow_publisher_s after its stamp
                    let client = client.clone();
                    tokio::spawn(async move {
                        tokio::time::sleep(Duration::from_secs_f64(slow_publisher_s)).await;
                        let _ = client.publish("rtls/v1/measurements/load", QoS::AtLeastOnce, false, payload).await;
                    });
                } else if client.publish("rtls/v1/measurements/load", QoS::AtLeastOnce, false, payload).await.is_err() {
                    break;
                }
                sent.fetch_add(per_batch, Ordering::Relaxed);
                if let Some(period) = period {
                    next += period;
                    tokio::time::sleep_until(next.into()).await;
                }
            }
            tokio::time::sleep(Duration::from_secs_f64(2.0 + slow_publisher_s)).await;
            let _ = client.disconnect().await;
            acks.abort();
        }));
    }
    tokio::time::sleep(warmup).await;
    measuring.store(true, Ordering::Relaxed);
    let rss_mb_start = resident();
    let acked_at_start = acked.load(Ordering::Relaxed);
    let measure_start = Instant::now();
    let mut windows = Vec::new();
    if let Some(report_s) = args.report_s {
        // one JSON line per window on stderr, and the list at the end
        let (mut window_start, mut acked_before) = (measure_start, acked_at_start);
        let period = Duration::from_secs_f64(report_s);
        for k in 1..=(args.seconds / report_s).floor() as u32 {
            tokio::time::sleep_until((measure_start + period * k).into()).await;
            let acked_now = acked.load(Ordering::Relaxed);
            let seconds = window_start.elapsed().as_secs_f64();
            let window = std::mem::replace(&mut latencies.lock().unwrap().window, latency_histogram());
            let line = serde_json::json!({
                "t_s": (measure_start.elapsed().as_secs_f64()).round(),
                "acknowledged_rps": ((acked_now - acked_before) as f64 / seconds).round(),
                "p50_ms": quantile_ms(&window, 0.5),
                "p99_ms": quantile_ms(&window, 0.99),
                "location_updates": window.len(),
                "rss_mb": resident(),
            });
            eprintln!("{line}");
            windows.push(line);
            (window_start, acked_before) = (Instant::now(), acked_now);
        }
    }
    tokio::time::sleep_until((measure_start + run).into()).await;
    let acked_in_run = acked.load(Ordering::Relaxed) - acked_at_start;
    let elapsed = measure_start.elapsed().as_secs_f64();
    measuring.store(false, Ordering::Relaxed);
    let rss_mb_end = resident();
    for publisher in publishers {
        let _ = publisher.await;
    }
    let total = std::mem::replace(&mut latencies.lock().unwrap().total, latency_histogram());
    let counters = server_counters(target.http, &args.token).await;
    let offered = if args.rate_hz > 0.0 {
        Some(args.tags as f64 * args.rate_hz)
    } else {
        None
    };
    // the publishers waited 2 s after their last batch for its acknowledgements
    let (sent, acknowledged) = (sent.load(Ordering::Relaxed), acked.load(Ordering::Relaxed));
    let report = serde_json::json!({
        "offered_rps": offered,
        "sustained_rps": (acked_in_run as f64 / elapsed).round(),
        "p50_ms": quantile_ms(&total, 0.5),
        "p99_ms": quantile_ms(&total, 0.99),
        "sent": sent,
        "acknowledged": acknowledged,
        "lost": sent.saturating_sub(acknowledged),
        "rss_mb_start": rss_mb_start,
        "rss_mb_end": rss_mb_end,
        "tags": args.tags,
        "rate_hz": args.rate_hz,
        "location_updates_measured": total.len(),
        "measured_s": elapsed,
        "windows": windows,
        "slow_publisher_s": args.slow_publisher_s,
        "track_updates": counters.as_ref().map(|c| c.0),
        "track_updates_revised": counters.as_ref().map(|c| c.1),
        "records_late": counters.as_ref().map(|c| c.2),
    });
    println!("{report}");
    if let Some((server, stop)) = target.own {
        let _ = stop.send(());
        let _ = server.await;
    }
    ws_task.abort();
    if let Some(dir) = target.dir {
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// The server's `rtls_track_updates_total`, `rtls_track_updates_revised_total` and its
/// records reported late (`rtls_records_unused_total{event="late"}`, summed over kinds), from
/// `GET /metrics`; `None` when it cannot be read.
async fn server_counters(http: SocketAddr, token: &str) -> Option<(f64, f64, f64)> {
    let text = reqwest::Client::new()
        .get(format!("http://{http}/metrics"))
        .bearer_auth(token)
        .send()
        .await
        .ok()?
        .text()
        .await
        .ok()?;
    let value = |line: &str| line.rsplit(' ').next().and_then(|v| v.parse::<f64>().ok());
    let mut counters = (0.0, 0.0, 0.0);
    for line in text.lines() {
        if line.starts_with("rtls_track_updates_total ") {
            counters.0 = value(line)?;
        } else if line.starts_with("rtls_track_updates_revised_total ") {
            counters.1 = value(line)?;
        } else if line.starts_with("rtls_records_unused_total{") && line.contains("event=\"late\"") {
            counters.2 += value(line)?;
        }
    }
    Some(counters)
}

/// Resident memory (MB) of process `pid`, or of this process (server and load generator
/// together) without one, from `/proc/…/status` (`VmRSS`); `None` where there is no procfs.
fn resident_mb(pid: Option<u32>) -> Option<f64> {
    let path = pid.map_or_else(|| "/proc/self/status".to_string(), |pid| format!("/proc/{pid}/status"));
    let status = std::fs::read_to_string(path).ok()?;
    let kb: f64 = status
        .lines()
        .find_map(|line| line.strip_prefix("VmRSS:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some((kb / 1024.0 * 10.0).round() / 10.0)
}
