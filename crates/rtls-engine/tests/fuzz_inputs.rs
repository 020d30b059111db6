//! A bounded mutation fuzz of the input parsers (JSON Lines and CSV records, the site TOML, the
//! radio map CSV) and of the tracker behind them. Valid inputs are mutated (byte flips,
//! truncation, numbers replaced by huge / tiny / NaN / negative ones, duplicated lines and keys,
//! very long lines); every result must be a value or an error naming the file and a line of the
//! input, never a panic, and everything accepted must be finite. The seeds are fixed, so a run
//! is deterministic and takes a few seconds.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

use rtls_engine::radio_map::RadioMap;
use rtls_engine::record::{parse_json_line, CsvRecords, JsonLines, Measurement, Record, MAX_ABS_TIME_S};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Output, Tracker};
use rtls_engine::EngineError;

const SITE: &str = include_str!("../../../examples/site.toml");
const RADIO_MAP: &str = include_str!("../../../examples/radio-map.csv");

const JSON_SEEDS: [&str; 9] = [
    r#"{"t": 12.5, "tag": "m1", "kind": "range", "anchor": "A1", "range_m": 4.21, "std_m": 0.1}"#,
    r#"{"t": 12.6, "tag": "m1", "kind": "rssi", "anchor": "B1", "rssi_dbm": -71.5}"#,
    r#"{"t": 12.7, "tag": "m1", "kind": "tdoa", "anchor": "A2", "reference": "A1", "range_difference_m": -3.42, "std_m": 0.3}"#,
    r#"{"t": 12.8, "tag": "m1", "kind": "rssi_vector", "readings": [{"anchor": "B1", "rssi_dbm": -70}, {"anchor": "B2", "rssi_dbm": -80}]}"#,
    r#"{"t": 12.9, "tag": "m1", "kind": "fix", "position_m": [3.2, 4.1], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}"#,
    r#"{"t": 13.0, "tag": "m1", "kind": "accelerometer", "acceleration_mps2": [0.12, -0.03], "std_mps2": 0.05}"#,
    r#"{"t": 13.1, "tag": "m1", "kind": "odometry", "speed_mps": 8.3, "heading_rad": 1.5708, "speed_std_mps": 0.1, "heading_std_rad": 0.02}"#,
    r#"{"t": 13.2, "tag": "m1", "kind": "velocity", "velocity_mps": [1.0, 0.5], "covariance_m2ps2": [0.01, 0.0, 0.0, 0.01]}"#,
    r#"{"t": 13.3, "tag": "m1", "kind": "pseudorange", "satellite": "G05", "satellite_position_m": [15600000.0, 7540000.0, 20140000.0], "pseudorange_m": 21312456.783, "std_m": 3.0}"#,
];

const CSV_SEED: &str = "t,tag,kind,anchor,reference,value,std,heading,heading_std,x,y,z,covariance,readings
12.5,m1,range,A1,,4.21,0.1,,,,,,,
12.6,m1,rssi,B1,,-71.5,,,,,,,,
12.7,m1,tdoa,A2,A1,-3.42,0.3,,,,,,,
12.8,m1,rssi_vector,,,,,,,,,,,B1=-70;B2=-80
12.9,m1,fix,,,,,,,3.2,4.1,,0.04;0;0;0.04,
13.0,m1,accelerometer,,,,0.05,,,0.12,-0.03,,,
13.1,m1,odometry,,,8.3,0.1,1.5708,0.02,,,,,
13.2,m1,velocity,,,,,,,1,0.5,,0.01;0;0;0.01,
13.3,m1,pseudorange,G05,,21312456.783,3.0,,,15600000,7540000,20140000,,
";

/// Replacements for a number: huge, tiny, not finite, negative, not a number at all.
const NUMBERS: [&str; 14] = [
    "1e308",
    "-1e308",
    "1e-300",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0",
    "1e16",
    "1e999",
    "99999999999999999999",
    "0x10",
];

/// One mutation of a text, as bytes.
#[derive(Debug, Clone)]
enum Mutation {
    /// Flip bit `bit` of the byte at `at` (fraction of the length).
    FlipBit { at: f64, bit: u8 },
    /// Cut the text at `at`.
    Truncate { at: f64 },
    /// Replace the `index`-th number of the text.
    Number { index: usize, with: usize },
    /// Repeat the line containing `at`.
    DuplicateLine { at: f64 },
    /// Repeat the `key = …` / `"key": …` at `at` on its line (a duplicated key).
    DuplicateSpan { at: f64, length: usize },
    /// Insert a long run of one character at `at`.
    LongRun { at: f64, byte: u8, length: usize },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (0.0..1.0, 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        (0.0..1.0).prop_map(|at| Mutation::Truncate { at }),
        (0usize..64, 0..NUMBERS.len()).prop_map(|(index, with)| Mutation::Number { index, with }),
        (0.0..1.0).prop_map(|at| Mutation::DuplicateLine { at }),
        (0.0..1.0, 1usize..40).prop_map(|(at, length)| Mutation::DuplicateSpan { at, length }),
        (
            0.0..1.0,
            prop::sample::select(vec![b'9', b'[', b'{', b'"', b',', b'\n', b'#', 0xff]),
            1usize..200_000
        )
            .prop_map(|(at, byte, length)| Mutation::LongRun { at, byte, length }),
    ]
}

fn position(bytes: &[u8], at: f64) -> usize {
    ((bytes.len() as f64 * at) as usize).min(bytes.len())
}

fn apply(text: &str, mutations: &[Mutation]) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    for m in mutations {
        match *m {
            Mutation::FlipBit { at, bit } => {
                if !bytes.is_empty() {
                    let i = position(&bytes, at).min(bytes.len() - 1);
                    bytes[i] ^= 1 << bit;
                }
            }
            Mutation::Truncate { at } => bytes.truncate(position(&bytes, at)),
            Mutation::Number { index, with } => {
                let text = String::from_utf8_lossy(&bytes).into_owned();
                let spans = number_spans(&text);
                if !spans.is_empty() {
                    let (start, end) = spans[index % spans.len()];
                    bytes = format!("{}{}{}", &text[..start], NUMBERS[with], &text[end..]).into_bytes();
                }
            }
            Mutation::DuplicateLine { at } => {
                let i = position(&bytes, at);
                let start = bytes[..i].iter().rposition(|&b| b == b'\n').map_or(0, |k| k + 1);
                let end = bytes[i..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |k| i + k + 1);
                let line = bytes[start..end].to_vec();
                bytes.splice(end..end, line);
            }
            Mutation::DuplicateSpan { at, length } => {
                let i = position(&bytes, at);
                let end = (i + length).min(bytes.len());
                let span = bytes[i..end].to_vec();
                bytes.splice(end..end, span);
            }
            Mutation::LongRun { at, byte, length } => {
                let i = position(&bytes, at);
                bytes.splice(i..i, std::iter::repeat_n(byte, length));
            }
        }
    }
    bytes
}

/// Byte spans of the numbers of a text (digits with an optional sign, point and exponent).
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && bytes[i - 1] == b'-' { i - 1 } else { i };
            let mut end = i;
            while end < bytes.len() && (bytes[end].is_ascii_digit() || matches!(bytes[end], b'.' | b'e' | b'E')) {
                end += 1;
            }
            spans.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    spans
}

fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(20_261_125),
        ..Config::default()
    }
}

/// Lines of a text as the readers count them (for the range an error's line must fall in).
fn line_count(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&b| b == b'\n').count() + 1
}

/// An error names `file` and a line of the input (0 only for an input with no content line).
fn check_error(error: &EngineError, file: &str, lines: usize) {
    match error {
        EngineError::Parse { file: f, line, .. } => {
            assert_eq!(f, file, "{error}");
            assert!(*line <= lines, "{error}: line beyond the {lines} lines of the input");
        }
        other => panic!("not a parse error naming file and line: {other}"),
    }
}

/// Every number of an accepted record is finite and its time plausible.
fn check_record(record: &Record) {
    assert!(
        record.time_s.is_finite() && record.time_s.abs() <= MAX_ABS_TIME_S,
        "{record:?}"
    );
    let numbers: Vec<f64> = match &record.measurement {
        Measurement::Range { range_m, std_m, .. } => [Some(*range_m), *std_m].into_iter().flatten().collect(),
        Measurement::Rssi { rssi_dbm, .. } => vec![*rssi_dbm],
        Measurement::Tdoa {
            range_difference_m,
            std_m,
            ..
        } => [Some(*range_difference_m), *std_m].into_iter().flatten().collect(),
        Measurement::RssiVector { readings } => readings.iter().map(|r| r.rssi_dbm).collect(),
        Measurement::Fix {
            position_m,
            covariance_m2,
        } => position_m.iter().chain(covariance_m2).copied().collect(),
        Measurement::Accelerometer {
            acceleration_mps2,
            std_mps2,
        } => acceleration_mps2.iter().copied().chain(*std_mps2).collect(),
        Measurement::Odometry {
            speed_mps,
            heading_rad,
            speed_std_mps,
            heading_std_rad,
        } => [Some(*speed_mps), *heading_rad, *speed_std_mps, *heading_std_rad]
            .into_iter()
            .flatten()
            .collect(),
        Measurement::YawRate {
            yaw_rate_radps,
            std_radps,
        } => [Some(*yaw_rate_radps), *std_radps].into_iter().flatten().collect(),
        Measurement::OdometryIncrement {
            distance_m,
            yaw_change_rad,
            interval_s,
            distance_std_m,
            yaw_change_std_rad,
        } => [
            Some(*distance_m),
            Some(*yaw_change_rad),
            Some(*interval_s),
            *distance_std_m,
            *yaw_change_std_rad,
        ]
        .into_iter()
        .flatten()
        .collect(),
        Measurement::Imu {
            acceleration_mps2,
            angular_rate_radps,
            std_mps2,
            std_radps,
        } => acceleration_mps2
            .iter()
            .chain(angular_rate_radps)
            .copied()
            .chain(*std_mps2)
            .chain(*std_radps)
            .collect(),
        Measurement::Velocity {
            velocity_mps,
            covariance_m2ps2,
        } => velocity_mps
            .iter()
            .chain(covariance_m2ps2.iter().flatten())
            .copied()
            .collect(),
        Measurement::Pseudorange {
            satellite_position_m,
            pseudorange_m,
            std_m,
            ..
        } => satellite_position_m
            .iter()
            .copied()
            .chain([*pseudorange_m])
            .chain(*std_m)
            .collect(),
    };
    assert!(numbers.iter().all(|v| v.is_finite()), "{record:?}");
}

/// Reads a JSON Lines or CSV document: the records accepted, each error checked.
fn read_records(bytes: &[u8], csv: bool) -> Vec<Record> {
    let lines = line_count(bytes);
    let mut records = Vec::new();
    let mut take = |result: Result<Record, EngineError>, file: &str| match result {
        Ok(record) => {
            check_record(&record);
            records.push(record);
        }
        Err(error) => check_error(&error, file, lines),
    };
    if csv {
        match CsvRecords::new(bytes, "fuzz.csv") {
            Ok(reader) => reader.for_each(|r| take(r, "fuzz.csv")),
            Err(error) => check_error(&error, "fuzz.csv", lines),
        }
    } else {
        JsonLines::new(bytes, "fuzz.jsonl").for_each(|r| take(r, "fuzz.jsonl"));
    }
    records
}

proptest! {
    #![proptest_config(config(400))]

    #[test]
    fn json_lines_never_panic_and_name_file_and_line(
        seed in 0..JSON_SEEDS.len(),
        mutations in prop::collection::vec(mutation(), 1..4),
    ) {
        let bytes = apply(JSON_SEEDS[seed], &mutations);
        if let Ok(text) = std::str::from_utf8(&bytes) {
            match parse_json_line(text, "fuzz.jsonl", 7) {
                Ok(record) => check_record(&record),
                Err(error) => check_error(&error, "fuzz.jsonl", 7),
            }
        }
        read_records(&bytes, false);
    }

    #[test]
    fn csv_records_never_panic_and_name_file_and_line(mutations in prop::collection::vec(mutation(), 1..4)) {
        read_records(&apply(CSV_SEED, &mutations), true);
    }
}

proptest! {
    #![proptest_config(config(150))]

    #[test]
    fn site_files_never_panic_and_name_file_and_line(mutations in prop::collection::vec(mutation(), 1..4)) {
        let bytes = apply(SITE, &mutations);
        let lines = line_count(&bytes);
        let Ok(text) = String::from_utf8(bytes) else { return Ok(()) };
        match Site::from_toml_str(&text, "fuzz.toml") {
            Err(error) => check_error(&error, "fuzz.toml", lines),
            Ok(site) => {
                // an accepted site runs: a tracker and its radio map build without panicking
                let tracker = Tracker::new(&site);
                prop_assert!(tracker.is_ok(), "{:?}", tracker.err());
                if let Err(error) = RadioMap::from_csv_str(RADIO_MAP, "radio-map.csv", &site) {
                    check_error(&error, "radio-map.csv", line_count(RADIO_MAP.as_bytes()));
                }
            }
        }
    }

    #[test]
    fn radio_maps_never_panic_and_name_file_and_line(mutations in prop::collection::vec(mutation(), 1..4)) {
        let site = Site::from_toml_str(SITE, "site.toml").unwrap();
        let bytes = apply(RADIO_MAP, &mutations);
        let lines = line_count(&bytes);
        let Ok(text) = String::from_utf8(bytes) else { return Ok(()) };
        if let Err(error) = RadioMap::from_csv_str(&text, "fuzz.csv", &site) {
            check_error(&error, "fuzz.csv", lines);
        }
    }
}

/// A valid stream of ~200 records of two tags walking through the example site.
fn stream() -> String {
    let site = Site::from_toml_str(SITE, "site.toml").unwrap();
    let anchors: Vec<(&str, [f64; 3])> = ["A1", "A2", "A3"]
        .iter()
        .map(|id| (*id, site.reader(id).unwrap().position_xyz_m()))
        .collect();
    let mut lines = Vec::new();
    for k in 0..70 {
        let t = 1.7e9 + f64::from(k) * 0.1;
        for (tag, speed) in [("w1", 1.0), ("w2", -0.5)] {
            let p = [15.0 + speed * f64::from(k) * 0.1, 10.0, 1.2];
            let (id, a) = anchors[k as usize % 3];
            let r = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt();
            lines.push(format!(
                r#"{{"t": {t}, "tag": "{tag}", "kind": "range", "anchor": "{id}", "range_m": {r}}}"#
            ));
        }
        if k % 10 == 0 {
            lines.push(format!(
                r#"{{"t": {t}, "tag": "w1", "kind": "rssi_vector", "readings": [{{"anchor": "B1", "rssi_dbm": -74}}, {{"anchor": "B2", "rssi_dbm": -82}}]}}"#
            ));
            lines.push(format!(
                r#"{{"t": {t}, "tag": "w2", "kind": "fix", "position_m": [14.0, 10.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#
            ));
        }
    }
    lines.join("\n")
}

proptest! {
    #![proptest_config(config(48))]

    #[test]
    fn mutated_streams_through_the_tracker_finish_with_finite_outputs(
        mutations in prop::collection::vec(mutation(), 1..6),
        pipeline in prop::sample::select(vec!["tightly-coupled", "fix-then-filter"]),
        motion in prop::sample::select(vec!["cv", "imm"]),
    ) {
        let start = Instant::now();
        let mut site = Site::from_toml_str(SITE, "site.toml").unwrap();
        site.tracker.pipeline = if pipeline == "fix-then-filter" {
            rtls_engine::site::Pipeline::FixThenFilter
        } else {
            rtls_engine::site::Pipeline::TightlyCoupled
        };
        site.tracker.motion_model = if motion == "imm" {
            rtls_engine::site::MotionModelKind::Imm
        } else {
            rtls_engine::site::MotionModelKind::Cv
        };
        let map = RadioMap::from_csv_str(RADIO_MAP, "radio-map.csv", &site).unwrap();
        let mut tracker = Tracker::new(&site).unwrap().with_radio_map(map);
        let mut out = Output::default();
        let bytes = apply(&stream(), &mutations);
        let records = read_records(&bytes, false);
        let count = records.len();
        for record in records {
            tracker.push(record, &mut out).unwrap();
        }
        tracker.finish(&mut out).unwrap();
        // bounded work: the 7 s stream (plus a day's jump at most, refused) gives a bounded output
        prop_assert!(start.elapsed() < Duration::from_secs(20), "{:?}", start.elapsed());
        prop_assert!(out.updates.len() <= 20 * (count + 10) + 1000, "{} updates from {count} records", out.updates.len());
        for update in &out.updates {
            prop_assert!(update.time_s.is_finite(), "{update:?}");
            prop_assert!(update.position_m.iter().chain(&update.velocity_mps).chain(&update.position_covariance_m2).all(|v| v.is_finite()), "{update:?}");
        }
        for event in &out.events {
            prop_assert!(event.time_s().is_finite(), "{event:?}");
            prop_assert!(!event.to_json_line().contains("null"), "{}", event.to_json_line());
        }
        for fix in &out.fixes {
            prop_assert!(!fix.to_json_line().contains("null"), "{}", fix.to_json_line());
        }
    }
}
