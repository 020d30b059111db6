//! The log-distance (one-slope) path-loss law of seed 002.

use core::f64::consts::LN_10;

use rtls_estimation::measurement::{LogDistancePathLoss, PathLoss};

use super::{clamp_distance, finite, finite_rssi, inverted_distance, law_error, non_negative, PathLossModel};
use crate::error::Result;

/// The log-distance law with log-normal shadowing (seed 002 eq. (1)):
///
/// `ρ(d) = ρ_T − 10 η lg(d / d₀) + X`, `X ~ N(0, σ_X²)`
///
/// with `ρ_T` the mean received power at the reference distance `d₀`, `η` the path-loss
/// exponent (2 in free space, 2–4 indoors, 4–6 obstructed) and `σ_X` the shadowing standard
/// deviation.
///
/// - mean `μ(d) = ρ_T − 10 η lg(d/d₀)`, slope `dμ/dd = −10 η / (d ln 10)`;
/// - inverse `μ⁻¹(ρ) = d₀ · 10^((ρ_T − ρ) / (10 η))` (the median range, see
///   [`super::DistanceEstimate`]);
/// - range standard deviation `σ_d(d) = d ln 10 σ_X / (10 η)`, bias factor
///   `exp(½ (σ_X ln 10 / (10 η))²)`.
///
/// The mean law is `rtls-estimation`'s [`LogDistancePathLoss`] (the one the filters'
/// RSS measurement model uses); this type adds the shadowing and the inversion. The fields are
/// private so that every value is valid (finite, `η > 0`, `d₀ > 0`, `σ_X ≥ 0`); build with
/// [`LogDistance::new`] or [`LogDistance::seed_002`], or calibrate with
/// [`super::fit_log_distance`].
///
/// # Units
/// `ρ_T` in dBm, `d₀` and `d` in m, `η` dimensionless, `σ_X` in dB.
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::{LogDistance, PathLossModel};
/// let law = LogDistance::new(-40.0, 2.5, 1.0, 3.0)?; // −40 dBm at 1 m
/// assert!((law.mean_rssi_dbm(10.0) + 65.0).abs() < 1e-12);
/// assert!((law.distance_m(-65.0)? - 10.0).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 002 eq. (1) (`ρ = ρ_T − 10 η lg d + X`, there with `d₀ = 1` m); T. S. Rappaport,
/// *Wireless Communications*, 2nd ed., 2002, §4.9–4.9.2 (log-distance law, log-normal
/// shadowing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogDistance {
    law: LogDistancePathLoss,
    shadowing_std_db: f64,
}

impl LogDistance {
    /// The law with mean power `reference_rssi_dbm` (`ρ_T`) at `reference_distance_m` (`d₀`),
    /// exponent `exponent` (`η`) and shadowing `shadowing_std_db` (`σ_X`).
    ///
    /// # Errors
    /// [`crate::PositioningError::InvalidParameter`] naming the parameter unless every value
    /// is finite, `η > 0`, `d₀ > 0` and `σ_X ≥ 0`.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::LogDistance;
    /// assert!(LogDistance::new(-40.0, 2.0, 1.0, 4.0).is_ok());
    /// assert!(LogDistance::new(-40.0, 0.0, 1.0, 4.0).is_err()); // η must be positive
    /// ```
    ///
    /// # References
    /// Seed 002 eq. (1).
    pub fn new(
        reference_rssi_dbm: f64,
        exponent: f64,
        reference_distance_m: f64,
        shadowing_std_db: f64,
    ) -> Result<Self> {
        finite(reference_rssi_dbm, "reference_rssi_dbm")?;
        non_negative(
            shadowing_std_db,
            "shadowing_std_db",
            "the shadowing standard deviation must be non-negative",
        )?;
        let law = LogDistancePathLoss::new(reference_rssi_dbm, reference_distance_m, exponent)
            .map_err(|e| law_error(e, &[("reference_power_dbm", "reference_rssi_dbm")]))?;
        Ok(Self { law, shadowing_std_db })
    }

    /// Seed 002's simulation law: `ρ_T = 0` dBm at `d₀ = 1` m, `η = 4`, `σ_X = 4` dB (the
    /// online RSSI noise variance `σ_p² = 16`).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::pathloss::{LogDistance, PathLossModel};
    /// let law = LogDistance::seed_002();
    /// assert!((law.mean_rssi_dbm(100.0) + 80.0).abs() < 1e-12);
    /// assert_eq!(law.shadowing_std_db(), 4.0);
    /// ```
    ///
    /// # References
    /// Seed 002, §3 (simulation parameters).
    #[must_use]
    pub fn seed_002() -> Self {
        Self {
            law: LogDistancePathLoss::seed_002(),
            shadowing_std_db: 4.0,
        }
    }

    /// `ρ_T`: mean received power at the reference distance (dBm).
    #[inline]
    #[must_use]
    pub fn reference_rssi_dbm(&self) -> f64 {
        self.law.reference_power_dbm()
    }

    /// `η`: path-loss exponent.
    #[inline]
    #[must_use]
    pub fn exponent(&self) -> f64 {
        self.law.exponent()
    }

    /// `d₀`: reference distance (m).
    #[inline]
    #[must_use]
    pub fn reference_distance_m(&self) -> f64 {
        self.law.reference_distance_m()
    }

    /// `σ_X`: shadowing standard deviation (dB).
    #[inline]
    #[must_use]
    pub fn shadowing_std_db(&self) -> f64 {
        self.shadowing_std_db
    }

    /// `s = σ_X ln 10 / (10 η)`: the standard deviation of `ln d̂` for an inverted range, the
    /// relative range error (`σ_d = s d`).
    #[inline]
    #[must_use]
    pub fn log_range_std(&self) -> f64 {
        self.shadowing_std_db * LN_10 / (10.0 * self.exponent())
    }
}

impl PathLossModel for LogDistance {
    fn mean_rssi_dbm(&self, distance_m: f64) -> f64 {
        // μ(d) = ρ_T − 10 η lg(d/d₀)
        self.law.value_db(clamp_distance(distance_m))
    }

    fn slope_db_per_m(&self, distance_m: f64) -> f64 {
        // dμ/dd = −10 η / (d ln 10)
        self.law.slope_db_per_m(clamp_distance(distance_m))
    }

    fn shadowing_std_db(&self) -> f64 {
        self.shadowing_std_db
    }

    fn distance_m(&self, rssi_dbm: f64) -> Result<f64> {
        let rssi_dbm = finite_rssi(rssi_dbm)?;
        // d = d₀ · 10^((ρ_T − ρ) / (10 η))
        inverted_distance(
            self.reference_distance_m() * 10f64.powf((self.reference_rssi_dbm() - rssi_dbm) / (10.0 * self.exponent())),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::{DistanceEstimate, MAX_DISTANCE_M, MIN_DISTANCE_M};
    use super::*;
    use crate::PositioningError;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn values_slope_and_inverse_round_trip() {
        let law = LogDistance::new(-35.0, 2.7, 2.0, 5.0).unwrap();
        assert!((law.mean_rssi_dbm(2.0) + 35.0).abs() < 1e-12);
        assert!((law.mean_rssi_dbm(20.0) + 62.0).abs() < 1e-12);
        for d in [0.01, 0.5, 1.0, 3.7, 10.0, 123.4, 5e4] {
            // inversion round trip
            let rho = law.mean_rssi_dbm(d);
            assert!((law.distance_m(rho).unwrap() - d).abs() < 1e-12 * d, "{d}");
            // the slope is the derivative (central difference)
            let h = 1e-6 * d;
            let numeric = (law.mean_rssi_dbm(d + h) - law.mean_rssi_dbm(d - h)) / (2.0 * h);
            assert!((law.slope_db_per_m(d) - numeric).abs() < 1e-6 * numeric.abs(), "{d}");
            // σ_d = d ln10 σ / (10 η) = σ / |slope|
            let sigma_d = law.range_std_m(d).unwrap();
            assert!((sigma_d - d * LN_10 * 5.0 / 27.0).abs() < 1e-12 * d);
            assert!((sigma_d - law.log_range_std() * d).abs() < 1e-12 * d);
        }
        // clamped outside [MIN, MAX] and for NaN: outputs stay finite
        assert_eq!(law.mean_rssi_dbm(0.0), law.mean_rssi_dbm(MIN_DISTANCE_M));
        assert_eq!(law.mean_rssi_dbm(-3.0), law.mean_rssi_dbm(MIN_DISTANCE_M));
        assert_eq!(law.mean_rssi_dbm(f64::NAN), law.mean_rssi_dbm(MIN_DISTANCE_M));
        assert_eq!(law.mean_rssi_dbm(f64::INFINITY), law.mean_rssi_dbm(MAX_DISTANCE_M));
        assert!(law.slope_db_per_m(0.0).is_finite());
        assert_eq!(LogDistance::seed_002(), LogDistance::new(0.0, 4.0, 1.0, 4.0).unwrap());
    }

    /// Monte Carlo of the inverted range: its median is the truth, its mean is
    /// `d exp(½ s²)`, the bias-corrected inversion is unbiased in mean, and its spread is
    /// `σ_d` to first order.
    #[test]
    fn inverted_ranges_are_median_unbiased_and_the_correction_removes_the_mean_bias() {
        let law = LogDistance::new(-40.0, 2.0, 1.0, 6.0).unwrap(); // s = 0.69: a strong bias
        let truth = 15.0;
        let noise = Normal::new(0.0, 6.0).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let runs = 40_000;
        let mut median_estimates = Vec::with_capacity(runs);
        let mut corrected_sum = 0.0;
        for _ in 0..runs {
            let rho = law.mean_rssi_dbm(truth) + noise.sample(&mut rng);
            median_estimates.push(law.estimate_distance_m(rho, DistanceEstimate::Median).unwrap());
            corrected_sum += law.estimate_distance_m(rho, DistanceEstimate::MeanUnbiased).unwrap();
        }
        let s = law.log_range_std();
        let mean = median_estimates.iter().sum::<f64>() / runs as f64;
        // E[d̂] = d exp(½ s²) = 1.27 d; the Monte Carlo standard error of the mean is
        // d √(e^{s²}(e^{s²} − 1)/N) ≈ 0.005 d
        assert!((mean / truth - (0.5 * s * s).exp()).abs() < 0.02, "mean {mean}");
        assert!(
            ((0.5 * s * s).exp() - law.range_bias_factor(truth).unwrap()).abs() < 1e-12,
            "bias factor"
        );
        let corrected = corrected_sum / runs as f64;
        assert!((corrected / truth - 1.0).abs() < 0.02, "corrected mean {corrected}");
        median_estimates.sort_by(f64::total_cmp);
        let median = median_estimates[runs / 2];
        assert!((median / truth - 1.0).abs() < 0.02, "median {median}");

        // small shadowing: the spread is the delta-method σ_d
        let quiet = LogDistance::new(-40.0, 3.0, 1.0, 1.0).unwrap(); // s = 0.077
        let noise = Normal::new(0.0, 1.0).unwrap();
        let estimates: Vec<f64> = (0..runs)
            .map(|_| {
                quiet
                    .distance_m(quiet.mean_rssi_dbm(truth) + noise.sample(&mut rng))
                    .unwrap()
            })
            .collect();
        let m = estimates.iter().sum::<f64>() / runs as f64;
        let std = (estimates.iter().map(|e| (e - m) * (e - m)).sum::<f64>() / (runs as f64 - 1.0)).sqrt();
        let sigma_d = quiet.range_std_m(truth).unwrap();
        assert!((std / sigma_d - 1.0).abs() < 0.03, "spread {std} vs σ_d {sigma_d}");
    }

    #[test]
    fn invalid_parameters_and_inputs_are_errors() {
        let name = |r: Result<LogDistance>| match r {
            Err(PositioningError::InvalidParameter { name, .. }) => name,
            other => panic!("expected InvalidParameter, got {other:?}"),
        };
        assert_eq!(name(LogDistance::new(f64::NAN, 2.0, 1.0, 1.0)), "reference_rssi_dbm");
        assert_eq!(name(LogDistance::new(0.0, 0.0, 1.0, 1.0)), "exponent");
        assert_eq!(name(LogDistance::new(0.0, -2.0, 1.0, 1.0)), "exponent");
        assert_eq!(name(LogDistance::new(0.0, f64::INFINITY, 1.0, 1.0)), "exponent");
        assert_eq!(name(LogDistance::new(0.0, 2.0, 0.0, 1.0)), "reference_distance_m");
        assert_eq!(name(LogDistance::new(0.0, 2.0, 1.0, -0.1)), "shadowing_std_db");
        assert_eq!(name(LogDistance::new(0.0, 2.0, 1.0, f64::NAN)), "shadowing_std_db");
        assert!(LogDistance::new(0.0, 2.0, 1.0, 0.0).is_ok());

        let law = LogDistance::seed_002();
        assert!(matches!(
            law.distance_m(f64::NAN),
            Err(PositioningError::NonFinite { .. })
        ));
        assert!(matches!(
            law.distance_m(f64::NEG_INFINITY),
            Err(PositioningError::NonFinite { .. })
        ));
        // far outside the floating-point range of distances
        assert!(matches!(
            law.distance_m(-1e5),
            Err(PositioningError::NoConsistentSolution { .. })
        ));
        assert!(matches!(
            law.distance_m(1e5),
            Err(PositioningError::NoConsistentSolution { .. })
        ));
        assert!(matches!(
            law.range_std_m(0.0),
            Err(PositioningError::InvalidParameter { name: "distance_m", .. })
        ));
        assert!(matches!(
            law.range_std_m(f64::NAN),
            Err(PositioningError::InvalidParameter { name: "distance_m", .. })
        ));
    }
}
