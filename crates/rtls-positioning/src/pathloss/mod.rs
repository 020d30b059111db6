//! Radio path-loss models: mean received signal strength as a function of distance, its
//! inversion (RSSI → distance), the accuracy of RSSI-derived ranges, and the calibration of the
//! model from surveyed samples.
//!
//! A [`PathLossModel`] is an immutable strategy: the multilateration and joint TOA + RSS
//! solvers use it to predict RSSI at a candidate position and its sensitivity to distance.
//!
//! - [`LogDistance`] — the one-slope law of seed 002, `ρ(d) = ρ_T − 10 η lg(d/d₀) + X`.
//! - [`Breakpoint`] — seed 001's UWB dual-slope law (continuous by default; the printed,
//!   discontinuous form on request, see [`BreakpointForm`]).
//! - [`fit_log_distance`], [`fit_shared`], [`fit_per_anchor`], [`fit_shared_exponent`] —
//!   least-squares calibration of `ρ_T`, `η` and `σ_X` with standard errors.
//!
//! # RSSI-derived ranges
//! With `ρ = μ(d) + X`, `X ~ N(0, σ_X²)`, the inverted range `d̂ = μ⁻¹(ρ)` is log-normal for a
//! log-distance law: `ln d̂ ~ N(ln d, s²)`, `s = σ_X ln 10 / (10 η)`. So `d̂` is the **median**
//! of the range (and its maximum-likelihood estimate), but its **mean** is `d · exp(½ s²)`:
//! with seed 002's `σ_X = 4` dB, `η = 4`, `s = 0.23` and ranges are 2.7 % long on average;
//! with `σ_X = 6` dB, `η = 2`, `s = 0.69` and 27 %. [`DistanceEstimate::MeanUnbiased`] divides
//! the factor out. To first order the range standard deviation is
//! `σ_d(d) = σ_X / |dμ/dd| = d ln 10 σ_X / (10 η) = s d` (the delta method,
//! [`PathLossModel::range_std_m`]): RSSI ranging has a constant *relative* error.

mod breakpoint;
mod calibration;
mod log_distance;

pub use breakpoint::{Breakpoint, BreakpointForm, BreakpointParameters};
pub use calibration::{
    fit_log_distance, fit_per_anchor, fit_shared, fit_shared_exponent, AnchorOffset, LogDistanceFit, RssiSample,
    SharedExponentFit,
};
pub use log_distance::LogDistance;

use rtls_estimation::EstimationError;

use crate::error::{PositioningError, Result};

/// Distances below this (m) are evaluated as this distance by the models of this module (the
/// laws diverge at `d = 0`; a tag can sit on an anchor). NaN distances are treated alike.
pub const MIN_DISTANCE_M: f64 = 1e-3;

/// Distances above this (m) are evaluated as this distance (keeps every output finite).
pub const MAX_DISTANCE_M: f64 = 1e9;

/// `d` clamped to `[MIN_DISTANCE_M, MAX_DISTANCE_M]`, NaN to `MIN_DISTANCE_M`.
pub(crate) fn clamp_distance(distance_m: f64) -> f64 {
    if distance_m.is_nan() {
        MIN_DISTANCE_M
    } else {
        distance_m.clamp(MIN_DISTANCE_M, MAX_DISTANCE_M)
    }
}

/// Which distance an RSSI inversion returns ([`PathLossModel::estimate_distance_m`]).
///
/// Under log-normal shadowing, `d̂ = μ⁻¹(ρ)` satisfies `ln d̂ ~ N(ln d, s²)` with
/// `s = σ_X / (d |dμ/dd|)` (`= σ_X ln 10 / (10 η)` for a log-distance law), so
/// `median d̂ = d` but `E[d̂] = d exp(½ s²)`.
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{DistanceEstimate, LogDistance, PathLossModel};
/// let law = LogDistance::new(-40.0, 2.0, 1.0, 6.0)?;
/// let median = law.estimate_distance_m(-60.0, DistanceEstimate::Median)?;
/// let unbiased = law.estimate_distance_m(-60.0, DistanceEstimate::MeanUnbiased)?;
/// assert!((median - 10.0).abs() < 1e-12);
/// let s = 6.0 * std::f64::consts::LN_10 / 20.0;
/// assert!((unbiased - 10.0 * (-0.5 * s * s).exp()).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002 eq. (1); N. Patwari et al., "Locating the nodes", *IEEE Signal Processing
/// Magazine* 22(4), 2005, §"RSS" (the median/mean bias of RSS ranging); the log-normal mean
/// `E[e^Y] = e^{μ + σ²/2}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DistanceEstimate {
    /// `d̂ = μ⁻¹(ρ)`: the median (and maximum-likelihood) range; `E[d̂] = d exp(½ s²)`.
    #[default]
    Median,
    /// `d̂ = μ⁻¹(ρ) exp(−½ s²)`: unbiased in mean (`E[d̂] = d`), with `s` evaluated at `μ⁻¹(ρ)`
    /// (exact for a log-distance law and within one branch of a breakpoint law).
    MeanUnbiased,
}

/// A deterministic path-loss law with log-normal shadowing:
/// `ρ(d) = μ(d) + X`, `X ~ N(0, σ_X²)` (dBm).
///
/// Implementations must be finite and strictly decreasing in `d` for `d > 0` (so that the
/// inversion is unique). The implementations of this module evaluate distances outside
/// `[MIN_DISTANCE_M, MAX_DISTANCE_M]` (and NaN) at the nearest bound, so their outputs are
/// always finite; callers should still validate distances.
///
/// # Units
/// Distances in metres, RSSI in dBm, derivatives in dB/m, `σ_X` in dB.
///
/// # References
/// Seed 002 eq. (1) (log-distance law); seed 001 eq. (8) (UWB breakpoint law).
pub trait PathLossModel {
    /// Mean received power `μ(d)` (dBm) at distance `distance_m` (> 0).
    fn mean_rssi_dbm(&self, distance_m: f64) -> f64;

    /// Sensitivity `dμ/dd` (dB/m) at `distance_m` (> 0); negative for a decreasing law.
    fn slope_db_per_m(&self, distance_m: f64) -> f64;

    /// Standard deviation `σ_X` (dB) of the log-normal shadowing.
    fn shadowing_std_db(&self) -> f64;

    /// Distance (m) whose mean power equals `rssi_dbm`: `d = μ⁻¹(ρ)`.
    ///
    /// Under log-normal shadowing this is the **median** of the range, not its mean; see
    /// [`DistanceEstimate`] and [`PathLossModel::estimate_distance_m`].
    ///
    /// # Errors
    /// [`crate::PositioningError::NonFinite`] for a NaN/∞ RSSI.
    fn distance_m(&self, rssi_dbm: f64) -> Result<f64>;

    /// Delta-method standard deviation (m) of an RSSI-derived range at true distance
    /// `distance_m`: `σ_d(d) = σ_X / |dμ/dd|` (for a log-distance law
    /// `d ln 10 σ_X / (10 η)`). Evaluated at an estimated range it is the usual plug-in value.
    ///
    /// First order in `s = σ_d / d`: accurate for `s ≲ 0.3`; beyond, the range is visibly
    /// log-normal (skewed, mean above the median).
    ///
    /// # Units
    /// `distance_m` and the result in m.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`distance_m`) unless the distance is finite
    /// and positive; [`PositioningError::DegenerateGeometry`] where the law is flat
    /// (`dμ/dd = 0`: RSSI carries no range information).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{LogDistance, PathLossModel};
    /// let law = LogDistance::seed_002(); // η = 4, σ_X = 4 dB
    /// let sigma_d = law.range_std_m(20.0)?;
    /// assert!((sigma_d - 20.0 * std::f64::consts::LN_10 * 4.0 / 40.0).abs() < 1e-12); // 4.6 m
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Patwari et al. (2005) (RSS ranging error grows linearly with distance); the delta
    /// method `Var g(X) ≈ g'(μ)² Var X` applied to `d = μ⁻¹(ρ)`.
    fn range_std_m(&self, distance_m: f64) -> Result<f64> {
        if !(distance_m.is_finite() && distance_m > 0.0) {
            return Err(PositioningError::InvalidParameter {
                name: "distance_m",
                reason: "the distance must be finite and positive",
            });
        }
        // σ_d = σ_X / |dμ/dd|
        let slope = self.slope_db_per_m(distance_m).abs();
        let sigma_m = self.shadowing_std_db() / slope;
        if slope > 0.0 && sigma_m.is_finite() {
            Ok(sigma_m)
        } else {
            Err(PositioningError::DegenerateGeometry {
                reason: "the path-loss law is flat at this distance, so rssi carries no range information",
            })
        }
    }

    /// The mean-bias factor `E[μ⁻¹(ρ)] / d = exp(½ s²)`, `s = σ_X / (d |dμ/dd|)`, of the
    /// inverted range at distance `distance_m` (for a log-distance law
    /// `exp(½ (σ_X ln 10 / (10 η))²)`, independent of `d`).
    ///
    /// # Errors
    /// As [`PathLossModel::range_std_m`].
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{LogDistance, PathLossModel};
    /// let law = LogDistance::seed_002();
    /// let s: f64 = 4.0 * std::f64::consts::LN_10 / 40.0;
    /// assert!((law.range_bias_factor(7.0)? - (0.5 * s * s).exp()).abs() < 1e-12); // 1.027
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// The log-normal mean `E[e^Y] = e^{μ + σ²/2}` with `Y = ln d̂ ~ N(ln d, s²)`.
    fn range_bias_factor(&self, distance_m: f64) -> Result<f64> {
        // s = σ_d / d
        let s = self.range_std_m(distance_m)? / distance_m;
        // exp(½ s²)
        let factor = (0.5 * s * s).exp();
        if factor.is_finite() {
            Ok(factor)
        } else {
            Err(PositioningError::NonFinite {
                what: "range bias factor (shadowing far larger than the path-loss slope)",
            })
        }
    }

    /// RSSI inversion with a choice of estimate: `μ⁻¹(ρ)` ([`DistanceEstimate::Median`]) or
    /// `μ⁻¹(ρ) / exp(½ s²)` ([`DistanceEstimate::MeanUnbiased`], `s` at `μ⁻¹(ρ)`).
    ///
    /// # Units
    /// `rssi_dbm` in dBm, result in m.
    ///
    /// # Errors
    /// Those of [`PathLossModel::distance_m`] and [`PathLossModel::range_bias_factor`].
    ///
    /// # Example
    /// See [`DistanceEstimate`].
    ///
    /// # References
    /// As [`DistanceEstimate`].
    fn estimate_distance_m(&self, rssi_dbm: f64, estimate: DistanceEstimate) -> Result<f64> {
        let median_m = self.distance_m(rssi_dbm)?;
        match estimate {
            DistanceEstimate::Median => Ok(median_m),
            // d̂ = μ⁻¹(ρ) · exp(−½ s²)
            DistanceEstimate::MeanUnbiased => Ok(median_m / self.range_bias_factor(median_m)?),
        }
    }
}

/// A parameter error of an `rtls-estimation` path-loss law, as this crate's error, with the
/// law's parameter names translated to the caller's (`renames`: `(law name, our name)`).
pub(crate) fn law_error(error: EstimationError, renames: &[(&'static str, &'static str)]) -> PositioningError {
    let rename = |name: &'static str| {
        renames
            .iter()
            .find(|(law, _)| *law == name)
            .map_or(name, |&(_, ours)| ours)
    };
    match error {
        EstimationError::InvalidParameter { name, reason } => PositioningError::InvalidParameter {
            name: rename(name),
            reason,
        },
        EstimationError::NonFinite { what } => PositioningError::InvalidParameter {
            name: rename(what),
            reason: "the value must be finite (not nan or infinity)",
        },
        _ => PositioningError::InvalidParameter {
            name: "path-loss law",
            reason: "the law's parameters were rejected",
        },
    }
}

/// Checks a finite parameter.
pub(crate) fn finite(value: f64, name: &'static str) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PositioningError::InvalidParameter {
            name,
            reason: "the value must be finite (not nan or infinity)",
        })
    }
}

/// Checks a finite, strictly positive parameter.
pub(crate) fn positive(value: f64, name: &'static str, reason: &'static str) -> Result<f64> {
    finite(value, name)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(PositioningError::InvalidParameter { name, reason })
    }
}

/// Checks a finite, non-negative parameter.
pub(crate) fn non_negative(value: f64, name: &'static str, reason: &'static str) -> Result<f64> {
    finite(value, name)?;
    if value >= 0.0 {
        Ok(value)
    } else {
        Err(PositioningError::InvalidParameter { name, reason })
    }
}

/// Checks an RSSI to invert.
pub(crate) fn finite_rssi(rssi_dbm: f64) -> Result<f64> {
    if rssi_dbm.is_finite() {
        Ok(rssi_dbm)
    } else {
        Err(PositioningError::NonFinite { what: "rssi" })
    }
}

/// Checks an inverted distance: finite and positive (not over- or underflowed).
pub(crate) fn inverted_distance(distance_m: f64) -> Result<f64> {
    if distance_m.is_finite() && distance_m > 0.0 {
        Ok(distance_m)
    } else {
        Err(PositioningError::NoConsistentSolution {
            reason: "the rssi implies a distance outside the floating-point range (it is far outside the \
                     model's range); check the rssi and the model's parameters",
        })
    }
}
