//! Validation rules, round trips through both formats, and the examples in `docs/FORMATS.md`.

use super::*;

const FORMATS: &str = include_str!("../../../../docs/FORMATS.md");

/// `(file, line, field)` of a parse error.
pub(super) fn located(error: &EngineError) -> (&str, usize, &str) {
    match error {
        EngineError::Parse { file, line, field, .. } => (file, *line, field),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

fn record(measurement: Measurement) -> Record {
    Record {
        time_s: 1.0,
        tag: "tag-1".into(),
        measurement,
    }
}

/// The field named by validating a measurement that must be rejected.
fn rejected_field(measurement: Measurement) -> String {
    let error = record(measurement).validate("f.jsonl", 3).unwrap_err();
    let (file, line, field) = located(&error);
    assert_eq!((file, line), ("f.jsonl", 3));
    field.to_string()
}

fn range(range_m: f64, std_m: Option<f64>) -> Measurement {
    Measurement::Range {
        anchor: "R1".into(),
        range_m,
        std_m,
        anchor_position_m: None,
    }
}

fn fix(position_m: &[f64], covariance_m2: &[f64]) -> Measurement {
    Measurement::Fix {
        position_m: position_m.to_vec(),
        covariance_m2: covariance_m2.to_vec(),
    }
}

fn reading(anchor: &str, rssi_dbm: f64) -> AnchorReading {
    AnchorReading {
        anchor: anchor.into(),
        rssi_dbm,
    }
}

#[test]
fn valid_records_of_every_kind_pass() {
    for measurement in sample_measurements() {
        record(measurement).validate("f", 1).unwrap();
    }
}

#[test]
fn time_and_tag_are_checked() {
    let mut bad = record(range(1.0, None));
    bad.time_s = f64::NAN;
    assert_eq!(located(&bad.validate("f", 1).unwrap_err()).2, "t");
    for tag in ["", " lead", "trail ", "a;b", "a=b", "tab\there"] {
        let bad = Record {
            tag: tag.into(),
            ..record(range(1.0, None))
        };
        assert_eq!(located(&bad.validate("f", 1).unwrap_err()).2, "tag", "tag {tag:?}");
    }
    let inner_space = Record {
        tag: "miner 17".into(),
        ..record(range(1.0, None))
    };
    assert!(inner_space.validate("f", 1).is_ok());
}

#[test]
fn ranges_are_finite_and_stds_non_negative() {
    // negative ranges (Wi-Fi FTM/RTT, close devices) are accepted
    assert!(record(range(-0.1, None)).validate("f", 1).is_ok());
    assert_eq!(rejected_field(range(f64::NAN, None)), "range_m");
    assert_eq!(rejected_field(range(f64::INFINITY, None)), "range_m");
    assert_eq!(rejected_field(range(1.0, Some(-1.0))), "std_m");
    assert!(record(range(0.0, Some(0.0))).validate("f", 1).is_ok());
    assert_eq!(
        rejected_field(Measurement::Rssi {
            anchor: "R1".into(),
            rssi_dbm: f64::NAN
        }),
        "rssi_dbm"
    );
    assert_eq!(
        rejected_field(Measurement::Rssi {
            anchor: String::new(),
            rssi_dbm: -50.0
        }),
        "anchor"
    );
    let odometry = |speed_mps, heading_rad, speed_std_mps, heading_std_rad| Measurement::Odometry {
        speed_mps,
        heading_rad: Some(heading_rad),
        speed_std_mps,
        heading_std_rad,
    };
    assert_eq!(rejected_field(odometry(-1.0, 0.0, None, None)), "speed_mps");
    assert_eq!(rejected_field(odometry(1.0, f64::NAN, None, None)), "heading_rad");
    assert_eq!(rejected_field(odometry(1.0, 0.0, Some(-0.1), None)), "speed_std_mps");
    assert_eq!(
        rejected_field(odometry(1.0, 0.0, None, Some(f64::NAN))),
        "heading_std_rad"
    );
    let accelerometer = Measurement::Accelerometer {
        acceleration_mps2: vec![0.0, 0.0],
        std_mps2: Some(-1.0),
    };
    assert_eq!(rejected_field(accelerometer), "std_mps2");
}

#[test]
fn tdoa_needs_two_different_anchors() {
    let tdoa = |anchor: &str, reference: &str, range_difference_m| Measurement::Tdoa {
        anchor: anchor.into(),
        reference: reference.into(),
        range_difference_m,
        std_m: None,
    };
    assert_eq!(rejected_field(tdoa("S1", "S1", 1.0)), "reference");
    assert_eq!(rejected_field(tdoa("S1", "", 1.0)), "reference");
    assert_eq!(rejected_field(tdoa("S1", "S2", f64::NAN)), "range_difference_m");
    assert!(record(tdoa("S1", "S2", -4.0)).validate("f", 1).is_ok());
}

fn pseudorange(satellite: &str, satellite_position_m: [f64; 3], pseudorange_m: f64, std_m: Option<f64>) -> Measurement {
    Measurement::Pseudorange {
        satellite: satellite.into(),
        satellite_position_m,
        pseudorange_m,
        std_m,
    }
}

#[test]
fn pseudoranges_name_a_satellite_in_orbit() {
    let orbit = [15_600e3, 7_540e3, 20_140e3];
    assert!(record(pseudorange("G05", orbit, 2.2e7, Some(3.0)))
        .validate("f", 1)
        .is_ok());
    assert_eq!(rejected_field(pseudorange("", orbit, 2.2e7, None)), "satellite");
    assert_eq!(
        rejected_field(pseudorange("G05", orbit, f64::NAN, None)),
        "pseudorange_m"
    );
    assert_eq!(rejected_field(pseudorange("G05", orbit, 2.2e7, Some(-1.0))), "std_m");
    let nan = [orbit[0], f64::INFINITY, orbit[2]];
    assert_eq!(
        rejected_field(pseudorange("G05", nan, 2.2e7, None)),
        "satellite_position_m[1]"
    );
    // km instead of m, a site-frame position, or beyond every orbit
    for wrong in [[15_600.0, 7_540.0, 20_140.0], [10.0, 20.0, 0.0], [6.0e7, 0.0, 0.0]] {
        let error = record(pseudorange("G05", wrong, 2.2e7, None))
            .validate("f", 1)
            .unwrap_err();
        assert!(error.to_string().contains("field `satellite_position_m`"), "{error}");
        assert!(error.to_string().contains("from the Earth's centre"), "{error}");
    }
}

#[test]
fn rssi_vectors_are_non_empty_without_duplicates() {
    assert_eq!(rejected_field(Measurement::RssiVector { readings: vec![] }), "readings");
    let duplicate = vec![reading("A", -60.0), reading("B", -70.0), reading("A", -61.0)];
    assert_eq!(
        rejected_field(Measurement::RssiVector { readings: duplicate }),
        "readings[2].anchor"
    );
    let nan = vec![reading("A", -60.0), reading("B", f64::NAN)];
    assert_eq!(
        rejected_field(Measurement::RssiVector { readings: nan }),
        "readings[1].rssi_dbm"
    );
    let bad_id = vec![reading("A=B", -60.0)];
    assert_eq!(
        rejected_field(Measurement::RssiVector { readings: bad_id }),
        "readings[0].anchor"
    );
}

#[test]
fn vectors_have_two_or_three_finite_components() {
    assert_eq!(rejected_field(fix(&[1.0], &[1.0])), "position_m");
    assert_eq!(rejected_field(fix(&[1.0, 2.0, 3.0, 4.0], &[1.0; 16])), "position_m");
    assert_eq!(
        rejected_field(fix(&[1.0, f64::NAN], &[1.0, 0.0, 0.0, 1.0])),
        "position_m[1]"
    );
    let velocity = Measurement::Velocity {
        velocity_mps: vec![0.0, 0.0, f64::INFINITY],
        covariance_m2ps2: None,
    };
    assert_eq!(rejected_field(velocity), "velocity_mps[2]");
    let accelerometer = Measurement::Accelerometer {
        acceleration_mps2: vec![],
        std_mps2: None,
    };
    assert_eq!(rejected_field(accelerometer), "acceleration_mps2");
}

#[test]
fn covariances_match_the_dimension_and_are_symmetric_psd() {
    // Wrong size for a 2-D position.
    assert_eq!(rejected_field(fix(&[1.0, 2.0], &[1.0, 0.0, 0.0])), "covariance_m2");
    assert_eq!(
        rejected_field(fix(&[1.0, 2.0, 3.0], &[1.0, 0.0, 0.0, 1.0])),
        "covariance_m2"
    );
    // Not finite, not symmetric, not PSD (eigenvalues 3 and −1).
    assert_eq!(
        rejected_field(fix(&[1.0, 2.0], &[1.0, f64::NAN, 0.0, 1.0])),
        "covariance_m2[1]"
    );
    assert_eq!(rejected_field(fix(&[1.0, 2.0], &[1.0, 0.5, 0.4, 1.0])), "covariance_m2");
    assert_eq!(rejected_field(fix(&[1.0, 2.0], &[1.0, 2.0, 2.0, 1.0])), "covariance_m2");
    assert_eq!(
        rejected_field(fix(&[1.0, 2.0], &[-1.0, 0.0, 0.0, 1.0])),
        "covariance_m2"
    );
    // Singular PSD (a fix known only along one direction) and symmetric within round-off pass.
    assert!(record(fix(&[1.0, 2.0], &[1.0, 1.0, 1.0, 1.0])).validate("f", 1).is_ok());
    assert!(record(fix(&[1.0, 2.0], &[1.0, 0.3, 0.3 + 1e-12, 1.0]))
        .validate("f", 1)
        .is_ok());
    let velocity = Measurement::Velocity {
        velocity_mps: vec![1.0, 2.0],
        covariance_m2ps2: Some(vec![1.0; 9]),
    };
    assert_eq!(rejected_field(velocity), "covariance_m2ps2");
}

#[test]
fn kind_names_match_the_formats() {
    let kinds: Vec<&str> = sample_measurements().iter().map(Measurement::kind).collect();
    for kind in [
        "range",
        "rssi",
        "tdoa",
        "rssi_vector",
        "fix",
        "accelerometer",
        "odometry",
        "velocity",
        "pseudorange",
    ] {
        assert!(kinds.contains(&kind), "no sample of {kind}");
    }
}

/// One or more measurements of every kind, including every optional field set and unset.
pub(super) fn sample_measurements() -> Vec<Measurement> {
    vec![
        range(4.21, Some(0.1)),
        range(0.0, None),
        Measurement::Rssi {
            anchor: "R12".into(),
            rssi_dbm: -71.5,
        },
        Measurement::Tdoa {
            anchor: "S2".into(),
            reference: "S1".into(),
            range_difference_m: -3.42,
            std_m: Some(0.3),
        },
        Measurement::Tdoa {
            anchor: "S3".into(),
            reference: "S1".into(),
            range_difference_m: 1e-7,
            std_m: None,
        },
        Measurement::RssiVector {
            readings: vec![reading("AP-1", -63.0), reading("AP 4", -81.5)],
        },
        fix(&[105.2, 48.7], &[4.0, 0.5, 0.5, 2.25]),
        fix(&[105.2, 48.7, -310.0], &[5.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 5.0]),
        Measurement::Accelerometer {
            acceleration_mps2: vec![0.12, -0.03],
            std_mps2: Some(0.05),
        },
        Measurement::Accelerometer {
            acceleration_mps2: vec![0.12, -0.03, 9.81],
            std_mps2: None,
        },
        Measurement::Odometry {
            speed_mps: 8.3,
            heading_rad: Some(1.25),
            speed_std_mps: Some(0.1),
            heading_std_rad: Some(0.02),
        },
        Measurement::Odometry {
            speed_mps: 0.0,
            heading_rad: Some(-3.0),
            speed_std_mps: None,
            heading_std_rad: None,
        },
        Measurement::Velocity {
            velocity_mps: vec![0.8, 0.1],
            covariance_m2ps2: Some(vec![0.01, 0.0, 0.0, 0.01]),
        },
        Measurement::Velocity {
            velocity_mps: vec![0.8, 0.1, 0.0],
            covariance_m2ps2: None,
        },
        Measurement::Range {
            anchor: "rover-2".into(),
            range_m: 14.25,
            std_m: Some(0.1),
            anchor_position_m: Some(vec![3.5, -1.25, 2.0]),
        },
        Measurement::Range {
            anchor: "rover-2".into(),
            range_m: 14.25,
            std_m: None,
            anchor_position_m: Some(vec![3.5, -1.25]),
        },
        Measurement::Odometry {
            speed_mps: 4.5,
            heading_rad: None,
            speed_std_mps: Some(0.05),
            heading_std_rad: None,
        },
        Measurement::YawRate {
            yaw_rate_radps: -0.125,
            std_radps: Some(0.004),
        },
        Measurement::YawRate {
            yaw_rate_radps: 0.0,
            std_radps: None,
        },
        Measurement::OdometryIncrement {
            distance_m: 0.42,
            yaw_change_rad: -0.01,
            interval_s: 0.1,
            distance_std_m: Some(0.005),
            yaw_change_std_rad: None,
        },
        Measurement::Imu {
            acceleration_mps2: vec![0.1, -0.2, 9.79],
            angular_rate_radps: vec![0.01, -0.02, 0.3],
            std_mps2: Some(0.05),
            std_radps: Some(0.003),
        },
        Measurement::Imu {
            acceleration_mps2: vec![0.1, -0.2],
            angular_rate_radps: vec![0.3],
            std_mps2: None,
            std_radps: None,
        },
        pseudorange("G05", [15_600e3, 7_540e3, 20_140e3], 21_312_456.783, Some(3.0)),
        pseudorange("E11", [-14_000e3, -19_000e3, 11_000e3], 2.5e7, None),
    ]
}

/// A deterministic stream of valid records with awkward numbers (tiny, huge, negative zero,
/// long fractions), for round trips.
pub(super) fn many_records() -> Vec<Record> {
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = move || {
        // SplitMix64.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut records = Vec::new();
    for i in 0..400_u32 {
        let bits = next();
        // Uniform in [0, 1) times a scale between 1e-6 and 1e6.
        #[allow(clippy::cast_precision_loss)]
        let unit = (bits >> 11) as f64 / (1_u64 << 53) as f64;
        let scale = 10_f64.powi(i32::try_from(bits % 13).unwrap() - 6);
        let value = unit * scale;
        let samples = sample_measurements();
        let mut sample = samples[usize::try_from(bits % samples.len() as u64).unwrap()].clone();
        match &mut sample {
            Measurement::Range { range_m, .. } => *range_m = value,
            Measurement::Rssi { rssi_dbm, .. } => *rssi_dbm = -value,
            Measurement::Tdoa { range_difference_m, .. } => {
                *range_difference_m = if i % 2 == 0 { -0.0 } else { -value }
            }
            Measurement::RssiVector { readings } => readings[1].rssi_dbm = -value,
            Measurement::Fix {
                position_m,
                covariance_m2,
            } => {
                position_m[0] = -value;
                covariance_m2[0] = value + 5.0;
            }
            Measurement::Accelerometer { acceleration_mps2, .. } => acceleration_mps2[1] = value,
            Measurement::Odometry { heading_rad, .. } => *heading_rad = Some(value),
            Measurement::Velocity { velocity_mps, .. } => velocity_mps[0] = value,
            Measurement::YawRate { yaw_rate_radps, .. } => *yaw_rate_radps = value,
            Measurement::OdometryIncrement { distance_m, .. } => *distance_m = value,
            Measurement::Imu { angular_rate_radps, .. } => angular_rate_radps[0] = -value,
            Measurement::Pseudorange {
                satellite_position_m,
                pseudorange_m,
                ..
            } => {
                *pseudorange_m = 2e7 + value;
                satellite_position_m[2] = -value;
            }
        }
        let time_s = 1.7e9 + f64::from(i) * 0.013 + unit;
        let record = Record {
            time_s,
            tag: format!("tag-{}", bits % 7),
            measurement: sample,
        };
        record.validate("generated", usize::try_from(i).unwrap()).unwrap();
        records.push(record);
    }
    records
}

#[test]
fn json_lines_round_trip_exactly() {
    for (i, record) in many_records().iter().enumerate() {
        let line = to_json_line(record);
        assert!(!line.contains('\n'));
        let parsed = parse_json_line(&line, "round-trip", i + 1).unwrap();
        assert_eq!(&parsed, record, "{line}");
        // Bit-exact, including the sign of zero.
        assert_eq!(to_json_line(&parsed), line);
    }
}

#[test]
fn csv_round_trips_exactly() {
    let records = many_records();
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(CSV_COLUMNS).unwrap();
    for record in &records {
        writer.write_record(to_csv_row(record)).unwrap();
    }
    let bytes = writer.into_inner().unwrap();
    let parsed: Vec<Record> = CsvRecords::new(bytes.as_slice(), "round-trip.csv")
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(parsed, records);
}

/// The bodies of the fenced blocks of one language in `docs/FORMATS.md`.
/// The code blocks of `language` in the measurement-record section of FORMATS.md (the later
/// sections, ground truth and radio maps, are tested by their own modules).
fn blocks(language: &str) -> Vec<&'static str> {
    let fence = format!("```{language}\n");
    let records_section = FORMATS.split("\n## Ground truth").next().unwrap_or(FORMATS);
    records_section
        .split(fence.as_str())
        .skip(1)
        .map(|rest| rest.split("```").next().unwrap_or_default())
        .collect()
}

#[test]
fn every_jsonl_example_in_formats_md_parses() {
    let examples: Vec<Record> = blocks("jsonl")
        .into_iter()
        .flat_map(|b| JsonLines::new(b.as_bytes(), "FORMATS.md"))
        .map(Result::unwrap)
        .collect();
    assert_eq!(examples.len(), 20);
    let mut kinds: Vec<&str> = examples.iter().map(|r| r.measurement.kind()).collect();
    kinds.dedup();
    assert_eq!(
        kinds,
        [
            "range",
            "rssi",
            "tdoa",
            "rssi_vector",
            "fix",
            "accelerometer",
            "odometry",
            "velocity",
            "yaw_rate",
            "odometry_increment",
            "imu",
            "pseudorange"
        ]
    );
}

#[test]
fn every_csv_example_in_formats_md_parses_and_matches_the_jsonl_examples() {
    let csv_blocks = blocks("csv");
    assert_eq!(csv_blocks.len(), 2);
    let from_json: Vec<Record> = blocks("jsonl")
        .into_iter()
        .flat_map(|b| JsonLines::new(b.as_bytes(), "FORMATS.md"))
        .map(Result::unwrap)
        .collect();
    let from_csv: Vec<Record> = CsvRecords::from_text(csv_blocks[0], "FORMATS.md")
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(from_csv, from_json);
    let narrow: Vec<Record> = CsvRecords::from_text(csv_blocks[1], "FORMATS.md")
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(narrow, from_json[..2]);
}

#[test]
fn the_json_schema_in_formats_md_is_json_and_covers_every_kind() {
    let schema = blocks("json");
    assert_eq!(schema.len(), 1);
    // Parsed as plain JSON only to check the document; the parser itself uses typed structs.
    let schema: serde_json::Value = serde_json::from_str(schema[0]).unwrap();
    assert_eq!(schema["$schema"], "https://json-schema.org/draft/2020-12/schema");
    let references = schema["oneOf"].as_array().unwrap();
    for measurement in sample_measurements() {
        let kind = measurement.kind();
        let reference = format!("#/$defs/{kind}");
        assert!(
            references.iter().any(|r| r["$ref"] == reference.as_str()),
            "{kind} missing from oneOf"
        );
        let definition = &schema["$defs"][kind];
        assert_eq!(definition["properties"]["kind"]["const"], kind);
        assert_eq!(definition["additionalProperties"], false);
        // The schema's keys for the kind are exactly the ones the writer can produce.
        let line = to_json_line(&record(measurement));
        let written: serde_json::Value = serde_json::from_str(&line).unwrap();
        for key in written.as_object().unwrap().keys() {
            assert!(
                definition["properties"].get(key).is_some(),
                "{kind}: key {key} not in the schema"
            );
        }
        for key in definition["required"].as_array().unwrap() {
            assert!(
                written.get(key.as_str().unwrap()).is_some(),
                "{kind}: required {key} not written"
            );
        }
    }
}
