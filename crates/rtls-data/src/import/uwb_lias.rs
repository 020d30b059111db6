//! LIAS CUHK-SZ planar rigid-body UWB dataset (`uwb_lias_cuhksz_planar_rbl`): a trolley carrying
//! a rigid body with three TWR tags ranging to eight anchors at 100 Hz, motion capture at
//! 120 Hz (Jiang et al., "Efficient Planar Pose Estimation via UWB Measurements", ICRA 2023;
//! MIT licence).
//!
//! # Runs written
//! `fast`, `mid` (dynamic; `slow` has motion capture but no UWB file and is skipped) and
//! `static-pos1` … `static-pos5` (the staged `deg_0` static files; truth = the surveyed pose of
//! `Static/README.md`). Each gets `site.toml`, `measurements.jsonl` (bias-corrected ranges),
//! `measurements-raw.jsonl` (the ranges as recorded) and `truth.csv`; `OUT/calibration.csv`
//! holds the calibration table.
//!
//! # Conventions (checked, see the notes and tests)
//! - Times are seconds since midnight of the recording's local wall clock (UWB and motion
//!   capture share it), exact to the millisecond of the files.
//! - Tag `Tk` position = centroid + `Rz(yaw)`·offset `k`, yaw = `2·atan2(col7, col6)`; the
//!   README's `(q_w, q_x, q_y, q_z)` order does not fit the ranges.
//! - Truth is 2-D (`x, y`) at the motion-capture rate for all three tags; tracking is 2-D with
//!   the tags at [`RIGID_BODY_HEIGHT_M`] (anchors are at 1.04 m).
//! - Ranges are corrected with the static-run calibration ([`calibration`]); record `std_m` is
//!   left empty so the per-anchor `range_std_m` of the site (post-calibration residual std)
//!   applies.

mod calibration;
mod parse;
mod site;

#[cfg(test)]
mod tests;

use std::path::Path;

use rtls_engine::record::{Measurement, Record};

use self::calibration::{Calibration, StaticRun};
use self::parse::{pair_anchor, pair_tag, read_mocap, read_static_poses, read_uwb, MocapRow, UwbRow};
use super::util::{bracket, content_error, mean_std, median, pearson, read_text, weight};
use super::{create_dir, write_records, write_text, write_truth, ImportedRun, TruthRow};
use crate::Result;

/// Anchor ids and positions `[x, y, z]`, m (dataset README, global motion-capture frame).
pub(super) const ANCHORS: [(&str, [f64; 3]); 8] = [
    ("A0", [-3.4203, 3.0053, 1.0442]),
    ("A1", [0.0016, 3.0110, 1.0446]),
    ("A2", [3.6056, 2.9795, 1.0463]),
    ("A3", [3.6011, -0.0008, 1.0422]),
    ("A4", [3.5674, -3.0087, 1.0443]),
    ("A5", [-0.0072, -2.9652, 1.0444]),
    ("A6", [-3.4673, -2.9587, 1.0445]),
    ("A7", [-3.4858, -0.0098, 1.0457]),
];

/// Tag ids and offsets in the rigid-body frame `[x, y, z]`, m.
pub(super) const TAGS: [(&str, [f64; 3]); 3] = [
    ("T0", [-0.0689, -0.1423, 0.0011]),
    ("T1", [-0.0750, 0.1402, 0.0016]),
    ("T2", [0.2034, 0.1451, -0.0008]),
];

/// Range columns per UWB row (8 anchors × 3 tags).
pub(super) const PAIRS: usize = 24;

/// Height of the rigid-body centroid, m: the motion capture puts it at 0.95–0.99 m (median
/// 0.971 m fast, 0.973 m mid); the static poses give no height, so the same trolley height is
/// used there. Against anchors at 1.04 m the height term changes a 1 m range by < 3 mm.
pub(super) const RIGID_BODY_HEIGHT_M: f64 = 0.97;

/// The dynamic runs with a UWB file.
const DYNAMIC_RUNS: [&str; 2] = ["fast", "mid"];

/// Number of staged static runs (`UWB_static_exp_8_14_pos{1..5}_deg_0.csv`).
const STATIC_RUNS: usize = 5;

/// Position of tag `tag` for a centroid and a yaw, m.
pub(super) fn tag_position_m(centroid_m: [f64; 3], yaw_rad: f64, tag: usize) -> [f64; 3] {
    let [ox, oy, oz] = TAGS[tag].1;
    let (sin, cos) = yaw_rad.sin_cos();
    // p = c + Rz(ψ)·o
    [
        centroid_m[0] + cos * ox - sin * oy,
        centroid_m[1] + sin * ox + cos * oy,
        centroid_m[2] + oz,
    ]
}

/// Appends the 2-D truth rows of the three tags for one rigid-body pose.
fn push_truth(truth: &mut Vec<TruthRow>, time_s: f64, centroid_m: [f64; 3], yaw_rad: f64) {
    for (tag, (id, _)) in TAGS.iter().enumerate() {
        let p = tag_position_m(centroid_m, yaw_rad, tag);
        truth.push(TruthRow {
            time_s,
            tag: (*id).to_string(),
            position_m: vec![p[0], p[1]],
        });
    }
}

/// Euclidean distance, m.
pub(super) fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Motion-capture track of a run on the run's clock, for interpolation.
struct Track {
    times_s: Vec<f64>,
    rows: Vec<MocapRow>,
}

/// An interpolated motion-capture pose.
struct Pose {
    centroid_m: [f64; 3],
    /// Yaw `2·atan2(col7, col6)`, interpolated along the shorter arc, rad.
    yaw_rad: f64,
    /// The four rotation columns, interpolated in the same hemisphere and normalised.
    rotation: [f64; 4],
}

impl Track {
    /// The pose at `t` (linear interpolation); `None` outside the recorded span.
    fn pose_at(&self, t: f64) -> Option<Pose> {
        let (i, j) = bracket(&self.times_s, t)?;
        let w = weight(self.times_s[i], self.times_s[j], t);
        let (a, b) = (&self.rows[i], &self.rows[j]);
        let centroid_m = std::array::from_fn(|k| a.centroid_m[k] + w * (b.centroid_m[k] - a.centroid_m[k]));
        let (ya, yb) = (a.yaw_rad(), b.yaw_rad());
        let dy = (yb - ya + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        // q and −q are the same rotation: interpolate towards the copy of b nearer to a
        let dot: f64 = (0..4).map(|k| a.rotation[k] * b.rotation[k]).sum();
        let sign = if dot < 0.0 { -1.0 } else { 1.0 };
        let q: [f64; 4] = std::array::from_fn(|k| a.rotation[k] + w * (sign * b.rotation[k] - a.rotation[k]));
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        Some(Pose {
            centroid_m,
            yaw_rad: ya + w * dy,
            rotation: q.map(|c| c / norm),
        })
    }
}

/// Range residuals `r − d` of a dynamic run against the interpolated motion capture.
struct ResidualCheck {
    raw_median_m: f64,
    corrected_median_m: f64,
    corrected_std_m: f64,
    documented_order_std_m: f64,
    outside_mocap: usize,
}

fn residual_check(rows: &[UwbRow], times_s: &[f64], track: &Track, calibration: &Calibration) -> Option<ResidualCheck> {
    let (mut raw, mut corrected, mut documented) = (Vec::new(), Vec::new(), Vec::new());
    let mut outside_mocap = 0;
    for (row, &t) in rows.iter().zip(times_s) {
        let pose = track.pose_at(t);
        for (pair, range) in row.ranges_m.iter().enumerate() {
            let Some(r) = range.filter(|&r| r > 0.0) else { continue };
            let Some(pose) = &pose else {
                outside_mocap += 1;
                continue;
            };
            let (anchor, tag) = (ANCHORS[pair_anchor(pair)].1, pair_tag(pair));
            let d = distance_m(tag_position_m(pose.centroid_m, pose.yaw_rad, tag), anchor);
            raw.push(r - d);
            corrected.push(calibration.pairs[pair].correct(r) - d);
            let offset = parse::rotate_documented_order(pose.rotation, TAGS[tag].1);
            let p: [f64; 3] = std::array::from_fn(|k| pose.centroid_m[k] + offset[k]);
            documented.push(r - distance_m(p, anchor));
        }
    }
    Some(ResidualCheck {
        raw_median_m: median(&raw)?,
        corrected_median_m: median(&corrected)?,
        corrected_std_m: mean_std(&corrected)?.1,
        documented_order_std_m: mean_std(&documented)?.1,
        outside_mocap,
    })
}

/// Times of UWB rows, s since midnight of `origin_day`.
fn row_times(rows: &[UwbRow], origin_day: i64) -> Vec<f64> {
    rows.iter()
        .map(|r| r.clock.seconds_since_midnight_of(origin_day))
        .collect()
}

/// The records of a run (corrected and raw) and what was left out.
struct RunRecords {
    corrected: Vec<Record>,
    raw: Vec<Record>,
    empty_cells: usize,
    extra_value_lines: Vec<u64>,
    zero_ranges: Vec<String>,
    below_bias: Vec<String>,
}

fn build_records(rows: &[UwbRow], times_s: &[f64], calibration: &Calibration) -> RunRecords {
    let mut out = RunRecords {
        corrected: Vec::new(),
        raw: Vec::new(),
        empty_cells: 0,
        extra_value_lines: Vec::new(),
        zero_ranges: Vec::new(),
        below_bias: Vec::new(),
    };
    for (row, &time_s) in rows.iter().zip(times_s) {
        if row.extra_values > 0 {
            out.extra_value_lines.push(row.line);
        }
        for (pair, range) in row.ranges_m.iter().enumerate() {
            let Some(range_m) = *range else {
                out.empty_cells += 1;
                continue;
            };
            let at = format!("line {} {}", row.line, parse::pair_column(pair));
            if range_m <= 0.0 {
                out.zero_ranges.push(at);
                continue;
            }
            let corrected_m = calibration.pairs[pair].correct(range_m);
            if corrected_m < 0.0 {
                out.below_bias.push(at);
                continue;
            }
            let record = |range_m: f64| Record {
                time_s,
                tag: TAGS[pair_tag(pair)].0.to_string(),
                measurement: Measurement::Range {
                    anchor: ANCHORS[pair_anchor(pair)].0.to_string(),
                    range_m,
                    std_m: None,
                    anchor_position_m: None,
                },
            };
            out.corrected.push(record(corrected_m));
            out.raw.push(record(range_m));
        }
    }
    out
}

/// Writes the four files of one run and returns its summary (notes to be completed).
fn write_run(
    out_dir: &Path,
    name: &str,
    site_text: &str,
    records: &RunRecords,
    truth: &[TruthRow],
    uwb_rows: usize,
) -> Result<ImportedRun> {
    let dir = out_dir.join(name);
    create_dir(&dir)?;
    let files = vec![
        dir.join("site.toml"),
        dir.join("measurements.jsonl"),
        dir.join("measurements-raw.jsonl"),
        dir.join("truth.csv"),
    ];
    write_text(&files[0], site_text)?;
    write_records(&files[1], &records.corrected)?;
    write_records(&files[2], &records.raw)?;
    write_truth(&files[3], truth)?;
    let mut notes = vec![format!(
        "{uwb_rows} UWB rows → {} range records per file; {} empty range cells (no measurement, no record)",
        records.corrected.len(),
        records.empty_cells
    )];
    if !records.extra_value_lines.is_empty() {
        notes.push(format!(
            "{} row(s) carry values after the 24 range columns (not ranges, e.g. 0 and 652.8; ignored): lines {:?}",
            records.extra_value_lines.len(),
            records.extra_value_lines
        ));
    }
    if !records.zero_ranges.is_empty() {
        notes.push(format!(
            "skipped {} range(s) of exactly 0 m (a failed exchange, not a distance), in both measurement files: {}",
            records.zero_ranges.len(),
            records.zero_ranges.join(", ")
        ));
    }
    if !records.below_bias.is_empty() {
        notes.push(format!(
            "skipped {} range(s) shorter than their pair's bias (negative after correction), in both files: {}",
            records.below_bias.len(),
            records.below_bias.join(", ")
        ));
    }
    Ok(ImportedRun {
        name: name.to_string(),
        files,
        records: records.corrected.len(),
        truth_rows: truth.len(),
        notes,
    })
}

/// Correlation of our biases with the dataset's `calibration/bias.csv` (whose pair order is
/// undocumented) under both plausible orders. Their numbers are not used.
fn compare_reference(dataset_dir: &Path, calibration: &Calibration) -> Result<String> {
    let path = dataset_dir.join("calibration/bias.csv");
    if !path.exists() {
        return Ok(format!("{} not found: no comparison", path.display()));
    }
    let text = read_text(&path)?;
    let mut theirs = Vec::new();
    for (index, line) in text.lines().enumerate() {
        if !line.trim().is_empty() {
            theirs.push(super::util::parse_finite(&path, index as u64 + 1, "bias", line)?);
        }
    }
    if theirs.len() != PAIRS {
        return Err(content_error(&path, format!("{} values, expected 24", theirs.len())));
    }
    let ours_anchor_major: Vec<f64> = calibration.pairs.iter().map(|p| p.bias_m).collect();
    let ours_tag_major: Vec<f64> = (0..PAIRS)
        .map(|i| calibration.pairs[(i % ANCHORS.len()) * TAGS.len() + i / ANCHORS.len()].bias_m)
        .collect();
    let fmt = |r: Option<f64>| r.map_or_else(|| "undefined".to_string(), |r| format!("{r:.2}"));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    Ok(format!(
        "comparison with the dataset's calibration/bias.csv (not used): Pearson r = {} if its order is anchor-major \
         (a0-t0, a0-t1, …, as the UWB columns), r = {} if tag-major (t0-a0, t0-a1, …); mean bias theirs {:.3} m vs \
         ours {:.3} m (their model may include their slope.csv term)",
        fmt(pearson(&theirs, &ours_anchor_major)),
        fmt(pearson(&theirs, &ours_tag_major)),
        mean(&theirs),
        mean(&ours_anchor_major)
    ))
}

/// Reads the static runs (poses from `Static/README.md`, ranges from the `deg_0` files).
fn read_static_runs(dataset_dir: &Path) -> Result<Vec<StaticRun>> {
    let poses = read_static_poses(&dataset_dir.join("Static/README.md"), STATIC_RUNS)?;
    let mut runs = Vec::new();
    for pose in poses {
        let path = dataset_dir.join(format!("Static/UWB_static_exp_8_14_pos{}_deg_0.csv", pose.pose));
        let rows = read_uwb(&path)?;
        if rows.is_empty() {
            return Err(content_error(&path, "no UWB rows"));
        }
        runs.push(StaticRun { pose, rows });
    }
    Ok(runs)
}

/// What every run of the dataset shares.
struct Shared<'a> {
    dataset_dir: &'a Path,
    out_dir: &'a Path,
    calibration: &'a Calibration,
    site_text: &'a str,
}

/// Imports dynamic run `name` (UWB + motion capture).
fn import_dynamic(shared: &Shared<'_>, name: &str) -> Result<ImportedRun> {
    let uwb_path = shared.dataset_dir.join(format!("Dynamic/UWB_dynamic_exp_{name}.csv"));
    let mocap_path = shared
        .dataset_dir
        .join(format!("Dynamic/motion_capture_dynamic_exp_{name}.csv"));
    let rows = read_uwb(&uwb_path)?;
    let mocap = read_mocap(&mocap_path)?;
    let origin_day = rows
        .first()
        .ok_or_else(|| content_error(&uwb_path, "no UWB rows"))?
        .clock
        .day();
    if mocap.is_empty() {
        return Err(content_error(&mocap_path, "no motion-capture rows"));
    }
    let times_s = row_times(&rows, origin_day);
    let mocap_times: Vec<f64> = mocap
        .iter()
        .map(|m| m.clock.seconds_since_midnight_of(origin_day))
        .collect();
    let duplicates = mocap_times.windows(2).filter(|w| w[1] == w[0]).count();
    if let Some(k) = mocap_times.windows(2).position(|w| w[1] < w[0]) {
        let line = mocap[k + 1].line;
        return Err(super::util::parse_error(
            &mocap_path,
            line,
            "time",
            "time stamp earlier than the previous row",
        ));
    }
    let mut truth: Vec<TruthRow> = Vec::with_capacity(mocap.len() * TAGS.len());
    // rows repeating a time stamp (the millisecond clock) are averaged into one sample per tag,
    // so that the truth is a function of time
    let mut start = 0;
    while start < mocap.len() {
        let t = mocap_times[start];
        let end = start + mocap_times[start..].iter().take_while(|&&u| u == t).count();
        let mut group = Vec::with_capacity((end - start) * TAGS.len());
        for row in &mocap[start..end] {
            push_truth(&mut group, t, row.centroid_m, row.yaw_rad());
        }
        // mean of each tag's positions over the group's rows
        let rows = (end - start) as f64;
        for (tag, sample) in group.iter().take(TAGS.len()).enumerate() {
            let mut mean = vec![0.0; sample.position_m.len()];
            for row in group.iter().skip(tag).step_by(TAGS.len()) {
                for (m, p) in mean.iter_mut().zip(&row.position_m) {
                    *m += p / rows;
                }
            }
            truth.push(TruthRow {
                position_m: mean,
                ..sample.clone()
            });
        }
        start = end;
    }
    let records = build_records(&rows, &times_s, shared.calibration);
    let track = Track {
        times_s: mocap_times,
        rows: mocap,
    };
    let mut run = write_run(shared.out_dir, name, shared.site_text, &records, &truth, rows.len())?;
    run.notes.push(format!(
        "times: seconds since midnight of the local clock ({} … {} s); truth: 3 tags × {} motion-capture rows \
         (2-D, yaw = 2·atan2(col7, col6)); {duplicates} motion-capture rows repeat the previous time stamp \
         (the millisecond clock): averaged with it into one truth sample",
        times_s.first().copied().unwrap_or_default(),
        times_s.last().copied().unwrap_or_default(),
        track.rows.len()
    ));
    if let Some(check) = residual_check(&rows, &times_s, &track, shared.calibration) {
        run.notes.push(format!(
            "check against the interpolated motion capture: raw r − d median {:+.3} m; corrected median {:+.3} m, \
             std {:.3} m; with the README's (q_w, q_x, q_y, q_z) order the raw spread would be {:.3} m; {} ranges \
             outside the motion-capture span not checked",
            check.raw_median_m,
            check.corrected_median_m,
            check.corrected_std_m,
            check.documented_order_std_m,
            check.outside_mocap
        ));
    }
    Ok(run)
}

/// Imports a static run (truth = the surveyed pose at every UWB row time).
fn import_static(shared: &Shared<'_>, run: &StaticRun) -> Result<ImportedRun> {
    let name = format!("static-pos{}", run.pose.pose);
    let origin_day = run.rows.first().map_or(0, |r| r.clock.day());
    let times_s = row_times(&run.rows, origin_day);
    let [x, y] = run.pose.centroid_m;
    let mut truth = Vec::with_capacity(times_s.len() * TAGS.len());
    for &t in &times_s {
        push_truth(&mut truth, t, [x, y, RIGID_BODY_HEIGHT_M], run.pose.yaw_rad);
    }
    let records = build_records(&run.rows, &times_s, shared.calibration);
    let mut imported = write_run(
        shared.out_dir,
        &name,
        shared.site_text,
        &records,
        &truth,
        run.rows.len(),
    )?;
    imported.notes.push(format!(
        "static: truth = the surveyed pose (x {x} m, y {y} m, yaw {:.3}°) for the 3 tags at every UWB row time; \
         this run is part of the calibration set, so its corrected ranges are not an independent test",
        run.pose.yaw_rad.to_degrees()
    ));
    Ok(imported)
}

/// Imports the LIAS dataset (see the module docs).
pub(super) fn import(dataset_dir: &Path, out_dir: &Path) -> Result<Vec<ImportedRun>> {
    let static_runs = read_static_runs(dataset_dir)?;
    let calibration = calibration::calibrate(&static_runs).ok_or_else(|| {
        content_error(
            &dataset_dir.join("Static"),
            "the static runs hold too little data to calibrate every (anchor, tag) pair",
        )
    })?;
    create_dir(out_dir)?;
    let calibration_path = out_dir.join("calibration.csv");
    write_text(&calibration_path, &calibration.to_csv())?;
    let site_text = site::site_toml(&calibration);
    let mut dataset_notes = calibration.notes();
    dataset_notes.push(compare_reference(dataset_dir, &calibration)?);
    dataset_notes
        .push("run `slow` skipped: its UWB file is not in the dataset snapshot (motion capture only)".to_string());
    dataset_notes.push(
        "record std_m is left empty: the site's per-anchor range_std_m (post-calibration static residual std) applies"
            .to_string(),
    );
    let shared = Shared {
        dataset_dir,
        out_dir,
        calibration: &calibration,
        site_text: &site_text,
    };
    let mut runs = Vec::new();
    for name in DYNAMIC_RUNS {
        runs.push(import_dynamic(&shared, name)?);
    }
    for run in &static_runs {
        runs.push(import_static(&shared, run)?);
    }
    if let Some(first) = runs.first_mut() {
        first.files.insert(0, calibration_path);
        let mut notes = dataset_notes;
        notes.append(&mut first.notes);
        first.notes = notes;
    }
    for run in runs.iter_mut().skip(1) {
        run.notes
            .push("ranges corrected with ../calibration.csv (see the notes of run `fast`)".to_string());
    }
    Ok(runs)
}
