//! GNSS pseudoranges: WGS-84 geodetic ↔ ECEF ↔ local ENU coordinates, the Earth-rotation
//! (Sagnac) correction, elevation-dependent noise, and a weighted least-squares point solver for
//! position and receiver clock bias with RAIM-style fault detection and exclusion.
//!
//! A pseudorange to satellite `i` is modelled as
//! ```text
//! ρ_i = ‖R_z(ω_E τ_i) s_i − p‖ + b + v_i,   v_i ~ N(0, σ_i²)
//! ```
//! with `s_i` the satellite's ECEF position at transmit time, `p` the receiver's ECEF position,
//! `τ_i` the signal's transit time, `b = c δt` the receiver clock bias (m) and the satellite
//! clock, ionosphere and troposphere already removed by the sender. Positions are solved in a
//! [`LocalFrame`] (east, north, up about a geodetic origin), so a site's planar coordinates
//! and a GNSS fix share one frame.
//!
//! - [`Geodetic`], [`LocalFrame`], [`elevation_rad`] — coordinates (Heikkinen's closed form for
//!   ECEF → geodetic).
//! - [`earth_rotation_correction`] — the Sagnac correction of a satellite position.
//! - [`elevation_std_m`] — `σ(el) = σ₀ / sin(max(el, el_min))` for a pseudorange without a
//!   stated noise.
//! - [`pseudorange_fix`] (3-D) and [`pseudorange_fix_at_height`] (planar, at a known height in
//!   the local frame) — weighted Gauss–Newton for `[p, b]` with an optional Gaussian prior on
//!   `b` (a predicted clock), the joint covariance, DOP, residuals and fault exclusion
//!   ([`PseudorangeSolution`]).
//!
//! # References
//! P. Misra, P. Enge, *Global Positioning System: Signals, Measurements, and Performance*,
//! 2nd ed., 2006 (pseudorange model, least-squares navigation solution, DOP, RAIM);
//! IS-GPS-200 (the Earth's rotation during signal transit); R. G. Brown, "A baseline GPS RAIM
//! scheme and a note on the equivalence of three RAIM methods", *Navigation* 39(3), 1992.

mod geodetic;
#[cfg(test)]
mod geodetic_tests;
mod pseudorange;
#[cfg(test)]
mod tests;

pub use geodetic::{elevation_rad, Geodetic, LocalFrame, WGS84_A_M, WGS84_F};
pub use pseudorange::{
    pseudorange_fix, pseudorange_fix_at_height, ClockPrior, GnssDop, Integrity, Pseudorange, PseudorangeOptions,
    PseudorangeSolution,
};

use nalgebra::Vector3;

use crate::error::{PositioningError, Result};

/// The WGS-84 value of the Earth's rotation rate `ω_E`, rad/s (IS-GPS-200, Table 20-IV).
pub const EARTH_ROTATION_RATE_RADPS: f64 = 7.292_115_146_7e-5;

/// The speed of light in vacuum `c`, m/s (exact, and IS-GPS-200's value).
pub const SPEED_OF_LIGHT_MPS: f64 = 299_792_458.0;

/// The elevation below which [`elevation_std_m`] stops growing, by default, degrees.
pub const DEFAULT_MIN_ELEVATION_DEG: f64 = 5.0;

/// The satellite position in the ECEF frame of the time of reception: the Earth turns by
/// `ω_E τ` while the signal travels, so a position given in the ECEF frame of the time of
/// transmission is rotated about the `z` axis by that angle (the Sagnac correction; up to
/// about 30 m of range).
///
/// ```text
/// τ = ‖s − r‖ / c                                  transit time (geometric, s)
/// θ = ω_E τ
///        ⎡  cos θ   sin θ   0 ⎤
/// s' =   ⎢ −sin θ   cos θ   0 ⎥ s
///        ⎣   0       0      1 ⎦
/// ```
/// `τ` is computed from the uncorrected position; iterating it changes `s'` by less than a
/// micrometre (`ω_E ‖s‖ Δτ` with `Δτ ≈ ω_E ‖s‖ τ / c`).
///
/// # Units
/// ECEF positions in m.
///
/// # Errors
/// [`PositioningError::NonFinite`] for a NaN/∞ coordinate.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use rtls_positioning::gnss::earth_rotation_correction;
/// let receiver = Vector3::new(6_378_137.0, 0.0, 0.0);
/// let satellite = Vector3::new(15_600e3, 7_540e3, 20_140e3);
/// let rotated = earth_rotation_correction(&satellite, &receiver)?;
/// // the same distance from the Earth's centre, moved west along an arc ω_E τ ‖s_xy‖ ≈ 99 m
/// assert!((rotated.norm() - satellite.norm()).abs() < 1e-6);
/// assert!(((rotated - satellite).norm() - 98.6).abs() < 0.5);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// IS-GPS-200, §20.3.3.4.3.3.2 (the ECEF frame rotates during the signal's transit);
/// Misra & Enge, *Global Positioning System*, 2nd ed., 2006 (the Earth-rotation correction of
/// the navigation solution); N. Ashby, "Relativity in the Global Positioning System", *Living
/// Rev. Relativ.* 6(1), 2003, §5 (the Sagnac effect).
pub fn earth_rotation_correction(
    satellite_ecef_m: &Vector3<f64>,
    receiver_ecef_m: &Vector3<f64>,
) -> Result<Vector3<f64>> {
    if !satellite_ecef_m
        .iter()
        .chain(receiver_ecef_m.iter())
        .all(|v| v.is_finite())
    {
        return Err(PositioningError::NonFinite {
            what: "satellite or receiver position",
        });
    }
    Ok(rotate_for_transit(satellite_ecef_m, receiver_ecef_m))
}

/// [`earth_rotation_correction`] on finite inputs.
pub(crate) fn rotate_for_transit(satellite: &Vector3<f64>, receiver: &Vector3<f64>) -> Vector3<f64> {
    // τ = ‖s − r‖ / c,  θ = ω_E τ
    let theta = EARTH_ROTATION_RATE_RADPS * (satellite - receiver).norm() / SPEED_OF_LIGHT_MPS;
    let (sin, cos) = theta.sin_cos();
    // s' = R_z(θ) s
    Vector3::new(
        cos * satellite[0] + sin * satellite[1],
        -sin * satellite[0] + cos * satellite[1],
        satellite[2],
    )
}

/// The elevation-dependent standard deviation of a pseudorange, for one whose sender states
/// none: low satellites travel a longer path through the atmosphere and suffer more multipath.
///
/// ```text
/// σ(el) = σ₀ / sin(max(el, el_min))
/// ```
///
/// # Units
/// `zenith_std_m` (`σ₀`, the standard deviation at the zenith) and the result in m; angles in
/// rad.
///
/// # Errors
/// [`PositioningError::InvalidParameter`] for `σ₀ ≤ 0` or non-finite (`zenith_std_m`), for
/// `el_min` outside (0, π/2] (`min_elevation_rad`), or a non-finite elevation
/// (`elevation_rad`).
///
/// # Example
/// ```
/// use rtls_positioning::gnss::elevation_std_m;
/// let floor = 5f64.to_radians();
/// assert!((elevation_std_m(3.0, std::f64::consts::FRAC_PI_2, floor)? - 3.0).abs() < 1e-12);
/// assert!((elevation_std_m(3.0, 30f64.to_radians(), floor)? - 6.0).abs() < 1e-12);
/// // below the floor (or below the horizon) the floor's value
/// assert_eq!(elevation_std_m(3.0, -0.1, floor)?, elevation_std_m(3.0, floor, floor)?);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Kaplan & Hegarty, *Understanding GPS/GNSS*, 3rd ed., 2017, §11 (elevation-dependent
/// weighting); H. Dach et al., *Bernese GNSS Software 5.2*, 2015 (the `1/sin(el)` model).
pub fn elevation_std_m(zenith_std_m: f64, elevation_rad: f64, min_elevation_rad: f64) -> Result<f64> {
    if !(zenith_std_m.is_finite() && zenith_std_m > 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "zenith_std_m",
            reason: "the zenith standard deviation must be finite and > 0",
        });
    }
    if !(min_elevation_rad > 0.0 && min_elevation_rad <= core::f64::consts::FRAC_PI_2) {
        return Err(PositioningError::InvalidParameter {
            name: "min_elevation_rad",
            reason: "the elevation floor must lie in (0, pi/2] rad, e.g. 5 degrees",
        });
    }
    if !elevation_rad.is_finite() {
        return Err(PositioningError::InvalidParameter {
            name: "elevation_rad",
            reason: "the elevation must be finite",
        });
    }
    // σ = σ₀ / sin(max(el, el_min))
    Ok(zenith_std_m / elevation_rad.max(min_elevation_rad).sin())
}
