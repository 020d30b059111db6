//! The Rauch–Tung–Striebel fixed-interval smoother for the KF, EKF and UKF.
//!
//! Given the filtered states `x̂ₖ|ₖ, Pₖ|ₖ` of a whole track (posteriors, or priors where no
//! measurement arrived), the smoother runs backwards:
//! ```text
//! x⁻ₖ₊₁ = f(x̂ₖ|ₖ)                 P⁻ₖ₊₁ = F Pₖ|ₖ Fᵀ + Q        (KF/EKF; unscented transform for the UKF)
//! Cₖ   = Pₖ|ₖ Fᵀ                   (UKF: Σ Wᶜ (χₖ − x̂ₖ)(χᶠ − x⁻ₖ₊₁)ᵀ)
//! Gₖ   = Cₖ (P⁻ₖ₊₁)⁻¹
//! x̂ₖ|ₙ = x̂ₖ|ₖ + Gₖ (x̂ₖ₊₁|ₙ − x⁻ₖ₊₁)
//! Pₖ|ₙ = Pₖ|ₖ + Gₖ (Pₖ₊₁|ₙ − P⁻ₖ₊₁) Gₖᵀ
//! ```
//! The step from `k` to `k+1` uses the states' own time stamps, so irregular sampling and
//! coasting gaps are smoothed correctly. Control inputs are not replayed: smooth tracks that
//! were predicted without control (or accept that the smoother ignores `B u`).
//!
//! # References
//! Rauch, Tung, Striebel (1965); Bar-Shalom, Li, Kirubarajan (2001) §8.6; Särkkä (2008),
//! "Unscented Rauch–Tung–Striebel smoother", IEEE TAC 53(3).

mod marginal;
mod tuned;

pub use marginal::marginal_intersection_bound;
pub use tuned::{tuned_smooth, InformationStep, NoiseFit, TunedSmoothing, FIT_STEPS_MAX};

use alloc::vec::Vec;

use nalgebra::DMatrix;

use crate::math::sqrt;

use crate::error::{EstimationError, Result};
use crate::filter::{sigma_points, weighted_moments};
use crate::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter};
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::motion::{LinearMotionModel, MotionModel};

/// One backward step given the filtered state, its one-step prediction, the cross-covariance
/// and the already-smoothed next state.
fn backward_step<const N: usize>(
    filtered: &Gaussian<N>,
    predicted_mean: &Vector<N>,
    predicted_cov: &Matrix<N>,
    cross_cov: &Matrix<N>,
    next_smoothed: &Gaussian<N>,
) -> Result<Gaussian<N>> {
    let chol = predicted_cov.cholesky().ok_or(EstimationError::NotPositiveDefinite {
        what: "predicted covariance (smoother)",
    })?;
    // G = C (P⁻)⁻¹  ⇔  Gᵀ = (P⁻)⁻¹ Cᵀ   (P⁻ symmetric)
    let gain = chol.solve(&cross_cov.transpose()).transpose();
    // x̂ₖ|ₙ = x̂ₖ|ₖ + G (x̂ₖ₊₁|ₙ − x⁻ₖ₊₁)
    let mean = filtered.mean() + gain * (next_smoothed.mean() - predicted_mean);
    // Pₖ|ₙ = Pₖ|ₖ + G (Pₖ₊₁|ₙ − P⁻ₖ₊₁) Gᵀ
    let covariance = filtered.covariance() + gain * (next_smoothed.covariance() - predicted_cov) * gain.transpose();
    Gaussian::from_step(mean, covariance, filtered.time_s(), "smoothed state")
}

/// A covariance for a smoothed mean that holds whatever the correlation between the errors
/// of what the past and what the future measurements say (covariance intersection).
///
/// The RTS mean fuses the filtered estimate (past measurements, `P_f`) with the information
/// the future measurements add, `I_b = P_s⁻¹ − P_f⁻¹`:
/// `x̂_s = A x̂_f + B x̂_b` with `A = P_s P_f⁻¹`, `B = P_s I_b`, `A + B = I`. `P_s` is its error
/// covariance only if the two errors are independent; measurement errors that persist for
/// seconds (multipath, a BLE fade) make them correlated, and `P_s` overconfident. For any
/// correlation, `(a + b)(a + b)ᵀ ≼ aaᵀ/ω + bbᵀ/(1 − ω)` bounds it:
/// ```text
/// M_f = A P_f Aᵀ = P_s P_f⁻¹ P_s          M_b = B I_b⁻¹ Bᵀ = P_s I_b P_s = P_s − M_f
/// P_ci(ω) = M_f / ω + M_b / (1 − ω)
/// ω* = √a / (√a + √b),  a = tr_S(M_f), b = tr_S(M_b)      (minimises tr_S P_ci = (√a + √b)²)
/// ```
/// where `tr_S` sums the diagonal entries listed in `components` (the reported ones, e.g.
/// the position axes). `P_s ≼ P_ci ≼` roughly `P_f`: equal to `P_s` where the future adds
/// nothing (`P_s = P_f`, the newest state) and to `P_f` where past and future weigh the same
/// (the worst case: fully correlated errors add nothing).
///
/// `P_f⁻¹` is its pseudo-inverse where `P_f` is singular (eigenvalues below `10⁻¹²` of the
/// largest). Where the smoother's model and the filter disagree so that `P_s ⋠ P_f` along some
/// direction (`M_b` would not be semi-definite: a CV backward pass over a coordinated turn's
/// states), nothing is taken from the future along it (`split_where_the_future_informs`).
///
/// # Errors
/// [`EstimationError::NotPositiveDefinite`] if `P_f` is zero or not finite, or the bound is
/// not positive semi-definite.
///
/// # Example
/// ```
/// use rtls_estimation::smoother::intersection_bound;
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// // past and future say as much (P_f = P_b = 1, so P_s = 1/2): with correlation unknown,
/// // the smoothed mean is only as sure as the filtered one
/// let filtered = Gaussian::new(Vector::<1>::new(0.0), Matrix::<1>::new(1.0), 0.0)?;
/// let smoothed = Gaussian::new(Vector::<1>::new(0.0), Matrix::<1>::new(0.5), 0.0)?;
/// let bound = intersection_bound(&filtered, &smoothed, &[0])?;
/// assert!((bound[(0, 0)] - 1.0).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// S. J. Julier, J. K. Uhlmann, "A non-divergent estimation algorithm in the presence of
/// unknown correlations", Proc. American Control Conference 1997; D. C. Fraser, J. E. Potter,
/// "The optimum linear smoother as a combination of two optimum linear filters", IEEE TAC
/// 14(4), 1969 (the smoother as a fusion of a forward and a backward filter).
pub fn intersection_bound<const N: usize>(
    filtered: &Gaussian<N>,
    smoothed: &Gaussian<N>,
    components: &[usize],
) -> Result<Matrix<N>> {
    let p_s = smoothed.covariance();
    // P_f⁺ by its eigenvalues: a filtered covariance may be singular along a direction a
    // measurement fixed (a speed of exactly known heading); P_s ≼ P_f is then as certain there,
    // and the pseudo-inverse is the limit of P_f⁻¹ on the rest
    let eigen = DMatrix::from_column_slice(N, N, filtered.covariance().as_slice()).symmetric_eigen();
    let largest = eigen.eigenvalues.max();
    if !(largest.is_finite() && largest > 0.0) {
        return Err(EstimationError::NotPositiveDefinite {
            what: "filtered covariance (smoothed covariance bound)",
        });
    }
    let pinv = Matrix::<N>::from_column_slice(psd_pseudo_inverse(&eigen).as_slice());
    // M_f = P_s P_f⁺ P_s
    let m_f = p_s * pinv * p_s;
    let m_f = (m_f + m_f.transpose()) * 0.5;
    // M_b = P_s I_b P_s = P_s − M_f
    let m_b = p_s - m_f;
    let (m_f, m_b) = if least_eigenvalue(&m_b) >= -1e-9 * largest {
        (m_f, m_b)
    } else {
        // the smoother's model and the filter disagree: somewhere P_s ⋠ P_f (the future "took"
        // information), e.g. a CV backward pass over a coordinated turn's states
        split_where_the_future_informs(&eigen, p_s)
    };
    // a = tr_S(M_f), b = tr_S(M_b) (b ≥ 0 unless the future lost information: then none is
    // taken from it)
    let a: f64 = components.iter().map(|&i| m_f[(i, i)]).sum();
    let b: f64 = components.iter().map(|&i| m_b[(i, i)]).sum();
    if !(a.is_finite() && a > 0.0 && b.is_finite()) {
        return Err(EstimationError::NotPositiveDefinite {
            what: "smoothed covariance bound",
        });
    }
    // (b within rounding of 0: the future added nothing, and the bound is P_s itself)
    let bound = if b <= 1e-12 * a {
        *p_s
    } else {
        // ω* = √a / (√a + √b);  P_ci = M_f/ω + M_b/(1 − ω)
        let omega = sqrt(a) / (sqrt(a) + sqrt(b));
        m_f / omega + m_b / (1.0 - omega)
    };
    // (semi-definite, like the P_s it bounds where a direction is known exactly)
    let least = least_eigenvalue(&bound);
    if least.is_finite() && least >= -1e-9 * largest {
        Ok(bound)
    } else {
        Err(EstimationError::NotPositiveDefinite {
            what: "smoothed covariance bound",
        })
    }
}

/// `M⁺` of a symmetric positive semi-definite matrix from its eigendecomposition: eigenvalues
/// at most `10⁻¹²` of the largest are taken as zero (the limit of `M⁻¹` on its range).
fn psd_pseudo_inverse(eigen: &nalgebra::SymmetricEigen<f64, nalgebra::Dyn>) -> DMatrix<f64> {
    let largest = eigen.eigenvalues.max();
    let inverted = eigen
        .eigenvalues
        .map(|lambda| if lambda > 1e-12 * largest { 1.0 / lambda } else { 0.0 });
    &eigen.eigenvectors * DMatrix::from_diagonal(&inverted) * eigen.eigenvectors.transpose()
}

/// The least eigenvalue of a symmetric matrix.
fn least_eigenvalue<const N: usize>(m: &Matrix<N>) -> f64 {
    DMatrix::from_column_slice(N, N, m.as_slice())
        .symmetric_eigenvalues()
        .min()
}

/// [`intersection_bound`]'s `M_f` and `M_b` where `P_s ⋠ P_f`. In coordinates that whiten the
/// filtered covariance (`P_f = R Rᵀ`, `R = U Λ^½` from its eigenvectors `U` and values `Λ`,
/// `W = U Λ^−½` on its range), `P_f` is `I` and `S = Wᵀ P_s W = V diag(s) Vᵀ`; there
/// `M_f = S²` and `M_b = S − S²`, each diagonal in `V`. Along a direction with `s ≤ 1` that is
/// the usual split; along one with `s > 1` the smoothed estimate claims to be less sure than
/// the filtered one (the smoother's model and the filter disagree) and nothing is taken from
/// the future: the whole of `s` is counted as the past's, which `1/ω` then inflates:
/// ```text
/// f = s², b = s − s²  (s ≤ 1);      f = s, b = 0  (s > 1)
/// M_f = R V diag(f) Vᵀ Rᵀ,   M_b = R V diag(b) Vᵀ Rᵀ
/// ```
/// Both are positive semi-definite, and `M_f + M_b ≽ P_s` on the range of `P_f`.
fn split_where_the_future_informs<const N: usize>(
    filtered: &nalgebra::SymmetricEigen<f64, nalgebra::Dyn>,
    p_s: &Matrix<N>,
) -> (Matrix<N>, Matrix<N>) {
    let largest = filtered.eigenvalues.max();
    let root = filtered.eigenvalues.map(|lambda| sqrt(lambda.max(0.0)));
    let inverse_root = filtered.eigenvalues.map(|lambda| {
        if lambda > 1e-12 * largest {
            1.0 / sqrt(lambda)
        } else {
            0.0
        }
    });
    // R = U Λ^½,  W = U Λ^−½
    let r = &filtered.eigenvectors * DMatrix::from_diagonal(&root);
    let w = &filtered.eigenvectors * DMatrix::from_diagonal(&inverse_root);
    // S = Wᵀ P_s W = V diag(s) Vᵀ
    let s = w.transpose() * DMatrix::from_column_slice(N, N, p_s.as_slice()) * &w;
    let s = (&s + s.transpose()) * 0.5;
    let eigen = s.symmetric_eigen();
    let (mut f, mut b) = (eigen.eigenvalues.clone(), eigen.eigenvalues.clone());
    for (i, &value) in eigen.eigenvalues.iter().enumerate() {
        let value = value.max(0.0);
        (f[i], b[i]) = if value <= 1.0 {
            (value * value, value - value * value)
        } else {
            (value, 0.0)
        };
    }
    // M = R V diag(·) Vᵀ Rᵀ
    let rv = r * &eigen.eigenvectors;
    let back = |d: &nalgebra::DVector<f64>| {
        let m = &rv * DMatrix::from_diagonal(d) * rv.transpose();
        let m = Matrix::<N>::from_column_slice(m.as_slice());
        (m + m.transpose()) * 0.5
    };
    (back(&f), back(&b))
}

/// Runs the backward pass with a per-step prediction function returning `(x⁻, P⁻, C)`.
fn smooth_with<const N: usize>(
    filtered: &[Gaussian<N>],
    mut predict: impl FnMut(&Gaussian<N>, f64) -> Result<(Vector<N>, Matrix<N>, Matrix<N>)>,
) -> Result<Vec<Gaussian<N>>> {
    let mut smoothed = filtered.to_vec();
    for k in (0..filtered.len().saturating_sub(1)).rev() {
        let dt_s = filtered[k].step_to(filtered[k + 1].time_s())?;
        let (xp, pp, c) = predict(&filtered[k], dt_s)?;
        smoothed[k] = backward_step(&filtered[k], &xp, &pp, &c, &smoothed[k + 1])?;
    }
    Ok(smoothed)
}

impl KalmanFilter {
    /// RTS-smooths a filtered track (oldest first) with a linear motion model.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if the states are not in time order;
    /// [`EstimationError::NotPositiveDefinite`] if a predicted covariance is singular.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::filter::KalmanFilter;
    /// use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// let motion = ConstantVelocity::new(ProcessNoise::discrete(0.5, NoiseGain::kinematic()))?;
    /// let kf = KalmanFilter::default();
    /// let x0 = Gaussian::new(Vector::<2>::new(0.0, 1.0), Matrix::<2>::identity(), 0.0)?;
    /// let x1 = kf.predict(&x0, &motion, 1.0)?;
    /// let smoothed = kf.smooth(&[x0, x1], &motion)?;
    /// // Without measurements, smoothing a pure prediction changes nothing.
    /// assert!((smoothed[0].mean() - x0.mean()).norm() < 1e-12);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn smooth<const N: usize, M: LinearMotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        smooth_with(filtered, |state, dt_s| {
            let f = model.transition_matrix(dt_s);
            // C = P Fᵀ
            let c = state.covariance() * f.transpose();
            // x⁻ = F x̂,  P⁻ = F P Fᵀ + Q
            Ok((f * state.mean(), f * c + model.process_noise_matrix(dt_s), c))
        })
    }
}

impl ExtendedKalmanFilter {
    /// RTS-smooths a filtered track with a (possibly nonlinear) motion model linearised at each
    /// filtered state (the extended RTS smoother).
    ///
    /// # Errors
    /// As [`KalmanFilter::smooth`].
    pub fn smooth<const N: usize, M: MotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        smooth_with(filtered, |state, dt_s| {
            // F = ∂f/∂x at x̂ₖ|ₖ
            let f = model.transition_jacobian(state.mean(), dt_s);
            // C = P Fᵀ
            let c = state.covariance() * f.transpose();
            // x⁻ = f(x̂),  P⁻ = F P Fᵀ + Q
            let q = model.process_noise(state.mean(), dt_s);
            Ok((model.transition(state.mean(), dt_s), f * c + q, c))
        })
    }
}

impl UnscentedKalmanFilter {
    /// Unscented RTS smoother (Särkkä 2008): predictions and cross-covariances by the
    /// unscented transform of the filtered states.
    ///
    /// # Errors
    /// As [`KalmanFilter::smooth`], plus sigma-point factorisation failures.
    pub fn smooth<const N: usize, M: MotionModel<N>>(
        &self,
        filtered: &[Gaussian<N>],
        model: &M,
    ) -> Result<Vec<Gaussian<N>>> {
        let weights = self.parameters.unscented_weights(N)?;
        smooth_with(filtered, |state, dt_s| {
            // χ = σ(x̂ₖ|ₖ, Pₖ|ₖ),  χᶠ = f(χ, dt)
            let points = sigma_points(state, weights.scale)?;
            let propagated: Vec<Vector<N>> = points.iter().map(|p| model.transition(p, dt_s)).collect();
            // x⁻ = Σ Wᵐ χᶠ,  P⁻ = Σ Wᶜ (χᶠ − x⁻)(…)ᵀ + Q
            let (xp, pp) = weighted_moments(&propagated, &weights);
            let pp = pp + model.process_noise(state.mean(), dt_s);
            // C = Σ Wᶜ (χ − x̂)(χᶠ − x⁻)ᵀ
            let mut c = Matrix::<N>::zeros();
            for (i, (p, pf)) in points.iter().zip(&propagated).enumerate() {
                c.ger(weights.covariance(i), &(p - state.mean()), &(pf - xp), 1.0);
            }
            Ok((xp, pp, c))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random symmetric positive definite 4 × 4 matrix `L Lᵀ + 0.1 I`.
    fn random_spd(rng: &mut ChaCha8Rng) -> Matrix<4> {
        let l = Matrix::<4>::from_fn(|_, _| rng.gen_range(-1.0..1.0));
        l * l.transpose() + Matrix::<4>::identity() * 0.1
    }

    /// The bound's traced components hold the smoothed mean's true error covariance
    /// `A P_f Aᵀ + B P_b Bᵀ + A X Bᵀ + B Xᵀ Aᵀ` for past/future errors with any valid
    /// cross-covariance `X`, and the bound is never below `P_s`.
    #[test]
    fn the_intersection_bound_holds_for_any_correlation_of_past_and_future() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let components = [0, 2];
        for _ in 0..200 {
            let p_f = random_spd(&mut rng);
            let p_b = random_spd(&mut rng);
            // P_s = (P_f⁻¹ + P_b⁻¹)⁻¹, A = P_s P_f⁻¹, B = P_s P_b⁻¹
            let info_f = p_f.try_inverse().unwrap();
            let info_b = p_b.try_inverse().unwrap();
            let p_s = (info_f + info_b).try_inverse().unwrap();
            let p_s = (p_s + p_s.transpose()) * 0.5;
            let (a, b) = (p_s * info_f, p_s * info_b);
            let filtered = Gaussian::new(Vector::<4>::zeros(), p_f, 0.0).unwrap();
            let smoothed = Gaussian::new(Vector::<4>::zeros(), p_s, 0.0).unwrap();
            let bound = intersection_bound(&filtered, &smoothed, &components).unwrap();
            // P_ci − P_s ≽ 0
            let least = (bound - p_s).symmetric_eigenvalues().min();
            assert!(least > -1e-9, "P_ci − P_s has eigenvalue {least}");
            for _ in 0..20 {
                // X = L_f K L_bᵀ with ‖K‖ ≤ 1 (a valid joint covariance of past and future errors)
                let k = Matrix::<4>::from_fn(|_, _| rng.gen_range(-1.0..1.0));
                let k = k / k.norm().max(1.0);
                let l_f = p_f.cholesky().unwrap().l();
                let l_b = p_b.cholesky().unwrap().l();
                let x = l_f * k * l_b.transpose();
                let actual = a * p_f * a.transpose()
                    + b * p_b * b.transpose()
                    + a * x * b.transpose()
                    + b * x.transpose() * a.transpose();
                let traced = |m: &Matrix<4>| components.iter().map(|&i| m[(i, i)]).sum::<f64>();
                assert!(traced(&actual) <= traced(&bound) + 1e-9);
            }
        }
    }

    /// Where the smoothed covariance exceeds the filtered one along a direction (the
    /// smoother's model and the filter disagree), the bound still exists and holds `P_s`:
    /// nothing is taken from the future along it.
    #[test]
    fn a_smoothed_covariance_above_the_filtered_one_takes_nothing_from_the_future_there() {
        // whitened: s = 2 along x (P_s ⋠ P_f), s = 0.5 along y
        let filtered = Gaussian::new(Vector::<2>::zeros(), Matrix::<2>::identity(), 0.0).unwrap();
        let smoothed = Gaussian::new(Vector::<2>::zeros(), Matrix::<2>::new(2.0, 0.0, 0.0, 0.5), 0.0).unwrap();
        let bound = intersection_bound(&filtered, &smoothed, &[0, 1]).unwrap();
        // f = (2, 0.25), b = (0, 0.25): a = 2.25, b = 0.25, ω = 1.5 / 2 = 0.75
        // P_ci = diag(2 / 0.75, 0.25 / 0.75 + 0.25 / 0.25)
        let expected = Matrix::<2>::new(2.0 / 0.75, 0.0, 0.0, 0.25 / 0.75 + 1.0);
        assert!((bound - expected).norm() < 1e-9, "{bound}");
        // and in a rotated, scaled frame, the bound is never below P_s
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let p_f = random_spd(&mut rng);
            let p_s = random_spd(&mut rng) * 2.0;
            let bound = intersection_bound(
                &Gaussian::new(Vector::<4>::zeros(), p_f, 0.0).unwrap(),
                &Gaussian::new(Vector::<4>::zeros(), p_s, 0.0).unwrap(),
                &[0, 2],
            )
            .unwrap();
            let least = (bound - p_s).symmetric_eigenvalues().min();
            assert!(least > -1e-9, "P_ci − P_s has eigenvalue {least}");
        }
    }

    #[test]
    fn the_newest_state_keeps_its_filtered_covariance() {
        let p = Matrix::<2>::new(2.0, 0.3, 0.3, 1.0);
        let state = Gaussian::new(Vector::<2>::zeros(), p, 0.0).unwrap();
        let bound = intersection_bound(&state, &state, &[0]).unwrap();
        assert!((bound - p).norm() < 1e-12);
    }
}
