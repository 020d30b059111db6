//! GNSS pseudoranges: a tag's pseudoranges of one epoch are buffered and solved together into
//! a fix, with a per-track receiver clock filter, in both pipelines.
//!
//! A pseudorange `ρ_i = ‖s_i − p‖ + b + v_i` holds the receiver clock bias `b = c δt`, common to
//! every satellite of the epoch and unknown to within kilometres: one pseudorange alone says
//! nothing about the position until `b` is known, so unlike a range it cannot update a filter
//! on its own (tightly coupled) without the clock in the state. The epoch's pseudoranges (equal
//! time stamps, or within `tracker.epoch_s`) are therefore solved together by
//! [`rtls_positioning::gnss`] — weighted Gauss–Newton for position and `b` in the site's ENU
//! frame about `[frame] origin`, with RAIM-style fault exclusion — and the fix updates the
//! track like any position fix (`fix_update`), in both pipelines. On a 2-D site the receiver is
//! at `tracker.tag_height_m` when given (east, north and `b` are solved), otherwise the 3-D fix's
//! horizontal part and its marginal covariance are used.
//!
//! Each track keeps a receiver clock filter, a Gaussian on `[b, ḃ]` (m, m/s) with a constant
//! drift model and random-walk noise (`[tracker.gnss]`):
//! ```text
//! x⁻ = F x,  F = [[1, Δt], [0, 1]]
//! P⁻ = F P Fᵀ + Q,  Q = [[q_b Δt + q_d Δt³/3, q_d Δt²/2], [q_d Δt²/2, q_d Δt]]
//! ```
//! Its prediction is the solver's prior on `b`, so three satellites (two at a known height)
//! still give a fix. After the solve, the posterior `N(b̂, σ̂²)` of `b` (the prior included)
//! becomes the filter's `b` marginal and is carried to the drift through their correlation:
//! ```text
//! k = P⁻ e₁ / P⁻_bb                      (regression of [b, ḃ] on b)
//! x⁺ = x⁻ + k (b̂ − b̄),  P⁺ = P⁻ + k (σ̂² − P⁻_bb) kᵀ
//! ```
//! When the epoch's satellites determine `b` without the prior and that solution's `b` lies
//! outside the validation gate of the prediction (a clock reset or jump, common on
//! smartphones), the prior is dropped and the filter restarts from the free solution.
//!
//! Every pseudorange that is not used is a `rejected` event naming why: no `[frame]` origin in
//! the site, a satellite repeated within an epoch, an epoch that cannot be solved (too few
//! satellites, degenerate geometry), or a satellite excluded by the fault detection.
//!
//! # References
//! Misra & Enge, *Global Positioning System*, 2nd ed., 2006 (navigation solution, RAIM);
//! R. G. Brown, P. Y. C. Hwang, *Introduction to Random Signals and Applied Kalman Filtering*,
//! 4th ed., 2012, §9.3 (the two-state clock model).

use std::sync::Arc;

use nalgebra::Vector3;
use rtls_positioning::gnss::{
    elevation_rad, elevation_std_m, pseudorange_fix, pseudorange_fix_at_height, LocalFrame, Pseudorange,
    PseudorangeOptions, PseudorangeSolution,
};

use super::gnss_state::{Reading, ReceiverClock};
use super::output::raw_fix;
use super::output::{Output, RawFix};
use super::track::{dimensions, rejected, Shared, Track};
use super::update::fix_update;
use crate::error::Result;
use crate::record::Measurement;

/// The kind name of pseudorange records.
const KIND: &str = "pseudorange";

/// A pseudorange record: refused without a site origin, else into the open epoch (which is
/// closed first if the record is beyond its window).
pub(super) fn pseudorange<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    measurement: &Measurement,
    out: &mut Output,
) -> Result<()> {
    let Measurement::Pseudorange {
        satellite,
        satellite_position_m,
        pseudorange_m,
        std_m,
    } = measurement
    else {
        return Ok(());
    };
    if shared.frame.is_none() {
        let reason = "a pseudorange needs the site's geodetic origin: add [frame] origin = { latitude_deg = …, \
                      longitude_deg = …, height_m = … } to the site"
            .to_string();
        out.events.push(rejected(&track.tag, time_s, KIND, reason));
        return Ok(());
    }
    close_due_gnss_epoch(shared, track, time_s, out)?;
    track.gnss.epoch.push(Reading {
        time_s,
        satellite: Arc::from(satellite.as_str()),
        satellite_ecef_m: *satellite_position_m,
        pseudorange_m: *pseudorange_m,
        std_m: *std_m,
    });
    Ok(())
}

/// Closes the open GNSS epoch if `now_s` is past its window (`f64::INFINITY`: at the end).
pub(super) fn close_due_gnss_epoch<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    out: &mut Output,
) -> Result<()> {
    match track.gnss.epoch.first() {
        // (automatic epochs: a receiver's pseudoranges of one epoch share its time stamp)
        Some(first) if now_s - first.time_s > shared.settings.epoch_s.unwrap_or(0.0) => close(shared, track, out),
        _ => Ok(()),
    }
}

/// Solves the open epoch and applies its fix at the epoch's last time.
fn close<const N: usize>(shared: &Shared, track: &mut Track<N>, out: &mut Output) -> Result<()> {
    let epoch = std::mem::take(&mut track.gnss.epoch);
    let (Some(frame), Some(last)) = (shared.frame.as_ref(), epoch.last()) else {
        return Ok(());
    };
    let time_s = last.time_s;
    let mut used: Vec<&Reading> = Vec::with_capacity(epoch.len());
    let mut observations = Vec::with_capacity(epoch.len());
    for (i, reading) in epoch.iter().enumerate() {
        if epoch[i + 1..].iter().any(|r| r.satellite == reading.satellite) {
            let reason = format!(
                "satellite {} appears again later in the same epoch; the later pseudorange is used",
                reading.satellite
            );
            out.events.push(rejected(&track.tag, reading.time_s, KIND, reason));
            continue;
        }
        match observation(shared, frame, reading) {
            Ok(o) => {
                observations.push(o);
                used.push(reading);
            }
            Err(reason) => out.events.push(rejected(&track.tag, reading.time_s, KIND, reason)),
        }
    }
    if used.is_empty() {
        return Ok(());
    }
    let predicted = track.gnss.clock.map(|c| c.predicted(time_s, &shared.settings.gnss));
    let start = track.state.as_ref().filter(|_| !track.is_lost()).map(|s| {
        let m = s.mean();
        if dimensions::<N>() == 3 {
            [m[0], m[2], m[4]]
        } else {
            [m[0], m[2], shared.tag_height_m]
        }
    });
    let solved = solve_epoch::<N>(shared, frame, &observations, time_s, predicted, start);
    let (epoch_fix, clock) = match solved {
        Ok(solved) => solved,
        Err(error) => {
            for reading in &used {
                let reason = format!("the epoch's {} pseudorange(s) give no fix: {error}", observations.len());
                out.events.push(rejected(&track.tag, reading.time_s, KIND, reason));
            }
            return Ok(());
        }
    };
    for &i in &epoch_fix.excluded {
        let reason = format!(
            "satellite {} excluded by the epoch's fault detection (χ² residual test at false-alarm probability {}): \
             residual {:.1} m",
            used[i].satellite, shared.settings.gnss.false_alarm_probability, epoch_fix.residuals_m[i]
        );
        out.events.push(rejected(&track.tag, used[i].time_s, KIND, reason));
    }
    track.gnss.clock = Some(clock);
    out.fixes.push(RawFix {
        method: Some(KIND),
        ..raw_fix(&track.tag, time_s, &epoch_fix.position, &epoch_fix.covariance)
    });
    fix_update(
        shared,
        track,
        time_s,
        &epoch_fix.position,
        &epoch_fix.covariance,
        KIND,
        out,
    )
    .map(|_updated| ())
}

/// A reading as the solver's input: its variance from `std_m` or the elevation at the origin.
fn observation(shared: &Shared, frame: &LocalFrame, reading: &Reading) -> std::result::Result<Pseudorange, String> {
    let std_m = match reading.std_m {
        Some(std_m) => std_m,
        None => {
            let gnss = &shared.settings.gnss;
            let satellite = Vector3::from(reading.satellite_ecef_m);
            elevation_rad(&frame.origin_ecef_m(), &satellite)
                .and_then(|el| elevation_std_m(gnss.pseudorange_std_m, el, gnss.min_elevation_deg.to_radians()))
                .map_err(|error| format!("no noise level for satellite {}: {error}", reading.satellite))?
        }
    };
    Ok(Pseudorange {
        satellite_ecef_m: reading.satellite_ecef_m,
        pseudorange_m: reading.pseudorange_m,
        // a zero standard deviation would make HᵀWH infinite: floor at (1 mm)²
        variance_m2: (std_m * std_m).max(1e-6),
    })
}

/// An epoch's fix on the tracked axes (row-major covariance), and which pseudoranges were
/// excluded with every residual.
struct EpochFix {
    position: Vec<f64>,
    covariance: Vec<f64>,
    excluded: Vec<usize>,
    residuals_m: Vec<f64>,
}

/// Solves the epoch with the clock prediction as the prior (unless the satellites alone put the
/// clock outside its gate: a clock jump), and returns the fix and the updated clock.
fn solve_epoch<const N: usize>(
    shared: &Shared,
    frame: &LocalFrame,
    observations: &[Pseudorange],
    time_s: f64,
    predicted: Option<ReceiverClock>,
    start_enu_m: Option<[f64; 3]>,
) -> rtls_positioning::Result<(EpochFix, ReceiverClock)> {
    let free = PseudorangeOptions {
        start_enu_m,
        false_alarm_probability: shared.settings.gnss.false_alarm_probability,
        ..PseudorangeOptions::default()
    };
    let height = if dimensions::<N>() == 2 {
        shared.settings.tag_height_m
    } else {
        None
    };
    let solve = |options: &PseudorangeOptions| match height {
        Some(h) => pseudorange_fix_at_height(frame, observations, h, options).map(|s| flatten(&s, 2)),
        None => pseudorange_fix(frame, observations, options).map(|s| flatten(&s, dimensions::<N>())),
    };
    // the satellites alone: a check of the clock prediction (and the fix when there is none)
    let alone = solve(&free);
    let prior_holds = match (&predicted, &alone) {
        (Some(clock), Ok((_, bias, variance))) => {
            // NIS of the free bias against the prediction, one degree of freedom
            let innovation = bias - clock.mean[0];
            innovation * innovation / (variance + clock.covariance[(0, 0)]) <= shared.gates[0]
        }
        (Some(_), Err(_)) => true,
        (None, _) => false,
    };
    match predicted.filter(|_| prior_holds) {
        Some(clock) => {
            let with_prior = PseudorangeOptions {
                clock_prior: Some(clock.prior()),
                ..free
            };
            let (fix, bias, variance) = solve(&with_prior)?;
            Ok((fix, clock.with_bias_posterior(bias, variance)))
        }
        None => {
            // no clock yet, or a clock jump: (re)start it from the satellites alone
            let (fix, bias, variance) = alone?;
            Ok((fix, ReceiverClock::start(bias, variance, time_s, &shared.settings.gnss)))
        }
    }
}

/// `(fix on the first d axes, b̂, σ̂²_b)` of a solution.
fn flatten<const D: usize>(s: &PseudorangeSolution<D>, d: usize) -> (EpochFix, f64, f64) {
    let k = d.min(D);
    let position = s.fix.position.iter().take(k).copied().collect();
    let covariance = (0..k * k).map(|i| s.fix.covariance[(i / k, i % k)]).collect();
    (
        EpochFix {
            position,
            covariance,
            excluded: s.excluded.clone(),
            residuals_m: s.residuals_m.clone(),
        },
        s.clock_bias_m,
        s.clock_variance_m2,
    )
}
