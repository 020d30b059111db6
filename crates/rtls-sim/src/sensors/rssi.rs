//! Received signal strength from a log-distance radio, and fingerprint databases (seed 002).

use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::{finite, finite2, non_negative, positive, Result, SimError};

/// A log-distance radio: mean RSSI `ρ̄(d) = ρ_T − 10 η log₁₀(max(d, d_min))` in dBm.
///
/// The law is undefined at `d = 0` (it diverges to +∞), and a receiver can sit on an anchor:
/// seed 002's anchors lie on reference points of the fingerprint grid. The distance is
/// therefore clamped to `d_min` (1 m by default, the usual reference distance of the law, so
/// `ρ_T` is also the power at 1 m). [`Default`] gives seed 002's values.
///
/// # Units
/// Powers in dBm, distances in m, `η` dimensionless.
///
/// # Errors
/// The methods validate the fields (see [`LogDistanceRadio::mean_rssi_dbm`]).
///
/// # Example
/// ```
/// let radio = rtls_sim::LogDistanceRadio::default();
/// assert!((radio.mean_rssi_dbm([0.0, 0.0], [100.0, 0.0])? + 80.0).abs() < 1e-12); // 0 − 40 lg 100
/// assert_eq!(radio.mean_rssi_dbm([10.0, 10.0], [10.0, 10.0])?, 0.0); // clamped at 1 m
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2, eq. (12): `ρ = ρ_T − 10 η lg‖S_i − P_l‖ + X`, `ρ_T = 0` dBm, `η = 4`;
/// T. S. Rappaport, *Wireless Communications*, 2nd ed., §4.9 (log-distance path loss).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogDistanceRadio {
    /// `ρ_T`: mean RSSI at `d_min` (1 m), dBm (seed 002: 0 dBm).
    pub reference_power_dbm: f64,
    /// `η`: path-loss exponent (seed 002: 4).
    pub exponent: f64,
    /// `d_min`: distances below it are clamped to it, m (default 1 m; must be `> 0`).
    pub min_distance_m: f64,
}

impl Default for LogDistanceRadio {
    /// Seed 002: `ρ_T = 0` dBm, `η = 4`, `d_min = 1` m.
    fn default() -> Self {
        Self {
            reference_power_dbm: 0.0,
            exponent: 4.0,
            min_distance_m: 1.0,
        }
    }
}

impl LogDistanceRadio {
    /// Mean RSSI at `point_m` from the anchor at `anchor_m`:
    /// `ρ̄ = ρ_T − 10 η log₁₀(max(d, d_min))`, `d = ‖point − anchor‖`, in dBm.
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for NaN/∞ positions or parameters;
    /// [`SimError::InvalidParameter`] for `d_min ≤ 0` or `η < 0`.
    ///
    /// # Example
    /// ```
    /// let radio = rtls_sim::LogDistanceRadio::default();
    /// assert!((radio.mean_rssi_dbm([0.0, 0.0], [6.0, 8.0])? + 40.0).abs() < 1e-12); // d = 10 m
    /// assert_eq!(radio.mean_rssi_dbm([0.0, 0.0], [0.3, 0.4])?, 0.0); // d = 0.5 m → 1 m
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §2, eq. (12).
    pub fn mean_rssi_dbm(&self, anchor_m: [f64; 2], point_m: [f64; 2]) -> Result<f64> {
        self.validate()?;
        self.mean_unchecked(finite2(anchor_m, "anchor")?, finite2(point_m, "point")?)
    }

    /// Noisy RSSI at `point_m` from every anchor, in anchor order:
    /// `ρ_i = ρ̄_i + X_i`, `X_i ~ N(0, σ²)` independent, `σ² = variance_db2` (dB²), in dBm.
    ///
    /// # Errors
    /// As [`mean_rssi_dbm`](Self::mean_rssi_dbm); [`SimError::EmptyInput`] for no anchors;
    /// [`SimError::InvalidParameter`] for a negative variance.
    ///
    /// # Example
    /// ```
    /// use rand::SeedableRng;
    /// use rtls_sim::{LogDistanceRadio, SEED_002_ANCHORS};
    /// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
    /// // Seed 002's online noise: σ_p² = 16 dB².
    /// let rssi = LogDistanceRadio::default().measure(&SEED_002_ANCHORS, [50.0, 50.0], 16.0, &mut rng)?;
    /// assert_eq!(rssi.len(), 25);
    /// assert!(rssi[12].abs() < 20.0); // the anchor at (50, 50): 0 dBm + noise
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §2, eq. (12) and Table 1 (`σ_p² = 16`).
    pub fn measure(
        &self,
        anchors_m: &[[f64; 2]],
        point_m: [f64; 2],
        variance_db2: f64,
        rng: &mut impl Rng,
    ) -> Result<Vec<f64>> {
        self.validate()?;
        check_anchors(anchors_m)?;
        let point_m = finite2(point_m, "point")?;
        // σ = √σ²
        let std_db = non_negative(variance_db2, "variance_db2", "a variance must be finite and ≥ 0")?.sqrt();
        anchors_m
            .iter()
            .map(|anchor| {
                // ρ_i = ρ̄_i + σ n_i
                Ok(self.mean_unchecked(*anchor, point_m)? + std_db * rng.sample::<f64, _>(StandardNormal))
            })
            .collect()
    }

    /// `ρ̄` for validated inputs.
    fn mean_unchecked(&self, anchor_m: [f64; 2], point_m: [f64; 2]) -> Result<f64> {
        // d = ‖p − s‖
        let distance_m = (point_m[0] - anchor_m[0]).hypot(point_m[1] - anchor_m[1]);
        // ρ̄ = ρ_T − 10 η log₁₀(max(d, d_min))
        finite(
            self.reference_power_dbm - 10.0 * self.exponent * distance_m.max(self.min_distance_m).log10(),
            "mean rssi",
        )
    }

    /// Checks the fields.
    fn validate(&self) -> Result<()> {
        finite(self.reference_power_dbm, "reference_power_dbm")?;
        non_negative(
            self.exponent,
            "exponent",
            "the path-loss exponent must be finite and ≥ 0 (2–4 indoors)",
        )?;
        positive(
            self.min_distance_m,
            "min_distance_m",
            "the clamp distance must be finite and > 0 m",
        )?;
        Ok(())
    }
}

/// Builds a fingerprint database: for each reference point, the mean of `samples` noisy RSSI
/// vectors ([`LogDistanceRadio::measure`] with variance `variance_db2`), one row per reference
/// point in input order, one column per anchor in input order.
///
/// Row `l` is `ρ_l = (1/M) Σ_{m=1}^{M} (ρ̄(S_i, P_l) + X_{i,m})`, so each entry's noise
/// variance is `σ²/M`. The paper adds variance-1 noise to each collected value and averages
/// "several" collections without saying how many; `samples = 1` reproduces a fingerprint
/// noise variance of exactly 1 dB².
///
/// # Units
/// Positions in m, RSSI in dBm, variance in dB².
///
/// # Errors
/// [`SimError::EmptyInput`] for no anchors or no reference points;
/// [`SimError::InvalidParameter`] for `samples = 0` or a negative variance; as
/// [`LogDistanceRadio::measure`] otherwise.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::{fingerprint_means, seed_002_reference_points, LogDistanceRadio, SEED_002_ANCHORS};
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
/// let rps = seed_002_reference_points();
/// let db = fingerprint_means(&SEED_002_ANCHORS, &rps, &LogDistanceRadio::default(), 1.0, 10, &mut rng)?;
/// assert_eq!((db.len(), db[0].len()), (121, 25));
/// // RP (10, 10) holds anchor 0: its mean RSSI is 0 dBm within a few σ/√10.
/// assert!(db[12][0].abs() < 1.5);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §1.1 (fingerprint = mean RSSI vector per reference point) and §2 (variance 1).
pub fn fingerprint_means(
    anchors_m: &[[f64; 2]],
    reference_points_m: &[[f64; 2]],
    radio: &LogDistanceRadio,
    variance_db2: f64,
    samples: usize,
    rng: &mut impl Rng,
) -> Result<Vec<Vec<f64>>> {
    check_anchors(anchors_m)?;
    if reference_points_m.is_empty() {
        return Err(SimError::EmptyInput {
            what: "reference points",
        });
    }
    if samples == 0 {
        return Err(SimError::InvalidParameter {
            name: "samples",
            reason: "average at least one reading per reference point",
        });
    }
    let inverse_count = 1.0 / samples as f64;
    reference_points_m
        .iter()
        .map(|point| {
            let mut sum_dbm = vec![0.0; anchors_m.len()];
            for _ in 0..samples {
                let reading = radio.measure(anchors_m, *point, variance_db2, rng)?;
                // Σ_m ρ_{i,m}
                sum_dbm.iter_mut().zip(&reading).for_each(|(sum, rho)| *sum += rho);
            }
            // ρ_l = (1/M) Σ_m ρ_{i,m}
            Ok(sum_dbm.into_iter().map(|sum| sum * inverse_count).collect())
        })
        .collect()
}

/// Checks that there is at least one anchor and all coordinates are finite.
fn check_anchors(anchors_m: &[[f64; 2]]) -> Result<()> {
    if anchors_m.is_empty() {
        return Err(SimError::EmptyInput { what: "anchors" });
    }
    for anchor in anchors_m {
        finite2(*anchor, "anchors")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenarios::{seed_002_reference_points, SEED_002_ANCHORS};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn mean_follows_the_log_distance_law() {
        let radio = LogDistanceRadio::default();
        // ρ̄ = 0 − 40 lg d
        for (d, expected) in [
            (10.0, -40.0),
            (100.0, -80.0),
            (2.0, -12.041_199_826_559_248),
            (1.0, 0.0),
        ] {
            let rho = radio.mean_rssi_dbm([5.0, 5.0], [5.0 + d, 5.0]).unwrap();
            assert!((rho - expected).abs() < 1e-12, "d = {d}: {rho}");
        }
        let other = LogDistanceRadio {
            reference_power_dbm: -30.0,
            exponent: 2.0,
            min_distance_m: 1.0,
        };
        assert!((other.mean_rssi_dbm([0.0, 0.0], [0.0, 10.0]).unwrap() + 50.0).abs() < 1e-12);
    }

    #[test]
    fn distance_is_clamped_below_d_min() {
        let radio = LogDistanceRadio {
            min_distance_m: 2.0,
            ..Default::default()
        };
        let at_clamp = radio.mean_rssi_dbm([0.0, 0.0], [2.0, 0.0]).unwrap();
        assert!((at_clamp + 40.0 * 2f64.log10()).abs() < 1e-12);
        for d in [0.0, 1e-9, 0.5, 1.999] {
            assert_eq!(radio.mean_rssi_dbm([0.0, 0.0], [d, 0.0]).unwrap(), at_clamp, "d = {d}");
        }
        assert!(radio.mean_rssi_dbm([0.0, 0.0], [2.5, 0.0]).unwrap() < at_clamp);
    }

    #[test]
    fn online_noise_has_the_requested_variance() {
        let radio = LogDistanceRadio::default();
        let mut rng = ChaCha8Rng::seed_from_u64(16);
        let anchors = [[0.0, 0.0], [30.0, 40.0]];
        let mean = [
            radio.mean_rssi_dbm(anchors[0], [0.0, 0.0]).unwrap(),
            -40.0 * 50f64.log10(),
        ];
        let mut errors = Vec::new();
        for _ in 0..20_000 {
            let z = radio.measure(&anchors, [0.0, 0.0], 16.0, &mut rng).unwrap();
            errors.push(z[0] - mean[0]);
            errors.push(z[1] - mean[1]);
        }
        let n = errors.len() as f64;
        let m = errors.iter().sum::<f64>() / n;
        let var = errors.iter().map(|e| (e - m).powi(2)).sum::<f64>() / (n - 1.0);
        assert!(m.abs() < 4.0 * 4.0 / n.sqrt(), "mean {m}");
        assert!((var / 16.0 - 1.0).abs() < 0.05, "variance {var}");
    }

    #[test]
    fn fingerprints_average_the_samples() {
        let radio = LogDistanceRadio::default();
        let rps = seed_002_reference_points();
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let exact = fingerprint_means(&SEED_002_ANCHORS, &rps, &radio, 0.0, 3, &mut rng).unwrap();
        for (row, p) in exact.iter().zip(&rps) {
            for (rho, a) in row.iter().zip(&SEED_002_ANCHORS) {
                assert!((rho - radio.mean_rssi_dbm(*a, *p).unwrap()).abs() < 1e-12);
            }
        }
        // averaging M = 4 readings of variance 1 leaves variance 1/4 (3025 entries)
        let noisy = fingerprint_means(&SEED_002_ANCHORS, &rps, &radio, 1.0, 4, &mut rng).unwrap();
        let errors: Vec<f64> = noisy
            .iter()
            .flatten()
            .zip(exact.iter().flatten())
            .map(|(a, b)| a - b)
            .collect();
        let var = errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64;
        assert!((var / 0.25 - 1.0).abs() < 0.1, "variance of the mean {var}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let radio = LogDistanceRadio::default();
        let mut rng = ChaCha8Rng::seed_from_u64(18);
        let rps = seed_002_reference_points();
        assert!(matches!(
            radio.measure(&[], [0.0, 0.0], 1.0, &mut rng),
            Err(SimError::EmptyInput { what: "anchors" })
        ));
        assert!(matches!(
            radio.measure(&SEED_002_ANCHORS, [0.0, 0.0], -1.0, &mut rng),
            Err(SimError::InvalidParameter {
                name: "variance_db2",
                ..
            })
        ));
        assert!(matches!(
            radio.mean_rssi_dbm([f64::NAN, 0.0], [0.0, 0.0]),
            Err(SimError::NonFinite { .. })
        ));
        let no_clamp = LogDistanceRadio {
            min_distance_m: 0.0,
            ..radio
        };
        assert!(matches!(
            no_clamp.mean_rssi_dbm([0.0, 0.0], [0.0, 0.0]),
            Err(SimError::InvalidParameter { .. })
        ));
        assert!(matches!(
            fingerprint_means(&SEED_002_ANCHORS, &[], &radio, 1.0, 1, &mut rng),
            Err(SimError::EmptyInput {
                what: "reference points"
            })
        ));
        assert!(matches!(
            fingerprint_means(&SEED_002_ANCHORS, &rps, &radio, 1.0, 0, &mut rng),
            Err(SimError::InvalidParameter { name: "samples", .. })
        ));
        assert!(fingerprint_means(&[], &rps, &radio, 1.0, 1, &mut rng).is_err());
    }
}
