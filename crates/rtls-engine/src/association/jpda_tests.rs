//! JPDA marginals against an independent brute-force enumeration, and the combined update
//! against the textbook spread-of-innovations form.

use nalgebra::{DVector, Matrix2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::jpda::{combine, jpda_marginals, JpdaMarginals, JpdaOutcome};
use super::test_support::brute_force_jpda as brute_force;
use crate::error::EngineError;

fn marginals(log_ratios: &[Vec<(usize, f64)>], miss: f64) -> JpdaMarginals {
    match jpda_marginals(log_ratios, miss.ln(), 1_000_000).unwrap() {
        JpdaOutcome::Marginals(m) => m,
        other => panic!("{other:?}"),
    }
}

#[test]
fn two_tracks_three_detections_by_hand() {
    // L(t0,d0) = 4, L(t0,d1) = 1, L(t1,d1) = 2, L(t1,d2) = 3, 1 − P_D P_G = 0.1.
    // The 8 feasible events (t0, t1) and weights:
    // (–,–) 0.01  (–,d1) 0.2  (–,d2) 0.3  (d0,–) 0.4  (d0,d1) 8  (d0,d2) 12  (d1,–) 0.1  (d1,d2) 3
    // total 24.01.
    let ratios = [vec![(0, 4f64.ln()), (1, 0.0)], vec![(1, 2f64.ln()), (2, 3f64.ln())]];
    let m = marginals(&ratios, 0.1);
    let total = 24.01;
    assert_eq!(m.events, 8);
    let expect = |got: f64, want: f64| assert!((got - want / total).abs() < 1e-12, "{got} vs {}", want / total);
    expect(m.association[0][0].1, 0.4 + 8.0 + 12.0);
    expect(m.association[0][1].1, 0.1 + 3.0);
    expect(m.miss[0], 0.01 + 0.2 + 0.3);
    expect(m.association[1][0].1, 0.2 + 8.0);
    expect(m.association[1][1].1, 0.3 + 12.0 + 3.0);
    expect(m.miss[1], 0.01 + 0.4 + 0.1);
    assert_eq!((m.association[1][0].0, m.association[1][1].0), (1, 2));

    // the same numbers from the independent enumeration
    let table = vec![vec![Some(4.0), Some(1.0), None], vec![None, Some(2.0), Some(3.0)]];
    let (miss, pair, events) = brute_force(&table, 3, 0.1);
    assert_eq!(events, 8);
    assert!((miss[0] - m.miss[0]).abs() < 1e-12 && (miss[1] - m.miss[1]).abs() < 1e-12);
    assert!((pair[1][2] - m.association[1][1].1).abs() < 1e-12);
}

#[test]
fn random_clusters_match_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for case in 0..200 {
        let tracks = rng.gen_range(1..=4);
        let detections = rng.gen_range(0..=5);
        let miss = rng.gen_range(0.01..0.5);
        let table: Vec<Vec<Option<f64>>> = (0..tracks)
            .map(|_| {
                (0..detections)
                    .map(|_| rng.gen_bool(0.6).then(|| rng.gen_range(1e-3f64..50.0)))
                    .collect()
            })
            .collect();
        let ratios: Vec<Vec<(usize, f64)>> = table
            .iter()
            .map(|row| {
                row.iter()
                    .enumerate()
                    .filter_map(|(d, l)| l.map(|l| (d, l.ln())))
                    .collect()
            })
            .collect();
        let m = marginals(&ratios, miss);
        let (miss_bf, pair_bf, events) = brute_force(&table, detections, miss);
        assert_eq!(m.events, events, "case {case}");
        for t in 0..tracks {
            assert!((m.miss[t] - miss_bf[t]).abs() < 1e-12, "case {case} track {t}");
            let mut sum = m.miss[t];
            for &(d, beta) in &m.association[t] {
                assert!((beta - pair_bf[t][d]).abs() < 1e-12, "case {case} ({t}, {d})");
                sum += beta;
            }
            assert!((sum - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn one_track_is_the_pda() {
    // β_d = L_d / (1 − P_D P_G + Σ L), β₀ = (1 − P_D P_G) / (1 − P_D P_G + Σ L)
    let l = [0.5f64, 3.0, 7.0];
    let miss = 0.05;
    let ratios = [l.iter().enumerate().map(|(d, l)| (d, l.ln())).collect::<Vec<_>>()];
    let m = marginals(&ratios, miss);
    let denominator = miss + l.iter().sum::<f64>();
    for (d, &(_, beta)) in m.association[0].iter().enumerate() {
        assert!((beta - l[d] / denominator).abs() < 1e-12);
    }
    assert!((m.miss[0] - miss / denominator).abs() < 1e-12);
}

#[test]
fn extreme_log_ratios_neither_overflow_nor_underflow() {
    let ratios = [vec![(0, 800.0), (1, -800.0)], vec![(0, 790.0)]];
    let m = marginals(&ratios, 1e-3);
    // events (t0, t1): (d0, –) e^{800}·m dominates (d1, d0) e^{−10}, (–, d0) e^{790}·m
    assert!((m.association[0][0].1 - 1.0).abs() < 1e-4);
    assert!(m.miss[1] > 0.9999);
    assert!(m.association.iter().flatten().all(|(_, b)| b.is_finite()));
}

#[test]
fn too_many_events_and_bad_input() {
    // 3 tracks × 3 detections, all gated: Σ_k C(3,k)² k! = 1 + 9 + 18 + 6 = 34 events
    let full: Vec<Vec<(usize, f64)>> = (0..3).map(|_| (0..3).map(|d| (d, 0.0)).collect()).collect();
    assert!(matches!(jpda_marginals(&full, 0.1f64.ln(), 34).unwrap(), JpdaOutcome::Marginals(m) if m.events == 34));
    assert_eq!(
        jpda_marginals(&full, 0.1f64.ln(), 33).unwrap(),
        JpdaOutcome::TooManyEvents { limit: 33 }
    );
    let name = |e: EngineError| match e {
        EngineError::InvalidParameter { name, .. } => name,
        other => panic!("{other}"),
    };
    assert_eq!(
        name(jpda_marginals(&[vec![(0, f64::NAN)]], -1.0, 10).unwrap_err()),
        "log_ratios"
    );
    assert_eq!(
        name(jpda_marginals(&[vec![(0, 1.0), (0, 2.0)]], -1.0, 10).unwrap_err()),
        "log_ratios"
    );
    assert_eq!(
        name(jpda_marginals(&[vec![(0, 1.0)]], f64::NEG_INFINITY, 10).unwrap_err()),
        "ln_miss"
    );
}

#[test]
fn combined_update_equals_the_spread_of_innovations_form() {
    // common H and R: x = x⁻ + K ν, P = β₀ P⁻ + (1 − β₀) P_c + K (Σ β ν νᵀ − ν νᵀ) Kᵀ
    let prior = Gaussian::new(
        Vector::<4>::new(1.0, 0.5, 2.0, -0.3),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(0.3, 0.2, 0.4, 0.1)) + {
            let mut c = Matrix::<4>::zeros();
            c[(0, 1)] = 0.05;
            c[(1, 0)] = 0.05;
            c[(0, 2)] = 0.02;
            c[(2, 0)] = 0.02;
            c
        },
        3.0,
    )
    .unwrap();
    let model = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 0.05).unwrap()).unwrap();
    let kf = KalmanFilter::default();
    let z = [[1.3, 1.8], [0.6, 2.4], [1.1, 2.05]];
    let beta = [0.5, 0.2, 0.25];
    let beta0 = 1.0 - beta.iter().sum::<f64>();
    let posteriors: Vec<(f64, Gaussian<4>)> = z
        .iter()
        .zip(beta)
        .map(|(z, b)| {
            (
                b,
                kf.update(&prior, &model, &DVector::from_column_slice(z)).unwrap().state,
            )
        })
        .collect();
    let combined = combine(&prior, beta0, &posteriors).unwrap();

    // textbook, from K = P Hᵀ S⁻¹ computed here with 2 × 2 algebra
    let p = prior.covariance();
    let s = Matrix2::new(p[(0, 0)] + 0.05, p[(0, 2)], p[(2, 0)], p[(2, 2)] + 0.05);
    let pht = nalgebra::Matrix4x2::from_columns(&[p.column(0).into_owned(), p.column(2).into_owned()]);
    let k = pht * s.try_inverse().unwrap();
    let innovations: Vec<Vector2<f64>> = z
        .iter()
        .map(|z| Vector2::new(z[0] - prior.mean()[0], z[1] - prior.mean()[2]))
        .collect();
    let nu: Vector2<f64> = innovations.iter().zip(beta).map(|(v, b)| v * b).sum();
    let mean = prior.mean() + k * nu;
    let p_c = posteriors[0].1.covariance();
    let spread: Matrix2<f64> = innovations
        .iter()
        .zip(beta)
        .map(|(v, b)| v * v.transpose() * b)
        .sum::<Matrix2<f64>>()
        - nu * nu.transpose();
    let covariance = p * beta0 + p_c * (1.0 - beta0) + k * spread * k.transpose();
    assert!((combined.mean() - mean).amax() < 1e-12);
    assert!((combined.covariance() - covariance).amax() < 1e-12);
    assert_eq!(combined.time_s(), 3.0);
    // every detection has the same posterior covariance in the common-R case
    assert!((posteriors[1].1.covariance() - p_c).amax() < 1e-14);
}
