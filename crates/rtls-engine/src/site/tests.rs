//! Site loading tests: the two example files, and every error path with its line and key path.

use super::*;
use crate::zones::{Shape, ZoneKind};

const EXAMPLE: &str = include_str!("../../../../examples/site.toml");
const MINE: &str = include_str!("../../../../examples/mine-site.toml");

const TRACKER: &str = r#"
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "kf"
acceleration_noise_std_mps2 = 1.0
gate_probability = 0.99
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 10.0
delete_timeout_s = 60.0
reorder_window_s = 0.5
"#;

const READERS: &str = r#"
[[readers]]
id = "A"
position_m = [0.0, 0.0]
technology = "ble"

[[readers]]
id = "B"
position_m = [10.0, 0.0, 3.0]
technology = "uwb"
"#;

/// Loads `text` and returns (line, field, reason) of the error.
fn error_of(text: &str) -> (usize, String, String) {
    match Site::from_toml_str(text, "bad.toml") {
        Err(EngineError::Parse {
            file,
            line,
            field,
            reason,
        }) => {
            assert_eq!(file, "bad.toml");
            (line, field, reason)
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

fn line_containing(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn the_annotated_example_loads() {
    let site = Site::from_toml_str(EXAMPLE, "site.toml").unwrap();
    assert_eq!(site.readers.len(), 7);
    let a1 = site.reader("A1").unwrap();
    assert_eq!(a1.technology, Technology::Uwb);
    assert_eq!(a1.radio.unwrap().range.unwrap().range_std_m, 0.10);
    assert!(!site.reader("A4").unwrap().working);
    let b1 = site.reader("B1").unwrap().radio.unwrap().path_loss.unwrap();
    assert_eq!((b1.exponent, b1.reference_power_dbm), (2.2, -59.0));
    assert_eq!(site.floor("mezzanine").unwrap().z_range_m, [3.5, 7.0]);
    // the floor was resolved into the polygon's height range
    let bay = site.zone("loading-bay").unwrap();
    assert!(matches!(
        bay.shape,
        Shape::Polygon {
            z_range_m: Some([0.0, 3.5]),
            ..
        }
    ));
    assert!(bay.contains([1.0, 10.0, 1.0]));
    assert!(!bay.contains([8.0, 8.0, 1.0])); // the notch of the L
    assert!(!bay.contains([1.0, 10.0, 5.0])); // the floor above
    assert_eq!(site.zone("server-room").unwrap().kind, ZoneKind::Restricted);
    assert_eq!(site.tracker.pipeline, Pipeline::TightlyCoupled);
    assert_eq!(site.tracker.filter, FilterKind::Ekf);
    assert_eq!(site.tracker.initiation.confirm_updates, 3);
    assert_eq!(site.zone_events.dwell_interval_s, Some(60.0));
    let db = site.fingerprints.as_ref().unwrap();
    assert_eq!(
        (db.format, db.readers.as_slice()),
        (
            FingerprintFormat::Csv,
            &["B1".to_string(), "B2".into(), "B3".into()][..]
        )
    );
    assert_eq!(site.zone_monitor().unwrap().zones().len(), 3);
}

#[test]
fn the_mine_example_loads_and_flags_the_collapse() {
    let site = Site::from_toml_str(MINE, "mine-site.toml").unwrap();
    let broken: Vec<&str> = site
        .readers
        .iter()
        .filter(|r| !r.working)
        .map(|r| r.id.as_str())
        .collect();
    assert_eq!(broken, ["R4"]);
    let collapse = site.zone("collapse-r4").unwrap();
    assert_eq!(collapse.kind, ZoneKind::Hazard);
    assert_eq!(collapse.readers, ["R4"]);
    let r4 = site.reader("R4").unwrap().position_xyz_m();
    assert!(collapse.contains(r4));
    // a miner walking along the tunnel at 1.2 m/s, 20 s ahead: predicted to reach it
    assert!(collapse.segment_enters([270.0, 2.0, 1.5], [294.0, 2.0, 1.5]));
    assert_eq!(site.tracker.motion_model, MotionModelKind::Cv);
}

#[test]
fn a_minimal_site_has_defaults() {
    let site = Site::from_toml_str(&format!("{READERS}{TRACKER}"), "min.toml").unwrap();
    assert_eq!(site.reader("A").unwrap().position_xyz_m(), [0.0, 0.0, 0.0]);
    assert!(site.reader("A").unwrap().working);
    assert!(site.zones.is_empty() && site.floors.is_empty() && site.fingerprints.is_none());
    assert_eq!(site.zone_events, ZoneEventSettings::default());
    assert!(site.zone_monitor().is_ok());
}

#[test]
fn syntax_type_and_unknown_key_errors_name_line_and_key() {
    let text = format!("{READERS}{TRACKER}").replace("technology = \"uwb\"", "technology = \"pigeon\"");
    let (line, field, reason) = error_of(&text);
    assert_eq!(
        (line, field.as_str()),
        (line_containing(&text, "pigeon"), "readers[1].technology")
    );
    assert!(reason.contains("uwb"), "{reason}");

    let text = format!("{READERS}colour = \"red\"\n{TRACKER}");
    let (line, field, reason) = error_of(&text);
    assert_eq!(
        (line, field.as_str()),
        (line_containing(&text, "colour"), "readers[1].colour")
    );
    assert!(reason.contains("unknown field"), "{reason}");

    let text = format!("{READERS}{TRACKER}").replace("gate_probability = 0.99", "gate_probability = \"high\"");
    let (line, field, _) = error_of(&text);
    assert_eq!(
        (line, field.as_str()),
        (line_containing(&text, "high"), "tracker.gate_probability")
    );

    let text = format!("{READERS}{TRACKER}").replace("id = \"B\"\n", "");
    let (_, field, reason) = error_of(&text);
    assert!(field.ends_with("id"), "{field}");
    assert!(reason.contains("missing field"), "{reason}");

    let (line, _, _) = error_of("[[readers]\nid = 1\n");
    assert_eq!(line, 1);
    // every [tracker] key has a default (site::platform), so readers alone are a site
    assert!(Site::from_toml_str(READERS, "readers-only.toml").is_ok());
}

#[test]
fn reader_errors_name_the_reader() {
    let cases = [
        (
            "position_m = [10.0, 0.0, 3.0]",
            "position_m = [10.0]",
            "readers[1].position_m",
        ),
        (
            "position_m = [10.0, 0.0, 3.0]",
            "position_m = [1.0, 2.0, 3.0, 4.0]",
            "readers[1].position_m",
        ),
        (
            "position_m = [10.0, 0.0, 3.0]",
            "position_m = [nan, 0.0]",
            "readers[1].position_m",
        ),
        ("id = \"B\"", "id = \"A\"", "readers[1].id"),
        ("id = \"B\"", "id = \" \"", "readers[1].id"),
    ];
    for (from, to, expected) in cases {
        let text = format!("{READERS}{TRACKER}").replace(from, to);
        let (line, field, reason) = error_of(&text);
        assert_eq!(field, expected, "{to}: {reason}");
        // the changed line is in the second reader (`id = "A"` also names the first)
        let last = text
            .lines()
            .collect::<Vec<_>>()
            .iter()
            .rposition(|l| l.contains(to))
            .unwrap()
            + 1;
        assert_eq!(line, last, "{to}");
    }
    let radio = |table: &str| format!("{READERS}radio = {{ {table} }}\n{TRACKER}");
    for (table, expected) in [
        (
            "path_loss = { reference_power_dbm = -40.0, exponent = 0.0, shadowing_std_db = 4.0, reference_distance_m = 1.0 }",
            "readers[1].radio.path_loss.exponent",
        ),
        (
            "path_loss = { reference_power_dbm = inf, exponent = 2.0, shadowing_std_db = 4.0, reference_distance_m = 1.0 }",
            "readers[1].radio.path_loss.reference_power_dbm",
        ),
        (
            "path_loss = { reference_power_dbm = -40.0, exponent = 2.0, shadowing_std_db = -1.0, reference_distance_m = 1.0 }",
            "readers[1].radio.path_loss.shadowing_std_db",
        ),
        (
            "path_loss = { reference_power_dbm = -40.0, exponent = 2.0, shadowing_std_db = 1.0, reference_distance_m = 0.0 }",
            "readers[1].radio.path_loss.reference_distance_m",
        ),
        ("range = { range_std_m = 0.0, bias_m = 0.0 }", "readers[1].radio.range.range_std_m"),
        ("range = { range_std_m = 0.1, bias_m = nan }", "readers[1].radio.range.bias_m"),
    ] {
        let text = radio(table);
        let (line, field, _) = error_of(&text);
        assert_eq!(field, expected);
        assert_eq!(line, line_containing(&text, "radio ="));
    }
}

const ZONE: &str = r#"
[[floors]]
id = "L1"
z_range_m = [0.0, 3.0]

[[zones]]
id = "z1"
name = "Zone 1"
kind = "hazard"
readers = ["A"]
shape = { type = "polygon", vertices_m = [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]], floor = "L1" }
"#;

#[test]
fn zone_and_floor_errors_name_the_zone() {
    let base = format!("{READERS}{ZONE}{TRACKER}");
    assert!(Site::from_toml_str(&base, "ok.toml").is_ok());
    let cases = [
        (
            "readers = [\"A\"]",
            "readers = [\"A\", \"Q\"]",
            "zones[0].readers[1]",
            "unknown reader `Q`",
        ),
        (
            "floor = \"L1\"",
            "floor = \"L9\"",
            "zones[0].shape.floor",
            "unknown floor",
        ),
        (
            "floor = \"L1\"",
            "floor = \"L1\", z_range_m = [0.0, 1.0]",
            "zones[0].shape.floor",
            "not both",
        ),
        (
            "[5.0, 5.0]]",
            "[5.0, 5.0], [0.0, 0.0]]",
            "zones[0].shape.vertices_m[3]",
            "repeats",
        ),
        (
            "[5.0, 5.0]]",
            "[0.0, 5.0], [5.0, 5.0]]",
            "zones[0].shape.vertices_m",
            "simple",
        ),
        (
            "z_range_m = [0.0, 3.0]",
            "z_range_m = [3.0, 0.0]",
            "floors[0].z_range_m",
            "z_min < z_max",
        ),
        ("id = \"L1\"", "id = \"\"", "floors[0].id", "empty"),
    ];
    for (from, to, expected, why) in cases {
        let text = base.replace(from, to);
        let (line, field, reason) = error_of(&text);
        assert_eq!(field, expected, "{to}: {reason}");
        assert!(reason.contains(why), "{reason}");
        assert_eq!(line, line_containing(&text, to), "{to}");
    }
    let twice = format!(
        "{READERS}{ZONE}{}{TRACKER}",
        ZONE.split("[[zones]]").nth(1).map(|z| format!("[[zones]]{z}")).unwrap()
    );
    let (line, field, reason) = error_of(&twice);
    assert_eq!(field, "zones[1].id");
    assert!(reason.contains("duplicate"), "{reason}");
    assert_eq!(
        line,
        twice
            .lines()
            .enumerate()
            .filter(|(_, l)| l.contains("id = \"z1\""))
            .nth(1)
            .unwrap()
            .0
            + 1
    );
    let boxed = base.replace(
        "shape = { type = \"polygon\", vertices_m = [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]], floor = \"L1\" }",
        "shape = { type = \"box\", min_m = [0.0, 0.0, 0.0], max_m = [1.0, 1.0, 0.0] }",
    );
    assert_eq!(error_of(&boxed).1, "zones[0].shape.max_m");
    let bad_kind = base.replace("kind = \"hazard\"", "kind = \"lava\"");
    assert_eq!(error_of(&bad_kind).1, "zones[0].kind");
}

#[test]
fn fingerprint_errors_name_the_key() {
    let db = |body: &str| format!("{READERS}[fingerprints]\n{body}\n{TRACKER}");
    assert!(Site::from_toml_str(&db("path = \"m.csv\"\nformat = \"csv\"\nreaders = [\"A\"]"), "ok").is_ok());
    assert_eq!(error_of(&db("path = \"\"\nformat = \"csv\"")).1, "fingerprints.path");
    let text = db("path = \"m.csv\"\nformat = \"csv\"\nreaders = [\"A\", \"Z\"]");
    assert_eq!(
        error_of(&text),
        (
            line_containing(&text, "\"Z\""),
            "fingerprints.readers[1]".into(),
            "unknown reader `Z`: not among the site's readers".into()
        )
    );
    assert_eq!(error_of(&db("path = \"m\"\nformat = \"xml\"")).1, "fingerprints.format");
}

#[test]
fn tracker_errors_name_the_key() {
    let base = format!("{READERS}{TRACKER}");
    let cases = [
        (
            "pipeline = \"fix-then-filter\"",
            "pipeline = \"tightly-coupled\"",
            "tracker.filter",
        ),
        (
            "acceleration_noise_std_mps2 = 1.0",
            "acceleration_noise_std_mps2 = 0.0",
            "tracker.acceleration_noise_std_mps2",
        ),
        (
            "gate_probability = 0.99",
            "gate_probability = 1.0",
            "tracker.gate_probability",
        ),
        (
            "confirm_updates = 3",
            "confirm_updates = 0",
            "tracker.initiation.confirm_updates",
        ),
        ("within_s = 5.0", "within_s = -5.0", "tracker.initiation.within_s"),
        (
            "coast_timeout_s = 10.0",
            "coast_timeout_s = nan",
            "tracker.coast_timeout_s",
        ),
        (
            "delete_timeout_s = 60.0",
            "delete_timeout_s = 5.0",
            "tracker.delete_timeout_s",
        ),
        (
            "reorder_window_s = 0.5",
            "reorder_window_s = -0.1",
            "tracker.reorder_window_s",
        ),
        (
            "motion_model = \"cv\"",
            "motion_model = \"singer\"",
            "tracker.motion_model",
        ),
    ];
    for (from, to, expected) in cases {
        let text = base.replace(from, to);
        let (line, field, reason) = error_of(&text);
        assert_eq!(field, expected, "{to}: {reason}");
        // the tightly-coupled/kf clash is reported at the filter key
        let needle = if expected == "tracker.filter" { "filter = " } else { to };
        let needle = if expected.starts_with("tracker.initiation") {
            "initiation"
        } else {
            needle
        };
        assert_eq!(line, line_containing(&text, needle), "{to}");
    }
    for filter in ["ekf", "ukf"] {
        let text = base
            .replace("\"fix-then-filter\"", "\"tightly-coupled\"")
            .replace("filter = \"kf\"", &format!("filter = \"{filter}\""));
        assert!(Site::from_toml_str(&text, "ok").is_ok());
    }
}

#[test]
fn zone_event_errors_name_the_key() {
    let with = |body: &str| format!("{READERS}[zone_events]\n{body}\n{TRACKER}");
    assert!(Site::from_toml_str(&with("tolerance_m = 1.0\ndelay_s = 2.0"), "ok").is_ok());
    assert_eq!(
        error_of(&with("tolerance_m = -1.0\ndelay_s = 2.0")).1,
        "zone_events.tolerance_m"
    );
    assert_eq!(
        error_of(&with("tolerance_m = 1.0\ndelay_s = inf")).1,
        "zone_events.delay_s"
    );
    let text = with("tolerance_m = 1.0\ndelay_s = 2.0\ndwell_interval_s = 0.0");
    assert_eq!(error_of(&text).0, line_containing(&text, "dwell_interval_s"));
    assert_eq!(error_of(&with("tolerance_m = 1.0")).1, "zone_events.delay_s");
}

#[test]
fn the_frame_origin_and_gnss_settings_are_range_checked() {
    let example = include_str!("../../../../examples/site.toml");
    let site = Site::from_toml_str(example, "site.toml").unwrap();
    let origin = site.frame.unwrap().origin;
    assert_eq!((origin.latitude_deg, origin.longitude_deg), (47.3769, 8.5417));
    assert_eq!(site.tracker.gnss, GnssSettings::default());
    for (from, to, field) in [
        (
            "latitude_deg = 47.3769",
            "latitude_deg = 91.0",
            "frame.origin.latitude_deg",
        ),
        ("height_m = 455.0", "height_m = 4.55e6", "frame.origin.height_m"),
        (
            "pseudorange_std_m = 5.0",
            "pseudorange_std_m = 0.0",
            "tracker.gnss.pseudorange_std_m",
        ),
        (
            "clock_drift_noise_m2ps3 = 0.1",
            "clock_drift_noise_m2ps3 = 1e300",
            "tracker.gnss.clock_drift_noise_m2ps3",
        ),
    ] {
        let error = Site::from_toml_str(&example.replace(from, to), "site.toml").unwrap_err();
        assert!(error.to_string().contains(&format!("field `{field}`")), "{error}");
        assert!(error.to_string().contains("outside the allowed range"), "{error}");
    }
    // without [frame]: no origin
    let start = example.find("[frame]").unwrap();
    let end = start + example[start..].find("\n\n").unwrap();
    let site = Site::from_toml_str(&format!("{}{}", &example[..start], &example[end..]), "site.toml").unwrap();
    assert!(site.frame.is_none());
}
