//! Input robustness of the tracker and the loaders: implausible times, time jumps, site values
//! out of range, oversized or binary inputs, omitted noise levels and negative ranges. Each test
//! is a problem a user found (a hang, an abort, a `null` time) and must finish in well under a
//! second of work.

use std::time::{Duration, Instant};

use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Event, Output, Tracker};
use rtls_engine::EngineError;

/// Three UWB anchors with range noise, around a 20 m × 20 m square; `extra` goes in `[tracker]`.
fn site(pipeline: &str, extra: &str) -> Site {
    let filter = if pipeline == "fix-then-filter" { "kf" } else { "ekf" };
    let text = format!(
        r#"
[[readers]]
id = "A"
position_m = [0.0, 0.0]
technology = "uwb"
radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }}
[[readers]]
id = "B"
position_m = [20.0, 0.0]
technology = "uwb"
radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }}
[[readers]]
id = "C"
position_m = [0.0, 20.0]
technology = "uwb"
radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }}
[[readers]]
id = "Q"
position_m = [20.0, 20.0]
technology = "uwb"

[tracker]
pipeline = "{pipeline}"
motion_model = "cv"
filter = "{filter}"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.99
initiation = {{ confirm_updates = 2, within_s = 5.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
{extra}
"#
    );
    Site::from_toml_str(&text, "site.toml").unwrap()
}

fn fix(time_s: f64, x: f64) -> Record {
    Record {
        time_s,
        tag: "w1".into(),
        measurement: Measurement::Fix {
            position_m: vec![x, 5.0],
            covariance_m2: vec![0.04, 0.0, 0.0, 0.04],
        },
    }
}

fn range(time_s: f64, anchor: &str, range_m: f64, std_m: Option<f64>) -> Record {
    Record {
        time_s,
        tag: "w1".into(),
        measurement: Measurement::Range {
            anchor: anchor.into(),
            range_m,
            std_m,
            anchor_position_m: None,
        },
    }
}

/// Runs `records` through a tracker of `site` within `limit`, and checks every output: finite
/// times and values, and no `null` in any JSON line.
fn run(site: &Site, records: Vec<Record>, limit: Duration) -> Output {
    let start = Instant::now();
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    for record in records {
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    assert!(start.elapsed() < limit, "took {:?}", start.elapsed());
    check_finite(&out);
    out
}

fn check_finite(out: &Output) {
    for update in &out.updates {
        assert!(update.time_s.is_finite(), "{update:?}");
        assert!(update.position_m.iter().all(|v| v.is_finite()), "{update:?}");
        assert!(update.velocity_mps.iter().all(|v| v.is_finite()), "{update:?}");
        assert!(
            update.position_covariance_m2.iter().all(|v| v.is_finite()),
            "{update:?}"
        );
        assert!(!update.to_json_line().contains("null"), "{}", update.to_json_line());
    }
    for event in &out.events {
        assert!(event.time_s().is_finite(), "{event:?}");
        assert!(!event.to_json_line().contains("null"), "{}", event.to_json_line());
    }
}

fn rejections(out: &Output) -> Vec<String> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { reason, .. } => Some(reason.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_nanosecond_time_after_seconds_is_refused_not_coasted_through() {
    let site = site("fix-then-filter", "");
    for bad in [1e16, 1.7e9] {
        let records = vec![fix(0.0, 1.0), fix(1.0, 1.1), fix(bad, 1.2), fix(2.0, 1.3)];
        let out = run(&site, records, Duration::from_secs(5));
        let rejected = rejections(&out);
        assert_eq!(rejected.len(), 1, "{bad}: {rejected:?}");
        assert!(
            rejected[0].contains("beyond") || rejected[0].contains("time jump"),
            "{}",
            rejected[0]
        );
        // the record after it is tracked, and nothing was coasted towards the bad time
        assert!(out.updates.iter().all(|u| u.time_s <= 2.0), "{bad}");
        assert!(out.updates.iter().any(|u| u.time_s == 2.0 && !u.predicted), "{bad}");
    }
}

#[test]
fn absurd_times_through_the_api_are_rejected_events() {
    let site = site("fix-then-filter", "");
    let accelerometer = Record {
        time_s: 1e308,
        tag: "w1".into(),
        measurement: Measurement::Accelerometer {
            acceleration_mps2: vec![0.1, 0.0],
            std_mps2: None,
        },
    };
    let records = vec![
        fix(0.0, 1.0),
        accelerometer,
        fix(1e308, 1.0),
        fix(f64::NAN, 1.0),
        fix(f64::INFINITY, 1.0),
        fix(1.0, 1.0),
    ];
    let out = run(&site, records, Duration::from_secs(5));
    assert_eq!(rejections(&out).len(), 4, "{:?}", rejections(&out));
}

#[test]
fn a_real_gap_is_accepted_after_confirming_records() {
    let site = site("fix-then-filter", "max_time_jump_s = 60.0");
    let mut records = vec![fix(0.0, 1.0), fix(1.0, 1.0)];
    records.extend((0..10).map(|k| fix(10_000.0 + f64::from(k), 1.0)));
    let out = run(&site, records, Duration::from_secs(5));
    assert_eq!(
        rejections(&out).len(),
        rejection_count_for_gap(),
        "{:?}",
        rejections(&out)
    );
    assert!(out.updates.iter().any(|u| u.time_s == 10_009.0 && !u.predicted));
    // no coasting output every interval through the 10 000 s gap
    assert!(out.updates.len() < 100, "{}", out.updates.len());
}

fn rejection_count_for_gap() -> usize {
    rtls_engine::record::JUMP_CONFIRMATIONS - 1
}

#[test]
fn a_tightly_coupled_track_that_never_starts_reports_a_finite_time() {
    // one range cannot initialise a track: at the end of input its reading expires, and the
    // rejected event used to carry t = ∞ (`"t": null` in JSON)
    let site = site("tightly-coupled", "");
    let out = run(&site, vec![range(3.0, "A", 5.0, None)], Duration::from_secs(5));
    let expired: Vec<&Event> = out
        .events
        .iter()
        .filter(|e| matches!(e, Event::Rejected { .. }))
        .collect();
    assert_eq!(expired.len(), 1, "{:?}", out.events);
    assert_eq!(expired[0].time_s(), 3.0);
}

#[test]
fn an_omitted_std_uses_the_readers_noise_or_says_why_not() {
    let site = site("tightly-coupled", "");
    // truth (5, 5): ranges to A, B, C without std_m (the readers' radio.range applies)
    let truth = [5.0_f64, 5.0];
    let anchors = [("A", [0.0, 0.0]), ("B", [20.0, 0.0]), ("C", [0.0, 20.0])];
    let mut records = Vec::new();
    for k in 0..30 {
        let (id, a) = anchors[k % 3];
        let r = ((truth[0] - a[0]).powi(2) + (truth[1] - a[1]).powi(2)).sqrt();
        records.push(range(f64::from(k as u32) * 0.1, id, r, None));
    }
    // reader Q has no radio.range: a range to it without std_m cannot be weighed
    records.push(range(3.0, "Q", 21.2, None));
    let out = run(&site, records, Duration::from_secs(5));
    let rejected = rejections(&out);
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    assert!(rejected[0].contains("give `std_m`"), "{}", rejected[0]);
    let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap();
    assert!((last.position_m[0] - 5.0).abs() < 0.1 && (last.position_m[1] - 5.0).abs() < 0.1);
}

#[test]
fn negative_ranges_are_tracked_without_non_finite_outputs() {
    for pipeline in ["tightly-coupled", "fix-then-filter"] {
        let site = site(pipeline, "");
        let mut records = Vec::new();
        for k in 0..30 {
            let t = f64::from(k) * 0.1;
            // a tag next to A: FTM/RTT ranges scatter around 0, some negative
            records.push(range(t, "A", if k % 2 == 0 { -0.3 } else { 0.2 }, None));
            records.push(range(t, "B", 20.0, None));
            records.push(range(t, "C", 20.0, None));
        }
        run(&site, records, Duration::from_secs(5));
    }
}

/// The error of loading `text` as a site: (line, field, reason).
fn site_error(text: &str) -> (usize, String, String) {
    match Site::from_toml_str(text, "bad.toml") {
        Err(EngineError::Parse {
            line, field, reason, ..
        }) => (line, field, reason),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

const TRACKER: &str = r#"[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "kf"
acceleration_noise_std_mps2 = 1.0
gate_probability = 0.99
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 10.0
delete_timeout_s = 60.0
reorder_window_s = 0.5
"#;

#[test]
fn site_values_out_of_range_name_key_value_and_range() {
    let cases = [
        (
            "reorder_window_s = 0.5",
            "reorder_window_s = 0.5\noutput_interval_s = 1e-300",
            "tracker.output_interval_s",
            "1e-300 is outside the allowed range [0.001, 3600] s",
        ),
        (
            "acceleration_noise_std_mps2 = 1.0",
            "acceleration_noise_std_mps2 = 1e308",
            "tracker.acceleration_noise_std_mps2",
            "1e308 is outside the allowed range [1e-6, 1000] m/s²",
        ),
        (
            "reorder_window_s = 0.5",
            "reorder_window_s = 0.5\nmax_time_jump_s = 0.0",
            "tracker.max_time_jump_s",
            "0 is outside the allowed range [1, 31536000] s",
        ),
    ];
    for (from, to, field, reason) in cases {
        let text = TRACKER.replace(from, to);
        let (line, found_field, found_reason) = site_error(&text);
        assert_eq!(found_field, field);
        assert_eq!(found_reason, reason);
        let expected_line = text
            .lines()
            .position(|l| l.starts_with(field.trim_start_matches("tracker.")))
            .unwrap()
            + 1;
        assert_eq!(line, expected_line, "{field}");
    }
}

#[test]
fn a_huge_zone_polygon_is_refused_quickly() {
    let n = 200_000;
    let vertices: Vec<String> = (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / f64::from(n);
            format!("[{}, {}]", 10.0 * a.cos(), 10.0 * a.sin())
        })
        .collect();
    let text = format!(
        "[[zones]]\nid = \"z\"\nname = \"z\"\nkind = \"hazard\"\nshape = {{ type = \"polygon\", vertices_m = [{}] }}\n{TRACKER}",
        vertices.join(", ")
    );
    let start = Instant::now();
    let (line, field, reason) = site_error(&text);
    assert!(start.elapsed() < Duration::from_secs(10), "{:?}", start.elapsed());
    assert_eq!((line, field.as_str()), (5, "zones[0].shape.vertices_m"));
    assert!(reason.contains("at most 10000"), "{reason}");
}

#[test]
fn a_radio_map_from_a_random_device_is_refused() {
    let path = std::path::Path::new("/dev/urandom");
    if !path.exists() {
        return;
    }
    let start = Instant::now();
    let error = rtls_engine::site::read_text_file(path, rtls_engine::site::MAX_RADIO_MAP_BYTES, "radio map")
        .unwrap_err()
        .to_string();
    assert!(start.elapsed() < Duration::from_secs(10));
    assert!(error.starts_with("/dev/urandom:"), "{error}");
    assert!(error.contains("not UTF-8") || error.contains("limit"), "{error}");
}
