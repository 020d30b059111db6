//! Measurement updates of a track: prediction, gating and acceptance, position fixes,
//! velocities and single anchor readings (tightly coupled).

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use rtls_estimation::filter::Updated;
use rtls_estimation::imm::ImmState;
use rtls_estimation::measurement::{ComponentSelection, MeasurementModel, NoiseCovariance};
use rtls_estimation::Gaussian;

use super::aided::AidedMotion;
use super::alarms::position_of;
use super::anchors::AnchorReading;
use super::jump;
use super::models::{AnchorLaw, AnchorMeasurement};
use super::noise::{NoiseClass, Source};
use super::output::{Event, Output, UpdateSource};
use super::range_bias::RoundReading;
use super::track::{dimensions, rejected, state_from_fix, Shared, Track, ACCELERATION_HOLD_S};
use crate::error::Result;
use crate::lifecycle::{Lifecycle, LifecycleEvent, TrackStatus};
use crate::site::FilterKind;

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

/// Accepts an update unless the track is confirmed and the NIS is outside the χ² gate; then
/// advances the lifecycle. Returns [`Verdict::Taken`], or [`Verdict::OutsideGate`] with a
/// `rejected` event (the last event it pushes).
pub(super) fn accept<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    updated: Updated<N>,
    modes: Option<ImmState>,
    kind: &'static str,
    source: UpdateSource,
    out: &mut Output,
) -> Result<Verdict> {
    let time_s = updated.state.time_s();
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
            updated.nis,
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
    let position_m = position_of(&updated.state, shared.tag_height_m).0;
    if matches!(source, UpdateSource::Fix | UpdateSource::Anchors) {
        let p = updated.state.covariance();
        track.heading.position_updated(
            time_s,
            [position_m[0], position_m[1]],
            [p[(0, 0)], p[(0, 2)], p[(2, 2)]],
        );
    }
    if shared.constraints.is_some() {
        track.hearing.updated(time_s);
    }
    track.state = Some(updated.state);
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
fn is_gated<const N: usize>(track: &Track<N>) -> bool {
    matches!(track.status(), Some(TrackStatus::Confirmed | TrackStatus::Coasting))
}

/// Whether [`accept`] will refuse `updated`: the track is gated and the NIS is outside the
/// `χ²` gate of its degrees of freedom.
fn outside_gate<const N: usize>(shared: &Shared, track: &Track<N>, updated: &Updated<N>) -> bool {
    let dof = updated.measurement_dim().clamp(1, 3);
    is_gated(track) && updated.nis > shared.gates[dof - 1]
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
    track.modes = None;
    track.epoch.clear();
    track.noise = Default::default();
    track.range_bias = Default::default();
    track.rejection_rate = 0.0;
    track.gated_updates = 0;
    track.jump = None;
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
fn push_switch<const N: usize>(
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

/// A position fix: starts the track, or updates it (`H` selects the position components).
/// Returns whether it updated the track's state (`false`: it started or restarted the track,
/// or was gated out or failed, with an event).
pub(super) fn fix_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<bool> {
    let class = NoiseClass::of_component_kind(kind, false);
    fix_update_as(shared, track, (time_s, position, covariance), kind, class, out)
}

/// [`fix_update`] with the fix's noise class given (an epoch fix solved from RSSI alone is
/// [`NoiseClass::RssiFix`]).
pub(super) fn fix_update_as<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    (time_s, position, covariance): (f64, &[f64], &[f64]),
    kind: &'static str,
    class: NoiseClass,
    out: &mut Output,
) -> Result<bool> {
    let k = position.len();
    let Some(state) = track.state.as_ref().filter(|_| !track.is_lost()) else {
        // a new track, or a lost one whose prior is too stale to update
        return start_from_fix(shared, track, time_s, position, covariance, kind, out).map(|()| false);
    };
    let indices: Vec<usize> = (0..k).map(|i| 2 * i).collect();
    let prior = predict(shared, track, state, time_s)?;
    let verdict = component_update(
        shared,
        track,
        prior,
        &indices,
        position,
        covariance,
        kind,
        (UpdateSource::Fix, class),
        out,
    )?;
    match verdict {
        Verdict::Taken => {
            // the track explains its fixes again
            track.jump = None;
            Ok(true)
        }
        // (a track the gate just re-initialised has no state to jump from)
        Verdict::OutsideGate if track.state.is_some() => {
            jump_hypothesis(shared, track, (time_s, position, covariance), kind, out)?;
            Ok(false)
        }
        Verdict::OutsideGate | Verdict::NotTaken => Ok(false),
    }
}

/// The `rejected` event the gate pushed for `track`'s measurement at `time_s`: the last event,
/// if it is that.
fn gate_rejection<'a, const N: usize>(track: &Track<N>, time_s: f64, out: &'a mut Output) -> Option<&'a mut String> {
    match out.events.last_mut() {
        Some(Event::Rejected {
            tag, time_s: t, reason, ..
        }) if *tag == track.tag && *t == time_s => Some(reason),
        _ => None,
    }
}

/// A fix the track gated out goes to its jump hypothesis ([`super::jump`]); once the
/// hypothesis is confirmed the track restarts at its state, with a `jumped` lifecycle event in
/// place of the fix's rejection.
fn jump_hypothesis<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    (time_s, position, covariance): (f64, &[f64], &[f64]),
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let hypothesis = jump::absorb(track.jump.take(), shared, time_s, position, covariance);
    let Some(hypothesis) = hypothesis else {
        return Ok(());
    };
    if !jump::is_confirmed(&hypothesis, shared) {
        if let Some(reason) = gate_rejection(track, time_s, out) {
            reason.push_str(&format!(
                "; held as a jump hypothesis ({} fixes agree so far)",
                hypothesis.fixes
            ));
        }
        track.jump = Some(hypothesis);
        return Ok(());
    }
    // the fix is used: its rejection is withdrawn
    if gate_rejection(track, time_s, out).is_some() {
        out.events.pop();
    }
    let state = hypothesis.state;
    reacquire(track);
    start_at(shared, track, state, kind, out)?;
    if let Some(state) = &track.state {
        out.events.push(Event::Lifecycle {
            tag: Arc::clone(&track.tag),
            time_s,
            event: LifecycleEvent::Jumped,
            position_m: position_of(state, shared.tag_height_m).0,
        });
    }
    Ok(())
}

/// (Re)starts a track at a fix: `x₀ = [p, 0]`, `P₀ = diag(Σ_fix, σ_v² I)`; a lost track
/// recovers, a new one starts its lifecycle.
pub(super) fn start_from_fix<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let state = match state_from_fix(shared, time_s, position, covariance) {
        Ok(state) => state,
        Err(error) => {
            let reason = format!("cannot start a track from this fix: {error}");
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            return Ok(());
        }
    };
    start_at(shared, track, state, kind, out)
}

/// (Re)starts a track at `state`: under the IMM its modes start in the quiet one; a lost track
/// recovers, a new one starts its lifecycle.
fn start_at<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    state: Gaussian<N>,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let time_s = state.time_s();
    if let Some(manoeuvres) = &shared.manoeuvres {
        match manoeuvres.start(&state) {
            Ok(modes) => {
                // a (re)started track is in the quiet mode
                if track.mode != 0 {
                    push_switch(shared, track, time_s, 0, modes.probabilities()[0], out);
                }
                track.modes = Some(modes);
            }
            Err(error) => {
                let reason = format!("cannot start the motion modes from this fix: {error}");
                out.events.push(rejected(&track.tag, time_s, kind, reason));
                return Ok(());
            }
        }
    }
    let position_m = position_of(&state, shared.tag_height_m).0;
    track.state = Some(state);
    track.heading_cross = None;
    track.lost_state = None;
    track.unreported = Some(UpdateSource::Fix);
    match track.lifecycle.as_mut() {
        None => track.lifecycle = Some(Lifecycle::start(shared.lifecycle, time_s)?),
        Some(lifecycle) => {
            if let Some(event) = lifecycle.update(time_s)? {
                out.events.push(Event::Lifecycle {
                    tag: Arc::clone(&track.tag),
                    time_s,
                    event,
                    position_m,
                });
            }
        }
    }
    Ok(())
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

/// A linear update of state components `indices` with `value` and its row-major covariance;
/// a failed update is reported, not applied. Returns what became of it.
#[allow(clippy::too_many_arguments)]
pub(super) fn component_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: Prior<N>,
    indices: &[usize],
    value: &[f64],
    covariance: &[f64],
    kind: &'static str,
    (source, class): (UpdateSource, NoiseClass),
    out: &mut Output,
) -> Result<Verdict> {
    let k = indices.len();
    // R ← c R for errors correlated in time (c = max(1, 2τ_c/Δt)), then λ on top
    let noise_source = Source {
        class,
        anchor: usize::MAX,
    };
    let inflation = track.noise.correlation_inflation(
        noise_source,
        prior.state.time_s(),
        class.correlation_s(&shared.settings.adaptive_noise),
        shared.error_correlation.as_ref(),
    );
    let stated: Vec<f64> = covariance.iter().map(|c| inflation * c).collect();
    let scale = track.noise.scale(class);
    let scaled: Vec<f64> = stated.iter().map(|c| scale * c).collect();
    let covariance_scaled = &scaled[..];
    // the single-model update of the (combined) prior gives the gate's NIS; under the IMM the
    // state is the modes' combined posterior
    let result = NoiseCovariance::full(DMatrix::from_row_slice(k, k, covariance_scaled))
        .and_then(|noise| ComponentSelection::<N>::new(indices, noise))
        .and_then(|model| {
            shared
                .kf
                .update(&prior.state, &model, &DVector::from_column_slice(value))
        })
        .and_then(|updated| match (&shared.manoeuvres, &prior.modes) {
            (Some(manoeuvres), Some(modes)) => {
                let posterior = manoeuvres.update_components(modes, indices, value, covariance_scaled)?;
                let state = manoeuvres.combined(&posterior)?;
                Ok((Updated { state, ..updated }, Some(posterior)))
            }
            _ => Ok((updated, None)),
        });
    match result {
        Ok((updated, modes)) => {
            let gate = shared.gates[k.clamp(1, 3) - 1];
            out.innovations.record(class, &updated, gate, scale);
            track
                .noise
                .observe(shared.adaptive.as_ref(), class, &updated, &stated, gate);
            track
                .noise
                .observe_correlation(shared.error_correlation.as_ref(), noise_source, &updated);
            let verdict = accept(shared, track, updated, modes, kind, source, out)?;
            if verdict == Verdict::Taken {
                carry_heading_cross(track, &prior.state)?;
            }
            Ok(verdict)
        }
        Err(error) => {
            let reason = format!("{} update failed: {error}", source.name());
            out.events
                .push(rejected(&track.tag, prior.state.time_s(), kind, reason));
            Ok(Verdict::NotTaken)
        }
    }
}

/// After an update of the state that did not involve the heading, carries the state's
/// cross-covariance with the heading channel's error (when it has one) from `prior` to the
/// track's new state ([`HeadingCross::after_position_update`](super::heading_cross::HeadingCross)).
fn carry_heading_cross<const N: usize>(track: &mut Track<N>, prior: &Gaussian<N>) -> Result<()> {
    // (nothing to carry, and nothing copied, on a track without speeds)
    if let (Some(cross), Some(posterior)) = (&track.heading_cross, &track.state) {
        track.heading_cross = Some(cross.after_position_update(prior, posterior)?);
    }
    Ok(())
}

/// The track's prediction to `time_s` for a velocity; `None` (with a rejection) without a
/// track or with a lost one.
///
/// # Errors
/// Numerical failures of the prediction.
pub(super) fn velocity_prior<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    time_s: f64,
    kind: &'static str,
    out: &mut Output,
) -> Result<Option<Prior<N>>> {
    let Some(state) = track.state.as_ref().filter(|_| !track.is_lost()) else {
        let reason =
            "no track (or a lost one): a velocity cannot start or recover it (it needs a position)".to_string();
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(None);
    };
    predict(shared, track, state, time_s).map(Some)
}

/// A velocity measurement of the first `k` axes.
pub(super) fn velocity_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    velocity: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(prior) = velocity_prior(shared, track, time_s, kind, out)? else {
        return Ok(());
    };
    let indices: Vec<usize> = (0..velocity.len()).map(|i| 2 * i + 1).collect();
    component_update(
        shared,
        track,
        prior,
        &indices,
        velocity,
        covariance,
        kind,
        (UpdateSource::Velocity, NoiseClass::Velocity),
        out,
    )
    .map(|_taken| ())
}

/// Tightly coupled: one range / RSSI / TDOA straight into the EKF or UKF (seed 003's
/// one-observation update).
pub(super) fn coupled_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let class = match reading {
        AnchorReading::Range { .. } => NoiseClass::Range,
        AnchorReading::Rssi { .. } => NoiseClass::Rssi,
        AnchorReading::Tdoa { .. } => NoiseClass::Tdoa,
    };
    let anchor = match reading {
        AnchorReading::Range { anchor, .. }
        | AnchorReading::Rssi { anchor, .. }
        | AnchorReading::Tdoa { anchor, .. } => anchor,
    };
    // R ← c R for errors correlated in time (c = max(1, 2τ_c/Δt) per reader), then λ R
    let source = Source { class, anchor };
    let inflation = track.noise.correlation_inflation(
        source,
        time_s,
        class.correlation_s(&shared.settings.adaptive_noise),
        shared.error_correlation.as_ref(),
    );
    let scale = inflation * track.noise.scale(class);
    // the anchor's learnt range offset: z' = r − b⁻, R' = λ c R + P_b⁻
    let bias_prior = match (&shared.range_bias, reading) {
        (Some(model), AnchorReading::Range { anchor, .. }) => Some(track.range_bias.offset(model, anchor, time_s)),
        _ => None,
    };
    let (model, z, stated_variance) = match reading {
        AnchorReading::Range {
            position_m,
            range_m,
            variance_m2,
            ..
        } => {
            let (offset_m, offset_variance_m2) = bias_prior.unwrap_or((0.0, 0.0));
            (
                AnchorMeasurement::new(
                    position_m,
                    shared.tag_height_m,
                    AnchorLaw::Range,
                    scale * variance_m2 + offset_variance_m2,
                ),
                range_m - offset_m,
                variance_m2,
            )
        }
        AnchorReading::Rssi {
            anchor,
            rssi_dbm,
            law: [p0, d0, n, _],
            variance_db2,
        } => {
            let law = AnchorLaw::LogDistance {
                reference_power_dbm: p0,
                reference_distance_m: d0,
                exponent: n,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    scale * variance_db2,
                ),
                rssi_dbm,
                variance_db2,
            )
        }
        AnchorReading::Tdoa {
            anchor,
            reference,
            range_difference_m,
            variance_m2,
        } => {
            let law = AnchorLaw::RangeDifference {
                reference_m: shared.anchors.get(reference).position_m,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    scale * variance_m2,
                ),
                range_difference_m,
                variance_m2,
            )
        }
    };
    let prior = predict(shared, track, state, time_s)?;
    let measured = z;
    let z = DVector::from_element(1, z);
    let result = match shared.settings.filter {
        FilterKind::Ukf => shared.ukf.update(&prior.state, &model, &z),
        FilterKind::Ekf | FilterKind::Kf => shared.ekf.update(&prior.state, &model, &z),
    }
    .and_then(|updated| match (&shared.manoeuvres, &prior.modes) {
        // every mode updated by an EKF step in its own layout
        (Some(manoeuvres), Some(modes)) => {
            let posterior = manoeuvres.update_anchor(modes, &model, measured)?;
            let state = manoeuvres.combined(&posterior)?;
            Ok((Updated { state, ..updated }, Some(posterior)))
        }
        _ => Ok((updated, None)),
    });
    match result {
        Ok((updated, modes)) => {
            out.innovations
                .record(class, &updated, shared.gates[0], scale / inflation);
            track.noise.observe(
                shared.adaptive.as_ref(),
                class,
                &updated,
                &[inflation * stated_variance],
                shared.gates[0],
            );
            track
                .noise
                .observe_correlation(shared.error_correlation.as_ref(), source, &updated);
            if let (Some(bias_model), Some((_, offset_variance_m2)), AnchorReading::Range { variance_m2, .. }) =
                (&shared.range_bias, bias_prior, reading)
            {
                // learn only from a confirmed track whose prediction is at least as sure as the
                // reading and as the offsets' prior along it (H P⁻ Hᵀ ≤ min(λ c σ², σ_b²)): a
                // start-up track's large errors are not linear in the position, and the
                // projection would not remove them
                let reading_variance_m2 = scale * variance_m2;
                let predicted_variance_m2 =
                    updated.innovation_covariance[(0, 0)] - reading_variance_m2 - offset_variance_m2;
                let prior_variance_m2 = bias_model.prior_std() * bias_model.prior_std();
                let correlation_s = shared.settings.adaptive_noise.correlation_s;
                if outside_gate(shared, track, &updated) {
                    // the prediction this round is measured against is in doubt
                    track.range_bias.discard_round();
                } else if is_gated(track)
                    && predicted_variance_m2 <= reading_variance_m2.min(prior_variance_m2)
                    && track.range_bias.wants(time_s, correlation_s)
                {
                    // the reading's part in its round: ν, λ σ² (one look) and ∂h/∂p at the
                    // prediction
                    if let Ok(jacobian) = MeasurementModel::jacobian(&model, prior.state.mean()) {
                        let mut gradient = [0.0; 3];
                        for (axis, g) in gradient.iter_mut().enumerate().take(dimensions::<N>()) {
                            *g = jacobian[(0, 2 * axis)];
                        }
                        let reading = RoundReading {
                            innovation_m: updated.innovation[0],
                            noise_variance_m2: reading_variance_m2 / inflation,
                            gradient,
                        };
                        track
                            .range_bias
                            .observe(bias_model, anchor, reading, time_s, dimensions::<N>(), correlation_s);
                    }
                }
            }
            if accept(shared, track, updated, modes, kind, UpdateSource::Anchors, out)? == Verdict::Taken {
                carry_heading_cross(track, &prior.state)?;
            }
            Ok(())
        }
        Err(error) => {
            out.events.push(rejected(
                &track.tag,
                time_s,
                kind,
                format!("filter update failed: {error}"),
            ));
            Ok(())
        }
    }
}
