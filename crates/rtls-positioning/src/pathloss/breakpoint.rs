//! Seed 001's UWB path-loss law with a breakpoint: the continuous dual-slope form (default)
//! and the printed, discontinuous one.

pub use rtls_estimation::measurement::BreakpointForm;
use rtls_estimation::measurement::{BreakpointPathLoss, PathLoss};

use super::{clamp_distance, finite, finite_rssi, inverted_distance, law_error, non_negative, PathLossModel};
use crate::error::Result;

/// The parameters of a [`Breakpoint`] law (validated by [`Breakpoint::new`]).
///
/// # Units
/// Powers in dBm, losses in dB, distances in m, exponents dimensionless, `σ_s` in dB.
///
/// # References
/// Seed 001, §2.2 (`n = 2`, `d_b = 10` m; `P0`, `d₀` and `σ_s` not given).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreakpointParameters {
    /// Transmit power `P_tx` (dBm); the received power is `P_tx − P(d)`.
    pub transmit_power_dbm: f64,
    /// `P0`: path loss at the reference distance (dB).
    pub reference_loss_db: f64,
    /// `d₀`: reference distance (m), `> 0`.
    pub reference_distance_m: f64,
    /// `n₁`: exponent up to the breakpoint, `> 0`.
    pub near_exponent: f64,
    /// `n₂`: exponent beyond the breakpoint, `> 0` (seed 001: `n₂ = n₁ = 2`).
    pub far_exponent: f64,
    /// `d_b`: breakpoint distance (m), `≥ d₀` (seed 001: 10 m).
    pub breakpoint_m: f64,
    /// `σ_s`: shadowing standard deviation (dB), `≥ 0`.
    pub shadowing_std_db: f64,
    /// Far-branch formula.
    pub form: BreakpointForm,
}

impl BreakpointParameters {
    /// Seed 001's law with this project's choices for what the paper leaves open:
    /// `n₁ = n₂ = 2`, `d_b = 10` m (the paper's), `d₀ = 1` m, `P0 = 48.7` dB (free-space loss
    /// at 1 m and 6.5 GHz, UWB channel 5), `P_tx = 0` dBm, `σ_s = 2` dB, continuous form.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{BreakpointForm, BreakpointParameters};
    /// let printed = BreakpointParameters { form: BreakpointForm::AsPrinted, ..BreakpointParameters::seed_001() };
    /// assert_eq!(printed.breakpoint_m, 10.0);
    /// ```
    ///
    /// # References
    /// Seed 001, §2.2; free-space loss `20 lg(4π d f / c)` (Friis).
    #[must_use]
    pub fn seed_001() -> Self {
        Self {
            transmit_power_dbm: 0.0,
            reference_loss_db: 48.7,
            reference_distance_m: 1.0,
            near_exponent: 2.0,
            far_exponent: 2.0,
            breakpoint_m: 10.0,
            shadowing_std_db: 2.0,
            form: BreakpointForm::Continuous,
        }
    }
}

/// Seed 001's UWB path-loss law with a breakpoint, as received power:
///
/// ```text
/// P(d) = P0 + 10 n₁ lg(d/d₀)                                     d ≤ d_b
///        P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d_b)   (Continuous)   d > d_b
///        P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d₀)    (AsPrinted)    d > d_b
/// μ(d) = P_tx − P(d),   ρ = μ(d) + θ,   θ ~ N(0, σ_s²)
/// ```
///
/// Seed 001's `P` is *path loss* (dB, increasing with `d`), computed by `rtls-estimation`'s
/// [`BreakpointPathLoss`] (the law the filters' RSS model uses); [`PathLossModel`] speaks
/// received power (dBm), hence the transmit power. The slope is
/// `dμ/dd = −10 n / (d ln 10)` with `n = n₁` for `d ≤ d_b` and `n₂` beyond (the same in both
/// forms; the printed form's jump is not part of the derivative). See [`BreakpointForm`] for
/// the erratum of the printed form.
///
/// Inversion: `d = d₀ 10^((P − P0)/(10 n₁))` up to the breakpoint loss
/// `P_b = P0 + 10 n₁ lg(d_b/d₀)`; beyond, `d = d_b 10^((P − P_b)/(10 n₂))` (continuous) or
/// `d = d₀ 10^((P − P_b)/(10 n₂))` (printed). The printed form leaves a gap: received powers
/// within the jump below `P_tx − P_b` have no preimage and are mapped to `d_b`.
///
/// # Units
/// As [`BreakpointParameters`].
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{Breakpoint, BreakpointForm, PathLossModel};
/// let law = Breakpoint::seed_001(BreakpointForm::Continuous);
/// // 0 dBm − (48.7 + 20 lg 10 + 20 lg 2) dB at 20 m
/// assert!((law.mean_rssi_dbm(20.0) + 48.7 + 20.0 + 20.0 * 2f64.log10()).abs() < 1e-12);
/// let printed = Breakpoint::seed_001(BreakpointForm::AsPrinted);
/// assert!((printed.discontinuity_db() - 20.0).abs() < 1e-12);
/// ```
///
/// # References
/// Seed 001 eq. (8) and §2.2; Erceg et al. (2004); Molisch et al. (2006), see
/// [`BreakpointForm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Breakpoint {
    law: BreakpointPathLoss,
    transmit_power_dbm: f64,
    shadowing_std_db: f64,
}

impl Breakpoint {
    /// A validated breakpoint law.
    ///
    /// # Errors
    /// [`crate::PositioningError::InvalidParameter`] naming the field unless every value is finite,
    /// `d₀ > 0`, `n₁ > 0`, `n₂ > 0`, `d_b ≥ d₀` and `σ_s ≥ 0`.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{Breakpoint, BreakpointParameters};
    /// let dual = Breakpoint::new(BreakpointParameters { far_exponent: 3.5, ..BreakpointParameters::seed_001() })?;
    /// assert_eq!(dual.parameters().far_exponent, 3.5);
    /// assert!(Breakpoint::new(BreakpointParameters { breakpoint_m: 0.5, ..BreakpointParameters::seed_001() }).is_err());
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Seed 001, §2.2.
    pub fn new(parameters: BreakpointParameters) -> Result<Self> {
        let p = parameters;
        finite(p.transmit_power_dbm, "transmit_power_dbm")?;
        non_negative(
            p.shadowing_std_db,
            "shadowing_std_db",
            "the shadowing standard deviation must be non-negative",
        )?;
        // the law's names → the fields of BreakpointParameters
        let renames = [("p0_db", "reference_loss_db"), ("exponent", "near_exponent")];
        let law = BreakpointPathLoss::new(
            p.reference_loss_db,
            p.reference_distance_m,
            p.near_exponent,
            p.breakpoint_m,
            p.form,
        )
        .and_then(|law| law.with_far_exponent(p.far_exponent))
        .map_err(|e| law_error(e, &renames))?;
        Ok(Self {
            law,
            transmit_power_dbm: p.transmit_power_dbm,
            shadowing_std_db: p.shadowing_std_db,
        })
    }

    /// [`BreakpointParameters::seed_001`] with the chosen far-branch `form`
    /// ([`BreakpointForm::AsPrinted`] reproduces the paper exactly).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{Breakpoint, BreakpointForm};
    /// assert_eq!(Breakpoint::seed_001(BreakpointForm::Continuous).discontinuity_db(), 0.0);
    /// ```
    ///
    /// # References
    /// Seed 001, §2.2.
    #[must_use]
    pub fn seed_001(form: BreakpointForm) -> Self {
        let p = BreakpointParameters::seed_001();
        let law = BreakpointPathLoss::new(
            p.reference_loss_db,
            p.reference_distance_m,
            p.near_exponent,
            p.breakpoint_m,
            form,
        )
        .expect("seed 001's constants are a valid law");
        Self {
            law,
            transmit_power_dbm: p.transmit_power_dbm,
            shadowing_std_db: p.shadowing_std_db,
        }
    }

    /// The law's parameters.
    #[must_use]
    pub fn parameters(&self) -> BreakpointParameters {
        BreakpointParameters {
            transmit_power_dbm: self.transmit_power_dbm,
            reference_loss_db: self.law.p0_db(),
            reference_distance_m: self.law.reference_distance_m(),
            near_exponent: self.law.exponent(),
            far_exponent: self.law.far_exponent(),
            breakpoint_m: self.law.breakpoint_m(),
            shadowing_std_db: self.shadowing_std_db,
            form: self.law.form(),
        }
    }

    /// Path loss `P(d)` (dB) at `distance_m`, the quantity seed 001 prints (distances outside
    /// `[MIN_DISTANCE_M, MAX_DISTANCE_M]` are clamped).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{Breakpoint, BreakpointForm};
    /// let printed = Breakpoint::seed_001(BreakpointForm::AsPrinted);
    /// // P0 + 10 n lg(10/d₀) + 10 n lg(d/d₀) at 20 m, as printed
    /// assert!((printed.path_loss_db(20.0) - (48.7 + 20.0 + 20.0 * 20f64.log10())).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn path_loss_db(&self, distance_m: f64) -> f64 {
        self.law.value_db(clamp_distance(distance_m))
    }

    /// The jump of the path loss at the breakpoint, `P(d_b⁺) − P(d_b)` (dB): 0 for the
    /// continuous form, `10 n₂ lg(d_b/d₀)` for the printed one (20 dB with seed 001's values).
    #[must_use]
    pub fn discontinuity_db(&self) -> f64 {
        let law = &self.law;
        match law.form() {
            BreakpointForm::Continuous => 0.0,
            // 10 n₂ lg(d_b/d₀)
            BreakpointForm::AsPrinted => {
                10.0 * law.far_exponent() * (law.breakpoint_m() / law.reference_distance_m()).log10()
            }
        }
    }
}

impl PathLossModel for Breakpoint {
    fn mean_rssi_dbm(&self, distance_m: f64) -> f64 {
        // μ(d) = P_tx − P(d)
        self.transmit_power_dbm - self.path_loss_db(distance_m)
    }

    fn slope_db_per_m(&self, distance_m: f64) -> f64 {
        // dμ/dd = −dP/dd = −10 n / (d ln 10)
        -self.law.slope_db_per_m(clamp_distance(distance_m))
    }

    fn shadowing_std_db(&self) -> f64 {
        self.shadowing_std_db
    }

    fn distance_m(&self, rssi_dbm: f64) -> Result<f64> {
        let rssi_dbm = finite_rssi(rssi_dbm)?;
        let law = &self.law;
        let (d0, db) = (law.reference_distance_m(), law.breakpoint_m());
        // P = P_tx − ρ
        let loss_db = self.transmit_power_dbm - rssi_dbm;
        // P_b = P0 + 10 n₁ lg(d_b/d₀): the loss at the breakpoint
        let at_breakpoint_db = law.value_db(db);
        let distance_m = if loss_db <= at_breakpoint_db {
            // d = d₀ 10^((P − P0)/(10 n₁))
            d0 * 10f64.powf((loss_db - law.p0_db()) / (10.0 * law.exponent()))
        } else {
            let far = 10f64.powf((loss_db - at_breakpoint_db) / (10.0 * law.far_exponent()));
            match law.form() {
                // d = d_b 10^((P − P_b)/(10 n₂))
                BreakpointForm::Continuous => db * far,
                // inside the printed form's jump: no preimage, the breakpoint is nearest
                BreakpointForm::AsPrinted if loss_db <= at_breakpoint_db + self.discontinuity_db() => db,
                // d = d₀ 10^((P − P_b)/(10 n₂))
                BreakpointForm::AsPrinted => d0 * far,
            }
        };
        inverted_distance(distance_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PositioningError;
    use core::f64::consts::LN_10;

    fn dual(form: BreakpointForm) -> Breakpoint {
        Breakpoint::new(BreakpointParameters {
            transmit_power_dbm: 10.0,
            reference_loss_db: 40.0,
            reference_distance_m: 0.5,
            near_exponent: 2.0,
            far_exponent: 3.5,
            breakpoint_m: 8.0,
            shadowing_std_db: 3.0,
            form,
        })
        .unwrap()
    }

    #[test]
    fn default_form_is_continuous_at_the_breakpoint() {
        for law in [
            Breakpoint::seed_001(BreakpointForm::Continuous),
            dual(BreakpointForm::Continuous),
        ] {
            let db = law.parameters().breakpoint_m;
            let jump = law.mean_rssi_dbm(db * (1.0 + 1e-12)) - law.mean_rssi_dbm(db);
            assert!(jump.abs() < 1e-9, "jump {jump}");
            assert_eq!(law.discontinuity_db(), 0.0);
        }
        assert_eq!(BreakpointForm::default(), BreakpointForm::Continuous);
        assert_eq!(BreakpointParameters::seed_001().form, BreakpointForm::Continuous);
        // n₁ = n₂: the continuous form is the one-slope law everywhere
        let law = Breakpoint::seed_001(BreakpointForm::Continuous);
        for d in [0.3_f64, 1.0, 9.0, 10.0, 11.0, 250.0] {
            let one_slope = -48.7 - 20.0 * d.log10();
            assert!((law.mean_rssi_dbm(d) - one_slope).abs() < 1e-12, "{d}");
        }
    }

    #[test]
    fn printed_form_reproduces_the_paper_and_jumps_by_10_n_lg_db_over_d0() {
        let law = Breakpoint::seed_001(BreakpointForm::AsPrinted);
        for d in [1.0_f64, 5.0, 10.0] {
            // P = P0 + 10 n lg(d/d₀)
            assert!((law.path_loss_db(d) - (48.7 + 20.0 * d.log10())).abs() < 1e-12);
        }
        for d in [10.5_f64, 20.0, 100.0] {
            // P = P0 + 10 n lg(10/d₀) + 10 n lg(d/d₀), as printed
            assert!((law.path_loss_db(d) - (48.7 + 20.0 * 10f64.log10() + 20.0 * d.log10())).abs() < 1e-12);
        }
        // the documented jump: 10 n lg(d_b/d₀) = 20 dB, received power drops by as much
        let jump = law.mean_rssi_dbm(10.0) - law.mean_rssi_dbm(10.0 * (1.0 + 1e-12));
        assert!((jump - 20.0).abs() < 1e-9, "jump {jump}");
        assert!((law.discontinuity_db() - 20.0).abs() < 1e-12);
        // with a far exponent: 10 n₂ lg(d_b/d₀)
        let law = dual(BreakpointForm::AsPrinted);
        let expected = 35.0 * (8.0f64 / 0.5).log10();
        assert!((law.discontinuity_db() - expected).abs() < 1e-12);
        let jump = law.mean_rssi_dbm(8.0) - law.mean_rssi_dbm(8.0 * (1.0 + 1e-12));
        assert!((jump - expected).abs() < 1e-9);
        // both forms agree up to the breakpoint and differ by the jump beyond it
        let continuous = dual(BreakpointForm::Continuous);
        assert_eq!(continuous.mean_rssi_dbm(3.0), law.mean_rssi_dbm(3.0));
        assert!((continuous.mean_rssi_dbm(30.0) - law.mean_rssi_dbm(30.0) - expected).abs() < 1e-9);
    }

    #[test]
    fn inversion_round_trip_slope_and_range_std_on_both_branches() {
        for form in [BreakpointForm::Continuous, BreakpointForm::AsPrinted] {
            let law = dual(form);
            for d in [0.01, 0.5, 2.0, 7.99, 8.0, 8.01, 30.0, 1e4] {
                let rho = law.mean_rssi_dbm(d);
                let back = law.distance_m(rho).unwrap();
                assert!((back - d).abs() < 1e-9 * d, "{form:?} {d}: {back}");
                let n = if d <= 8.0 { 2.0 } else { 3.5 };
                assert!((law.slope_db_per_m(d) + 10.0 * n / (d * LN_10)).abs() < 1e-12 / d);
                // σ_d = d ln 10 σ_s / (10 n)
                let sigma_d = law.range_std_m(d).unwrap();
                assert!((sigma_d - d * LN_10 * 3.0 / (10.0 * n)).abs() < 1e-12 * d);
            }
            // the slope is the derivative away from the breakpoint
            for d in [3.0, 20.0] {
                let h = 1e-6 * d;
                let numeric = (law.mean_rssi_dbm(d + h) - law.mean_rssi_dbm(d - h)) / (2.0 * h);
                assert!((law.slope_db_per_m(d) - numeric).abs() < 1e-6 * numeric.abs());
            }
        }
        // powers inside the printed form's jump map to the breakpoint
        let law = Breakpoint::seed_001(BreakpointForm::AsPrinted);
        let just_before = law.mean_rssi_dbm(10.0);
        for rho in [just_before - 0.1, just_before - 10.0, just_before - 19.9] {
            assert_eq!(law.distance_m(rho).unwrap(), 10.0);
        }
        assert!(law.distance_m(just_before - 20.1).unwrap() > 10.0);
    }

    #[test]
    fn invalid_parameters_and_inputs_are_errors() {
        let base = BreakpointParameters::seed_001();
        let name = |p: BreakpointParameters| match Breakpoint::new(p) {
            Err(PositioningError::InvalidParameter { name, .. }) => name,
            other => panic!("expected InvalidParameter, got {other:?}"),
        };
        assert_eq!(
            name(BreakpointParameters {
                transmit_power_dbm: f64::NAN,
                ..base
            }),
            "transmit_power_dbm"
        );
        assert_eq!(
            name(BreakpointParameters {
                reference_loss_db: f64::INFINITY,
                ..base
            }),
            "reference_loss_db"
        );
        assert_eq!(
            name(BreakpointParameters {
                reference_distance_m: 0.0,
                ..base
            }),
            "reference_distance_m"
        );
        assert_eq!(
            name(BreakpointParameters {
                near_exponent: -1.0,
                ..base
            }),
            "near_exponent"
        );
        assert_eq!(
            name(BreakpointParameters {
                far_exponent: 0.0,
                ..base
            }),
            "far_exponent"
        );
        assert_eq!(
            name(BreakpointParameters {
                breakpoint_m: 0.9,
                ..base
            }),
            "breakpoint_m"
        );
        assert_eq!(
            name(BreakpointParameters {
                breakpoint_m: f64::NAN,
                ..base
            }),
            "breakpoint_m"
        );
        assert_eq!(
            name(BreakpointParameters {
                shadowing_std_db: -2.0,
                ..base
            }),
            "shadowing_std_db"
        );
        assert_eq!(
            Breakpoint::new(base).unwrap(),
            Breakpoint::seed_001(BreakpointForm::Continuous)
        );
        let law = Breakpoint::seed_001(BreakpointForm::AsPrinted);
        assert!(matches!(
            law.distance_m(f64::NAN),
            Err(PositioningError::NonFinite { .. })
        ));
        assert!(matches!(
            law.distance_m(1e6),
            Err(PositioningError::NoConsistentSolution { .. })
        ));
    }
}
