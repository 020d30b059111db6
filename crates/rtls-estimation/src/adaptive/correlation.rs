//! Error correlation in time, measured from a source's innovations: the inflation a
//! measurement's variance needs so that a filter, which takes successive measurements as
//! independent, does not count errors that move together as independent looks.
//!
//! # Equations
//! A filter fed `n` measurements whose errors form an AR(1) sequence with lag-one correlation
//! `ρ` treats their mean as having the variance `σ²/n`; it really has (for `n ≫ 1`)
//!
//! ```text
//! Var(ē) = (σ²/n) · (1 + 2 Σₖ ρᵏ) = (σ²/n) · (1 + ρ)/(1 − ρ)
//! ```
//!
//! so each variance is inflated by `c = (1 + ρ)/(1 − ρ)` (the effective sample size of a
//! correlated sequence; Bartlett 1946, Bayley & Hammersley 1946). `ρ` is estimated from the
//! source's normalised innovations `uₖ = νₖ / √Sₖ` (per component), clipped to
//! `|u| ≤` [`CLIP_SIGMAS`] so one outlier does not decide it, with exponential memory `τ`:
//!
//! ```text
//! Cₖ = e^(−Δt/τ) Cₖ₋₁ + uₖ uₖ₋₁,   Qₖ = e^(−Δt/τ) Qₖ₋₁ + (uₖ² + uₖ₋₁²)/2,
//! ρ̂ = clamp(C / (Q + n₀), 0, ρ_max)
//! ```
//!
//! with `n₀ =` [`PRIOR_PAIRS`] pseudo-pairs of independent errors (a handful of pairs cannot
//! claim a correlation) and `ρ_max =` [`MAX_CORRELATION`] (`c ≤ 19`). A negative `ρ̂` is
//! taken as 0: the filter is never made more confident than the stated noise.
//!
//! An optimal filter's innovations are white (Mehra 1970); a filter whose measurement errors
//! are correlated, or whose prediction is too sure, has innovations that are not — the
//! correlation is measured where it hurts. A filter that follows its measurements closely
//! (a loose motion model) whitens its innovations and is left alone; one that averages over
//! many measurements (a tight velocity from odometry, a slow tag) sees the correlation and is
//! given the information its window really holds.
//!
//! # Example
//! ```
//! use rtls_estimation::adaptive::correlation::{CorrelationEstimate, ErrorCorrelation};
//!
//! // errors that hold their sign for 4 samples: 3 of 4 neighbours agree, ρ = 0.5 at lag one
//! let strategy = ErrorCorrelation::new(60.0)?;
//! let mut estimate = CorrelationEstimate::default();
//! for k in 0..400 {
//!     let u = if (k / 4) % 2 == 0 { 1.0 } else { -1.0 };
//!     estimate = strategy.observe(&estimate, 0.1 * f64::from(k), &[u])?;
//! }
//! let c = strategy.inflation(&estimate);
//! assert!((2.7..3.0).contains(&c), "{c}"); // (1 + ρ)/(1 − ρ) = 3, less the prior pairs
//! # Ok::<(), rtls_estimation::EstimationError>(())
//! ```
//!
//! # References
//! R. K. Mehra, "On the identification of variances and adaptive Kalman filtering", IEEE
//! Trans. Automatic Control 15(2), 1970 (innovation whiteness); M. S. Bartlett, "On the
//! theoretical specification and sampling properties of autocorrelated time-series", JRSS
//! Suppl. 8, 1946; A. Gelb, *Applied Optimal Estimation*, 1974, §4.6 (correlated measurement
//! noise).

use crate::error::{EstimationError, Result};

/// Normalised innovations are clipped to this many standard deviations.
pub const CLIP_SIGMAS: f64 = 3.0;

/// Pseudo-pairs of independent errors the estimate starts from.
pub const PRIOR_PAIRS: f64 = 10.0;

/// The largest lag-one correlation used (`c = (1 + ρ)/(1 − ρ) ≤ 19`).
pub const MAX_CORRELATION: f64 = 0.9;

/// The strategy: the memory of the estimate. Immutable; each source's estimate is a
/// [`CorrelationEstimate`] value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorCorrelation {
    /// `τ`, s.
    memory_s: f64,
}

/// One source's running sums (a value its track owns).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CorrelationEstimate {
    /// The previous measurement's time, s, and its normalised innovation (first two components).
    previous: Option<(f64, [f64; 2])>,
    /// `C = Σ uₖ uₖ₋₁`, decayed.
    cross: f64,
    /// `Q = Σ (uₖ² + uₖ₋₁²)/2`, decayed.
    power: f64,
}

impl ErrorCorrelation {
    /// A strategy forgetting over `memory_s` seconds.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a non-finite or non-positive `memory_s`.
    pub fn new(memory_s: f64) -> Result<Self> {
        if !(memory_s.is_finite() && memory_s > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "memory_s",
                reason: "must be a finite number of seconds > 0",
            });
        }
        Ok(Self { memory_s })
    }

    /// The estimate after a measurement at `time_s` with normalised innovation components
    /// `u = ν / √diag(S)` (the first two are used). A measurement at or before the previous
    /// one's time (a second reading of one round) is paired like any other.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a non-finite time or innovation (the estimate is
    /// left as it was by the caller).
    pub fn observe(
        &self,
        estimate: &CorrelationEstimate,
        time_s: f64,
        normalised: &[f64],
    ) -> Result<CorrelationEstimate> {
        if !time_s.is_finite() || normalised.iter().any(|u| !u.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "normalised innovation",
            });
        }
        // u ← clamp(u, −3, 3), at most two components
        let mut current = [0.0; 2];
        for (slot, u) in current.iter_mut().zip(normalised) {
            *slot = u.clamp(-CLIP_SIGMAS, CLIP_SIGMAS);
        }
        let components = normalised.len().min(2);
        let Some((previous_s, previous)) = estimate.previous else {
            return Ok(CorrelationEstimate {
                previous: Some((time_s, current)),
                ..*estimate
            });
        };
        // e^(−Δt/τ)
        let elapsed_s = (time_s - previous_s).max(0.0);
        let decay = libm::exp(-elapsed_s / self.memory_s);
        // C ← e^(−Δt/τ) C + Σᵢ uₖ,ᵢ uₖ₋₁,ᵢ;  Q ← e^(−Δt/τ) Q + Σᵢ (uₖ,ᵢ² + uₖ₋₁,ᵢ²)/2
        let (mut cross, mut power) = (0.0, 0.0);
        for i in 0..components {
            cross += current[i] * previous[i];
            power += 0.5 * (current[i] * current[i] + previous[i] * previous[i]);
        }
        Ok(CorrelationEstimate {
            previous: Some((time_s, current)),
            cross: decay * estimate.cross + cross,
            power: decay * estimate.power + power,
        })
    }

    /// `ρ̂ = clamp(C / (Q + n₀), 0, ρ_max)`.
    #[must_use]
    pub fn correlation(&self, estimate: &CorrelationEstimate) -> f64 {
        (estimate.cross / (estimate.power + PRIOR_PAIRS)).clamp(0.0, MAX_CORRELATION)
    }

    /// The variance inflation `c = (1 + ρ̂)/(1 − ρ̂) ∈ [1, 19]`.
    #[must_use]
    pub fn inflation(&self, estimate: &CorrelationEstimate) -> f64 {
        let rho = self.correlation(estimate);
        (1.0 + rho) / (1.0 - rho)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic AR(1) sequence with lag-one correlation `rho` and unit variance (a
    /// linear congruential generator's uniform draws, summed to a near-Gaussian).
    fn ar1(rho: f64, n: usize) -> Vec<f64> {
        let mut state: u64 = 12345;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut e = 0.0;
        (0..n)
            .map(|_| {
                // Irwin–Hall: Σ of 12 uniforms − 6 has variance 1
                let w: f64 = (0..12).map(|_| uniform()).sum::<f64>() - 6.0;
                e = rho * e + (1.0 - rho * rho).sqrt() * w;
                e
            })
            .collect()
    }

    fn estimate(rho: f64, n: usize) -> f64 {
        let strategy = ErrorCorrelation::new(1e6).unwrap();
        let mut estimate = CorrelationEstimate::default();
        for (k, u) in ar1(rho, n).into_iter().enumerate() {
            estimate = strategy.observe(&estimate, k as f64 * 0.1, &[u]).unwrap();
        }
        strategy.correlation(&estimate)
    }

    #[test]
    fn white_errors_are_not_inflated() {
        let rho = estimate(0.0, 5000);
        assert!(rho < 0.05, "{rho}");
    }

    #[test]
    fn the_lag_one_correlation_of_an_ar1_sequence_is_recovered() {
        for truth in [0.3, 0.6, 0.8] {
            let rho = estimate(truth, 20_000);
            assert!((rho - truth).abs() < 0.05, "{truth}: {rho}");
        }
    }

    #[test]
    fn a_few_pairs_cannot_claim_a_correlation() {
        // three identical innovations: C = 2, Q = 2, ρ̂ = 2 / 12
        let strategy = ErrorCorrelation::new(20.0).unwrap();
        let mut estimate = CorrelationEstimate::default();
        for k in 0..3 {
            estimate = strategy.observe(&estimate, f64::from(k), &[1.0]).unwrap();
        }
        let rho = strategy.correlation(&estimate);
        assert!(rho < 0.2, "{rho}");
    }

    #[test]
    fn inflation_is_bounded_and_never_below_one() {
        let strategy = ErrorCorrelation::new(20.0).unwrap();
        let mut same = CorrelationEstimate::default();
        let mut alternating = CorrelationEstimate::default();
        for k in 0..1000 {
            same = strategy.observe(&same, f64::from(k), &[1e9, 2.0]).unwrap();
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            alternating = strategy.observe(&alternating, f64::from(k), &[sign]).unwrap();
        }
        assert!((strategy.inflation(&same) - 19.0).abs() < 1e-9);
        assert_eq!(strategy.inflation(&alternating), 1.0);
    }

    #[test]
    fn old_correlation_is_forgotten() {
        let strategy = ErrorCorrelation::new(5.0).unwrap();
        let mut estimate = CorrelationEstimate::default();
        for k in 0..200 {
            estimate = strategy.observe(&estimate, 0.1 * f64::from(k), &[1.0]).unwrap();
        }
        assert!(strategy.correlation(&estimate) > 0.6);
        for (k, u) in ar1(0.0, 2000).into_iter().enumerate() {
            estimate = strategy.observe(&estimate, 20.0 + 0.1 * k as f64, &[u]).unwrap();
        }
        assert!(strategy.correlation(&estimate) < 0.1);
    }

    #[test]
    fn non_finite_input_is_an_error() {
        let strategy = ErrorCorrelation::new(20.0).unwrap();
        let estimate = CorrelationEstimate::default();
        assert!(strategy.observe(&estimate, 0.0, &[f64::NAN]).is_err());
        assert!(strategy.observe(&estimate, f64::INFINITY, &[0.0]).is_err());
        assert!(ErrorCorrelation::new(0.0).is_err());
    }
}
