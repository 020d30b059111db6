//! The measurement-update kernel shared by the KF and the EKF, and the update result type.

use nalgebra::{Const, DMatrix, DVector, Dyn, OMatrix};

use crate::error::{EstimationError, Result};
use crate::gaussian::{Gaussian, Matrix};
use crate::measurement::MeasurementJacobian;

/// Kalman gain `K` (`N × m`).
pub type Gain<const N: usize> = OMatrix<f64, Const<N>, Dyn>;

/// Which algebraic form the KF/EKF uses for the posterior covariance.
///
/// Both are equal in exact arithmetic. The Joseph form keeps `P` symmetric positive
/// semi-definite under rounding and for any (even suboptimal) gain, so it is the default.
///
/// # References
/// Bucy & Joseph (1968); Bar-Shalom, Li, Kirubarajan (2001) eq. (5.2.3-18); seed 000 eq. (20)
/// prints the simple form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CovarianceUpdate {
    /// `P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`.
    #[default]
    Joseph,
    /// `P = (I − K H) P⁻` (seed 000 eq. (20)); cheaper, less robust to rounding.
    Simple,
}

/// The result of a measurement update: the posterior and the quantities that produced it.
///
/// # Fields
/// - `state`: the posterior `N(x̂, P)`.
/// - `innovation`: `ν = z − ẑ` (angle components wrapped by the model's residual).
/// - `innovation_covariance`: `S` (`m × m`).
/// - `gain`: `K` (`N × m`).
/// - `nis`: normalised innovation squared `νᵀ S⁻¹ ν`, `χ²(m)` under the model; compare it
///   with a [`crate::stats::ChiSquareGate`] to gate, or average it for a consistency test.
#[derive(Debug, Clone, PartialEq)]
pub struct Updated<const N: usize> {
    /// The posterior state.
    pub state: Gaussian<N>,
    /// Innovation `ν = z − ẑ`.
    pub innovation: DVector<f64>,
    /// Innovation covariance `S`.
    pub innovation_covariance: DMatrix<f64>,
    /// Kalman gain `K`.
    pub gain: Gain<N>,
    /// Normalised innovation squared `νᵀ S⁻¹ ν`.
    pub nis: f64,
}

impl<const N: usize> Updated<N> {
    /// Number of measurement components `m` (the degrees of freedom of the NIS).
    #[must_use]
    pub fn measurement_dim(&self) -> usize {
        self.innovation.len()
    }
}

/// Checks a measurement vector against the model's size and for finiteness.
pub(crate) fn check_measurement(z: &DVector<f64>, expected: usize) -> Result<()> {
    if z.len() != expected {
        return Err(EstimationError::DimensionMismatch {
            what: "measurement vector",
            expected,
            found: z.len(),
        });
    }
    crate::math::ensure_finite(z, "measurement vector")
}

/// Checks a model's Jacobian and noise sizes.
pub(crate) fn check_model_shapes<const N: usize>(h: &MeasurementJacobian<N>, r: &DMatrix<f64>, m: usize) -> Result<()> {
    if h.nrows() != m {
        return Err(EstimationError::DimensionMismatch {
            what: "measurement jacobian rows",
            expected: m,
            found: h.nrows(),
        });
    }
    if r.nrows() != m || r.ncols() != m {
        return Err(EstimationError::DimensionMismatch {
            what: "measurement noise covariance",
            expected: m,
            found: r.nrows(),
        });
    }
    Ok(())
}

/// Linearised Kalman update given `ν`, `H` and `R` at the prior `state`.
///
/// ```text
/// S = H P⁻ Hᵀ + R
/// K = P⁻ Hᵀ S⁻¹
/// x̂ = x⁻ + K ν
/// P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ      (Joseph)   or   (I − K H) P⁻   (simple)
/// ```
pub(crate) fn linearized_update<const N: usize>(
    prior: &Gaussian<N>,
    innovation: DVector<f64>,
    h: &MeasurementJacobian<N>,
    r: &DMatrix<f64>,
    form: CovarianceUpdate,
) -> Result<Updated<N>> {
    let p = prior.covariance();
    // P Hᵀ  (N × m)
    let pht: Gain<N> = p * h.transpose();
    // S = H P Hᵀ + R
    let s: DMatrix<f64> = h * &pht + r;
    // S = L Lᵀ
    let chol = s
        .clone()
        .cholesky()
        .ok_or(EstimationError::InnovationNotPositiveDefinite)?;
    // Kᵀ = S⁻¹ (P Hᵀ)ᵀ   ⇒   K = P Hᵀ S⁻¹   (S symmetric)
    let mut gain_t = pht.transpose();
    chol.solve_mut(&mut gain_t);
    let gain: Gain<N> = gain_t.transpose();
    // NIS = νᵀ S⁻¹ ν = |L⁻¹ ν|²
    let whitened = chol
        .l_dirty()
        .solve_lower_triangular(&innovation)
        .ok_or(EstimationError::InnovationNotPositiveDefinite)?;
    let nis = whitened.norm_squared();
    // x̂ = x⁻ + K ν
    let mean = prior.mean() + &gain * &innovation;
    // I − K H
    let i_kh: Matrix<N> = Matrix::<N>::identity() - &gain * h;
    let covariance = match form {
        // P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ
        CovarianceUpdate::Joseph => i_kh * p * i_kh.transpose() + (&gain * r) * &gain_t,
        // P = (I − K H) P⁻
        CovarianceUpdate::Simple => i_kh * p,
    };
    let state = Gaussian::from_step(mean, covariance, prior.time_s(), "posterior state")?;
    if !nis.is_finite() {
        return Err(EstimationError::NonFinite {
            what: "normalised innovation squared",
        });
    }
    Ok(Updated {
        state,
        innovation,
        innovation_covariance: s,
        gain,
        nis,
    })
}
