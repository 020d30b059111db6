//! The Schmidt–Kalman ("consider") update: a measurement whose error contains a parameter `p`
//! another filter estimates (a heading channel's heading error, an anchor's offset), taken into
//! account without estimating `p` here.
//!
//! The measurement and the errors (`e = estimate − truth`):
//! ```text
//! z = H x + J p + w,   w ~ N(0, R),   p̂ = 0 here: p is the other filter's error
//! ν = z − H x⁻ = −H eₓ − J eₚ + w
//! X = cov(eₓ, eₚ)  (N × M),   Pₚ = cov(eₚ)  (M × M)
//! S = H P Hᵀ + H X Jᵀ + J Xᵀ Hᵀ + J Pₚ Jᵀ + R
//! K = (P Hᵀ + X Jᵀ) S⁻¹
//! x̂ = x⁻ + K ν
//! A = I − K H
//! P = A P Aᵀ − A X Jᵀ Kᵀ − K J Xᵀ Aᵀ + K (J Pₚ Jᵀ + R) Kᵀ   (Joseph form: cov of A eₓ − K J eₚ + K w)
//! X ← A X − K J Pₚ                                            (p itself is not updated)
//! ```
//! `P` stays the covariance of the state's actual error even though `p` persists from one
//! measurement to the next: a filter that took `J Pₚ Jᵀ` as fresh noise of each measurement
//! would average a shared error away and report a covariance far too small.
//!
//! Every other update of the state carries the cross-covariance: after a prediction
//! `X ← F X`, after a Kalman update `X ← (I − K H) X = P⁺ (P⁻)⁻¹ X`
//! ([`carry_cross_covariance`]), and when the other filter predicts or updates `p`,
//! `X ← X Φₚᵀ` or `X ← X (Pₚ⁺ (Pₚ⁻)⁻¹)ᵀ`.
//!
//! # References
//! Schmidt (1966), "Application of state-space methods to navigation problems"; Simon (2006),
//! *Optimal State Estimation* §7.5 (the Schmidt–Kalman filter); Brown & Hwang (2012) §9.2.

use nalgebra::{DMatrix, DVector, SMatrix};

use super::update::{solve_gain, GainSolution, Updated};
use crate::error::{EstimationError, Result};
use crate::measurement::MeasurementJacobian;
use crate::{Gaussian, Matrix};

/// The result of a [`consider_update`]: the updated state and the new cross-covariance `X`.
#[derive(Debug, Clone)]
pub struct ConsiderUpdated<const N: usize, const M: usize> {
    /// The posterior state, innovation, `S`, gain and NIS.
    pub updated: Updated<N>,
    /// `X = cov(eₓ, eₚ)` after the update.
    pub cross_covariance: SMatrix<f64, N, M>,
}

/// One Schmidt–Kalman update with innovation `ν = z − H x⁻`: for `z = H x + J p + w`, with
/// `X = cov(eₓ, eₚ)` and `Pₚ = cov(eₚ)`,
/// ```text
/// S = H P Hᵀ + H X Jᵀ + J Xᵀ Hᵀ + J Pₚ Jᵀ + R,   K = (P Hᵀ + X Jᵀ) S⁻¹,   x̂ = x⁻ + K ν
/// A = I − K H,   P = A P Aᵀ − A X Jᵀ Kᵀ − K J Xᵀ Aᵀ + K (J Pₚ Jᵀ + R) Kᵀ,   X ← A X − K J Pₚ
/// ```
/// (`p` itself is not updated; after other updates carry `X` with
/// [`carry_cross_covariance`]).
///
/// `h` is `m × N`, `j` is `m × M` (how the parameter enters the measurement), `r` is `m × m`.
///
/// # Errors
/// [`EstimationError::DimensionMismatch`] for inconsistent shapes;
/// [`EstimationError::InnovationNotPositiveDefinite`] when `S` cannot be factorised;
/// [`EstimationError::NonFinite`] for a non-finite result.
///
/// # Example
/// ```
/// use nalgebra::{DMatrix, DVector, Matrix2, SMatrix, Vector2};
/// use rtls_estimation::filter::consider_update;
/// use rtls_estimation::measurement::MeasurementJacobian;
/// use rtls_estimation::Gaussian;
/// // a scalar-position state x = [p, v]; z = v + p_bias + w, the bias known to 0.5 m/s
/// let prior = Gaussian::new(Vector2::new(0.0, 1.0), Matrix2::identity(), 0.0)?;
/// let h = MeasurementJacobian::<2>::from_row_slice(&[0.0, 1.0]);
/// let j = DMatrix::from_row_slice(1, 1, &[1.0]);
/// let r = DMatrix::from_row_slice(1, 1, &[0.01]);
/// let consider = SMatrix::<f64, 1, 1>::new(0.25);
/// let no_cross = SMatrix::<f64, 2, 1>::zeros();
/// let result = consider_update(&prior, &no_cross, &consider, &h, &j, &r, DVector::from_element(1, 0.5))?;
/// // S = 1 + 0.25 + 0.01: the bias's variance is part of the innovation covariance
/// assert!((result.updated.innovation_covariance[(0, 0)] - 1.26).abs() < 1e-12);
/// // the velocity's error now shares the bias: X = −K J Pₚ ≠ 0
/// assert!(result.cross_covariance[(1, 0)] < 0.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
pub fn consider_update<const N: usize, const M: usize>(
    prior: &Gaussian<N>,
    cross_covariance: &SMatrix<f64, N, M>,
    consider_covariance: &SMatrix<f64, M, M>,
    h: &MeasurementJacobian<N>,
    j: &DMatrix<f64>,
    r: &DMatrix<f64>,
    innovation: DVector<f64>,
) -> Result<ConsiderUpdated<N, M>> {
    let m = innovation.len();
    for (what, found) in [
        ("measurement Jacobian rows", h.nrows()),
        ("consider Jacobian rows", j.nrows()),
        ("measurement noise rows", r.nrows()),
        ("measurement noise columns", r.ncols()),
    ] {
        if found != m {
            return Err(EstimationError::DimensionMismatch {
                what,
                expected: m,
                found,
            });
        }
    }
    if j.ncols() != M {
        return Err(EstimationError::DimensionMismatch {
            what: "consider Jacobian columns",
            expected: M,
            found: j.ncols(),
        });
    }
    let p = prior.covariance();
    let x = cross_covariance;
    // X Jᵀ  (N × m),  J Pₚ  (m × M)
    let xjt = x * j.transpose();
    let jpp = j * consider_covariance;
    // P Hᵀ + X Jᵀ: the state's cross-covariance with −ν
    let cross = p * h.transpose() + &xjt;
    // S = H P Hᵀ + H X Jᵀ + J Xᵀ Hᵀ + J Pₚ Jᵀ + R
    let hxjt = h * &xjt;
    let s = h * p * h.transpose() + &hxjt + hxjt.transpose() + &jpp * j.transpose() + r;
    let GainSolution {
        gain,
        gain_t,
        nis,
        log_det,
    } = solve_gain(&s, &cross, &innovation)?;
    // x̂ = x⁻ + K ν
    let mean = prior.mean() + &gain * &innovation;
    // A = I − K H
    let a: Matrix<N> = Matrix::<N>::identity() - &gain * h;
    // K J  (N × M)
    let kj = &gain * j;
    // A X Jᵀ Kᵀ
    let axjtkt = a * &xjt * &gain_t;
    // P = A P Aᵀ − A X Jᵀ Kᵀ − (A X Jᵀ Kᵀ)ᵀ + K (J Pₚ Jᵀ + R) Kᵀ
    let noise = &jpp * j.transpose() + r;
    let covariance = a * p * a.transpose() - axjtkt.transpose() - axjtkt + &gain * noise * &gain_t;
    let covariance = Matrix::<N>::from_iterator(covariance.iter().copied());
    // X ← A X − K J Pₚ
    let updated_cross = a * x - SMatrix::<f64, N, M>::from_iterator((kj * consider_covariance).iter().copied());
    if updated_cross.iter().any(|v| !v.is_finite()) {
        return Err(EstimationError::NonFinite {
            what: "consider cross-covariance",
        });
    }
    let state = Gaussian::from_step(mean, covariance, prior.time_s(), "posterior state")?;
    Ok(ConsiderUpdated {
        updated: Updated {
            state,
            innovation,
            innovation_covariance: s,
            gain,
            nis,
            log_det_innovation_covariance: log_det,
        },
        cross_covariance: updated_cross,
    })
}

/// Carries `X = cov(eₓ, eₚ)` through an update of the state that did not involve `p`:
/// `X ← (I − K H) X = P⁺ (P⁻)⁻¹ X`, which holds for any Kalman update with the optimal gain
/// (`P⁺ = (I − K H) P⁻`: the KF, the EKF at its linearisation point, the UKF's statistical
/// linearisation), so the caller needs only the prior and posterior covariances.
///
/// # Errors
/// [`EstimationError::NotPositiveDefinite`] when `P⁻` cannot be factorised;
/// [`EstimationError::NonFinite`] for a non-finite result.
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, SMatrix};
/// use rtls_estimation::filter::carry_cross_covariance;
/// // an update that halved every variance halves the cross-covariance
/// let x = SMatrix::<f64, 2, 1>::new(0.2, -0.1);
/// let carried = carry_cross_covariance(&Matrix2::identity(), &(0.5 * Matrix2::identity()), &x)?;
/// assert!((carried - 0.5 * x).norm() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
pub fn carry_cross_covariance<const N: usize, const M: usize>(
    prior_covariance: &Matrix<N>,
    posterior_covariance: &Matrix<N>,
    cross_covariance: &SMatrix<f64, N, M>,
) -> Result<SMatrix<f64, N, M>> {
    // Y = (P⁻)⁻¹ X
    let chol = prior_covariance
        .cholesky()
        .ok_or(EstimationError::NotPositiveDefinite {
            what: "prior covariance",
        })?;
    let y = chol.solve(cross_covariance);
    // X⁺ = P⁺ Y
    let carried = posterior_covariance * y;
    if carried.iter().any(|v| !v.is_finite()) {
        return Err(EstimationError::NonFinite {
            what: "consider cross-covariance",
        });
    }
    Ok(carried)
}

#[cfg(test)]
pub(super) mod tests {
    use nalgebra::{DMatrix, DVector, SMatrix, Vector4};

    use super::*;
    use crate::filter::KalmanFilter;
    use crate::measurement::{ComponentSelection, NoiseCovariance};

    /// A 4-state prior, a 2-parameter consider covariance and a cross-covariance that keep the
    /// joint covariance positive definite (also the scalar form's test prior).
    pub(in crate::filter) fn setup() -> (Gaussian<4>, SMatrix<f64, 4, 2>, SMatrix<f64, 2, 2>) {
        let p = Matrix::<4>::new(
            2.0, 0.3, 0.1, 0.0, //
            0.3, 1.0, 0.0, 0.2, //
            0.1, 0.0, 1.5, 0.4, //
            0.0, 0.2, 0.4, 0.8,
        );
        let prior = Gaussian::new(Vector4::new(1.0, 0.5, -2.0, 0.1), p, 3.0).unwrap();
        let x = SMatrix::<f64, 4, 2>::new(0.2, 0.0, -0.1, 0.15, 0.05, 0.0, 0.1, -0.05);
        let pp = SMatrix::<f64, 2, 2>::new(0.3, 0.05, 0.05, 0.2);
        (prior, x, pp)
    }

    fn h() -> MeasurementJacobian<4> {
        MeasurementJacobian::<4>::from_row_slice(&[0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    }

    fn j() -> DMatrix<f64> {
        DMatrix::from_row_slice(2, 2, &[-0.4, 0.0, 0.9, 1.0])
    }

    fn r() -> DMatrix<f64> {
        DMatrix::from_row_slice(2, 2, &[0.05, 0.01, 0.01, 0.08])
    }

    /// The joint covariance of `[eₓ, eₚ, w]` and the map `T = [A, −K J, K]` give the
    /// posterior's error covariance and its cross-covariance with `eₚ` directly.
    #[test]
    fn the_posterior_covariances_are_those_of_the_error_propagated_in_closed_form() {
        let (prior, x, pp) = setup();
        let result = consider_update(&prior, &x, &pp, &h(), &j(), &r(), DVector::from_vec(vec![0.3, -0.2])).unwrap();
        // Σ = [[P, X, 0], [Xᵀ, Pₚ, 0], [0, 0, R]]  (8 × 8)
        let mut sigma = DMatrix::<f64>::zeros(8, 8);
        sigma.view_mut((0, 0), (4, 4)).copy_from(prior.covariance());
        sigma.view_mut((0, 4), (4, 2)).copy_from(&x);
        sigma.view_mut((4, 0), (2, 4)).copy_from(&x.transpose());
        sigma.view_mut((4, 4), (2, 2)).copy_from(&pp);
        sigma.view_mut((6, 6), (2, 2)).copy_from(&r());
        let k = DMatrix::from_iterator(4, 2, result.updated.gain.iter().copied());
        let a = DMatrix::<f64>::identity(4, 4) - &k * h();
        let mut t = DMatrix::<f64>::zeros(4, 8);
        t.view_mut((0, 0), (4, 4)).copy_from(&a);
        t.view_mut((0, 4), (4, 2)).copy_from(&(-(&k * j())));
        t.view_mut((0, 6), (4, 2)).copy_from(&k);
        let joint = &t * &sigma;
        let posterior = &joint * t.transpose();
        let cross = joint.view((0, 4), (4, 2)).clone_owned();
        for r in 0..4 {
            for c in 0..4 {
                assert!((posterior[(r, c)] - result.updated.state.covariance()[(r, c)]).abs() < 1e-12);
            }
            for c in 0..2 {
                assert!((cross[(r, c)] - result.cross_covariance[(r, c)]).abs() < 1e-12);
            }
        }
    }

    /// The state and its covariance equal the state part of a Kalman filter over the state
    /// augmented with `p` (one update: the Schmidt gain is the augmented gain's state rows).
    #[test]
    fn one_update_matches_the_augmented_kalman_filter_on_the_state() {
        let (prior, x, pp) = setup();
        // the augmented prior [x; p̂ = 0] with [[P, X], [Xᵀ, Pₚ]] (errors, so the mean of p is 0)
        let mut joint = Matrix::<6>::zeros();
        joint.view_mut((0, 0), (4, 4)).copy_from(prior.covariance());
        joint.view_mut((0, 4), (4, 2)).copy_from(&x);
        joint.view_mut((4, 0), (2, 4)).copy_from(&x.transpose());
        joint.view_mut((4, 4), (2, 2)).copy_from(&pp);
        let mut mean = nalgebra::SVector::<f64, 6>::zeros();
        mean.fixed_rows_mut::<4>(0).copy_from(prior.mean());
        let augmented = Gaussian::new(mean, joint, 3.0).unwrap();
        // z = H x + J p + w  →  [H, J] on the augmented state
        let mut ha = DMatrix::<f64>::zeros(2, 6);
        ha.view_mut((0, 0), (2, 4)).copy_from(&h());
        ha.view_mut((0, 4), (2, 2)).copy_from(&j());
        // the textbook update of the augmented state: S = Hₐ Pₐ Hₐᵀ + R, K = Pₐ Hₐᵀ S⁻¹,
        // x = x + K ν, P = (I − K Hₐ) Pₐ
        let pa = DMatrix::from_iterator(6, 6, augmented.covariance().iter().copied());
        let s = &ha * &pa * ha.transpose() + r();
        let k = &pa * ha.transpose() * s.clone().try_inverse().unwrap();
        let nu = DVector::from_vec(vec![0.3, -0.2]);
        let reference_mean = DVector::from_iterator(6, augmented.mean().iter().copied()) + &k * &nu;
        let reference_covariance = (DMatrix::<f64>::identity(6, 6) - &k * &ha) * &pa;
        let reference_nis = (nu.transpose() * s.try_inverse().unwrap() * &nu)[(0, 0)];
        let ours = consider_update(&prior, &x, &pp, &h(), &j(), &r(), DVector::from_vec(vec![0.3, -0.2])).unwrap();
        for r in 0..4 {
            assert!((reference_mean[r] - ours.updated.state.mean()[r]).abs() < 1e-12);
            for c in 0..4 {
                let (a, b) = (reference_covariance[(r, c)], ours.updated.state.covariance()[(r, c)]);
                assert!((a - b).abs() < 1e-12, "P[{r},{c}] {a} vs {b}");
            }
        }
        assert!((reference_nis - ours.updated.nis).abs() < 1e-12);
    }

    /// Without a parameter (`J = 0`, `X = 0`) it is the Kalman update.
    #[test]
    fn without_a_parameter_it_is_the_kalman_update() {
        let (prior, _, pp) = setup();
        let zero_j = DMatrix::<f64>::zeros(2, 2);
        let ours = consider_update(
            &prior,
            &SMatrix::<f64, 4, 2>::zeros(),
            &pp,
            &h(),
            &zero_j,
            &r(),
            DVector::from_vec(vec![0.3, -0.2]),
        )
        .unwrap();
        let z = DVector::from_vec(vec![0.3, -0.2]) + h() * prior.mean();
        let model = ComponentSelection::<4>::new(&[1, 3], NoiseCovariance::full(r()).unwrap()).unwrap();
        let reference = KalmanFilter::default().update(&prior, &model, &z).unwrap();
        assert!((reference.state.covariance() - ours.updated.state.covariance()).norm() < 1e-12);
        assert!((reference.state.mean() - ours.updated.state.mean()).norm() < 1e-12);
        assert!(ours.cross_covariance.norm() < 1e-15);
    }

    /// After a Kalman update of the state, `P⁺ (P⁻)⁻¹ X` is `(I − K H) X`.
    #[test]
    fn carrying_through_a_kalman_update_is_i_minus_kh() {
        let (prior, x, _) = setup();
        let z = DVector::from_vec(vec![0.3, -0.2]);
        let model = ComponentSelection::<4>::new(&[1, 3], NoiseCovariance::full(r()).unwrap()).unwrap();
        let updated = KalmanFilter::default().update(&prior, &model, &z).unwrap();
        let k = DMatrix::from_iterator(4, 2, updated.gain.iter().copied());
        let expected = (DMatrix::<f64>::identity(4, 4) - &k * h()) * DMatrix::from_iterator(4, 2, x.iter().copied());
        let carried = carry_cross_covariance(prior.covariance(), updated.state.covariance(), &x).unwrap();
        for (a, b) in expected.iter().zip(carried.iter()) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn shapes_are_checked() {
        let (prior, x, pp) = setup();
        let wrong = DMatrix::<f64>::zeros(1, 2);
        let error = consider_update(&prior, &x, &pp, &h(), &wrong, &r(), DVector::from_vec(vec![0.3, -0.2]));
        assert!(matches!(error, Err(EstimationError::DimensionMismatch { .. })));
    }
}
