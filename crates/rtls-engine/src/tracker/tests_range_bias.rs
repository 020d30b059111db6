//! Range self-calibration (`[tracker.range_bias]`): a tag moving among anchors whose ranges
//! carry offsets the site does not state.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{run, site, slant, ANCHORS};
use super::*;
use crate::record::Measurement;

/// A walker on a circle of radius 6 m about the square's centre, one lap per 40 s.
fn circle(t: f64) -> [f64; 2] {
    let w = 2.0 * std::f64::consts::PI / 40.0;
    [10.0 + 6.0 * (w * t).cos(), 10.0 + 6.0 * (w * t).sin()]
}

/// The anchors' true offsets beyond the site's `bias_m` (0.2 m), m.
const OFFSETS_M: [f64; 4] = [0.25, 0.05, -0.15, 0.3];

/// Round-robin ranges, one anchor per 25 ms, σ 0.1 m, with [`OFFSETS_M`].
fn biased_ranges(seconds: f64, seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.1).unwrap();
    (0..(seconds * 40.0) as usize)
        .map(|k| {
            let t = k as f64 * 0.025;
            let (id, a) = ANCHORS[k % 4];
            Record {
                time_s: t,
                tag: "w1".into(),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: slant(circle(t), a) + 0.2 + OFFSETS_M[k % 4] + noise.sample(&mut rng),
                    std_m: None,
                    anchor_position_m: None,
                },
            }
        })
        .collect()
}

/// RMSE after `after_s` and the share of truths inside the 95 % ellipse.
fn score(out: &Output, after_s: f64) -> (f64, f64) {
    let late: Vec<&TrackUpdate> = out
        .updates
        .iter()
        .filter(|u| u.time_s >= after_s && !u.predicted)
        .collect();
    let mut squared = 0.0;
    let mut inside = 0usize;
    for u in &late {
        let truth = circle(u.time_s);
        let (dx, dy) = (u.position_m[0] - truth[0], u.position_m[1] - truth[1]);
        squared += dx * dx + dy * dy;
        let c = &u.position_covariance_m2;
        let det = c[0] * c[4] - c[1] * c[3];
        let nees = (c[4] * dx * dx - (c[1] + c[3]) * dx * dy + c[0] * dy * dy) / det;
        inside += usize::from(nees <= 5.991);
    }
    let n = late.len() as f64;
    ((squared / n).sqrt(), inside as f64 / n)
}

/// `records` tracked with the offsets learnt and with `range_bias` off: each run's RMSE and
/// share inside the 95 % ellipse after 30 s.
fn learnt_and_fixed(pipeline: &str, filter: &str, records: Vec<Record>) -> [(f64, f64); 2] {
    ["", "range_bias = { enabled = false }"].map(|extra| {
        let out = run(
            &mut Tracker::new(&site(pipeline, filter, extra)).unwrap(),
            records.clone(),
        );
        score(&out, 30.0)
    })
}

#[test]
fn unstated_range_offsets_are_learnt_and_the_ellipses_hold_the_truth() {
    let [(learnt_rmse, learnt_inside), (fixed_rmse, fixed_inside)] =
        learnt_and_fixed("tightly-coupled", "ekf", biased_ranges(120.0, 7));
    println!(
        "learnt: {learnt_rmse:.3} m, {:.1} %; fixed: {fixed_rmse:.3} m, {:.1} %",
        100.0 * learnt_inside,
        100.0 * fixed_inside
    );
    assert!(
        learnt_rmse < 0.4 * fixed_rmse,
        "learnt {learnt_rmse} vs fixed {fixed_rmse}"
    );
    // the offsets' uncertainty is in the reported covariance from the start
    assert!(learnt_inside > 0.85, "{learnt_inside}");
}

#[test]
fn fix_then_filter_learns_the_offsets_from_its_epochs() {
    // the same ranges in 0.1 s epochs of all four anchors (equal time stamps)
    let records: Vec<Record> = biased_ranges(120.0, 8)
        .into_iter()
        .enumerate()
        .map(|(k, mut record)| {
            record.time_s = (k / 4) as f64 * 0.1;
            record
        })
        .collect();
    let [(learnt_rmse, learnt_inside), (fixed_rmse, _)] = learnt_and_fixed("fix-then-filter", "kf", records);
    println!(
        "fix-then-filter learnt: {learnt_rmse:.3} m, {:.1} %; fixed: {fixed_rmse:.3} m",
        100.0 * learnt_inside
    );
    assert!(
        learnt_rmse < 0.5 * fixed_rmse,
        "learnt {learnt_rmse} vs fixed {fixed_rmse}"
    );
    // 81 % when written: a fix's covariance counts the offsets' variance but not the
    // correlation between their errors and the fix's (a little optimistic, unlike the tightly
    // coupled pipeline's ~90 %)
    assert!(learnt_inside > 0.75, "{learnt_inside}");
}
