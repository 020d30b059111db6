use super::*;
use crate::record::tests::located;

fn error_field(text: &str) -> String {
    let error = parse_json_line(text, "in.jsonl", 9).unwrap_err();
    let (file, line, field) = located(&error);
    assert_eq!((file, line), ("in.jsonl", 9), "{error}");
    field.to_string()
}

#[test]
fn the_brief_example_parses() {
    let text = r#"{"t": 12.5, "tag": "miner-017", "kind": "range", "anchor": "R12", "range_m": 4.21, "std_m": 0.1}"#;
    let record = parse_json_line(text, "in.jsonl", 1).unwrap();
    assert_eq!(record.time_s, 12.5);
    assert_eq!(record.tag, "miner-017");
    assert_eq!(
        record.measurement,
        Measurement::Range {
            anchor: "R12".into(),
            range_m: 4.21,
            std_m: Some(0.1),
            anchor_position_m: None,
        }
    );
}

#[test]
fn unknown_duplicate_and_foreign_keys_are_errors_naming_the_key() {
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1, "extra": 1}"#),
        "extra"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "anchor": "S", "rssi_dbm": -1}"#),
        "anchor"
    );
    // `range_m` is a known key, but not one of kind `rssi`.
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1, "range_m": 2}"#),
        "range_m"
    );
    let error = parse_json_line(
        r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1, "std_m": 2}"#,
        "f",
        1,
    );
    assert!(error.unwrap_err().to_string().contains("is not used by kind `rssi`"));
}

#[test]
fn missing_keys_are_errors_naming_the_key() {
    assert_eq!(
        error_field(r#"{"tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#),
        "t"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#),
        "tag"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "anchor": "R", "rssi_dbm": -1}"#),
        "kind"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "tdoa", "anchor": "R", "range_difference_m": 1}"#),
        "reference"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "fix", "position_m": [1, 2]}"#),
        "covariance_m2"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "odometry_increment", "distance_m": 1, "interval_s": 1}"#),
        "yaw_change_rad"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi_vector"}"#),
        "readings"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "velocity"}"#),
        "velocity_mps"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "accelerometer"}"#),
        "acceleration_mps2"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "pseudorange", "satellite": "G05", "pseudorange_m": 2.2e7}"#),
        "satellite_position_m"
    );
    assert_eq!(
        error_field(
            r#"{"t": 1, "tag": "a", "kind": "pseudorange", "satellite": "G05", "satellite_position_m": [1.5e7, 7e6], "pseudorange_m": 2.2e7}"#
        ),
        "satellite_position_m"
    );
    assert_eq!(
        error_field(
            r#"{"t": 1, "tag": "a", "kind": "pseudorange", "anchor": "G05", "satellite_position_m": [1.5e7, 7e6, 2e7], "pseudorange_m": 2.2e7}"#
        ),
        "satellite"
    );
}

#[test]
fn unknown_kinds_list_the_known_ones() {
    let error = parse_json_line(r#"{"t": 1, "tag": "a", "kind": "lidar"}"#, "f", 1).unwrap_err();
    assert_eq!(located(&error).2, "kind");
    assert!(
        error.to_string().contains("expected one of range, rssi, tdoa"),
        "{error}"
    );
}

#[test]
fn wrong_types_name_the_key() {
    assert_eq!(
        error_field(r#"{"t": "noon", "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#),
        "t"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": 7, "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#),
        "tag"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": null}"#),
        "rssi_dbm"
    );
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "fix", "position_m": [1, "2"], "covariance_m2": []}"#),
        "position_m"
    );
    let reading_key = r#"{"t": 1, "tag": "a", "kind": "rssi_vector", "readings": [{"anchor": "R", "rssi": -1}]}"#;
    assert_eq!(error_field(reading_key), "readings");
    // Overflowing numbers are not silently infinite.
    assert_eq!(
        error_field(r#"{"t": 1e999, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#),
        "t"
    );
}

#[test]
fn values_are_validated_with_the_key_named() {
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "range", "anchor": "R", "range_m": 4, "std_m": -1}"#),
        "std_m"
    );
    // Wi-Fi FTM/RTT gives negative ranges for close devices: finite ones are accepted
    let close = parse_json_line(
        r#"{"t": 1, "tag": "a", "kind": "range", "anchor": "R", "range_m": -0.4}"#,
        "f",
        1,
    );
    assert!(close.is_ok(), "{close:?}");
    // a gateway sending nanoseconds: refused, naming the time
    let error = parse_json_line(
        r#"{"t": 1e16, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1}"#,
        "f",
        3,
    )
    .unwrap_err()
    .to_string();
    assert!(error.starts_with("f:3: field `t`: 1e16 s is beyond"), "{error}");
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "", "kind": "range", "anchor": "R", "range_m": 4}"#),
        "tag"
    );
    let asymmetric = r#"{"t": 1, "tag": "a", "kind": "fix", "position_m": [1, 2], "covariance_m2": [1, 0.5, 0, 1]}"#;
    assert_eq!(error_field(asymmetric), "covariance_m2");
}

#[test]
fn malformed_lines_are_errors_for_the_record_as_a_whole() {
    for text in ["[1, 2]", "{\"t\": 1,", "not json", "{} {}", "42"] {
        let field = error_field(text);
        assert!(field == "-" || field == "t", "{text}: field {field}");
    }
    assert_eq!(error_field("[1, 2]"), "-");
    // Trailing characters after a complete object.
    assert_eq!(
        error_field(r#"{"t": 1, "tag": "a", "kind": "rssi", "anchor": "R", "rssi_dbm": -1} x"#),
        "-"
    );
}

#[test]
fn reader_skips_blank_and_comment_lines_and_counts_lines() {
    let text = "\n# comment\n  # indented comment\r\n{\"t\": 1, \"tag\": \"a\", \"kind\": \"rssi\", \"anchor\": \"R\", \"rssi_dbm\": -1}\r\n\
                \n{\"t\": 2, \"tag\": \"a\", \"kind\": \"rssi\"}\n{\"t\": 3, \"tag\": \"b\", \"kind\": \"rssi\", \"anchor\": \"R\", \"rssi_dbm\": -2}";
    let results: Vec<Result<Record>> = JsonLines::new(text.as_bytes(), "stream").collect();
    assert_eq!(results.len(), 3);
    assert_eq!(results[0].as_ref().unwrap().time_s, 1.0);
    assert_eq!(located(results[1].as_ref().unwrap_err()), ("stream", 6, "anchor"));
    // The last line has no newline and is still read.
    assert_eq!(results[2].as_ref().unwrap().tag, "b");
}

#[test]
fn reader_reports_non_utf8_lines_and_continues() {
    let mut bytes = b"{\"t\": 1, \"tag\": \"\xff\", \"kind\": \"rssi\"}\n".to_vec();
    bytes.extend_from_slice(b"{\"t\": 2, \"tag\": \"a\", \"kind\": \"rssi\", \"anchor\": \"R\", \"rssi_dbm\": -1}\n");
    let results: Vec<Result<Record>> = JsonLines::new(bytes.as_slice(), "bin").collect();
    assert_eq!(results.len(), 2);
    let error = results[0].as_ref().unwrap_err();
    assert_eq!(located(error), ("bin", 1, "-"));
    assert!(error.to_string().contains("UTF-8"));
    assert!(results[1].is_ok());
}

/// A reader that yields one line, then fails.
struct Failing {
    sent: bool,
}

impl std::io::Read for Failing {
    fn read(&mut self, buffer: &mut [u8]) -> std::io::Result<usize> {
        if self.sent {
            return Err(std::io::Error::other("link down"));
        }
        self.sent = true;
        let line = b"{\"t\": 1, \"tag\": \"a\", \"kind\": \"rssi\", \"anchor\": \"R\", \"rssi_dbm\": -1}\n";
        buffer[..line.len()].copy_from_slice(line);
        Ok(line.len())
    }
}

#[test]
fn reader_reports_a_read_error_once_and_stops() {
    let results: Vec<Result<Record>> =
        JsonLines::new(std::io::BufReader::new(Failing { sent: false }), "socket").collect();
    assert_eq!(results.len(), 2);
    assert!(results[0].is_ok());
    // a read error, not a malformed record: a caller stops rather than skipping it
    let error = results[1].as_ref().unwrap_err();
    assert!(
        matches!(error, EngineError::Read { file, line: 1, .. } if file == "socket"),
        "{error:?}"
    );
    assert!(error.to_string().contains("link down"));
}

#[test]
fn optional_values_left_out_are_not_written() {
    let record = Record {
        time_s: 5.0,
        tag: "a".into(),
        measurement: Measurement::Velocity {
            velocity_mps: vec![1.0, 2.0],
            covariance_m2ps2: None,
        },
    };
    assert_eq!(
        to_json_line(&record),
        r#"{"t":5.0,"tag":"a","kind":"velocity","velocity_mps":[1.0,2.0]}"#
    );
}
