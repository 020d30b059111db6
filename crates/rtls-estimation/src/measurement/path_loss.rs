//! Path-loss laws: log-distance (seed 002) and the UWB breakpoint law (seed 001).

use core::f64::consts::LN_10;

use crate::error::{EstimationError, Result};
use crate::math::log10;

/// A deterministic path-loss law: the mean signal level as a function of the tag–anchor
/// distance, and its derivative.
///
/// Implementations decide what the value is (received power in dBm, or path loss in dB) and
/// document it; [`RssPathLoss`](super::RssPathLoss) only needs the value and the slope. Both are called with
/// `distance_m > 0` only.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{LogDistancePathLoss, PathLoss};
/// let law = LogDistancePathLoss::seed_002();
/// assert!((law.value_db(100.0) + 80.0).abs() < 1e-12); // ρ = 0 − 40 lg 100 dBm
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
pub trait PathLoss {
    /// The law's value at `distance_m` metres (dB or dBm, as the implementation documents).
    fn value_db(&self, distance_m: f64) -> f64;
    /// Derivative of [`PathLoss::value_db`] with respect to the distance, in dB/m.
    fn slope_db_per_m(&self, distance_m: f64) -> f64;
}

/// Checks a finite value.
pub(crate) fn finite(value: f64, name: &'static str) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(EstimationError::NonFinite { what: name })
    }
}

/// Checks a finite, strictly positive value.
fn positive(value: f64, name: &'static str, reason: &'static str) -> Result<f64> {
    finite(value, name)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(EstimationError::InvalidParameter { name, reason })
    }
}

/// The log-distance (one-slope) law of received power:
/// `ρ(d) = ρ_T − 10 η log₁₀(d / d₀)` dBm.
///
/// [`PathLoss::value_db`] returns the received power `ρ` in dBm (it *decreases* with distance);
/// the slope is `∂ρ/∂d = −10 η / (d ln 10)` dBm/m.
///
/// # Units
/// `ρ_T` in dBm (received power at `d₀`), `d₀` and `d` in m, `η` dimensionless.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{LogDistancePathLoss, PathLoss};
/// let law = LogDistancePathLoss::new(0.0, 1.0, 4.0)?;
/// assert!((law.value_db(10.0) + 40.0).abs() < 1e-12); // −40 dBm at 10 m
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 002, eq. (14): `ρ = ρ_T − 10 η log₁₀ ‖S − P‖ + X` (there with `d₀ = 1` m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogDistancePathLoss {
    reference_power_dbm: f64,
    reference_distance_m: f64,
    exponent: f64,
}

impl LogDistancePathLoss {
    /// The law with received power `reference_power_dbm` (`ρ_T`) at `reference_distance_m`
    /// (`d₀`) and path-loss exponent `exponent` (`η`, 2–4 indoors).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a NaN/∞ parameter;
    /// [`EstimationError::InvalidParameter`] if `d₀ ≤ 0` or `η ≤ 0`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::LogDistancePathLoss;
    /// assert!(LogDistancePathLoss::new(-40.0, 1.0, 2.0).is_ok());
    /// assert!(LogDistancePathLoss::new(-40.0, 0.0, 2.0).is_err());
    /// ```
    ///
    /// # References
    /// Seed 002, eq. (14).
    pub fn new(reference_power_dbm: f64, reference_distance_m: f64, exponent: f64) -> Result<Self> {
        finite(reference_power_dbm, "reference_power_dbm")?;
        positive(
            reference_distance_m,
            "reference_distance_m",
            "the reference distance must be positive",
        )?;
        positive(exponent, "exponent", "the path-loss exponent must be positive")?;
        Ok(Self {
            reference_power_dbm,
            reference_distance_m,
            exponent,
        })
    }

    /// Seed 002's simulation law: `ρ_T = 0` dBm at `d₀ = 1` m, `η = 4`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{LogDistancePathLoss, PathLoss};
    /// let law = LogDistancePathLoss::seed_002();
    /// assert_eq!(law.exponent(), 4.0);
    /// assert!((law.value_db(10.0) + 40.0).abs() < 1e-12);
    /// ```
    ///
    /// # References
    /// Seed 002, Table 1 (`ρ_T = 0` dBm, `η = 4`).
    #[must_use]
    pub fn seed_002() -> Self {
        Self {
            reference_power_dbm: 0.0,
            reference_distance_m: 1.0,
            exponent: 4.0,
        }
    }

    /// Received power `ρ_T` at the reference distance, in dBm.
    #[inline]
    #[must_use]
    pub fn reference_power_dbm(&self) -> f64 {
        self.reference_power_dbm
    }

    /// Reference distance `d₀`, in m.
    #[inline]
    #[must_use]
    pub fn reference_distance_m(&self) -> f64 {
        self.reference_distance_m
    }

    /// Path-loss exponent `η`.
    #[inline]
    #[must_use]
    pub fn exponent(&self) -> f64 {
        self.exponent
    }
}

impl PathLoss for LogDistancePathLoss {
    fn value_db(&self, distance_m: f64) -> f64 {
        // ρ = ρ_T − 10 η log₁₀(d / d₀)
        self.reference_power_dbm - 10.0 * self.exponent * log10(distance_m / self.reference_distance_m)
    }

    fn slope_db_per_m(&self, distance_m: f64) -> f64 {
        // ∂ρ/∂d = −10 η / (d ln 10)
        -10.0 * self.exponent / (distance_m * LN_10)
    }
}

/// Which of the two far-branch formulas a [`BreakpointPathLoss`] uses beyond the breakpoint.
///
/// **Erratum (seed 001).** The paper prints the far branch as
/// `P0 + 10 n lg(10/d₀) + 10 n lg(d/d₀)`: it adds the whole near-branch loss again instead of
/// continuing from the breakpoint, so the path loss jumps up by `10 n lg(d_b/d₀)` at `d_b`
/// (20 dB for `n = 2`, `d_b = 10` m, `d₀ = 1` m). No physical channel does that; the standard
/// dual-slope law continues from the breakpoint and is the [`Default`].
///
/// # References
/// Seed 001, §2.2; V. Erceg et al., "TGn channel models", IEEE 802.11-03/940r4, 2004, eq. (1)
/// (dual-slope law continuous at the breakpoint); A. F. Molisch et al., "A comprehensive
/// standardized model for ultrawideband propagation channels", *IEEE Trans. Antennas Propag.*
/// 54(11), 2006.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BreakpointForm {
    /// Seed 001 as printed: `P0 + 10 n lg(d_b/d₀) + 10 n lg(d/d₀)` beyond `d_b`.
    ///
    /// **Discontinuous** at `d = d_b`: the value jumps up by `10 n lg(d_b/d₀)` dB (20 dB for
    /// `n = 2`, `d_b = 10` m, `d₀ = 1` m). Use it to reproduce the paper; an EKF linearising
    /// near `d_b` sees a Jacobian that ignores the jump.
    AsPrinted,
    /// The continuous dual-slope form `P0 + 10 n lg(d_b/d₀) + 10 n lg(d/d_b)` beyond `d_b`,
    /// equal to the near branch at `d = d_b`. With a single exponent it coincides with the
    /// one-slope law `P0 + 10 n lg(d/d₀)` everywhere; set a different far exponent with
    /// [`BreakpointPathLoss::with_far_exponent`] for a genuine dual-slope law.
    #[default]
    Continuous,
}

/// The UWB path-loss law with a breakpoint (seed 001): path loss `P(d)` in dB, *increasing*
/// with distance.
///
/// ```text
/// P(d) = P0 + 10 n lg(d/d₀)                                  d ≤ d_b
///        P0 + 10 n lg(d_b/d₀) + 10 n₂ lg(d/d₀)   (AsPrinted)  d > d_b
///        P0 + 10 n lg(d_b/d₀) + 10 n₂ lg(d/d_b)  (Continuous) d > d_b
/// ```
/// with the far exponent `n₂ = n` unless set by [`BreakpointPathLoss::with_far_exponent`].
/// The slope is `∂P/∂d = 10 n / (d ln 10)` for `d ≤ d_b` and `10 n₂ / (d ln 10)` beyond (the
/// same in both forms: they differ by a constant).
///
/// # Units
/// `P0` and `P` in dB (path loss at `d₀`), `d₀`, `d_b`, `d` in m, exponents dimensionless.
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{BreakpointPathLoss, PathLoss};
/// let law = BreakpointPathLoss::seed_001(40.0, 1.0)?; // n = 2, d_b = 10 m, as printed
/// assert!((law.value_db(5.0) - (40.0 + 20.0 * 5f64.log10())).abs() < 1e-12);
/// assert!((law.value_db(20.0) - (40.0 + 20.0 + 20.0 * 20f64.log10())).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 001, §2.2, the RSS measurement model `P_k` (breakpoint at 10 m, `n = 2`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreakpointPathLoss {
    p0_db: f64,
    reference_distance_m: f64,
    exponent: f64,
    far_exponent: f64,
    breakpoint_m: f64,
    form: BreakpointForm,
}

impl BreakpointPathLoss {
    /// The law with path loss `p0_db` at `reference_distance_m` (`d₀`), exponent `exponent`
    /// (`n`, on both sides of the breakpoint) and breakpoint `breakpoint_m` (`d_b`).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a NaN/∞ parameter;
    /// [`EstimationError::InvalidParameter`] if `d₀ ≤ 0`, `n ≤ 0` or `d_b < d₀`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{BreakpointForm, BreakpointPathLoss, PathLoss};
    /// let law = BreakpointPathLoss::new(40.0, 1.0, 2.0, 10.0, BreakpointForm::Continuous)?;
    /// assert!((law.value_db(20.0) - (60.0 + 20.0 * 2f64.log10())).abs() < 1e-12);
    /// assert!(BreakpointPathLoss::new(40.0, 1.0, 2.0, 0.5, BreakpointForm::AsPrinted).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 001, §2.2.
    pub fn new(
        p0_db: f64,
        reference_distance_m: f64,
        exponent: f64,
        breakpoint_m: f64,
        form: BreakpointForm,
    ) -> Result<Self> {
        finite(p0_db, "p0_db")?;
        positive(
            reference_distance_m,
            "reference_distance_m",
            "the reference distance must be positive",
        )?;
        positive(exponent, "exponent", "the path-loss exponent must be positive")?;
        finite(breakpoint_m, "breakpoint_m")?;
        if breakpoint_m < reference_distance_m {
            return Err(EstimationError::InvalidParameter {
                name: "breakpoint_m",
                reason: "the breakpoint must not be closer than the reference distance",
            });
        }
        Ok(Self {
            p0_db,
            reference_distance_m,
            exponent,
            far_exponent: exponent,
            breakpoint_m,
            form,
        })
    }

    /// Seed 001's law as printed: `n = 2`, `d_b = 10` m, [`BreakpointForm::AsPrinted`]; the
    /// paper does not give `P0` and `d₀`, so the caller chooses them.
    ///
    /// # Errors
    /// As [`BreakpointPathLoss::new`] (`d₀` must lie in `(0, 10]` m).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{BreakpointForm, BreakpointPathLoss};
    /// let law = BreakpointPathLoss::seed_001(40.0, 1.0)?;
    /// assert_eq!(law.breakpoint_m(), 10.0);
    /// assert_eq!(law.form(), BreakpointForm::AsPrinted);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 001, §2.2 (`n` "generally 2", breakpoint at 10 m).
    pub fn seed_001(p0_db: f64, d0_m: f64) -> Result<Self> {
        Self::new(p0_db, d0_m, 2.0, 10.0, BreakpointForm::AsPrinted)
    }

    /// The same law with exponent `n₂` beyond the breakpoint (a dual-slope law; the
    /// constructors set `n₂ = n`).
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] or [`EstimationError::InvalidParameter`] unless `n₂` is
    /// finite and positive.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{BreakpointForm, BreakpointPathLoss, PathLoss};
    /// let law = BreakpointPathLoss::new(40.0, 1.0, 2.0, 10.0, BreakpointForm::Continuous)?
    ///     .with_far_exponent(4.0)?;
    /// assert!((law.value_db(100.0) - (40.0 + 20.0 + 40.0)).abs() < 1e-12);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn with_far_exponent(self, far_exponent: f64) -> Result<Self> {
        positive(
            far_exponent,
            "far_exponent",
            "the far path-loss exponent must be positive",
        )?;
        Ok(Self { far_exponent, ..self })
    }

    /// Path loss `P0` at the reference distance, in dB.
    #[inline]
    #[must_use]
    pub fn p0_db(&self) -> f64 {
        self.p0_db
    }

    /// Reference distance `d₀`, in m.
    #[inline]
    #[must_use]
    pub fn reference_distance_m(&self) -> f64 {
        self.reference_distance_m
    }

    /// Exponent `n` up to the breakpoint.
    #[inline]
    #[must_use]
    pub fn exponent(&self) -> f64 {
        self.exponent
    }

    /// Exponent `n₂` beyond the breakpoint.
    #[inline]
    #[must_use]
    pub fn far_exponent(&self) -> f64 {
        self.far_exponent
    }

    /// Breakpoint distance `d_b`, in m.
    #[inline]
    #[must_use]
    pub fn breakpoint_m(&self) -> f64 {
        self.breakpoint_m
    }

    /// The far-branch formula.
    #[inline]
    #[must_use]
    pub fn form(&self) -> BreakpointForm {
        self.form
    }
}

impl PathLoss for BreakpointPathLoss {
    fn value_db(&self, distance_m: f64) -> f64 {
        let (d, d0, db) = (distance_m, self.reference_distance_m, self.breakpoint_m);
        if d <= db {
            // P = P0 + 10 n lg(d/d₀)
            return self.p0_db + 10.0 * self.exponent * log10(d / d0);
        }
        // Loss accumulated up to the breakpoint: P0 + 10 n lg(d_b/d₀)
        let at_breakpoint = self.p0_db + 10.0 * self.exponent * log10(db / d0);
        match self.form {
            // P = P0 + 10 n lg(d_b/d₀) + 10 n₂ lg(d/d₀)
            BreakpointForm::AsPrinted => at_breakpoint + 10.0 * self.far_exponent * log10(d / d0),
            // P = P0 + 10 n lg(d_b/d₀) + 10 n₂ lg(d/d_b)
            BreakpointForm::Continuous => at_breakpoint + 10.0 * self.far_exponent * log10(d / db),
        }
    }

    fn slope_db_per_m(&self, distance_m: f64) -> f64 {
        let exponent = if distance_m <= self.breakpoint_m {
            self.exponent
        } else {
            self.far_exponent
        };
        // ∂P/∂d = 10 n / (d ln 10)
        10.0 * exponent / (distance_m * LN_10)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn log_distance_values_at_known_distances() {
        let law = LogDistancePathLoss::new(0.0, 1.0, 4.0).unwrap();
        assert!(close(law.value_db(1.0), 0.0));
        assert!(close(law.value_db(10.0), -40.0));
        assert!(close(law.value_db(100.0), -80.0));
        // ∂ρ/∂d = −40 / (10 ln 10) at 10 m
        assert!(close(law.slope_db_per_m(10.0), -4.0 / LN_10));
        let shifted = LogDistancePathLoss::new(-30.0, 2.0, 2.0).unwrap();
        assert!(close(shifted.value_db(20.0), -50.0));
        assert_eq!(LogDistancePathLoss::seed_002(), law);
    }

    #[test]
    fn breakpoint_as_printed_on_both_sides_of_10_m() {
        let law = BreakpointPathLoss::seed_001(40.0, 1.0).unwrap();
        // d ≤ 10: P0 + 20 lg d
        assert!(close(law.value_db(1.0), 40.0));
        assert!(close(law.value_db(5.0), 40.0 + 20.0 * log10(5.0)));
        assert!(close(law.value_db(10.0), 60.0));
        // d > 10: P0 + 20 lg 10 + 20 lg d (as printed)
        assert!(close(law.value_db(20.0), 60.0 + 20.0 * log10(20.0)));
        assert!(close(law.value_db(100.0), 100.0));
        // The printed form jumps by 10 n lg(d_b/d₀) = 20 dB at the breakpoint.
        let jump = law.value_db(10.0 + 1e-9) - law.value_db(10.0);
        assert!((jump - 20.0).abs() < 1e-6);
        // The slope is the same formula on both sides.
        assert!(close(law.slope_db_per_m(5.0), 20.0 / (5.0 * LN_10)));
        assert!(close(law.slope_db_per_m(20.0), 20.0 / (20.0 * LN_10)));
    }

    #[test]
    fn breakpoint_continuous_and_dual_slope() {
        let law = BreakpointPathLoss::new(40.0, 1.0, 2.0, 10.0, BreakpointForm::Continuous).unwrap();
        assert!(close(law.value_db(5.0), 40.0 + 20.0 * log10(5.0)));
        // d > 10: P0 + 20 lg 10 + 20 lg(d/10)
        assert!(close(law.value_db(20.0), 60.0 + 20.0 * log10(2.0)));
        assert!((law.value_db(10.0 + 1e-9) - law.value_db(10.0)).abs() < 1e-6);
        let dual = law.with_far_exponent(3.5).unwrap();
        assert!(close(dual.value_db(100.0), 60.0 + 35.0));
        assert!(close(dual.value_db(5.0), law.value_db(5.0)));
        assert!(close(dual.slope_db_per_m(20.0), 35.0 / (20.0 * LN_10)));
        let printed_dual = BreakpointPathLoss::seed_001(40.0, 1.0)
            .unwrap()
            .with_far_exponent(3.5)
            .unwrap();
        assert!(close(printed_dual.value_db(100.0), 60.0 + 70.0));
    }

    #[test]
    fn bad_laws_are_rejected() {
        assert!(matches!(
            LogDistancePathLoss::new(0.0, 0.0, 4.0),
            Err(EstimationError::InvalidParameter {
                name: "reference_distance_m",
                ..
            })
        ));
        assert!(matches!(
            LogDistancePathLoss::new(0.0, 1.0, -2.0),
            Err(EstimationError::InvalidParameter { name: "exponent", .. })
        ));
        assert!(matches!(
            LogDistancePathLoss::new(f64::NAN, 1.0, 4.0),
            Err(EstimationError::NonFinite { .. })
        ));
        assert!(matches!(
            BreakpointPathLoss::seed_001(40.0, -1.0),
            Err(EstimationError::InvalidParameter {
                name: "reference_distance_m",
                ..
            })
        ));
        assert!(matches!(
            BreakpointPathLoss::seed_001(40.0, 11.0),
            Err(EstimationError::InvalidParameter {
                name: "breakpoint_m",
                ..
            })
        ));
        assert!(matches!(
            BreakpointPathLoss::new(40.0, 1.0, 2.0, f64::INFINITY, BreakpointForm::AsPrinted),
            Err(EstimationError::NonFinite { .. })
        ));
        let law = BreakpointPathLoss::seed_001(40.0, 1.0).unwrap();
        assert!(matches!(
            law.with_far_exponent(0.0),
            Err(EstimationError::InvalidParameter {
                name: "far_exponent",
                ..
            })
        ));
    }
}
