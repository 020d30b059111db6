//! Criterion benchmarks of the manoeuvring-target filters, each beside the single-model KF step
//! on the same inputs in the same run.
//!
//! Run: `cargo bench -p rtls-estimation --bench manoeuvring`
//!
//! - `vd_step`: one VD-KF cycle (predict + update + detector) in the CV model, in the CA
//!   model, and the onset step that re-filters the Δ + 1 stored observations; baseline one
//!   CV KF predict + update with the same position + velocity observation (seed 004, `H = I₄`).
//! - `imm_step`: one cycle of a 3-model IMM (CV 4-state KF, CA 6-state KF, CT 5-state EKF) with
//!   a position fix; baseline one CV KF predict + update with the same fix.

#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DVector;
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::imm::{FilterMode, ImmMode, InteractingMultipleModel, ModeEstimate, ModeTransitions, StateLayout};
use rtls_estimation::manoeuvre::{LinearObservation, ManoeuvreDetector, Threshold, VariableDimensionFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{
    ConstantAcceleration, ConstantVelocity, CoordinatedTurnWithRate, NoiseGain, ProcessNoise,
};
use rtls_estimation::{Gaussian, Matrix, Vector};

fn initial() -> Gaussian<4> {
    Gaussian::new(
        Vector::<4>::new(0.0, 10.0, 0.0, 0.0),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(100.0, 4.0, 100.0, 4.0)),
        0.0,
    )
    .unwrap()
}

fn bench_vd(c: &mut Criterion) {
    let vd = VariableDimensionFilter::seed_004(0.01, 0.01).unwrap();
    let full =
        ComponentSelection::<4>::position_velocity(2, NoiseCovariance::diagonal(&[900.0, 1.0, 900.0, 1.0]).unwrap())
            .unwrap();
    let z = DVector::from_vec(vec![10.0, 10.0, 0.5, 0.1]);
    let obs = LinearObservation::from_model(1.0, &full, z.clone()).unwrap();
    // A CV state whose history window is full (as in steady tracking).
    let mut cv_state = vd.initial_state(initial());
    for k in 0..10 {
        let o = LinearObservation::from_model(k as f64 * 0.1, &full, DVector::from_vec(vec![k as f64, 10.0, 0.0, 0.0]))
            .unwrap();
        cv_state = vd.step(&cv_state, &o).unwrap().state;
    }
    let obs_late = LinearObservation::from_model(1.5, &full, z.clone()).unwrap();
    // A CA state (forced onset with a tiny threshold).
    let eager = vd
        .with_detector(ManoeuvreDetector {
            onset: Threshold::Fixed(1e-9),
            exit: Threshold::Fixed(1e-9),
            ..ManoeuvreDetector::default()
        })
        .unwrap();
    let ca_state = eager.step(&eager.initial_state(initial()), &obs).unwrap().state;
    let kf = KalmanFilter::default();
    let cv = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::seed_004_cv())).unwrap();
    let x0 = initial();

    let mut group = c.benchmark_group("vd_step");
    group.bench_function("single_cv_kf_baseline", |b| {
        b.iter(|| {
            let prior = kf.predict(black_box(&x0), &cv, 1.0).unwrap();
            kf.update(&prior, &full, black_box(&z)).unwrap()
        })
    });
    group.bench_function("vd_in_cv", |b| {
        b.iter(|| vd.step(black_box(&cv_state), black_box(&obs_late)).unwrap())
    });
    group.bench_function("vd_in_ca", |b| {
        b.iter(|| vd.step(black_box(&ca_state), black_box(&obs_late)).unwrap())
    });
    group.bench_function("vd_onset_refilter", |b| {
        b.iter(|| eager.step(black_box(&cv_state), black_box(&obs_late)).unwrap())
    });
    group.finish();
}

fn bench_imm(c: &mut Criterion) {
    let r = NoiseCovariance::isotropic(2, 9.0).unwrap();
    let cv_model = ConstantVelocity::new(ProcessNoise::discrete(0.005, NoiseGain::kinematic())).unwrap();
    let fix4 = ComponentSelection::<4>::position(2, r.clone()).unwrap();
    let modes: Vec<Box<dyn ImmMode>> = vec![
        Box::new(
            FilterMode::<4, _, _, _>::new(
                "CV",
                StateLayout::cv_2d(),
                cv_model,
                fix4.clone(),
                KalmanFilter::default(),
            )
            .unwrap(),
        ),
        Box::new(
            FilterMode::<6, _, _, _>::new(
                "CA",
                StateLayout::ca_2d(),
                ConstantAcceleration::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic())).unwrap(),
                ComponentSelection::<6>::position(2, r.clone()).unwrap(),
                KalmanFilter::default(),
            )
            .unwrap(),
        ),
        Box::new(
            FilterMode::<5, _, _, _>::new(
                "CT",
                StateLayout::ct_2d(),
                CoordinatedTurnWithRate::new(ProcessNoise::discrete(0.005, NoiseGain::kinematic()), 1e-5).unwrap(),
                ComponentSelection::<5>::position(2, r).unwrap(),
                ExtendedKalmanFilter::default(),
            )
            .unwrap(),
        ),
    ];
    let imm =
        InteractingMultipleModel::new(modes, ModeTransitions::mean_sojourn(vec![60.0, 15.0, 20.0]).unwrap()).unwrap();
    let x0 = initial();
    let state = imm
        .initial_state(
            &ModeEstimate::from_gaussian(&x0),
            &StateLayout::cv_2d(),
            0.01,
            &[0.6, 0.2, 0.2],
            0.0,
        )
        .unwrap();
    let z = DVector::from_vec(vec![10.0, 0.5]);
    let kf = KalmanFilter::default();

    let mut group = c.benchmark_group("imm_step");
    group.bench_function("single_cv_kf_baseline", |b| {
        b.iter(|| {
            let prior = kf.predict(black_box(&x0), &cv_model, 1.0).unwrap();
            kf.update(&prior, &fix4, black_box(&z)).unwrap()
        })
    });
    group.bench_function("imm_cv_ca_ct", |b| {
        b.iter(|| {
            let prior = imm.predict(black_box(&state), 1.0).unwrap();
            imm.update(&prior, black_box(&z)).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_vd, bench_imm);
criterion_main!(benches);
