//! The fixed-size fix path ([`super::update`]'s `fixed_component_update`) against the general
//! kernel it replaces, through the whole tracker: the same records give the same updates and
//! events, with adaptive noise, gating and re-acquisition, jump hypotheses, coasting and loss,
//! velocities, fix-then-filter epochs, measured error correlation, rewinds of late records and
//! 3-D tracks.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{range_record, site_text, slant, ANCHORS};
use super::update::GENERAL_KERNEL_ONLY;
use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// Fixes of two tags (σ stated 0.3 m, real 0.6 m, so the adaptive scale grows), with outliers,
/// a 285 m jump, a 12 s gap, velocities, 3-D fixes of 2-D tags and, out of order, fixes
/// up to 1.5 s late.
fn records(seed: u64, spatial: bool) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.6).unwrap();
    let mut records = Vec::new();
    for k in 0..400 {
        let t = 0.25 * f64::from(k);
        if (40.0..52.0).contains(&t) {
            continue; // a gap: the tracks coast, then are lost
        }
        for (i, tag) in ["f1", "f2"].into_iter().enumerate() {
            let jump = if i == 1 && t >= 70.0 { 285.0 } else { 0.0 };
            let truth = [2.0 + 0.7 * t + 4.0 * i as f64, 3.0 + 0.3 * t + jump, 1.0];
            let outlier = if rng.gen_bool(0.03) { 25.0 } else { 0.0 };
            let mut position_m: Vec<f64> = truth.iter().map(|p| p + noise.sample(&mut rng)).collect();
            position_m[0] += outlier;
            let (position_m, covariance_m2) = if spatial || k % 7 == 0 {
                (position_m, vec![0.09, 0.01, 0.0, 0.01, 0.09, 0.0, 0.0, 0.0, 0.16])
            } else {
                (position_m[..2].to_vec(), vec![0.09, 0.02, 0.02, 0.09])
            };
            let time_s = t + 0.01 * i as f64 - if k % 11 == 5 { 1.5 } else { 0.0 };
            records.push(Record {
                time_s,
                tag: tag.into(),
                measurement: Measurement::Fix {
                    position_m,
                    covariance_m2,
                },
            });
            if k % 5 == 0 {
                let d = if spatial { 3 } else { 2 };
                let mut covariance = vec![0.0; d * d];
                for axis in 0..d {
                    covariance[axis * d + axis] = 0.04;
                }
                records.push(Record {
                    time_s: time_s + 0.1,
                    tag: tag.into(),
                    measurement: Measurement::Velocity {
                        velocity_mps: [0.7, 0.3, 0.0][..d].to_vec(),
                        covariance_m2ps2: Some(covariance),
                    },
                });
            }
        }
        // a third tag by ranges (fix-then-filter epochs of the four anchors, σ = 0.1 m)
        let walker = [10.0 + 0.2 * t, 8.0 - 0.1 * t];
        for (id, a) in ANCHORS {
            records.push(range_record(
                t + 0.02,
                "r1",
                id,
                slant(walker, a) + 0.1 * noise.sample(&mut rng),
            ));
        }
    }
    records
}

/// Every record through a tracker of the test site with `extra` tracker settings, the fixed
/// kernel allowed or not.
fn run(extra: &str, records: &[Record], general_only: bool) -> Output {
    let mut text = site_text("fix-then-filter", "kf", extra);
    if extra.contains("rewind_horizon_s") {
        text = text.replace("reorder_window_s = 0.5", "reorder_window_s = 0.0");
    }
    if extra.contains("dimensions = 3") {
        // (a tag height is for 2-D tracks only)
        text = text.replace("tag_height_m = 1.0", "");
    }
    let site = Site::from_toml_str(&text, "fixed-path.toml").unwrap();
    GENERAL_KERNEL_ONLY.with(|flag| flag.set(general_only));
    let mut tracker = Tracker::new(&site).unwrap();
    let mut out = Output::default();
    for record in records.iter().cloned() {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    GENERAL_KERNEL_ONLY.with(|flag| flag.set(false));
    out
}

fn close(a: f64, b: f64) -> bool {
    // 1e-9 relative: one ulp differences of the kernels compounded over hundreds of updates
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

fn assert_same(extra: &str, spatial: bool, seed: u64) {
    let records = records(seed, spatial);
    let fast = run(extra, &records, false);
    let general = run(extra, &records, true);
    assert_eq!(fast.updates.len(), general.updates.len(), "{extra}: update count");
    assert!(fast.updates.len() > 300, "{extra}: {} updates", fast.updates.len());
    for (f, g) in fast.updates.iter().zip(&general.updates) {
        let numbers = |u: &TrackUpdate| {
            let mut v = vec![u.time_s];
            v.extend(u.position_m);
            v.extend(u.velocity_mps);
            v.extend(u.position_covariance_m2);
            v
        };
        assert!(
            numbers(f).iter().zip(numbers(g)).all(|(a, b)| close(*a, b)),
            "{extra}: {f:?} vs {g:?}"
        );
        assert_eq!(
            (&f.tag, f.predicted, f.status, f.source, f.revised),
            (&g.tag, g.predicted, g.status, g.source, g.revised),
            "{extra}"
        );
    }
    // the same events (rejections with their NIS, jumps, lifecycle, zones), in the same order
    let kinds = |out: &Output| -> Vec<String> { out.events.iter().map(|e| format!("{e:?}")).collect() };
    assert_eq!(kinds(&fast), kinds(&general), "{extra}: events");
    assert!(
        fast.events
            .iter()
            .any(|e| matches!(e, Event::Rejected { reason, .. } if reason.contains("validation gate"))),
        "{extra}: the scenario gates something out"
    );
    let (f, g) = (
        fast.innovations.of(NoiseClass::Fix),
        general.innovations.of(NoiseClass::Fix),
    );
    assert_eq!(f.updates, g.updates);
    assert!(close(f.nis, g.nis) && close(f.log_likelihood, g.log_likelihood) && close(f.noise_scale, g.noise_scale));
    assert!(
        f.mean_noise_scale().unwrap() > 1.5,
        "{extra}: the adaptive scale grew: {f:?}"
    );
}

#[test]
fn the_fixed_kernel_tracks_as_the_general_one() {
    assert_same("", false, 1);
}

#[test]
fn the_fixed_kernel_tracks_as_the_general_one_with_measured_correlation_and_rewinds() {
    let extra = "rewind_horizon_s = 2.0\n[tracker.adaptive_noise]\ncorrelation_from_innovations = true";
    assert_same(extra, false, 2);
}

#[test]
fn the_fixed_kernel_tracks_as_the_general_one_in_3d() {
    assert_same("dimensions = 3", true, 3);
}
