//! `wsn-ekf` — seed 003: three robots tracked by an ultrasonic wireless sensor network with the
//! paper's single-observation EKF and adaptive node scheduling, against the paper's
//! least-squares baseline and against our EKF with data association.
//!
//! Every method runs in closed loop (its own estimates drive the node scheduling, done by
//! [`rtls_engine::scheduling`]) on the same seeds; the report adds the energy the schedules cost
//! against all nodes on, and the tracking with the nodes' clocks re-synced every cycle or
//! free-running. See [`crate::reproduction::seed_003`] for one run and
//! `scenarios/003-test-bed.toml` for every parameter.

mod figures;
mod notes;
mod scenario;
mod summary;
mod tables;

use super::{find_source, ReproOptions, ScenarioSource};
use crate::error::Result;
use crate::report::{ExperimentReport, Metric};
use crate::reproduction::seed_003::{run_seed_003, Method, Seed003Config, Seed003Run};
use rtls_sim::montecarlo::{monte_carlo, run_seed, Progress};
use rtls_sim::scenarios::seed_003::shared_cell_intervals;

use self::scenario::Scenario;
use self::summary::{Context, MethodTotals, BIN_S};

/// A clock configuration run on the same seeds as the scenario's, for the clock table.
#[derive(Debug, Clone)]
struct ClockVariant {
    /// The scenario's configuration with other clocks.
    config: Seed003Config,
    /// The methods to run.
    methods: Vec<Method>,
}

/// The totals of a clock variant.
#[derive(Debug, Clone)]
pub(crate) struct ClockResult {
    /// Clock drift σ (ppm).
    pub drift_std_ppm: f64,
    /// Whether every cycle re-synced the clocks.
    pub resync_every_cycle: bool,
    /// Totals per method run.
    pub totals: Vec<(Method, MethodTotals)>,
}

/// What [`simulate`] returns: the totals per method (in [`Method::ALL`] order), per clock
/// variant, and the full runs of the first seed (for the figures).
struct Simulation {
    totals: Vec<MethodTotals>,
    clock: Vec<ClockResult>,
    first: Vec<Seed003Run>,
}

/// The clock variants of the report: the other sync mode at the configured drift (every
/// method), and both sync modes at the stress drift (ours).
fn clock_variants(scenario: &Scenario) -> Vec<ClockVariant> {
    let config = &scenario.config;
    let with = |drift_std_ppm: f64, resync_every_cycle: bool| {
        let mut c = config.clone();
        c.clock.drift_std_ppm = drift_std_ppm;
        c.clock.resync_every_cycle = resync_every_cycle;
        c
    };
    let (drift, resync) = (config.clock.drift_std_ppm, config.clock.resync_every_cycle);
    let stress = scenario.evaluation.clock_stress_drift_ppm;
    vec![
        ClockVariant {
            config: with(drift, !resync),
            methods: Method::ALL.to_vec(),
        },
        ClockVariant {
            config: with(stress, true),
            methods: vec![Method::AssociatedEkf],
        },
        ClockVariant {
            config: with(stress, false),
            methods: vec![Method::AssociatedEkf],
        },
    ]
}

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

/// Runs every method on `config` and every clock variant's methods on its configuration, for
/// `runs` seeds (one progress unit per seed), and adds up the totals in run order.
fn simulate(
    config: &Seed003Config,
    variants: &[ClockVariant],
    context: &Context<'_>,
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<Simulation> {
    let first_seed = run_seed(options.seed, 0);
    let per_run = monte_carlo(options.runs, options.seed, progress, |seed| {
        let runs = Method::ALL
            .iter()
            .map(|&method| run_seed_003(config, method, seed))
            .collect::<Result<Vec<_>>>()?;
        let totals: Vec<MethodTotals> = runs.iter().map(|run| MethodTotals::from_run(run, context)).collect();
        let clock = variants
            .iter()
            .map(|v| {
                v.methods
                    .iter()
                    .map(|&m| Ok(MethodTotals::from_run(&run_seed_003(&v.config, m, seed)?, context)))
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((totals, clock, (seed == first_seed).then_some(runs)))
    })?;
    // sum in run order: identical for any thread count
    let mut totals = vec![MethodTotals::default(); Method::ALL.len()];
    let mut clock: Vec<ClockResult> = variants
        .iter()
        .map(|v| ClockResult {
            drift_std_ppm: v.config.clock.drift_std_ppm,
            resync_every_cycle: v.config.clock.resync_every_cycle,
            totals: v.methods.iter().map(|&m| (m, MethodTotals::default())).collect(),
        })
        .collect();
    let mut first = Vec::new();
    for (run_totals, run_clock, runs) in per_run {
        for (sum, t) in totals.iter_mut().zip(&run_totals) {
            sum.merge(t)?;
        }
        for (result, variant_totals) in clock.iter_mut().zip(&run_clock) {
            for ((_, sum), t) in result.totals.iter_mut().zip(variant_totals) {
                sum.merge(t)?;
            }
        }
        if let Some(runs) = runs {
            first = runs;
        }
    }
    Ok(Simulation { totals, clock, first })
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
        routes: &config.robots,
    };
    let Simulation { totals, clock, first } =
        simulate(config, &clock_variants(&scenario), &context, options, progress)?;
    let mut sweep = vec![(config.scheduling.task_nodes, totals.clone())];
    for k in extra_sweep_values(&scenario) {
        let mut variant = config.clone();
        variant.scheduling.task_nodes = k;
        sweep.push((k, simulate(&variant, &[], &context, options, progress)?.totals));
    }
    sweep.sort_by_key(|(k, _)| *k);

    let mut report = ExperimentReport::new(
        "wsn-ekf",
        "Seed 003 — multi-robot tracking in an ultrasonic WSN: single-observation EKF with adaptive node scheduling",
        options.runs,
        options.seed,
    );
    report.metrics = metrics(&scenario, &intervals, &totals, &clock);
    report.tables = vec![
        tables::per_robot_table(&scenario, &totals),
        tables::bounds_table(&totals),
        tables::sweep_table(&sweep),
        tables::counters_table(&totals),
        tables::energy_table(&scenario, &totals),
    ];
    report
        .tables
        .extend(tables::energy_per_node_table(&scenario, &totals, Method::AssociatedEkf));
    report.tables.push(tables::clock_table(&scenario, &totals, &clock));
    report.figures = figures::all(&scenario, &intervals, &totals, &first)?;
    report.notes = notes::all(&scenario, &intervals, &totals, &sweep, &clock, options);
    Ok(report)
}

/// The metric rows.
fn metrics(
    scenario: &Scenario,
    intervals: &[(f64, f64)],
    totals: &[MethodTotals],
    clock: &[ClockResult],
) -> Vec<Metric> {
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
    for (method, t) in Method::ALL.iter().zip(totals).skip(1) {
        let Some(ledger) = &t.energy else { continue };
        let sum = ledger.totals();
        let power = ledger.model().power;
        metrics.push(Metric::new(
            format!("{}: energy per run with scheduling (radio + sonar)", method.label()),
            "J",
            t.per_run_f64(sum.scheduled.total_j(&power)),
        ));
        metrics.push(Metric::new(
            format!("{}: energy per run with all nodes on (radio + sonar)", method.label()),
            "J",
            t.per_run_f64(sum.all_on.total_j(&power)),
        ));
        metrics.push(Metric::new(
            format!("{}: energy saved by scheduling (radio + sonar)", method.label()),
            "%",
            sum.energy_saving_percent(),
        ));
    }
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
    for variant in clock {
        for (method, t) in &variant.totals {
            let drift = if variant.drift_std_ppm == scenario.config.clock.drift_std_ppm {
                String::new()
            } else {
                format!("{:.0} ppm ", variant.drift_std_ppm)
            };
            metrics.push(Metric::new(
                format!(
                    "{}: position RMSE, {drift}clocks {}",
                    method.label(),
                    tables::sync_label(variant.resync_every_cycle)
                ),
                "m",
                t.all.rmse_m(),
            ));
        }
    }
    metrics
}
