//! The measurement-update kernels shared by the KF and the EKF (batch and one component at a
//! time), and the update result type.

use nalgebra::{Const, DMatrix, DVector, Dyn, OMatrix};

use crate::error::{EstimationError, Result};
use crate::gaussian::{Gaussian, Matrix};
use crate::measurement::{MeasurementJacobian, MeasurementModel};

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
/// - `log_det_innovation_covariance`: `ln |S|`, from the same Cholesky factor; with the NIS it
///   gives the measurement log-likelihood ([`Updated::log_likelihood`]) an IMM weighs modes by.
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
    /// `ln |S|` (natural logarithm of the determinant of the innovation covariance).
    pub log_det_innovation_covariance: f64,
}

impl<const N: usize> Updated<N> {
    /// Number of measurement components `m` (the degrees of freedom of the NIS).
    #[must_use]
    pub fn measurement_dim(&self) -> usize {
        self.innovation.len()
    }

    /// Gaussian log-likelihood of the measurement under the prior:
    /// `ln N(ν; 0, S) = −½ (νᵀ S⁻¹ ν + ln |S| + m ln 2π)`.
    ///
    /// This is the mode likelihood `Λⱼ` of an interacting multiple model filter, kept in the
    /// log domain so that very unlikely modes do not underflow to 0.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::filter::KalmanFilter;
    /// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// use nalgebra::DVector;
    /// let fix = ComponentSelection::<2>::new(&[0], NoiseCovariance::isotropic(1, 1.0)?)?;
    /// let prior = Gaussian::new(Vector::<2>::zeros(), Matrix::<2>::identity(), 0.0)?;
    /// // S = 1 + 1 = 2, ν = 0: ln N(0; 0, 2) = −½ ln(2π·2)
    /// let up = KalmanFilter::default().update(&prior, &fix, &DVector::from_vec(vec![0.0]))?;
    /// assert!((up.log_likelihood() + 0.5 * (4.0 * std::f64::consts::PI).ln()).abs() < 1e-12);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Bar-Shalom, Li, Kirubarajan (2001), eq. (11.6.6-8) (mode-matched likelihood).
    #[must_use]
    pub fn log_likelihood(&self) -> f64 {
        // −½ (νᵀ S⁻¹ ν + ln |S| + m ln 2π)
        let m = self.measurement_dim() as f64;
        -0.5 * (self.nis + self.log_det_innovation_covariance + m * crate::math::ln(core::f64::consts::TAU))
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

/// The gain and NIS of an update, solved from `S` by one Cholesky factorisation.
pub(crate) struct GainSolution<const N: usize> {
    /// `K` (`N × m`).
    pub(crate) gain: Gain<N>,
    /// `Kᵀ` (`m × N`), kept because the covariance updates need it too.
    pub(crate) gain_t: MeasurementJacobian<N>,
    /// `νᵀ S⁻¹ ν`.
    pub(crate) nis: f64,
    /// `ln |S| = 2 Σ ln Lᵢᵢ`.
    pub(crate) log_det: f64,
}

/// Solves the gain and NIS shared by every Kalman update, given the innovation covariance `S`,
/// the state–measurement cross-covariance `C` (`P⁻ Hᵀ` for the KF/EKF, the sigma-point `Pxz`
/// for the UKF) and the innovation `ν`:
/// ```text
/// S = L Lᵀ
/// Kᵀ = S⁻¹ Cᵀ        ⇔   K = C S⁻¹   (S symmetric)
/// NIS = νᵀ S⁻¹ ν = |L⁻¹ ν|²
/// ln |S| = 2 Σ ln Lᵢᵢ
/// ```
///
/// # Errors
/// [`EstimationError::InnovationNotPositiveDefinite`] if `S` cannot be factorised;
/// [`EstimationError::NonFinite`] if the NIS is not finite.
pub(crate) fn solve_gain<const N: usize>(
    s: &DMatrix<f64>,
    cross_covariance: &Gain<N>,
    innovation: &DVector<f64>,
) -> Result<GainSolution<N>> {
    // S = L Lᵀ
    let chol = s
        .clone()
        .cholesky()
        .ok_or(EstimationError::InnovationNotPositiveDefinite)?;
    // Kᵀ = S⁻¹ Cᵀ
    let mut gain_t = cross_covariance.transpose();
    chol.solve_mut(&mut gain_t);
    // NIS = |L⁻¹ ν|²
    let nis = chol
        .l_dirty()
        .solve_lower_triangular(innovation)
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
    Ok(GainSolution {
        gain: gain_t.transpose(),
        gain_t,
        nis,
        log_det,
    })
}

/// `P⁻ Hᵀ` and `S = H P⁻ Hᵀ + R` of a linearised update.
pub(crate) fn linearized_innovation_covariance<const N: usize>(
    prior: &Gaussian<N>,
    h: &MeasurementJacobian<N>,
    r: &DMatrix<f64>,
) -> (Gain<N>, DMatrix<f64>) {
    // P Hᵀ  (N × m)
    let pht: Gain<N> = prior.covariance() * h.transpose();
    // S = H P Hᵀ + R
    let s = h * &pht + r;
    (pht, s)
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
    let (pht, s) = linearized_innovation_covariance(prior, h, r);
    let GainSolution {
        gain,
        gain_t,
        nis,
        log_det,
    } = solve_gain(&s, &pht, &innovation)?;
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
    Ok(Updated {
        state,
        innovation,
        innovation_covariance: s,
        gain,
        nis,
        log_det_innovation_covariance: log_det,
    })
}

/// Scalar-at-a-time update, re-linearising before each component.
pub(crate) fn sequential_update<const N: usize, H: MeasurementModel<N>>(
    prior: &Gaussian<N>,
    model: &H,
    z: &DVector<f64>,
    form: CovarianceUpdate,
) -> Result<Updated<N>> {
    let m = model.dim();
    check_measurement(z, m)?;
    let r = model.noise_covariance();
    let h0 = model.jacobian(prior.mean())?;
    check_model_shapes(&h0, r, m)?;
    for i in 0..m {
        for j in 0..m {
            if i != j && r[(i, j)] != 0.0 {
                return Err(EstimationError::CorrelatedNoise);
            }
        }
    }
    // Batch quantities at the prior, for gating and NIS: ν, S = H P Hᵀ + R, K, νᵀ S⁻¹ ν.
    let innovation = model.residual(z, &model.predict(prior.mean())?);
    let (pht, innovation_covariance) = linearized_innovation_covariance(prior, &h0, r);
    let GainSolution { gain, nis, log_det, .. } = solve_gain(&innovation_covariance, &pht, &innovation)?;
    let mut state = *prior;
    for i in 0..m {
        // hᵢ(x), Hᵢ = ∂hᵢ/∂x at the current estimate
        let predicted = model.predict(state.mean())?;
        let h_row = model.jacobian(state.mean())?.rows(i, 1).into_owned();
        // νᵢ = zᵢ − hᵢ(x)   (through the model's residual, so angles wrap)
        let nu = model.residual(z, &predicted)[i];
        let r_i = DMatrix::from_element(1, 1, r[(i, i)]);
        state = linearized_update(&state, DVector::from_element(1, nu), &h_row, &r_i, form)?.state;
    }
    Ok(Updated {
        state,
        innovation,
        innovation_covariance,
        gain,
        nis,
        log_det_innovation_covariance: log_det,
    })
}
