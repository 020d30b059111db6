//! `rtls serve --demo`: seed 000's simulated mine (307 readers along seven drifts and a
//! cross-cut, hundreds of roaming miners, a roof fall whose reader is broken, a miner sent
//! towards it every two minutes), composed here in the binary: rtls-sim builds the mine and
//! its site file, rtls-server's [`rtls_server::feed`] publishes its records in real time
//! through the same ingest path as real readers — MQTT to the embedded broker with the write
//! token, or the pipeline's sink when MQTT is off or external. The server does not depend on
//! the simulator.

use rtls_server::convert::uuid_for;
use rtls_server::feed::{self, FeedIdentity};
use rtls_server::omlox::{Trackable, TrackableType};
use rtls_server::pipeline::unix_s;
use rtls_server::serve::Feed;
use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, SiteOptions};

/// The demo's MQTT topic (one gateway forwarding every reader's detections).
pub const DEMO_TOPIC: &str = "rtls/v1/measurements/demo-gateway";

/// The demo mine's site file: one zone per drift for head counts, and a portal at the west
/// end of the first drift as the muster board's entry zone.
#[must_use]
pub fn site_toml() -> String {
    let mine = MineLayout::seed000();
    let mut text = mine.site_toml(&SiteOptions {
        name: Some("Demo mine (seed 000: 307 readers, a roof fall on drift 3)".into()),
        drift_zones: true,
        without_map: false,
    });
    if let Some(first) = mine.drifts.first() {
        // 8 m of the drift's walkable west end, 3 m either side of its centreline
        let (west, y) = (first.walkable_x_m[0], first.y_m);
        text.push_str(&format!(
            "\n[[zones]]\nid = \"portal\"\nname = \"Portal (lamp room)\"\nkind = \"area-of-interest\"\n\
             shape = {{ type = \"polygon\", vertices_m = [[{x0:.2}, {y0:.2}], [{x1:.2}, {y0:.2}], [{x1:.2}, {y1:.2}], [{x0:.2}, {y1:.2}]] }}\n\
             \n[muster]\nentry_zone = \"portal\"\n",
            x0 = west - 2.0,
            x1 = west + 8.0,
            y0 = y - 3.0,
            y1 = y + 3.0,
        ));
    }
    text
}

/// Given names and family names the demo's crew is named from (tag `miner-k` gets given name
/// `k mod 40` and family name `(k / 40) mod 40`: 1 600 distinct names, then they repeat with
/// the tag in brackets telling them apart).
const GIVEN_NAMES: [&str; 40] = [
    "Ana", "Bongani", "Chen", "Dagny", "Emeka", "Fatima", "Goran", "Hana", "Ivan", "Jia", "Kofi", "Lena", "Mateo",
    "Nadia", "Olu", "Priya", "Quentin", "Rosa", "Sipho", "Tomás", "Uma", "Viktor", "Wen", "Ximena", "Yusuf", "Zanele",
    "Arjun", "Birgit", "Carlos", "Dilnoza", "Erik", "Farid", "Greta", "Hamid", "Ines", "Jonas", "Keiko", "Lars",
    "Mina", "Nikolai",
];
const FAMILY_NAMES: [&str; 40] = [
    "Abara",
    "Berg",
    "Castillo",
    "Dlamini",
    "Eriksen",
    "Fofana",
    "Gupta",
    "Haddad",
    "Ivanova",
    "Jensen",
    "Kowalski",
    "Lindqvist",
    "Mokoena",
    "Nakamura",
    "Okafor",
    "Petrov",
    "Quispe",
    "Rossi",
    "Santos",
    "Tanaka",
    "Urbina",
    "Vargas",
    "Wang",
    "Xu",
    "Yilmaz",
    "Zulu",
    "Andersson",
    "Bianchi",
    "Chowdhury",
    "Dubois",
    "Engel",
    "Ferreira",
    "García",
    "Horvat",
    "Ibrahim",
    "Jovanović",
    "Kim",
    "López",
    "Moreau",
    "Novak",
];

/// The demo's miners as omlox trackables: one per tag `miner-000` …, named, with the tag as its
/// location provider, so `/v2/trackables` and the dashboard show people, not tag ids. Ids are
/// name-based UUIDs of the tag, so a restart finds them registered.
#[must_use]
pub fn crew(miners: usize) -> Vec<Trackable> {
    (0..miners)
        .map(|k| {
            let tag = format!("miner-{k:03}");
            let name = format!(
                "{} {}",
                GIVEN_NAMES[k % GIVEN_NAMES.len()],
                FAMILY_NAMES[(k / GIVEN_NAMES.len()) % FAMILY_NAMES.len()]
            );
            let name = if k >= GIVEN_NAMES.len() * FAMILY_NAMES.len() {
                format!("{name} ({tag})")
            } else {
                name
            };
            Trackable {
                id: uuid_for("trackable", &tag),
                kind: TrackableType::Virtual,
                name: Some(name),
                geometry: None,
                extrusion: None,
                location_providers: Some(vec![tag]),
                fence_timeout: None,
                exit_tolerance: None,
                tolerance_timeout: None,
                exit_delay: None,
                radius: None,
                properties: None,
                locating_rules: None,
            }
        })
        .collect()
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
