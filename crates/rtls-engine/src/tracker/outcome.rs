//! What the tracker's bookkeeping reads of a measurement update — the posterior, `ν`, `S`,
//! the NIS and `ln |S|` — whether the update came from the general (heap-sized) kernel,
//! [`Updated`], or from the fixed-size one of position fixes and velocities, [`FixedUpdated`]
//! (see [`super::update`]); so gating, the innovation totals and the adaptive noise treat both
//! alike.

use nalgebra::{DMatrix, SMatrix};
use rtls_estimation::adaptive::{AdaptiveNoise, NoiseScale};
use rtls_estimation::filter::{FixedUpdated, Updated};
use rtls_estimation::Gaussian;

/// The result of a measurement update as the tracker reads it.
pub(super) trait UpdateOutcome<const N: usize> {
    /// The posterior.
    fn state(&self) -> &Gaussian<N>;
    /// The posterior, by value.
    fn into_state(self) -> Gaussian<N>;
    /// `νᵀ S⁻¹ ν`.
    fn nis(&self) -> f64;
    /// `ln |S|`.
    fn log_det_innovation_covariance(&self) -> f64;
    /// `m`, the measurement's components.
    fn measurement_dim(&self) -> usize;
    /// `νᵢ`.
    fn innovation(&self, i: usize) -> f64;
    /// `Sᵢᵢ`.
    fn innovation_variance(&self, i: usize) -> f64;
    /// `K[i, j]`.
    fn gain(&self, i: usize, j: usize) -> f64;
    /// `S[i, j]`.
    fn innovation_covariance(&self, i: usize, j: usize) -> f64;
    /// The update's position correction `Δp = (K ν)_p` and its covariance `(K S Kᵀ)_pp` in the
    /// CV layout `[x, v_x, y, v_y, z, v_z]` (positions at the even indices), for the first
    /// `dimensions` axes; the rest 0.
    fn position_correction(&self, dimensions: usize) -> ([f64; 3], [[f64; 3]; 3]) {
        let m = self.measurement_dim();
        let (mut correction, mut covariance) = ([0.0; 3], [[0.0; 3]; 3]);
        if m == 1 {
            // one reading (the tightly coupled case): Δp_a = K_a ν, (K S Kᵀ)_ab = K_a K_b S
            let (nu, s) = (self.innovation(0), self.innovation_covariance(0, 0));
            let mut k = [0.0; 3];
            for (a, k_a) in k.iter_mut().enumerate().take(dimensions) {
                *k_a = self.gain(2 * a, 0);
                correction[a] = *k_a * nu;
            }
            for (a, row) in covariance.iter_mut().enumerate().take(dimensions) {
                for (b, entry) in row.iter_mut().enumerate().take(dimensions) {
                    *entry = k[a] * k[b] * s;
                }
            }
            return (correction, covariance);
        }
        for a in 0..dimensions {
            // Δp_a = Σ_j K[2a, j] ν_j
            correction[a] = (0..m).map(|j| self.gain(2 * a, j) * self.innovation(j)).sum();
            for (b, entry) in covariance[a].iter_mut().enumerate().take(dimensions) {
                // (K S Kᵀ)[2a, 2b] = Σ_j Σ_l K[2a, j] S[j, l] K[2b, l]
                *entry = (0..m)
                    .map(|j| {
                        let ks: f64 = (0..m)
                            .map(|l| self.innovation_covariance(j, l) * self.gain(2 * b, l))
                            .sum();
                        self.gain(2 * a, j) * ks
                    })
                    .sum();
            }
        }
        (correction, covariance)
    }
    /// [`AdaptiveNoise::observe`] on this update's `ν` and `S` with the stated noise `R`
    /// (row-major `m × m`; its length is checked by the caller).
    fn observe_noise(
        &self,
        adaptive: &AdaptiveNoise,
        scale: &NoiseScale,
        elapsed_s: f64,
        stated_noise: &[f64],
        gate: f64,
    ) -> rtls_estimation::Result<NoiseScale>;
}

impl<const N: usize> UpdateOutcome<N> for Updated<N> {
    fn state(&self) -> &Gaussian<N> {
        &self.state
    }

    fn into_state(self) -> Gaussian<N> {
        self.state
    }

    fn nis(&self) -> f64 {
        self.nis
    }

    fn log_det_innovation_covariance(&self) -> f64 {
        self.log_det_innovation_covariance
    }

    fn measurement_dim(&self) -> usize {
        Updated::measurement_dim(self)
    }

    fn innovation(&self, i: usize) -> f64 {
        self.innovation[i]
    }

    fn innovation_variance(&self, i: usize) -> f64 {
        self.innovation_covariance[(i, i)]
    }

    fn gain(&self, i: usize, j: usize) -> f64 {
        self.gain[(i, j)]
    }

    fn innovation_covariance(&self, i: usize, j: usize) -> f64 {
        self.innovation_covariance[(i, j)]
    }

    fn observe_noise(
        &self,
        adaptive: &AdaptiveNoise,
        scale: &NoiseScale,
        elapsed_s: f64,
        stated_noise: &[f64],
        gate: f64,
    ) -> rtls_estimation::Result<NoiseScale> {
        let m = self.innovation.len();
        let noise = DMatrix::from_row_slice(m, m, stated_noise);
        adaptive.observe(
            scale,
            elapsed_s,
            &self.innovation,
            &self.innovation_covariance,
            &noise,
            gate,
        )
    }
}

impl<const N: usize, const M: usize> UpdateOutcome<N> for FixedUpdated<N, M> {
    fn state(&self) -> &Gaussian<N> {
        &self.state
    }

    fn into_state(self) -> Gaussian<N> {
        self.state
    }

    fn nis(&self) -> f64 {
        self.nis
    }

    fn log_det_innovation_covariance(&self) -> f64 {
        self.log_det_innovation_covariance
    }

    fn measurement_dim(&self) -> usize {
        M
    }

    fn innovation(&self, i: usize) -> f64 {
        self.innovation[i]
    }

    fn innovation_variance(&self, i: usize) -> f64 {
        self.innovation_covariance[(i, i)]
    }

    fn gain(&self, i: usize, j: usize) -> f64 {
        self.gain[(i, j)]
    }

    fn innovation_covariance(&self, i: usize, j: usize) -> f64 {
        self.innovation_covariance[(i, j)]
    }

    fn observe_noise(
        &self,
        adaptive: &AdaptiveNoise,
        scale: &NoiseScale,
        elapsed_s: f64,
        stated_noise: &[f64],
        gate: f64,
    ) -> rtls_estimation::Result<NoiseScale> {
        let noise = SMatrix::<f64, M, M>::from_row_slice(stated_noise);
        adaptive.observe_fixed(
            scale,
            elapsed_s,
            &self.innovation,
            &self.innovation_covariance,
            &noise,
            gate,
        )
    }
}
