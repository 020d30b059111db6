//! Negative information, the corridor map and the speed limit end to end (seed 000's manager
//! layer): a miner walks a mine section — east along drift A, north through the cross-cut, east
//! along drift B into a roof fall where no reader hears him — while wall readers report RSSI
//! (log-distance, 3 dB shadowing, −82 dBm sensitivity, nothing through the rock between drifts).
//! The map holds the estimate in the tunnels while the miner is heard; once nobody hears him,
//! only the silent readers on either side of the fall say where he is.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// Drift A at y = 0, drift B at y = 40, both x ∈ [0, 300]; the cross-cut at x = 150.
const DRIFT_B_Y_M: f64 = 40.0;
const CROSS_CUT_X_M: f64 = 150.0;
const LENGTH_M: f64 = 300.0;
/// The roof fall on drift B, `[west, east]` along x: nobody hears the miner inside, and its
/// readers are broken.
const FALL_X_M: [f64; 2] = [200.0, 232.0];
/// Where the miner stops, inside the fall, m.
const STOP_X_M: f64 = 215.0;
const HALF_WIDTH_M: f64 = 2.5;
const SPEED_MPS: f64 = 1.2;
/// Length of the run, s.
const SECONDS: usize = 320;
/// The miner walks this far left of the centreline (he keeps to one side), m.
const OFFSET_M: f64 = 0.8;
const P0_DBM: f64 = -40.0;
const EXPONENT: f64 = 3.0;
const SHADOWING_DB: f64 = 3.0;
const SENSITIVITY_DBM: f64 = -82.0;

/// Which corridors a point is in: drift A, drift B, the cross-cut.
fn corridors_of(p: [f64; 2]) -> [bool; 3] {
    [
        p[1].abs() <= HALF_WIDTH_M,
        (p[1] - DRIFT_B_Y_M).abs() <= HALF_WIDTH_M,
        (p[0] - CROSS_CUT_X_M).abs() <= HALF_WIDTH_M && (-HALF_WIDTH_M..=DRIFT_B_Y_M + HALF_WIDTH_M).contains(&p[1]),
    ]
}

/// Whether `p` is inside the roof fall.
fn in_fall(p: [f64; 2]) -> bool {
    (p[1] - DRIFT_B_Y_M).abs() <= HALF_WIDTH_M && (FALL_X_M[0]..=FALL_X_M[1]).contains(&p[0])
}

/// Readers: `(id, position, working)`, every 15 m on alternating walls of both drifts and every
/// 10 m in the cross-cut; those of drift B inside the fall are broken.
fn readers() -> Vec<(String, [f64; 2], bool)> {
    let mut out = Vec::new();
    let wall = |k: usize| {
        if k.is_multiple_of(2) {
            -HALF_WIDTH_M
        } else {
            HALF_WIDTH_M
        }
    };
    for k in 0..=20 {
        let x = 15.0 * k as f64;
        out.push((format!("A{k:02}"), [x, wall(k)], true));
        out.push((
            format!("B{k:02}"),
            [x, DRIFT_B_Y_M + wall(k)],
            !in_fall([x, DRIFT_B_Y_M]),
        ));
    }
    for k in 1..4 {
        out.push((format!("X{k}"), [CROSS_CUT_X_M + wall(k), 10.0 * k as f64], true));
    }
    out
}

/// The miner at `t`: east along A from x = 10, north up the cross-cut, east along B into the
/// fall, then standing there.
fn miner(t: f64) -> [f64; 2] {
    let legs = [CROSS_CUT_X_M - 10.0, DRIFT_B_Y_M, STOP_X_M - CROSS_CUT_X_M];
    let s = (SPEED_MPS * t).min(legs.iter().sum());
    if s <= legs[0] {
        [10.0 + s, OFFSET_M]
    } else if s <= legs[0] + legs[1] {
        [CROSS_CUT_X_M - OFFSET_M, s - legs[0]]
    } else {
        [CROSS_CUT_X_M + s - legs[0] - legs[1], DRIFT_B_Y_M + OFFSET_M]
    }
}

/// Which parts of the site file to write.
#[derive(Clone, Copy)]
struct Knowledge {
    corridors: bool,
    sensitivity: bool,
    max_speed: bool,
}

fn site(knowledge: Knowledge) -> Site {
    let sensitivity = if knowledge.sensitivity {
        format!(", sensitivity_dbm = {SENSITIVITY_DBM}")
    } else {
        String::new()
    };
    let mut text = String::new();
    for (id, [x, y], working) in readers() {
        text.push_str(&format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{x}, {y}]\ntechnology = \"rfid\"\nworking = {working}\n\
             radio = {{ path_loss = {{ reference_power_dbm = {P0_DBM}, exponent = {EXPONENT}, \
             shadowing_std_db = {SHADOWING_DB}, reference_distance_m = 1.0 }}{sensitivity} }}\n"
        ));
    }
    if knowledge.corridors {
        text.push_str(&format!(
            "[[corridors]]\nid = \"A\"\npoints_m = [[0.0, 0.0], [{LENGTH_M}, 0.0]]\nhalf_width_m = {HALF_WIDTH_M}\n\
             [[corridors]]\nid = \"B\"\npoints_m = [[0.0, {DRIFT_B_Y_M}], [{LENGTH_M}, {DRIFT_B_Y_M}]]\n\
             half_width_m = {HALF_WIDTH_M}\n\
             [[corridors]]\nid = \"X\"\npoints_m = [[{CROSS_CUT_X_M}, 0.0], [{CROSS_CUT_X_M}, {DRIFT_B_Y_M}]]\n\
             half_width_m = {HALF_WIDTH_M}\n"
        ));
    }
    text.push_str(
        "[tracker]\nplatform = \"walker\"\nacceleration_noise_std_mps2 = 0.3\ncoast_timeout_s = 60.0\n\
         delete_timeout_s = 120.0\nreorder_window_s = 0.0\n",
    );
    if knowledge.max_speed {
        text.push_str("max_speed_mps = 2.0\n");
    }
    let mut site = Site::from_toml_str(&text, "mine-section.toml").unwrap();
    if !knowledge.max_speed {
        // nor the walker's default limit
        site.tracker.max_speed_mps = None;
    }
    site
}

/// One scan a second for `seconds`: every working reader sharing a corridor with the miner
/// reports `ρ = P₀ − 10 n log₁₀ d + X` if it reaches the sensitivity; nothing inside the fall.
fn scans(seed: u64, seconds: usize) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let shadowing = Normal::new(0.0, SHADOWING_DB).unwrap();
    let readers = readers();
    let mut records = Vec::new();
    for k in 0..seconds {
        let t = k as f64;
        let p = miner(t);
        if in_fall(p) {
            continue;
        }
        let inside = corridors_of(p);
        for (id, r, working) in &readers {
            let shared = corridors_of(*r).iter().zip(inside).any(|(a, b)| *a && b);
            if !working || !shared {
                continue;
            }
            let d = (p[0] - r[0]).hypot(p[1] - r[1]).max(0.1);
            let rssi_dbm = P0_DBM - 10.0 * EXPONENT * d.log10() + shadowing.sample(&mut rng);
            if rssi_dbm >= SENSITIVITY_DBM {
                records.push(Record {
                    time_s: t,
                    tag: "miner".into(),
                    measurement: Measurement::Rssi {
                        anchor: id.clone(),
                        rssi_dbm,
                    },
                });
            }
        }
    }
    records
}

/// RMSE of the outputs (updates and coasting predictions) while the miner is heard and while
/// he is inside the fall, and the share of all outputs whose 95 % ellipse holds the truth.
struct Score {
    heard_rmse_m: f64,
    fall_rmse_m: f64,
    in95: f64,
}

fn score(out: &Output) -> Score {
    let (mut count, mut inside, mut fall_sum, mut fall_count) = (0usize, 0usize, 0.0, 0usize);
    let mut heard = (0.0, 0usize);
    for u in out.updates.iter().filter(|u| u.time_s >= 10.0) {
        let truth = miner(u.time_s);
        let e = [u.position_m[0] - truth[0], u.position_m[1] - truth[1]];
        let e2 = e[0] * e[0] + e[1] * e[1];
        count += 1;
        // NEES = eᵀ P⁻¹ e ≤ χ²₂(0.95) = 5.991
        inside += usize::from(super::tests::horizontal_nees(u, e) <= 5.991);
        if in_fall(truth) {
            fall_sum += e2;
            fall_count += 1;
        } else {
            heard.0 += e2;
            heard.1 += 1;
        }
    }
    assert!(
        count > 200 && fall_count > 10,
        "{count} outputs, {fall_count} in the fall"
    );
    Score {
        heard_rmse_m: (heard.0 / heard.1 as f64).sqrt(),
        fall_rmse_m: (fall_sum / fall_count as f64).sqrt(),
        in95: inside as f64 / count as f64,
    }
}

fn run(knowledge: Knowledge, records: &[Record]) -> Output {
    let mut tracker = Tracker::new(&site(knowledge)).unwrap();
    let mut out = Output::default();
    let end_s = records.last().map_or(0.0, |r| r.time_s);
    let mut next = records.iter().peekable();
    // the clock advances every second, heard or not (as `rtls serve` advances it)
    for k in 0..=SECONDS {
        let t = k as f64;
        while let Some(r) = next.next_if(|r| r.time_s <= t) {
            tracker.push(r.clone(), &mut out).unwrap();
        }
        if t > end_s {
            tracker.advance_to(t, &mut out).unwrap();
        }
    }
    tracker.finish(&mut out).unwrap();
    out
}

#[test]
fn the_map_and_silent_readers_keep_the_miner_in_the_tunnels_and_find_him_behind_the_fall() {
    // 245 m (204 s), the last 15 m inside the fall, then standing there for 2 minutes
    let records = scans(2000, SECONDS);
    let plain = Knowledge {
        corridors: false,
        sensitivity: false,
        max_speed: false,
    };
    let mapped = Knowledge {
        corridors: true,
        ..plain
    };
    let everything = Knowledge {
        corridors: true,
        sensitivity: true,
        max_speed: true,
    };
    let [p, m, e] = [plain, mapped, everything].map(|k| score(&run(k, &records)));
    eprintln!(
        "RMSE while heard / inside the fall, in 95 %: RSSI only {:.2} / {:.2} m, {:.3}; + corridors {:.2} / {:.2} m, \
         {:.3}; + silent readers and speed limit {:.2} / {:.2} m, {:.3}",
        p.heard_rmse_m,
        p.fall_rmse_m,
        p.in95,
        m.heard_rmse_m,
        m.fall_rmse_m,
        m.in95,
        e.heard_rmse_m,
        e.fall_rmse_m,
        e.in95
    );
    assert!(
        m.heard_rmse_m < 0.9 * p.heard_rmse_m,
        "heard: corridors {:.2} vs {:.2} m",
        m.heard_rmse_m,
        p.heard_rmse_m
    );
    assert!(
        e.fall_rmse_m < 0.3 * m.fall_rmse_m.min(p.fall_rmse_m),
        "in the fall: silence {:.2} vs {:.2} / {:.2} m",
        e.fall_rmse_m,
        m.fall_rmse_m,
        p.fall_rmse_m
    );
    assert!(
        e.heard_rmse_m <= 1.05 * m.heard_rmse_m,
        "heard: {:.2} vs {:.2} m",
        e.heard_rmse_m,
        m.heard_rmse_m
    );
    assert!(e.in95 > 0.85 && m.in95 > 0.85, "in 95 %: {:.3} / {:.3}", m.in95, e.in95);
}

#[test]
fn without_corridors_or_sensitivities_nothing_changes() {
    let records = scans(7, 100);
    let plain = Knowledge {
        corridors: false,
        sensitivity: false,
        max_speed: false,
    };
    let site_plain = site(plain);
    assert!(Tracker::new(&site_plain).unwrap().shared().constraints.is_none());
    let mut off = site(Knowledge {
        corridors: true,
        sensitivity: true,
        max_speed: false,
    });
    off.tracker.map.enabled = false;
    off.tracker.negative_information = false;
    let mut a = Tracker::new(&site_plain).unwrap();
    let mut b = Tracker::new(&off).unwrap();
    let (mut out_a, mut out_b) = (Output::default(), Output::default());
    for r in records {
        a.push(r.clone(), &mut out_a).unwrap();
        b.push(r, &mut out_b).unwrap();
    }
    a.finish(&mut out_a).unwrap();
    b.finish(&mut out_b).unwrap();
    assert_eq!(out_a.updates, out_b.updates);
}

/// 3-D tracking in a decline: a walker goes down a 10 % grade while UWB readers on the walls,
/// all about as high above the walking line as each other, range him. The ranges hardly see his
/// height (every reader is near the plane of the walk); the corridor's `heights_m` does.
#[test]
fn a_corridor_with_heights_holds_a_3d_estimate_on_its_walking_line() {
    const GRADE: f64 = -0.1;
    let height = |x: f64| 1.5 + GRADE * x;
    let mut text = String::new();
    for k in 0..=10 {
        let x = 10.0 * f64::from(k);
        let y = if k % 2 == 0 { -2.0 } else { 2.0 };
        let z = height(x) + if k % 4 < 2 { 0.8 } else { 1.2 };
        text.push_str(&format!(
            "[[readers]]\nid = \"R{k}\"\nposition_m = [{x}, {y}, {z}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = 0.3, bias_m = 0.0 }} }}\n"
        ));
    }
    let run = |heights: bool| {
        let mut site = text.clone();
        site.push_str("[[corridors]]\nid = \"decline\"\npoints_m = [[0.0, 0.0], [100.0, 0.0]]\nhalf_width_m = 2.0\n");
        if heights {
            site.push_str(&format!("heights_m = [{}, {}]\n", height(0.0), height(100.0)));
        }
        site.push_str(
            "[tracker]\nplatform = \"walker\"\ndimensions = 3\nreorder_window_s = 0.0\n\
             [tracker.map]\nvertical_std_m = 0.2\n",
        );
        let site = Site::from_toml_str(&site, "decline.toml").unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.3).unwrap();
        let mut tracker = Tracker::new(&site).unwrap();
        let mut out = Output::default();
        for step in 0..600 {
            let t = f64::from(step) * 0.1;
            let truth = [5.0 + 1.2 * t, 0.5, height(5.0 + 1.2 * t)];
            let k = step % 11;
            let anchor = site.reader(&format!("R{k}")).unwrap().position_xyz_m();
            let d = ((truth[0] - anchor[0]).powi(2) + (truth[1] - anchor[1]).powi(2) + (truth[2] - anchor[2]).powi(2))
                .sqrt();
            let measurement = Measurement::Range {
                anchor: format!("R{k}"),
                range_m: d + noise.sample(&mut rng),
                std_m: None,
                anchor_position_m: None,
            };
            let record = Record {
                time_s: t,
                tag: "w".into(),
                measurement,
            };
            tracker.push(record, &mut out).unwrap();
        }
        tracker.finish(&mut out).unwrap();
        // height error of the updates after the first 10 s
        let errors: Vec<f64> = out
            .updates
            .iter()
            .filter(|u| u.time_s > 10.0)
            .map(|u| u.position_m[2] - height(5.0 + 1.2 * u.time_s))
            .collect();
        assert!(errors.len() > 300, "{} updates", errors.len());
        (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
    };
    let (with, without) = (run(true), run(false));
    eprintln!("height RMSE: with heights_m {with:.3} m, without {without:.3} m");
    assert!(with < 0.25, "height RMSE on the walking line {with:.3} m");
    assert!(with < 0.5 * without, "with heights {with:.3} m, without {without:.3} m");
}

/// Whether `p` lies more than 1 m outside every corridor: in the rock.
fn in_rock(p: [f64; 3]) -> bool {
    let wide = HALF_WIDTH_M + 1.0;
    !(p[1].abs() <= wide
        || (p[1] - DRIFT_B_Y_M).abs() <= wide
        || ((p[0] - CROSS_CUT_X_M).abs() <= wide && (-wide..=DRIFT_B_Y_M + wide).contains(&p[1])))
}

#[test]
fn a_track_the_readers_cannot_see_moves_to_the_corridor_they_can_see() {
    // six walks; every output counted that sits in the rock between the drifts, where the
    // readers that heard the miner cannot see it (the restart at the epoch's fix, or the
    // estimate itself, moves to the corridor nearest it that they can see)
    let everything = Knowledge {
        corridors: true,
        sensitivity: true,
        max_speed: true,
    };
    let (mut outputs, mut rock, mut heard_sum) = (0usize, 0usize, 0.0);
    for seed in 1..=6 {
        let out = run(everything, &scans(seed, SECONDS));
        for u in out.updates.iter().filter(|u| u.time_s >= 10.0) {
            outputs += 1;
            rock += usize::from(in_rock(u.position_m));
        }
        heard_sum += score(&out).heard_rmse_m;
    }
    let share = rock as f64 / outputs as f64;
    eprintln!(
        "{rock} of {outputs} outputs in the rock ({:.2} %), mean RMSE while heard {:.2} m",
        100.0 * share,
        heard_sum / 6.0
    );
    // (before the move: 5 of 1 806, 0.28 %)
    assert_eq!(rock, 0, "{rock} of {outputs} outputs in the rock");
}

/// In fix-then-filter each fix closes an epoch, and the speed limit applies there: a track
/// whose fixes run away (fingerprints on the wrong floor) never reports, nor coasts at, more
/// than the limit. Without the limit the same fixes give it more than twice that.
#[test]
fn a_fix_then_filter_track_never_reports_more_than_the_speed_limit() {
    // 0.1 s apart: faster than the tracker reports
    let records = super::tests::running_fixes(0.1, 200);
    let fastest = |extra: &str| {
        let mut tracker = Tracker::new(&super::tests::site("fix-then-filter", "kf", extra)).unwrap();
        let out = super::tests::run(&mut tracker, records.clone());
        assert!(out.updates.iter().filter(|u| !u.predicted).count() >= 150);
        out.updates
            .iter()
            .map(|u| u.velocity_mps[0].hypot(u.velocity_mps[1]))
            .fold(0.0, f64::max)
    };
    let free = fastest("");
    assert!(free > 6.0, "fastest without a limit: {free} m/s");
    let limited = fastest("max_speed_mps = 3.0");
    assert!(limited <= 3.0 + 1e-9, "fastest with the 3 m/s limit: {limited} m/s");
}
