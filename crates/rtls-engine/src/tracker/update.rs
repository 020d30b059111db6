//! Updates of a track's state components: position fixes (starting, restarting and jumping a
//! track) and velocities, through the fixed-size Kalman update where the sizes allow
//! ([`KalmanFilter::update_fixed`](rtls_estimation::filter::KalmanFilter::update_fixed)) and
//! the general one otherwise.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use rtls_estimation::filter::Updated;
use rtls_estimation::imm::ImmState;
use rtls_estimation::measurement::{ComponentSelection, FixedSelection, NoiseCovariance};
use rtls_estimation::Gaussian;

use super::alarms::position_of;
use super::jump;
use super::noise::{NoiseClass, Source};
use super::outcome::UpdateOutcome;
use super::output::{Event, Output, UpdateSource};
use super::step::{accept, carry_heading_cross, predict, push_switch, reacquire, Prior, Verdict};
use super::track::{rejected, state_from_fix, Shared, Track};
use crate::error::Result;
use crate::lifecycle::{Lifecycle, LifecycleEvent};

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
    // one id sent by two transmitters: each keeps its own state, the fix goes to the likelier
    // (only where the state is all the track learnt: no heading, offsets or modes beside it)
    let plain = track.modes.is_none() && track.heading_cross.is_none() && track.offset_cross.is_none();
    let switched = plain && jump::from_departed(&mut track.alternation, state, shared, time_s, position, covariance);
    if switched {
        jump::switch_places(track);
    }
    let Some(state) = track.state.as_ref() else {
        return Ok(false);
    };
    let indices = AxisIndices::new(0, k);
    let prior = predict(shared, track, state, time_s)?;
    let verdict = component_update(
        shared,
        track,
        prior,
        indices.as_slice(),
        position,
        covariance,
        kind,
        (UpdateSource::Fix, class),
        out,
    )?;
    if switched && verdict != Verdict::Taken && track.state.is_some() {
        // the place it switched to did not take the fix after all: back to the track's own
        jump::switch_places(track);
    }
    match verdict {
        Verdict::Taken => {
            if track.alternation.departed.is_some() {
                track.alternation.taken += 1;
            }
            // the track explains its fixes again; the hypothesis it drops is kept, to tell
            // fixes that come back to it (an id sent by two transmitters)
            if let Some(dropped) = track.jump.take() {
                track.alternation.departed = Some(dropped);
            }
            Ok(true)
        }
        // (a track the gate just re-initialised has no state to jump from)
        Verdict::OutsideGate if track.state.is_some() => {
            jump_hypothesis(shared, track, (time_s, position, covariance), kind, true, out)?;
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

/// A fix the track gated out (`gated`, its `rejected` event the last one out) or a check fix
/// off the track ([`super::check`]) goes to its jump hypothesis ([`super::jump`]); once the
/// hypothesis is confirmed the track restarts at its state, with a `jumped` lifecycle event
/// (in place of a gated fix's rejection).
pub(super) fn jump_hypothesis<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    (time_s, position, covariance): (f64, &[f64], &[f64]),
    kind: &'static str,
    gated: bool,
    out: &mut Output,
) -> Result<()> {
    if track.jump.is_none() && jump::returned(&mut track.alternation, shared, time_s, position, covariance) {
        out.events.push(Event::Lifecycle {
            tag: Arc::clone(&track.tag),
            time_s,
            event: LifecycleEvent::Alternating,
            // the other place: the fix, at the tag's height in 2-D
            position_m: [
                position[0],
                position.get(1).copied().unwrap_or(0.0),
                position.get(2).copied().unwrap_or(shared.tag_height_m),
            ],
        });
    }
    let hypothesis = jump::absorb(
        track.jump.take().map(|kept| *kept),
        shared,
        time_s,
        position,
        covariance,
    );
    let Some(hypothesis) = hypothesis else {
        return Ok(());
    };
    if !jump::is_confirmed(&hypothesis, shared) {
        if let Some(reason) = gate_rejection(track, time_s, out).filter(|_| gated) {
            reason.push_str(&format!(
                "; held as a jump hypothesis ({} fixes agree so far)",
                hypothesis.fixes
            ));
        }
        track.jump = Some(Box::new(hypothesis));
        return Ok(());
    }
    // the fix is used: its rejection is withdrawn
    if gated && gate_rejection(track, time_s, out).is_some() {
        out.events.pop();
    }
    jump_to(shared, track, hypothesis.state, time_s, kind, out)
}

/// Restarts a track at a fix that the track has been shown not to explain (a run of check
/// fixes off it, [`super::check`]): `x₀ = [p, 0]`, `P₀ = diag(Σ_fix, σ_v² I)`, with a
/// `jumped` event. A fix that cannot start a state is refused with an event and the track
/// keeps its state.
pub(super) fn jump_to_fix<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    (time_s, position, covariance): (f64, &[f64], &[f64]),
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let state = match state_from_fix(shared, time_s, position, covariance) {
        Ok(state) => state,
        Err(error) => {
            let reason = format!("cannot restart the track at this fix: {error}");
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            return Ok(());
        }
    };
    jump_to(shared, track, state, time_s, kind, out)
}

/// Restarts `track` at `state` (everything it learnt dropped, [`reacquire`]) with a `jumped`
/// lifecycle event at `time_s`.
fn jump_to<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    state: Gaussian<N>,
    time_s: f64,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
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
    track.start_segment();
    track.heading_cross = None;
    track.offset_cross = None;
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

#[cfg(test)]
thread_local! {
    /// Tests: every component update takes the general kernel, the fixed one's reference
    /// (`tests_fixed_path`).
    pub(super) static GENERAL_KERNEL_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// A linear update of state components `indices` with `value` and its row-major covariance;
/// a failed update is reported, not applied. Returns what became of it.
///
/// One to three components without an IMM to update (a 2-D / 3-D position fix, a velocity)
/// take the fixed-size kernel, [`fixed_component_update`]; the rest the general one. Both give
/// the same results (`rtls-estimation`'s `fixed_kernels` test).
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
    let imm = shared.manoeuvres.is_some() && prior.modes.is_some();
    let fixed = !imm && value.len() == k && covariance.len() == k * k;
    #[cfg(test)]
    let fixed = fixed && !GENERAL_KERNEL_ONLY.with(std::cell::Cell::get);
    if fixed {
        let measurement = (indices, value, covariance);
        match k {
            1 => return fixed_component_update::<N, 1>(shared, track, prior, measurement, kind, (source, class), out),
            2 => return fixed_component_update::<N, 2>(shared, track, prior, measurement, kind, (source, class), out),
            3 => return fixed_component_update::<N, 3>(shared, track, prior, measurement, kind, (source, class), out),
            _ => {}
        }
    }
    let (noise_source, inflation) = noise_inflation(shared, track, &prior.state, class);
    // c R, then λ c R
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
            let noise = (&stated[..], scale, noise_source);
            conclude(shared, track, &prior.state, (updated, modes), noise, kind, source, out)
        }
        Err(error) => {
            let reason = format!("{} update failed: {error}", source.name());
            out.events
                .push(rejected(&track.tag, prior.state.time_s(), kind, reason));
            Ok(Verdict::NotTaken)
        }
    }
}

/// [`component_update`] of `M` components with fixed sizes and no heap allocation
/// ([`KalmanFilter::update_fixed`](rtls_estimation::filter::KalmanFilter::update_fixed)):
/// `R`, `S`, `K` and the adaptive noise's factorisations on the stack. The caller has checked
/// the sizes (`M` indices and values, `M²` covariance entries) and that no IMM is to update.
fn fixed_component_update<const N: usize, const M: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: Prior<N>,
    (indices, value, covariance): (&[usize], &[f64], &[f64]),
    kind: &'static str,
    (source, class): (UpdateSource, NoiseClass),
    out: &mut Output,
) -> Result<Verdict> {
    let (noise_source, inflation) = noise_inflation(shared, track, &prior.state, class);
    // c R (row-major, M × M)
    let mut stated = [0.0; 9];
    for (s, c) in stated.iter_mut().zip(covariance) {
        *s = inflation * c;
    }
    let stated = &stated[..M * M];
    // λ c R
    let scale = track.noise.scale(class);
    let scaled = SMatrix::<f64, M, M>::from_row_iterator(stated.iter().map(|c| scale * c));
    let mut selected = [0; M];
    selected.copy_from_slice(indices);
    let result = FixedSelection::<N, M>::new(selected, scaled).and_then(|model| {
        shared
            .kf
            .update_fixed(&prior.state, &model, &SVector::from_column_slice(value))
    });
    match result {
        Ok(updated) => {
            let noise = (stated, scale, noise_source);
            conclude(shared, track, &prior.state, (updated, None), noise, kind, source, out)
        }
        Err(error) => {
            let reason = format!("{} update failed: {error}", source.name());
            out.events
                .push(rejected(&track.tag, prior.state.time_s(), kind, reason));
            Ok(Verdict::NotTaken)
        }
    }
}

/// A component update's noise source (its class, class-wide) and the inflation `c` of its
/// stated variance for errors correlated in time (`c = max(1, 2τ_c/Δt)`, see
/// [`NoiseScales::correlation_inflation`](super::noise::NoiseScales::correlation_inflation)),
/// recording this update's time.
fn noise_inflation<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: &Gaussian<N>,
    class: NoiseClass,
) -> (Source, f64) {
    let source = Source {
        class,
        anchor: usize::MAX,
    };
    let inflation = track.noise.correlation_inflation(
        source,
        prior.time_s(),
        class.correlation_s(&shared.settings.adaptive_noise),
        shared.error_correlation.as_ref(),
    );
    (source, inflation)
}

/// After a component update computed with `λ c R` (`noise`: the stated `c R`, row-major, `λ`
/// and the source): the innovation totals, the adaptive noise scale and the error correlation
/// observe it, then the track accepts or gates it out ([`accept`]).
#[allow(clippy::too_many_arguments)]
fn conclude<const N: usize, U: UpdateOutcome<N>>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: &Gaussian<N>,
    (updated, modes): (U, Option<ImmState>),
    (stated, scale, noise_source): (&[f64], f64, Source),
    kind: &'static str,
    source: UpdateSource,
    out: &mut Output,
) -> Result<Verdict> {
    let class = noise_source.class;
    let gate = shared.gates[updated.measurement_dim().clamp(1, 3) - 1];
    out.innovations.record(class, &updated, gate, scale);
    track
        .noise
        .observe(shared.adaptive.as_ref(), class, &updated, stated, gate);
    track
        .noise
        .observe_correlation(shared.error_correlation.as_ref(), noise_source, &updated);
    let verdict = accept(shared, track, (prior, updated), modes, kind, source, out)?;
    if verdict == Verdict::Taken {
        carry_heading_cross(track, prior)?;
    }
    Ok(verdict)
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
    let indices = AxisIndices::new(1, velocity.len());
    component_update(
        shared,
        track,
        prior,
        indices.as_slice(),
        velocity,
        covariance,
        kind,
        (UpdateSource::Velocity, NoiseClass::Velocity),
        out,
    )
    .map(|_taken| ())
}

/// The state indices `first, first + 2, …` of `k` axes of a CV state `[x, vx, y, vy, …]`: its
/// position (`first = 0`) or velocity (`first = 1`) components, on the stack up to 3 axes.
enum AxisIndices {
    Few([usize; 3], usize),
    Many(Vec<usize>),
}

impl AxisIndices {
    fn new(first: usize, k: usize) -> Self {
        if k <= 3 {
            Self::Few([first, first + 2, first + 4], k)
        } else {
            Self::Many((0..k).map(|i| 2 * i + first).collect())
        }
    }

    fn as_slice(&self) -> &[usize] {
        match self {
            Self::Few(indices, k) => &indices[..*k],
            Self::Many(indices) => indices,
        }
    }
}
