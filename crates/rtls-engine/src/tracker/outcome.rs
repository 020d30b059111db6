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
