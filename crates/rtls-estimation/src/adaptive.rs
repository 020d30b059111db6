//! Innovation-based adaptive measurement noise: a scale `λ ≥ 1` on a measurement's stated
//! noise `R`, estimated online from the innovations so that the filter's covariance stays
//! consistent when the real errors are larger than stated (wrong datasheet values, multipath,
//! body shadowing, a radio map denser than its accuracy).
//!
//! # Equations
//! With the scaled noise `λR` the filter's innovation covariance is `S = H P⁻ Hᵀ + λ R`. If the
//! real noise is `λ* R`, then `E[ν νᵀ] = H P⁻ Hᵀ + λ* R`, so (covariance matching, Mehra 1972;
//! Myers & Tapley 1976, restricted to one scale factor)
//!
//! ```text
//! E[νᵀ R⁻¹ ν] = tr(R⁻¹ H P⁻ Hᵀ) + m λ*   ⇒   λ̂* = λ + (νᵀ R⁻¹ ν − tr(R⁻¹ S)) / m
//! ```
//!
//! one unbiased sample of `λ*` per update (`m` measurement components) when the filter's
//! other assumptions hold. They may not: an innovation larger than `S` can also be a motion the
//! model under-predicts, so the excess is blamed on the measurement only in its share of `S`,
//! `ρ = min(1, tr λR / tr S)`: `λ̂* = λ + ρ (νᵀ R⁻¹ ν − tr(R⁻¹ S)) / m`. A sample is only as
//! informative as the measurement is against the prior: its variance grows as `1/ρ²`,
//! so when the prediction dominates (`H P⁻ Hᵀ ≫ λR`, e.g. fixes a minute apart) it says almost
//! nothing about `R`. The samples are therefore averaged with precision weights
//! `wₖ = ρₖ² ∈ (0, 1]` over a time window `τ` (`memory_s`):
//!
//! ```text
//! Wₖ = e^(−Δtₖ/τ) Wₖ₋₁ + wₖ,   λ̄ₖ = λ̄ₖ₋₁ + (wₖ / Wₖ)(λ̂*ₖ − λ̄ₖ₋₁),   W₀ = 1, λ̄₀ = 1
//! ```
//!
//! (the stated noise counts as one full-weight sample, so a wrong one is corrected within a few
//! updates; then the window forgets at `τ` seconds, whatever the measurement rate). The scale
//! used is `λ = clamp(λ̄, 1, max_scale)`: never more confident than the stated noise (an honest
//! floor), never unboundedly pessimistic.
//!
//! A window of seconds to tens of seconds separates a site's noise level, which changes
//! slowly, from a manoeuvre, whose large innovations last a few seconds and are the motion
//! model's to explain (the IMM's manoeuvre modes, a larger `σ_a`), not the sensor's.
//!
//! An outlier would drag the average up, so a sample's innovation is first shrunk to the
//! validation gate, `ν ← ν · √(min(1, γ / NIS))` (a Huber-like clip at `NIS = γ`). Innovations
//! the tracker gates out are still observed this way: a run of rejections raises `λ`, so a
//! filter whose stated noise is too small widens its gate instead of rejecting every
//! measurement for ever.
//!
//! # Example
//! ```
//! use nalgebra::{DMatrix, DVector};
//! use rtls_estimation::adaptive::{AdaptiveNoise, NoiseScale};
//!
//! // the stated σ = 0.1 m, the real σ = 0.3 m: λ* = 9; the prior is tight (H P Hᵀ = 0.001)
//! let adaptive = AdaptiveNoise::new(20.0, 100.0)?;
//! let r = DMatrix::from_element(1, 1, 0.01);
//! let mut scale = NoiseScale::default();
//! for k in 0..2000 {
//!     let nu = 0.3 * [1.0, -1.0][k % 2]; // |ν| = σ* in every update: E[ν²] = 0.09 ≈ λ* R
//!     let s = DMatrix::from_element(1, 1, 0.001 + scale.scale() * 0.01);
//!     scale = adaptive.observe(&scale, 0.1, &DVector::from_element(1, nu), &s, &r, 10.83)?;
//! }
//! assert!((scale.scale() - 8.9).abs() < 0.1);
//! # Ok::<(), rtls_estimation::EstimationError>(())
//! ```
//!
//! # References
//! R. K. Mehra, "Approaches to adaptive filtering", IEEE Trans. Automatic Control 17(5), 1972;
//! K. A. Myers & B. D. Tapley, "Adaptive sequential estimation with unknown noise statistics",
//! IEEE Trans. Automatic Control 21(4), 1976; A. H. Mohamed & K. P. Schwarz, "Adaptive Kalman
//! filtering for INS/GPS", Journal of Geodesy 73, 1999 (innovation-based adaptive estimation).

pub mod corrections;
pub mod correlation;

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use crate::error::{EstimationError, Result};

/// The adaptive-noise strategy: how fast the scale follows and its bounds. Immutable; the
/// per-track estimate is a [`NoiseScale`] value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveNoise {
    /// `τ`, the averaging window, s.
    memory_s: f64,
    max_scale: f64,
}

/// One measurement class's current noise scale for one track (a value the track owns).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NoiseScale {
    /// `λ̄`, the weighted running average of the scale samples (unclamped).
    average: f64,
    /// `W`, the decayed sum of the samples' weights (the stated noise counts 1).
    weight_sum: f64,
    /// `λ = clamp(λ̄, 1, max)`.
    scale: f64,
    /// Number of updates observed.
    updates: u32,
}

impl Default for NoiseScale {
    /// `λ = 1`: the stated noise, before any innovation is seen.
    fn default() -> Self {
        Self {
            average: 1.0,
            weight_sum: 1.0,
            scale: 1.0,
            updates: 0,
        }
    }
}

impl NoiseScale {
    /// The scale `λ ≥ 1` to multiply the stated noise `R` by.
    #[must_use]
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Number of updates observed so far.
    #[must_use]
    pub fn updates(&self) -> u32 {
        self.updates
    }
}

impl AdaptiveNoise {
    /// A strategy averaging over a window of `memory_s` seconds, with `λ ≤ max_scale`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a non-positive `memory_s` or `max_scale < 1`
    /// (or either non-finite).
    pub fn new(memory_s: f64, max_scale: f64) -> Result<Self> {
        if !(memory_s.is_finite() && memory_s > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "memory_s",
                reason: "must be a finite number of seconds > 0",
            });
        }
        if !(max_scale.is_finite() && max_scale >= 1.0) {
            return Err(EstimationError::InvalidParameter {
                name: "max_scale",
                reason: "must be finite and at least 1 (1 turns the adaptation off)",
            });
        }
        Ok(Self { memory_s, max_scale })
    }

    /// The scale after one more update, `elapsed_s` after the class's previous one, with
    /// innovation `ν`, innovation covariance `S` (computed with the scaled noise `λR`,
    /// `λ = scale.scale()`) and the stated (unscaled) noise `R`;
    /// the innovation is clipped to `NIS ≤ clip_nis` (the validation gate `γ`, a χ² quantile
    /// for the measurement's dimension).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a non-positive or non-finite `clip_nis`;
    /// [`EstimationError::DimensionMismatch`] when the sizes of `ν`, `S` and `R` differ;
    /// [`EstimationError::NotPositiveDefinite`] when `R` or `S` cannot be Cholesky-factorised;
    /// [`EstimationError::NonFinite`] for a non-finite innovation.
    pub fn observe(
        &self,
        scale: &NoiseScale,
        elapsed_s: f64,
        innovation: &DVector<f64>,
        innovation_covariance: &DMatrix<f64>,
        noise: &DMatrix<f64>,
        clip_nis: f64,
    ) -> Result<NoiseScale> {
        check_clip(clip_nis)?;
        let m = innovation.len();
        for (what, rows, cols) in [
            (
                "innovation covariance",
                innovation_covariance.nrows(),
                innovation_covariance.ncols(),
            ),
            ("measurement noise", noise.nrows(), noise.ncols()),
        ] {
            if rows != m || cols != m {
                return Err(EstimationError::DimensionMismatch {
                    what,
                    expected: m,
                    found: rows.max(cols),
                });
            }
        }
        if m == 0 {
            return Ok(*scale);
        }
        if innovation.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite { what: "innovation" });
        }
        let r_factor = noise.clone().cholesky().ok_or(EstimationError::NotPositiveDefinite {
            what: "measurement noise R",
        })?;
        let s_factor = innovation_covariance
            .clone()
            .cholesky()
            .ok_or(EstimationError::NotPositiveDefinite {
                what: "innovation covariance S",
            })?;
        // NIS = νᵀ S⁻¹ ν
        let nis = s_factor.solve(innovation).dot(innovation);
        // q = νᵀ R⁻¹ ν (before the clip)
        let q = r_factor.solve(innovation).dot(innovation);
        // tr(R⁻¹ S)
        let trace = r_factor.solve(innovation_covariance).trace();
        self.fold(
            scale,
            elapsed_s,
            Sample {
                m,
                nis,
                q,
                trace,
                noise_trace: noise.trace(),
                innovation_trace: innovation_covariance.trace(),
            },
            clip_nis,
        )
    }

    /// [`AdaptiveNoise::observe`] for an `M`-component measurement with fixed sizes (a 2-D or
    /// 3-D position fix): the same equations and errors, with `R` and `S` factorised on the
    /// stack (tested against [`AdaptiveNoise::observe`] to 1e-12 relative).
    ///
    /// # Errors
    /// As [`AdaptiveNoise::observe`] (no size mismatch can occur).
    pub fn observe_fixed<const M: usize>(
        &self,
        scale: &NoiseScale,
        elapsed_s: f64,
        innovation: &SVector<f64, M>,
        innovation_covariance: &SMatrix<f64, M, M>,
        noise: &SMatrix<f64, M, M>,
        clip_nis: f64,
    ) -> Result<NoiseScale> {
        check_clip(clip_nis)?;
        if M == 0 {
            return Ok(*scale);
        }
        if innovation.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite { what: "innovation" });
        }
        let r_factor = noise.cholesky().ok_or(EstimationError::NotPositiveDefinite {
            what: "measurement noise R",
        })?;
        let s_factor = innovation_covariance
            .cholesky()
            .ok_or(EstimationError::NotPositiveDefinite {
                what: "innovation covariance S",
            })?;
        // NIS = νᵀ S⁻¹ ν
        let nis = s_factor.solve(innovation).dot(innovation);
        // q = νᵀ R⁻¹ ν (before the clip)
        let q = r_factor.solve(innovation).dot(innovation);
        // tr(R⁻¹ S)
        let trace = r_factor.solve(innovation_covariance).trace();
        self.fold(
            scale,
            elapsed_s,
            Sample {
                m: M,
                nis,
                q,
                trace,
                noise_trace: noise.trace(),
                innovation_trace: innovation_covariance.trace(),
            },
            clip_nis,
        )
    }

    /// The scale after one sample (see the module's equations), from its quadratic forms.
    fn fold(&self, scale: &NoiseScale, elapsed_s: f64, sample: Sample, clip_nis: f64) -> Result<NoiseScale> {
        let Sample {
            m,
            nis,
            q,
            trace,
            noise_trace,
            innovation_trace,
        } = sample;
        // ν ← ν · √(min(1, γ / NIS)), so νᵀ R⁻¹ ν shrinks by the same factor
        let clip = if nis > clip_nis { clip_nis / nis } else { 1.0 };
        // q = νᵀ R⁻¹ ν (clipped)
        let q = clip * q;
        // the measurement's share of S, ρ = min(1, tr λR / tr S)
        let share = (scale.scale * noise_trace / innovation_trace).min(1.0);
        // λ̂* = λ + ρ (νᵀ R⁻¹ ν − tr(R⁻¹ S)) / m: an innovation larger than S is blamed on the
        // measurement only in the measurement's share of S (the rest is the prediction's: a
        // manoeuvre or a long gap the motion model under-predicts)
        let sample = scale.scale + share * (q - trace) / m as f64;
        if !sample.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "noise scale sample",
            });
        }
        // w = ρ², the sample's precision relative to a tight prior's
        let precision = share * share;
        // W = e^(−Δt/τ) W + w (no decay before the first update or for a zero Δt)
        let decay = if elapsed_s.is_finite() && elapsed_s > 0.0 {
            libm::exp(-elapsed_s / self.memory_s)
        } else {
            1.0
        };
        let weight_sum = decay * scale.weight_sum + precision;
        // λ̄ ← λ̄ + (w / W)(λ̂* − λ̄), kept within [0, max] so a long run cannot wind it up
        let average = (scale.average + precision / weight_sum * (sample - scale.average)).clamp(0.0, self.max_scale);
        Ok(NoiseScale {
            average,
            weight_sum,
            // λ = clamp(λ̄, 1, max)
            scale: average.clamp(1.0, self.max_scale),
            updates: scale.updates.saturating_add(1),
        })
    }
}

/// One update's quadratic forms, whatever the size types: `m`, `νᵀ S⁻¹ ν`, `νᵀ R⁻¹ ν`
/// (unclipped), `tr(R⁻¹ S)`, `tr R`, `tr S`.
struct Sample {
    m: usize,
    nis: f64,
    q: f64,
    trace: f64,
    noise_trace: f64,
    innovation_trace: f64,
}

/// The clip `γ` must be a finite positive χ² value.
fn check_clip(clip_nis: f64) -> Result<()> {
    if clip_nis.is_finite() && clip_nis > 0.0 {
        Ok(())
    } else {
        Err(EstimationError::InvalidParameter {
            name: "clip_nis",
            reason: "must be a finite positive χ² value",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar(value: f64) -> DMatrix<f64> {
        DMatrix::from_element(1, 1, value)
    }

    /// Deterministic standard-normal-like samples: ±1 alternating has E[ν²] = 1.
    fn unit(k: usize) -> f64 {
        [1.0, -1.0][k % 2]
    }

    #[test]
    fn stated_noise_that_is_right_keeps_the_scale_at_one() {
        let adaptive = AdaptiveNoise::new(20.0, 100.0).unwrap();
        let mut scale = NoiseScale::default();
        for k in 0..500 {
            // R = 1, HPHᵀ = 0.5, real noise 1: E[ν²] = 1.5 = S
            let nu = 1.5f64.sqrt() * unit(k);
            let s = scalar(0.5 + scale.scale());
            scale = adaptive
                .observe(&scale, 0.1, &DVector::from_element(1, nu), &s, &scalar(1.0), 10.83)
                .unwrap();
        }
        assert!((scale.scale() - 1.0).abs() < 1e-9, "{scale:?}");
        assert_eq!(scale.updates(), 500);
    }

    #[test]
    fn vector_measurements_find_the_real_scale() {
        // 2-D fix with R = diag(1, 4), real noise 5 R, HPHᵀ = 0.2 I
        let adaptive = AdaptiveNoise::new(30.0, 100.0).unwrap();
        let r = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 4.0]));
        let hph = DMatrix::identity(2, 2) * 0.2;
        let mut scale = NoiseScale::default();
        for k in 0..3000 {
            // ν with E[ν νᵀ] = HPHᵀ + 5R, component-wise ±√(…)
            let nu = DVector::from_vec(vec![
                (0.2f64 + 5.0).sqrt() * unit(k),
                (0.2f64 + 20.0).sqrt() * unit(k / 2),
            ]);
            let s = &hph + &r * scale.scale();
            scale = adaptive.observe(&scale, 0.1, &nu, &s, &r, 13.8).unwrap();
        }
        assert!((scale.scale() - 5.0).abs() < 0.3, "{scale:?}");
    }

    #[test]
    fn outliers_are_clipped_and_the_scale_is_bounded() {
        let adaptive = AdaptiveNoise::new(1.0, 50.0).unwrap();
        let mut scale = NoiseScale::default();
        // one enormous outlier counts as NIS = γ: λ̂* = 1 + (γ − 1) = 9, weighed against the
        // stated noise's sample (decayed by e^(−Δt/τ)): λ̄ = 1 + 8 / (1 + e^(−0.1))
        scale = adaptive
            .observe(
                &scale,
                0.1,
                &DVector::from_element(1, 1e6),
                &scalar(1.0),
                &scalar(1.0),
                9.0,
            )
            .unwrap();
        assert!(
            (scale.scale() - (1.0 + 8.0 / (1.0 + (-0.1f64).exp()))).abs() < 1e-9,
            "{scale:?}"
        );
        // a long run of them saturates at the bound, never beyond
        for _ in 0..10_000 {
            let s = scalar(scale.scale());
            scale = adaptive
                .observe(&scale, 0.1, &DVector::from_element(1, 1e6), &s, &scalar(1.0), 9.0)
                .unwrap();
        }
        assert_eq!(scale.scale(), 50.0);
        // and it comes back when the innovations do
        for k in 0..200 {
            let s = scalar(scale.scale());
            scale = adaptive
                .observe(&scale, 0.1, &DVector::from_element(1, unit(k)), &s, &scalar(1.0), 9.0)
                .unwrap();
        }
        assert!(scale.scale() < 1.5, "{scale:?}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(AdaptiveNoise::new(0.0, 10.0).is_err());
        assert!(AdaptiveNoise::new(f64::INFINITY, 10.0).is_err());
        assert!(AdaptiveNoise::new(10.0, 0.5).is_err());
        assert!(AdaptiveNoise::new(f64::NAN, 10.0).is_err());
        let adaptive = AdaptiveNoise::new(10.0, 10.0).unwrap();
        let scale = NoiseScale::default();
        let nu = DVector::from_element(1, 1.0);
        assert!(adaptive
            .observe(&scale, 0.1, &nu, &scalar(1.0), &scalar(0.0), 9.0)
            .is_err());
        assert!(adaptive
            .observe(&scale, 0.1, &nu, &scalar(1.0), &scalar(1.0), f64::NAN)
            .is_err());
        assert!(adaptive
            .observe(&scale, 0.1, &nu, &scalar(-1.0), &scalar(1.0), 9.0)
            .is_err());
        assert!(adaptive
            .observe(
                &scale,
                0.1,
                &DVector::from_element(1, f64::NAN),
                &scalar(1.0),
                &scalar(1.0),
                9.0
            )
            .is_err());
        assert!(adaptive
            .observe(
                &scale,
                0.1,
                &DVector::from_element(2, 1.0),
                &scalar(1.0),
                &scalar(1.0),
                9.0
            )
            .is_err());
    }
}
