//! `rtls sim mine` writes files that `rtls track` and `rtls eval` run on: the demo mine's
//! tunnel map and silent readers measured from files, as a user would.

mod common;

use common::{rtls, temp_dir};

/// `rtls sim mine` (with or without the map) → `rtls track` → `rtls eval --json`: RMSE, m.
fn rmse_from_files(name: &str, without_map: bool) -> f64 {
    let dir = temp_dir("sim", name);
    let out = dir.to_str().unwrap();
    let mut args = vec!["sim", "mine", "--out", out, "--miners", "12", "--duration-s", "600"];
    if without_map {
        args.push("--without-map");
    }
    let sim = rtls(&args);
    assert!(sim.status.success(), "{}", String::from_utf8_lossy(&sim.stderr));
    let site = dir.join("site.toml");
    let input = dir.join("measurements.jsonl");
    let tracks = dir.join("tracks.jsonl");
    let truth = dir.join("truth.csv");
    let track = rtls(&[
        "track",
        "--site",
        site.to_str().unwrap(),
        "--input",
        input.to_str().unwrap(),
        "--output",
        tracks.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(track.status.success(), "{}", String::from_utf8_lossy(&track.stderr));
    let eval = rtls(&[
        "eval",
        "--truth",
        truth.to_str().unwrap(),
        "--tracks",
        tracks.to_str().unwrap(),
        "--include-predicted",
        "--json",
    ]);
    assert!(eval.status.success(), "{}", String::from_utf8_lossy(&eval.stderr));
    let report: serde_json::Value = serde_json::from_slice(&eval.stdout).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    report["overall"]["rmse_m"]
        .as_f64()
        .unwrap_or_else(|| panic!("no overall.rmse_m in {report}"))
}

#[test]
fn the_simulated_mine_from_files_is_tracked_better_with_its_tunnel_map_and_silent_readers() {
    let plain = rmse_from_files("plain", true);
    let mapped = rmse_from_files("mapped", false);
    eprintln!("rtls sim mine → track → eval, 12 miners, 10 min: RMSE without the map {plain:.2} m, with {mapped:.2} m");
    assert!(mapped < 0.7 * plain, "{mapped:.2} vs {plain:.2} m");
}

#[test]
fn a_bad_duration_is_refused_with_the_flag_named() {
    let dir = temp_dir("sim", "bad");
    let out = rtls(&["sim", "mine", "--out", dir.to_str().unwrap(), "--duration-s", "-5"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--duration-s"));
    let _ = std::fs::remove_dir_all(&dir);
}
