//! The tables of the `wsn-ekf` report: RMSE per robot, bounds, the task-node sweep, echo
//! counters, energy per method and per node, and the clock sync.

use rtls_engine::scheduling::NodeUsage;

use crate::report::Table;
use crate::reproduction::seed_003::Method;

use super::scenario::Scenario;
use super::summary::{MethodTotals, SquareSums};
use super::ClockResult;

/// RMSE per robot and method, with the bound.
pub(super) fn per_robot_table(scenario: &Scenario, totals: &[MethodTotals]) -> Table {
    let mut header = vec!["robot".to_string()];
    header.extend(Method::ALL.iter().map(|m| format!("{} RMSE (m)", m.label())));
    header.extend(Method::ALL.iter().map(|m| format!("{} √PCRB (m)", m.label())));
    let rows = scenario
        .names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut row = vec![name.clone()];
            row.extend(
                totals
                    .iter()
                    .map(|t| format!("{:.3}", t.per_robot.get(i).map_or(0.0, |s| s.rmse_m()))),
            );
            row.extend(
                totals
                    .iter()
                    .map(|t| format!("{:.3}", t.per_robot.get(i).map_or(0.0, |s| s.bound_m()))),
            );
            row
        })
        .collect();
    Table {
        title: "Position RMSE per robot (all runs and epochs)".to_string(),
        header,
        rows,
    }
}

/// RMSE against the two PCRBs: conditional on the true manoeuvres (the reported bound) and
/// under the trackers' CV model.
pub(super) fn bounds_table(totals: &[MethodTotals]) -> Table {
    let header = [
        "method",
        "epochs",
        "RMSE (m)",
        "√PCRB, true manoeuvres (m)",
        "√PCRB, trackers' CV model (m)",
    ]
    .map(str::to_string)
    .to_vec();
    let mut rows = Vec::new();
    for (label, pick) in [
        (
            "one robot per cell",
            (|t: &MethodTotals| t.before) as fn(&MethodTotals) -> SquareSums,
        ),
        ("near borders, one robot per cell", |t: &MethodTotals| t.border),
        ("robots sharing a cell", |t: &MethodTotals| t.shared),
        ("whole run", |t: &MethodTotals| t.all),
    ] {
        for (method, t) in Method::ALL.iter().zip(totals) {
            let sums = pick(t);
            rows.push(vec![
                method.label().to_string(),
                label.to_string(),
                format!("{:.4}", sums.rmse_m()),
                format!("{:.4}", sums.bound_m()),
                format!("{:.4}", sums.model_bound_m()),
            ]);
        }
    }
    Table {
        title: "bounds: RMSE against the PCRB conditional on the true manoeuvres (reported) and under the trackers' CV model"
            .to_string(),
        header,
        rows,
    }
}

/// Two or three task nodes (the paper's "two or three nearest nodes").
pub(super) fn sweep_table(sweep: &[(usize, Vec<MethodTotals>)]) -> Table {
    let mut header = vec!["task nodes".to_string(), "paper EKF cycle (s)".to_string()];
    header.extend(Method::ALL.iter().map(|m| format!("{} RMSE (m)", m.label())));
    header.push("paper EKF wake-ups (1/s)".to_string());
    header.push("paper EKF task-node changes per run".to_string());
    header.push("LS fixes from 2 ranges (%)".to_string());
    let rows = sweep
        .iter()
        .map(|(k, totals)| {
            let paper = &totals[1];
            let ls = &totals[0].counters.ls_fixes;
            let mut row = vec![k.to_string(), format!("{:.3}", paper.mean_cycle_s())];
            row.extend(totals.iter().map(|t| format!("{:.3}", t.all.rmse_m())));
            row.push(format!("{:.1}", paper.rate_per_s(paper.counters.awake_node_cycles)));
            row.push(format!("{:.1}", paper.per_run(paper.counters.schedule_changes)));
            row.push(format!("{:.1}", MethodTotals::percent(ls[1], ls.iter().sum())));
            row
        })
        .collect();
    Table {
        title: "Task nodes per robot and cycle: measurement period and accuracy".to_string(),
        header,
        rows,
    }
}

/// What happened to the echoes.
pub(super) fn counters_table(totals: &[MethodTotals]) -> Table {
    let header = [
        "method",
        "firings per run",
        "echoes (% of firings)",
        "foreign echoes (% of echoes)",
        "echoes used (% of echoes)",
        "wrong-robot ranges (% of used)",
        "gated out (% of echoes)",
        "schedule accepted (%)",
        "task-node changes per run",
    ]
    .map(str::to_string)
    .to_vec();
    let rows = Method::ALL
        .iter()
        .zip(totals)
        .map(|(m, t)| {
            let c = &t.counters;
            vec![
                m.label().to_string(),
                format!("{:.0}", t.per_run(c.firings)),
                format!("{:.1}", MethodTotals::percent(c.echoes, c.firings)),
                format!("{:.1}", MethodTotals::percent(c.foreign_echoes, c.echoes)),
                format!("{:.1}", MethodTotals::percent(c.used, c.echoes)),
                format!("{:.2}", MethodTotals::percent(c.wrong_associations, c.used)),
                format!("{:.1}", MethodTotals::percent(c.gated_out, c.echoes)),
                format!(
                    "{:.1}",
                    MethodTotals::percent(c.schedule_accepted, c.schedule_decisions)
                ),
                format!("{:.1}", t.per_run(c.schedule_changes)),
            ]
        })
        .collect();
    Table {
        title: "Echoes and scheduling per method (all runs)".to_string(),
        header,
        rows,
    }
}

/// `value / runs` formatted with `digits` decimals.
fn per_run(value: f64, runs: usize, digits: usize) -> String {
    format!("{:.digits$}", value / runs.max(1) as f64)
}

/// Radio and sonar on-time and energy per method: scheduled against all nodes on, per node and
/// run (on-times) and per run over the network (energy).
pub(super) fn energy_table(scenario: &Scenario, totals: &[MethodTotals]) -> Table {
    let nodes = scenario.config.bed.nodes_m().len().max(1) as f64;
    let header = [
        "method",
        "nodes awake per cycle",
        "radio on per node per run, scheduled (s)",
        "radio on per node per run, all on (s)",
        "sonar on per node per run, scheduled (s)",
        "sonar on per node per run, all on (s)",
        "energy per run, scheduled (J)",
        "energy per run, all on (J)",
        "radio time saved (%)",
        "sonar time saved (%)",
        "energy saved (%)",
    ]
    .map(str::to_string)
    .to_vec();
    let rows = Method::ALL
        .iter()
        .zip(totals)
        .filter_map(|(m, t)| {
            let ledger = t.energy.as_ref()?;
            let sum = ledger.totals();
            let p = ledger.model().power;
            let runs = t.runs;
            Some(vec![
                m.label().to_string(),
                format!(
                    "{:.2}",
                    sum.scheduled.awake_cycles as f64 / ledger.cycles().max(1) as f64
                ),
                per_run(sum.scheduled.radio_on_s() / nodes, runs, 2),
                per_run(sum.all_on.radio_on_s() / nodes, runs, 2),
                per_run(sum.scheduled.sonar_on_s / nodes, runs, 3),
                per_run(sum.all_on.sonar_on_s / nodes, runs, 3),
                per_run(sum.scheduled.total_j(&p), runs, 2),
                per_run(sum.all_on.total_j(&p), runs, 2),
                format!("{:.1}", sum.radio_time_saving_percent()),
                format!("{:.1}", sum.sonar_time_saving_percent()),
                format!("{:.1}", sum.energy_saving_percent()),
            ])
        })
        .collect();
    Table {
        title: "Energy: radio (CC2420) and sonar (SRF08) on-time and energy, scheduled against all nodes on, per method (mean over runs)"
            .to_string(),
        header,
        rows,
    }
}

/// Per node, for `method`: awake cycles, radio and sonar on-time and energy per run, scheduled
/// and all on.
pub(super) fn energy_per_node_table(scenario: &Scenario, totals: &[MethodTotals], method: Method) -> Option<Table> {
    let index = Method::ALL.iter().position(|&m| m == method)?;
    let t = totals.get(index)?;
    let ledger = t.energy.as_ref()?;
    let p = ledger.model().power;
    let runs = t.runs;
    let header = [
        "node",
        "position (m)",
        "cycles awake per run",
        "radio on per run, scheduled (s)",
        "radio on per run, all on (s)",
        "sonar on per run, scheduled (s)",
        "sonar on per run, all on (s)",
        "energy per run, scheduled (J)",
        "energy per run, all on (J)",
    ]
    .map(str::to_string)
    .to_vec();
    let row = |label: String, position: String, s: &NodeUsage, a: &NodeUsage| {
        vec![
            label,
            position,
            per_run(s.awake_cycles as f64, runs, 1),
            per_run(s.radio_on_s(), runs, 2),
            per_run(a.radio_on_s(), runs, 2),
            per_run(s.sonar_on_s, runs, 3),
            per_run(a.sonar_on_s, runs, 3),
            per_run(s.total_j(&p), runs, 3),
            per_run(a.total_j(&p), runs, 3),
        ]
    };
    let mut rows: Vec<Vec<String>> = ledger
        .scheduled()
        .iter()
        .zip(ledger.all_on())
        .enumerate()
        .map(|(n, (s, a))| {
            let position = scenario
                .config
                .bed
                .nodes_m()
                .get(n)
                .map_or_else(String::new, |q| format!("({:.0}, {:.0})", q[0], q[1]));
            row(n.to_string(), position, s, a)
        })
        .collect();
    let sum = ledger.totals();
    rows.push(row("all".to_string(), String::new(), &sum.scheduled, &sum.all_on));
    Some(Table {
        title: format!(
            "Energy per node ({}, mean over runs): the nodes near the robots' routes wake most",
            method.label()
        ),
        header,
        rows,
    })
}

/// Tracking with the clocks re-synced every cycle or free-running after the first sync, at the
/// configured drift and at the stress drift.
pub(super) fn clock_table(scenario: &Scenario, totals: &[MethodTotals], variants: &[ClockResult]) -> Table {
    let header = [
        "clocks",
        "drift σ (ppm)",
        "method",
        "RMSE, whole run (m)",
        "robots tracked",
        "RMS time-stamp error (ms)",
        "max time-stamp error (ms)",
        "max time-of-flight range error (mm)",
    ]
    .map(str::to_string)
    .to_vec();
    let clock = &scenario.config.clock;
    let mut rows = Vec::new();
    let mut push = |label: &str, drift_ppm: f64, method: Method, t: &MethodTotals| {
        rows.push(vec![
            label.to_string(),
            format!("{drift_ppm:.0}"),
            method.label().to_string(),
            format!("{:.4}", t.all.rmse_m()),
            format!("{:.2}", t.per_run(t.tracked)),
            format!("{:.4}", t.clock.rms_stamp_error_s() * 1e3),
            format!("{:.4}", t.clock.stamp_error_max_s * 1e3),
            format!("{:.4}", t.clock.range_bias_max_m * 1e3),
        ]);
    };
    for (method, t) in Method::ALL.iter().zip(totals) {
        push(sync_label(clock.resync_every_cycle), clock.drift_std_ppm, *method, t);
    }
    for v in variants {
        for (method, t) in &v.totals {
            push(sync_label(v.resync_every_cycle), v.drift_std_ppm, *method, t);
        }
    }
    Table {
        title: "Clock sync: re-synced by every cycle's token broadcast against free-running after the first sync (the paper's one-time sync)"
            .to_string(),
        header,
        rows,
    }
}

/// How the clocks are synced, for tables and notes.
pub(super) fn sync_label(resync_every_cycle: bool) -> &'static str {
    if resync_every_cycle {
        "re-synced every cycle"
    } else {
        "free-running after the first sync"
    }
}
