//! The nodes' clocks and seed 003's one-way broadcast synchronisation (§3.1).
//!
//! Each node's clock runs at rate `1 + δᵢ` (drift `δᵢ`, drawn once per run) and is set on a
//! reference broadcast: the base station sends its time `t_b`; the node, on reception, sets its
//! clock to `t_b + d`, `d` the known propagation and processing delay. The true delay is `d`
//! plus a reception jitter `j ~ N(0, σ_j²)` (interrupt latency, start-of-frame detection), so
//! right after the sync the node's clock is off by `−j`, and afterwards
//!
//! ```text
//! eᵢ(t) = −jᵢ + δᵢ (t − t_sync)                 clock error at true time t
//! ```
//!
//! A range is time-stamped with the node's clock (the stamp is off by `eᵢ`), and its time of
//! flight is counted on the same clock (the range is scaled by `1 + δᵢ`: over a 17.5 ms window
//! at 20 ppm that is 0.35 µs, 0.06 mm at 343 m/s).
//!
//! The paper syncs once, at start-up ("nodes then use the relative time Δt = t_cur − t₀");
//! with [`ClockConfig::resync_every_cycle`] the token broadcast that opens every cycle re-syncs
//! every node, which costs nothing extra since every node receives it anyway.

use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::error::{non_negative, Result, SimError};

/// The clocks of a run.
///
/// # Units
/// Drift in parts per million, jitter in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockConfig {
    /// Standard deviation of the nodes' rate errors `δᵢ` (ppm), ≥ 0.
    pub drift_std_ppm: f64,
    /// Standard deviation of the sync reception jitter `σ_j` (s), ≥ 0.
    pub sync_jitter_std_s: f64,
    /// Re-sync every node on every cycle's token broadcast (else once, at start-up).
    pub resync_every_cycle: bool,
}

impl ClockConfig {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`drift_std_ppm`, `sync_jitter_std_s`) for a negative
    /// value, a drift of 10⁵ ppm (10 %) or more, or a jitter of 1 s or more;
    /// [`SimError::NonFinite`] for NaN/∞.
    pub fn validate(&self) -> Result<()> {
        non_negative(
            self.drift_std_ppm,
            "drift_std_ppm",
            "the clock drift must not be negative",
        )?;
        if self.drift_std_ppm >= 1e5 {
            return Err(SimError::InvalidParameter {
                name: "drift_std_ppm",
                reason: "a clock drift of 10 % or more is not a clock",
            });
        }
        non_negative(
            self.sync_jitter_std_s,
            "sync_jitter_std_s",
            "the sync jitter must not be negative",
        )?;
        if self.sync_jitter_std_s >= 1.0 {
            return Err(SimError::InvalidParameter {
                name: "sync_jitter_std_s",
                reason: "the sync jitter must be below 1 s",
            });
        }
        Ok(())
    }
}

/// Every node's clock: rate error, time of the last sync and the error it left.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NodeClocks {
    /// Rate errors `δᵢ` (dimensionless).
    drift: Vec<f64>,
    /// True time of each node's last sync (s).
    synced_s: Vec<f64>,
    /// Error left by each node's last sync, `−jᵢ` (s).
    error_at_sync_s: Vec<f64>,
    /// Jitter standard deviation `σ_j` (s).
    jitter_std_s: f64,
}

impl NodeClocks {
    /// `nodes` clocks with rate errors drawn from `N(0, σ_δ²)` (one draw per node), not yet synced.
    ///
    /// # Errors
    /// As [`ClockConfig::validate`].
    pub fn new(nodes: usize, config: &ClockConfig, rng: &mut impl Rng) -> Result<Self> {
        config.validate()?;
        let drift_std = config.drift_std_ppm * 1e-6;
        let drift = (0..nodes)
            .map(|_| {
                let z: f64 = StandardNormal.sample(rng);
                drift_std * z
            })
            .collect();
        Ok(Self {
            drift,
            synced_s: vec![0.0; nodes],
            error_at_sync_s: vec![0.0; nodes],
            jitter_std_s: config.sync_jitter_std_s,
        })
    }

    /// Every node receives the reference broadcast at true time `time_s`: its error becomes
    /// `−j`, a fresh jitter draw per node (one draw per node even for σ_j = 0, so that the random
    /// stream does not depend on the jitter).
    pub fn sync(&mut self, time_s: f64, rng: &mut impl Rng) {
        for (synced, error) in self.synced_s.iter_mut().zip(&mut self.error_at_sync_s) {
            *synced = time_s;
            let z: f64 = StandardNormal.sample(rng);
            *error = -self.jitter_std_s * z;
        }
    }

    /// Node `node`'s clock error at true time `time_s`, `eᵢ(t) = −jᵢ + δᵢ (t − t_sync)` (s); 0
    /// for an unknown node.
    pub fn error_s(&self, node: usize, time_s: f64) -> f64 {
        match (
            self.error_at_sync_s.get(node),
            self.drift.get(node),
            self.synced_s.get(node),
        ) {
            (Some(e), Some(d), Some(t)) => e + d * (time_s - t),
            _ => 0.0,
        }
    }

    /// Node `node`'s clock rate `1 + δᵢ` (1 for an unknown node).
    pub fn rate(&self, node: usize) -> f64 {
        1.0 + self.drift.get(node).copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_error_grows_with_the_drift_and_a_sync_resets_it_to_the_jitter() {
        let config = ClockConfig {
            drift_std_ppm: 20.0,
            sync_jitter_std_s: 0.0,
            resync_every_cycle: true,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut clocks = NodeClocks::new(400, &config, &mut rng).unwrap();
        clocks.sync(2.0, &mut rng);
        // without jitter: e(t) = δ (t − 2); δ = rate − 1
        let delta = clocks.rate(3) - 1.0;
        assert!((clocks.error_s(3, 12.0) - delta * 10.0).abs() < 1e-12);
        // the drifts have the configured spread (400 draws: σ within ±15 %)
        let std_ppm = ((0..400).map(|i| (clocks.rate(i) - 1.0).powi(2)).sum::<f64>() / 400.0).sqrt() * 1e6;
        assert!((17.0..23.0).contains(&std_ppm), "{std_ppm}");
        // a re-sync at 12 s clears the accumulated error
        clocks.sync(12.0, &mut rng);
        assert_eq!(clocks.error_s(3, 12.0), 0.0);
        assert_eq!((clocks.error_s(999, 5.0), clocks.rate(999)), (0.0, 1.0));
    }

    #[test]
    fn jitter_is_drawn_per_node_and_sync() {
        let config = ClockConfig {
            drift_std_ppm: 0.0,
            sync_jitter_std_s: 1e-4,
            resync_every_cycle: true,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut clocks = NodeClocks::new(1000, &config, &mut rng).unwrap();
        clocks.sync(0.0, &mut rng);
        let errors: Vec<f64> = (0..1000).map(|i| clocks.error_s(i, 5.0)).collect();
        let std = (errors.iter().map(|e| e * e).sum::<f64>() / 1000.0).sqrt();
        assert!((std - 1e-4).abs() < 1e-5, "{std}");
        // no drift: the error stays what the sync left
        assert_eq!(clocks.error_s(7, 5.0), clocks.error_s(7, 500.0));
        assert_eq!(clocks.rate(7), 1.0);
    }

    #[test]
    fn bad_clocks_are_errors() {
        let good = ClockConfig {
            drift_std_ppm: 20.0,
            sync_jitter_std_s: 2e-5,
            resync_every_cycle: false,
        };
        assert!(good.validate().is_ok());
        for (bad, name) in [
            (
                ClockConfig {
                    drift_std_ppm: -1.0,
                    ..good
                },
                "drift_std_ppm",
            ),
            (
                ClockConfig {
                    drift_std_ppm: 2e5,
                    ..good
                },
                "drift_std_ppm",
            ),
            (
                ClockConfig {
                    sync_jitter_std_s: 2.0,
                    ..good
                },
                "sync_jitter_std_s",
            ),
        ] {
            assert!(
                matches!(bad.validate(), Err(SimError::InvalidParameter { name: n, .. }) if n == name),
                "{bad:?}"
            );
        }
        assert!(matches!(
            ClockConfig {
                sync_jitter_std_s: f64::NAN,
                ..good
            }
            .validate(),
            Err(SimError::NonFinite { .. })
        ));
    }
}
