//! `rtls repro mekf` — seed 000 (ME-KF: motion equation + Kalman filter, mine personnel
//! location, Paishanlou mine).
//!
//! Two parts:
//! 1. **The mine walk** (`000-mine-walk.toml`): a miner walks down a decline, along a drift,
//!    over a rockfall into a collapsed zone whose reader is broken (a coverage hole) and back,
//!    then up a cross-cut. Per epoch the reader layer produces RSSI multilateration and DV-Hop
//!    fixes (or an empty location), the paper's ME-KF smooths the RSSI fixes and predicts
//!    through the hole, and our tracker runs an EKF on the raw RSSI. Reported: PEL, per-axis
//!    error rates, 3-D RMSE against the PCRB, predictive alarm lead times and false alarms,
//!    and an obstacle analysis from the RSSI innovations.
//! 2. **Table 1** (`000-table-1.toml`): the paper's printed data re-evaluated — error rates of
//!    its columns, our ME-KF re-run on its RSSI column, and why its PEL of 6.7 % cannot come
//!    from 20 samples.

mod evaluate;
mod figures;
mod notes;
mod scenario;
mod table1;

use super::{find_source, ReproOptions, ScenarioSource};
use crate::error::Result;
use crate::report::{ExperimentReport, Metric, Table};
use crate::reproduction::seed_000::{run_seed_000, Seed000Run, TrackState, TrackerCounts};
use evaluate::{AlarmSummary, MethodSummary, METHODS};
use rtls_sim::montecarlo::{monte_carlo, Progress};
use scenario::{MINE_WALK, TABLE_1};

/// Picks a tracker's states out of a run.
type StatesOf = fn(&Seed000Run) -> &[TrackState];

/// The paper's values per method (RSSI, DV-Hop, ME-KF, ours): PEL (%), Table 2.
const PAPER_PEL: [Option<f64>; 4] = [Some(6.7), Some(6.7), Some(0.0), None];
/// The paper's mean x error rates (%), §5.2 / Fig. 4: "about 20 %" and "about 5 %".
const PAPER_X_RATE: [Option<f64>; 4] = [Some(20.0), Some(20.0), Some(5.0), None];

/// Progress units of [`reproduce`]: one per Monte Carlo run of the mine walk.
///
/// # Errors
/// [`crate::SimError::Scenario`] if a scenario file is missing or malformed.
pub fn work_units(sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    scenario::mine_walk(find_source(sources, MINE_WALK)?)?;
    table1::table_1(find_source(sources, TABLE_1)?)?;
    Ok(options.runs as u64)
}

/// Run `run` of base seed `seed` of the mine walk as files: the site, the readers' records
/// and the truth that the "ours" row tracks (`rtls sim mekf` writes them).
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed scenario; the reader layer's
/// errors.
pub fn recording(sources: &[ScenarioSource], seed: u64, run: usize) -> Result<crate::recording::Recording> {
    let walk = scenario::mine_walk(find_source(sources, MINE_WALK)?)?;
    crate::reproduction::seed_000::seed_000_recording(&walk.setup, rtls_sim::montecarlo::run_seed(seed, run))
}

/// Runs the reproduction: `options.runs` seeded runs of the mine walk, and the Table 1
/// re-evaluation.
///
/// # Errors
/// [`crate::SimError::Scenario`] naming the file and field for a missing or malformed
/// scenario; any simulation or filter error.
pub fn reproduce(
    sources: &[ScenarioSource],
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<ExperimentReport> {
    let walk = scenario::mine_walk(find_source(sources, MINE_WALK)?)?;
    let table = table1::table_1(find_source(sources, TABLE_1)?)?;
    let runs = monte_carlo(options.runs, options.seed, progress, |seed| {
        run_seed_000(&walk.setup, seed)
    })?;
    let bounds = evaluate::pcrb(&walk, &walk.setup.information)?;
    let naive_bounds = evaluate::pcrb(&walk, &walk.setup.detected_information)?;
    let truth = walk.setup.truth_m();
    let located = evaluate::located(&runs);
    let mut summaries = Vec::with_capacity(METHODS.len());
    for (name, method) in METHODS.iter().zip(&located) {
        summaries.push(evaluate::summarise(name, method, &truth, &bounds)?);
    }
    let bins = evaluate::distance_bins(&located, &truth)?;
    let trackers: [(&str, StatesOf); 2] = [("ME-KF", |r| &r.mekf), ("ours", |r| &r.ours)];
    let horizons = [
        ("one-step prediction".to_string(), walk.period_s),
        (format!("{} s look-ahead", walk.look_ahead_s), walk.look_ahead_s),
    ];
    let mut alarms = Vec::new();
    for (tracker, states) in trackers {
        for (label, horizon_s) in &horizons {
            alarms.push((
                tracker,
                label.clone(),
                evaluate::alarm_summary(&walk, &runs, states, *horizon_s),
            ));
        }
    }
    let (kinds, dv_hop_failures) = evaluate::fix_breakdown(&runs);
    let innovations = evaluate::mean_innovations(&runs, walk.layout.readers().len());
    let table_1 = table1::evaluate(&table)?;

    let mut report = ExperimentReport::new(
        "mekf",
        "Seed 000 — ME-KF: motion equation + Kalman filter for mine personnel location (Wang, Deng, Liu, Yin, Computer Science 42(12), 2015)",
        options.runs,
        options.seed,
    );
    report.metrics = accuracy_metrics(&summaries);
    let naive = [
        evaluate::pooled_bound(&located[3], &naive_bounds)?,
        evaluate::pooled_bound(&located[0], &naive_bounds)?,
    ];
    report.metrics.push(Metric::new(
        "√PCRB without silences and map, trackers' epochs (not a bound)",
        "m",
        naive[0],
    ));
    report.metrics.push(Metric::new(
        "√PCRB without silences and map, RSSI fix epochs (not a bound)",
        "m",
        naive[1],
    ));
    let hole = 100.0 * walk.setup.in_zone.iter().filter(|&&z| z).count() as f64 / walk.setup.in_zone.len() as f64;
    report.metrics.push(Metric::new(
        "walker in the danger zone (coverage hole)",
        "% of epochs",
        hole,
    ));
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        report.metrics.push(
            Metric::new(
                format!("RSSI fixes: {name} mean squared error"),
                "m²",
                summaries[0].axis_mse_m2[axis],
            )
            .paper(walk.setup.mekf.measurement_variance),
        );
    }
    report.metrics.extend(alarm_metrics(&alarms));
    let heard: usize = runs.iter().map(|r| r.heard.iter().filter(|&&h| h > 0).count()).sum();
    let counts = runs.iter().fold(TrackerCounts::default(), |a, r| TrackerCounts {
        accepted: a.accepted + r.counts.accepted,
        rejected: a.rejected + r.counts.rejected,
        reinitialised: a.reinitialised + r.counts.reinitialised,
    });
    report.metrics.push(Metric::new(
        "ours: RSSI values gated out",
        "%",
        100.0 * counts.rejected as f64 / (counts.accepted + counts.rejected).max(1) as f64,
    ));
    report.metrics.push(Metric::new(
        "ours: track re-initialisations",
        "per run",
        counts.reinitialised as f64 / runs.len() as f64,
    ));
    let dv_hop_failures_percent = 100.0 * dv_hop_failures as f64 / heard.max(1) as f64;
    report.metrics.push(Metric::new(
        "DV-Hop: epochs heard without a DV-Hop fix",
        "% of heard epochs",
        dv_hop_failures_percent,
    ));
    let extras = evaluate::extras(&walk, &runs, &located, &bounds)?;
    if let Some(lag) = extras.rssi_lag_m {
        report.metrics.push(Metric::new(
            "RSSI fixes: mean x error in the 5 epochs before the zone entry",
            "m",
            lag,
        ));
    }
    let obstacles = evaluate::obstacles(&walk, &innovations);
    for r in &obstacles.readers {
        report.metrics.push(Metric::new(
            format!(
                "obstacle analysis: mean RSSI innovation at {} ({:.0} dB obstacle)",
                r.name, r.loss_db
            ),
            "dB",
            r.mean_innovation_db,
        ));
    }
    if let Some(median) = obstacles.clear_median_db {
        report.metrics.push(Metric::new(
            "obstacle analysis: median mean RSSI innovation of the clear readers",
            "dB",
            median,
        ));
    }
    report.metrics.extend(table1_metrics(&table_1));
    report.tables = vec![
        accuracy_table(&summaries),
        notes::distance_table(&bins),
        notes::alarm_table(&alarms),
        notes::fix_table(&kinds),
        notes::obstacle_table(&walk, &innovations),
    ];
    report.tables.extend(table1::tables(&table, &table_1));
    report.figures =
        figures::mine_walk_figures(&walk, &runs[0], &located_run(&located), &summaries, &bounds, runs.len())?;
    report.figures.push(figures::table_1_figure(&table_1));
    report.notes = notes::notes(&notes::NotesInput {
        walk: &walk,
        summaries: &summaries,
        bins: &bins,
        alarms: &alarms,
        kinds,
        counts,
        dv_hop_failures_percent,
        extras: &extras,
        obstacles: &obstacles,
        naive_bounds_m: naive,
        table: &table,
        table_1: &table_1,
        runs: runs.len(),
    });
    Ok(report)
}

/// Run 0 of every method.
fn located_run(located: &evaluate::Located) -> Vec<Vec<Option<[f64; 3]>>> {
    located.iter().map(|m| m[0].clone()).collect()
}

/// PEL, error rates, RMSE with bound, and ours vs ME-KF.
fn accuracy_metrics(summaries: &[MethodSummary]) -> Vec<Metric> {
    let mut metrics = Vec::new();
    for (i, s) in summaries.iter().enumerate() {
        let mut pel = Metric::new(format!("{}: PEL", s.name), "%", s.pel_percent);
        if let Some(p) = PAPER_PEL[i] {
            pel = pel.paper(p);
        }
        metrics.push(pel);
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            let mut rate = Metric::new(
                format!("{}: {name} error rate", s.name),
                "%",
                100.0 * s.error_rates[axis],
            );
            if let (0, Some(p)) = (axis, PAPER_X_RATE[i]) {
                rate = rate.paper(p);
            }
            metrics.push(rate);
        }
        metrics.push(Metric::new(format!("{}: 3-D RMSE", s.name), "m", s.rmse_m).bound(s.bound_m));
    }
    if let (Some(mekf), Some(ours)) = (summaries.get(2), summaries.get(3)) {
        metrics.push(Metric::new(
            "ours vs ME-KF: 3-D RMSE reduction",
            "%",
            100.0 * (1.0 - ours.rmse_m / mekf.rmse_m),
        ));
    }
    metrics
}

/// Lead time, share warned in time and false alarms per tracker and horizon.
fn alarm_metrics(alarms: &[(&str, String, AlarmSummary)]) -> Vec<Metric> {
    let mut metrics = Vec::new();
    for (tracker, label, a) in alarms {
        if let Some(lead) = a.mean_lead_s {
            metrics.push(Metric::new(format!("{tracker}: alarm lead time, {label}"), "s", lead));
        }
        metrics.push(Metric::new(
            format!("{tracker}: entries warned in time, {label}"),
            "% of runs",
            a.warned_percent,
        ));
        metrics.push(Metric::new(
            format!("{tracker}: false alarms, {label}"),
            "per run",
            a.false_per_run,
        ));
    }
    metrics
}

/// Table 1's re-evaluation as metrics.
fn table1_metrics(t: &table1::Table1Evaluation) -> Vec<Metric> {
    let mut metrics = Vec::new();
    for (column, paper) in t.columns.iter().zip([20.0, 20.0, 5.0, 5.0]) {
        metrics.push(
            Metric::new(
                format!("Table 1: {} x error rate", column.name),
                "%",
                100.0 * column.rates[0],
            )
            .paper(paper),
        );
    }
    metrics.push(Metric::new(
        "Table 1: RMS distance of our KF from the printed ME-KF column",
        "m",
        t.kf_vs_printed_m,
    ));
    for (name, pel) in ["RSSI", "DV-Hop"].iter().zip(t.printed_pel_percent) {
        metrics.push(Metric::new(format!("Table 1: PEL of the printed {name} column"), "%", pel).paper(6.7));
    }
    metrics.push(
        Metric::new(
            format!("Table 1: PEL closest to 6.7 % possible with {} samples", t.rows),
            "%",
            t.nearest_pel_percent,
        )
        .paper(6.7),
    );
    if let Some((_, n)) = t.smallest_sample {
        metrics.push(Metric::new(
            "Table 1: fewest samples that give a PEL of 6.7 %",
            "samples",
            n as f64,
        ));
    }
    metrics
}

/// One row per method.
fn accuracy_table(summaries: &[MethodSummary]) -> Table {
    let pct = |v: f64| format!("{:.1}", 100.0 * v);
    Table {
        title: "Accuracy per method over all runs (fix methods over the epochs with a fix; trackers over every epoch)"
            .to_string(),
        header: [
            "method",
            "PEL (%)",
            "x rate (%)",
            "y rate (%)",
            "z rate (%)",
            "x / y / z RMSE (m)",
            "3-D RMSE (m)",
            "√PCRB (m)",
            "RMSE / √PCRB",
        ]
        .map(String::from)
        .to_vec(),
        rows: summaries
            .iter()
            .map(|s| {
                vec![
                    s.name.to_string(),
                    format!("{:.1}", s.pel_percent),
                    pct(s.error_rates[0]),
                    pct(s.error_rates[1]),
                    pct(s.error_rates[2]),
                    format!(
                        "{:.2} / {:.2} / {:.2}",
                        s.axis_mse_m2[0].sqrt(),
                        s.axis_mse_m2[1].sqrt(),
                        s.axis_mse_m2[2].sqrt()
                    ),
                    format!("{:.2}", s.rmse_m),
                    format!("{:.2}", s.bound_m),
                    format!("{:.2}", s.rmse_m / s.bound_m.max(f64::MIN_POSITIVE)),
                ]
            })
            .collect(),
    }
}
