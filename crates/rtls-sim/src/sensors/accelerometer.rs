//! A two-axis accelerometer with absolute or reading-proportional noise (seed 002).

use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::{finite, finite2, non_negative, positive, Result};
use crate::trajectory::Trajectory;

/// How the accelerometer's per-axis noise standard deviation is set.
///
/// # Example
/// ```
/// use rtls_sim::AccelerometerNoise;
/// let proportional = AccelerometerNoise::ProportionalToReading { fraction: 0.1 };
/// assert_eq!(proportional.std_mps2([0.2, -0.5]), [0.1 * 0.2, 0.1 * 0.5]);
/// assert_eq!(AccelerometerNoise::SEED_002_ABSOLUTE.std_mps2([0.2, -0.5]), [0.01, 0.01]);
/// ```
///
/// # References
/// Seed 002 §2, Table 1 (`ε = 0.01` m/s²) and the Fig. 5/6 experiment ("加速度测量噪声误差的
/// 标准差为测量值的 10%").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AccelerometerNoise {
    /// `σ_d = std_mps2` on each axis, independent of the signal.
    Absolute {
        /// Standard deviation per axis, m/s² (seed 002: 0.01).
        std_mps2: f64,
    },
    /// `σ_d = fraction · |a_d|` on each axis `d`, proportional to the true acceleration.
    ProportionalToReading {
        /// Ratio of the standard deviation to the magnitude of the axis' acceleration
        /// (seed 002: 0.1).
        fraction: f64,
    },
}

impl AccelerometerNoise {
    /// Seed 002 Table 1: `ε = 0.01` m/s² on each axis.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::AccelerometerNoise;
    /// assert_eq!(AccelerometerNoise::SEED_002_ABSOLUTE, AccelerometerNoise::Absolute { std_mps2: 0.01 });
    /// ```
    ///
    /// # References
    /// Seed 002 §2, Table 1 (加速度测量噪声均方差 `ε_d`).
    pub const SEED_002_ABSOLUTE: Self = Self::Absolute { std_mps2: 0.01 };

    /// Seed 002's Fig. 5/6 experiment: the noise std is 10 % of the reading.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::AccelerometerNoise;
    /// assert_eq!(AccelerometerNoise::SEED_002_PROPORTIONAL.std_mps2([0.3, 0.0]), [0.1 * 0.3, 0.0]);
    /// ```
    ///
    /// # References
    /// Seed 002 §2 ("加速度测量噪声误差的标准差为测量值的 10%").
    pub const SEED_002_PROPORTIONAL: Self = Self::ProportionalToReading { fraction: 0.1 };

    /// The per-axis standard deviation (m/s²) for the acceleration `acceleration_mps2`:
    /// `σ_d = std` (absolute) or `σ_d = fraction · |a_d|` (proportional).
    ///
    /// The simulator calls this with the *true* acceleration. A real filter does not know
    /// it and must call it with the *reading* instead (see [`filter_std_mps2`](Self::filter_std_mps2)).
    ///
    /// # Example
    /// ```
    /// use rtls_sim::AccelerometerNoise;
    /// let noise = AccelerometerNoise::ProportionalToReading { fraction: 0.1 };
    /// assert_eq!(noise.std_mps2([0.0, 2.0]), [0.0, 0.2]);
    /// ```
    ///
    /// # References
    /// Seed 002 §2.
    #[must_use]
    pub fn std_mps2(&self, acceleration_mps2: [f64; 2]) -> [f64; 2] {
        match *self {
            // σ_d = σ
            Self::Absolute { std_mps2 } => [std_mps2, std_mps2],
            // σ_d = f · |a_d|
            Self::ProportionalToReading { fraction } => [
                fraction * acceleration_mps2[0].abs(),
                fraction * acceleration_mps2[1].abs(),
            ],
        }
    }

    /// The per-axis standard deviation (m/s²) a real filter should assume for a reading
    /// `reading_mps2`: `σ_d = fraction · |ã_d|` (proportional) or the constant (absolute).
    ///
    /// This differs from [`AccelerometerReading::std_mps2`], which is `fraction · |a_d|` of the
    /// true acceleration the simulator used; the two agree to first order in `fraction`.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::AccelerometerNoise;
    /// let noise = AccelerometerNoise::SEED_002_PROPORTIONAL;
    /// let s = noise.filter_std_mps2([0.11, -0.3]);
    /// assert!((s[0] - 0.011).abs() < 1e-15 && (s[1] - 0.03).abs() < 1e-15);
    /// ```
    ///
    /// # References
    /// Seed 002 §2 ("测量值的 10%": 10 % of the measured value).
    #[must_use]
    pub fn filter_std_mps2(&self, reading_mps2: [f64; 2]) -> [f64; 2] {
        self.std_mps2(reading_mps2)
    }

    /// Checks the parameter.
    fn validate(&self) -> Result<()> {
        match *self {
            Self::Absolute { std_mps2 } => {
                non_negative(std_mps2, "std_mps2", "a standard deviation must be finite and ≥ 0")?;
            }
            Self::ProportionalToReading { fraction } => {
                non_negative(fraction, "fraction", "the noise fraction must be finite and ≥ 0")?;
            }
        }
        Ok(())
    }
}

/// Simulates a two-axis accelerometer: `ã_d = a_d + σ_d n_d`, `n_d ~ N(0, 1)` independent per
/// axis, with `σ_d` from the [`AccelerometerNoise`] model.
///
/// # Units
/// Accelerations and standard deviations in m/s², times in s.
///
/// # Errors
/// [`AccelerometerSimulator::measure`] validates the noise parameter.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::{AccelerometerNoise, AccelerometerSimulator};
/// let sim = AccelerometerSimulator { noise: AccelerometerNoise::SEED_002_ABSOLUTE };
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
/// let r = sim.measure(1.0, [0.1, -0.2], &mut rng)?;
/// assert_eq!(r.std_mps2, [0.01, 0.01]);
/// assert!((r.acceleration_mps2[0] - 0.1).abs() < 0.05);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §1.2 (accelerometer as control input) and §2 (noise levels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerSimulator {
    /// The noise model.
    pub noise: AccelerometerNoise,
}

impl AccelerometerSimulator {
    /// One reading at `time_s` of the true acceleration `true_acceleration_mps2`:
    /// `ã_d = a_d + σ_d n_d` with `σ_d = noise.std_mps2(a)`.
    ///
    /// # Errors
    /// [`SimError::NonFinite`](crate::SimError::NonFinite) for NaN/∞ inputs;
    /// [`SimError::InvalidParameter`](crate::SimError::InvalidParameter) for a negative noise
    /// parameter.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// use rtls_sim::{AccelerometerNoise, AccelerometerSimulator};
    /// let sim = AccelerometerSimulator { noise: AccelerometerNoise::SEED_002_PROPORTIONAL };
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    /// let r = sim.measure(3.0, [0.0, 0.2], &mut rng)?;
    /// assert_eq!(r.acceleration_mps2[0], 0.0); // 10 % of nothing is nothing
    /// assert!((r.std_mps2[1] - 0.02).abs() < 1e-15);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §2.
    pub fn measure(
        &self,
        time_s: f64,
        true_acceleration_mps2: [f64; 2],
        rng: &mut impl Rng,
    ) -> Result<AccelerometerReading> {
        self.noise.validate()?;
        let time_s = finite(time_s, "time")?;
        let a = finite2(true_acceleration_mps2, "true acceleration")?;
        // σ_d from the noise model at the true acceleration
        let std = self.noise.std_mps2(a);
        // ã_d = a_d + σ_d n_d
        let reading = [
            a[0] + std[0] * rng.sample::<f64, _>(StandardNormal),
            a[1] + std[1] * rng.sample::<f64, _>(StandardNormal),
        ];
        Ok(AccelerometerReading {
            time_s,
            acceleration_mps2: reading,
            std_mps2: std,
        })
    }

    /// Readings at `t_k = k · dt` for `k = 1 … ⌊T/dt⌋`, each of the mean acceleration over
    /// `((k − 1) dt, k dt]` ([`Trajectory::mean_acceleration`]). On a profile that is constant
    /// on each interval this is exactly that interval's acceleration `a(k)`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`](crate::SimError::InvalidParameter) unless `dt_s` is finite
    /// and `> 0`; as [`measure`](Self::measure) otherwise. A `dt_s` longer than the trajectory
    /// gives no readings (an empty vector).
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// use rtls_sim::{AccelerometerNoise, AccelerometerSimulator, Trajectory};
    /// let truth = Trajectory::builder([0.0, 0.0], [0.0, 0.0])
    ///     .constant_acceleration(1.0, [0.1, 0.0])
    ///     .constant_acceleration(1.0, [0.0, 0.3])
    ///     .build()?;
    /// let exact = AccelerometerSimulator { noise: AccelerometerNoise::Absolute { std_mps2: 0.0 } };
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    /// let readings = exact.measure_trajectory(&truth, 1.0, &mut rng)?;
    /// assert_eq!(readings.len(), 2);
    /// assert_eq!((readings[1].time_s, readings[1].acceleration_mps2), (2.0, [0.0, 0.3]));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §1.2: `a(k)` is the acceleration collected at `k`, constant over `(k − 1, k]`.
    pub fn measure_trajectory(
        &self,
        trajectory: &Trajectory,
        dt_s: f64,
        rng: &mut impl Rng,
    ) -> Result<Vec<AccelerometerReading>> {
        self.noise.validate()?;
        let dt_s = positive(dt_s, "dt_s", "the sampling interval must be finite and > 0 s")?;
        // the sample grid t_k = k dt, k = 0 … K; readings for k ≥ 1
        let grid = trajectory.sample(dt_s)?;
        grid.windows(2)
            .map(|pair| {
                let (t0, t1) = (pair[0].time_s, pair[1].time_s);
                // ā_k = (1/dt) ∫_{t_{k−1}}^{t_k} a(t) dt
                let mean = trajectory.mean_acceleration(t0, t1)?;
                self.measure(t1, mean, rng)
            })
            .collect()
    }
}

/// One accelerometer reading with the noise level that produced it.
///
/// # Units
/// `time_s` in s; `acceleration_mps2` and `std_mps2` in m/s², `[x, y]`.
///
/// # Example
/// ```
/// let r = rtls_sim::AccelerometerReading { time_s: 1.0, acceleration_mps2: [0.1, 0.0], std_mps2: [0.01, 0.01] };
/// assert_eq!(r.variance_mps4(), [0.01 * 0.01, 0.01 * 0.01]);
/// ```
///
/// # References
/// Seed 002 §1.2 (`diag(ε²)`: the per-axis acceleration variance the filter uses).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerReading {
    /// Time of the reading, s (the end of the interval it covers).
    pub time_s: f64,
    /// Measured acceleration `ã = [ã_x, ã_y]`, m/s².
    pub acceleration_mps2: [f64; 2],
    /// The per-axis standard deviation the simulator used, m/s². For proportional noise it is
    /// `fraction · |a_true|`, which a real filter cannot know: use
    /// [`AccelerometerNoise::filter_std_mps2`] on the reading for a realistic filter, this
    /// value for an oracle one.
    pub std_mps2: [f64; 2],
}

impl AccelerometerReading {
    /// Per-axis variance `ε_d² = σ_d²` in (m/s²)², the diagonal of the paper's `diag(ε²)`.
    ///
    /// # Example
    /// ```
    /// let r = rtls_sim::AccelerometerReading { time_s: 0.0, acceleration_mps2: [0.0; 2], std_mps2: [0.1, 0.2] };
    /// let v = r.variance_mps4();
    /// assert!((v[1] - 0.04).abs() < 1e-15);
    /// ```
    ///
    /// # References
    /// Seed 002 §1.2, eq. (9).
    #[must_use]
    pub fn variance_mps4(&self) -> [f64; 2] {
        // ε_d² = σ_d²
        [self.std_mps2[0] * self.std_mps2[0], self.std_mps2[1] * self.std_mps2[1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenarios::{seed_002_step_acceleration, seed_002_trajectory};
    use crate::SimError;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Per-axis mean and standard deviation of 20 000 readings of `a`.
    fn stats(sim: &AccelerometerSimulator, a: [f64; 2], seed: u64) -> ([f64; 2], [f64; 2]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let readings: Vec<[f64; 2]> = (0..20_000)
            .map(|_| sim.measure(0.0, a, &mut rng).unwrap().acceleration_mps2)
            .collect();
        let n = readings.len() as f64;
        let mean: [f64; 2] = core::array::from_fn(|d| readings.iter().map(|r| r[d]).sum::<f64>() / n);
        let std: [f64; 2] = core::array::from_fn(|d| {
            (readings.iter().map(|r| (r[d] - mean[d]).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        });
        (mean, std)
    }

    #[test]
    fn proportional_noise_is_ten_percent_of_the_acceleration() {
        let sim = AccelerometerSimulator {
            noise: AccelerometerNoise::SEED_002_PROPORTIONAL,
        };
        let a = [0.2, -0.05];
        let (mean, std) = stats(&sim, a, 10);
        for d in 0..2 {
            assert!(
                (std[d] / (0.1 * a[d].abs()) - 1.0).abs() < 0.03,
                "axis {d}: std {}",
                std[d]
            );
            assert!(
                (mean[d] - a[d]).abs() < 4.0 * 0.1 * a[d].abs() / 20_000f64.sqrt(),
                "axis {d}: mean {}",
                mean[d]
            );
        }
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let r = sim.measure(0.0, a, &mut rng).unwrap();
        assert!((r.std_mps2[0] - 0.02).abs() < 1e-15 && (r.std_mps2[1] - 0.005).abs() < 1e-15);
    }

    #[test]
    fn absolute_noise_has_the_table_1_level() {
        let sim = AccelerometerSimulator {
            noise: AccelerometerNoise::SEED_002_ABSOLUTE,
        };
        let (mean, std) = stats(&sim, [0.0, 0.3], 12);
        for (d, s) in std.iter().enumerate() {
            assert!((s / 0.01 - 1.0).abs() < 0.03, "axis {d}: std {s}");
        }
        assert!((mean[1] - 0.3).abs() < 4.0 * 0.01 / 20_000f64.sqrt());
    }

    #[test]
    fn trajectory_readings_are_the_step_accelerations() {
        let exact = AccelerometerSimulator {
            noise: AccelerometerNoise::Absolute { std_mps2: 0.0 },
        };
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let readings = exact
            .measure_trajectory(&seed_002_trajectory().unwrap(), 1.0, &mut rng)
            .unwrap();
        assert_eq!(readings.len(), 99);
        for (i, r) in readings.iter().enumerate() {
            let k = i + 1;
            let a = seed_002_step_acceleration(k);
            assert_eq!(r.time_s, k as f64);
            assert!((r.acceleration_mps2[0] - a[0]).abs() < 1e-15 && (r.acceleration_mps2[1] - a[1]).abs() < 1e-15);
        }
    }

    #[test]
    fn filter_std_uses_the_reading() {
        let noise = AccelerometerNoise::SEED_002_PROPORTIONAL;
        assert_eq!(noise.filter_std_mps2([-0.5, 0.0]), [0.05, 0.0]);
        assert_eq!(
            AccelerometerNoise::SEED_002_ABSOLUTE.filter_std_mps2([5.0, 5.0]),
            [0.01, 0.01]
        );
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let sim = AccelerometerSimulator {
            noise: AccelerometerNoise::SEED_002_ABSOLUTE,
        };
        assert!(matches!(
            sim.measure(0.0, [f64::NAN, 0.0], &mut rng),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            sim.measure(f64::INFINITY, [0.0, 0.0], &mut rng),
            Err(SimError::NonFinite { .. })
        ));
        let negative = AccelerometerSimulator {
            noise: AccelerometerNoise::ProportionalToReading { fraction: -0.1 },
        };
        assert!(matches!(
            negative.measure(0.0, [0.1, 0.1], &mut rng),
            Err(SimError::InvalidParameter { .. })
        ));
        let track = seed_002_trajectory().unwrap();
        assert!(matches!(
            sim.measure_trajectory(&track, 0.0, &mut rng),
            Err(SimError::InvalidParameter { .. })
        ));
        assert!(sim.measure_trajectory(&track, 1000.0, &mut rng).unwrap().is_empty());
    }
}
