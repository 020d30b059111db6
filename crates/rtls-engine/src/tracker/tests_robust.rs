//! Robustness: random but valid record streams (random anchors, ranges with outliers and
//! gaps, odometry including standstill and exact headings, velocities, accelerometers, fixes)
//! through both pipelines and both motion models never abort the run and never output a
//! non-finite or diverged state.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// A site with `anchors` random readers in a 60 m × 60 m square at 0–5 m height.
fn random_site(rng: &mut ChaCha8Rng, pipeline: &str, filter: &str, motion_model: &str) -> (Site, Vec<[f64; 3]>) {
    let count = rng.gen_range(3..=6);
    let mut readers = String::new();
    let mut positions = Vec::new();
    for i in 0..count {
        let p = [
            rng.gen_range(0.0..60.0),
            rng.gen_range(0.0..60.0),
            rng.gen_range(0.0..5.0),
        ];
        positions.push(p);
        readers.push_str(&format!(
            "[[readers]]\nid = \"A{i}\"\nposition_m = [{}, {}, {}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }}\n",
            p[0], p[1], p[2]
        ));
    }
    let text = format!(
        r#"{readers}
[tracker]
pipeline = "{pipeline}"
motion_model = "{motion_model}"
filter = "{filter}"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 5.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.2
tag_height_m = 1.0
epoch_s = 0.06
"#
    );
    (Site::from_toml_str(&text, "random.toml").unwrap(), positions)
}

/// A random stream for two tags over `seconds`: 10 Hz range epochs with 10 % outliers and
/// random silences, odometry (a quarter at standstill, some with σ_θ = 0), velocities,
/// accelerometer samples and the odd fix.
fn random_records(rng: &mut ChaCha8Rng, anchors: &[[f64; 3]], seconds: f64) -> Vec<Record> {
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut records = Vec::new();
    for tag in ["t1", "t2"] {
        let mut p = [rng.gen_range(5.0..55.0), rng.gen_range(5.0..55.0)];
        let mut v = [0.0, 0.0];
        let mut t = 0.0;
        while t < seconds {
            // a random walk in velocity, kept inside the site
            for axis in 0..2 {
                v[axis] = (v[axis] + rng.gen_range(-0.3..0.3_f64)).clamp(-2.0, 2.0);
                p[axis] = (p[axis] + 0.1 * v[axis]).clamp(0.0, 60.0);
            }
            if rng.gen_bool(0.01) {
                // a silence of up to 30 s (coasting, lost, sometimes deleted)
                t += rng.gen_range(1.0..30.0);
            }
            for (i, a) in anchors.iter().enumerate() {
                if rng.gen_bool(0.2) {
                    continue;
                }
                let truth = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (1.0 - a[2]).powi(2)).sqrt();
                let range_m = if rng.gen_bool(0.1) {
                    rng.gen_range(0.0..200.0)
                } else {
                    (truth + noise.sample(rng)).max(0.0)
                };
                records.push(Record {
                    time_s: t + rng.gen_range(0.0..0.05),
                    tag: tag.into(),
                    measurement: Measurement::Range {
                        anchor: format!("A{i}"),
                        range_m,
                        std_m: None,
                        anchor_position_m: None,
                    },
                });
            }
            let odometry_t = t + rng.gen_range(0.0..0.1);
            let measurement = match rng.gen_range(0..8) {
                0 | 1 => Measurement::Odometry {
                    speed_mps: if rng.gen_bool(0.5) {
                        0.0
                    } else {
                        rng.gen_range(0.0..3.0)
                    },
                    heading_rad: Some(rng.gen_range(-4.0..4.0)),
                    speed_std_mps: Some(if rng.gen_bool(0.2) { 0.0 } else { 0.1 }),
                    heading_std_rad: Some(if rng.gen_bool(0.3) { 0.0 } else { 0.05 }),
                },
                2 => Measurement::Velocity {
                    velocity_mps: vec![v[0], v[1]],
                    covariance_m2ps2: Some(vec![0.01, 0.0, 0.0, 0.01]),
                },
                3 => Measurement::Accelerometer {
                    acceleration_mps2: vec![rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0)],
                    std_mps2: Some(0.1),
                },
                4 if rng.gen_bool(0.2) => Measurement::Fix {
                    position_m: vec![p[0] + noise.sample(rng), p[1] + noise.sample(rng)],
                    covariance_m2: vec![0.01, 0.0, 0.0, 0.01],
                },
                _ => {
                    t += 0.1;
                    continue;
                }
            };
            records.push(Record {
                time_s: odometry_t,
                tag: tag.into(),
                measurement,
            });
            t += 0.1;
        }
    }
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    records
}

fn assert_sane(out: &Output, context: &str) {
    for update in &out.updates {
        let finite = update.position_m.iter().all(|x| x.is_finite())
            && update.velocity_mps.iter().all(|x| x.is_finite())
            && update.position_covariance_m2.iter().all(|x| x.is_finite());
        assert!(finite, "{context}: non-finite update {update:?}");
        // the random sites span 60 m: 10 km out is divergence
        assert!(
            update.position_m[..2].iter().all(|x| x.abs() < 20_000.0),
            "{context}: diverged update {update:?}"
        );
    }
}

#[test]
fn random_valid_streams_never_abort_and_never_output_non_finite_states() {
    let mut rejected = std::collections::BTreeMap::<String, usize>::new();
    for seed in 0..24_u64 {
        for (pipeline, filter) in [("fix-then-filter", "kf"), ("tightly-coupled", "ekf")] {
            for motion_model in ["cv", "imm"] {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let (site, anchors) = random_site(&mut rng, pipeline, filter, motion_model);
                let records = random_records(&mut rng, &anchors, 60.0);
                let context = format!("seed {seed}, {pipeline}, {motion_model}");
                let mut tracker = Tracker::new(&site).unwrap();
                let mut out = Output::default();
                for record in records {
                    if let Err(error) = tracker.push(record.clone(), &mut out) {
                        panic!("{context}: {record:?} aborted the run: {error}");
                    }
                }
                tracker
                    .finish(&mut out)
                    .unwrap_or_else(|e| panic!("{context}: finish: {e}"));
                assert_sane(&out, &context);
                assert!(!out.updates.is_empty(), "{context}: no track");
                for event in &out.events {
                    if let Event::Rejected { kind, reason, .. } = event {
                        if reason.starts_with("track diverged") {
                            println!("{context}: {kind}: {reason}");
                        }
                        let category: String = reason.chars().take_while(|c| !c.is_ascii_digit()).take(40).collect();
                        *rejected.entry(format!("{kind}: {category}")).or_default() += 1;
                    }
                }
            }
        }
    }
    println!("{rejected:#?}");
}

/// The test site of the tracker's tests (4 anchors on a 20 m square) under `motion_model`.
fn square_site(pipeline: &str, filter: &str, motion_model: &str) -> Site {
    let text = super::tests::site_text(pipeline, filter, "")
        .replace("motion_model = \"cv\"", &format!("motion_model = \"{motion_model}\""));
    Site::from_toml_str(&text, "square.toml").unwrap()
}

/// A walker at (2 + 0.8 t, 3 + 0.5 t) m.
fn walker(t: f64) -> [f64; 2] {
    [2.0 + 0.8 * t, 3.0 + 0.5 * t]
}

fn rejections<'a>(out: &'a Output, of_kind: &'a str) -> impl Iterator<Item = &'a str> + 'a {
    out.events.iter().filter_map(move |e| match e {
        Event::Rejected { kind, reason, .. } if *kind == of_kind => Some(reason.as_str()),
        _ => None,
    })
}

/// Pushes every record; a record that aborts the run fails the test with the record.
fn run_all(tracker: &mut Tracker, records: Vec<Record>) -> Output {
    let mut out = Output::default();
    for record in records {
        if let Err(error) = tracker.push(record.clone(), &mut out) {
            panic!("{record:?} aborted the run: {error}");
        }
    }
    tracker.finish(&mut out).unwrap();
    out
}

/// Odometry of the walker (speed 0.94 m/s along atan2(0.5, 0.8)) `offset_s` after each 10 Hz
/// range epoch; `standstill`: speed 0 with a heading that wanders (a compass at rest) and
/// σ_θ = 0.05 rad; otherwise σ_θ = 0 (an exact heading).
fn odometry_records(seconds: f64, offset_s: f64, standstill: bool) -> Vec<Record> {
    let epochs = (seconds * 10.0) as usize;
    (0..epochs)
        .map(|k| Record {
            time_s: k as f64 * 0.1 + offset_s,
            tag: "w1".into(),
            measurement: Measurement::Odometry {
                speed_mps: if standstill {
                    0.0
                } else {
                    (0.8_f64.powi(2) + 0.25).sqrt()
                },
                heading_rad: Some(if standstill {
                    0.37 * k as f64
                } else {
                    0.5_f64.atan2(0.8)
                }),
                speed_std_mps: Some(0.05),
                heading_std_rad: Some(if standstill { 0.05 } else { 0.0 }),
            },
        })
        .collect()
}

fn merged(mut records: Vec<Record>, more: Vec<Record>) -> Vec<Record> {
    records.extend(more);
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    records
}

#[test]
fn fix_then_filter_with_odometry_between_epochs_keeps_time_order() {
    // each epoch's fix is dated at its readings (t); the odometry at t + 0.05 arrives while
    // that epoch is still open (it closes with the next readings at t + 0.1)
    for motion_model in ["cv", "imm"] {
        let records = merged(
            super::tests::range_records(10.0, 5, walker),
            odometry_records(10.0, 0.05, false),
        );
        let out = run_all(
            &mut Tracker::new(&square_site("fix-then-filter", "kf", motion_model)).unwrap(),
            records,
        );
        let failures: Vec<&Event> = out
            .events
            .iter()
            .filter(|e| {
                matches!(
                    e,
                    Event::Rejected {
                        kind: "odometry" | "epoch" | "fix",
                        ..
                    }
                )
            })
            .collect();
        assert!(failures.is_empty(), "{motion_model}: {failures:?}");
        // every epoch and every odometry record updated the track, in time order
        let times: Vec<f64> = out.updates.iter().filter(|u| !u.predicted).map(|u| u.time_s).collect();
        assert!(times.windows(2).all(|w| w[0] <= w[1]), "{motion_model}: {times:?}");
        assert!(out.updates.iter().any(|u| u.source == UpdateSource::Velocity));
        let last = out.updates.last().unwrap();
        let truth = walker(last.time_s);
        assert!(
            (last.position_m[0] - truth[0]).hypot(last.position_m[1] - truth[1]) < 0.3,
            "{motion_model}: {last:?}"
        );
    }
}

#[test]
fn odometry_at_a_standstill_or_with_an_exact_heading_is_used() {
    for (standstill, motion_model) in [(true, "cv"), (false, "cv"), (true, "imm"), (false, "imm")] {
        // tightly coupled: each odometry record updates the track at once
        let records = merged(
            super::tests::range_records(6.0, 6, walker),
            odometry_records(6.0, 0.05, standstill),
        );
        let out = run_all(
            &mut Tracker::new(&square_site("tightly-coupled", "ekf", motion_model)).unwrap(),
            records,
        );
        let refused: Vec<&str> = rejections(&out, "odometry").collect();
        assert!(
            refused.is_empty(),
            "standstill {standstill}, {motion_model}: {} refused, first {:?}",
            refused.len(),
            refused.first()
        );
        let velocity_updates = out
            .updates
            .iter()
            .filter(|u| u.source == UpdateSource::Velocity)
            .count();
        assert!(velocity_updates > 40, "{velocity_updates}");
    }
}

/// A tag accelerating along x at 0.5 m/s² from (2, 10) at rest.
fn accelerating(t: f64) -> [f64; 2] {
    [2.0 + 0.25 * t * t, 10.0]
}

#[test]
fn the_imm_uses_accelerometer_samples_as_the_cv_modes_control_input() {
    let accelerometer = |seconds: f64| -> Vec<Record> {
        (0..(seconds * 20.0) as usize)
            .map(|k| Record {
                time_s: k as f64 * 0.05 + 0.01,
                tag: "w1".into(),
                measurement: Measurement::Accelerometer {
                    acceleration_mps2: vec![0.5, 0.0],
                    std_mps2: Some(0.05),
                },
            })
            .collect()
    };
    let ranges = super::tests::range_records(8.0, 7, accelerating);
    let with = run_all(
        &mut Tracker::new(&square_site("fix-then-filter", "kf", "imm")).unwrap(),
        merged(ranges.clone(), accelerometer(8.0)),
    );
    let without = run_all(
        &mut Tracker::new(&square_site("fix-then-filter", "kf", "imm")).unwrap(),
        ranges,
    );
    let refused: Vec<&str> = rejections(&with, "accelerometer").collect();
    assert!(
        refused.is_empty(),
        "{} refused, first {:?}",
        refused.len(),
        refused.first()
    );
    let error = |out: &Output| {
        let positions: Vec<(f64, [f64; 3])> = out
            .updates
            .iter()
            .filter(|u| !u.predicted)
            .map(|u| (u.time_s, u.position_m))
            .collect();
        super::tests::rmse(&positions, accelerating, 2.0)
    };
    let (aided, unaided) = (error(&with), error(&without));
    println!("IMM position RMSE after 2 s: with the accelerometer {aided:.4} m, without {unaided:.4} m");
    assert!(aided < unaided, "{aided} vs {unaided}");
}

#[test]
fn a_track_sent_beyond_the_site_is_reported_and_restarts_from_its_next_fix() {
    for motion_model in ["cv", "imm"] {
        let mut records = super::tests::range_records(4.0, 8, walker);
        // a fix 50 000 km away: the track jumps there (a fresh track is not gated)
        records.insert(
            0,
            Record {
                time_s: 0.0,
                tag: "w1".into(),
                measurement: Measurement::Fix {
                    position_m: vec![5.0e7, 0.0],
                    covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
                },
            },
        );
        let out = run_all(
            &mut Tracker::new(&square_site("fix-then-filter", "kf", motion_model)).unwrap(),
            records,
        );
        let diverged: Vec<&str> = rejections(&out, "fix")
            .filter(|r| r.starts_with("track diverged"))
            .collect();
        assert_eq!(diverged.len(), 1, "{motion_model}: {:?}", out.events);
        assert!(
            out.updates.iter().all(|u| u.position_m[0].abs() < 100.0),
            "{motion_model}"
        );
        let last = out.updates.last().unwrap();
        let truth = walker(last.time_s);
        assert!((last.position_m[0] - truth[0]).hypot(last.position_m[1] - truth[1]) < 0.5);
    }
}
