//! Reading ground-truth CSV and track JSON Lines: values, line numbers, and errors that name the
//! file, line and field.

use super::{parse_track_line, parse_track_lines, parse_truth_csv};
use crate::EngineError;

/// The (file, line, field) of a parse error, and its message.
fn located(error: EngineError) -> (String, usize, String, String) {
    let message = error.to_string();
    match error {
        EngineError::Parse { file, line, field, .. } => (file, line, field, message),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

fn truth_error(text: &str) -> (String, usize, String, String) {
    located(parse_truth_csv(text, "truth.csv").unwrap_err())
}

fn track_error(text: &str) -> (String, usize, String, String) {
    located(parse_track_line(text, "tracks.jsonl", 12).unwrap_err())
}

#[test]
fn truth_rows_read_2d_and_3d_with_their_file_lines() {
    let text = "t,tag,x,y,z\n# written by a test\n0,a,1,2,\n\n   \n1.5,\"b,2\", 3 ,4,-5.25\n0.25,a,-1e-3,2e3,\n";
    let truth = parse_truth_csv(text, "truth.csv").unwrap();
    assert_eq!(truth.len(), 3);
    assert_eq!((truth[0].time_s, truth[0].tag.as_str()), (0.0, "a"));
    assert_eq!(
        (truth[0].position_m, truth[0].has_z, truth[0].line),
        ([1.0, 2.0, 0.0], false, 3)
    );
    assert_eq!(truth[1].tag, "b,2"); // quoted cells may hold commas
    assert_eq!(
        (truth[1].position_m, truth[1].has_z, truth[1].line),
        ([3.0, 4.0, -5.25], true, 6)
    );
    // rows need not be sorted
    assert_eq!(
        (truth[2].time_s, truth[2].position_m, truth[2].line),
        (0.25, [-0.001, 2000.0, 0.0], 7)
    );
}

#[test]
fn truth_columns_may_come_in_any_order_and_z_may_be_left_out() {
    let truth = parse_truth_csv("tag,y,x,t\nrobot,2,1,0.5\n", "truth.csv").unwrap();
    assert_eq!(
        (truth[0].time_s, truth[0].position_m, truth[0].has_z),
        (0.5, [1.0, 2.0, 0.0], false)
    );
    let crlf = parse_truth_csv("t,tag,x,y,z\r\n1,a,2,3,4\r\n", "truth.csv").unwrap();
    assert_eq!(crlf[0].position_m, [2.0, 3.0, 4.0]);
}

#[test]
fn truth_header_errors_name_line_and_column() {
    let (file, line, field, message) = truth_error("t,tag,x,y,w\n0,a,1,2,3\n");
    assert_eq!((file.as_str(), line, field.as_str()), ("truth.csv", 1, "w"));
    assert!(
        message.contains("unknown column") && message.contains("t,tag,x,y,z"),
        "{message}"
    );
    let (_, line, field, message) = truth_error("# c\nt,tag,x,y,t\n");
    assert_eq!((line, field.as_str()), (2, "t"));
    assert!(message.contains("column appears twice"), "{message}");
    let (_, line, field, message) = truth_error("t,tag,x,z\n0,a,1,2\n");
    assert_eq!((line, field.as_str()), (1, "y"));
    assert!(message.contains("column is missing"), "{message}");
    assert!(truth_error("").3.contains("no header row"));
    let (_, line, _, message) = truth_error("t,tag,x,y,z\n\n");
    assert_eq!(line, 1);
    assert!(message.contains("no ground-truth rows"), "{message}");
}

#[test]
fn truth_value_errors_name_line_and_column() {
    for (text, line, field, needle) in [
        (
            "t,tag,x,y,z\n0,a,1,2,\nsoon,a,1,2,\n",
            3,
            "t",
            "`soon` is not a finite number",
        ),
        ("t,tag,x,y,z\n0,a,inf,2,\n", 2, "x", "`inf` is not a finite number"),
        ("t,tag,x,y,z\n0,a,1,NaN,\n", 2, "y", "`NaN`"),
        ("t,tag,x,y,z\n0,a,1,2,high\n", 2, "z", "`high`"),
        ("t,tag,x,y,z\n0,a,1,,\n", 2, "y", "`` is not a finite number"),
        ("t,tag,x,y,z\n0,,1,2,\n", 2, "tag", "is empty"),
        (
            "t,tag,x,y,z\n0,a,1,2,\n# x\n1,a,1,2\n",
            4,
            "-",
            "4 cells, the header has 5",
        ),
        ("t,tag,x,y,z\n0,a,1,2,,\n", 2, "-", "6 cells"),
        (",,,,\n", 1, "", "unknown column"),
    ] {
        let (file, got_line, got_field, message) = truth_error(text);
        assert_eq!(file, "truth.csv");
        assert_eq!((got_line, got_field.as_str()), (line, field), "{text:?}: {message}");
        assert!(message.contains(needle), "{text:?}: {message}");
        assert!(
            message.starts_with(&format!("truth.csv:{line}: field `{field}`")),
            "{message}"
        );
    }
}

#[test]
fn truth_rows_at_the_same_time_must_agree() {
    // the same position twice is fine
    let same = parse_truth_csv("t,tag,x,y,z\n1,a,1,2,\n1,b,5,5,\n1,a,1,2,\n", "truth.csv").unwrap();
    assert_eq!(same.len(), 3);
    let (_, line, field, message) = truth_error("t,tag,x,y,z\n2,a,0,0,\n1,a,1,2,\n1,b,9,9,\n1,a,1,2.5,\n");
    assert_eq!((line, field.as_str()), (5, "y"));
    assert!(message.contains("tag `a`") && message.contains("line 3"), "{message}");
    // 2-D and 3-D rows at one time differ in z
    let (_, line, field, _) = truth_error("t,tag,x,y,z\n1,a,1,2,\n1,a,1,2,0\n");
    assert_eq!((line, field.as_str()), (3, "z"));
}

#[test]
fn track_lines_read_the_needed_keys_and_ignore_the_rest() {
    let line = r#"{"t": 12.5, "vx": 0.1, "cov": [1, 0, 0, 0, 1, 0, 0, 0, 2], "tag": "miner-017", "x": 10, "y": -2.5, "z": 1.75,
        "status": "confirmed", "events": {"zone": "A"}, "predicted": false}"#
        .replace('\n', " ");
    let sample = parse_track_line(&line, "tracks.jsonl", 4).unwrap().unwrap();
    assert_eq!((sample.time_s, sample.tag.as_str()), (12.5, "miner-017"));
    assert_eq!(
        (sample.position_m, sample.has_z, sample.predicted, sample.line),
        ([10.0, -2.5, 1.75], true, false, 4)
    );
    assert_eq!(
        sample.covariance_m2.as_deref(),
        Some(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0][..])
    );
    // a covariance of the wrong size or nested is an error naming `cov`
    for bad in [r#"[[1, 0], [0, 1]]"#, "[1, 0, 0]", "[1, 0, 0, 1e999]"] {
        let line = format!(r#"{{"t": 1, "tag": "a", "x": 1, "y": 2, "cov": {bad}}}"#);
        let error = parse_track_line(&line, "tracks.jsonl", 2).unwrap_err().to_string();
        assert!(error.starts_with("tracks.jsonl:2: field `cov`"), "{error}");
    }
    // a raw fix: no velocity, no predicted flag
    let fix = parse_track_line(r#"{"t": 1, "tag": "a", "x": 1, "y": 2}"#, "fixes.jsonl", 1)
        .unwrap()
        .unwrap();
    assert_eq!(
        (fix.position_m, fix.has_z, fix.predicted),
        ([1.0, 2.0, 0.0], false, false)
    );
    let coasting = parse_track_line(r#"{"t": 1, "tag": "a", "x": 1, "y": 2, "predicted": true}"#, "-", 1)
        .unwrap()
        .unwrap();
    assert!(coasting.predicted);
    assert_eq!(parse_track_line(" \t ", "tracks.jsonl", 3).unwrap(), None);
    assert_eq!(parse_track_line("", "tracks.jsonl", 3).unwrap(), None);
}

#[test]
fn track_line_errors_name_line_and_key() {
    for (text, field, needle) in [
        (r#"{"t": 1, "tag": "a", "x": 1"#, "x", "EOF"),
        ("not json", "-", "expected"),
        (r#"[1, "a", 2, 3]"#, "-", "a track object"),
        (r#"{"tag": "a", "x": 1, "y": 2}"#, "t", "is missing"),
        (r#"{"t": 1, "x": 1, "y": 2}"#, "tag", "is missing"),
        (r#"{"t": 1, "tag": "a", "y": 2}"#, "x", "is missing"),
        (r#"{"t": 1, "tag": "a", "x": 2}"#, "y", "is missing"),
        (r#"{"t": 1, "tag": "a", "x": "2", "y": 2}"#, "x", "invalid type"),
        (
            r#"{"t": 1, "tag": "a", "x": 2, "y": 2, "z": null}"#,
            "z",
            "invalid type: null",
        ),
        (
            r#"{"t": 1, "tag": "a", "x": 2, "y": 2, "predicted": "yes"}"#,
            "predicted",
            "invalid type",
        ),
        (
            r#"{"t": 1, "tag": "a", "x": 2, "x": 3, "y": 2}"#,
            "x",
            "duplicate field",
        ),
        (r#"{"t": 1, "tag": "", "x": 2, "y": 2}"#, "tag", "is empty"),
        (r#"{"t": 1, "tag": 7, "x": 2, "y": 2}"#, "tag", "invalid type"),
        (
            r#"{"t": 1, "tag": "a", "x": 2, "y": 2} {"t": 2}"#,
            "-",
            "trailing characters",
        ),
        (r#"{"t": 1e999, "tag": "a", "x": 2, "y": 2}"#, "t", "out of range"),
    ] {
        let (file, line, got_field, message) = track_error(text);
        assert_eq!((file.as_str(), line), ("tracks.jsonl", 12));
        assert_eq!(got_field, field, "{text}: {message}");
        assert!(message.contains(needle), "{text}: {message}");
        assert!(
            message.starts_with(&format!("tracks.jsonl:12: field `{field}`")),
            "{message}"
        );
    }
}

#[test]
fn track_files_number_lines_from_one_counting_blank_ones() {
    let text =
        "{\"t\": 0, \"tag\": \"a\", \"x\": 1, \"y\": 2}\r\n\r\n  \n{\"t\": 1, \"tag\": \"b\", \"x\": 3, \"y\": 4}\n";
    let samples = parse_track_lines(text, "tracks.jsonl").unwrap();
    assert_eq!(
        samples.iter().map(|s| (s.tag.as_str(), s.line)).collect::<Vec<_>>(),
        [("a", 1), ("b", 4)]
    );
    let bad = "{\"t\": 0, \"tag\": \"a\", \"x\": 1, \"y\": 2}\n\n{\"t\": 1, \"tag\": \"b\", \"x\": 3}\n";
    let (_, line, field, _) = located(parse_track_lines(bad, "tracks.jsonl").unwrap_err());
    assert_eq!((line, field.as_str()), (3, "y"));
    assert!(parse_track_lines("", "tracks.jsonl").unwrap().is_empty());
}

#[test]
fn the_examples_of_docs_formats_parse() {
    let formats = include_str!("../../../../docs/FORMATS.md");
    let section = formats
        .split("\n## ")
        .find(|section| section.starts_with("Ground truth and track files"))
        .expect("docs/FORMATS.md has the section");
    let block = |language: &str| -> &str {
        let start = section.find(&format!("```{language}\n")).unwrap() + language.len() + 4;
        &section[start..start + section[start..].find("```").unwrap()]
    };
    let truth = parse_truth_csv(block("csv"), "FORMATS.md").unwrap();
    assert_eq!(truth.len(), 3);
    assert_eq!(
        (truth[2].tag.as_str(), truth[2].position_m, truth[2].has_z),
        ("drone-2", [4.0, 0.5, 1.2], true)
    );
    let tracks = parse_track_lines(block("json"), "FORMATS.md").unwrap();
    assert_eq!(tracks.len(), 3);
    assert_eq!((tracks[1].predicted, tracks[2].has_z), (true, true));
    // the error messages quoted there
    let error = parse_truth_csv("t,tag,x,y,z\n0,a,0,0,\n# comment\n1,a,10,ten,\n", "truth.csv").unwrap_err();
    assert!(section.contains(&format!("``{error}``")), "{error}");
    let error = parse_track_line(r#"{"t": 3, "tag": "a", "x": "north", "y": 0}"#, "tracks.jsonl", 7).unwrap_err();
    let quoted = error.to_string();
    let quoted = &quoted[..quoted.find(" at line").unwrap()];
    assert!(section.contains(&format!("``{quoted} …``")), "{quoted}");
}
