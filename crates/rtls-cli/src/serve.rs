//! `rtls serve`: the control-room server (crate rtls-server) — MQTT and HTTP ingest, the
//! omlox hub API and WebSocket, history, alarms, metrics. `--demo` runs seed 000's simulated
//! mine through it (composed in [`crate::demo`]).

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;
use rtls_engine::site::Site;
use rtls_server::adapters::Vendor;
use rtls_server::auth::Tokens;
use rtls_server::config::{MqttMode, ServerConfig};
use rtls_server::http::plans::FloorPlans;
use rtls_server::serve::{init_logging, serve, Bound, ServeOptions};

/// Arguments of `rtls serve` (each overrides the config file).
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Configuration file (TOML; see `rtls_server::config` and examples/server.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// The site file (readers, zones, tracker settings).
    #[arg(long)]
    site: Option<PathBuf>,
    /// Run seed 000's simulated mine (its own site) through the server.
    #[arg(long)]
    demo: bool,
    /// Miners in the demo mine.
    #[arg(long, default_value_t = 600)]
    demo_miners: usize,
    /// HTTP listen address.
    #[arg(long)]
    http: Option<SocketAddr>,
    /// Database: `sqlite:PATH` (default `sqlite:rtls.db`) or `postgres://user:password@host/db`.
    #[arg(long)]
    db: Option<String>,
    /// Embedded MQTT broker's listen address.
    #[arg(long)]
    mqtt_listen: Option<SocketAddr>,
    /// Use an external MQTT broker instead of the embedded one (`mqtt://host:port?client_id=…`;
    /// TLS: `mqtts://host:port?ca_file=ca.pem`).
    #[arg(long, conflicts_with = "no_mqtt")]
    mqtt_url: Option<String>,
    /// No MQTT at all.
    #[arg(long)]
    no_mqtt: bool,
    /// UDP ingest of our measurement JSON lines, one payload per datagram (best-effort: no
    /// acknowledgement; MQTT QoS 1 or HTTP where every record must arrive).
    #[arg(long)]
    udp_listen: Option<SocketAddr>,
    /// UDP ingest of a vendor's messages through its adapter, one message per datagram:
    /// `VENDOR=ADDR` (`quuppa=0.0.0.0:9001`; pozyx, quuppa, sewio, zebra, openrtls, generic);
    /// repeatable.
    #[arg(long, value_parser = parse_udp_adapter)]
    udp_adapter: Vec<(Vendor, SocketAddr)>,
    /// A Zebra Dart hub's output to connect to and read, `HOST:PORT` (its Dart format port,
    /// 5117); reconnects when the connection drops (`[adapters.zebra]` sets its unit).
    #[arg(long, value_name = "HOST:PORT")]
    zebra_hub: Option<String>,
    /// Days of history kept.
    #[arg(long)]
    retention_days: Option<f64>,
    /// Tag partitions (worker threads).
    #[arg(long)]
    partitions: Option<usize>,
    /// Records' times are not the wall clock (replays): only records move the trackers' time.
    #[arg(long)]
    data_clock: bool,
    /// TLS certificate chain (PEM), with `--tls-key`: HTTPS / WSS and MQTTS.
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// TLS private key (PEM), with `--tls-cert`.
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Serve TLS with a self-signed certificate for localhost (generated at `--tls-cert` /
    /// `--tls-key`, or rtls-self-signed.crt / .key here, unless there already).
    #[arg(long)]
    tls_self_signed: bool,
    /// `text` or `json` logs (stderr).
    #[arg(long)]
    log_format: Option<String>,
    /// Run as one node of a cluster on NATS JetStream: `nats://host:port[,nats://…]` (needs a
    /// shared `--db postgres://…`; docs/CLUSTER.md).
    #[arg(long, value_delimiter = ',')]
    cluster: Vec<String>,
    /// This node's id in the cluster (default `<hostname>-<pid>`).
    #[arg(long, requires = "cluster")]
    node_id: Option<String>,
}

/// Runs the server until Ctrl-C or SIGTERM.
///
/// # Errors
/// Bad configuration, an unreadable site, a port in use, a database that cannot be opened.
pub fn run(args: &ServeArgs) -> anyhow::Result<()> {
    let mut config = match &args.config {
        Some(path) => ServerConfig::from_file(path)?,
        None => ServerConfig::default(),
    };
    apply_overrides(&mut config, args);
    // the environment's tokens take precedence and are validated with the file's
    if let Ok(token) = std::env::var("RTLS_WRITE_TOKEN") {
        config.auth.write_token = Some(token);
    }
    if let Ok(token) = std::env::var("RTLS_READ_TOKEN") {
        config.auth.read_token = Some(token);
    }
    config.validate()?;
    init_logging(&config.server.log_format);

    let (site_text, site_name, site_dir) = if args.demo {
        (crate::demo::site_toml(), "demo mine".to_string(), None)
    } else {
        let path = config
            .server
            .site
            .clone()
            .context("a site file is needed: --site PATH (or server.site in the config), or --demo")?;
        let text =
            std::fs::read_to_string(&path).with_context(|| format!("reading the site file {}", path.display()))?;
        let dir = path.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
        (text, path.display().to_string(), Some(dir))
    };
    let site = Site::from_toml_str(&site_text, &site_name)?;
    for line in site.advice() {
        eprintln!("{site_name}: {line}");
    }
    let floor_plans = match &site_dir {
        Some(dir) => FloorPlans::load(&site, dir).map_err(|e| anyhow::anyhow!("site file {site_name}: {e}"))?,
        None => FloorPlans::default(),
    };

    let write = match config.auth.write_token.clone() {
        Some(token) => token,
        None if args.demo => {
            let token = rtls_server::auth::random_token();
            eprintln!("demo write token (set RTLS_WRITE_TOKEN to choose one): {token}");
            token
        }
        None => bail!("writes need a token: set RTLS_WRITE_TOKEN or auth.write_token in the config file"),
    };
    let read = match config.auth.read_token.clone() {
        Some(token) => Some(token),
        None if config.auth.open_reads => None,
        None => {
            let token = rtls_server::auth::random_token();
            eprintln!(
                "read token (set RTLS_READ_TOKEN to choose one, or [auth] open_reads = true for none): {token}\n\
                 dashboard: {}://{}/?token={token}",
                if config.tls.files().is_some() { "https" } else { "http" },
                config.server.http
            );
            Some(token)
        }
    };
    let tokens = Tokens::new(write.clone(), read).with_open_reads(config.auth.open_reads);
    let feed: Option<rtls_server::serve::Feed> = if args.demo {
        let miners = args.demo_miners;
        if miners == 0 {
            bail!("--demo-miners must be at least 1");
        }
        Some(crate::demo::feed(write, miners))
    } else {
        None
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let served = runtime.block_on(async move {
        let options = ServeOptions {
            config,
            site,
            site_text,
            tokens,
            trackables: if args.demo {
                crate::demo::crew(args.demo_miners)
            } else {
                Vec::new()
            },
            floor_plans,
            feed,
        };
        serve(options, announce, shutdown_signal()).await
    });
    // a pipeline thread that did not drain (a stalled partition) must not hold the exit
    runtime.shutdown_timeout(std::time::Duration::from_secs(1));
    served?;
    Ok(())
}

/// Prints where the server listens as one JSON line on stdout (for scripts and tests).
fn announce(bound: Bound) {
    let line = serde_json::json!({
        "http": bound.http.to_string(),
        "mqtt": bound.mqtt.map(|a| a.to_string()),
        "udp": bound.udp.iter().map(|(vendor, address)| serde_json::json!({
            "adapter": vendor.map(Vendor::name),
            "address": address.to_string(),
        })).collect::<Vec<_>>(),
        "tls": bound.tls,
    });
    println!("{line}");
}

fn apply_overrides(config: &mut ServerConfig, args: &ServeArgs) {
    if let Some(site) = &args.site {
        config.server.site = Some(site.clone());
    }
    if let Some(http) = args.http {
        config.server.http = http;
    }
    if let Some(db) = &args.db {
        config.server.db.clone_from(db);
    }
    if !args.cluster.is_empty() {
        config.cluster.servers.clone_from(&args.cluster);
    }
    if let Some(node) = &args.node_id {
        config.cluster.node_id.clone_from(node);
    }
    if let Some(listen) = args.mqtt_listen {
        config.mqtt.listen = listen;
    }
    if let Some(url) = &args.mqtt_url {
        config.mqtt.mode = MqttMode::External;
        config.mqtt.url = Some(url.clone());
    }
    if args.no_mqtt {
        config.mqtt.mode = MqttMode::Off;
    }
    if let Some(listen) = args.udp_listen {
        config.udp.listen = Some(listen);
    }
    for (vendor, address) in &args.udp_adapter {
        config.udp.adapters.set(*vendor, *address);
    }
    if let Some(hub) = &args.zebra_hub {
        config.adapters.zebra.hub = Some(hub.clone());
    }
    if let Some(days) = args.retention_days {
        config.server.retention_days = days;
    }
    if let Some(partitions) = args.partitions {
        config.pipeline.partitions = partitions;
    }
    if args.data_clock {
        config.pipeline.live_clock = false;
    }
    if let (Some(cert), Some(key)) = (&args.tls_cert, &args.tls_key) {
        config.tls.cert = Some(cert.clone());
        config.tls.key = Some(key.clone());
    }
    if args.tls_self_signed {
        config.tls.self_signed = true;
    }
    if let Some(format) = &args.log_format {
        config.server.log_format.clone_from(format);
    }
}

/// `VENDOR=ADDR` of `--udp-adapter`.
fn parse_udp_adapter(text: &str) -> Result<(Vendor, SocketAddr), String> {
    let (vendor, address) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}` is not VENDOR=ADDR (e.g. quuppa=0.0.0.0:9001)"))?;
    let known = || Vendor::ALL.map(Vendor::name).join(", ");
    let vendor = Vendor::from_name(vendor).ok_or_else(|| format!("unknown adapter `{vendor}` (known: {})", known()))?;
    let address = address
        .parse()
        .map_err(|e| format!("`{address}` is not a listen address like 0.0.0.0:9001: {e}"))?;
    Ok((vendor, address))
}

/// Resolves on Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = terminate => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_udp_adapter_is_a_vendor_and_an_address() {
        assert_eq!(
            parse_udp_adapter("quuppa=127.0.0.1:9001"),
            Ok((Vendor::Quuppa, "127.0.0.1:9001".parse().unwrap()))
        );
        assert_eq!(
            parse_udp_adapter("zebra=127.0.0.1:9002"),
            Ok((Vendor::Zebra, "127.0.0.1:9002".parse().unwrap()))
        );
        let error = parse_udp_adapter("acme=127.0.0.1:9001").unwrap_err();
        assert!(
            error.contains("pozyx, quuppa, sewio, zebra, openrtls, generic"),
            "{error}"
        );
        assert!(parse_udp_adapter("quuppa").unwrap_err().contains("VENDOR=ADDR"));
        assert!(parse_udp_adapter("quuppa=localhost").unwrap_err().contains("localhost"));
    }
}
