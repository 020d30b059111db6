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

    // by hand: the 3 smallest Sørensen distances, w ∝ 1/D, x̂ = Σ w P, spread + s²/12
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
    let floor_m2 = 2.0 * 2.0 / 12.0; // grid spacing 2 m
    assert!((fix.position_m[0] - x[0]).abs() < 1e-12 && (fix.position_m[1] - x[1]).abs() < 1e-12);
    for (r, (fix_row, spread_row)) in fix.covariance_m2.iter().zip(&spread).enumerate() {
        for (c, (got, spread)) in fix_row.iter().zip(spread_row).enumerate() {
            let expected = spread + if r == c { floor_m2 } else { 0.0 };
            assert!((got - expected).abs() < 1e-12, "({r},{c})");
        }
    }
    assert!((map.min_std_m() - (floor_m2).sqrt()).abs() < 1e-15);
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
    let floor_m2 = 0.5 * 0.5 / 12.0;
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
