//! The posterior Cramér–Rao bound (PCRB): the smallest mean-square error any estimator can
//! reach on a scenario, computed with Tichavský's recursion.
//!
//! # Equations
//! For `x_{k+1} = F_k x_k + w_k`, `w_k ~ N(0, Q_k)`, and measurements `z_k ~ p(z | x_k)`,
//! Tichavský, Muravchik & Nehorai (1998) give the Fisher information recursion
//! `J_{k+1} = D²² − D²¹ (J_k + D¹¹)⁻¹ D¹²`, which for linear-Gaussian dynamics reduces to
//!
//! `J_{k+1} = (Q_k + F_k J_k⁻¹ F_kᵀ)⁻¹ + E[H_{k+1}ᵀ R⁻¹ H_{k+1}]`,
//!
//! where `H = ∂h/∂x` is the measurement Jacobian and the expectation is over the true state.
//! We run it in covariance form so that a singular `Q` (the CV model's noise gain) or a known
//! initial state (`P₀ = 0`) need no inverse of either:
//!
//! `B⁻ = F B Fᵀ + Q` (prediction of the bound), `B = B⁻ (I + J_z B⁻)⁻¹` (information added),
//!
//! with `B = J⁻¹` the bound on the error covariance and `J_z = E[Hᵀ R⁻¹ H]` the measurement
//! information (`(B⁻⁻¹ + J_z)⁻¹ = B⁻ (I + J_z B⁻)⁻¹` by the push-through identity). An epoch
//! without a measurement has `J_z = 0`. For a linear-Gaussian measurement the bound is exactly
//! the Kalman filter's covariance; for a nonlinear one `J_z` is averaged over the Monte Carlo
//! truths ([`mean_information`]), the standard estimate of the expectation.
//!
//! # Units
//! The state's units; `B` in those units squared.
//!
//! # References
//! P. Tichavský, C. H. Muravchik, A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time
//! nonlinear filtering", *IEEE Trans. Signal Processing* 46(5), 1998, eq. (21)–(23);
//! B. Ristic, S. Arulampalam, N. Gordon, *Beyond the Kalman Filter*, Artech House 2004, §4.2.

use nalgebra::{Cholesky, DMatrix};

use crate::error::{Result, SimError};

/// One step of the recursion: the dynamics from the previous epoch and the measurement
/// information at this epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct PcrbStep {
    /// `F_k` (`n × n`).
    pub transition: DMatrix<f64>,
    /// `Q_k` (`n × n`, symmetric positive semi-definite).
    pub process_noise: DMatrix<f64>,
    /// `J_z = E[Hᵀ R⁻¹ H]` at the new epoch (`n × n`; zeros when nothing is measured).
    pub measurement_information: DMatrix<f64>,
}

/// Runs the recursion from the prior covariance `prior_covariance` (`P₀`, the initial-state
/// uncertainty the trackers are given) through `steps`, returning the bound `B_k` after each.
///
/// # Errors
/// [`SimError::LengthMismatch`] for a matrix of the wrong size; [`SimError::NonFinite`] for a
/// NaN/∞ entry; [`SimError::InvalidParameter`] (`steps`) if `I + J_z B⁻` is singular (a
/// negative-definite information matrix).
///
/// # Example
/// A random walk `x_{k+1} = x_k + w`, `Q = q`, observed directly with variance `r`: the bound is
/// the scalar Kalman filter's variance, `b⁻ = b + q`, `b = b⁻ r/(b⁻ + r)`.
/// ```
/// use nalgebra::DMatrix;
/// use rtls_sim::pcrb::{posterior_crb, PcrbStep};
/// let (q, r) = (0.5, 2.0);
/// let step = PcrbStep {
///     transition: DMatrix::from_element(1, 1, 1.0),
///     process_noise: DMatrix::from_element(1, 1, q),
///     measurement_information: DMatrix::from_element(1, 1, 1.0 / r),
/// };
/// let bounds = posterior_crb(&DMatrix::from_element(1, 1, 10.0), vec![step; 50])?;
/// let steady = (-q + (q * q + 4.0 * q * r).sqrt()) / 2.0; // b² + q b − q r = 0
/// assert!((bounds[49][(0, 0)] - steady).abs() < 1e-9);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn posterior_crb(
    prior_covariance: &DMatrix<f64>,
    steps: impl IntoIterator<Item = PcrbStep>,
) -> Result<Vec<DMatrix<f64>>> {
    let n = prior_covariance.nrows();
    check_square(prior_covariance, n, "PCRB prior covariance")?;
    let identity = DMatrix::<f64>::identity(n, n);
    let mut bound = prior_covariance.clone();
    let mut bounds = Vec::new();
    for step in steps {
        check_square(&step.transition, n, "PCRB transition")?;
        check_square(&step.process_noise, n, "PCRB process noise")?;
        check_square(&step.measurement_information, n, "PCRB measurement information")?;
        // B⁻ = F B Fᵀ + Q
        let predicted = &step.transition * &bound * step.transition.transpose() + &step.process_noise;
        // B = B⁻ (I + J_z B⁻)⁻¹
        let gain_inverse = (&identity + &step.measurement_information * &predicted)
            .try_inverse()
            .ok_or(SimError::InvalidParameter {
                name: "steps",
                reason: "I + J_z B⁻ is singular: the measurement information must be positive semi-definite",
            })?;
        let updated = &predicted * gain_inverse;
        // symmetrise against rounding: B = (B + Bᵀ)/2
        bound = (&updated + updated.transpose()) * 0.5;
        bounds.push(bound.clone());
    }
    Ok(bounds)
}

/// Measurement information `Hᵀ R⁻¹ H` of one measurement with Jacobian `h` (`m × n`) and noise
/// covariance `r` (`m × m`).
///
/// # Errors
/// [`SimError::LengthMismatch`] if the sizes disagree; [`SimError::InvalidParameter`] (`r`)
/// if `r` is not positive definite; [`SimError::NonFinite`] for NaN/∞ entries.
///
/// # Example
/// A range to an anchor at the origin from `(3, 4)` with σ = 0.1 m informs only the radial
/// direction `u = (0.6, 0.8)`: `J = u uᵀ/σ²`.
/// ```
/// use nalgebra::DMatrix;
/// let h = DMatrix::from_row_slice(1, 2, &[0.6, 0.8]);
/// let j = rtls_sim::pcrb::measurement_information(&h, &DMatrix::from_element(1, 1, 0.01))?;
/// assert!((j[(0, 1)] - 48.0).abs() < 1e-9);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn measurement_information(h: &DMatrix<f64>, r: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    check_square(r, h.nrows(), "measurement noise covariance")?;
    if h.iter().any(|v| !v.is_finite()) {
        return Err(SimError::NonFinite {
            what: "measurement Jacobian",
        });
    }
    let cholesky = Cholesky::new(r.clone()).ok_or(SimError::InvalidParameter {
        name: "r",
        reason: "the measurement noise covariance must be symmetric positive definite",
    })?;
    // J = Hᵀ R⁻¹ H
    Ok(h.transpose() * cholesky.solve(h))
}

/// `E[J_z]` estimated by the mean over Monte Carlo runs: `information[run][epoch]` → mean per
/// epoch, for nonlinear measurements whose information depends on the true state.
///
/// # Errors
/// [`SimError::EmptyInput`] for no runs; [`SimError::LengthMismatch`] if runs have different
/// lengths or matrix sizes.
///
/// # Example
/// ```
/// use nalgebra::DMatrix;
/// let runs = vec![vec![DMatrix::from_element(1, 1, 1.0)], vec![DMatrix::from_element(1, 1, 3.0)]];
/// assert_eq!(rtls_sim::pcrb::mean_information(&runs)?[0][(0, 0)], 2.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn mean_information(information: &[Vec<DMatrix<f64>>]) -> Result<Vec<DMatrix<f64>>> {
    let first = information.first().ok_or(SimError::EmptyInput {
        what: "measurement information runs",
    })?;
    let mut mean = first.clone();
    for run in &information[1..] {
        if run.len() != mean.len() {
            return Err(SimError::LengthMismatch {
                what: "epochs of the measurement information runs",
                expected: mean.len(),
                found: run.len(),
            });
        }
        for (sum, j) in mean.iter_mut().zip(run) {
            check_square(j, sum.nrows(), "measurement information")?;
            *sum += j;
        }
    }
    let scale = 1.0 / information.len() as f64;
    for sum in &mut mean {
        *sum *= scale;
    }
    Ok(mean)
}

/// `√(Σ_{i ∈ indices} B_ii)`: the bound on the RMSE of the components `indices` (e.g. the
/// position `[0, 2]` of a `[x, vx, y, vy]` state) given the error-covariance bound `bound`.
///
/// # Errors
/// [`SimError::InvalidParameter`] (`indices`) for an index outside the matrix.
///
/// # Example
/// ```
/// use nalgebra::DMatrix;
/// let b = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![0.09, 1.0, 0.16, 1.0]));
/// assert!((rtls_sim::pcrb::rmse_bound(&b, &[0, 2])? - 0.5).abs() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn rmse_bound(bound: &DMatrix<f64>, indices: &[usize]) -> Result<f64> {
    let mut sum = 0.0;
    for &i in indices {
        if i >= bound.nrows() || i >= bound.ncols() {
            return Err(SimError::InvalidParameter {
                name: "indices",
                reason: "an index is outside the bound matrix",
            });
        }
        sum += bound[(i, i)];
    }
    Ok(sum.max(0.0).sqrt())
}

/// The RMSE bound over a whole run, `√((1/K) Σ_k Σ_{i ∈ indices} B_k,ii)`: the figure to set
/// beside a tracker's RMSE pooled over all epochs.
///
/// # Errors
/// [`SimError::EmptyInput`] for no bounds; as [`rmse_bound`].
pub fn pooled_rmse_bound(bounds: &[DMatrix<f64>], indices: &[usize]) -> Result<f64> {
    if bounds.is_empty() {
        return Err(SimError::EmptyInput { what: "PCRB bounds" });
    }
    let mut sum = 0.0;
    for bound in bounds {
        sum += rmse_bound(bound, indices)?.powi(2);
    }
    Ok((sum / bounds.len() as f64).sqrt())
}

fn check_square(matrix: &DMatrix<f64>, n: usize, what: &'static str) -> Result<()> {
    if matrix.nrows() != n || matrix.ncols() != n {
        return Err(SimError::LengthMismatch {
            what,
            expected: n,
            found: if matrix.nrows() != n {
                matrix.nrows()
            } else {
                matrix.ncols()
            },
        });
    }
    if matrix.iter().any(|v| !v.is_finite()) {
        return Err(SimError::NonFinite { what });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DVector, Matrix4, Vector4};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use rtls_estimation::filter::KalmanFilter;
    use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, ProcessNoise};
    use rtls_estimation::Gaussian;

    /// For a linear-Gaussian model the PCRB is the Kalman filter's covariance, step by step.
    #[test]
    fn linear_gaussian_bound_equals_the_kalman_covariance() {
        let model = ConstantVelocity::new(ProcessNoise::discrete(
            0.3,
            rtls_estimation::motion::NoiseGain::kinematic(),
        ))
        .unwrap();
        let h = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 0.25).unwrap()).unwrap();
        let p0 = Matrix4::from_diagonal(&Vector4::new(4.0, 1.0, 4.0, 1.0));
        let hm = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        let j = measurement_information(&hm, &(DMatrix::identity(2, 2) * 0.25)).unwrap();
        let step = PcrbStep {
            transition: DMatrix::from_column_slice(
                4,
                4,
                LinearMotionModel::<4>::transition_matrix(&model, 1.0).as_slice(),
            ),
            process_noise: DMatrix::from_column_slice(
                4,
                4,
                LinearMotionModel::<4>::process_noise_matrix(&model, 1.0).as_slice(),
            ),
            measurement_information: j,
        };
        let bounds = posterior_crb(&DMatrix::from_column_slice(4, 4, p0.as_slice()), vec![step; 20]).unwrap();
        let kf = KalmanFilter::default();
        let mut state = Gaussian::new(Vector4::zeros(), p0, 0.0).unwrap();
        for (k, bound) in bounds.iter().enumerate() {
            let prior = kf.predict(&state, &model, (k + 1) as f64).unwrap();
            state = kf.update(&prior, &h, &DVector::from_vec(vec![0.0, 0.0])).unwrap().state;
            let difference = (DMatrix::from_column_slice(4, 4, state.covariance().as_slice()) - bound)
                .abs()
                .max();
            assert!(difference < 1e-10, "epoch {k}: {difference}");
        }
    }

    /// The bound holds: the Monte Carlo MSE of the optimal (Kalman) filter on data generated by
    /// the model is at the bound, and a deliberately mistuned filter is above it.
    #[test]
    fn kalman_mse_meets_the_bound_and_a_mistuned_filter_exceeds_it() {
        let (q, r) = (0.2, 1.0);
        let step = PcrbStep {
            transition: DMatrix::from_element(1, 1, 1.0),
            process_noise: DMatrix::from_element(1, 1, q),
            measurement_information: DMatrix::from_element(1, 1, 1.0 / r),
        };
        let bound = posterior_crb(&DMatrix::from_element(1, 1, 1.0), vec![step; 30]).unwrap()[29][(0, 0)];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (w, v, x0) = (
            Normal::new(0.0, q.sqrt()).unwrap(),
            Normal::new(0.0, r.sqrt()).unwrap(),
            Normal::new(0.0, 1.0).unwrap(),
        );
        let (mut optimal, mut mistuned) = (0.0, 0.0);
        let runs = 4000;
        for _ in 0..runs {
            let mut x: f64 = x0.sample(&mut rng);
            let (mut m1, mut p1, mut m2, mut p2) = (0.0, 1.0, 0.0, 1.0);
            for _ in 0..30 {
                x += w.sample(&mut rng);
                let z = x + v.sample(&mut rng);
                for (m, p, qf) in [(&mut m1, &mut p1, q), (&mut m2, &mut p2, 0.01 * q)] {
                    *p += qf;
                    let k = *p / (*p + r);
                    *m += k * (z - *m);
                    *p *= 1.0 - k;
                }
            }
            optimal += (m1 - x).powi(2);
            mistuned += (m2 - x).powi(2);
        }
        let (optimal, mistuned) = (optimal / runs as f64, mistuned / runs as f64);
        assert!(
            (optimal / bound - 1.0).abs() < 0.08,
            "optimal {optimal} vs bound {bound}"
        );
        assert!(mistuned > 1.5 * bound, "mistuned {mistuned} vs bound {bound}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let ok = DMatrix::identity(2, 2);
        let bad_step = PcrbStep {
            transition: DMatrix::identity(3, 3),
            process_noise: ok.clone(),
            measurement_information: ok.clone(),
        };
        assert!(matches!(
            posterior_crb(&ok, vec![bad_step]),
            Err(SimError::LengthMismatch { .. })
        ));
        let negative = PcrbStep {
            transition: ok.clone(),
            process_noise: DMatrix::zeros(2, 2),
            measurement_information: -ok.clone(),
        };
        assert!(posterior_crb(&ok, vec![negative]).is_err());
        assert!(measurement_information(&DMatrix::zeros(1, 2), &DMatrix::from_element(1, 1, -1.0)).is_err());
        assert!(rmse_bound(&ok, &[2]).is_err());
        assert!(mean_information(&[]).is_err());
    }
}
