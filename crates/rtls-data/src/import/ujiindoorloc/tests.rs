use rtls_engine::radio_map::RadioMap;
use rtls_engine::record::Measurement;
use rtls_engine::site::Site;

use super::*;
use crate::import::test_support::{read_records, TempDir};

fn fingerprint(
    readings_dbm: Vec<(usize, f64)>,
    position_m: [f64; 2],
    floor: i32,
    phone_id: u32,
    timestamp_s: i64,
) -> Fingerprint {
    Fingerprint {
        readings_dbm,
        position_m,
        floor,
        building: 0,
        space_id: 7,
        relative_position: 1,
        user_id: 0,
        phone_id,
        timestamp_s,
    }
}

#[test]
fn converts_a_small_survey() {
    // two records at one location (averaged), one at another; AP 2 and AP 9 are never heard
    let training = vec![
        fingerprint(vec![(0, -50.0), (1, -70.0)], [-7600.4, 4864800.9], 1, 1, 0),
        fingerprint(vec![(0, -60.0)], [-7600.4, 4864800.9], 1, 1, 1),
        fingerprint(vec![(1, -40.0), (3, -80.0)], [-7590.2, 4864790.5], 2, 1, 2),
    ];
    let validation = vec![
        fingerprint(
            vec![(0, -55.0), (2, -90.0), (9, -91.0)],
            [-7595.0, 4864795.0],
            1,
            13,
            500,
        ),
        fingerprint(vec![(3, -75.0)], [-7591.0, 4864791.0], 2, 13, 500),
        fingerprint(vec![(1, -45.0)], [-7592.0, 4864792.0], 2, 4, 100),
        fingerprint(vec![(9, -60.0)], [-7592.0, 4864792.0], 2, 4, 101),
        fingerprint(vec![(0, -65.0)], [-7599.0, 4864799.0], 1, 13, 500),
    ];
    let c = convert(&training, &validation).unwrap();
    // origin = floor of the training minima
    assert_eq!(c.origin_m, [-7601.0, 4864790.0]);
    assert_eq!(c.reader_ids, vec!["WAP001", "WAP002", "WAP004"]);
    // AP 3 is heard by one reference point only: its estimate is that point, in the local frame
    let [x, y] = c.reader_positions_m[2];
    assert!((x - 10.8).abs() < 1e-9 && (y - 0.5).abs() < 1e-9, "{x} {y}");
    // the first location averages its two records; AP 1 was heard by one of them only
    assert_eq!(c.map.len(), 2);
    assert_eq!(c.map[0].floor, Some(1));
    assert_eq!(c.map[0].rssi_dbm, vec![Some(-55.0), Some(-70.0), None]);
    assert!((c.map[0].position_m[0] - 0.6).abs() < 1e-9 && (c.map[0].position_m[1] - 10.9).abs() < 1e-6);
    assert_eq!(c.map[1].rssi_dbm, vec![None, Some(-40.0), Some(-80.0)]);

    // validation: the row hearing only AP 9 is skipped and counted; phone 13's three rows at
    // t = 500 are kept 1 ms apart, in file order; records in time order
    let times: Vec<(String, f64)> = c.records.iter().map(|r| (r.tag.clone(), r.time_s)).collect();
    assert_eq!(
        times,
        vec![
            ("phone-4".to_string(), 100.0),
            ("phone-13".to_string(), 500.0),
            ("phone-13".to_string(), 500.001),
            ("phone-13".to_string(), 500.002),
        ]
    );
    let Measurement::RssiVector { readings } = &c.records[1].measurement else {
        panic!("{:?}", c.records[1]);
    };
    assert_eq!(readings.len(), 1);
    assert_eq!((readings[0].anchor.as_str(), readings[0].rssi_dbm), ("WAP001", -55.0));
    assert_eq!(c.truth.len(), 4);
    assert_eq!((c.truth[3].time_s, c.truth[3].tag.as_str()), (500.002, "phone-13"));
    assert!((c.truth[3].position_m[0] - 2.0).abs() < 1e-9 && (c.truth[3].position_m[1] - 9.0).abs() < 1e-6);
    let notes = c.notes.join("\n");
    assert!(
        notes.contains("3 readings of access points never heard in training were removed"),
        "{notes}"
    );
    assert!(notes.contains("1 validation rows were skipped"), "{notes}");
    assert!(
        notes.contains("2 validation rows repeat a phone's TIMESTAMP"),
        "{notes}"
    );
}

#[test]
fn real_dataset_imports_and_wknn_on_the_radio_map_matches_the_documented_error() {
    let dataset = crate::data_dir().join("ujiindoorloc");
    if !dataset.join("UJIndoorLoc/trainingData.csv").exists() {
        println!("skipped: {} not found", dataset.display());
        return;
    }
    let temp = TempDir::new("uji", "real");
    let out = &temp.0;
    let runs = import(&dataset, out).unwrap();
    assert_eq!(runs.len(), 1);
    let run = &runs[0];
    let dir = out.join("validation");
    assert_eq!(
        (run.name.as_str(), run.records, run.truth_rows),
        ("validation", 1111, 1111)
    );
    let notes = run.notes.join("\n");
    // counted with numpy from the CSV files: 465 access points heard in training, 982 validation
    // readings of the other 55, 7 repeated (phone, TIMESTAMP) rows, 933 locations
    assert!(notes.contains("465 of 520 access points"), "{notes}");
    assert!(notes.contains("982 readings"), "{notes}");
    assert!(notes.contains("7 validation rows repeat"), "{notes}");
    assert!(notes.contains("into 933 reference locations"), "{notes}");
    assert!(
        notes.contains("x = LONGITUDE - (-7692), y = LATITUDE - 4864745"),
        "{notes}"
    );

    let records = read_records(&dir.join("measurements.jsonl"));
    assert_eq!(records.len(), 1111);
    assert!(records.windows(2).all(|w| w[0].time_s <= w[1].time_s));
    let truth_text = std::fs::read_to_string(dir.join("truth.csv")).unwrap();
    let truth: Vec<(f64, String, [f64; 2], String)> = truth_text
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (
                c[0].parse().unwrap(),
                c[1].to_string(),
                [c[2].parse().unwrap(), c[3].parse().unwrap()],
                c[4].to_string(),
            )
        })
        .collect();
    assert_eq!(truth.len(), 1111);
    for (record, (t, tag, _, z)) in records.iter().zip(&truth) {
        assert_eq!((record.time_s, &record.tag), (*t, tag));
        assert!(z.is_empty(), "2-D truth");
    }

    let site_text = std::fs::read_to_string(dir.join("site.toml")).unwrap();
    let site = Site::from_toml_str(&site_text, "site.toml").unwrap();
    assert_eq!(site.readers.len(), 465);
    assert!(site.readers.iter().all(|r| r.position_m.len() == 2));
    let map_text = std::fs::read_to_string(dir.join("radio-map.csv")).unwrap();
    let map = RadioMap::from_csv_str(&map_text, "radio-map.csv", &site).unwrap();
    assert_eq!(map.reference_point_count(), 933);
    assert_eq!(map.reader_ids().len(), 465);

    let mut errors_m = Vec::with_capacity(records.len());
    for (record, (_, _, position, _)) in records.iter().zip(&truth) {
        let Measurement::RssiVector { readings } = &record.measurement else {
            panic!("{record:?}");
        };
        let fix = map.locate(readings).unwrap();
        // the scans only hold readers of the map
        assert_eq!((fix.unused_readings, fix.below_floor_readings), (0, 0));
        errors_m.push((fix.position_m[0] - position[0]).hypot(fix.position_m[1] - position[1]));
    }
    let mean_m = errors_m.iter().sum::<f64>() / errors_m.len() as f64;
    println!(
        "WKNN (k = {}) on the averaged radio map: mean 2-D error {mean_m:.3} m",
        map.neighbours()
    );
    // docs/FINGERPRINTING.md: WKNN on the individual training records 6.47 m; on the records
    // averaged per location (933 reference points, this map) 7.8–8.3 m (its numpy prototype).
    // The averaged map must land in that range, give or take 0.3 m for the prototype's unstated
    // details (averaging of partly heard access points, k); a wrong frame or averaging is off by
    // metres.
    assert!((7.5..=8.6).contains(&mean_m), "{mean_m}");
}
