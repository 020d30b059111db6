//! Tests of [`super::multilaterate`].

use nalgebra::{SVector, Vector2, Vector3};

use super::*;

fn ranges_to<const D: usize>(anchors: &[[f64; D]], p: &SVector<f64, D>) -> Vec<f64> {
    anchors.iter().map(|a| (p - SVector::from(*a)).norm()).collect()
}

#[test]
fn co_located_anchors_are_merged_and_their_scatter_counts_in_chi_square() {
    // anchors 0 and 3 on one mast, seen in the plane
    let anchors = [[0.0, 0.0], [20.0, 0.0], [0.0, 15.0], [0.0, 0.0]];
    let truth = Vector2::new(7.0, 5.0);
    let mut r = ranges_to(&anchors, &truth);
    r[0] += 0.1;
    r[3] -= 0.1;
    let v = [0.01; 4];
    let fix = multilaterate(&anchors, &r, &v, None, &GaussNewtonOptions::default()).unwrap();
    assert_eq!(fix.method, FixMethod::GaussNewton(Start::Linear));
    assert_eq!(fix.distinct_anchors, 3);
    assert!(fix.failures.is_empty());
    // the two merge to their mean (the truth), exactly determined otherwise
    assert!((fix.fix.position - truth).norm() < 1e-6);
    let solution = fix.solution.unwrap();
    // χ² = Σ w (r − r̄)² = 2 · 0.1² / 0.01 = 2, dof = 4 − 2
    assert!((solution.chi_square - 2.0).abs() < 1e-6);
    assert_eq!(solution.degrees_of_freedom, 2);
    assert!((solution.variance_factor - 1.0).abs() < 1e-6);
    // the plain solver refuses them
    assert_eq!(
        gauss_newton(&anchors, &r, &v, Initial::Linear, &GaussNewtonOptions::default()).unwrap_err(),
        PositioningError::DuplicateAnchors { first: 0, second: 3 }
    );
}

#[test]
fn too_few_distinct_positions_and_flat_anchors_are_explicit_errors() {
    let options = GaussNewtonOptions::default();
    let two = [[0.0, 0.0], [0.0, 0.0], [10.0, 0.0]];
    assert_eq!(
        multilaterate(&two, &[3.0, 3.1, 8.0], &[0.01; 3], None, &options).unwrap_err(),
        PositioningError::Underdetermined { anchors: 2, needed: 3 }
    );
    // with a guess, two distinct positions suffice
    let r = 34.0_f64.sqrt();
    let fix = multilaterate(&two, &[r, r, r], &[0.01; 3], Some(Vector2::new(5.0, 2.0)), &options).unwrap();
    assert_eq!(fix.method, FixMethod::GaussNewton(Start::Guess));
    assert!((fix.fix.position - Vector2::new(5.0, 3.0)).norm() < 1e-6);
    let line = [[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]];
    assert!(matches!(
        multilaterate(&line, &[3.0, 3.0, 8.0], &[0.01; 3], None, &options),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}

#[test]
fn negative_ranges_are_measurements() {
    // Wi-Fi FTM at 0.3 m from anchor 0 reports −0.4 m
    let anchors = [[0.0, 0.0], [12.0, 0.0], [0.0, 9.0], [12.0, 9.0]];
    let truth = Vector2::new(0.3, 0.0);
    let mut r = ranges_to(&anchors, &truth);
    r[0] = -0.4;
    let fix = multilaterate(&anchors, &r, &[1.0; 4], None, &GaussNewtonOptions::default()).unwrap();
    assert!(!fix.method.is_fallback());
    assert!((fix.fix.position - truth).norm() < 1.0, "{}", fix.fix.position);
    let solution = gauss_newton(&anchors, &r, &[1.0; 4], Initial::Linear, &GaussNewtonOptions::default()).unwrap();
    assert_eq!(solution.fix, fix.fix);
}

#[test]
fn a_solver_that_cannot_converge_falls_back_to_the_centroid_visibly_and_honestly() {
    let anchors = [[0.0, 0.0, 3.0], [20.0, 0.0, 2.5], [0.0, 15.0, 3.0], [20.0, 15.0, 0.5]];
    let truth = Vector3::new(6.0, 9.0, 1.5);
    let mut r = ranges_to(&anchors, &truth);
    r[1] += 2.0; // NLOS: the linear start is not the minimum
                 // one iteration and a tolerance no step meets: every Gauss–Newton start fails
    let options = GaussNewtonOptions {
        max_iterations: 1,
        relative_tolerance: 1e-15,
    };
    let fix = multilaterate(&anchors, &r, &[0.01; 4], None, &options).unwrap();
    assert_eq!(fix.method, FixMethod::WeightedCentroid);
    assert_eq!(fix.method.name(), "weighted-centroid");
    assert!(fix.method.is_fallback());
    assert!(fix.solution.is_none());
    assert_eq!(
        fix.failures,
        vec![PositioningError::DidNotConverge { iterations: 1 }; 2]
    );
    // honest: the truth is inside one standard deviation per axis (the covariance is large)
    let error = fix.fix.position - truth;
    for axis in 0..3 {
        assert!(
            error[axis].abs() < fix.fix.covariance[(axis, axis)].sqrt(),
            "{error} {}",
            fix.fix.covariance
        );
    }
    assert!(fix.fix.check_plausible(&anchors, 0.0).is_ok());
}

#[test]
fn the_covariance_grows_with_inconsistent_ranges_but_never_shrinks() {
    let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0], [5.0, -3.0]];
    let truth = Vector2::new(3.0, 4.0);
    let options = GaussNewtonOptions::default();
    let clean = ranges_to(&anchors, &truth);
    let exact = multilaterate(&anchors, &clean, &[0.01; 5], None, &options).unwrap();
    let exact_solution = exact.solution.unwrap();
    // no residuals: σ̂₀² = max(1, 0) = 1, the a-priori covariance
    assert_eq!(exact_solution.variance_factor, 1.0);
    let mut nlos = clean.clone();
    nlos[3] += 1.5;
    let solution = gauss_newton(&anchors, &nlos, &[0.01; 5], Initial::Linear, &options).unwrap();
    // σ̂₀² = χ² / (5 − 2)
    let factor = solution.chi_square / 3.0;
    assert!(factor > 10.0);
    assert!((solution.variance_factor - factor).abs() < 1e-9 * factor);
    let robust = multilaterate(&anchors, &nlos, &[0.01; 5], None, &options).unwrap();
    assert!((robust.fix.covariance - solution.fix.covariance).amax() < 1e-9 * solution.fix.covariance.amax());
    // P = σ̂₀² (JᵀWJ)⁻¹: at (nearly) the same point the covariance is the clean one × factor
    let ratio = solution.fix.covariance.trace() / exact.fix.covariance.trace();
    assert!((ratio / factor - 1.0).abs() < 0.2, "{ratio} vs {factor}");
}

#[test]
fn malformed_inputs_are_errors() {
    let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
    let options = GaussNewtonOptions::default();
    assert!(matches!(
        multilaterate(&anchors, &[1.0, f64::NAN, 2.0], &[1.0; 3], None, &options),
        Err(PositioningError::NonFiniteEntry { row: 1, .. })
    ));
    assert!(matches!(
        multilaterate(&anchors, &[1.0, 2.0, 2.0], &[1.0, 0.0, 1.0], None, &options),
        Err(PositioningError::InvalidParameter { .. })
    ));
    assert!(matches!(
        multilaterate(
            &[[0.0, f64::INFINITY], [1.0, 1.0], [2.0, 0.0]],
            &[1.0; 3],
            &[1.0; 3],
            None,
            &options
        ),
        Err(PositioningError::NonFiniteEntry { row: 0, column: 1, .. })
    ));
    assert!(matches!(
        multilaterate(
            &anchors,
            &[1.0; 3],
            &[1.0; 3],
            Some(Vector2::new(f64::NAN, 0.0)),
            &options
        ),
        Err(PositioningError::NonFinite { .. })
    ));
    let empty: [[f64; 2]; 0] = [];
    assert_eq!(
        multilaterate(&empty, &[], &[], None, &options).unwrap_err(),
        PositioningError::Underdetermined { anchors: 0, needed: 3 }
    );
}
