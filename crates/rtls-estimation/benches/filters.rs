//! Criterion benchmarks of the filter kernels, each with a baseline measured in the same run.
//!
//! Run: `cargo bench -p rtls-estimation --bench filters`
//!
//! - `cv3d_step`: one predict + update of the 3-D constant-velocity model with a 3-D position
//!   fix (seed 000's ME-KF, T = 1 s, σ_w² = 5, σ_v² = 5): our decoupled fast path, our general
//!   KF path, and the `adskalman` crate on identical inputs.
//! - `ukf_step`: UKF predict + update, 4-state CV with ranges to two anchors (seed 001),
//!   α = 0.01, against the EKF on the same inputs.
//! - `ekf_step`: EKF predict + update with a single range (seed 003), against the UKF on the
//!   same inputs.
//! - `rts_1000`: RTS smoothing of 1000 filtered 6-state CV steps, ours vs `adskalman`.

#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::hint::black_box;

use adskalman::{KalmanFilterNoControl, ObservationModel, StateAndCovariance, TransitionModelLinearNoControl};
use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{DVector, SMatrix, SVector};
use rtls_estimation::filter::{
    CvAxis, DecoupledCvFilter, DecoupledCvState, ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters,
    UnscentedKalmanFilter,
};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

const SIGMA_W2: f64 = 5.0;
const SIGMA_V2: f64 = 5.0;

struct AdsMotion {
    f: SMatrix<f64, 6, 6>,
    ft: SMatrix<f64, 6, 6>,
    q: SMatrix<f64, 6, 6>,
}
impl TransitionModelLinearNoControl<f64, nalgebra::U6> for AdsMotion {
    fn F(&self) -> &SMatrix<f64, 6, 6> {
        &self.f
    }
    fn FT(&self) -> &SMatrix<f64, 6, 6> {
        &self.ft
    }
    fn Q(&self) -> &SMatrix<f64, 6, 6> {
        &self.q
    }
}
struct AdsFix {
    h: SMatrix<f64, 3, 6>,
    ht: SMatrix<f64, 6, 3>,
    r: SMatrix<f64, 3, 3>,
}
impl ObservationModel<f64, nalgebra::U6, nalgebra::U3> for AdsFix {
    fn H(&self) -> &SMatrix<f64, 3, 6> {
        &self.h
    }
    fn HT(&self) -> &SMatrix<f64, 6, 3> {
        &self.ht
    }
    fn R(&self) -> &SMatrix<f64, 3, 3> {
        &self.r
    }
}

fn cv_model() -> ConstantVelocity {
    ConstantVelocity::new(ProcessNoise::discrete(SIGMA_W2, NoiseGain::kinematic())).expect("valid noise")
}

fn ads_models() -> (AdsMotion, AdsFix) {
    let motion = cv_model();
    let f: Matrix<6> = motion.transition_matrix(1.0);
    let q: Matrix<6> = motion.process_noise_matrix(1.0);
    let mut h = SMatrix::<f64, 3, 6>::zeros();
    for axis in 0..3 {
        h[(axis, 2 * axis)] = 1.0;
    }
    (
        AdsMotion {
            f,
            ft: f.transpose(),
            q,
        },
        AdsFix {
            h,
            ht: h.transpose(),
            r: SMatrix::<f64, 3, 3>::identity() * SIGMA_V2,
        },
    )
}

fn initial_mean() -> Vector<6> {
    Vector::<6>::from_row_slice(&[1.0, 1.2, 2.0, 0.9, 0.5, 0.0])
}

fn cv3d_step(c: &mut Criterion) {
    let fix = [2.3, 2.8, 0.6];
    let mut group = c.benchmark_group("cv3d_step");

    let fast = DecoupledCvFilter::new(ProcessNoise::discrete(SIGMA_W2, NoiseGain::kinematic())).unwrap();
    let m = initial_mean();
    let axes = [0, 1, 2].map(|a| CvAxis {
        position_m: m[2 * a],
        velocity_mps: m[2 * a + 1],
        var_position: 10.0,
        cov_position_velocity: 0.0,
        var_velocity: 2.0,
    });
    let fast_state = DecoupledCvState::new(axes, 0.0).unwrap();
    group.bench_function("rtls_decoupled", |b| {
        b.iter(|| {
            fast.step(
                black_box(&fast_state),
                black_box(1.0),
                black_box(&fix),
                black_box(&[SIGMA_V2; 3]),
            )
            .unwrap()
        })
    });

    let kf = KalmanFilter::default();
    let motion = cv_model();
    let fix_model = ComponentSelection::<6>::position(3, NoiseCovariance::isotropic(3, SIGMA_V2).unwrap()).unwrap();
    let general_state: Gaussian<6> = fast_state.to_gaussian();
    let z = DVector::from_row_slice(&fix);
    group.bench_function("rtls_general_kf", |b| {
        b.iter(|| {
            let prior = kf.predict(black_box(&general_state), &motion, black_box(1.0)).unwrap();
            kf.update(&prior, &fix_model, black_box(&z)).unwrap()
        })
    });

    let (ads_motion, ads_fix) = ads_models();
    let ads = KalmanFilterNoControl::new(&ads_motion, &ads_fix);
    let ads_state = StateAndCovariance::new(*general_state.mean(), *general_state.covariance());
    let ads_z = SVector::<f64, 3>::from_row_slice(&fix);
    group.bench_function("adskalman", |b| {
        b.iter(|| ads.step(black_box(&ads_state), black_box(&ads_z)).unwrap())
    });
    group.finish();
}

fn ukf_step(c: &mut Criterion) {
    let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::seed_001());
    let motion = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic())).unwrap();
    let ranges = Ranges::planar(
        &[[2.0, 2.0], [20.0, 40.0]],
        NoiseCovariance::isotropic(2, 0.09).unwrap(),
    )
    .unwrap();
    let state = Gaussian::new(
        Vector::<4>::new(2.0, 0.1, 10.0, 0.5),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(1.0, 0.1, 1.0, 0.1)),
        0.0,
    )
    .unwrap();
    let z = DVector::from_row_slice(&[8.6, 29.6]);
    let mut group = c.benchmark_group("ukf_step");
    group.bench_function("rtls_ukf_4state_2ranges", |b| {
        b.iter(|| {
            let prior = ukf.predict(black_box(&state), &motion, black_box(1.0)).unwrap();
            ukf.update(&prior, &ranges, black_box(&z)).unwrap()
        })
    });
    let ekf = ExtendedKalmanFilter::default();
    group.bench_function("rtls_ekf_4state_2ranges", |b| {
        b.iter(|| {
            let prior = ekf.predict(black_box(&state), &motion, black_box(1.0)).unwrap();
            ekf.update(&prior, &ranges, black_box(&z)).unwrap()
        })
    });
    group.finish();
}

fn ekf_step(c: &mut Criterion) {
    let ekf = ExtendedKalmanFilter::default();
    let motion = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic()))
        .unwrap()
        .with_acceleration_input();
    let node = Ranges::planar(&[[400.0, 0.0]], NoiseCovariance::isotropic(1, 4.0).unwrap()).unwrap();
    let state = Gaussian::new(
        Vector::<4>::new(100.0, 50.0, 100.0, 0.0),
        Matrix::<4>::identity() * 25.0,
        0.0,
    )
    .unwrap();
    let z = DVector::from_element(1, 330.0);
    let mut group = c.benchmark_group("ekf_step");
    group.bench_function("rtls_ekf_single_range", |b| {
        b.iter(|| {
            let prior = ekf.predict(black_box(&state), &motion, black_box(0.2)).unwrap();
            ekf.update(&prior, &node, black_box(&z)).unwrap()
        })
    });
    let ukf = UnscentedKalmanFilter::default();
    group.bench_function("rtls_ukf_single_range", |b| {
        b.iter(|| {
            let prior = ukf.predict(black_box(&state), &motion, black_box(0.2)).unwrap();
            ukf.update(&prior, &node, black_box(&z)).unwrap()
        })
    });
    group.finish();
}

fn rts_1000(c: &mut Criterion) {
    let kf = KalmanFilter::default();
    let motion = cv_model();
    let fix_model = ComponentSelection::<6>::position(3, NoiseCovariance::isotropic(3, SIGMA_V2).unwrap()).unwrap();
    let mut state = Gaussian::new(initial_mean(), Matrix::<6>::identity() * 10.0, 0.0).unwrap();
    let mut filtered = Vec::with_capacity(1000);
    let mut ads_filtered = Vec::with_capacity(1000);
    for k in 1..=1000 {
        let t = k as f64;
        let prior = kf.predict(&state, &motion, t).unwrap();
        // A deterministic wiggly walk as the fixes.
        let z = DVector::from_row_slice(&[1.2 * t + (0.37 * t).sin(), 0.9 * t + (0.21 * t).cos(), 0.5]);
        state = kf.update(&prior, &fix_model, &z).unwrap().state;
        filtered.push(state);
        ads_filtered.push(StateAndCovariance::new(*state.mean(), *state.covariance()));
    }
    let (ads_motion, ads_fix) = ads_models();
    let ads = KalmanFilterNoControl::new(&ads_motion, &ads_fix);
    let mut group = c.benchmark_group("rts_1000");
    group.sample_size(30);
    group.bench_function("rtls_kf_smooth", |b| {
        b.iter(|| kf.smooth(black_box(&filtered), &motion).unwrap())
    });
    group.bench_function("adskalman_smooth", |b| {
        b.iter(|| ads.smooth_from_filtered(black_box(ads_filtered.clone())).unwrap())
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default();
    targets = cv3d_step, ukf_step, ekf_step, rts_1000
}
criterion_main!(benches);
