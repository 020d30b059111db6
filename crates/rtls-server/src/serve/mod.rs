//! `rtls serve`: opens the store, starts the pipeline, the HTTP/WebSocket server, the MQTT
//! broker (or the bridge to an external one), the UDP listeners, retention, the webhooks, the
//! NATS forwards, and a live [`Feed`] if one is given (`rtls serve --demo`'s simulated mine);
//! stops them in order on shutdown.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rtls_engine::site::Site;
use tokio::sync::watch;

use crate::auth::Tokens;
use crate::config::{MqttMode, ServerConfig};
use crate::http::listener::{GuardedListener, HttpLimits};
use crate::http::rate::RateLimit;
use crate::http::QueryStore;
use crate::http::{router, AppState};
use crate::metrics::Metrics;
use crate::mqtt::{BrokerConfig, EmbeddedBroker, ExternalBroker};
use crate::nats_forward::{Forwarder, NatsForward};
use crate::pipeline::{Pipeline, PipelineConfig, TimeWindow};
use crate::sink::MeasurementSink;
use crate::store::{self, SqliteSync};
use crate::tls::{self, CertificateStore, TlsFiles};
use crate::webhooks::{Dispatcher, Webhook};

mod maintenance;
use maintenance::{compaction, retention};

/// A failure to start or run the server.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Bad configuration.
    #[error("{0}")]
    Config(String),
    /// The store could not be opened.
    #[error("database: {0}")]
    Store(#[from] store::StoreError),
    /// The pipeline could not start.
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// A listener could not be bound or served.
    #[error("{what} {address}: {reason}")]
    Listen {
        /// `HTTP`, `MQTT` or `UDP`.
        what: &'static str,
        /// The address.
        address: String,
        /// The OS error.
        reason: String,
    },
    /// The TLS certificate or key cannot be used.
    #[error(transparent)]
    Tls(#[from] tls::TlsError),
    /// The pipeline did not drain within [`DRAIN_DEADLINE`] at shutdown (a stalled partition).
    #[error(
        "the pipeline did not drain within {0:?} (a stalled partition?); stopped anyway: every \
         acknowledged record is in the ingest log and is replayed on the next start"
    )]
    Drain(Duration),
}

/// How long a shutdown waits for the pipeline to drain (the trackers flush, the outputs and
/// the checkpoint are stored) before it gives up on a stalled thread.
pub const DRAIN_DEADLINE: Duration = Duration::from_secs(10);

/// Where the running server listens (ports resolved, for `:0`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bound {
    /// HTTP and WebSocket.
    pub http: SocketAddr,
    /// The embedded MQTT broker, if it runs.
    pub mqtt: Option<SocketAddr>,
    /// The UDP listeners (`[udp]`): `None` for measurement lines, else the vendor whose
    /// messages it reads, with the bound address.
    pub udp: Vec<(Option<crate::adapters::Vendor>, SocketAddr)>,
    /// Whether both speak TLS (HTTPS / WSS, MQTTS).
    pub tls: bool,
}

/// A site and what to do with it.
pub struct ServeOptions {
    /// The configuration.
    pub config: ServerConfig,
    /// The site.
    pub site: Site,
    /// The site file's text (stored as configuration).
    pub site_text: String,
    /// The tokens (resolved from the config, the environment or generated).
    pub tokens: Tokens,
    /// omlox trackables registered at start when the store has none with their id (the demo's
    /// named miners); trackables created through the API are kept as they are.
    pub trackables: Vec<crate::omlox::Trackable>,
    /// The site's floor-plan images ([`crate::http::plans::FloorPlans::load`]; empty for none).
    pub floor_plans: crate::http::plans::FloorPlans,
    /// A feed to start once listening (`rtls serve --demo`'s mine), given the pipeline as its
    /// sink and the bound addresses.
    pub feed: Option<Feed>,
}

/// A feed started once the server listens (`rtls serve --demo`'s mine): given the pipeline,
/// the bound addresses and the stop signal, it returns its task — typically
/// [`crate::feed::start`] with a [`crate::feed::RecordSource`].
pub type Feed = Box<dyn FnOnce(Pipeline, Bound, watch::Receiver<bool>) -> tokio::task::JoinHandle<()> + Send>;

/// Runs the server until `shutdown` resolves; `on_bound` is told the addresses once
/// listening.
///
/// # Errors
/// [`ServeError`] when something cannot start.
pub async fn serve(
    options: ServeOptions,
    on_bound: impl FnOnce(Bound) + Send,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServeError> {
    let ServeOptions {
        config,
        site,
        site_text,
        tokens,
        trackables,
        floor_plans,
        feed,
    } = options;
    let db = config.server.db.clone();
    let sync = if config.server.sqlite_sync == "normal" {
        SqliteSync::Normal
    } else {
        SqliteSync::Full
    };
    let open = move || store::open(&db, sync);
    // before anything starts: a missing secret variable is a configuration error
    let webhooks = Webhook::from_config(&config.webhooks).map_err(|e| ServeError::Config(e.to_string()))?;
    let forwards = NatsForward::from_config(&config.nats_forward).map_err(|e| ServeError::Config(e.to_string()))?;
    let metrics = Arc::new(Metrics::new());
    // a cluster's node: the ingest log is the cluster's stream, outputs go to the peers too
    let cluster = if config.cluster.enabled() {
        Some(
            crate::cluster::Cluster::join(config.cluster.clone())
                .await
                .map_err(|e| ServeError::Config(e.to_string()))?,
        )
    } else {
        None
    };
    let (peers_tx, peers_rx) = tokio::sync::mpsc::channel(crate::cluster::PEER_QUEUE);
    let pipeline_config = PipelineConfig {
        partitions: if let Some(cluster) = &cluster {
            cluster.settings.partitions
        } else if config.pipeline.partitions == 0 {
            PipelineConfig::default().partitions
        } else {
            config.pipeline.partitions
        },
        live_clock: config.pipeline.live_clock,
        clock_lag: config.pipeline.clock_lag_s,
        time_window: Some(TimeWindow {
            max_age_s: config.pipeline.max_record_age_s,
            max_lead_s: config.pipeline.max_record_lead_s,
        }),
        cluster: cluster.as_ref().map(|c| crate::pipeline::ClusterHooks {
            log: c.log(),
            peers: peers_tx,
        }),
        default_accuracy_m: config.server.default_accuracy_m,
        history_interval_s: config.server.history_interval_s,
        generic_adapter: config.adapters.generic.clone(),
        zebra_adapter: config.adapters.zebra.clone(),
        ..PipelineConfig::default()
    };
    // the stores are synchronous (the PostgreSQL client blocks on a runtime of its own): open
    // them, store the site and start the pipeline (which reads the checkpoint) off the runtime
    let pipeline_site = site.clone();
    let pipeline_metrics = Arc::clone(&metrics);
    let want_hub = !webhooks.is_empty();
    let want_forwards = !forwards.is_empty();
    let issued_tokens = tokens.clone();
    let (pipeline, query_store, hub, forwards_hub) = tokio::task::spawn_blocking(move || -> Result<_, ServeError> {
        let (ingest_store, output_store, mut query_store) = (open()?, open()?, open()?);
        query_store.put_config("site", "current", &site_text)?;
        for trackable in &trackables {
            if query_store
                .get_config(crate::http::TRACKABLE_CONFIG, &trackable.id)?
                .is_none()
            {
                let json = serde_json::to_string(trackable)
                    .map_err(|e| ServeError::Config(format!("trackable {}: {e}", trackable.id)))?;
                query_store.put_config(crate::http::TRACKABLE_CONFIG, &trackable.id, &json)?;
            }
        }
        let pipeline = Pipeline::start(
            &pipeline_site,
            ingest_store,
            output_store,
            pipeline_config,
            pipeline_metrics,
        )?;
        // the stored trackables (the configured ones just added), for the topics about them
        let trackables = crate::http::trackable_sync::read_trackables(&mut *query_store)?;
        pipeline.live().set_trackables(trackables);
        // the webhooks' subscription, as soon as the hub exists (the trackers' replay of the
        // ingest log has just started: alarms it raised in these microseconds are not sent)
        let hub = want_hub.then(|| pipeline.subscribe_local());
        let forwards_hub = want_forwards.then(|| pipeline.subscribe_local());
        // the tokens issued through the API before this start (their hashes)
        let issued = query_store.list_config(crate::http::tokens::TOKEN_CONFIG)?;
        for (id, json) in issued {
            match serde_json::from_str::<crate::auth::IssuedToken>(&json) {
                Ok(token) => issued_tokens.remember(token),
                Err(e) => tracing::error!(token_id = %id, error = %e, "a stored token is corrupt; it is not accepted"),
            }
        }
        if let Some(zones) = crate::http::fences::stored_zones(query_store.as_mut()).map_err(ServeError::Config)? {
            tracing::info!(
                zones = zones.len(),
                "watching the zone set edited through the API (DELETE /api/v1/zones/edits returns to the site file's)"
            );
            pipeline.live().set_zones(zones);
        }
        Ok((pipeline, query_store, hub, forwards_hub))
    })
    .await
    .map_err(|e| ServeError::Config(format!("opening the database: {e}")))??;
    tracing::info!(backend = query_store.backend(), db = %crate::config::redact_password(&config.server.db), "database open");
    let dispatcher = match hub {
        Some(hub) => Some(Dispatcher::start(webhooks, hub, &metrics).map_err(ServeError::Config)?),
        None => None,
    };
    let forwarder = match forwards_hub {
        Some(hub) => Some(
            Forwarder::start(forwards, hub, &metrics)
                .await
                .map_err(ServeError::Config)?,
        ),
        None => None,
    };
    let queries = Arc::new(Mutex::new(QueryStore::new(query_store)));
    let tokens = Arc::new(tokens);
    let state = AppState {
        pipeline: pipeline.clone(),
        queries: Arc::clone(&queries),
        tokens: Arc::clone(&tokens),
        site: Arc::new(site),
        default_accuracy_m: config.server.default_accuracy_m,
        started: Instant::now(),
        floor_plans: Arc::new(floor_plans),
    };

    let (stop_tx, stop_rx) = watch::channel(false);
    let stopped = |mut rx: watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|stop| *stop).await;
    };

    let certificates = tls_certificates(&config)?;
    let listener = tokio::net::TcpListener::bind(config.server.http)
        .await
        .map_err(|e| listen_error("HTTP", config.server.http, &e))?;
    let http_addr = listener
        .local_addr()
        .map_err(|e| listen_error("HTTP", config.server.http, &e))?;

    let sink: Arc<dyn MeasurementSink> = Arc::new(pipeline.clone());
    let mut tasks = Vec::new();
    if let Some((store, files)) = &certificates {
        tasks.push(tokio::spawn(tls::watch_files(
            Arc::clone(store),
            files.clone(),
            stop_rx.clone(),
        )));
    }
    let mut mqtt_addr = None;
    match config.mqtt.mode {
        MqttMode::Embedded => {
            let broker_config = BrokerConfig {
                max_connections: config.mqtt.max_connections,
                max_read_connections: config.mqtt.max_read_connections,
                max_connections_per_ip: config.mqtt.max_connections_per_ip,
                max_pending_connects: config.mqtt.max_pending_connects,
                ..BrokerConfig::new((*tokens).clone())
            };
            let broker = EmbeddedBroker::bind(
                config.mqtt.listen,
                broker_config,
                Arc::clone(&sink),
                pipeline.publications(),
            )
            .await
            .map_err(|e| ServeError::Listen {
                what: "MQTT",
                address: config.mqtt.listen.to_string(),
                reason: e.to_string(),
            })?;
            mqtt_addr = Some(broker.local_addr());
            let broker = match &certificates {
                Some((store, _)) => broker.with_tls(store.acceptor(&[])?),
                None => broker,
            };
            tasks.push(tokio::spawn(broker.run(stopped(stop_rx.clone()))));
        }
        MqttMode::External => {
            let mut url = config.mqtt.url.clone().unwrap_or_default();
            let mut filter = crate::mqtt::MEASUREMENT_FILTER.to_string();
            if config.cluster.enabled() {
                // one client id per node, and each measurement to one node of the cluster
                url = crate::cluster::node_mqtt_url(&url, &config.cluster.node_name());
                filter = crate::cluster::shared_measurement_filter();
            }
            let bridge = ExternalBroker::connect(&url, Arc::clone(&sink), pipeline.local_publications(), &filter)
                .await
                .map_err(|e| ServeError::Config(format!("mqtt.url: {e}")))?;
            tasks.push(tokio::spawn(bridge.run(stopped(stop_rx.clone()))));
        }
        MqttMode::Off => {}
    }
    let mut udp_addrs = Vec::new();
    let udp_listeners = crate::udp::bind_all(&config.udp, &metrics)
        .await
        .map_err(|(address, e)| listen_error("UDP", address, &e))?;
    for listener in udp_listeners {
        let address = listener.local_addr().map_err(|e| listen_error("UDP", http_addr, &e))?;
        udp_addrs.push((listener.vendor(), address));
        tasks.push(listener.start(pipeline.clone(), stop_rx.clone()));
    }
    if let Some(hub) = &config.adapters.zebra.hub {
        let idle = Duration::from_secs_f64(config.adapters.zebra.idle_timeout_s);
        tasks.push(crate::zebra_hub::ZebraHub::new(hub, idle, pipeline.clone()).start(stop_rx.clone()));
    }
    if let Some(cluster) = cluster {
        // trackables changed through another node reach this one's live topics
        tasks.push(tokio::spawn(crate::http::trackable_sync::refresh_trackables_every(
            Arc::clone(&queries),
            pipeline.clone(),
            crate::http::trackable_sync::CLUSTER_PERIOD,
            stopped(stop_rx.clone()),
        )));
        tasks.extend(crate::cluster::start_node(
            cluster,
            pipeline.clone(),
            peers_rx,
            &stop_rx,
        ));
    }
    tasks.push(tokio::spawn(retention(
        Arc::clone(&queries),
        config.server.retention_days,
        config.server.raw_retention_days,
        stopped(stop_rx.clone()),
    )));
    tasks.push(tokio::spawn(compaction(
        Arc::clone(&queries),
        Arc::clone(&metrics),
        config.server.compact_after_s,
        stopped(stop_rx.clone()),
    )));

    let bound = Bound {
        http: http_addr,
        mqtt: mqtt_addr,
        udp: udp_addrs,
        tls: certificates.is_some(),
    };
    tracing::info!(http = %http_addr, mqtt = ?mqtt_addr, udp = ?bound.udp, "listening");
    on_bound(bound.clone());
    // the feed stops first, while the broker can still acknowledge its last payload
    let (feed_stop_tx, feed_stop_rx) = watch::channel(false);
    let feed_task = feed.map(|start| start(pipeline.clone(), bound, feed_stop_rx));

    let mut app = with_cors(router(state), &config.server.cors_origins);
    if let Some(rate) = RateLimit::new(config.server.max_requests_per_s_per_ip, Arc::clone(&metrics)) {
        app = app.layer(axum::middleware::from_fn_with_state(rate, crate::http::rate::limit));
    }
    let http_stopped = stopped(stop_rx.clone());
    let https = match &certificates {
        Some((store, _)) => Some(store.acceptor(&[b"http/1.1"])?),
        None => None,
    };
    let listener = GuardedListener::new(
        listener,
        HttpLimits {
            max_connections: config.server.max_connections,
            max_connections_per_ip: config.server.max_connections_per_ip,
            idle: Duration::from_secs_f64(config.server.idle_timeout_s),
        },
        https,
        Arc::clone(&metrics),
    );
    let http = tokio::spawn(async move {
        let app = app.into_make_service_with_connect_info::<crate::http::listener::Peer>();
        if let Err(e) = axum::serve(listener, app).with_graceful_shutdown(http_stopped).await {
            tracing::error!(error = %e, "HTTP server failed");
        }
    });
    shutdown.await;
    if let Some(task) = feed_task {
        let _ = feed_stop_tx.send(true);
        let _ = tokio::time::timeout(Duration::from_secs(10), task).await;
    }
    tracing::info!("shutting down: closing listeners");
    let _ = stop_tx.send(true);
    let _ = tokio::time::timeout(Duration::from_secs(10), http).await;
    for task in tasks {
        let _ = tokio::time::timeout(Duration::from_secs(10), task).await;
    }
    tracing::info!("draining the pipeline");
    let draining = pipeline.clone();
    let drained = tokio::time::timeout(DRAIN_DEADLINE, tokio::task::spawn_blocking(move || draining.shutdown())).await;
    if let Some(dispatcher) = dispatcher {
        // after the pipeline: the trackers' last alarms are queued too
        tracing::info!("delivering the webhooks' queued events (2 s at most)");
        dispatcher.shutdown().await;
    }
    if let Some(forwarder) = forwarder {
        tracing::info!("publishing the NATS forwards' queued messages (2 s at most)");
        forwarder.shutdown().await;
    }
    if drained.is_err() {
        let error = ServeError::Drain(DRAIN_DEADLINE);
        tracing::error!(error = %error, "shutdown");
        return Err(error);
    }
    tracing::info!("stopped");
    Ok(())
}

/// The TLS certificate store and its files when `[tls]` is on: a self-signed pair generated
/// first if asked for and absent.
fn tls_certificates(config: &ServerConfig) -> Result<Option<(Arc<CertificateStore>, TlsFiles)>, ServeError> {
    let Some((cert, key)) = config.tls.files() else {
        return Ok(None);
    };
    if config.tls.self_signed {
        let mut names = vec!["localhost".to_string(), "127.0.0.1".to_string(), "::1".to_string()];
        for address in [config.server.http.ip(), config.mqtt.listen.ip()] {
            if !address.is_unspecified() && !names.contains(&address.to_string()) {
                names.push(address.to_string());
            }
        }
        if tls::ensure_self_signed(&cert, &key, &names)? {
            tracing::info!(cert = %cert.display(), key = %key.display(), ?names, "tls: generated a self-signed certificate (clients trust it by this file)");
        }
    }
    let store = CertificateStore::new(tls::load(&cert, &key)?);
    tracing::info!(cert = %cert.display(), "tls: HTTPS, WSS and MQTTS on");
    let files = TlsFiles {
        cert,
        key,
        reload_every: Duration::from_secs_f64(config.tls.reload_s),
    };
    Ok(Some((store, files)))
}

fn listen_error(what: &'static str, address: SocketAddr, error: &std::io::Error) -> ServeError {
    ServeError::Listen {
        what,
        address: address.to_string(),
        reason: error.to_string(),
    }
}

/// Installs the log subscriber: `text` or `json` lines on stderr, filtered by `RTLS_LOG`
/// (default `info`).
pub fn init_logging(format: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_env("RTLS_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = if format == "json" {
        builder.json().try_init()
    } else {
        builder.try_init()
    };
}

/// The router with a CORS layer for `origins` (`server.cors_origins`; none: unchanged): simple
/// and preflight requests from those origins may read responses and send `Authorization`.
pub fn with_cors(app: axum::Router, origins: &[String]) -> axum::Router {
    use axum::http::{header, HeaderValue, Method};
    use tower_http::cors::{AllowOrigin, CorsLayer};
    if origins.is_empty() {
        return app;
    }
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        // validated by ServerConfig::validate
        AllowOrigin::list(origins.iter().filter_map(|o| o.parse::<HeaderValue>().ok()))
    };
    app.layer(
        CorsLayer::new()
            .allow_origin(allow)
            .allow_methods([Method::GET, Method::POST, Method::PUT, Method::DELETE])
            .allow_headers([header::AUTHORIZATION, header::CONTENT_TYPE])
            .max_age(std::time::Duration::from_secs(3600)),
    )
}
