//! A track's GNSS state: the open pseudorange epoch and the receiver clock filter `[b, ḃ]`;
//! what pseudorange records do with it is in the `gnss` module.

use std::sync::Arc;

use nalgebra::{Matrix2, Vector2};
use rtls_positioning::gnss::ClockPrior;

use crate::site::GnssSettings;

/// A buffered pseudorange: its time, satellite id, position and value as received.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Reading {
    pub(super) time_s: f64,
    pub(super) satellite: Arc<str>,
    pub(super) satellite_ecef_m: [f64; 3],
    pub(super) pseudorange_m: f64,
    pub(super) std_m: Option<f64>,
}

/// A track's GNSS state: the open epoch and the receiver clock filter.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct GnssTrack {
    pub(super) epoch: Vec<Reading>,
    pub(super) clock: Option<ReceiverClock>,
}

impl GnssTrack {
    /// Whether the open epoch holds readings from before `now_s`.
    pub(super) fn holds_readings_before(&self, now_s: f64) -> bool {
        self.epoch.first().is_some_and(|r| r.time_s < now_s)
    }
}

/// The receiver clock filter: `[b, ḃ]` (m, m/s) with its covariance at `time_s`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct ReceiverClock {
    pub(super) mean: Vector2<f64>,
    pub(super) covariance: Matrix2<f64>,
    pub(super) time_s: f64,
}

impl ReceiverClock {
    /// The prediction to `time_s` (never backwards: an earlier time keeps the state).
    pub(super) fn predicted(&self, time_s: f64, gnss: &GnssSettings) -> Self {
        let dt = (time_s - self.time_s).max(0.0);
        let (qb, qd) = (gnss.clock_bias_noise_m2ps, gnss.clock_drift_noise_m2ps3);
        // F = [[1, Δt], [0, 1]]
        let f = Matrix2::new(1.0, dt, 0.0, 1.0);
        // Q = [[q_b Δt + q_d Δt³/3, q_d Δt²/2], [q_d Δt²/2, q_d Δt]]
        let q = Matrix2::new(
            qb * dt + qd * dt.powi(3) / 3.0,
            qd * dt * dt / 2.0,
            qd * dt * dt / 2.0,
            qd * dt,
        );
        Self {
            // x⁻ = F x
            mean: f * self.mean,
            // P⁻ = F P Fᵀ + Q
            covariance: f * self.covariance * f.transpose() + q,
            time_s: time_s.max(self.time_s),
        }
    }

    /// The prior on `b` this prediction gives the solver.
    pub(super) fn prior(&self) -> ClockPrior {
        ClockPrior {
            mean_m: self.mean[0],
            variance_m2: self.covariance[(0, 0)],
        }
    }

    /// The filter with `b`'s marginal replaced by the solver's posterior `N(b̂, σ̂²)`.
    pub(super) fn with_bias_posterior(&self, bias_m: f64, variance_m2: f64) -> Self {
        let p_bb = self.covariance[(0, 0)];
        // k = P⁻ e₁ / P⁻_bb
        let k = self.covariance.column(0) / p_bb;
        Self {
            // x⁺ = x⁻ + k (b̂ − b̄)
            mean: self.mean + k * (bias_m - self.mean[0]),
            // P⁺ = P⁻ + k (σ̂² − P⁻_bb) kᵀ, symmetrised
            covariance: symmetric(self.covariance + k * (variance_m2 - p_bb) * k.transpose()),
            time_s: self.time_s,
        }
    }

    /// A clock starting at the solved bias, with the drift unknown.
    pub(super) fn start(bias_m: f64, variance_m2: f64, time_s: f64, gnss: &GnssSettings) -> Self {
        Self {
            mean: Vector2::new(bias_m, 0.0),
            covariance: Matrix2::new(variance_m2, 0.0, 0.0, gnss.initial_clock_drift_std_mps.powi(2)),
            time_s,
        }
    }
}

pub(super) fn symmetric(m: Matrix2<f64>) -> Matrix2<f64> {
    (m + m.transpose()) * 0.5
}
