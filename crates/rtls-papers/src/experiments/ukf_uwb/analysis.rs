//! Aggregation of the `ukf-uwb` Monte Carlo runs: per-epoch and pooled RMSE of every tracker
//! with the √PCRB, NEES/NIS against their χ² intervals, lost tracks, the single-epoch fixes
//! with their Cramér–Rao bound, and the NLOS extension. Every aggregate is a sum in run order,
//! so the results do not depend on the thread count.

use nalgebra::DMatrix;
use rtls_estimation::stats::{average_consistency_interval, ConsistencyInterval};

use super::config::ReportSettings;
use crate::error::{Result, SimError};
use crate::reproduction::seed_001::{FilterTrack, Seed001Config, Seed001Filter, Seed001Run};
use rtls_sim::metrics::average_over_runs;
use rtls_sim::pcrb::{mean_information, posterior_crb, rmse_bound, PcrbStep};

/// Position indices `x`, `y` of the `[x, vx, y, vy]` state.
pub(super) const POSITION: [usize; 2] = [0, 2];

/// Confidence of the two-sided NEES/NIS intervals.
pub(super) const CONSISTENCY_CONFIDENCE: f64 = 0.95;

/// One tracker over all runs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct TrackerSummary {
    /// Label.
    pub(super) name: String,
    /// `√((1/M) Σ_runs ‖p̂ − p‖²)` at each epoch, m.
    pub(super) rmse_per_epoch_m: Vec<f64>,
    /// RMSE pooled over the evaluated epochs (`t > converged_after_s`) and runs, m.
    pub(super) pooled_rmse_m: f64,
    /// Smallest per-epoch RMSE among the evaluated epochs, m.
    pub(super) min_rmse_m: f64,
    /// Largest per-epoch RMSE among the evaluated epochs, m.
    pub(super) max_rmse_m: f64,
    /// Mean over runs of `|x̂ − x|`, `|v̂x − vx|`, `|ŷ − y|`, `|v̂y − vy|` at each epoch (m, m/s).
    pub(super) mean_abs_error: [Vec<f64>; 4],
    /// Degrees of freedom of the NEES: 4 (`[x, vx, y, vy]`, the baselines) or 2 (the position,
    /// the engine).
    pub(super) nees_dof: usize,
    /// The 95 % interval of a run-averaged NEES with `nees_dof` degrees of freedom.
    pub(super) nees_interval: ConsistencyInterval,
    /// Time average over the evaluated epochs of the run-averaged NEES (`nees_dof` for a
    /// consistent filter).
    pub(super) mean_nees: f64,
    /// Share of evaluated epochs whose run-averaged NEES lies in the 95 % interval.
    pub(super) nees_inside: f64,
    /// As `mean_nees` for the NIS of the joint measurement (its dimension for a consistent
    /// filter); `None` for the engine, which updates one reading at a time.
    pub(super) mean_nis: Option<f64>,
    /// As `nees_inside` for the NIS.
    pub(super) nis_inside: Option<f64>,
    /// Runs whose last position error exceeds the lost-track threshold.
    pub(super) lost_tracks: usize,
    /// Share of evaluated (run, epoch) pairs with `|x̂ − x|` below the paper's threshold.
    pub(super) share_x_below: f64,
    /// Ranges the engine's validation gate refused, per range measured (0 for the baselines).
    pub(super) downweighted_share: f64,
}

/// The √PCRB of the position over the epochs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BoundSummary {
    /// `√(B_xx + B_yy)` at each epoch, m.
    pub(super) per_epoch_m: Vec<f64>,
    /// Pooled over the evaluated epochs, m.
    pub(super) pooled_m: f64,
    /// Smallest and largest per-epoch bound among the evaluated epochs, m.
    pub(super) min_m: f64,
    /// See `min_m`.
    pub(super) max_m: f64,
    /// `√(mean B_xx)` and `√(mean B_yy)` over the evaluated epochs, m.
    pub(super) axis_m: [f64; 2],
}

/// The single-epoch joint TOA-RSS fixes (the paper's "before UKF").
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FixSummary {
    /// RMSE of the fixes over the evaluated epochs, m.
    pub(super) rmse_m: f64,
    /// `√(mean tr(J_pos⁻¹))`: the single-epoch Cramér–Rao bound of an unbiased fix, pooled the
    /// same way, m.
    pub(super) crb_m: f64,
    /// Epochs (over all runs) without a fix.
    pub(super) failures: usize,
}

/// The NLOS extension over all runs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct NlosSummary {
    /// The paper's UKF on NLOS-biased ranges.
    pub(super) ukf: TrackerSummary,
    /// The engine's CV UKF on the same ranges.
    pub(super) robust: TrackerSummary,
    /// The engine's CV UKF on the line-of-sight ranges.
    pub(super) robust_los: TrackerSummary,
    /// Share of NLOS ranges.
    pub(super) nlos_share: f64,
    /// Mean bias over all ranges, m.
    pub(super) mean_bias_m: f64,
}

/// Everything the report says about one scenario.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ScenarioAnalysis {
    /// Epoch times, s.
    pub(super) times_s: Vec<f64>,
    /// Index of the first evaluated epoch.
    pub(super) first_epoch: usize,
    /// Monte Carlo runs.
    pub(super) runs: usize,
    /// Size of the joint measurement (the NIS's degrees of freedom).
    pub(super) measurement_dim: usize,
    /// One summary per [`Seed001Filter::ALL`] entry the runs computed (the baselines only for
    /// the variants), in that order.
    pub(super) trackers: Vec<TrackerSummary>,
    /// Index (into `trackers`) of the lowest pooled RMSE.
    pub(super) best: usize,
    /// √PCRB with the joint TOA + RSS information.
    pub(super) bound: BoundSummary,
    /// Pooled √PCRB with the TOA information only, m.
    pub(super) toa_bound_pooled_m: f64,
    /// Mean share of the position information that the RSS contributes.
    pub(super) rss_information_share: f64,
    /// The closest any true position came to a station, over all runs, m.
    pub(super) closest_station_m: f64,
    /// Distance of the initial position from the line through the first two stations, m.
    pub(super) start_to_baseline_m: f64,
    /// The fixes.
    pub(super) fixes: FixSummary,
    /// The 95 % interval of a run-averaged NEES of the baselines (dimension 4).
    pub(super) nees_interval: ConsistencyInterval,
    /// The 95 % interval of a run-averaged position NEES of the engine (dimension 2).
    pub(super) position_nees_interval: ConsistencyInterval,
    /// The 95 % interval of a run-averaged NIS (dimension = measurement size).
    pub(super) nis_interval: ConsistencyInterval,
    /// The NLOS extension, if run.
    pub(super) nlos: Option<NlosSummary>,
}

/// Analyses the runs of one scenario.
///
/// # Errors
/// [`SimError::EmptyInput`] for no runs; PCRB and interval errors.
pub(super) fn analyse(
    config: &Seed001Config,
    settings: &ReportSettings,
    runs: &[Seed001Run],
) -> Result<ScenarioAnalysis> {
    let first_run = runs.first().ok_or(SimError::EmptyInput { what: "seed 001 runs" })?;
    let times_s = first_run.times_s.clone();
    let first_epoch =
        times_s
            .iter()
            .position(|&t| t > settings.converged_after_s)
            .ok_or(SimError::InvalidParameter {
                name: "converged_after_s",
                reason: "no epoch comes after the convergence time",
            })?;
    let stations = config.stations_m.len();
    let measurement_dim = 2 * stations;
    let nees_interval =
        average_consistency_interval(4, runs.len(), CONSISTENCY_CONFIDENCE).map_err(SimError::estimation(0.0))?;
    let nis_interval = average_consistency_interval(measurement_dim, runs.len(), CONSISTENCY_CONFIDENCE)
        .map_err(SimError::estimation(0.0))?;
    let position_nees_interval =
        average_consistency_interval(2, runs.len(), CONSISTENCY_CONFIDENCE).map_err(SimError::estimation(0.0))?;
    let ctx = Context {
        runs,
        settings,
        stations,
        first_epoch,
        nees_intervals: [position_nees_interval, nees_interval],
        nis_interval,
    };
    let trackers = Seed001Filter::ALL
        .iter()
        .take_while(|f| runs.iter().all(|r| r.track(**f).is_some()))
        .map(|f| ctx.summarise(f.name(), |r| r.track(*f)))
        .collect::<Result<Vec<_>>>()?;
    let best = (0..trackers.len()).fold(0, |best, i| {
        if trackers[i].pooled_rmse_m < trackers[best].pooled_rmse_m {
            i
        } else {
            best
        }
    });
    let joint: Vec<Vec<DMatrix<f64>>> = runs.iter().map(|r| r.information.clone()).collect();
    let toa: Vec<Vec<DMatrix<f64>>> = runs.iter().map(|r| r.toa_information.clone()).collect();
    let bound = summarise_bound(&pcrb(config, &joint)?, first_epoch)?;
    let toa_bound_pooled_m = summarise_bound(&pcrb(config, &toa)?, first_epoch)?.pooled_m;
    let nlos = summarise_nlos(&ctx)?;
    Ok(ScenarioAnalysis {
        times_s,
        first_epoch,
        runs: runs.len(),
        measurement_dim,
        trackers,
        best,
        bound,
        toa_bound_pooled_m,
        rss_information_share: rss_share(runs),
        closest_station_m: closest_station(config, runs),
        start_to_baseline_m: start_to_baseline(config),
        fixes: summarise_fixes(runs, first_epoch)?,
        nees_interval,
        position_nees_interval,
        nis_interval,
        nlos,
    })
}

/// The PCRB `B_k`: the scenario's truth dynamics (`F`, `Q = G σ_ω² Gᵀ`) from the filters'
/// prior `P₀`, with the measurement information at the true states averaged over the runs.
///
/// # Errors
/// As [`posterior_crb`] and [`mean_information`].
pub(super) fn pcrb(config: &Seed001Config, information: &[Vec<DMatrix<f64>>]) -> Result<Vec<DMatrix<f64>>> {
    let mean = mean_information(information)?;
    let f = config.truth.transition_matrix()?;
    let q = config.truth.process_noise_matrix()?;
    let steps = mean.into_iter().map(|j| PcrbStep {
        transition: DMatrix::from_column_slice(4, 4, f.as_slice()),
        process_noise: DMatrix::from_column_slice(4, 4, q.as_slice()),
        measurement_information: j,
    });
    posterior_crb(
        &DMatrix::from_column_slice(4, 4, config.initial_covariance().as_slice()),
        steps,
    )
}

/// The bound per epoch, pooled, its range and per axis over the evaluated epochs.
fn summarise_bound(bounds: &[DMatrix<f64>], first_epoch: usize) -> Result<BoundSummary> {
    let per_epoch_m = bounds
        .iter()
        .map(|b| rmse_bound(b, &POSITION))
        .collect::<Result<Vec<_>>>()?;
    let evaluated = &per_epoch_m[first_epoch.min(per_epoch_m.len())..];
    let pooled_m = (evaluated.iter().map(|b| b * b).sum::<f64>() / evaluated.len().max(1) as f64).sqrt();
    let axis = |i: usize| -> f64 {
        let tail = &bounds[first_epoch.min(bounds.len())..];
        (tail.iter().map(|b| b[(i, i)].max(0.0)).sum::<f64>() / tail.len().max(1) as f64).sqrt()
    };
    Ok(BoundSummary {
        pooled_m,
        min_m: evaluated.iter().copied().fold(f64::INFINITY, f64::min),
        max_m: evaluated.iter().copied().fold(0.0, f64::max),
        axis_m: [axis(0), axis(2)],
        per_epoch_m,
    })
}

/// What the tracker summaries share.
struct Context<'a> {
    runs: &'a [Seed001Run],
    settings: &'a ReportSettings,
    stations: usize,
    first_epoch: usize,
    /// The NEES intervals for 2 and 4 degrees of freedom.
    nees_intervals: [ConsistencyInterval; 2],
    nis_interval: ConsistencyInterval,
}

impl Context<'_> {
    /// The summary of the track `select(run)` over all runs.
    fn summarise(&self, name: &str, select: impl Fn(&Seed001Run) -> Option<&FilterTrack>) -> Result<TrackerSummary> {
        let tracks = self
            .runs
            .iter()
            .map(|r| {
                select(r).ok_or(SimError::EmptyInput {
                    what: "a seed 001 track the analysis asked for",
                })
            })
            .collect::<Result<Vec<&FilterTrack>>>()?;
        let nees_dof = tracks.first().map_or(4, |t| t.nees_dof);
        let nees_interval = if nees_dof == 2 {
            self.nees_intervals[0]
        } else {
            self.nees_intervals[1]
        };
        let epochs = self.runs.first().map_or(0, |r| r.truth.len());
        let m = self.runs.len() as f64;
        let mut squared = vec![0.0; epochs];
        let mut mean_abs_error: [Vec<f64>; 4] = std::array::from_fn(|_| vec![0.0; epochs]);
        let (mut lost_tracks, mut below, mut downweighted) = (0, 0usize, 0usize);
        for (run, track) in self.runs.iter().zip(&tracks) {
            if track.estimates.len() != epochs || run.truth.len() != epochs {
                return Err(SimError::LengthMismatch {
                    what: "epochs of a seed 001 track",
                    expected: epochs,
                    found: track.estimates.len(),
                });
            }
            for (k, (estimate, truth)) in track.estimates.iter().zip(&run.truth).enumerate() {
                // e = x̂ − x per component
                let e: [f64; 4] = std::array::from_fn(|i| estimate[i] - truth[i]);
                squared[k] += e[0] * e[0] + e[2] * e[2];
                for (sum, value) in mean_abs_error.iter_mut().zip(e) {
                    sum[k] += value.abs() / m;
                }
                if k >= self.first_epoch && e[0].abs() < self.settings.x_error_threshold_m {
                    below += 1;
                }
            }
            let last = epochs.saturating_sub(1);
            if let (Some(estimate), Some(truth)) = (track.estimates.get(last), run.truth.get(last)) {
                let error = (estimate[0] - truth[0]).hypot(estimate[2] - truth[2]);
                lost_tracks += usize::from(error > self.settings.lost_track_error_m);
            }
            downweighted += track.downweighted_ranges;
        }
        let rmse_per_epoch_m: Vec<f64> = squared.iter().map(|s| (s / m).sqrt()).collect();
        let evaluated = &rmse_per_epoch_m[self.first_epoch.min(epochs)..];
        let evaluated_count = evaluated.len().max(1) as f64;
        let pooled_rmse_m =
            (squared[self.first_epoch.min(epochs)..].iter().sum::<f64>() / (m * evaluated_count)).sqrt();
        let nees = average_over_runs(&tracks.iter().map(|t| t.nees.clone()).collect::<Vec<_>>())?;
        let (mean_nees, nees_inside) = self.time_average(&nees, &nees_interval);
        let (mean_nis, nis_inside) = if tracks.iter().all(|t| t.nis.len() == epochs) {
            let nis = average_over_runs(&tracks.iter().map(|t| t.nis.clone()).collect::<Vec<_>>())?;
            let (mean, inside) = self.time_average(&nis, &self.nis_interval);
            (Some(mean), Some(inside))
        } else {
            (None, None)
        };
        // ranges measured per run: one per station and epoch
        let ranges_measured = (epochs * self.stations).max(1) as f64;
        Ok(TrackerSummary {
            name: name.to_string(),
            pooled_rmse_m,
            min_rmse_m: evaluated.iter().copied().fold(f64::INFINITY, f64::min),
            max_rmse_m: evaluated.iter().copied().fold(0.0, f64::max),
            rmse_per_epoch_m,
            mean_abs_error,
            nees_dof,
            nees_interval,
            mean_nees,
            nees_inside,
            mean_nis,
            nis_inside,
            lost_tracks,
            share_x_below: below as f64 / (m * evaluated_count),
            downweighted_share: downweighted as f64 / (m * ranges_measured),
        })
    }

    /// The mean of `values` over the evaluated epochs and the share of them inside `interval`.
    fn time_average(&self, values: &[f64], interval: &ConsistencyInterval) -> (f64, f64) {
        let evaluated = &values[self.first_epoch.min(values.len())..];
        let n = evaluated.len().max(1) as f64;
        let inside = evaluated.iter().filter(|v| interval.contains(**v)).count() as f64;
        (evaluated.iter().sum::<f64>() / n, inside / n)
    }
}

/// The NLOS extension's trackers, if the runs have it.
fn summarise_nlos(ctx: &Context<'_>) -> Result<Option<NlosSummary>> {
    if ctx.runs.iter().any(|r| r.nlos.is_none()) {
        return Ok(None);
    }
    let nlos_of = |r: &Seed001Run| r.nlos.as_ref().map(|n| (n.nlos_fraction, n.mean_bias_m));
    let m = ctx.runs.len() as f64;
    let (share, bias) = ctx
        .runs
        .iter()
        .filter_map(nlos_of)
        .fold((0.0, 0.0), |(s, b), (fs, fb)| (s + fs / m, b + fb / m));
    Ok(Some(NlosSummary {
        ukf: ctx.summarise("UKF (CV), NLOS ranges", |r| r.nlos.as_ref().map(|n| &n.ukf))?,
        robust: ctx.summarise("engine UKF (CV), NLOS ranges", |r| r.nlos.as_ref().map(|n| &n.robust))?,
        robust_los: ctx.summarise("engine UKF (CV), line-of-sight ranges", |r| {
            r.nlos.as_ref().map(|n| &n.robust_los)
        })?,
        nlos_share: share,
        mean_bias_m: bias,
    }))
}

/// RMSE of the fixes and their single-epoch CRB over the evaluated epochs.
fn summarise_fixes(runs: &[Seed001Run], first_epoch: usize) -> Result<FixSummary> {
    let (mut squared, mut count, mut failures) = (0.0, 0usize, 0usize);
    let (mut crb, mut crb_count) = (0.0, 0usize);
    for run in runs {
        for (k, (fix, truth)) in run.fixes.iter().zip(&run.truth).enumerate() {
            failures += usize::from(fix.is_none());
            if k < first_epoch {
                continue;
            }
            if let Some(f) = fix {
                squared += (f[0] - truth[0]).powi(2) + (f[1] - truth[2]).powi(2);
                count += 1;
            }
            // J_pos = the (x, y) block of Hᵀ R⁻¹ H;  CRB = tr(J_pos⁻¹)
            let j = &run.information[k];
            let j_pos = nalgebra::Matrix2::new(j[(0, 0)], j[(0, 2)], j[(2, 0)], j[(2, 2)]);
            if let Some(inverse) = j_pos.try_inverse() {
                crb += inverse.trace();
                crb_count += 1;
            }
        }
    }
    if count == 0 || crb_count == 0 {
        return Err(SimError::EmptyInput {
            what: "seed 001 fixes after convergence",
        });
    }
    Ok(FixSummary {
        rmse_m: (squared / count as f64).sqrt(),
        crb_m: (crb / crb_count as f64).sqrt(),
        failures,
    })
}

/// Mean over runs and epochs of `1 − tr(J_TOA,pos)/tr(J_pos)`: the share of the position
/// information the RSS adds.
fn rss_share(runs: &[Seed001Run]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for run in runs {
        for (j, jt) in run.information.iter().zip(&run.toa_information) {
            let total = j[(0, 0)] + j[(2, 2)];
            if total > 0.0 {
                sum += 1.0 - (jt[(0, 0)] + jt[(2, 2)]) / total;
                n += 1;
            }
        }
    }
    sum / n.max(1) as f64
}

/// The smallest distance between a true position and a station over all runs, m.
fn closest_station(config: &Seed001Config, runs: &[Seed001Run]) -> f64 {
    runs.iter()
        .flat_map(|r| r.truth.iter())
        .flat_map(|s| config.stations_m.iter().map(move |a| (s[0] - a[0]).hypot(s[2] - a[1])))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from the initial position to the line through the first two stations, m:
/// `|(p − a) × (b − a)| / ‖b − a‖`.
fn start_to_baseline(config: &Seed001Config) -> f64 {
    let (a, b) = (config.stations_m[0], config.stations_m[1]);
    let p = [config.truth.initial_state[0], config.truth.initial_state[2]];
    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
    let length = ux.hypot(uy);
    if length > 0.0 {
        ((p[0] - a[0]) * uy - (p[1] - a[1]) * ux).abs() / length
    } else {
        0.0
    }
}
