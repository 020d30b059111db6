//! `examples/site.toml` shows every key the loader accepts. The keys are read from the serde
//! structs themselves (each struct's `deny_unknown_fields` error lists its fields), so a key
//! added to a struct — e.g. a new `[tracker]` setting — fails this test until the example
//! documents it.

use std::collections::BTreeSet;

use serde::de::DeserializeOwned;

use super::*;
use crate::association::AnonymousTrackerSettings;
use crate::lifecycle::LifecycleSettings;
use crate::zones::Shape;

const EXAMPLE: &str = include_str!("../../../../examples/site.toml");

/// The fields a struct accepts, from the error of deserialising an unknown key (`before` puts
/// e.g. an enum's tag first).
fn fields_of<T: DeserializeOwned + std::fmt::Debug>(before: &str) -> Vec<String> {
    let text = format!("{before}__probe__ = 0\n");
    let error = toml::from_str::<T>(&text).expect_err("the probe key must be unknown");
    let message = error.message().to_string();
    let (_, expected) = message
        .split_once("expected")
        .unwrap_or_else(|| panic!("not an unknown-field error: {message}"));
    let fields: Vec<String> = expected.split('`').skip(1).step_by(2).map(str::to_string).collect();
    assert!(!fields.is_empty(), "{message}");
    fields
}

/// Every key path of the site structs, arrays written `[]` (`readers[].radio.range.bias_m`).
fn accepted_keys() -> BTreeSet<String> {
    // (path of the table, its fields); a new nested struct needs a line here, a new key does not
    let tables: Vec<(&str, Vec<String>)> = vec![
        ("", fields_of::<Site>("")),
        ("frame", fields_of::<FrameSettings>("")),
        ("frame.origin", fields_of::<GeodeticOrigin>("")),
        ("readers[]", fields_of::<Reader>("")),
        ("readers[].radio", fields_of::<Radio>("")),
        ("readers[].radio.path_loss", fields_of::<PathLoss>("")),
        ("readers[].radio.range", fields_of::<RangeErrors>("")),
        ("corridors[]", fields_of::<Corridor>("")),
        ("floors[]", fields_of::<Floor>("")),
        ("floors[].plan", fields_of::<FloorPlan>("")),
        ("zones[]", fields_of::<crate::zones::Zone>("")),
        ("zones[].shape", fields_of::<Shape>("type = \"polygon\"\n")),
        ("zones[].shape", fields_of::<Shape>("type = \"box\"\n")),
        ("zone_events", fields_of::<ZoneEventSettings>("")),
        ("fingerprints", fields_of::<FingerprintDatabase>("")),
        ("tracker", fields_of::<TrackerSettings>("")),
        ("tracker.initiation", fields_of::<Initiation>("")),
        ("tracker.imm", fields_of::<ImmSettings>("")),
        ("tracker.adaptive_noise", fields_of::<AdaptiveNoiseSettings>("")),
        ("tracker.heading", fields_of::<HeadingSettings>("")),
        ("tracker.range_bias", fields_of::<RangeBiasSettings>("")),
        ("tracker.consistency", fields_of::<ConsistencySettings>("")),
        ("tracker.gnss", fields_of::<GnssSettings>("")),
        ("tracker.map", fields_of::<MapSettings>("")),
        ("anonymous", fields_of::<AnonymousTrackerSettings>("")),
        ("anonymous.lifecycle", fields_of::<LifecycleSettings>("")),
        ("scheduling", fields_of::<SchedulingSettings>("")),
        ("scheduling.cells[]", fields_of::<SchedulingCell>("")),
        ("alarms", fields_of::<AlarmSettings>("")),
        ("muster", fields_of::<crate::zones::MusterSettings>("")),
    ];
    // the shape enum's tag
    let mut keys = BTreeSet::from(["zones[].shape.type".to_string()]);
    for (table, fields) in tables {
        for field in fields {
            keys.insert(if table.is_empty() {
                field
            } else {
                format!("{table}.{field}")
            });
        }
    }
    keys
}

/// Every key path present in a TOML value, arrays written `[]`.
fn present_keys(value: &toml::Value, prefix: &str, keys: &mut BTreeSet<String>) {
    match value {
        toml::Value::Table(table) => {
            for (key, value) in table {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                keys.insert(path.clone());
                present_keys(value, &path, keys);
            }
        }
        toml::Value::Array(items) => {
            for item in items.iter().filter(|item| item.is_table()) {
                present_keys(item, &format!("{prefix}[]"), keys);
            }
        }
        _ => {}
    }
}

#[test]
fn the_example_shows_every_key_the_loader_accepts() {
    let accepted = accepted_keys();
    // the probe sees the keys (a sanity check of the probe itself)
    for key in [
        "tracker.output_interval_s",
        "tracker.imm.switch_probability",
        "zones[].shape.min_m",
    ] {
        assert!(accepted.contains(key), "{key} not in {accepted:?}");
    }
    let value: toml::Value = toml::from_str(EXAMPLE).unwrap();
    let mut present = BTreeSet::new();
    present_keys(&value, "", &mut present);
    let missing: Vec<&String> = accepted.iter().filter(|k| !present.contains(*k)).collect();
    assert!(
        missing.is_empty(),
        "examples/site.toml does not show these keys the loader accepts (add each, with its unit, \
         range and default): {missing:?}"
    );
    // and every key it shows is accepted (arrays of plain values are not tables)
    let unknown: Vec<&String> = present.iter().filter(|k| !accepted.contains(*k)).collect();
    assert!(unknown.is_empty(), "{unknown:?}");
}

#[test]
fn the_example_and_its_radio_map_load() {
    let site = Site::from_toml_str(EXAMPLE, "examples/site.toml").unwrap();
    let db = site.fingerprints.as_ref().unwrap();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(&db.path);
    let text = read_text_file(&path, MAX_RADIO_MAP_BYTES, "radio map").unwrap();
    let map = crate::radio_map::RadioMap::from_csv_str(&text, "radio-map.csv", &site).unwrap();
    assert_eq!(map.reader_ids(), ["B1", "B2", "B3"]);
    assert_eq!(map.neighbours(), db.neighbours);
    assert_eq!(map.signal_space().representation.floor_dbm(), db.noise_floor_dbm);
    assert_eq!(Some(map.min_std_m()), db.min_std_m);
    assert!(map.calibration().is_some());
    assert!(crate::tracker::Tracker::new(&site).is_ok());
}

#[test]
fn the_fingerprint_and_imm_settings_are_read_from_the_site() {
    let text = EXAMPLE
        .replace("neighbours = 3", "neighbours = 5")
        .replace("noise_floor_dbm = -104.0", "noise_floor_dbm = -100.0")
        .replace(
            "cv_acceleration_noise_std_mps2 = 1.0",
            "cv_acceleration_noise_std_mps2 = 0.1",
        );
    let site = Site::from_toml_str(&text, "site.toml").unwrap();
    assert_eq!(site.tracker.imm_cv_acceleration_noise_std_mps2(), 0.1);
    let map_text = include_str!("../../../../examples/radio-map.csv");
    let map = crate::radio_map::RadioMap::from_csv_str(map_text, "radio-map.csv", &site).unwrap();
    assert_eq!(map.neighbours(), 5);
    assert_eq!(map.signal_space().representation.floor_dbm(), -100.0);
    // absent: the present behaviour (the CV filter's noise; k = 3, −104 dBm)
    let text = EXAMPLE
        .replace("cv_acceleration_noise_std_mps2 = 1.0\n", "")
        .replace(
            "acceleration_noise_std_mps2 = 1.0\n# Probability",
            "acceleration_noise_std_mps2 = 0.7\n# Probability",
        )
        .replace("neighbours = 3\n", "")
        .replace("noise_floor_dbm = -104.0\n", "")
        .replace("min_std_m = 1.5\n", "");
    let site = Site::from_toml_str(&text, "site.toml").unwrap();
    assert_eq!(site.tracker.imm_cv_acceleration_noise_std_mps2(), 0.7);
    let map = crate::radio_map::RadioMap::from_csv_str(map_text, "radio-map.csv", &site).unwrap();
    assert_eq!(map.neighbours(), 3);
    assert_eq!(map.signal_space().representation.floor_dbm(), -104.0);
    // min_std_m absent: the leave-one-out floor, never below the spacing floor
    let calibration = map.calibration().unwrap();
    assert_eq!(map.min_std_m(), calibration.fitted_std_m.max(map.spacing_std_m()));
    let error = Site::from_toml_str(&EXAMPLE.replace("min_std_m = 1.5", "min_std_m = 0.0"), "site.toml").unwrap_err();
    assert!(
        error
            .to_string()
            .contains("field `fingerprints.min_std_m`: 0 is outside the allowed range [0.001, 10000] m"),
        "{error}"
    );
    // out of range: named with the value and the range
    let error = Site::from_toml_str(&EXAMPLE.replace("neighbours = 3", "neighbours = 0"), "site.toml").unwrap_err();
    assert!(
        error
            .to_string()
            .contains("field `fingerprints.neighbours`: 0 is outside the allowed range [1, 100]"),
        "{error}"
    );
}
