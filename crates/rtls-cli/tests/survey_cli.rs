//! `rtls survey` as a user runs it: a site, a measurement file and its tracks in; the cell and
//! reader tables and the map out; a summary naming the attenuated reader; bad input named by
//! file, line and field.

mod common;

use common::rtls;
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("survey-cli", name)
}

/// Ten BLE readers every 10 m along y = ±3 m, law `−40 − 20 log₁₀ d`.
fn site() -> String {
    let mut text = String::new();
    for k in 0..10 {
        let y = if k % 2 == 0 { -3.0 } else { 3.0 };
        text.push_str(&format!(
            "[[readers]]\nid = \"R{k}\"\nposition_m = [{}, {y}]\ntechnology = \"ble\"\n\
             radio = {{ path_loss = {{ reference_power_dbm = -40.0, exponent = 2.0, shadowing_std_db = 2.0, reference_distance_m = 1.0 }} }}\n",
            10 * k
        ));
    }
    text.push_str(
        "[tracker]\npipeline = \"tightly-coupled\"\nmotion_model = \"cv\"\nfilter = \"ekf\"\n\
         acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.999\n\
         initiation = { confirm_updates = 3, within_s = 5.0 }\ncoast_timeout_s = 5.0\n\
         delete_timeout_s = 60.0\nreorder_window_s = 0.0\n",
    );
    text
}

/// A tag walking back and forth along y = 1 between x = 0 and 90 m at 1 m/s for 900 s,
/// scanned every 0.5 s by the readers within 25 m; R4's links are 10 dB weaker while the tag
/// is at 42 ≤ x ≤ 60 m. The noise is a deterministic ±1 dB pattern. The track file is the
/// true path (one update per scan).
fn inputs(dir: &Path) -> (String, String, String) {
    let (mut records, mut tracks) = (String::new(), String::new());
    for k in 0..1800 {
        let t = k as f64 * 0.5;
        let phase = t % 180.0;
        let x = if phase <= 90.0 { phase } else { 180.0 - phase };
        tracks.push_str(&format!("{{\"t\": {t}, \"tag\": \"w\", \"x\": {x}, \"y\": 1}}\n"));
        for r in 0..10 {
            let (rx, ry) = (10.0 * r as f64, if r % 2 == 0 { -3.0 } else { 3.0 });
            let d = ((x - rx).powi(2) + (1.0f64 - ry).powi(2)).sqrt();
            if d > 25.0 {
                continue;
            }
            let noise = ((k * 7919 + r * 104_729) % 13) as f64 / 6.0 - 1.0;
            let loss = if r == 4 && (42.0..=60.0).contains(&x) {
                10.0
            } else {
                0.0
            };
            let rssi = -40.0 - 20.0 * d.log10() - loss + noise;
            records.push_str(&format!(
                "{{\"t\": {t}, \"tag\": \"w\", \"kind\": \"rssi\", \"anchor\": \"R{r}\", \"rssi_dbm\": {rssi}}}\n"
            ));
        }
    }
    let paths = ["site.toml", "records.jsonl", "tracks.jsonl"].map(|name| dir.join(name));
    std::fs::write(&paths[0], site()).unwrap();
    std::fs::write(&paths[1], records).unwrap();
    std::fs::write(&paths[2], tracks).unwrap();
    let [a, b, c] = paths.map(|p| p.display().to_string());
    (a, b, c)
}

#[test]
fn survey_flags_the_attenuated_reader_and_writes_tables_and_a_map() {
    let dir = temp_dir("ok");
    let (site, records, tracks) = inputs(&dir);
    let cells = dir.join("cells.csv").display().to_string();
    let readers = dir.join("readers.csv").display().to_string();
    let png = dir.join("map.png").display().to_string();
    let output = rtls(&[
        "survey",
        "--site",
        &site,
        "--input",
        &records,
        "--tracks",
        &tracks,
        "--out",
        &cells,
        "--readers-out",
        &readers,
        "--png",
        &png,
    ]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    // the first 5 s of the track are skipped (10 scans), nothing else is lost
    assert!(stdout.contains("without one: initial_skipped "), "{stdout}");
    assert!(
        !stdout.contains("outside_track") && !stdout.contains("unknown_reader"),
        "{stdout}"
    );

    // the cell table: R4's cells on the shadowed stretch are flagged, nothing else; the most
    // significant first in the summary, the cell table in cell order
    let text = std::fs::read_to_string(&cells).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("x_min_m,x_max_m,y_min_m,y_max_m,reader,kind,n,distance_m,bias,std,z,spread_z,flagged,reason")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() > 30, "{}", rows.len());
    let flagged: Vec<&Vec<&str>> = rows.iter().filter(|r| r[12] == "true").collect();
    let cells_flagged: Vec<(&str, &str, &str)> = flagged.iter().map(|r| (r[4], r[0], r[1])).collect();
    assert_eq!(cells_flagged, [("R4", "40", "50"), ("R4", "50", "60")], "{text}");
    // [50, 60) is all in the shadow: −10 dB; [40, 50) from x = 42 m on: about −10 × 8/10
    let (partly, fully) = (flagged[0], flagged[1]);
    let bias = |row: &Vec<&str>| row[8].parse::<f64>().unwrap();
    assert!((bias(fully) + 10.0).abs() < 0.5, "{fully:?}");
    assert!(bias(partly) < -6.0 && bias(partly) > -9.0, "{partly:?}");
    for row in [partly, fully] {
        assert!(row[10].parse::<f64>().unwrap() < -3.5 && row[13] == "bias", "{row:?}");
    }

    // the reader table names R4, flagged through its cell
    let text = std::fs::read_to_string(&readers).unwrap();
    assert!(text.starts_with("reader,kind,n,distance_m,bias,std,z,spread_z,flagged_cells,flagged,reason\n"));
    let r4: Vec<&str> = text
        .lines()
        .find(|l| l.starts_with("R4,"))
        .unwrap()
        .split(',')
        .collect();
    assert_eq!((r4[1], r4[8], r4[9]), ("rssi", "2", "true"), "{r4:?}");
    assert!(r4[10].contains("cells"), "{r4:?}");
    assert_eq!(text.lines().filter(|l| l.contains(",true,")).count(), 1, "{text}");
    assert!(
        stdout.contains("2 flagged; readers:") && stdout.contains("  R4 "),
        "{stdout}"
    );

    // the map
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert!(bytes.len() > 10_000, "{}", bytes.len());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn survey_errors_name_the_file_line_and_field() {
    let dir = temp_dir("errors");
    let (site, records, tracks) = inputs(&dir);
    let out = dir.join("cells.csv").display().to_string();
    let text = std::fs::read_to_string(&tracks).unwrap();
    let bad = text.replacen("\"x\": 1,", "\"x\": \"one\",", 1);
    assert_ne!(bad, text);
    std::fs::write(&tracks, bad).unwrap();
    let output = rtls(&[
        "survey", "--site", &site, "--input", &records, "--tracks", &tracks, "--out", &out,
    ]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains(&format!("{tracks}:3: field `x`")), "{stderr}");

    let output = rtls(&[
        "survey", "--site", &site, "--input", &records, "--tracks", &tracks, "--out", &out, "--cell-m", "0",
    ]);
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("--cell-m"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A malformed measurement record costs only itself: the survey of the rest is the same but
/// for that record, and its summary names it; `--strict` stops at it.
#[test]
fn survey_skips_a_malformed_record_and_names_it() {
    let dir = temp_dir("malformed");
    let (site, records, tracks) = inputs(&dir);
    let out = dir.join("cells.csv").display().to_string();
    let survey = |extra: &[&str]| {
        let mut args = vec![
            "survey", "--site", &site, "--input", &records, "--tracks", &tracks, "--out", &out,
        ];
        args.extend_from_slice(extra);
        rtls(&args)
    };
    let good = survey(&[]);
    assert!(good.status.success(), "{}", String::from_utf8_lossy(&good.stderr));
    let good = String::from_utf8_lossy(&good.stdout).to_string();
    // line 3: a mistyped RSSI
    let text = std::fs::read_to_string(&records).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let value = lines[2].rsplit_once("\"rssi_dbm\": ").unwrap().0.to_string();
    lines[2] = format!("{value}\"rssi_dbm\": \"loud\"}}");
    std::fs::write(&records, lines.join("\n") + "\n").unwrap();
    let skipped = survey(&[]);
    assert!(skipped.status.success(), "{}", String::from_utf8_lossy(&skipped.stderr));
    let stdout = String::from_utf8_lossy(&skipped.stdout);
    let count = |summary: &str| -> usize { summary.split(" records:").next().unwrap().trim().parse().unwrap() };
    assert_eq!(count(&stdout) + 1, count(&good), "{stdout}\n---\n{good}");
    assert!(stdout.contains("1 malformed record(s) skipped"), "{stdout}");
    assert!(stdout.contains(&format!("{records}:3: field `rssi_dbm`")), "{stdout}");
    let strict = survey(&["--strict"]);
    assert!(!strict.status.success());
    let stderr = String::from_utf8_lossy(&strict.stderr);
    assert!(stderr.contains(&format!("{records}:3: field `rssi_dbm`")), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// RMSE of a track file against the walk of `inputs` where R4 is attenuated (42 ≤ x ≤ 60 m).
fn shadowed_rmse(tracks_path: &Path) -> f64 {
    let text = std::fs::read_to_string(tracks_path).unwrap();
    let mut squared = Vec::new();
    for line in text.lines() {
        let value: serde_json::Value = serde_json::from_str(line).unwrap();
        let t = value["t"].as_f64().unwrap();
        let phase = t % 180.0;
        let x = if phase <= 90.0 { phase } else { 180.0 - phase };
        if t >= 10.0 && (42.0..=60.0).contains(&x) {
            let (ex, ey) = (value["x"].as_f64().unwrap() - x, value["y"].as_f64().unwrap() - 1.0);
            squared.push(ex * ex + ey * ey);
        }
    }
    assert!(squared.len() > 100, "{}", squared.len());
    (squared.iter().sum::<f64>() / squared.len() as f64).sqrt()
}

#[test]
fn track_corrects_records_with_the_surveyed_bias() {
    let dir = temp_dir("correct");
    let (site, records, tracks) = inputs(&dir);
    let cells = dir.join("cells.csv").display().to_string();
    let readers = dir.join("readers.csv").display().to_string();
    let survey = rtls(&[
        "survey",
        "--site",
        &site,
        "--input",
        &records,
        "--tracks",
        &tracks,
        "--out",
        &cells,
        "--readers-out",
        &readers,
    ]);
    assert!(survey.status.success(), "{}", String::from_utf8_lossy(&survey.stderr));
    let plain = dir.join("plain.jsonl");
    let corrected = dir.join("corrected.jsonl");
    let plain_name = plain.display().to_string();
    let corrected_name = corrected.display().to_string();
    let run = |extra: &[&str], output: &str| {
        let mut args = vec![
            "track", "--site", &site, "--input", &records, "--output", output, "--quiet",
        ];
        args.extend_from_slice(extra);
        let result = rtls(&args);
        assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
    };
    run(&[], &plain_name);
    run(&["--correct", &cells, "--correct-readers", &readers], &corrected_name);
    let (before, after) = (shadowed_rmse(&plain), shadowed_rmse(&corrected));
    println!("shadowed stretch RMSE: {before:.3} m uncorrected, {after:.3} m corrected");
    // measured: 2.209 m uncorrected, 1.935 m corrected (readers on one line, so RSSI geometry
    // and not only the bias limit the accuracy there)
    assert!(after < 0.95 * before, "corrected {after} vs {before}");
    // --correct needs its readers table
    let refused = rtls(&["track", "--site", &site, "--input", &records, "--correct", &cells]);
    assert!(!refused.status.success());
}
