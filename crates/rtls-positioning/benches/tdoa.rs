//! Criterion benchmarks of the TDOA kernels.
//!
//! Run: `cargo bench -p rtls-positioning --bench tdoa`
//!
//! - `chan/2d/N`: Chan's two-step WLS in the plane with `N` = 4 and 8 stations.
//! - `chan/3d/N`: Chan's two-step WLS in space with `N` = 5 and 8 stations.
//! - `chan_taylor/2d/4`: Chan's fix refined to the maximum-likelihood fix (Levenberg–Marquardt)
//!   with 4 stations.
//!
//! Stations on a circle of radius 40 m (in space alternating between 0.5 m and 3 m height),
//! a tag inside, differenced TOA noise σ = 5 cm (fixed seed), the covariance of differenced
//! independent TOAs, reference station 0.

#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::{DMatrix, SVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_positioning::tdoa::{chan, chan_taylor, differenced_range_covariance, range_differences_at};

const SIGMA_M: f64 = 0.05;

/// `n` stations, noisy range differences (reference 0) and their covariance.
fn case<const D: usize>(n: usize, seed: u64) -> (Vec<[f64; D]>, Vec<f64>, DMatrix<f64>) {
    let stations: Vec<[f64; D]> = (0..n)
        .map(|k| {
            let angle = k as f64 * core::f64::consts::TAU / n as f64 + 0.3;
            let mut s = [0.0; D];
            s[0] = 40.0 * angle.cos();
            s[1] = 40.0 * angle.sin();
            if D == 3 {
                s[2] = if k % 2 == 0 { 3.0 } else { 0.5 };
            }
            s
        })
        .collect();
    let mut tag = SVector::<f64, D>::zeros();
    tag[0] = 7.0;
    tag[1] = -11.0;
    if D == 3 {
        tag[2] = 1.2;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, SIGMA_M).unwrap();
    let toa: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
    let clean = range_differences_at(&stations, 0, &tag).unwrap();
    let r: Vec<f64> = clean.iter().zip(1..n).map(|(c, i)| c + toa[i] - toa[0]).collect();
    let q = differenced_range_covariance(&vec![SIGMA_M * SIGMA_M; n], 0).unwrap();
    (stations, r, q)
}

fn bench_chan(c: &mut Criterion) {
    let mut group = c.benchmark_group("chan");
    for n in [4, 8] {
        let (stations, r, q) = case::<2>(n, 1);
        chan(&stations, 0, &r, &q).expect("benchmark case must solve");
        group.bench_with_input(BenchmarkId::new("2d", n), &n, |b, _| {
            b.iter(|| chan(black_box(&stations), 0, black_box(&r), black_box(&q)))
        });
    }
    for n in [5, 8] {
        let (stations, r, q) = case::<3>(n, 2);
        chan(&stations, 0, &r, &q).expect("benchmark case must solve");
        group.bench_with_input(BenchmarkId::new("3d", n), &n, |b, _| {
            b.iter(|| chan(black_box(&stations), 0, black_box(&r), black_box(&q)))
        });
    }
    group.finish();
}

fn bench_chan_taylor(c: &mut Criterion) {
    let mut group = c.benchmark_group("chan_taylor");
    let (stations, r, q) = case::<2>(4, 3);
    chan_taylor(&stations, 0, &r, &q).expect("benchmark case must solve");
    group.bench_with_input(BenchmarkId::new("2d", 4), &4, |b, _| {
        b.iter(|| chan_taylor(black_box(&stations), 0, black_box(&r), black_box(&q)))
    });
    group.finish();
}

criterion_group!(benches, bench_chan, bench_chan_taylor);
criterion_main!(benches);
