//! The figures of the `ukf-uwb` report, as data: velocities before and after the UKF (paper
//! Fig. 1–2), the UKF's errors over time (Fig. 3), RMSE over time of UKF and EKF with the
//! √PCRB (Fig. 4 and 8), trajectories (Fig. 5 and 6), the x/y errors of EKF and UKF on the
//! turn (Fig. 7), and the RMSE of the NLOS extension.

use super::analysis::{ScenarioAnalysis, TrackerSummary};
use crate::report::{Figure, Series, SeriesStyle};
use crate::reproduction::seed_001::{Seed001Config, Seed001Filter, Seed001Run};

/// The figures of one scenario; `prefix` is e.g. `ukf-uwb-cv`, `label` e.g. "scenario 1 (CV)",
/// `paper` the paper's figure numbers for (trajectory, RMSE).
pub(super) fn scenario_figures(
    prefix: &str,
    label: &str,
    paper: (&str, &str),
    config: &Seed001Config,
    analysis: &ScenarioAnalysis,
    run: &Seed001Run,
) -> Vec<Figure> {
    let mut figures = velocity_figures(prefix, label, config, run);
    figures.extend(error_figures(prefix, label, analysis));
    figures.push(rmse_figure(prefix, label, paper.1, analysis));
    figures.push(trajectory_figure(prefix, label, paper.0, config, analysis, run));
    figures
}

/// Paper Fig. 1–2: true velocity, the velocity of differenced fixes ("before UKF") and the
/// UKF's, for one run.
fn velocity_figures(prefix: &str, label: &str, config: &Seed001Config, run: &Seed001Run) -> Vec<Figure> {
    let x0 = config.truth.initial_state;
    let step_s = config.truth.step_s;
    let ukf: &[[f64; 4]] = run.track(Seed001Filter::Ukf).map_or(&[], |t| &t.estimates);
    // v_k = (p_k − p_{k−1}) / t from consecutive fixes (the known start before the first)
    let mut previous = Some([x0[0], x0[2]]);
    let mut differenced: [Vec<[f64; 2]>; 2] = [Vec::new(), Vec::new()];
    for (&t, fix) in run.times_s.iter().zip(&run.fixes) {
        if let (Some(p), Some(q)) = (previous, fix) {
            differenced[0].push([t, (q[0] - p[0]) / step_s]);
            differenced[1].push([t, (q[1] - p[1]) / step_s]);
        }
        previous = *fix;
    }
    [("x", 1usize, "1"), ("y", 3, "2")]
        .into_iter()
        .zip(differenced)
        .map(|((axis, index, fig), before)| {
            let over_time = |states: &[[f64; 4]]| -> Vec<[f64; 2]> {
                run.times_s.iter().zip(states).map(|(&t, s)| [t, s[index]]).collect()
            };
            Figure::new(
                format!("{prefix}-velocity-{axis}"),
                format!("{label}: {axis} velocity before and after the UKF, run 0 (paper Fig. {fig})"),
                "time (s)",
                format!("v_{axis} (m/s)"),
            )
            .with(Series::new("truth", SeriesStyle::Line, over_time(&run.truth)))
            .with(Series::new(
                "before UKF: differenced TOA-RSS fixes",
                SeriesStyle::Points,
                before,
            ))
            .with(Series::new("after UKF", SeriesStyle::Line, over_time(ukf)))
        })
        .collect()
}

/// Paper Fig. 3: the UKF's mean absolute position and velocity errors over time.
fn error_figures(prefix: &str, label: &str, analysis: &ScenarioAnalysis) -> Vec<Figure> {
    let ukf = &analysis.trackers[Seed001Filter::Ukf.index()];
    let runs = analysis.runs;
    let series = |name: &str, i: usize| over_time(name, SeriesStyle::Line, analysis, &ukf.mean_abs_error[i]);
    vec![
        Figure::new(
            format!("{prefix}-ukf-position-errors"),
            format!("{label}: UKF position errors, mean |error| over {runs} runs (paper Fig. 3 A, C)"),
            "time (s)",
            "mean |position error| (m)",
        )
        .with(series("A: x", 0))
        .with(series("C: y", 2)),
        Figure::new(
            format!("{prefix}-ukf-velocity-errors"),
            format!("{label}: UKF velocity errors, mean |error| over {runs} runs (paper Fig. 3 B, D)"),
            "time (s)",
            "mean |velocity error| (m/s)",
        )
        .with(series("B: v_x", 1))
        .with(series("D: v_y", 3)),
    ]
}

/// Paper Fig. 4 / 8: RMSE over time of UKF and EKF (and our best when it is another tracker),
/// with the √PCRB.
fn rmse_figure(prefix: &str, label: &str, paper: &str, analysis: &ScenarioAnalysis) -> Figure {
    let mut figure = Figure::new(
        format!("{prefix}-rmse"),
        format!(
            "{label}: position RMSE over {} runs, UKF vs EKF, and √PCRB (paper {paper})",
            analysis.runs
        ),
        "time (s)",
        "position RMSE (m)",
    );
    let mut shown = vec![Seed001Filter::Ukf.index(), Seed001Filter::Ekf.index()];
    if !shown.contains(&analysis.best) {
        shown.push(analysis.best);
    }
    for i in shown {
        let t = &analysis.trackers[i];
        figure = figure.with(rmse_series(t, analysis));
    }
    figure.with(over_time(
        "√PCRB",
        SeriesStyle::Dashed,
        analysis,
        &analysis.bound.per_epoch_m,
    ))
}

/// Paper Fig. 5 / 6: one run's true track, fixes, UKF, EKF (and best) tracks, and the stations.
fn trajectory_figure(
    prefix: &str,
    label: &str,
    paper: &str,
    config: &Seed001Config,
    analysis: &ScenarioAnalysis,
    run: &Seed001Run,
) -> Figure {
    let positions = |states: &[[f64; 4]]| states.iter().map(|s| [s[0], s[2]]).collect::<Vec<_>>();
    let x0 = config.truth.initial_state;
    let mut truth = vec![[x0[0], x0[2]]];
    truth.extend(positions(&run.truth));
    let mut figure = Figure::new(
        format!("{prefix}-trajectory"),
        format!("{label}: trajectories of run 0 (paper {paper})"),
        "x (m)",
        "y (m)",
    )
    .equal_aspect()
    .with(Series::new("truth", SeriesStyle::Line, truth))
    .with(Series::new(
        "TOA-RSS fixes",
        SeriesStyle::Points,
        run.fixes.iter().flatten().copied().collect(),
    ));
    let mut shown = vec![Seed001Filter::Ukf, Seed001Filter::Ekf];
    if let Some(best) = Seed001Filter::ALL.get(analysis.best) {
        if !shown.contains(best) {
            shown.push(*best);
        }
    }
    for filter in shown {
        if let Some(track) = run.track(filter) {
            figure = figure.with(Series::new(
                filter.name(),
                SeriesStyle::Line,
                positions(&track.estimates),
            ));
        }
    }
    figure.with(Series::new(
        "base stations",
        SeriesStyle::Points,
        config.stations_m.clone(),
    ))
}

/// Paper Fig. 7 (scenario 2): mean |x| and |y| errors of EKF and UKF over time.
pub(super) fn axis_error_figure(prefix: &str, label: &str, analysis: &ScenarioAnalysis) -> Figure {
    let ukf = &analysis.trackers[Seed001Filter::Ukf.index()];
    let ekf = &analysis.trackers[Seed001Filter::Ekf.index()];
    Figure::new(
        format!("{prefix}-axis-errors"),
        format!(
            "{label}: mean |x| and |y| errors of EKF and UKF over {} runs (paper Fig. 7)",
            analysis.runs
        ),
        "time (s)",
        "mean |position error| (m)",
    )
    .with(over_time("UKF x", SeriesStyle::Line, analysis, &ukf.mean_abs_error[0]))
    .with(over_time(
        "EKF x",
        SeriesStyle::Dashed,
        analysis,
        &ekf.mean_abs_error[0],
    ))
    .with(over_time("UKF y", SeriesStyle::Line, analysis, &ukf.mean_abs_error[2]))
    .with(over_time(
        "EKF y",
        SeriesStyle::Dashed,
        analysis,
        &ekf.mean_abs_error[2],
    ))
}

/// The NLOS extension: RMSE over time of the UKF on line-of-sight and on NLOS ranges, of the
/// engine's CV UKF on both, and the line-of-sight √PCRB.
pub(super) fn nlos_figure(prefix: &str, analysis: &ScenarioAnalysis) -> Option<Figure> {
    let nlos = analysis.nlos.as_ref()?;
    let ukf = &analysis.trackers[Seed001Filter::Ukf.index()];
    Some(
        Figure::new(
            format!("{prefix}-nlos-rmse"),
            format!(
                "Scenario 1 with NLOS ranges ({:.0} % NLOS): position RMSE over {} runs",
                100.0 * nlos.nlos_share,
                analysis.runs
            ),
            "time (s)",
            "position RMSE (m)",
        )
        .with(Series::new(
            "UKF, line-of-sight ranges",
            SeriesStyle::Line,
            rmse_series(ukf, analysis).points,
        ))
        .with(rmse_series(&nlos.ukf, analysis))
        .with(rmse_series(&nlos.robust, analysis))
        .with(rmse_series(&nlos.robust_los, analysis))
        .with(over_time(
            "√PCRB (line of sight)",
            SeriesStyle::Dashed,
            analysis,
            &analysis.bound.per_epoch_m,
        )),
    )
}

/// A tracker's RMSE over time.
fn rmse_series(tracker: &TrackerSummary, analysis: &ScenarioAnalysis) -> Series {
    over_time(&tracker.name, SeriesStyle::Line, analysis, &tracker.rmse_per_epoch_m)
}

/// `values[k]` against the epoch times.
fn over_time(label: &str, style: SeriesStyle, analysis: &ScenarioAnalysis, values: &[f64]) -> Series {
    Series::new(
        label,
        style,
        analysis.times_s.iter().zip(values).map(|(&t, &v)| [t, v]).collect(),
    )
}
