//! Seed 000's obstacle analysis on the engine: a simulated mine where parked equipment next to
//! six readers attenuates their links, tracked by the tightly coupled EKF; the survey of the
//! records against the tracks must find those readers and the shadowed cells, and its
//! correction table must undo the attenuation.
//!
//! Layout: three parallel drifts 300 m long (centre lines y = 5, 45, 85 m, inside one row of
//! 10 m survey cells each), a reader every 15 m on alternating walls (±2.5 m): 63 readers.
//! Radio: `ρ = −40 dBm − 30 log₁₀ d + N(0, 3²)`, heard when `ρ ≥ −82 dBm` (median range 25 m),
//! one scan per miner per second; 60 miners walk back and forth for 120 s.
//!
//! Obstacles: next to six readers, on one side along the drift, equipment adds 8–12 dB of loss
//! to the reader's links with tags from 2 m to 30 m on that side (the radio shadow). With the
//! extra loss those tags are heard out to about 12 m only.
//!
//! Truth for the scores: a reader is degraded when it has an obstacle. A (cell, reader) entry
//! is a correct flag when the cell's x-interval overlaps its reader's shadow (same drift), and
//! it counts towards recall when at least half of the cell's x-interval is shadowed and the
//! entry has enough residuals to be scored.

use std::collections::HashMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::survey::{residuals, samples_from_updates, SurveyMap, SurveySettings};
use rtls_engine::tracker::{Output, TrackUpdate, Tracker};

const DRIFTS: usize = 3;
const DRIFT_Y_M: [f64; DRIFTS] = [5.0, 85.0, 165.0];
const DRIFT_LENGTH_M: f64 = 300.0;
const READER_SPACING_M: f64 = 15.0;
const READERS_PER_DRIFT: usize = 21;
const TAGS: usize = 60;
const DURATION_S: usize = 600;
const SHADOW_START_M: f64 = 2.0;
const SHADOW_END_M: f64 = 30.0;
const DETECTION_DBM: f64 = -88.0;

/// `(drift, reader index along it, side +1 east / −1 west, extra loss dB)`.
const OBSTACLES: [(usize, usize, f64, f64); 6] = [
    (0, 4, 1.0, 10.0),
    (0, 13, -1.0, 8.0),
    (1, 7, 1.0, 12.0),
    (1, 16, -1.0, 9.0),
    (2, 3, 1.0, 11.0),
    (2, 11, -1.0, 10.0),
];

struct Reader {
    id: String,
    drift: usize,
    position_m: [f64; 2],
    /// `(side, loss dB)` of its obstacle.
    obstacle: Option<(f64, f64)>,
}

impl Reader {
    /// The x-interval of its radio shadow, m.
    fn shadow_m(&self) -> Option<[f64; 2]> {
        let (side, _) = self.obstacle?;
        let x = self.position_m[0];
        Some(if side > 0.0 {
            [x + SHADOW_START_M, x + SHADOW_END_M]
        } else {
            [x - SHADOW_END_M, x - SHADOW_START_M]
        })
    }

    /// The extra loss on its link with a tag at `p`, dB.
    fn extra_loss_db(&self, p: [f64; 2], drift: usize) -> f64 {
        match (self.obstacle, self.shadow_m()) {
            (Some((_, loss)), Some([a, b])) if drift == self.drift && (a..=b).contains(&p[0]) => loss,
            _ => 0.0,
        }
    }
}

fn readers() -> Vec<Reader> {
    let mut readers = Vec::new();
    for (drift, y) in DRIFT_Y_M.iter().enumerate() {
        for k in 0..READERS_PER_DRIFT {
            let wall = if k % 2 == 0 { -2.5 } else { 2.5 };
            let obstacle = OBSTACLES.iter().find(|o| o.0 == drift && o.1 == k).map(|o| (o.2, o.3));
            readers.push(Reader {
                id: format!("D{drift}-{k:02}"),
                drift,
                position_m: [k as f64 * READER_SPACING_M, y + wall],
                obstacle,
            });
        }
    }
    readers
}

fn site(readers: &[Reader]) -> Site {
    let mut text = String::new();
    for r in readers {
        text.push_str(&format!(
            "[[readers]]\nid = \"{}\"\nposition_m = [{}, {}]\ntechnology = \"rfid\"\n\
             radio = {{ path_loss = {{ reference_power_dbm = -40.0, exponent = 3.0, shadowing_std_db = 3.0, reference_distance_m = 1.0 }} }}\n",
            r.id, r.position_m[0], r.position_m[1]
        ));
    }
    text.push_str(
        "[tracker]\npipeline = \"tightly-coupled\"\nmotion_model = \"cv\"\nfilter = \"ekf\"\n\
         acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.99\n\
         initiation = { confirm_updates = 3, within_s = 5.0 }\ncoast_timeout_s = 10.0\n\
         delete_timeout_s = 120.0\nreorder_window_s = 1.0\noutput_interval_s = 1.0\n",
    );
    Site::from_toml_str(&text, "obstacles.toml").unwrap()
}

/// A miner walking back and forth along a drift.
#[derive(Debug, Clone, Copy)]
struct Walker {
    drift: usize,
    lateral_m: f64,
    start_x_m: f64,
    speed_mps: f64,
    direction: f64,
}

impl Walker {
    fn position_m(&self, t: f64) -> [f64; 2] {
        let (a, b) = (5.0, DRIFT_LENGTH_M - 5.0);
        let length = b - a;
        let travelled = self.start_x_m - a + self.direction * self.speed_mps * t;
        let phase = travelled.rem_euclid(2.0 * length);
        let x = if phase <= length {
            a + phase
        } else {
            b - (phase - length)
        };
        [x, DRIFT_Y_M[self.drift] + self.lateral_m]
    }
}

/// One simulated shift: walkers, their scans in time order, and the truth of each record.
struct Run {
    walkers: Vec<Walker>,
    records: Vec<Record>,
}

fn simulate(readers: &[Reader], seed: u64) -> Run {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let walkers: Vec<Walker> = (0..TAGS)
        .map(|i| Walker {
            drift: i % DRIFTS,
            lateral_m: rng.gen_range(-1.5..1.5),
            start_x_m: rng.gen_range(5.0..DRIFT_LENGTH_M - 5.0),
            speed_mps: rng.gen_range(0.8..1.5),
            direction: if rng.gen_bool(0.5) { 1.0 } else { -1.0 },
        })
        .collect();
    let shadowing = Normal::new(0.0, 3.0).unwrap();
    let phases: Vec<f64> = walkers.iter().map(|_| rng.gen_range(0.0..1.0)).collect();
    let mut records = Vec::new();
    for second in 0..DURATION_S {
        let mut batch: Vec<(f64, usize)> = phases.iter().enumerate().map(|(i, p)| (second as f64 + p, i)).collect();
        batch.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t, i) in batch {
            let walker = &walkers[i];
            let p = walker.position_m(t);
            for reader in readers {
                let d = ((p[0] - reader.position_m[0]).powi(2) + (p[1] - reader.position_m[1]).powi(2)).sqrt();
                if d > 100.0 {
                    continue;
                }
                // ρ = −40 − 30 log₁₀ d − L + X
                let rssi_dbm = -40.0 - 30.0 * d.max(0.1).log10() - reader.extra_loss_db(p, walker.drift)
                    + shadowing.sample(&mut rng);
                if rssi_dbm >= DETECTION_DBM {
                    records.push(Record {
                        time_s: t,
                        tag: format!("miner-{i:02}"),
                        measurement: Measurement::Rssi {
                            anchor: reader.id.clone(),
                            rssi_dbm,
                        },
                    });
                }
            }
        }
    }
    Run { walkers, records }
}

fn track(site: &Site, records: impl IntoIterator<Item = Record>) -> Vec<TrackUpdate> {
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out.updates
}

/// Tracks the records, correcting each with the map at its tag's last reported position (the
/// live use of the table); returns the updates and how many records had no position yet.
fn track_corrected(site: &Site, records: &[Record], map: &SurveyMap) -> (Vec<TrackUpdate>, usize) {
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    let mut last: HashMap<String, [f64; 2]> = HashMap::new();
    let mut updates = Vec::new();
    let mut uncorrected = 0;
    for record in records {
        let corrected = match last.get(&record.tag) {
            Some(&p) => map.correct_record(record, p),
            None => {
                uncorrected += 1;
                record.clone()
            }
        };
        tracker.push(corrected, &mut out).unwrap();
        for u in &out.updates {
            last.insert(u.tag.to_string(), [u.position_m[0], u.position_m[1]]);
        }
        updates.append(&mut out.updates);
        out.clear();
    }
    tracker.finish(&mut out).unwrap();
    updates.append(&mut out.updates);
    (updates, uncorrected)
}

fn survey(site: &Site, records: &[Record], updates: &[TrackUpdate], settings: &SurveySettings) -> SurveyMap {
    let found = residuals(site, records, &samples_from_updates(updates), settings).unwrap();
    let matched = found.residuals.len() as f64 / (found.residuals.len() + found.unmatched.total()) as f64;
    eprintln!(
        "obstacles: {} residuals ({:.1} % of the readings), unmatched {:?}",
        found.residuals.len(),
        100.0 * matched,
        found.unmatched
    );
    assert!(matched > 0.9, "{matched}");
    SurveyMap::build(&found.residuals, settings).unwrap()
}

/// Half-width of the band around a drift's centre line where its tags may be tracked, m
/// (readers along one line leave the cross-track position weakly observed).
const BAND_HALF_WIDTH_M: f64 = 10.0;

/// Fraction of cell `bounds`' x-interval inside the reader's shadow, when the cell lies in the
/// band of the reader's drift (else 0).
fn shadowed_fraction(reader: &Reader, bounds: [f64; 4]) -> f64 {
    let Some([a, b]) = reader.shadow_m() else {
        return 0.0;
    };
    let y = DRIFT_Y_M[reader.drift];
    if bounds[3] <= y - BAND_HALF_WIDTH_M || bounds[2] >= y + BAND_HALF_WIDTH_M {
        return 0.0;
    }
    ((b.min(bounds[1]) - a.max(bounds[0])) / (bounds[1] - bounds[0])).max(0.0)
}

/// Whether the cell is on the drift's centre line and more than half of it is in the shadow.
fn mostly_shadowed(reader: &Reader, bounds: [f64; 4]) -> bool {
    (bounds[2]..bounds[3]).contains(&DRIFT_Y_M[reader.drift]) && shadowed_fraction(reader, bounds) > 0.5
}

/// Precision and recall of a map's flags against the truth.
#[derive(Debug)]
struct Scores {
    reader_precision: f64,
    reader_recall: f64,
    cell_precision: f64,
    cell_recall: f64,
    /// Mostly shadowed cell entries with enough residuals to be scored.
    testable_cells: usize,
    flagged_cells: usize,
}

fn scores(readers: &[Reader], map: &SurveyMap) -> Scores {
    let by_id: HashMap<&str, &Reader> = readers.iter().map(|r| (r.id.as_str(), r)).collect();
    let bounds = |cell| map.settings().cell_bounds_m(cell);
    let flagged: Vec<&str> = map.flagged_readers().iter().map(|e| e.reader.as_str()).collect();
    let true_readers = flagged.iter().filter(|id| by_id[*id].obstacle.is_some()).count();
    let flagged_cells = map.flagged_cells();
    let true_cells = flagged_cells
        .iter()
        .filter(|e| shadowed_fraction(by_id[e.reader.as_str()], bounds(e.cell)) > 0.0)
        .count();
    for e in flagged_cells
        .iter()
        .filter(|e| shadowed_fraction(by_id[e.reader.as_str()], bounds(e.cell)) == 0.0)
    {
        eprintln!(
            "obstacles: flag outside the shadows: {} in {:?}, n {}, bias {:.2} dB, z {:.1}",
            e.reader,
            bounds(e.cell),
            e.summary.count,
            e.summary.bias,
            e.summary.z.unwrap_or(f64::NAN)
        );
    }
    let testable: Vec<bool> = map
        .cells()
        .iter()
        .filter(|e| e.summary.z.is_some() && mostly_shadowed(by_id[e.reader.as_str()], bounds(e.cell)))
        .map(|e| e.summary.degraded.any())
        .collect();
    Scores {
        reader_precision: true_readers as f64 / flagged.len().max(1) as f64,
        reader_recall: true_readers as f64 / OBSTACLES.len() as f64,
        cell_precision: true_cells as f64 / flagged_cells.len().max(1) as f64,
        cell_recall: testable.iter().filter(|f| **f).count() as f64 / testable.len().max(1) as f64,
        testable_cells: testable.len(),
        flagged_cells: flagged_cells.len(),
    }
}

/// Median bias of the scored cell entries outside every shadow whose mean distance to their
/// reader is in `[from, to)` m, dB.
fn unobstructed_median_bias_db(readers: &[Reader], map: &SurveyMap, [from, to]: [f64; 2]) -> f64 {
    let by_id: HashMap<&str, &Reader> = readers.iter().map(|r| (r.id.as_str(), r)).collect();
    let mut biases: Vec<f64> = map
        .cells()
        .iter()
        .filter(|e| e.summary.z.is_some() && (from..to).contains(&e.summary.distance_m))
        .filter(|e| shadowed_fraction(by_id[e.reader.as_str()], map.settings().cell_bounds_m(e.cell)) == 0.0)
        .map(|e| e.summary.bias)
        .collect();
    biases.sort_by(f64::total_cmp);
    biases[biases.len() / 2]
}

#[test]
fn the_survey_finds_the_attenuated_readers_and_their_shadowed_cells() {
    let readers = readers();
    assert_eq!(readers.len(), 63);
    let site = site(&readers);
    let run = simulate(&readers, 2026);
    let updates = track(&site, run.records.iter().cloned());
    let settings = SurveySettings::default();
    let map = survey(&site, &run.records, &updates, &settings);
    let found = scores(&readers, &map);
    eprintln!(
        "obstacles: readers flagged {:?}",
        map.flagged_readers()
            .iter()
            .map(|e| format!("{} ({})", e.reader, e.summary.degraded.name()))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "obstacles: readers precision {:.2} recall {:.2}; cells: {} entries ({} scored), {} flagged, precision {:.2}, \
         recall {:.2} over {} mostly shadowed scored entries",
        found.reader_precision,
        found.reader_recall,
        map.cells().len(),
        map.cells().iter().filter(|e| e.summary.z.is_some()).count(),
        found.flagged_cells,
        found.cell_precision,
        found.cell_recall,
        found.testable_cells
    );
    assert!(found.reader_precision >= 0.8 && found.reader_recall >= 0.8, "{found:?}");
    assert!(found.cell_precision >= 0.8 && found.cell_recall >= 0.8, "{found:?}");
    assert!(found.testable_cells >= 2 * OBSTACLES.len(), "{found:?}");

    // an obstacle reader's own bias, over all its links, is diluted by its unshadowed side:
    // the readers are found through their cells
    for entry in map
        .readers()
        .iter()
        .filter(|e| readers.iter().any(|r| r.id == e.reader && r.obstacle.is_some()))
    {
        eprintln!(
            "obstacles: {} over all links: bias {:.2} dB, z {:.1}, {} flagged cells",
            entry.reader,
            entry.summary.bias,
            entry.summary.z.unwrap_or(f64::NAN),
            entry.flagged_cells
        );
        assert!(entry.flagged_cells >= 1 && entry.summary.degraded.cells);
    }

    // why cells are compared within distance bands: the detection threshold (−88 dBm) lets
    // only the stronger readings through far from a reader, so unobstructed biases grow with
    // distance, and one population for all distances has a median above that of the near
    // cells, where the obstacles' shadows are (printed for comparison)
    let near = unobstructed_median_bias_db(&readers, &map, [0.0, 20.0]);
    let far = unobstructed_median_bias_db(&readers, &map, [40.0, 60.0]);
    let one_population = SurveySettings {
        distance_band_m: None,
        ..settings
    };
    let unbanded = scores(&readers, &survey(&site, &run.records, &updates, &one_population));
    eprintln!(
        "obstacles: unobstructed median bias {near:.2} dB within 20 m, {far:.2} dB at 40–60 m; one population \
         for all distances: readers precision {:.2} recall {:.2}, cells {} flagged, precision {:.2} recall {:.2}",
        unbanded.reader_precision,
        unbanded.reader_recall,
        unbanded.flagged_cells,
        unbanded.cell_precision,
        unbanded.cell_recall
    );
    assert!(far > near + 2.0, "{near} {far}");
}

/// 2-D errors of the non-predicted updates after each tag's first 10 s, split into those
/// whose true position is in a radio shadow and the others: `(shadow RMSE, other RMSE)`, m.
fn rmse_in_and_out_of_shadows(readers: &[Reader], run: &Run, updates: &[TrackUpdate]) -> (f64, f64, usize) {
    let mut first: HashMap<&str, f64> = HashMap::new();
    let (mut inside, mut outside) = ((0.0, 0usize), (0.0, 0usize));
    for u in updates.iter().filter(|u| !u.predicted) {
        let start = *first.entry(&u.tag).or_insert(u.time_s);
        if u.time_s < start + 10.0 {
            continue;
        }
        let walker = &run.walkers[u.tag["miner-".len()..].parse::<usize>().unwrap()];
        let truth = walker.position_m(u.time_s);
        let e2 = (u.position_m[0] - truth[0]).powi(2) + (u.position_m[1] - truth[1]).powi(2);
        let shadowed = readers.iter().any(|r| r.extra_loss_db(truth, walker.drift) > 0.0);
        let sum = if shadowed { &mut inside } else { &mut outside };
        sum.0 += e2;
        sum.1 += 1;
    }
    (
        (inside.0 / inside.1 as f64).sqrt(),
        (outside.0 / outside.1 as f64).sqrt(),
        inside.1,
    )
}

/// Mean bias of the scored entries on the drifts' centre lines that are mostly shadowed, dB.
fn shadowed_bias_db(readers: &[Reader], map: &SurveyMap) -> f64 {
    let by_id: HashMap<&str, &Reader> = readers.iter().map(|r| (r.id.as_str(), r)).collect();
    let biases: Vec<f64> = map
        .cells()
        .iter()
        .filter(|e| e.summary.z.is_some())
        .filter(|e| mostly_shadowed(by_id[e.reader.as_str()], map.settings().cell_bounds_m(e.cell)))
        .map(|e| e.summary.bias)
        .collect();
    assert!(biases.len() >= OBSTACLES.len(), "{}", biases.len());
    biases.iter().sum::<f64>() / biases.len() as f64
}

#[test]
fn the_learned_correction_removes_the_attenuation_and_improves_the_tracks_in_the_shadows() {
    let readers = readers();
    let site = site(&readers);
    let settings = SurveySettings::default();
    // learn on one shift
    let learning = simulate(&readers, 2026);
    let map = survey(
        &site,
        &learning.records,
        &track(&site, learning.records.iter().cloned()),
        &settings,
    );
    // apply to another
    let run = simulate(&readers, 2027);
    let plain = track(&site, run.records.iter().cloned());
    let (corrected, uncorrected) = track_corrected(&site, &run.records, &map);
    let corrected_records: Vec<Record> = {
        // the records as the corrected tracker saw them, for the second survey
        let mut last: HashMap<String, [f64; 2]> = HashMap::new();
        let mut updates = corrected.iter().peekable();
        run.records
            .iter()
            .map(|record| {
                while let Some(u) = updates.next_if(|u| u.time_s < record.time_s) {
                    last.insert(u.tag.to_string(), [u.position_m[0], u.position_m[1]]);
                }
                last.get(&record.tag)
                    .map_or_else(|| record.clone(), |&p| map.correct_record(record, p))
            })
            .collect()
    };
    let (shadow_before, elsewhere_before, shadow_count) = rmse_in_and_out_of_shadows(&readers, &run, &plain);
    let (shadow_after, elsewhere_after, _) = rmse_in_and_out_of_shadows(&readers, &run, &corrected);
    let bias_before = shadowed_bias_db(&readers, &survey(&site, &run.records, &plain, &settings));
    let bias_after = shadowed_bias_db(&readers, &survey(&site, &corrected_records, &corrected, &settings));
    eprintln!(
        "obstacles: correction ({uncorrected} records before their tag had a position): RMSE in the shadows \
         ({shadow_count} updates) {shadow_before:.2} → {shadow_after:.2} m, elsewhere {elsewhere_before:.2} → \
         {elsewhere_after:.2} m; mean bias of the shadowed cells {bias_before:.2} → {bias_after:.2} dB"
    );
    assert!(shadow_after < 0.9 * shadow_before, "{shadow_before} → {shadow_after}");
    assert!(
        elsewhere_after < 1.05 * elsewhere_before,
        "{elsewhere_before} → {elsewhere_after}"
    );
    assert!(
        bias_after.abs() < 0.3 * bias_before.abs(),
        "{bias_before} → {bias_after}"
    );

    // why only flagged entries correct by default: off-drift cells, where the tracker's
    // cross-track error put the tags, learn that error, and correcting with them confirms it
    let everything = SurveySettings {
        correct_unflagged: true,
        ..settings
    };
    let map_all = survey(
        &site,
        &learning.records,
        &track(&site, learning.records.iter().cloned()),
        &everything,
    );
    let (all, _) = track_corrected(&site, &run.records, &map_all);
    let (shadow_all, elsewhere_all, _) = rmse_in_and_out_of_shadows(&readers, &run, &all);
    eprintln!(
        "obstacles: correcting with every entry instead: RMSE in the shadows {shadow_all:.2} m, elsewhere {elsewhere_all:.2} m"
    );
    assert!(shadow_all > shadow_after && elsewhere_all > elsewhere_after);
}
