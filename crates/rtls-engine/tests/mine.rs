//! Seed 000 at its scale: a simulated coal mine with 307 RSSI readers and 600 miners, tracked
//! by the tightly coupled EKF, with a collapsed section whose reader is broken.
//!
//! Layout: seven parallel drifts 600 m long (y = 0, 40, …, 240 m) with a reader every 15 m on
//! alternating walls (7 × 41 = 287 readers) and a cross-cut at x = 300 m with 20 readers
//! (307 in all). The collapse is drift 3 (y = 120 m) between x = 400 and 440 m; its reader
//! (x = 420 m) is broken and the rubble shields the section, so a miner inside is heard by no
//! reader. Radio: `ρ = −40 dBm − 30 log₁₀ d + N(0, 3²)`, heard when `ρ ≥ −82 dBm` (median range
//! 25 m), one scan per second.
//!
//! Checks (seed 000's claims, on the engine): predictive alarms fire before every miner who
//! walks into the collapse reaches it, with a lead time; a position is output for every miner
//! in every second (PEL = 0, gap filling); the engine loses no miner while he is in coverage.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Event, Output, Tracker};

const DRIFTS: usize = 7;
const DRIFT_SPACING_M: f64 = 40.0;
const DRIFT_LENGTH_M: f64 = 600.0;
const READER_SPACING_M: f64 = 15.0;
const COLLAPSE_DRIFT: usize = 3;
const COLLAPSE_X_M: [f64; 2] = [400.0, 440.0];
const BROKEN_READER: usize = 28; // x = 420 m on drift 3
const DURATION_S: f64 = 180.0;
const TAGS: usize = 600;
const ENTERING_TAGS: usize = 30;
const COAST_TIMEOUT_S: f64 = 10.0;

struct Reader {
    id: String,
    position_m: [f64; 2],
    working: bool,
}

fn readers() -> Vec<Reader> {
    let mut readers = Vec::new();
    for drift in 0..DRIFTS {
        let y = drift as f64 * DRIFT_SPACING_M;
        for k in 0..=(DRIFT_LENGTH_M / READER_SPACING_M) as usize {
            let wall = if k % 2 == 0 { -2.5 } else { 2.5 };
            readers.push(Reader {
                id: format!("D{drift}-{k:02}"),
                position_m: [k as f64 * READER_SPACING_M, y + wall],
                working: !(drift == COLLAPSE_DRIFT && k == BROKEN_READER),
            });
        }
    }
    for k in 0..20 {
        let wall = if k % 2 == 0 { -2.5 } else { 2.5 };
        readers.push(Reader {
            id: format!("X-{k:02}"),
            position_m: [300.0 + wall, 6.0 + 12.0 * k as f64],
            working: true,
        });
    }
    readers
}

fn site_toml(readers: &[Reader]) -> String {
    let mut text = String::from("name = \"simulated mine (seed 000 scale)\"\n");
    for r in readers {
        text.push_str(&format!(
            "[[readers]]\nid = \"{}\"\nposition_m = [{}, {}]\ntechnology = \"rfid\"\nworking = {}\n\
             radio = {{ path_loss = {{ reference_power_dbm = -40.0, exponent = 3.0, shadowing_std_db = 3.0, reference_distance_m = 1.0 }} }}\n",
            r.id, r.position_m[0], r.position_m[1], r.working
        ));
    }
    let y = COLLAPSE_DRIFT as f64 * DRIFT_SPACING_M;
    text.push_str(&format!(
        "[[zones]]\nid = \"collapse\"\nname = \"Roof fall, drift 3\"\nkind = \"hazard\"\nreaders = [\"D{COLLAPSE_DRIFT}-{BROKEN_READER:02}\"]\n\
         shape = {{ type = \"polygon\", vertices_m = [[{x0}, {y0}], [{x1}, {y0}], [{x1}, {y1}], [{x0}, {y1}]] }}\n",
        x0 = COLLAPSE_X_M[0],
        x1 = COLLAPSE_X_M[1],
        // the section of the drift as the map draws it: the band closer to drift 3 than to
        // its neighbours (±20 m), since with readers along one line the estimate's cross-track
        // error reaches several metres (no tunnel map constrains it here)
        y0 = y - 19.5,
        y1 = y + 19.5
    ));
    text.push_str(&format!(
        "[tracker]\npipeline = \"tightly-coupled\"\nmotion_model = \"cv\"\nfilter = \"ekf\"\n\
         acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.999\n\
         initiation = {{ confirm_updates = 3, within_s = 5.0 }}\ncoast_timeout_s = {COAST_TIMEOUT_S}\n\
         delete_timeout_s = 120.0\nreorder_window_s = 1.0\noutput_interval_s = 1.0\n\
         [alarms]\nhorizon_s = 10.0\nstep_s = 0.5\nentry_probability = 0.5\n"
    ));
    text
}

/// A miner walking back and forth along a drift at a constant speed.
#[derive(Debug, Clone, Copy)]
struct Walker {
    drift: usize,
    lateral_m: f64,
    start_x_m: f64,
    speed_mps: f64,
    /// Bounces between these.
    limits_m: [f64; 2],
    /// +1 east, −1 west at the start.
    direction: f64,
}

impl Walker {
    fn position_m(&self, t: f64) -> [f64; 2] {
        // unfold the bouncing walk: distance travelled along a 2L-periodic track
        let [a, b] = self.limits_m;
        let length = b - a;
        let unfolded = if self.direction > 0.0 {
            self.start_x_m - a + self.speed_mps * t
        } else {
            2.0 * length - (self.start_x_m - a) + self.speed_mps * t
        };
        let phase = unfolded.rem_euclid(2.0 * length);
        let x = if phase <= length {
            a + phase
        } else {
            b - (phase - length)
        };
        [x, self.drift as f64 * DRIFT_SPACING_M + self.lateral_m]
    }

    fn in_collapse(&self, t: f64) -> bool {
        let [x, _] = self.position_m(t);
        self.drift == COLLAPSE_DRIFT && (COLLAPSE_X_M[0]..=COLLAPSE_X_M[1]).contains(&x)
    }
}

fn walkers(rng: &mut ChaCha8Rng) -> Vec<Walker> {
    (0..TAGS)
        .map(|i| {
            let speed_mps = rng.gen_range(0.8..1.5);
            let lateral_m = rng.gen_range(-1.5..1.5);
            if i < ENTERING_TAGS {
                // heading east into the collapse from 60–140 m before it
                Walker {
                    drift: COLLAPSE_DRIFT,
                    lateral_m,
                    start_x_m: rng.gen_range(260.0..340.0),
                    speed_mps,
                    limits_m: [250.0, 560.0],
                    direction: 1.0,
                }
            } else {
                let drift = i % DRIFTS;
                // the others on drift 3 stay west of the collapse
                let limits_m = if drift == COLLAPSE_DRIFT {
                    [10.0, 380.0]
                } else {
                    [10.0, 590.0]
                };
                Walker {
                    drift,
                    lateral_m,
                    start_x_m: rng.gen_range(limits_m[0]..limits_m[1]),
                    speed_mps,
                    limits_m,
                    direction: if rng.gen_bool(0.5) { 1.0 } else { -1.0 },
                }
            }
        })
        .collect()
}

/// Every scan of every miner, in time order.
fn scans(readers: &[Reader], walkers: &[Walker], rng: &mut ChaCha8Rng) -> Vec<Record> {
    let shadowing = Normal::new(0.0, 3.0).unwrap();
    let phases: Vec<f64> = walkers.iter().map(|_| rng.gen_range(0.0..1.0)).collect();
    let mut records = Vec::new();
    for second in 0..DURATION_S as usize {
        let mut batch: Vec<(f64, usize)> = phases
            .iter()
            .enumerate()
            .map(|(i, phase)| (second as f64 + phase, i))
            .collect();
        batch.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t, i) in batch {
            let walker = &walkers[i];
            if walker.in_collapse(t) {
                continue;
            }
            let p = walker.position_m(t);
            for reader in readers.iter().filter(|r| r.working) {
                let d = ((p[0] - reader.position_m[0]).powi(2) + (p[1] - reader.position_m[1]).powi(2)).sqrt();
                if d > 60.0 {
                    continue;
                }
                // ρ = −40 − 30 log₁₀ d + X
                let rssi_dbm = -40.0 - 30.0 * d.max(0.1).log10() + shadowing.sample(rng);
                if rssi_dbm >= -82.0 {
                    records.push(Record {
                        time_s: t,
                        tag: format!("miner-{i:03}"),
                        measurement: Measurement::Rssi {
                            anchor: reader.id.clone(),
                            rssi_dbm,
                        },
                    });
                }
            }
        }
    }
    records
}

#[test]
fn a_mine_of_600_miners_and_307_readers_alarms_before_the_collapse_with_no_position_loss() {
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let readers = readers();
    assert_eq!(readers.len(), 307);
    let site = Site::from_toml_str(&site_toml(&readers), "mine.toml").unwrap();
    let walkers = walkers(&mut rng);
    let records = scans(&readers, &walkers, &mut rng);
    let mut tracker = Tracker::new(&site).unwrap();
    let mut out = Output::default();
    for record in records.iter().cloned() {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let tag_index = |tag: &str| tag["miner-".len()..].parse::<usize>().unwrap();

    // every miner is tracked
    assert_eq!(tracker.track_count(), TAGS);

    // PEL = 0 (seed 000): from each miner's first confirmed update, every 1-s positioning
    // cycle of his scanner has an output — measured, predicted while coasting, or the kept
    // position while lost
    let mut times: Vec<Vec<(f64, bool)>> = vec![Vec::new(); TAGS];
    for update in &out.updates {
        let confirmed = update.status != rtls_engine::lifecycle::TrackStatus::Tentative;
        times[tag_index(&update.tag)].push((update.time_s, confirmed));
    }
    let (mut missing, mut cycles, mut predicted) = (0, 0, 0);
    for (i, outputs) in times.iter().enumerate() {
        let first = outputs
            .iter()
            .find(|(_, c)| *c)
            .map(|(t, _)| *t)
            .unwrap_or(f64::INFINITY);
        assert!(first < 10.0, "miner {i} confirmed only at {first}");
        let mut start = first - 1e-6;
        while start + 1.0 <= DURATION_S - 1.0 {
            cycles += 1;
            if !outputs.iter().any(|(t, _)| *t >= start && *t < start + 1.0) {
                missing += 1;
            }
            start += 1.0;
        }
    }
    predicted += out.updates.iter().filter(|u| u.predicted).count();
    assert_eq!(missing, 0, "PEL = {missing}/{cycles}");
    assert!(predicted > 0);

    // no miner is lost while in coverage: lost only in the collapse, after the coast timeout
    for event in &out.events {
        if let Event::Lifecycle {
            tag,
            time_s,
            event: rtls_engine::lifecycle::LifecycleEvent::Lost,
            ..
        } = event
        {
            let walker = &walkers[tag_index(tag)];
            // silent for the coast timeout, most of it (all but the last scans before the
            // border, which may go unheard) inside the collapse
            let silent_since = time_s - COAST_TIMEOUT_S;
            assert!(
                walker.in_collapse(silent_since + 3.0) && walker.in_collapse(*time_s - 0.5),
                "{tag} lost at {time_s} s outside the collapse"
            );
        }
    }

    // predictive alarms: every miner who walks in is warned first, with a lead time
    let mut leads = Vec::new();
    for (i, walker) in walkers.iter().enumerate().take(ENTERING_TAGS) {
        // truth entry: first time in the collapse (0.01 s resolution)
        let entry_s = (0..(DURATION_S * 100.0) as usize)
            .map(|k| k as f64 / 100.0)
            .find(|&t| walker.in_collapse(t))
            .expect("an entering miner enters");
        let tag = format!("miner-{i:03}");
        let alarm_s = out
            .events
            .iter()
            .find_map(|e| match e {
                Event::HazardPredicted {
                    tag: t, zone, time_s, ..
                } if **t == *tag && zone == "collapse" => Some(*time_s),
                _ => None,
            })
            .unwrap_or_else(|| panic!("{tag}: no alarm before entering at {entry_s} s"));
        assert!(
            alarm_s < entry_s - 2.0,
            "{tag}: alarm at {alarm_s} s, entry at {entry_s} s"
        );
        leads.push(entry_s - alarm_s);
        assert!(
            out.events
                .iter()
                .any(|e| matches!(e, Event::NoCoverage { tag: t, zone, .. } if **t == *tag && zone == "collapse")),
            "{tag}: no no-coverage event"
        );
    }
    leads.sort_by(f64::total_cmp);
    let median = leads[leads.len() / 2];
    eprintln!(
        "mine: {} records, {} updates, alarm lead min {:.1} s median {median:.1} s",
        records.len(),
        out.updates.len(),
        leads[0]
    );
    assert!(median > 5.0, "median lead {median}");

    // drift-3 miners who turn back 20 m short of the collapse may be warned (they were heading
    // into danger within the horizon); miners of other drifts only through a cross-track error
    // of ~20 m, which readers along one line allow without a tunnel map (issue 7's map
    // constraint): count both, and bound the second
    let (mut near_misses, mut other_drifts) = (0, 0);
    for event in &out.events {
        if let Event::HazardPredicted { tag, .. } = event {
            let i = tag_index(tag);
            if i >= ENTERING_TAGS {
                if walkers[i].drift == COLLAPSE_DRIFT {
                    near_misses += 1;
                } else {
                    other_drifts += 1;
                }
            }
        }
    }
    eprintln!("mine: alarms for {near_misses} drift-3 miners who turned back short, {other_drifts} on other drifts");
    assert!(other_drifts <= 6, "{other_drifts} miners of other drifts warned (1 %)");
}
