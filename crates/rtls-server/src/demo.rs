//! `rtls serve --demo`: seed 000's simulated mine (307 readers along seven drifts and a
//! cross-cut, hundreds of roaming miners, a roof fall whose reader is broken, a miner sent
//! towards it every two minutes) feeding the server in real time through the same ingest
//! path as real readers — MQTT to the embedded broker with the write token, or the pipeline's
//! sink when MQTT is off or external.

use std::time::Duration;

use rtls_engine::record::to_json_line;
use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, SiteOptions};
use rumqttc::{AsyncClient, Event, MqttOptions, Outgoing, Packet, QoS};
use tokio::sync::watch;

use crate::pipeline::{unix_s, Pipeline};
use crate::serve::Bound;
use crate::sink::MeasurementSink;

/// The demo's MQTT topic (one gateway forwarding every reader's detections).
pub const DEMO_TOPIC: &str = "rtls/v1/measurements/demo-gateway";

/// The demo mine's site file (with one zone per drift for head counts).
#[must_use]
pub fn demo_site_toml() -> String {
    MineLayout::seed000().site_toml(&SiteOptions {
        name: Some("Demo mine (seed 000: 307 readers, a roof fall on drift 3)".into()),
        drift_zones: true,
        without_map: false,
    })
}

/// Starts the feed: every second, the miners' scans up to now are published. Stops when
/// `stop` turns true.
///
/// # Errors
/// The simulation's configuration error (a bad miner count).
pub fn start(
    pipeline: Pipeline,
    bound: Bound,
    write_token: String,
    miners: usize,
    mut stop: watch::Receiver<bool>,
) -> Result<tokio::task::JoinHandle<()>, String> {
    let config = MineConfig {
        miners,
        entering_miners: (miners / 60).clamp(1, 10),
        start_time_s: unix_s().floor(),
        ..MineConfig::default()
    };
    let mut simulation = MineSimulation::new(MineLayout::seed000(), config).map_err(|e| e.to_string())?;
    Ok(tokio::spawn(async move {
        let mut publisher = bound.mqtt.map(|address| connect(address, &write_token));
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tracing::info!(
            miners,
            via = if publisher.is_some() { "mqtt" } else { "sink" },
            "demo mine started"
        );
        loop {
            tokio::select! {
                _ = stop.wait_for(|s| *s) => break,
                _ = tick.tick() => {}
            }
            // scans up to one reorder window behind now, so every record is on time
            let records = simulation.step(unix_s() - 0.5);
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
                    .publish(DEMO_TOPIC, QoS::AtLeastOnce, false, payload.into_bytes())
                    .await
                    .map_err(|e| e.to_string()),
                None => pipeline
                    .ingest("demo", payload.into())
                    .await
                    .map(|_| ())
                    .map_err(|e| e.to_string()),
            };
            if let Err(e) = result {
                tracing::warn!(error = %e, records = records.len(), "demo feed: records not delivered");
            }
        }
        if let Some(client) = publisher {
            let _ = client.disconnect().await;
        }
        tracing::info!("demo mine stopped");
    }))
}

/// An MQTT client on the embedded broker, its event loop driven by a task of its own.
fn connect(address: std::net::SocketAddr, write_token: &str) -> AsyncClient {
    let mut options = MqttOptions::new("rtls-demo-mine", address.ip().to_string(), address.port());
    options.set_credentials("demo", write_token);
    options.set_keep_alive(Duration::from_secs(30));
    options.set_max_packet_size(16 * 1024 * 1024, 16 * 1024 * 1024);
    let (client, mut event_loop) = AsyncClient::new(options, 64);
    tokio::spawn(async move {
        loop {
            match event_loop.poll().await {
                // our own disconnect at shutdown: the broker closes the connection next
                Ok(Event::Incoming(Packet::Disconnect) | Event::Outgoing(Outgoing::Disconnect)) => break,
                Ok(_) => {}
                Err(rumqttc::ConnectionError::RequestsDone) => break,
                Err(e) => {
                    tracing::warn!(error = %e, "demo feed: MQTT connection lost; reconnecting");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
            }
        }
    });
    client
}
