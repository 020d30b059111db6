//! Tests of the path-loss calibration: exact recovery, agreement of the reported standard
//! errors with the Monte Carlo spread of the estimates, equivalence of the shared-exponent
//! closed form with a direct least-squares solve, and every error path.

use super::*;
use crate::pathloss::PathLossModel;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Survey distances (m): 1–60 m, unevenly spaced.
const DISTANCES_M: [f64; 12] = [1.0, 1.5, 2.0, 3.0, 4.5, 6.0, 8.0, 12.0, 18.0, 25.0, 40.0, 60.0];

fn law(rho_t: f64, eta: f64, d0: f64, sigma: f64) -> LogDistance {
    LogDistance::new(rho_t, eta, d0, sigma).unwrap()
}

/// `[d, μ(d) + noise]` at the survey distances.
fn survey(model: &LogDistance, noise: Option<(&Normal<f64>, &mut ChaCha8Rng)>) -> Vec<[f64; 2]> {
    match noise {
        None => DISTANCES_M.iter().map(|&d| [d, model.mean_rssi_dbm(d)]).collect(),
        Some((normal, rng)) => DISTANCES_M
            .iter()
            .map(|&d| [d, model.mean_rssi_dbm(d) + normal.sample(rng)])
            .collect(),
    }
}

#[test]
fn noise_free_samples_are_recovered_exactly() {
    let truth = law(-37.5, 2.8, 2.0, 0.0);
    let fit = fit_log_distance(&survey(&truth, None), 2.0).unwrap();
    assert!((fit.model.reference_rssi_dbm() + 37.5).abs() < 1e-10);
    assert!((fit.model.exponent() - 2.8).abs() < 1e-12);
    assert_eq!(fit.model.reference_distance_m(), 2.0);
    assert!(fit.model.shadowing_std_db() < 1e-10);
    assert!(fit.exponent_std_error < 1e-10 && fit.reference_rssi_std_error_db < 1e-10);
    assert_eq!(fit.samples, DISTANCES_M.len());

    // per anchor, shared, shared exponent: three anchors with different ρ_T, one η
    let offsets = [-30.0, -36.0, -33.5];
    let samples: Vec<RssiSample> = offsets
        .iter()
        .enumerate()
        .flat_map(|(anchor, &rho_t)| {
            let model = law(rho_t, 3.1, 1.0, 0.0);
            DISTANCES_M.iter().map(move |&d| RssiSample {
                anchor,
                distance_m: d,
                rssi_dbm: model.mean_rssi_dbm(d),
            })
        })
        .collect();
    let per_anchor = fit_per_anchor(&samples, 4, 1.0).unwrap();
    assert_eq!(per_anchor.len(), 4);
    for (a, &rho_t) in offsets.iter().enumerate() {
        let fit = per_anchor[a].as_ref().unwrap();
        assert!((fit.model.reference_rssi_dbm() - rho_t).abs() < 1e-10);
        assert!((fit.model.exponent() - 3.1).abs() < 1e-12);
    }
    assert_eq!(
        per_anchor[3],
        Err(PositioningError::TooFewSamples { found: 0, needed: 3 })
    );
    let shared = fit_shared_exponent(&samples, 4, 1.0).unwrap();
    assert!((shared.exponent - 3.1).abs() < 1e-12);
    assert!(shared.shadowing_std_db < 1e-10);
    for (a, &rho_t) in offsets.iter().enumerate() {
        let offset = shared.offsets[a].unwrap();
        assert!((offset.reference_rssi_dbm - rho_t).abs() < 1e-10);
        assert_eq!(offset.samples, DISTANCES_M.len());
        assert!(
            (shared.model(a).unwrap().mean_rssi_dbm(7.0) - law(rho_t, 3.1, 1.0, 0.0).mean_rssi_dbm(7.0)).abs() < 1e-9
        );
    }
    assert!(shared.offsets[3].is_none() && shared.model(3).is_none() && shared.model(9).is_none());
    // pooled: one model cannot fit three offsets, and says so through σ̂_X
    let pooled = fit_shared(&samples, 1.0).unwrap();
    assert!((pooled.model.exponent() - 3.1).abs() < 1e-9);
    assert!((pooled.model.reference_rssi_dbm() - offsets.iter().sum::<f64>() / 3.0).abs() < 1e-9);
    assert!(pooled.model.shadowing_std_db() > 2.0);
}

/// 2000 seeded surveys: the spread of `η̂` and `ρ̂_T` equals the reported standard errors
/// (root mean square over the trials) within 10 %, their correlation matches, and `σ̂_X²` is
/// unbiased.
#[test]
fn standard_errors_match_the_monte_carlo_spread() {
    let truth = law(-42.0, 2.6, 1.0, 4.0);
    let noise = Normal::new(0.0, 4.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2002);
    let trials = 2000;
    let mut estimates = Vec::with_capacity(trials);
    let mut reported = Matrix2::zeros();
    let mut variance_sum = 0.0;
    for _ in 0..trials {
        let fit = fit_log_distance(&survey(&truth, Some((&noise, &mut rng))), 1.0).unwrap();
        estimates.push(nalgebra::Vector2::new(
            fit.model.reference_rssi_dbm(),
            fit.model.exponent(),
        ));
        reported += fit.parameter_covariance / trials as f64;
        variance_sum += fit.model.shadowing_std_db().powi(2);
    }
    let mean = estimates.iter().sum::<nalgebra::Vector2<f64>>() / trials as f64;
    let empirical = estimates
        .iter()
        .map(|e| (e - mean) * (e - mean).transpose())
        .sum::<Matrix2<f64>>()
        / (trials as f64 - 1.0);
    // unbiased estimates
    assert!((mean.x + 42.0).abs() < 4.0 * (empirical[(0, 0)] / trials as f64).sqrt());
    assert!((mean.y - 2.6).abs() < 4.0 * (empirical[(1, 1)] / trials as f64).sqrt());
    // standard errors (rms of the reported ones) vs the spread, within 10 %
    for i in 0..2 {
        let ratio = (empirical[(i, i)] / reported[(i, i)]).sqrt();
        assert!(
            (0.9..1.1).contains(&ratio),
            "parameter {i}: spread / standard error = {ratio}"
        );
    }
    let correlation = |c: &Matrix2<f64>| c[(0, 1)] / (c[(0, 0)] * c[(1, 1)]).sqrt();
    assert!((correlation(&empirical) - correlation(&reported)).abs() < 0.05);
    // E[s²] = σ²
    assert!((variance_sum / trials as f64 / 16.0 - 1.0).abs() < 0.05);
}

/// The same for the shared-exponent fit: `η̂` and one anchor's `ρ̂_T`.
#[test]
fn shared_exponent_standard_errors_match_the_monte_carlo_spread() {
    let offsets = [-30.0, -38.0, -34.0];
    let noise = Normal::new(0.0, 5.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2003);
    let trials = 2000;
    let (mut eta, mut rho) = (Vec::with_capacity(trials), Vec::with_capacity(trials));
    let (mut eta_se2, mut rho_se2, mut variance) = (0.0, 0.0, 0.0);
    for _ in 0..trials {
        // anchor 1 is surveyed at only three distances: its offset leans on the shared η
        let samples: Vec<RssiSample> = offsets
            .iter()
            .enumerate()
            .flat_map(|(anchor, &rho_t)| {
                let distances: &[f64] = if anchor == 1 { &DISTANCES_M[5..8] } else { &DISTANCES_M };
                distances
                    .iter()
                    .map(|&d| RssiSample {
                        anchor,
                        distance_m: d,
                        rssi_dbm: rho_t - 35.0 * d.log10() + noise.sample(&mut rng),
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let fit = fit_shared_exponent(&samples, 3, 1.0).unwrap();
        let offset = fit.offsets[1].unwrap();
        eta.push(fit.exponent);
        rho.push(offset.reference_rssi_dbm);
        eta_se2 += fit.exponent_std_error.powi(2) / trials as f64;
        rho_se2 += offset.std_error_db.powi(2) / trials as f64;
        variance += fit.shadowing_std_db.powi(2) / trials as f64;
    }
    let spread = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (
            m,
            (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() as f64 - 1.0)).sqrt(),
        )
    };
    let (eta_mean, eta_std) = spread(&eta);
    let (rho_mean, rho_std) = spread(&rho);
    assert!((eta_mean - 3.5).abs() < 4.0 * eta_std / (trials as f64).sqrt());
    assert!((rho_mean + 38.0).abs() < 4.0 * rho_std / (trials as f64).sqrt());
    let eta_ratio = eta_std / eta_se2.sqrt();
    let rho_ratio = rho_std / rho_se2.sqrt();
    assert!((0.9..1.1).contains(&eta_ratio), "η spread / se = {eta_ratio}");
    assert!((0.9..1.1).contains(&rho_ratio), "ρ_T spread / se = {rho_ratio}");
    assert!((variance / 25.0 - 1.0).abs() < 0.05);
}

/// The within-anchor closed form equals the least-squares solution of the dummy-variable
/// design `[e_a, x]` solved directly, and its standard errors are `s² (AᵀA)⁻¹`.
#[test]
fn shared_exponent_closed_form_equals_the_direct_least_squares_solution() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 3.0).unwrap();
    let mut samples = Vec::new();
    for (anchor, rho_t, distances) in [
        (0usize, -31.0, &DISTANCES_M[..5]),
        (2, -36.0, &DISTANCES_M[3..]),
        (3, -29.0, &DISTANCES_M[6..7]),
    ] {
        for &d in distances {
            samples.push(RssiSample {
                anchor,
                distance_m: d,
                rssi_dbm: rho_t - 27.0 * (d / 1.5).log10() + noise.sample(&mut rng),
            });
        }
    }
    let fit = fit_shared_exponent(&samples, 4, 1.5).unwrap();
    // columns: ρ_T[0], ρ_T[2], ρ_T[3], η
    let column = |a: usize| match a {
        0 => 0,
        2 => 1,
        _ => 2,
    };
    let n = samples.len();
    let design = DMatrix::from_fn(n, 4, |k, j| {
        let s = &samples[k];
        if j == 3 {
            -10.0 * (s.distance_m / 1.5).log10()
        } else if j == column(s.anchor) {
            1.0
        } else {
            0.0
        }
    });
    let y = DVector::from_iterator(n, samples.iter().map(|s| s.rssi_dbm));
    let normal_inverse = (design.transpose() * &design).try_inverse().unwrap();
    let beta = &normal_inverse * design.transpose() * &y;
    let residual = &y - &design * &beta;
    let s2 = residual.norm_squared() / (n - 4) as f64;
    assert!((fit.exponent - beta[3]).abs() < 1e-9);
    assert!((fit.shadowing_std_db - s2.sqrt()).abs() < 1e-9);
    assert!((fit.exponent_std_error - (s2 * normal_inverse[(3, 3)]).sqrt()).abs() < 1e-9);
    for a in [0, 2, 3] {
        let offset = fit.offsets[a].unwrap();
        let j = column(a);
        assert!((offset.reference_rssi_dbm - beta[j]).abs() < 1e-9, "anchor {a}");
        assert!((offset.std_error_db - (s2 * normal_inverse[(j, j)]).sqrt()).abs() < 1e-9);
    }
    assert!(fit.offsets[1].is_none());
    assert_eq!(fit.offsets[3].unwrap().samples, 1);
}

#[test]
fn error_paths() {
    let good: Vec<[f64; 2]> = vec![[1.0, -40.0], [2.0, -46.0], [4.0, -52.5]];
    // too few samples
    for n in 0..3 {
        assert_eq!(
            fit_log_distance(&good[..n], 1.0),
            Err(PositioningError::TooFewSamples { found: n, needed: 3 })
        );
    }
    // all at one distance
    assert!(matches!(
        fit_log_distance(&[[3.0, -40.0], [3.0, -41.0], [3.0, -39.0]], 1.0),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
    // NaN/∞ entries name row and column
    let mut bad = good.clone();
    bad[2][1] = f64::NAN;
    assert!(matches!(
        fit_log_distance(&bad, 1.0),
        Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
    ));
    let mut bad = good.clone();
    bad[1][0] = f64::INFINITY;
    assert!(matches!(
        fit_log_distance(&bad, 1.0),
        Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
    ));
    // d ≤ 0, d₀ ≤ 0
    let mut bad = good.clone();
    bad[0][0] = 0.0;
    assert!(matches!(
        fit_log_distance(&bad, 1.0),
        Err(PositioningError::InvalidParameter { name: "distance_m", .. })
    ));
    bad[0][0] = -2.0;
    assert!(matches!(
        fit_log_distance(&bad, 1.0),
        Err(PositioningError::InvalidParameter { name: "distance_m", .. })
    ));
    for d0 in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            fit_log_distance(&good, d0),
            Err(PositioningError::InvalidParameter {
                name: "reference_distance_m",
                ..
            })
        ));
    }
    // rssi rising with distance
    assert!(matches!(
        fit_log_distance(&[[1.0, -60.0], [2.0, -50.0], [4.0, -45.0]], 1.0),
        Err(PositioningError::NoConsistentSolution { .. })
    ));

    // multi-anchor tables
    let sample = |anchor: usize, d: f64, rho: f64| RssiSample {
        anchor,
        distance_m: d,
        rssi_dbm: rho,
    };
    let table = vec![
        sample(0, 1.0, -40.0),
        sample(0, 2.0, -46.0),
        sample(1, 1.0, -42.0),
        sample(1, 3.0, -52.0),
        sample(1, 9.0, -61.0),
    ];
    assert!(matches!(
        fit_per_anchor(&table, 1, 1.0),
        Err(PositioningError::InvalidParameter { name: "anchors", .. })
    ));
    assert!(matches!(
        fit_shared_exponent(&table, 1, 1.0),
        Err(PositioningError::InvalidParameter { name: "anchors", .. })
    ));
    let mut bad = table.clone();
    bad[3].rssi_dbm = f64::NAN;
    assert!(matches!(
        fit_per_anchor(&bad, 2, 1.0),
        Err(PositioningError::NonFiniteEntry { row: 3, column: 1, .. })
    ));
    assert!(matches!(
        fit_shared(&bad, 1.0),
        Err(PositioningError::NonFiniteEntry { row: 3, column: 1, .. })
    ));
    assert!(matches!(
        fit_shared_exponent(&bad, 2, 1.0),
        Err(PositioningError::NonFiniteEntry { row: 3, column: 1, .. })
    ));
    let mut bad = table.clone();
    bad[4].distance_m = 0.0;
    assert!(matches!(
        fit_shared_exponent(&bad, 2, 1.0),
        Err(PositioningError::InvalidParameter { name: "distance_m", .. })
    ));
    // per anchor: anchor 0 has two samples (inner error), anchor 1 fits
    let fits = fit_per_anchor(&table, 2, 1.0).unwrap();
    assert_eq!(fits[0], Err(PositioningError::TooFewSamples { found: 2, needed: 3 }));
    assert!(fits[1].is_ok());
    // shared exponent: needs A + 2 samples, and one anchor with two distances
    assert_eq!(
        fit_shared_exponent(&table[..3], 2, 1.0),
        Err(PositioningError::TooFewSamples { found: 3, needed: 4 })
    );
    let one_distance_each = vec![
        sample(0, 2.0, -40.0),
        sample(0, 2.0, -41.0),
        sample(1, 5.0, -50.0),
        sample(1, 5.0, -52.0),
    ];
    assert!(matches!(
        fit_shared_exponent(&one_distance_each, 2, 1.0),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
    let rising = vec![
        sample(0, 1.0, -60.0),
        sample(0, 4.0, -50.0),
        sample(1, 1.0, -62.0),
        sample(1, 4.0, -51.0),
    ];
    assert!(matches!(
        fit_shared_exponent(&rising, 2, 1.0),
        Err(PositioningError::NoConsistentSolution { .. })
    ));
    assert!(fit_shared_exponent(&table, 2, 1.0).is_ok());
}
