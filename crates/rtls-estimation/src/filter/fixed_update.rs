//! The linear update of selected state components with fixed sizes (a position fix of a
//! constant-velocity track): [`KalmanFilter::update`] for a [`FixedSelection`], with `S`,
//! its Cholesky factor and `K` on the stack and `H` never formed.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::kf::KalmanFilter;
use super::update::{CovarianceUpdate, Gain, Updated};
use crate::error::{EstimationError, Result};
use crate::gaussian::{Gaussian, Matrix};
use crate::measurement::FixedSelection;

/// The result of [`KalmanFilter::update_fixed`]: [`Updated`] with fixed sizes.
///
/// # Fields
/// As [`Updated`]: the posterior, `ν` (`M`), `S` (`M × M`), `K` (`N × M`), the NIS
/// `νᵀ S⁻¹ ν` and `ln |S|`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedUpdated<const N: usize, const M: usize> {
    /// The posterior state.
    pub state: Gaussian<N>,
    /// Innovation `ν = z − H x⁻`.
    pub innovation: SVector<f64, M>,
    /// Innovation covariance `S = H P⁻ Hᵀ + R`.
    pub innovation_covariance: SMatrix<f64, M, M>,
    /// Kalman gain `K = P⁻ Hᵀ S⁻¹`.
    pub gain: SMatrix<f64, N, M>,
    /// Normalised innovation squared `νᵀ S⁻¹ ν`.
    pub nis: f64,
    /// `ln |S|`.
    pub log_det_innovation_covariance: f64,
}

impl<const N: usize, const M: usize> FixedUpdated<N, M> {
    /// The same update as an [`Updated`] (heap-allocated `ν`, `S`, `K`), for code written
    /// against the general result.
    #[must_use]
    pub fn to_updated(&self) -> Updated<N> {
        Updated {
            state: self.state,
            innovation: DVector::from_column_slice(self.innovation.as_slice()),
            innovation_covariance: DMatrix::from_column_slice(M, M, self.innovation_covariance.as_slice()),
            gain: Gain::<N>::from_column_slice(self.gain.as_slice()),
            nis: self.nis,
            log_det_innovation_covariance: self.log_det_innovation_covariance,
        }
    }
}

impl KalmanFilter {
    /// Updates a predicted state with a measurement `z` of selected components, with fixed
    /// sizes and no heap allocation; equal to [`KalmanFilter::update`] with the
    /// [`ComponentSelection`](crate::measurement::ComponentSelection) of the same indices and
    /// noise (tested to 1e-12 relative).
    ///
    /// ```text
    /// ν = z − H x⁻               (the selected components of x⁻)
    /// S = H P⁻ Hᵀ + R            (the selected rows and columns of P⁻)
    /// K = P⁻ Hᵀ S⁻¹              (S = L Lᵀ)
    /// x̂ = x⁻ + K ν
    /// P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ     (Joseph)   or   (I − K H) P⁻   (simple)
    /// ```
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for NaN/∞ in `z` or the result;
    /// [`EstimationError::InnovationNotPositiveDefinite`] if `S` cannot be factorised.
    ///
    /// # Example
    /// ```
    /// use nalgebra::{Matrix2, Vector2};
    /// use rtls_estimation::filter::KalmanFilter;
    /// use rtls_estimation::measurement::FixedSelection;
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// let fix = FixedSelection::<4, 2>::new([0, 2], Matrix2::identity() * 0.04)?;
    /// let prior = Gaussian::new(Vector::<4>::new(15.0, 0.0, 15.0, 0.0), Matrix::<4>::identity(), 0.0)?;
    /// let updated = KalmanFilter::default().update_fixed(&prior, &fix, &Vector2::new(15.1, 14.9))?;
    /// assert!(updated.state.covariance()[(0, 0)] < 0.04);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn update_fixed<const N: usize, const M: usize>(
        &self,
        prior: &Gaussian<N>,
        model: &FixedSelection<N, M>,
        z: &SVector<f64, M>,
    ) -> Result<FixedUpdated<N, M>> {
        if z.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "measurement vector",
            });
        }
        let (p, r, indices) = (prior.covariance(), model.noise(), model.indices());
        // ν = z − H x⁻
        let innovation = z - model.predict(prior.mean());
        // P⁻ Hᵀ: the selected columns of P⁻  (N × M)
        let pht = SMatrix::<f64, N, M>::from_fn(|i, c| p[(i, indices[c])]);
        // S = H P⁻ Hᵀ + R: the selected rows of P⁻ Hᵀ, plus R
        let s = SMatrix::<f64, M, M>::from_fn(|r_, c| pht[(indices[r_], c)]) + r;
        // S = L Lᵀ
        let chol = s.cholesky().ok_or(EstimationError::InnovationNotPositiveDefinite)?;
        // Kᵀ = S⁻¹ (P⁻ Hᵀ)ᵀ
        let gain_t = chol.solve(&pht.transpose());
        let gain = gain_t.transpose();
        // NIS = |L⁻¹ ν|²
        let nis = chol
            .l_dirty()
            .solve_lower_triangular(&innovation)
            .ok_or(EstimationError::InnovationNotPositiveDefinite)?
            .norm_squared();
        if !nis.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "normalised innovation squared",
            });
        }
        // ln |S| = 2 Σ ln Lᵢᵢ
        let log_det = 2.0
            * chol
                .l_dirty()
                .diagonal()
                .iter()
                .map(|&l| crate::math::ln(l))
                .sum::<f64>();
        // x̂ = x⁻ + K ν
        let mean = prior.mean() + gain * innovation;
        // I − K H: the identity less K's columns in the selected columns
        let mut i_kh = Matrix::<N>::identity();
        for (c, &j) in indices.iter().enumerate() {
            for i in 0..N {
                i_kh[(i, j)] -= gain[(i, c)];
            }
        }
        let covariance = match self.covariance_update {
            // P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ
            CovarianceUpdate::Joseph => i_kh * p * i_kh.transpose() + (gain * r) * gain_t,
            // P = (I − K H) P⁻
            CovarianceUpdate::Simple => i_kh * p,
        };
        let state = Gaussian::from_step(mean, covariance, prior.time_s(), "posterior state")?;
        Ok(FixedUpdated {
            state,
            innovation,
            innovation_covariance: s,
            gain,
            nis,
            log_det_innovation_covariance: log_det,
        })
    }
}
