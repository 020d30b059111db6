//! `rtls repro lwknn`: seed 002 — L-WKNN fingerprint fixes over a 100 m field, tracked with
//! the accelerometer as control input (the paper's first- and second-order models as printed,
//! and ours: the textbook `[p, v]` model in the engine's tracker on the same data as a
//! recording), with Table 2, the σ_p² sweep, the model-order run, the engine's NEES and the
//! PCRB.

mod bound;
mod scenario;

use crate::error::Result;
use crate::experiments::common::{cdf_series, fmt, pooled_rmse, squared_errors};
use crate::experiments::template::{files::LWKNN as T, render};
use crate::experiments::{find_source, parse_scenario, ReproOptions, ScenarioSource};
use crate::report::{ExperimentReport, Figure, Metric, Series, SeriesStyle, Table};
use crate::reproduction::{run_seed_002, Seed002Config, Seed002Run};
use rtls_sim::metrics::{average_over_runs, euclidean_errors, percentile};
use rtls_sim::montecarlo::{monte_carlo, Progress};

use bound::Bounds;
use scenario::{
    check_accelerometer, check_locator, scenario_error, FieldScenario, ModelOrderScenario, NoiseSweepScenario,
    Table2Scenario, FIELD, MODEL_ORDER, NOISE_SWEEP, TABLE_2,
};

/// Everything read from the four files.
struct Scenarios {
    field: FieldScenario,
    base: Seed002Config,
    table_2: Table2Scenario,
    noise: NoiseSweepScenario,
    model_order: ModelOrderScenario,
}

fn read(sources: &[ScenarioSource]) -> Result<Scenarios> {
    let field: FieldScenario = parse_scenario(find_source(sources, FIELD)?)?;
    let base = field.config()?;
    let table_2: Table2Scenario = parse_scenario(find_source(sources, TABLE_2)?)?;
    for (i, row) in table_2.rows.iter().enumerate() {
        check_locator(
            TABLE_2,
            &format!("rows[{i}]"),
            row.strongest_anchors,
            row.radius_m,
            row.neighbours,
        )?;
    }
    let noise: NoiseSweepScenario = parse_scenario(find_source(sources, NOISE_SWEEP)?)?;
    if noise.rssi_variance_db2.is_empty() || noise.rssi_variance_db2.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(scenario_error(
            NOISE_SWEEP,
            "rssi_variance_db2",
            "give at least one finite variance > 0",
        ));
    }
    let model_order: ModelOrderScenario = parse_scenario(find_source(sources, MODEL_ORDER)?)?;
    check_accelerometer(MODEL_ORDER, model_order.accelerometer)?;
    Ok(Scenarios {
        field,
        base,
        table_2,
        noise,
        model_order,
    })
}

/// Progress units: one per run of every configuration.
///
/// # Errors
/// [`crate::SimError::Scenario`] if a scenario is missing or malformed.
pub fn work_units(sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    let s = read(sources)?;
    let configurations = 1 + s.table_2.rows.len() + s.noise.rssi_variance_db2.len() + 1;
    Ok((configurations * options.runs) as u64)
}

/// Per-run error summaries of one configuration.
struct Outcome {
    runs: Vec<Seed002Run>,
    /// Squared errors per run: fixes, first order, second order, textbook.
    squared: [Vec<Vec<f64>>; 4],
    /// Mean Euclidean error per run, same order.
    run_means: [Vec<f64>; 4],
}

/// The engine's position NEES pooled over every run and epoch of `outcome`.
fn mean_nees(outcome: &Outcome) -> f64 {
    let nees: Vec<f64> = outcome
        .runs
        .iter()
        .flat_map(|r| r.textbook_nees.iter().copied())
        .collect();
    nees.iter().sum::<f64>() / nees.len().max(1) as f64
}

/// The metric of ours' consistency.
pub const NEES_METRIC: &str = "Fig. 1: textbook [p, v] KF, engine: mean position NEES (2 if consistent)";

impl Outcome {
    /// Mean Euclidean error over every run and epoch of estimator `i`.
    fn mean(&self, i: usize) -> f64 {
        self.run_means[i].iter().sum::<f64>() / self.run_means[i].len() as f64
    }

    /// Standard deviation of the per-run mean errors (Table 2's σ_MSE).
    fn std_of_run_means(&self, i: usize) -> f64 {
        let mean = self.mean(i);
        let n = self.run_means[i].len() as f64;
        (self.run_means[i].iter().map(|m| (m - mean).powi(2)).sum::<f64>() / n).sqrt()
    }

    fn errors(&self, i: usize) -> Vec<f64> {
        self.squared[i].iter().flatten().map(|e| e.sqrt()).collect()
    }
}

fn simulate(config: &Seed002Config, options: &ReproOptions, progress: Progress<'_>) -> Result<Outcome> {
    let runs = monte_carlo(options.runs, options.seed, progress, |seed| run_seed_002(config, seed))?;
    let mut squared: [Vec<Vec<f64>>; 4] = Default::default();
    let mut run_means: [Vec<f64>; 4] = Default::default();
    for run in &runs {
        for (i, estimates) in [&run.fixes, &run.first_order, &run.second_order, &run.textbook]
            .into_iter()
            .enumerate()
        {
            squared[i].push(squared_errors(&run.truth, estimates)?);
            let errors = euclidean_errors(&run.truth, estimates)?;
            run_means[i].push(errors.iter().sum::<f64>() / errors.len() as f64);
        }
    }
    Ok(Outcome {
        runs,
        squared,
        run_means,
    })
}

const NAMES: [&str; 4] = [
    "L-WKNN fixes",
    "1st order (as printed)",
    "2nd order (as printed)",
    "textbook [p, v] (ours)",
];

/// Run `run` of base seed `seed` of the Fig. 1 field (`002-field.toml`) as files: the site,
/// the records and the truth its "ours" row tracks (`rtls sim lwknn` writes them).
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed scenario file; the simulation's
/// errors.
pub fn recording(sources: &[ScenarioSource], seed: u64, run: usize) -> Result<crate::recording::Recording> {
    let field: FieldScenario = parse_scenario(find_source(sources, FIELD)?)?;
    crate::reproduction::seed_002::seed_002_recording(&field.config()?, rtls_sim::montecarlo::run_seed(seed, run))
}

/// Runs the reproduction.
///
/// # Errors
/// [`crate::SimError::Scenario`] for a bad scenario; any simulation error.
pub fn reproduce(
    sources: &[ScenarioSource],
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<ExperimentReport> {
    let s = read(sources)?;
    let mut report = ExperimentReport::new(
        "lwknn",
        "Seed 002 — L-WKNN fingerprinting with accelerometer-aided Kalman tracking",
        options.runs,
        options.seed,
    );

    // Fig. 1–3: the base field
    let field = simulate(&s.base, options, progress)?;
    let field_bounds = Bounds::new(&s.base)?;
    let paper = s.field.paper;
    let lwknn_errors = field.errors(0);
    let agreement = {
        let flags: Vec<bool> = field
            .runs
            .iter()
            .flat_map(|r| r.same_neighbours_as_wknn.iter().copied())
            .collect();
        100.0 * flags.iter().filter(|same| **same).count() as f64 / flags.len().max(1) as f64
    };
    report.metrics.extend([
        Metric::new("Fig. 1: L-WKNN mean error", "m", field.mean(0)).paper(paper.lwknn_mean_error_m),
        Metric::new(
            "Fig. 3: L-WKNN 90th-percentile error",
            "m",
            percentile(&lwknn_errors, 90.0)?,
        ),
        Metric::new(
            "Fig. 3: 2nd-order KF 90th-percentile error",
            "m",
            percentile(&field.errors(2), 90.0)?,
        )
        .paper(paper.p90_error_m),
        Metric::new(
            "Fig. 1: L-WKNN RMSE (bound: single-epoch CRB)",
            "m",
            pooled_rmse(&field.squared[0])?,
        )
        .bound(field_bounds.snapshot_rmse_m),
        Metric::new(
            "Fig. 1: L-WKNN picks the same neighbours as global WKNN",
            "%",
            agreement,
        )
        .paper(paper.same_neighbours_percent),
        Metric::new("Fig. 1: 1st-order KF (as printed) mean error", "m", field.mean(1)),
        Metric::new("Fig. 1: 2nd-order KF (as printed) mean error", "m", field.mean(2))
            .paper(paper.second_order_mean_error_m),
        Metric::new("Fig. 1: textbook [p, v] KF mean error (ours)", "m", field.mean(3)),
        Metric::new(NEES_METRIC, "", mean_nees(&field)),
    ]);
    for (i, name) in NAMES.iter().enumerate().skip(1) {
        report.metrics.push(
            Metric::new(format!("Fig. 1: {name} RMSE"), "m", pooled_rmse(&field.squared[i])?)
                .bound(field_bounds.tracking_rmse_m),
        );
    }

    // Table 2
    let mut table_rows = Vec::new();
    let mut ours_table_2 = Vec::new();
    for row in &s.table_2.rows {
        let config = Seed002Config {
            locator: scenario::LocatorSection {
                strongest_anchors: row.strongest_anchors,
                radius_m: row.radius_m,
                neighbours: row.neighbours,
            }
            .locator(),
            ..s.base
        };
        let outcome = simulate(&config, options, progress)?;
        let label = format!(
            "N_k = {}, {} m, n = {}",
            row.strongest_anchors, row.radius_m, row.neighbours
        );
        report.metrics.push(
            Metric::new(format!("Table 2 ({label}): L-WKNN mean error"), "m", outcome.mean(0))
                .paper(row.paper_mean_error_m),
        );
        ours_table_2.push(outcome.mean(0));
        table_rows.push(vec![
            label,
            fmt(row.paper_mean_error_m, 2),
            fmt(outcome.mean(0), 2),
            fmt(row.paper_std_m, 2),
            fmt(outcome.std_of_run_means(0), 2),
            fmt(outcome.mean(2), 2),
        ]);
    }
    report.tables.push(Table {
        title: format!(
            "Table 2: L-WKNN on the Fig. 1 trajectory, {} runs per setting (e = mean error, σ = std of the per-run mean error)",
            options.runs
        ),
        header: [
            "(N_k, radius, n)",
            "paper e (m)",
            "ours e (m)",
            "paper σ (m)",
            "ours σ (m)",
            "ours 2nd-order KF (m)",
        ]
        .map(String::from)
        .to_vec(),
        rows: table_rows,
    });

    // Fig. 4: σ_p² sweep
    let mut sweep_rows = Vec::new();
    let mut sweep_series: [Vec<[f64; 2]>; 4] = Default::default();
    for &variance in &s.noise.rssi_variance_db2 {
        let config = Seed002Config {
            rssi_variance_db2: variance,
            ..s.base
        };
        let outcome = simulate(&config, options, progress)?;
        report.metrics.push(
            Metric::new(
                format!("Fig. 4 (σ_p² = {variance}): 2nd-order KF mean error"),
                "m",
                outcome.mean(2),
            )
            .paper(s.noise.paper_second_order_mean_error_m),
        );
        report.metrics.push(Metric::new(
            format!("Fig. 4 (σ_p² = {variance}): textbook KF mean error (ours)"),
            "m",
            outcome.mean(3),
        ));
        let mut row = vec![format!("{variance}")];
        for (i, series) in sweep_series.iter_mut().enumerate() {
            series.push([variance, outcome.mean(i)]);
            row.push(fmt(outcome.mean(i), 2));
        }
        sweep_rows.push(row);
    }
    report.tables.push(Table {
        title: "Fig. 4: mean error (m) against the online RSSI noise σ_p² (dB²)".to_string(),
        header: std::iter::once("σ_p² (dB²)").chain(NAMES).map(String::from).collect(),
        rows: sweep_rows,
    });

    // Fig. 5–6: first vs second order
    let order_config = Seed002Config {
        trajectory: s.model_order.trajectory.into(),
        accelerometer: s.model_order.accelerometer.into(),
        ..s.base
    };
    let order = simulate(&order_config, options, progress)?;
    let order_bounds = Bounds::new(&order_config)?;
    let order_paper = s.model_order.paper;
    report.metrics.extend([
        Metric::new("Fig. 6: 1st-order KF (as printed) mean error", "m", order.mean(1))
            .paper(order_paper.first_order_mean_error_m),
        Metric::new("Fig. 6: 2nd-order KF (as printed) mean error", "m", order.mean(2))
            .paper(order_paper.second_order_mean_error_m),
        Metric::new("Fig. 6: textbook [p, v] KF mean error (ours)", "m", order.mean(3)),
        Metric::new(
            "Fig. 6: textbook [p, v] KF RMSE (ours)",
            "m",
            pooled_rmse(&order.squared[3])?,
        )
        .bound(order_bounds.tracking_rmse_m),
    ]);

    report.figures = figures(&field, &field_bounds, &order, &sweep_series)?;
    report.notes = notes(&s, &field, &field_bounds, &order, &order_bounds, &ours_table_2)?;
    Ok(report)
}

fn figures(field: &Outcome, bounds: &Bounds, order: &Outcome, sweep: &[Vec<[f64; 2]>; 4]) -> Result<Vec<Figure>> {
    let run = &field.runs[0];
    let trajectory = Figure::new(
        "lwknn-trajectory",
        "Seed 002 run 0: truth, L-WKNN fixes and the trackers (cf. Fig. 1)",
        "x (m)",
        "y (m)",
    )
    .equal_aspect()
    .with(Series::new("L-WKNN fixes", SeriesStyle::Points, run.fixes.clone()))
    .with(Series::new("truth", SeriesStyle::Line, run.truth.clone()))
    .with(Series::new(
        "2nd order (as printed)",
        SeriesStyle::Line,
        run.second_order.clone(),
    ))
    .with(Series::new(
        "textbook [p, v] (ours)",
        SeriesStyle::Line,
        run.textbook.clone(),
    ));

    let mean_over_time = |outcome: &Outcome, i: usize| -> Result<Vec<f64>> {
        let per_run: Vec<Vec<f64>> = outcome.squared[i]
            .iter()
            .map(|r| r.iter().map(|e| e.sqrt()).collect())
            .collect();
        average_over_runs(&per_run)
    };
    let mut errors = Figure::new(
        "lwknn-error-over-time",
        "Seed 002: mean error at each epoch over the runs (cf. Fig. 2), with the √PCRB",
        "time (s)",
        "error (m)",
    );
    for (i, name) in NAMES.iter().enumerate() {
        errors = errors.with(Series::over_index(
            *name,
            SeriesStyle::Line,
            1.0,
            1.0,
            &mean_over_time(field, i)?,
        ));
    }
    errors = errors.with(Series::over_index(
        "√PCRB",
        SeriesStyle::Dashed,
        1.0,
        1.0,
        &bounds.tracking_over_time_m,
    ));

    let mut cdf = Figure::new(
        "lwknn-cdf",
        "Seed 002: CDF of the position error, all runs (cf. Fig. 3)",
        "error (m)",
        "P(error ≤ e)",
    );
    for (i, name) in NAMES.iter().enumerate() {
        cdf = cdf.with(cdf_series(name, &field.errors(i))?);
    }

    let mut noise = Figure::new(
        "lwknn-noise-sweep",
        "Seed 002: mean error against the RSSI noise σ_p² (cf. Fig. 4)",
        "σ_p² (dB²)",
        "mean error (m)",
    );
    for (series, name) in sweep.iter().zip(NAMES) {
        noise = noise.with(Series::new(name, SeriesStyle::Line, series.clone()));
    }

    let mut model_order = Figure::new(
        "lwknn-model-order",
        "Seed 002: first- vs second-order model, accelerometer noise 10 % of the reading (cf. Fig. 6)",
        "time (s)",
        "mean error (m)",
    );
    for (i, name) in NAMES.iter().enumerate().skip(1) {
        model_order = model_order.with(Series::over_index(
            *name,
            SeriesStyle::Line,
            1.0,
            1.0,
            &mean_over_time(order, i)?,
        ));
    }
    Ok(vec![trajectory, errors, cdf, noise, model_order])
}

fn notes(
    s: &Scenarios,
    field: &Outcome,
    field_bounds: &Bounds,
    order: &Outcome,
    order_bounds: &Bounds,
    ours_table_2: &[f64],
) -> Result<Vec<String>> {
    let table_means: Vec<f64> = s.table_2.rows.iter().map(|r| r.paper_mean_error_m).collect();
    let (paper_low, paper_high) = range(&table_means);
    let textbook_rmse = pooled_rmse(&field.squared[3])?;
    Ok(vec![
        render!(
            T,
            "setup",
            fingerprint_variance_db2 = s.base.fingerprint_variance_db2,
            rssi_variance_db2 = s.base.rssi_variance_db2,
            strongest_anchors = s.base.locator.strongest_anchors,
            radius_m = s.base.locator.radius_m,
            neighbours = s.base.locator.knn.neighbours,
            fix_variance_x_m2 = s.base.fix_variance_m2[0],
            fix_variance_y_m2 = s.base.fix_variance_m2[1],
        ),
        render!(
            T,
            "fixes",
            lwknn_mean_m = fmt(field.mean(0), 2),
            lwknn_p90_m = fmt(percentile(&field.errors(0), 90.0)?, 2),
            second_order_p90_m = fmt(percentile(&field.errors(2), 90.0)?, 2),
            paper_table_low_m = fmt(paper_low, 2),
            paper_table_high_m = fmt(paper_high, 2),
            table_spread_m = fmt(spread(ours_table_2), 2),
        ),
        render!(
            T,
            "tracking",
            second_order_m = fmt(field.mean(2), 2),
            first_order_m = fmt(field.mean(1), 2),
            textbook_m = fmt(field.mean(3), 2),
            textbook_nees = fmt(mean_nees(field), 1),
            order_gain_m = fmt(order.mean(1) - order.mean(2), 2),
            order_second_m = fmt(order.mean(2), 2),
            order_first_m = fmt(order.mean(1), 2),
        ),
        render!(
            T,
            "pcrb",
            field_bound_m = fmt(field_bounds.tracking_rmse_m, 2),
            order_bound_m = fmt(order_bounds.tracking_rmse_m, 2),
            field_ratio = fmt(textbook_rmse / field_bounds.tracking_rmse_m, 1),
            order_ratio = fmt(pooled_rmse(&order.squared[3])? / order_bounds.tracking_rmse_m, 1),
            snapshot_crb_m = fmt(field_bounds.snapshot_rmse_m, 2),
            lwknn_rmse_m = fmt(pooled_rmse(&field.squared[0])?, 2),
        ),
    ])
}

/// `(min, max)` of `values`.
fn range(values: &[f64]) -> (f64, f64) {
    values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(*v), hi.max(*v))
    })
}

/// `max − min` of `values` (0 for none).
fn spread(values: &[f64]) -> f64 {
    let (lo, hi) = range(values);
    if values.is_empty() {
        0.0
    } else {
        hi - lo
    }
}
