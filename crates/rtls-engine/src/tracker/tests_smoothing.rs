//! The smoothed history ([`super::Smoother`]): it lowers the error of a noisy walk, its 95 %
//! ellipses still hold the truth about 95 % of the time, its newest state keeps the filter's
//! covariance, each segment of fixes is smoothed with its own fitted noise (odometry with the
//! site's), it never crosses a restart or a re-creation of the track, and a revised update
//! replaces the kept ones.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tests::{fix_update_at, horizontal_nees, site};
use super::*;
use crate::lifecycle::TrackStatus;
use crate::record::Measurement;
use crate::site::Site;

/// A tag walking a circle of radius 8 m about (10, 10) at 1 m/s: not a constant velocity.
fn circle(t: f64) -> [f64; 2] {
    let angle = t / 8.0;
    [10.0 + 8.0 * angle.cos(), 10.0 + 8.0 * angle.sin()]
}

/// Fixes of `tags` tags every 0.5 s for `seconds`, σ = 1 m per axis, each tag with its own
/// noise; `truth(tag, t)` is where the tag is.
fn fixes(tags: usize, seconds: f64, truth: impl Fn(usize, f64) -> [f64; 2]) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let mut records = Vec::new();
    let mut t = 0.0;
    while t < seconds {
        for tag in 0..tags {
            let p = truth(tag, t);
            records.push(Record {
                time_s: t,
                tag: format!("w{tag}"),
                measurement: Measurement::Fix {
                    position_m: vec![p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)],
                    covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
                },
            });
        }
        t += 0.5;
    }
    records
}

/// Tracks `records` keeping states; returns the filtered updates and the smoothed ones.
fn track_and_smooth(records: Vec<Record>) -> (Vec<TrackUpdate>, SmoothedTracks) {
    track_and_smooth_on(&site("fix-then-filter", "kf", ""), records)
}

/// [`track_and_smooth`] on `site`.
fn track_and_smooth_on(site: &Site, records: Vec<Record>) -> (Vec<TrackUpdate>, SmoothedTracks) {
    let mut tracker = Tracker::new(site).unwrap();
    let mut smoother = tracker.smoother();
    let mut out = Output::keeping_states();
    let mut filtered = Vec::new();
    for record in records {
        tracker.push(record, &mut out).unwrap();
        smoother.take(&out);
        filtered.append(&mut out.updates);
        out.clear();
    }
    tracker.finish(&mut out).unwrap();
    smoother.take(&out);
    filtered.append(&mut out.updates);
    (filtered, smoother.finish())
}

/// Every segment smoothed, each with the site's model for an update that told more than its
/// information (the reason says so).
fn assert_site_model_for_every_segment(smoothed: &SmoothedTracks) {
    assert!(smoothed.failures.is_empty(), "{:?}", smoothed.failures);
    assert!(!smoothed.fits.is_empty());
    for segment in &smoothed.fits {
        let reason = segment.fit.as_ref().expect_err("the site's model");
        assert!(reason.contains("told more than its information"), "{reason}");
    }
}

/// Squared position error and its Mahalanobis distance `d² = eᵀ P⁻¹ e` (2-D).
fn error_and_distance(update: &TrackUpdate, truth: [f64; 2]) -> (f64, f64) {
    let e = [update.position_m[0] - truth[0], update.position_m[1] - truth[1]];
    (e[0] * e[0] + e[1] * e[1], horizontal_nees(update, e))
}

/// RMSE (m) and the share of 95 % ellipses holding the truth, over the measured updates after
/// the first 5 s of each tag.
fn score(updates: &[TrackUpdate], truth: impl Fn(usize, f64) -> [f64; 2]) -> (f64, f64, usize) {
    let scored: Vec<(f64, f64)> = updates
        .iter()
        .filter(|u| !u.predicted && u.time_s >= 5.0)
        .map(|u| {
            let tag: usize = u.tag[1..].parse().unwrap();
            error_and_distance(u, truth(tag, u.time_s))
        })
        .collect();
    let n = scored.len();
    let rmse = (scored.iter().map(|s| s.0).sum::<f64>() / n as f64).sqrt();
    // χ²₂(0.95) = 5.991
    let coverage = scored.iter().filter(|s| s.1 <= 5.991).count() as f64 / n as f64;
    (rmse, coverage, n)
}

#[test]
fn smoothing_a_noisy_walk_lowers_its_error_and_its_ellipses_still_hold_the_truth() {
    let (filtered, smoothed) = track_and_smooth(fixes(12, 120.0, on_circle));
    assert!(smoothed.failures.is_empty(), "{:?}", smoothed.failures);
    assert_eq!(smoothed.updates.len(), filtered.len());
    assert!(smoothed.updates.iter().all(|u| u.smoothed));

    // the reported covariance is a bound for any correlation of past and future errors: with
    // white errors (as here) it is conservative
    assert_smoothing_helps(&filtered, &smoothed, on_circle, 0.85, 0.95);
}

/// `[(RMSE, 95 % coverage)]` of the filtered and the smoothed updates (scored as [`score`]),
/// printed.
fn compared(
    filtered: &[TrackUpdate],
    smoothed: &SmoothedTracks,
    truth: impl Fn(usize, f64) -> [f64; 2] + Copy,
) -> [(f64, f64); 2] {
    let (filtered_rmse, filtered_coverage, n) = score(filtered, truth);
    let (smoothed_rmse, smoothed_coverage, _) = score(&smoothed.updates, truth);
    println!(
        "{n} updates: filtered RMSE {filtered_rmse:.3} m, 95 % coverage {filtered_coverage:.3}; \
         smoothed {smoothed_rmse:.3} m, {smoothed_coverage:.3}"
    );
    [(filtered_rmse, filtered_coverage), (smoothed_rmse, smoothed_coverage)]
}

/// The smoothed updates' RMSE is below `ratio` × the filtered one's, and their 95 % ellipses
/// hold the truth at least `coverage` of the time (scored as [`score`]).
fn assert_smoothing_helps(
    filtered: &[TrackUpdate],
    smoothed: &SmoothedTracks,
    truth: impl Fn(usize, f64) -> [f64; 2] + Copy,
    ratio: f64,
    coverage: f64,
) {
    let [(filtered_rmse, _), (smoothed_rmse, smoothed_coverage)] = compared(filtered, smoothed, truth);
    assert!(
        smoothed_rmse < ratio * filtered_rmse,
        "smoothed {smoothed_rmse} m against filtered {filtered_rmse} m"
    );
    assert!(
        smoothed_coverage >= coverage,
        "smoothed 95 % ellipses hold the truth {smoothed_coverage:.3} of the time"
    );
}

/// Where tag `tag` is at `t`: its own phase of [`circle`].
fn on_circle(tag: usize, t: f64) -> [f64; 2] {
    circle(t + 7.0 * tag as f64)
}

/// Fixes every 0.5 s for 120 s of `tags` tags on [`on_circle`], each tag's errors AR(1) per axis:
/// `e_k = ρ e_{k−1} + √(1 − ρ²) w_k`, `w ~ N(0, 1 m²)` (σ = 1 m, as each fix states).
fn ar1_fix_records(rho: f64, tags: usize, seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let mut errors = vec![[0.0, 0.0]; tags];
    let mut records = Vec::new();
    for k in 0..240 {
        let t = 0.5 * f64::from(k);
        for (tag, error) in errors.iter_mut().enumerate() {
            for e in error.iter_mut() {
                *e = if k == 0 {
                    noise.sample(&mut rng)
                } else {
                    rho * *e + (1.0 - rho * rho).sqrt() * noise.sample(&mut rng)
                };
            }
            let p = on_circle(tag, t);
            records.push(Record {
                time_s: t,
                tag: format!("w{tag}"),
                measurement: Measurement::Fix {
                    position_m: vec![p[0] + error[0], p[1] + error[1]],
                    covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
                },
            });
        }
    }
    records
}

/// Fix errors that stay for far longer than the filter's memory (a UWB fix off by the
/// anchors' geometry wherever the tag walks slowly): the past and the future share them, and
/// the smoothed ellipses must not claim the future halved them. The bound over the whole state
/// (`intersection_bound`) did, and held the truth markedly less often than the filter's.
#[test]
fn with_fix_errors_that_persist_for_a_minute_the_smoothed_ellipses_keep_the_filters_calibration() {
    // e_k = ρ e_{k−1} + √(1 − ρ²) w_k, ρ = 0.99 per 0.5 s (a correlation time of 50 s), σ = 1 m
    let (filtered, smoothed) = track_and_smooth(ar1_fix_records(0.99, 24, 5));
    let [(_, filtered_coverage), (_, smoothed_coverage)] = compared(&filtered, &smoothed, on_circle);
    assert!(
        smoothed_coverage >= filtered_coverage - 0.02,
        "smoothed 95 % ellipses hold the truth {smoothed_coverage:.3} of the time, filtered {filtered_coverage:.3}"
    );
}

#[test]
fn with_fix_errors_that_persist_for_seconds_the_smoothed_ellipses_keep_the_filters_calibration() {
    // each tag's fix errors are AR(1): e_k = ρ e_{k−1} + √(1 − ρ²) w_k, ρ = 0.8 per 0.5 s
    // (a correlation time of 2.2 s: a multipath or a fade that stays), σ = 1 m
    let (filtered, smoothed) = track_and_smooth(ar1_fix_records(0.8, 12, 11));
    let [(filtered_rmse, filtered_coverage), (smoothed_rmse, smoothed_coverage)] =
        compared(&filtered, &smoothed, on_circle);
    assert!(smoothed_rmse < 0.9 * filtered_rmse);
    // the smoother keeps the filter's calibration (the filter's own, under errors it takes as
    // white, is short of 95 %: 0.79); the smoother's own covariance Pₖ|ₙ would lose it
    assert!(
        smoothed_coverage >= filtered_coverage - 0.02,
        "smoothed 95 % ellipses hold the truth {smoothed_coverage:.3} of the time, filtered {filtered_coverage:.3}"
    );
}

#[test]
fn the_newest_smoothed_state_keeps_the_filters_covariance_and_lies_in_its_ellipse() {
    let (filtered, smoothed) = track_and_smooth(fixes(1, 30.0, |_, t| circle(t)));
    let last_filtered = filtered.last().unwrap();
    let last_smoothed = smoothed.updates.last().unwrap();
    assert_eq!(last_filtered.time_s, last_smoothed.time_s);
    for (a, b) in last_filtered
        .position_covariance_m2
        .iter()
        .zip(&last_smoothed.position_covariance_m2)
    {
        assert!((a - b).abs() < 1e-9);
    }
    // the mean is the fitted model's filter at that time, not the tracker's: within the
    // tracker's 95 % ellipse (χ²(2) 5.99)
    let e = [
        last_smoothed.position_m[0] - last_filtered.position_m[0],
        last_smoothed.position_m[1] - last_filtered.position_m[1],
    ];
    assert!(horizontal_nees(last_filtered, e) < 5.99);
    // and an earlier one moved: the smoother did something
    let k = filtered.len() / 2;
    assert!((filtered[k].position_m[0] - smoothed.updates[k].position_m[0]).abs() > 1e-6);
}

/// Each segment of fixes is smoothed with its own fitted noise; a steady walk is given a
/// smaller `q` than the site's (σ_a = 0.5 m/s²: 0.25 m²/s³). A track that took odometry is
/// not: its updates tell more than their information in the CV layout says.
#[test]
fn fixes_are_smoothed_with_their_own_fitted_noise_and_odometry_with_the_sites() {
    let (_, smoothed) = track_and_smooth(fixes(3, 120.0, |tag, t| [1.0 * t, 3.0 * tag as f64]));
    assert_eq!(smoothed.fits.len(), 3, "{:?}", smoothed.fits);
    for segment in &smoothed.fits {
        let fit = segment.fit.as_ref().expect("a fitted segment");
        assert!(fit.acceleration_psd_m2ps3 < 0.25, "{fit:?}");
    }

    let mut tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut smoother = tracker.smoother();
    let mut out = Output::keeping_states();
    for k in 0..100 {
        let t = f64::from(k) * 0.5;
        let fix = Measurement::Fix {
            position_m: vec![0.8 * t, 0.5 * t],
            covariance_m2: vec![0.25, 0.0, 0.0, 0.25],
        };
        let odometry = Measurement::Odometry {
            speed_mps: (0.8f64 * 0.8 + 0.5 * 0.5).sqrt(),
            heading_rad: Some(0.5f64.atan2(0.8)),
            speed_std_mps: Some(0.02),
            heading_std_rad: Some(0.02),
        };
        for (dt_s, measurement) in [(0.0, fix), (0.25, odometry)] {
            let record = Record {
                time_s: t + dt_s,
                tag: "r1".into(),
                measurement,
            };
            tracker.push(record, &mut out).unwrap();
            smoother.take(&out);
            out.clear();
        }
    }
    tracker.finish(&mut out).unwrap();
    smoother.take(&out);
    let smoothed = smoother.finish();
    assert_site_model_for_every_segment(&smoothed);
    assert!(smoothed.updates.iter().all(|u| u.smoothed));
}

/// A track predicted with an accelerometer's control input: the re-filter has no `B u`, so its
/// segment is smoothed with the site's model (seed 002's node: fitted 1.26 m against 0.86 m).
#[test]
fn accelerometer_aided_tracks_are_smoothed_with_the_sites_model() {
    let mut records = fixes(1, 40.0, |_, t| [0.25 * t * t, 0.0]);
    records.extend((0..400).map(|k| Record {
        time_s: f64::from(k) * 0.1 + 0.05,
        tag: "w0".into(),
        measurement: Measurement::Accelerometer {
            acceleration_mps2: vec![0.5, 0.0],
            std_mps2: Some(0.05),
        },
    }));
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let (_, smoothed) = track_and_smooth(records);
    assert_site_model_for_every_segment(&smoothed);
}

/// Under the IMM a track's combined prior and posterior are mixtures, not one linear update:
/// its segments are smoothed with the site's model.
#[test]
fn imm_tracks_are_smoothed_with_the_sites_model() {
    let text =
        super::tests::site_text("fix-then-filter", "kf", "").replace("motion_model = \"cv\"", "motion_model = \"imm\"");
    let imm = Site::from_toml_str(&text, "imm.toml").unwrap();
    let (_, smoothed) = track_and_smooth_on(&imm, fixes(1, 60.0, |_, t| circle(t)));
    assert_site_model_for_every_segment(&smoothed);
}

/// A tag whose track was deleted and created again starts a segment of its own: the smoother
/// does not join the two tracks.
#[test]
fn a_track_created_again_after_its_deletion_is_a_new_segment() {
    let mut records = fixes(1, 20.0, |_, t| circle(t));
    // silent past the delete timeout, then back 200 m away
    records.extend(fixes(1, 20.0, |_, t| circle(t)).into_iter().map(|mut r| {
        r.time_s += 1_000.0;
        if let Measurement::Fix { position_m, .. } = &mut r.measurement {
            position_m[0] += 200.0;
        }
        r
    }));
    let (_, smoothed) = track_and_smooth(records);
    assert!(smoothed.failures.is_empty(), "{:?}", smoothed.failures);
    assert_eq!(smoothed.fits.len(), 2, "{:?}", smoothed.fits);
    // (the first segment ends with its coasting predictions)
    assert!(
        smoothed.fits[0].to_s < 100.0 && smoothed.fits[1].from_s >= 1_000.0,
        "{:?}",
        smoothed.fits
    );
}

#[test]
fn the_smoother_never_crosses_a_restart_of_the_track() {
    // from t = 40 s the tag's fixes are 285 m north: the track jumps (a new segment)
    let truth = |_: usize, t: f64| {
        let p = circle(t);
        if t >= 40.0 {
            [p[0], p[1] + 285.0]
        } else {
            p
        }
    };
    let (_, smoothed) = track_and_smooth(fixes(1, 80.0, truth));
    assert!(smoothed.failures.is_empty(), "{:?}", smoothed.failures);
    // every smoothed update before the jump stays with the walk, none is pulled north
    let before: Vec<&TrackUpdate> = smoothed
        .updates
        .iter()
        .filter(|u| u.time_s < 40.0 && u.status != TrackStatus::Lost)
        .collect();
    assert!(before.len() > 60);
    for update in before {
        let p = circle(update.time_s);
        let error_m = (update.position_m[0] - p[0]).hypot(update.position_m[1] - p[1]);
        assert!(
            error_m < 4.0,
            "at {} s the smoothed track is {error_m:.1} m off",
            update.time_s
        );
    }
    // and the updates after it follow the tag there
    let last = smoothed.updates.last().unwrap();
    assert!(last.position_m[1] > 250.0);
}

#[test]
fn a_revised_update_replaces_the_kept_updates_at_and_after_its_time() {
    let tracker = Tracker::new(&site("fix-then-filter", "kf", "")).unwrap();
    let mut smoother = tracker.smoother();
    let update = |time_s: f64, x: f64, revised: bool| TrackUpdate {
        revised,
        ..fix_update_at("a", time_s, x, [1.0, 1.0])
    };
    let mut out = Output {
        updates: vec![
            update(1.0, 1.0, false),
            update(2.0, 2.0, false),
            update(3.0, 3.0, false),
        ],
        ..Output::default()
    };
    smoother.take(&out);
    out.updates = vec![update(2.0, 20.0, true)];
    smoother.take(&out);
    let smoothed = smoother.finish();
    // updates without their states pass unchanged
    let kept: Vec<(f64, f64, bool)> = smoothed
        .updates
        .iter()
        .map(|u| (u.time_s, u.position_m[0], u.smoothed))
        .collect();
    assert_eq!(kept, vec![(1.0, 1.0, false), (2.0, 20.0, false)]);
}

#[test]
fn a_coordinated_turn_is_smoothed_with_its_own_model() {
    // tags circling 4 m about (10, 10) at 1.2 m/s (ω = 0.3 rad/s), tracked with the turn rate
    // as a state: a CV backward pass would cut every arc short
    let truth = |tag: usize, t: f64| {
        let angle = 0.3 * t + tag as f64;
        [10.0 + 4.0 * angle.cos(), 10.0 + 4.0 * angle.sin()]
    };
    let text =
        super::tests::site_text("fix-then-filter", "ekf", "").replace("motion_model = \"cv\"", "motion_model = \"ct\"");
    let site = Site::from_toml_str(&text, "ct.toml").unwrap();
    let (filtered, smoothed) = track_and_smooth_on(&site, fixes(6, 120.0, truth));
    assert!(smoothed.failures.is_empty(), "{:?}", smoothed.failures);
    assert!(smoothed.updates.iter().all(|u| u.smoothed));
    for segment in &smoothed.fits {
        let reason = segment.fit.as_ref().expect_err("the tracker's own model");
        assert!(reason.contains("coordinated turn"), "{reason}");
    }
    assert_smoothing_helps(&filtered, &smoothed, truth, 0.8, 0.9);
}

/// A track whose speed the limit cut is smoothed with the site's model over its own states,
/// which hold the cut, not re-filtered from its updates' information, which does not: the
/// smoothed speed stays near the limit instead of the fixes' run.
#[test]
fn a_track_the_speed_limit_cut_is_smoothed_over_its_own_states() {
    // fixes 1 s apart running at 8 m/s; the limit is 3 m/s
    let records = super::tests::running_fixes(1.0, 30);
    let (_, smoothed) = track_and_smooth_on(&site("fix-then-filter", "kf", "max_speed_mps = 3.0"), records.clone());
    assert_site_model_for_every_segment(&smoothed);
    // without the limit the same fixes are re-filtered with their own fitted noise
    let (_, free) = track_and_smooth_on(&site("fix-then-filter", "kf", ""), records);
    assert!(free.fits.iter().all(|segment| segment.fit.is_ok()), "{:?}", free.fits);
}
