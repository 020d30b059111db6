//! The notes of the `wsn-ekf` report: setup, choices, results and differences from the paper,
//! every number computed from the runs; the prose is in `templates/wsn-ekf.md`.

use crate::experiments::common::fmt;
use crate::experiments::template::{files::WSN_EKF as T, render};
use crate::experiments::ReproOptions;

use super::scenario::Scenario;
use super::summary::MethodTotals;
use super::tables::sync_label;
use super::ClockResult;

/// Every note paragraph. `totals` are in [`crate::reproduction::seed_003::Method::ALL`] order
/// (LS, paper EKF, ours); `sweep` holds the totals per task-node count, ascending.
pub(super) fn all(
    scenario: &Scenario,
    intervals: &[(f64, f64)],
    totals: &[MethodTotals],
    sweep: &[(usize, Vec<MethodTotals>)],
    clock: &[ClockResult],
    options: &ReproOptions,
) -> Vec<String> {
    let [ls, paper, ours] = totals else {
        return Vec::new();
    };
    vec![
        setup(scenario, intervals, options),
        tokens(scenario, paper),
        energy(scenario, paper, ours),
        crossings(scenario, intervals, ls, paper, ours),
        shared_cell(scenario, intervals, paper, ours),
        association(ours, scenario.config.tracker.manoeuvre_speed_change_mps),
        swaps(scenario, ours),
        bounds(ls, paper, ours),
        latency(ls, paper, scenario),
        clock_sync(scenario, totals, clock),
        task_nodes(sweep),
        not_modelled(),
    ]
}

/// The names of the robots sharing a cell in `interval`, e.g. "A and B".
fn sharing(scenario: &Scenario, interval: (f64, f64)) -> String {
    let config = &scenario.config;
    let t = (interval.0 + interval.1) / 2.0;
    let cells: Vec<Option<usize>> = config
        .robots
        .iter()
        .map(|r| {
            r.state_at(t)
                .ok()
                .map(|s| config.bed.cell_of([s.position_m[0], s.position_m[1]]))
        })
        .collect();
    let names: Vec<&str> = (0..cells.len())
        .filter(|&i| cells[i].is_some() && (0..cells.len()).any(|j| j != i && cells[j] == cells[i]))
        .filter_map(|i| scenario.names.get(i).map(String::as_str))
        .collect();
    names.join(" and ")
}

fn setup(scenario: &Scenario, intervals: &[(f64, f64)], options: &ReproOptions) -> String {
    let c = &scenario.config;
    let [w, h] = c.bed.size_m();
    let episodes = if intervals.is_empty() {
        render!(T, "setup-no-sharing")
    } else {
        intervals
            .iter()
            .map(|&i| {
                render!(
                    T,
                    "setup-sharing",
                    robots = sharing(scenario, i),
                    start_s = fmt(i.0, 1),
                    end_s = fmt(i.1, 1),
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    };
    render!(
        T,
        "setup",
        width_m = w,
        height_m = h,
        nodes = c.bed.nodes_m().len(),
        cells = c.bed.cell_count(),
        cell_side_m = c.bed.cell_side_m(),
        sonars = c.sonar.sonars,
        sector_deg = c.sonar.sector_width_deg,
        range_std_cm = fmt(c.sonar.range_noise_std_m * 100.0, 0),
        echo_window_ms = fmt(c.sonar.echo_window_s * 1000.0, 1),
        max_range_m = fmt(c.sonar.max_range_m(), 2),
        sound_speed_mps = c.sonar.speed_of_sound_mps,
        ping_loss_percent = fmt((1.0 - c.sonar.detection_probability) * 100.0, 0),
        robots = c.robots.len(),
        robot_names = scenario.names.join(", "),
        duration_s = c.duration_s,
        episodes = episodes,
        runs = options.runs,
        seed = options.seed,
        initial_position_std_m = c.tracker.initial_position_std_m,
        initial_velocity_std_mps = c.tracker.initial_velocity_std_mps,
    )
}

fn tokens(scenario: &Scenario, paper: &MethodTotals) -> String {
    let c = &scenario.config;
    let k = &paper.counters;
    let nodes = c.bed.nodes_m().len();
    let cycle_s = paper.mean_cycle_s();
    let awake = k.awake_node_cycles as f64 / k.cycles.max(1) as f64;
    render!(
        T,
        "tokens",
        task_nodes = c.scheduling.task_nodes,
        edge_margin_m = c.scheduling.edge_margin_m,
        comm_slot_ms = fmt(c.timing.comm_slot_s * 1000.0, 0),
        ranging_slot_ms = fmt(c.timing.ranging_slot_s * 1000.0, 0),
        cycle_s = fmt(cycle_s, 3),
        cycles_per_s = fmt(1.0 / cycle_s.max(f64::MIN_POSITIVE), 1),
        firings_per_s = fmt(paper.rate_per_s(paper.sonar_firings), 1),
        awake = fmt(awake, 2),
        nodes = nodes,
        fewer_wakeups_percent = fmt(100.0 - MethodTotals::percent(k.awake_node_cycles, nodes * k.cycles), 1),
        accepted_percent = fmt(MethodTotals::percent(k.schedule_accepted, k.schedule_decisions), 2),
        cycle_move_cm = fmt(0.5 * cycle_s * 100.0, 0),
        changes_per_run = fmt(paper.per_run(k.schedule_changes), 1),
    )
}

fn energy(scenario: &Scenario, paper: &MethodTotals, ours: &MethodTotals) -> String {
    let (Some(p_ledger), Some(o_ledger)) = (&paper.energy, &ours.energy) else {
        return render!(T, "energy-none");
    };
    let c = &scenario.config;
    let nodes = c.bed.nodes_m().len().max(1) as f64;
    let (p, o) = (p_ledger.totals(), o_ledger.totals());
    let power = p_ledger.model().power;
    let per_node_run = |t: &MethodTotals, v: f64| t.per_run_f64(v) / nodes;
    let (radio_j, sonar_j) = (p.scheduled.radio_j(&power), p.scheduled.sonar_j(&power));
    let radio_share = 100.0 * radio_j / (radio_j + sonar_j).max(f64::MIN_POSITIVE);
    let share = if radio_j > sonar_j {
        render!(T, "energy-radio-share", radio_share_percent = fmt(radio_share, 0))
    } else {
        render!(
            T,
            "energy-sonar-share",
            sonar_share_percent = fmt(100.0 - radio_share, 0)
        )
    };
    render!(
        T,
        "energy",
        report_ms = fmt(c.timing.comm_slot_s * 1000.0, 0),
        ping_ms = fmt(c.energy.sonar_ping_s * 1000.0, 1),
        echo_window_ms = fmt(c.sonar.echo_window_s * 1000.0, 1),
        all_on_sonars = c.energy.all_on_sonars_per_node,
        radio_rx_mw = fmt(power.radio_rx_w * 1000.0, 1),
        radio_tx_mw = fmt(power.radio_tx_w * 1000.0, 1),
        sonar_mw = fmt(power.sonar_w * 1000.0, 0),
        radio_on_s = fmt(per_node_run(paper, p.scheduled.radio_on_s()), 2),
        all_on_radio_on_s = fmt(per_node_run(paper, p.all_on.radio_on_s()), 2),
        sonar_on_s = fmt(per_node_run(paper, p.scheduled.sonar_on_s), 3),
        all_on_sonar_on_s = fmt(per_node_run(paper, p.all_on.sonar_on_s), 3),
        radio_saving_percent = fmt(p.radio_time_saving_percent(), 1),
        sonar_saving_percent = fmt(p.sonar_time_saving_percent(), 1),
        energy_j = fmt(paper.per_run_f64(p.scheduled.total_j(&power)), 2),
        all_on_energy_j = fmt(paper.per_run_f64(p.all_on.total_j(&power)), 2),
        energy_saving_percent = fmt(p.energy_saving_percent(), 1),
        share = share,
        ours_saving_percent = fmt(o.energy_saving_percent(), 1),
        ours_energy_j = fmt(ours.per_run_f64(o.scheduled.total_j(&power)), 2),
        ours_all_on_energy_j = fmt(ours.per_run_f64(o.all_on.total_j(&power)), 2),
    )
}

fn crossings(
    scenario: &Scenario,
    intervals: &[(f64, f64)],
    ls: &MethodTotals,
    paper: &MethodTotals,
    ours: &MethodTotals,
) -> String {
    let band = scenario.evaluation.border_band_m;
    let until = intervals.first().map_or(scenario.config.duration_s, |i| i.0);
    let smoother = paper.border_path_excess_percent() < ls.border_path_excess_percent();
    let better = paper.border.rmse_m() < ls.border.rmse_m();
    let verdict = match (smoother, better) {
        (true, true) => "crossings-reproduced",
        (true, false) => "crossings-smoother",
        (false, true) => "crossings-closer",
        (false, false) => "crossings-not-reproduced",
    };
    let k = &ls.counters;
    render!(
        T,
        "crossings",
        until_s = fmt(until, 1),
        ls_rmse_m = fmt(ls.before.rmse_m(), 3),
        paper_rmse_m = fmt(paper.before.rmse_m(), 3),
        ours_rmse_m = fmt(ours.before.rmse_m(), 3),
        band_m = band,
        ls_border_rmse_m = fmt(ls.border.rmse_m(), 3),
        paper_border_rmse_m = fmt(paper.border.rmse_m(), 3),
        ours_border_rmse_m = fmt(ours.border.rmse_m(), 3),
        ls_excess_percent = fmt(ls.border_path_excess_percent(), 1),
        paper_excess_percent = fmt(paper.border_path_excess_percent(), 1),
        ours_excess_percent = fmt(ours.border_path_excess_percent(), 1),
        verdict = render!(T, verdict),
        ls_two_range_percent = fmt(MethodTotals::percent(k.ls_fixes[1], k.ls_fixes.iter().sum()), 1),
        ls_tracked = fmt(ls.per_run(ls.tracked), 2),
    )
}

fn shared_cell(scenario: &Scenario, intervals: &[(f64, f64)], paper: &MethodTotals, ours: &MethodTotals) -> String {
    let Some(&first) = intervals.first() else {
        return render!(T, "shared-cell-none");
    };
    let e = &scenario.evaluation;
    let k = &paper.counters;
    render!(
        T,
        "shared-cell",
        robots = sharing(scenario, first),
        start_s = fmt(first.0, 1),
        end_s = fmt(first.1, 1),
        paper_wrong_per_run = fmt(paper.per_run(paper.shared_wrong), 1),
        paper_foreign_percent = fmt(MethodTotals::percent(k.foreign_echoes, k.echoes), 1),
        paper_shared_rmse_m = fmt(paper.shared.rmse_m(), 3),
        paper_swaps = fmt(paper.per_run(paper.swaps), 2),
        tracked_error_m = e.tracked_error_m,
        swap_window_s = e.swap_window_s,
        paper_tracked = fmt(paper.per_run(paper.tracked), 2),
        paper_rmse_m = fmt(paper.all.rmse_m(), 3),
        ours_wrong_per_run = fmt(ours.per_run(ours.shared_wrong), 1),
        ours_shared_rmse_m = fmt(ours.shared.rmse_m(), 3),
        ours_swaps = fmt(ours.per_run(ours.swaps), 2),
        ours_tracked = fmt(ours.per_run(ours.tracked), 2),
        ours_rmse_m = fmt(ours.all.rmse_m(), 3),
    )
}

fn association(ours: &MethodTotals, speed_change_mps: f64) -> String {
    let k = &ours.counters;
    render!(
        T,
        "association",
        speed_change_mps = fmt(speed_change_mps, 1),
        sole_candidate_per_run = fmt(ours.per_run(k.sole_candidate), 1),
        dropped_per_run = fmt(ours.per_run(k.gated_out), 1),
        dropped_percent = fmt(MethodTotals::percent(k.gated_out, k.echoes), 2),
        ambiguous_per_run = fmt(ours.per_run(k.ambiguous), 1),
        wrong_percent = fmt(MethodTotals::percent(k.wrong_associations, k.used), 2),
    )
}

fn swaps(scenario: &Scenario, ours: &MethodTotals) -> String {
    let events = &ours.swap_events;
    let e = &scenario.evaluation;
    if events.is_empty() {
        return render!(T, "swaps-none", tracked_error_m = e.tracked_error_m, runs = ours.runs);
    }
    let name = |robot: usize| scenario.names.get(robot).map_or("?", String::as_str);
    let listed: Vec<String> = events
        .iter()
        .map(|s| {
            render!(
                T,
                "swap-event",
                seed = s.seed,
                robot = name(s.robot),
                time_s = fmt(s.time_s, 1),
                x_m = fmt(s.truth_m[0], 2),
                y_m = fmt(s.truth_m[1], 2),
                error_m = fmt(s.error_m, 2),
                standing = if s.standing {
                    render!(T, "swap-standing")
                } else {
                    String::new()
                },
                recovered = render!(
                    T,
                    if s.recovered {
                        "swap-recovered"
                    } else {
                        "swap-never-back"
                    }
                ),
            )
        })
        .collect();
    let standing = events.iter().filter(|s| s.standing).count();
    let recovered = events.iter().filter(|s| s.recovered).count();
    let cause = if standing == events.len() {
        format!(" {}", render!(T, "swaps-cause-standing"))
    } else {
        String::new()
    };
    let kind = if recovered == events.len() {
        "swaps-all-transient"
    } else if recovered == 0 {
        "swaps-none-back"
    } else {
        "swaps-others-lost"
    };
    render!(
        T,
        "swaps",
        swaps = events.len(),
        runs = ours.runs,
        swaps_per_run = fmt(ours.per_run(events.len()), 3),
        events = listed.join("; "),
        standing = standing,
        recovered = recovered,
        kind = render!(T, kind),
        cause = cause,
    )
}

fn bounds(ls: &MethodTotals, paper: &MethodTotals, ours: &MethodTotals) -> String {
    render!(
        T,
        "bounds",
        ours_border_rmse_m = fmt(ours.border.rmse_m(), 3),
        model_bound_m = fmt(ours.border.model_bound_m(), 3),
        ours_before_ratio = fmt(ratio(ours.before.rmse_m(), ours.before.bound_m()), 2),
        ours_ratio = fmt(ratio(ours.all.rmse_m(), ours.all.bound_m()), 2),
        paper_ratio = fmt(ratio(paper.all.rmse_m(), paper.all.bound_m()), 1),
        ls_ratio = fmt(ratio(ls.all.rmse_m(), ls.all.bound_m()), 1),
    )
}

fn ratio(value: f64, bound: f64) -> f64 {
    if bound > 0.0 {
        value / bound
    } else {
        0.0
    }
}

fn latency(ls: &MethodTotals, paper: &MethodTotals, scenario: &Scenario) -> String {
    render!(
        T,
        "latency",
        ekf_latency_s = fmt(paper.mean_latency_s(), 3),
        ranging_slot_ms = fmt(scenario.config.timing.ranging_slot_s * 1000.0, 0),
        comm_slot_ms = fmt(scenario.config.timing.comm_slot_s * 1000.0, 0),
        ls_latency_s = fmt(ls.mean_latency_s(), 3),
        cycle_s = fmt(paper.mean_cycle_s(), 3),
    )
}

fn clock_sync(scenario: &Scenario, totals: &[MethodTotals], clock: &[ClockResult]) -> String {
    let c = &scenario.config;
    let Some(ours) = totals.get(2) else {
        return String::new();
    };
    let mode = sync_label(c.clock.resync_every_cycle);
    // the other sync mode at the configured drift, and the stress drift in both modes (ours)
    let find = |drift: f64, resync: bool| {
        clock
            .iter()
            .find(|v| v.drift_std_ppm == drift && v.resync_every_cycle == resync)
            .and_then(|v| v.totals.iter().find(|(m, _)| m.label() == "ours (EKF + GNN)"))
            .map(|(_, t)| t)
    };
    let other = find(c.clock.drift_std_ppm, !c.clock.resync_every_cycle);
    let stress = scenario.evaluation.clock_stress_drift_ppm;
    let (stress_sync, stress_free) = (find(stress, true), find(stress, false));
    let ms = |t: &MethodTotals| (t.clock.rms_stamp_error_s() * 1e3, t.clock.stamp_error_max_s * 1e3);
    let mut text = render!(
        T,
        "clock-sync",
        drift_ppm = fmt(c.clock.drift_std_ppm, 0),
        jitter_ms = fmt(c.clock.sync_jitter_std_s * 1e3, 2),
        mode = mode,
        stamp_rms_ms = fmt(ms(ours).0, 4),
        stamp_max_ms = fmt(ms(ours).1, 4),
        range_bias_mm = fmt(ours.clock.range_bias_max_m * 1e3, 3),
        echo_window_ms = fmt(c.sonar.echo_window_s * 1e3, 1),
        ours_rmse_m = fmt(ours.all.rmse_m(), 4),
    );
    if let Some(t) = other {
        let verdict = if (t.all.rmse_m() - ours.all.rmse_m()).abs() <= 0.1 * ours.all.rmse_m() {
            render!(T, "clock-other-same", duration_s = fmt(c.duration_s, 0))
        } else {
            render!(T, "clock-other-differs")
        };
        text.push(' ');
        text.push_str(&render!(
            T,
            "clock-other-mode",
            mode = sync_label(!c.clock.resync_every_cycle),
            stamp_rms_ms = fmt(ms(t).0, 4),
            stamp_max_ms = fmt(ms(t).1, 4),
            rmse_m = fmt(t.all.rmse_m(), 4),
            move_mm = fmt(0.5 * t.clock.stamp_error_max_s * 1e3, 3),
            range_noise_cm = fmt(c.sonar.range_noise_std_m * 100.0, 0),
            verdict = verdict,
        ));
    }
    if let (Some(a), Some(b)) = (stress_sync, stress_free) {
        text.push(' ');
        text.push_str(&render!(
            T,
            "clock-stress",
            stress_ppm = fmt(stress, 0),
            synced_rms_ms = fmt(ms(a).0, 3),
            synced_range_bias_mm = fmt(a.clock.range_bias_max_m * 1e3, 0),
            synced_rmse_m = fmt(a.all.rmse_m(), 4),
            synced_tracked = fmt(a.per_run(a.tracked), 2),
            free_rms_ms = fmt(ms(b).0, 1),
            free_max_ms = fmt(ms(b).1, 0),
            free_rmse_m = fmt(b.all.rmse_m(), 4),
            free_tracked = fmt(b.per_run(b.tracked), 2),
        ));
    }
    text
}

fn task_nodes(sweep: &[(usize, Vec<MethodTotals>)]) -> String {
    let rows: Vec<String> = sweep
        .iter()
        .filter_map(|(k, t)| {
            let paper = t.get(1)?;
            let ours = t.get(2)?;
            Some(render!(
                T,
                "task-nodes-row",
                task_nodes = k,
                cycle_s = fmt(paper.mean_cycle_s(), 3),
                changes_per_run = fmt(paper.per_run(paper.counters.schedule_changes), 1),
                paper_rmse_m = fmt(paper.all.rmse_m(), 3),
                ours_rmse_m = fmt(ours.all.rmse_m(), 3),
            ))
        })
        .collect();
    render!(T, "task-nodes", rows = rows.join("; "))
}

fn not_modelled() -> String {
    render!(T, "not-modelled")
}
