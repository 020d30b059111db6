//! A tightly coupled track checked against fixes of its own readings.
//!
//! A tightly coupled EKF takes each reading linearised about its own estimate. Started or
//! pulled metres off (a first fix of faint RSSI readings, a nearby reader shadowed by a body
//! for seconds), it can settle where the readings' gradients are shallow — outside the
//! anchors, where an RSSI reading moves the estimate centimetres — while every reading still
//! shrinks its covariance: the track reports a 2 m ellipse 20 m from the tag, and no reading
//! falls outside its gate. Nothing in the filter itself notices.
//!
//! So every [`CHECK_SPAN_S`] the readings the track took are also solved into a fix on their
//! own (no guess from the track: multilateration's own start), as fix-then-filter would, and
//! the fix is compared with the track. The fix is a check, never an update (its readings are
//! in the state already). A fix the track explains drops any jump hypothesis; one outside the
//! track's gate goes to the track's jump hypothesis ([`super::jump`]), and once such fixes agree
//! with each other (`[tracker] initiation`: `M` of them over at least 1 s) the track restarts
//! at them with a `jumped` event.
//!
//! A track can also stay a few metres off while each check fix, metres uncertain itself (BLE
//! RSSI), falls inside the gate: every fix alone is a passing disagreement, a run of them is
//! not. The last [`CHECK_RUN`] consecutive fixes are tested together, `T = Σⱼ d²ⱼ`, against
//! the `χ²(k · CHECK_RUN)` quantile at the gate probability (the fixes' readings are disjoint
//! windows; each shares its readings with the track, which makes `d²` smaller, not larger);
//! above it, the track restarts at the latest fix with a `jumped` event. A window the track
//! explains (the skip below) ends the run.
//!
//! Most windows need no solve: for a linear model the readings' cost at the track's
//! predictions, `C = Σ νᵢ² / Rᵢ` (each against the prior it updated, with the variance the
//! solver weights it by), exceeds the fix's own by `(p̂ − ẑ)ᵀ Σ_fix⁻¹ (p̂ − ẑ) ≥ d²`, so
//! `C ≤ γ` means no fix of them falls outside the gate (for a moving tag, and to first order
//! for ranges and RSSI, an approximation). On the tracker bench (1 000 tags, ranges at 10 Hz)
//! solving every window cost a fifth of the tightly coupled throughput.
//!
//! ```text
//! skip when:              C = Σ νᵢ² / Rᵢ ≤ γ
//! readings over [t₀, t]:  ẑ, Σ_fix  (solved alone)
//! motion blur:            Σ_blur = (t − t₀)²/4 · (v̂ v̂ᵀ + P_vv)   (a moving tag's readings span the window)
//! distance:               d² = (ẑ − p̂)ᵀ (P_pp + Σ_fix + Σ_blur)⁻¹ (ẑ − p̂)
//! d² ≤ γ: the track explains its readings;  d² > γ: a jump hypothesis at (ẑ, Σ_fix + Σ_blur)
//! run:                    T = Σⱼ d²ⱼ over the last CHECK_RUN fixes > χ²(k · CHECK_RUN): restart at ẑ
//! ```
//!
//! # References
//! Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
//! Navigation* (2001), §5.4 (filter consistency from innovations) — here from fixes, which
//! see errors a linearised filter's innovations do not.

use nalgebra::DMatrix;

use super::anchors::AnchorReading;
use super::output::Output;
use super::readings_fix::{corrected_range, solve, uninformative};
use super::step::{is_gated, predict};
use super::track::{dimensions, Shared, Track};
use super::update::{jump_hypothesis, jump_to_fix};
use crate::error::Result;

/// The span of readings a check fix is solved from, s: a round of every reader a tag hears
/// (RSSI scanners report about twice a second; UWB round robins take tens of ms).
pub(super) const CHECK_SPAN_S: f64 = 1.0;

/// The consecutive check fixes whose distances are tested together (module documentation).
pub(super) const CHECK_RUN: usize = 5;

/// Keeps `reading` (taken by the track at `time_s`) for the next check, and checks the track
/// once the readings span [`CHECK_SPAN_S`].
pub(super) fn check_reading<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    out: &mut Output,
) -> Result<()> {
    track.check.push((time_s, reading));
    let first_s = track.check[0].0;
    if time_s - first_s < CHECK_SPAN_S {
        return Ok(());
    }
    let cost = std::mem::take(&mut track.check_cost);
    // a new or re-initialising track's readings are not gated: nothing to check it against;
    // readings the track explains within the gate have no fix outside it (see above). The
    // buffer keeps its capacity for the next window.
    if !is_gated(track) || cost <= shared.gates[dimensions::<N>().min(3) - 1] {
        track.check.clear();
        track.check_distances.clear();
        return Ok(());
    }
    let readings: Vec<AnchorReading> = track
        .check
        .iter()
        .map(|(t, r)| corrected_range(shared, track, *r, *t))
        .collect();
    track.check.clear();
    let Ok(fixes) = solve::<N>(shared, &readings, None) else {
        return Ok(());
    };
    // two mirror-image fixes, or one that says no more than "among the anchors", check nothing
    let [fix] = fixes.as_slice() else {
        return Ok(());
    };
    if uninformative::<N>(shared, fix) {
        return Ok(());
    }
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let prior = predict(shared, track, state, time_s)?.state;
    let (position, fix_covariance, _) = fix;
    let k = position.len();
    let mean = prior.mean();
    let p = prior.covariance();
    // Σ = Σ_fix + (t − t₀)²/4 · (v̂ v̂ᵀ + P_vv)
    let half_span_s = 0.5 * (time_s - first_s);
    let covariance = DMatrix::from_fn(k, k, |i, j| {
        fix_covariance[i * k + j]
            + half_span_s * half_span_s * (mean[2 * i + 1] * mean[2 * j + 1] + p[(2 * i + 1, 2 * j + 1)])
    });
    // ν = ẑ − p̂,  S = P_pp + Σ
    let innovation = nalgebra::DVector::from_fn(k, |i, _| position[i] - mean[2 * i]);
    let s = DMatrix::from_fn(k, k, |i, j| p[(2 * i, 2 * j)]) + &covariance;
    // d² = νᵀ S⁻¹ ν
    let Some(cholesky) = s.cholesky() else {
        return Ok(());
    };
    let distance2 = innovation.dot(&cholesky.solve(&innovation));
    if !distance2.is_finite() {
        return Ok(());
    }
    if track.check_distances.len() == CHECK_RUN {
        track.check_distances.remove(0);
    }
    track.check_distances.push(distance2);
    let flat: Vec<f64> = covariance.transpose().iter().copied().collect();
    if distance2 > shared.gate(k) {
        return jump_hypothesis(shared, track, (time_s, position, &flat), "check", false, out);
    }
    if run_disagrees(&track.check_distances, shared.check_run_gates[k.clamp(1, 3) - 1]) {
        return jump_to_fix(shared, track, (time_s, position, &flat), "check", out);
    }
    // the track explains its readings: a hypothesis it held was a passing disagreement
    if let Some(dropped) = track.jump.take() {
        track.alternation.departed = Some(dropped);
    }
    Ok(())
}

/// Whether a full run of [`CHECK_RUN`] consecutive check fixes, each inside the track's gate,
/// together says the track does not explain its readings: `T = Σⱼ d²ⱼ ~ χ²(k · CHECK_RUN)`
/// while it does (`k` position axes per fix), so `T` above `threshold`, that quantile at the
/// gate probability (`Shared::check_run_gates`). A shorter run says nothing yet.
pub(super) fn run_disagrees(distances: &[f64], threshold: f64) -> bool {
    // T = Σⱼ d²ⱼ
    distances.len() >= CHECK_RUN && distances.iter().sum::<f64>() > threshold
}
