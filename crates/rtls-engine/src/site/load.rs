//! Parsing and validation of a site file.

use std::collections::HashMap;

use super::{invalid, keys, FilterKind, Pipeline, Site};
use crate::error::{EngineError, Result};
use crate::zones::Shape;

pub(super) fn load(text: &str, file: &str) -> Result<Site> {
    let mut site: Site = toml::from_str(text).map_err(|e| syntax_error(text, file, &e))?;
    validate(&mut site, text, file)?;
    Ok(site)
}

/// A TOML syntax, type or unknown-key error, located by its span.
fn syntax_error(text: &str, file: &str, error: &toml::de::Error) -> EngineError {
    let (line, mut field) = error
        .span()
        .map_or((0, String::new()), |span| keys::path_at(text, span.start));
    let message = error.message().trim().to_string();
    // `unknown field `x``, `missing field `x``: the key named in the message
    if message.starts_with("unknown field") || message.starts_with("missing field") {
        if let Some(named) = message.split('`').nth(1) {
            if !field.ends_with(named) {
                field = if field.is_empty() {
                    named.to_string()
                } else {
                    format!("{field}.{named}")
                };
            }
        }
    }
    EngineError::Parse {
        file: file.to_string(),
        line,
        field: if field.is_empty() { "-".into() } else { field },
        reason: message,
    }
}

fn positive(value: f64) -> bool {
    value.is_finite() && value > 0.0
}

fn non_negative(value: f64) -> bool {
    value.is_finite() && value >= 0.0
}

/// Checks `(path, ok, reason)` triples in order.
fn check(text: &str, file: &str, checks: &[(String, bool, &str)]) -> Result<()> {
    match checks.iter().find(|(_, ok, _)| !ok) {
        Some((path, _, reason)) => Err(invalid(file, text, path, *reason)),
        None => Ok(()),
    }
}

/// Ids must be non-empty and unique; returns id → index.
fn unique_ids<'a>(
    text: &str,
    file: &str,
    section: &str,
    ids: impl Iterator<Item = &'a str>,
) -> Result<HashMap<&'a str, usize>> {
    let mut seen = HashMap::new();
    for (i, id) in ids.enumerate() {
        let path = format!("{section}[{i}].id");
        if id.trim().is_empty() {
            return Err(invalid(file, text, &path, "must not be empty"));
        }
        if let Some(first) = seen.insert(id, i) {
            return Err(invalid(
                file,
                text,
                &path,
                format!("duplicate id `{id}` (also {section}[{first}]): ids must be unique"),
            ));
        }
    }
    Ok(seen)
}

fn validate(site: &mut Site, text: &str, file: &str) -> Result<()> {
    let readers = unique_ids(text, file, "readers", site.readers.iter().map(|r| r.id.as_str()))?;
    for (i, reader) in site.readers.iter().enumerate() {
        let p = &reader.position_m;
        check(
            text,
            file,
            &[(
                format!("readers[{i}].position_m"),
                (p.len() == 2 || p.len() == 3) && p.iter().all(|c| c.is_finite()),
                "must be [x, y] or [x, y, z] with finite coordinates, m",
            )],
        )?;
        let Some(radio) = reader.radio else { continue };
        if let Some(pl) = radio.path_loss {
            let at = |key: &str| format!("readers[{i}].radio.path_loss.{key}");
            check(
                text,
                file,
                &[
                    (
                        at("reference_power_dbm"),
                        pl.reference_power_dbm.is_finite(),
                        "must be finite, dBm",
                    ),
                    (at("exponent"), positive(pl.exponent), "must be a finite number > 0"),
                    (
                        at("shadowing_std_db"),
                        non_negative(pl.shadowing_std_db),
                        "must be a finite number ≥ 0, dB",
                    ),
                    (
                        at("reference_distance_m"),
                        positive(pl.reference_distance_m),
                        "must be a finite number > 0, m",
                    ),
                ],
            )?;
        }
        if let Some(range) = radio.range {
            let at = |key: &str| format!("readers[{i}].radio.range.{key}");
            check(
                text,
                file,
                &[
                    (
                        at("range_std_m"),
                        positive(range.range_std_m),
                        "must be a finite number > 0, m",
                    ),
                    (at("bias_m"), range.bias_m.is_finite(), "must be finite, m"),
                ],
            )?;
        }
    }
    let known_reader = |path: String, id: &str| {
        if readers.contains_key(id) {
            Ok(())
        } else {
            Err(invalid(
                file,
                text,
                &path,
                format!("unknown reader `{id}`: not among the site's readers"),
            ))
        }
    };

    let floors = unique_ids(text, file, "floors", site.floors.iter().map(|f| f.id.as_str()))?;
    for (i, floor) in site.floors.iter().enumerate() {
        let [lo, hi] = floor.z_range_m;
        check(
            text,
            file,
            &[(
                format!("floors[{i}].z_range_m"),
                lo.is_finite() && hi.is_finite() && lo < hi,
                "must be [z_min, z_max] with finite z_min < z_max, m",
            )],
        )?;
    }

    unique_ids(text, file, "zones", site.zones.iter().map(|z| z.id.as_str()))?;
    for (i, zone) in site.zones.iter_mut().enumerate() {
        for (j, id) in zone.readers.iter().enumerate() {
            known_reader(format!("zones[{i}].readers[{j}]"), id)?;
        }
        if let Shape::Polygon {
            floor: Some(floor_id),
            z_range_m,
            ..
        } = &mut zone.shape
        {
            let path = format!("zones[{i}].shape.floor");
            if z_range_m.is_some() {
                return Err(invalid(file, text, &path, "give either floor or z_range_m, not both"));
            }
            let Some(&k) = floors.get(floor_id.as_str()) else {
                return Err(invalid(file, text, &path, format!("unknown floor `{floor_id}`")));
            };
            *z_range_m = Some(site.floors[k].z_range_m);
        }
        if let Err(EngineError::Parse { field, reason, .. }) = zone.validate() {
            return Err(invalid(file, text, &format!("zones[{i}].{field}"), reason));
        }
    }

    if let Some(db) = &site.fingerprints {
        if db.path.as_os_str().is_empty() {
            return Err(invalid(file, text, "fingerprints.path", "must name a file"));
        }
        for (j, id) in db.readers.iter().enumerate() {
            known_reader(format!("fingerprints.readers[{j}]"), id)?;
        }
    }

    let t = &site.tracker;
    let at = |key: &str| format!("tracker.{key}");
    check(
        text,
        file,
        &[
            (
                at("filter"),
                !(t.pipeline == Pipeline::TightlyCoupled && t.filter == FilterKind::Kf),
                "a tightly coupled pipeline uses nonlinear measurements: choose \"ekf\" or \"ukf\"",
            ),
            (
                at("acceleration_noise_std_mps2"),
                positive(t.acceleration_noise_std_mps2),
                "must be a finite number > 0, m/s²",
            ),
            (
                at("gate_probability"),
                t.gate_probability > 0.0 && t.gate_probability < 1.0,
                "must lie strictly between 0 and 1",
            ),
            (
                at("initiation.confirm_updates"),
                t.initiation.confirm_updates >= 1,
                "must be at least 1",
            ),
            (
                at("initiation.within_s"),
                positive(t.initiation.within_s),
                "must be a finite number > 0, s",
            ),
            (
                at("coast_timeout_s"),
                positive(t.coast_timeout_s),
                "must be a finite number > 0, s",
            ),
            (
                at("delete_timeout_s"),
                t.delete_timeout_s.is_finite() && t.delete_timeout_s >= t.coast_timeout_s,
                "must be finite and ≥ coast_timeout_s, s",
            ),
            (
                at("reorder_window_s"),
                non_negative(t.reorder_window_s),
                "must be a finite number ≥ 0, s",
            ),
            (
                at("dimensions"),
                t.dimensions == 2 || t.dimensions == 3,
                "must be 2 or 3",
            ),
            (at("epoch_s"), non_negative(t.epoch_s), "must be a finite number ≥ 0, s"),
            (
                at("tag_height_m"),
                t.tag_height_m.is_none_or(f64::is_finite),
                "must be a finite number, m",
            ),
            (
                at("tag_height_m"),
                t.tag_height_m.is_none() || t.dimensions == 2,
                "only applies to 2-D tracking (dimensions = 2)",
            ),
            (
                at("output_interval_s"),
                positive(t.output_interval_s),
                "must be a finite number > 0, s",
            ),
            (
                at("initial_speed_std_mps"),
                positive(t.initial_speed_std_mps),
                "must be a finite number > 0, m/s",
            ),
            (
                at("imm.cv_sojourn_s"),
                positive(t.imm.cv_sojourn_s),
                "must be a finite number > 0, s",
            ),
            (
                at("imm.ca_sojourn_s"),
                positive(t.imm.ca_sojourn_s),
                "must be a finite number > 0, s",
            ),
            (
                at("imm.ct_sojourn_s"),
                positive(t.imm.ct_sojourn_s),
                "must be a finite number > 0, s",
            ),
            (
                at("imm.ca_jerk_noise_std_mps3"),
                positive(t.imm.ca_jerk_noise_std_mps3),
                "must be a finite number > 0, m/s³",
            ),
            (
                at("imm.ct_turn_rate_noise_std_radps2"),
                positive(t.imm.ct_turn_rate_noise_std_radps2),
                "must be a finite number > 0, rad/s²",
            ),
            (
                at("imm.switch_probability"),
                t.imm.switch_probability > 0.0 && t.imm.switch_probability < 1.0,
                "must lie strictly between 0 and 1",
            ),
            (
                at("adaptive_noise.memory_s"),
                t.adaptive_noise.memory_s.is_finite() && (1e-3..=1e6).contains(&t.adaptive_noise.memory_s),
                "must be a number of seconds from 0.001 to 10⁶",
            ),
            (
                at("adaptive_noise.max_scale"),
                t.adaptive_noise.max_scale.is_finite() && (1.0..=1e6).contains(&t.adaptive_noise.max_scale),
                "must be a number from 1 to 10⁶ (a multiple of the stated variance)",
            ),
            (
                at("adaptive_noise.correlation_s"),
                t.adaptive_noise.correlation_s.is_finite() && (0.0..=3600.0).contains(&t.adaptive_noise.correlation_s),
                "must be a number of seconds from 0 to 3600",
            ),
        ],
    )?;

    if let Some(scheduling) = &site.scheduling {
        check(
            text,
            file,
            &[
                (
                    "scheduling.cycle_s".into(),
                    scheduling.cycle_s.is_finite() && scheduling.cycle_s > 0.0,
                    "must be a finite number > 0, s",
                ),
                (
                    "scheduling.task_nodes".into(),
                    scheduling.task_nodes >= 1,
                    "must be at least 1",
                ),
            ],
        )?;
        for (i, cell) in scheduling.cells.iter().enumerate() {
            for (j, id) in cell.readers.iter().enumerate() {
                known_reader(format!("scheduling.cells[{i}].readers[{j}]"), id)?;
            }
        }
        match crate::tracker::scheduling_layout(site) {
            Ok(_) => {}
            Err(EngineError::InvalidParameter { name, reason }) => {
                check(text, file, &[(format!("scheduling.{name}"), false, reason)])?;
            }
            Err(other) => return Err(other),
        }
    }
    if let Some(anonymous) = &site.anonymous {
        match anonymous.validate() {
            Ok(()) => {}
            Err(EngineError::InvalidParameter { name, reason }) => {
                check(text, file, &[(format!("anonymous.{name}"), false, reason)])?;
            }
            Err(other) => return Err(other),
        }
    }

    let a = site.alarms;
    check(
        text,
        file,
        &[
            (
                "alarms.horizon_s".into(),
                positive(a.horizon_s),
                "must be a finite number > 0, s",
            ),
            (
                "alarms.step_s".into(),
                positive(a.step_s) && a.step_s <= a.horizon_s,
                "must be a finite number > 0 and ≤ alarms.horizon_s, s",
            ),
            (
                "alarms.entry_probability".into(),
                a.entry_probability > 0.0 && a.entry_probability < 1.0,
                "must lie strictly between 0 and 1",
            ),
        ],
    )?;

    let z = site.zone_events;
    check(
        text,
        file,
        &[
            (
                "zone_events.tolerance_m".into(),
                non_negative(z.tolerance_m),
                "must be a finite number ≥ 0, m",
            ),
            (
                "zone_events.delay_s".into(),
                non_negative(z.delay_s),
                "must be a finite number ≥ 0, s",
            ),
            (
                "zone_events.dwell_interval_s".into(),
                z.dwell_interval_s.is_none_or(positive),
                "must be a finite number > 0, s",
            ),
        ],
    )?;
    // everything the monitor needs has been checked above; this keeps the two in step
    debug_assert!(site.zone_monitor().is_ok());
    Ok(())
}
