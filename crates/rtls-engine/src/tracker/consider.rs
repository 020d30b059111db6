//! The heading channel's error considered in the position filter (Schmidt–Kalman, see
//! [`rtls_estimation::filter::consider_update`]).
//!
//! A speed becomes a velocity along the channel's heading `ψ̂`, so every such velocity carries
//! the channel's error `e_h = [e_ψ, e_b, e_δ]`, and that error persists from one speed to the
//! next (an odometer's heading drifts, a gyro's integrated heading wanders). Taken as fresh
//! noise of each velocity, it would be averaged away and the track would report ellipses far
//! smaller than its error. Instead the track keeps `X = cov(eₓ, e_h)` (`N × 3`):
//!
//! ```text
//! speed s ± σ_s along ψ̂:  z = s u(ψ̂) = H x + J e_h + w,  H = the velocity components,
//!                          J = [s u⊥, 0, 0],  w ~ N(0, σ_s² u uᵀ),  u = (cos ψ̂, sin ψ̂),  u⊥ = (−sin ψ̂, cos ψ̂)
//!                          the Schmidt–Kalman update with P_h, the channel's covariance
//! position filter:         prediction X ← F X;  any other update X ← P⁺ (P⁻)⁻¹ X
//! heading channel:         prediction X ← X Φᵀ;  update X ← X (P_h⁺ (P_h⁻)⁻¹)ᵀ  (super::heading_cross)
//! ```
//! The channel's own course references, made from the track's positions, are taken as
//! independent of `X` (their variance is inflated for that instead, see [`super::heading`]).
//! Under the IMM (`motion_model = "imm"`) the speeds are velocity updates with the heading's
//! variance in `R`, as with `consider_heading_error = false`.
//!
//! # References
//! Schmidt (1966); Simon (2006) §7.5; Groves (2013) §16.2 (odometry's heading error).

use nalgebra::{DMatrix, DVector, Matrix3};
use rtls_estimation::filter::consider_update;
use rtls_estimation::measurement::MeasurementJacobian;

use super::heading_cross::HeadingCross;
use super::noise::{NoiseClass, Source};
use super::output::{Output, UpdateSource};
use super::step::{accept, apply_fading, Prior, Verdict};
use super::track::{rejected, Shared, Track};
use crate::error::Result;

/// A speed `s ± σ_s` along `heading_rad` (the channel's `ψ̂`, turned back by an increment's
/// lag) as a Schmidt–Kalman velocity update with the channel's covariance `P_h`
/// (equations in the [module documentation](self)). Returns whether it was taken.
///
/// # Errors
/// Numerical failures of the prediction or of the update's acceptance; a failed update itself
/// is reported as a rejected record, not an error.
#[allow(clippy::too_many_arguments)]
pub(super) fn speed_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: Prior<N>,
    speed_mps: f64,
    speed_std_mps: f64,
    heading_rad: f64,
    heading_covariance: &Matrix3<f64>,
    kind: &'static str,
    out: &mut Output,
) -> Result<bool> {
    let time_s = prior.state.time_s();
    let (sin, cos) = heading_rad.sin_cos();
    // z = s u,  u = (cos ψ̂, sin ψ̂)
    let z = [speed_mps * cos, speed_mps * sin];
    // H: the horizontal velocity components
    let mut h = MeasurementJacobian::<N>::zeros(2);
    h[(0, 1)] = 1.0;
    h[(1, 3)] = 1.0;
    // J = [s u⊥, 0, 0],  u⊥ = (−sin ψ̂, cos ψ̂)
    let j = DMatrix::from_row_slice(2, 3, &[-speed_mps * sin, 0.0, 0.0, speed_mps * cos, 0.0, 0.0]);
    // w ~ N(0, c λ σ_s² u uᵀ): the speed's own noise, inflated for its correlation in time (c)
    // and scaled by the adaptive noise (λ) as every velocity is
    let noise_source = Source {
        class: NoiseClass::Velocity,
        anchor: usize::MAX,
    };
    let inflation = track.noise.correlation_inflation(
        noise_source,
        time_s,
        shared.settings.adaptive_noise.correlation_s,
        shared.error_correlation.as_ref(),
    );
    let scale = track.noise.scale(NoiseClass::Velocity);
    let speed_variance = inflation * speed_std_mps * speed_std_mps;
    let uut = [cos * cos, cos * sin, cos * sin, sin * sin];
    let r = DMatrix::from_iterator(2, 2, uut.iter().map(|c| scale * speed_variance * c));
    // ν = z − H x⁻  (ê_h = 0: the channel's estimate is unbiased)
    let innovation = DVector::from_column_slice(&z) - &h * prior.state.mean();
    let cross = track
        .heading_cross
        .map_or_else(nalgebra::SMatrix::zeros, |held| held.predicted(time_s));
    match consider_update(&prior.state, &cross, heading_covariance, &h, &j, &r, innovation) {
        Ok(result) => {
            let gate = shared.gates[1];
            let updated = result.updated;
            // A = I − K H, for the state's cross-covariance with the range offsets
            let a = rtls_estimation::Matrix::<N>::identity() - &updated.gain * &h;
            out.innovations.record(NoiseClass::Velocity, &updated, gate, scale);
            // what the velocity's noise would be with the heading's error as fresh noise:
            // the adaptive scale is learnt against it
            // R = σ_s² u uᵀ + s² P_ψψ u⊥ u⊥ᵀ
            let across = heading_covariance[(0, 0)] * speed_mps * speed_mps;
            let u_perp_u_perp_t = [sin * sin, -sin * cos, -sin * cos, cos * cos];
            let stated: Vec<f64> = uut
                .iter()
                .zip(u_perp_u_perp_t)
                .map(|(along, perp)| speed_variance * along + across * perp)
                .collect();
            track
                .noise
                .observe(shared.adaptive.as_ref(), NoiseClass::Velocity, &updated, &stated, gate);
            track
                .noise
                .observe_correlation(shared.error_correlation.as_ref(), noise_source, &updated);
            let taken = accept(
                shared,
                track,
                (&prior.state, updated),
                None,
                kind,
                UpdateSource::Velocity,
                out,
            )? == Verdict::Taken;
            if taken {
                track.heading_cross = Some(HeadingCross::new(time_s, result.cross_covariance));
                // X_b ← (I − K H) F X_b: the speed does not involve the offsets
                track.offset_cross = track.offset_cross.as_ref().map(|cross| cross.after_gain(time_s, &a));
                apply_fading(track)?;
            }
            Ok(taken)
        }
        Err(error) => {
            let reason = format!("velocity update failed: {error}");
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            Ok(false)
        }
    }
}
