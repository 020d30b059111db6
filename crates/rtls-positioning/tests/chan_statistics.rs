//! Statistical conformance of Chan's estimator: agreement with a maximum-likelihood minimiser
//! at small noise, and seeded Monte Carlo of its error covariance against the covariance it
//! reports and against the Cramér–Rao bound.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_positioning::tdoa::{chan, differenced_range_covariance, range_differences_at};

/// Stations, reference, true position.
type Case<'a> = (&'a [[f64; 2]], usize, Vector2<f64>);
/// Stations, reference, true position, TOA standard deviation (m).
type NoisyCase<'a> = (&'a [[f64; 2]], usize, Vector2<f64>, f64);

/// `h(p)` and its Jacobian `J_i = (p − s_i)ᵀ/r_i − (p − s_ref)ᵀ/r_ref`.
fn model(stations: &[[f64; 2]], reference: usize, p: &Vector2<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let h = DVector::from_vec(range_differences_at(stations, reference, p).unwrap());
    let unit = |s: &[f64; 2]| {
        let d = p - Vector2::new(s[0], s[1]);
        d / d.norm()
    };
    let u_ref = unit(&stations[reference]);
    let rows: Vec<Vector2<f64>> = stations
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != reference)
        .map(|(_, s)| unit(s) - u_ref)
        .collect();
    (h, DMatrix::from_fn(rows.len(), 2, |i, k| rows[i][k]))
}

/// `(r − h(p))ᵀ Q⁻¹ (r − h(p))`.
fn cost(stations: &[[f64; 2]], reference: usize, r: &DVector<f64>, q_inv: &DMatrix<f64>, p: &Vector2<f64>) -> f64 {
    let e = r - model(stations, reference, p).0;
    (e.transpose() * q_inv * e)[(0, 0)]
}

/// Maximum-likelihood fix by Gauss–Newton on `(r − h(p))ᵀ Q⁻¹ (r − h(p))`, started at `start`:
/// `p ← p + (Jᵀ Q⁻¹ J)⁻¹ Jᵀ Q⁻¹ (r − h(p))`, 30 iterations (quadratic convergence from a start
/// within the noise of the minimum), checked to have converged to round-off.
fn maximum_likelihood(
    stations: &[[f64; 2]],
    reference: usize,
    r: &DVector<f64>,
    q_inv: &DMatrix<f64>,
    start: Vector2<f64>,
) -> Vector2<f64> {
    let mut p = start;
    let mut last_step_m = f64::INFINITY;
    for _ in 0..30 {
        let (h, j) = model(stations, reference, &p);
        let info = j.transpose() * q_inv * &j;
        let step = info.try_inverse().unwrap() * j.transpose() * q_inv * (r - h);
        p += Vector2::new(step[0], step[1]);
        last_step_m = step.norm();
    }
    assert!(
        last_step_m < 1e-10 * (1.0 + p.norm()),
        "gauss-newton did not converge: last step {last_step_m} m"
    );
    p
}

/// `(Jᵀ Q⁻¹ J)⁻¹` at `p`.
fn crlb(stations: &[[f64; 2]], reference: usize, q_inv: &DMatrix<f64>, p: &Vector2<f64>) -> Matrix2<f64> {
    let (_, j) = model(stations, reference, p);
    let info = j.transpose() * q_inv * j;
    Matrix2::new(info[(0, 0)], info[(0, 1)], info[(1, 0)], info[(1, 1)])
        .try_inverse()
        .unwrap()
}

/// Range differences at `truth` plus differenced TOA noise of standard deviation `sigma_m`.
fn noisy_differences(
    stations: &[[f64; 2]],
    reference: usize,
    truth: &Vector2<f64>,
    sigma_m: f64,
    rng: &mut ChaCha8Rng,
) -> DVector<f64> {
    let noise = Normal::new(0.0, sigma_m).unwrap();
    let toa: Vec<f64> = stations.iter().map(|_| noise.sample(rng)).collect();
    let clean = range_differences_at(stations, reference, truth).unwrap();
    let others = (0..stations.len()).filter(|&i| i != reference);
    DVector::from_iterator(
        clean.len(),
        clean.iter().zip(others).map(|(c, i)| c + toa[i] - toa[reference]),
    )
}

#[test]
fn chan_agrees_with_the_maximum_likelihood_fix_at_small_noise() {
    let pentagon: Vec<[f64; 2]> = (0..5)
        .map(|k| {
            let a = k as f64 * core::f64::consts::TAU / 5.0;
            [40.0 * a.cos(), 40.0 * a.sin()]
        })
        .collect();
    let cases: [Case<'_>; 5] = [
        (&pentagon, 0, Vector2::new(7.0, 11.0)),
        (&pentagon, 2, Vector2::new(-15.0, -22.0)),
        (&pentagon, 4, Vector2::new(55.0, 30.0)),
        (
            &[[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]],
            3,
            Vector2::new(1200.0, 800.0),
        ),
        (
            &[[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]],
            1,
            Vector2::new(-1000.0, 2000.0),
        ),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(1994);
    for (stations, reference, truth) in cases {
        let size_m = stations.iter().map(|s| s[0].abs().max(s[1].abs())).fold(0.0, f64::max);
        // Chan − ML is second order in the noise, so relative to the position standard
        // deviation it shrinks linearly with σ: check both its size and its scaling.
        let mut mean_ratio = [0.0; 2];
        for (slot, relative_sigma) in [1e-5, 1e-4].into_iter().enumerate() {
            let sigma_m = relative_sigma * size_m;
            let q = differenced_range_covariance(&vec![sigma_m * sigma_m; stations.len()], reference).unwrap();
            let q_inv = q.clone().try_inverse().unwrap();
            let position_sigma_m = crlb(stations, reference, &q_inv, &truth).trace().sqrt();
            let runs = 200;
            for _ in 0..runs {
                let r = noisy_differences(stations, reference, &truth, sigma_m, &mut rng);
                let fix = chan(stations, reference, r.as_slice(), &q).unwrap().fix;
                let ml = maximum_likelihood(stations, reference, &r, &q_inv, truth);
                let (ml_cost, chan_cost) = (
                    cost(stations, reference, &r, &q_inv, &ml),
                    cost(stations, reference, &r, &q_inv, &fix.position),
                );
                assert!(
                    ml_cost <= chan_cost * (1.0 + 1e-9) + 1e-12,
                    "the ml minimiser is not a minimum"
                );
                let ratio = (fix.position - ml).norm() / position_sigma_m;
                if slot == 0 {
                    assert!(
                        ratio < 0.01,
                        "{} stations, reference {reference}, truth {truth:?}: chan {:?} vs ml {ml:?} ({ratio} σ)",
                        stations.len(),
                        fix.position
                    );
                }
                mean_ratio[slot] += ratio / runs as f64;
            }
        }
        let growth = mean_ratio[1] / mean_ratio[0];
        assert!(
            (5.0..20.0).contains(&growth),
            "{} stations, reference {reference}: chan − ml does not scale as σ² (×{growth} for ×10 σ; {mean_ratio:?})",
            stations.len()
        );
    }
}

/// Monte Carlo statistics of Chan's fixes at one geometry.
struct MonteCarlo {
    empirical: Matrix2<f64>,
    mean_reported: Matrix2<f64>,
    bound: Matrix2<f64>,
    mean_error: Vector2<f64>,
    mean_nees: f64,
}

fn monte_carlo(
    stations: &[[f64; 2]],
    reference: usize,
    truth: Vector2<f64>,
    sigma_m: f64,
    runs: usize,
    seed: u64,
) -> MonteCarlo {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let q = differenced_range_covariance(&vec![sigma_m * sigma_m; stations.len()], reference).unwrap();
    let q_inv = q.clone().try_inverse().unwrap();
    let mut errors = Vec::with_capacity(runs);
    let mut mean_reported = Matrix2::zeros();
    let mut nees = 0.0;
    for _ in 0..runs {
        let r = noisy_differences(stations, reference, &truth, sigma_m, &mut rng);
        let fix = chan(stations, reference, r.as_slice(), &q).unwrap().fix;
        let e = fix.position - truth;
        nees += (e.transpose() * fix.covariance.try_inverse().unwrap() * e)[(0, 0)];
        mean_reported += fix.covariance;
        errors.push(e);
    }
    let n = runs as f64;
    let mean_error = errors.iter().sum::<Vector2<f64>>() / n;
    let empirical = errors
        .iter()
        .map(|e| (e - mean_error) * (e - mean_error).transpose())
        .sum::<Matrix2<f64>>()
        / (n - 1.0);
    MonteCarlo {
        empirical,
        mean_reported: mean_reported / n,
        bound: crlb(stations, reference, &q_inv, &truth),
        mean_error,
        mean_nees: nees / n,
    }
}

#[test]
fn monte_carlo_covariance_matches_the_reported_covariance_and_the_crlb() {
    // Seed 004-like cellular geometry (3 km square, σ = 0.3 m ≈ 1 ns) and a small indoor array
    // (σ = 1 cm). The noise must be small relative to the distances *as seen by step 1*: its
    // intermediate (x, y, r_ref) is 10–30× noisier than the final fix, and once that error
    // is a few % of r_ref, Chan's second-order bias shows (already at σ = 10 m, a third of seed 004's 100 ns,
    // the square's first case has an empirical covariance 2.6× the bound).
    let square = [[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]];
    let hexagon = [
        [0.0, 0.0],
        [12.0, 1.0],
        [20.0, 9.0],
        [15.0, 22.0],
        [3.0, 18.0],
        [-4.0, 8.0],
    ];
    let cases: [NoisyCase<'_>; 4] = [
        (&square, 0, Vector2::new(1200.0, 800.0), 0.3),
        (&square, 3, Vector2::new(-1000.0, 2000.0), 0.3),
        (&hexagon, 2, Vector2::new(7.0, 12.0), 0.01),
        (&hexagon, 5, Vector2::new(30.0, -6.0), 0.01),
    ];
    for (k, (stations, reference, truth, sigma_m)) in cases.into_iter().enumerate() {
        let mc = monte_carlo(stations, reference, truth, sigma_m, 2500, 4000 + k as u64);
        let empirical = mc.empirical.trace();
        let reported = mc.mean_reported.trace();
        let bound = mc.bound.trace();
        let context = format!(
            "case {k}: empirical {empirical:.4e}, reported {reported:.4e}, crlb {bound:.4e}, bias {:?}, nees {:.3}",
            mc.mean_error, mc.mean_nees
        );
        assert!((0.8..1.25).contains(&(empirical / reported)), "{context}");
        assert!((0.8..1.25).contains(&(empirical / bound)), "{context}");
        // reported covariance ≈ CRLB at the truth (first order)
        assert!((0.9..1.1).contains(&(reported / bound)), "{context}");
        // per-element agreement (not only the trace): ‖C_emp − C_crlb‖ small vs ‖C_crlb‖
        assert!((mc.empirical - mc.bound).norm() < 0.15 * mc.bound.norm(), "{context}");
        // consistency: E[eᵀ P⁻¹ e] = 2 (±3 standard errors of √(4/2500) = 0.04, plus 5 % margin)
        assert!((1.8..2.2).contains(&mc.mean_nees), "{context}");
        // no bias beyond second order: |ē| < 0.1 σ_position
        assert!(mc.mean_error.norm() < 0.1 * bound.sqrt(), "{context}");
    }
}
