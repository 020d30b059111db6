//! Seed 001's UWB path-loss law with a breakpoint: the continuous dual-slope form (default)
//! and the printed, discontinuous one.

use core::f64::consts::LN_10;

use super::{clamp_distance, finite, finite_rssi, inverted_distance, non_negative, positive, PathLossModel};
use crate::error::{PositioningError, Result};

/// Which far-branch formula a [`Breakpoint`] law uses beyond the breakpoint `d_b`.
///
/// **Erratum (seed 001).** The paper prints the far branch as
/// `P0 + 10 n lg(10/d₀) + 10 n lg(d/d₀)`: it adds the whole near-branch loss
/// `10 n lg(d/d₀)` again instead of continuing from the breakpoint, so the path loss jumps up
/// by `10 n lg(d_b/d₀)` at `d_b` — **20 dB** for the paper's `n = 2`, `d_b = 10` m and
/// `d₀ = 1` m (the received power drops by 20 dB between 10 m and 10 m + ε). No physical
/// channel does that; the standard dual-slope law continues from the breakpoint,
/// `P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d_b)`, and is the default here.
///
/// # References
/// Seed 001, §2.2 (the printed RSS model, breakpoint at 10 m); V. Erceg et al., "TGn channel
/// models", IEEE 802.11-03/940r4, 2004, eq. (1) (dual-slope law continuous at the
/// breakpoint); A. F. Molisch et al., "A comprehensive standardized model for ultrawideband
/// propagation channels", *IEEE Trans. Antennas Propag.* 54(11), 2006 (IEEE 802.15.4a UWB
/// path loss `PL0 + 10 n lg(d/d₀)` with log-normal shadowing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BreakpointForm {
    /// `P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d_b)` beyond `d_b`: continuous at `d_b` (the
    /// standard dual-slope law). With `n₁ = n₂` it is the one-slope law everywhere.
    #[default]
    Continuous,
    /// Seed 001 as printed: `P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d₀)` beyond `d_b`; jumps up by
    /// `10 n₂ lg(d_b/d₀)` dB at `d_b`. Use it only to reproduce the paper.
    AsPrinted,
}

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
/// Seed 001's `P` is *path loss* (dB, increasing with `d`); [`PathLossModel`] speaks
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
    parameters: BreakpointParameters,
}

impl Breakpoint {
    /// A validated breakpoint law.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] naming the field unless every value is finite,
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
        finite(p.reference_loss_db, "reference_loss_db")?;
        positive(
            p.reference_distance_m,
            "reference_distance_m",
            "the reference distance must be positive (usually 1 m)",
        )?;
        positive(
            p.near_exponent,
            "near_exponent",
            "the path-loss exponent must be positive",
        )?;
        positive(
            p.far_exponent,
            "far_exponent",
            "the path-loss exponent must be positive",
        )?;
        finite(p.breakpoint_m, "breakpoint_m")?;
        if p.breakpoint_m < p.reference_distance_m {
            return Err(PositioningError::InvalidParameter {
                name: "breakpoint_m",
                reason: "the breakpoint must not be closer than the reference distance",
            });
        }
        non_negative(
            p.shadowing_std_db,
            "shadowing_std_db",
            "the shadowing standard deviation must be non-negative",
        )?;
        Ok(Self { parameters })
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
        Self {
            parameters: BreakpointParameters {
                form,
                ..BreakpointParameters::seed_001()
            },
        }
    }

    /// The law's parameters.
    #[inline]
    #[must_use]
    pub fn parameters(&self) -> &BreakpointParameters {
        &self.parameters
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
        let p = &self.parameters;
        let (d, d0, db) = (clamp_distance(distance_m), p.reference_distance_m, p.breakpoint_m);
        if d <= db {
            // P = P0 + 10 n₁ lg(d/d₀)
            return p.reference_loss_db + 10.0 * p.near_exponent * (d / d0).log10();
        }
        let at_breakpoint_db = self.breakpoint_loss_db();
        match p.form {
            // P = P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d_b)
            BreakpointForm::Continuous => at_breakpoint_db + 10.0 * p.far_exponent * (d / db).log10(),
            // P = P0 + 10 n₁ lg(d_b/d₀) + 10 n₂ lg(d/d₀)
            BreakpointForm::AsPrinted => at_breakpoint_db + 10.0 * p.far_exponent * (d / d0).log10(),
        }
    }

    /// The jump of the path loss at the breakpoint, `P(d_b⁺) − P(d_b)` (dB): 0 for the
    /// continuous form, `10 n₂ lg(d_b/d₀)` for the printed one (20 dB with seed 001's values).
    #[must_use]
    pub fn discontinuity_db(&self) -> f64 {
        let p = &self.parameters;
        match p.form {
            BreakpointForm::Continuous => 0.0,
            // 10 n₂ lg(d_b/d₀)
            BreakpointForm::AsPrinted => 10.0 * p.far_exponent * (p.breakpoint_m / p.reference_distance_m).log10(),
        }
    }

    /// `P_b = P0 + 10 n₁ lg(d_b/d₀)`: the path loss at the breakpoint (dB).
    fn breakpoint_loss_db(&self) -> f64 {
        let p = &self.parameters;
        p.reference_loss_db + 10.0 * p.near_exponent * (p.breakpoint_m / p.reference_distance_m).log10()
    }
}

impl PathLossModel for Breakpoint {
    fn mean_rssi_dbm(&self, distance_m: f64) -> f64 {
        // μ(d) = P_tx − P(d)
        self.parameters.transmit_power_dbm - self.path_loss_db(distance_m)
    }

    fn slope_db_per_m(&self, distance_m: f64) -> f64 {
        let p = &self.parameters;
        let d = clamp_distance(distance_m);
        let exponent = if d <= p.breakpoint_m {
            p.near_exponent
        } else {
            p.far_exponent
        };
        // dμ/dd = −10 n / (d ln 10)
        -10.0 * exponent / (d * LN_10)
    }

    fn shadowing_std_db(&self) -> f64 {
        self.parameters.shadowing_std_db
    }

    fn distance_m(&self, rssi_dbm: f64) -> Result<f64> {
        let rssi_dbm = finite_rssi(rssi_dbm)?;
        let p = &self.parameters;
        // P = P_tx − ρ
        let loss_db = p.transmit_power_dbm - rssi_dbm;
        let at_breakpoint_db = self.breakpoint_loss_db();
        let distance_m = if loss_db <= at_breakpoint_db {
            // d = d₀ 10^((P − P0)/(10 n₁))
            p.reference_distance_m * 10f64.powf((loss_db - p.reference_loss_db) / (10.0 * p.near_exponent))
        } else {
            match p.form {
                // d = d_b 10^((P − P_b)/(10 n₂))
                BreakpointForm::Continuous => {
                    p.breakpoint_m * 10f64.powf((loss_db - at_breakpoint_db) / (10.0 * p.far_exponent))
                }
                // inside the printed form's jump: no preimage, the breakpoint is nearest
                BreakpointForm::AsPrinted if loss_db <= at_breakpoint_db + self.discontinuity_db() => p.breakpoint_m,
                // d = d₀ 10^((P − P_b)/(10 n₂))
                BreakpointForm::AsPrinted => {
                    p.reference_distance_m * 10f64.powf((loss_db - at_breakpoint_db) / (10.0 * p.far_exponent))
                }
            }
        };
        inverted_distance(distance_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
