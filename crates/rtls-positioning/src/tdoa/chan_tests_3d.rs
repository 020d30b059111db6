//! Unit tests of Chan's estimator in space: noise-free recovery over random geometries for
//! every reference station, the four-station exact solution, equivalence of step 2 and the
//! covariance with the printed forms, and the degenerate inputs. Monte Carlo statistics are in
//! `tests/chan_statistics.rs`.

use super::*;
use crate::tdoa::{chan_taylor, differenced_range_covariance, range_differences_at, taylor};
use nalgebra::{Matrix3, Matrix4x3, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::tests::crlb;

/// Thinnest extent of the stations relative to their size: the smallest singular value of the
/// centred station matrix over the largest.
fn flatness(stations: &[[f64; 3]]) -> f64 {
    let n = stations.len() as f64;
    let centre = stations.iter().fold(Vector3::zeros(), |a, s| a + Vector3::from(*s)) / n;
    let centred = DMatrix::from_fn(stations.len(), 3, |i, k| stations[i][k] - centre[k]);
    let sv = centred.singular_values();
    sv.min() / sv.max()
}

/// A random site: `n` stations uniform in a cube of side `L` (10 m to 3 km), not too flat
/// (a well-posed geometry; near-flat ones are tested separately).
fn random_site(rng: &mut ChaCha8Rng, n: usize) -> (Vec<[f64; 3]>, f64) {
    let size_m = 10f64.powf(rng.gen_range(1.0..3.5));
    loop {
        let stations: Vec<[f64; 3]> = (0..n)
            .map(|_| {
                [
                    rng.gen_range(0.0..size_m),
                    rng.gen_range(0.0..size_m),
                    rng.gen_range(0.0..size_m),
                ]
            })
            .collect();
        if flatness(&stations) > 0.15 {
            return (stations, size_m);
        }
    }
}

/// A random tag in a box 1.5× the site around its centre, at least 2 % of the site size away
/// from every station (at a station the TDOA Jacobian is undefined).
fn random_tag(rng: &mut ChaCha8Rng, stations: &[[f64; 3]], size_m: f64) -> Vector3<f64> {
    loop {
        let p = Vector3::from_fn(|_, _| rng.gen_range(-0.25 * size_m..1.25 * size_m));
        if stations.iter().all(|s| (p - Vector3::from(*s)).norm() > 0.02 * size_m) {
            return p;
        }
    }
}

#[test]
fn noise_free_recovery_over_random_spatial_geometries_for_every_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut checked = 0;
    let mut worst = 0.0_f64;
    for case in 0..240 {
        let n = 5 + case % 4; // 5 to 8 stations
        let (stations, size_m) = random_site(&mut rng, n);
        let truth = random_tag(&mut rng, &stations, size_m);
        let q = differenced_range_covariance(&vec![1e-4 * size_m * size_m; n], 0).unwrap();
        for reference in 0..n {
            let r = range_differences_at(&stations, reference, &truth).unwrap();
            let solution = chan(&stations, reference, &r, &q).unwrap();
            let error = (solution.fix.position - truth).norm() / size_m;
            worst = worst.max(error);
            assert!(
                error < 1e-7,
                "case {case}, {n} stations, reference {reference}, truth {truth:?}: relative error {error}"
            );
            assert!(solution.alternative.is_none());
            // the covariance is the CRLB at the truth
            let bound = crlb(&stations, reference, &truth, &q);
            assert!(
                (solution.fix.covariance - bound).amax() < 1e-6 * bound.amax(),
                "case {case}, reference {reference}"
            );
            // and the ML refinement stays there
            let refined = chan_taylor(&stations, reference, &r, &q).unwrap();
            assert!((refined.position - truth).norm() / size_m < 1e-7);
            checked += 1;
        }
    }
    assert_eq!(checked, 60 * (5 + 6 + 7 + 8));
    assert!(worst < 1e-7, "worst relative error {worst}");
}

#[test]
fn four_stations_exact_solution_contains_the_truth_for_every_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(44);
    let mut ambiguous = 0;
    let mut total = 0;
    for case in 0..150 {
        let (stations, size_m) = random_site(&mut rng, 4);
        let truth = random_tag(&mut rng, &stations, size_m);
        let q = differenced_range_covariance(&[1.0; 4], 0).unwrap();
        for reference in 0..4 {
            let r = range_differences_at(&stations, reference, &truth).unwrap();
            let solution = chan(&stations, reference, &r, &q).unwrap();
            let candidates: Vec<Vector3<f64>> = core::iter::once(solution.fix)
                .chain(solution.alternative)
                .map(|f| f.position)
                .collect();
            let best = candidates
                .iter()
                .map(|c| (c - truth).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                best < 1e-7 * size_m,
                "case {case}, reference {reference}, truth {truth:?}: {candidates:?}"
            );
            // every candidate reproduces the measurements
            for c in &candidates {
                let predicted = range_differences_at(&stations, reference, c).unwrap();
                for (a, b) in predicted.iter().zip(&r) {
                    assert!((a - b).abs() < 1e-7 * size_m, "candidate {c:?} does not fit");
                }
            }
            // the prior picks the truth
            let near = truth + Vector3::repeat(1e-3 * size_m);
            assert!((solution.closest_to(&near).position - truth).norm() < 1e-7 * size_m);
            ambiguous += usize::from(solution.is_ambiguous());
            total += 1;
        }
    }
    assert!(ambiguous > 0 && ambiguous < total, "ambiguous {ambiguous} of {total}");
}

#[test]
fn spatial_step_two_equals_the_printed_weighted_least_squares() {
    let stations = [
        [0.0, 0.0, 3.0],
        [20.0, 0.0, 3.0],
        [20.0, 15.0, 2.5],
        [0.0, 15.0, 3.0],
        [10.0, 0.0, 0.5],
        [10.0, 15.0, 0.5],
    ];
    let q = differenced_range_covariance(&[0.04; 6], 1).unwrap();
    let truth = Vector3::new(7.0, 9.0, 1.0);
    let mut r = range_differences_at(&stations, 1, &truth).unwrap();
    for (k, v) in r.iter_mut().enumerate() {
        *v += 0.05 * ((k as f64) * 1.7).sin();
    }
    let problem = Problem::new(&stations, 1, &r, &q).unwrap();
    let (z_a, fisher) = problem.step_one().unwrap();
    let implemented = step_two::<3>(&z_a, &fisher, problem.scale_m).unwrap();
    // Printed form: h' = z_a ⊙ z_a, G' = [I₃; 1 1 1], B' = diag(z_a), Ψ' = 4 B' F⁻¹ B',
    // z' = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h', p = sign ⊙ √z'.
    let z_a = Vector4::from_column_slice(z_a.as_slice());
    let fisher = nalgebra::Matrix4::from_column_slice(fisher.as_slice());
    let h2 = z_a.component_mul(&z_a);
    let g2 = Matrix4x3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0);
    let b2 = nalgebra::Matrix4::from_diagonal(&z_a);
    let w2 = (b2 * fisher.try_inverse().unwrap() * b2 * 4.0).try_inverse().unwrap();
    let z2 = (g2.transpose() * w2 * g2).try_inverse().unwrap() * g2.transpose() * w2 * h2;
    assert!(z2.iter().all(|&c| c > 0.0));
    let printed = Vector3::from_fn(|i, _| z_a[i].signum() * z2[i].sqrt());
    assert!((implemented - printed).norm() < 1e-9, "{implemented:?} vs {printed:?}");
    assert!((implemented - z_a.xyz()).norm() > 1e-6, "step 2 must move the estimate");
}

#[test]
fn spatial_covariance_equals_the_printed_step_two_covariance() {
    let stations = [
        [0.0, 0.0, 0.0],
        [30.0, 0.0, 5.0],
        [30.0, 30.0, 0.0],
        [0.0, 30.0, 5.0],
        [15.0, 15.0, 25.0],
    ];
    let q = differenced_range_covariance(&[0.01, 0.02, 0.015, 0.01, 0.03], 2).unwrap();
    let truth = Vector3::new(11.0, 7.0, 4.0);
    let r = range_differences_at(&stations, 2, &truth).unwrap();
    let problem = Problem::new(&stations, 2, &r, &q).unwrap();
    let p = truth - Vector3::from(stations[2]);
    let implemented = problem.covariance_at(&p).unwrap();
    // Printed: Φ = ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹, Ψ' = 4 B' cov(z_a) B', all at the fix.
    let b = DMatrix::from_diagonal(&DVector::from_iterator(
        4,
        problem.others_m.iter().map(|s| (p - s).norm()),
    ));
    let psi = &b * &q * &b;
    let cov_za = (problem.g.transpose() * psi.try_inverse().unwrap() * &problem.g)
        .try_inverse()
        .unwrap();
    let b1 = DMatrix::from_diagonal(&DVector::from_column_slice(&[p.x, p.y, p.z, p.norm()]));
    let psi2 = &b1 * cov_za * &b1 * 4.0;
    let g2 = DMatrix::from_row_slice(4, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
    let cov_z2 = (g2.transpose() * psi2.try_inverse().unwrap() * &g2)
        .try_inverse()
        .unwrap();
    let b2_inv = Matrix3::from_diagonal(&Vector3::new(1.0 / p.x, 1.0 / p.y, 1.0 / p.z));
    let printed = b2_inv * Matrix3::from_column_slice(cov_z2.as_slice()) * b2_inv * 0.25;
    assert!(
        (implemented - printed).amax() < 1e-9 * printed.amax(),
        "{implemented} vs {printed}"
    );
    let bound = crlb(&stations, 2, &truth, &q);
    assert!((implemented - bound).amax() < 1e-9 * bound.amax());
}

#[test]
fn spatial_error_paths() {
    let hall = [
        [0.0, 0.0, 3.0],
        [20.0, 0.0, 3.0],
        [20.0, 15.0, 3.0],
        [0.0, 15.0, 0.5],
        [10.0, 7.5, 0.5],
    ];
    let tag = Vector3::new(6.0, 4.0, 1.2);
    let q4 = differenced_range_covariance(&[0.01; 5], 0).unwrap();
    let q3 = differenced_range_covariance(&[0.01; 4], 0).unwrap();
    let q2 = differenced_range_covariance(&[0.01; 3], 0).unwrap();
    let r4 = range_differences_at(&hall, 0, &tag).unwrap();

    // three stations cannot fix a point in space (four are the minimum)
    let r2 = range_differences_at(&hall[..3], 0, &tag).unwrap();
    assert_eq!(
        chan(&hall[..3], 0, &r2, &q2),
        Err(PositioningError::Underdetermined { anchors: 3, needed: 4 })
    );
    assert_eq!(
        chan_taylor(&hall[..3], 0, &r2, &q2),
        Err(PositioningError::Underdetermined { anchors: 3, needed: 4 })
    );
    assert_eq!(
        taylor(&hall[..3], 0, &r2, &q2, &tag),
        Err(PositioningError::Underdetermined { anchors: 3, needed: 4 })
    );

    // coplanar: every anchor at the ceiling height (5 and 4 stations), and a tilted plane
    let ceiling = [
        [0.0, 0.0, 3.0],
        [20.0, 0.0, 3.0],
        [20.0, 15.0, 3.0],
        [0.0, 15.0, 3.0],
        [10.0, 7.5, 3.0],
    ];
    let tilted: Vec<[f64; 3]> = ceiling
        .iter()
        .map(|s| [s[0], s[1], 0.3 * s[0] - 0.2 * s[1] + 1.0])
        .collect();
    for stations in [&ceiling[..], &tilted[..]] {
        for reference in 0..5 {
            let r = range_differences_at(stations, reference, &tag).unwrap();
            assert!(
                matches!(
                    chan(stations, reference, &r, &q4),
                    Err(PositioningError::DegenerateGeometry { .. })
                ),
                "coplanar stations, reference {reference}"
            );
            assert!(matches!(
                chan_taylor(stations, reference, &r, &q4),
                Err(PositioningError::DegenerateGeometry { .. })
            ));
            let r3 = range_differences_at(&stations[..4], reference % 4, &tag).unwrap();
            assert!(matches!(
                chan(&stations[..4], reference % 4, &r3, &q3),
                Err(PositioningError::DegenerateGeometry { .. })
            ));
        }
    }
    // collinear stations are coplanar too
    let line: Vec<[f64; 3]> = (0..5).map(|k| [k as f64, 2.0 * k as f64, 3.0 - k as f64]).collect();
    let r_line = range_differences_at(&line, 2, &tag).unwrap();
    assert!(matches!(
        chan(&line, 2, &r_line, &q4),
        Err(PositioningError::DegenerateGeometry { .. })
    ));

    // duplicate stations
    let mut twin = hall;
    twin[4] = twin[1];
    assert_eq!(
        chan(&twin, 0, &r4, &q4),
        Err(PositioningError::DuplicateAnchors { first: 1, second: 4 })
    );
    assert_eq!(
        chan_taylor(&twin, 3, &r4, &q4),
        Err(PositioningError::DuplicateAnchors { first: 1, second: 4 })
    );

    // non-finite inputs
    let mut bad = hall;
    bad[3][2] = f64::NAN;
    assert!(matches!(
        chan(&bad, 0, &r4, &q4),
        Err(PositioningError::NonFiniteEntry { row: 3, column: 2, .. })
    ));
    assert!(matches!(
        chan(&hall, 0, &[r4[0], r4[1], f64::NAN, r4[3]], &q4),
        Err(PositioningError::NonFinite {
            what: "range differences"
        })
    ));
    assert!(matches!(
        taylor(&hall, 0, &r4, &q4, &Vector3::new(1.0, f64::INFINITY, 0.0)),
        Err(PositioningError::NonFinite { .. })
    ));

    // sizes and reference
    assert!(matches!(
        chan(&hall, 0, &r4[..3], &q4),
        Err(PositioningError::DimensionMismatch {
            expected: 4,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        chan(&hall, 5, &r4, &q4),
        Err(PositioningError::InvalidParameter { name: "reference", .. })
    ));

    // a tag at a station
    let at = Vector3::from(hall[2]);
    let r_at = range_differences_at(&hall, 0, &at).unwrap();
    assert!(matches!(
        chan(&hall, 0, &r_at, &q4),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}

#[test]
fn taylor_resolves_the_coplanar_mirror_ambiguity_from_the_guess() {
    let ceiling = [
        [0.0, 0.0, 3.0],
        [20.0, 0.0, 3.0],
        [20.0, 15.0, 3.0],
        [0.0, 15.0, 3.0],
        [10.0, 7.5, 3.0],
    ];
    let tag = Vector3::new(6.0, 4.0, 1.2);
    let mirror = Vector3::new(6.0, 4.0, 4.8);
    let q = differenced_range_covariance(&[1e-4; 5], 2).unwrap();
    let r = range_differences_at(&ceiling, 2, &tag).unwrap();
    let below = taylor(&ceiling, 2, &r, &q, &Vector3::new(10.0, 7.5, 0.0)).unwrap();
    assert!((below.position - tag).norm() < 1e-6, "{:?}", below.position);
    let above = taylor(&ceiling, 2, &r, &q, &Vector3::new(10.0, 7.5, 6.0)).unwrap();
    assert!((above.position - mirror).norm() < 1e-6, "{:?}", above.position);
    // the two minima have the same covariance up to the sign of the z correlations
    assert!((below.covariance[(2, 2)] - above.covariance[(2, 2)]).abs() < 1e-9 * below.covariance[(2, 2)]);
    // a guess in the plane of the stations cannot leave it
    assert!(matches!(
        taylor(&ceiling, 2, &r, &q, &Vector3::new(8.0, 6.0, 3.0)),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}

#[test]
fn spatial_fix_is_invariant_to_translating_the_site() {
    let stations = [
        [0.0, 0.0, 0.0],
        [30.0, 0.0, 5.0],
        [30.0, 30.0, 0.0],
        [0.0, 30.0, 5.0],
        [15.0, 15.0, 25.0],
        [5.0, 20.0, 12.0],
    ];
    let shift = Vector3::new(-4.0e5, 2.5e5, 1.0e3);
    let moved: Vec<[f64; 3]> = stations.iter().map(|s| (Vector3::from(*s) + shift).into()).collect();
    let q = differenced_range_covariance(&[0.01; 6], 4).unwrap();
    let truth = Vector3::new(12.0, 8.0, 3.0);
    let mut r = range_differences_at(&stations, 4, &truth).unwrap();
    r[1] += 0.1;
    r[3] -= 0.07;
    let here = chan(&stations, 4, &r, &q).unwrap().fix;
    let there = chan(&moved, 4, &r, &q).unwrap().fix;
    assert!((there.position - shift - here.position).norm() < 1e-6);
    assert!((there.covariance - here.covariance).amax() < 1e-6 * here.covariance.amax());
}
