//! `scenarios/003-test-bed.toml`: the file's layout, its validation (errors name the file and
//! the field) and its conversion into [`Seed003Config`].

use serde::Deserialize;

use crate::error::{Result, SimError};
use crate::experiments::ScenarioSource;
use crate::reproduction::seed_003::{
    ClockConfig, EnergyConfig, SchedulingConfig, Seed003Config, TokenTiming, TrackerConfig,
};
use rtls_engine::scheduling::PowerModel;
use rtls_sim::scenarios::seed_003::{planar_route, TestBed};
use rtls_sim::sensors::ultrasonic::SonarRing;
use rtls_sim::trajectory::WaypointPath;

/// The scenario file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TestBedFile {
    duration_s: f64,
    bed: BedSection,
    sonar: SonarSection,
    tokens: TokenSection,
    scheduling: SchedulingSection,
    tracker: TrackerSection,
    clock: ClockSection,
    energy: EnergySection,
    evaluation: EvaluationSection,
    robots: Vec<RobotSection>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct BedSection {
    width_m: f64,
    height_m: f64,
    cell_side_m: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct SonarSection {
    sonars_per_node: usize,
    sector_width_deg: f64,
    range_noise_std_m: f64,
    min_range_m: f64,
    echo_window_s: f64,
    detection_probability: f64,
    speed_of_sound_mps: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct TokenSection {
    ranging_slot_s: f64,
    comm_slot_s: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct SchedulingSection {
    task_nodes: usize,
    edge_margin_m: f64,
    dual_sonar_margin_deg: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackerSection {
    acceleration_psd_m2ps3: f64,
    initial_position_std_m: f64,
    initial_velocity_std_mps: f64,
    gate_probability: f64,
    sector_margin_deg: f64,
    manoeuvre_margin_m: f64,
    manoeuvre_velocity_std_mps: f64,
    manoeuvre_speed_change_mps: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClockSection {
    drift_std_ppm: f64,
    sync_jitter_std_s: f64,
    resync_every_cycle: bool,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnergySection {
    radio_rx_w: f64,
    radio_tx_w: f64,
    sonar_w: f64,
    sonar_ping_s: f64,
    all_on_sonars_per_node: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct EvaluationSection {
    border_band_m: f64,
    tracked_error_m: f64,
    tracked_fraction: f64,
    swap_window_s: f64,
    task_node_sweep: Vec<usize>,
    clock_stress_drift_ppm: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotSection {
    name: String,
    speed_mps: f64,
    waypoints_m: Vec<[f64; 2]>,
    #[serde(default)]
    start_delay_s: f64,
    #[serde(default)]
    pauses_s: Vec<f64>,
}

/// How the runs are evaluated.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Evaluation {
    /// Epochs whose truth lies within this distance of an inner border count as "near a border" (m).
    pub border_band_m: f64,
    /// Error below which an epoch counts as tracked (m).
    pub tracked_error_m: f64,
    /// Fraction of tracked epochs for a robot to count as tracked.
    pub tracked_fraction: f64,
    /// Swaps are counted from the shared-cell episode's start to this long after its end (s).
    pub swap_window_s: f64,
    /// Task-node counts compared in the sweep table.
    pub task_node_sweep: Vec<usize>,
    /// A clock drift σ (ppm) far above the configured one, to show when the sync matters.
    pub clock_stress_drift_ppm: f64,
}

/// The parsed, validated scenario.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scenario {
    /// The simulation.
    pub config: Seed003Config,
    /// The robots' names, in route order.
    pub names: Vec<String>,
    /// Evaluation settings.
    pub evaluation: Evaluation,
}

/// An error naming the file and the field.
fn field_error(source: &ScenarioSource, field: &str, reason: impl std::fmt::Display) -> SimError {
    SimError::Scenario {
        file: source.name.clone(),
        reason: format!("`{field}` {reason}"),
    }
}

/// Checks that `value` is finite and positive.
fn positive(source: &ScenarioSource, field: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(field_error(
            source,
            field,
            format_args!("must be a positive number, got {value}"),
        ))
    }
}

/// Checks that `value` is finite and not negative.
fn non_negative(source: &ScenarioSource, field: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(field_error(
            source,
            field,
            format_args!("must be a number ≥ 0, got {value}"),
        ))
    }
}

/// Checks that `value` lies in the open interval (`low`, `high`) or, with `high_closed`, (`low`, `high`].
fn in_interval(
    source: &ScenarioSource,
    field: &str,
    value: f64,
    low: f64,
    high: f64,
    high_closed: bool,
) -> Result<f64> {
    let inside = value > low && (value < high || (high_closed && value == high));
    if value.is_finite() && inside {
        Ok(value)
    } else {
        let bracket = if high_closed { ']' } else { ')' };
        Err(field_error(
            source,
            field,
            format_args!("must lie in ({low}, {high}{bracket}, got {value}"),
        ))
    }
}

/// Parses and validates `source` (`003-test-bed.toml`).
///
/// # Errors
/// [`SimError::Scenario`] naming the file and the offending field (unknown keys, wrong types,
/// values out of range, routes shorter than `duration_s`).
pub(crate) fn parse(source: &ScenarioSource) -> Result<Scenario> {
    let file: TestBedFile = crate::experiments::parse_scenario(source)?;
    let duration_s = positive(source, "duration_s", file.duration_s)?;
    let b = file.bed;
    let bed = TestBed::new(
        positive(source, "bed.width_m", b.width_m)?,
        positive(source, "bed.height_m", b.height_m)?,
        positive(source, "bed.cell_side_m", b.cell_side_m)?,
    )
    .map_err(|e| field_error(source, "bed.cell_side_m", format_args!("is invalid: {e}")))?;
    let s = file.sonar;
    if s.sonars_per_node == 0 || s.sonars_per_node > 360 {
        return Err(field_error(
            source,
            "sonar.sonars_per_node",
            "must be between 1 and 360",
        ));
    }
    let sector_width_deg = positive(source, "sonar.sector_width_deg", s.sector_width_deg)?;
    if sector_width_deg * s.sonars_per_node as f64 > 360.0 + 1e-9 {
        return Err(field_error(
            source,
            "sonar.sector_width_deg",
            format_args!(
                "× sonars_per_node must not exceed 360°, got {sector_width_deg}° × {}",
                s.sonars_per_node
            ),
        ));
    }
    let sonar = SonarRing {
        sonars: s.sonars_per_node,
        sector_width_deg,
        range_noise_std_m: positive(source, "sonar.range_noise_std_m", s.range_noise_std_m)?,
        min_range_m: non_negative(source, "sonar.min_range_m", s.min_range_m)?,
        echo_window_s: positive(source, "sonar.echo_window_s", s.echo_window_s)?,
        detection_probability: in_interval(
            source,
            "sonar.detection_probability",
            s.detection_probability,
            0.0,
            1.0,
            true,
        )?,
        speed_of_sound_mps: positive(source, "sonar.speed_of_sound_mps", s.speed_of_sound_mps)?,
    };
    if sonar.max_range_m() <= sonar.min_range_m {
        return Err(field_error(
            source,
            "sonar.echo_window_s",
            format_args!(
                "gives a maximum range c·T/2 = {:.3} m that must exceed min_range_m",
                sonar.max_range_m()
            ),
        ));
    }
    let timing = TokenTiming {
        ranging_slot_s: positive(source, "tokens.ranging_slot_s", file.tokens.ranging_slot_s)?,
        comm_slot_s: positive(source, "tokens.comm_slot_s", file.tokens.comm_slot_s)?,
    };
    let sc = file.scheduling;
    let task_nodes = check_task_nodes(source, "scheduling.task_nodes", sc.task_nodes)?;
    let scheduling = SchedulingConfig {
        task_nodes,
        edge_margin_m: non_negative(source, "scheduling.edge_margin_m", sc.edge_margin_m)?,
        dual_sonar_margin_deg: non_negative(source, "scheduling.dual_sonar_margin_deg", sc.dual_sonar_margin_deg)?,
    };
    let t = file.tracker;
    let tracker = TrackerConfig {
        acceleration_psd_m2ps3: non_negative(source, "tracker.acceleration_psd_m2ps3", t.acceleration_psd_m2ps3)?,
        initial_position_std_m: positive(source, "tracker.initial_position_std_m", t.initial_position_std_m)?,
        initial_velocity_std_mps: positive(source, "tracker.initial_velocity_std_mps", t.initial_velocity_std_mps)?,
        gate_probability: in_interval(source, "tracker.gate_probability", t.gate_probability, 0.0, 1.0, false)?,
        sector_margin_deg: non_negative(source, "tracker.sector_margin_deg", t.sector_margin_deg)?,
        manoeuvre_margin_m: non_negative(source, "tracker.manoeuvre_margin_m", t.manoeuvre_margin_m)?,
        manoeuvre_velocity_std_mps: non_negative(
            source,
            "tracker.manoeuvre_velocity_std_mps",
            t.manoeuvre_velocity_std_mps,
        )?,
        manoeuvre_speed_change_mps: non_negative(
            source,
            "tracker.manoeuvre_speed_change_mps",
            t.manoeuvre_speed_change_mps,
        )?,
    };
    let clock = clock_config(source, file.clock)?;
    let en = file.energy;
    if en.all_on_sonars_per_node == 0 || en.all_on_sonars_per_node > sonar.sonars {
        return Err(field_error(
            source,
            "energy.all_on_sonars_per_node",
            format_args!(
                "must be 1 to sonar.sonars_per_node = {}, got {}",
                sonar.sonars, en.all_on_sonars_per_node
            ),
        ));
    }
    let energy = EnergyConfig {
        power: PowerModel {
            radio_rx_w: non_negative(source, "energy.radio_rx_w", en.radio_rx_w)?,
            radio_tx_w: non_negative(source, "energy.radio_tx_w", en.radio_tx_w)?,
            sonar_w: non_negative(source, "energy.sonar_w", en.sonar_w)?,
        },
        sonar_ping_s: non_negative(source, "energy.sonar_ping_s", en.sonar_ping_s)?,
        all_on_sonars_per_node: en.all_on_sonars_per_node,
    };
    let e = file.evaluation;
    if e.task_node_sweep.is_empty() {
        return Err(field_error(
            source,
            "evaluation.task_node_sweep",
            "must list at least one task-node count",
        ));
    }
    for &k in &e.task_node_sweep {
        check_task_nodes(source, "evaluation.task_node_sweep", k)?;
    }
    let evaluation = Evaluation {
        border_band_m: positive(source, "evaluation.border_band_m", e.border_band_m)?,
        tracked_error_m: positive(source, "evaluation.tracked_error_m", e.tracked_error_m)?,
        tracked_fraction: in_interval(
            source,
            "evaluation.tracked_fraction",
            e.tracked_fraction,
            0.0,
            1.0,
            true,
        )?,
        swap_window_s: non_negative(source, "evaluation.swap_window_s", e.swap_window_s)?,
        task_node_sweep: e.task_node_sweep,
        clock_stress_drift_ppm: in_interval(
            source,
            "evaluation.clock_stress_drift_ppm",
            e.clock_stress_drift_ppm,
            0.0,
            1e5,
            false,
        )?,
    };
    let (robots, names) = routes(source, &file.robots, &bed, duration_s)?;
    let config = Seed003Config {
        bed,
        sonar,
        timing,
        scheduling,
        tracker,
        clock,
        energy,
        robots,
        duration_s,
    };
    config
        .validate()
        .map_err(|e| field_error(source, "(configuration)", format_args!("is invalid: {e}")))?;
    Ok(Scenario {
        config,
        names,
        evaluation,
    })
}

/// The `[clock]` section, checked: drift in [0, 10⁵) ppm, jitter in [0, 1) s.
fn clock_config(source: &ScenarioSource, c: ClockSection) -> Result<ClockConfig> {
    let drift_std_ppm = non_negative(source, "clock.drift_std_ppm", c.drift_std_ppm)?;
    if drift_std_ppm >= 1e5 {
        return Err(field_error(
            source,
            "clock.drift_std_ppm",
            format_args!("must be below 10⁵ ppm (10 %), got {drift_std_ppm}"),
        ));
    }
    let sync_jitter_std_s = non_negative(source, "clock.sync_jitter_std_s", c.sync_jitter_std_s)?;
    if sync_jitter_std_s >= 1.0 {
        return Err(field_error(
            source,
            "clock.sync_jitter_std_s",
            format_args!("must be below 1 s, got {sync_jitter_std_s}"),
        ));
    }
    Ok(ClockConfig {
        drift_std_ppm,
        sync_jitter_std_s,
        resync_every_cycle: c.resync_every_cycle,
    })
}

/// Task nodes of a cell: 1 to 4.
fn check_task_nodes(source: &ScenarioSource, field: &str, k: usize) -> Result<usize> {
    if (1..=4).contains(&k) {
        Ok(k)
    } else {
        Err(field_error(
            source,
            field,
            format_args!("must be 1 to 4 (nodes of one cell), got {k}"),
        ))
    }
}

/// The robots' routes, checked: inside the bed, positive speeds, lasting `duration_s`.
fn routes(
    source: &ScenarioSource,
    robots: &[RobotSection],
    bed: &TestBed,
    duration_s: f64,
) -> Result<(Vec<WaypointPath>, Vec<String>)> {
    if robots.is_empty() {
        return Err(field_error(source, "robots", "must list at least one robot"));
    }
    let [width_m, height_m] = bed.size_m();
    let mut paths = Vec::with_capacity(robots.len());
    let mut names = Vec::with_capacity(robots.len());
    for (i, r) in robots.iter().enumerate() {
        let field = |name: &str| format!("robots[{i}].{name}");
        positive(source, &field("speed_mps"), r.speed_mps)?;
        non_negative(source, &field("start_delay_s"), r.start_delay_s)?;
        for &p in &r.pauses_s {
            non_negative(source, &field("pauses_s"), p)?;
        }
        if r.waypoints_m.len() < 2 {
            return Err(field_error(source, &field("waypoints_m"), "needs at least two points"));
        }
        for p in &r.waypoints_m {
            let inside =
                p.iter().all(|c| c.is_finite()) && (0.0..=width_m).contains(&p[0]) && (0.0..=height_m).contains(&p[1]);
            if !inside {
                return Err(field_error(
                    source,
                    &field("waypoints_m"),
                    format_args!("must lie inside the bed [0, {width_m}] × [0, {height_m}] m, got {p:?}"),
                ));
            }
        }
        let path = planar_route(&r.waypoints_m, r.speed_mps, r.start_delay_s, &r.pauses_s)
            .map_err(|e| field_error(source, &field("waypoints_m"), format_args!("is not a route: {e}")))?;
        if path.duration_s() < duration_s {
            return Err(field_error(
                source,
                &field("waypoints_m"),
                format_args!(
                    "gives a {:.1} s route, shorter than duration_s = {duration_s} s",
                    path.duration_s()
                ),
            ));
        }
        paths.push(path);
        names.push(r.name.clone());
    }
    Ok((paths, names))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::ExperimentId;

    fn shipped() -> ScenarioSource {
        ExperimentId::WsnEkf.embedded_scenarios().remove(0)
    }

    #[test]
    fn the_shipped_scenario_parses_with_the_paper_values() {
        let s = parse(&shipped()).unwrap();
        assert_eq!(s.config.bed, TestBed::paper().unwrap());
        assert_eq!((s.config.sonar.sonars, s.config.sonar.sector_width_deg), (6, 60.0));
        assert_eq!(s.names, vec!["A", "B", "C"]);
        assert_eq!(s.evaluation.task_node_sweep, vec![2, 3]);
        // the library's defaults are the file's values
        let defaults = Seed003Config::paper(s.config.robots.clone(), s.config.duration_s).unwrap();
        assert_eq!(s.config, defaults);
    }

    #[test]
    fn bad_values_name_the_file_and_the_field() {
        let cases = [
            (
                "range_noise_std_m = 0.03",
                "range_noise_std_m = -0.03",
                "sonar.range_noise_std_m",
            ),
            ("task_nodes = 3", "task_nodes = 7", "scheduling.task_nodes"),
            (
                "gate_probability = 0.99",
                "gate_probability = 1.5",
                "tracker.gate_probability",
            ),
            ("duration_s = 35.0", "duration_s = 99.0", "robots[0].waypoints_m"),
            (
                "[0.8, 0.7], [3.2, 0.7]",
                "[0.8, 0.7], [9.2, 0.7]",
                "robots[0].waypoints_m",
            ),
            (
                "task_node_sweep = [2, 3]",
                "task_node_sweep = []",
                "evaluation.task_node_sweep",
            ),
            ("drift_std_ppm = 20.0", "drift_std_ppm = -20.0", "clock.drift_std_ppm"),
            ("drift_std_ppm = 20.0", "drift_std_ppm = 2e5", "clock.drift_std_ppm"),
            (
                "sync_jitter_std_s = 0.0001",
                "sync_jitter_std_s = 3.0",
                "clock.sync_jitter_std_s",
            ),
            ("radio_rx_w = 0.0564", "radio_rx_w = -1.0", "energy.radio_rx_w"),
            (
                "all_on_sonars_per_node = 6",
                "all_on_sonars_per_node = 7",
                "energy.all_on_sonars_per_node",
            ),
            (
                "clock_stress_drift_ppm = 10000.0",
                "clock_stress_drift_ppm = 0.0",
                "evaluation.clock_stress_drift_ppm",
            ),
        ];
        for (from, to, field) in cases {
            let mut source = shipped();
            assert!(source.text.contains(from), "{from}");
            source.text = source.text.replacen(from, to, 1);
            let err = parse(&source).unwrap_err().to_string();
            assert!(err.contains("003-test-bed.toml") && err.contains(field), "{err}");
        }
    }
}
