//! The explanatory tables and notes of the `mekf` report; every number in them is computed in
//! the run, and the notes' prose is in `templates/mekf.md`.

use super::evaluate::{AlarmSummary, DistanceBin, Extras, MethodSummary, ObstacleAnalysis, METHODS};
use super::scenario::MineWalk;
use super::table1::{Table1, Table1Evaluation};
use crate::experiments::common::fmt;
use crate::experiments::template::{files::MEKF as T, render};
use crate::report::Table;
use crate::reproduction::seed_000::TrackerCounts;
use rtls_sim::sensors::readers::ReaderStatus;

/// Everything the notes quote.
pub(super) struct NotesInput<'a> {
    pub(super) walk: &'a MineWalk,
    pub(super) summaries: &'a [MethodSummary],
    pub(super) bins: &'a [DistanceBin],
    pub(super) alarms: &'a [(&'a str, String, AlarmSummary)],
    /// RSSI fix kinds (%): multilateration, guided, centroid.
    pub(super) kinds: [f64; 3],
    /// Our tracker's decisions summed over the runs.
    pub(super) counts: TrackerCounts,
    /// DV-Hop: heard epochs without a fix, %.
    pub(super) dv_hop_failures_percent: f64,
    pub(super) extras: &'a Extras,
    pub(super) obstacles: &'a ObstacleAnalysis,
    /// √PCRB from the detected readers only, no map: trackers' epochs, RSSI fix epochs (m).
    pub(super) naive_bounds_m: [f64; 2],
    pub(super) table: &'a Table1,
    pub(super) table_1: &'a Table1Evaluation,
    pub(super) runs: usize,
}

fn opt(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or_else(|| "–".to_string(), |v| format!("{:.*}", digits, scale * v))
}

/// Error rate and |error| in x by distance of the truth from the origin.
pub(super) fn distance_table(bins: &[DistanceBin]) -> Table {
    let mut header = vec!["true |x| (m)".to_string(), "epochs".to_string()];
    header.extend(METHODS.iter().map(|m| format!("{m} x rate (%)")));
    header.extend(METHODS.iter().map(|m| format!("{m} |x error| (m)")));
    let rows = bins
        .iter()
        .map(|b| {
            let mut row = vec![
                match b.upper_m {
                    Some(u) => format!("[{}, {})", b.lower_m, u),
                    None => format!("≥ {}", b.lower_m),
                },
                b.count.to_string(),
            ];
            row.extend(b.rates.iter().map(|r| opt(*r, 100.0, 1)));
            row.extend(b.abs_errors_m.iter().map(|e| opt(*e, 1.0, 2)));
            row
        })
        .collect();
    Table {
        title: "The error rate |D − N|/N falls with the distance from the origin while the error in metres does not: x rate and mean |x error| by true |x|".to_string(),
        header,
        rows,
    }
}

/// Alarm statistics per tracker and horizon.
pub(super) fn alarm_table(alarms: &[(&str, String, AlarmSummary)]) -> Table {
    Table {
        title: "Predictive danger-zone alarm: the CV prediction of the track enters the zone".to_string(),
        header: [
            "tracker",
            "prediction",
            "warned before entry (% of runs)",
            "mean lead time (s)",
            "false alarms per run",
        ]
        .map(String::from)
        .to_vec(),
        rows: alarms
            .iter()
            .map(|(tracker, label, a)| {
                vec![
                    (*tracker).to_string(),
                    label.clone(),
                    format!("{:.0}", a.warned_percent),
                    opt(a.mean_lead_s, 1.0, 2),
                    format!("{:.2}", a.false_per_run),
                ]
            })
            .collect(),
    }
}

/// How the RSSI fixes were obtained.
pub(super) fn fix_table(kinds: &[f64; 3]) -> Table {
    let names = [
        "≥ 4 readers: Gauss–Newton from the linear LS fix",
        "3 readers (or coplanar): Gauss–Newton from below the readers' centroid",
        "1–2 readers: range-weighted centroid",
    ];
    Table {
        title: "RSSI fixes by how they were obtained (% of non-empty fixes)".to_string(),
        header: ["method", "share (%)"].map(String::from).to_vec(),
        rows: names
            .iter()
            .zip(kinds)
            .map(|(n, k)| vec![(*n).to_string(), format!("{k:.1}")])
            .collect(),
    }
}

/// Mean RSSI innovation of our tracker per reader (obstacle analysis, paper capability 4).
pub(super) fn obstacle_table(walk: &MineWalk, innovations: &[(Option<f64>, usize)]) -> Table {
    Table {
        title: "Obstacle analysis: mean RSSI innovation (measured − predicted) of our tracker per reader; an obstacle next to a reader makes it strongly negative".to_string(),
        header: ["reader", "status", "obstacle loss (truth, dB)", "innovations", "mean innovation (dB)"]
            .map(String::from)
            .to_vec(),
        rows: walk
            .layout
            .readers()
            .iter()
            .zip(innovations)
            .map(|(r, (mean, count))| {
                vec![
                    r.name.clone(),
                    match r.status {
                        ReaderStatus::Working => "working".to_string(),
                        ReaderStatus::Broken => "broken".to_string(),
                    },
                    format!("{:.1}", r.obstacle_loss_db),
                    count.to_string(),
                    opt(*mean, 1.0, 2),
                ]
            })
            .collect(),
    }
}

/// The notes: setup, every difference from the paper and why, all numbers from this run.
pub(super) fn notes(input: &NotesInput<'_>) -> Vec<String> {
    let mut notes = vec![setup_note(input)];
    notes.extend(accuracy_notes(input));
    notes.push(alarm_note(input));
    notes.push(obstacle_note(input));
    notes.extend(table_notes(input));
    notes
}

fn setup_note(input: &NotesInput<'_>) -> String {
    let walk = input.walk;
    let setup = &walk.setup;
    let law = setup.layer.radio().law();
    let readers = walk.layout.readers();
    let broken: Vec<&str> = readers
        .iter()
        .filter(|r| r.status == ReaderStatus::Broken)
        .map(|r| r.name.as_str())
        .collect();
    let tunnels: Vec<&str> = walk.layout.tunnels().iter().map(|t| t.name()).collect();
    let e = input.extras;
    let rssi_pel = input.summaries[0].pel_percent;
    let hole_percent = 100.0 * e.hole_epochs as f64 / setup.epochs.len() as f64;
    render!(
        T,
        "setup",
        runs = input.runs,
        duration_s = fmt(walk.path.duration_s(), 0),
        epochs = setup.epochs.len(),
        period_s = walk.period_s,
        tunnels = tunnels.join(", "),
        working = readers.len() - broken.len(),
        broken = broken.join(", "),
        rho_dbm = law.reference_rssi_dbm(),
        d0_m = law.reference_distance_m(),
        eta = law.exponent(),
        sigma_db = law.shadowing_std_db(),
        sensitivity_dbm = setup.layer.radio().sensitivity_dbm(),
        detection_range_m = fmt(setup.layer.radio().median_detection_range_m(), 0),
        nlos_db = walk.nlos_loss_db,
        heard_readers = fmt(e.heard_mean, 1),
        four_percent = fmt(e.heard_four_percent, 0),
        hole_epochs = e.hole_epochs,
        hole_percent = fmt(hole_percent, 1),
        shadow_percent = fmt((rssi_pel - hole_percent).max(0.0), 1),
        pel_percent = fmt(rssi_pel, 1),
    )
}

fn accuracy_notes(input: &NotesInput<'_>) -> Vec<String> {
    let s = input.summaries;
    let e = input.extras;
    let walk = input.walk;
    let pct = |v: f64| 100.0 * v;
    let (first, last) = (&input.bins[0], &input.bins[input.bins.len() - 1]);
    let rate = |b: &DistanceBin| opt(b.rates[0], 100.0, 1);
    let abs = |b: &DistanceBin| opt(b.abs_errors_m[0], 1.0, 1);
    let hole_rmse = |i: usize| opt(e.rmse_inside_m[i], 1.0, 1);
    let out_rmse = |i: usize| opt(e.rmse_outside_m[i], 1.0, 2);
    let o = &walk.setup.ours;
    let c = input.counts;
    let dv_hop = if input.dv_hop_failures_percent > 0.0 {
        render!(
            T,
            "pel-dv-hop-failed",
            failed_percent = fmt(input.dv_hop_failures_percent, 1)
        )
    } else {
        render!(T, "pel-dv-hop-always")
    };
    let naive_is_no_bound = input.naive_bounds_m[0] > s[3].rmse_m || input.naive_bounds_m[1] > s[0].rmse_m;
    vec![
        render!(
            T,
            "pel",
            rssi_pel_percent = fmt(s[0].pel_percent, 1),
            dv_hop_pel_percent = fmt(s[1].pel_percent, 1),
            dv_hop = dv_hop,
        ),
        render!(
            T,
            "error-rate",
            near_m = first.upper_m.unwrap_or(f64::INFINITY),
            near_rate_percent = rate(first),
            near_error_m = abs(first),
            far_m = last.lower_m,
            far_rate_percent = rate(last),
            far_error_m = abs(last),
            table_max_x_m = fmt(
                input.table.rows.iter().map(|r| r.actual[0].abs()).fold(0.0, f64::max),
                1
            ),
            walk_max_x_m = fmt(
                walk.setup
                    .epochs
                    .iter()
                    .map(|e| e.position_m[0].abs())
                    .fold(0.0, f64::max),
                0
            ),
            rssi_rate_percent = fmt(pct(s[0].error_rates[0]), 1),
            dv_hop_rate_percent = fmt(pct(s[1].error_rates[0]), 1),
            mekf_rate_percent = fmt(pct(s[2].error_rates[0]), 1),
            rssi_z_rate_percent = fmt(pct(s[0].error_rates[2]), 0),
        ),
        render!(
            T,
            "mekf-as-printed",
            r_m2 = walk.setup.mekf.measurement_variance,
            mse_x_m2 = fmt(s[0].axis_mse_m2[0], 1),
            mse_y_m2 = fmt(s[0].axis_mse_m2[1], 1),
            mse_z_m2 = fmt(s[0].axis_mse_m2[2], 1),
            q = walk.setup.mekf.process_variance,
            q_std_mps2 = fmt(walk.setup.mekf.process_variance.sqrt(), 1),
            mekf_outside_m = out_rmse(2),
            rssi_outside_m = out_rmse(0),
            hole_epochs = e.hole_epochs,
            mekf_inside_m = hole_rmse(2),
            mekf_rmse_m = fmt(s[2].rmse_m, 2),
        ),
        render!(
            T,
            "our-tracker",
            horizontal_std_mps2 = fmt(o.motion.horizontal_std_mps2(), 2),
            vertical_std_mps2 = fmt(o.motion.vertical_std_mps2(), 2),
            gated_percent = fmt(100.0 * c.rejected as f64 / (c.accepted + c.rejected).max(1) as f64, 1),
            lateral_std_m = o.map.lateral_std_m,
            vertical_std_m = o.map.vertical_std_m,
            junction_radius_m = o.junction_radius_m,
            reinitialised = c.reinitialised,
            runs = input.runs,
            ours_rmse_m = fmt(s[3].rmse_m, 2),
            mekf_rmse_m = fmt(s[2].rmse_m, 2),
            reduction_percent = fmt(100.0 * (1.0 - s[3].rmse_m / s[2].rmse_m), 0),
            ours_outside_m = out_rmse(3),
            mekf_outside_m = out_rmse(2),
            ours_inside_m = hole_rmse(3),
            mekf_inside_m = hole_rmse(2),
            ours_x_rate_percent = fmt(pct(s[3].error_rates[0]), 1),
            ours_median_m = fmt(e.per_run_rmse_m[1].0, 2),
            mekf_median_m = fmt(e.per_run_rmse_m[0].0, 2),
            ours_worst_m = fmt(e.per_run_rmse_m[1].1, 1),
            mekf_worst_m = fmt(e.per_run_rmse_m[0].1, 1),
        ),
        render!(
            T,
            "bound",
            prior_position_m = fmt(walk.setup.prior.position_variance_m2.sqrt(), 1),
            prior_velocity_mps = fmt(walk.setup.prior.velocity_variance_m2s2.sqrt(), 1),
            max_bound_m = fmt(e.max_bound_m, 1),
            tracker_bound_m = fmt(s[2].bound_m, 2),
            fix_bound_m = fmt(s[0].bound_m, 2),
            naive_tracker_bound_m = fmt(input.naive_bounds_m[0], 2),
            naive_fix_bound_m = fmt(input.naive_bounds_m[1], 2),
            ours_rmse_m = fmt(s[3].rmse_m, 2),
            rssi_rmse_m = fmt(s[0].rmse_m, 2),
            verdict = if naive_is_no_bound {
                render!(T, "bound-naive-is-no-bound")
            } else {
                String::new()
            },
            rssi_ratio = fmt(s[0].rmse_m / s[0].bound_m, 2),
            dv_hop_ratio = fmt(s[1].rmse_m / s[1].bound_m, 2),
            mekf_ratio = fmt(s[2].rmse_m / s[2].bound_m, 2),
            ours_ratio = fmt(s[3].rmse_m / s[3].bound_m, 2),
        ),
        render!(
            T,
            "fixes-and-dv-hop",
            multilateration_percent = fmt(input.kinds[0], 0),
            three_reader_percent = fmt(input.kinds[1], 0),
            centroid_percent = fmt(input.kinds[2], 0),
            reader_links = walk.reader_links,
            dv_hop_x_m = fmt(s[1].axis_mse_m2[0].sqrt(), 1),
            dv_hop_y_m = fmt(s[1].axis_mse_m2[1].sqrt(), 1),
            dv_hop_z_m = fmt(s[1].axis_mse_m2[2].sqrt(), 1),
            dv_hop_rmse_m = fmt(s[1].rmse_m, 1),
        ),
    ]
}

fn alarm_note(input: &NotesInput<'_>) -> String {
    let find = |tracker: &str, one_step: bool| {
        input
            .alarms
            .iter()
            .find(|(t, label, _)| *t == tracker && label.starts_with("one-step") == one_step)
            .map(|(_, _, a)| a.clone())
    };
    let describe = |a: Option<AlarmSummary>| {
        a.map_or_else(
            || "–".to_string(),
            |a| {
                render!(
                    T,
                    "warning-alarms",
                    warned_percent = fmt(a.warned_percent, 0),
                    lead_s = opt(a.mean_lead_s, 1.0, 1),
                    false_per_run = fmt(a.false_per_run, 2),
                )
            },
        )
    };
    render!(
        T,
        "warning",
        entry_s = opt(input.walk.entry_time_s, 1.0, 1),
        mekf_one_step = describe(find("ME-KF", true)),
        look_ahead_s = input.walk.look_ahead_s,
        mekf_look_ahead = describe(find("ME-KF", false)),
        ours_one_step = describe(find("ours", true)),
        ours_look_ahead = describe(find("ours", false)),
        lag_m = opt(input.extras.rssi_lag_m.map(|l| -l), 1.0, 1),
    )
}

fn obstacle_note(input: &NotesInput<'_>) -> String {
    let analysis = input.obstacles;
    let described: Vec<String> = analysis
        .readers
        .iter()
        .map(|r| {
            render!(
                T,
                "obstacles-reader",
                reader = r.name,
                loss_db = fmt(r.loss_db, 0),
                mean_innovation_db = fmt(r.mean_innovation_db, 2),
                lowest = if r.lowest {
                    render!(T, "obstacles-reader-lowest")
                } else {
                    String::new()
                },
            )
        })
        .collect();
    render!(
        T,
        "obstacles",
        readers = if described.is_empty() {
            render!(T, "obstacles-none")
        } else {
            described.join("; ")
        },
        clear_median_db = opt(analysis.clear_median_db, 1.0, 2),
        shows = if analysis.readers.iter().any(|r| r.lowest) {
            format!(" {}", render!(T, "obstacles-shows"))
        } else {
            String::new()
        },
    )
}

/// What the printed rates say about the paper's 20 %, 20 % and 5 %.
fn table_verdict(t: &Table1Evaluation) -> String {
    let x = |i: usize| 100.0 * t.columns[i].rates[0];
    let fixes = if x(0) < 15.0 && x(1) < 15.0 {
        "table-1-fixes-below-20"
    } else {
        "table-1-fixes-near-20"
    };
    let filter = if (x(2) - 5.0).abs() < 1.5 {
        "table-1-filter-5-can"
    } else {
        "table-1-filter-5-cannot"
    };
    let gain = if x(2) > 0.8 * x(0) {
        render!(T, "table-1-no-gain")
    } else {
        String::new()
    };
    render!(
        T,
        "table-1-verdict",
        fixes = render!(T, fixes),
        filter = render!(T, filter),
        gain = gain,
    )
}

fn table_notes(input: &NotesInput<'_>) -> Vec<String> {
    let t = input.table_1;
    let table = input.table;
    let c = |i: usize| &t.columns[i];
    let pct = |v: f64| 100.0 * v;
    let excluded: Vec<String> = table
        .excluded
        .iter()
        .map(|e| format!("{} s ({})", e.time_s, e.reason))
        .collect();
    let flagged: Vec<String> = table
        .flagged
        .iter()
        .map(|f| format!("{} s {}", f.time_s, f.column))
        .collect();
    let smallest = t.smallest_sample.map_or_else(String::new, |(k, n)| {
        render!(
            T,
            "pel-table-1-smallest",
            paper_pel_percent = table.paper_pel_percent,
            empty = k,
            samples = n,
            empty_percent = fmt(100.0 * k as f64 / n as f64, 2),
            twice = 2 * n,
            thrice = 3 * n,
        )
    });
    vec![
        render!(
            T,
            "table-1",
            intact_rows = t.intact_rows,
            rows = t.rows,
            excluded = excluded.join("; "),
            flagged = flagged.join(", "),
            rssi_rate_percent = fmt(pct(c(0).rates[0]), 1),
            dv_hop_rate_percent = fmt(pct(c(1).rates[0]), 1),
            mekf_rate_percent = fmt(pct(c(2).rates[0]), 1),
            rssi_rmse_m = fmt(c(0).rmse_m, 2),
            dv_hop_rmse_m = fmt(c(1).rmse_m, 2),
            mekf_rmse_m = fmt(c(2).rmse_m, 2),
            verdict = table_verdict(t),
            period_s = table.period_s,
            initial_time_s = table.initial_time_s,
            position_variance_m2 = table.prior.position_variance_m2,
            velocity_variance_m2s2 = table.prior.velocity_variance_m2s2,
            rerun_rate_percent = fmt(pct(c(3).rates[0]), 1),
            rerun_vs_printed_m = fmt(t.kf_vs_printed_m, 2),
            x_above_truth = c(0).x_above_truth,
            rssi_mean_x_error_m = format!("{:+.2}", c(0).mean_x_error_m),
            rerun_mean_x_error_m = format!("{:+.2}", c(3).mean_x_error_m),
            mekf_mean_x_error_m = format!("{:+.2}", c(2).mean_x_error_m),
            rssi_unflagged_percent = fmt(pct(c(0).rates_unflagged[0]), 1),
            dv_hop_unflagged_percent = fmt(pct(c(1).rates_unflagged[0]), 1),
            mekf_unflagged_percent = fmt(pct(c(2).rates_unflagged[0]), 1),
        ),
        render!(
            T,
            "pel-table-1",
            paper_pel_percent = table.paper_pel_percent,
            rows = t.rows,
            step_percent = fmt(100.0 / t.rows as f64, 0),
            two_percent = fmt(200.0 / t.rows as f64, 0),
            nearest_percent = fmt(t.nearest_pel_percent, 1),
            rssi_pel_percent = fmt(t.printed_pel_percent[0], 0),
            dv_hop_pel_percent = fmt(t.printed_pel_percent[1], 0),
            smallest = smallest,
        ),
    ]
}
