//! Tests of the TDOA UTIL importer: the real dataset (skipped with a message when absent) and
//! small malformed files.

use std::path::PathBuf;

use rtls_engine::record::{parse_json_line, Measurement};
use rtls_engine::site::Site;

use super::*;
use crate::import::test_support::{dataset as dataset_in, TempDir};

fn dataset() -> Option<PathBuf> {
    dataset_in("tdoa_util_static_prerelease")
}

fn pose(path: &Path, key: &str) -> [f64; 3] {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text.lines().find(|l| l.starts_with(&format!("{key},"))).unwrap();
    let v: Vec<f64> = line.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
    [v[0], v[1], v[2]]
}

#[test]
fn real_dataset_imports_every_run_with_the_verified_sign() {
    let Some(dataset) = dataset() else { return };
    let temp = TempDir::new("tdoa", "import");
    let out = &temp.0;
    let runs = import(&dataset, out).unwrap();
    assert_eq!(runs.len(), 31);
    let names: Vec<&str> = runs.iter().map(|r| r.name.as_str()).collect();
    for expected in [
        "los-distTest-distT1",
        "los-angleTest-angleT12",
        "nlos-anTag-metal-data1",
        "nlos-los-data",
    ] {
        assert!(names.contains(&expected), "{names:?}");
    }
    let mut sign_checked = 0;
    for run in &runs {
        eprintln!("{}: {}", run.name, run.notes[2]);
        let dir = out.join(&run.name);
        let site = Site::from_toml_str(&std::fs::read_to_string(dir.join("site.toml")).unwrap(), "site.toml").unwrap();
        assert_eq!((site.readers.len(), site.tracker.dimensions), (2, 3));
        let root = dataset.join("static-dataset");
        let data = data_files(&root)
            .unwrap()
            .into_iter()
            .find(|f| run_name(&root, f) == run.name)
            .unwrap();
        let pose_file = PathBuf::from(data.to_string_lossy().replace("_data.csv", "_pose.txt"));
        let expected: Vec<f64> = std::fs::read_to_string(&data)
            .unwrap()
            .lines()
            .skip(1)
            .filter_map(|l| {
                l.split(',')
                    .next()
                    .filter(|c| !c.is_empty())
                    .map(|c| c.parse().unwrap())
            })
            .collect();
        let text = std::fs::read_to_string(dir.join("measurements.jsonl")).unwrap();
        let mut values = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let record = parse_json_line(line, "measurements.jsonl", i + 1).unwrap();
            record.validate("measurements.jsonl", i + 1).unwrap();
            // rows without tdoa12 come only at the end, so sample i is at i / 100 Hz
            assert_eq!(record.time_s, i as f64 / NOMINAL_RATE_HZ);
            let Measurement::Tdoa {
                anchor,
                reference,
                range_difference_m,
                std_m,
            } = record.measurement
            else {
                panic!("not a TDOA")
            };
            assert_eq!((anchor.as_str(), reference.as_str(), std_m), ("an2", "an1", None));
            values.push(range_difference_m);
        }
        assert_eq!(values, expected, "{}", run.name);
        let truth_rows = std::fs::read_to_string(dir.join("truth.csv")).unwrap().lines().count() - 1;
        assert_eq!(
            (truth_rows, run.truth_rows, run.records),
            (values.len(), values.len(), values.len())
        );
        // sign: tdoa12 ≈ ‖tag − an2‖ − ‖tag − an1‖, checked where the difference is large
        let (an1, an2, tag) = (
            pose(&pose_file, "an1_p"),
            pose(&pose_file, "an2_p"),
            pose(&pose_file, "tag_p"),
        );
        let d = |a: [f64; 3]| ((a[0] - tag[0]).powi(2) + (a[1] - tag[1]).powi(2) + (a[2] - tag[2]).powi(2)).sqrt();
        let truth = d(an2) - d(an1);
        values.sort_by(f64::total_cmp);
        let median = values[values.len() / 2];
        if run.name.starts_with("los-") {
            assert!((median - truth).abs() < 0.11, "{}: {median} vs {truth}", run.name);
        }
        if truth.abs() > 0.3 {
            assert!(
                (median + truth).abs() > 0.5,
                "{}: the opposite sign must not fit",
                run.name
            );
            sign_checked += 1;
        }
    }
    // distT1–T7 and T9–T12 have |d2 − d1| > 0.3 m
    assert!(sign_checked >= 10, "{sign_checked}");
    let first = runs.iter().find(|r| r.name == "los-distTest-distT1").unwrap();
    assert!(first.notes[0].contains("761 trailing rows"), "{}", first.notes[0]);
}

#[test]
fn malformed_files_name_file_line_and_field() {
    let temp = TempDir::new("tdoa", "bad");
    let dir = &temp.0;
    let data = dir.join("run_data.csv");
    std::fs::write(&data, "tdoa12,tdoa21\n-3.43,3.49\n-3.4x,3.5\n").unwrap();
    let error = read_tdoa(&data).unwrap_err().to_string();
    assert_eq!(
        error,
        format!("{}:3: field `tdoa12`: `-3.4x` is not a number", data.display())
    );
    std::fs::write(&data, "snr,tdoa21\n1,2\n").unwrap();
    let error = read_tdoa(&data).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:1: field `tdoa12`", data.display())),
        "{error}"
    );
    // an empty tdoa12 before the last value is counted, not an error
    std::fs::write(&data, "tdoa12,tdoa21\n1.0,2\n,3\n1.5,4\n,5\n,6\n").unwrap();
    let column = read_tdoa(&data).unwrap();
    assert_eq!(
        (column.samples, column.rows, column.trailing_empty, column.inner_empty),
        (vec![(0, 1.0), (2, 1.5)], 5, 2, vec![3])
    );

    let pose_file = dir.join("run_pose.txt");
    std::fs::write(&pose_file, "an1_p,1,2,3\nan2_p,4,5,6\ntag_p,7,x,9\n").unwrap();
    let error = read_poses(&pose_file).unwrap_err().to_string();
    assert_eq!(
        error,
        format!("{}:3: field `tag_p[1]`: `x` is not a number", pose_file.display())
    );
    std::fs::write(&pose_file, "an1_p,1,2,3\nan2_p,4,5\n").unwrap();
    let error = read_poses(&pose_file).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:2: field `an2_p[2]`", pose_file.display())),
        "{error}"
    );
    std::fs::write(&pose_file, "an1_p,1,2,3\nan2_p,4,5,6\n").unwrap();
    let error = read_poses(&pose_file).unwrap_err().to_string();
    assert!(error.contains("needs an1_p, an2_p and tag_p"), "{error}");
    // a whole-run import names the bad data file
    std::fs::write(&pose_file, "an1_p,0,0,0\nan2_p,4,0,0\ntag_p,1,1,0\n").unwrap();
    std::fs::write(&data, "tdoa12\n0.5\nnan?\n").unwrap();
    let error = import_run(dir, &data, &dir.join("out")).unwrap_err().to_string();
    assert!(
        error.starts_with(&format!("{}:3: field `tdoa12`", data.display())),
        "{error}"
    );
}

#[test]
fn run_names_come_from_the_directory() {
    let root = Path::new("/d/static-dataset");
    assert_eq!(
        run_name(root, &root.join("los/distTest/distT1/distT1_data.csv")),
        "los-distTest-distT1"
    );
    assert_eq!(
        run_name(root, &root.join("nlos/anTag/foam/data1/foam-anTag-data1_data.csv")),
        "nlos-anTag-foam-data1"
    );
}
