//! The Labyrinth dataset (TU Chemnitz, T. Pfeifer, libRSF; CC BY-SA 4.0): a small
//! differential-drive robot in a 2.4 m × 2.4 m labyrinth, UWB ranges to four anchors in
//! round robin (one anchor per 0.128 s step) and wheel odometry at the same time stamps.
//!
//! # Files
//! `Indoor_UWB_Input.txt` — whitespace separated, first token the type:
//! - `range2 t range range_variance anchor_x anchor_y anchor_id snr` → a
//!   [`Measurement::Range`] to anchor `anchor_id` with `std_m = √range_variance`;
//! - `odom2diff t v_right v_left v_y wheel_base var_vr var_vl var_vy` (the readme numbers the
//!   variances 9–11; in the file they are tokens 7–9) → a [`Measurement::Odometry`].
//!
//! `Indoor_UWB_GT.txt` — `point2 t x y` + four zeros (a 2 × 2 covariance) → `truth.csv`.
//!
//! # Odometry → speed and heading
//! Speed `v = (v_r + v_l)/2`. Yaw rate `ω = (v_l − v_r)/(2·L)` with `L` the file's
//! `wheel_base` — the model of the dataset's own library (libRSF,
//! `include/factors/OdometryFactor2DDifferential.h`: wheel speeds `v ∓ L·ω` in the file's
//! column order), so `L` is the half-track and column 3 turns the other way than "right"
//! suggests. The textbook `(v_r − v_l)/L` turns the wrong way by twice the angle: dead
//! reckoning from the true start drifts 2.5 m by the end with it and 0.5 m with libRSF's (the
//! import notes give both).
//!
//! The heading is integrated forward, `ψ_k = ψ_0 + Σ_{j<k} ω_j·(t_{j+1} − t_j)` (each
//! sample's rate held until the next sample, the convention of the dataset check whose path
//! length is 9.33 m). Its variance grows as a random walk,
//! `σ²_ψ,k = Σ_{j<k} (σ²_vr,j + σ²_vl,j)/(4·L_j²) · (t_{j+1} − t_j)²` (independent wheel-speed
//! errors per sample), and the speed std is `√(σ²_vr + σ²_vl)/2`. A negative `v` (the robot
//! backing up) is written as speed `|v|` with heading `ψ + π`.
//!
//! The initial heading `ψ_0` is not in the data: it is the direction from the first
//! ground-truth point to the first one at least [`ALIGNMENT_DISTANCE_M`] away (the usual
//! initial alignment), stated in the notes.

#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::path::Path;

use rtls_engine::record::{Measurement, Record};

use super::util::{bracket, content_error, median, parse_error, parse_finite, read_text, weight};
use super::{create_dir, write_records, write_text, write_truth, ImportedRun, TruthRow};
use crate::Result;

/// Distance from the first ground-truth point that fixes the initial heading, m.
pub(super) const ALIGNMENT_DISTANCE_M: f64 = 0.1;

/// The tag id of the robot.
const TAG: &str = "robot";

/// One `range2` line.
#[derive(Debug, Clone, PartialEq)]
struct RangeLine {
    time_s: f64,
    range_m: f64,
    variance_m2: f64,
    anchor: String,
}

/// One `odom2diff` line.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OdometryLine {
    time_s: f64,
    v_right_mps: f64,
    v_left_mps: f64,
    wheel_base_m: f64,
    var_right_m2ps2: f64,
    var_left_m2ps2: f64,
}

impl OdometryLine {
    /// Yaw rate `ω = (v_l − v_r)/(2·L)`, rad/s (libRSF's model, see the module docs).
    fn yaw_rate_radps(&self) -> f64 {
        (self.v_left_mps - self.v_right_mps) / (2.0 * self.wheel_base_m)
    }

    /// The textbook `(v_r − v_l)/L`, rad/s: only used to show that it does not fit.
    fn textbook_yaw_rate_radps(&self) -> f64 {
        (self.v_right_mps - self.v_left_mps) / self.wheel_base_m
    }
}

/// Dead reckoning from the first truth point with heading `ψ_0` and a yaw-rate model: the
/// mean and the final distance to the truth at the odometry time stamps, m.
fn dead_reckoning_errors(
    odometry: &[OdometryLine],
    truth: &[TruthRow],
    times: &[f64],
    initial_heading_rad: f64,
    yaw_rate: fn(&OdometryLine) -> f64,
) -> Option<(f64, f64)> {
    let start = truth.first()?;
    let (mut x, mut y, mut heading) = (start.position_m[0], start.position_m[1], initial_heading_rad);
    let mut errors = Vec::new();
    for pair in odometry.windows(2) {
        let (o, dt) = (&pair[0], pair[1].time_s - pair[0].time_s);
        let v = 0.5 * (o.v_right_mps + o.v_left_mps);
        // p ← p + v·Δt·(cos ψ, sin ψ); ψ ← ψ + ω·Δt
        x += v * dt * heading.cos();
        y += v * dt * heading.sin();
        heading += yaw_rate(o) * dt;
        if let Some(p) = truth_at(truth, times, pair[1].time_s) {
            errors.push((x - p[0]).hypot(y - p[1]));
        }
    }
    let last = *errors.last()?;
    Some((errors.iter().sum::<f64>() / errors.len() as f64, last))
}

/// What `Indoor_UWB_Input.txt` holds.
#[derive(Debug, Default)]
struct Input {
    ranges: Vec<RangeLine>,
    odometry: Vec<OdometryLine>,
    /// Anchor id → position `[x, y]`, m.
    anchors: BTreeMap<String, [f64; 2]>,
}

const RANGE_FIELDS: [&str; 8] = [
    "type",
    "t",
    "range",
    "range_variance",
    "anchor_x",
    "anchor_y",
    "anchor_id",
    "snr",
];
const ODOMETRY_FIELDS: [&str; 9] = [
    "type",
    "t",
    "v_right",
    "v_left",
    "v_y",
    "wheel_base",
    "var_vr",
    "var_vl",
    "var_vy",
];
const TRUTH_FIELDS: [&str; 8] = ["type", "t", "x", "y", "cov[0]", "cov[1]", "cov[2]", "cov[3]"];

/// Checks the token count; names the first missing field (or the surplus).
fn check_count(path: &Path, line: u64, tokens: &[&str], fields: &[&str]) -> Result<()> {
    if tokens.len() == fields.len() {
        return Ok(());
    }
    let field = fields.get(tokens.len()).copied().unwrap_or("(end of line)");
    Err(parse_error(
        path,
        line,
        field,
        format!(
            "`{}` line has {} tokens, expected {}",
            tokens[0],
            tokens.len(),
            fields.len()
        ),
    ))
}

/// A finite number that must be ≥ 0 (`positive` → > 0).
fn non_negative(path: &Path, line: u64, field: &str, text: &str, positive: bool) -> Result<f64> {
    let value = parse_finite(path, line, field, text)?;
    if value < 0.0 || (positive && value == 0.0) {
        let bound = if positive { "> 0" } else { "≥ 0" };
        return Err(parse_error(path, line, field, format!("{value} must be {bound}")));
    }
    Ok(value)
}

fn read_input(path: &Path) -> Result<Input> {
    let text = read_text(path)?;
    let mut input = Input::default();
    for (index, raw) in text.lines().enumerate() {
        let line = index as u64 + 1;
        let tokens: Vec<&str> = raw.split_whitespace().collect();
        let Some(&kind) = tokens.first() else { continue };
        match kind {
            "range2" => {
                check_count(path, line, &tokens, &RANGE_FIELDS)?;
                let number = |k: usize| parse_finite(path, line, RANGE_FIELDS[k], tokens[k]);
                let position = [number(4)?, number(5)?];
                let anchor = tokens[6].to_string();
                if let Some(known) = input.anchors.get(&anchor) {
                    if *known != position {
                        return Err(parse_error(
                            path,
                            line,
                            "anchor_x",
                            format!("anchor {anchor} at {position:?}, earlier at {known:?}"),
                        ));
                    }
                }
                input.anchors.insert(anchor.clone(), position);
                input.ranges.push(RangeLine {
                    time_s: number(1)?,
                    range_m: non_negative(path, line, "range", tokens[2], false)?,
                    variance_m2: non_negative(path, line, "range_variance", tokens[3], false)?,
                    anchor,
                });
            }
            "odom2diff" => {
                check_count(path, line, &tokens, &ODOMETRY_FIELDS)?;
                let number = |k: usize| parse_finite(path, line, ODOMETRY_FIELDS[k], tokens[k]);
                number(4)?; // v_y: a differential drive has none (all zero); checked, not used
                number(8)?;
                input.odometry.push(OdometryLine {
                    time_s: number(1)?,
                    v_right_mps: number(2)?,
                    v_left_mps: number(3)?,
                    wheel_base_m: non_negative(path, line, "wheel_base", tokens[5], true)?,
                    var_right_m2ps2: non_negative(path, line, "var_vr", tokens[6], false)?,
                    var_left_m2ps2: non_negative(path, line, "var_vl", tokens[7], false)?,
                });
            }
            other => {
                return Err(parse_error(
                    path,
                    line,
                    "type",
                    format!("unknown line type `{other}` (expected range2 or odom2diff)"),
                ))
            }
        }
    }
    Ok(input)
}

fn read_truth(path: &Path) -> Result<Vec<TruthRow>> {
    let text = read_text(path)?;
    let mut rows: Vec<TruthRow> = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let line = index as u64 + 1;
        let tokens: Vec<&str> = raw.split_whitespace().collect();
        let Some(&kind) = tokens.first() else { continue };
        if kind != "point2" {
            return Err(parse_error(
                path,
                line,
                "type",
                format!("unknown line type `{kind}` (expected point2)"),
            ));
        }
        check_count(path, line, &tokens, &TRUTH_FIELDS)?;
        let number = |k: usize| parse_finite(path, line, TRUTH_FIELDS[k], tokens[k]);
        let time_s = number(1)?;
        if rows.last().is_some_and(|last| time_s < last.time_s) {
            return Err(parse_error(
                path,
                line,
                "t",
                "time earlier than the previous point2 line",
            ));
        }
        rows.push(TruthRow {
            time_s,
            tag: TAG.to_string(),
            position_m: vec![number(2)?, number(3)?],
        });
    }
    Ok(rows)
}

/// Odometry turned into speed and heading records, with the figures the notes report.
struct Integrated {
    records: Vec<Record>,
    /// Σ |v|·Δt, m.
    path_length_m: f64,
    /// Σ v·Δt (signed), m.
    signed_distance_m: f64,
    /// Samples with v < 0 (written as |v| with the heading turned by π).
    reversing: usize,
    /// Final heading std, rad.
    final_heading_std_rad: f64,
}

/// Integrates the heading (see the module docs). `odometry` must be in time order.
fn integrate(odometry: &[OdometryLine], initial_heading_rad: f64) -> Integrated {
    let mut out = Integrated {
        records: Vec::with_capacity(odometry.len()),
        path_length_m: 0.0,
        signed_distance_m: 0.0,
        reversing: 0,
        final_heading_std_rad: 0.0,
    };
    let (mut heading_rad, mut heading_var_rad2) = (initial_heading_rad, 0.0_f64);
    for (k, o) in odometry.iter().enumerate() {
        // v = (v_r + v_l)/2, σ_v = √(σ²_r + σ²_l)/2
        let v = 0.5 * (o.v_right_mps + o.v_left_mps);
        let speed_std = 0.5 * (o.var_right_m2ps2 + o.var_left_m2ps2).sqrt();
        let direction = if v < 0.0 {
            out.reversing += 1;
            heading_rad + std::f64::consts::PI
        } else {
            heading_rad
        };
        out.records.push(Record {
            time_s: o.time_s,
            tag: TAG.to_string(),
            measurement: Measurement::Odometry {
                speed_mps: v.abs(),
                heading_rad: Some(
                    (direction + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI,
                ),
                speed_std_mps: Some(speed_std),
                heading_std_rad: Some(heading_var_rad2.sqrt()),
            },
        });
        out.final_heading_std_rad = heading_var_rad2.sqrt();
        if let Some(next) = odometry.get(k + 1) {
            let dt = next.time_s - o.time_s;
            // ψ ← ψ + ω·Δt
            heading_rad += o.yaw_rate_radps() * dt;
            // σ²_ψ ← σ²_ψ + (σ²_r + σ²_l)/(4L²) · Δt²
            heading_var_rad2 += (o.var_right_m2ps2 + o.var_left_m2ps2) / (4.0 * o.wheel_base_m.powi(2)) * dt * dt;
            out.path_length_m += v.abs() * dt;
            out.signed_distance_m += v * dt;
        }
    }
    out
}

/// Direction of the first displacement of at least [`ALIGNMENT_DISTANCE_M`], rad, with the
/// index of that truth row.
fn initial_heading(truth: &[TruthRow]) -> Option<(f64, usize)> {
    let first = truth.first()?;
    let (x0, y0) = (first.position_m[0], first.position_m[1]);
    truth.iter().enumerate().find_map(|(i, row)| {
        let (dx, dy) = (row.position_m[0] - x0, row.position_m[1] - y0);
        (dx.hypot(dy) >= ALIGNMENT_DISTANCE_M).then(|| (dy.atan2(dx), i))
    })
}

/// Truth position at `t` (linear interpolation).
fn truth_at(truth: &[TruthRow], times: &[f64], t: f64) -> Option<[f64; 2]> {
    let (i, j) = bracket(times, t)?;
    let w = weight(times[i], times[j], t);
    let (a, b) = (&truth[i].position_m, &truth[j].position_m);
    Some([a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])])
}

fn site_toml(anchors: &BTreeMap<String, [f64; 2]>, range_std_m: f64) -> String {
    let mut text = String::from(
        "# The Labyrinth dataset (TU Chemnitz, T. Pfeifer, libRSF; CC BY-SA 4.0), written by `rtls import`.\n\
         name = \"TU Chemnitz labyrinth: UWB ranges to 4 anchors + wheel odometry\"\n\n\
         # Anchor positions from the range2 lines (2-D; the dataset gives no heights and treats ranges as planar).\n\
         # range_std_m = sqrt(range_variance) of the file. bias_m = 0: no calibration data exist for this run;\n\
         # the measured range - |truth - anchor| medians (+0.07..+0.15 m) are in the import notes.\n",
    );
    for (id, [x, y]) in anchors {
        text.push_str(&format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{x:?}, {y:?}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = {range_std_m:?}, bias_m = 0.0 }} }}\n\n"
        ));
    }
    text.push_str(
        "[tracker]\n\
         pipeline = \"tightly-coupled\"\n\
         motion_model = \"cv\"\n\
         filter = \"ekf\"\n\
         # A small robot (7.85 cm half-track) at up to 0.4 m/s that stops and turns at the labyrinth's corners\n\
         # within about a second: accelerations of a few tenths of m/s^2, so 0.5 m/s^2.\n\
         acceleration_noise_std_mps2 = 0.5\n\
         gate_probability = 0.999\n\
         initiation = { confirm_updates = 3, within_s = 2.0 }\n\
         coast_timeout_s = 2.0\n\
         delete_timeout_s = 60.0\n\
         # The measurement file is in time order; 0.1 s is less than one 0.128 s step.\n\
         reorder_window_s = 0.1\n\
         # The dataset is planar (2-D anchors and truth); anchors and robot are taken to be coplanar.\n\
         dimensions = 2\n\
         # One round-robin cycle: the 4 anchors answer one per 0.128 s step, so a cycle's ranges span\n\
         # 0.384 s from the first; 0.45 s takes those 4 and never the next cycle's first (0.512 s).\n\
         epoch_s = 0.45\n",
    );
    text
}

/// Imports the labyrinth dataset into `OUT/labyrinth/`.
pub(super) fn import(dataset_dir: &Path, out_dir: &Path) -> Result<Vec<ImportedRun>> {
    let input_path = dataset_dir.join("Indoor_UWB_Input.txt");
    let truth_path = dataset_dir.join("Indoor_UWB_GT.txt");
    let mut input = read_input(&input_path)?;
    let truth = read_truth(&truth_path)?;
    if input.ranges.is_empty() || input.odometry.is_empty() {
        return Err(content_error(&input_path, "needs both range2 and odom2diff lines"));
    }
    let (initial_heading_rad, aligned_at) = initial_heading(&truth).ok_or_else(|| {
        content_error(
            &truth_path,
            format!("the ground truth never moves {ALIGNMENT_DISTANCE_M} m: no initial heading"),
        )
    })?;
    input.odometry.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    input.ranges.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let integrated = integrate(&input.odometry, initial_heading_rad);

    let ranges: Vec<Record> = input
        .ranges
        .iter()
        .map(|r| Record {
            time_s: r.time_s,
            tag: TAG.to_string(),
            measurement: Measurement::Range {
                anchor: r.anchor.clone(),
                range_m: r.range_m,
                std_m: Some(r.variance_m2.sqrt()),
                anchor_position_m: None,
            },
        })
        .collect();
    // merge by time (stable: at equal times the range comes first)
    let mut all = Vec::with_capacity(ranges.len() + integrated.records.len());
    let (mut i, mut j) = (0, 0);
    while i < ranges.len() || j < integrated.records.len() {
        let take_range =
            j == integrated.records.len() || (i < ranges.len() && ranges[i].time_s <= integrated.records[j].time_s);
        if take_range {
            all.push(ranges[i].clone());
            i += 1;
        } else {
            all.push(integrated.records[j].clone());
            j += 1;
        }
    }

    // notes: range residuals per anchor, path lengths
    let times: Vec<f64> = truth.iter().map(|r| r.time_s).collect();
    let mut per_anchor: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    let mut unchecked = 0;
    for r in &input.ranges {
        let (Some(p), Some(a)) = (truth_at(&truth, &times, r.time_s), input.anchors.get(&r.anchor)) else {
            unchecked += 1;
            continue;
        };
        per_anchor
            .entry(&r.anchor)
            .or_default()
            .push(r.range_m - (p[0] - a[0]).hypot(p[1] - a[1]));
    }
    let medians: Vec<String> = per_anchor
        .iter()
        .filter_map(|(id, v)| median(v).map(|m| format!("{id} {m:+.3} m (n {})", v.len())))
        .collect();
    let truth_length_m: f64 = truth
        .windows(2)
        .map(|w| (w[1].position_m[0] - w[0].position_m[0]).hypot(w[1].position_m[1] - w[0].position_m[1]))
        .sum();
    let range_std_m = median(&input.ranges.iter().map(|r| r.variance_m2.sqrt()).collect::<Vec<_>>())
        .ok_or_else(|| content_error(&input_path, "no range2 lines"))?;
    let dead_reckoning = |model: fn(&OdometryLine) -> f64| {
        dead_reckoning_errors(&input.odometry, &truth, &times, initial_heading_rad, model).map_or_else(
            || "not computable".to_string(),
            |(mean, end)| format!("mean {mean:.2} m, end {end:.2} m"),
        )
    };
    let dead_reckoning_note = format!(
        "yaw-rate model check, dead reckoning from the true start with ψ0: libRSF's (v_l − v_r)/(2L) → {}; the \
         textbook (v_r − v_l)/L → {} (so the former is used)",
        dead_reckoning(OdometryLine::yaw_rate_radps),
        dead_reckoning(OdometryLine::textbook_yaw_rate_radps)
    );

    let dir = out_dir.join("labyrinth");
    create_dir(&dir)?;
    let files = vec![
        dir.join("site.toml"),
        dir.join("measurements.jsonl"),
        dir.join("measurements-uwb-only.jsonl"),
        dir.join("truth.csv"),
    ];
    write_text(&files[0], &site_toml(&input.anchors, range_std_m))?;
    write_records(&files[1], &all)?;
    write_records(&files[2], &ranges)?;
    write_truth(&files[3], &truth)?;
    let notes = vec![
        format!(
            "{} range2 lines → range records (std_m = √range_variance), {} odom2diff lines → odometry records, {} \
             point2 lines → truth; measurements-uwb-only.jsonl holds the ranges alone",
            ranges.len(),
            integrated.records.len(),
            truth.len()
        ),
        format!(
            "initial heading NOT in the data: taken from the ground truth's first displacement (point 1 to point {}, \
             the first ≥ {ALIGNMENT_DISTANCE_M} m away): {:.1}° — the usual initial alignment",
            aligned_at + 1,
            initial_heading_rad.to_degrees()
        ),
        format!(
            "heading = ψ0 + Σ ω·Δt with ω = (v_l − v_r)/(2L) (libRSF's differential-drive model; L = the file's \
             wheel_base); heading std grows as √Σ (var_vr + var_vl)/(4L²)·Δt² (random walk of the integrated yaw-rate \
             noise), {:.3} rad at the end; speed = (v_r + v_l)/2, std √(var_vr + var_vl)/2",
            integrated.final_heading_std_rad
        ),
        dead_reckoning_note,
        format!(
            "{} odometry samples with negative speed (backing up, down to {:.3} m/s) are written as |v| with the \
             heading turned by π",
            integrated.reversing,
            input
                .odometry
                .iter()
                .map(|o| 0.5 * (o.v_right_mps + o.v_left_mps))
                .fold(0.0, f64::min)
        ),
        format!(
            "integrated odometry: signed distance {:.2} m, path length Σ|v|Δt {:.2} m; ground-truth path {:.2} m",
            integrated.signed_distance_m, integrated.path_length_m, truth_length_m
        ),
        format!(
            "range − |truth − anchor| median per anchor (NOT calibrated: no separate calibration data): {}{}",
            medians.join(", "),
            if unchecked > 0 {
                format!("; {unchecked} ranges outside the truth span not checked")
            } else {
                String::new()
            }
        ),
    ];
    Ok(vec![ImportedRun {
        name: "labyrinth".to_string(),
        files,
        records: all.len(),
        truth_rows: truth.len(),
        notes,
    }])
}
