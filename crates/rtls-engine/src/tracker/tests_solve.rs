//! Epoch fixes (fix-then-filter, and the first fix of a tightly coupled track): co-located
//! anchors, anchor heights in 2-D TDOA, projected range variances, negative ranges, named
//! fallbacks, and a seeded random search for non-finite or unbounded fixes.

use nalgebra::{SVector, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::record::{Measurement, Record};
use crate::site::Site;
use crate::tracker::{Event, Output, Tracker};

/// A site with UWB readers at `anchors` (σ_r = 0.1 m, no bias), 2-D with tag height 1 m
/// unless `three` (3-D).
fn make_site(anchors: &[(&str, [f64; 3])], pipeline: &str, three: bool) -> Site {
    let dimensions = if three { "dimensions = 3" } else { "tag_height_m = 1.0" };
    let readers: String = anchors
        .iter()
        .map(|(id, [x, y, z])| {
            format!(
                "[[readers]]\nid = \"{id}\"\nposition_m = [{x:.3}, {y:.3}, {z:.3}]\ntechnology = \"uwb\"\n\
                 radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }}\n"
            )
        })
        .collect();
    let text = format!(
        r#"{readers}
[tracker]
pipeline = "{pipeline}"
motion_model = "cv"
filter = "ekf"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 2.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 20.0
reorder_window_s = 0.0
{dimensions}
"#
    );
    Site::from_toml_str(&text, "solve-test.toml").unwrap()
}

/// Two anchors on one mast at (0, 0) (heights 2.5 m and 0.3 m) and two more.
const MAST: [(&str, [f64; 3]); 4] = [
    ("A1", [0.0, 0.0, 2.5]),
    ("M", [0.0, 0.0, 0.3]),
    ("A2", [20.0, 0.0, 2.5]),
    ("A4", [0.0, 20.0, 2.5]),
];

fn slant(p: [f64; 3], a: [f64; 3]) -> f64 {
    ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt()
}

/// Exact range readings from `tag` to the given anchors (indices into `anchors`).
fn ranges(anchors: &[(&str, [f64; 3])], tag: [f64; 3]) -> Vec<AnchorReading> {
    anchors
        .iter()
        .enumerate()
        .map(|(anchor, (_, a))| AnchorReading::Range {
            anchor,
            range_m: slant(tag, *a),
            variance_m2: 0.01,
            position_m: *a,
        })
        .collect()
}

#[test]
fn anchors_sharing_x_y_are_merged_in_2d_and_the_epoch_solves() {
    let site = make_site(&MAST, "fix-then-filter", false);
    let anchors = Anchors::new(&site);
    let fixes = solve_epoch::<2>(&anchors, &ranges(&MAST, [6.0, 4.0, 1.0]), 1.0, None).unwrap();
    assert_eq!(fixes.len(), 1);
    assert_eq!(fixes[0].method, "gauss-newton");
    assert!(
        (fixes[0].fix.position - Vector2::new(6.0, 4.0)).norm() < 1e-3,
        "{}",
        fixes[0].fix.position
    );
}

#[test]
fn too_few_distinct_anchor_positions_say_why() {
    let site = make_site(&MAST, "fix-then-filter", false);
    let anchors = Anchors::new(&site);
    let readings = &ranges(&MAST, [6.0, 4.0, 1.0])[..3];
    let reason = solve_epoch::<2>(&anchors, readings, 1.0, None).unwrap_err();
    assert!(reason.contains("2 distinct anchor position(s)"), "{reason}");
    assert!(
        reason.contains("`A1` and `M` share one position in the plane"),
        "{reason}"
    );
}

/// Round-robin range records from the given anchors, 10 Hz, for `seconds`, tag at rest.
fn records(anchors: &[(&str, [f64; 3])], tag: [f64; 3], seconds: f64) -> Vec<Record> {
    (0..(seconds * 10.0) as usize)
        .map(|k| {
            let (id, a) = anchors[k % anchors.len()];
            Record {
                time_s: k as f64 * 0.1,
                tag: "t".into(),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: slant(tag, a),
                    std_m: None,
                    anchor_position_m: None,
                },
            }
        })
        .collect()
}

fn run(site: &Site, records: Vec<Record>) -> Output {
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out
}

#[test]
fn tightly_coupled_tracks_start_with_anchors_on_one_mast() {
    let site = make_site(&MAST, "tightly-coupled", false);
    let out = run(&site, records(&MAST, [6.0, 4.0, 1.0], 5.0));
    assert!(!out.updates.is_empty(), "{:?}", out.events);
    let last = out.updates.last().unwrap();
    assert!((last.position_m[0] - 6.0).abs() < 0.2 && (last.position_m[1] - 4.0).abs() < 0.2);
    // and when the mast and one more anchor are all there is, the reason is reported
    let out = run(&site, records(&MAST[..3], [6.0, 4.0, 1.0], 5.0));
    assert!(out.updates.is_empty());
    let reasons: Vec<&String> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { reason, .. } => Some(reason),
            _ => None,
        })
        .collect();
    assert!(
        reasons.iter().any(|r| r.contains("`A1` and `M` share one position")),
        "{reasons:?}"
    );
}

#[test]
fn planar_tdoa_accounts_for_anchor_heights() {
    let stations = [
        ("S0", [0.0, 0.0, 3.0]),
        ("S1", [20.0, 0.0, 2.5]),
        ("S2", [20.0, 15.0, 3.0]),
        ("S3", [0.0, 15.0, 2.5]),
        ("S4", [10.0, 7.0, 0.3]),
    ];
    let site = make_site(&stations, "fix-then-filter", false);
    let anchors = Anchors::new(&site);
    let tag = [3.0, 12.0, 1.0];
    let readings: Vec<AnchorReading> = (1..stations.len())
        .map(|i| AnchorReading::Tdoa {
            anchor: i,
            reference: 0,
            range_difference_m: slant(tag, stations[i].1) - slant(tag, stations[0].1),
            variance_m2: 1e-4,
        })
        .collect();
    let fixes = solve_epoch::<2>(&anchors, &readings, 1.0, None).unwrap();
    assert_eq!(fixes[0].method, "tdoa");
    assert!(
        (fixes[0].fix.position - Vector2::new(3.0, 12.0)).norm() < 1e-3,
        "{}",
        fixes[0].fix.position
    );
    // range differences no tag position can produce are refused, never an absurd fix
    let absurd: Vec<AnchorReading> = (1..stations.len())
        .map(|i| AnchorReading::Tdoa {
            anchor: i,
            reference: 0,
            range_difference_m: 1e7 * (i as f64 - 2.5),
            variance_m2: 1e-4,
        })
        .collect();
    match solve_epoch::<2>(&anchors, &absurd, 1.0, None) {
        Ok(fixes) => {
            let corners: Vec<[f64; 2]> = stations.iter().map(|(_, a)| [a[0], a[1]]).collect();
            assert!(fixes[0].fix.check_plausible(&corners, 0.0).is_ok());
        }
        Err(reason) => assert!(reason.contains("TDOA"), "{reason}"),
    }
}

#[test]
fn spatial_tdoa_covariance_grows_with_inconsistent_differences() {
    let room = [
        ("A", [0.0, 0.0, 0.2]),
        ("B", [12.0, 0.0, 2.0]),
        ("C", [0.0, 9.0, 3.0]),
        ("D", [12.0, 9.0, 0.5]),
        ("E", [6.0, 4.0, 3.0]),
        ("F", [3.0, 8.0, 1.0]),
    ];
    let site = make_site(&room, "fix-then-filter", true);
    let anchors = Anchors::new(&site);
    let tag = [4.0, 3.0, 1.2];
    let readings = |nlos: f64| -> Vec<AnchorReading> {
        (1..room.len())
            .map(|i| AnchorReading::Tdoa {
                anchor: i,
                reference: 0,
                range_difference_m: slant(tag, room[i].1) - slant(tag, room[0].1) + if i == 3 { nlos } else { 0.0 },
                variance_m2: 1e-4,
            })
            .collect()
    };
    let clean = solve_epoch::<3>(&anchors, &readings(0.0), 1.0, None).unwrap();
    let biased = solve_epoch::<3>(&anchors, &readings(1.0), 1.0, None).unwrap();
    // a 1 m NLOS excess at σ = 1 cm: χ²/dof ≫ 1 inflates the covariance far beyond the clean one
    let ratio = biased[0].fix.covariance.trace() / clean[0].fix.covariance.trace();
    assert!(ratio > 100.0, "{ratio}");
}

#[test]
fn projected_ranges_carry_the_propagated_variance() {
    let site = make_site(&MAST, "fix-then-filter", false);
    let anchors = Anchors::new(&site);
    // A1 is 1.5 m above the tag: slant 2.5 m → h = 2 m, σ_h = 0.1 · 2.5/2
    let reading = AnchorReading::Range {
        anchor: 0,
        range_m: 2.5,
        variance_m2: 0.01,
        position_m: anchors.get(0).position_m,
    };
    let projected = epoch_ranges::<2>(&anchors, &[reading], 1.0).unwrap();
    assert!((projected[0].range_m - 2.0).abs() < 1e-12);
    assert!((projected[0].variance_m2 - 0.125_f64.powi(2)).abs() < 1e-12);
    // a range shorter than the height difference: h = 0, σ_h² = r⁺ σ_r = 1.5 · 0.1, finite
    for range_m in [1.4, 0.0, -0.3] {
        let reading = AnchorReading::Range {
            anchor: 0,
            range_m,
            variance_m2: 0.01,
            position_m: anchors.get(0).position_m,
        };
        let projected = epoch_ranges::<2>(&anchors, &[reading], 1.0).unwrap();
        assert_eq!(projected[0].range_m, 0.0);
        assert!(
            (projected[0].variance_m2 - 0.15).abs() < 1e-12,
            "{range_m}: {}",
            projected[0].variance_m2
        );
    }
}

#[test]
fn negative_ranges_are_measurements_not_errors() {
    let room = [
        ("A", [0.0, 0.0, 0.0]),
        ("B", [12.0, 0.0, 2.0]),
        ("C", [0.0, 9.0, 3.0]),
        ("D", [12.0, 9.0, 0.5]),
        ("E", [6.0, 4.0, 3.0]),
    ];
    let site = make_site(&room, "fix-then-filter", true);
    let anchors = Anchors::new(&site);
    let tag = [0.2, 0.1, 0.1];
    let mut readings = ranges(&room, tag);
    // Wi-Fi FTM close to anchor A: −0.2 m
    if let AnchorReading::Range { range_m, .. } = &mut readings[0] {
        *range_m = -0.2;
    }
    let fixes = solve_epoch::<3>(&anchors, &readings, 1.0, None).unwrap();
    assert!((fixes[0].fix.position - SVector::<f64, 3>::from(tag)).norm() < 1.0);
    // 2-D, an anchor at the tag's height: the negative range passes through unprojected
    let flat = [("A", [0.0, 0.0, 1.0]), ("B", [12.0, 0.0, 1.0]), ("C", [0.0, 9.0, 1.0])];
    let site = make_site(&flat, "fix-then-filter", false);
    let anchors = Anchors::new(&site);
    let reading = AnchorReading::Range {
        anchor: 0,
        range_m: -0.2,
        variance_m2: 0.01,
        position_m: anchors.get(0).position_m,
    };
    assert_eq!(epoch_ranges::<2>(&anchors, &[reading], 1.0).unwrap()[0].range_m, -0.2);
}

#[test]
fn raw_fixes_name_their_method() {
    let site = make_site(&MAST, "fix-then-filter", false);
    // every anchor at each time stamp: one epoch per 0.1 s
    let mut all = records(&MAST, [6.0, 4.0, 1.0], 3.0);
    for (k, record) in all.iter_mut().enumerate() {
        record.time_s = (k / MAST.len()) as f64 * 0.1;
    }
    let out = run(&site, all);
    assert!(!out.fixes.is_empty(), "{:?}", out.events);
    assert!(
        out.fixes.iter().all(|f| f.method == Some("gauss-newton")),
        "{:?}",
        out.fixes[0]
    );
    assert!(out.fixes[0].to_json_line().contains(r#""method":"gauss-newton""#));
}

/// `(position, column-major covariance)`.
type Flat = (Vec<f64>, Vec<f64>);

/// Random anchors (co-located, collinear, far, duplicated; 1–12) and readings (negative,
/// zero, huge): every epoch gives finite fixes with a symmetric positive-definite covariance
/// and a plausible position, or a reason.
#[test]
fn random_epochs_give_bounded_fixes_or_reasons() {
    let mut rng = ChaCha8Rng::seed_from_u64(20_261_125);
    let (mut solved, mut refused) = (0, 0);
    for case in 0..300 {
        let n = rng.gen_range(1..=12);
        let mut anchors: Vec<(String, [f64; 3])> = Vec::with_capacity(n);
        for i in 0..n {
            let position = match rng.gen_range(0..6) {
                // duplicate or co-located in the plane
                0 if i > 0 => anchors[rng.gen_range(0..i)].1,
                1 if i > 0 => {
                    let p = anchors[rng.gen_range(0..i)].1;
                    [p[0], p[1], rng.gen_range(-5.0..5.0)]
                }
                // on the line y = 0
                2 => [rng.gen_range(-30.0..30.0), 0.0, 2.5],
                // far away
                3 => [
                    rng.gen_range(-1e6..1e6),
                    rng.gen_range(-1e6..1e6),
                    rng.gen_range(-1e3..1e3),
                ],
                _ => [
                    rng.gen_range(-30.0..30.0),
                    rng.gen_range(-30.0..30.0),
                    rng.gen_range(0.0..4.0),
                ],
            };
            anchors.push((format!("R{i}"), position));
        }
        let named: Vec<(&str, [f64; 3])> = anchors.iter().map(|(id, p)| (id.as_str(), *p)).collect();
        let three = rng.gen_bool(0.5);
        let site = make_site(&named, "fix-then-filter", three);
        let table = Anchors::new(&site);
        let value = |rng: &mut ChaCha8Rng| match rng.gen_range(0..5) {
            0 => -rng.gen_range(0.0..5.0),
            1 => 0.0,
            2 => rng.gen_range(1e5..1e9),
            _ => rng.gen_range(0.0..60.0),
        };
        let mut readings = Vec::new();
        for _ in 0..rng.gen_range(1..=2 * n) {
            let anchor = rng.gen_range(0..n);
            let variance_m2 = 10f64.powf(rng.gen_range(-6.0..2.0));
            let reading = if rng.gen_bool(0.7) {
                AnchorReading::Range {
                    anchor,
                    range_m: value(&mut rng),
                    variance_m2,
                    position_m: table.get(anchor).position_m,
                }
            } else {
                AnchorReading::Tdoa {
                    anchor,
                    reference: rng.gen_range(0..n),
                    range_difference_m: value(&mut rng) - value(&mut rng),
                    variance_m2,
                }
            };
            readings.push(reading);
        }
        let guess = rng
            .gen_bool(0.3)
            .then(|| [rng.gen_range(-40.0..40.0), rng.gen_range(-40.0..40.0), 1.0]);
        let fixes: Result<Vec<Flat>, String> = if three {
            solve_epoch::<3>(&table, &readings, 1.0, guess.map(SVector::from)).map(|f| {
                f.iter()
                    .map(|f| (f.fix.position.as_slice().to_vec(), f.fix.covariance.as_slice().to_vec()))
                    .collect()
            })
        } else {
            solve_epoch::<2>(
                &table,
                &readings,
                1.0,
                guess.map(|g| SVector::<f64, 2>::new(g[0], g[1])),
            )
            .map(|f| {
                f.iter()
                    .map(|f| (f.fix.position.as_slice().to_vec(), f.fix.covariance.as_slice().to_vec()))
                    .collect()
            })
        };
        match fixes {
            Ok(fixes) => {
                solved += 1;
                for (position, covariance) in fixes {
                    assert!(position.iter().chain(&covariance).all(|v| v.is_finite()), "case {case}");
                    let d = position.len();
                    let p = nalgebra::DMatrix::from_column_slice(d, d, &covariance);
                    assert!((&p - p.transpose()).amax() <= 1e-9 * p.amax(), "case {case}: {p}");
                    assert!(p.clone().cholesky().is_some(), "case {case}: {p}");
                    // within the anchors' extent (plus the largest range) of their centroid
                    let scale = anchors
                        .iter()
                        .flat_map(|(_, a)| a.iter())
                        .map(|v| v.abs())
                        .fold(0.0, f64::max);
                    let reach = readings
                        .iter()
                        .map(|r| match r {
                            AnchorReading::Range {
                                range_m, variance_m2, ..
                            } => range_m + 3.0 * variance_m2.sqrt(),
                            _ => 0.0,
                        })
                        .fold(0.0, f64::max);
                    let bound = 10.0 * scale + reach + 1.0;
                    assert!(
                        position.iter().all(|v| v.abs() <= bound),
                        "case {case}: {position:?} beyond {bound}"
                    );
                }
            }
            Err(reason) => {
                refused += 1;
                assert!(!reason.is_empty(), "case {case}");
            }
        }
    }
    eprintln!("random epochs: {solved} solved, {refused} refused with a reason");
    assert!(solved > 30 && refused > 30, "{solved} {refused}");
}

/// Three anchors along a wall (y ≈ 0) and one across the room.
const WALL: [(&str, [f64; 3]); 4] = [
    ("W1", [0.0, 0.0, 2.5]),
    ("W2", [10.0, 0.05, 2.5]),
    ("W3", [20.0, 0.0, 2.5]),
    ("F", [10.0, 15.0, 2.5]),
];

/// A tag at rest at (12, 5) heard by the anchors of `WALL[..count]` in turn, one range per
/// 50 ms, for `seconds`; W2's ranges are 0.09 m long, so the tag's mirror image across the
/// wall, (12, −5.1), fits the three wall ranges better than the truth does.
fn wall_records(count: usize, seconds: f64) -> Vec<Record> {
    (0..(seconds * 20.0) as usize)
        .map(|k| {
            let (id, a) = WALL[k % count];
            let error_m = if id == "W2" { 0.09 } else { 0.0 };
            Record {
                time_s: k as f64 * 0.05,
                tag: "t".into(),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: slant([12.0, 5.0, 1.0], a) + error_m,
                    std_m: None,
                    anchor_position_m: None,
                },
            }
        })
        .collect()
}

#[test]
fn plan_spread_ratio_tells_a_line_from_a_spread() {
    use crate::tracker::anchors::{on_a_line, plan_spread_ratio};
    assert_eq!(plan_spread_ratio(&[[1.0, 1.0]]), 0.0);
    assert_eq!(plan_spread_ratio(&[[0.0, 0.0], [3.0, 4.0], [6.0, 8.0]]), 0.0);
    // a square spreads equally: √(λ₂/λ₁) = 1
    let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    assert!((plan_spread_ratio(&square) - 1.0).abs() < 1e-12);
    let wall: Vec<[f64; 2]> = WALL[..3].iter().map(|(_, p)| [p[0], p[1]]).collect();
    assert!(on_a_line(&wall));
    let room: Vec<[f64; 2]> = WALL.iter().map(|(_, p)| [p[0], p[1]]).collect();
    assert!(!on_a_line(&room));
}

/// The first three anchors a tightly coupled track hears lie along a wall: a fix from them may
/// be the tag's mirror image across it, 10 m off. The track waits for the anchor across the room
/// (50 ms later) and starts where the tag is.
#[test]
fn a_tightly_coupled_track_does_not_start_from_a_line_of_anchors_when_the_site_has_more() {
    let site = make_site(&WALL, "tightly-coupled", false);
    let out = run(&site, wall_records(4, 3.0));
    let first = out.fixes.first().expect("a track starts");
    assert!(
        first.time_s >= 0.15,
        "started at {} s from the wall's anchors alone",
        first.time_s
    );
    for update in out.updates.iter().filter(|u| !u.predicted) {
        let error_m = (update.position_m[0] - 12.0).hypot(update.position_m[1] - 5.0);
        assert!(error_m < 0.5, "{update:?}");
    }
    // a tag that hears only the wall still starts, after the wait (1 s)
    let out = run(&site, wall_records(3, 3.0));
    let first = out
        .fixes
        .first()
        .expect("a track starts from the wall's anchors after the wait");
    assert!(
        first.time_s >= crate::tracker::epoch::SPANNING_WAIT_S,
        "{}",
        first.time_s
    );
    // a recording shorter than the wait says why it gave no track
    let out = run(&site, wall_records(3, 0.5));
    assert!(out.fixes.is_empty());
    assert!(
        out.events
            .iter()
            .any(|e| matches!(e, Event::Rejected { reason, .. } if reason.contains("lie on one line"))),
        "{:?}",
        out.events
    );
    // a site whose anchors all lie along the drift starts from them at once
    let drift = make_site(&WALL[..3], "tightly-coupled", false);
    let out = run(&drift, wall_records(3, 3.0));
    assert!(out.fixes.first().expect("a track starts").time_s < 0.15);
}

/// Four anchors on a 20 m square ceiling, all at 3 m.
const CEILING: [(&str, [f64; 3]); 4] = [
    ("C1", [0.0, 0.0, 3.0]),
    ("C2", [20.0, 0.0, 3.0]),
    ("C3", [20.0, 20.0, 3.0]),
    ("C4", [0.0, 20.0, 3.0]),
];

/// Anchors that all hang at one height leave a 3-D fix two mirror images, above and below their
/// plane: the solver refused it ("coplanar"), so no 3-D track ever started on such a site (the
/// usual one). A fix from them now starts below the anchors, where the tags are.
#[test]
fn a_3d_track_starts_below_anchors_that_hang_at_one_height() {
    let site = make_site(&CEILING, "tightly-coupled", true);
    let out = run(&site, records(&CEILING, [6.0, 4.0, 1.0], 5.0));
    let last = out
        .updates
        .last()
        .unwrap_or_else(|| panic!("no track: {:?}", out.events));
    let error_m = slant(last.position_m, [6.0, 4.0, 1.0]);
    assert!(error_m < 0.2, "{last:?}");
    assert!(out.fixes.iter().all(|f| f.position_m[2] < 3.0), "{:?}", out.fixes);
    // the start: the plan centroid 1.5 m under the anchors; none when their heights spread
    use crate::tracker::anchors::start_below_plane;
    let points: Vec<[f64; 3]> = CEILING.iter().map(|(_, p)| *p).collect();
    assert_eq!(start_below_plane(&points), Some([10.0, 10.0, 1.5]));
    let mut spread = points.clone();
    spread[0][2] = 0.5;
    assert_eq!(start_below_plane(&spread), None);
    assert_eq!(start_below_plane(&points[..2]), None);
}
