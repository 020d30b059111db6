//! Jump hypotheses ([`super::jump`]): a tag whose fixes move 285 m at once is followed within
//! the confirmation's evidence, not after the rejection rate's nine fixes; single outliers and
//! outliers that do not agree with each other never move the track.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{jump_times, site};
use super::*;
use crate::lifecycle::LifecycleEvent;
use crate::record::Measurement;

/// A tag `p1` walking east from (5, 5), located every `period_s` with fixes of `std_m` noise
/// (stated as it is), the noise drawn from `seed`.
#[derive(Clone, Copy)]
struct Walk {
    period_s: f64,
    speed_mps: f64,
    std_m: f64,
    seed: u64,
}

/// `count` fixes of `walk`; `displaced(k, t)` gives fix `k`'s offset from the walk at `t`.
fn walk_fixes(walk: Walk, count: u32, displaced: impl Fn(u32, f64) -> [f64; 2]) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(walk.seed);
    let noise = Normal::new(0.0, walk.std_m).unwrap();
    let variance = walk.std_m * walk.std_m;
    (0..count)
        .map(|k| {
            let t = f64::from(k) * walk.period_s;
            let offset = displaced(k, t);
            Record {
                time_s: t,
                tag: "p1".into(),
                measurement: Measurement::Fix {
                    position_m: vec![
                        5.0 + walk.speed_mps * t + offset[0] + noise.sample(&mut rng),
                        5.0 + offset[1] + noise.sample(&mut rng),
                    ],
                    covariance_m2: vec![variance, 0.0, 0.0, variance],
                },
            }
        })
        .collect()
}

/// One fix per second (σ = 0.5 m) of a tag walking east at 1 m/s from (5, 5); `displaced`
/// gives each fix's offset from the walk.
fn fixes(seconds: u32, displaced: impl Fn(f64) -> [f64; 2]) -> Vec<Record> {
    let walk = Walk {
        period_s: 1.0,
        speed_mps: 1.0,
        std_m: 0.5,
        seed: 21,
    };
    walk_fixes(walk, seconds, |_, t| displaced(t))
}

fn track(records: Vec<Record>) -> Output {
    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out
}

/// The measured (not predicted) updates' positions from `from_s` on.
fn measured_from(out: &Output, from_s: f64) -> Vec<(f64, [f64; 3])> {
    out.updates
        .iter()
        .filter(|u| !u.predicted && u.time_s >= from_s)
        .map(|u| (u.time_s, u.position_m))
        .collect()
}

#[test]
fn a_tag_whose_fixes_move_285_m_is_followed_after_the_confirmation_evidence() {
    // from t = 20 s the fixes are 285 m north of the walk
    let out = track(fixes(40, |t| if t >= 20.0 { [0.0, 285.0] } else { [0.0, 0.0] }));
    // initiation: 3 fixes within 5 s, so the track jumps at the third displaced fix, t = 22 s
    // (the rejection rate alone took nine: t = 28 s)
    assert_eq!(jump_times(&out), vec![22.0]);
    let after = measured_from(&out, 22.0);
    assert!(!after.is_empty());
    for (t, p) in &after {
        assert!((p[1] - 290.0).abs() < 2.0, "t = {t}: {p:?}");
    }
    // the two displaced fixes before it were gated out, and say they are held
    let held = out
        .events
        .iter()
        .filter(|e| matches!(e, Event::Rejected { reason, .. } if reason.contains("jump hypothesis")))
        .count();
    assert_eq!(held, 2);
    // the fix that confirmed the jump is not reported rejected
    assert!(!out
        .events
        .iter()
        .any(|e| matches!(e, Event::Rejected { time_s, .. } if *time_s == 22.0)));
    // the jumped track is consistent again at once: its velocity is the walk's, not 285 m/s
    let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap();
    assert!(
        (last.velocity_mps[0] - 1.0).abs() < 0.5 && last.velocity_mps[1].abs() < 0.5,
        "{last:?}"
    );
}

#[test]
fn outliers_that_do_not_agree_never_move_the_track() {
    // a single 50 m outlier at t = 10; at t = 20..22 three outliers scattered 40–80 m apart
    let out = track(fixes(40, |t| match t as u32 {
        10 => [50.0, 0.0],
        20 => [0.0, 60.0],
        21 => [0.0, -60.0],
        22 => [70.0, 30.0],
        _ => [0.0, 0.0],
    }));
    assert!(jump_times(&out).is_empty(), "{:?}", jump_times(&out));
    for (t, p) in measured_from(&out, 3.0) {
        assert!(p[1].abs() < 7.0 && (p[0] - 5.0 - t).abs() < 2.0, "t = {t}: {p:?}");
    }
}

#[test]
fn a_burst_of_agreeing_outliers_shorter_than_the_span_does_not_move_a_fast_track() {
    // 10 Hz fixes; for 0.5 s (6 fixes) they agree on a point 3 m off, a persisting reflection
    let walk = Walk {
        period_s: 0.1,
        speed_mps: 1.0,
        std_m: 0.1,
        seed: 3,
    };
    let records = walk_fixes(walk, 200, |k, _| {
        if (100..106).contains(&k) {
            [0.0, 3.0]
        } else {
            [0.0, 0.0]
        }
    });
    let out = track(records);
    assert!(jump_times(&out).is_empty(), "{:?}", jump_times(&out));
    for (t, p) in measured_from(&out, 1.0) {
        assert!((p[1] - 5.0).abs() < 0.5, "t = {t}: {p:?}");
    }
}

/// The `alternating` events of `out`, with their positions.
fn alternations(out: &Output) -> Vec<(f64, [f64; 3])> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Lifecycle {
                event: LifecycleEvent::Alternating,
                time_s,
                position_m,
                ..
            } => Some((*time_s, *position_m)),
            _ => None,
        })
        .collect()
}

#[test]
fn fixes_from_two_transmitters_under_one_id_are_reported_alternating_once() {
    // from t = 10 s every third fix comes from a second transmitter standing at (0, 205)
    // (UJIIndoorLoc's phone 20: one id, two phones in different buildings)
    let out = track(fixes(60, |t| {
        if t >= 10.0 && (t as u32).is_multiple_of(3) {
            [-5.0 - t, 200.0]
        } else {
            [0.0, 0.0]
        }
    }));
    let reported = alternations(&out);
    assert_eq!(reported.len(), 1, "{reported:?}");
    let (t, p) = reported[0];
    // the third return: the fourth fix of the second transmitter, t = 21 s
    assert_eq!(t, 21.0);
    assert!(p[0].abs() < 2.0 && (p[1] - 205.0).abs() < 2.0, "{p:?}");
    // the track stays on the first transmitter until then; from the report on, each
    // transmitter's fixes update its own state (the fix's true place is 205 m or 5 m north)
    let measured = measured_from(&out, 3.0);
    let second_measured = measured
        .iter()
        .filter(|(t, _)| *t > 21.0 && (*t as u32).is_multiple_of(3))
        .count();
    // t = 24, 27, …, 57 s
    assert_eq!(second_measured, 12, "{measured:?}");
    for (t, p) in measured {
        let second = t > 21.0 && (t as u32).is_multiple_of(3);
        let north = if second { 205.0 } else { 5.0 };
        assert!((p[1] - north).abs() < 3.0, "t = {t}: {p:?}");
        if second {
            assert!(p[0].abs() < 3.0, "t = {t}: {p:?}");
        } else {
            assert!((p[0] - 5.0 - t).abs() < 3.0, "t = {t}: {p:?}");
        }
    }
}

/// Two people carrying one id, 80 m apart, scanned one at a time every 4–12 s with fixes of
/// σ = 5 m (UJIIndoorLoc's phone 20): the gaps leave the track's gate wide enough to take
/// some of the other person's fixes, and until it reports `alternating` it is pulled between
/// them; from the report on each person's fixes update that person's own state, so the track
/// is closer to the person of each fix than the fix is.
#[test]
fn two_people_under_one_id_each_keep_their_own_state_once_reported() {
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    let noise = Normal::new(0.0, 5.0).unwrap();
    // person A walks east along y = 0 at 0.05 m/s, person B stands at (60, 50); who is
    // scanned next alternates irregularly (runs of one to three), 4–12 s apart
    let mut records = Vec::new();
    let mut truths = Vec::new();
    let mut t = 0.0;
    for k in 0..150_u32 {
        t += 4.0 + f64::from((k * 7) % 9);
        let person_b = (k / 2 + k % 3).is_multiple_of(2);
        let truth = if person_b { [60.0, 50.0] } else { [0.05 * t, 0.0] };
        truths.push((t, truth));
        records.push(Record {
            time_s: t,
            tag: "phone".into(),
            measurement: Measurement::Fix {
                position_m: vec![truth[0] + noise.sample(&mut rng), truth[1] + noise.sample(&mut rng)],
                covariance_m2: vec![25.0, 0.0, 0.0, 25.0],
            },
        });
    }
    let fixes: Vec<[f64; 2]> = records
        .iter()
        .map(|r| match &r.measurement {
            Measurement::Fix { position_m, .. } => [position_m[0], position_m[1]],
            _ => unreachable!(),
        })
        .collect();
    // a site for scans minutes apart (the UJIIndoorLoc import's lifecycle and noise)
    let text = super::tests::site_text("fix-then-filter", "kf", "platform = \"walker\"")
        .replace(
            "confirm_updates = 3, within_s = 5.0",
            "confirm_updates = 1, within_s = 60.0",
        )
        .replace("coast_timeout_s = 5.0", "coast_timeout_s = 120.0")
        .replace("delete_timeout_s = 20.0", "delete_timeout_s = 600.0")
        .replace("acceleration_noise_std_mps2 = 0.5", "acceleration_noise_std_mps2 = 1.0");
    let mut tracker = Tracker::new(&crate::site::Site::from_toml_str(&text, "test-site.toml").unwrap()).unwrap();
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let reported = alternations(&out);
    assert_eq!(reported.len(), 1, "{reported:?}");
    let since = reported[0].0;
    let measured = measured_from(&out, since);
    // root-mean-square error of the track's updates and of the fixes, at the same times
    let (mut track_sq, mut fix_sq, mut n) = (0.0, 0.0, 0.0);
    for (time_s, p) in &measured {
        let i = truths.iter().position(|(tt, _)| tt == time_s).unwrap();
        let truth = truths[i].1;
        track_sq += (p[0] - truth[0]).powi(2) + (p[1] - truth[1]).powi(2);
        fix_sq += (fixes[i][0] - truth[0]).powi(2) + (fixes[i][1] - truth[1]).powi(2);
        n += 1.0;
    }
    assert!(n > 100.0, "{n} updates after the report at {since} s");
    let (track_rmse, fix_rmse) = ((track_sq / n).sqrt(), (fix_sq / n).sqrt());
    assert!(
        track_rmse < fix_rmse,
        "track {track_rmse:.2} m against its fixes' {fix_rmse:.2} m"
    );
}

#[test]
fn outliers_at_scattered_places_are_not_alternating() {
    // outliers every third second, each somewhere else
    let out = track(fixes(60, |t| {
        if t >= 10.0 && (t as u32).is_multiple_of(3) {
            [40.0 * (t * 0.7).sin(), 60.0 + 40.0 * (t * 1.3).cos()]
        } else {
            [0.0, 0.0]
        }
    }));
    assert!(alternations(&out).is_empty(), "{:?}", alternations(&out));
}

/// A reflection that recurs (every twelfth fix of a 4 Hz stream 25 m east of the walk,
/// moving with it) is reported `alternating`, but it sends a twelfth of the fixes, under the
/// share of a second transmitter: the track never switches to it, and its fixes stay gated
/// out.
#[test]
fn a_recurring_reflection_is_reported_but_never_followed() {
    let walk = Walk {
        period_s: 0.25,
        speed_mps: 0.7,
        std_m: 0.3,
        seed: 12,
    };
    let records = walk_fixes(walk, 800, |k, _| if k % 12 == 11 { [25.0, 0.0] } else { [0.0, 0.0] });
    let out = track(records);
    assert_eq!(alternations(&out).len(), 1, "{:?}", alternations(&out));
    for (t, p) in measured_from(&out, 3.0) {
        assert!(
            (p[0] - 5.0 - 0.7 * t).abs() < 2.0 && (p[1] - 5.0).abs() < 2.0,
            "t = {t}: {p:?}"
        );
    }
}
