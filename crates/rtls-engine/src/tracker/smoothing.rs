//! A smoothed history: the Rauch–Tung–Striebel fixed-interval smoother over each track's
//! reported states, for a recording tracked after the fact (`rtls track --smooth`).
//!
//! The tracker is causal: a state at `tₖ` knows the measurements up to `tₖ`. A replay, a report
//! or an evaluation knows the later ones too, and the smoother lets them correct the past:
//! ```text
//! x⁻ₖ₊₁ = F(Δt) x̂ₖ|ₖ            P⁻ₖ₊₁ = F Pₖ|ₖ Fᵀ + Q(Δt)      (the site's CV model, q = σ_a²)
//! Gₖ    = Pₖ|ₖ Fᵀ (P⁻ₖ₊₁)⁻¹
//! x̂ₖ|ₙ  = x̂ₖ|ₖ + Gₖ (x̂ₖ₊₁|ₙ − x⁻ₖ₊₁)
//! Pₖ|ₙ  = Pₖ|ₖ + Gₖ (Pₖ₊₁|ₙ − P⁻ₖ₊₁) Gₖᵀ
//! ```
//! ([`rtls_estimation::filter::KalmanFilter::smooth`], golden-tested against FilterPy's
//! `rts_smoother`). `Pₖ|ₙ` is the error covariance only if what the past and the future
//! measurements say have independent errors; recorded fixes have errors that persist for
//! seconds (multipath, a BLE fade), and on the shared recordings `Pₖ|ₙ`'s 95 % ellipses held the
//! truth 67–90 % of the time (means per configuration, docs/EVALUATION.md). The covariance
//! reported is therefore a covariance-intersection bound over the position axes
//! ([`rtls_estimation::smoother::marginal_intersection_bound`]): what the past (`Pₖ|ₖ`) and
//! what the future (the information `Pₖ|ₙ⁻¹ − Pₖ|ₖ⁻¹` the backward pass added) each say about
//! the *position*, fused for any correlation between their errors. It lies between `Pₖ|ₙ` and,
//! in trace, `Pₖ|ₖ`, equals `Pₖ|ₖ` at a track's newest state and wherever the future says as
//! much about the position as the past, and is smaller where the future knows more (after a
//! track's start). The bound over the whole state (`intersection_bound`, used before
//! 2026-11-29) also trusted the two sides' velocities and their correlations with the position,
//! mirror images of each other, as independent evidence; an error that persists for seconds
//! (UWB geometry) is shared by both, and its ellipses held the truth 84–91 % of the time on
//! the UWB recordings where the filtered ones held it 92–99.7 % (docs/EVALUATION.md).
//! state. The filtered states `x̂ₖ|ₖ, Pₖ|ₖ` are the tracker's own, as reported: after its
//! adaptive measurement noise, gating, constraints and covariance fading. The prediction
//! between them is the site's constant-velocity model; where the tracker predicted otherwise
//! (an accelerometer's control input, the IMM's mode mixing) the smoother is an approximation
//! of the exact one, never of a different track.
//!
//! The smoothed *means* come from a smoother that fits its own noise to each segment
//! ([`rtls_estimation::smoother::tuned_smooth`]): what each tracker update added is kept in
//! information form (`J = P⁺⁻¹ − P⁻⁻¹`, `j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻`, [`ReportedState::information`]),
//! and the segment is re-filtered from it with the CV intensity `q` and the noise scale `c` of
//! the largest innovation likelihood (a grid around the site's `q`), then smoothed. A tracker's
//! `σ_a` is set to follow a turn now; a smoother can average over a longer window where the
//! track shows a steady walk (BLE path loss: 1.82 → 1.65 m, docs/EVALUATION.md). Segments of
//! fewer than [`FIT_STATES_MIN`] measured states, and those whose updates told more than their
//! information in the CV layout says (updates correlated with the heading's drift or a range
//! offset, predicted with an accelerometer's control input, the IMM's mixtures, states a
//! constraint moved — silent readers, the corridors, the speed limit:
//! [`ReportedState::partial_information`]), are smoothed
//! with the site's model over the tracker's states as above. The reported covariance is the
//! bound above either way (the fitted model assumes white errors and its own covariances are
//! overconfident on recorded data), except where the updates told more than the CV layout
//! holds: there the backward pass is not the tracker's model, what it says the future knows is
//! not credited, and the filtered covariance `Pₖ|ₖ` is reported (the labyrinth's UWB +
//! odometry: the bound's ellipses held the truth 78.9 % of the time, `Pₖ|ₖ`'s 98.7 %,
//! docs/EVALUATION.md).
//!
//! A track with the turn rate as a state (`motion_model = "ct"`) keeps its whole state
//! `[x, vx, y, vy, ω]` with each update ([`ReportedState::turn`]); its segments are smoothed
//! with the tracker's own coordinated turn (the extended RTS smoother linearised at each
//! filtered state), not the CV model, which would cut every arc short (seed 001's turn: 0.383 m
//! filtered, 0.168 m smoothed, docs/EVALUATION.md), with the same covariance bound.
//!
//! A smoother does not cross a (re)start of the track from a fix (first fix, re-acquisition,
//! a jump) nor a track created again after its deletion (each a new
//! [`ReportedState::segment`]); a revised update replaces the updates of its
//! tag at and after its time; updates without a state behind them (a lost track's frozen
//! position, anonymous tracks) pass unchanged. A segment whose backward pass fails numerically
//! keeps its filtered updates and is reported in [`SmoothedTracks::failures`].
//!
//! # Memory
//! The whole history is held until [`Smoother::finish`]: about 1.3 kB per track update
//! (`rtls track --smooth` on LIAS's fast run, 40 443 updates: peak resident memory 61 MB
//! against 11 MB without smoothing; 1.4 s against 0.6 s).
//!
//! # References
//! Rauch, Tung, Striebel (1965), "Maximum likelihood estimates of linear dynamic systems",
//! AIAA J. 3(8); Bar-Shalom, Li, Kirubarajan (2001) §8.6.

use std::collections::HashMap;
use std::sync::Arc;

use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::motion::{ConstantVelocity, CoordinatedTurnWithRate};
use rtls_estimation::smoother::{marginal_intersection_bound, tuned_smooth, InformationStep, NoiseFit};
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::alarms::position_of;
use super::output::{Output, ReportedState, TrackUpdate};

/// Collects a run's track updates with the states behind them, then smooths each track.
///
/// # Example
/// ```
/// use rtls_engine::record::{Measurement, Record};
/// use rtls_engine::site::Site;
/// use rtls_engine::tracker::{Output, Tracker};
///
/// let site = Site::from_toml_str(r#"
///     [[readers]]
///     id = "A"
///     position_m = [0.0, 0.0]
///     technology = "uwb"
///     radio = { range = { range_std_m = 0.1, bias_m = 0.0 } }
///     [tracker]
///     acceleration_noise_std_mps2 = 0.5
/// "#, "site.toml")?;
/// let mut tracker = Tracker::new(&site)?;
/// let mut smoother = tracker.smoother();
/// let mut out = Output::keeping_states();
/// for k in 0..20 {
///     let t = f64::from(k) * 0.5;
///     let x = 0.8 * t + if k % 2 == 0 { 0.3 } else { -0.3 };
///     let fix = Measurement::Fix { position_m: vec![x, 0.0], covariance_m2: vec![0.25, 0.0, 0.0, 0.25] };
///     tracker.push(Record { time_s: t, tag: "w1".into(), measurement: fix }, &mut out)?;
///     smoother.take(&out);
///     out.clear();
/// }
/// tracker.finish(&mut out)?;
/// smoother.take(&out);
/// let smoothed = smoother.finish();
/// assert!(smoothed.failures.is_empty());
/// assert!(smoothed.updates.iter().all(|u| u.smoothed));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct Smoother {
    kf: KalmanFilter,
    motion: ConstantVelocity,
    /// The site's `q = σ_a²`, m²/s³: the centre of the tuned smoother's grid.
    q_mps2: f64,
    tag_height_m: f64,
    /// The tracker's coordinated turn (`motion_model = "ct"`): segments whose states carry
    /// the turn rate are smoothed with it.
    turn: Option<CoordinatedTurnWithRate>,
    /// Each tag's updates in time order, with the state behind each (when there is one).
    tags: HashMap<Arc<str>, Vec<(TrackUpdate, Option<ReportedState>)>>,
}

/// What [`Smoother::finish`] gives: every kept update, smoothed where it could be.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SmoothedTracks {
    /// The updates in time order (tags in name order at equal times); those smoothed have
    /// [`TrackUpdate::smoothed`] set.
    pub updates: Vec<TrackUpdate>,
    /// The segments the backward pass failed on (their filtered updates are kept).
    pub failures: Vec<SmoothingFailure>,
    /// The noise model each smoothed segment was fitted with.
    pub fits: Vec<SegmentFit>,
}

/// The noise model a segment of a track was smoothed with.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentFit {
    /// Tag id.
    pub tag: Arc<str>,
    /// First time of the segment, s.
    pub from_s: f64,
    /// Last time of the segment, s.
    pub to_s: f64,
    /// The maximum-likelihood noise ([`tuned_smooth`]), or why the site's CV model smoothed
    /// the tracker's own states instead: fewer than [`FIT_STATES_MIN`] states with a
    /// measurement, an update that told more than its information
    /// ([`ReportedState::partial_information`]), or the fit's numerical error.
    pub fit: Result<NoiseFit, String>,
}

/// The fewest states with a measurement a segment needs for its noise model to be fitted.
pub const FIT_STATES_MIN: usize = 10;

/// A segment of a track the smoother could not smooth.
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothingFailure {
    /// Tag id.
    pub tag: Arc<str>,
    /// First time of the segment, s.
    pub from_s: f64,
    /// Last time of the segment, s.
    pub to_s: f64,
    /// Why (the numerical error).
    pub reason: String,
}

impl Smoother {
    pub(super) fn new(kf: KalmanFilter, motion: ConstantVelocity, q_mps2: f64, tag_height_m: f64) -> Self {
        Self {
            kf,
            motion,
            q_mps2,
            tag_height_m,
            turn: None,
            tags: HashMap::new(),
        }
    }

    /// The tracker's coordinated turn, for the segments of tracks with a turn-rate state.
    pub(super) fn with_turn(mut self, turn: Option<CoordinatedTurnWithRate>) -> Self {
        self.turn = turn;
        self
    }

    /// Keeps the track updates of `out` with their states ([`Output::keeping_states`]; an
    /// output that keeps none gives updates that pass unsmoothed). A revised update drops its
    /// tag's kept updates at and after its time.
    pub fn take(&mut self, out: &Output) {
        let mut states = out.states.as_deref().unwrap_or(&[]).iter().peekable();
        for (index, update) in out.updates.iter().enumerate() {
            let state = states.next_if(|s| s.update == index).copied();
            let kept = self.tags.entry(Arc::clone(&update.tag)).or_default();
            if kept.last().is_some_and(|(last, _)| last.time_s >= update.time_s) {
                let keep = kept.partition_point(|(u, _)| u.time_s < update.time_s);
                kept.truncate(keep);
            }
            kept.push((update.clone(), state));
        }
    }

    /// Smooths every tag's segments and returns all updates in time order.
    #[must_use]
    pub fn finish(mut self) -> SmoothedTracks {
        let mut result = SmoothedTracks::default();
        let mut tags: Vec<_> = std::mem::take(&mut self.tags).into_iter().collect();
        tags.sort_by(|a, b| a.0.cmp(&b.0));
        for (tag, mut kept) in tags {
            // runs of consecutive states of one segment (updates without a state between them
            // are skipped over, not a break: a lost track restarts in a new segment anyway)
            let with_state: Vec<(usize, u64)> = kept
                .iter()
                .enumerate()
                .filter_map(|(i, (_, state))| state.map(|s| (i, s.segment)))
                .collect();
            for run in with_state.chunk_by(|a, b| a.1 == b.1) {
                let run: Vec<usize> = run.iter().map(|&(i, _)| i).collect();
                let (from_s, to_s) = (kept[run[0]].0.time_s, kept[run[run.len() - 1]].0.time_s);
                match self.smooth_run(&mut kept, &run) {
                    Ok(fit) => result.fits.push(SegmentFit {
                        tag: Arc::clone(&tag),
                        from_s,
                        to_s,
                        fit,
                    }),
                    Err(reason) => result.failures.push(SmoothingFailure {
                        tag: Arc::clone(&tag),
                        from_s,
                        to_s,
                        reason,
                    }),
                }
            }
            result.updates.extend(kept.into_iter().map(|(update, _)| update));
        }
        result
            .updates
            .sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then_with(|| a.tag.cmp(&b.tag)));
        result
    }

    /// Smooths the updates `run` (indices into `kept`, one segment, time order) in place and
    /// returns the fitted noise (or why the site's model was used); on an error none of them
    /// is changed.
    fn smooth_run(
        &self,
        kept: &mut [(TrackUpdate, Option<ReportedState>)],
        run: &[usize],
    ) -> Result<Result<NoiseFit, String>, String> {
        if let Some(turn) = &self.turn {
            // a CV backward pass over a turn's states would cut every arc short: never that
            if !run.iter().all(|&i| kept[i].1.is_some_and(|s| s.turn.is_some())) {
                return Err("a coordinated-turn segment with updates that keep no turn rate".into());
            }
            return self.smooth_turn(turn, kept, run);
        }
        match kept[run[0]].0.dimensions {
            2 => self.smooth_sized::<4>(kept, run),
            3 => self.smooth_sized::<6>(kept, run),
            other => Err(format!("a track of {other} dimensions (2-D and 3-D are tracked)")),
        }
    }

    fn smooth_sized<const N: usize>(
        &self,
        kept: &mut [(TrackUpdate, Option<ReportedState>)],
        run: &[usize],
    ) -> Result<Result<NoiseFit, String>, String> {
        // the tracker's filtered states and what each update added, in one pass over the run
        let mut filtered: Vec<Gaussian<N>> = Vec::with_capacity(run.len());
        let mut steps: Vec<InformationStep<N>> = Vec::with_capacity(run.len());
        let mut partial = false;
        for &i in run {
            let (time_s, state) = (kept[i].0.time_s, kept[i].1.ok_or("an update without its state")?);
            let mean = Vector::<N>::from_column_slice(&state.mean[..N]);
            let covariance = Matrix::<N>::from_row_slice(&state.covariance[..N * N]);
            filtered.push(Gaussian::new(mean, covariance, time_s).map_err(|e| e.to_string())?);
            steps.push(InformationStep {
                time_s,
                information: Matrix::<N>::from_column_slice(&state.information[..N * N]),
                information_vector: Vector::<N>::from_column_slice(&state.information_vector[..N]),
            });
            partial |= state.partial_information;
        }
        // Pₖ|ₙ's bound for correlated past and future errors (the position axes' marginals of
        // each side), from the backward pass of the site's model over the tracker's own states: the
        // tracker's covariances are calibrated online (adaptive noise, correlated errors'
        // inflation), the tuned model's are not. Where the tracker's updates told more than
        // the CV layout holds (`partial`: odometry's heading drift, range offsets, control
        // inputs, the IMM, constraints), that backward pass is not the tracker's own model, and what it
        // says the future knows is not credited: the filtered covariance is reported
        let smoothed = self.kf.smooth(&filtered, &self.motion).map_err(|e| e.to_string())?;
        let positions: Vec<usize> = (0..N / 2).map(|axis| 2 * axis).collect();
        let mut reported = smoothed
            .iter()
            .zip(&filtered)
            .map(|(state, past)| {
                let bound = if partial {
                    *past.covariance()
                } else {
                    marginal_intersection_bound(past, state, &positions).map_err(|e| e.to_string())?
                };
                Gaussian::new(*state.mean(), bound, state.time_s()).map_err(|e| e.to_string())
            })
            .collect::<Result<Vec<Gaussian<N>>, String>>()?;
        // x̂ₖ|ₙ from the smoother tuned to the segment, where its updates say all they told in
        // their information and enough of them measured (the first state's is its start)
        let measured = steps.iter().skip(1).filter(|s| s.information.norm() > 0.0).count();
        let tuned = if partial {
            Err(
                "an update told more than its information in the CV layout (the heading's drift, a \
                 range offset, an accelerometer's control input, the IMM, a constraint)"
                    .to_string(),
            )
        } else if measured < FIT_STATES_MIN {
            Err(format!("{measured} measured states, fewer than {FIT_STATES_MIN}"))
        } else {
            tuned_smooth(&filtered[0], &steps, self.q_mps2).map_err(|e| format!("the fit failed: {e}"))
        };
        if let Ok(tuned) = &tuned {
            for (state, better) in reported.iter_mut().zip(&tuned.smoothed) {
                *state =
                    Gaussian::new(*better.mean(), *state.covariance(), state.time_s()).map_err(|e| e.to_string())?;
            }
        }
        for (&i, state) in run.iter().zip(&reported) {
            self.write_smoothed(&mut kept[i].0, state);
        }
        Ok(tuned.map(|tuned| tuned.fit))
    }
}

impl Smoother {
    /// Writes a smoothed CV-layout state into its update: position and its covariance at the
    /// tag's height, velocity, and the `smoothed` flag.
    fn write_smoothed<const N: usize>(&self, update: &mut TrackUpdate, state: &Gaussian<N>) {
        let (position_m, covariance_m2) = position_of(state, self.tag_height_m);
        update.position_m = position_m;
        update.position_covariance_m2 = covariance_m2;
        for axis in 0..N / 2 {
            update.velocity_mps[axis] = state.mean()[2 * axis + 1];
        }
        update.smoothed = true;
    }

    /// Smooths a coordinated-turn segment with the tracker's own model (the extended RTS
    /// smoother over `[x, vx, y, vy, ω]`, linearised at each filtered state), so the backward
    /// pass follows the turn a CV model would cut short; the covariance is the intersection
    /// bound over the position axes, as for the CV segments. Not fitted (the fit is the CV
    /// model's): the reason says so.
    fn smooth_turn(
        &self,
        model: &CoordinatedTurnWithRate,
        kept: &mut [(TrackUpdate, Option<ReportedState>)],
        run: &[usize],
    ) -> Result<Result<NoiseFit, String>, String> {
        let mut filtered: Vec<Gaussian<5>> = Vec::with_capacity(run.len());
        for &i in run {
            let turn = kept[i]
                .1
                .and_then(|s| s.turn)
                .ok_or("an update without its turn state")?;
            let mean = Vector::<5>::from_column_slice(&turn.mean);
            let covariance = Matrix::<5>::from_row_slice(&turn.covariance);
            filtered.push(Gaussian::new(mean, covariance, kept[i].0.time_s).map_err(|e| e.to_string())?);
        }
        let smoothed = ExtendedKalmanFilter::default()
            .smooth(&filtered, model)
            .map_err(|e| e.to_string())?;
        for (&i, (state, past)) in run.iter().zip(smoothed.iter().zip(&filtered)) {
            // P_ci over x and y, then the [x, vx, y, vy] marginal of it
            let bound = marginal_intersection_bound(past, state, &[0, 2]).map_err(|e| e.to_string())?;
            let marginal = Gaussian::<4>::new(
                state.mean().fixed_rows::<4>(0).into_owned(),
                bound.fixed_view::<4, 4>(0, 0).into_owned(),
                state.time_s(),
            )
            .map_err(|e| e.to_string())?;
            self.write_smoothed(&mut kept[i].0, &marginal);
        }
        Ok(Err(
            "a coordinated turn, smoothed with the tracker's own model (the turn rate a state; not fitted)".into(),
        ))
    }
}
