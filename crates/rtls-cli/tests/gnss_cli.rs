//! `rtls track` on GNSS pseudoranges: a site with a geodetic origin and a small generated
//! pseudorange file (a receiver at rest, 6 satellites, 20 s at 1 Hz, σ = 3 m) in, track
//! updates and raw fixes near the truth out.

mod common;

use common::rtls;
use nalgebra::Vector3;
use rtls_positioning::gnss::{earth_rotation_correction, Geodetic, LocalFrame};

const SITE: &str = r#"
[frame]
origin = { latitude_deg = -33.8688, longitude_deg = 151.2093, height_m = 58.0 }

[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "kf"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
tag_height_m = 1.0
"#;

/// The receiver, ENU m about the origin.
const TRUTH: [f64; 3] = [35.0, -12.0, 1.0];

/// Pseudoranges from TRUTH to six satellites (clock 1e5 m + 20 m/s), deterministic noise of
/// about ±3 m, as JSON Lines; the second epoch leaves `std_m` out (the site's elevation model).
fn records() -> String {
    let frame = LocalFrame::new(Geodetic {
        latitude_deg: -33.8688,
        longitude_deg: 151.2093,
        height_m: 58.0,
    })
    .unwrap();
    let receiver = frame.ecef_from_enu(&Vector3::from(TRUTH));
    let sky = [
        (20.0, 70.0),
        (80.0, 30.0),
        (150.0, 45.0),
        (210.0, 20.0),
        (270.0, 55.0),
        (330.0, 25.0),
    ];
    let mut text = String::new();
    for k in 0..20 {
        let t = 100.0 + f64::from(k);
        for (i, &(az, el)) in sky.iter().enumerate() {
            let (az, el): (f64, f64) = (f64::to_radians(az), f64::to_radians(el));
            let u = frame.rotation().transpose() * Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
            let ru = receiver.dot(&u);
            let distance = -ru + (ru * ru - receiver.norm_squared() + 26_560e3_f64.powi(2)).sqrt();
            let s = receiver + u * distance;
            let geometric = (earth_rotation_correction(&s, &receiver).unwrap() - receiver).norm();
            // a fixed pseudo-random pattern of errors within ±3 m
            let noise = 3.0 * ((f64::from(k) * 7.3 + i as f64 * 3.1).sin());
            let rho = geometric + 1e5 + 20.0 * f64::from(k) + noise;
            let std = if k == 1 {
                String::new()
            } else {
                ", \"std_m\": 3.0".to_string()
            };
            text.push_str(&format!(
                "{{\"t\": {t}, \"tag\": \"phone-1\", \"kind\": \"pseudorange\", \"satellite\": \"G{i:02}\", \
                 \"satellite_position_m\": [{}, {}, {}], \"pseudorange_m\": {rho}{std}}}\n",
                s[0], s[1], s[2]
            ));
        }
    }
    text
}

#[test]
fn track_solves_pseudorange_epochs_on_a_site_with_an_origin() {
    let dir = common::temp_dir("gnss-cli", "track");
    let (site, input, tracks, fixes) = (
        dir.join("site.toml"),
        dir.join("in.jsonl"),
        dir.join("tracks.jsonl"),
        dir.join("fixes.jsonl"),
    );
    std::fs::write(&site, SITE).unwrap();
    std::fs::write(&input, records()).unwrap();
    let output = rtls(&[
        "track",
        "--site",
        site.to_str().unwrap(),
        "--input",
        input.to_str().unwrap(),
        "--output",
        tracks.to_str().unwrap(),
        "--fixes",
        fixes.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let lines = |path: &std::path::Path| -> Vec<serde_json::Value> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let raw = lines(&fixes);
    assert_eq!(raw.len(), 20, "one fix per epoch");
    assert!(raw.iter().all(|f| f["method"] == "pseudorange"), "{raw:?}");
    let updates = lines(&tracks);
    let last = updates.last().unwrap();
    let error =
        ((last["x"].as_f64().unwrap() - TRUTH[0]).powi(2) + (last["y"].as_f64().unwrap() - TRUTH[1]).powi(2)).sqrt();
    assert!(error < 3.0, "last update {last} is {error} m from the truth");
    assert_eq!(last["status"], "confirmed");
}
