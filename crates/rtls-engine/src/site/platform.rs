//! `tracker.platform`: default tracking models for what carries the tag — a walker, a vehicle
//! or a robot — and the generic defaults of the `[tracker]` keys a site file leaves out.
//!
//! A key written in the site file always wins; the platform only fills the keys left out.
//!
//! | key | generic | `walker` | `vehicle` | `robot` |
//! | --- | --- | --- | --- | --- |
//! | `motion_model` | cv | cv | imm | cv |
//! | `acceleration_noise_std_mps2` | 1.0 | 1.0 | 2.0 | 0.5 |
//! | `heading.course_heading_std_rad` | 0.05 | 0.2 | 0.05 | 0.03 |
//! | `heading.heading_random_walk_rad_per_sqrt_s` | 0.3 | 0.5 | 0.2 | 0.3 |
//! | `max_speed_mps` | none | 6.0 | none | none |
//!
//! Generic defaults of the other keys: `pipeline = "tightly-coupled"` (every reading is used,
//! also when fewer anchors than a fix needs answer an epoch) — `"fix-then-filter"` when every
//! reader is `ble` (`pipeline_for_readers`) — `filter = "ekf"`,
//! `gate_probability = 0.999`, `initiation = { confirm_updates = 3, within_s = 5.0 }`,
//! `coast_timeout_s = 5`, `delete_timeout_s = 60`, `reorder_window_s = 0.5`.
//!
//! Why: a walker accelerates gently (σ_a ≈ 1 m/s², Bar-Shalom et al. 2001 §6.2.2 take half the
//! largest acceleration) but the sensor sways about the walking direction; a vehicle brakes and
//! turns harder, and its turns are the IMM's coordinated-turn mode; a robot moves smoothly and
//! its body points where it drives. A person on foot does not keep up 6 m/s (a fast run; brisk
//! walking is 1.5–2 m/s), while fixes that jump (a fingerprint on the wrong floor, two
//! transmitters under one id) give a track tens of m/s to coast on: UJIIndoorLoc's validation,
//! fingerprint fix-then-filter, 22.2 → 17.2 m RMSE with the limit (docs/EVALUATION.md).

use serde::Deserialize;

use super::{Initiation, MotionModelKind, Pipeline, TrackerSettings};
use crate::site::FilterKind;

/// What carries the tag (`tracker.platform`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Platform {
    /// A person walking (hand-carried, helmet or belt tag, phone).
    Walker,
    /// A car, truck, forklift or mine vehicle.
    Vehicle,
    /// A wheeled ground robot (AGV, AMR).
    Robot,
}

pub(super) fn default_pipeline() -> Pipeline {
    Pipeline::TightlyCoupled
}

/// The pipeline of a site file that names none: fix-then-filter when every reader is `ble`,
/// tightly coupled otherwise.
///
/// Why: RSSI shadowing is correlated over seconds (BLE: ρ 0.2–0.3 at 0.5–2 s, 5 dB) and the
/// log-distance law is steep near a reader, so an EKF linearised at its own estimate is pulled
/// metres off by a reader a body shadows; a fix of a second's readings solved on its own, then
/// filtered, is not. On the 9 recorded BLE runs (docs/EVALUATION.md, 2026-11-28) fix-then-filter
/// gave 2.11 m and 92.9 % inside the 95 % ellipse against the tightly coupled EKF's 2.68 m and
/// 91.3 %. Ranges, TDOA and Wi-Fi (round-trip time) keep every reading in the filter, and so
/// does RFID: seed 000's mine tracks best tightly coupled, where readers that stay silent and
/// the tunnel map constrain each reading (docs/REPRODUCTIONS.md).
pub(super) fn pipeline_for_readers(readers: &[super::Reader]) -> Pipeline {
    let ble_only = !readers.is_empty() && readers.iter().all(|reader| reader.technology == super::Technology::Ble);
    if ble_only {
        Pipeline::FixThenFilter
    } else {
        default_pipeline()
    }
}

pub(super) fn default_motion_model() -> MotionModelKind {
    MotionModelKind::Cv
}

pub(super) fn default_filter() -> FilterKind {
    FilterKind::Ekf
}

pub(super) fn default_acceleration_noise_std_mps2() -> f64 {
    1.0
}

pub(super) fn default_gate_probability() -> f64 {
    0.999
}

pub(super) fn default_initiation() -> Initiation {
    Initiation {
        confirm_updates: 3,
        within_s: 5.0,
    }
}

pub(super) fn default_coast_timeout_s() -> f64 {
    5.0
}

pub(super) fn default_delete_timeout_s() -> f64 {
    60.0
}

pub(super) fn default_reorder_window_s() -> f64 {
    0.5
}

impl Default for TrackerSettings {
    /// The generic defaults: what an empty `[tracker]` table reads as.
    fn default() -> Self {
        toml::from_str("").unwrap_or_else(|error| unreachable!("every [tracker] key has a default: {error}"))
    }
}

/// Fills the keys of `settings.platform`'s preset that the site file's `[tracker]` table
/// (`tracker_table`, as written) leaves out.
pub(super) fn apply(settings: &mut TrackerSettings, tracker_table: Option<&toml::Table>) {
    let Some(platform) = settings.platform else {
        return;
    };
    let given = |key: &str| tracker_table.is_some_and(|t| t.contains_key(key));
    let heading_given = |key: &str| {
        tracker_table
            .and_then(|t| t.get("heading"))
            .and_then(toml::Value::as_table)
            .is_some_and(|t| t.contains_key(key))
    };
    let (motion_model, acceleration, slip, random_walk, max_speed_mps) = match platform {
        Platform::Walker => (MotionModelKind::Cv, 1.0, 0.2, 0.5, Some(WALKER_MAX_SPEED_MPS)),
        Platform::Vehicle => (MotionModelKind::Imm, 2.0, 0.05, 0.2, None),
        Platform::Robot => (MotionModelKind::Cv, 0.5, 0.03, 0.3, None),
    };
    if !given("motion_model") {
        settings.motion_model = motion_model;
    }
    if !given("acceleration_noise_std_mps2") {
        settings.acceleration_noise_std_mps2 = acceleration;
    }
    if !heading_given("course_heading_std_rad") {
        settings.heading.course_heading_std_rad = slip;
    }
    if !heading_given("heading_random_walk_rad_per_sqrt_s") {
        settings.heading.heading_random_walk_rad_per_sqrt_s = random_walk;
    }
    if !given("max_speed_mps") {
        settings.max_speed_mps = max_speed_mps;
    }
}

/// `max_speed_mps` of `platform = "walker"`: faster than a person on foot keeps up.
pub const WALKER_MAX_SPEED_MPS: f64 = 6.0;

#[cfg(test)]
mod tests {
    use crate::site::{MotionModelKind, Pipeline, Site};

    const READERS: &str = r#"
[[readers]]
id = "A"
position_m = [0.0, 0.0]
technology = "uwb"
"#;

    #[test]
    fn a_site_without_tracker_settings_gets_the_generic_defaults() {
        let site = Site::from_toml_str(READERS, "bare.toml").unwrap();
        assert_eq!(site.tracker.pipeline, Pipeline::TightlyCoupled);
        assert_eq!(site.tracker.motion_model, MotionModelKind::Cv);
        assert_eq!(site.tracker.acceleration_noise_std_mps2, 1.0);
        assert_eq!(site.tracker.platform, None);
    }

    #[test]
    fn a_platform_fills_only_the_keys_left_out() {
        let vehicle = Site::from_toml_str(&format!("{READERS}[tracker]\nplatform = \"vehicle\"\n"), "v.toml").unwrap();
        assert_eq!(vehicle.tracker.motion_model, MotionModelKind::Imm);
        assert_eq!(vehicle.tracker.acceleration_noise_std_mps2, 2.0);
        let walker = Site::from_toml_str(
            &format!(
                "{READERS}[tracker]\nplatform = \"walker\"\nacceleration_noise_std_mps2 = 0.7\n\
                 [tracker.heading]\ncourse_heading_std_rad = 0.1\n"
            ),
            "w.toml",
        )
        .unwrap();
        assert_eq!(walker.tracker.acceleration_noise_std_mps2, 0.7);
        assert_eq!(walker.tracker.heading.course_heading_std_rad, 0.1);
        assert_eq!(walker.tracker.heading.heading_random_walk_rad_per_sqrt_s, 0.5);
        assert_eq!(walker.tracker.max_speed_mps, Some(6.0));
        assert_eq!(vehicle.tracker.max_speed_mps, None);
        let written = format!("{READERS}[tracker]\nplatform = \"walker\"\nmax_speed_mps = 2.0\n");
        let slow = Site::from_toml_str(&written, "s.toml").unwrap();
        assert_eq!(slow.tracker.max_speed_mps, Some(2.0));
        let error = Site::from_toml_str(&format!("{READERS}[tracker]\nplatform = \"boat\"\n"), "b.toml").unwrap_err();
        assert!(error.to_string().contains("platform"), "{error}");
    }

    #[test]
    fn a_site_of_ble_readers_defaults_to_fix_then_filter_unless_it_names_a_pipeline() {
        let ble = |id: &str| format!("[[readers]]\nid = \"{id}\"\nposition_m = [0.0, 0.0]\ntechnology = \"ble\"\n");
        let ble_site = format!("{}{}", ble("B1"), ble("B2"));
        let site = Site::from_toml_str(&ble_site, "ble.toml").unwrap();
        assert_eq!(site.tracker.pipeline, Pipeline::FixThenFilter);
        let walker = Site::from_toml_str(&format!("{ble_site}[tracker]\nplatform = \"walker\"\n"), "w.toml").unwrap();
        assert_eq!(walker.tracker.pipeline, Pipeline::FixThenFilter);
        let written = format!("{ble_site}[tracker]\npipeline = \"tightly-coupled\"\n");
        let site = Site::from_toml_str(&written, "tc.toml").unwrap();
        assert_eq!(site.tracker.pipeline, Pipeline::TightlyCoupled);
        // one UWB anchor among them: ranges are taken reading by reading
        let mixed = Site::from_toml_str(&format!("{ble_site}{READERS}"), "mixed.toml").unwrap();
        assert_eq!(mixed.tracker.pipeline, Pipeline::TightlyCoupled);
        // RFID (seed 000's mine: silent readers and the tunnel map constrain each reading)
        let rfid = Site::from_toml_str(&ble("R1").replace("ble", "rfid"), "rfid.toml").unwrap();
        assert_eq!(rfid.tracker.pipeline, Pipeline::TightlyCoupled);
    }
}
