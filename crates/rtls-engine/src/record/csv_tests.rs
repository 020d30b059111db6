use super::*;
use crate::record::tests::located;

const HEADER: &str =
    "t,tag,kind,anchor,reference,value,std,heading,heading_std,x,y,z,covariance,readings,interval,rate,rate_std";

fn header_error(text: &str) -> (usize, String) {
    let error = CsvRecords::from_text(text, "in.csv").unwrap_err();
    let (file, line, field) = located(&error);
    assert_eq!(file, "in.csv");
    (line, field.to_string())
}

/// The (line, column) of the error of the single data row `row` under the full header.
fn row_error(row: &str) -> (usize, String) {
    // the rows below spell out the first 14 columns; the last three (interval, rate, rate_std)
    // are empty
    let text = format!("{HEADER}\n{row},,,\n");
    let mut records = CsvRecords::from_text(&text, "in.csv").unwrap();
    let error = records.next().unwrap().unwrap_err();
    let (file, line, field) = located(&error);
    assert_eq!(file, "in.csv");
    (line, field.to_string())
}

#[test]
fn header_columns_are_checked() {
    assert_eq!(header_error("t,tag,kind,rssi\n"), (1, "rssi".into()));
    assert_eq!(header_error("t,tag,kind,value,value\n"), (1, "value".into()));
    assert_eq!(header_error("t,kind,anchor,value\n"), (1, "tag".into()));
    assert_eq!(header_error(""), (0, "-".into()));
    assert_eq!(header_error("\n# only a comment\n"), (2, "-".into()));
    // Comment lines before the header are skipped and counted.
    assert_eq!(header_error("# records\nt,tag,kind,bogus\n"), (2, "bogus".into()));
}

#[test]
fn columns_may_be_left_out_and_reordered() {
    let text = "kind,value,tag,t,anchor\nrssi,-70,a,1.5,R1\n";
    let records: Vec<Record> = CsvRecords::from_text(text, "in.csv")
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(
        records,
        [Record {
            time_s: 1.5,
            tag: "a".into(),
            measurement: Measurement::Rssi {
                anchor: "R1".into(),
                rssi_dbm: -70.0
            }
        }]
    );
}

#[test]
fn cells_a_kind_does_not_use_are_errors() {
    assert_eq!(row_error("1,a,rssi,R1,,-70,0.5,,,,,,,"), (2, "std".into()));
    assert_eq!(row_error("1,a,range,R1,S2,4,,,,,,,,"), (2, "reference".into()));
    assert_eq!(row_error("1,a,fix,R1,,,,,,1,2,,1;0;0;1,"), (2, "anchor".into()));
    assert_eq!(row_error("1,a,velocity,,,,,,,1,2,,,R1=-40"), (2, "readings".into()));
}

#[test]
fn missing_cells_name_the_column() {
    assert_eq!(row_error(",a,rssi,R1,,-70,,,,,,,,"), (2, "t".into()));
    assert_eq!(row_error("1,,rssi,R1,,-70,,,,,,,,"), (2, "tag".into()));
    assert_eq!(row_error("1,a,,R1,,-70,,,,,,,,"), (2, "kind".into()));
    assert_eq!(row_error("1,a,rssi,,,-70,,,,,,,,"), (2, "anchor".into()));
    assert_eq!(row_error("1,a,range,R1,,,,,,,,,,"), (2, "value".into()));
    assert_eq!(row_error("1,a,tdoa,R1,,3,,,,,,,,"), (2, "reference".into()));
    assert_eq!(row_error("1,a,odometry_increment,,,3,,,,,,,,"), (2, "heading".into()));
    assert_eq!(row_error("1,a,imu,,,,,,,1,2,,,"), (2, "rate".into()));
    assert_eq!(row_error("1,a,fix,,,,,,,1,,,1;0;0;1,"), (2, "y".into()));
    assert_eq!(row_error("1,a,fix,,,,,,,1,2,,,"), (2, "covariance".into()));
    assert_eq!(row_error("1,a,rssi_vector,,,,,,,,,,,"), (2, "readings".into()));
    assert_eq!(
        row_error("1,a,pseudorange,,,2.2e7,,,,1.5e7,7e6,,,"),
        (2, "anchor".into())
    );
    assert_eq!(row_error("1,a,pseudorange,G05,,2.2e7,,,,1.5e7,7e6,,,"), (2, "z".into()));
    assert_eq!(
        row_error("1,a,pseudorange,G05,,,,,,1.5e7,7e6,2e7,,"),
        (2, "value".into())
    );
    // a satellite position in km is named by its columns
    assert_eq!(
        row_error("1,a,pseudorange,G05,,2.2e7,,,,1.5e4,7e3,2e4,,"),
        (2, "x,y,z".into())
    );
}

#[test]
fn bad_numbers_name_the_column() {
    assert_eq!(row_error("noon,a,rssi,R1,,-70,,,,,,,,"), (2, "t".into()));
    assert_eq!(row_error("1,a,rssi,R1,,NaN,,,,,,,,"), (2, "value".into()));
    assert_eq!(row_error("1,a,accelerometer,,,,,,,1,2,inf,,"), (2, "z".into()));
    assert_eq!(row_error("1,a,fix,,,,,,,1,2,,1;x;0;1,"), (2, "covariance".into()));
    assert_eq!(row_error("1,a,rssi_vector,,,,,,,,,,,R1=-70;R2"), (2, "readings".into()));
    assert_eq!(row_error("1,a,rssi_vector,,,,,,,,,,,R1=loud"), (2, "readings".into()));
}

#[test]
fn validation_errors_name_the_csv_column() {
    assert_eq!(row_error("1,a,range,R1,,nan,,,,,,,,"), (2, "value".into()));
    assert_eq!(row_error("1e16,a,range,R1,,4,,,,,,,,"), (2, "t".into()));
    // Wi-Fi FTM/RTT gives negative ranges for close devices: finite ones are accepted
    let text = format!("{HEADER}\n1,a,range,R1,,-0.4,,,,,,,,,,,\n");
    assert!(CsvRecords::from_text(&text, "in.csv").unwrap().next().unwrap().is_ok());
    assert_eq!(row_error("1,a,range,R1,,4,-1,,,,,,,"), (2, "std".into()));
    assert_eq!(row_error("1,a,tdoa,R1,R1,3,,,,,,,,"), (2, "reference".into()));
    assert_eq!(row_error("1,a,odometry,,,3,,1,-0.1,,,,,"), (2, "heading_std".into()));
    assert_eq!(row_error("1,a,fix,,,,,,,1,2,,1;0.5;0;1,"), (2, "covariance".into()));
    assert_eq!(row_error("1,a,fix,,,,,,,1,2,3,1;0;0;1,"), (2, "covariance".into()));
    assert_eq!(
        row_error("1,a,rssi_vector,,,,,,,,,,,R1=-70;R1=-71"),
        (2, "readings".into())
    );
    assert_eq!(row_error("1,a;b,rssi,R1,,-70,,,,,,,,"), (2, "tag".into()));
}

#[test]
fn unknown_kind_is_an_error() {
    assert_eq!(row_error("1,a,lidar,,,,,,,,,,,"), (2, "kind".into()));
}

#[test]
fn short_rows_are_errors_and_reading_continues() {
    let text = format!("{HEADER}\n# comment\n\n1,a,rssi,R1\n2,a,rssi,R1,,-70,,,,,,,,,,,\n");
    let results: Vec<Result<Record>> = CsvRecords::from_text(&text, "in.csv").unwrap().collect();
    assert_eq!(results.len(), 2);
    let error = results[0].as_ref().unwrap_err();
    assert_eq!(located(error), ("in.csv", 4, "-"));
    assert!(
        error.to_string().contains("row has 4 cells but the header has 17"),
        "{error}"
    );
    assert_eq!(results[1].as_ref().unwrap().time_s, 2.0);
}

#[test]
fn quoted_cells_and_spaces_are_read() {
    let text = "t, tag, kind, anchor, value\n 1.0 ,\"miner, 17\", rssi , R1 , -70 \n";
    let record = CsvRecords::from_text(text, "in.csv").unwrap().next().unwrap().unwrap();
    assert_eq!(record.tag, "miner, 17");
    assert_eq!(
        record.measurement,
        Measurement::Rssi {
            anchor: "R1".into(),
            rssi_dbm: -70.0
        }
    );
}

#[test]
fn every_kind_is_written_in_its_own_columns() {
    for measurement in crate::record::tests::sample_measurements() {
        let record = Record {
            time_s: 3.25,
            tag: "x".into(),
            measurement,
        };
        let row = to_csv_row(&record);
        let line = format!("{HEADER}\n{}\n", row.join(","));
        let parsed = CsvRecords::from_text(&line, "w.csv").unwrap().next().unwrap().unwrap();
        assert_eq!(parsed, record, "{line}");
    }
}

#[test]
fn non_utf8_rows_are_errors_and_reading_continues() {
    let mut bytes = format!("{HEADER}\n").into_bytes();
    bytes.extend_from_slice(b"1,\xff,rssi,R1,,-70,,,,,,,,,,,\n");
    bytes.extend_from_slice(b"2,a,rssi,R1,,-70,,,,,,,,,,,\n");
    let results: Vec<Result<Record>> = CsvRecords::new(bytes.as_slice(), "bin.csv").unwrap().collect();
    assert_eq!(results.len(), 2);
    let error = results[0].as_ref().unwrap_err();
    assert_eq!(located(error), ("bin.csv", 2, "-"));
    assert!(error.to_string().contains("UTF-8"), "{error}");
    assert!(results[1].is_ok());
}
