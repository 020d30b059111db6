//! Direct measurements of a track's state — position fixes (`fix` records, fingerprint scans),
//! velocities and odometry — and their time order with the fix-then-filter pipeline's epochs.
//!
//! A fix-then-filter epoch's fix is dated at its readings' mean time and applied when the epoch
//! closes. A direct measurement that arrives while an epoch is open is therefore held, and
//! applied in time order when the epoch closes: those dated before the fix first, then the
//! fix, then the others. Applied at once, it would move the state past the fix's time, and the
//! fix's prediction would go backwards in time.

use super::heading;
use super::output::raw_fix;
use super::output::Output;
use super::track::{dimensions, rejected, Shared, Track};
use super::update::{fix_update, velocity_update};
use crate::error::Result;
use crate::record::Measurement;
use crate::site::Pipeline;

/// A direct measurement: applied now, or held until the open fix-then-filter epoch closes
/// (see the [module documentation](self)).
///
/// # Errors
/// As [`apply_direct`].
pub(super) fn direct_measurement<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    measurement: &Measurement,
    out: &mut Output,
) -> Result<()> {
    if shared.settings.pipeline == Pipeline::FixThenFilter && !track.epoch.is_empty() {
        track.deferred.push((time_s, measurement.clone()));
        return Ok(());
    }
    apply_direct(shared, track, time_s, measurement, out)
}

/// Applies the held direct measurements dated strictly before `before_s`, in time order
/// (`f64::INFINITY`: all of them).
///
/// # Errors
/// As [`apply_direct`]; the measurements after a failing one stay held.
pub(crate) fn apply_deferred<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    before_s: f64,
    out: &mut Output,
) -> Result<()> {
    // held in arrival order, which is time order
    let due = track.deferred.iter().take_while(|(t, _)| *t < before_s).count();
    let held: Vec<(f64, Measurement)> = track.deferred.drain(..due).collect();
    for (time_s, measurement) in &held {
        apply_direct(shared, track, *time_s, measurement, out)?;
    }
    Ok(())
}

/// Applies a position fix, fingerprint scan, velocity or odometry record to the track; one
/// that cannot be used is reported as rejected.
///
/// Odometry becomes a velocity with the positive definite covariance of
/// [`odometry_velocity`] (standstill and exact headings included).
///
/// # Errors
/// Numerical failures of the prediction or the lifecycle.
pub(super) fn apply_direct<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    measurement: &Measurement,
    out: &mut Output,
) -> Result<()> {
    let d = dimensions::<N>();
    match measurement {
        Measurement::Fix {
            position_m,
            covariance_m2,
        } => {
            let k = position_m.len();
            if k < d {
                let reason = format!("a {k}-D fix cannot update a {d}-D track");
                out.events.push(rejected(&track.tag, time_s, "fix", reason));
                return Ok(());
            }
            // the tracked axes: the leading D × D block
            let mut covariance = [0.0; 9];
            for (i, c) in covariance.iter_mut().enumerate().take(d * d) {
                *c = covariance_m2[(i / d) * k + i % d];
            }
            fix_update(
                shared,
                track,
                time_s,
                &position_m[..d],
                &covariance[..d * d],
                "fix",
                out,
            )
            .map(|_updated| ())
        }
        Measurement::RssiVector { readings } => match &shared.radio_map {
            None => {
                let reason = "no fingerprint radio map is loaded (site [fingerprints])".to_string();
                out.events.push(rejected(&track.tag, time_s, "rssi_vector", reason));
                Ok(())
            }
            Some(map) => match map.locate(readings) {
                Ok(fix) => {
                    let c = fix.covariance_m2;
                    let covariance = [c[0][0], c[0][1], c[1][0], c[1][1]];
                    out.fixes
                        .push(raw_fix(&track.tag, time_s, &fix.position_m, &covariance));
                    fix_update(shared, track, time_s, &fix.position_m, &covariance, "rssi_vector", out)
                        .map(|_updated| ())
                }
                Err(error) => {
                    let reason = format!("fingerprint fix failed: {error}");
                    out.events.push(rejected(&track.tag, time_s, "rssi_vector", reason));
                    Ok(())
                }
            },
        },
        Measurement::Velocity {
            velocity_mps,
            covariance_m2ps2,
        } => {
            let k = velocity_mps.len().min(d);
            let Some(c) = covariance_m2ps2 else {
                let reason = "a velocity needs `covariance_m2ps2`".to_string();
                out.events.push(rejected(&track.tag, time_s, "velocity", reason));
                return Ok(());
            };
            let covariance: Vec<f64> = (0..k * k).map(|i| c[(i / k) * velocity_mps.len() + i % k]).collect();
            velocity_update(shared, track, time_s, &velocity_mps[..k], &covariance, "velocity", out)
        }
        Measurement::Odometry {
            speed_mps,
            heading_rad,
            speed_std_mps,
            heading_std_rad,
        } => heading::odometry(
            shared,
            track,
            time_s,
            *speed_mps,
            *heading_rad,
            *speed_std_mps,
            *heading_std_rad,
            "odometry",
            out,
        ),
        Measurement::YawRate {
            yaw_rate_radps,
            std_radps,
        } => heading::yaw_rate(shared, track, time_s, *yaw_rate_radps, *std_radps),
        Measurement::OdometryIncrement {
            distance_m,
            yaw_change_rad,
            interval_s,
            distance_std_m,
            yaw_change_std_rad,
        } => heading::increment(
            shared,
            track,
            time_s,
            *distance_m,
            *yaw_change_rad,
            *interval_s,
            *distance_std_m,
            *yaw_change_std_rad,
            "odometry_increment",
            out,
        ),
        Measurement::Imu {
            acceleration_mps2,
            angular_rate_radps,
            std_radps,
            ..
        } => heading::imu(shared, track, time_s, acceleration_mps2, angular_rate_radps, *std_radps),
        Measurement::Range { .. }
        | Measurement::Rssi { .. }
        | Measurement::Tdoa { .. }
        | Measurement::Accelerometer { .. }
        | Measurement::Pseudorange { .. } => Ok(()),
    }
}
