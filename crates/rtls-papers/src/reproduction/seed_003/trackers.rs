//! The three position estimators of the seed 003 reproduction, fed the same kind of cycle data
//! (timed sonar firings and their echoes):
//!
//! - least-squares multilateration per cycle (the paper's baseline, §2.4);
//! - the paper's single-observation EKF (§3.3): every echo updates the robot its sonar was
//!   aimed at;
//! - ours: the same EKF per robot, each echo assigned to the track whose predicted range it
//!   matches (χ² gate on the NIS, global nearest neighbour over the echoes of one instant); an
//!   echo no track gates goes to the one track in the beam whose predicted range is within the
//!   manoeuvre margin of it, if there is exactly one (a manoeuvre, not another robot).

use nalgebra::{DVector, Matrix2, Vector2};
use rtls_engine::association::{solve_assignment, CostMatrix};
use rtls_estimation::filter::{ExtendedKalmanFilter, Updated};
use rtls_estimation::measurement::{NoiseCovariance, Ranges};
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::stats::ChiSquareGate;
use rtls_estimation::{EstimationError, Gaussian};
use rtls_positioning::multilateration::{gauss_newton, two_range, GaussNewtonOptions, Initial};
use rtls_positioning::Fix2;

use super::schedule::Timed;
use crate::error::{Result, SimError};
use rtls_sim::sensors::ultrasonic::{Echo, SonarRing};

/// A firing of this cycle with its echo, as the base station sees it (plus the simulation's
/// truth about who reflected it, in `echo.source`, used only for counting).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Observation {
    /// The timed firing (true firing time; its slot identifies the firing instant).
    pub timed: Timed,
    /// The firing's time stamp by the node's clock (s): the time the EKFs use.
    pub stamp_s: f64,
    /// The accepted echo, if any (its range counted on the node's clock).
    pub echo: Option<Echo>,
}

/// What a tracker did with one cycle.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct CycleOutcome {
    /// For each observation of the cycle (same order), the robot whose estimate used it.
    pub used_by: Vec<Option<usize>>,
    /// Latency (s) from firing to the estimate it produced: per EKF update, arrival − firing;
    /// per LS fix, arrival of its last report − its first firing.
    pub latencies_s: Vec<f64>,
    /// LS fixes from ≥ 3 ranges (Gauss–Newton), from 2 ranges (two-range), and robots left
    /// without a fix (fewer than 2 ranges or a solver failure).
    pub ls_fixes: [usize; 3],
    /// Echoes an association gate rejected for every track.
    pub gated_out: usize,
    /// Echoes outside every gate given to the only track in the beam (ours).
    pub sole_candidate: usize,
    /// Echoes outside every gate that several tracks could have made after a manoeuvre
    /// (dropped: which one manoeuvred is unknown), ours.
    pub ambiguous: usize,
    /// EKF updates skipped because a track sat on the firing node (undefined direction).
    pub singular: usize,
}

/// Parameters shared by the trackers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrackerSettings {
    /// The EKFs' motion model.
    pub motion: ConstantVelocity,
    /// Range noise variance `σ²` the trackers assume (m²).
    pub range_variance_m2: f64,
    /// Association gate (ours).
    pub gate: ChiSquareGate,
    /// Association widens each sonar sector by this much on each side (rad).
    pub sector_margin_rad: f64,
    /// Largest range innovation a manoeuvring track may show (m).
    pub manoeuvre_margin_m: f64,
    /// Velocity uncertainty per axis re-opened on a track found manoeuvring (m/s).
    pub manoeuvre_velocity_std_mps: f64,
    /// Largest velocity change a robot makes (m/s): bounds how far a track updated `Δt` ago
    /// can have drifted, `|Δv| Δt`.
    pub manoeuvre_speed_change_mps: f64,
}

/// One of the three estimators, holding every robot's estimate.
#[derive(Debug, Clone)]
pub(crate) enum Tracker {
    /// Least-squares fix per cycle; the last fix per robot (m).
    LeastSquares(Vec<[f64; 2]>),
    /// EKF per robot; `associate` selects ours (gated GNN) over the paper's (echo = robot).
    Ekf {
        /// Track states `[x, vx, y, vy]`.
        tracks: Vec<Gaussian<4>>,
        /// Whether echoes are associated by gate and GNN.
        associate: bool,
    },
}

impl Tracker {
    /// Every robot's position estimate at `time_s` (m): the EKF mean predicted to that time,
    /// or the last LS fix.
    pub fn positions_at(&self, settings: &TrackerSettings, time_s: f64) -> Result<Vec<[f64; 2]>> {
        match self {
            Self::LeastSquares(fixes) => Ok(fixes.clone()),
            Self::Ekf { tracks, .. } => tracks
                .iter()
                .map(|track| {
                    let predicted = predict(track, settings, time_s)?;
                    Ok(position(&predicted))
                })
                .collect(),
        }
    }

    /// Processes one cycle's observations (sorted by firing time).
    pub fn process(
        &mut self,
        settings: &TrackerSettings,
        sonar: &SonarRing,
        nodes_m: &[[f64; 2]],
        observations: &[Observation],
    ) -> Result<CycleOutcome> {
        let mut outcome = CycleOutcome {
            used_by: vec![None; observations.len()],
            ..CycleOutcome::default()
        };
        match self {
            Self::LeastSquares(fixes) => least_squares_cycle(fixes, settings, nodes_m, observations, &mut outcome),
            Self::Ekf { tracks, associate } => {
                // observations fired at one instant (different cells) form one group
                let mut start = 0;
                while start < observations.len() {
                    let time_s = observations[start].timed.time_s;
                    let end = start
                        + observations[start..]
                            .iter()
                            .take_while(|o| o.timed.time_s == time_s)
                            .count();
                    if *associate {
                        associate_group(tracks, settings, sonar, nodes_m, observations, start..end, &mut outcome)?;
                    } else {
                        for i in start..end {
                            paper_update(tracks, settings, nodes_m, observations, i, &mut outcome)?;
                        }
                    }
                    start = end;
                }
                Ok(())
            }
        }?;
        Ok(outcome)
    }
}

/// `[x, y]` of a `[x, vx, y, vy]` state.
pub(crate) fn position(state: &Gaussian<4>) -> [f64; 2] {
    [state.mean()[0], state.mean()[2]]
}

/// The state predicted to `time_s` (unchanged if it is already there).
fn predict(state: &Gaussian<4>, settings: &TrackerSettings, time_s: f64) -> Result<Gaussian<4>> {
    ExtendedKalmanFilter::default()
        .predict(state, &settings.motion, time_s.max(state.time_s()))
        .map_err(SimError::estimation(time_s))
}

/// The single-range EKF update of `prior` with range `range_m` to the node at `node_m`
/// (seed 003 eq. (6)–(9)); `None` when the prior sits on the node.
fn range_update(
    prior: &Gaussian<4>,
    settings: &TrackerSettings,
    node_m: [f64; 2],
    range_m: f64,
) -> Result<Option<Updated<4>>> {
    let time_s = prior.time_s();
    let noise = NoiseCovariance::isotropic(1, settings.range_variance_m2).map_err(SimError::estimation(time_s))?;
    let model = Ranges::planar(&[node_m], noise).map_err(SimError::estimation(time_s))?;
    // d = ‖p − a‖, H = [(x − xa)/d, 0, (y − ya)/d, 0]; ν = z − d; S = H P Hᵀ + R; K = P Hᵀ S⁻¹
    match ExtendedKalmanFilter::default().update(prior, &model, &DVector::from_element(1, range_m)) {
        Ok(updated) => Ok(Some(updated)),
        Err(EstimationError::SingularMeasurement { .. }) => Ok(None),
        Err(e) => Err(SimError::estimation(time_s)(e)),
    }
}

/// The paper's EKF: the echo of observation `i` updates the robot the sonar was aimed at.
fn paper_update(
    tracks: &mut [Gaussian<4>],
    settings: &TrackerSettings,
    nodes_m: &[[f64; 2]],
    observations: &[Observation],
    i: usize,
    outcome: &mut CycleOutcome,
) -> Result<()> {
    let Observation { timed, stamp_s, echo } = observations[i];
    let Some(echo) = echo else { return Ok(()) };
    let robot = timed.request.robot;
    let prior = predict(&tracks[robot], settings, stamp_s)?;
    match range_update(&prior, settings, nodes_m[timed.request.node], echo.range_m)? {
        Some(updated) => {
            tracks[robot] = updated.state;
            outcome.used_by[i] = Some(robot);
            outcome.latencies_s.push(timed.arrival_s - timed.time_s);
        }
        None => {
            tracks[robot] = prior;
            outcome.singular += 1;
        }
    }
    Ok(())
}

/// Ours: the echoes of observations `group` (one firing instant) are assigned to tracks by
/// global nearest neighbour. A track is a candidate for an echo if its prediction lies in the
/// sonar's beam (its sector(s) widened by the margin, its predicted range within 3 σ of the
/// echo window's); a candidate inside the χ² gate `νᵀ S⁻¹ ν ≤ γ` costs `νᵀ S⁻¹ ν + ln |S|` (the
/// negative log-likelihood up to a constant). When no candidate passes the gate and exactly
/// one candidate's range innovation is within the manoeuvre margin (`|ν| ≤ m`), that track
/// may still take the echo, at a cost above any gated pairing: only robots reflect inside the
/// echo window, so the echo is that robot's, and a gate failure means it manoeuvred (a 90° turn
/// at 0.5 m/s leaves the CV prediction 10–20 cm off within a cycle); its velocity is then
/// re-opened before the update, `P⁻ += diag(0, σ_m², 0, σ_m²)`, so that the range can correct a
/// velocity the CV model still holds from before the turn. The assignment maximises the number
/// of assigned echoes, then minimises the total cost. Unassigned echoes are dropped, among them
/// the echoes outside every gate for which several tracks are within the manoeuvre margin
/// (counted as ambiguous: one of them manoeuvred, but which one is unknown).
fn associate_group(
    tracks: &mut [Gaussian<4>],
    settings: &TrackerSettings,
    sonar: &SonarRing,
    nodes_m: &[[f64; 2]],
    observations: &[Observation],
    group: std::ops::Range<usize>,
    outcome: &mut CycleOutcome,
) -> Result<()> {
    /// Cost added to a pairing outside the gate, above any gated cost.
    const UNGATED_COST: f64 = 1e6;
    let Some(first) = observations.get(group.start) else {
        return Ok(());
    };
    let threshold = settings
        .gate
        .threshold(1)
        .map_err(SimError::estimation(first.stamp_s))?;
    // candidates[e] = (track, cost, updated) for the tracks that may take echo e
    let mut echoes: Vec<usize> = Vec::new();
    let mut candidates: Vec<Vec<(usize, f64, Updated<4>)>> = Vec::new();
    for i in group {
        let Observation { timed, stamp_s, echo } = observations[i];
        let Some(echo) = echo else { continue };
        // every track predicted to the echo's time stamp (the nodes' clocks differ slightly)
        let time_s = stamp_s;
        let priors = tracks
            .iter()
            .map(|track| predict(track, settings, time_s))
            .collect::<Result<Vec<_>>>()?;
        let node_m = nodes_m[timed.request.node];
        // the tracks that can be in the beam: inside the aimed sector(s) (widened by the margin)
        // and not beyond the echo window's range by more than 3 σ of the predicted range
        let mut in_beam = Vec::new();
        for (track, prior) in priors.iter().enumerate() {
            if !sonar.in_aim(node_m, timed.request.aim, position(prior), settings.sector_margin_rad) {
                continue;
            }
            let Some(updated) = range_update(prior, settings, node_m, echo.range_m)? else {
                outcome.singular += 1;
                continue;
            };
            // predicted range d̂ = z − ν, its σ = √S
            let predicted_m = echo.range_m - updated.innovation[0];
            let sigma_m = updated.innovation_covariance[(0, 0)].max(0.0).sqrt();
            if predicted_m - 3.0 * sigma_m <= sonar.max_range_m() {
                in_beam.push((track, updated));
            }
        }
        let plausible: Vec<usize> = in_beam
            .iter()
            .filter(|(_, u)| u.innovation[0].abs() <= settings.manoeuvre_margin_m)
            .map(|(track, _)| *track)
            .collect();
        let any_gated = in_beam.iter().any(|(_, u)| u.nis <= threshold);
        // of several plausible tracks, those that can have drifted that far since their last
        // update: |ν| ≤ 3 √S + |Δv|max (t − t_last), the CV prediction's drift after any
        // velocity change since then
        let reachable: Vec<usize> = in_beam
            .iter()
            .filter(|(track, u)| {
                let since_update_s = (time_s - tracks[*track].time_s()).max(0.0);
                let sigma_m = u.innovation_covariance[(0, 0)].max(0.0).sqrt();
                let drift_m = 3.0 * sigma_m + settings.manoeuvre_speed_change_mps * since_update_s;
                plausible.contains(track) && u.innovation[0].abs() <= drift_m
            })
            .map(|(track, _)| *track)
            .collect();
        // the track that may take the echo as a manoeuvre: the only plausible one, or else the
        // only one that can have drifted that far; otherwise one of them has manoeuvred but
        // which is unknown: dropped
        let manoeuvring = match (plausible.as_slice(), reachable.as_slice()) {
            ([only], _) | (_, [only]) => Some(*only),
            _ => None,
        };
        outcome.ambiguous += usize::from(manoeuvring.is_none() && plausible.len() > 1 && !any_gated);
        let mut gated = Vec::new();
        for (track, updated) in in_beam {
            // gate: νᵀ S⁻¹ ν ≤ γ; cost = νᵀ S⁻¹ ν + ln |S|
            let cost = updated.nis + updated.log_det_innovation_covariance;
            if updated.nis <= threshold {
                gated.push((track, cost, updated));
            } else if manoeuvring == Some(track) {
                // manoeuvre: P⁻ += diag(0, σ_m², 0, σ_m²), then the range update
                let mut covariance = *priors[track].covariance();
                let opened = settings.manoeuvre_velocity_std_mps.powi(2);
                covariance[(1, 1)] += opened;
                covariance[(3, 3)] += opened;
                let prior = Gaussian::new(*priors[track].mean(), covariance, priors[track].time_s())
                    .map_err(SimError::estimation(time_s))?;
                if let Some(updated) = range_update(&prior, settings, node_m, echo.range_m)? {
                    gated.push((track, UNGATED_COST + cost, updated));
                }
            }
        }
        echoes.push(i);
        candidates.push(gated);
    }
    let costs: Vec<Vec<(usize, f64)>> = candidates
        .iter()
        .map(|echo| echo.iter().map(|(track, cost, _)| (*track, *cost)).collect())
        .collect();
    let assignment = best_assignment(&costs, tracks.len())?;
    for (k, (&i, choice)) in echoes.iter().zip(&assignment).enumerate() {
        match choice {
            Some(c) => {
                let (track, cost, updated) = &candidates[k][*c];
                tracks[*track] = updated.state;
                outcome.used_by[i] = Some(*track);
                outcome.sole_candidate += usize::from(*cost >= UNGATED_COST);
                let timed = observations[i].timed;
                outcome.latencies_s.push(timed.arrival_s - timed.time_s);
            }
            None => outcome.gated_out += 1,
        }
    }
    Ok(())
}

/// The assignment of echoes to distinct tracks (index into each echo's `(track, cost)`
/// candidate list, or `None`) with the most assigned echoes and, among those, the least total cost: the engine's
/// [`solve_assignment`] with echo rows, track columns (pairs without a candidate forbidden) and
/// one non-assignment cost `c₀` for every echo, larger than any difference between the costs of
/// two assignments, `c₀ = 1 + 2 Σₑ maxₜ |cₑₜ|`, so that assigning one more echo always pays.
/// Ties are broken by the echoes' order (firing order), i.e. by the data alone.
fn best_assignment(candidates: &[Vec<(usize, f64)>], tracks: usize) -> Result<Vec<Option<usize>>> {
    let mut costs = CostMatrix::forbidden(candidates.len(), tracks).map_err(SimError::from_engine)?;
    let mut largest_sum = 0.0;
    for (e, echo) in candidates.iter().enumerate() {
        let mut largest: f64 = 0.0;
        for &(track, cost) in echo {
            costs.set(e, track, cost).map_err(SimError::from_engine)?;
            largest = largest.max(cost.abs());
        }
        largest_sum += largest;
    }
    // c₀ > Σ cost(assignment with k + 1 echoes) − Σ cost(assignment with k echoes)
    let non_assignment = vec![1.0 + 2.0 * largest_sum; candidates.len()];
    let assignment = solve_assignment(&costs, &non_assignment).map_err(SimError::from_engine)?;
    Ok(assignment
        .row_to_column
        .iter()
        .zip(candidates)
        .map(|(column, echo)| column.and_then(|track| echo.iter().position(|&(t, _)| t == track)))
        .collect())
}

/// The paper's baseline: per robot, the ranges of the firings aimed at it this cycle give a
/// fix — Gauss–Newton least squares from ≥ 3 ranges (started from the linear LS fix, or from
/// the previous fix when the nodes are collinear), the two-range fix with 2 (the candidate
/// nearer the previous fix); with fewer, the previous fix is kept.
fn least_squares_cycle(
    fixes: &mut [[f64; 2]],
    settings: &TrackerSettings,
    nodes_m: &[[f64; 2]],
    observations: &[Observation],
    outcome: &mut CycleOutcome,
) -> Result<()> {
    let options = GaussNewtonOptions::default();
    for (robot, fix) in fixes.iter_mut().enumerate() {
        let used: Vec<usize> = (0..observations.len())
            .filter(|&i| observations[i].timed.request.robot == robot && observations[i].echo.is_some())
            .collect();
        let anchors: Vec<[f64; 2]> = used
            .iter()
            .map(|&i| nodes_m[observations[i].timed.request.node])
            .collect();
        let ranges: Vec<f64> = used
            .iter()
            .filter_map(|&i| observations[i].echo.map(|e| e.range_m))
            .collect();
        let variances = vec![settings.range_variance_m2; ranges.len()];
        let previous = Vector2::from(*fix);
        let solved = match ranges.len() {
            0 | 1 => None,
            2 => {
                let prior = Fix2 {
                    position: previous,
                    covariance: Matrix2::identity(),
                };
                two_range(
                    &[anchors[0], anchors[1]],
                    &[ranges[0], ranges[1]],
                    &[variances[0]; 2],
                    Some(&prior),
                )
                .ok()
                .map(|s| (s.fix.position, 1))
            }
            _ => gauss_newton(&anchors, &ranges, &variances, Initial::Linear, &options)
                .or_else(|_| gauss_newton(&anchors, &ranges, &variances, Initial::Guess(previous), &options))
                .ok()
                .map(|s| (s.fix.position, 0)),
        };
        match solved {
            Some((p, kind)) => {
                *fix = [p.x, p.y];
                outcome.ls_fixes[kind] += 1;
                for &i in &used {
                    outcome.used_by[i] = Some(robot);
                }
                // the fix exists once its last report is in; its oldest range is its first firing
                let first_s = used
                    .iter()
                    .map(|&i| observations[i].timed.time_s)
                    .fold(f64::INFINITY, f64::min);
                let last_s = used
                    .iter()
                    .map(|&i| observations[i].timed.arrival_s)
                    .fold(0.0, f64::max);
                outcome.latencies_s.push(last_s - first_s);
            }
            None => outcome.ls_fixes[2] += 1,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
