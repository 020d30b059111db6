//! The Schmidt–Kalman update of one scalar measurement with one considered parameter (a range
//! and its anchor's offset), on the stack: [`consider_update`](super::consider_update) with
//! `m = M = 1`, without its dynamic matrices (the tightly coupled tracker's hot path).

use nalgebra::{DMatrix, DVector, SVector};

use super::update::{Gain, Updated};
use crate::error::{EstimationError, Result};
use crate::{Gaussian, Matrix};

/// One Schmidt–Kalman update of a scalar `z = h x + p + w`, `w ~ N(0, r)`, with innovation
/// `ν = z − h x⁻`, `x = cov(eₓ, eₚ)` (`N`) and `pₚ = var(eₚ)`:
///
/// ```text
/// c = P hᵀ + x,   s = h P hᵀ + 2 h x + pₚ + r,   k = c / s,   x̂ = x⁻ + k ν
/// A = I − k h,   P = A P Aᵀ − A x kᵀ − k xᵀ Aᵀ + (pₚ + r) k kᵀ,   x ← A x − k pₚ
/// ```
///
/// (the equations of [`consider_update`](super::consider_update) with `J = 1`). Returns the
/// update, the new `x` and `A`, which carries every other column of a cross-covariance the
/// caller keeps (`xⱼ ← A xⱼ − k cov(eₚ, eₚⱼ)`).
///
/// # Errors
/// [`EstimationError::InnovationNotPositiveDefinite`] when `s ≤ 0`;
/// [`EstimationError::NonFinite`] for a non-finite result.
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, SVector, Vector2};
/// use rtls_estimation::filter::consider_update_scalar;
/// use rtls_estimation::Gaussian;
/// // a position and velocity; the position measured with an offset known to 0.5 (variance 0.25)
/// let prior = Gaussian::new(Vector2::new(0.0, 1.0), Matrix2::identity(), 0.0)?;
/// let h = SVector::<f64, 2>::new(1.0, 0.0);
/// let (updated, cross, _) = consider_update_scalar(&prior, &SVector::zeros(), 0.25, &h, 0.01, 0.5)?;
/// // s = 1 + 0.25 + 0.01
/// assert!((updated.innovation_covariance[(0, 0)] - 1.26).abs() < 1e-12);
/// // the position's error now shares the offset's
/// assert!(cross[0] < 0.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Schmidt (1966); Simon (2006) §7.5.
pub fn consider_update_scalar<const N: usize>(
    prior: &Gaussian<N>,
    cross: &SVector<f64, N>,
    consider_variance: f64,
    h: &SVector<f64, N>,
    r: f64,
    innovation: f64,
) -> Result<(Updated<N>, SVector<f64, N>, Matrix<N>)> {
    let p = prior.covariance();
    // P hᵀ and c = P hᵀ + x
    let pht = p * h;
    let c = pht + cross;
    // s = h P hᵀ + 2 h x + pₚ + r
    let s = h.dot(&pht) + 2.0 * h.dot(cross) + consider_variance + r;
    if s.is_nan() || s <= 0.0 {
        return Err(EstimationError::InnovationNotPositiveDefinite);
    }
    // k = c / s,  x̂ = x⁻ + k ν
    let k = c / s;
    let mean = prior.mean() + k * innovation;
    // A = I − k h
    let a = Matrix::<N>::identity() - k * h.transpose();
    // A x kᵀ
    let ax = a * cross;
    let axkt = ax * k.transpose();
    // P = A P Aᵀ − A x kᵀ − (A x kᵀ)ᵀ + (pₚ + r) k kᵀ
    let covariance = a * p * a.transpose() - axkt - axkt.transpose() + (consider_variance + r) * (k * k.transpose());
    // x ← A x − k pₚ
    let updated_cross = ax - k * consider_variance;
    if updated_cross.iter().any(|v| !v.is_finite()) {
        return Err(EstimationError::NonFinite {
            what: "consider cross-covariance",
        });
    }
    let nis = innovation * innovation / s;
    if !nis.is_finite() {
        return Err(EstimationError::NonFinite {
            what: "normalised innovation squared",
        });
    }
    let state = Gaussian::from_step(mean, covariance, prior.time_s(), "posterior state")?;
    let updated = Updated {
        state,
        innovation: DVector::from_element(1, innovation),
        innovation_covariance: DMatrix::from_element(1, 1, s),
        gain: Gain::<N>::from_column_slice(k.as_slice()),
        nis,
        log_det_innovation_covariance: crate::math::ln(s),
    };
    Ok((updated, updated_cross, a))
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector, SMatrix, Vector4};

    use super::*;
    use crate::filter::consider_update;
    use crate::measurement::MeasurementJacobian;

    #[test]
    fn equals_the_general_consider_update_with_one_measurement_and_one_parameter() {
        let (prior, _, _) = super::super::consider::tests::setup();
        let h = Vector4::new(0.6, 0.0, -0.8, 0.0);
        let cross = Vector4::new(-0.1, 0.02, 0.05, 0.0);
        let (pp, r, nu) = (0.3, 0.05, 0.7);
        let general = consider_update(
            &prior,
            &SMatrix::<f64, 4, 1>::from(cross),
            &SMatrix::<f64, 1, 1>::new(pp),
            &MeasurementJacobian::<4>::from_row_slice(h.as_slice()),
            &DMatrix::from_element(1, 1, 1.0),
            &DMatrix::from_element(1, 1, r),
            DVector::from_element(1, nu),
        )
        .unwrap();
        let (scalar, scalar_cross, a) = consider_update_scalar(&prior, &cross, pp, &h, r, nu).unwrap();
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * (1.0 + y.abs());
        let all_close = |xs: &[f64], ys: &[f64]| xs.len() == ys.len() && xs.iter().zip(ys).all(|(x, y)| close(*x, *y));
        let g = &general.updated;
        assert!(all_close(g.state.mean().as_slice(), scalar.state.mean().as_slice()));
        assert!(all_close(
            g.state.covariance().as_slice(),
            scalar.state.covariance().as_slice()
        ));
        assert!(all_close(general.cross_covariance.as_slice(), scalar_cross.as_slice()));
        assert!(all_close(g.gain.as_slice(), scalar.gain.as_slice()));
        assert!(
            close(g.nis, scalar.nis) && close(g.log_det_innovation_covariance, scalar.log_det_innovation_covariance)
        );
        assert!(close(
            g.innovation_covariance[(0, 0)],
            scalar.innovation_covariance[(0, 0)]
        ));
        // A = I − k h
        let expected_a = Matrix::<4>::identity() - Vector4::from_fn(|i, _| g.gain[(i, 0)]) * h.transpose();
        assert!((a - expected_a).norm() < 1e-12);
    }

    #[test]
    fn a_non_positive_innovation_variance_is_an_error() {
        let prior = Gaussian::new(Vector4::zeros(), Matrix::<4>::identity(), 0.0).unwrap();
        let h = Vector4::zeros();
        assert!(matches!(
            consider_update_scalar(&prior, &Vector4::zeros(), 0.0, &h, 0.0, 1.0),
            Err(EstimationError::InnovationNotPositiveDefinite)
        ));
    }
}
