//! Tests of the labyrinth importer: the real dataset (skipped with a message when absent) and
//! small malformed files.

use std::path::{Path, PathBuf};

use rtls_engine::record::Measurement;
use rtls_engine::site::Site;

use super::*;
use crate::import::test_support::{dataset as dataset_in, read_records, TempDir};

fn dataset() -> Option<PathBuf> {
    dataset_in("uwb_odometry_labyrinth_tuc")
}

/// `(t, x, y)` rows of the written truth file.
fn read_written_truth(path: &Path) -> Vec<(f64, f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,tag,x,y,z"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!((f[1], f[4]), ("robot", ""));
            (f[0].parse().unwrap(), f[2].parse().unwrap(), f[3].parse().unwrap())
        })
        .collect()
}

#[test]
fn real_dataset_imports_with_valid_files_and_plausible_odometry() {
    let Some(dataset) = dataset() else { return };
    let temp = TempDir::new("labyrinth", "import");
    let out = &temp.0;
    let runs = import(&dataset, out).unwrap();
    assert_eq!(runs.len(), 1);
    let run = &runs[0];
    for note in &run.notes {
        eprintln!("note: {note}");
    }
    let dir = out.join("labyrinth");
    let site = Site::from_toml_str(&std::fs::read_to_string(dir.join("site.toml")).unwrap(), "site.toml").unwrap();
    let ids: Vec<&str> = site.readers.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids, ["105", "107", "108", "109"]);
    assert_eq!(site.reader("108").unwrap().position_m, vec![2.385, 2.36]);
    assert_eq!((site.tracker.dimensions, site.tracker.epoch_s), (2, Some(0.45)));

    let all = read_records(&dir.join("measurements.jsonl"));
    let uwb = read_records(&dir.join("measurements-uwb-only.jsonl"));
    let input = std::fs::read_to_string(dataset.join("Indoor_UWB_Input.txt")).unwrap();
    let count = |kind: &str| input.lines().filter(|l| l.starts_with(kind)).count();
    assert_eq!(
        (all.len(), uwb.len(), run.records),
        (count("range2") + count("odom2diff"), count("range2"), all.len())
    );
    assert!(
        all.windows(2).all(|w| w[0].time_s <= w[1].time_s),
        "records in time order"
    );
    assert!(uwb
        .iter()
        .all(|r| matches!(r.measurement, Measurement::Range { std_m: Some(s), .. } if (s - 0.1).abs() < 1e-12)));

    let truth = read_written_truth(&dir.join("truth.csv"));
    let gt_lines = std::fs::read_to_string(dataset.join("Indoor_UWB_GT.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .count();
    assert_eq!((truth.len(), run.truth_rows), (gt_lines, gt_lines));
    let truth_length: f64 = truth.windows(2).map(|w| (w[1].1 - w[0].1).hypot(w[1].2 - w[0].2)).sum();

    // odometry records: integrate speed along heading from the first truth point
    let odometry: Vec<(f64, f64, f64, f64)> = all
        .iter()
        .filter_map(|r| match r.measurement {
            Measurement::Odometry {
                speed_mps,
                heading_rad,
                heading_std_rad,
                ..
            } => Some((r.time_s, speed_mps, heading_rad.unwrap(), heading_std_rad.unwrap())),
            _ => None,
        })
        .collect();
    // the initial heading is the direction from GT point 1 to the first point ≥ 0.1 m away
    let (x0, y0) = (truth[0].1, truth[0].2);
    let far = truth.iter().find(|t| (t.1 - x0).hypot(t.2 - y0) >= 0.1).unwrap();
    assert!((odometry[0].2 - (far.2 - y0).atan2(far.1 - x0)).abs() < 1e-12);
    let (mut x, mut y, mut length, mut errors) = (x0, y0, 0.0, Vec::new());
    for (k, w) in odometry.windows(2).enumerate() {
        let dt = w[1].0 - w[0].0;
        x += w[0].1 * dt * w[0].2.cos();
        y += w[0].1 * dt * w[0].2.sin();
        length += w[0].1 * dt;
        errors.push((x - truth[k + 1].1).hypot(y - truth[k + 1].2));
    }
    let mean_error = errors.iter().sum::<f64>() / errors.len() as f64;
    eprintln!(
        "odometry path {length:.3} m, truth path {truth_length:.3} m, dead reckoning mean {mean_error:.3} m, end {:.3} m",
        errors.last().unwrap()
    );
    // README: 9.33 m (signed sum) vs 9.25 m; |v| adds the few backing-up samples
    assert!((length - 9.33).abs() < 0.06, "{length}");
    assert!((truth_length - 9.25).abs() < 0.01, "{truth_length}");
    // the heading convention holds: dead reckoning stays near the truth for 30 s
    assert!(
        mean_error < 0.3 && *errors.last().unwrap() < 0.7,
        "{mean_error} {errors:?}"
    );
    // heading std: random walk √Σ (σ²_r + σ²_l)/(4L²)·Δt², σ² = 1e-4, L = 0.0785 (all lines)
    let expected_var: f64 = odometry
        .windows(2)
        .map(|w| 2e-4 / (4.0 * 0.0785_f64.powi(2)) * (w[1].0 - w[0].0).powi(2))
        .sum();
    assert!((odometry.last().unwrap().3 - expected_var.sqrt()).abs() < 1e-9);
    assert_eq!(odometry[0].3, 0.0);
}

#[test]
fn integration_follows_the_formulas_on_a_hand_made_track() {
    let line = |t: f64, vr: f64, vl: f64| OdometryLine {
        time_s: t,
        v_right_mps: vr,
        v_left_mps: vl,
        wheel_base_m: 0.5,
        var_right_m2ps2: 0.01,
        var_left_m2ps2: 0.03,
    };
    // ω = (v_l − v_r)/(2L) = (1.5 − 0.5)/1 = 1 rad/s for 0.5 s, then straight backwards
    let odometry = [line(0.0, 0.5, 1.5), line(0.5, -1.0, -1.0), line(1.5, 0.0, 0.0)];
    let out = integrate(&odometry, 0.25);
    let heading = |k: usize| match out.records[k].measurement {
        Measurement::Odometry {
            speed_mps,
            heading_rad,
            speed_std_mps,
            heading_std_rad,
        } => (
            speed_mps,
            heading_rad.unwrap(),
            speed_std_mps.unwrap(),
            heading_std_rad.unwrap(),
        ),
        _ => panic!("not odometry"),
    };
    let (v0, h0, s0, hs0) = heading(0);
    assert_eq!((v0, h0, hs0), (1.0, 0.25, 0.0));
    assert!((s0 - 0.04_f64.sqrt() / 2.0).abs() < 1e-15);
    let (v1, h1, _, hs1) = heading(1);
    // ψ = 0.25 + 1·0.5; backing up: |v| and ψ + π, wrapped to [−π, π)
    assert_eq!(v1, 1.0);
    assert!((h1 - (0.75 + std::f64::consts::PI - std::f64::consts::TAU)).abs() < 1e-12);
    // σ²_ψ = (0.01 + 0.03)/(4·0.25)·0.25 = 0.01
    assert!((hs1 - 0.1).abs() < 1e-12);
    assert_eq!(out.reversing, 1);
    assert!((out.path_length_m - 1.5).abs() < 1e-12 && (out.signed_distance_m + 0.5).abs() < 1e-12);
}

#[test]
fn malformed_lines_name_file_line_and_field() {
    let temp = TempDir::new("labyrinth", "bad");
    let dir = &temp.0;
    let range = "range2 0.127943992614746 2.95522014829822 0.01 -0.02 -0.01 105 0";
    let odom = "odom2diff 0.127943992614746 0 0 0 0.0785 0.0001 0.0001 0.0001";
    let cases = [
        (
            format!("{range}\nrange2 0.25 x 0.01 -0.02 -0.01 105 0\n{odom}"),
            2,
            "range",
            "`x` is not a number",
        ),
        (
            format!("{range}\nrange2 0.25 1.0 0.01 -0.02 -0.01 105\n"),
            2,
            "snr",
            "has 7 tokens",
        ),
        (
            format!("{range}\nrange2 0.25 1.0 0.01 0.5 -0.01 105 0\n"),
            2,
            "anchor_x",
            "anchor 105 at",
        ),
        (
            format!("{range}\n{odom}\nodom2diff 0.25 0 0 0 0 0.0001 0.0001 0.0001\n"),
            3,
            "wheel_base",
            "0 must be > 0",
        ),
        (
            format!("{odom}\nrange2 0.25 -1.0 0.01 -0.02 -0.01 105 0\n"),
            2,
            "range",
            "-1 must be ≥ 0",
        ),
        (format!("{range}\ngt2 0.25 1 1\n"), 2, "type", "unknown line type `gt2`"),
    ];
    for (k, (text, line, field, reason)) in cases.iter().enumerate() {
        let path = dir.join(format!("input{k}.txt"));
        std::fs::write(&path, text).unwrap();
        let error = read_input(&path).unwrap_err().to_string();
        let expected = format!("{}:{line}: field `{field}`: ", path.display());
        assert!(error.starts_with(&expected) && error.contains(reason), "{error}");
    }
    let path = dir.join("gt.txt");
    std::fs::write(&path, "point2 0.1 1 2 0 0 0 0\npoint2 0.2 1 2 0 0 0\n").unwrap();
    let error = read_truth(&path).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:2: field `cov[3]`", path.display())),
        "{error}"
    );
    std::fs::write(&path, "point2 0.2 1 2 0 0 0 0\npoint2 0.1 1 2 0 0 0 0\n").unwrap();
    let error = read_truth(&path).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:2: field `t`", path.display())),
        "{error}"
    );
}
