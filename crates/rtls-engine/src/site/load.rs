//! Parsing and validation of a site file.

use std::collections::HashMap;

use super::{
    invalid, keys, platform, ranges, FilterKind, ImmModeKind, MotionModelKind, Pipeline, Site, MAX_SITE_BYTES,
};
use crate::error::{EngineError, Result};
use crate::zones::Shape;

pub(super) fn load(text: &str, file: &str) -> Result<Site> {
    if text.len() as u64 > MAX_SITE_BYTES {
        return Err(EngineError::Parse {
            file: file.to_string(),
            line: 0,
            field: "-".into(),
            reason: format!("the site file is larger than the {MAX_SITE_BYTES}-byte limit; is it the right file?"),
        });
    }
    let mut site: Site = toml::from_str(text).map_err(|e| syntax_error(text, file, &e))?;
    // the keys the file wrote win over the defaults that depend on the site
    let table: toml::Table = toml::from_str(text).map_err(|e| syntax_error(text, file, &e))?;
    let tracker_table = table.get("tracker").and_then(toml::Value::as_table);
    if tracker_table.is_none_or(|t| !t.contains_key("pipeline")) {
        site.tracker.pipeline = platform::pipeline_for_readers(&site.readers);
    }
    platform::apply(&mut site.tracker, tracker_table);
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

/// Checks `(path, ok, reason)` triples in order.
fn check<S: AsRef<str>>(text: &str, file: &str, checks: &[(String, bool, S)]) -> Result<()> {
    match checks.iter().find(|(_, ok, _)| !ok) {
        Some((path, _, reason)) => Err(invalid(file, text, path, reason.as_ref())),
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
    // every numeric value in its physically plausible range first
    check(text, file, &ranges::checks(site))?;
    let readers = unique_ids(text, file, "readers", site.readers.iter().map(|r| r.id.as_str()))?;
    for (i, reader) in site.readers.iter().enumerate() {
        let p = &reader.position_m;
        check(
            text,
            file,
            &[(
                format!("readers[{i}].position_m"),
                p.len() == 2 || p.len() == 3,
                "must be [x, y] or [x, y, z] with finite coordinates, m",
            )],
        )?;
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

    unique_ids(text, file, "corridors", site.corridors.iter().map(|c| c.id.as_str()))?;
    for (i, corridor) in site.corridors.iter().enumerate() {
        let points = &corridor.points_m;
        let distinct = points.windows(2).all(|w| w[0] != w[1]);
        check(
            text,
            file,
            &[(
                format!("corridors[{i}].points_m"),
                points.len() >= 2 && distinct,
                "must be a polyline of at least two points [x, y] with no point repeated back to back, m",
            )],
        )?;
        check(
            text,
            file,
            &[(
                format!("corridors[{i}].heights_m"),
                corridor.heights_m.as_ref().is_none_or(|h| h.len() == points.len()),
                "must give one height per point of points_m, m",
            )],
        )?;
    }
    for (i, reader) in site.readers.iter().enumerate() {
        let radio = reader.radio.as_ref();
        let sensitivity = radio.is_some_and(|r| r.sensitivity_dbm.is_some());
        check(
            text,
            file,
            &[(
                format!("readers[{i}].radio.sensitivity_dbm"),
                !sensitivity || radio.is_some_and(|r| r.path_loss.is_some()),
                "needs the reader's radio.path_loss too (what it should have received is computed from it)",
            )],
        )?;
    }

    let floors = unique_ids(text, file, "floors", site.floors.iter().map(|f| f.id.as_str()))?;
    for (i, floor) in site.floors.iter().enumerate() {
        let [lo, hi] = floor.z_range_m;
        check(
            text,
            file,
            &[(
                format!("floors[{i}].z_range_m"),
                lo < hi,
                "must be [z_min, z_max] with finite z_min < z_max, m",
            )],
        )?;
    }

    for (i, floor) in site.floors.iter().enumerate() {
        let Some(plan) = &floor.plan else { continue };
        let [[x0, y0], [x1, y1]] = plan.bounds_m;
        check(
            text,
            file,
            &[
                (
                    format!("floors[{i}].plan.image"),
                    plan.media_type().is_some(),
                    "must name a .png, .jpg, .jpeg, .svg, .webp or .gif file, relative to the site file",
                ),
                (
                    format!("floors[{i}].plan.bounds_m"),
                    x0 < x1 && y0 < y1,
                    "must be [[x_min, y_min], [x_max, y_max]] with x_min < x_max and y_min < y_max, m",
                ),
            ],
        )?;
    }

    unique_ids(text, file, "zones", site.zones.iter().map(|z| z.id.as_str()))?;
    if let Some(muster) = &site.muster {
        let known_zone = |path: String, id: &str| {
            if site.zones.iter().any(|z| z.id == id) {
                Ok(())
            } else {
                Err(invalid(
                    file,
                    text,
                    &path,
                    format!("unknown zone `{id}`: not among the site's zones"),
                ))
            }
        };
        known_zone("muster.entry_zone".into(), &muster.entry_zone)?;
        for (j, id) in muster.outside_zones.iter().enumerate() {
            known_zone(format!("muster.outside_zones[{j}]"), id)?;
        }
    }
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
    check(
        text,
        file,
        &[
            (
                "tracker.filter".to_string(),
                !(t.pipeline == Pipeline::TightlyCoupled && t.filter == FilterKind::Kf),
                "a tightly coupled pipeline uses nonlinear measurements: choose \"ekf\" or \"ukf\"",
            ),
            (
                "tracker.tag_height_m".to_string(),
                t.tag_height_m.is_none() || t.dimensions == 2,
                "only applies to 2-D tracking (dimensions = 2)",
            ),
            (
                "tracker.motion_model".to_string(),
                t.motion_model != MotionModelKind::Ct || t.dimensions == 2,
                "the coordinated turn (\"ct\") is a 2-D model: use dimensions = 2, or \"cv\" / \"imm\" in 3-D",
            ),
            (
                "tracker.imm.modes".to_string(),
                t.dimensions == 2 || !t.imm.modes.is_some_and(|m| m.modes().contains(&ImmModeKind::Ct)),
                "the coordinated turn (\"ct\") is a 2-D mode: leave it out in 3-D",
            ),
        ],
    )?;

    if let Some(scheduling) = &site.scheduling {
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

    // everything the monitor needs has been checked above; this keeps the two in step
    debug_assert!(site.zone_monitor().is_ok());
    Ok(())
}
