//! Unit tests of Chan's estimator: exact recovery, equivalence of the implemented step 2 and
//! covariance with the printed forms, error paths. Statistical tests (agreement with the
//! maximum-likelihood estimate, Monte Carlo covariance) are in `tests/chan_statistics.rs`.

use super::*;
use crate::tdoa::{differenced_range_covariance, range_differences_at};
use nalgebra::{Matrix2, Matrix2x3, Matrix3, SMatrix, SVector, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Station layouts: a square (seed 004-like), a pentagon, an irregular hexagon.
fn layouts() -> Vec<Vec<[f64; 2]>> {
    vec![
        vec![[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0], [3000.0, 3000.0]],
        (0..5)
            .map(|k| {
                let a = k as f64 * core::f64::consts::TAU / 5.0 + 0.3;
                [50.0 + 40.0 * a.cos(), -20.0 + 40.0 * a.sin()]
            })
            .collect(),
        vec![
            [0.0, 0.0],
            [12.0, 1.0],
            [20.0, 9.0],
            [15.0, 22.0],
            [3.0, 18.0],
            [-4.0, 8.0],
        ],
    ]
}

/// Centre and radius of the stations' bounding circle (about the centroid).
fn extent(stations: &[[f64; 2]]) -> (Vector2<f64>, f64) {
    let n = stations.len() as f64;
    let centre = stations
        .iter()
        .fold(Vector2::zeros(), |a: Vector2<f64>, s| a + Vector2::new(s[0], s[1]))
        / n;
    let radius = stations
        .iter()
        .map(|s| (Vector2::new(s[0], s[1]) - centre).norm())
        .fold(0.0, f64::max);
    (centre, radius)
}

/// `(Jᵀ Q⁻¹ J)⁻¹` with `J_i = (p − s_i)ᵀ/r_i − (p − s_ref)ᵀ/r_ref`, in `D` dimensions (the
/// independent reference the 2-D and 3-D tests compare covariances with).
pub(super) fn crlb<const D: usize>(
    stations: &[[f64; D]],
    reference: usize,
    p: &SVector<f64, D>,
    q: &DMatrix<f64>,
) -> SMatrix<f64, D, D> {
    let unit = |s: &[f64; D]| {
        let d = p - SVector::<f64, D>::from(*s);
        d / d.norm()
    };
    let u_ref = unit(&stations[reference]);
    let rows: Vec<SVector<f64, D>> = stations
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != reference)
        .map(|(_, s)| unit(s) - u_ref)
        .collect();
    let j = DMatrix::from_fn(rows.len(), D, |i, k| rows[i][k]);
    let info = j.transpose() * q.clone().try_inverse().unwrap() * j;
    SMatrix::<f64, D, D>::from_column_slice(info.as_slice())
        .try_inverse()
        .unwrap()
}

#[test]
fn noise_free_recovery_inside_and_outside_the_hull_for_every_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut checked = 0;
    for stations in layouts() {
        let (centre, radius) = extent(&stations);
        let q = differenced_range_covariance(&vec![1.0; stations.len()], 0).unwrap();
        for _ in 0..200 {
            // Uniform in a disc of 3× the station radius: inside and outside the hull.
            let rho = 3.0 * radius * rng.gen::<f64>().sqrt();
            let angle = rng.gen_range(0.0..core::f64::consts::TAU);
            let truth = centre + Vector2::new(rho * angle.cos(), rho * angle.sin());
            for reference in 0..stations.len() {
                let r = range_differences_at(&stations, reference, &truth).unwrap();
                let solution = chan(&stations, reference, &r, &q).unwrap();
                let error = (solution.fix.position - truth).norm();
                assert!(
                    error < 1e-6,
                    "{} stations, reference {reference}, truth {truth:?}: error {error} m",
                    stations.len()
                );
                assert!(solution.alternative.is_none());
                let c = solution.fix.covariance;
                assert!((c[(0, 1)] - c[(1, 0)]).abs() <= 1e-12 * c.amax());
                assert!(c[(0, 0)] > 0.0 && c.determinant() > 0.0, "covariance not PD: {c:?}");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 200 * (4 + 5 + 6));
}

#[test]
fn three_stations_exact_solution_contains_the_truth_for_every_reference() {
    let stations = [[0.0, 0.0], [100.0, 10.0], [30.0, 90.0]];
    let q = differenced_range_covariance(&[1.0; 3], 0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut ambiguous = 0;
    for _ in 0..300 {
        let truth = Vector2::new(rng.gen_range(-150.0..250.0), rng.gen_range(-150.0..250.0));
        for reference in 0..3 {
            let r = range_differences_at(&stations, reference, &truth).unwrap();
            let solution = chan(&stations, reference, &r, &q).unwrap();
            let candidates: Vec<Vector2<f64>> = core::iter::once(solution.fix)
                .chain(solution.alternative)
                .map(|f| f.position)
                .collect();
            let best = candidates
                .iter()
                .map(|c| (c - truth).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-6, "reference {reference}, truth {truth:?}: {candidates:?}");
            // Every candidate reproduces the measurements.
            for c in &candidates {
                let predicted = range_differences_at(&stations, reference, c).unwrap();
                for (a, b) in predicted.iter().zip(&r) {
                    assert!((a - b).abs() < 1e-6, "candidate {c:?} does not fit");
                }
            }
            // The closest_to rule recovers the truth given a prior near it.
            let near = truth + Vector2::new(0.5, -0.5);
            assert!((solution.closest_to(&near).position - truth).norm() < 1e-6);
            ambiguous += usize::from(solution.is_ambiguous());
        }
    }
    // Outside the triangle, three stations are often ambiguous: the test covers both cases.
    assert!(ambiguous > 0 && ambiguous < 900, "ambiguous {ambiguous} of 900");
}

#[test]
fn three_station_covariance_is_the_crlb() {
    let stations = [[0.0, 0.0], [100.0, 10.0], [30.0, 90.0]];
    let q = differenced_range_covariance(&[0.25, 0.5, 1.0], 2).unwrap();
    let truth = Vector2::new(45.0, 35.0);
    let r = range_differences_at(&stations, 2, &truth).unwrap();
    let solution = chan(&stations, 2, &r, &q).unwrap();
    let expected = crlb(&stations, 2, &truth, &q);
    assert!((solution.fix.covariance - expected).amax() < 1e-9 * expected.amax());
}

#[test]
fn step_two_equals_the_printed_weighted_least_squares() {
    // A noisy step-1 solution, so that h' is not exactly consistent.
    let stations = layouts()[2].clone();
    let q = differenced_range_covariance(&[0.04; 6], 3).unwrap();
    let truth = Vector2::new(9.0, 30.0);
    let mut r = range_differences_at(&stations, 3, &truth).unwrap();
    for (k, v) in r.iter_mut().enumerate() {
        *v += 0.3 * ((k as f64) * 1.7).sin();
    }
    let problem = Problem::new(&stations, 3, &r, &q).unwrap();
    let (z_a, fisher) = problem.step_one().unwrap();
    let implemented = step_two::<2>(&z_a, &fisher, problem.scale_m).unwrap();
    let z_a = Vector3::from_column_slice(z_a.as_slice());
    let fisher = Matrix3::from_column_slice(fisher.as_slice());
    // Printed form: h' = z_a ⊙ z_a, G' = [I; 1 1], B' = diag(z_a), Ψ' = 4 B' F⁻¹ B',
    // z' = (G'ᵀ Ψ'⁻¹ G')⁻¹ G'ᵀ Ψ'⁻¹ h', p = sign ⊙ √z'.
    let h2 = z_a.component_mul(&z_a);
    let g2 = nalgebra::Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 1.0, 1.0);
    let b2 = Matrix3::from_diagonal(&z_a);
    let psi2 = b2 * fisher.try_inverse().unwrap() * b2 * 4.0;
    let w2 = psi2.try_inverse().unwrap();
    let z2 = (g2.transpose() * w2 * g2).try_inverse().unwrap() * g2.transpose() * w2 * h2;
    let printed = Vector2::new(z_a.x.signum() * z2.x.sqrt(), z_a.y.signum() * z2.y.sqrt());
    assert!(z2.x > 0.0 && z2.y > 0.0);
    assert!((implemented - printed).norm() < 1e-9, "{implemented:?} vs {printed:?}");
    // and step 2 moved the estimate (it is not the step-1 fallback)
    assert!((implemented - z_a.xy()).norm() > 1e-6);
}

#[test]
fn covariance_equals_the_printed_step_two_covariance_and_the_crlb() {
    let stations = layouts()[1].clone();
    let q = differenced_range_covariance(&[0.01, 0.02, 0.015, 0.01, 0.03], 1).unwrap();
    let truth = Vector2::new(63.0, -41.0);
    let r = range_differences_at(&stations, 1, &truth).unwrap();
    let problem = Problem::new(&stations, 1, &r, &q).unwrap();
    let p = truth - Vector2::new(stations[1][0], stations[1][1]);
    let implemented = problem.covariance_at(&p).unwrap();
    // Printed: Φ = ¼ B''⁻¹ (G'ᵀ Ψ'⁻¹ G')⁻¹ B''⁻¹, Ψ' = 4 B' cov(z_a) B', cov(z_a) = (G_aᵀ Ψ⁻¹ G_a)⁻¹,
    // all at the fix.
    let others: Vec<Vector2<f64>> = stations
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != 1)
        .map(|(_, s)| Vector2::new(s[0], s[1]) - Vector2::new(stations[1][0], stations[1][1]))
        .collect();
    let b = DMatrix::from_diagonal(&DVector::from_iterator(4, others.iter().map(|s| (p - s).norm())));
    let psi = &b * &q * &b;
    let g = DMatrix::from_fn(4, 3, |i, j| match j {
        0 => -others[i].x,
        1 => -others[i].y,
        _ => -r[i],
    });
    let cov_za = (g.transpose() * psi.try_inverse().unwrap() * &g).try_inverse().unwrap();
    let b1 = DMatrix::from_diagonal(&DVector::from_column_slice(&[p.x, p.y, p.norm()]));
    let psi2 = &b1 * cov_za * &b1 * 4.0;
    let g2 = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    let cov_z2 = (g2.transpose() * psi2.try_inverse().unwrap() * &g2)
        .try_inverse()
        .unwrap();
    let b2_inv = Matrix2::new(1.0 / p.x, 0.0, 0.0, 1.0 / p.y);
    let cov_z2 = Matrix2::new(cov_z2[(0, 0)], cov_z2[(0, 1)], cov_z2[(1, 0)], cov_z2[(1, 1)]);
    let printed = b2_inv * cov_z2 * b2_inv * 0.25;
    assert!(
        (implemented - printed).amax() < 1e-9 * printed.amax(),
        "{implemented} vs {printed}"
    );
    let bound = crlb(&stations, 1, &truth, &q);
    assert!(
        (implemented - bound).amax() < 1e-9 * bound.amax(),
        "{implemented} vs {bound}"
    );
}

#[test]
fn step_one_falls_back_when_step_two_has_a_negative_square() {
    // z_a with r_ref ≤ 0 → the step-1 position is returned unchanged.
    let dynamic = |z: &Vector3<f64>, f: &Matrix3<f64>| {
        (
            DVector::from_column_slice(z.as_slice()),
            DMatrix::from_column_slice(3, 3, f.as_slice()),
        )
    };
    let fisher = Matrix3::identity();
    let z_a = Vector3::new(3.0, -4.0, -1.0);
    let (z, f) = dynamic(&z_a, &fisher);
    assert_eq!(step_two::<2>(&z, &f, 10.0).unwrap(), Vector2::new(3.0, -4.0));
    // M = [I; (x, y)/r], v = (Mᵀ F M)⁻¹ Mᵀ F z_a; a strongly correlated F can give
    // x̂ v_x < 0 (a negative squared coordinate).
    let z_a = Vector3::new(0.1, 5.0, 0.2);
    let a = Matrix3::new(0.3, 0.8, 0.3, -1.3, 0.9, 0.4, -0.5, 0.6, 0.4);
    let fisher = a * a.transpose() + Matrix3::identity() * 0.01;
    let m = Matrix2x3::new(1.0, 0.0, 0.5, 0.0, 1.0, 25.0).transpose();
    let v = (m.transpose() * fisher * m).try_inverse().unwrap() * m.transpose() * fisher * z_a;
    assert!(z_a.x * v.x < 0.0, "test premise: {v:?}");
    let (z, f) = dynamic(&z_a, &fisher);
    assert_eq!(step_two::<2>(&z, &f, 10.0).unwrap(), Vector2::new(0.1, 5.0));
}

#[test]
fn error_paths() {
    let square = [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]];
    let q3 = differenced_range_covariance(&[1.0; 4], 0).unwrap();
    let r3 = range_differences_at(&square, 0, &Vector2::new(30.0, 60.0)).unwrap();
    let q2 = differenced_range_covariance(&[1.0; 3], 0).unwrap();

    // Underdetermined
    assert_eq!(
        chan(&square[..2], 0, &[1.0], &DMatrix::identity(1, 1)),
        Err(PositioningError::Underdetermined { anchors: 2, needed: 3 })
    );
    // reference out of range
    assert!(matches!(
        chan(&square, 4, &r3, &q3),
        Err(PositioningError::InvalidParameter { name: "reference", .. })
    ));
    // length mismatch: differences, covariance
    assert!(matches!(
        chan(&square, 0, &r3[..2], &q3),
        Err(PositioningError::DimensionMismatch {
            expected: 3,
            found: 2,
            ..
        })
    ));
    assert!(matches!(
        chan(&square, 0, &r3, &q2),
        Err(PositioningError::DimensionMismatch {
            expected: 3,
            found: 2,
            ..
        })
    ));
    // non-finite inputs
    let mut bad_stations = square;
    bad_stations[2][1] = f64::NAN;
    assert!(matches!(
        chan(&bad_stations, 0, &r3, &q3),
        Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
    ));
    assert!(matches!(
        chan(&square, 0, &[r3[0], f64::INFINITY, r3[2]], &q3),
        Err(PositioningError::NonFinite {
            what: "range differences"
        })
    ));
    let mut bad_q = q3.clone();
    bad_q[(1, 1)] = f64::NAN;
    assert!(matches!(
        chan(&square, 0, &r3, &bad_q),
        Err(PositioningError::NonFinite { .. })
    ));
    // asymmetric and indefinite covariance
    let mut asymmetric = q3.clone();
    asymmetric[(0, 2)] += 0.5;
    assert!(matches!(
        chan(&square, 0, &r3, &asymmetric),
        Err(PositioningError::InvalidParameter {
            name: "covariance_m2",
            ..
        })
    ));
    assert!(matches!(
        chan(&square, 0, &r3, &(-q3.clone())),
        Err(PositioningError::NotPositiveDefinite { .. })
    ));
    // collinear stations (4 and 3), duplicate stations
    let line = [[0.0, 0.0], [10.0, 10.0], [25.0, 25.0], [40.0, 40.0]];
    let r_line = range_differences_at(&line, 0, &Vector2::new(5.0, 30.0)).unwrap();
    assert!(matches!(
        chan(&line, 0, &r_line, &q3),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
    let r_line3 = range_differences_at(&line[..3], 1, &Vector2::new(5.0, 30.0)).unwrap();
    assert!(matches!(
        chan(&line[..3], 1, &r_line3, &q2),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
    let heap = [[5.0, 5.0]; 4];
    assert_eq!(
        chan(&heap, 0, &[0.0; 3], &q3),
        Err(PositioningError::DuplicateAnchors { first: 0, second: 1 })
    );
    let twin = [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 0.0]];
    assert_eq!(
        chan(&twin, 2, &r3, &q3),
        Err(PositioningError::DuplicateAnchors { first: 1, second: 3 })
    );
    assert_eq!(
        chan(&twin[1..], 0, &r3[..2], &q2),
        Err(PositioningError::DuplicateAnchors { first: 0, second: 2 })
    );
    // a tag exactly at a station: the covariance (TDOA Jacobian) is undefined there
    for (reference, station) in [(0, 1), (0, 0), (2, 3)] {
        let at = Vector2::new(square[station][0], square[station][1]);
        let r_at = range_differences_at(&square, reference, &at).unwrap();
        assert!(
            matches!(
                chan(&square, reference, &r_at, &q3),
                Err(PositioningError::DegenerateGeometry { .. })
            ),
            "reference {reference}, tag at station {station}"
        );
    }
    // three stations whose differences exceed the baselines: no consistent position
    assert!(matches!(
        chan(&square[..3], 0, &[150.0, 150.0], &q2),
        Err(PositioningError::NoConsistentSolution { .. })
    ));
    assert!(matches!(
        chan(&square[..3], 0, &[-90.0, 95.0], &q2),
        Err(PositioningError::NoConsistentSolution { .. })
    ));
}

#[test]
fn fix_is_invariant_to_translating_the_site() {
    let stations = layouts()[2].clone();
    let shift = Vector2::new(-4.0e5, 2.5e5);
    let moved: Vec<[f64; 2]> = stations.iter().map(|s| [s[0] + shift.x, s[1] + shift.y]).collect();
    let q = differenced_range_covariance(&[0.01; 6], 4).unwrap();
    let truth = Vector2::new(2.0, 11.0);
    let mut r = range_differences_at(&stations, 4, &truth).unwrap();
    r[1] += 0.1;
    r[3] -= 0.07;
    let here = chan(&stations, 4, &r, &q).unwrap().fix;
    let there = chan(&moved, 4, &r, &q).unwrap().fix;
    assert!((there.position - shift - here.position).norm() < 1e-6);
    assert!((there.covariance - here.covariance).amax() < 1e-6 * here.covariance.amax());
}
