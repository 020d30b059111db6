//! Tracker throughput and latency.
//!
//! - `fix_then_filter/100k_tags`: a stream of position fixes spread over 100 000 tags (one fix
//!   per tag per second, in time order), every track already started: records per second on one
//!   thread, next to the bare KF predict + update of one 4-state track (the floor the tracker's
//!   bookkeeping adds to). `fix_then_filter/1k_tags`: the same over 1 000 tags (100 rounds),
//!   whose tracks stay in the cache — the difference between the two is what the memory costs
//!   (a 2-D track is 2.1 kB; its tag's index entry and text are further loads).
//! - `tightly_coupled/ranges`: UWB ranges of 1 000 tags to 4 anchors (one per record) into the
//!   EKF, next to the bare EKF predict + range update.
//! - `checkpoint`: a cluster checkpoint of the 1 000 tightly coupled tracks — the tracker's state
//!   taken and encoded as CBOR (`Tracker::state`, what `rtls serve --cluster` stores every
//!   `checkpoint_s`), and decoded and restored into a fresh tracker; its size is printed.
//! - per-record latency percentiles (p50, p99, p99.9, max) of both streams, printed, measured with
//!   `Instant` around each `push` (ticks over all tracks included).
//!
//! Run: `cargo bench -p rtls-engine --bench tracker`.
#![allow(missing_docs)] // criterion_group! generates an undocumented fn

use std::cell::RefCell;
use std::hint::black_box;
use std::time::Instant;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkGroup, Criterion, Throughput};
use nalgebra::DVector;
use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Output, Tracker};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};

/// Records per timed fix-then-filter batch (and bare KF steps).
const FIX_BATCH: usize = 100_000;
const RANGE_TAGS: usize = 1_000;

fn site(pipeline: &str, filter: &str) -> Site {
    Site::from_toml_str(
        &format!(
            r#"
readers = [
  {{ id = "A1", position_m = [0.0, 0.0], technology = "uwb", radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }} }},
  {{ id = "A2", position_m = [30.0, 0.0], technology = "uwb", radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }} }},
  {{ id = "A3", position_m = [30.0, 30.0], technology = "uwb", radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }} }},
  {{ id = "A4", position_m = [0.0, 30.0], technology = "uwb", radio = {{ range = {{ range_std_m = 0.1, bias_m = 0.0 }} }} }},
]
[tracker]
pipeline = "{pipeline}"
motion_model = "cv"
filter = "{filter}"
acceleration_noise_std_mps2 = 1.0
gate_probability = 0.999
initiation = {{ confirm_updates = 3, within_s = 5.0 }}
coast_timeout_s = 10.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
"#
        ),
        "bench.toml",
    )
    .expect("bench site")
}

/// Tag `i` walks a circle; its fix `k` is at `k + i / tags` s.
fn fix_round(tags: usize, round: usize) -> Vec<Record> {
    (0..tags)
        .map(|i| {
            let t = round as f64 + i as f64 / tags as f64;
            let phase = i as f64 * 0.001 + 0.1 * t;
            Record {
                time_s: t,
                tag: format!("tag-{i:06}"),
                measurement: Measurement::Fix {
                    position_m: vec![15.0 + 10.0 * phase.cos(), 15.0 + 10.0 * phase.sin()],
                    covariance_m2: vec![0.04, 0.0, 0.0, 0.04],
                },
            }
        })
        .collect()
}

const ANCHORS: [(&str, [f64; 2]); 4] = [
    ("A1", [0.0, 0.0]),
    ("A2", [30.0, 0.0]),
    ("A3", [30.0, 30.0]),
    ("A4", [0.0, 30.0]),
];

/// Round `round` of ranges: every tag ranges to one anchor (round robin), 10 rounds per second.
fn range_round(tags: usize, round: usize) -> Vec<Record> {
    (0..tags)
        .map(|i| {
            let t = 0.1 * round as f64 + 0.1 * i as f64 / tags as f64;
            let p = [
                15.0 + 5.0 * (0.1 * t + i as f64).cos(),
                15.0 + 5.0 * (0.1 * t + i as f64).sin(),
            ];
            let (id, a) = ANCHORS[(round + i) % 4];
            Record {
                time_s: t,
                tag: format!("tag-{i:04}"),
                measurement: Measurement::Range {
                    anchor: id.into(),
                    range_m: ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt(),
                    std_m: None,
                    anchor_position_m: None,
                },
            }
        })
        .collect()
}

/// A tracker that has seen `warm_rounds` rounds, and the next round.
fn warmed(site: &Site, rounds: &dyn Fn(usize) -> Vec<Record>, warm_rounds: usize) -> (Tracker, Vec<Record>) {
    let mut tracker = Tracker::new(site).expect("tracker");
    let mut out = Output::default();
    for round in 0..warm_rounds {
        for record in rounds(round) {
            tracker.push(record, &mut out).expect("push");
            out.clear();
        }
    }
    (tracker, rounds(warm_rounds))
}

fn percentiles(mut samples_ns: Vec<u64>) -> String {
    samples_ns.sort_unstable();
    let at = |p: f64| samples_ns[((samples_ns.len() - 1) as f64 * p).round() as usize];
    format!(
        "p50 {} ns, p99 {} ns, p99.9 {} ns, max {} ns over {} records",
        at(0.5),
        at(0.99),
        at(0.999),
        samples_ns[samples_ns.len() - 1],
        samples_ns.len()
    )
}

fn latency(name: &str, tracker: &Tracker, records: &[Record]) {
    let mut tracker = tracker.clone();
    let mut out = Output::default();
    let mut samples = Vec::with_capacity(records.len());
    for record in records.iter().cloned() {
        let start = Instant::now();
        tracker.push(record, &mut out).expect("push");
        samples.push(start.elapsed().as_nanos() as u64);
        out.clear();
    }
    println!("{name} per-record latency: {}", percentiles(samples));
}

/// Times pushing `records` into copies of `tracker` as benchmark `name` of `group`.
///
/// One output list serves every batch, cleared after each record, as a live caller keeps it
/// (the server's partitions do): a fresh one per batch would time its growth to the 50 000
/// updates of one tick — reallocations and first-touch page faults, 10–15 % of the batch —
/// rather than the tracker. The emptied batch and the tracker are dropped after the timing.
fn bench_pushes(group: &mut BenchmarkGroup<'_, WallTime>, name: &str, tracker: &Tracker, records: &[Record]) {
    group.throughput(Throughput::Elements(records.len() as u64));
    let spare = RefCell::new(Output::default());
    group.bench_function(name, |b| {
        b.iter_batched(
            || (tracker.clone(), records.to_vec()),
            |(mut tracker, mut records)| {
                let mut out = spare.take();
                for record in records.drain(..) {
                    tracker.push(record, &mut out).expect("push");
                    out.clear();
                }
                spare.replace(out);
                (tracker, records)
            },
            BatchSize::PerIteration,
        );
    });
}

fn fix_then_filter(c: &mut Criterion) {
    let site = site("fix-then-filter", "kf");
    let mut group = c.benchmark_group("fix_then_filter");
    group.sample_size(10);
    // 100 000 tags: every record's track, index entry and tag text are cache misses; 1 000
    // tags (100 rounds per batch): all of them stay in the cache — the two apart say what the
    // memory costs. Each batch holds FIX_BATCH records.
    for (name, tags) in [("100k_tags", 100_000), ("1k_tags", 1_000)] {
        let (tracker, _) = warmed(&site, &|r| fix_round(tags, r), 3);
        let rounds = FIX_BATCH / tags;
        let next: Vec<Record> = (3..3 + rounds).flat_map(|r| fix_round(tags, r)).collect();
        latency(&format!("fix-then-filter ({name})"), &tracker, &next);
        bench_pushes(&mut group, name, &tracker, &next);
    }
    // baseline: the bare KF predict + update of one 4-state track per record
    let motion = ConstantVelocity::new(ProcessNoise::continuous(1.0)).expect("cv");
    let model = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 0.04).expect("R")).expect("H");
    let kf = KalmanFilter::default();
    let start = Gaussian::new(Vector::<4>::new(15.0, 0.0, 15.0, 0.0), Matrix::<4>::identity(), 0.0).expect("x0");
    let z = DVector::from_vec(vec![15.1, 14.9]);
    group.throughput(Throughput::Elements(FIX_BATCH as u64));
    group.bench_function("bare_kf_step", |b| {
        b.iter_batched(
            || (start, 0.0),
            |(mut state, mut t)| {
                for _ in 0..FIX_BATCH {
                    t += 1.0;
                    let prior = kf.predict(&state, &motion, t).expect("predict");
                    state = kf.update(&prior, &model, black_box(&z)).expect("update").state;
                }
                state
            },
            BatchSize::PerIteration,
        );
    });
    group.finish();
}

fn tightly_coupled(c: &mut Criterion) {
    let site = site("tightly-coupled", "ekf");
    let (tracker, next) = warmed(&site, &|r| range_round(RANGE_TAGS, r), 20);
    let mut records = next;
    for round in 21..120 {
        records.extend(range_round(RANGE_TAGS, round));
    }
    latency("tightly coupled (1k tags, ranges)", &tracker, &records);
    let mut group = c.benchmark_group("tightly_coupled");
    group.sample_size(10);
    bench_pushes(&mut group, "ranges_1k_tags", &tracker, &records);
    let motion = ConstantVelocity::new(ProcessNoise::continuous(1.0)).expect("cv");
    let ekf = ExtendedKalmanFilter::default();
    let start = Gaussian::new(Vector::<4>::new(15.0, 0.0, 15.0, 0.0), Matrix::<4>::identity(), 0.0).expect("x0");
    group.bench_function("bare_ekf_range_step", |b| {
        b.iter_batched(
            || (start, 0.0),
            |(mut state, mut t)| {
                for k in 0..records.len() {
                    t += 0.1;
                    let (_, a) = ANCHORS[k % 4];
                    let model = Ranges::planar(&[a], NoiseCovariance::isotropic(1, 0.01).expect("R")).expect("H");
                    let prior = ekf.predict(&state, &motion, t).expect("predict");
                    let d = ((15.0 - a[0]).powi(2) + (15.0 - a[1]).powi(2)).sqrt();
                    state = ekf
                        .update(&prior, &model, &DVector::from_element(1, d))
                        .expect("update")
                        .state;
                }
                state
            },
            BatchSize::PerIteration,
        );
    });
    group.finish();
}

fn checkpoint(c: &mut Criterion) {
    let site = site("tightly-coupled", "ekf");
    let (tracker, _) = warmed(&site, &|r| range_round(RANGE_TAGS, r), 20);
    let encode = |tracker: &Tracker| {
        let mut bytes = Vec::new();
        ciborium::into_writer(&tracker.state(), &mut bytes).expect("encode");
        bytes
    };
    let bytes = encode(&tracker);
    println!(
        "checkpoint of {} tracks: {} bytes ({} bytes per track)",
        tracker.track_count(),
        bytes.len(),
        bytes.len() / tracker.track_count().max(1)
    );
    let mut group = c.benchmark_group("checkpoint");
    group.sample_size(10);
    group.throughput(Throughput::Elements(tracker.track_count() as u64));
    group.bench_function("take_and_encode_1k_tracks", |b| b.iter(|| encode(black_box(&tracker))));
    group.bench_function("decode_and_restore_1k_tracks", |b| {
        b.iter(|| {
            let state: rtls_engine::tracker::TrackerState =
                ciborium::from_reader(black_box(bytes.as_slice())).expect("decode");
            let mut fresh = Tracker::new(&site).expect("tracker");
            fresh.restore(state).expect("restore");
            fresh
        });
    });
    group.finish();
}

criterion_group!(benches, fix_then_filter, tightly_coupled, checkpoint);
criterion_main!(benches);
