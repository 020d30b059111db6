//! A covariance for a smoothed position that credits the future only with what it says about
//! the position: the covariance intersection of the past's and the future's marginals.

use alloc::vec::Vec;

use nalgebra::DMatrix;

use crate::error::{EstimationError, Result};
use crate::gaussian::{Gaussian, Matrix};
use crate::math::sqrt;

use super::psd_pseudo_inverse;

/// Golden-section steps of the search for `ω*` (the bracket shrinks by 0.618 per step: 10⁻¹⁰
/// of `[0, 1]` after 48).
const OMEGA_STEPS: usize = 48;

/// A covariance for a smoothed mean's `components` (the position axes) that assumes only that
/// what the past and what the future measurements say about *those components* is honest, and
/// nothing about how their errors are correlated.
///
/// [`super::intersection_bound`] bounds the smoothed mean's error over the whole state: it
/// trusts the filtered and the backward covariances in every component, velocities and their
/// correlations with the position included. Recorded errors that persist (a UWB fix off by the
/// anchors' geometry for seconds at a place) break that: the past and the future then share the
/// position error, while their velocity correlations are mirror images, which the full-state
/// bound reads as independent evidence (on LIAS's mid run its 95 % ellipses held the truth
/// 90.9 % of the time against 99.7 % for the filtered ones, docs/EVALUATION.md). This bound
/// takes from each side only its marginal over `S = components`:
/// ```text
/// I_b  = P_s⁻¹ − P_f⁻¹                              (what the future adds: P_s⁻¹ = P_f⁻¹ + I_b)
/// J_b  = I_b,SS − I_b,SR I_b,RR⁺ I_b,RS             (its information about S alone, the Schur
///                                                    complement; R = the other components)
/// A    = (P_f,SS)⁻¹                                  (the past's information about S)
/// P_ci(ω) = (ω A + (1 − ω) J_b)⁻¹,  ω* = argmin_{ω ∈ (0, 1]} tr P_ci(ω)
/// ```
/// `P_ci(ω*)` bounds the error covariance of the fused marginal
/// `P_ci (ω A x_f,S + (1 − ω) J_b x_b,S)` for any correlation of the two errors (Julier and
/// Uhlmann). It lies between `P_s,SS` (the marginal of the fusion of independent errors: the
/// Schur complement of `P_f⁻¹ + I_b` is at least `A + J_b`) and, in trace, `P_f,SS` (`ω = 1`,
/// where the future says nothing, as at a track's newest state); where past and future say
/// the same about the position it is `P_f,SS` itself. Negative eigenvalues of `I_b` (the
/// smoother's model and the filter disagree, so `P_s ⋠ P_f` along some direction) are taken as
/// zero: nothing is taken from the future there.
///
/// The returned matrix is `P_s` with its `S × S` block replaced by `P_ci(ω*)`, positive
/// semi-definite because that block only grew. The caller reports it with the smoothed mean,
/// which uses the velocities' coupling too; that it is at least as close to the truth as the
/// fused marginal is an observation on the recordings (docs/EVALUATION.md), not a theorem.
///
/// `P_f⁻¹` and `P_s⁻¹` are pseudo-inverses by eigenvalues (those below `10⁻¹²` of the largest
/// taken as zero), as in [`super::intersection_bound`].
///
/// # Errors
/// [`EstimationError::NotPositiveDefinite`] if `P_f` is zero or not finite, `P_f,SS` is not
/// positive definite, `components` is empty or out of range, or the result is not positive
/// semi-definite.
///
/// # Example
/// ```
/// use rtls_estimation::smoother::marginal_intersection_bound;
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// // [p, v]: the past and the future each know the position to 1 m² and the velocity to
/// // 1 (m/s)², with opposite correlations (the future runs backwards in time)
/// let past = Matrix::<2>::new(1.0, 0.5, 0.5, 1.0);
/// let future = Matrix::<2>::new(1.0, -0.5, -0.5, 1.0);
/// let p_s = (past.try_inverse().unwrap() + future.try_inverse().unwrap()).try_inverse().unwrap();
/// let filtered = Gaussian::new(Vector::<2>::zeros(), past, 0.0)?;
/// let smoothed = Gaussian::new(Vector::<2>::zeros(), p_s, 0.0)?;
/// let bound = marginal_intersection_bound(&filtered, &smoothed, &[0])?;
/// // independent errors would give 0.375 m²; about the position alone each says 1 m², and
/// // with their correlation unknown the smoothed position is no surer than that
/// assert!((p_s[(0, 0)] - 0.375).abs() < 1e-12);
/// assert!((bound[(0, 0)] - 1.0).abs() < 1e-6);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// S. J. Julier, J. K. Uhlmann, "A non-divergent estimation algorithm in the presence of
/// unknown correlations", Proc. American Control Conference 1997; D. C. Fraser, J. E. Potter,
/// "The optimum linear smoother as a combination of two optimum linear filters", IEEE TAC
/// 14(4), 1969.
pub fn marginal_intersection_bound<const N: usize>(
    filtered: &Gaussian<N>,
    smoothed: &Gaussian<N>,
    components: &[usize],
) -> Result<Matrix<N>> {
    let not_definite = |what| EstimationError::NotPositiveDefinite { what };
    if components.is_empty() || components.iter().any(|&i| i >= N) {
        return Err(not_definite("smoothed covariance bound (its components)"));
    }
    let p_f = DMatrix::from_column_slice(N, N, filtered.covariance().as_slice());
    let eigen_f = p_f.clone().symmetric_eigen();
    let largest = eigen_f.eigenvalues.max();
    if !(largest.is_finite() && largest > 0.0) {
        return Err(not_definite("filtered covariance (smoothed covariance bound)"));
    }
    let eigen_s = DMatrix::from_column_slice(N, N, smoothed.covariance().as_slice()).symmetric_eigen();
    // I_b = P_s⁺ − P_f⁺, its negative part (the future taking information) dropped
    let info_b = clamped(&(psd_pseudo_inverse(&eigen_s) - psd_pseudo_inverse(&eigen_f)), 0.0);
    // J_b = I_b,SS − I_b,SR I_b,RR⁺ I_b,RS
    let rest: Vec<usize> = (0..N).filter(|i| !components.contains(i)).collect();
    let block = |m: &DMatrix<f64>, rows: &[usize], cols: &[usize]| {
        DMatrix::from_fn(rows.len(), cols.len(), |r, c| m[(rows[r], cols[c])])
    };
    let i_ss = block(&info_b, components, components);
    let j_b = if rest.is_empty() {
        i_ss
    } else {
        let i_sr = block(&info_b, components, &rest);
        let i_rr = block(&info_b, &rest, &rest);
        clamped(
            &(&i_ss - &i_sr * psd_pseudo_inverse(&i_rr.symmetric_eigen()) * i_sr.transpose()),
            0.0,
        )
    };
    // A = (P_f,SS)⁻¹
    let a = block(&p_f, components, components)
        .cholesky()
        .ok_or(not_definite("filtered covariance of the smoothed components"))?
        .inverse();
    // P_ci(ω) = (ω A + (1 − ω) J_b)⁻¹ and its trace (∞ where singular: ω → 0 with J_b singular)
    let fused = |omega: f64| (&a * omega + &j_b * (1.0 - omega)).cholesky().map(|c| c.inverse());
    let trace = |omega: f64| fused(omega).map_or(f64::INFINITY, |p| p.trace());
    // ω* = argmin tr P_ci(ω): tr P_ci is convex in ω (Julier, Uhlmann), golden section on
    // (0, 1], then the end ω = 1 (the past alone), which the section only approaches
    let golden = 0.5 * (sqrt(5.0) - 1.0);
    let (mut low, mut high) = (0.0, 1.0);
    let (mut left, mut right) = (high - golden * (high - low), low + golden * (high - low));
    let (mut f_left, mut f_right) = (trace(left), trace(right));
    for _ in 0..OMEGA_STEPS {
        if f_left <= f_right {
            (high, right, f_right) = (right, left, f_left);
            left = high - golden * (high - low);
            f_left = trace(left);
        } else {
            (low, left, f_left) = (left, right, f_right);
            right = low + golden * (high - low);
            f_right = trace(right);
        }
    }
    let p_ci = [fused(0.5 * (low + high)), fused(1.0)]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.trace().total_cmp(&b.trace()))
        .ok_or(not_definite("smoothed covariance bound"))?;
    // P_s with its S × S block replaced by P_ci(ω*)
    let mut bound = *smoothed.covariance();
    for (r, &i) in components.iter().enumerate() {
        for (c, &j) in components.iter().enumerate() {
            bound[(i, j)] = 0.5 * (p_ci[(r, c)] + p_ci[(c, r)]);
        }
    }
    let least = DMatrix::from_column_slice(N, N, bound.as_slice())
        .symmetric_eigenvalues()
        .min();
    if bound.iter().all(|v| v.is_finite()) && least >= -1e-9 * largest {
        Ok(bound)
    } else {
        Err(not_definite("smoothed covariance bound"))
    }
}

/// A symmetric matrix with its eigenvalues below `floor` raised to it.
fn clamped(m: &DMatrix<f64>, floor: f64) -> DMatrix<f64> {
    let symmetric = (m + m.transpose()) * 0.5;
    let eigen = symmetric.symmetric_eigen();
    let raised = eigen.eigenvalues.map(|lambda| lambda.max(floor));
    &eigen.eigenvectors * DMatrix::from_diagonal(&raised) * eigen.eigenvectors.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gaussian::Vector;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_spd(rng: &mut ChaCha8Rng) -> Matrix<4> {
        let l = Matrix::<4>::from_fn(|_, _| rng.gen_range(-1.0..1.0));
        l * l.transpose() + Matrix::<4>::identity() * 0.1
    }

    fn state(covariance: Matrix<4>) -> Gaussian<4> {
        Gaussian::new(Vector::<4>::zeros(), covariance, 0.0).unwrap()
    }

    fn block(m: &Matrix<4>, s: &[usize]) -> DMatrix<f64> {
        DMatrix::from_fn(s.len(), s.len(), |r, c| m[(s[r], s[c])])
    }

    /// The block is the CI of the two marginals at the ω a brute-force grid finds least in
    /// trace, it lies between `P_s,SS` and (in trace) `P_f,SS`, and the fused marginal's error
    /// covariance under any cross-covariance of past and future stays inside it in trace.
    #[test]
    fn the_marginal_bound_is_the_least_trace_intersection_of_past_and_future() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let s = [0, 2];
        for _ in 0..100 {
            let (p_f, p_b) = (random_spd(&mut rng), random_spd(&mut rng));
            let p_s = (p_f.try_inverse().unwrap() + p_b.try_inverse().unwrap())
                .try_inverse()
                .unwrap();
            let p_s = (p_s + p_s.transpose()) * 0.5;
            let bound = marginal_intersection_bound(&state(p_f), &state(p_s), &s).unwrap();
            let got = block(&bound, &s);
            // brute force over ω of tr (ω A + (1 − ω) B)⁻¹, B = (P_b,SS)⁻¹ (the backward
            // marginal's information)
            let a = block(&p_f, &s).try_inverse().unwrap();
            let b = block(&p_b, &s).try_inverse().unwrap();
            let at = |w: f64| (&a * w + &b * (1.0 - w)).try_inverse().unwrap();
            let least = (1..=10_000)
                .map(|i| f64::from(i) / 10_000.0)
                .map(|w| (at(w).trace(), w))
                .min_by(|x, y| x.0.total_cmp(&y.0))
                .unwrap();
            assert!(
                got.trace() <= least.0 + 1e-9,
                "{} > brute force {}",
                got.trace(),
                least.0
            );
            assert!(
                (&got - at(least.1)).norm() < 1e-3 * got.norm(),
                "{got} vs {}",
                at(least.1)
            );
            // P_s,SS ≼ P_ci,  tr P_ci ≤ tr P_f,SS
            assert!((&got - block(&p_s, &s)).symmetric_eigenvalues().min() > -1e-9);
            assert!(got.trace() <= block(&p_f, &s).trace() + 1e-9);
            // the other entries are P_s's
            assert_eq!(bound[(1, 1)], p_s[(1, 1)]);
            assert_eq!(bound[(0, 1)], p_s[(0, 1)]);
            // fused marginal x = P (ω A x_f + (1 − ω) B x_b): error covariance with X = cov(e_f,S, e_b,S)
            let omega = least.1;
            let (wf, wb) = (&got * &a * omega, &got * &b * (1.0 - omega));
            let (l_f, l_b) = (
                block(&p_f, &s).cholesky().unwrap().l(),
                block(&p_b, &s).cholesky().unwrap().l(),
            );
            for _ in 0..20 {
                let k: DMatrix<f64> = DMatrix::from_fn(2, 2, |_, _| rng.gen_range(-1.0..1.0));
                let k = &k / k.norm().max(1.0);
                let x = &l_f * k * l_b.transpose();
                let actual = &wf * block(&p_f, &s) * wf.transpose()
                    + &wb * block(&p_b, &s) * wb.transpose()
                    + &wf * &x * wb.transpose()
                    + &wb * x.transpose() * wf.transpose();
                assert!(actual.trace() <= got.trace() * (1.0 + 1e-6) + 1e-9);
            }
        }
    }

    /// Past and future that say the same about the position (the same marginal, whatever the
    /// velocities say) leave the position as sure as the past alone; a future that says
    /// nothing (the newest state) leaves `P_f`.
    #[test]
    fn a_future_that_repeats_the_past_adds_nothing() {
        let past = Matrix::<4>::new(
            1.0, 0.5, 0.0, 0.0, //
            0.5, 1.0, 0.0, 0.0, //
            0.0, 0.0, 2.0, -0.8, //
            0.0, 0.0, -0.8, 1.0,
        );
        let mut future = past;
        for (i, j) in [(0, 1), (1, 0), (2, 3), (3, 2)] {
            future[(i, j)] = -past[(i, j)];
        }
        let p_s = (past.try_inverse().unwrap() + future.try_inverse().unwrap())
            .try_inverse()
            .unwrap();
        let bound = marginal_intersection_bound(&state(past), &state(p_s), &[0, 2]).unwrap();
        let got = block(&bound, &[0, 2]);
        assert!((&got - block(&past, &[0, 2])).norm() < 1e-6, "{got}");
        // the full-state bound credits the mirrored correlations
        let full = super::super::intersection_bound(&state(past), &state(p_s), &[0, 2]).unwrap();
        assert!(full[(0, 0)] + full[(2, 2)] < 0.8 * (past[(0, 0)] + past[(2, 2)]));
        // the newest state
        let newest = marginal_intersection_bound(&state(past), &state(past), &[0, 2]).unwrap();
        assert!((newest - past).norm() < 1e-9);
    }

    #[test]
    fn bad_components_and_a_zero_covariance_are_errors() {
        let p = Matrix::<4>::identity();
        assert!(marginal_intersection_bound(&state(p), &state(p), &[]).is_err());
        assert!(marginal_intersection_bound(&state(p), &state(p), &[4]).is_err());
        let zero = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::zeros(), 0.0);
        if let Ok(zero) = zero {
            assert!(marginal_intersection_bound(&zero, &zero, &[0]).is_err());
        }
    }
}
