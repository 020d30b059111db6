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

/// `rtls sim <paper> --seed 2026 --run 0` → `rtls track` gives exactly the track updates that
/// the "ours" row of `rtls repro <paper> --seed 2026` scores for its run 0: one tracking loop,
/// from files as in memory.
#[test]
fn a_paper_scenario_from_files_is_tracked_exactly_as_its_reproduction_tracks_it() {
    use rtls_papers::experiments::ExperimentId;
    for (name, id) in [
        ("mekf", ExperimentId::Mekf),
        ("ukf-uwb", ExperimentId::UkfUwb),
        ("lwknn", ExperimentId::Lwknn),
        ("vdkf", ExperimentId::Vdkf),
    ] {
        let dir = temp_dir("sim", name);
        let path = |file: &str| dir.join(file).to_str().unwrap().to_string();
        let sim = rtls(&["sim", name, "--out", &path(""), "--seed", "2026", "--run", "0"]);
        assert!(sim.status.success(), "{}", String::from_utf8_lossy(&sim.stderr));
        let track = rtls(&[
            "track",
            "--site",
            &path("site.toml"),
            "--input",
            &path("measurements.jsonl"),
            "--output",
            &path("tracks.jsonl"),
            "--quiet",
        ]);
        assert!(track.status.success(), "{}", String::from_utf8_lossy(&track.stderr));
        let from_files: Vec<[f64; 3]> = std::fs::read_to_string(path("tracks.jsonl"))
            .unwrap()
            .lines()
            .map(|line| {
                let v: serde_json::Value = serde_json::from_str(line).unwrap();
                [
                    v["t"].as_f64().unwrap(),
                    v["x"].as_f64().unwrap(),
                    v["y"].as_f64().unwrap(),
                ]
            })
            .collect();
        let recording = id
            .recording(&id.embedded_scenarios(), 2026, 0)
            .expect("has a recording")
            .unwrap();
        let in_memory: Vec<[f64; 3]> = recording
            .track()
            .unwrap()
            .updates
            .iter()
            .map(|u| [u.time_s, u.position_m[0], u.position_m[1]])
            .collect();
        assert!(from_files.len() > 40, "{name}: {} updates", from_files.len());
        assert_eq!(from_files.len(), in_memory.len(), "{name}");
        for (a, b) in from_files.iter().zip(&in_memory) {
            assert!(
                a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9),
                "{name}: {a:?} vs {b:?}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
