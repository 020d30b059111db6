//! Anonymous multi-target association.
//!
//! - `association_step/{gnn,jpda}/N`: one scan of the [`AnonymousTracker`] with `N` confirmed
//!   tracks and `N` fixes (predict all, gate, clusters, cost matrices, assignment or JPDA, KF
//!   updates, lifecycle, report). The targets sit on a 5 m grid and move at 0.2 m/s, so gating
//!   keeps the clusters small (the sparse case the tracker is built for).
//! - `kf_baseline/N`: the bare rtls-estimation KF predict + position update of `N` tracks, the
//!   floor the association adds to.
//! - `assignment_dense/N`: [`solve_assignment`] alone on a dense `N × N` matrix of uniform
//!   random costs in `[0, 100)` with a non-assignment cost of 1000 (every row assigned): the
//!   worst case, which gating avoids in the tracker.
//!
//! Run: `cargo bench -p rtls-engine --bench association` (add `-- --quick` for a short run).
#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_engine::association::{
    solve_assignment, AnonymousTracker, AnonymousTrackerSettings, Association, CostMatrix, Detection,
};
use rtls_engine::lifecycle::TrackStatus;
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

const SIZES: [usize; 3] = [10, 100, 1000];
const SIGMA_M: f64 = 0.1;

/// Target `i` of `n`: on a 5 m grid, moving at 0.2 m/s in its own direction (neighbours stay
/// ≥ 3 m apart over the 5 s run).
fn target(i: usize, n: usize, t: f64) -> [f64; 2] {
    let side = (n as f64).sqrt().ceil() as usize;
    let heading = i as f64 * 2.399; // golden angle: directions spread evenly
    [
        5.0 * (i % side) as f64 + 0.2 * t * heading.cos(),
        5.0 * (i / side) as f64 + 0.2 * t * heading.sin(),
    ]
}

fn scan(rng: &mut ChaCha8Rng, n: usize, t: f64) -> Vec<Detection> {
    let noise = Normal::new(0.0, SIGMA_M).expect("σ > 0");
    let variance = SIGMA_M * SIGMA_M;
    (0..n)
        .map(|i| {
            let p = target(i, n, t);
            Detection::fix(
                [p[0] + noise.sample(rng), p[1] + noise.sample(rng)],
                [[variance, 0.0], [0.0, variance]],
            )
            .expect("valid fix")
        })
        .collect()
}

/// A tracker with `n` confirmed tracks after 5 scans at 1 Hz, and the 6th scan.
fn warmed_up(association: Association, n: usize) -> (AnonymousTracker, Vec<Detection>) {
    let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
    let settings = AnonymousTrackerSettings {
        association,
        ..AnonymousTrackerSettings::default()
    };
    let mut tracker = AnonymousTracker::new(settings).expect("valid settings");
    for k in 0..5 {
        let t = k as f64;
        tracker.process_scan(t, &scan(&mut rng, n, t)).expect("scan");
    }
    assert_eq!(tracker.tracks().len(), n);
    assert!(tracker.tracks().iter().all(|t| t.status() == TrackStatus::Confirmed));
    (tracker, scan(&mut rng, n, 5.0))
}

fn association_step(c: &mut Criterion) {
    for (name, association) in [("gnn", Association::Gnn), ("jpda", Association::Jpda)] {
        let mut group = c.benchmark_group(format!("association_step/{name}"));
        group.sample_size(10);
        for n in SIZES {
            let (tracker, detections) = warmed_up(association, n);
            // one scan: every detection is assigned to its own track
            let report = tracker.clone().process_scan(5.0, &detections).expect("scan");
            assert_eq!(report.counts.assigned, n);
            assert_eq!(report.clusters, n);
            group.throughput(Throughput::Elements(n as u64));
            group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
                b.iter_batched(
                    || tracker.clone(),
                    |mut tracker| black_box(tracker.process_scan(5.0, &detections).expect("scan")),
                    BatchSize::LargeInput,
                )
            });
        }
        group.finish();
    }
}

fn kf_baseline(c: &mut Criterion) {
    let mut group = c.benchmark_group("kf_baseline");
    group.sample_size(10);
    let motion = ConstantVelocity::new(ProcessNoise::discrete(0.25, NoiseGain::kinematic())).expect("model");
    let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, SIGMA_M * SIGMA_M).expect("R"))
        .expect("model");
    let kf = KalmanFilter::default();
    for n in SIZES {
        let states: Vec<Gaussian<4>> = (0..n)
            .map(|i| {
                let p = target(i, n, 4.0);
                Gaussian::new(
                    Vector::<4>::new(p[0], 0.0, p[1], 0.0),
                    Matrix::<4>::identity() * 0.01,
                    4.0,
                )
                .expect("state")
            })
            .collect();
        let fixes: Vec<DVector<f64>> = (0..n).map(|i| DVector::from_column_slice(&target(i, n, 5.0))).collect();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                for (state, z) in states.iter().zip(&fixes) {
                    let prior = kf.predict(state, &motion, 5.0).expect("predict");
                    black_box(kf.update(&prior, &fix, z).expect("update"));
                }
            })
        });
    }
    group.finish();
}

fn assignment_dense(c: &mut Criterion) {
    let mut group = c.benchmark_group("assignment_dense");
    group.sample_size(10);
    for n in SIZES {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let costs = CostMatrix::new(n, n, (0..n * n).map(|_| rng.gen_range(0.0..100.0)).collect()).expect("costs");
        let unassigned = vec![1000.0; n];
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| black_box(solve_assignment(&costs, &unassigned).expect("solve")))
        });
    }
    group.finish();
}

criterion_group!(benches, association_step, kf_baseline, assignment_dense);
criterion_main!(benches);
