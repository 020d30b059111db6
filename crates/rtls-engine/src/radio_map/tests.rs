use super::csv_text::parse;
use super::*;

/// A site with readers A (0, 0), B (10, 0), C (0, 10) and, when `fingerprint_readers` is
/// given, a `[fingerprints]` section listing them.
fn site(fingerprint_readers: Option<&str>) -> Site {
    let fingerprints = fingerprint_readers
        .map(|readers| format!("[fingerprints]\npath = \"radio-map.csv\"\nformat = \"csv\"\nreaders = [{readers}]\n"))
        .unwrap_or_default();
    let text = format!(
        r#"
[[readers]]
id = "A"
position_m = [0.0, 0.0, 2.5]
technology = "ble"

[[readers]]
id = "B"
position_m = [10.0, 0.0]
technology = "ble"

[[readers]]
id = "C"
position_m = [0.0, 10.0]
technology = "ble"

{fingerprints}
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "kf"
acceleration_noise_std_mps2 = 1.0
gate_probability = 0.99
initiation = {{ confirm_updates = 1, within_s = 1.0 }}
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.5
"#
    );
    Site::from_toml_str(&text, "site.toml").unwrap()
}

fn reading(anchor: &str, rssi_dbm: f64) -> AnchorReading {
    AnchorReading {
        anchor: anchor.into(),
        rssi_dbm,
    }
}

fn parse_error(text: &str, site: &Site) -> (usize, String, String) {
    match RadioMap::from_csv_str(text, "map.csv", site) {
        Err(EngineError::Parse {
            file,
            line,
            field,
            reason,
        }) => {
            assert_eq!(file, "map.csv");
            (line, field, reason)
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn written_map_parses_back_exactly() {
    let readers: Vec<String> = ["A", "B", "C"].map(String::from).to_vec();
    let rows = vec![
        RadioMapRow {
            position_m: [0.1 + 0.2, -3.0],
            floor: Some(-1),
            rssi_dbm: vec![Some(-61.123456789012345), None, Some(-80.0)],
        },
        RadioMapRow {
            position_m: [1e-7, 12.75],
            floor: Some(2),
            rssi_dbm: vec![None, Some(-0.5), None],
        },
    ];
    let text = radio_map_csv(&readers, &rows).unwrap();
    assert!(text.starts_with("x_m,y_m,floor,A,B,C\n"));
    let parsed = parse(&text, "map.csv", &site(None)).unwrap();
    assert_eq!(parsed.reader_ids, readers);
    assert_eq!(parsed.positions_m, vec![rows[0].position_m, rows[1].position_m]);
    assert_eq!(parsed.floors, Some(vec![-1, 2]));
    assert_eq!(
        parsed.readings_dbm,
        vec![vec![(0, -61.123456789012345), (2, -80.0)], vec![(1, -0.5)]]
    );
    assert_eq!(parsed.lines, vec![2, 3]);
    // and through the public parser
    let map = RadioMap::from_csv_str(&text, "map.csv", &site(None)).unwrap();
    assert_eq!((map.reader_ids(), map.reference_point_count()), (&readers[..], 2));
    assert_eq!(map.neighbours(), RadioMap::DEFAULT_NEIGHBOURS);
    assert_eq!(map.signal_space(), SignalSpace::powed_sorensen());
}

#[test]
fn comments_blank_lines_and_no_floor_column() {
    let text = "# a radio map\n\n  # indented comment\nx_m, y_m, A, B\n0,0,-50,\n\n5,0,,-60\n";
    let parsed = parse(text, "map.csv", &site(None)).unwrap();
    assert_eq!(parsed.floors, None);
    assert_eq!(parsed.lines, vec![5, 7]);
    assert_eq!(parsed.readings_dbm, vec![vec![(0, -50.0)], vec![(1, -60.0)]]);
}

#[test]
fn header_must_match_the_sites_fingerprint_readers() {
    let site = site(Some(r#""A", "B", "C""#));
    let (line, field, reason) = parse_error("# map\nx_m,y_m,A,C,B\n0,0,-50,-60,-70\n", &site);
    assert_eq!((line, field.as_str()), (2, "C"));
    assert!(
        reason.contains("column 4") && reason.contains("readers[1] is `B`"),
        "{reason}"
    );

    let (line, field, reason) = parse_error("x_m,y_m,A,B\n0,0,-50,-60\n", &site);
    assert_eq!((line, field.as_str()), (1, "C"));
    assert!(reason.contains("ends after 2 reader columns"), "{reason}");

    let (_, field, reason) = parse_error("x_m,y_m,floor,A,B,C,D\n0,0,0,-50,-60,-70,-80\n", &site);
    assert_eq!(field, "D");
    assert!(
        reason.contains("column 7") && reason.contains("beyond the 3 readers"),
        "{reason}"
    );

    // the same order parses
    assert!(RadioMap::from_csv_str("x_m,y_m,A,B,C\n0,0,-50,,\n", "map.csv", &site).is_ok());
}

#[test]
fn header_errors_name_the_column() {
    let site = site(None);
    let (line, field, reason) = parse_error("x_m,y_m,A,Z\n0,0,-50,-60\n", &site);
    assert_eq!((line, field.as_str()), (1, "Z"));
    assert!(
        reason.contains("column 4") && reason.contains("not a reader of the site"),
        "{reason}"
    );

    let (_, field, reason) = parse_error("x_m,y_m,A,A\n0,0,-50,-60\n", &site);
    assert_eq!(field, "A");
    assert!(reason.contains("column 4") && reason.contains("twice"), "{reason}");

    let (_, field, reason) = parse_error("x,y_m,A\n0,0,-50\n", &site);
    assert_eq!(field, "x");
    assert!(reason.contains("expected `x_m`"), "{reason}");

    let (_, field, reason) = parse_error("x_m,y_m,A,,B\n0,0,-50,,-60\n", &site);
    assert_eq!(field, "-");
    assert!(reason.contains("column 4 is empty"), "{reason}");

    let (_, _, reason) = parse_error("x_m,y_m,floor\n0,0,1\n", &site);
    assert!(reason.contains("no reader columns"), "{reason}");

    let (line, _, reason) = parse_error("# nothing\n", &site);
    assert_eq!(line, 0);
    assert!(reason.contains("no header"), "{reason}");

    let (line, _, reason) = parse_error("x_m,y_m,A\n", &site);
    assert_eq!(line, 1);
    assert!(reason.contains("no reference points"), "{reason}");
}

#[test]
fn bad_cells_name_line_and_column() {
    let site = site(None);
    let text = "# comment\nx_m,y_m,floor,A,B\n0,0,1,-50,-60\n1,0,1,-50,-6x\n";
    let (line, field, reason) = parse_error(text, &site);
    assert_eq!((line, field.as_str()), (4, "B"));
    assert!(reason.contains("`-6x` is not a finite number"), "{reason}");

    let (line, field, _) = parse_error("x_m,y_m,A\n0,0,-50\n\nNaN,0,-50\n", &site);
    assert_eq!((line, field.as_str()), (4, "x_m"));

    let (line, field, reason) = parse_error("x_m,y_m,floor,A\n0,0,1.5,-50\n", &site);
    assert_eq!((line, field.as_str()), (2, "floor"));
    assert!(reason.contains("integer"), "{reason}");

    let (line, field, reason) = parse_error("x_m,y_m,A,B\n0,0,-50\n", &site);
    assert_eq!((line, field.as_str()), (2, "-"));
    assert!(reason.contains("3 cells") && reason.contains("4 columns"), "{reason}");

    let (line, _, reason) = parse_error("x_m,y_m,A,B\n0,0,-50,-60\n3,3,,\n", &site);
    assert_eq!(line, 3);
    assert!(reason.contains("no reader is heard"), "{reason}");

    // below the powed representation's floor (−104 dBm)
    let (line, field, reason) = parse_error("x_m,y_m,A,B\n0,0,-50,-60\n3,3,-50,-110\n", &site);
    assert_eq!((line, field.as_str()), (3, "B"));
    assert!(reason.contains("below the signal space's floor"), "{reason}");
}

#[test]
fn writer_rejects_what_the_parser_would() {
    let readers: Vec<String> = ["A", "B"].map(String::from).to_vec();
    let row = |floor, rssi_dbm: Vec<Option<f64>>| RadioMapRow {
        position_m: [0.0, 0.0],
        floor,
        rssi_dbm,
    };
    let field_of = |error: EngineError| match error {
        EngineError::Parse { line, field, .. } => (line, field),
        other => panic!("{other:?}"),
    };
    let mixed = [
        row(Some(0), vec![Some(-50.0), None]),
        row(None, vec![Some(-50.0), None]),
    ];
    assert_eq!(
        field_of(radio_map_csv(&readers, &mixed).unwrap_err()),
        (3, "floor".into())
    );
    let short = [row(None, vec![Some(-50.0)])];
    assert_eq!(
        field_of(radio_map_csv(&readers, &short).unwrap_err()),
        (2, "rssi_dbm".into())
    );
    let silent = [row(None, vec![None, None])];
    assert_eq!(
        field_of(radio_map_csv(&readers, &silent).unwrap_err()),
        (2, "rssi_dbm".into())
    );
    let nan = [row(None, vec![None, Some(f64::NAN)])];
    assert_eq!(field_of(radio_map_csv(&readers, &nan).unwrap_err()), (2, "B".into()));
    let bad_id = vec!["A".to_string(), "B,C".to_string()];
    let good = [row(None, vec![Some(-50.0), None])];
    assert_eq!(field_of(radio_map_csv(&bad_id, &good).unwrap_err()), (1, "B,C".into()));
    assert!(radio_map_csv(&["floor".to_string()], &[row(None, vec![Some(-50.0)])]).is_err());
    assert!(radio_map_csv(&readers, &[]).is_err());
}

/// Torres-Sospedra's powed representation, `ψ = ((ρ + 104)/104)^e`.
fn powed(rssi_dbm: Option<f64>) -> f64 {
    rssi_dbm.map_or(0.0, |r| ((r + 104.0) / 104.0).powf(std::f64::consts::E))
}

/// Sørensen distance `Σ|a − b| / Σ(a + b)` of two dBm vectors.
fn sorensen(a: &[Option<f64>], b: &[Option<f64>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        num += (powed(x) - powed(y)).abs();
        den += powed(x) + powed(y);
    }
    num / den
}

#[test]
fn locate_matches_a_hand_computed_wknn() {
    // a 2 m grid of 6 reference points; the query is between the first three
    let points = [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [0.0, 2.0], [2.0, 2.0], [4.0, 2.0]];
    let fingerprints: [[Option<f64>; 3]; 6] = [
        [Some(-45.0), Some(-75.0), Some(-70.0)],
        [Some(-55.0), Some(-65.0), Some(-74.0)],
        [Some(-62.0), Some(-58.0), None],
        [Some(-50.0), Some(-78.0), Some(-60.0)],
        [Some(-57.0), Some(-70.0), Some(-64.0)],
        [Some(-66.0), Some(-61.0), Some(-69.0)],
    ];
    let readers: Vec<String> = ["A", "B", "C"].map(String::from).to_vec();
    let rows: Vec<RadioMapRow> = points
        .iter()
        .zip(&fingerprints)
        .map(|(p, f)| RadioMapRow {
            position_m: *p,
            floor: None,
            rssi_dbm: f.to_vec(),
        })
        .collect();
    let text = radio_map_csv(&readers, &rows).unwrap();
    let map = RadioMap::from_csv_str(&text, "map.csv", &site(None))
        .unwrap()
        .with_neighbours(3)
        .unwrap();
    let query = [Some(-52.0), Some(-68.0), Some(-73.0)];
    let scan = [reading("A", -52.0), reading("B", -68.0), reading("C", -73.0)];
    let fix = map.locate(&scan).unwrap();

    // by hand: the 3 smallest Sørensen distances, w ∝ 1/D, x̂ = Σ w P, spread + σ² I
    let mut by_distance: Vec<(f64, [f64; 2])> = fingerprints
        .iter()
        .zip(&points)
        .map(|(f, p)| (sorensen(&query, f), *p))
        .collect();
    by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
    let nearest = &by_distance[..3];
    let total: f64 = nearest.iter().map(|(d, _)| 1.0 / d).sum();
    let mut x = [0.0; 2];
    for (d, p) in nearest {
        x[0] += p[0] / d / total;
        x[1] += p[1] / d / total;
    }
    let mut spread = [[0.0; 2]; 2];
    for (d, p) in nearest {
        let w = 1.0 / d / total;
        let e = [p[0] - x[0], p[1] - x[1]];
        for (row, e_r) in spread.iter_mut().zip(e) {
            for (cell, e_c) in row.iter_mut().zip(e) {
                *cell += w * e_r * e_c;
            }
        }
    }
    // the floor: leave-one-out calibrated, never below s²/12 (grid spacing 2 m)
    let floor_m2 = map.min_std_m().powi(2);
    assert!((map.spacing_std_m() - (2.0 * 2.0 / 12.0_f64).sqrt()).abs() < 1e-15);
    let calibration = map.calibration().unwrap();
    assert_eq!((calibration.queried, calibration.located), (6, 6));
    assert_eq!(map.min_std_m(), calibration.fitted_std_m.max(map.spacing_std_m()));
    assert!((fix.position_m[0] - x[0]).abs() < 1e-12 && (fix.position_m[1] - x[1]).abs() < 1e-12);
    for (r, (fix_row, spread_row)) in fix.covariance_m2.iter().zip(&spread).enumerate() {
        for (c, (got, spread)) in fix_row.iter().zip(spread_row).enumerate() {
            let expected = spread + if r == c { floor_m2 } else { 0.0 };
            assert!((got - expected).abs() < 1e-12, "({r},{c})");
        }
    }
    assert_eq!((fix.floor, fix.unused_readings, fix.below_floor_readings), (None, 0, 0));
    // the query is nearest the point (2, 0) in signal space: the fix lies left of x = 3
    assert!(
        fix.position_m[0] < 3.0 && fix.position_m[1] < 1.0,
        "{:?}",
        fix.position_m
    );
}

#[test]
fn exact_match_has_the_floor_covariance_and_is_positive_definite() {
    let text = "x_m,y_m,A,B\n0,0,-40,-80\n0.5,0,-60,-60\n1,0,-80,-40\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None)).unwrap();
    let fix = map.locate(&[reading("A", -60.0), reading("B", -60.0)]).unwrap();
    assert_eq!(fix.position_m, [0.5, 0.0]);
    // three distinct positions: the floor is calibrated, never below s²/12 (s = 0.5 m)
    let floor_m2 = map.min_std_m().powi(2);
    assert!(floor_m2 >= 0.5 * 0.5 / 12.0);
    assert!(map.calibration().is_some());
    assert!((fix.covariance_m2[0][0] - floor_m2).abs() < 1e-15);
    assert!((fix.covariance_m2[1][1] - floor_m2).abs() < 1e-15);
    assert_eq!(fix.covariance_m2[0][1], 0.0);
    let map = map.with_min_std_m(2.0).unwrap();
    let fix = map.locate(&[reading("A", -60.0), reading("B", -60.0)]).unwrap();
    assert_eq!(fix.covariance_m2, [[4.0, 0.0], [0.0, 4.0]]);
    assert!(map.clone().with_min_std_m(0.0).is_err());
    assert!(map.with_neighbours(0).is_err());
}

#[test]
fn unused_and_below_floor_readings_are_counted() {
    let text = "x_m,y_m,A,B\n0,0,-40,-80\n10,0,-80,-40\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None))
        .unwrap()
        .with_neighbours(1)
        .unwrap();
    // C is a site reader but not a map column; "ghost" is not even in the site
    let scan = [
        reading("C", -50.0),
        reading("B", -41.0),
        reading("ghost", -70.0),
        reading("A", -120.0),
    ];
    let fix = map.locate(&scan).unwrap();
    assert_eq!(fix.position_m, [10.0, 0.0]);
    assert_eq!((fix.unused_readings, fix.below_floor_readings), (2, 1));

    // nothing usable: an error, not a fix
    let none = map.locate(&[reading("C", -50.0), reading("A", -110.0)]);
    assert!(matches!(
        none,
        Err(EngineError::Positioning(PositioningError::NoCommonAnchors))
    ));
    assert!(matches!(map.locate(&[]), Err(EngineError::Positioning(_))));
    // a reader twice, or a NaN, is an error
    let twice = map.locate(&[reading("A", -50.0), reading("A", -51.0)]);
    assert!(matches!(
        twice,
        Err(EngineError::InvalidParameter { name: "readings", .. })
    ));
    let twice_below = map.locate(&[reading("A", -50.0), reading("A", -150.0)]);
    assert!(matches!(twice_below, Err(EngineError::InvalidParameter { .. })));
    assert!(map.locate(&[reading("A", f64::NAN)]).is_err());
}

#[test]
fn floors_are_voted_and_only_the_voted_floor_is_averaged() {
    // the same two places on floors 0 and 1; readers heard differently per floor
    let text = "x_m,y_m,floor,A,B,C\n0,0,0,-40,-70,\n4,0,0,-70,-40,\n0,0,1,,-90,-45\n4,0,1,-95,,-50\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None))
        .unwrap()
        .with_neighbours(3)
        .unwrap();
    let fix = map.locate(&[reading("C", -47.0), reading("B", -91.0)]).unwrap();
    assert_eq!(fix.floor, Some(1));
    // only the two floor-1 points are averaged, so x lies between them with y = 0
    assert!(fix.position_m[0] > 0.0 && fix.position_m[0] < 4.0);
    assert_eq!(fix.position_m[1], 0.0);
    // distinct positions are (0, 0) and (4, 0): s = 4 m
    assert!((map.min_std_m() - (16.0_f64 / 12.0).sqrt()).abs() < 1e-15);
}

#[test]
fn another_signal_space_reindexes_and_checks_its_floor() {
    let text = "x_m,y_m,A,B\n0,0,-40,-100\n10,0,-100,-40\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None)).unwrap();
    let euclidean = map.clone().with_signal_space(SignalSpace::default()).unwrap();
    assert_eq!(euclidean.signal_space(), SignalSpace::default());
    let tight = rtls_positioning::fingerprint::SignalSpace {
        representation: rtls_positioning::fingerprint::SignalRepresentation::Positive { floor_dbm: -90.0 },
        distance: rtls_positioning::fingerprint::SignalDistance::Euclidean,
    };
    match map.with_signal_space(tight) {
        Err(EngineError::Parse { line, field, .. }) => assert_eq!((line, field.as_str()), (2, "B")),
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_example_and_errors_of_docs_formats_parse_as_quoted() {
    let formats = include_str!("../../../../docs/FORMATS.md");
    let section = formats
        .split("\n## ")
        .find(|section| section.starts_with("Radio map (fingerprint database) CSV"))
        .expect("docs/FORMATS.md has the section");
    let start = section.find("```text\n").unwrap() + "```text\n".len();
    let example = &section[start..start + section[start..].find("```").unwrap()];
    let mut text = String::from("[tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n");
    text.push_str("acceleration_noise_std_mps2 = 1.0\ngate_probability = 0.99\n");
    text.push_str("initiation = { confirm_updates = 1, within_s = 1.0 }\ncoast_timeout_s = 5.0\n");
    text.push_str("delete_timeout_s = 60.0\nreorder_window_s = 0.5\n");
    text.push_str(
        "[fingerprints]\npath = \"radio-map.csv\"\nformat = \"csv\"\nreaders = [\"AP-1\", \"AP-2\", \"AP-3\"]\n",
    );
    for (k, id) in ["AP-1", "AP-2", "AP-3"].iter().enumerate() {
        text.push_str(&format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{}.0, 0.0]\ntechnology = \"wifi\"\n",
            5 * k
        ));
    }
    let site = Site::from_toml_str(&text, "site.toml").unwrap();
    let map = RadioMap::from_csv_str(example, "radio-map.csv", &site).unwrap();
    assert_eq!(map.reference_point_count(), 3);
    let fix = map.locate(&[reading("AP-2", -71.0), reading("AP-3", -58.75)]).unwrap();
    assert_eq!(fix.floor, Some(1));

    // the error messages quoted there
    let bad_cell = example.replace("0.75,0.25,0,-63,-90.25,", "0.75,0.25,0,-63,-6x,");
    let error = RadioMap::from_csv_str(&bad_cell, "radio-map.csv", &site).unwrap_err();
    assert!(section.contains(&format!("``{error}``")), "{error}");
    let swapped = example.replace("AP-1,AP-2,AP-3", "AP-1,AP-3,AP-2");
    let error = RadioMap::from_csv_str(&swapped, "radio-map.csv", &site)
        .unwrap_err()
        .to_string();
    let quoted: String = error.split(';').next().unwrap().to_string();
    let flowed = section.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(flowed.contains(&format!("``{quoted}; …``")), "{error}");
}

/// A site with readers A (0, 0), B (10, 0), C (0, 10) and the given `[fingerprints]` lines.
fn site_with_fingerprints(lines: &str) -> Site {
    let text = format!(
        "[[readers]]\nid = \"A\"\nposition_m = [0.0, 0.0]\ntechnology = \"ble\"\n\
         [[readers]]\nid = \"B\"\nposition_m = [10.0, 0.0]\ntechnology = \"ble\"\n\
         [[readers]]\nid = \"C\"\nposition_m = [0.0, 10.0]\ntechnology = \"ble\"\n\
         [fingerprints]\npath = \"radio-map.csv\"\nformat = \"csv\"\n{lines}\n\
         [tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n\
         acceleration_noise_std_mps2 = 1.0\ngate_probability = 0.99\n\
         initiation = {{ confirm_updates = 1, within_s = 1.0 }}\ncoast_timeout_s = 5.0\n\
         delete_timeout_s = 60.0\nreorder_window_s = 0.5\n"
    );
    Site::from_toml_str(&text, "site.toml").unwrap()
}

/// One BLE scan at `p` from readers A, B, C: `ρ = −59 − 22 lg(max(d, 1 m))` dBm plus
/// independent shadowing.
fn ble_scan(p: [f64; 2], shadowing: &rand_distr::Normal<f64>, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
    use rand_distr::Distribution;
    [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]
        .iter()
        .map(|a: &[f64; 2]| -59.0 - 22.0 * (p[0] - a[0]).hypot(p[1] - a[1]).max(1.0).log10() + shadowing.sample(rng))
        .collect()
}

#[test]
fn a_dense_map_reports_an_honest_covariance() {
    use rand::{Rng, SeedableRng};
    // issue 17: a dense map (0.5 m grid, one 3 dB-shadowed scan per point) and WKNN's spread
    // plus s²/12 gave σ ≈ 0.2 m against metres of error
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let shadowing = rand_distr::Normal::new(0.0, 3.0).unwrap();
    let readers: Vec<String> = ["A", "B", "C"].map(String::from).to_vec();
    let rows: Vec<RadioMapRow> = (0..21 * 21)
        .map(|k| {
            let p = [0.5 * (k % 21) as f64, 0.5 * (k / 21) as f64];
            RadioMapRow {
                position_m: p,
                floor: None,
                rssi_dbm: ble_scan(p, &shadowing, &mut rng).into_iter().map(Some).collect(),
            }
        })
        .collect();
    let text = radio_map_csv(&readers, &rows).unwrap();
    let map = RadioMap::from_csv_str(&text, "map.csv", &site(None)).unwrap();
    let calibration = *map.calibration().unwrap();
    assert_eq!((calibration.queried, calibration.located), (441, 441));
    assert_eq!(map.loo_queries(), 441);
    assert!((map.spacing_std_m() - (0.25_f64 / 12.0).sqrt()).abs() < 1e-12);
    assert!(map.min_std_m() > 5.0 * map.spacing_std_m(), "{calibration:?}");
    assert_eq!(map.loo_rmse_m(), Some(calibration.rmse_m));

    // independent scans at random points: NEES with the reported covariance, and with the old
    // one (spread + s²/12)
    let old_shift = map.spacing_std_m().powi(2) - map.min_std_m().powi(2);
    let nees = |e: [f64; 2], p: [[f64; 2]; 2]| {
        let det = p[0][0] * p[1][1] - p[0][1] * p[1][0];
        (e[0] * e[0] * p[1][1] - 2.0 * e[0] * e[1] * p[0][1] + e[1] * e[1] * p[0][0]) / det
    };
    let (mut new, mut old, mut inside, mut squares) = (0.0, 0.0, 0_u32, 0.0);
    let count = 300;
    for _ in 0..count {
        let truth = [rng.gen_range(0.0..10.0), rng.gen_range(0.0..10.0)];
        let scan: Vec<AnchorReading> = ["A", "B", "C"]
            .iter()
            .zip(ble_scan(truth, &shadowing, &mut rng))
            .map(|(id, rssi)| reading(id, rssi))
            .collect();
        let fix = map.locate(&scan).unwrap();
        let e = [fix.position_m[0] - truth[0], fix.position_m[1] - truth[1]];
        let p = fix.covariance_m2;
        let q = nees(e, p);
        new += q;
        inside += u32::from(q <= 5.991);
        old += nees(e, [[p[0][0] + old_shift, p[0][1]], [p[1][0], p[1][1] + old_shift]]);
        squares += e[0] * e[0] + e[1] * e[1];
    }
    let n = f64::from(count);
    let (new, old, inside, rmse) = (new / n, old / n, f64::from(inside) / n, (squares / n).sqrt());
    assert!((1.3..3.0).contains(&new), "NEES {new}, {calibration:?}, RMSE {rmse}");
    assert!((0.88..0.99).contains(&inside), "{inside}");
    assert!(old > 10.0, "old NEES {old}");
}

#[test]
fn repeated_rows_at_one_position_do_not_leak_into_the_calibration() {
    // 3 × 3 places 2 m apart, each surveyed five times with almost the same fingerprint: a
    // leave-one-out that kept the copies would find the place itself (error ~0, floor s²/12)
    let mut text = String::from("x_m,y_m,A,B,C\n");
    for k in 0..9 {
        let p = [2.0 * (k % 3) as f64, 2.0 * (k / 3) as f64];
        for copy in 0..5 {
            let rssi: Vec<String> = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]
                .iter()
                .map(|a: &[f64; 2]| {
                    let d = (p[0] - a[0]).hypot(p[1] - a[1]).max(1.0);
                    format!("{}", -59.0 - 22.0 * d.log10() + 0.1 * f64::from(copy))
                })
                .collect();
            text.push_str(&format!("{},{},{}\n", p[0], p[1], rssi.join(",")));
        }
    }
    let map = RadioMap::from_csv_str(&text, "map.csv", &site(None)).unwrap();
    let calibration = map.calibration().unwrap();
    assert_eq!((calibration.queried, calibration.located), (45, 45));
    // every place is located from its neighbours, ≥ 2 m / k away; never from its copies
    assert!(calibration.rmse_m > 0.5, "{calibration:?}");
    assert!(map.min_std_m() > map.spacing_std_m(), "{calibration:?}");
}

#[test]
fn a_tiny_map_falls_back_to_the_spacing_floor() {
    // two distinct positions (several rows and floors): no calibration, s²/12 with s = 4 m
    let text = "x_m,y_m,floor,A,B\n0,0,0,-40,-70\n0,0,0,-41,-69\n4,0,0,-70,-40\n0,0,1,-50,-60\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None)).unwrap();
    assert!(map.calibration().is_none());
    assert_eq!(map.loo_rmse_m(), None);
    assert!((map.min_std_m() - (16.0_f64 / 12.0).sqrt()).abs() < 1e-15);
    assert!(map.locate(&[reading("A", -45.0)]).is_ok());
    // one row: the 1 m fallback
    let map = RadioMap::from_csv_str("x_m,y_m,A\n3,3,-50\n", "map.csv", &site(None)).unwrap();
    assert_eq!((map.min_std_m(), map.calibration()), (1.0, None));
    let fix = map.locate(&[reading("A", -45.0)]).unwrap();
    assert_eq!(fix.covariance_m2, [[1.0, 0.0], [0.0, 1.0]]);
}

#[test]
fn the_site_min_std_m_overrides_the_calibrated_floor() {
    let text = "x_m,y_m,A,B,C\n0,0,-40,-80,-60\n5,0,-60,-60,-70\n10,0,-80,-40,-75\n0,5,-50,-70,-45\n";
    let calibrated = RadioMap::from_csv_str(text, "map.csv", &site_with_fingerprints("")).unwrap();
    let set = RadioMap::from_csv_str(text, "map.csv", &site_with_fingerprints("min_std_m = 7.5")).unwrap();
    assert_eq!(set.min_std_m(), 7.5);
    // the calibration is still reported, and survives a change of k
    assert_eq!(set.calibration(), calibrated.calibration());
    let set = set.with_neighbours(1).unwrap();
    assert_eq!(set.min_std_m(), 7.5);
    assert_ne!(set.calibration(), calibrated.calibration());
    let fix = set
        .locate(&[reading("A", -40.0), reading("B", -80.0), reading("C", -60.0)])
        .unwrap();
    assert_eq!(fix.covariance_m2, [[56.25, 0.0], [0.0, 56.25]]);
}

#[test]
fn absurd_coordinates_load_without_a_nan() {
    // leave-one-out spreads near 1e240 m² overflow the NEES: no calibration, the spacing floor
    let text = "x_m,y_m,A,B\n0,0,-40,-80\n1e120,0,-60,-60\n-1e120,0,-80,-40\n5,5,-50,-50\n0,1e120,-70,-70\n";
    let map = RadioMap::from_csv_str(text, "map.csv", &site(None)).unwrap();
    assert!(map.min_std_m().is_finite() && map.min_std_m() > 0.0);
    if let Some(calibration) = map.calibration() {
        assert!(calibration.rmse_m.is_finite() && calibration.mean_nees.is_finite());
    }
    let fix = map.locate(&[reading("A", -41.0), reading("B", -79.0)]).unwrap();
    assert!(fix.covariance_m2.iter().flatten().all(|v| v.is_finite()));
}
