//! GNSS pseudoranges end to end: simulated satellites on circular orbits, a car driving loops
//! around the site's geodetic origin with a drifting receiver clock, records through
//! `Tracker::push` / `finish`.

use nalgebra::{Matrix2, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_positioning::gnss::{earth_rotation_correction, Geodetic, LocalFrame};

use super::{Event, Output, Tracker, UpdateSource};
use crate::record::{Measurement, Record};
use crate::site::Site;

/// GPS orbit radius, m, and mean motion (one revolution per half sidereal day), rad/s.
const ORBIT_RADIUS_M: f64 = 26_560e3;
const MEAN_MOTION_RADPS: f64 = 2.0 * std::f64::consts::PI / 43_082.0;
const SIGMA_M: f64 = 3.0;
const ANTENNA_HEIGHT_M: f64 = 1.5;
/// The receiver clock: bias b₀ + ḃ t, m.
const CLOCK_BIAS_M: f64 = 3.0e5;
const CLOCK_DRIFT_MPS: f64 = 50.0;

const ORIGIN: [f64; 3] = [47.3769, 8.5417, 455.0];

fn frame() -> LocalFrame {
    LocalFrame::new(Geodetic {
        latitude_deg: ORIGIN[0],
        longitude_deg: ORIGIN[1],
        height_m: ORIGIN[2],
    })
    .unwrap()
}

fn site(pipeline: &str, filter: &str, dimensions: u8, with_origin: bool) -> Site {
    let frame = if with_origin {
        format!(
            "[frame]\norigin = {{ latitude_deg = {}, longitude_deg = {}, height_m = {} }}\n",
            ORIGIN[0], ORIGIN[1], ORIGIN[2]
        )
    } else {
        String::new()
    };
    let height = if dimensions == 2 {
        format!("tag_height_m = {ANTENNA_HEIGHT_M}")
    } else {
        String::new()
    };
    let text = format!(
        r#"{frame}
[tracker]
pipeline = "{pipeline}"
motion_model = "cv"
filter = "{filter}"
acceleration_noise_std_mps2 = 1.0
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 5.0 }}
coast_timeout_s = 10.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
dimensions = {dimensions}
{height}
"#
    );
    Site::from_toml_str(&text, "gnss-site.toml").unwrap()
}

/// One satellite: its position at t = 0 (seen from the origin at an azimuth and elevation)
/// and the axis of its circular orbit.
struct Orbit {
    id: String,
    start: Vector3<f64>,
    axis: Vector3<f64>,
}

impl Orbit {
    /// The ECEF position at `t`: `start` turned about `axis` by `n t` (Rodrigues).
    fn at(&self, t: f64) -> Vector3<f64> {
        let (sin, cos) = (MEAN_MOTION_RADPS * t).sin_cos();
        let (k, v) = (self.axis, self.start);
        v * cos + k.cross(&v) * sin + k * k.dot(&v) * (1.0 - cos)
    }
}

/// Eight satellites spread over the sky, on orbits inclined in turn.
fn constellation(frame: &LocalFrame) -> Vec<Orbit> {
    let sky = [
        (10.0, 75.0),
        (60.0, 35.0),
        (120.0, 20.0),
        (170.0, 50.0),
        (220.0, 15.0),
        (260.0, 40.0),
        (310.0, 25.0),
        (350.0, 12.0),
    ];
    sky.iter()
        .enumerate()
        .map(|(i, &(az, el)): (usize, &(f64, f64))| {
            let (az, el) = (az.to_radians(), el.to_radians());
            let u = frame.rotation().transpose() * Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
            let r0 = frame.origin_ecef_m();
            // ‖r₀ + d u‖ = R
            let ru = r0.dot(&u);
            let start = r0 + u * (-ru + (ru * ru - r0.norm_squared() + ORBIT_RADIUS_M * ORBIT_RADIUS_M).sqrt());
            // an axis perpendicular to the satellite, tilted differently for each
            let tilt = Vector3::new((i as f64).cos(), (i as f64).sin(), 1.5).normalize();
            let axis = (tilt - start.normalize() * tilt.dot(&start.normalize())).normalize();
            Orbit {
                id: format!("G{:02}", i + 1),
                start,
                axis,
            }
        })
        .collect()
}

/// The car: loops of radius 80 m about (20, −10) at 8 m/s, ENU m.
fn truth(t: f64) -> Vector3<f64> {
    let angle = 0.1 * t;
    Vector3::new(20.0 + 80.0 * angle.cos(), -10.0 + 80.0 * angle.sin(), ANTENNA_HEIGHT_M)
}

/// Pseudorange records at 1 Hz for `seconds`: `(time, satellites used)` per epoch from `pick`,
/// and `outlier = Some((epoch, satellite index, error))` added to one pseudorange.
fn records(
    seconds: usize,
    seed: u64,
    pick: impl Fn(usize) -> usize,
    outlier: Option<(usize, usize, f64)>,
) -> Vec<Record> {
    let frame = frame();
    let orbits = constellation(&frame);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, SIGMA_M).unwrap();
    let mut out = Vec::new();
    for k in 0..seconds {
        let t = k as f64;
        let receiver = frame.ecef_from_enu(&truth(t));
        let bias = CLOCK_BIAS_M + CLOCK_DRIFT_MPS * t;
        for (i, orbit) in orbits.iter().enumerate().take(pick(k)) {
            let s = orbit.at(t);
            let geometric = (earth_rotation_correction(&s, &receiver).unwrap() - receiver).norm();
            let fault = outlier.filter(|&(e, sat, _)| e == k && sat == i).map_or(0.0, |o| o.2);
            out.push(Record {
                time_s: 1.7e9 + t,
                tag: "car-1".into(),
                measurement: Measurement::Pseudorange {
                    satellite: orbit.id.clone(),
                    satellite_position_m: [s[0], s[1], s[2]],
                    pseudorange_m: geometric + bias + noise.sample(&mut rng) + fault,
                    std_m: Some(SIGMA_M),
                },
            });
        }
    }
    out
}

/// CAN odometry at 1 Hz (speed and heading of the loop, σ 0.1 m/s and 0.02 rad), merged into
/// `records` in time order (odometry first at equal times).
fn with_odometry(records: Vec<Record>, seconds: usize, seed: u64) -> Vec<Record> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (speed_noise, heading_noise) = (Normal::new(0.0, 0.1).unwrap(), Normal::new(0.0, 0.02).unwrap());
    let mut merged: Vec<Record> = (0..seconds)
        .map(|k| {
            let t = k as f64;
            Record {
                time_s: 1.7e9 + t,
                tag: "car-1".into(),
                measurement: Measurement::Odometry {
                    speed_mps: 8.0 + speed_noise.sample(&mut rng),
                    // the loop turns counter-clockwise: heading = angle + π/2
                    heading_rad: Some(0.1 * t + std::f64::consts::FRAC_PI_2 + heading_noise.sample(&mut rng)),
                    speed_std_mps: Some(0.1),
                    heading_std_rad: Some(0.02),
                },
            }
        })
        .collect();
    merged.extend(records);
    // a stable sort keeps the odometry before the pseudoranges of the same time
    merged.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    merged
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

/// `(horizontal RMSE of the measured track updates, share of truths inside their 95 %
/// ellipse, horizontal RMSE of the raw pseudorange fixes, updates)`, after the first `skip_s`.
fn scores(out: &Output, skip_s: f64) -> (f64, f64, f64, usize) {
    let mut squared = 0.0;
    let mut inside = 0;
    let mut n = 0;
    for u in &out.updates {
        let t = u.time_s - 1.7e9;
        if u.predicted || u.source != UpdateSource::Fix || t < skip_s {
            continue;
        }
        let e = Vector2::new(u.position_m[0], u.position_m[1]) - truth(t).xy();
        let d = u.dimensions;
        let c = &u.position_covariance_m2;
        let p = Matrix2::new(c[0], c[1], c[d], c[d + 1]);
        squared += e.norm_squared();
        // d² = eᵀ P⁻¹ e ≤ χ²₂(0.95)
        if (e.transpose() * p.try_inverse().unwrap() * e)[0] <= 5.991 {
            inside += 1;
        }
        n += 1;
    }
    let raw: Vec<f64> = out
        .fixes
        .iter()
        .filter(|f| f.method == Some("pseudorange") && f.time_s - 1.7e9 >= skip_s)
        .map(|f| (Vector2::new(f.position_m[0], f.position_m[1]) - truth(f.time_s - 1.7e9).xy()).norm_squared())
        .collect();
    let raw_rmse = (raw.iter().sum::<f64>() / raw.len() as f64).sqrt();
    ((squared / n as f64).sqrt(), inside as f64 / n as f64, raw_rmse, n)
}

fn rejections<'a>(out: &'a Output, kind: &str) -> Vec<&'a str> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { kind: k, reason, .. } if *k == kind => Some(reason.as_str()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_drifting_receiver_is_tracked_in_both_pipelines() {
    for (pipeline, filter) in [("fix-then-filter", "kf"), ("tightly-coupled", "ekf")] {
        let out = run(&site(pipeline, filter, 2, true), records(180, 11, |_| 8, None));
        let (rmse, coverage, raw_rmse, n) = scores(&out, 10.0);
        println!(
            "{pipeline}: {n} updates, track horizontal RMSE {rmse:.2} m, raw fix RMSE {raw_rmse:.2} m, \
             95 % ellipse coverage {:.1} %",
            100.0 * coverage
        );
        assert!(n >= 160, "{n} updates");
        assert!(
            rejections(&out, "pseudorange").is_empty(),
            "{:?}",
            rejections(&out, "pseudorange")
        );
        // pseudoranges alone, a car turning at 0.8 m/s²: the CV filter smooths a little
        assert!(rmse < 0.95 * raw_rmse, "track {rmse} m vs raw fixes {raw_rmse} m");
        assert!(raw_rmse < 2.0 * SIGMA_M, "raw fixes {raw_rmse} m");
        assert!(coverage >= 0.9, "{coverage}");
    }
}

#[test]
fn can_odometry_between_the_epochs_smooths_the_fixes() {
    for (pipeline, filter) in [("fix-then-filter", "kf"), ("tightly-coupled", "ekf")] {
        let input = with_odometry(records(180, 11, |_| 8, None), 180, 12);
        let out = run(&site(pipeline, filter, 2, true), input);
        let (rmse, coverage, raw_rmse, n) = scores(&out, 10.0);
        println!(
            "{pipeline} with odometry: {n} updates, track horizontal RMSE {rmse:.2} m, raw fix RMSE \
             {raw_rmse:.2} m, 95 % ellipse coverage {:.1} %",
            100.0 * coverage
        );
        assert!(n >= 160, "{n} updates");
        assert!(rmse < 0.6 * raw_rmse, "track {rmse} m vs raw fixes {raw_rmse} m");
        assert!(coverage >= 0.9, "{coverage}");
    }
}

#[test]
fn a_three_satellite_epoch_still_gives_a_fix_thanks_to_the_clock_prior() {
    // 3-D: four unknowns (position and clock); every tenth epoch after 30 s hears 3 satellites
    let thin = |k: usize| if k >= 30 && k.is_multiple_of(10) { 3 } else { 8 };
    let out = run(&site("fix-then-filter", "kf", 3, true), records(90, 5, thin, None));
    assert!(
        rejections(&out, "pseudorange").is_empty(),
        "{:?}",
        rejections(&out, "pseudorange")
    );
    for k in [30.0, 40.0, 50.0, 60.0, 70.0, 80.0] {
        let fix = out
            .fixes
            .iter()
            .find(|f| f.time_s - 1.7e9 == k)
            .unwrap_or_else(|| panic!("no fix at {k} s"));
        let error = (Vector2::new(fix.position_m[0], fix.position_m[1]) - truth(k).xy()).norm();
        println!("3 satellites at {k} s: horizontal fix error {error:.2} m");
        assert!(fix.dimensions == 3 && error < 30.0, "{error} m at {k} s");
    }
    let (rmse, _, _, _) = scores(&out, 10.0);
    assert!(rmse < 2.0 * SIGMA_M, "{rmse}");
}

#[test]
fn a_multipath_outlier_is_excluded_with_a_rejected_event() {
    let out = run(
        &site("fix-then-filter", "kf", 2, true),
        records(40, 3, |_| 8, Some((25, 4, 100.0))),
    );
    let rejected = rejections(&out, "pseudorange");
    println!("{rejected:?}");
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    assert!(
        rejected[0].starts_with("satellite G05 excluded by the epoch's fault detection"),
        "{}",
        rejected[0]
    );
    let fix = out.fixes.iter().find(|f| f.time_s - 1.7e9 == 25.0).unwrap();
    assert!((Vector2::new(fix.position_m[0], fix.position_m[1]) - truth(25.0).xy()).norm() < 15.0);
}

#[test]
fn a_site_without_an_origin_rejects_every_pseudorange_with_a_reason() {
    let out = run(&site("fix-then-filter", "kf", 2, false), records(5, 1, |_| 8, None));
    let rejected = rejections(&out, "pseudorange");
    assert_eq!(rejected.len(), 40);
    assert!(rejected
        .iter()
        .all(|r| r.contains("geodetic origin") && r.contains("[frame]")));
    assert!(out.updates.is_empty() && out.fixes.is_empty());
}

#[test]
fn too_few_satellites_without_a_clock_are_rejected_with_a_reason() {
    // the first epoch has no clock prediction: 2 satellites fix nothing even at a known height
    let out = run(&site("fix-then-filter", "kf", 2, true), records(1, 1, |_| 2, None));
    let rejected = rejections(&out, "pseudorange");
    assert_eq!(rejected.len(), 2);
    assert!(rejected[0].contains("underdetermined"), "{}", rejected[0]);
}
