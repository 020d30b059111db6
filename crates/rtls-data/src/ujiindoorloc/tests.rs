//! Reader tests on synthetic files: the header, the sentinel, and errors that name the line
//! and the field.

use std::path::Path;

use super::*;

fn header() -> String {
    let mut names: Vec<String> = (1..=ACCESS_POINTS).map(|k| format!("WAP{k:03}")).collect();
    names.extend(LABEL_COLUMNS.iter().map(|s| (*s).to_string()));
    names.join(",")
}

fn row(heard: &[(usize, &str)], labels: [&str; 9]) -> String {
    let mut fields = vec!["100".to_string(); ACCESS_POINTS];
    for &(ap, value) in heard {
        fields[ap] = value.to_string();
    }
    fields.extend(labels.iter().map(|s| (*s).to_string()));
    fields.join(",")
}

const LABELS: [&str; 9] = ["-7500.5", "4864900.25", "2", "1", "106", "2", "2", "23", "1371713733"];

fn parse(text: &str) -> Result<Vec<Fingerprint>> {
    read(text.as_bytes(), Path::new("t.csv"))
}

fn parse_error(text: &str) -> (u64, String, String) {
    match parse(text) {
        Err(DataError::Parse {
            line, field, reason, ..
        }) => (line, field, reason),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn records_are_parsed_and_the_sentinel_becomes_absence() {
    let text = format!(
        "{}\n{}\n{}\n",
        header(),
        row(&[(0, "-45"), (519, "-104"), (7, "0")], LABELS),
        row(&[], LABELS)
    );
    let records = parse(&text).unwrap();
    assert_eq!(records.len(), 2);
    assert_eq!(records[0].readings_dbm, vec![(0, -45.0), (7, 0.0), (519, -104.0)]);
    assert_eq!(records[0].position_m, [-7500.5, 4864900.25]);
    assert_eq!(
        (
            records[0].floor,
            records[0].building,
            records[0].space_id,
            records[0].phone_id
        ),
        (2, 1, 106, 23)
    );
    assert_eq!(records[0].timestamp_s, 1_371_713_733);
    assert!(records[1].readings_dbm.is_empty());
    let query = records[0].query();
    assert_eq!((query[0], query[1], query[519]), (Some(-45.0), None, Some(-104.0)));
    let survey = survey(&records);
    assert_eq!(survey.readings_dbm[0], records[0].readings_dbm);
    assert_eq!(survey.floors, Some(vec![2, 2]));
}

#[test]
fn errors_name_the_line_and_the_field() {
    // line 3 (second record), WAP006 off the scale
    let text = format!("{}\n{}\n{}\n", header(), row(&[], LABELS), row(&[(5, "-120")], LABELS));
    let (line, field, reason) = parse_error(&text);
    assert_eq!((line, field.as_str()), (3, "WAP006"));
    assert!(reason.contains("-120"), "{reason}");
    // a non-numeric label
    let mut labels = LABELS;
    labels[2] = "ground";
    let (line, field, _) = parse_error(&format!("{}\n{}\n", header(), row(&[], labels)));
    assert_eq!((line, field.as_str()), (2, "FLOOR"));
    // a fractional building
    labels = LABELS;
    labels[3] = "1.5";
    let (_, field, _) = parse_error(&format!("{}\n{}\n", header(), row(&[], labels)));
    assert_eq!(field, "BUILDINGID");
    // NaN coordinates
    labels = LABELS;
    labels[0] = "NaN";
    let (_, field, _) = parse_error(&format!("{}\n{}\n", header(), row(&[], labels)));
    assert_eq!(field, "LONGITUDE");
    // a short record
    let short = format!("{}\n{}\n", header(), "100,100");
    let (line, _, _) = parse_error(&short);
    assert_eq!(line, 2);
    // a wrong header name
    let bad_header = header().replace("WAP017", "WAP17");
    let (line, field, reason) = parse_error(&format!("{bad_header}\n{}\n", row(&[], LABELS)));
    assert_eq!((line, field.as_str()), (1, "column 17"));
    assert!(reason.contains("WAP017"));
    // no records
    assert!(matches!(
        parse(&format!("{}\n", header())),
        Err(DataError::Content { .. })
    ));
    // a missing file names the file
    let missing = load(Path::new("/nonexistent/uji.csv")).unwrap_err();
    assert!(missing.to_string().contains("/nonexistent/uji.csv"), "{missing}");
}
