//! The figures of the `wsn-ekf` report: the test-bed map (paper Fig. 5), a border crossing
//! (Fig. 4), the shared-cell episode, error over time, RMSE per method and the error CDF.

use crate::error::Result;
use crate::experiments::common::cdf_series;
use crate::report::{Figure, Series, SeriesStyle};
use crate::reproduction::seed_003::{Method, Seed003Run};

use super::scenario::Scenario;
use super::summary::{MethodTotals, BIN_S};

/// Every figure (the maps only when the first run is available).
pub(super) fn all(
    scenario: &Scenario,
    intervals: &[(f64, f64)],
    totals: &[MethodTotals],
    first: &[Seed003Run],
) -> Result<Vec<Figure>> {
    let mut figures = Vec::new();
    if first.len() == Method::ALL.len() {
        figures.push(map(scenario, first));
        if let Some(figure) = crossing(scenario, first) {
            figures.push(figure);
        }
        if let Some(figure) = shared_cell(scenario, intervals, first) {
            figures.push(figure);
        }
    }
    figures.push(error_over_time(totals));
    figures.push(rmse_comparison(totals));
    figures.push(cdf(totals)?);
    Ok(figures)
}

/// `(x, y)` of robot `i` over a run's epochs in `[from_s, to_s]`: truth or estimate.
fn track(run: &Seed003Run, i: usize, truth: bool, from_s: f64, to_s: f64) -> Vec<[f64; 2]> {
    run.epochs
        .iter()
        .filter(|e| (from_s..=to_s).contains(&e.time_s))
        .map(|e| if truth { e.truth_m[i] } else { e.estimate_m[i] })
        .collect()
}

/// Paper Fig. 5: the bed with its nodes and cells, the three routes, the LS fixes and the
/// paper's EKF tracks of the first run.
fn map(scenario: &Scenario, first: &[Seed003Run]) -> Figure {
    let bed = &scenario.config.bed;
    let all = f64::INFINITY;
    let mut figure = Figure::new(
        "wsn-ekf-map",
        "Test bed (paper Fig. 5): 12 nodes on the corners of 6 cells, true routes, LS fixes and the paper's EKF tracks (run 1)",
        "x (m)",
        "y (m)",
    )
    .equal_aspect()
    .with(Series::new("cell borders", SeriesStyle::Dashed, bed.grid_polyline_m()))
    .with(Series::new("nodes", SeriesStyle::Points, bed.nodes_m().to_vec()));
    for (i, name) in scenario.names.iter().enumerate() {
        figure = figure.with(Series::new(
            format!("truth {name}"),
            SeriesStyle::Line,
            track(&first[0], i, true, 0.0, all),
        ));
    }
    let ls: Vec<[f64; 2]> = (0..scenario.names.len())
        .flat_map(|i| track(&first[0], i, false, 0.0, all))
        .collect();
    figure = figure.with(Series::new("LS fixes", SeriesStyle::Points, ls));
    for (i, name) in scenario.names.iter().enumerate() {
        figure = figure.with(Series::new(
            format!("paper EKF {name}"),
            SeriesStyle::Line,
            track(&first[1], i, false, 0.0, all),
        ));
    }
    figure
}

/// Paper Fig. 4: the first robot's first border crossing, LS against the EKFs (run 1).
fn crossing(scenario: &Scenario, first: &[Seed003Run]) -> Option<Figure> {
    let bed = &scenario.config.bed;
    let run = &first[0];
    // the first epoch at which robot 0's true cell changes
    let k = (1..run.epochs.len())
        .find(|&k| bed.cell_of(run.epochs[k].truth_m[0]) != bed.cell_of(run.epochs[k - 1].truth_m[0]))?;
    let crossing_s = run.epochs[k].time_s;
    let (from_s, to_s) = (crossing_s - 1.5, crossing_s + 1.5);
    let truth = track(run, 0, true, from_s, to_s);
    // the border crossed: vertical if the column changed
    let side = bed.cell_side_m();
    let (a, b) = (run.epochs[k - 1].truth_m[0], run.epochs[k].truth_m[0]);
    let vertical = (a[0] / side).floor() != (b[0] / side).floor();
    let border = if vertical {
        let x = (a[0].max(b[0]) / side).floor() * side;
        vec![[x, a[1] - 0.3], [x, a[1] + 0.3]]
    } else {
        let y = (a[1].max(b[1]) / side).floor() * side;
        vec![[a[0] - 0.3, y], [a[0] + 0.3, y]]
    };
    let name = scenario.names.first().cloned().unwrap_or_default();
    let mut figure = Figure::new(
        "wsn-ekf-crossing",
        format!("Robot {name} crossing a cell border (paper Fig. 4): LS fixes against the EKF tracks, ±1.5 s around the crossing (run 1)"),
        "x (m)",
        "y (m)",
    )
    .equal_aspect()
    .with(Series::new("cell border", SeriesStyle::Dashed, border))
    .with(Series::new("truth", SeriesStyle::Line, truth));
    for (method, run) in Method::ALL.iter().zip(first) {
        let style = if *method == Method::LeastSquares {
            SeriesStyle::Points
        } else {
            SeriesStyle::Line
        };
        figure = figure.with(Series::new(method.label(), style, track(run, 0, false, from_s, to_s)));
    }
    Some(figure)
}

/// The shared-cell episode (limit ①): the paper's EKF against ours for the robots sharing the
/// cell, from 1 s before to 2 s after (run 1).
fn shared_cell(scenario: &Scenario, intervals: &[(f64, f64)], first: &[Seed003Run]) -> Option<Figure> {
    let &(start_s, end_s) = intervals.first()?;
    let (from_s, to_s) = (start_s - 1.0, end_s + 2.0);
    let run = &first[1];
    let bed = &scenario.config.bed;
    // the robots sharing a cell at the episode's middle
    let middle = run.epochs.iter().min_by(|a, b| {
        (a.time_s - (start_s + end_s) / 2.0)
            .abs()
            .total_cmp(&(b.time_s - (start_s + end_s) / 2.0).abs())
    })?;
    let cells: Vec<usize> = middle.truth_m.iter().map(|&p| bed.cell_of(p)).collect();
    let sharing: Vec<usize> = (0..cells.len())
        .filter(|&i| (0..cells.len()).any(|j| j != i && cells[j] == cells[i]))
        .collect();
    let mut figure = Figure::new(
        "wsn-ekf-shared-cell",
        format!(
            "Two robots in one cell (paper limit ①), {start_s:.1}–{end_s:.1} s: the paper's EKF (echo = scheduled robot) against ours (gated GNN association), run 1"
        ),
        "x (m)",
        "y (m)",
    )
    .equal_aspect();
    for &i in &sharing {
        let name = scenario.names.get(i).cloned().unwrap_or_default();
        figure = figure
            .with(Series::new(
                format!("truth {name}"),
                SeriesStyle::Dashed,
                track(run, i, true, from_s, to_s),
            ))
            .with(Series::new(
                format!("paper EKF {name}"),
                SeriesStyle::Line,
                track(&first[1], i, false, from_s, to_s),
            ))
            .with(Series::new(
                format!("ours {name}"),
                SeriesStyle::Line,
                track(&first[2], i, false, from_s, to_s),
            ));
    }
    Some(figure)
}

/// RMSE over runs and robots per time bin, with ours' √PCRB.
fn error_over_time(totals: &[MethodTotals]) -> Figure {
    let mut figure = Figure::new(
        "wsn-ekf-error-time",
        format!("Position RMSE over runs and robots in {BIN_S} s bins; √PCRB of ours dashed"),
        "time (s)",
        "RMSE (m)",
    );
    let centre = |k: usize| (k as f64 + 0.5) * BIN_S;
    for (method, t) in Method::ALL.iter().zip(totals) {
        let points = t
            .bins
            .iter()
            .enumerate()
            .filter(|(_, b)| b.count > 0)
            .map(|(k, b)| [centre(k), b.rmse_m()])
            .collect();
        figure = figure.with(Series::new(method.label(), SeriesStyle::Line, points));
    }
    if let Some(ours) = totals.get(2) {
        let points = ours
            .bins
            .iter()
            .enumerate()
            .filter(|(_, b)| b.count > 0)
            .map(|(k, b)| [centre(k), b.bound_m()])
            .collect();
        figure = figure.with(Series::new("√PCRB (ours' ranges)", SeriesStyle::Dashed, points));
    }
    figure
}

/// RMSE per method (x = 1 LS, 2 paper EKF, 3 ours): one robot per cell, near borders (one
/// robot per cell), robots sharing a cell, whole run, and the √PCRB of the first.
fn rmse_comparison(totals: &[MethodTotals]) -> Figure {
    let at = |f: &dyn Fn(&MethodTotals) -> f64| -> Vec<[f64; 2]> {
        totals.iter().enumerate().map(|(i, t)| [(i + 1) as f64, f(t)]).collect()
    };
    Figure::new(
        "wsn-ekf-rmse",
        "Position RMSE per method (1 = LS, 2 = paper EKF, 3 = ours): one robot per cell, near cell borders, robots sharing a cell, whole run; √PCRB (one robot per cell) dashed",
        "method",
        "RMSE (m)",
    )
    .with(Series::new("one robot per cell", SeriesStyle::Points, at(&|t| t.before.rmse_m())))
    .with(Series::new("near borders", SeriesStyle::Points, at(&|t| t.border.rmse_m())))
    .with(Series::new("shared cell", SeriesStyle::Points, at(&|t| t.shared.rmse_m())))
    .with(Series::new("whole run", SeriesStyle::Points, at(&|t| t.all.rmse_m())))
    .with(Series::new("√PCRB (one robot per cell)", SeriesStyle::Dashed, at(&|t| t.before.bound_m())))
}

/// Empirical CDF of the position errors of every run, robot and epoch.
fn cdf(totals: &[MethodTotals]) -> Result<Figure> {
    let mut figure = Figure::new(
        "wsn-ekf-cdf",
        "CDF of the position error (all runs, robots and epochs)",
        "position error (m)",
        "fraction of epochs",
    );
    for (method, t) in Method::ALL.iter().zip(totals) {
        figure = figure.with(cdf_series(method.label(), &t.errors_m)?);
    }
    Ok(figure)
}
