//! L-WKNN against global WKNN, query time at UJIIndoorLoc size, in one run:
//! - on UJIIndoorLoc itself (19 937 reference points, 520 access points at estimated
//!   positions; powed representation, Sørensen distance, k = 13), cycling through the 1 111
//!   validation queries;
//! - on a seed-002-style grid site of the same size with known anchor positions
//!   ([`rtls_sim::GridSite::ujiindoorloc_size`]; Euclidean on dBm, k = 4, seed 002's
//!   N_k = 4, radius 30 m), cycling through 200 random queries.
//!
//! ```sh
//! cargo bench -p rtls-data --bench fingerprint
//! ```
//! The neighbour agreement of the same configurations is measured by
//! `crates/rtls-data/tests/ujiindoorloc.rs` and `crates/rtls-data/tests/grid_site.rs`.

#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use rand::{Rng, SeedableRng};
use rtls_data::{data_dir, ujiindoorloc};
use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalSpace};
use rtls_sim::GridSite;

/// L-WKNN on UJIIndoorLoc: the 3 strongest access points, 40 m.
const UJI_LOCAL: LocalWknn = LocalWknn {
    strongest_anchors: 3,
    radius_m: 40.0,
    knn: Knn::wknn(13),
};

fn ujiindoorloc_queries(c: &mut Criterion) {
    let dir = data_dir();
    let training = ujiindoorloc::load(&dir.join(ujiindoorloc::TRAINING)).expect("UJIIndoorLoc training data");
    let validation = ujiindoorloc::load(&dir.join(ujiindoorloc::VALIDATION)).expect("UJIIndoorLoc validation data");
    let database = FingerprintDatabase::from_survey(ujiindoorloc::survey(&training))
        .and_then(|db| db.with_estimated_anchors(8))
        .expect("survey");
    let index = FingerprintIndex::new(database, SignalSpace::powed_sorensen()).expect("index");
    let queries: Vec<Vec<Option<f64>>> = validation.iter().map(ujiindoorloc::Fingerprint::query).collect();
    let locator = UJI_LOCAL.build(&index).expect("l-wknn");
    let mut group = c.benchmark_group("ujiindoorloc_query");
    let mut k = 0;
    group.bench_function(BenchmarkId::new("global_wknn", "k13"), |b| {
        b.iter(|| {
            k = (k + 1) % queries.len();
            UJI_LOCAL.knn.locate(&index, &queries[k]).expect("fix")
        });
    });
    group.bench_function(BenchmarkId::new("l_wknn", "nk3_r40_k13"), |b| {
        b.iter(|| {
            k = (k + 1) % queries.len();
            locator.locate(&queries[k]).expect("fix")
        });
    });
    group.finish();
}

fn grid_site_queries(c: &mut Criterion) {
    let site = GridSite::ujiindoorloc_size();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2002);
    let database = FingerprintDatabase::from_survey(site.survey(1.0, &mut rng).expect("survey")).expect("database");
    let index = FingerprintIndex::new(database, site.signal_space()).expect("index");
    let queries: Vec<Vec<Option<f64>>> = (0..200)
        .map(|_| {
            let p = [rng.gen_range(20.0..500.0), rng.gen_range(20.0..380.0)];
            site.query(p, 16.0, &mut rng).expect("query")
        })
        .collect();
    let local = LocalWknn {
        radius_m: 30.0,
        ..LocalWknn::default()
    };
    let locator = local.build(&index).expect("l-wknn");
    let mut group = c.benchmark_group("grid_site_query");
    let mut k = 0;
    group.bench_function(BenchmarkId::new("global_wknn", "k4"), |b| {
        b.iter(|| {
            k = (k + 1) % queries.len();
            local.knn.locate(&index, &queries[k]).expect("fix")
        });
    });
    group.bench_function(BenchmarkId::new("l_wknn", "nk4_r30_k4"), |b| {
        b.iter(|| {
            k = (k + 1) % queries.len();
            locator.locate(&queries[k]).expect("fix")
        });
    });
    group.finish();
}

criterion_group!(benches, ujiindoorloc_queries, grid_site_queries);
criterion_main!(benches);
