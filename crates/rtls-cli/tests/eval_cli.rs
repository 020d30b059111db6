//! `rtls eval` and `rtls import` as a user runs them: hand-checkable numbers in the table and
//! the JSON, and errors that name the file, line and field.

mod common;

use common::rtls;
use std::path::PathBuf;

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("eval-cli", name)
}

/// Truth: `a` moves along x at 10 m/s, sampled every 0.5 s; `b` stands at (5, 5).
const TRUTH: &str = "t,tag,x,y,z\n0,a,0,0,\n0.5,a,5,0,\n1,a,10,0,\n0,b,5,5,\n0.5,b,5,5,\n";

/// Tracks: `a` at 0.25 s is off by (0.3, 0.4) → 0.5 m; `b` at 0.25 s by (0, 1.5) → 1.5 m; one
/// predicted sample (0 m when scored), one after the truth ends, one of a tag without truth.
const TRACKS: &str = r#"{"t": 0.25, "tag": "a", "x": 2.8, "y": 0.4, "vx": 10, "vy": 0, "cov": [1, 0, 0, 1], "predicted": false, "status": "confirmed"}
{"t": 0.25, "tag": "b", "x": 5, "y": 6.5}

{"t": 0.75, "tag": "a", "x": 7.5, "y": 0, "predicted": true, "status": "coasting"}
{"t": 2, "tag": "a", "x": 0, "y": 0}
{"t": 0.25, "tag": "c", "x": 0, "y": 0}
"#;

/// Writes the truth and tracks files; returns their paths.
fn write_inputs(dir: &std::path::Path, truth: &str, tracks: &str) -> (String, String) {
    let truth_path = dir.join("truth.csv");
    let tracks_path = dir.join("tracks.jsonl");
    std::fs::write(&truth_path, truth).unwrap();
    std::fs::write(&tracks_path, tracks).unwrap();
    (truth_path.display().to_string(), tracks_path.display().to_string())
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

#[test]
fn eval_prints_the_statistics_and_the_unmatched_counts() {
    let dir = temp_dir("table");
    let (truth, tracks) = write_inputs(&dir, TRUTH, TRACKS);
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let stdout = String::from_utf8(output.stdout).unwrap();
    let row = |tag: &str| -> Vec<String> {
        let line = stdout
            .lines()
            .find(|line| line.split_whitespace().next() == Some(tag))
            .unwrap_or_else(|| panic!("no row `{tag}` in\n{stdout}"));
        line.split_whitespace().skip(1).map(str::to_string).collect()
    };
    // errors 0.5 and 1.5: RMSE √1.25, mean 1, median 1, p90 0.5 + 0.9·1, p95 0.5 + 0.95·1, max 1.5
    assert_eq!(
        row("overall"),
        ["2", "1.118", "1.000", "1.000", "1.400", "1.450", "1.500"],
        "{stdout}"
    );
    assert_eq!(
        row("a"),
        ["1", "0.500", "0.500", "0.500", "0.500", "0.500", "0.500"],
        "{stdout}"
    );
    assert_eq!(
        row("b"),
        ["1", "1.500", "1.500", "1.500", "1.500", "1.500", "1.500"],
        "{stdout}"
    );
    assert!(stdout.contains("5 samples, 3 tags"), "{stdout}");
    assert!(stdout.contains("unmatched track samples: 3 of 5"), "{stdout}");
    let reason = |needle: &str| {
        stdout
            .lines()
            .find(|line| line.contains(needle))
            .unwrap_or_default()
            .to_string()
    };
    assert!(reason("predicted, excluded").contains(" 1  (tag: a)"), "{stdout}");
    assert!(reason("tag without ground truth").contains(" 1  (tag: c)"), "{stdout}");
    assert!(
        reason("outside the ground truth's time span").contains(" 1  (tag: a)"),
        "{stdout}"
    );
    assert!(reason("gap longer than 0.5 s").trim_end().ends_with(" 0"), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn eval_json_is_one_object_with_the_same_numbers() {
    let dir = temp_dir("json");
    let (truth, tracks) = write_inputs(&dir, TRUTH, TRACKS);
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks, "--json"]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "{text}");
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let overall = &value["overall"];
    assert_eq!(overall["count"], 2);
    assert!(close(overall["rmse_m"].as_f64().unwrap(), 1.25f64.sqrt()));
    assert!(close(overall["mean_m"].as_f64().unwrap(), 1.0));
    assert!(close(overall["p90_m"].as_f64().unwrap(), 1.4));
    assert!(close(overall["p95_m"].as_f64().unwrap(), 1.45));
    assert!(close(overall["max_m"].as_f64().unwrap(), 1.5));
    let per_tag = value["per_tag"].as_array().unwrap();
    assert_eq!(per_tag.len(), 2);
    assert_eq!((&per_tag[0]["tag"], &per_tag[0]["count"]), (&"a".into(), &1.into()));
    assert!(close(per_tag[0]["rmse_m"].as_f64().unwrap(), 0.5));
    assert!(close(per_tag[1]["median_m"].as_f64().unwrap(), 1.5));
    let unmatched = &value["unmatched"];
    for (key, count) in [
        ("predicted_excluded", 1),
        ("initial_skipped", 0),
        ("tag_not_in_truth", 1),
        ("outside_truth_span", 1),
        ("truth_gap", 0),
        ("total", 3),
    ] {
        assert_eq!(unmatched[key], count, "{key}: {text}");
    }
    assert_eq!(value["unmatched_per_tag"][1]["tag"], "c");
    assert_eq!(value["unmatched_per_tag"][1]["tag_not_in_truth"], 1);
    assert_eq!((&value["dimensions"], &value["max_gap_s"]), (&2.into(), &0.5.into()));
    assert_eq!(
        (&value["track_samples"], &value["truth_samples"]),
        (&5.into(), &5.into())
    );

    // the predicted sample lies on the truth (7.5, 0): errors 0.5, 0, 1.5
    let output = rtls(&[
        "eval",
        "--truth",
        &truth,
        "--tracks",
        &tracks,
        "--json",
        "--include-predicted",
    ]);
    let value: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(value["overall"]["count"], 3);
    assert!(close(value["overall"]["mean_m"].as_f64().unwrap(), 2.0 / 3.0));
    assert_eq!(value["unmatched"]["predicted_excluded"], 0);

    // skipping each track's first 0.3 s leaves nothing of a at 0.25 s and b
    let output = rtls(&[
        "eval",
        "--truth",
        &truth,
        "--tracks",
        &tracks,
        "--json",
        "--skip-initial",
        "0.3",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(
        stderr.contains("no track sample could be scored") && stderr.contains("3 in a track's first 0.3 s"),
        "{stderr}"
    );

    // a 0.1 s gap limit leaves the 0.25 s samples in gaps
    let output = rtls(&[
        "eval",
        "--truth",
        &truth,
        "--tracks",
        &tracks,
        "--json",
        "--max-gap",
        "0.1",
        "--include-predicted",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("3 in truth gaps longer than 0.1 s"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn eval_in_3d_uses_z_and_names_the_sample_without_it() {
    let dir = temp_dir("3d");
    let truth_3d = "t,tag,x,y,z\n0,a,0,0,0\n0.5,a,0,0,2\n";
    // at 0.25 s the truth is (0, 0, 1): difference (1, 2, 2) → 3 m in 3-D, √5 m in 2-D
    let (truth, tracks) = write_inputs(
        &dir,
        truth_3d,
        "{\"t\": 0.25, \"tag\": \"a\", \"x\": 1, \"y\": 2, \"z\": 3}\n",
    );
    let json = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["eval", "--truth", &truth, "--tracks", &tracks, "--json"];
        args.extend_from_slice(extra);
        let output = rtls(&args);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        serde_json::from_slice(&output.stdout).unwrap()
    };
    assert!(close(
        json(&["--dimensions", "3"])["overall"]["max_m"].as_f64().unwrap(),
        3.0
    ));
    assert!(close(json(&[])["overall"]["max_m"].as_f64().unwrap(), 5f64.sqrt()));

    // 2-D truth rows: the error names the truth file, its line and `z`
    let (truth, tracks) = write_inputs(
        &dir,
        TRUTH,
        "{\"t\": 0.25, \"tag\": \"a\", \"x\": 1, \"y\": 2, \"z\": 3}\n",
    );
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks, "--dimensions", "3"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(stderr.contains(&format!("{truth}:2: field `z`")), "{stderr}");
    assert!(stderr.contains(&format!("({tracks} line 1)")), "{stderr}");
    // a track line without z
    let (truth, tracks) = write_inputs(&dir, truth_3d, "\n{\"t\": 0.25, \"tag\": \"a\", \"x\": 1, \"y\": 2}\n");
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks, "--dimensions", "3"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains(&format!("{tracks}:2: field `z`")), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn eval_errors_name_file_line_and_field() {
    let dir = temp_dir("errors");
    let bad_tracks = format!("{TRACKS}{{\"t\": 3, \"tag\": \"a\", \"x\": \"north\", \"y\": 0}}\n");
    let (truth, tracks) = write_inputs(&dir, TRUTH, &bad_tracks);
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(
        stderr.contains(&format!("{tracks}:7: field `x`: invalid type")),
        "{stderr}"
    );

    let (truth, tracks) = write_inputs(&dir, "t,tag,x,y,z\n0,a,0,0,\n# comment\n1,a,10,ten,\n", TRACKS);
    let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(&format!("{truth}:4: field `y`: `ten` is not a finite number")),
        "{stderr}"
    );

    let missing = dir.join("missing.csv").display().to_string();
    let output = rtls(&["eval", "--truth", &missing, "--tracks", &tracks]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains(&format!("reading {missing}")), "{stderr}");

    for (flag, value) in [
        ("--dimensions", "4"),
        ("--max-gap", "-1"),
        ("--skip-initial", "-0.5"),
        ("--skip-initial", "inf"),
    ] {
        let output = rtls(&["eval", "--truth", &truth, "--tracks", &tracks, flag, value]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success());
        assert!(stderr.contains(flag) && stderr.contains(value), "{flag}: {stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn import_refuses_an_unknown_directory() {
    let dir = temp_dir("import");
    let out = dir.join("out");
    let output = rtls(&["import", dir.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(
        stderr.contains(dir.to_str().unwrap()) && stderr.contains("not a known dataset directory"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing is written for an unknown dataset");
    std::fs::remove_dir_all(&dir).unwrap();
}
