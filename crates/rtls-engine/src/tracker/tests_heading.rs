//! The heading channel end to end: a vehicle on a loop with noisy UWB fixes, wheel speed and a
//! biased gyro (as `odometry` without heading + `yaw_rate`, as `odometry_increment`, and as a
//! tilted body-frame `imu`), and ranges to a moving anchor.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// Loop centre (m), radius (m), speed (m/s).
const CENTRE: [f64; 2] = [30.0, 30.0];
const RADIUS_M: f64 = 20.0;
const SPEED_MPS: f64 = 5.0;
/// The gyro's bias, rad/s.
const GYRO_BIAS_RADPS: f64 = 0.02;

const ANCHORS: [(&str, [f64; 3]); 4] = [
    ("A1", [0.0, 0.0, 1.0]),
    ("A2", [60.0, 0.0, 1.0]),
    ("A3", [60.0, 60.0, 1.0]),
    ("A4", [0.0, 60.0, 1.0]),
];

/// Counter-clockwise on the loop: position, heading.
fn vehicle(t: f64) -> ([f64; 2], f64) {
    let omega = SPEED_MPS / RADIUS_M;
    let angle = omega * t;
    (
        [CENTRE[0] + RADIUS_M * angle.cos(), CENTRE[1] + RADIUS_M * angle.sin()],
        angle + std::f64::consts::FRAC_PI_2,
    )
}

fn site() -> Site {
    site_with("")
}

/// The test site with `extra` TOML appended (tables after `[tracker]`).
fn site_with(extra: &str) -> Site {
    let readers: String = ANCHORS
        .iter()
        .map(|(id, [x, y, z])| {
            format!(
                "[[readers]]\nid = \"{id}\"\nposition_m = [{x}, {y}, {z}]\ntechnology = \"uwb\"\n\
                 radio = {{ range = {{ range_std_m = 0.5, bias_m = 0.0 }} }}\n"
            )
        })
        .collect();
    let text = format!(
        r#"{readers}
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "kf"
acceleration_noise_std_mps2 = 1.5
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 5.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
tag_height_m = 1.0
{extra}"#
    );
    Site::from_toml_str(&text, "heading-site.toml").unwrap()
}

fn record(t: f64, measurement: Measurement) -> Record {
    Record {
        time_s: t,
        tag: "truck".into(),
        measurement,
    }
}

/// Ranges (σ 0.5 m) to the four anchors every 0.5 s for `seconds`.
fn ranges(rng: &mut ChaCha8Rng, seconds: f64) -> Vec<Record> {
    let noise = Normal::new(0.0, 0.5).unwrap();
    let mut records = Vec::new();
    for k in 0..(seconds * 2.0) as usize {
        let t = k as f64 * 0.5;
        let (p, _) = vehicle(t);
        for (id, a) in ANCHORS {
            let d = (p[0] - a[0]).hypot(p[1] - a[1]);
            records.push(record(
                t,
                Measurement::Range {
                    anchor: id.into(),
                    range_m: d + noise.sample(rng),
                    std_m: None,
                    anchor_position_m: None,
                },
            ));
        }
    }
    records
}

/// Merges record streams in time order (stable: ranges first at equal times).
fn merged(mut streams: Vec<Vec<Record>>) -> Vec<Record> {
    let mut all: Vec<Record> = streams.drain(..).flatten().collect();
    all.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    all
}

/// RMSE after 20 s and the share of truths inside the reported 95 % ellipse.
fn score(out: &Output) -> (f64, f64) {
    let (mut sum, mut count, mut inside) = (0.0, 0usize, 0usize);
    for u in out.updates.iter().filter(|u| u.time_s >= 20.0 && !u.predicted) {
        let (truth, _) = vehicle(u.time_s);
        let e = [u.position_m[0] - truth[0], u.position_m[1] - truth[1]];
        sum += e[0] * e[0] + e[1] * e[1];
        count += 1;
        // NEES = eᵀ P⁻¹ e, inside the 95 % ellipse when ≤ χ²₂(0.95) = 5.991
        inside += usize::from(super::tests::horizontal_nees(u, e) <= 5.991);
    }
    assert!(count > 100, "{count} updates");
    ((sum / count as f64).sqrt(), inside as f64 / count as f64)
}

fn track(records: Vec<Record>) -> (Output, Tracker) {
    track_on(&site(), records)
}

fn track_on(site: &Site, records: Vec<Record>) -> (Output, Tracker) {
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    for r in records {
        tracker.push(r, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    (out, tracker)
}

fn rejected_kinds(out: &Output, kind: &str) -> Vec<String> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { kind: k, reason, .. } if *k == kind => Some(reason.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn speed_and_a_biased_gyro_without_headings_improve_the_track_and_the_bias_is_learned() {
    let seconds = 150.0;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let gyro_noise = Normal::new(0.0, 0.005).unwrap();
    let speed_noise = Normal::new(0.0, 0.05).unwrap();
    let only_ranges = ranges(&mut rng, seconds);
    let mut odometry = Vec::new();
    for k in 0..(seconds * 50.0) as usize {
        let t = k as f64 * 0.02 + 0.01;
        odometry.push(record(
            t,
            Measurement::YawRate {
                yaw_rate_radps: SPEED_MPS / RADIUS_M + GYRO_BIAS_RADPS + gyro_noise.sample(&mut rng),
                std_radps: Some(0.005),
            },
        ));
        if k % 5 == 0 {
            odometry.push(record(
                t,
                Measurement::Odometry {
                    speed_mps: SPEED_MPS + speed_noise.sample(&mut rng),
                    heading_rad: None,
                    speed_std_mps: Some(0.05),
                    heading_std_rad: None,
                },
            ));
        }
    }
    let (plain, _) = track(only_ranges.clone());
    let (aided, tracker) = track(merged(vec![only_ranges, odometry]));
    let (plain_rmse, plain_in95) = score(&plain);
    let (aided_rmse, aided_in95) = score(&aided);
    eprintln!("ranges only: RMSE {plain_rmse:.3} m, in 95 % {plain_in95:.3}; + speed and yaw rate: {aided_rmse:.3} m, {aided_in95:.3}");
    assert!(
        aided_rmse < 0.75 * plain_rmse,
        "ranges only {plain_rmse:.3} m, + speed and yaw rate {aided_rmse:.3} m"
    );
    assert!(
        plain_in95 > 0.8 && aided_in95 > 0.85,
        "in 95 %: {plain_in95:.3} / {aided_in95:.3}"
    );
    let heading = tracker.heading_state("truck").expect("a heading channel");
    let (bias, variance) = heading.gyro_bias();
    assert!(
        (bias - GYRO_BIAS_RADPS).abs() < 0.005 && (bias - GYRO_BIAS_RADPS).abs() < 4.0 * variance.sqrt(),
        "b̂ {bias:.4} ± {:.4} rad/s",
        variance.sqrt()
    );
    // before the course aligned the heading, speeds were rejected with the reason, not dropped
    let early = rejected_kinds(&aided, "odometry");
    assert!(
        !early.is_empty() && early.iter().all(|r| r.contains("heading is not known")),
        "{early:?}"
    );
}

#[test]
fn odometry_increments_and_a_tilted_imu_drive_the_same_channel() {
    let seconds = 120.0;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let only_ranges = ranges(&mut rng, seconds);
    let omega = SPEED_MPS / RADIUS_M;
    // wheel encoders at 10 Hz: distance and change of heading over 0.1 s
    let increments: Vec<Record> = (1..(seconds * 10.0) as usize)
        .map(|k| {
            record(
                k as f64 * 0.1 + 0.05,
                Measurement::OdometryIncrement {
                    distance_m: SPEED_MPS * 0.1,
                    yaw_change_rad: omega * 0.1,
                    interval_s: 0.1,
                    distance_std_m: Some(0.005),
                    yaw_change_std_rad: Some(0.001),
                },
            )
        })
        .collect();
    let (plain, _) = track(only_ranges.clone());
    let (aided, _) = track(merged(vec![only_ranges.clone(), increments]));
    let (plain_rmse, _) = score(&plain);
    let (aided_rmse, aided_in95) = score(&aided);
    assert!(aided_rmse < 0.75 * plain_rmse, "{plain_rmse:.3} → {aided_rmse:.3} m");
    assert!(aided_in95 > 0.85, "in 95 %: {aided_in95:.3}");

    // an IMU tilted 20° about its x axis: gravity and the yaw rate are shared by y and z
    let tilt = 20f64.to_radians();
    let (s, c) = tilt.sin_cos();
    let imu: Vec<Record> = (0..(seconds * 50.0) as usize)
        .map(|k| {
            let w = omega + GYRO_BIAS_RADPS;
            // body = Rₓ(tilt)ᵀ · level: up = (0, sin, cos) in the body
            record(
                k as f64 * 0.02 + 0.01,
                Measurement::Imu {
                    acceleration_mps2: vec![0.0, 9.80665 * s, 9.80665 * c],
                    angular_rate_radps: vec![0.0, w * s, w * c],
                    std_mps2: Some(0.05),
                    std_radps: Some(0.005),
                },
            )
        })
        .collect();
    let speeds: Vec<Record> = (0..(seconds * 10.0) as usize)
        .map(|k| {
            record(
                k as f64 * 0.1 + 0.01,
                Measurement::Odometry {
                    speed_mps: SPEED_MPS,
                    heading_rad: None,
                    speed_std_mps: Some(0.05),
                    heading_std_rad: None,
                },
            )
        })
        .collect();
    let (with_imu, tracker) = track(merged(vec![only_ranges, imu, speeds]));
    let (imu_rmse, imu_in95) = score(&with_imu);
    eprintln!(
        "ranges only {plain_rmse:.3} m; + increments {aided_rmse:.3} m (in 95 % {aided_in95:.3}); + tilted IMU and speed {imu_rmse:.3} m ({imu_in95:.3})"
    );
    assert!(imu_rmse < 0.75 * plain_rmse, "{plain_rmse:.3} → {imu_rmse:.3} m");
    assert!(imu_in95 > 0.85, "in 95 %: {imu_in95:.3}");
    let (bias, _) = tracker.heading_state("truck").unwrap().gyro_bias();
    assert!(
        (bias - GYRO_BIAS_RADPS).abs() < 0.005,
        "b̂ {bias:.4} rad/s from the tilted IMU"
    );
}

#[test]
fn an_odometer_heading_offset_is_estimated_from_the_course() {
    let seconds = 150.0;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let only_ranges = ranges(&mut rng, seconds);
    // the odometer's heading is 0.1 rad off the site's
    let offset = 0.1;
    let odometry: Vec<Record> = (0..(seconds * 10.0) as usize)
        .map(|k| {
            let t = k as f64 * 0.1 + 0.01;
            record(
                t,
                Measurement::Odometry {
                    speed_mps: SPEED_MPS,
                    heading_rad: Some(vehicle(t).1 + offset),
                    speed_std_mps: Some(0.05),
                    heading_std_rad: Some(0.01),
                },
            )
        })
        .collect();
    let (out, tracker) = track(merged(vec![only_ranges, odometry]));
    let (delta, variance) = tracker.heading_state("truck").unwrap().odometer_offset();
    assert!(
        (delta - offset).abs() < 0.03,
        "δ̂ {delta:.3} ± {:.3} rad",
        variance.sqrt()
    );
    let (_, in95) = score(&out);
    assert!(in95 > 0.85, "in 95 %: {in95:.3}");
}

/// Odometry whose heading error accumulates (a random walk of 0.01 rad/√s, the std each
/// record states growing with it, as a wheel odometer's integrated heading does), without
/// course references (`course_is_heading = false`): ~0.1 rad off after 100 s.
fn drifting_odometry(rng: &mut ChaCha8Rng, seconds: f64) -> Vec<Record> {
    const DRIFT_RAD_PER_SQRT_S: f64 = 0.01;
    let step = Normal::new(0.0, DRIFT_RAD_PER_SQRT_S * 0.1f64.sqrt()).unwrap();
    let mut error_rad = 0.0;
    (0..(seconds * 10.0) as usize)
        .map(|k| {
            let t = k as f64 * 0.1 + 0.01;
            error_rad += step.sample(rng);
            record(
                t,
                Measurement::Odometry {
                    speed_mps: SPEED_MPS,
                    heading_rad: Some(vehicle(t).1 + error_rad),
                    speed_std_mps: Some(0.05),
                    heading_std_rad: Some(DRIFT_RAD_PER_SQRT_S * t.sqrt()),
                },
            )
        })
        .collect()
}

#[test]
fn an_odometer_whose_heading_error_accumulates_keeps_the_ellipses_honest() {
    let seconds = 120.0;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    // ranges every 2 s: between them the odometry carries the track
    let sparse: Vec<Record> = ranges(&mut rng, seconds)
        .into_iter()
        .filter(|r| r.time_s % 2.0 == 0.0)
        .collect();
    let records = merged(vec![sparse, drifting_odometry(&mut rng, seconds)]);
    let no_course = "[tracker.heading]\ncourse_is_heading = false\n";
    let (out, tracker) = track_on(&site_with(no_course), records.clone());

    let (rmse, in95) = score(&out);
    // the offset's std follows what the records state (√(0.05² + 0.01² · 120) ≈ 0.12 rad)
    let (_, variance) = tracker.heading_state("truck").unwrap().odometer_offset();
    assert!(variance.sqrt() > 0.1, "σ_δ {:.3} rad", variance.sqrt());
    assert!(in95 > 0.85, "RMSE {rmse:.3} m, in 95 %: {in95:.3}");
    // the heading's error taken as fresh noise of each velocity instead of considered: as
    // accurate or worse (measured: 0.474 m and 96.1 % inside considered, 0.471 m and 100 %
    // as fresh noise, whose ellipses are larger than the error asks)
    let fresh = format!("{no_course}consider_heading_error = false\n");
    let (out_fresh, _) = track_on(&site_with(&fresh), records.clone());
    let (rmse_fresh, in95_fresh) = score(&out_fresh);
    eprintln!("considered: RMSE {rmse:.3} m, in 95 % {in95:.3}; fresh noise: {rmse_fresh:.3} m, {in95_fresh:.3}");
    assert!(
        rmse <= 1.05 * rmse_fresh && in95 > 0.9,
        "considered {rmse:.3} m / {in95:.3}, fresh noise {rmse_fresh:.3} m / {in95_fresh:.3}"
    );
    // without the consider update, the heading error taken as persisting 10 s: the velocities'
    // across-track variance grows, and so does the position covariance the track reports
    let persisting = format!("{fresh}heading_error_correlation_s = 10.0\n");
    let (out_persisting, _) = track_on(&site_with(&persisting), records);
    let (_, in95_persisting) = score(&out_persisting);
    let mean_variance = |out: &Output| {
        let late: Vec<f64> = out
            .updates
            .iter()
            .filter(|u| u.time_s >= 20.0)
            .map(|u| {
                let [xx, _, yy] = super::tests::horizontal_covariance_m2(u);
                xx + yy
            })
            .collect();
        late.iter().sum::<f64>() / late.len() as f64
    };
    assert!(
        mean_variance(&out_persisting) > 1.2 * mean_variance(&out_fresh) && in95_persisting > 0.9,
        "tr P {:.3} → {:.3} m², in 95 % {in95_fresh:.3} → {in95_persisting:.3}",
        mean_variance(&out_fresh),
        mean_variance(&out_persisting)
    );
}

#[test]
fn ranges_to_a_moving_anchor_use_the_position_in_the_record() {
    // a static tag at (12, 7); one anchor drives along y = 0 and reports its position per range,
    // two fixed anchors complete the geometry
    let site = Site::from_toml_str(
        r#"
[[readers]]
id = "rover"
position_m = [0.0, 0.0]
technology = "uwb"
radio = { range = { range_std_m = 0.05, bias_m = 0.0 } }
[[readers]]
id = "F1"
position_m = [0.0, 20.0]
technology = "uwb"
radio = { range = { range_std_m = 0.05, bias_m = 0.0 } }
[[readers]]
id = "F2"
position_m = [25.0, 20.0]
technology = "uwb"
radio = { range = { range_std_m = 0.05, bias_m = 0.0 } }
[tracker]
pipeline = "tightly-coupled"
motion_model = "cv"
filter = "ekf"
acceleration_noise_std_mps2 = 0.1
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
"#,
        "moving.toml",
    )
    .unwrap();
    let tag = [12.0, 7.0];
    let mut records = Vec::new();
    for k in 0..300 {
        let t = k as f64 * 0.1;
        let rover = [k as f64 * 0.1, 0.0];
        for (id, a, moving) in [
            ("rover", rover, true),
            ("F1", [0.0, 20.0], false),
            ("F2", [25.0, 20.0], false),
        ] {
            records.push(Record {
                time_s: t,
                tag: "static".into(),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: (tag[0] - a[0]).hypot(tag[1] - a[1]),
                    std_m: None,
                    anchor_position_m: moving.then(|| a.to_vec()),
                },
            });
        }
    }
    let mut tracker = Tracker::new(&site).unwrap();
    let mut out = Output::default();
    for r in records {
        tracker.push(r, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap();
    let error = (last.position_m[0] - tag[0]).hypot(last.position_m[1] - tag[1]);
    assert!(error < 0.05, "error {error:.3} m at {:?}", last.position_m);
    assert!(
        rejected_kinds(&out, "range").is_empty(),
        "{:?}",
        rejected_kinds(&out, "range")
    );
}

#[test]
fn unvalidated_imu_shapes_pushed_in_code_do_not_panic() {
    // Tracker::push does not re-validate records: shapes the parsers refuse must still not panic
    let mut tracker = Tracker::new(&site()).unwrap();
    let mut out = Output::default();
    for (k, (acceleration, rate)) in [(vec![], vec![]), (vec![0.1], vec![0.2, 0.3]), (vec![0.1, 0.2], vec![])]
        .into_iter()
        .enumerate()
    {
        let measurement = Measurement::Imu {
            acceleration_mps2: acceleration,
            angular_rate_radps: rate,
            std_mps2: None,
            std_radps: None,
        };
        tracker.push(record(k as f64, measurement), &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    assert!(out.updates.is_empty(), "an IMU alone gives no position");
}
