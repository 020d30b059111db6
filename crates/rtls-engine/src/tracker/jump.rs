//! A track's jump hypothesis: fixes that fall outside the track's gate but agree with each
//! other.
//!
//! A tag can move farther than its motion model allows between two fixes: carried in a
//! vehicle through an area without coverage, moved to another floor, or located by another
//! system whose positions a provider pushes. A confirmed track gates such fixes out, and its
//! running rejection rate re-initialises it only after about nine gated-out updates (9 s at
//! 1 Hz). Instead, the first gated-out fix starts a second hypothesis, a new track at that
//! fix; each further gated-out fix updates it if it falls inside the hypothesis's own gate,
//! and starts it again otherwise. Once the hypothesis holds the evidence a new track needs to
//! be confirmed (`[tracker] initiation`: `M` fixes within `within_s`), and they span at least
//! [`JUMP_MIN_SPAN_S`], the track jumps: the hypothesis becomes its state. A fix inside the
//! track's gate drops the hypothesis (the track explains its fixes again).
//!
//! ```text
//! start:         x₀ = [p, 0],  P₀ = diag(Σ_fix, σ_v² I)                       (a new track's)
//! each fix:      x⁻ = F x,  P⁻ = F P Fᵀ + Q;  ν = z − H x⁻,  S = H P⁻ Hᵀ + R
//!                νᵀ S⁻¹ ν ≤ γ  →  Kalman update, n ← n + 1;  otherwise start again at z
//! jump when:     n ≥ max(2, M)  and  t_n − t_1 ≥ JUMP_MIN_SPAN_S  (t_n − t_1 ≤ within_s)
//! ```
//!
//! **Alternation.** Two transmitters sending as one tag id (a mis-configured tag, two phones
//! under one account) give fixes from two places in turn: the track follows one, the other's
//! fixes are gated out, start a hypothesis, and the next fix of the first drops it. The track
//! keeps the hypothesis it dropped last; when a gated-out fix falls inside that hypothesis's
//! gate (predicted to the fix), the fixes have come back to the other place. After
//! [`ALTERNATION_RETURNS`] such returns the track reports `alternating` once, at the other
//! place: no motion model of one tag explains the fixes, and the operator should know which
//! id (a recurring reflection looks the same, and is worth knowing about too). From then on,
//! while at least [`ALTERNATION_MIN_SHARE`] of the fixes come from the other place, the
//! track keeps a state at each: a fix inside the departed hypothesis's gate and likelier
//! under it than under the track ([`from_departed`]) switches the two ([`switch_places`])
//! before it updates, so each transmitter's fixes update its own state instead of pulling
//! one state between two places (a track whose state is all it learnt: not one with
//! heading, range-offset or IMM states beside it). A reflection that recurs now and then
//! stays a minority, and its fixes stay gated out.
//!
//! A burst of outliers that agree with each other (a reflection that persists) must last
//! [`JUMP_MIN_SPAN_S`] before the track follows it: at 10 Hz that is about as many gated-out
//! fixes as the rejection rate needs to re-initialise the track, so the hypothesis is never
//! more credulous than that rule; at 1 Hz it follows a real jump after `M − 1` seconds.
//!
//! # References
//! Y. Bar-Shalom, P. K. Willett, X. Tian, *Tracking and Data Fusion* (2011), §3.3 (M-of-N
//! track initiation); S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking
//! Systems* (1999), §6.3 (track splitting on unassociated measurements).

use nalgebra::DVector;
use rtls_estimation::filter::Updated;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::Gaussian;

use super::jump_state::{Alternation, JumpHypothesis};
use super::track::{state_from_fix, Shared, Track};

/// The least time a jump hypothesis's fixes must span before the track follows it, s.
pub(super) const JUMP_MIN_SPAN_S: f64 = 1.0;

/// Returns of gated-out fixes to a dropped hypothesis before the track reports `alternating`
/// (module documentation).
pub(super) const ALTERNATION_RETURNS: u32 = 3;

/// The least share of an alternating id's fixes that must come from the other place for the
/// track to keep a state there ([`from_departed`]).
pub(super) const ALTERNATION_MIN_SHARE: f64 = 0.25;

/// Whether a gated-out fix came back to the hypothesis the track's own fixes dropped last:
/// it falls inside that hypothesis's gate, predicted to the fix. Counts the return in
/// `alternation`; `true` once the returns reach [`ALTERNATION_RETURNS`] for the first time
/// on this track (the caller reports it).
pub(super) fn returned<const N: usize>(
    alternation: &mut Alternation<N>,
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> bool {
    let Some(departed) = alternation.departed.as_ref() else {
        return false;
    };
    // νᵀ S⁻¹ ν ≤ γ against the dropped hypothesis predicted to the fix
    if updated(departed, shared, time_s, position, covariance).is_none() {
        return false;
    }
    alternation.returns += 1;
    let report = alternation.returns >= ALTERNATION_RETURNS && !alternation.reported;
    alternation.reported |= report;
    if report {
        // the share of the other place's fixes is counted from here on, from the two places
        // on an equal footing: before, the track took the other's fixes inside its gate as
        // its own
        alternation.taken = alternation.returns;
    }
    report
}

/// A hypothesis holding one fix; `None` when the fix cannot start a state.
fn start<const N: usize>(
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> Option<JumpHypothesis<N>> {
    state_from_fix(shared, time_s, position, covariance)
        .ok()
        .map(|state| JumpHypothesis {
            state,
            fixes: 1,
            first_s: time_s,
        })
}

/// Takes a fix the track gated out: the hypothesis updated by it when it falls inside the
/// hypothesis's gate within the confirmation window, else a new hypothesis at the fix.
pub(super) fn absorb<const N: usize>(
    hypothesis: Option<JumpHypothesis<N>>,
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> Option<JumpHypothesis<N>> {
    let grown = hypothesis
        .filter(|held| time_s - held.first_s <= shared.lifecycle.confirm_window_s)
        .and_then(|held| updated(&held, shared, time_s, position, covariance));
    grown.or_else(|| start(shared, time_s, position, covariance))
}

/// The hypothesis after one more fix; `None` when the fix falls outside its gate or the
/// update fails.
fn updated<const N: usize>(
    held: &JumpHypothesis<N>,
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> Option<JumpHypothesis<N>> {
    let updated = fix_on(&held.state, shared, time_s, position, covariance)?;
    // νᵀ S⁻¹ ν ≤ γ
    (updated.nis <= shared.gate(position.len())).then(|| JumpHypothesis {
        state: updated.state,
        fixes: held.fixes + 1,
        first_s: held.first_s,
    })
}

/// `state` predicted to the fix with the site's motion model and updated by it (position
/// axes `0, 2, 4`, the fix's stated covariance); `None` when either step fails.
fn fix_on<const N: usize>(
    state: &Gaussian<N>,
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> Option<Updated<N>> {
    let k = position.len();
    let indices: Vec<usize> = (0..k).map(|i| 2 * i).collect();
    // x⁻ = F x,  P⁻ = F P Fᵀ + Q
    let prior = shared.kf.predict(state, &shared.motion, time_s).ok()?;
    // ν = z − H x⁻,  S = H P⁻ Hᵀ + R,  the posterior with its NIS νᵀ S⁻¹ ν and ln |S|
    let model = NoiseCovariance::full(nalgebra::DMatrix::from_row_slice(k, k, covariance))
        .and_then(|noise| ComponentSelection::<N>::new(&indices, noise))
        .ok()?;
    shared
        .kf
        .update(&prior, &model, &DVector::from_column_slice(position))
        .ok()
}

/// After the track reported `alternating`: whether a fix came from the place the track
/// departed rather than from the track's own, so that the track should switch to it. A fix
/// is likelier from the departed place when it falls inside that hypothesis's gate and
///
/// ```text
/// ℓ = −½ (νᵀ S⁻¹ ν + ln |S|),   ℓ_departed > ℓ_track
/// ```
///
/// each predicted to the fix (the fix's stated covariance in both: the comparison is of the
/// two places, not of the track's learnt noise scales). The track switches only while the
/// departed place's fixes, this one counted, are at least [`ALTERNATION_MIN_SHARE`] of the
/// fixes since the report (its returns against the fixes the track took, each starting at the
/// report's [`ALTERNATION_RETURNS`]; before the report the track took the other place's
/// fixes inside its gate as its own): two transmitters each send a fair share of an id's
/// fixes, a reflection that recurs a few (its fixes stay gated out, as before the report). A
/// departed place not heard from for longer than a track coasts (`coast_timeout_s`) is
/// forgotten: its prediction would span the whole site and outbid any track.
pub(super) fn from_departed<const N: usize>(
    alternation: &mut Alternation<N>,
    state: &Gaussian<N>,
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> bool {
    if alternation
        .departed
        .as_ref()
        .is_some_and(|d| time_s - d.state.time_s() > shared.lifecycle.coast_timeout_s)
    {
        alternation.departed = None;
    }
    let Some(departed) = alternation.departed.as_ref().filter(|_| alternation.reported) else {
        return false;
    };
    let Some(there) = fix_on(&departed.state, shared, time_s, position, covariance) else {
        return false;
    };
    if there.nis > shared.gate(position.len()) {
        return false;
    }
    let log_likelihood = |u: &Updated<N>| -0.5 * (u.nis + u.log_det_innovation_covariance);
    let likelier = fix_on(state, shared, time_s, position, covariance)
        .is_none_or(|here| log_likelihood(&there) > log_likelihood(&here));
    // (r + 1) / (r + 1 + taken) ≥ the least share, r the other place's fixes so far
    let other = f64::from(alternation.returns + 1);
    likelier && other >= ALTERNATION_MIN_SHARE * (other + f64::from(alternation.taken))
}

/// Switches an alternating track to the place it departed: the departed hypothesis's state
/// becomes the track's and the track's becomes the departed one, so each transmitter keeps
/// its own state; their counts of fixes (`returns`, `taken`) are swapped with them. The
/// track's next reported state starts a new segment (a smoother does not cross between the
/// two places).
pub(super) fn switch_places<const N: usize>(track: &mut Track<N>) {
    let (Some(departed), Some(state)) = (track.alternation.departed.take(), track.state.take()) else {
        return;
    };
    let departed = *departed;
    track.state = Some(departed.state);
    // each place keeps its count of fixes: the track's are now the departed place's
    std::mem::swap(&mut track.alternation.returns, &mut track.alternation.taken);
    track.alternation.departed = Some(Box::new(JumpHypothesis {
        first_s: state.time_s(),
        state,
        fixes: departed.fixes,
    }));
    track.start_segment();
}

/// Whether the track should jump to the hypothesis: `n ≥ max(2, M)` fixes spanning at
/// least [`JUMP_MIN_SPAN_S`].
pub(super) fn is_confirmed<const N: usize>(hypothesis: &JumpHypothesis<N>, shared: &Shared) -> bool {
    hypothesis.fixes >= shared.lifecycle.confirm_updates.max(2)
        && hypothesis.state.time_s() - hypothesis.first_s >= JUMP_MIN_SPAN_S
}
