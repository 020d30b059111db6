//! Tests of the LIAS importer: the real dataset (skipped with a message when absent) and small
//! malformed files written to a temporary directory.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rtls_engine::record::Measurement;
use rtls_engine::site::Site;

use super::parse::{parse_clock, read_mocap, read_static_poses, read_uwb};
use super::*;
use crate::import::test_support::{dataset as dataset_in, read_records, TempDir};

fn dataset() -> Option<PathBuf> {
    dataset_in("uwb_lias_cuhksz_planar_rbl")
}

/// Truth rows per tag: `(t, x, y)`, in file order.
fn read_truth(path: &Path) -> HashMap<String, Vec<(f64, f64, f64)>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,tag,x,y,z"));
    let mut truth: HashMap<String, Vec<(f64, f64, f64)>> = HashMap::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 5, "{line}");
        assert_eq!(f[4], "", "2-D truth has an empty z: {line}");
        truth.entry(f[1].to_string()).or_default().push((
            f[0].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
        ));
    }
    truth
}

/// Truth position of a tag at `t` by linear interpolation (own implementation).
fn truth_at(rows: &[(f64, f64, f64)], t: f64) -> Option<(f64, f64)> {
    if t < rows[0].0 || t > rows[rows.len() - 1].0 {
        return None;
    }
    let j = rows.partition_point(|r| r.0 <= t).min(rows.len() - 1);
    let i = j.saturating_sub(1);
    let (a, b) = (rows[i], rows[j]);
    let w = if b.0 > a.0 { (t - a.0) / (b.0 - a.0) } else { 0.0 };
    Some((a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)))
}

/// Counts the empty range cells of a UWB file by plain text splitting.
fn empty_cells(path: &Path) -> usize {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split(',').skip(1).take(24).filter(|c| c.trim().is_empty()).count())
        .sum()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn clock_is_seconds_since_midnight_to_the_millisecond() {
    let f = Path::new("u.csv");
    let origin = parse_clock(f, 1, "time", "2022-08-15 9:42:24.766").unwrap();
    assert_eq!(origin.seconds_since_midnight_of(origin.day()), 34_944.766);
    let next_day = parse_clock(f, 2, "time", "2022-08-16 0:00:01.5").unwrap();
    assert_eq!(next_day.seconds_since_midnight_of(origin.day()), 86_401.5);
    let error = parse_clock(f, 9, "time", "2022-08-15 25:00:00.000")
        .unwrap_err()
        .to_string();
    assert!(error.starts_with("u.csv:9: field `time`"), "{error}");
}

#[test]
fn malformed_uwb_rows_name_file_line_and_column() {
    let temp = TempDir::new("lias", "bad-uwb");
    let dir = &temp.0;
    let good = "2022-08-15 9:42:24.766,3.98,3.67,4.06,1.31,0.97,0.94,3.85,3.79,3.44,4.05,4.1,4.02,6.09,6.27,6.23,4.98,5.38,5.23,6.22,6.58,6.55,4.32,4.47,4.7";
    let cases = [
        (
            good.replacen(",0.94,", ",abc,", 1),
            "field `a1-t2`: `abc` is not a number",
        ),
        (good.replacen(",0.94,", ",-0.94,", 1), "field `a1-t2`: negative range"),
        (good.replacen("9:42:24.766", "9:4x:24.766", 1), "field `time`"),
        (good.rsplit_once(',').unwrap().0.to_string(), "field `a7-t2`: missing"),
    ];
    for (k, (bad, expected)) in cases.iter().enumerate() {
        let path = dir.join(format!("uwb{k}.csv"));
        std::fs::write(&path, format!("{good}\n{good},,,\n{bad}\n")).unwrap();
        let error = read_uwb(&path).unwrap_err().to_string();
        let prefix = format!("{}:3: ", path.display());
        assert!(error.starts_with(&prefix) && error.contains(expected), "{error}");
    }
    // trailing empty columns (the pos2 quirk) and empty cells are accepted
    let path = dir.join("ok.csv");
    std::fs::write(
        &path,
        format!("{good},,,,\n{}\n{good},0,652.8,,\n", good.replacen(",0.94,", ",,", 1)),
    )
    .unwrap();
    let rows = read_uwb(&path).unwrap();
    assert_eq!(
        (rows.len(), rows[0].ranges_m[5], rows[1].ranges_m[5]),
        (3, Some(0.94), None)
    );
    // values after column 25 are not ranges: counted, not parsed
    assert_eq!(
        (rows[0].extra_values, rows[2].extra_values, rows[2].ranges_m[23]),
        (0, 2, Some(4.7))
    );
}

#[test]
fn malformed_mocap_and_readme_name_file_line_and_field() {
    let temp = TempDir::new("lias", "bad-mocap");
    let dir = &temp.0;
    let path = dir.join("mocap.csv");
    std::fs::write(
        &path,
        "time,x,y,z,rotation,,,\n2022-08-15 9:42:22.968,0.2,1.9,0.96,0.003,0.99,0.017,-0.002\n\
         2022-08-15 9:42:22.977,0.2,1.9,0.96,0.003,0.99,zz,-0.002\n",
    )
    .unwrap();
    let error = read_mocap(&path).unwrap_err().to_string();
    assert_eq!(
        error,
        format!("{}:3: field `rotation[2]`: `zz` is not a number", path.display())
    );
    let readme = dir.join("README.md");
    std::fs::write(
        &readme,
        "### 2022/8/14\n| Poses | Yaw | X | Y |\n| --- | --- | --- | --- |\n| Pose 1 | -0.019 | -1.9298 | oops |\n",
    )
    .unwrap();
    let error = read_static_poses(&readme, 1).unwrap_err().to_string();
    assert_eq!(
        error,
        format!("{}:4: field `Y`: `oops` is not a number", readme.display())
    );
}

#[test]
fn import_of_a_malformed_static_file_names_it() {
    let Some(real) = dataset() else { return };
    let temp = TempDir::new("lias", "fake-dataset");
    let fake = &temp.0;
    std::fs::create_dir_all(fake.join("Static")).unwrap();
    std::fs::copy(real.join("Static/README.md"), fake.join("Static/README.md")).unwrap();
    let bad = fake.join("Static/UWB_static_exp_8_14_pos1_deg_0.csv");
    std::fs::write(&bad, "2022-08-14 11:43:11.724,4.85\n").unwrap();
    let error = import(fake, &fake.join("out")).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:1: field `a0-t1`", bad.display())),
        "{error}"
    );
}

#[test]
fn static_readme_poses_are_the_deg_0_rows() {
    let Some(dir) = dataset() else { return };
    let poses = read_static_poses(&dir.join("Static/README.md"), 5).unwrap();
    let expected = [
        (-0.019, -1.9298, -1.2368),
        (0.0230, 1.7393, -1.2132),
        (1.375, 1.7362, 1.2086),
        (0.322, -1.8708, 1.1814),
        (0.233, -0.0475, -0.0122),
    ];
    for (pose, (yaw_deg, x, y)) in poses.iter().zip(expected) {
        assert!((pose.yaw_rad.to_degrees() - yaw_deg).abs() < 1e-9);
        assert_eq!(pose.centroid_m, [x, y]);
    }
}

/// The real dataset, imported once: every check below runs on the same output, which is then
/// removed.
#[test]
fn real_dataset_import() {
    let Some(dataset) = dataset() else { return };
    let temp = TempDir::new("lias", "import");
    let runs = import(&dataset, &temp.0).unwrap();
    every_file_is_written_and_parses_back(&dataset, &temp.0, &runs);
    static_calibration_transfers_to_the_dynamic_runs(&temp.0);
    calibration_bias_matches_an_independent_median(&dataset, &temp.0);
    static_truth_is_the_surveyed_pose(&temp.0);
}

fn every_file_is_written_and_parses_back(dataset: &Path, out: &Path, runs: &[ImportedRun]) {
    let names: Vec<&str> = runs.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "fast",
            "mid",
            "static-pos1",
            "static-pos2",
            "static-pos3",
            "static-pos4",
            "static-pos5"
        ]
    );
    assert!(out.join("calibration.csv").exists());
    for run in runs {
        for note in &run.notes {
            eprintln!("{}: {note}", run.name);
        }
        let dir = out.join(&run.name);
        let site_text = std::fs::read_to_string(dir.join("site.toml")).unwrap();
        let site = Site::from_toml_str(&site_text, "site.toml").unwrap();
        assert_eq!(site.readers.len(), 8);
        assert_eq!(site.tracker.dimensions, 2);
        assert_eq!(site.tracker.tag_height_m, Some(RIGID_BODY_HEIGHT_M));
        let corrected = read_records(&dir.join("measurements.jsonl"));
        let raw = read_records(&dir.join("measurements-raw.jsonl"));
        assert_eq!(corrected.len(), run.records);
        assert_eq!(raw.len(), corrected.len());
        let (uwb, mocap_rows) = match run.name.as_str() {
            "fast" | "mid" => {
                let mocap = dataset.join(format!("Dynamic/motion_capture_dynamic_exp_{}.csv", run.name));
                // distinct time stamps: rows repeating the previous one are averaged into it
                let text = std::fs::read_to_string(mocap).unwrap();
                let times: Vec<&str> = text.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
                let rows = times.len() - times.windows(2).filter(|w| w[0] == w[1]).count();
                (
                    dataset.join(format!("Dynamic/UWB_dynamic_exp_{}.csv", run.name)),
                    Some(rows),
                )
            }
            name => {
                let pos = name.trim_start_matches("static-pos");
                (
                    dataset.join(format!("Static/UWB_static_exp_8_14_pos{pos}_deg_0.csv")),
                    None,
                )
            }
        };
        let uwb_rows = std::fs::read_to_string(&uwb).unwrap().lines().count();
        let zero = usize::from(run.name == "mid"); // one 0.0 m range at mid line 6171 (a7-t0)
        assert_eq!(
            corrected.len(),
            24 * uwb_rows - empty_cells(&uwb) - zero,
            "{}",
            run.name
        );
        // truth: 3 tags per motion-capture time stamp (dynamic) or per UWB row (static)
        let truth_rows = std::fs::read_to_string(dir.join("truth.csv")).unwrap().lines().count() - 1;
        assert_eq!(truth_rows, 3 * mocap_rows.unwrap_or(uwb_rows), "{}", run.name);
        assert_eq!(truth_rows, run.truth_rows);
    }
    // the expected figures, counted independently with python (empty cells 30 and 6)
    assert_eq!((runs[0].records, runs[1].records), (323_514, 309_785));
}

/// Corrected (and raw) range minus the true slant distance from the written truth, per run.
fn residual_medians(out: &Path, run: &str) -> (f64, f64, usize) {
    let dir = out.join(run);
    let site = Site::from_toml_str(&std::fs::read_to_string(dir.join("site.toml")).unwrap(), "site.toml").unwrap();
    let height = site.tracker.tag_height_m.unwrap();
    let truth = read_truth(&dir.join("truth.csv"));
    let residuals = |file: &str| -> Vec<f64> {
        read_records(&dir.join(file))
            .iter()
            .filter_map(|r| {
                let Measurement::Range { anchor, range_m, .. } = &r.measurement else {
                    panic!("not a range")
                };
                let (x, y) = truth_at(&truth[&r.tag], r.time_s)?;
                let [ax, ay, az] = site.reader(anchor).unwrap().position_xyz_m();
                Some(range_m - ((x - ax).powi(2) + (y - ay).powi(2) + (height - az).powi(2)).sqrt())
            })
            .collect()
    };
    let corrected = residuals("measurements.jsonl");
    let n = corrected.len();
    (median(corrected), median(residuals("measurements-raw.jsonl")), n)
}

fn static_calibration_transfers_to_the_dynamic_runs(out: &Path) {
    for run in ["fast", "mid"] {
        let (corrected, raw, n) = residual_medians(out, run);
        eprintln!("{run}: median corrected − true {corrected:+.4} m, raw − true {raw:+.4} m ({n} ranges)");
        assert!(n > 300_000, "{run}: {n}");
        assert!(corrected.abs() < 0.03, "{run}: corrected median {corrected}");
        assert!((0.14..0.20).contains(&raw), "{run}: raw median {raw}");
    }
}

#[test]
fn yaw_from_columns_6_and_7_fits_and_the_documented_order_does_not() {
    let Some(dataset) = dataset() else { return };
    let rows = read_uwb(&dataset.join("Dynamic/UWB_dynamic_exp_fast.csv")).unwrap();
    let mocap = read_mocap(&dataset.join("Dynamic/motion_capture_dynamic_exp_fast.csv")).unwrap();
    let day = rows[0].clock.day();
    let track = Track {
        times_s: mocap.iter().map(|m| m.clock.seconds_since_midnight_of(day)).collect(),
        rows: mocap,
    };
    let static_calibration = reimport_calibration(&dataset);
    let check = residual_check(&rows, &row_times(&rows, day), &track, &static_calibration).unwrap();
    eprintln!(
        "fast: corrected std {:.4} m, documented-order raw std {:.4} m",
        check.corrected_std_m, check.documented_order_std_m
    );
    assert!(check.corrected_std_m < 0.12, "{}", check.corrected_std_m);
    assert!(check.documented_order_std_m > 0.18, "{}", check.documented_order_std_m);
}

fn reimport_calibration(dataset: &Path) -> Calibration {
    let poses = read_static_poses(&dataset.join("Static/README.md"), 5).unwrap();
    let runs: Vec<StaticRun> = poses
        .into_iter()
        .map(|pose| StaticRun {
            rows: read_uwb(&dataset.join(format!("Static/UWB_static_exp_8_14_pos{}_deg_0.csv", pose.pose))).unwrap(),
            pose,
        })
        .collect();
    calibration::calibrate(&runs).unwrap()
}

fn calibration_bias_matches_an_independent_median(dataset: &Path, out: &Path) {
    let text = std::fs::read_to_string(out.join("calibration.csv")).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 24);
    assert_eq!(
        (rows[0][0], rows[0][1], rows[23][0], rows[23][1]),
        ("A0", "T0", "A7", "T2")
    );
    // pair a3-t1 (column 11), recomputed from the files with the README poses typed in here
    let poses = [
        (1, -0.019_f64, -1.9298, -1.2368),
        (2, 0.0230, 1.7393, -1.2132),
        (3, 1.375, 1.7362, 1.2086),
        (4, 0.322, -1.8708, 1.1814),
        (5, 0.233, -0.0475, -0.0122),
    ];
    let (anchor, offset) = ([3.6011, -0.0008, 1.0422], [-0.0750, 0.1402, 0.0016]);
    let mut residuals = Vec::new();
    for (pos, yaw_deg, x, y) in poses {
        let (s, c) = yaw_deg.to_radians().sin_cos();
        let tag = [
            x + c * offset[0] - s * offset[1],
            y + s * offset[0] + c * offset[1],
            0.97 + offset[2],
        ];
        let d = ((tag[0] - anchor[0]).powi(2) + (tag[1] - anchor[1]).powi(2) + (tag[2] - anchor[2]).powi(2)).sqrt();
        let file = dataset.join(format!("Static/UWB_static_exp_8_14_pos{pos}_deg_0.csv"));
        for line in std::fs::read_to_string(file).unwrap().lines() {
            let cell = line.split(',').nth(11).unwrap();
            if !cell.is_empty() {
                residuals.push(cell.parse::<f64>().unwrap() - d);
            }
        }
    }
    residuals.sort_by(f64::total_cmp);
    let n = residuals.len();
    let expected = if n % 2 == 1 {
        residuals[n / 2]
    } else {
        0.5 * (residuals[n / 2 - 1] + residuals[n / 2])
    };
    let row = &rows[3 * 3 + 1];
    assert_eq!((row[0], row[1]), ("A3", "T1"));
    let (bias, slope): (f64, f64) = (row[2].parse().unwrap(), row[3].parse().unwrap());
    assert_eq!(slope, 0.0, "the slope test keeps the bias-only model on these runs");
    assert!((bias - expected).abs() < 1e-12, "{bias} vs {expected}");
    assert_eq!(row[5].parse::<usize>().unwrap(), n);
    // every bias positive (TWR ranges are long) and every std plausible
    for row in &rows {
        let (b, s): (f64, f64) = (row[2].parse().unwrap(), row[4].parse().unwrap());
        assert!((0.0..0.4).contains(&b) && (0.01..0.15).contains(&s), "{row:?}");
    }
}

fn static_truth_is_the_surveyed_pose(out: &Path) {
    let truth = read_truth(&out.join("static-pos5/truth.csv"));
    // pose 5: yaw 0.233°, centroid (−0.0475, −0.0122); tag T2 offset (0.2034, 0.1451)
    let (s, c) = 0.233_f64.to_radians().sin_cos();
    let expected = (-0.0475 + c * 0.2034 - s * 0.1451, -0.0122 + s * 0.2034 + c * 0.1451);
    let rows = &truth["T2"];
    assert!(rows.len() > 10_000);
    for &(_, x, y) in [rows[0], rows[rows.len() - 1]].iter() {
        assert!((x - expected.0).abs() < 1e-12 && (y - expected.1).abs() < 1e-12);
    }
}
