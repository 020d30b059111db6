//! `wsn-ekf` — seed 003: three robots tracked by an ultrasonic wireless sensor network with the
//! paper's single-observation EKF and adaptive node scheduling, against the paper's
//! least-squares baseline and against our EKF with data association.
//!
//! Every method runs in closed loop (its own estimates drive the node scheduling) on the same
//! seeds; see [`crate::reproduction::seed_003`] for one run and `scenarios/003-test-bed.toml`
//! for every parameter.

mod figures;
mod notes;
mod scenario;
mod summary;

use super::{find_source, ReproOptions, ScenarioSource};
use crate::error::Result;
use crate::montecarlo::{monte_carlo, run_seed, Progress};
use crate::report::{ExperimentReport, Metric, Table};
use crate::reproduction::seed_003::{run_seed_003, Method, Seed003Config, Seed003Run};
use crate::scenarios::seed_003::shared_cell_intervals;

use self::scenario::Scenario;
use self::summary::{Context, MethodTotals, BIN_S};

/// The experiment's scenario file.
const FILE: &str = "003-test-bed.toml";

/// Sampling step for finding the intervals in which robots share a cell (s).
const SHARED_STEP_S: f64 = 0.05;

/// Progress units of [`reproduce`]: `runs` per task-node configuration (the scenario's
/// configuration plus every other value of `evaluation.task_node_sweep`).
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed `003-test-bed.toml`.
pub fn work_units(sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    let scenario = scenario::parse(find_source(sources, FILE)?)?;
    Ok((options.runs * (1 + extra_sweep_values(&scenario).len())) as u64)
}

/// Task-node counts of the sweep other than the scenario's own.
fn extra_sweep_values(scenario: &Scenario) -> Vec<usize> {
    let mut values: Vec<usize> = scenario
        .evaluation
        .task_node_sweep
        .iter()
        .copied()
        .filter(|&k| k != scenario.config.scheduling.task_nodes)
        .collect();
    values.sort_unstable();
    values.dedup();
    values
}

/// Totals per method (in [`Method::ALL`] order) over `runs` seeded runs of `config`, and the
/// full runs of the first seed (for the figures).
fn simulate(
    config: &Seed003Config,
    context: &Context<'_>,
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<(Vec<MethodTotals>, Vec<Seed003Run>)> {
    let first_seed = run_seed(options.seed, 0);
    let per_run = monte_carlo(options.runs, options.seed, progress, |seed| {
        let runs = Method::ALL
            .iter()
            .map(|&method| run_seed_003(config, method, seed))
            .collect::<Result<Vec<_>>>()?;
        let totals: Vec<MethodTotals> = runs.iter().map(|run| MethodTotals::from_run(run, context)).collect();
        Ok((totals, (seed == first_seed).then_some(runs)))
    })?;
    // sum in run order: identical for any thread count
    let mut totals = vec![MethodTotals::default(); Method::ALL.len()];
    let mut first = Vec::new();
    for (run_totals, runs) in per_run {
        for (sum, t) in totals.iter_mut().zip(&run_totals) {
            sum.merge(t);
        }
        if let Some(runs) = runs {
            first = runs;
        }
    }
    Ok((totals, first))
}

/// Runs the reproduction (see the module docs) and returns its report.
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed `003-test-bed.toml`; any
/// simulation error of [`run_seed_003`].
pub fn reproduce(
    sources: &[ScenarioSource],
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<ExperimentReport> {
    let scenario = scenario::parse(find_source(sources, FILE)?)?;
    let config = &scenario.config;
    let intervals = shared_cell_intervals(&config.bed, &config.robots, config.duration_s, SHARED_STEP_S)?;
    let context = Context {
        bed: &config.bed,
        evaluation: &scenario.evaluation,
        shared_intervals: &intervals,
        bins: (config.duration_s / BIN_S).ceil() as usize,
    };
    let (totals, first) = simulate(config, &context, options, progress)?;
    let mut sweep = vec![(config.scheduling.task_nodes, totals.clone())];
    for k in extra_sweep_values(&scenario) {
        let mut variant = config.clone();
        variant.scheduling.task_nodes = k;
        sweep.push((k, simulate(&variant, &context, options, progress)?.0));
    }
    sweep.sort_by_key(|(k, _)| *k);

    let mut report = ExperimentReport::new(
        "wsn-ekf",
        "Seed 003 — multi-robot tracking in an ultrasonic WSN: single-observation EKF with adaptive node scheduling",
        options.runs,
        options.seed,
    );
    report.metrics = metrics(&scenario, &intervals, &totals);
    report.tables = vec![
        per_robot_table(&scenario, &totals),
        bounds_table(&totals),
        sweep_table(&sweep),
        counters_table(&totals),
    ];
    report.figures = figures::all(&scenario, &intervals, &totals, &first)?;
    report.notes = notes::all(&scenario, &intervals, &totals, &sweep, options);
    Ok(report)
}

/// The metric rows.
fn metrics(scenario: &Scenario, intervals: &[(f64, f64)], totals: &[MethodTotals]) -> Vec<Metric> {
    let e = &scenario.evaluation;
    let band = e.border_band_m;
    let episode_s = intervals.first().map_or(scenario.config.duration_s, |i| i.0);
    let mut metrics = Vec::new();
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(
            Metric::new(
                format!(
                    "{}: position RMSE, one robot per cell (0–{episode_s:.1} s)",
                    method.label()
                ),
                "m",
                t.before.rmse_m(),
            )
            .bound(t.before.bound_m()),
        );
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(
            Metric::new(
                format!("{}: position RMSE, whole run", method.label()),
                "m",
                t.all.rmse_m(),
            )
            .bound(t.all.bound_m()),
        );
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(
            Metric::new(
                format!(
                    "{}: RMSE within {band} m of a cell border, one robot per cell",
                    method.label()
                ),
                "m",
                t.border.rmse_m(),
            )
            .bound(t.border.bound_m()),
        );
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(Metric::new(
            format!(
                "{}: path-length excess within {band} m of a cell border, one robot per cell (zig-zag)",
                method.label()
            ),
            "%",
            t.border_path_excess_percent(),
        ));
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(
            Metric::new(
                format!("{}: RMSE while two robots share a cell", method.label()),
                "m",
                t.shared.rmse_m(),
            )
            .bound(t.shared.bound_m()),
        );
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(Metric::new(
            format!(
                "{}: track swaps per run (shared-cell episode + {} s)",
                method.label(),
                e.swap_window_s
            ),
            "",
            t.per_run(t.swaps),
        ));
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(Metric::new(
            format!(
                "{}: wrong-robot ranges used per run (shared-cell episode)",
                method.label()
            ),
            "",
            t.per_run(t.shared_wrong),
        ));
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(
            Metric::new(
                format!(
                    "{}: robots tracked ({:.0} % of errors < {} m)",
                    method.label(),
                    e.tracked_fraction * 100.0,
                    e.tracked_error_m
                ),
                "",
                t.per_run(t.tracked),
            )
            .paper(3.0),
        );
    }
    let paper = &totals[1];
    let nodes = scenario.config.bed.nodes_m().len();
    let awake_rate = paper.rate_per_s(paper.counters.awake_node_cycles);
    let all_on_rate = paper.rate_per_s(nodes * paper.counters.cycles);
    metrics.push(Metric::new(
        "paper EKF: node wake-ups per second with scheduling",
        "1/s",
        awake_rate,
    ));
    metrics.push(Metric::new(
        format!("all {nodes} nodes awake every cycle: node wake-ups per second"),
        "1/s",
        all_on_rate,
    ));
    metrics.push(Metric::new(
        "energy saved by scheduling (node wake-ups)",
        "%",
        100.0 - MethodTotals::percent(paper.counters.awake_node_cycles, nodes * paper.counters.cycles),
    ));
    metrics.push(Metric::new(
        "paper EKF: sonar firings per second",
        "1/s",
        paper.rate_per_s(paper.sonar_firings),
    ));
    metrics.push(Metric::new(
        "paper EKF: scheduling prediction acceptance rate",
        "%",
        MethodTotals::percent(paper.counters.schedule_accepted, paper.counters.schedule_decisions),
    ));
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(Metric::new(
            format!("{}: mean cycle period", method.label()),
            "s",
            t.mean_cycle_s(),
        ));
    }
    for (method, t) in Method::ALL.iter().zip(totals) {
        metrics.push(Metric::new(
            format!("{}: mean latency from firing to estimate", method.label()),
            "s",
            t.mean_latency_s(),
        ));
    }
    metrics
}

/// RMSE per robot and method, with the bound.
fn per_robot_table(scenario: &Scenario, totals: &[MethodTotals]) -> Table {
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
fn bounds_table(totals: &[MethodTotals]) -> Table {
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
            (|t: &MethodTotals| t.before) as fn(&MethodTotals) -> summary::SquareSums,
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
fn sweep_table(sweep: &[(usize, Vec<MethodTotals>)]) -> Table {
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
fn counters_table(totals: &[MethodTotals]) -> Table {
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
