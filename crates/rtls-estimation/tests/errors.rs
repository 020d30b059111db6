//! Bad input reaches the caller as a typed error naming the problem — never a panic or a NaN.

use nalgebra::{DMatrix, DVector};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters, UnscentedKalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{EstimationError, Gaussian, Matrix, Vector};

fn state() -> Gaussian<4> {
    Gaussian::new(Vector::<4>::new(1.0, 0.5, 2.0, -0.5), Matrix::<4>::identity(), 10.0).unwrap()
}

fn motion() -> ConstantVelocity {
    ConstantVelocity::new(ProcessNoise::discrete(0.5, NoiseGain::kinematic())).unwrap()
}

fn fixes() -> ComponentSelection<4> {
    ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 1.0).unwrap()).unwrap()
}

#[test]
fn predicting_into_the_past_is_time_went_backwards() {
    let err = KalmanFilter::default().predict(&state(), &motion(), 9.0).unwrap_err();
    assert_eq!(
        err,
        EstimationError::TimeWentBackwards {
            state_time_s: 10.0,
            requested_time_s: 9.0
        }
    );
    assert!(err.to_string().contains("time went backwards"));
    assert!(matches!(
        UnscentedKalmanFilter::default().predict(&state(), &motion(), f64::NAN),
        Err(EstimationError::NonFinite { what: "requested time" })
    ));
}

#[test]
fn wrong_measurement_size_is_a_dimension_mismatch() {
    let z = DVector::from_row_slice(&[1.0, 2.0, 3.0]);
    for result in [
        KalmanFilter::default().update(&state(), &fixes(), &z),
        ExtendedKalmanFilter::default().update(&state(), &fixes(), &z),
        UnscentedKalmanFilter::default().update(&state(), &fixes(), &z),
    ] {
        assert_eq!(
            result.unwrap_err(),
            EstimationError::DimensionMismatch {
                what: "measurement vector",
                expected: 2,
                found: 3
            }
        );
    }
}

#[test]
fn nan_in_a_measurement_is_non_finite() {
    let z = DVector::from_row_slice(&[1.0, f64::NAN]);
    for result in [
        KalmanFilter::default().update(&state(), &fixes(), &z),
        ExtendedKalmanFilter::default().update_sequential(&state(), &fixes(), &z),
        UnscentedKalmanFilter::default().update(&state(), &fixes(), &z),
    ] {
        assert_eq!(
            result.unwrap_err(),
            EstimationError::NonFinite {
                what: "measurement vector"
            }
        );
    }
}

#[test]
fn control_errors_are_named() {
    let u = DVector::from_row_slice(&[0.1, 0.2]);
    assert_eq!(
        KalmanFilter::default()
            .predict_with_control(&state(), &motion(), &u, 11.0)
            .unwrap_err(),
        EstimationError::NoControlInput
    );
    let driven = motion().with_acceleration_input();
    let wrong = DVector::from_row_slice(&[0.1, 0.2, 0.3]);
    assert_eq!(
        ExtendedKalmanFilter::default()
            .predict_with_control(&state(), &driven, &wrong, 11.0)
            .unwrap_err(),
        EstimationError::DimensionMismatch {
            what: "control input",
            expected: 2,
            found: 3
        }
    );
    // And the valid control moves the mean by B u: Δx = dt²/2 · u = 0.05.
    let moved = KalmanFilter::default()
        .predict_with_control(&state(), &driven, &u, 11.0)
        .unwrap();
    let coasted = KalmanFilter::default().predict(&state(), &driven, 11.0).unwrap();
    assert!((moved.mean()[0] - coasted.mean()[0] - 0.05).abs() < 1e-12);
}

#[test]
fn range_jacobian_at_the_anchor_is_singular_measurement() {
    let anchor_on_state = Ranges::planar(&[[1.0, 2.0]], NoiseCovariance::isotropic(1, 0.1).unwrap()).unwrap();
    let err = ExtendedKalmanFilter::default()
        .update(&state(), &anchor_on_state, &DVector::from_element(1, 0.3))
        .unwrap_err();
    assert!(
        matches!(err, EstimationError::SingularMeasurement { model: "ranges", .. }),
        "{err:?}"
    );
}

#[test]
fn indefinite_innovation_covariance_is_reported() {
    // Symmetric with non-negative variances, but indefinite in (x, y): S = H P Hᵀ + R is too.
    let mut p = Matrix::<4>::identity();
    p[(0, 2)] = 2.0;
    p[(2, 0)] = 2.0;
    let bad = Gaussian::new(Vector::<4>::zeros(), p, 0.0).unwrap();
    let tight = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 1e-3).unwrap()).unwrap();
    let err = KalmanFilter::default()
        .update(&bad, &tight, &DVector::from_row_slice(&[0.1, 0.1]))
        .unwrap_err();
    assert_eq!(err, EstimationError::InnovationNotPositiveDefinite);
    assert!(matches!(
        UnscentedKalmanFilter::default().predict(&bad, &motion(), 1.0),
        Err(EstimationError::NotPositiveDefinite { .. })
    ));
}

#[test]
fn sequential_update_refuses_correlated_noise() {
    let correlated = NoiseCovariance::full(DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 9.0])).unwrap();
    let model = ComponentSelection::<4>::position(2, correlated).unwrap();
    assert_eq!(
        KalmanFilter::default()
            .update_sequential(&state(), &model, &DVector::from_row_slice(&[1.0, 2.0]))
            .unwrap_err(),
        EstimationError::CorrelatedNoise
    );
}

#[test]
fn sigma_point_parameters_that_collapse_the_spread_are_rejected() {
    assert!(SigmaPointParameters::new(0.0, 2.0, 0.0).is_err());
    // n + λ = α² (n + κ) ≤ 0 for κ = −n.
    let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::new(1.0, 2.0, -4.0).unwrap());
    assert!(matches!(
        ukf.predict(&state(), &motion(), 11.0),
        Err(EstimationError::InvalidParameter { name: "kappa", .. })
    ));
}
