//! The steps every measurement update shares: the prediction (`x⁻ = F x̂`, IMM mixing),
//! the χ² gate and the acceptance of a posterior (lifecycle, rejection rate, re-acquisition,
//! motion-mode switches), and carrying the heading cross-covariance over a position update.

use std::sync::Arc;

use nalgebra::DVector;
use rtls_estimation::imm::ImmState;
use rtls_estimation::smoother::InformationStep;
use rtls_estimation::Gaussian;

use super::aided::AidedMotion;
use super::alarms::position_of;
use super::outcome::UpdateOutcome;
use super::output::{Event, Output, UpdateSource};
use super::track::{dimensions, rejected, Shared, Track, ACCELERATION_HOLD_S};
use crate::error::Result;
use crate::lifecycle::TrackStatus;

/// A predicted state, and under `motion_model = "imm"` the predicted modes it combines.
pub(super) struct Prior<const N: usize> {
    /// The (combined) CV-layout prediction.
    pub(super) state: Gaussian<N>,
    /// The modes after mixing and mode-matched prediction (IMM only).
    pub(super) modes: Option<ImmState>,
}

/// `x⁻ = F x̂ (+ B a)`, `P⁻ = F P Fᵀ + Q` to `time_s`, with a recent accelerometer sample as
/// the control input and its noise in `Q` (seed 002's acceleration-driven prediction, see
/// [`super::aided`]); under the IMM, the modes' mixing and prediction and their
/// moment-matched combination.
pub(super) fn predict<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    state: &Gaussian<N>,
    time_s: f64,
) -> Result<Prior<N>> {
    let held = track
        .acceleration
        .filter(|held| time_s - held.time_s <= ACCELERATION_HOLD_S);
    if let (Some(manoeuvres), Some(modes)) = (&shared.manoeuvres, &track.modes) {
        // the CV mode takes the accelerometer as its control input, like the single CV model
        let modes = match held {
            Some(held) => {
                manoeuvres.predict_with_control(modes, time_s, &held.acceleration_mps2[..dimensions::<N>()])?
            }
            None => manoeuvres.predict(modes, time_s)?,
        };
        return Ok(Prior {
            state: manoeuvres.combined(&modes)?,
            modes: Some(modes),
        });
    }
    let state = match held {
        Some(held) => {
            let a = held.acceleration_mps2;
            let u = DVector::from_iterator(dimensions::<N>(), a.iter().copied().take(dimensions::<N>()));
            // Q = Q_c(σ_r²) + B ε² Bᵀ
            let model = AidedMotion::new(shared.aided_motion, held.std_mps2)?;
            shared.kf.predict_with_control(state, &model, &u, time_s)?
        }
        None => shared.kf.predict(state, &shared.motion, time_s)?,
    };
    Ok(Prior { state, modes: None })
}

/// Adds what the update from `prior` to `posterior` told (`J = P⁺⁻¹ − P⁻⁻¹`,
/// `j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻`) to the track's information since its last reported state, for a
/// smoother ([`super::Smoother`]). An update correlated with states outside the CV layout (a
/// speed whose heading's drift is considered, a range whose offset is), one whose prior was
/// predicted with an accelerometer's control input (the re-filter has no `B u`) and the IMM's
/// (`modes`: its combined prior and posterior are mixtures, not one linear update) mark it
/// partial; so does one whose covariances cannot be inverted.
fn keep_information<const N: usize>(track: &mut Track<N>, prior: &Gaussian<N>, posterior: &Gaussian<N>, modes: bool) {
    if modes || track.acceleration.is_some() || track.heading_cross.is_some() || track.offset_cross.is_some() {
        track.information_partial = true;
    }
    match (InformationStep::between(prior, posterior), track.information.as_mut()) {
        (Ok(step), Some(kept)) => kept.add(&step),
        (Ok(step), None) => track.information = Some(Box::new(step)),
        (Err(_), _) => track.information_partial = true,
    }
}

/// Accepts an update (computed from `prior`) unless the track is confirmed and the NIS is
/// outside the χ² gate; then advances the lifecycle. Returns [`Verdict::Taken`], or [`Verdict::OutsideGate`] with a
/// `rejected` event (the last event it pushes).
pub(super) fn accept<const N: usize, U: UpdateOutcome<N>>(
    shared: &Shared,
    track: &mut Track<N>,
    (prior, updated): (&Gaussian<N>, U),
    modes: Option<ImmState>,
    kind: &'static str,
    source: UpdateSource,
    out: &mut Output,
) -> Result<Verdict> {
    let time_s = updated.state().time_s();
    let dof = updated.measurement_dim().clamp(1, 3);
    let gated = is_gated(track);
    let outside = outside_gate(shared, track, &updated);
    if gated {
        // r ← (1 − α) r + α·[outside the gate]
        track.rejection_rate += REJECTION_RATE_WEIGHT * (f64::from(u8::from(outside)) - track.rejection_rate);
        track.gated_updates = track.gated_updates.saturating_add(1);
    }
    if outside {
        let mut reason = format!(
            "outside the χ²({dof}) validation gate: NIS {:.2} > {:.2}",
            updated.nis(),
            shared.gates[dof - 1]
        );
        if track.gated_updates >= REACQUIRE_MIN_UPDATES && track.rejection_rate > REACQUIRE_REJECTION_RATE {
            // the track no longer explains its measurements (locked on a mirror solution or
            // left behind by a manoeuvre): start again from a fresh fix rather than gate out
            // every measurement for ever
            reason.push_str(&format!(
                "; {:.0} % of the track's recent measurements fell outside the gate, so the track \
                 re-initialises from its next fix",
                100.0 * track.rejection_rate
            ));
            reacquire(track);
        }
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(Verdict::OutsideGate);
    }
    let position_m = position_of(updated.state(), shared.tag_height_m).0;
    if matches!(source, UpdateSource::Fix | UpdateSource::Anchors) {
        let p = updated.state().covariance();
        track.heading.position_updated(
            time_s,
            [position_m[0], position_m[1]],
            [p[(0, 0)], p[(0, 2)], p[(2, 2)]],
        );
    }
    if shared.constraints.is_some() {
        track.hearing.updated(time_s);
    }
    if let (Some(test), None, UpdateSource::Anchors) = (&shared.consistency, &shared.manoeuvres, source) {
        // a reading's pull Δp = (K ν)_p and its expected spread (K S Kᵀ)_pp join the window; a
        // window pulled one way by more than the covariance admits inflates it. Fixes do not
        // take part: a positioning stage's errors persist unseen by the tracker (a fingerprint
        // snapped to its reference points; seed 002's L-WKNN fixes made its KF 1.08 → 1.76 m
        // with them in)
        let (correction_m, reduction_m2) = updated.position_correction(dimensions::<N>());
        track.fading = test
            .observe(
                &mut track.corrections,
                time_s,
                correction_m,
                reduction_m2,
                dimensions::<N>(),
            )
            // a non-finite correction (a diverged update) tests nothing; the divergence check
            // reports the state itself
            .ok()
            .flatten()
            .unwrap_or(1.0);
    }
    if out.states.is_some() {
        keep_information(track, prior, updated.state(), shared.manoeuvres.is_some());
    }
    track.state = Some(updated.into_state());
    track.lost_state = None;
    if let Some(modes) = modes {
        switch_mode(shared, track, &modes, out);
        track.modes = Some(modes);
    }
    if let Some(event) = track
        .lifecycle
        .as_mut()
        .map(|l| l.update(time_s))
        .transpose()?
        .flatten()
    {
        out.events.push(Event::Lifecycle {
            tag: Arc::clone(&track.tag),
            time_s,
            event,
            position_m,
        });
    }
    track.unreported = Some(source);
    Ok(Verdict::Taken)
}

/// Whether the track's updates are gated (confirmed or coasting; a tentative track takes every
/// measurement).
pub(super) fn is_gated<const N: usize>(track: &Track<N>) -> bool {
    matches!(track.status(), Some(TrackStatus::Confirmed | TrackStatus::Coasting))
}

/// Whether [`accept`] will refuse `updated`: the track is gated and the NIS is outside the
/// `χ²` gate of its degrees of freedom.
pub(super) fn outside_gate<const N: usize>(shared: &Shared, track: &Track<N>, updated: &impl UpdateOutcome<N>) -> bool {
    let dof = updated.measurement_dim().clamp(1, 3);
    is_gated(track) && updated.nis() > shared.gates[dof - 1]
}

/// Weight `α` of one gated update in a track's running rejection rate (about the last 20).
const REJECTION_RATE_WEIGHT: f64 = 0.1;

/// A confirmed track whose running rejection rate exceeds this re-initialises.
const REACQUIRE_REJECTION_RATE: f64 = 0.6;

/// Gated updates a track needs before its rejection rate can re-initialise it.
const REACQUIRE_MIN_UPDATES: u32 = 10;

/// Drops the track's state (keeping its lifecycle, so it is reported as the same track) so its
/// next fix starts it again; the adaptive noise scales and the range offsets, learnt on a wrong
/// state, start over.
pub(super) fn reacquire<const N: usize>(track: &mut Track<N>) {
    track.state = None;
    track.heading_cross = None;
    track.offset_cross = None;
    track.modes = None;
    track.epoch.clear();
    track.check.clear();
    track.check_cost = 0.0;
    track.check_distances.clear();
    track.noise = Default::default();
    track.range_bias = Default::default();
    track.corrections = Default::default();
    track.fading = 1.0;
    track.rejection_rate = 0.0;
    track.gated_updates = 0;
    track.jump = None;
    track.alternation = Default::default();
}

/// Under the IMM: reports a `model-switch` when the mode to report changes (see
/// [`Manoeuvres::reported_mode`](super::modes::Manoeuvres::reported_mode)).
fn switch_mode<const N: usize>(shared: &Shared, track: &mut Track<N>, modes: &ImmState, out: &mut Output) {
    if let Some(manoeuvres) = &shared.manoeuvres {
        let mode = manoeuvres.reported_mode(modes, track.mode);
        if mode != track.mode {
            push_switch(shared, track, modes.time_s(), mode, modes.probabilities()[mode], out);
        }
    }
}

/// Reports the switch of `track` to `mode` and records it.
pub(super) fn push_switch<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    mode: usize,
    probability: f64,
    out: &mut Output,
) {
    if let Some(manoeuvres) = &shared.manoeuvres {
        out.events.push(Event::ModelSwitch {
            tag: Arc::clone(&track.tag),
            time_s,
            from: manoeuvres.name(track.mode),
            to: manoeuvres.name(mode),
            probability,
        });
    }
    track.mode = mode;
}

/// What became of an update.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Verdict {
    /// The track took it.
    Taken,
    /// The track is gated and it fell outside the gate (a `rejected` event says so).
    OutsideGate,
    /// It failed or was refused otherwise (with an event).
    NotTaken,
}

/// After an update of the state that involved neither the heading nor the range offsets,
/// carries the state's cross-covariances with the heading channel's error and with the
/// offsets' errors (when it has them) from `prior` to the track's new state
/// ([`HeadingCross::after_position_update`](super::heading_cross::HeadingCross),
/// [`OffsetCross::after_position_update`](super::offset_cross::OffsetCross)).
pub(super) fn carry_heading_cross<const N: usize>(track: &mut Track<N>, prior: &Gaussian<N>) -> Result<()> {
    carry_cross_covariances(track, prior)?;
    apply_fading(track)
}

/// [`carry_heading_cross`] without the fading: for a pseudo-measurement of the map or a silent
/// reader, which takes no part in the consistency test.
pub(super) fn carry_cross_covariances<const N: usize>(track: &mut Track<N>, prior: &Gaussian<N>) -> Result<()> {
    // (nothing to carry, and nothing copied, on a track without speeds or considered offsets)
    if let (Some(cross), Some(posterior)) = (&track.heading_cross, &track.state) {
        track.heading_cross = Some(cross.after_position_update(prior, posterior)?);
    }
    if let (Some(cross), Some(posterior)) = (&track.offset_cross, &track.state) {
        track.offset_cross = Some(cross.after_position_update(prior, posterior)?);
    }
    Ok(())
}

/// Applies the inflation `λ` the consistency test of the update just taken asked for
/// ([`rtls_estimation::adaptive::corrections`]): `P ← λ P` and, so the joint covariance of the
/// state's and the heading channel's (or range offsets') errors stays positive semi-definite
/// (`diag(√λ I, I) [[P, X], [Xᵀ, P_h]] diag(√λ I, I)`), `X ← √λ X`. Called once the update's
/// cross-covariance is carried.
///
/// # Errors
/// A covariance that is no longer finite (λ is bounded, so only on an already huge one).
pub(super) fn apply_fading<const N: usize>(track: &mut Track<N>) -> Result<()> {
    let lambda = std::mem::replace(&mut track.fading, 1.0);
    if lambda <= 1.0 {
        return Ok(());
    }
    if let Some(state) = track.state.as_mut() {
        *state = Gaussian::new(*state.mean(), state.covariance() * lambda, state.time_s())?;
    }
    if let Some(cross) = track.heading_cross.as_mut() {
        cross.scale(lambda.sqrt());
    }
    if let Some(cross) = track.offset_cross.as_mut() {
        cross.scale(lambda.sqrt());
    }
    Ok(())
}
