//! The NLOS extension of a seed 001 run: the same truth, initial estimate and Gaussian noise
//! with NLOS-biased ranges, tracked by the paper's UKF and by a robust UKF.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_estimation::filter::UnscentedKalmanFilter;
use rtls_estimation::measurement::{NoiseCovariance, Ranges, Stacked};
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::stats::ChiSquareGate;
use rtls_estimation::Gaussian;

use super::trackers::run_filter;
use super::{FilterTrack, JointMeasurement, NlosRun, RunData, Seed001Config, Seed001Nlos};
use crate::error::{Result, SimError};

/// The NLOS extension on the same truth, initial estimate and Gaussian noise.
pub(super) fn run_nlos(
    config: &Seed001Config,
    nlos: &Seed001Nlos,
    joint: &JointMeasurement,
    initial: &Gaussian<4>,
    data: &RunData<'_>,
    seed: u64,
) -> Result<NlosRun> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(1);
    let stations = config.stations_m.len();
    let (mut biased_count, mut bias_sum) = (0usize, 0.0);
    let mut biased = data.measurements.to_vec();
    for z in &mut biased {
        for i in 0..stations {
            // rᵢ ← rᵢ + bᵢ
            let b = nlos.bias.sample(&mut rng)?;
            z[i] += b;
            bias_sum += b;
            biased_count += usize::from(b > 0.0);
        }
    }
    let nlos_data = RunData {
        measurements: &biased,
        ..*data
    };
    let cv = ConstantVelocity::new(config.truth.process_noise()).map_err(SimError::estimation(0.0))?;
    let ukf = UnscentedKalmanFilter::new(config.sigma_points);
    let gate = ChiSquareGate::new(nlos.gate_probability)
        .and_then(|g| g.threshold(1))
        .map_err(SimError::estimation(0.0))?;
    let robust = RobustRanges {
        config,
        gate,
        ukf,
        motion: cv,
    };
    let total = (stations * data.truth.len()).max(1) as f64;
    Ok(NlosRun {
        nlos_fraction: biased_count as f64 / total,
        mean_bias_m: bias_sum / total,
        ukf: run_filter(&ukf, &cv, joint, *initial, &nlos_data)?,
        robust: robust.run(joint, *initial, &nlos_data)?,
        robust_los: robust.run(joint, *initial, data)?,
    })
}

/// The robust UKF: a range longer than predicted by more than the gate is down-weighted by
/// inflating its variance so that its normalised innovation equals the gate (a one-step
/// Huber-type M-estimate; one-sided because NLOS only lengthens a range).
///
/// ```text
/// ν, S = UKF innovation and covariance with the nominal R
/// for each range i:  if νᵢ > 0 and νᵢ² / Sᵢᵢ > γ:  Rᵢᵢ ← Rᵢᵢ + νᵢ²/γ − Sᵢᵢ
/// update again from the same prior with the inflated R
/// ```
struct RobustRanges<'a> {
    config: &'a Seed001Config,
    gate: f64,
    ukf: UnscentedKalmanFilter,
    motion: ConstantVelocity,
}

impl RobustRanges<'_> {
    fn run(&self, joint: &JointMeasurement, initial: Gaussian<4>, data: &RunData<'_>) -> Result<FilterTrack> {
        let stations = self.config.stations_m.len();
        let nominal_m2 = self.config.range_std_m.powi(2);
        let mut state = initial;
        let mut track = FilterTrack::with_capacity(data.truth.len());
        for ((&t, z), truth) in data.times_s.iter().zip(data.measurements).zip(data.truth) {
            let prior = self
                .ukf
                .predict(&state, &self.motion, t)
                .map_err(SimError::estimation(t))?;
            let first = self.ukf.update(&prior, joint, z).map_err(SimError::estimation(t))?;
            let mut variances_m2 = vec![nominal_m2; stations];
            let mut inflated = 0;
            for (i, variance) in variances_m2.iter_mut().enumerate() {
                let (nu, s) = (first.innovation[i], first.innovation_covariance[(i, i)]);
                // one-sided test: νᵢ > 0 and νᵢ²/Sᵢᵢ > γ
                if nu > 0.0 && nu * nu > self.gate * s {
                    // Rᵢᵢ ← Rᵢᵢ + νᵢ²/γ − Sᵢᵢ
                    *variance += nu * nu / self.gate - s;
                    inflated += 1;
                }
            }
            let updated = if inflated == 0 {
                first
            } else {
                let ranges = NoiseCovariance::diagonal(&variances_m2)
                    .and_then(|r| Ranges::planar(&self.config.stations_m, r))
                    .map_err(SimError::estimation(t))?;
                let model = Stacked::new::<4>(ranges, joint.second().clone());
                self.ukf.update(&prior, &model, z).map_err(SimError::estimation(t))?
            };
            state = updated.state;
            track.downweighted_ranges += inflated;
            track.record(&state, truth, updated.nis, t)?;
        }
        Ok(track)
    }
}
