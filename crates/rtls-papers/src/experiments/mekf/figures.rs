//! The figures of the `mekf` report, as data: the mine map with one run's tracks, the x-axis
//! error rate over time (paper Fig. 4), the x displacement over time with empty locations
//! (Fig. 5), the RMSE over time against the √PCRB, the error CDF, and Table 1's x error rates.

use nalgebra::DMatrix;

use super::evaluate::{MethodSummary, METHODS};
use super::scenario::MineWalk;
use super::table1::Table1Evaluation;
use crate::error::Result;
use crate::experiments::common::cdf_series;
use crate::report::{Figure, Series, SeriesStyle};
use crate::reproduction::seed_000::{Seed000Run, POSITION_INDICES};
use rtls_sim::metrics::error_rate;
use rtls_sim::pcrb::rmse_bound;
use rtls_sim::sensors::readers::ReaderStatus;

/// All figures of the mine walk; `run` is the run drawn in the per-run figures (run 0).
pub(super) fn mine_walk_figures(
    walk: &MineWalk,
    run: &Seed000Run,
    located_run: &[Vec<Option<[f64; 3]>>],
    summaries: &[MethodSummary],
    bounds: &[DMatrix<f64>],
    runs: usize,
) -> Result<Vec<Figure>> {
    let truth = walk.setup.truth_m();
    let times: Vec<f64> = walk.setup.epochs.iter().map(|s| s.time_s).collect();
    let mut figures = vec![map(walk, &truth, located_run)];
    // x error rate over time (paper Fig. 4): empty locations count as 100 %
    let mut rates = Figure::new(
        "mekf-x-error-rate",
        format!(
            "x error rate |D − N|/N, run 0 (seed {}); empty locations at 100 % as in Fig. 4",
            run.seed
        ),
        "time (s)",
        "x error rate (%)",
    );
    for (name, method) in METHODS.iter().zip(located_run) {
        let mut points = Vec::with_capacity(times.len());
        for ((t, actual), estimate) in times.iter().zip(&truth).zip(method) {
            if actual[0] != 0.0 {
                points.push([*t, 100.0 * error_rate(actual[0], estimate.map(|p| p[0]))?]);
            }
        }
        rates = rates.with(Series::new(*name, SeriesStyle::Line, points));
    }
    figures.push(rates);
    figures.push(displacement(&times, &truth, located_run, run.seed));
    // RMSE over time with the bound
    let mut over_time = Figure::new(
        "mekf-rmse-over-time",
        format!("3-D RMSE per epoch over {runs} runs, √PCRB, and the epochs in the danger zone (at 0)"),
        "time (s)",
        "3-D RMSE (m)",
    );
    for s in summaries {
        let points = times
            .iter()
            .zip(&s.rmse_by_epoch)
            .filter_map(|(t, r)| r.map(|r| [*t, r]))
            .collect();
        // the fix methods have gaps (the hole): markers, so no line bridges them
        over_time = over_time.with(Series::new(s.name, style_of(s.name), points));
    }
    let mut bound_points = Vec::with_capacity(bounds.len());
    for (t, b) in times.iter().zip(bounds) {
        bound_points.push([*t, rmse_bound(b, &POSITION_INDICES)?]);
    }
    over_time = over_time.with(Series::new("√PCRB", SeriesStyle::Dashed, bound_points));
    let hole: Vec<[f64; 2]> = times
        .iter()
        .zip(&walk.setup.in_zone)
        .filter(|(_, &z)| z)
        .map(|(t, _)| [*t, 0.0])
        .collect();
    figures.push(over_time.with(Series::new("walker in the danger zone", SeriesStyle::Points, hole)));
    figures.push(cdf(summaries)?);
    Ok(figures)
}

/// Plan view of the mine with run 0.
fn map(walk: &MineWalk, truth: &[[f64; 3]], located_run: &[Vec<Option<[f64; 3]>>]) -> Figure {
    let mut figure = Figure::new(
        "mekf-map",
        "Mine section in plan, run 0: tunnels, readers, rockfall, danger zone, truth and estimates",
        "x (m)",
        "y (m)",
    )
    .equal_aspect();
    for tunnel in walk.layout.tunnels() {
        let points = tunnel.centreline_m().iter().map(|p| [p[0], p[1]]).collect();
        figure = figure.with(Series::new(
            format!("tunnel: {}", tunnel.name()),
            SeriesStyle::Line,
            points,
        ));
    }
    let readers = walk.layout.readers();
    let pick = |keep: &dyn Fn(&rtls_sim::sensors::readers::Reader) -> bool| -> Vec<[f64; 2]> {
        readers
            .iter()
            .filter(|r| keep(r))
            .map(|r| [r.position_m[0], r.position_m[1]])
            .collect()
    };
    figure = figure
        .with(Series::new(
            "working readers",
            SeriesStyle::Points,
            pick(&|r| r.status == ReaderStatus::Working && r.obstacle_loss_db == 0.0),
        ))
        .with(Series::new(
            "reader behind equipment (obstacle)",
            SeriesStyle::Points,
            pick(&|r| r.status == ReaderStatus::Working && r.obstacle_loss_db > 0.0),
        ))
        .with(Series::new(
            "broken reader",
            SeriesStyle::Points,
            pick(&|r| r.status == ReaderStatus::Broken),
        ));
    for zone in walk.layout.zones() {
        figure = figure.with(Series::new(
            format!("danger zone: {}", zone.name),
            SeriesStyle::Dashed,
            zone.area.outline(),
        ));
    }
    for o in walk.layout.obstructions() {
        figure = figure.with(Series::new(o.name.clone(), SeriesStyle::Line, vec![o.from_m, o.to_m]));
    }
    figure = figure.with(Series::new(
        "truth",
        SeriesStyle::Line,
        truth.iter().map(|p| [p[0], p[1]]).collect(),
    ));
    for (name, method) in METHODS.iter().zip(located_run) {
        let points = method.iter().flatten().map(|p| [p[0], p[1]]).collect();
        figure = figure.with(Series::new(*name, style_of(name), points));
    }
    figure
}

/// x over time (paper Fig. 5), empty locations drawn at 0 as the paper does.
fn displacement(times: &[f64], truth: &[[f64; 3]], located_run: &[Vec<Option<[f64; 3]>>], seed: u64) -> Figure {
    let mut figure = Figure::new(
        "mekf-x-displacement",
        format!("x over time, run 0 (seed {seed}); empty locations at 0 as in Fig. 5"),
        "time (s)",
        "x (m)",
    )
    .with(Series::new(
        "truth",
        SeriesStyle::Line,
        times.iter().zip(truth).map(|(t, p)| [*t, p[0]]).collect(),
    ));
    for (name, method) in METHODS.iter().zip(located_run) {
        let points = times
            .iter()
            .zip(method)
            .filter_map(|(t, p)| p.map(|p| [*t, p[0]]))
            .collect();
        figure = figure.with(Series::new(*name, style_of(name), points));
    }
    let empty = times
        .iter()
        .zip(&located_run[0])
        .filter(|(_, p)| p.is_none())
        .map(|(t, _)| [*t, 0.0])
        .collect();
    figure.with(Series::new("empty location (drawn at 0)", SeriesStyle::Points, empty))
}

/// Fix methods (with empty epochs) as markers, trackers as lines.
fn style_of(method: &str) -> SeriesStyle {
    if method == METHODS[0] || method == METHODS[1] {
        SeriesStyle::Points
    } else {
        SeriesStyle::Line
    }
}

/// Empirical CDF of the 3-D errors.
fn cdf(summaries: &[MethodSummary]) -> Result<Figure> {
    let mut figure = Figure::new(
        "mekf-error-cdf",
        "CDF of the 3-D error over all runs (fix methods: epochs with a fix)",
        "3-D error (m)",
        "cumulative probability (fraction of errors ≤ x)",
    );
    for s in summaries {
        figure = figure.with(cdf_series(s.name, &s.errors_m)?);
    }
    Ok(figure)
}

/// Table 1's x error rate per row (paper Fig. 4 is drawn from these data).
pub(super) fn table_1_figure(evaluation: &Table1Evaluation) -> Figure {
    let mut figure = Figure::new(
        "mekf-table-1-x-error-rate",
        "Table 1: x error rate of the printed columns and of our KF on the printed RSSI",
        "time (s)",
        "x error rate (%)",
    );
    for (name, rates) in &evaluation.x_rate_series {
        figure = figure.with(Series::new(name.clone(), SeriesStyle::Line, rates.clone()));
    }
    figure
}
