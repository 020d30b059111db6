//! Anonymous detections (tag `"*"`) through the tracker: two targets in one 2 m cell, started
//! from fixes and then followed on ranges that carry no identity (seed 003's limit ①).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{run, site, site_text, slant, ANCHORS};
use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// Target A walks east at 0.4 m/s from (9, 9.4); target B walks west at 0.4 m/s from
/// (11, 10.6): they pass each other 1.2 m apart in the middle of the square.
fn target(which: usize, t: f64) -> [f64; 2] {
    if which == 0 {
        [9.0 + 0.4 * t, 9.4]
    } else {
        [11.0 - 0.4 * t, 10.6]
    }
}

/// 1 s of anonymous fixes (σ = 5 cm) at 10 Hz, then anonymous ranges (σ = 5 cm, bias 0.2 m as
/// the site declares) from the four anchors at 10 Hz, both targets in every epoch.
fn anonymous_records(seconds: f64, seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut records = Vec::new();
    for k in 0..(seconds * 10.0) as usize {
        let t = k as f64 * 0.1;
        for which in 0..2 {
            let p = target(which, t);
            let measurement = if t < 1.0 {
                Measurement::Fix {
                    position_m: vec![p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)],
                    covariance_m2: vec![0.0025, 0.0, 0.0, 0.0025],
                }
            } else {
                // one reader per 25 ms slot, both echoes at its time stamp
                let (id, a) = ANCHORS[k % 4];
                records.push(Record {
                    time_s: t + 0.025 * (k % 4) as f64 / 4.0,
                    tag: ANONYMOUS_TAG.into(),
                    measurement: Measurement::Range {
                        anchor: id.into(),
                        range_m: slant(p, a) + 0.2 + noise.sample(&mut rng),
                        std_m: Some(0.05),
                        anchor_position_m: None,
                    },
                });
                continue;
            };
            records.push(Record {
                time_s: t,
                tag: ANONYMOUS_TAG.into(),
                measurement,
            });
        }
    }
    records
}

fn anonymous_site(association: &str) -> Site {
    let text = site_text("fix-then-filter", "kf", "").replace(
        "[tracker]",
        &format!(
            "[anonymous]\nassociation = \"{association}\"\nacceleration_noise_std_mps2 = 0.3\n\
             lifecycle = {{ confirm_updates = 3, confirm_window_s = 1.0, coast_timeout_s = 2.0, delete_timeout_s = 5.0 }}\n\n[tracker]"
        ),
    );
    Site::from_toml_str(&text, "anonymous.toml").unwrap()
}

#[test]
fn two_anonymous_targets_in_one_cell_keep_their_tracks_on_ranges() {
    for association in ["gnn", "jpda"] {
        let out = run(
            &mut Tracker::new(&anonymous_site(association)).unwrap(),
            anonymous_records(10.0, 5),
        );
        let mut ids: Vec<&str> = out.updates.iter().map(|u| &*u.tag).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids, ["anon-1", "anon-2"], "{association}");
        // each track follows one target all the way (no swap when they pass 1.2 m apart)
        for id in ids {
            let updates: Vec<&TrackUpdate> = out
                .updates
                .iter()
                .filter(|u| &*u.tag == id && u.time_s >= 0.5)
                .collect();
            let first = updates.first().unwrap();
            let which = usize::from(first.position_m[1] > 10.0);
            let worst = updates
                .iter()
                .map(|u| {
                    let p = target(which, u.time_s);
                    ((u.position_m[0] - p[0]).powi(2) + (u.position_m[1] - p[1]).powi(2)).sqrt()
                })
                .fold(0.0, f64::max);
            assert!(worst < 0.3, "{association} {id}: worst error {worst:.3} m");
            assert_eq!(
                updates.last().unwrap().status,
                TrackStatus::Confirmed,
                "{association} {id}"
            );
        }
        // the 99 % gate leaves about 1 % of true ranges unmatched; they are reported, counted
        let unused: usize = out
            .events
            .iter()
            .filter_map(|e| match e {
                Event::Rejected { reason, .. } => {
                    reason.split_whitespace().next().and_then(|n| n.parse::<usize>().ok())
                }
                _ => None,
            })
            .sum();
        let ranges = 2 * 90;
        println!("{association}: {unused} of {ranges} ranges matched no track");
        assert!(
            unused * 100 <= 3 * ranges,
            "{association}: {unused} unmatched of {ranges}"
        );
    }
}

#[test]
fn anonymous_records_without_the_section_or_of_other_kinds_are_rejected_with_the_reason() {
    let records = || {
        let mut records = anonymous_records(0.3, 6);
        records.push(Record {
            time_s: 0.3,
            tag: ANONYMOUS_TAG.into(),
            measurement: Measurement::Velocity {
                velocity_mps: vec![0.1, 0.0],
                covariance_m2ps2: Some(vec![0.01, 0.0, 0.0, 0.01]),
            },
        });
        records
    };
    let out = run(
        &mut Tracker::new(&site("fix-then-filter", "kf", "")).unwrap(),
        records(),
    );
    assert!(out.updates.is_empty());
    assert!(out
        .events
        .iter()
        .all(|e| matches!(e, Event::Rejected { reason, .. } if reason.contains("[anonymous]"))));
    let out = run(&mut Tracker::new(&anonymous_site("gnn")).unwrap(), records());
    assert!(out
        .events
        .iter()
        .any(|e| matches!(e, Event::Rejected { kind: "velocity", reason, .. } if reason.contains("range or a fix"))));
    // a bad setting is an error naming its key
    let text =
        site_text("fix-then-filter", "kf", "").replace("[tracker]", "[anonymous]\ngate_probability = 1.5\n\n[tracker]");
    let error = Site::from_toml_str(&text, "anonymous.toml").unwrap_err().to_string();
    assert!(error.contains("anonymous.gate_probability"), "{error}");
}

#[test]
fn anonymous_tracks_enter_and_leave_zones_and_are_counted() {
    // both targets start inside the 4 m × 4 m "office" ([8, 12]²) and leave it at 7.5 s
    let mut tracker = Tracker::new(&anonymous_site("gnn")).unwrap();
    let mut out = Output::default();
    let records = anonymous_records(10.0, 7);
    let (early, late): (Vec<Record>, Vec<Record>) = records.into_iter().partition(|r| r.time_s < 5.0);
    for record in early {
        tracker.push(record, &mut out).unwrap();
    }
    assert_eq!(tracker.head_count("office"), 2);
    for record in late {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    assert_eq!(tracker.head_count("office"), 0);
    for id in ["anon-1", "anon-2"] {
        let entered = out.events.iter().any(
            |e| matches!(e, Event::Zone(crate::zones::ZoneEvent::Enter { tag, zone, .. }) if &**tag == id && zone == "office"),
        );
        let exit_s = out.events.iter().find_map(|e| match e {
            Event::Zone(crate::zones::ZoneEvent::Exit { tag, zone, time_s, .. })
                if &**tag == id && zone == "office" =>
            {
                Some(*time_s)
            }
            _ => None,
        });
        assert!(entered, "{id}");
        let exit_s = exit_s.unwrap_or_else(|| panic!("{id} never left"));
        assert!((7.0..8.5).contains(&exit_s), "{id} left at {exit_s}");
    }
}
