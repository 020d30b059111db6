//! On-board speed and heading sensors with a slowly drifting heading (seed 004).

use core::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;
use rtls_estimation::wrap_angle;

use crate::error::{finite, non_negative, Result, SimError};
use crate::trajectory::TruthSample;

/// Seed 004's heading drift, 20°/h in rad/s (`20 · π/180 / 3600 ≈ 9.70e-5`).
///
/// # Example
/// ```
/// let per_hour_deg = rtls_sim::SEED_004_HEADING_DRIFT_RAD_PER_S.to_degrees() * 3600.0;
/// assert!((per_hour_deg - 20.0).abs() < 1e-12);
/// ```
///
/// # References
/// Seed 004 §3: "随机附加 20°/h 的角度测量漂移误差".
pub const SEED_004_HEADING_DRIFT_RAD_PER_S: f64 = 20.0 * PI / 180.0 / 3600.0;

/// Seed 004's per-reading heading noise, 0.5° in rad.
///
/// The paper gives only the drift. A gyro-stabilised compass reads to a fraction of a degree;
/// 0.5° keeps the white part small next to the drift (8.3° after 1500 s), so the drift is the
/// error the experiment is about, as in the paper.
///
/// # Example
/// ```
/// assert!((rtls_sim::SEED_004_HEADING_NOISE_STD_RAD.to_degrees() - 0.5).abs() < 1e-12);
/// ```
///
/// # References
/// Seed 004 §3 (white heading noise not stated: our choice).
pub const SEED_004_HEADING_NOISE_STD_RAD: f64 = 0.5 * PI / 180.0;

/// Parameters of simulated odometry: speed from an odometer, heading from a gyro/compass.
///
/// A reading at time `t` is
///
/// ```text
/// s̃ = s + n_s,                 n_s ~ N(0, σ_s²)
/// ψ̃ = wrap(ψ + d · δ · t + n_ψ), n_ψ ~ N(0, σ_ψ²),  d = ±1 drawn once per run
/// ```
/// with `s`, `ψ = atan2(vy, vx)` the true speed and heading, `δ` the drift rate and `t` the
/// time since the heading sensor was aligned at `t = 0`. The speed is not clipped at 0, so
/// its noise stays zero-mean as a filter assumes. [`Default`] gives seed 004's values.
///
/// # Units
/// `σ_s` in m/s, `δ` in rad/s, `σ_ψ` in rad.
///
/// # Errors
/// [`OdometrySimulator::start_run`] validates the fields.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::{OdometrySimulator, Trajectory};
/// let truth = Trajectory::builder([0.0, 0.0], [10.0, 0.0]).constant_velocity(3600.0).build()?;
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
/// let quiet = OdometrySimulator { speed_std_mps: 0.0, heading_noise_std_rad: 0.0, ..Default::default() };
/// let mut run = quiet.start_run(&mut rng)?;
/// let reading = run.measure(&truth.state_at(3600.0)?, &mut rng)?;
/// // after one hour the heading has drifted by ±20°
/// assert!((reading.heading_rad.abs().to_degrees() - 20.0).abs() < 1e-9);
/// assert_eq!(reading.speed_mps, 10.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3: heading drift 20°/h and speed error 1 m/s, added "randomly" to the true
/// heading and speed, at 1 Hz.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometrySimulator {
    /// Standard deviation `σ_s` of the speed error, m/s (seed 004: 1 m/s).
    pub speed_std_mps: f64,
    /// Magnitude `δ` of the heading drift, rad/s (seed 004: 20°/h); its sign is drawn per run.
    pub heading_drift_rad_per_s: f64,
    /// Standard deviation `σ_ψ` of the white heading noise, rad (our choice: 0.5°).
    pub heading_noise_std_rad: f64,
}

impl Default for OdometrySimulator {
    /// Seed 004: `σ_s = 1` m/s, `δ = 20°/h`, `σ_ψ = 0.5°`.
    fn default() -> Self {
        Self {
            speed_std_mps: 1.0,
            heading_drift_rad_per_s: SEED_004_HEADING_DRIFT_RAD_PER_S,
            heading_noise_std_rad: SEED_004_HEADING_NOISE_STD_RAD,
        }
    }
}

impl OdometrySimulator {
    /// Starts one run: validates the parameters and draws the drift sign `d = ±1` with equal
    /// probability (the paper adds the drift "randomly").
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] / [`SimError::NonFinite`] unless every field is finite and
    /// `≥ 0`.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    /// let run = rtls_sim::OdometrySimulator::default().start_run(&mut rng)?;
    /// assert_eq!(run.drift_sign().abs(), 1.0);
    /// let bad = rtls_sim::OdometrySimulator { speed_std_mps: -1.0, ..Default::default() };
    /// assert!(bad.start_run(&mut rng).is_err());
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    pub fn start_run(&self, rng: &mut impl Rng) -> Result<OdometryRun> {
        non_negative(
            self.speed_std_mps,
            "speed_std_mps",
            "a standard deviation must be finite and ≥ 0",
        )?;
        non_negative(
            self.heading_drift_rad_per_s,
            "heading_drift_rad_per_s",
            "the drift rate must be finite and ≥ 0",
        )?;
        non_negative(
            self.heading_noise_std_rad,
            "heading_noise_std_rad",
            "a standard deviation must be finite and ≥ 0",
        )?;
        // d = ±1 with probability ½ each
        let drift_sign = if rng.gen::<bool>() { 1.0 } else { -1.0 };
        Ok(OdometryRun {
            params: *self,
            drift_sign,
            last_heading_rad: 0.0,
            last_time_s: None,
        })
    }
}

/// One run of simulated odometry: the parameters, the drift sign drawn for the run, and the
/// last true heading (the heading of a standing vehicle).
///
/// When the true speed is 0 ([`TruthSample::heading_rad`] is `None`) the true heading is the
/// last one the vehicle had while moving, as a parked vehicle keeps pointing where it was
/// going; before it has ever moved that is 0 rad (the +x axis).
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::{OdometrySimulator, Trajectory};
/// let truth = Trajectory::builder([0.0, 0.0], [0.0, 5.0]).constant_velocity(10.0).stop(10.0).build()?;
/// let quiet = OdometrySimulator { speed_std_mps: 0.0, heading_drift_rad_per_s: 0.0, heading_noise_std_rad: 0.0 };
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
/// let mut run = quiet.start_run(&mut rng)?;
/// run.measure(&truth.state_at(5.0)?, &mut rng)?;
/// let parked = run.measure(&truth.state_at(15.0)?, &mut rng)?;
/// assert_eq!((parked.speed_mps, parked.heading_rad), (0.0, std::f64::consts::FRAC_PI_2));
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3 (400–450 s stop).
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryRun {
    params: OdometrySimulator,
    drift_sign: f64,
    last_heading_rad: f64,
    last_time_s: Option<f64>,
}

impl OdometryRun {
    /// The drift sign `d` of this run, `+1.0` or `−1.0`.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    /// let run = rtls_sim::OdometrySimulator::default().start_run(&mut rng)?;
    /// assert!(run.drift_sign() == 1.0 || run.drift_sign() == -1.0);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    #[must_use]
    pub fn drift_sign(&self) -> f64 {
        self.drift_sign
    }

    /// The signed drift rate `d · δ` of this run, rad/s.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    /// let run = rtls_sim::OdometrySimulator::default().start_run(&mut rng)?;
    /// assert_eq!(run.drift_rate_rad_per_s().abs(), rtls_sim::SEED_004_HEADING_DRIFT_RAD_PER_S);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    #[must_use]
    pub fn drift_rate_rad_per_s(&self) -> f64 {
        self.drift_sign * self.params.heading_drift_rad_per_s
    }

    /// A reading of the true state `truth`: `s̃ = s + n_s`,
    /// `ψ̃ = wrap(ψ + d δ t + n_ψ)` with `t = truth.time_s` (see [`OdometrySimulator`]).
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for a NaN/∞ time or velocity; [`SimError::InvalidParameter`]
    /// (`time_s`) if `truth.time_s` is earlier than the previous reading's (the parked heading
    /// is carried forward in time).
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// use rtls_sim::{OdometrySimulator, TruthSample};
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    /// let mut run = OdometrySimulator::default().start_run(&mut rng)?;
    /// let truth = TruthSample { time_s: 1.0, position_m: [0.0; 2], velocity_mps: [10.0, 0.0], acceleration_mps2: [0.0; 2] };
    /// let reading = run.measure(&truth, &mut rng)?;
    /// assert!((reading.speed_mps - 10.0).abs() < 5.0); // σ = 1 m/s
    /// assert!(reading.heading_rad.abs() < 0.1);
    /// let earlier = TruthSample { time_s: 0.5, ..truth };
    /// assert!(run.measure(&earlier, &mut rng).is_err());
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    pub fn measure(&mut self, truth: &TruthSample, rng: &mut impl Rng) -> Result<OdometryReading> {
        let t = finite(truth.time_s, "truth time")?;
        finite(truth.velocity_mps[0], "truth velocity")?;
        finite(truth.velocity_mps[1], "truth velocity")?;
        if self.last_time_s.is_some_and(|last| t < last) {
            return Err(SimError::InvalidParameter {
                name: "time_s",
                reason: "odometry readings must be taken in non-decreasing time order: start a new run to go back",
            });
        }
        self.last_time_s = Some(t);
        // ψ = atan2(vy, vx) while moving, else the last heading
        if let Some(heading_rad) = truth.heading_rad() {
            self.last_heading_rad = heading_rad;
        }
        // s̃ = s + n_s
        let speed_mps = truth.speed_mps() + self.params.speed_std_mps * rng.sample::<f64, _>(StandardNormal);
        // ψ̃ = wrap(ψ + d δ t + n_ψ)
        let drift_rad = self.drift_rate_rad_per_s() * t;
        let noise_rad = self.params.heading_noise_std_rad * rng.sample::<f64, _>(StandardNormal);
        let heading_rad = wrap_angle(self.last_heading_rad + drift_rad + noise_rad);
        Ok(OdometryReading {
            time_s: t,
            speed_mps,
            heading_rad,
        })
    }
}

/// One odometry reading.
///
/// # Units
/// `time_s` in s, `speed_mps` in m/s (may be negative: the noise is not clipped),
/// `heading_rad` in rad in `(−π, π]`, from +x counter-clockwise.
///
/// # Example
/// ```
/// let r = rtls_sim::OdometryReading { time_s: 1.0, speed_mps: 10.0, heading_rad: 0.0 };
/// assert_eq!(r.velocity_mps(), [10.0, 0.0]);
/// ```
///
/// # References
/// Seed 004 §1 (speed and direction of motion from local sensors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryReading {
    /// Time of the reading, s.
    pub time_s: f64,
    /// Measured speed `s̃`, m/s.
    pub speed_mps: f64,
    /// Measured heading `ψ̃`, rad in `(−π, π]`.
    pub heading_rad: f64,
}

impl OdometryReading {
    /// The velocity the reading implies, `[s̃ cos ψ̃, s̃ sin ψ̃]` in m/s: the paper's
    /// `(z_vx, z_vy)` observation for `H = I₄`.
    ///
    /// # Example
    /// ```
    /// let r = rtls_sim::OdometryReading { time_s: 0.0, speed_mps: 2.0, heading_rad: std::f64::consts::FRAC_PI_2 };
    /// let v = r.velocity_mps();
    /// assert!(v[0].abs() < 1e-15 && (v[1] - 2.0).abs() < 1e-15);
    /// ```
    ///
    /// # References
    /// Seed 004 §1, eq. (9).
    #[must_use]
    pub fn velocity_mps(&self) -> [f64; 2] {
        let (sin_h, cos_h) = self.heading_rad.sin_cos();
        // [s̃ cos ψ̃, s̃ sin ψ̃]
        [self.speed_mps * cos_h, self.speed_mps * sin_h]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenarios::seed_004_trajectory;
    use crate::trajectory::Trajectory;
    use core::f64::consts::FRAC_PI_2;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn speed_error_has_unit_standard_deviation() {
        let sim = OdometrySimulator::default();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut run = sim.start_run(&mut rng).unwrap();
        let truth = TruthSample {
            time_s: 0.0,
            position_m: [0.0; 2],
            velocity_mps: [6.0, 8.0],
            acceleration_mps2: [0.0; 2],
        };
        let errors: Vec<f64> = (0..20_000)
            .map(|_| run.measure(&truth, &mut rng).unwrap().speed_mps - 10.0)
            .collect();
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let std = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert!(mean.abs() < 0.03, "mean {mean}");
        assert!((std - 1.0).abs() < 0.03, "std {std}");
    }

    #[test]
    fn heading_error_grows_linearly_at_20_deg_per_hour_with_random_sign() {
        let sim = OdometrySimulator::default();
        let heading: f64 = 0.3;
        let truth = Trajectory::builder([0.0, 0.0], [10.0 * heading.cos(), 10.0 * heading.sin()])
            .constant_velocity(1500.0)
            .build()
            .unwrap()
            .sample(1.0)
            .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(20);
        let runs = 100;
        let mut positive = 0;
        for _ in 0..runs {
            let mut run = sim.start_run(&mut rng).unwrap();
            // least-squares slope of the heading error against time
            let (mut st, mut se, mut stt, mut ste) = (0.0, 0.0, 0.0, 0.0);
            let mut residual_sq = Vec::new();
            for s in &truth {
                let e = wrap_angle(run.measure(s, &mut rng).unwrap().heading_rad - heading);
                (st, se, stt, ste) = (st + s.time_s, se + e, stt + s.time_s * s.time_s, ste + s.time_s * e);
                residual_sq.push((s.time_s, e));
            }
            let n = truth.len() as f64;
            let slope = (n * ste - st * se) / (n * stt - st * st);
            let intercept = (se - slope * st) / n;
            let expected = run.drift_sign() * SEED_004_HEADING_DRIFT_RAD_PER_S;
            // slope standard error ≈ σ_ψ / √(Σ(t − t̄)²) ≈ 5e-7 rad/s, 0.5 % of the drift
            assert!((slope / expected - 1.0).abs() < 0.03, "slope {slope} vs {expected}");
            assert!(intercept.abs() < 2e-3, "intercept {intercept}");
            // the residual is the white heading noise, σ = 0.5°
            let var = residual_sq
                .iter()
                .map(|(t, e)| (e - intercept - slope * t).powi(2))
                .sum::<f64>()
                / (n - 2.0);
            assert!(
                (var.sqrt() / SEED_004_HEADING_NOISE_STD_RAD - 1.0).abs() < 0.1,
                "noise std {}",
                var.sqrt()
            );
            if run.drift_sign() > 0.0 {
                positive += 1;
            }
        }
        // both signs occur, about equally often (binomial(100, ½): ±4σ = ±20)
        assert!(
            (30..=70).contains(&positive),
            "{positive} of {runs} runs drifted positive"
        );
    }

    #[test]
    fn parked_vehicle_keeps_its_last_heading() {
        let quiet = OdometrySimulator {
            speed_std_mps: 0.0,
            heading_drift_rad_per_s: 0.0,
            heading_noise_std_rad: 0.0,
        };
        let truth = seed_004_trajectory(10.0).unwrap().sample(1.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut run = quiet.start_run(&mut rng).unwrap();
        for s in &truth[..=460] {
            let r = run.measure(s, &mut rng).unwrap();
            let expected = match s.time_s {
                t if t < 400.0 => -FRAC_PI_2, // along −y
                t if t < 450.0 => -FRAC_PI_2, // stopped: last heading held
                _ => 0.0,                     // along +x
            };
            assert!(
                (r.heading_rad - expected).abs() < 1e-12,
                "at {} s: {}",
                s.time_s,
                r.heading_rad
            );
            assert_eq!(r.speed_mps, s.speed_mps());
        }
    }

    #[test]
    fn drift_is_added_while_parked_and_before_moving() {
        let drifting = OdometrySimulator {
            speed_std_mps: 0.0,
            heading_noise_std_rad: 0.0,
            ..Default::default()
        };
        let truth = Trajectory::builder([0.0, 0.0], [0.0, 0.0])
            .stop(3600.0)
            .build()
            .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut run = drifting.start_run(&mut rng).unwrap();
        // never moved: heading 0 rad plus 20° of drift after an hour
        let r = run.measure(&truth.state_at(3600.0).unwrap(), &mut rng).unwrap();
        assert!((r.heading_rad - run.drift_sign() * 20f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for bad in [
            OdometrySimulator {
                speed_std_mps: -1.0,
                ..Default::default()
            },
            OdometrySimulator {
                heading_drift_rad_per_s: f64::NAN,
                ..Default::default()
            },
            OdometrySimulator {
                heading_noise_std_rad: -0.1,
                ..Default::default()
            },
        ] {
            assert!(bad.start_run(&mut rng).is_err(), "{bad:?}");
        }
        let mut run = OdometrySimulator::default().start_run(&mut rng).unwrap();
        let s = TruthSample {
            time_s: 10.0,
            position_m: [0.0; 2],
            velocity_mps: [1.0, 0.0],
            acceleration_mps2: [0.0; 2],
        };
        run.measure(&s, &mut rng).unwrap();
        assert!(matches!(
            run.measure(&TruthSample { time_s: 9.0, ..s }, &mut rng),
            Err(SimError::InvalidParameter { name: "time_s", .. })
        ));
        assert!(matches!(
            run.measure(&TruthSample { time_s: f64::NAN, ..s }, &mut rng),
            Err(SimError::NonFinite { .. })
        ));
        assert!(matches!(
            run.measure(
                &TruthSample {
                    velocity_mps: [f64::INFINITY, 0.0],
                    ..s
                },
                &mut rng
            ),
            Err(SimError::NonFinite { .. })
        ));
    }
}
