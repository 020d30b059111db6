//! Property tests of the filters' invariants and of equivalent forms against each other.

use nalgebra::DVector;
use proptest::prelude::*;
use rtls_estimation::filter::{
    CovarianceUpdate, CvAxis, DecoupledCvFilter, DecoupledCvState, ExtendedKalmanFilter, KalmanFilter,
    SigmaPointParameters, UnscentedKalmanFilter,
};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

/// A random symmetric positive-definite 4 × 4 covariance `A Aᵀ + ε I`.
fn spd4() -> impl Strategy<Value = Matrix<4>> {
    (proptest::collection::vec(-3.0..3.0f64, 16), 0.01..2.0f64).prop_map(|(a, eps)| {
        let a = Matrix::<4>::from_row_slice(&a);
        a * a.transpose() + Matrix::<4>::identity() * eps
    })
}

fn state4() -> impl Strategy<Value = Gaussian<4>> {
    (proptest::collection::vec(-50.0..50.0f64, 4), spd4())
        .prop_map(|(m, p)| Gaussian::new(Vector::<4>::from_row_slice(&m), p, 0.0).unwrap())
}

fn assert_spd(p: &Matrix<4>) {
    assert_eq!(*p, p.transpose(), "covariance must be exactly symmetric");
    assert!(p.cholesky().is_some(), "covariance must be positive definite: {p}");
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    let scale = b.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * scale)
}

#[derive(Debug, Clone)]
enum Op {
    Predict(f64),
    Fix(f64, f64),
    Range(usize, f64),
}

fn ops() -> impl Strategy<Value = Vec<Op>> {
    proptest::collection::vec(
        prop_oneof![
            (0.01..5.0f64).prop_map(Op::Predict),
            (-100.0..100.0f64, -100.0..100.0f64).prop_map(|(x, y)| Op::Fix(x, y)),
            (0usize..3, 0.5..150.0f64).prop_map(|(a, r)| Op::Range(a, r)),
        ],
        1..40,
    )
}

const ANCHORS: [[f64; 2]; 3] = [[-200.0, -200.0], [250.0, -180.0], [10.0, 260.0]];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// After any sequence of predicts and updates the covariance stays symmetric positive definite
    #[test]
    fn covariance_stays_spd_under_any_sequence(x0 in state4(), ops in ops(), which in 0usize..3) {
        let motion = ConstantVelocity::new(ProcessNoise::discrete(0.3, NoiseGain::kinematic())).unwrap();
        let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&[2.0, 3.0]).unwrap()).unwrap();
        let kf = KalmanFilter::default();
        let ekf = ExtendedKalmanFilter::default();
        let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::default());
        let mut x = x0;
        let mut t = 0.0;
        for op in ops {
            let op_label = op.clone();
            let next = match op {
                Op::Predict(dt) => {
                    t += dt;
                    match which { 0 => kf.predict(&x, &motion, t), 1 => ekf.predict(&x, &motion, t), _ => ukf.predict(&x, &motion, t) }
                }
                Op::Fix(px, py) => {
                    let z = DVector::from_row_slice(&[px, py]);
                    match which { 0 => kf.update(&x, &fixes, &z), 1 => ekf.update(&x, &fixes, &z), _ => ukf.update(&x, &fixes, &z) }.map(|u| u.state)
                }
                Op::Range(a, r) => {
                    let model = Ranges::planar(&[ANCHORS[a]], NoiseCovariance::isotropic(1, 0.25).unwrap()).unwrap();
                    let z = DVector::from_element(1, r);
                    match which { 2 => ukf.update(&x, &model, &z), _ => ekf.update(&x, &model, &z) }.map(|u| u.state)
                }
            };
            match next {
                Ok(n) => { assert_spd(n.covariance()); prop_assert!(n.mean().iter().all(|v| v.is_finite())); x = n; }
                // The states stay far from the anchors, so no step has a reason to fail.
                Err(e) => prop_assert!(false, "step {:?} failed: {}", op_label, e),
            }
        }
    }

    /// On a linear model the KF, EKF and UKF (any α) compute the same predict + update.
    #[test]
    fn kf_ekf_ukf_agree_on_linear_models(x0 in state4(), dt in 0.05..3.0f64, zx in -60.0..60.0f64, zy in -60.0..60.0f64, alpha in 0.1..1.0f64) {
        let motion = ConstantVelocity::new(ProcessNoise::discrete(0.7, NoiseGain::kinematic())).unwrap();
        let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::full(nalgebra::DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 9.0])).unwrap()).unwrap();
        let z = DVector::from_row_slice(&[zx, zy]);
        let kf = KalmanFilter::default();
        let a = kf.update(&kf.predict(&x0, &motion, dt).unwrap(), &fixes, &z).unwrap();
        let ekf = ExtendedKalmanFilter::default();
        let b = ekf.update(&ekf.predict(&x0, &motion, dt).unwrap(), &fixes, &z).unwrap();
        let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::new(alpha, 2.0, 0.0).unwrap());
        let c = ukf.update(&ukf.predict(&x0, &motion, dt).unwrap(), &fixes, &z).unwrap();
        for other in [&b, &c] {
            prop_assert!(close(other.state.mean().as_slice(), a.state.mean().as_slice(), 1e-7));
            prop_assert!(close(other.state.covariance().as_slice(), a.state.covariance().as_slice(), 1e-7));
            prop_assert!((other.nis - a.nis).abs() <= 1e-6 * a.nis.max(1.0));
        }
    }

    /// The Joseph and the simple covariance forms agree.
    #[test]
    fn joseph_and_simple_forms_agree(x0 in state4(), zx in -60.0..60.0f64, zy in -60.0..60.0f64) {
        let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&[2.0, 0.5]).unwrap()).unwrap();
        let z = DVector::from_row_slice(&[zx, zy]);
        let joseph = KalmanFilter::new(CovarianceUpdate::Joseph).update(&x0, &fixes, &z).unwrap();
        let simple = KalmanFilter::new(CovarianceUpdate::Simple).update(&x0, &fixes, &z).unwrap();
        prop_assert!(close(joseph.state.covariance().as_slice(), simple.state.covariance().as_slice(), 1e-9));
        prop_assert!(close(joseph.state.mean().as_slice(), simple.state.mean().as_slice(), 1e-12));
    }

    /// Sequential scalar updates equal the batch update for a linear model with diagonal R.
    #[test]
    fn sequential_equals_batch_for_linear_models(x0 in state4(), zx in -60.0..60.0f64, zy in -60.0..60.0f64) {
        let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&[2.0, 0.5]).unwrap()).unwrap();
        let z = DVector::from_row_slice(&[zx, zy]);
        let kf = KalmanFilter::default();
        let batch = kf.update(&x0, &fixes, &z).unwrap();
        let sequential = kf.update_sequential(&x0, &fixes, &z).unwrap();
        prop_assert!(close(sequential.state.mean().as_slice(), batch.state.mean().as_slice(), 1e-9));
        prop_assert!(close(sequential.state.covariance().as_slice(), batch.state.covariance().as_slice(), 1e-9));
        prop_assert_eq!(sequential.nis, batch.nis);
    }

    /// The decoupled CV fast path equals the general KF on the same inputs.
    #[test]
    fn decoupled_cv_equals_general_kf(
        init in proptest::collection::vec((-50.0..50.0f64, -3.0..3.0f64, 0.1..50.0f64, -0.9..0.9f64, 0.1..10.0f64), 3),
        steps in proptest::collection::vec((0.05..3.0f64, -80.0..80.0f64, -80.0..80.0f64, -5.0..5.0f64), 1..30),
    ) {
        let noise = ProcessNoise::discrete(2.0, NoiseGain::kinematic());
        let fast = DecoupledCvFilter::new(noise).unwrap();
        let motion = ConstantVelocity::new(noise).unwrap();
        let variances = [5.0, 3.0, 8.0];
        let fixes = ComponentSelection::<6>::position(3, NoiseCovariance::diagonal(&variances).unwrap()).unwrap();
        let axes: Vec<CvAxis> = init.iter().map(|&(p, v, pp, rho, vv)| CvAxis {
            position_m: p, velocity_mps: v, var_position: pp, cov_position_velocity: rho * (pp * vv).sqrt(), var_velocity: vv,
        }).collect();
        let mut fast_state = DecoupledCvState::new([axes[0], axes[1], axes[2]], 0.0).unwrap();
        let mut general: Gaussian<6> = fast_state.to_gaussian();
        let kf = KalmanFilter::default();
        let mut t = 0.0;
        for (dt, x, y, z) in steps {
            t += dt;
            fast_state = fast.step(&fast_state, t, &[x, y, z], &variances).unwrap();
            let prior = kf.predict(&general, &motion, t).unwrap();
            general = kf.update(&prior, &fixes, &DVector::from_row_slice(&[x, y, z])).unwrap().state;
            let converted: Gaussian<6> = fast_state.to_gaussian();
            prop_assert!(close(converted.mean().as_slice(), general.mean().as_slice(), 1e-9));
            prop_assert!(close(converted.covariance().as_slice(), general.covariance().as_slice(), 1e-9));
        }
    }
}
