//! The three position estimators of the seed 003 reproduction, fed the same kind of cycle data
//! (timed sonar firings and their echoes):
//!
//! - least-squares multilateration per cycle (the paper's baseline, §2.4);
//! - the paper's single-observation EKF (§3.3): every echo updates the robot its sonar was
//!   aimed at;
//! - ours: the engine's multi-target tracker, [`AnonymousTracker`], with one seeded track per
//!   robot: each firing instant's echoes are one scan of anonymous ranges, each with its
//!   sonar's sector as field of view; χ² gating on the NIS, global nearest neighbour, and the
//!   engine's manoeuvre fallback (an echo outside every gate goes to the one track in the beam
//!   whose predicted range is within the manoeuvre margin of it, or the one that can have
//!   drifted that far).

use nalgebra::{DVector, Matrix2, Vector2};
use rtls_engine::association::{
    AnonymousTracker, AnonymousTrackerSettings, Association, Detection, DetectionFate, FieldOfView, ManoeuvreFallback,
};
use rtls_engine::lifecycle::LifecycleSettings;
use rtls_estimation::filter::{ExtendedKalmanFilter, Updated};
use rtls_estimation::measurement::{NoiseCovariance, Ranges};
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::{EstimationError, Gaussian};
use rtls_positioning::multilateration::{gauss_newton, two_range, GaussNewtonOptions, Initial};
use rtls_positioning::Fix2;

use super::schedule::Timed;
use crate::error::{Result, SimError};
use rtls_sim::sensors::ultrasonic::{Aim, Echo, SonarRing};

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
    /// The EKFs' motion model (continuous white acceleration of PSD `q`).
    pub motion: ConstantVelocity,
    /// `q` of `motion` (m²/s³), for the engine's tracker.
    pub acceleration_psd_m2ps3: f64,
    /// Range noise variance `σ²` the trackers assume (m²).
    pub range_variance_m2: f64,
    /// Association gate probability `P_G` (ours).
    pub gate_probability: f64,
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

/// Expected false echoes per firing per metre of range in ours' association: inside the echo
/// window only robots reflect (the simulated bed has no clutter), so an echo is left unassigned
/// only when no track can take it. With `λ = 10⁻⁶ /m` the price of an unassigned echo,
/// `c₀ = −2 ln λ − ln 2π + 2 ln P_D − 2 ln(1 − P_D P_G) ≈ 31`, exceeds any gated pairing's
/// `d² + ln |S| ≤ χ²₀.₉₉(1) + ln S ≈ 6.6 − 4` by far: the assignment takes as many echoes as
/// the gates allow, then the most likely pairing.
const ECHO_CLUTTER_DENSITY_PER_M: f64 = 1e-6;

/// A time no track of a run reaches without an update (s): the robots stay on the bed, so their
/// tracks are never lost or deleted.
const NEVER_S: f64 = 1e9;

/// One of the three estimators, holding every robot's estimate.
#[derive(Debug, Clone)]
pub(crate) enum Tracker {
    /// Least-squares fix per cycle; the last fix per robot (m).
    LeastSquares(Vec<[f64; 2]>),
    /// The paper's EKF per robot (`[x, vx, y, vy]`): every echo updates the robot its sonar was
    /// aimed at.
    PaperEkf(Vec<Gaussian<4>>),
    /// Ours: the engine's anonymous multi-target tracker, track `robot-<i>` for robot `i`
    /// (seeded, never deleted, so track `i` is robot `i`).
    Engine(Box<AnonymousTracker>),
}

impl Tracker {
    /// Ours: the engine's [`AnonymousTracker`] with a confirmed track `robot-<i>` seeded at each
    /// robot's initial estimate: GNN, the CV model with continuous white acceleration `q`, the χ²
    /// gate `P_G`, the sonar's `P_D`, [`ECHO_CLUTTER_DENSITY_PER_M`], the manoeuvre fallback, and
    /// tracks never lost ([`NEVER_S`]).
    ///
    /// # Errors
    /// As [`SimError::from_engine`], for settings the engine rejects.
    pub fn engine(settings: &TrackerSettings, sonar: &SonarRing, initial: &[Gaussian<4>]) -> Result<Self> {
        let engine_settings = AnonymousTrackerSettings {
            association: Association::Gnn,
            acceleration_psd_m2ps3: Some(settings.acceleration_psd_m2ps3),
            gate_probability: settings.gate_probability,
            detection_probability: sonar.detection_probability,
            range_clutter_density_per_m: ECHO_CLUTTER_DENSITY_PER_M,
            lifecycle: LifecycleSettings {
                confirm_updates: 1,
                confirm_window_s: 0.0,
                coast_timeout_s: NEVER_S,
                delete_timeout_s: NEVER_S,
            },
            manoeuvre: Some(ManoeuvreFallback {
                margin_m: settings.manoeuvre_margin_m,
                velocity_std_mps: settings.manoeuvre_velocity_std_mps,
                speed_change_mps: settings.manoeuvre_speed_change_mps,
            }),
            ..AnonymousTrackerSettings::default()
        };
        let mut tracker = AnonymousTracker::new(engine_settings).map_err(SimError::from_engine)?;
        for (robot, state) in initial.iter().enumerate() {
            tracker
                .seed_track(format!("robot-{robot}"), *state)
                .map_err(SimError::from_engine)?;
        }
        Ok(Self::Engine(Box::new(tracker)))
    }

    /// Every robot's position estimate at `time_s` (m): the EKF mean predicted to that time
    /// (not before its state), or the last LS fix.
    pub fn positions_at(&self, settings: &TrackerSettings, time_s: f64) -> Result<Vec<[f64; 2]>> {
        match self {
            Self::LeastSquares(fixes) => Ok(fixes.clone()),
            Self::PaperEkf(tracks) => tracks
                .iter()
                .map(|track| {
                    let predicted = predict(track, settings, time_s)?;
                    Ok(position(&predicted))
                })
                .collect(),
            Self::Engine(tracker) => {
                let time_s = tracker.last_scan_s().map_or(time_s, |last| time_s.max(last));
                let predicted = tracker.predict_tracks(time_s).map_err(SimError::from_engine)?;
                Ok(predicted.iter().map(position).collect())
            }
        }
    }

    /// Processes one cycle's observations (sorted by firing time); the observations fired at
    /// one instant (in different cells) form one group.
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
        if let Self::LeastSquares(fixes) = self {
            least_squares_cycle(fixes, settings, nodes_m, observations, &mut outcome)?;
            return Ok(outcome);
        }
        let mut start = 0;
        while start < observations.len() {
            let time_s = observations[start].timed.time_s;
            let end = start
                + observations[start..]
                    .iter()
                    .take_while(|o| o.timed.time_s == time_s)
                    .count();
            match self {
                Self::LeastSquares(_) => {}
                Self::PaperEkf(tracks) => {
                    for i in start..end {
                        paper_update(tracks, settings, nodes_m, observations, i, &mut outcome)?;
                    }
                }
                Self::Engine(tracker) => {
                    engine_scan(
                        tracker,
                        settings,
                        sonar,
                        nodes_m,
                        observations,
                        start..end,
                        &mut outcome,
                    )?;
                }
            }
            start = end;
        }
        Ok(outcome)
    }
}

/// The sector of a firing as the engine's field of view: from the start of the first fired
/// sonar's sector to the end of the last one's (the union of adjacent sectors; the hull, were
/// there gaps between narrower sectors), widened by `margin_rad` on each side, out to the echo
/// window's range.
///
/// # Errors
/// As [`SimError::from_engine`], for a sector the engine rejects (a zero width).
fn field_of_view(sonar: &SonarRing, aim: Aim, margin_rad: f64) -> Result<FieldOfView> {
    let spacing_rad = std::f64::consts::TAU / sonar.sonars as f64;
    // [θ₀, θ₁] = [k s, (k + c − 1) s + w]
    let start_rad = aim.first as f64 * spacing_rad;
    let end_rad = (aim.first + aim.count.max(1) - 1) as f64 * spacing_rad + sonar.sector_width_deg.to_radians();
    let half_width_rad = (0.5 * (end_rad - start_rad) + margin_rad).min(std::f64::consts::PI);
    FieldOfView::new(0.5 * (start_rad + end_rad), half_width_rad, sonar.max_range_m()).map_err(SimError::from_engine)
}

/// Ours: the echoes of observations `group` (one firing instant) as one scan of the engine's
/// tracker: each echo a [`Detection::range`] from its node with its sonar's sector as field of
/// view. The scan time is the mean of the firings' time stamps (the nodes' clocks, which differ
/// by the sync error: well under a millisecond, a tenth of a millimetre at 0.5 m/s), kept from
/// going back before the previous scan. The scan report gives each echo's robot (`Assigned`, or
/// `Manoeuvre`: outside every gate, given by the fallback — counted as `sole_candidate`), the
/// unused echoes (`gated_out`), the ambiguous ones and the singular pairs.
fn engine_scan(
    tracker: &mut AnonymousTracker,
    settings: &TrackerSettings,
    sonar: &SonarRing,
    nodes_m: &[[f64; 2]],
    observations: &[Observation],
    group: std::ops::Range<usize>,
    outcome: &mut CycleOutcome,
) -> Result<()> {
    let mut echoes: Vec<usize> = Vec::new();
    let mut detections: Vec<Detection> = Vec::new();
    let mut stamps_s = 0.0;
    for i in group {
        let Observation { timed, stamp_s, echo } = observations[i];
        let Some(echo) = echo else { continue };
        let view = field_of_view(sonar, timed.request.aim, settings.sector_margin_rad)?;
        let detection = Detection::range(nodes_m[timed.request.node], echo.range_m, settings.range_variance_m2)
            .and_then(|d| d.within(view))
            .map_err(SimError::from_engine)?;
        echoes.push(i);
        detections.push(detection);
        stamps_s += stamp_s;
    }
    if echoes.is_empty() {
        return Ok(());
    }
    let mean_stamp_s = stamps_s / echoes.len() as f64;
    let time_s = tracker
        .last_scan_s()
        .map_or(mean_stamp_s, |last| mean_stamp_s.max(last));
    let report = tracker
        .process_scan(time_s, &detections)
        .map_err(SimError::from_engine)?;
    for (&i, detection) in echoes.iter().zip(&report.detections) {
        let (track, manoeuvre) = match &detection.fate {
            DetectionFate::Assigned { track } => (track, false),
            DetectionFate::Manoeuvre { track } => (track, true),
            DetectionFate::Weighted { .. } | DetectionFate::StartedTrack { .. } | DetectionFate::UnusedRange => {
                outcome.gated_out += 1;
                continue;
            }
        };
        let robot = tracker
            .tracks()
            .iter()
            .position(|t| t.id() == &**track)
            .ok_or(SimError::EmptyInput {
                what: "the engine's track of an assigned echo",
            })?;
        outcome.used_by[i] = Some(robot);
        outcome.sole_candidate += usize::from(manoeuvre);
        let timed = observations[i].timed;
        outcome.latencies_s.push(timed.arrival_s - timed.time_s);
    }
    outcome.ambiguous += report.manoeuvre_ambiguous;
    outcome.singular += report.singular_pairs;
    Ok(())
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
