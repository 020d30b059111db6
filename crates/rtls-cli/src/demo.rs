//! `rtls serve --demo`: seed 000's simulated mine (307 readers along seven drifts and a
//! cross-cut, hundreds of roaming miners, a roof fall whose reader is broken, a miner sent
//! towards it every two minutes), composed here in the binary: rtls-sim builds the mine and
//! its site file, rtls-server's [`rtls_server::feed`] publishes its records in real time
//! through the same ingest path as real readers — MQTT to the embedded broker with the write
//! token, or the pipeline's sink when MQTT is off or external. The server does not depend on
//! the simulator.

use rtls_server::feed::{self, FeedIdentity};
use rtls_server::pipeline::unix_s;
use rtls_server::serve::Feed;
use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, SiteOptions};

/// The demo's MQTT topic (one gateway forwarding every reader's detections).
pub const DEMO_TOPIC: &str = "rtls/v1/measurements/demo-gateway";

/// The demo mine's site file (with one zone per drift for head counts).
#[must_use]
pub fn site_toml() -> String {
    MineLayout::seed000().site_toml(&SiteOptions {
        name: Some("Demo mine (seed 000: 307 readers, a roof fall on drift 3)".into()),
        drift_zones: true,
        without_map: false,
    })
}

/// The feed the server starts once listening: `miners` miners, the first scans at the second
/// the server is bound, published with `write_token`.
#[must_use]
pub fn feed(write_token: String, miners: usize) -> Feed {
    Box::new(move |pipeline, bound, stop| {
        let config = MineConfig {
            miners,
            entering_miners: (miners / 60).clamp(1, 10),
            start_time_s: unix_s().floor(),
            ..MineConfig::default()
        };
        match MineSimulation::new(MineLayout::seed000(), config) {
            Ok(mut simulation) => {
                let identity = FeedIdentity {
                    name: "demo".into(),
                    client_id: "rtls-demo-mine".into(),
                    topic: DEMO_TOPIC.into(),
                    write_token,
                };
                feed::start(identity, move |up_to_s| simulation.step(up_to_s), pipeline, bound, stop)
            }
            Err(e) => {
                eprintln!("error: demo feed: {e}");
                tokio::spawn(async {})
            }
        }
    })
}
