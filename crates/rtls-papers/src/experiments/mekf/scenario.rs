//! The scenario files of the `mekf` experiment — `000-mine-walk.toml`, the simulated mine walk,
//! here; `000-table-1.toml` in [`super::table1`] — parsed with unknown keys rejected,
//! validated with errors naming the file and the field, and converted into typed
//! configurations.

use serde::Deserialize;

use super::super::{parse_scenario, ScenarioSource};
use crate::error::{Result, SimError};
use crate::reproduction::seed_000::{
    MapSpread, MekfConfig, OursConfig, PedestrianCv, Seed000Setup, SetupOptions, TrackerPrior,
};
use rtls_estimation::stats::ChiSquareGate;
use rtls_positioning::pathloss::LogDistance;
use rtls_sim::scenarios::seed_000::{DangerZone, MineLayout, Obstruction, PlanBox, Tunnel, Wall};
use rtls_sim::sensors::readers::{Reader, ReaderRadio, ReaderStatus};
use rtls_sim::trajectory::{Waypoint, WaypointPath};

/// File name of the mine walk.
pub const MINE_WALK: &str = "000-mine-walk.toml";
/// File name of Table 1.
pub const TABLE_1: &str = "000-table-1.toml";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MineWalkFile {
    period_s: f64,
    mekf: MekfSection,
    prior: PriorSection,
    radio: RadioSection,
    dv_hop: DvHopSection,
    ours: OursSection,
    alarm: AlarmSection,
    map: MapSection,
    tunnels: Vec<TunnelSection>,
    readers: Vec<ReaderSection>,
    #[serde(default)]
    obstructions: Vec<ObstructionSection>,
    danger_zones: Vec<ZoneSection>,
    walk: Vec<Waypoint>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MekfSection {
    process_variance: f64,
    measurement_variance: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PriorSection {
    position_m: [f64; 3],
    velocity_mps: [f64; 3],
    position_std_m: f64,
    velocity_std_mps: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RadioSection {
    reference_rssi_dbm: f64,
    reference_distance_m: f64,
    exponent: f64,
    shadowing_std_db: f64,
    sensitivity_dbm: f64,
    nlos_loss_db: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DvHopSection {
    link_range_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OursSection {
    horizontal_acceleration_std_mps2: f64,
    vertical_acceleration_std_mps2: f64,
    gate_probability: f64,
    max_speed_mps: f64,
    junction_radius_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MapSection {
    lateral_std_m: f64,
    vertical_std_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AlarmSection {
    look_ahead_s: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TunnelSection {
    name: String,
    half_width_m: f64,
    centreline_m: Vec<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReaderSection {
    name: String,
    tunnel: String,
    chainage_m: f64,
    wall: Wall,
    height_m: f64,
    #[serde(default)]
    broken: bool,
    #[serde(default)]
    obstacle_loss_db: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObstructionSection {
    name: String,
    from_m: [f64; 2],
    to_m: [f64; 2],
    loss_db: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ZoneSection {
    name: String,
    min_m: [f64; 2],
    max_m: [f64; 2],
}

/// The mine walk, typed: the run setup plus what the evaluation needs.
#[derive(Debug, Clone, PartialEq)]
pub struct MineWalk {
    /// The layout (tunnels, readers, zones, rockfalls).
    pub layout: MineLayout,
    /// The walker's path.
    pub path: WaypointPath,
    /// Everything a run needs.
    pub setup: Seed000Setup,
    /// Epoch period `T`, s.
    pub period_s: f64,
    /// Look-ahead of the extended alarm, s.
    pub look_ahead_s: f64,
    /// First time the walker enters a danger zone, s (sampled every 10 ms), if he does.
    pub entry_time_s: Option<f64>,
    /// The pedestrian model (also the PCRB's dynamics).
    pub motion: PedestrianCv,
    /// Reader–reader links of the DV-Hop network.
    pub reader_links: usize,
    /// Extra loss of a path that leaves the tunnels, dB.
    pub nlos_loss_db: f64,
}

/// `SimError::Scenario` for `file` with `reason`.
pub(super) fn invalid(file: &str, reason: String) -> SimError {
    SimError::Scenario {
        file: file.to_string(),
        reason,
    }
}

/// Checks `value` finite and `> 0` (or `≥ 0` with `allow_zero`), naming `field`.
pub(super) fn check(file: &str, field: &str, value: f64, allow_zero: bool) -> Result<f64> {
    let ok = value.is_finite() && (value > 0.0 || (allow_zero && value == 0.0));
    if ok {
        Ok(value)
    } else {
        let need = if allow_zero {
            "finite and ≥ 0"
        } else {
            "finite and > 0"
        };
        Err(invalid(file, format!("`{field}` must be {need}, got {value}")))
    }
}

/// Checks a finite value, naming `field`.
pub(super) fn check_finite(file: &str, field: &str, values: &[f64]) -> Result<()> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(invalid(file, format!("`{field}` must be finite, got {v}"))),
        None => Ok(()),
    }
}

/// Parses and validates `000-mine-walk.toml`.
///
/// # Errors
/// [`SimError::Scenario`] naming the file and the field for a parse error, an unknown key or
/// an invalid value (non-positive variance, unknown tunnel, reader or waypoint outside the
/// tunnels, disconnected reader network …).
pub fn mine_walk(source: &ScenarioSource) -> Result<MineWalk> {
    let file = source.name.as_str();
    let raw: MineWalkFile = parse_scenario(source)?;
    let period_s = check(file, "period_s", raw.period_s, false)?;
    let mekf = MekfConfig {
        process_variance: check(file, "mekf.process_variance", raw.mekf.process_variance, false)?,
        measurement_variance: check(file, "mekf.measurement_variance", raw.mekf.measurement_variance, false)?,
    };
    check_finite(file, "prior.position_m", &raw.prior.position_m)?;
    check_finite(file, "prior.velocity_mps", &raw.prior.velocity_mps)?;
    let prior = TrackerPrior {
        position_m: raw.prior.position_m,
        velocity_mps: raw.prior.velocity_mps,
        position_variance_m2: check(file, "prior.position_std_m", raw.prior.position_std_m, false)?.powi(2),
        velocity_variance_m2s2: check(file, "prior.velocity_std_mps", raw.prior.velocity_std_mps, false)?.powi(2),
    };
    let r = &raw.radio;
    check_finite(file, "radio.reference_rssi_dbm", &[r.reference_rssi_dbm])?;
    let law = LogDistance::new(
        r.reference_rssi_dbm,
        check(file, "radio.exponent", r.exponent, false)?,
        check(file, "radio.reference_distance_m", r.reference_distance_m, false)?,
        check(file, "radio.shadowing_std_db", r.shadowing_std_db, true)?,
    )?;
    check_finite(file, "radio.sensitivity_dbm", &[r.sensitivity_dbm])?;
    let radio =
        ReaderRadio::new(law, r.sensitivity_dbm).map_err(|e| invalid(file, format!("`radio.sensitivity_dbm`: {e}")))?;
    let nlos_loss_db = check(file, "radio.nlos_loss_db", r.nlos_loss_db, true)?;
    let o = &raw.ours;
    let h = check(
        file,
        "ours.horizontal_acceleration_std_mps2",
        o.horizontal_acceleration_std_mps2,
        false,
    )?;
    let v = check(
        file,
        "ours.vertical_acceleration_std_mps2",
        o.vertical_acceleration_std_mps2,
        false,
    )?;
    let motion = PedestrianCv::new(h * h, v * v)?;
    let gate = ChiSquareGate::new(o.gate_probability)
        .map_err(|e| invalid(file, format!("`ours.gate_probability` must lie in (0, 1): {e}")))?;
    let look_ahead_s = check(file, "alarm.look_ahead_s", raw.alarm.look_ahead_s, false)?;
    let (layout, mean_height_m) = layout(file, &raw, nlos_loss_db)?;
    let path = walk(file, &raw.walk, &layout)?;
    let link_range_m = check(file, "dv_hop.link_range_m", raw.dv_hop.link_range_m, false)?;
    let options = SetupOptions {
        period_s,
        link_range_m,
        guess_below_m: mean_height_m,
        prior,
        mekf,
        ours: OursConfig {
            motion,
            gate_probability: gate.probability(),
            map: MapSpread {
                lateral_std_m: check(file, "map.lateral_std_m", raw.map.lateral_std_m, false)?,
                vertical_std_m: check(file, "map.vertical_std_m", raw.map.vertical_std_m, false)?,
            },
            max_speed_mps: check(file, "ours.max_speed_mps", o.max_speed_mps, false)?,
            junction_radius_m: check(file, "ours.junction_radius_m", o.junction_radius_m, true)?,
        },
    };
    let setup = Seed000Setup::new(&layout, radio, &path, &options).map_err(|e| {
        invalid(
            file,
            format!("the readers, the walk or the DV-Hop network are unusable: {e}"),
        )
    })?;
    let entry_time_s = first_entry_s(&layout, &path)?;
    Ok(MineWalk {
        reader_links: layout.reader_links(link_range_m).len(),
        nlos_loss_db,
        layout,
        path,
        setup,
        period_s,
        look_ahead_s,
        entry_time_s,
        motion,
    })
}

/// Builds the layout; returns it with the mean reader height above the walking line (m).
fn layout(file: &str, raw: &MineWalkFile, nlos_loss_db: f64) -> Result<(MineLayout, f64)> {
    let mut tunnels = Vec::with_capacity(raw.tunnels.len());
    for (i, t) in raw.tunnels.iter().enumerate() {
        let width = check(file, &format!("tunnels[{i}].half_width_m"), t.half_width_m, false)?;
        let tunnel = Tunnel::new(t.name.clone(), t.centreline_m.clone(), width)
            .map_err(|e| invalid(file, format!("`tunnels[{i}].centreline_m` ({}): {e}", t.name)))?;
        tunnels.push(tunnel);
    }
    let mut readers = Vec::with_capacity(raw.readers.len());
    let mut height_sum_m = 0.0;
    for (i, r) in raw.readers.iter().enumerate() {
        let tunnel = tunnels.iter().find(|t| t.name() == r.tunnel).ok_or_else(|| {
            invalid(
                file,
                format!("`readers[{i}].tunnel` ({}) names no tunnel: \"{}\"", r.name, r.tunnel),
            )
        })?;
        let height_m = check(file, &format!("readers[{i}].height_m"), r.height_m, true)?;
        let position_m = MineLayout::mount(tunnel, r.chainage_m, r.wall, height_m).map_err(|e| {
            invalid(
                file,
                format!(
                    "`readers[{i}].chainage_m` ({}) must lie on tunnel \"{}\": {e}",
                    r.name, r.tunnel
                ),
            )
        })?;
        height_sum_m += height_m;
        readers.push(Reader {
            name: r.name.clone(),
            position_m,
            status: if r.broken {
                ReaderStatus::Broken
            } else {
                ReaderStatus::Working
            },
            obstacle_loss_db: check(
                file,
                &format!("readers[{i}].obstacle_loss_db"),
                r.obstacle_loss_db,
                true,
            )?,
        });
    }
    if readers.is_empty() {
        return Err(invalid(file, "`readers` must list at least one reader".to_string()));
    }
    let mut obstructions = Vec::with_capacity(raw.obstructions.len());
    for (i, o) in raw.obstructions.iter().enumerate() {
        check_finite(file, &format!("obstructions[{i}].from_m"), &o.from_m)?;
        check_finite(file, &format!("obstructions[{i}].to_m"), &o.to_m)?;
        obstructions.push(Obstruction {
            name: o.name.clone(),
            from_m: o.from_m,
            to_m: o.to_m,
            loss_db: check(file, &format!("obstructions[{i}].loss_db"), o.loss_db, true)?,
        });
    }
    let mut zones = Vec::with_capacity(raw.danger_zones.len());
    for (i, z) in raw.danger_zones.iter().enumerate() {
        check_finite(
            file,
            &format!("danger_zones[{i}]"),
            &[z.min_m[0], z.min_m[1], z.max_m[0], z.max_m[1]],
        )?;
        if !(z.min_m[0] < z.max_m[0] && z.min_m[1] < z.max_m[1]) {
            return Err(invalid(
                file,
                format!("`danger_zones[{i}]` ({}) needs min_m < max_m on both axes", z.name),
            ));
        }
        zones.push(DangerZone {
            name: z.name.clone(),
            area: PlanBox {
                min_m: z.min_m,
                max_m: z.max_m,
            },
        });
    }
    let mean_height_m = height_sum_m / readers.len() as f64;
    let layout = MineLayout::new(tunnels, readers, zones, obstructions, nlos_loss_db)
        .map_err(|e| invalid(file, format!("`readers`/`tunnels`: {e}")))?;
    Ok((layout, mean_height_m))
}

/// Builds the walk and checks that it stays in the tunnels.
fn walk(file: &str, waypoints: &[Waypoint], layout: &MineLayout) -> Result<WaypointPath> {
    for (i, w) in waypoints.iter().enumerate() {
        check_finite(file, &format!("walk[{i}].position_m"), &w.position_m)?;
        if !layout.inside_tunnels(w.position_m) {
            return Err(invalid(
                file,
                format!("`walk[{i}].position_m` lies outside every tunnel"),
            ));
        }
        if i > 0 {
            let speed = check(file, &format!("walk[{i}].speed_mps"), w.speed_mps, false)?;
            if !(0.9..=1.5).contains(&speed) {
                return Err(invalid(
                    file,
                    format!("`walk[{i}].speed_mps` = {speed} is outside the paper's walking speeds, 0.9–1.5 m/s"),
                ));
            }
            if !layout.line_of_sight(waypoints[i - 1].position_m, w.position_m) {
                return Err(invalid(file, format!("the leg to `walk[{i}]` leaves the tunnels")));
            }
        }
        check(file, &format!("walk[{i}].pause_s"), w.pause_s, true)?;
    }
    WaypointPath::new(waypoints.to_vec()).map_err(|e| invalid(file, format!("`walk`: {e}")))
}

/// First time (10 ms resolution) the walker is in a danger zone.
fn first_entry_s(layout: &MineLayout, path: &WaypointPath) -> Result<Option<f64>> {
    for sample in path.sample(0.01)? {
        if layout.in_danger_zone(sample.position_m) {
            return Ok(Some(sample.time_s));
        }
    }
    Ok(None)
}
