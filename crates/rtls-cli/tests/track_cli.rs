//! `rtls track` as a user runs it: a site and a measurement file in, track updates, events and
//! raw fixes out; bad input named by file, line and field; then `rtls eval` on the result.

mod common;

use common::rtls;
use std::path::PathBuf;

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("track-cli", name)
}

const SITE: &str = r#"
readers = [
  { id = "A1", position_m = [0.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
  { id = "A2", position_m = [20.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
  { id = "A3", position_m = [20.0, 20.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
  { id = "A4", position_m = [0.0, 20.0], technology = "uwb", radio = { range = { range_std_m = 0.05, bias_m = 0.0 } } },
]
[[zones]]
id = "pit"
name = "Pit"
kind = "hazard"
shape = { type = "box", min_m = [15.0, -5.0, -1.0], max_m = [30.0, 25.0, 1.0] }

[tracker]
pipeline = "tightly-coupled"
motion_model = "cv"
filter = "ekf"
acceleration_noise_std_mps2 = 0.3
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.2
"#;

/// A walker at (2 + t, 10) m, noise-free ranges to one anchor per 0.1 s (round robin), 15 s;
/// and the matching ground truth.
fn inputs(dir: &std::path::Path) -> (String, String, String) {
    let anchors = [
        ("A1", [0.0, 0.0]),
        ("A2", [20.0, 0.0]),
        ("A3", [20.0, 20.0]),
        ("A4", [0.0, 20.0]),
    ];
    let mut records = String::new();
    let mut truth = String::from("t,tag,x,y,z\n");
    for k in 0..150 {
        let t = k as f64 * 0.1;
        let p = [2.0 + t, 10.0];
        let (id, a) = anchors[k % 4];
        let range = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
        records.push_str(&format!(
            "{{\"t\": {t}, \"tag\": \"w\", \"kind\": \"range\", \"anchor\": \"{id}\", \"range_m\": {range}}}\n"
        ));
        truth.push_str(&format!("{t},w,{},{},\n", p[0], p[1]));
    }
    let site = dir.join("site.toml");
    let input = dir.join("in.jsonl");
    let truth_path = dir.join("truth.csv");
    std::fs::write(&site, SITE).unwrap();
    std::fs::write(&input, records).unwrap();
    std::fs::write(&truth_path, truth).unwrap();
    (
        site.display().to_string(),
        input.display().to_string(),
        truth_path.display().to_string(),
    )
}

#[test]
fn track_writes_updates_and_events_that_eval_scores() {
    let dir = temp_dir("ok");
    let (site, input, truth) = inputs(&dir);
    let tracks = dir.join("tracks.jsonl").display().to_string();
    let events = dir.join("events.jsonl").display().to_string();
    let output = rtls(&[
        "track", "--site", &site, "--input", &input, "--output", &tracks, "--events", &events, "--quiet",
    ]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let summary = String::from_utf8_lossy(&output.stderr);
    assert!(summary.starts_with("150 records,"), "{summary}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&tracks)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // the track starts after 3 anchors (t = 0.2 s), then one update per range
    assert!(lines.len() >= 147, "{}", lines.len());
    let last = lines.last().unwrap();
    assert!((last["x"].as_f64().unwrap() - 16.9).abs() < 0.05, "{last}");
    assert_eq!(last["cov"].as_array().unwrap().len(), 4);
    assert_eq!(last["status"], "confirmed");
    // the walker heads for the pit (x ≥ 15 at t = 13 s): alarmed ahead of the entry
    let events: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let alarm = events
        .iter()
        .find(|e| e["type"] == "hazard-predicted")
        .expect("an alarm");
    let entry = events.iter().find(|e| e["type"] == "zone-enter").expect("an entry");
    assert!(
        entry["t"].as_f64().unwrap() - alarm["t"].as_f64().unwrap() > 8.0,
        "{alarm} {entry}"
    );
    // and rtls eval scores it against the truth
    let scored = rtls(&[
        "eval",
        "--truth",
        &truth,
        "--tracks",
        &tracks,
        "--skip-initial",
        "2",
        "--json",
    ]);
    assert!(scored.status.success(), "{}", String::from_utf8_lossy(&scored.stderr));
    let report: serde_json::Value = serde_json::from_slice(&scored.stdout).unwrap();
    assert!(report["overall"]["rmse_m"].as_f64().unwrap() < 0.02, "{report}");
}

#[test]
fn a_bad_record_costs_itself_named_by_file_line_and_field_and_strict_stops_there() {
    let dir = temp_dir("bad");
    let (site, input, _) = inputs(&dir);
    let events = dir.join("events.jsonl").display().to_string();
    let text = std::fs::read_to_string(&input).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // an anchor the site does not have on line 4, a malformed value on line 9, a time in
    // nanoseconds on line 20 and a line that is not JSON at the end (a negative range is
    // valid: Wi-Fi FTM/RTT reports them)
    lines[3] = lines[3].replace("\"A4\"", "\"A9\"");
    lines[8] = lines[8].replace("\"range_m\": ", "\"range_m\": true, \"x\": ");
    lines[19] = lines[19].replace("\"t\": 1.9", "\"t\": 1900000000000000000");
    lines.push("{\"t\": 15.0, \"tag\": \"w\"".into());
    std::fs::write(&input, lines.join("\n")).unwrap();
    let output = rtls(&[
        "track", "--site", &site, "--input", &input, "--events", &events, "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("4 malformed record(s) skipped"), "{stderr}");
    assert!(stderr.contains(&format!("{input}:4: field `anchor`")), "{stderr}");
    assert!(stderr.contains(&format!("{input}:9: field `range_m`")), "{stderr}");
    assert!(stderr.contains("147 records"), "{stderr}");
    let malformed: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str::<serde_json::Value>(line).unwrap())
        .filter(|event| event["type"] == "malformed")
        .collect();
    let at: Vec<(u64, &str)> = malformed
        .iter()
        .map(|e| (e["line"].as_u64().unwrap(), e["field"].as_str().unwrap()))
        .collect();
    assert_eq!(at[..3], [(4, "anchor"), (9, "range_m"), (20, "t")]);
    // the truncated line: the parser names where it ended
    assert_eq!(at[3].0, 151);
    // each at the newest record time read so far: the unknown anchor's own (its record
    // parsed), the mistyped value's line 8 before it
    assert_eq!(malformed[0]["t"], 0.30000000000000004);
    assert_eq!(malformed[1]["t"], 0.7000000000000001);
    assert!(malformed.iter().all(|e| e["t"].as_f64().is_some_and(f64::is_finite)));
    // --strict: the first stops the run, named
    let output = rtls(&["track", "--site", &site, "--input", &input, "--strict", "--quiet"]);
    assert!(!output.status.success());
    let error = String::from_utf8_lossy(&output.stderr);
    assert!(error.contains(&format!("{input}:4: field `anchor`")), "{error}");
    // an input of which nothing can be used is an error, not an empty run
    let garbage = dir.join("garbage.jsonl");
    std::fs::write(&garbage, "not a record\n{}\n").unwrap();
    let garbage = garbage.display().to_string();
    let output = rtls(&["track", "--site", &site, "--input", &garbage, "--quiet"]);
    assert!(!output.status.success());
    let error = String::from_utf8_lossy(&output.stderr);
    assert!(error.contains("none of its records could be used"), "{error}");
    // a tightly coupled KF is refused
    let output = rtls(&["track", "--site", &site, "--input", &input, "--filter", "kf", "--quiet"]);
    assert!(String::from_utf8_lossy(&output.stderr).contains("needs --filter ekf or ukf"));
}

#[test]
fn a_tag_with_records_but_no_track_is_named_and_the_exit_status_is_3() {
    let dir = temp_dir("untracked");
    let (site, input, _) = inputs(&dir);
    // a second tag heard by one anchor only: its readings never initialise a track
    let mut lines: Vec<(f64, String)> = std::fs::read_to_string(&input)
        .unwrap()
        .lines()
        .map(|l| {
            let value: serde_json::Value = serde_json::from_str(l).unwrap();
            (value["t"].as_f64().unwrap(), l.to_string())
        })
        .collect();
    for k in 0..60 {
        let t = k as f64 * 0.25 + 0.01;
        lines.push((
            t,
            format!(
                "{{\"t\": {t}, \"tag\": \"ghost\", \"kind\": \"range\", \"anchor\": \"A1\", \"range_m\": {}}}",
                5.0 + 0.01 * k as f64
            ),
        ));
    }
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    let text: Vec<String> = lines.into_iter().map(|(_, l)| l).collect();
    std::fs::write(&input, text.join("\n")).unwrap();
    let tracks = dir.join("tracks.jsonl").display().to_string();
    let output = rtls(&[
        "track", "--site", &site, "--input", &input, "--output", &tracks, "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    // the tracked tag's output is still written, and the summary comes first
    assert!(std::fs::read_to_string(&tracks).unwrap().lines().count() >= 147);
    assert!(stderr.starts_with("210 records,"), "{stderr}");
    assert!(
        stderr.contains("rejected by reason: ") && stderr.contains("range: # reading(s) expired"),
        "{stderr}"
    );
    let line = stderr
        .lines()
        .find(|l| l.starts_with("no track for tag ghost: 60 records, rejected "))
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        line.contains("reading(s) expired before enough anchors could initialise the track"),
        "{line}"
    );
    assert!(!stderr.contains("no track for tag w:"), "{stderr}");
    assert!(stderr.contains("1 tag(s) had records but no track output"), "{stderr}");
    // the exit status is documented in the command's help
    let help = rtls(&["track", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("Exit status"));
}

#[test]
fn fix_then_filter_with_odometry_and_an_imm_tracks_the_whole_file() {
    let dir = temp_dir("odometry");
    let (site, input, _) = inputs(&dir);
    // odometry between the ranges (speed 1 m/s east; at a standstill for the first second)
    let mut lines: Vec<String> = std::fs::read_to_string(&input)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let mut with_odometry = Vec::new();
    for (k, line) in lines.drain(..).enumerate() {
        with_odometry.push(line);
        if k % 4 == 3 {
            let t = k as f64 * 0.1 + 0.05;
            let speed = if t < 1.0 { 0.0 } else { 1.0 };
            with_odometry.push(format!(
                "{{\"t\": {t}, \"tag\": \"w\", \"kind\": \"odometry\", \"speed_mps\": {speed}, \"heading_rad\": 0.0, \
                 \"speed_std_mps\": 0.05, \"heading_std_rad\": 0.0}}"
            ));
        }
    }
    std::fs::write(&input, with_odometry.join("\n")).unwrap();
    // fix-then-filter: the four round-robin ranges of 0.3 s make one epoch
    std::fs::write(
        &site,
        SITE.replace("reorder_window_s = 0.2", "reorder_window_s = 0.2\nepoch_s = 0.35"),
    )
    .unwrap();
    let events = dir.join("events.jsonl").display().to_string();
    for motion_model in ["cv", "imm"] {
        let output = rtls(&[
            "track",
            "--site",
            &site,
            "--input",
            &input,
            "--pipeline",
            "fix-then-filter",
            "--filter",
            "kf",
            "--motion-model",
            motion_model,
            "--events",
            &events,
            "--quiet",
        ]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{motion_model}: {stderr}");
        let events = std::fs::read_to_string(&events).unwrap();
        assert!(!events.contains("positive definite"), "{motion_model}: {events}");
        assert!(!events.contains("backwards"), "{motion_model}: {events}");
        let tracks: Vec<serde_json::Value> = String::from_utf8_lossy(&output.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        let last = tracks.last().unwrap();
        // an epoch's fix is dated at its last reading but solved from 0.3 s of walking
        assert!(
            (last["x"].as_f64().unwrap() - 16.9).abs() < 0.5,
            "{motion_model}: {last}"
        );
    }
}

/// Scores `tracks` against `truth` with `rtls eval --json`: (RMSE m, share inside the 95 %
/// ellipse).
fn scored(truth: &str, tracks: &str) -> (f64, f64) {
    let output = rtls(&[
        "eval",
        "--truth",
        truth,
        "--tracks",
        tracks,
        "--skip-initial",
        "2",
        "--json",
    ]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    (
        report["overall"]["rmse_m"].as_f64().unwrap(),
        report["consistency"]["inside_95"].as_f64().unwrap(),
    )
}

#[test]
fn track_smooth_writes_every_update_smoothed_with_a_lower_error() {
    let dir = temp_dir("smooth");
    let (site, _, truth) = inputs(&dir);
    // the walker's ranges with ±0.3 m of (deterministic, white-looking) noise
    let noisy: String = (0..150)
        .map(|k| {
            let t = k as f64 * 0.1;
            let anchors = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]];
            let a: [f64; 2] = anchors[k % 4];
            let range = ((2.0 + t - a[0]).powi(2) + (10.0 - a[1]).powi(2)).sqrt();
            let noise = ((k * 7919 % 13) as f64 / 12.0 - 0.5) * 0.6;
            format!(
                "{{\"t\": {t}, \"tag\": \"w\", \"kind\": \"range\", \"anchor\": \"A{}\", \"range_m\": {}, \"std_m\": 0.2}}\n",
                k % 4 + 1,
                range + noise
            )
        })
        .collect();
    let input = dir.join("noisy.jsonl");
    std::fs::write(&input, noisy).unwrap();
    let input = input.display().to_string();
    let run = |name: &str, extra: &[&str]| -> Vec<serde_json::Value> {
        let tracks = dir.join(name).display().to_string();
        let mut args = vec![
            "track", "--site", &site, "--input", &input, "--output", &tracks, "--quiet",
        ];
        args.extend_from_slice(extra);
        let output = rtls(&args);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        if !extra.is_empty() {
            let summary = String::from_utf8_lossy(&output.stderr);
            assert!(summary.contains("smoothed 148 of 148 track updates"), "{summary}");
        }
        std::fs::read_to_string(&tracks)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let filtered = run("filtered.jsonl", &[]);
    let smoothed = run("smoothed.jsonl", &["--smooth"]);
    assert_eq!(filtered.len(), smoothed.len());
    assert!(smoothed.iter().all(|u| u["smoothed"] == true));
    assert!(filtered.iter().all(|u| u.get("smoothed").is_none()));
    // the newest update is the filter's own
    let (f, s) = (filtered.last().unwrap(), smoothed.last().unwrap());
    assert!(
        (f["x"].as_f64().unwrap() - s["x"].as_f64().unwrap()).abs() < 1e-9,
        "{f} {s}"
    );
    let path = |name: &str| dir.join(name).display().to_string();
    let (filtered_rmse, _) = scored(&truth, &path("filtered.jsonl"));
    let (smoothed_rmse, smoothed_inside) = scored(&truth, &path("smoothed.jsonl"));
    assert!(
        smoothed_rmse < filtered_rmse,
        "smoothed {smoothed_rmse} m, filtered {filtered_rmse} m"
    );
    assert!(smoothed_inside >= 0.9, "{smoothed_inside}");
}
