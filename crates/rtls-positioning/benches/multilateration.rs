//! Criterion benchmarks of the multilateration kernels.
//!
//! Run: `cargo bench -p rtls-positioning --bench multilateration`
//!
//! - `lls/{2d,3d}/N`: unweighted linear least squares (reference differencing) from `N` ranges.
//! - `wlls/{2d,3d}/N`: weighted linear least squares with its covariance.
//! - `gauss_newton/{2d,3d}/N`: the weighted Gauss–Newton / Levenberg–Marquardt fix with
//!   covariance, GDOP and χ², started by the weighted linear fix (the default).
//!
//! `N` = 4, 8, 16 anchors spread over a 30 m × 30 m (× 4 m high in 3-D) site, the tag inside,
//! ranges with σ = 10 cm noise (fixed seed), so GN takes its usual few iterations.

#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::SVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_positioning::multilateration::{
    gauss_newton, linear_least_squares, weighted_linear_least_squares, GaussNewtonOptions, Initial, ReferenceAnchor,
};

const SIGMA_M: f64 = 0.1;

/// `n` anchors on the site, a tag inside, noisy ranges and their variances.
fn case<const D: usize>(n: usize, seed: u64) -> (Vec<[f64; D]>, Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let extent = |axis: usize| if axis < 2 { 30.0 } else { 4.0 };
    let anchors: Vec<[f64; D]> = (0..n)
        .map(|_| core::array::from_fn(|axis| rng.gen_range(0.0..extent(axis))))
        .collect();
    let truth = SVector::<f64, D>::from_fn(|axis, _| rng.gen_range(0.25..0.75) * extent(axis));
    let noise = Normal::new(0.0, SIGMA_M).unwrap();
    let ranges = anchors
        .iter()
        .map(|a| ((truth - SVector::from(*a)).norm() + noise.sample(&mut rng)).abs())
        .collect();
    (anchors, ranges, vec![SIGMA_M * SIGMA_M; n])
}

fn bench_dimension<const D: usize>(c: &mut Criterion, label: &str) {
    let options = GaussNewtonOptions::default();
    for n in [4usize, 8, 16] {
        let (anchors, ranges, variances) = case::<D>(n, 42 + n as u64);
        // the case must be solvable, or the benchmark measures an error path
        let fix =
            gauss_newton(&anchors, &ranges, &variances, Initial::Linear, &options).expect("benchmark case is solvable");
        eprintln!(
            "case {label}/{n}: Gauss–Newton converges in {} iterations, GDOP {:.1}",
            fix.iterations, fix.gdop
        );
        c.bench_with_input(BenchmarkId::new(format!("lls/{label}"), n), &n, |b, _| {
            b.iter(|| {
                linear_least_squares(black_box(&anchors), black_box(&ranges), ReferenceAnchor::NearestRange).unwrap()
            });
        });
        c.bench_with_input(BenchmarkId::new(format!("wlls/{label}"), n), &n, |b, _| {
            b.iter(|| {
                weighted_linear_least_squares(
                    black_box(&anchors),
                    black_box(&ranges),
                    black_box(&variances),
                    ReferenceAnchor::NearestRange,
                )
                .unwrap()
            });
        });
        c.bench_with_input(BenchmarkId::new(format!("gauss_newton/{label}"), n), &n, |b, _| {
            b.iter(|| {
                gauss_newton(
                    black_box(&anchors),
                    black_box(&ranges),
                    black_box(&variances),
                    Initial::Linear,
                    &options,
                )
                .unwrap()
            });
        });
    }
}

fn multilateration(c: &mut Criterion) {
    bench_dimension::<2>(c, "2d");
    bench_dimension::<3>(c, "3d");
}

criterion_group!(benches, multilateration);
criterion_main!(benches);
