//! Cellular TDOA with Gaussian timing noise and a uniform NLOS delay (seed 004).

use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::{finite2, non_negative, positive, Result, SimError};
use crate::scenarios::SEED_004_STATIONS;

/// Speed of light in vacuum, m/s (exact by the SI definition of the metre).
///
/// # Example
/// ```
/// assert!((rtls_sim::SPEED_OF_LIGHT_MPS * 100e-9 - 29.9792458).abs() < 1e-9);
/// ```
///
/// # References
/// BIPM, *The International System of Units*, 9th ed., 2019.
pub const SPEED_OF_LIGHT_MPS: f64 = 299_792_458.0;

/// Simulates TDOA range differences from base stations to a target.
///
/// For every station `i ≠ ref`, in station order,
///
/// ```text
/// z_i = ‖p − s_i‖ − ‖p − s_ref‖ + c (n_g + n_u),   n_g ~ N(0, σ_g²),   n_u ~ U(0, u_max)
/// ```
///
/// in metres, with independent noise per time difference (the paper puts the error on the
/// time difference itself, not on each station's TOA). `n_u ≥ 0` models the extra path length
/// of non-line-of-sight propagation, so the noise has mean `c u_max/2` (a bias) and variance
/// `c² (σ_g² + u_max²/12)`. The convention is that of `rtls_estimation::measurement::Tdoa`
/// (range differences to a reference anchor, anchor order, reference omitted).
///
/// # Units
/// Stations and positions in m, times in s, `c` in m/s, range differences in m.
///
/// # Errors
/// [`TdoaSimulator::measure`] validates the fields (see there).
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::TdoaSimulator;
/// let sim = TdoaSimulator::seed_004();
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
/// let z = sim.measure([0.0, 0.0], 0, &mut rng)?;
/// assert_eq!(z.len(), 3);
/// assert!((sim.range_difference_bias_m() - 29.9792458).abs() < 1e-9); // c · 100 ns
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3: "时差的观测误差为 100 ns 的高斯白噪声和 0~200 ns 的均匀噪声"; Chan & Ho,
/// *IEEE Trans. SP* 42(8), 1994 (range differences).
#[derive(Debug, Clone, PartialEq)]
pub struct TdoaSimulator {
    /// Base-station positions `[x, y]`, m (at least two).
    pub stations: Vec<[f64; 2]>,
    /// Propagation speed `c`, m/s.
    pub speed_of_light_mps: f64,
    /// Standard deviation `σ_g` of the Gaussian timing noise, s (seed 004: 100 ns).
    pub gaussian_std_s: f64,
    /// Upper end `u_max` of the uniform NLOS delay, s (seed 004: 200 ns; 0 disables it).
    pub nlos_uniform_max_s: f64,
}

impl TdoaSimulator {
    /// A simulator for `stations` with seed 004's noise: `σ_g = 100` ns, `u_max = 200` ns,
    /// `c` = [`SPEED_OF_LIGHT_MPS`].
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`stations`) for fewer than two stations;
    /// [`SimError::NonFinite`] for a NaN/∞ coordinate.
    ///
    /// # Example
    /// ```
    /// let sim = rtls_sim::TdoaSimulator::new(&[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]])?;
    /// assert_eq!(sim.gaussian_std_s, 100e-9);
    /// assert!(rtls_sim::TdoaSimulator::new(&[[0.0, 0.0]]).is_err());
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    pub fn new(stations: &[[f64; 2]]) -> Result<Self> {
        let sim = Self {
            stations: stations.to_vec(),
            speed_of_light_mps: SPEED_OF_LIGHT_MPS,
            gaussian_std_s: 100e-9,
            nlos_uniform_max_s: 200e-9,
        };
        sim.validate()?;
        Ok(sim)
    }

    /// The seed 004 simulator: [`SEED_004_STATIONS`](crate::SEED_004_STATIONS) and the noise
    /// of [`TdoaSimulator::new`].
    ///
    /// # Example
    /// ```
    /// let sim = rtls_sim::TdoaSimulator::seed_004();
    /// assert_eq!(sim.stations.len(), 4);
    /// assert_eq!(sim.nlos_uniform_max_s, 200e-9);
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (stations: our choice).
    #[must_use]
    pub fn seed_004() -> Self {
        Self {
            stations: SEED_004_STATIONS.to_vec(),
            speed_of_light_mps: SPEED_OF_LIGHT_MPS,
            gaussian_std_s: 100e-9,
            nlos_uniform_max_s: 200e-9,
        }
    }

    /// Noise-free range differences `‖p − s_i‖ − ‖p − s_ref‖` (m) for every `i ≠ reference`,
    /// in station order.
    ///
    /// # Errors
    /// As [`TdoaSimulator::measure`].
    ///
    /// # Example
    /// ```
    /// let sim = rtls_sim::TdoaSimulator::new(&[[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0]])?;
    /// let z = sim.true_range_differences([0.0, 4000.0], 0)?;
    /// assert_eq!(z, vec![1000.0, -3000.0]); // 5000 − 4000, 1000 − 4000
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Chan & Ho (1994), eq. (2): `r_{i,1} = r_i − r_1`.
    pub fn true_range_differences(&self, position_m: [f64; 2], reference: usize) -> Result<Vec<f64>> {
        self.validate()?;
        let p = finite2(position_m, "position")?;
        if reference >= self.stations.len() {
            return Err(SimError::InvalidParameter {
                name: "reference",
                reason: "the reference station index must be less than the number of stations",
            });
        }
        // r_i = ‖p − s_i‖
        let range_m = |s: &[f64; 2]| (p[0] - s[0]).hypot(p[1] - s[1]);
        let reference_range_m = range_m(&self.stations[reference]);
        Ok(self
            .stations
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != reference)
            // r_i − r_ref
            .map(|(_, s)| range_m(s) - reference_range_m)
            .collect())
    }

    /// Noisy range differences `z_i = ‖p − s_i‖ − ‖p − s_ref‖ + c (n_g + n_u)` (m) for every
    /// `i ≠ reference`, in station order, with independent `n_g ~ N(0, σ_g²)` and
    /// `n_u ~ U(0, u_max)` per difference.
    ///
    /// For the paper's "cyclic master station" scheme, rotate `reference` between calls.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for fewer than two stations, `reference ≥` the number of
    /// stations, `c ≤ 0`, or a negative `σ_g` / `u_max`; [`SimError::NonFinite`] for a NaN/∞
    /// station, position or parameter.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// let mut sim = rtls_sim::TdoaSimulator::new(&[[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0]])?;
    /// sim.gaussian_std_s = 0.0;
    /// sim.nlos_uniform_max_s = 0.0;
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    /// assert_eq!(sim.measure([0.0, 4000.0], 0, &mut rng)?, vec![1000.0, -3000.0]);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (error model); Chan & Ho (1994).
    pub fn measure(&self, position_m: [f64; 2], reference: usize, rng: &mut impl Rng) -> Result<Vec<f64>> {
        let mut z = self.true_range_differences(position_m, reference)?;
        let c = self.speed_of_light_mps;
        for z_i in &mut z {
            // n_g ~ N(0, σ_g²)
            let n_g = self.gaussian_std_s * rng.sample::<f64, _>(StandardNormal);
            // n_u ~ U(0, u_max)
            let n_u = self.nlos_uniform_max_s * rng.gen::<f64>();
            // z_i += c (n_g + n_u)
            *z_i += c * (n_g + n_u);
        }
        Ok(z)
    }

    /// Variance of one range difference's noise, `c² (σ_g² + u_max²/12)` in m² (Gaussian
    /// variance plus that of the uniform NLOS delay), the value to put on the diagonal of a
    /// filter's `R`; the differences are independent, so `R` is diagonal.
    ///
    /// # Example
    /// ```
    /// let sim = rtls_sim::TdoaSimulator::seed_004();
    /// let c = rtls_sim::SPEED_OF_LIGHT_MPS;
    /// let expected = c * c * (1e-14 + 4e-14 / 12.0);
    /// assert!((sim.range_difference_variance_m2() - expected).abs() < 1e-9 * expected);
    /// ```
    ///
    /// # References
    /// Seed 004 §3; the variance of `U(0, u)` is `u²/12`.
    #[must_use]
    pub fn range_difference_variance_m2(&self) -> f64 {
        let c = self.speed_of_light_mps;
        let u = self.nlos_uniform_max_s;
        // c² (σ_g² + u²/12)
        c * c * (self.gaussian_std_s * self.gaussian_std_s + u * u / 12.0)
    }

    /// Mean of one range difference's noise, `c u_max / 2` in m (the NLOS bias): subtract it
    /// from measurements if a filter assumes zero-mean noise, or state that the filter ignores
    /// it.
    ///
    /// # Example
    /// ```
    /// let sim = rtls_sim::TdoaSimulator::seed_004();
    /// assert!((sim.range_difference_bias_m() - 29.9792458).abs() < 1e-9);
    /// ```
    ///
    /// # References
    /// Seed 004 §3; the mean of `U(0, u)` is `u/2`.
    #[must_use]
    pub fn range_difference_bias_m(&self) -> f64 {
        // c u_max / 2
        self.speed_of_light_mps * self.nlos_uniform_max_s / 2.0
    }

    /// Checks the fields (for a simulator whose public fields were set directly).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for fewer than two stations or a negative or non-finite
    /// timing error; [`SimError::NonFinite`] for a NaN/∞ station coordinate.
    pub fn validate(&self) -> Result<()> {
        if self.stations.len() < 2 {
            return Err(SimError::InvalidParameter {
                name: "stations",
                reason: "tdoa needs at least two stations: add stations",
            });
        }
        for station in &self.stations {
            finite2(*station, "stations")?;
        }
        positive(
            self.speed_of_light_mps,
            "speed_of_light_mps",
            "the propagation speed must be finite and > 0",
        )?;
        non_negative(
            self.gaussian_std_s,
            "gaussian_std_s",
            "a standard deviation must be finite and ≥ 0",
        )?;
        non_negative(
            self.nlos_uniform_max_s,
            "nlos_uniform_max_s",
            "the nlos delay bound must be finite and ≥ 0",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rtls_estimation::measurement::{MeasurementModel, Tdoa};
    use rtls_estimation::Vector;

    /// Mean and (unbiased) variance.
    fn mean_var(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        (mean, x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0))
    }

    #[test]
    fn noise_has_the_stated_bias_and_variance() {
        let sim = TdoaSimulator::seed_004();
        let mut rng = ChaCha8Rng::seed_from_u64(400);
        let p = [500.0, -300.0];
        let truth = sim.true_range_differences(p, 1).unwrap();
        let mut errors = Vec::new();
        for _ in 0..20_000 {
            let z = sim.measure(p, 1, &mut rng).unwrap();
            errors.extend(z.iter().zip(&truth).map(|(z, t)| z - t));
        }
        let (mean, var) = mean_var(&errors);
        let c = SPEED_OF_LIGHT_MPS;
        // mean = c · 100 ns ≈ 29.98 m; standard error √(var/60000) ≈ 0.14 m
        assert!((mean - c * 100e-9).abs() < 0.6, "mean {mean}");
        assert!((sim.range_difference_bias_m() - c * 100e-9).abs() < 1e-9);
        // var = c² (σ² + u²/12) ≈ 1198 m²
        let expected = c * c * (100e-9f64.powi(2) + 200e-9f64.powi(2) / 12.0);
        assert!((sim.range_difference_variance_m2() - expected).abs() < 1e-9 * expected);
        assert!((var / expected - 1.0).abs() < 0.05, "variance {var} vs {expected}");
    }

    #[test]
    fn differences_are_independent() {
        // The paper puts the error on each time difference; differencing TOAs would instead
        // correlate them with ρ = ½.
        let sim = TdoaSimulator::seed_004();
        let mut rng = ChaCha8Rng::seed_from_u64(401);
        let truth = sim.true_range_differences([0.0, 0.0], 0).unwrap();
        let (mut e0, mut e1) = (Vec::new(), Vec::new());
        for _ in 0..20_000 {
            let z = sim.measure([0.0, 0.0], 0, &mut rng).unwrap();
            e0.push(z[0] - truth[0]);
            e1.push(z[1] - truth[1]);
        }
        let ((m0, v0), (m1, v1)) = (mean_var(&e0), mean_var(&e1));
        let cov = e0.iter().zip(&e1).map(|(a, b)| (a - m0) * (b - m1)).sum::<f64>() / (e0.len() as f64 - 1.0);
        let rho = cov / (v0 * v1).sqrt();
        assert!(rho.abs() < 0.03, "correlation {rho}");
    }

    #[test]
    fn nlos_part_is_non_negative_and_bounded() {
        let mut sim = TdoaSimulator::seed_004();
        sim.gaussian_std_s = 0.0;
        let mut rng = ChaCha8Rng::seed_from_u64(402);
        let truth = sim.true_range_differences([1000.0, 1000.0], 2).unwrap();
        let bound = SPEED_OF_LIGHT_MPS * 200e-9;
        for _ in 0..2000 {
            for (z, t) in sim.measure([1000.0, 1000.0], 2, &mut rng).unwrap().iter().zip(&truth) {
                assert!(
                    (0.0..bound).contains(&(z - t)),
                    "uniform error {} outside [0, {bound})",
                    z - t
                );
            }
        }
    }

    #[test]
    fn convention_matches_the_estimation_tdoa_model() {
        let sim = TdoaSimulator::seed_004();
        let p = [1234.0, -567.0];
        for reference in 0..4 {
            let model = Tdoa::planar_from_toa_variance(&SEED_004_STATIONS, reference, 900.0).unwrap();
            let predicted = model.predict(&Vector::<4>::new(p[0], 0.0, p[1], 0.0)).unwrap();
            let simulated = sim.true_range_differences(p, reference).unwrap();
            assert_eq!(simulated.len(), predicted.len());
            for (s, h) in simulated.iter().zip(predicted.iter()) {
                assert!((s - h).abs() < 1e-9, "reference {reference}: {s} vs {h}");
            }
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let sim = TdoaSimulator::seed_004();
        let mut rng = ChaCha8Rng::seed_from_u64(403);
        assert!(matches!(
            sim.measure([0.0, 0.0], 4, &mut rng),
            Err(SimError::InvalidParameter { name: "reference", .. })
        ));
        assert!(matches!(
            sim.measure([f64::NAN, 0.0], 0, &mut rng),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            TdoaSimulator::new(&[[0.0, 0.0]]),
            Err(SimError::InvalidParameter { name: "stations", .. })
        ));
        assert!(matches!(
            TdoaSimulator::new(&[[0.0, 0.0], [1.0, f64::INFINITY]]),
            Err(SimError::NonFinite { .. })
        ));
        let negative = TdoaSimulator {
            gaussian_std_s: -1e-9,
            ..TdoaSimulator::seed_004()
        };
        assert!(matches!(
            negative.measure([0.0, 0.0], 0, &mut rng),
            Err(SimError::InvalidParameter { .. })
        ));
        let no_light = TdoaSimulator {
            speed_of_light_mps: 0.0,
            ..TdoaSimulator::seed_004()
        };
        assert!(no_light.measure([0.0, 0.0], 0, &mut rng).is_err());
    }
}
