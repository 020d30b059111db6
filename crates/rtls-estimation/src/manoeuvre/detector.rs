//! Manoeuvre detection parameters and thresholds of the variable-dimension filter.

use crate::error::{EstimationError, Result};
use crate::stats::chi_square_quantile;

/// A detection threshold: explicit, or the quantile of the statistic's χ² distribution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Threshold {
    /// The `probability` quantile of the statistic's (approximate) χ² distribution when the
    /// hypothesis "no manoeuvre" / "no acceleration" holds.
    ChiSquare {
        /// Quantile in `(0, 1)`.
        probability: f64,
    },
    /// A fixed value of the statistic.
    Fixed(f64),
}

/// Seed 004's manoeuvre detector and the rule that ends a manoeuvre.
///
/// **Onset** (in the CV model): the fading-memory sum of normalised innovations
/// ```text
/// μ(k) = α μ(k−1) + ν(k)ᵀ S(k)⁻¹ ν(k)                (seed 004 eq. (11))
/// Δ = 1 / (1 − α)                                     effective window (steps)
/// manoeuvre declared when μ(k) ≥ Th
/// ```
/// Under "no manoeuvre" each term is `χ²(m)`, so `μ` has mean `mΔ` and variance
/// `2m/(1−α²)`. The default threshold matches these two moments with a scaled χ²,
/// `μ ≈ c·χ²(ν)`, `c = 1/(1+α)`, `ν = m(1+α)/(1−α)`, and takes `Th = c·χ²_ν(0.99)`: a 1 %
/// false-alarm rate per step. (Bar-Shalom's `χ²(mΔ)` approximation matches only the mean and,
/// for α = 0.8, sets Th 16 % higher: slower detection.)
///
/// **Exit** (in the CA model): the acceleration's significance over the last `p` steps
/// ```text
/// δₐ(k) = âᵀ Pₐ⁻¹ â                                   (seed 004 eq. (12))
/// Uₐ(k) = Σ_{j=k−p+1..k} δₐ(j)                        (seed 004 eq. (13))
/// return to CV when Uₐ(k) < χ²_{2p}(0.5)              (no more significant than noise)
/// ```
///
/// # Defaults and why
/// - `fading_factor` α = 0.8: `Δ = 5` steps, a 5 s memory at seed 004's 1 Hz, long enough
///   to integrate a weak manoeuvre and short enough to declare a strong one within a few steps.
/// - `onset` = χ² 0.99 (1 % false alarms per step, see above).
/// - `exit_window_steps` p = 5 (= Δ): the acceleration must be insignificant for as long as the
///   onset window, so one noisy step does not end a manoeuvre.
/// - `exit` = χ² 0.5: the CA model is left when `Uₐ` falls below its median under "no
///   acceleration", i.e. the estimated acceleration is no larger than its own noise. The
///   customary 0.95 quantile leaves CA while a weak manoeuvre is still under way (on seed 004's
///   0.16 m/s² turn the filter then chattered CV ↔ CA every few steps); 0.5 with the 0.99 onset
///   gives the detector hysteresis.
/// - `onset_acceleration_std_mps2` = 1 m/s²: the prior on the acceleration when the CA model
///   is started `Δ` steps back; a vehicle's or walker's manoeuvre stays well inside ±2 m/s², and
///   the re-filtered measurements then determine it.
///
/// # Example
/// ```
/// use rtls_estimation::manoeuvre::ManoeuvreDetector;
/// let detector = ManoeuvreDetector::default();
/// assert_eq!(detector.window_steps(), 5);
/// // Seed 004 observes [x, vx, y, vy] (m = 4): Th ≈ 32.6, below Bar-Shalom's χ²₂₀(0.99) = 37.6.
/// let th = detector.onset_threshold(4)?;
/// assert!(th > 30.0 && th < 35.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 §2, eq. (11)–(13); Y. Bar-Shalom, K. Birmiwal, "Variable dimension filter for
/// maneuvering target tracking", *IEEE Trans. AES* 18(5), 1982; Bar-Shalom, Li, Kirubarajan
/// (2001), §11.4 (fading-memory detection, significance test).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManoeuvreDetector {
    /// α in `(0, 1)`.
    pub fading_factor: f64,
    /// `Th` for `μ(k)`.
    pub onset: Threshold,
    /// `p`: the window of the exit test (steps, ≥ 1).
    pub exit_window_steps: usize,
    /// Threshold below which `Uₐ` ends the manoeuvre.
    pub exit: Threshold,
    /// Standard deviation of the acceleration prior when the CA model starts (m/s²).
    pub onset_acceleration_std_mps2: f64,
}

impl Default for ManoeuvreDetector {
    fn default() -> Self {
        Self {
            fading_factor: 0.8,
            onset: Threshold::ChiSquare { probability: 0.99 },
            exit_window_steps: 5,
            exit: Threshold::ChiSquare { probability: 0.5 },
            onset_acceleration_std_mps2: 1.0,
        }
    }
}

impl ManoeuvreDetector {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] naming the parameter that is out of range.
    pub fn validate(&self) -> Result<()> {
        if !(self.fading_factor > 0.0 && self.fading_factor < 1.0) {
            return Err(EstimationError::InvalidParameter {
                name: "fading_factor",
                reason: "α must lie strictly between 0 and 1",
            });
        }
        if self.exit_window_steps == 0 {
            return Err(EstimationError::InvalidParameter {
                name: "exit_window_steps",
                reason: "the exit window needs at least one step",
            });
        }
        if !(self.onset_acceleration_std_mps2.is_finite() && self.onset_acceleration_std_mps2 > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "onset_acceleration_std_mps2",
                reason: "must be positive and finite",
            });
        }
        for (name, threshold) in [("onset", self.onset), ("exit", self.exit)] {
            let valid = match threshold {
                Threshold::ChiSquare { probability } => probability > 0.0 && probability < 1.0,
                Threshold::Fixed(value) => value.is_finite() && value > 0.0,
            };
            if !valid {
                return Err(EstimationError::InvalidParameter {
                    name,
                    reason: "a χ² probability must lie in (0, 1) and a fixed threshold be positive",
                });
            }
        }
        Ok(())
    }

    /// The effective window `Δ = 1/(1 − α)`, rounded to whole steps (at least 1).
    #[must_use]
    pub fn window_steps(&self) -> usize {
        // Δ = 1/(1 − α)
        let delta = 1.0 / (1.0 - self.fading_factor);
        // round half up without std (no_std): Δ ≥ 1
        ((delta + 0.5) as usize).max(1)
    }

    /// `Th` for a measurement of `m` components.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for `m = 0` or invalid parameters.
    pub fn onset_threshold(&self, m: usize) -> Result<f64> {
        if m == 0 {
            return Err(EstimationError::InvalidParameter {
                name: "m",
                reason: "a measurement has at least one component",
            });
        }
        match self.onset {
            Threshold::Fixed(value) => Ok(value),
            Threshold::ChiSquare { probability } => {
                let alpha = self.fading_factor;
                // c = 1/(1+α),  ν = m(1+α)/(1−α)
                let c = 1.0 / (1.0 + alpha);
                let dof = m as f64 * (1.0 + alpha) / (1.0 - alpha);
                // Th = c · χ²_ν(P)
                Ok(c * chi_square_quantile(probability, dof)?)
            }
        }
    }

    /// The exit threshold for `Uₐ` over `p` steps of a `axes`-dimensional acceleration.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for invalid parameters.
    pub fn exit_threshold(&self, axes: usize) -> Result<f64> {
        match self.exit {
            Threshold::Fixed(value) => Ok(value),
            // χ²_{axes·p}(P)
            Threshold::ChiSquare { probability } => {
                chi_square_quantile(probability, (axes * self.exit_window_steps) as f64)
            }
        }
    }
}
