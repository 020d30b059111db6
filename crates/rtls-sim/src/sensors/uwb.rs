//! UWB sensors of seed 001: time-of-arrival ranges (Gaussian noise plus an optional positive
//! non-line-of-sight bias) and received signal strength through the breakpoint path-loss law
//! with log-normal shadowing.
//!
//! Every simulator takes its randomness as `rng: &mut impl rand::Rng`, so a seeded generator
//! reproduces a run exactly. Measurements are returned in station order, the order of
//! `rtls_estimation::measurement::Ranges` and `RssPathLoss` built on the same stations.

use rand::Rng;
use rand_distr::{Distribution, Exp, StandardNormal};
use rtls_estimation::measurement::{BreakpointPathLoss, PathLoss};

use crate::error::{finite, finite2, non_negative, Result, SimError};

/// Distances below this (m) count as "the tag is on the station": the path loss diverges.
const MIN_SEPARATION_M: f64 = 1e-9;

/// Non-line-of-sight (NLOS) bias of a UWB range: with probability `p` the direct path is
/// blocked and the first detected path is longer by `b ~ Exp(mean b̄)`; otherwise `b = 0`.
///
/// ```text
/// b = 0 with probability 1 − p,   b ~ Exp(1/b̄) with probability p
/// E[b] = p b̄,   Var[b] = p (2 − p) b̄²
/// ```
/// The bias is never negative: a blocked direct path can only make the first arrival later.
///
/// # Units
/// `mean_bias_m` and the biases in m; `probability` dimensionless in `[0, 1]`.
///
/// # Example
/// ```
/// use rtls_sim::sensors::uwb::NlosBias;
/// let nlos = NlosBias::new(0.2, 1.0)?;
/// assert!((nlos.expected_bias_m() - 0.2).abs() < 1e-12);
/// assert!((nlos.bias_variance_m2() - 0.36).abs() < 1e-12);
/// assert!(NlosBias::new(1.5, 1.0).is_err());
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// B. Alavi, K. Pahlavan, "Modeling of the TOA-based distance measurement error using UWB
/// indoor radio measurements", *IEEE Commun. Letters* 10(4), 2006 (positive NLOS ranging
/// bias; seed 001's ref. \[11\] is by the same group); S. Gezici et al., "Localization via
/// ultra-wideband radios", *IEEE Signal Processing Magazine* 22(4), 2005, §"NLOS
/// propagation" (exponentially distributed excess delay).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NlosBias {
    /// `p`: probability that a range is NLOS, in `[0, 1]`.
    pub probability: f64,
    /// `b̄`: mean bias of an NLOS range, m (`> 0`).
    pub mean_bias_m: f64,
}

impl NlosBias {
    /// A validated NLOS bias model.
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for NaN/∞; [`SimError::InvalidParameter`] unless
    /// `0 ≤ probability ≤ 1` and `mean_bias_m > 0`.
    ///
    /// # Example
    /// ```
    /// assert!(rtls_sim::sensors::uwb::NlosBias::new(0.0, 1.0).is_ok());
    /// assert!(rtls_sim::sensors::uwb::NlosBias::new(0.2, 0.0).is_err());
    /// ```
    pub fn new(probability: f64, mean_bias_m: f64) -> Result<Self> {
        let nlos = Self {
            probability,
            mean_bias_m,
        };
        nlos.validate()?;
        Ok(nlos)
    }

    /// Checks the fields (see [`NlosBias::new`]).
    ///
    /// # Errors
    /// As [`NlosBias::new`].
    pub fn validate(&self) -> Result<()> {
        finite(self.probability, "nlos probability")?;
        finite(self.mean_bias_m, "nlos mean bias")?;
        if !(0.0..=1.0).contains(&self.probability) {
            return Err(SimError::InvalidParameter {
                name: "probability",
                reason: "the NLOS probability must lie in [0, 1]",
            });
        }
        if self.mean_bias_m <= 0.0 {
            return Err(SimError::InvalidParameter {
                name: "mean_bias_m",
                reason: "the mean NLOS bias must be positive (use probability 0 for no NLOS)",
            });
        }
        Ok(())
    }

    /// `E[b] = p b̄`, m.
    #[must_use]
    pub fn expected_bias_m(&self) -> f64 {
        // E[b] = p b̄
        self.probability * self.mean_bias_m
    }

    /// `Var[b] = p (2 − p) b̄²`, m².
    #[must_use]
    pub fn bias_variance_m2(&self) -> f64 {
        // E[b²] = p · 2 b̄²,  Var[b] = E[b²] − E[b]² = p (2 − p) b̄²
        self.probability * (2.0 - self.probability) * self.mean_bias_m * self.mean_bias_m
    }

    /// One bias draw `b ≥ 0` (m): a uniform draw decides NLOS, then an exponential draw its
    /// size (two draws whatever the outcome, so the random stream does not depend on it).
    ///
    /// # Errors
    /// As [`NlosBias::validate`].
    pub fn sample(&self, rng: &mut impl Rng) -> Result<f64> {
        self.validate()?;
        let exponential = Exp::new(1.0 / self.mean_bias_m).map_err(|_| SimError::InvalidParameter {
            name: "mean_bias_m",
            reason: "the mean NLOS bias must be positive",
        })?;
        // u ~ U(0, 1): NLOS when u < p
        let u: f64 = rng.gen();
        // e ~ Exp(1/b̄)
        let e = exponential.sample(rng);
        Ok(if u < self.probability { e } else { 0.0 })
    }
}

/// One epoch of UWB TOA ranges, in station order.
#[derive(Debug, Clone, PartialEq)]
pub struct ToaReading {
    /// Measured ranges `rᵢ = dᵢ + aᵢ + bᵢ`, m (Gaussian noise may make a range to a very close
    /// station negative: the measurement model is Gaussian and is not clamped).
    pub ranges_m: Vec<f64>,
    /// The NLOS bias `bᵢ ≥ 0` included in each range, m (0 for line-of-sight ranges).
    pub nlos_bias_m: Vec<f64>,
}

/// Simulates seed 001's UWB TOA ranges: `rᵢ = ‖p − sᵢ‖ + aᵢ (+ bᵢ)`, `aᵢ ~ N(0, σ²)`
/// independent, plus an optional NLOS bias `bᵢ` ([`NlosBias`]).
///
/// # Units
/// Stations, positions, `σ` and ranges in m.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::sensors::uwb::{NlosBias, UwbToaSimulator};
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
/// let toa = UwbToaSimulator::new(&[[2.0, 2.0], [20.0, 40.0]], 0.2)?;
/// let reading = toa.measure([2.0, 10.0], &mut rng)?;
/// assert_eq!(reading.ranges_m.len(), 2);
/// assert!((reading.ranges_m[0] - 8.0).abs() < 1.5); // within 7.5 σ
/// assert_eq!(reading.nlos_bias_m, vec![0.0, 0.0]);
/// let blocked = toa.with_nlos(NlosBias::new(1.0, 1.0)?);
/// assert!(blocked.measure([2.0, 10.0], &mut rng)?.nlos_bias_m.iter().all(|b| *b > 0.0));
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 001 §2.1: `r_TOA = d_k + a_k`, `a_k` zero-mean Gaussian with constant variance.
#[derive(Debug, Clone, PartialEq)]
pub struct UwbToaSimulator {
    /// Base stations `[x, y]`, m (at least one).
    pub stations_m: Vec<[f64; 2]>,
    /// `σ`: standard deviation of the Gaussian ranging noise, m (`≥ 0`).
    pub range_std_m: f64,
    /// NLOS bias, `None` for line of sight to every station.
    pub nlos: Option<NlosBias>,
}

impl UwbToaSimulator {
    /// A line-of-sight simulator for `stations_m` with ranging noise `range_std_m`.
    ///
    /// # Errors
    /// As [`UwbToaSimulator::validate`].
    pub fn new(stations_m: &[[f64; 2]], range_std_m: f64) -> Result<Self> {
        let sim = Self {
            stations_m: stations_m.to_vec(),
            range_std_m,
            nlos: None,
        };
        sim.validate()?;
        Ok(sim)
    }

    /// The same simulator with NLOS bias `nlos` on every station's ranges.
    #[must_use]
    pub fn with_nlos(self, nlos: NlosBias) -> Self {
        Self {
            nlos: Some(nlos),
            ..self
        }
    }

    /// Checks the fields.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for no stations; [`SimError::NonFinite`] for a NaN/∞ value;
    /// [`SimError::InvalidParameter`] (`range_std_m`) for a negative noise; the errors of
    /// [`NlosBias::validate`].
    pub fn validate(&self) -> Result<()> {
        validate_stations(&self.stations_m)?;
        non_negative(
            self.range_std_m,
            "range_std_m",
            "the ranging noise standard deviation must not be negative",
        )?;
        if let Some(nlos) = &self.nlos {
            nlos.validate()?;
        }
        Ok(())
    }

    /// Noise-free ranges `‖p − sᵢ‖` (m), in station order.
    ///
    /// # Errors
    /// As [`UwbToaSimulator::validate`]; [`SimError::NonFinite`] for a NaN/∞ position.
    pub fn true_ranges_m(&self, position_m: [f64; 2]) -> Result<Vec<f64>> {
        self.validate()?;
        let p = finite2(position_m, "tag position")?;
        Ok(self.stations_m.iter().map(|s| distance_m(p, *s)).collect())
    }

    /// Noisy ranges from the tag at `position_m` to every station. Per station, in station
    /// order: one standard normal draw for `aᵢ`, then (with NLOS configured) the two draws of
    /// [`NlosBias::sample`].
    ///
    /// # Errors
    /// As [`UwbToaSimulator::true_ranges_m`].
    pub fn measure(&self, position_m: [f64; 2], rng: &mut impl Rng) -> Result<ToaReading> {
        let distances_m = self.true_ranges_m(position_m)?;
        let mut ranges_m = Vec::with_capacity(distances_m.len());
        let mut nlos_bias_m = Vec::with_capacity(distances_m.len());
        for d in distances_m {
            // aᵢ = σ n,  n ~ N(0, 1)
            let noise_m = self.range_std_m * rng.sample::<f64, _>(StandardNormal);
            // bᵢ ≥ 0 (0 without NLOS)
            let bias_m = match &self.nlos {
                Some(nlos) => nlos.sample(rng)?,
                None => 0.0,
            };
            // rᵢ = dᵢ + aᵢ + bᵢ
            ranges_m.push(d + noise_m + bias_m);
            nlos_bias_m.push(bias_m);
        }
        Ok(ToaReading { ranges_m, nlos_bias_m })
    }
}

/// Simulates seed 001's UWB RSS as path loss: `Pᵢ = L(‖p − sᵢ‖) + θᵢ`, `θᵢ ~ N(0, σ_s²)`
/// independent, with `L` the breakpoint law ([`BreakpointPathLoss`], either far-branch form).
///
/// The value is path loss in dB (it grows with distance), the quantity seed 001 prints and
/// `rtls_estimation::measurement::RssPathLoss<BreakpointPathLoss>` predicts; a receiver
/// reports `P_tx − Pᵢ` dBm.
///
/// # Units
/// Stations and positions in m; `σ_s`, `L` and `Pᵢ` in dB.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_estimation::measurement::{BreakpointForm, BreakpointPathLoss};
/// use rtls_sim::sensors::uwb::UwbRssSimulator;
/// let law = BreakpointPathLoss::new(48.7, 1.0, 2.0, 10.0, BreakpointForm::Continuous)?;
/// let rss = UwbRssSimulator::new(&[[2.0, 2.0], [20.0, 40.0]], law, 0.0)?;
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
/// let p = rss.measure([2.0, 12.0], &mut rng)?; // 10 m from the first station, no shadowing
/// assert!((p[0] - 68.7).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # References
/// Seed 001 §2.2, the UWB path-loss law with a breakpoint at 10 m and `θ ~ N(0, σ²)`;
/// A. F. Molisch et al., "A comprehensive standardized model for ultrawideband propagation
/// channels", *IEEE Trans. Antennas Propag.* 54(11), 2006 (log-normal shadowing of UWB).
#[derive(Debug, Clone, PartialEq)]
pub struct UwbRssSimulator {
    /// Base stations `[x, y]`, m (at least one).
    pub stations_m: Vec<[f64; 2]>,
    /// The mean path-loss law `L(d)`, dB.
    pub law: BreakpointPathLoss,
    /// `σ_s`: shadowing standard deviation, dB (`≥ 0`).
    pub shadowing_std_db: f64,
}

impl UwbRssSimulator {
    /// A simulator for `stations_m` with law `law` and shadowing `shadowing_std_db`.
    ///
    /// # Errors
    /// As [`UwbRssSimulator::validate`].
    pub fn new(stations_m: &[[f64; 2]], law: BreakpointPathLoss, shadowing_std_db: f64) -> Result<Self> {
        let sim = Self {
            stations_m: stations_m.to_vec(),
            law,
            shadowing_std_db,
        };
        sim.validate()?;
        Ok(sim)
    }

    /// Checks the fields.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for no stations; [`SimError::NonFinite`] for NaN/∞;
    /// [`SimError::InvalidParameter`] (`shadowing_std_db`) for a negative shadowing.
    pub fn validate(&self) -> Result<()> {
        validate_stations(&self.stations_m)?;
        non_negative(
            self.shadowing_std_db,
            "shadowing_std_db",
            "the shadowing standard deviation must not be negative",
        )?;
        Ok(())
    }

    /// Mean path loss `L(‖p − sᵢ‖)` (dB) to every station, in station order.
    ///
    /// # Errors
    /// As [`UwbRssSimulator::validate`]; [`SimError::NonFinite`] for a NaN/∞ position;
    /// [`SimError::InvalidParameter`] (`position_m`) for a tag on a station, where the law
    /// diverges.
    pub fn mean_path_loss_db(&self, position_m: [f64; 2]) -> Result<Vec<f64>> {
        self.validate()?;
        let p = finite2(position_m, "tag position")?;
        self.stations_m
            .iter()
            .map(|s| {
                let d = distance_m(p, *s);
                if d < MIN_SEPARATION_M {
                    return Err(SimError::InvalidParameter {
                        name: "position_m",
                        reason: "the tag is on a base station, where the path loss diverges",
                    });
                }
                // L(dᵢ)
                finite(self.law.value_db(d), "path loss")
            })
            .collect()
    }

    /// Noisy path loss `Pᵢ = L(dᵢ) + θᵢ` (dB) to every station, one standard normal draw per
    /// station in station order.
    ///
    /// # Errors
    /// As [`UwbRssSimulator::mean_path_loss_db`].
    pub fn measure(&self, position_m: [f64; 2], rng: &mut impl Rng) -> Result<Vec<f64>> {
        let mut loss_db = self.mean_path_loss_db(position_m)?;
        for p in &mut loss_db {
            // Pᵢ = L(dᵢ) + σ_s n,  n ~ N(0, 1)
            *p += self.shadowing_std_db * rng.sample::<f64, _>(StandardNormal);
        }
        Ok(loss_db)
    }
}

/// `‖p − s‖` in the plane.
fn distance_m(p: [f64; 2], s: [f64; 2]) -> f64 {
    (p[0] - s[0]).hypot(p[1] - s[1])
}

/// At least one station, all finite.
fn validate_stations(stations_m: &[[f64; 2]]) -> Result<()> {
    if stations_m.is_empty() {
        return Err(SimError::EmptyInput { what: "base stations" });
    }
    for s in stations_m {
        finite2(*s, "base station")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rtls_estimation::measurement::BreakpointForm;

    use super::*;

    const STATIONS: [[f64; 2]; 2] = [[2.0, 2.0], [20.0, 40.0]];

    fn law(form: BreakpointForm) -> BreakpointPathLoss {
        BreakpointPathLoss::new(48.7, 1.0, 2.0, 10.0, form).unwrap()
    }

    #[test]
    fn toa_noise_has_the_configured_mean_and_spread() {
        let toa = UwbToaSimulator::new(&STATIONS, 0.2).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let e = toa.measure([2.0, 10.0], &mut rng).unwrap().ranges_m[0] - 8.0;
            sum += e;
            sum2 += e * e;
        }
        let (mean, var) = (sum / n as f64, sum2 / n as f64);
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var.sqrt() / 0.2 - 1.0).abs() < 0.03, "std {}", var.sqrt());
    }

    #[test]
    fn nlos_bias_is_positive_with_the_configured_rate_and_mean() {
        let nlos = NlosBias::new(0.25, 1.2).unwrap();
        let toa = UwbToaSimulator::new(&STATIONS, 0.0).unwrap().with_nlos(nlos);
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let n = 40_000;
        let (mut count, mut sum, mut sum_all) = (0usize, 0.0, 0.0);
        for _ in 0..n {
            let reading = toa.measure([5.0, 12.0], &mut rng).unwrap();
            let b = reading.nlos_bias_m[1];
            assert!(b >= 0.0);
            // σ = 0: the range is the distance plus the bias
            let d = ((5.0f64 - 20.0).powi(2) + (12.0f64 - 40.0).powi(2)).sqrt();
            assert!((reading.ranges_m[1] - d - b).abs() < 1e-12);
            if b > 0.0 {
                count += 1;
                sum += b;
            }
            sum_all += b;
        }
        let rate = count as f64 / n as f64;
        assert!((rate - 0.25).abs() < 0.01, "rate {rate}");
        assert!(
            (sum / count as f64 / 1.2 - 1.0).abs() < 0.04,
            "mean {}",
            sum / count as f64
        );
        assert!((sum_all / n as f64 - nlos.expected_bias_m()).abs() < 0.02);
    }

    #[test]
    fn rss_follows_the_law_and_the_shadowing() {
        let rss = UwbRssSimulator::new(&STATIONS, law(BreakpointForm::Continuous), 2.0).unwrap();
        let mean = rss.mean_path_loss_db([2.0, 22.0]).unwrap(); // 20 m from the first station
        assert!((mean[0] - (48.7 + 20.0 * 20f64.log10())).abs() < 1e-9);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let e = rss.measure([2.0, 22.0], &mut rng).unwrap()[0] - mean[0];
            sum += e;
            sum2 += e * e;
        }
        assert!((sum / n as f64).abs() < 0.05);
        assert!(((sum2 / n as f64).sqrt() / 2.0 - 1.0).abs() < 0.03);
        // The printed form jumps by 20 dB at the breakpoint; the continuous one does not.
        let printed = UwbRssSimulator::new(&STATIONS, law(BreakpointForm::AsPrinted), 0.0).unwrap();
        let continuous = UwbRssSimulator::new(&STATIONS, law(BreakpointForm::Continuous), 0.0).unwrap();
        let (near, far) = ([2.0, 12.0 - 1e-6], [2.0, 12.0 + 1e-6]);
        let jump =
            |sim: &UwbRssSimulator| sim.mean_path_loss_db(far).unwrap()[0] - sim.mean_path_loss_db(near).unwrap()[0];
        assert!((jump(&printed) - 20.0).abs() < 1e-3);
        assert!(jump(&continuous).abs() < 1e-3);
    }

    #[test]
    fn bad_inputs_are_errors_not_nan() {
        assert!(matches!(
            UwbToaSimulator::new(&[], 0.1),
            Err(SimError::EmptyInput { .. })
        ));
        assert!(UwbToaSimulator::new(&STATIONS, -0.1).is_err());
        assert!(UwbToaSimulator::new(&[[f64::NAN, 0.0]], 0.1).is_err());
        let toa = UwbToaSimulator::new(&STATIONS, 0.1).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        assert!(toa.measure([f64::INFINITY, 0.0], &mut rng).is_err());
        let bad_nlos = NlosBias {
            probability: 0.5,
            mean_bias_m: -1.0,
        };
        assert!(toa.clone().with_nlos(bad_nlos).measure([0.0, 0.0], &mut rng).is_err());
        assert!(NlosBias::new(f64::NAN, 1.0).is_err());
        assert!(NlosBias::new(-0.1, 1.0).is_err());
        let rss = UwbRssSimulator::new(&STATIONS, law(BreakpointForm::Continuous), 2.0).unwrap();
        assert!(matches!(
            rss.measure([2.0, 2.0], &mut rng),
            Err(SimError::InvalidParameter { name: "position_m", .. })
        ));
        assert!(UwbRssSimulator::new(&STATIONS, law(BreakpointForm::Continuous), -2.0).is_err());
    }

    #[test]
    fn the_same_seed_gives_the_same_readings() {
        let toa = UwbToaSimulator::new(&STATIONS, 0.3)
            .unwrap()
            .with_nlos(NlosBias::new(0.3, 1.0).unwrap());
        let draw = |seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            (0..10)
                .map(|_| toa.measure([3.0, 9.0], &mut rng).unwrap())
                .collect::<Vec<_>>()
        };
        assert_eq!(draw(9), draw(9));
        assert_ne!(draw(9), draw(10));
    }
}
