//! A live feed of measurement records into the running server, through the same ingest path
//! as real readers: MQTT to the embedded broker with the write token, or the pipeline's sink
//! when MQTT is off or external.
//!
//! The server knows nothing about where the records come from: a [`RecordSource`] (a
//! simulation, a replay) is asked once a second for the records up to half a second (one
//! reorder window) behind the wall clock, and what it returns is published. `rtls serve
//! --demo` composes seed 000's simulated mine into a source in the `rtls` binary (crate
//! rtls-cli), so this crate does not depend on the simulator.

use std::time::Duration;

use rtls_engine::record::{to_json_line, Record};
use rumqttc::{AsyncClient, Event, MqttOptions, Outgoing, Packet, QoS};
use tokio::sync::watch;

use crate::pipeline::{unix_s, Pipeline};
use crate::serve::Bound;
use crate::sink::MeasurementSink;

/// How often the source is asked for records: as a reader network sends its scans, a record
/// leaves at most this long after its time (the demo's latency was 0.5–1.5 s with a 1 s period
/// and a 0.5 s lag for the re-ordering window the trackers no longer need).
const PERIOD: Duration = Duration::from_millis(100);

/// How far behind the wall clock the source is asked to stay (s): none — a record that
/// overtakes an earlier one is re-filtered by the tracker (`rewind_horizon_s`).
const LAG_S: f64 = 0.0;

/// Where the records of a live feed come from.
///
/// Any `FnMut(f64) -> Vec<Record>` closure that is `Send + 'static` is one.
pub trait RecordSource: Send + 'static {
    /// The records with times up to `up_to_unix_s` (Unix seconds) not returned before, in
    /// time order; empty when there is nothing new.
    fn records_up_to(&mut self, up_to_unix_s: f64) -> Vec<Record>;
}

impl<F> RecordSource for F
where
    F: FnMut(f64) -> Vec<Record> + Send + 'static,
{
    fn records_up_to(&mut self, up_to_unix_s: f64) -> Vec<Record> {
        self(up_to_unix_s)
    }
}

/// How a feed shows itself to the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FeedIdentity {
    /// The feed's name: the MQTT user name, the pipeline sink's source label and the logs'
    /// `feed` field (e.g. `demo`).
    pub name: String,
    /// The MQTT client id on the embedded broker (e.g. `rtls-demo-mine`).
    pub client_id: String,
    /// The MQTT topic the records are published on (e.g.
    /// `rtls/v1/measurements/demo-gateway`).
    pub topic: String,
    /// The write token the MQTT client authenticates with.
    pub write_token: String,
}

/// Starts the feed: every 100 ms, `source`'s records up to now are published over the
/// embedded broker (when `bound.mqtt` is set, without TLS) or pushed into `pipeline`'s sink. Stops when
/// `stop` turns true.
pub fn start(
    identity: FeedIdentity,
    mut source: impl RecordSource,
    pipeline: Pipeline,
    bound: Bound,
    mut stop: watch::Receiver<bool>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let FeedIdentity {
            name,
            client_id,
            topic,
            write_token,
        } = identity;
        // over MQTTS the feed hands its records to the sink (same path after the transport)
        let mut publisher = bound
            .mqtt
            .filter(|_| !bound.tls)
            .map(|address| connect(address, &client_id, &name, &write_token));
        let mut tick = tokio::time::interval(PERIOD);
        // each payload is awaited before the next: the order holds by itself
        let mut order = crate::sink::IngestOrder::default();
        tracing::info!(
            feed = %name,
            via = if publisher.is_some() { "mqtt" } else { "sink" },
            "feed started"
        );
        loop {
            tokio::select! {
                _ = stop.wait_for(|s| *s) => break,
                _ = tick.tick() => {}
            }
            let records = source.records_up_to(unix_s() - LAG_S);
            if records.is_empty() {
                continue;
            }
            let mut payload = String::with_capacity(records.len() * 96);
            for record in &records {
                payload.push_str(&to_json_line(record));
                payload.push('\n');
            }
            let result = match &mut publisher {
                Some(client) => client
                    .publish(topic.as_str(), QoS::AtLeastOnce, false, payload.into_bytes())
                    .await
                    .map_err(|e| e.to_string()),
                None => pipeline
                    .ingest(&name, payload.into(), &mut order)
                    .await
                    .map(|_| ())
                    .map_err(|e| e.to_string()),
            };
            if let Err(e) = result {
                tracing::warn!(feed = %name, error = %e, records = records.len(), "feed: records not delivered");
            }
        }
        if let Some(client) = publisher {
            let _ = client.disconnect().await;
        }
        tracing::info!(feed = %name, "feed stopped");
    })
}

/// An MQTT client on the embedded broker, its event loop driven by a task of its own.
fn connect(address: std::net::SocketAddr, client_id: &str, user: &str, write_token: &str) -> AsyncClient {
    let mut options = MqttOptions::new(client_id, address.ip().to_string(), address.port());
    options.set_credentials(user, write_token);
    options.set_keep_alive(Duration::from_secs(30));
    options.set_max_packet_size(16 * 1024 * 1024, 16 * 1024 * 1024);
    let (client, mut event_loop) = AsyncClient::new(options, 64);
    let user = user.to_string();
    tokio::spawn(async move {
        loop {
            match event_loop.poll().await {
                // our own disconnect at shutdown: the broker closes the connection next
                Ok(Event::Incoming(Packet::Disconnect) | Event::Outgoing(Outgoing::Disconnect)) => break,
                Ok(_) => {}
                Err(rumqttc::ConnectionError::RequestsDone) => break,
                Err(e) => {
                    tracing::warn!(feed = %user, error = %e, "feed: MQTT connection lost; reconnecting");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
            }
        }
    });
    client
}
