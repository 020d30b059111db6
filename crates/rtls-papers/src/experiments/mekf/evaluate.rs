//! Aggregation of the Monte Carlo runs of the mine walk: per-method PEL, per-axis error rates,
//! 3-D RMSE with the PCRB, error rates by distance from the origin, predictive alarms, the
//! RSSI fix breakdown and the obstacle analysis. Every aggregate is a sum in run order, so
//! the results do not depend on the thread count.

use nalgebra::DMatrix;
use rtls_estimation::motion::LinearMotionModel;

use super::scenario::MineWalk;
use crate::error::{Result, SimError};
use crate::reproduction::seed_000::{extrapolate, position_of, Seed000Run, TrackState, POSITION_INDICES};
use rtls_sim::metrics::{empty_location_percentage, error_rate, mean_axis_error_rates};
use rtls_sim::pcrb::{posterior_crb, rmse_bound, PcrbStep};
use rtls_sim::sensors::readers::{distance_m, RssiFixKind};

/// The four methods compared, in report order.
pub(super) const METHODS: [&str; 4] = ["RSSI", "DV-Hop", "ME-KF", "ours"];

/// Edges of the distance-from-origin bins of the error-rate table, m.
pub(super) const DISTANCE_BINS_M: [f64; 4] = [0.0, 10.0, 30.0, 60.0];

/// `located[method][run][epoch]`: what each method reported.
pub(super) type Located = Vec<Vec<Vec<Option<[f64; 3]>>>>;

/// What each method reported at each epoch of each run.
pub(super) fn located(runs: &[Seed000Run]) -> Located {
    let rssi = runs
        .iter()
        .map(|r| r.rssi.iter().map(|f| f.map(|f| f.position_m)).collect())
        .collect();
    let dv_hop = runs.iter().map(|r| r.dv_hop.clone()).collect();
    let track = |states: &[TrackState]| states.iter().map(|s| Some(position_of(s))).collect::<Vec<_>>();
    let mekf = runs.iter().map(|r| track(&r.mekf)).collect();
    let ours = runs.iter().map(|r| track(&r.ours)).collect();
    vec![rssi, dv_hop, mekf, ours]
}

/// The PCRB `B_k` at every epoch: the pedestrian CV model of our tracker from the trackers'
/// prior, with the information `information` at each epoch (the setup's expected information
/// of the censored RSSI and the map, [`crate::reproduction::seed_000::expected_information`],
/// or the naive one for comparison).
pub(super) fn pcrb(walk: &MineWalk, information: &[DMatrix<f64>]) -> Result<Vec<DMatrix<f64>>> {
    let f = walk.motion.transition_matrix(walk.period_s);
    let q = walk.motion.process_noise_matrix(walk.period_s);
    let prior = walk.setup.prior.gaussian(0.0)?;
    let steps = information.iter().map(|j| PcrbStep {
        transition: DMatrix::from_column_slice(6, 6, f.as_slice()),
        process_noise: DMatrix::from_column_slice(6, 6, q.as_slice()),
        measurement_information: j.clone(),
    });
    posterior_crb(&DMatrix::from_column_slice(6, 6, prior.covariance().as_slice()), steps)
}

/// `√((1/n) Σ tr B_k,pos)` over the (run, epoch) pairs at which `located` has a location.
///
/// # Errors
/// [`SimError::EmptyInput`] without any location; as [`rmse_bound`].
pub(super) fn pooled_bound(located: &[Vec<Option<[f64; 3]>>], bounds: &[DMatrix<f64>]) -> Result<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for run in located {
        for (estimate, bound) in run.iter().zip(bounds) {
            if estimate.is_some() {
                sum += rmse_bound(bound, &POSITION_INDICES)?.powi(2);
                n += 1;
            }
        }
    }
    if n == 0 {
        return Err(SimError::EmptyInput {
            what: "epochs with a location",
        });
    }
    Ok((sum / n as f64).sqrt())
}

/// Accuracy of one method over all runs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MethodSummary {
    pub(super) name: &'static str,
    /// Percentage of empty locations.
    pub(super) pel_percent: f64,
    /// Mean error rate `|D − N|/N` per axis (fraction), over epochs with a location.
    pub(super) error_rates: [f64; 3],
    /// 3-D RMSE over epochs with a location, m.
    pub(super) rmse_m: f64,
    /// `√PCRB` pooled over the same (run, epoch) pairs, m.
    pub(super) bound_m: f64,
    /// Mean squared error per axis, m².
    pub(super) axis_mse_m2: [f64; 3],
    /// 3-D errors, run-major, m.
    pub(super) errors_m: Vec<f64>,
    /// RMSE per epoch over the runs with a location, m.
    pub(super) rmse_by_epoch: Vec<Option<f64>>,
}

/// Summarises one method.
pub(super) fn summarise(
    name: &'static str,
    located: &[Vec<Option<[f64; 3]>>],
    truth: &[[f64; 3]],
    bounds: &[DMatrix<f64>],
) -> Result<MethodSummary> {
    let all: Vec<Option<[f64; 3]>> = located.iter().flatten().copied().collect();
    let truths: Vec<[f64; 3]> = located.iter().flat_map(|_| truth.iter().copied()).collect();
    let pel_percent = empty_location_percentage(&all)?;
    let error_rates = mean_axis_error_rates(&truths, &all)?;
    let mut errors_m = Vec::new();
    let (mut bound_sum, mut axis_sum) = (0.0, [0.0; 3]);
    let mut by_epoch = vec![(0.0, 0usize); truth.len()];
    for run in located {
        if run.len() != truth.len() {
            return Err(SimError::LengthMismatch {
                what: "epochs of a run vs truth",
                expected: truth.len(),
                found: run.len(),
            });
        }
        for (k, (estimate, actual)) in run.iter().zip(truth).enumerate() {
            let Some(p) = estimate else { continue };
            // e = ‖p̂ − p‖
            let e = distance_m(*p, *actual);
            errors_m.push(e);
            for axis in 0..3 {
                axis_sum[axis] += (p[axis] - actual[axis]).powi(2);
            }
            // the bound at this epoch: tr of the position block of B_k
            bound_sum += rmse_bound(&bounds[k], &POSITION_INDICES)?.powi(2);
            by_epoch[k].0 += e * e;
            by_epoch[k].1 += 1;
        }
    }
    if errors_m.is_empty() {
        return Err(SimError::EmptyInput {
            what: "epochs with a location",
        });
    }
    let count = errors_m.len() as f64;
    Ok(MethodSummary {
        name,
        pel_percent,
        error_rates,
        // RMSE = √(Σ e² / n)
        rmse_m: (errors_m.iter().map(|e| e * e).sum::<f64>() / count).sqrt(),
        bound_m: (bound_sum / count).sqrt(),
        axis_mse_m2: axis_sum.map(|s| s / count),
        errors_m,
        rmse_by_epoch: by_epoch
            .iter()
            .map(|&(sum, n)| (n > 0).then(|| (sum / n as f64).sqrt()))
            .collect(),
    })
}

/// One bin of true `|x|` (distance from the origin along x).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct DistanceBin {
    /// Lower edge, m.
    pub(super) lower_m: f64,
    /// Upper edge, m (`None`: unbounded).
    pub(super) upper_m: Option<f64>,
    /// (run, epoch) pairs whose truth falls in the bin.
    pub(super) count: usize,
    /// Mean x error rate of each method (fraction; `None` without a location in the bin).
    pub(super) rates: Vec<Option<f64>>,
    /// Mean |x error| of each method, m.
    pub(super) abs_errors_m: Vec<Option<f64>>,
}

/// Mean x error rate and mean |x error| of each method in each bin of true `|x|`.
pub(super) fn distance_bins(located: &Located, truth: &[[f64; 3]]) -> Result<Vec<DistanceBin>> {
    let mut bins = Vec::with_capacity(DISTANCE_BINS_M.len());
    for (b, &lower) in DISTANCE_BINS_M.iter().enumerate() {
        let upper = DISTANCE_BINS_M.get(b + 1).copied().unwrap_or(f64::INFINITY);
        let in_bin = |x: f64| (lower..upper).contains(&x.abs());
        let count = truth.iter().filter(|p| in_bin(p[0])).count() * located.first().map_or(0, Vec::len);
        let (mut rates, mut abs_errors) = (Vec::new(), Vec::new());
        for method in located {
            let (mut rate_sum, mut abs_sum, mut n) = (0.0, 0.0, 0usize);
            for run in method {
                for (estimate, actual) in run.iter().zip(truth) {
                    if let (Some(p), true) = (estimate, in_bin(actual[0]) && actual[0] != 0.0) {
                        rate_sum += error_rate(actual[0], Some(p[0]))?;
                        abs_sum += (p[0] - actual[0]).abs();
                        n += 1;
                    }
                }
            }
            let mean = |s: f64| (n > 0).then(|| s / n as f64);
            rates.push(mean(rate_sum));
            abs_errors.push(mean(abs_sum));
        }
        bins.push(DistanceBin {
            lower_m: lower,
            upper_m: DISTANCE_BINS_M.get(b + 1).copied(),
            count,
            rates,
            abs_errors_m: abs_errors,
        });
    }
    Ok(bins)
}

/// Outcome of the danger-zone alarm in one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct AlarmOutcome {
    /// `t_entry − t_alarm` of the warning (negative if it came after the entry), s; `None`
    /// when the entry was never alarmed.
    pub(super) lead_s: Option<f64>,
    /// Alarm episodes not related to the entry (raised and cleared outside the zone).
    pub(super) false_alarms: usize,
}

/// Alarm at each epoch: a CV extrapolation of the state `T, 2T, …, horizon` ahead lies in a
/// danger zone.
pub(super) fn alarms(walk: &MineWalk, states: &[TrackState], horizon_s: f64) -> Vec<bool> {
    let steps = (horizon_s / walk.period_s).round().max(1.0) as usize;
    states
        .iter()
        .map(|s| (1..=steps).any(|h| walk.layout.in_danger_zone(extrapolate(s, h as f64 * walk.period_s))))
        .collect()
}

/// Scores the alarms of one run. The warning is the alarm episode still raised at the last
/// epoch before the walker enters (its start gives the lead time); failing that, the first
/// episode while he is inside (a late warning, negative lead). Episodes overlapping the
/// epochs from the one before the entry to the last one inside belong to the entry; the rest
/// are false alarms.
pub(super) fn score_alarms(walk: &MineWalk, alarm: &[bool]) -> AlarmOutcome {
    let times: Vec<f64> = walk.setup.epochs.iter().map(|s| s.time_s).collect();
    let inside = &walk.setup.in_zone;
    // maximal runs of raised alarms: [start, end]
    let mut episodes = Vec::new();
    let mut start = None;
    for (k, &a) in alarm.iter().chain(std::iter::once(&false)).enumerate() {
        match (a, start) {
            (true, None) => start = Some(k),
            (false, Some(s)) => {
                episodes.push((s, k - 1));
                start = None;
            }
            _ => {}
        }
    }
    let (Some(entry_s), Some(first)) = (walk.entry_time_s, inside.iter().position(|&z| z)) else {
        return AlarmOutcome {
            lead_s: None,
            false_alarms: episodes.len(),
        };
    };
    let last = inside.iter().rposition(|&z| z).unwrap_or(first);
    let window = (first.saturating_sub(1), last);
    let related = |&(s, e): &(usize, usize)| s <= window.1 && e >= window.0;
    let warning = episodes
        .iter()
        .find(|&&(s, e)| first > 0 && s < first && e >= first - 1)
        .or_else(|| episodes.iter().find(|&&(s, _)| (first..=last).contains(&s)));
    AlarmOutcome {
        lead_s: warning.map(|&(s, _)| entry_s - times[s]),
        false_alarms: episodes.iter().filter(|e| !related(e)).count(),
    }
}

/// Alarm statistics of one tracker and horizon over all runs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct AlarmSummary {
    /// Share of runs warned before the entry, %.
    pub(super) warned_percent: f64,
    /// Mean lead time over the runs warned before the entry, s (`None` if none was).
    pub(super) mean_lead_s: Option<f64>,
    /// Mean number of false alarm episodes per run.
    pub(super) false_per_run: f64,
}

/// Scores every run's alarms for `states(run)` at `horizon_s`.
pub(super) fn alarm_summary(
    walk: &MineWalk,
    runs: &[Seed000Run],
    states: impl Fn(&Seed000Run) -> &[TrackState],
    horizon_s: f64,
) -> AlarmSummary {
    let outcomes: Vec<AlarmOutcome> = runs
        .iter()
        .map(|r| score_alarms(walk, &alarms(walk, states(r), horizon_s)))
        .collect();
    let timely: Vec<f64> = outcomes.iter().filter_map(|o| o.lead_s).filter(|&l| l > 0.0).collect();
    let n = outcomes.len().max(1) as f64;
    AlarmSummary {
        warned_percent: 100.0 * timely.len() as f64 / n,
        mean_lead_s: (!timely.is_empty()).then(|| timely.iter().sum::<f64>() / timely.len() as f64),
        false_per_run: outcomes.iter().map(|o| o.false_alarms as f64).sum::<f64>() / n,
    }
}

/// Shares (%) of the RSSI fixes by kind — multilateration, guided, centroid — and the number
/// of epochs in which readers heard the tag but DV-Hop found no fix.
pub(super) fn fix_breakdown(runs: &[Seed000Run]) -> ([f64; 3], usize) {
    let mut counts = [0usize; 3];
    let mut dv_hop_failures = 0;
    for run in runs {
        for ((fix, dv), &heard) in run.rssi.iter().zip(&run.dv_hop).zip(&run.heard) {
            if let Some(f) = fix {
                counts[match f.kind {
                    RssiFixKind::Multilateration => 0,
                    RssiFixKind::GuidedMultilateration => 1,
                    RssiFixKind::Centroid => 2,
                }] += 1;
            }
            if heard > 0 && dv.is_none() {
                dv_hop_failures += 1;
            }
        }
    }
    let total = counts.iter().sum::<usize>().max(1) as f64;
    (counts.map(|c| 100.0 * c as f64 / total), dv_hop_failures)
}

/// Per reader: `(mean innovation dB, count)` of our tracker's RSSI innovations over all runs.
pub(super) fn mean_innovations(runs: &[Seed000Run], readers: usize) -> Vec<(Option<f64>, usize)> {
    (0..readers)
        .map(|i| {
            let (sum, count) = runs.iter().fold((0.0, 0usize), |(s, c), r| {
                (s + r.innovations[i].sum_db, c + r.innovations[i].count)
            });
            ((count > 0).then(|| sum / count as f64), count)
        })
        .collect()
}

/// Figures of the runs the notes quote.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Extras {
    /// Mean readers hearing the tag per epoch outside the danger zone.
    pub(super) heard_mean: f64,
    /// Share of those epochs with ≥ 4 readers, %.
    pub(super) heard_four_percent: f64,
    /// Epochs the truth spends in a danger zone.
    pub(super) hole_epochs: usize,
    /// RMSE of each method inside / outside the danger zone (epochs with a location), m.
    pub(super) rmse_inside_m: Vec<Option<f64>>,
    /// RMSE of each method outside the danger zone, m.
    pub(super) rmse_outside_m: Vec<Option<f64>>,
    /// Mean signed x error of the RSSI fixes in the 5 epochs before the entry, m.
    pub(super) rssi_lag_m: Option<f64>,
    /// Median and largest per-run RMSE of the ME-KF and ours, m.
    pub(super) per_run_rmse_m: [(f64, f64); 2],
    /// Largest √PCRB over the epochs, m.
    pub(super) max_bound_m: f64,
}

/// Computes [`Extras`].
pub(super) fn extras(
    walk: &MineWalk,
    runs: &[Seed000Run],
    located: &Located,
    bounds: &[DMatrix<f64>],
) -> Result<Extras> {
    let truth = walk.setup.truth_m();
    let inside = &walk.setup.in_zone;
    let (mut heard_sum, mut heard_four, mut outside_epochs) = (0usize, 0usize, 0usize);
    for run in runs {
        for (&h, &z) in run.heard.iter().zip(inside) {
            if !z {
                heard_sum += h;
                heard_four += usize::from(h >= 4);
                outside_epochs += 1;
            }
        }
    }
    let split_rmse = |method: &Vec<Vec<Option<[f64; 3]>>>, want_inside: bool| -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for run in method {
            for ((estimate, actual), &z) in run.iter().zip(&truth).zip(inside) {
                if let (Some(p), true) = (estimate, z == want_inside) {
                    sum += distance_m(*p, *actual).powi(2);
                    n += 1;
                }
            }
        }
        (n > 0).then(|| (sum / n as f64).sqrt())
    };
    let entry = inside.iter().position(|&z| z);
    let rssi_lag_m = entry.and_then(|e| {
        let (mut sum, mut n) = (0.0, 0usize);
        for run in runs {
            let before = e.saturating_sub(5);
            for (fix, actual) in run.rssi[before..e].iter().zip(&truth[before..e]) {
                if let Some(f) = fix {
                    sum += f.position_m[0] - actual[0];
                    n += 1;
                }
            }
        }
        (n > 0).then(|| sum / n as f64)
    });
    let per_run = |states: &dyn Fn(&Seed000Run) -> &[TrackState]| -> (f64, f64) {
        let mut rmse: Vec<f64> = runs
            .iter()
            .map(|r| {
                let sum: f64 = states(r)
                    .iter()
                    .zip(&truth)
                    .map(|(s, t)| distance_m(position_of(s), *t).powi(2))
                    .sum();
                (sum / truth.len().max(1) as f64).sqrt()
            })
            .collect();
        rmse.sort_by(f64::total_cmp);
        (rmse[rmse.len() / 2], rmse[rmse.len() - 1])
    };
    let mut max_bound_m: f64 = 0.0;
    for b in bounds {
        max_bound_m = max_bound_m.max(rmse_bound(b, &POSITION_INDICES)?);
    }
    Ok(Extras {
        heard_mean: heard_sum as f64 / outside_epochs.max(1) as f64,
        heard_four_percent: 100.0 * heard_four as f64 / outside_epochs.max(1) as f64,
        hole_epochs: inside.iter().filter(|&&z| z).count(),
        rmse_inside_m: located.iter().map(|m| split_rmse(m, true)).collect(),
        rmse_outside_m: located.iter().map(|m| split_rmse(m, false)).collect(),
        rssi_lag_m,
        per_run_rmse_m: [per_run(&|r| &r.mekf), per_run(&|r| &r.ours)],
        max_bound_m,
    })
}

/// A reader with equipment next to it, as the obstacle analysis sees it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ObstacleReader {
    /// Its name.
    pub(super) name: String,
    /// The true obstacle loss, dB.
    pub(super) loss_db: f64,
    /// Our tracker's mean RSSI innovation at it, dB.
    pub(super) mean_innovation_db: f64,
    /// Whether that is the lowest of all readers.
    pub(super) lowest: bool,
}

/// The obstacle analysis: the readers with equipment next to them, and the median mean
/// innovation of the clear working readers (dB).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ObstacleAnalysis {
    pub(super) readers: Vec<ObstacleReader>,
    pub(super) clear_median_db: Option<f64>,
}

/// Computes the [`ObstacleAnalysis`] from the per-reader mean innovations.
pub(super) fn obstacles(walk: &MineWalk, innovations: &[(Option<f64>, usize)]) -> ObstacleAnalysis {
    let readers = walk.layout.readers();
    let lowest = innovations
        .iter()
        .enumerate()
        .filter_map(|(i, (m, _))| m.map(|m| (i, m)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i);
    let flagged = readers
        .iter()
        .zip(innovations)
        .enumerate()
        .filter(|(_, (r, _))| r.obstacle_loss_db > 0.0)
        .filter_map(|(i, (r, (m, _)))| {
            m.map(|m| ObstacleReader {
                name: r.name.clone(),
                loss_db: r.obstacle_loss_db,
                mean_innovation_db: m,
                lowest: lowest == Some(i),
            })
        })
        .collect();
    let mut clear: Vec<f64> = readers
        .iter()
        .zip(innovations)
        .filter(|(r, _)| r.obstacle_loss_db == 0.0)
        .filter_map(|(_, (m, _))| *m)
        .collect();
    clear.sort_by(f64::total_cmp);
    ObstacleAnalysis {
        readers: flagged,
        clear_median_db: (!clear.is_empty()).then(|| clear[clear.len() / 2]),
    }
}
