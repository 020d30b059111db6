//! The allowed range of every numeric value of a site file: physically plausible intervals, so
//! that a typo (`1e-300`, `1e308`, a unit off by 10⁶) is an error naming the key, the value and
//! the range instead of a run that hangs or aborts.
//!
//! `docs/FORMATS.md` ("Site file: allowed ranges") lists the same table for users.

use std::fmt;

use super::Site;
use crate::zones::Shape;

/// A closed, half-open or open interval of allowed values, with its unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bounds {
    lo: f64,
    hi: f64,
    lo_open: bool,
    hi_open: bool,
    unit: &'static str,
}

impl Bounds {
    const fn closed(lo: f64, hi: f64, unit: &'static str) -> Self {
        Self {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
            unit,
        }
    }

    const fn open(lo: f64, hi: f64, unit: &'static str) -> Self {
        Self {
            lo,
            hi,
            lo_open: true,
            hi_open: true,
            unit,
        }
    }

    const fn open_closed(lo: f64, hi: f64, unit: &'static str) -> Self {
        Self {
            lo,
            hi,
            lo_open: true,
            hi_open: false,
            unit,
        }
    }

    fn contains(&self, value: f64) -> bool {
        let above = if self.lo_open {
            value > self.lo
        } else {
            value >= self.lo
        };
        let below = if self.hi_open {
            value < self.hi
        } else {
            value <= self.hi
        };
        value.is_finite() && above && below
    }
}

/// A number as a user would write it: plain, or in exponent form when very large or small
/// (`1e308`, not 309 digits).
fn number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude >= 1e9 || (magnitude > 0.0 && magnitude < 1e-3) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

impl fmt::Display for Bounds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (open, close) = (
            if self.lo_open { '(' } else { '[' },
            if self.hi_open { ')' } else { ']' },
        );
        write!(f, "{open}{}, {}{close}", number(self.lo), number(self.hi))?;
        if !self.unit.is_empty() {
            write!(f, " {}", self.unit)?;
        }
        Ok(())
    }
}

/// Site coordinates (reader positions, floors, zones, cells, tag height), m: ±10 000 km, so
/// that projected coordinates such as UTM fit.
pub(super) const COORDINATE_M: Bounds = Bounds::closed(-1e7, 1e7, "m");
const REFERENCE_POWER_DBM: Bounds = Bounds::closed(-150.0, 50.0, "dBm");
const PATH_LOSS_EXPONENT: Bounds = Bounds::closed(0.5, 10.0, "");
const SHADOWING_STD_DB: Bounds = Bounds::closed(0.0, 50.0, "dB");
const REFERENCE_DISTANCE_M: Bounds = Bounds::closed(0.01, 1000.0, "m");
const RANGE_STD_M: Bounds = Bounds::closed(1e-4, 1000.0, "m");
const RANGE_BIAS_M: Bounds = Bounds::closed(-1000.0, 1000.0, "m");
const RANGE_SCALE: Bounds = Bounds::closed(0.5, 2.0, "");
const ACCELERATION_NOISE_MPS2: Bounds = Bounds::closed(1e-6, 1000.0, "m/s²");
/// 0 allowed: an accelerometer-driven prediction may rest on the samples' own noise alone.
const AIDED_ACCELERATION_NOISE_MPS2: Bounds = Bounds::closed(0.0, 1000.0, "m/s²");
const GATE_PROBABILITY: Bounds = Bounds::closed(0.5, 1.0 - 1e-9, "");
const PROBABILITY: Bounds = Bounds::open(0.0, 1.0, "");
const WINDOW_S: Bounds = Bounds::closed(1e-3, 86_400.0, "s");
const REORDER_WINDOW_S: Bounds = Bounds::closed(0.0, 3600.0, "s");
/// The per-track history a rewind keeps: minutes at most (it holds every input in the horizon).
const REWIND_HORIZON_S: Bounds = Bounds::closed(0.0, 600.0, "s");
const EPOCH_S: Bounds = Bounds::closed(0.0, 60.0, "s");
const OUTPUT_INTERVAL_S: Bounds = Bounds::closed(1e-3, 3600.0, "s");
const SPEED_STD_MPS: Bounds = Bounds::closed(1e-3, 1000.0, "m/s");
const MAX_TIME_JUMP_S: Bounds = Bounds::closed(1.0, 31_536_000.0, "s");
const SOJOURN_S: Bounds = Bounds::closed(1e-2, 1e6, "s");
const JERK_NOISE_MPS3: Bounds = Bounds::closed(1e-6, 1e4, "m/s³");
const TURN_RATE_STD_RADPS: Bounds = Bounds::closed(1e-3, 10.0, "rad/s");
const TURN_NOISE_RADPS2: Bounds = Bounds::closed(1e-6, 100.0, "rad/s²");
const MEMORY_S: Bounds = Bounds::closed(1e-3, 1e6, "s");
const NOISE_SCALE: Bounds = Bounds::closed(1.0, 1e6, "(multiple of the stated variance)");
const CORRELATION_S: Bounds = Bounds::closed(0.0, 3600.0, "s");
const BIAS_PRIOR_STD_M: Bounds = Bounds::closed(1e-4, 100.0, "m");
const BIAS_RANDOM_WALK: Bounds = Bounds::closed(0.0, 10.0, "m/√s");
const BIAS_MAX_M: Bounds = Bounds::closed(1e-3, 1000.0, "m");
const CONSISTENCY_WINDOW_S: Bounds = Bounds::closed(0.1, 3600.0, "s");
const CONSISTENCY_PROBABILITY: Bounds = Bounds::closed(0.5, 0.999_999, "");
const MAX_INFLATION: Bounds = Bounds::closed(1.0, 1e6, "(multiple of the covariance)");
const RATE_STD_RADPS: Bounds = Bounds::closed(1e-7, 10.0, "rad/s");
const RATE_RANDOM_WALK: Bounds = Bounds::closed(1e-9, 1.0, "rad/s/√s");
const ANGLE_RANDOM_WALK: Bounds = Bounds::closed(1e-7, 10.0, "rad/√s");
const ANGLE_STD_RAD: Bounds = Bounds::closed(1e-5, 3.2, "rad");
const SPEED_MPS: Bounds = Bounds::closed(1e-3, 100.0, "m/s");
const DELETE_TIMEOUT_MAX_S: f64 = 604_800.0;
const TOLERANCE_M: Bounds = Bounds::closed(0.0, 1000.0, "m");
const DELAY_S: Bounds = Bounds::closed(0.0, 86_400.0, "s");
const DWELL_INTERVAL_S: Bounds = Bounds::closed(1e-3, 1e6, "s");
const HORIZON_S: Bounds = Bounds::closed(1e-2, 3600.0, "s");
/// The alarm's prediction steps per update, at most (`horizon_s / step_s`).
const MAX_ALARM_STEPS: f64 = 10_000.0;
const CYCLE_S: Bounds = Bounds::closed(1e-3, 3600.0, "s");
const EDGE_MARGIN_M: Bounds = Bounds::closed(0.0, 1000.0, "m");
const DETECTION_PROBABILITY: Bounds = Bounds::open_closed(0.0, 1.0, "");
const CLUTTER_DENSITY: Bounds = Bounds::closed(1e-12, 1000.0, "per m² or per m");
const NOISE_FLOOR_DBM: Bounds = Bounds::closed(-150.0, -30.0, "dBm");
const LATITUDE_DEG: Bounds = Bounds::closed(-90.0, 90.0, "degrees");
const LONGITUDE_DEG: Bounds = Bounds::closed(-180.0, 180.0, "degrees");
const BEARING_DEG: Bounds = Bounds::closed(0.0, 360.0, "degrees");
const ELLIPSOID_HEIGHT_M: Bounds = Bounds::closed(-11_000.0, 100_000.0, "m");
const PSEUDORANGE_STD_M: Bounds = Bounds::closed(0.01, 1000.0, "m");
const MIN_ELEVATION_DEG: Bounds = Bounds::closed(0.1, 90.0, "degrees");
const FALSE_ALARM_PROBABILITY: Bounds = Bounds::closed(1e-9, 0.5, "");
const CLOCK_BIAS_NOISE_M2PS: Bounds = Bounds::closed(1e-9, 1e6, "m²/s");
const CLOCK_DRIFT_NOISE_M2PS3: Bounds = Bounds::closed(1e-9, 1e6, "m²/s³");
const CLOCK_DRIFT_STD_MPS: Bounds = Bounds::closed(1e-3, 1e5, "m/s");
const FIX_STD_M: Bounds = Bounds::closed(1e-3, 1e4, "m");
const SENSITIVITY_DBM: Bounds = Bounds::closed(-200.0, 50.0, "dBm");
const HALF_WIDTH_M: Bounds = Bounds::closed(0.01, 1000.0, "m");
const LATERAL_STD_M: Bounds = Bounds::closed(1e-3, 1000.0, "m");
const JUNCTION_RADIUS_M: Bounds = Bounds::closed(0.0, 1000.0, "m");
const MAX_SPEED_MPS: Bounds = Bounds::closed(1e-3, 1e4, "m/s");
const COUNT_MAX: usize = 1000;
const NEIGHBOURS_MAX: usize = 100;
const JPDA_EVENTS_MAX: usize = 10_000_000;

/// One check: the key path, whether it holds, and the reason when it does not.
pub(super) type Check = (String, bool, String);

/// `value` at `path` lies in `bounds`.
fn within(path: impl Into<String>, value: f64, bounds: Bounds) -> Check {
    (
        path.into(),
        bounds.contains(value),
        format!("{} is outside the allowed range {bounds}", number(value)),
    )
}

/// Every coordinate of `values` (the array at `path`) lies in [`COORDINATE_M`].
fn coordinates(path: impl Into<String>, values: &[f64]) -> Check {
    let path = path.into();
    match values.iter().position(|v| !COORDINATE_M.contains(*v)) {
        Some(k) => (
            path,
            false,
            format!(
                "coordinate {k} = {} is outside the allowed range {COORDINATE_M}",
                number(values[k])
            ),
        ),
        None => (path, true, String::new()),
    }
}

/// An integer count at `path` lies in `[lo, hi]`.
fn count(path: impl Into<String>, value: usize, lo: usize, hi: usize) -> Check {
    (
        path.into(),
        (lo..=hi).contains(&value),
        format!("{value} is outside the allowed range [{lo}, {hi}]"),
    )
}

/// The range checks of every numeric value of `site`, in file order.
pub(super) fn checks(site: &Site) -> Vec<Check> {
    let mut out = Vec::new();
    if let Some(frame) = &site.frame {
        let o = frame.origin;
        out.push(within("frame.origin.latitude_deg", o.latitude_deg, LATITUDE_DEG));
        out.push(within("frame.origin.longitude_deg", o.longitude_deg, LONGITUDE_DEG));
        out.push(within("frame.origin.height_m", o.height_m, ELLIPSOID_HEIGHT_M));
        out.push(within(
            "frame.x_axis_bearing_deg",
            frame.x_axis_bearing_deg,
            BEARING_DEG,
        ));
    }
    for (i, reader) in site.readers.iter().enumerate() {
        out.push(coordinates(format!("readers[{i}].position_m"), &reader.position_m));
        let Some(radio) = reader.radio else { continue };
        if let Some(pl) = radio.path_loss {
            let at = |key: &str| format!("readers[{i}].radio.path_loss.{key}");
            out.push(within(
                at("reference_power_dbm"),
                pl.reference_power_dbm,
                REFERENCE_POWER_DBM,
            ));
            out.push(within(at("exponent"), pl.exponent, PATH_LOSS_EXPONENT));
            out.push(within(at("shadowing_std_db"), pl.shadowing_std_db, SHADOWING_STD_DB));
            out.push(within(
                at("reference_distance_m"),
                pl.reference_distance_m,
                REFERENCE_DISTANCE_M,
            ));
        }
        if let Some(sensitivity_dbm) = radio.sensitivity_dbm {
            out.push(within(
                format!("readers[{i}].radio.sensitivity_dbm"),
                sensitivity_dbm,
                SENSITIVITY_DBM,
            ));
        }
        if let Some(range) = radio.range {
            let at = |key: &str| format!("readers[{i}].radio.range.{key}");
            out.push(within(at("range_std_m"), range.range_std_m, RANGE_STD_M));
            out.push(within(at("bias_m"), range.bias_m, RANGE_BIAS_M));
            out.push(within(at("scale"), range.scale, RANGE_SCALE));
            if let Some(offset_std_m) = range.offset_std_m {
                out.push(within(at("offset_std_m"), offset_std_m, BIAS_PRIOR_STD_M));
            }
        }
    }
    for (i, corridor) in site.corridors.iter().enumerate() {
        if let Some(j) = corridor
            .points_m
            .iter()
            .position(|v| !v.iter().all(|c| COORDINATE_M.contains(*c)))
        {
            out.push(coordinates(
                format!("corridors[{i}].points_m[{j}]"),
                &corridor.points_m[j],
            ));
        }
        if let Some(j) = corridor
            .heights_m
            .iter()
            .flatten()
            .position(|h| !COORDINATE_M.contains(*h))
        {
            out.push(within(
                format!("corridors[{i}].heights_m[{j}]"),
                corridor.heights_m.as_ref().map_or(0.0, |h| h[j]),
                COORDINATE_M,
            ));
        }
        out.push(within(
            format!("corridors[{i}].half_width_m"),
            corridor.half_width_m,
            HALF_WIDTH_M,
        ));
    }
    for (i, floor) in site.floors.iter().enumerate() {
        out.push(coordinates(format!("floors[{i}].z_range_m"), &floor.z_range_m));
        if let Some(plan) = &floor.plan {
            for (k, corner) in plan.bounds_m.iter().enumerate() {
                out.push(coordinates(format!("floors[{i}].plan.bounds_m[{k}]"), corner));
            }
        }
    }
    for (i, zone) in site.zones.iter().enumerate() {
        match &zone.shape {
            Shape::Polygon {
                vertices_m, z_range_m, ..
            } => {
                if let Some(j) = vertices_m
                    .iter()
                    .position(|v| !v.iter().all(|c| COORDINATE_M.contains(*c)))
                {
                    out.push(coordinates(format!("zones[{i}].shape.vertices_m[{j}]"), &vertices_m[j]));
                }
                if let Some(z) = z_range_m {
                    out.push(coordinates(format!("zones[{i}].shape.z_range_m"), z));
                }
            }
            Shape::Box { min_m, max_m } => {
                out.push(coordinates(format!("zones[{i}].shape.min_m"), min_m));
                out.push(coordinates(format!("zones[{i}].shape.max_m"), max_m));
            }
        }
    }
    let z = site.zone_events;
    out.push(within("zone_events.tolerance_m", z.tolerance_m, TOLERANCE_M));
    out.push(within("zone_events.delay_s", z.delay_s, DELAY_S));
    if let Some(dwell) = z.dwell_interval_s {
        out.push(within("zone_events.dwell_interval_s", dwell, DWELL_INTERVAL_S));
    }
    if let Some(db) = &site.fingerprints {
        out.push(count("fingerprints.neighbours", db.neighbours, 1, NEIGHBOURS_MAX));
        out.push(within(
            "fingerprints.noise_floor_dbm",
            db.noise_floor_dbm,
            NOISE_FLOOR_DBM,
        ));
        if let Some(min_std_m) = db.min_std_m {
            out.push(within("fingerprints.min_std_m", min_std_m, FIX_STD_M));
        }
    }
    tracker(site, &mut out);
    if let Some(a) = &site.anonymous {
        let at = |key: &str| format!("anonymous.{key}");
        out.push(within(
            at("acceleration_noise_std_mps2"),
            a.acceleration_noise_std_mps2,
            ACCELERATION_NOISE_MPS2,
        ));
        out.push(within(
            at("initial_velocity_std_mps"),
            a.initial_velocity_std_mps,
            SPEED_STD_MPS,
        ));
        out.push(within(at("gate_probability"), a.gate_probability, GATE_PROBABILITY));
        out.push(within(
            at("detection_probability"),
            a.detection_probability,
            DETECTION_PROBABILITY,
        ));
        out.push(within(
            at("fix_clutter_density_per_m2"),
            a.fix_clutter_density_per_m2,
            CLUTTER_DENSITY,
        ));
        out.push(within(
            at("range_clutter_density_per_m"),
            a.range_clutter_density_per_m,
            CLUTTER_DENSITY,
        ));
        let l = &a.lifecycle;
        out.push(count(
            at("lifecycle.confirm_updates"),
            l.confirm_updates as usize,
            1,
            COUNT_MAX,
        ));
        out.push(within(at("lifecycle.confirm_window_s"), l.confirm_window_s, WINDOW_S));
        out.push(within(at("lifecycle.coast_timeout_s"), l.coast_timeout_s, WINDOW_S));
        let delete = Bounds::closed(l.coast_timeout_s, DELETE_TIMEOUT_MAX_S, "s (≥ coast_timeout_s)");
        out.push(within(at("lifecycle.delete_timeout_s"), l.delete_timeout_s, delete));
        out.push(count(
            at("jpda_max_joint_events"),
            a.jpda_max_joint_events,
            1,
            JPDA_EVENTS_MAX,
        ));
    }
    if let Some(s) = &site.scheduling {
        out.push(within("scheduling.cycle_s", s.cycle_s, CYCLE_S));
        out.push(count("scheduling.task_nodes", s.task_nodes, 1, COUNT_MAX));
        out.push(within("scheduling.edge_margin_m", s.edge_margin_m, EDGE_MARGIN_M));
        for (i, cell) in s.cells.iter().enumerate() {
            out.push(coordinates(format!("scheduling.cells[{i}].min_m"), &cell.min_m));
            out.push(coordinates(format!("scheduling.cells[{i}].max_m"), &cell.max_m));
        }
    }
    let a = site.alarms;
    out.push(within("alarms.horizon_s", a.horizon_s, HORIZON_S));
    let step = Bounds::closed(
        a.horizon_s / MAX_ALARM_STEPS,
        a.horizon_s,
        "s (horizon_s / 10 000 to horizon_s)",
    );
    out.push(within("alarms.step_s", a.step_s, step));
    out.push(within("alarms.entry_probability", a.entry_probability, PROBABILITY));
    out
}

/// `[tracker]` and `[tracker.imm]`.
fn tracker(site: &Site, out: &mut Vec<Check>) {
    let t = &site.tracker;
    let at = |key: &str| format!("tracker.{key}");
    out.push(within(
        at("acceleration_noise_std_mps2"),
        t.acceleration_noise_std_mps2,
        ACCELERATION_NOISE_MPS2,
    ));
    if let Some(noise) = t.aided_acceleration_noise_std_mps2 {
        out.push(within(
            at("aided_acceleration_noise_std_mps2"),
            noise,
            AIDED_ACCELERATION_NOISE_MPS2,
        ));
    }
    out.push(within(at("gate_probability"), t.gate_probability, GATE_PROBABILITY));
    out.push(count(
        at("initiation.confirm_updates"),
        t.initiation.confirm_updates as usize,
        1,
        COUNT_MAX,
    ));
    out.push(within(at("initiation.within_s"), t.initiation.within_s, WINDOW_S));
    out.push(within(at("coast_timeout_s"), t.coast_timeout_s, WINDOW_S));
    let delete = Bounds::closed(t.coast_timeout_s, DELETE_TIMEOUT_MAX_S, "s (≥ coast_timeout_s)");
    out.push(within(at("delete_timeout_s"), t.delete_timeout_s, delete));
    out.push(within(at("reorder_window_s"), t.reorder_window_s, REORDER_WINDOW_S));
    out.push(within(at("rewind_horizon_s"), t.rewind_horizon_s, REWIND_HORIZON_S));
    out.push(count(at("dimensions"), usize::from(t.dimensions), 2, 3));
    if let Some(epoch_s) = t.epoch_s {
        out.push(within(at("epoch_s"), epoch_s, EPOCH_S));
    }
    if let Some(height) = t.tag_height_m {
        out.push(within(at("tag_height_m"), height, COORDINATE_M));
    }
    out.push(within(at("output_interval_s"), t.output_interval_s, OUTPUT_INTERVAL_S));
    out.push(within(
        at("initial_speed_std_mps"),
        t.initial_speed_std_mps,
        SPEED_STD_MPS,
    ));
    out.push(within(at("max_time_jump_s"), t.max_time_jump_s, MAX_TIME_JUMP_S));
    out.push(within(
        at("initial_turn_rate_std_radps"),
        t.initial_turn_rate_std_radps,
        TURN_RATE_STD_RADPS,
    ));
    out.push(within(
        at("turn_rate_noise_std_radps2"),
        t.turn_rate_noise_std_radps2,
        TURN_NOISE_RADPS2,
    ));
    let imm = &t.imm;
    if let Some(noise) = imm.cv_acceleration_noise_std_mps2 {
        out.push(within(
            at("imm.cv_acceleration_noise_std_mps2"),
            noise,
            ACCELERATION_NOISE_MPS2,
        ));
    }
    out.push(within(at("imm.cv_sojourn_s"), imm.cv_sojourn_s, SOJOURN_S));
    out.push(within(at("imm.ca_sojourn_s"), imm.ca_sojourn_s, SOJOURN_S));
    out.push(within(at("imm.ct_sojourn_s"), imm.ct_sojourn_s, SOJOURN_S));
    out.push(within(
        at("imm.ca_jerk_noise_std_mps3"),
        imm.ca_jerk_noise_std_mps3,
        JERK_NOISE_MPS3,
    ));
    out.push(within(
        at("imm.ct_turn_rate_noise_std_radps2"),
        imm.ct_turn_rate_noise_std_radps2,
        TURN_NOISE_RADPS2,
    ));
    out.push(within(
        at("imm.switch_probability"),
        imm.switch_probability,
        PROBABILITY,
    ));
    let adaptive = &t.adaptive_noise;
    out.push(within(at("adaptive_noise.memory_s"), adaptive.memory_s, MEMORY_S));
    out.push(within(at("adaptive_noise.max_scale"), adaptive.max_scale, NOISE_SCALE));
    out.push(within(
        at("adaptive_noise.correlation_s"),
        adaptive.correlation_s,
        CORRELATION_S,
    ));
    out.push(within(
        at("adaptive_noise.rssi_correlation_s"),
        adaptive.rssi_correlation_s,
        CORRELATION_S,
    ));
    out.push(within(
        at("adaptive_noise.rssi_reading_correlation_s"),
        adaptive.rssi_reading_correlation_s,
        CORRELATION_S,
    ));
    let range_bias = &t.range_bias;
    if let Some(prior_std_m) = range_bias.prior_std_m {
        out.push(within(at("range_bias.prior_std_m"), prior_std_m, BIAS_PRIOR_STD_M));
    }
    if let Some(max_abs_m) = range_bias.max_abs_m {
        out.push(within(at("range_bias.max_abs_m"), max_abs_m, BIAS_MAX_M));
    }
    for (key, value, bounds) in [
        (
            "range_bias.random_walk_m_per_sqrt_s",
            range_bias.random_walk_m_per_sqrt_s,
            BIAS_RANDOM_WALK,
        ),
        ("consistency.window_s", t.consistency.window_s, CONSISTENCY_WINDOW_S),
        (
            "consistency.probability",
            t.consistency.probability,
            CONSISTENCY_PROBABILITY,
        ),
        ("consistency.max_inflation", t.consistency.max_inflation, MAX_INFLATION),
    ] {
        out.push(within(at(key), value, bounds));
    }
    let heading = &t.heading;
    for (key, value, bounds) in [
        (
            "heading.gyro_noise_std_radps",
            heading.gyro_noise_std_radps,
            RATE_STD_RADPS,
        ),
        (
            "heading.gyro_bias_std_radps",
            heading.gyro_bias_std_radps,
            RATE_STD_RADPS,
        ),
        (
            "heading.gyro_bias_random_walk_radps_per_sqrt_s",
            heading.gyro_bias_random_walk_radps_per_sqrt_s,
            RATE_RANDOM_WALK,
        ),
        (
            "heading.heading_random_walk_rad_per_sqrt_s",
            heading.heading_random_walk_rad_per_sqrt_s,
            ANGLE_RANDOM_WALK,
        ),
        (
            "heading.odometer_drift_rad_per_sqrt_s",
            heading.odometer_drift_rad_per_sqrt_s,
            ANGLE_RANDOM_WALK,
        ),
        (
            "heading.odometer_offset_std_rad",
            heading.odometer_offset_std_rad,
            ANGLE_STD_RAD,
        ),
        ("heading.course_min_speed_mps", heading.course_min_speed_mps, SPEED_MPS),
        (
            "heading.course_heading_std_rad",
            heading.course_heading_std_rad,
            ANGLE_STD_RAD,
        ),
        (
            "heading.heading_error_correlation_s",
            heading.heading_error_correlation_s,
            CORRELATION_S,
        ),
    ] {
        out.push(within(at(key), value, bounds));
    }
    if let Some(std) = t.map.lateral_std_m {
        out.push(within(at("map.lateral_std_m"), std, LATERAL_STD_M));
    }
    if let Some(radius) = t.map.junction_radius_m {
        out.push(within(at("map.junction_radius_m"), radius, JUNCTION_RADIUS_M));
    }
    out.push(within(at("map.vertical_std_m"), t.map.vertical_std_m, LATERAL_STD_M));
    if let Some(speed) = t.max_speed_mps {
        out.push(within(at("max_speed_mps"), speed, MAX_SPEED_MPS));
    }
    let gnss = &t.gnss;
    out.push(within(
        at("gnss.pseudorange_std_m"),
        gnss.pseudorange_std_m,
        PSEUDORANGE_STD_M,
    ));
    out.push(within(
        at("gnss.min_elevation_deg"),
        gnss.min_elevation_deg,
        MIN_ELEVATION_DEG,
    ));
    out.push(within(
        at("gnss.false_alarm_probability"),
        gnss.false_alarm_probability,
        FALSE_ALARM_PROBABILITY,
    ));
    out.push(within(
        at("gnss.clock_bias_noise_m2ps"),
        gnss.clock_bias_noise_m2ps,
        CLOCK_BIAS_NOISE_M2PS,
    ));
    out.push(within(
        at("gnss.clock_drift_noise_m2ps3"),
        gnss.clock_drift_noise_m2ps3,
        CLOCK_DRIFT_NOISE_M2PS3,
    ));
    out.push(within(
        at("gnss.initial_clock_drift_std_mps"),
        gnss.initial_clock_drift_std_mps,
        CLOCK_DRIFT_STD_MPS,
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_describe_themselves() {
        assert_eq!(ACCELERATION_NOISE_MPS2.to_string(), "[1e-6, 1000] m/s²");
        assert_eq!(number(1e308), "1e308");
        assert_eq!(number(0.5), "0.5");
        assert_eq!(OUTPUT_INTERVAL_S.to_string(), "[0.001, 3600] s");
        assert_eq!(PROBABILITY.to_string(), "(0, 1)");
        assert!(!OUTPUT_INTERVAL_S.contains(1e-300));
        assert!(!ACCELERATION_NOISE_MPS2.contains(1e308));
        assert!(!COORDINATE_M.contains(f64::NAN));
        assert!(DETECTION_PROBABILITY.contains(1.0) && !DETECTION_PROBABILITY.contains(0.0));
    }
}
