//! The track's heading channel ([`HeadingModel`]: heading `ψ`, gyro bias `b_g`, odometer
//! heading offset `δ`) and the records that use it: `yaw_rate`, `odometry` (with or without a
//! heading), `odometry_increment` and body-frame `imu` samples.
//!
//! - A **yaw rate** (a `yaw_rate` record, an increment's change of heading over its interval,
//!   an IMU's rate about the vertical) is held until the next one and integrated into `ψ`,
//!   minus the estimated bias.
//! - **Heading references** calibrate the channel: an odometer's heading (`z = ψ + δ`) and,
//!   with `course_is_heading` (a vehicle, a robot, a walker carrying the sensor facing forward),
//!   the course over ground: the direction of the chord between two of the track's positions
//!   after position updates (fixes or anchor measurements), at least
//!   [`COURSE_MIN_INTERVAL_S`] apart and far enough apart that the chord's direction is known
//!   to [`MAX_HEADING_STD_RAD`]. A chord's direction is the heading at its middle when the
//!   rate of turn is constant, so it is carried to the present by the yaw rates integrated
//!   since (`z = atan2(Δy, Δx) + θ_now − (θ₁ + θ₂)/2`, `θ` the integrated bias-corrected rate).
//!   Chords do not overlap, and their variance is ×[`COURSE_VARIANCE_INFLATION`] (the
//!   positions are filtered, so they carry some of the odometry the heading produced). The
//!   track's velocity is not used: it holds the odometry's own heading, and the loop would
//!   confirm any heading error.
//! - A **speed** (`odometry`, an increment's distance over its interval) becomes a velocity
//!   along `ψ̂` with the heading's variance ([`odometry_velocity`]) once the channel is aligned
//!   (`σ_ψ ≤` [`MAX_HEADING_STD_RAD`]); before that it is rejected with the reason.
//! - A body-frame **IMU** sample gives the rate about the vertical, `ω·û` with `û` the
//!   low-passed specific force (gravity; the sensor may be tilted) when it has three axes, else
//!   its `z` rate (sensor level). Its horizontal specific force, rotated by `ψ̂` into the site
//!   frame, drives the CV prediction only with `imu_acceleration = true` (an uncalibrated
//!   accelerometer's bias and tilt leakage integrate into velocity errors the CV model's noise
//!   does not cover).
//!
//! The channel starts unaligned (`ψ = 0 ± π`): the first reference aligns it; rates before
//! that still integrate, so the heading changes they measured are kept.
//!
//! # References
//! Groves (2013) §14.1, §16.2; seed 004 (odometry with heading drift).

use rtls_estimation::aided::{odometry_velocity, HeadingModel, HeadingState};

use super::aided::HeldAcceleration;
use super::consider;
use super::heading_state::{
    COURSE_MIN_INTERVAL_S, COURSE_VARIANCE_INFLATION, GATE_SIGMAS, GRAVITY_MPS2, GRAVITY_TIME_CONSTANT_S,
    MAX_HEADING_STD_RAD, RATE_HOLD_S,
};
use super::output::Output;
use super::track::{rejected, Shared, Track};
use super::update::{velocity_prior, velocity_update};
use crate::error::Result;

/// Predicts the channel to `time_s` with the held rate (a random walk without a recent one),
/// starting it unaligned if it has no state.
fn advance<const N: usize>(model: &HeadingModel, track: &mut Track<N>, time_s: f64) -> Result<()> {
    let state = match track.heading.state {
        Some(state) => state,
        None => {
            // a new channel's error is not the one the track's state was correlated with
            track.heading_cross = None;
            // ψ = 0 ± π: unaligned; the first reference sets it
            model.start(time_s, 0.0, core::f64::consts::PI * core::f64::consts::PI)?
        }
    };
    let channel = &mut track.heading;
    if time_s <= state.time_s() {
        channel.state = Some(state);
        return Ok(());
    }
    // a gyro's rate holds for RATE_HOLD_S; an odometer's covers exactly its record's interval
    let from_odometer = channel.rate_from_odometer;
    let rate = channel
        .rate
        .filter(|(t, _, _)| from_odometer || time_s - t <= RATE_HOLD_S)
        .map(|(_, w, v)| (w, v));
    if let Some((w, _)) = rate {
        // θ ← θ + (ω − b̂_g) Δt
        let corrected = w - state.gyro_bias().0;
        channel.integrated_rad += corrected * (time_s - state.time_s());
        channel.integrated_time_s = time_s;
        channel.integrated_rate_radps = corrected;
    }
    channel.state = Some(model.propagate(&state, time_s, rate)?);
    // X ← X Φᵀ
    if let Some(cross) = track.heading_cross.as_mut() {
        cross.after_heading_prediction(time_s - state.time_s(), rate.is_some());
    }
    Ok(())
}

/// Takes the channel's update from `prior` to `posterior` into the track's cross-covariance
/// with it (`X ← X (P_h⁺ (P_h⁻)⁻¹)ᵀ`).
fn set_updated<const N: usize>(track: &mut Track<N>, prior: &HeadingState, posterior: HeadingState) {
    track.heading_cross = track
        .heading_cross
        .and_then(|cross| cross.after_heading_update(prior.gaussian().covariance(), posterior.gaussian().covariance()));
    track.heading.state = Some(posterior);
}

/// Takes the course over ground, the direction of the chord between two positions after
/// position updates, as a heading reference when `course_is_heading` and the chord is long
/// enough (see the [module documentation](self)).
fn observe_course<const N: usize>(shared: &Shared, model: &HeadingModel, track: &mut Track<N>) -> Result<()> {
    let settings = &shared.settings.heading;
    let channel = &track.heading;
    if !settings.course_is_heading {
        return Ok(());
    }
    let (Some(start), Some(end), Some(heading)) = (channel.chord_start, channel.chord_end, channel.state) else {
        return Ok(());
    };
    let duration_s = end.time_s - start.time_s;
    let (dx, dy) = (
        end.position_m[0] - start.position_m[0],
        end.position_m[1] - start.position_m[1],
    );
    let length_m = dx.hypot(dy);
    if duration_s < COURSE_MIN_INTERVAL_S || length_m < settings.course_min_speed_mps * duration_s {
        return Ok(());
    }
    // σ²_chord = u⊥ᵀ (P₁ + P₂) u⊥ / d²,  u⊥ = (−Δy, Δx)/d
    let (ux, uy) = (-dy / length_m, dx / length_m);
    let [axx, axy, ayy] = start.covariance_m2;
    let [bxx, bxy, byy] = end.covariance_m2;
    let across = ux * ux * (axx + bxx) + 2.0 * ux * uy * (axy + bxy) + uy * uy * (ayy + byy);
    let chord_variance = across / (length_m * length_m);
    // R = c σ²_chord + σ_slip²
    let slip = settings.course_heading_std_rad;
    let variance = COURSE_VARIANCE_INFLATION * chord_variance + slip * slip;
    if !(variance.is_finite() && variance > 0.0 && variance.sqrt() <= MAX_HEADING_STD_RAD) {
        return Ok(());
    }
    // z = atan2(Δy, Δx) + θ_now − (θ₁ + θ₂)/2
    let turned = channel.integrated_rad - 0.5 * (start.integrated_rad + end.integrated_rad);
    let course = dy.atan2(dx) + turned;
    if let Some(updated) = model.observe_heading(&heading, course, variance, GATE_SIGMAS)? {
        set_updated(track, &heading, updated);
        track.heading.course_times_s = (track.heading.course_times_s.1, Some(end.time_s));
    }
    // the next chord starts where this one ended: chords do not share information
    track.heading.chord_start = Some(end);
    track.heading.chord_end = None;
    Ok(())
}

/// Brings the channel to `time_s` and takes the course if due.
fn prepare<const N: usize>(shared: &Shared, track: &mut Track<N>, time_s: f64) -> Result<()> {
    let model = &shared.heading_model;
    advance(model, track, time_s)?;
    observe_course(shared, model, track)
}

/// Holds a yaw rate `ω` (rad/s) with variance `σ²` measured at `time_s`.
fn hold_rate<const N: usize>(track: &mut Track<N>, time_s: f64, rate_radps: f64, variance: f64) {
    track.heading.rate = Some((time_s, rate_radps, variance));
    track.heading.rate_from_odometer = false;
}

/// A `yaw_rate` record.
///
/// # Errors
/// Numerical failures of the channel (non-finite values).
pub(super) fn yaw_rate<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    rate_radps: f64,
    std_radps: Option<f64>,
) -> Result<()> {
    prepare(shared, track, time_s)?;
    let std = std_radps.unwrap_or(shared.settings.heading.gyro_noise_std_radps);
    hold_rate(track, time_s, rate_radps, std * std);
    Ok(())
}

/// An `odometry` record: a speed along the record's heading (an odometer heading, whose offset
/// the channel estimates) or, without one, along the channel's heading.
///
/// # Errors
/// Numerical failures of the channel or of the velocity update.
#[allow(clippy::too_many_arguments)]
pub(super) fn odometry<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    speed_mps: f64,
    heading_rad: Option<f64>,
    speed_std_mps: Option<f64>,
    heading_std_rad: Option<f64>,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(speed_std) = speed_std_mps else {
        let reason = "odometry needs `speed_std_mps`".to_string();
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(());
    };
    // the odometer heading and its std, checked before the record touches the channel
    let odometer = match (heading_rad, heading_std_rad) {
        (Some(heading), Some(std)) => Some((heading, std)),
        (Some(_), None) => {
            let reason = "odometry with `heading_rad` needs `heading_std_rad`".to_string();
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            return Ok(());
        }
        (None, _) => None,
    };
    if let Some((heading, _)) = odometer {
        // without a gyro, the odometer's heading change since its previous record is the yaw
        // rate over that interval, ω = wrap(z − z_prev) / Δt (an odometer's relative heading is
        // good even when its absolute heading drifts); the rate goes in with the gyro bias
        // added back, ω + b̂_g, so the channel's ψ ← ψ + (ω + b̂_g − b̂_g) Δt follows it
        let channel = &mut track.heading;
        let gyro_fresh = !channel.rate_from_odometer && channel.rate.is_some_and(|(t, _, _)| time_s - t <= RATE_HOLD_S);
        if let (false, Some((previous_s, previous))) = (gyro_fresh, channel.odometer_heading) {
            if time_s > previous_s {
                let rate = rtls_estimation::wrap_angle(heading - previous) / (time_s - previous_s);
                let bias = channel.state.map_or(0.0, |s| s.gyro_bias().0);
                let std = shared.settings.heading.gyro_noise_std_radps;
                channel.rate = Some((previous_s, rate + bias, std * std));
                channel.rate_from_odometer = true;
            }
        }
        channel.odometer_heading = Some((time_s, heading));
    }
    prepare(shared, track, time_s)?;
    if track.heading.rate_from_odometer {
        // used for its interval; the next odometry record brings the next one
        track.heading.rate = None;
        track.heading.rate_from_odometer = false;
    }
    // prepare() leaves the channel with a state (started unaligned if it had none)
    if let (Some((heading, heading_std)), Some(state)) = (odometer, track.heading.state) {
        // an odometer's heading error is accumulated: the growth of its stated variance since
        // the previous record is its offset drifting, P_δδ ← P_δδ + max(0, σₖ² − σₖ₋₁²), and
        // only the smallest std it has stated is a fresh error of each record, v (floored: a
        // heading is never exact); z = ψ + δ + v
        let (previous_std, white_std) = track
            .heading
            .odometer_std_rad
            .map_or((heading_std, heading_std), |(previous, white)| {
                (previous, white.min(heading_std))
            });
        track.heading.odometer_std_rad = Some((heading_std, white_std));
        let growth = (heading_std * heading_std - previous_std * previous_std).max(0.0);
        let state = shared.heading_model.drift_odometer_offset(&state, growth)?;
        let variance = white_std.max(1e-4).powi(2);
        match shared
            .heading_model
            .observe_odometer_heading(&state, heading, variance, GATE_SIGMAS)?
        {
            Some(updated) => set_updated(track, &state, updated),
            None => {
                let (psi, std) = (state.heading_rad(), state.heading_variance_rad2().sqrt());
                let reason = format!(
                    "odometer heading {heading:.3} rad is more than {GATE_SIGMAS} σ from the track's \
                     heading {psi:.3} ± {std:.3} rad (offset included)"
                );
                out.events.push(rejected(&track.tag, time_s, kind, reason));
                return Ok(());
            }
        }
    }
    speed_update(shared, track, time_s, speed_mps, speed_std, 0.0, kind, out)
}

/// The largest heading std a speed is turned into a velocity with after the inflation for
/// the heading error's correlation, rad.
const INFLATED_HEADING_STD_MAX_RAD: f64 = 1.0;

/// A speed `s ± σ_s` along the channel's heading, turned back by `lag_rad` (an increment's
/// mean direction is half its change of heading behind its end).
#[allow(clippy::too_many_arguments)]
fn speed_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    speed_mps: f64,
    speed_std_mps: f64,
    lag_rad: f64,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some((heading, heading_std)) = track.heading.heading() else {
        let std = track
            .heading
            .state
            .map_or(f64::INFINITY, |s| s.heading_variance_rad2().sqrt());
        let reason = format!(
            "the heading is not known well enough to turn the speed into a velocity (σ {:.0}° > {:.0}°): give \
             `heading_rad`, or let the track move at ≥ {} m/s so its course aligns the heading",
            std.to_degrees(),
            MAX_HEADING_STD_RAD.to_degrees(),
            shared.settings.heading.course_min_speed_mps
        );
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(());
    };
    // the heading's error persists over τ_ψ (until the next course reference renews it, at most
    // heading_error_correlation_s): its part of the velocity's variance is inflated by
    // c_ψ = max(1, 2 τ_ψ / Δt) in all, of which the velocity update applies max(1, 2 τ_c / Δt)
    // to the whole covariance; σ_ψ ← σ_ψ √(c_ψ / c)
    let elapsed_s = track
        .heading
        .last_speed_s
        .replace(time_s)
        .map_or(f64::INFINITY, |previous_s| (time_s - previous_s).max(1e-3));
    // (an aligned heading above means the channel has a state)
    let channel = track
        .heading
        .state
        .filter(|_| shared.settings.heading.consider_heading_error && shared.manoeuvres.is_none());
    if let Some(channel) = channel {
        // the heading's error considered: the track keeps its cross-covariance with it
        let Some(prior) = velocity_prior(shared, track, time_s, kind, out)? else {
            return Ok(());
        };
        let covariance = *channel.gaussian().covariance();
        return consider::speed_update(
            shared,
            track,
            prior,
            speed_mps,
            speed_std_mps,
            heading - lag_rad,
            &covariance,
            kind,
            out,
        )
        .map(|_taken| ());
    }
    let correlated = |tau_s: f64| (2.0 * tau_s / elapsed_s).max(1.0);
    let persists_s = track
        .heading
        .error_correlation_s(time_s, shared.settings.heading.heading_error_correlation_s);
    let extra = correlated(persists_s) / correlated(shared.settings.adaptive_noise.correlation_s);
    // (at most 1 rad: beyond it the across-track σ exceeds the speed and says only that the
    // direction is unknown)
    let heading_std = (heading_std * extra.max(1.0).sqrt()).min(INFLATED_HEADING_STD_MAX_RAD);
    match odometry_velocity(speed_mps, heading - lag_rad, speed_std_mps, heading_std) {
        Ok((v, r)) => {
            // the horizontal velocity (in 3-D the vertical one is left to the other sensors)
            let covariance = [r[(0, 0)], r[(0, 1)], r[(1, 0)], r[(1, 1)]];
            velocity_update(shared, track, time_s, &[v[0], v[1]], &covariance, kind, out)
        }
        Err(error) => {
            let reason = format!("odometry cannot be used: {error}");
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            Ok(())
        }
    }
}

/// An `odometry_increment` record: distance `d` and change of heading `Δψ` over `T` ending at
/// `time_s` — a yaw rate `Δψ/T` over the interval and a speed `d/T` along its mean heading.
///
/// # Errors
/// Numerical failures of the channel or of the velocity update.
#[allow(clippy::too_many_arguments)]
pub(super) fn increment<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    distance_m: f64,
    yaw_change_rad: f64,
    interval_s: f64,
    distance_std_m: Option<f64>,
    yaw_change_std_rad: Option<f64>,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(distance_std) = distance_std_m else {
        let reason = "an odometry increment needs `distance_std_m`".to_string();
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(());
    };
    // the interval's start: up to there the previous rate holds
    let start_s = time_s - interval_s;
    if track.heading.state.is_some_and(|s| start_s > s.time_s()) {
        advance(&shared.heading_model, track, start_s)?;
    }
    // ω = Δψ / T, σ_ω = σ_Δψ / T
    let rate = yaw_change_rad / interval_s;
    let rate_std = yaw_change_std_rad.map_or(shared.settings.heading.gyro_noise_std_radps, |s| s / interval_s);
    hold_rate(
        track,
        start_s.max(track.heading.rate.map_or(start_s, |r| r.0)),
        rate,
        rate_std * rate_std,
    );
    prepare(shared, track, time_s)?;
    // s = d / T, σ_s = σ_d / T, along ψ̂ − Δψ/2
    let speed = distance_m / interval_s;
    let speed_std = distance_std / interval_s;
    speed_update(shared, track, time_s, speed, speed_std, yaw_change_rad / 2.0, kind, out)
}

/// An `imu` record: the rate about the vertical into the channel; with `imu_acceleration`, the
/// horizontal specific force rotated into the site frame as the CV model's control input.
///
/// # Errors
/// Numerical failures of the channel.
pub(super) fn imu<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    acceleration_mps2: &[f64],
    angular_rate_radps: &[f64],
    std_radps: Option<f64>,
) -> Result<()> {
    let (vertical_rate, forward_left) = body_to_level(track, time_s, acceleration_mps2, angular_rate_radps);
    prepare(shared, track, time_s)?;
    let std = std_radps.unwrap_or(shared.settings.heading.gyro_noise_std_radps);
    hold_rate(track, time_s, vertical_rate, std * std);
    if shared.settings.heading.imu_acceleration {
        if let (Some((heading, _)), Some([forward, left])) = (track.heading.heading(), forward_left) {
            // a = R(ψ) [a_fwd, a_left]ᵀ
            let (sin, cos) = heading.sin_cos();
            let a = [cos * forward - sin * left, sin * forward + cos * left, 0.0];
            // the IMU record states no accelerometer noise: the residual noise covers it
            track.acceleration = Some(HeldAcceleration {
                time_s,
                acceleration_mps2: a,
                std_mps2: 0.0,
            });
        }
    }
    Ok(())
}

/// The rate about the vertical (rad/s) and the horizontal specific force `[forward, left]`
/// (m/s²) of a body-frame sample.
///
/// With three axes of both: `û = ĝ/‖ĝ‖` from the low-passed specific force, `ω_v = ω·û`,
/// `x_h = (x_b − (x_b·û)û)/‖…‖`, `y_h = û × x_h`, `f_fwd = f·x_h`, `f_left = f·y_h`.
/// Otherwise the sensor is taken level: `ω_v = ω_z`, `[f_x, f_y]`.
fn body_to_level<const N: usize>(
    track: &mut Track<N>,
    time_s: f64,
    acceleration_mps2: &[f64],
    angular_rate_radps: &[f64],
) -> (f64, Option<[f64; 2]>) {
    // shapes are validated by the parsers; a record built in code with other shapes gives what
    // it can (no rate: 0, no horizontal force: none) rather than a panic
    let rate_z = angular_rate_radps.last().copied().unwrap_or(0.0);
    let ([fx, fy, fz], [wx, wy, wz]) = match (acceleration_mps2, angular_rate_radps) {
        ([fx, fy, fz], [wx, wy, wz]) => ([*fx, *fy, *fz], [*wx, *wy, *wz]),
        ([fx, fy, ..], _) => return (rate_z, Some([*fx, *fy])),
        _ => return (rate_z, None),
    };
    // ĝ ← ĝ + α (f − ĝ),  α = min(1, Δt / τ)
    let f = [fx, fy, fz];
    let g = match track.heading.gravity {
        Some((t, g)) => {
            let alpha = ((time_s - t) / GRAVITY_TIME_CONSTANT_S).clamp(0.0, 1.0);
            [
                g[0] + alpha * (f[0] - g[0]),
                g[1] + alpha * (f[1] - g[1]),
                g[2] + alpha * (f[2] - g[2]),
            ]
        }
        None => f,
    };
    track.heading.gravity = Some((time_s, g));
    let norm = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if !(0.5 * GRAVITY_MPS2..=1.5 * GRAVITY_MPS2).contains(&norm) {
        // no gravity to level with (free fall, a bad axis): take the sensor level
        return (wz, Some([fx, fy]));
    }
    let up = [g[0] / norm, g[1] / norm, g[2] / norm];
    // ω_v = ω · û
    let vertical_rate = wx * up[0] + wy * up[1] + wz * up[2];
    // x_h = x_b − (x_b·û) û, normalised
    let xh = [1.0 - up[0] * up[0], -up[0] * up[1], -up[0] * up[2]];
    let xh_norm = (xh[0] * xh[0] + xh[1] * xh[1] + xh[2] * xh[2]).sqrt();
    if xh_norm < 0.1 {
        // the sensor's x axis points (nearly) up: no forward direction
        return (vertical_rate, None);
    }
    let xh = [xh[0] / xh_norm, xh[1] / xh_norm, xh[2] / xh_norm];
    // y_h = û × x_h
    let yh = [
        up[1] * xh[2] - up[2] * xh[1],
        up[2] * xh[0] - up[0] * xh[2],
        up[0] * xh[1] - up[1] * xh[0],
    ];
    let forward = f[0] * xh[0] + f[1] * xh[1] + f[2] * xh[2];
    let left = f[0] * yh[0] + f[1] * yh[1] + f[2] * yh[2];
    (vertical_rate, Some([forward, left]))
}
