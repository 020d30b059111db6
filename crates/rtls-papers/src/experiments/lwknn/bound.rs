//! The Cramér–Rao bounds of seed 002's scenario: the PCRB of a `[x, vx, y, vy]` tracker driven
//! by the accelerometer and observing the raw RSSI, and the CRB of a single-epoch fix.

use nalgebra::{DMatrix, Matrix2};

use crate::error::{Result, SimError};
use crate::reproduction::{Seed002Config, Seed002Trajectory};
use rtls_sim::pcrb::{pooled_rmse_bound, posterior_crb, rmse_bound, PcrbStep};
use rtls_sim::scenarios::{seed_002_manoeuvre_then_cruise, seed_002_trajectory};

/// The bounds of one configuration.
pub(super) struct Bounds {
    /// √PCRB of the position pooled over the run, m.
    pub tracking_rmse_m: f64,
    /// √PCRB of the position at each epoch `t = 1, 2, …` s, m.
    pub tracking_over_time_m: Vec<f64>,
    /// `√((1/K) Σ_k tr(J_z,k⁻¹))`: the RMSE bound of a fix from one epoch's readings, m.
    pub snapshot_rmse_m: f64,
}

impl Bounds {
    /// # Equations
    /// Per axis `F = [[1, T], [0, 1]]`, `Q = B σ_a² Bᵀ`, `B = [T²/2, T]ᵀ` with `σ_a` the
    /// accelerometer's noise at the true acceleration (plus the textbook model's extra
    /// variance); the RSSI `ρᵢ = ρ_T − 10 η log10(dᵢ)` has gradient
    /// `∇ρᵢ = −(10 η / ln 10) (p − aᵢ) / dᵢ²`, so `J_z = Σᵢ ∇ρᵢ ∇ρᵢᵀ / σ_p²` on the position.
    /// The start is known (`P₀ = 0`), as the trackers are told.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a singular snapshot information (fewer than two
    /// anchors in general position); trajectory errors.
    pub fn new(config: &Seed002Config) -> Result<Self> {
        let trajectory = match config.trajectory {
            Seed002Trajectory::Tracking => seed_002_trajectory()?,
            Seed002Trajectory::ManoeuvreThenCruise => seed_002_manoeuvre_then_cruise()?,
        };
        let samples = trajectory.sample(1.0)?;
        let anchors = config.site.anchors_m();
        let radio = config.site.radio;
        let slope = 10.0 * radio.exponent / std::f64::consts::LN_10;
        let dt: f64 = 1.0;
        let mut steps = Vec::with_capacity(samples.len());
        let mut snapshot_sum = 0.0;
        for pair in samples.windows(2) {
            let (from, truth) = (&pair[0], &pair[1]);
            let acceleration = trajectory.mean_acceleration(from.time_s, truth.time_s)?;
            let std = config.accelerometer.std_mps2(acceleration);
            let mut transition = DMatrix::identity(4, 4);
            let mut process_noise = DMatrix::zeros(4, 4);
            for (axis, std_axis) in std.iter().enumerate() {
                let (p, v) = (2 * axis, 2 * axis + 1);
                transition[(p, v)] = dt;
                // Q = B σ_a² Bᵀ, B = [T²/2, T]ᵀ
                let variance = std_axis * std_axis + config.textbook_extra_variance_m2ps4;
                let b = [dt * dt / 2.0, dt];
                process_noise[(p, p)] = b[0] * b[0] * variance;
                process_noise[(p, v)] = b[0] * b[1] * variance;
                process_noise[(v, p)] = b[0] * b[1] * variance;
                process_noise[(v, v)] = b[1] * b[1] * variance;
            }
            // J_z = Σᵢ ∇ρᵢ ∇ρᵢᵀ / σ_p²
            let mut position_information = Matrix2::<f64>::zeros();
            for anchor in &anchors {
                let dx = truth.position_m[0] - anchor[0];
                let dy = truth.position_m[1] - anchor[1];
                let d2 = (dx * dx + dy * dy).max(radio.min_distance_m * radio.min_distance_m);
                // ∇ρ = −(10 η / ln 10) (p − a) / d²
                let g = [-slope * dx / d2, -slope * dy / d2];
                for r in 0..2 {
                    for c in 0..2 {
                        position_information[(r, c)] += g[r] * g[c] / config.rssi_variance_db2;
                    }
                }
            }
            let snapshot = position_information.try_inverse().ok_or(SimError::InvalidParameter {
                name: "site",
                reason: "the anchors give no position information (singular Fisher matrix)",
            })?;
            snapshot_sum += snapshot.trace();
            let mut information = DMatrix::zeros(4, 4);
            for (r, sr) in [0, 2].into_iter().enumerate() {
                for (c, sc) in [0, 2].into_iter().enumerate() {
                    information[(sr, sc)] = position_information[(r, c)];
                }
            }
            steps.push(PcrbStep {
                transition,
                process_noise,
                measurement_information: information,
            });
        }
        let epochs = steps.len();
        let bounds = posterior_crb(&DMatrix::zeros(4, 4), steps)?;
        Ok(Self {
            tracking_rmse_m: pooled_rmse_bound(&bounds, &[0, 2])?,
            tracking_over_time_m: bounds
                .iter()
                .map(|b| rmse_bound(b, &[0, 2]))
                .collect::<Result<Vec<_>>>()?,
            snapshot_rmse_m: (snapshot_sum / epochs.max(1) as f64).sqrt(),
        })
    }
}
