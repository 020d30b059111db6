//! The `rtls repro` command as a user runs it: JSON lines, thread-count independence, the
//! markdown report with its figures, and clear errors for bad input.

mod common;

use common::rtls;

#[test]
fn json_lines_follow_the_schema_and_do_not_depend_on_threads() {
    let one = rtls(&[
        "repro",
        "lwknn",
        "--runs",
        "2",
        "--seed",
        "7",
        "--json",
        "--threads",
        "1",
    ]);
    assert!(one.status.success(), "{}", String::from_utf8_lossy(&one.stderr));
    let two = rtls(&[
        "repro",
        "lwknn",
        "--runs",
        "2",
        "--seed",
        "7",
        "--json",
        "--threads",
        "2",
    ]);
    assert_eq!(one.stdout, two.stdout);
    let text = String::from_utf8(one.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "{text}");
    let value: serde_json::Value = serde_json::from_str(lines[0]).unwrap();
    assert_eq!(value["experiment"], "lwknn");
    assert_eq!(value["runs"], 2);
    assert_eq!(value["seed"], 7);
    let metrics = value["metrics"].as_array().unwrap();
    assert!(metrics.len() > 10);
    for metric in metrics {
        let keys: Vec<&str> = metric.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(keys, ["bound", "name", "ours", "paper", "unit"], "{metric}");
        assert!(metric["ours"].is_number());
        assert!(metric["paper"].is_number() || metric["paper"].is_null());
    }
    // a different seed gives different numbers
    let other = rtls(&["repro", "lwknn", "--runs", "2", "--seed", "8", "--json"]);
    assert_ne!(String::from_utf8(other.stdout).unwrap(), text);
}

#[test]
fn out_writes_the_report_and_its_figures() {
    let dir = std::env::temp_dir().join(format!("rtls-repro-cli-{}", std::process::id()));
    let output = rtls(&["repro", "vdkf", "--runs", "2", "--out", dir.to_str().unwrap()]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(stdout.contains("metric") && stdout.contains("PCRB") && stdout.contains("RMSE: KF (CV) on fixes"));
    let report = std::fs::read_to_string(dir.join("REPRODUCTIONS.md")).unwrap();
    assert!(report.contains("| metric | unit | paper | ours | PCRB | ours / PCRB |"));
    for figure in ["vdkf-trajectory", "vdkf-rmse", "vdkf-cdf", "vdkf-modes"] {
        assert!(report.contains(&format!("figures/{figure}.png")), "{figure}");
        assert!(
            dir.join("figures").join(format!("{figure}.png")).is_file(),
            "{figure}.png"
        );
        assert!(
            dir.join("figures").join(format!("{figure}.svg")).is_file(),
            "{figure}.svg"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_a_clear_error() {
    let zero = rtls(&["repro", "vdkf", "--runs", "0"]);
    assert!(!zero.status.success());
    assert!(String::from_utf8_lossy(&zero.stderr).contains("--runs"));

    let dir = std::env::temp_dir().join(format!("rtls-repro-scenarios-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = rtls(&["repro", "vdkf", "--scenarios", dir.to_str().unwrap()]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("004-vehicle.toml"));

    std::fs::write(dir.join("004-vehicle.toml"), "speed_mps = 10.0\nbogus = 1\n").unwrap();
    let malformed = rtls(&["repro", "vdkf", "--scenarios", dir.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&malformed.stderr);
    assert!(!malformed.status.success());
    assert!(
        stderr.contains("004-vehicle.toml") && stderr.contains("line"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
