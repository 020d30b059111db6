//! The fixed-size kernels against the general ones they replace on the tracker's fix path:
//! [`KalmanFilter::update_fixed`] against [`KalmanFilter::update`] with a
//! [`ComponentSelection`], [`AdaptiveNoise::observe_fixed`] against [`AdaptiveNoise::observe`],
//! and [`FixedSelection::new`]'s checks against `NoiseCovariance::full` + `ComponentSelection::new`,
//! on random states, covariances and measurements (seeded): equal to 1e-12 relative.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtls_estimation::adaptive::{AdaptiveNoise, NoiseScale};
use rtls_estimation::filter::{CovarianceUpdate, KalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, FixedSelection, NoiseCovariance};
use rtls_estimation::{Gaussian, Matrix, Vector};

const RELATIVE: f64 = 1e-12;

/// `max |a − b| ≤ 1e-12 · max |b|`, entry by entry over the slices.
fn assert_close(what: &str, a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len(), "{what}: sizes");
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    let worst = a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(worst <= RELATIVE * scale, "{what}: {a:?} vs {b:?} (worst {worst:e})");
}

/// A random symmetric positive definite `n × n` matrix `D A Aᵀ D + εI` with entries spread
/// over six decades (`D` diagonal, `10^U(−3, 3)`).
fn spd(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
    let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
    let d = DMatrix::from_diagonal(&DVector::from_fn(n, |_, _| 10f64.powf(rng.gen_range(-3.0..3.0))));
    let m = &d * (&a * a.transpose() + DMatrix::identity(n, n) * 0.05) * &d;
    (&m + m.transpose()) * 0.5
}

fn prior<const N: usize>(rng: &mut ChaCha8Rng) -> Gaussian<N> {
    let mean = Vector::<N>::from_fn(|_, _| rng.gen_range(-100.0..100.0));
    let p = spd(rng, N);
    Gaussian::new(mean, Matrix::<N>::from_column_slice(p.as_slice()), 3.5).expect("prior")
}

fn compare<const N: usize, const M: usize>(rng: &mut ChaCha8Rng, indices: [usize; M], form: CovarianceUpdate) {
    let kf = KalmanFilter::new(form);
    let prior = prior::<N>(rng);
    let r = spd(rng, M);
    let z = SVector::<f64, M>::from_fn(|_, _| rng.gen_range(-100.0..100.0));
    let general_model =
        ComponentSelection::<N>::new(&indices, NoiseCovariance::full(r.clone()).expect("R")).expect("H");
    let general = kf
        .update(&prior, &general_model, &DVector::from_column_slice(z.as_slice()))
        .expect("general update");
    let fixed_model =
        FixedSelection::<N, M>::new(indices, SMatrix::<f64, M, M>::from_column_slice(r.as_slice())).expect("H");
    let fixed = kf.update_fixed(&prior, &fixed_model, &z).expect("fixed update");
    assert_close("mean", fixed.state.mean().as_slice(), general.state.mean().as_slice());
    assert_close(
        "covariance",
        fixed.state.covariance().as_slice(),
        general.state.covariance().as_slice(),
    );
    assert_eq!(fixed.state.time_s(), general.state.time_s());
    assert_close("innovation", fixed.innovation.as_slice(), general.innovation.as_slice());
    assert_close(
        "innovation covariance",
        fixed.innovation_covariance.as_slice(),
        general.innovation_covariance.as_slice(),
    );
    assert_close("gain", fixed.gain.as_slice(), general.gain.as_slice());
    assert_close("nis", &[fixed.nis], &[general.nis]);
    assert_close(
        "ln |S|",
        &[fixed.log_det_innovation_covariance],
        &[general.log_det_innovation_covariance],
    );
    // the conversion is exact
    let converted = fixed.to_updated();
    assert_eq!(converted.innovation.as_slice(), fixed.innovation.as_slice());
    assert_eq!(
        converted.innovation_covariance.as_slice(),
        fixed.innovation_covariance.as_slice()
    );
    assert_eq!(converted.gain.as_slice(), fixed.gain.as_slice());
    assert_eq!(converted.measurement_dim(), M);

    // the adaptive scale from the update's innovation, both ways, over a few steps
    let adaptive = AdaptiveNoise::new(rng.gen_range(1.0..60.0), 100.0).expect("adaptive");
    let gate = rng.gen_range(1.0..20.0);
    let (mut general_scale, mut fixed_scale) = (NoiseScale::default(), NoiseScale::default());
    for step in 0..4 {
        let elapsed_s = [f64::NAN, 0.0, 0.7, 12.0][step];
        let nu = SVector::<f64, M>::from_fn(|_, _| rng.gen_range(-3.0..3.0)) * (step as f64 * 3.0 + 0.1);
        let s = fixed.innovation_covariance;
        let r_fixed = *fixed_model.noise();
        general_scale = adaptive
            .observe(
                &general_scale,
                elapsed_s,
                &DVector::from_column_slice(nu.as_slice()),
                &DMatrix::from_column_slice(M, M, s.as_slice()),
                &DMatrix::from_column_slice(M, M, r_fixed.as_slice()),
                gate,
            )
            .expect("general observe");
        fixed_scale = adaptive
            .observe_fixed(&fixed_scale, elapsed_s, &nu, &s, &r_fixed, gate)
            .expect("fixed observe");
        assert_close("noise scale", &[fixed_scale.scale()], &[general_scale.scale()]);
        assert_eq!(fixed_scale.updates(), general_scale.updates());
    }
}

#[test]
fn fixed_update_equals_the_general_update_on_random_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    for _ in 0..300 {
        for form in [CovarianceUpdate::Joseph, CovarianceUpdate::Simple] {
            // 2-D CV [x, vx, y, vy]: fixes, one axis, velocities
            compare::<4, 2>(&mut rng, [0, 2], form);
            compare::<4, 1>(&mut rng, [0], form);
            compare::<4, 2>(&mut rng, [1, 3], form);
            // 3-D CV [x, vx, y, vy, z, vz]
            compare::<6, 3>(&mut rng, [0, 2, 4], form);
            compare::<6, 2>(&mut rng, [0, 2], form);
            compare::<6, 3>(&mut rng, [1, 3, 5], form);
            // any selection, in any order
            compare::<6, 2>(&mut rng, [4, 1], form);
        }
    }
}

#[test]
fn fixed_selection_refuses_what_the_general_model_refuses() {
    let cases: [(SMatrix<f64, 2, 2>, [usize; 2]); 6] = [
        (SMatrix::<f64, 2, 2>::new(1.0, 0.0, 0.0, f64::NAN), [0, 2]),
        (SMatrix::<f64, 2, 2>::new(1.0, 0.5, 0.4, 1.0), [0, 2]),
        (SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0), [0, 2]),
        (SMatrix::<f64, 2, 2>::new(1.0, 0.0, 0.0, 1.0), [0, 4]),
        (SMatrix::<f64, 2, 2>::new(1.0, 0.0, 0.0, 1.0), [2, 2]),
        (SMatrix::<f64, 2, 2>::new(1.0, 0.0, 0.0, 1.0), [0, 2]),
    ];
    for (r, indices) in cases {
        let general = NoiseCovariance::full(DMatrix::from_column_slice(2, 2, r.as_slice()))
            .and_then(|noise| ComponentSelection::<4>::new(&indices, noise))
            .map(|_| ());
        let fixed = FixedSelection::<4, 2>::new(indices, r).map(|_| ());
        assert_eq!(fixed, general, "R = {r:?}, indices {indices:?}");
    }
}

#[test]
fn fixed_update_fails_where_the_general_update_fails() {
    let kf = KalmanFilter::default();
    let prior = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::identity(), 0.0).expect("prior");
    let fixed_model = FixedSelection::<4, 2>::new([0, 2], SMatrix::<f64, 2, 2>::identity()).expect("H");
    let general_model =
        ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 1.0).expect("R")).expect("H");
    let z = SVector::<f64, 2>::new(1.0, f64::INFINITY);
    let fixed = kf.update_fixed(&prior, &fixed_model, &z).map(|_| ());
    let general = kf
        .update(&prior, &general_model, &DVector::from_column_slice(z.as_slice()))
        .map(|_| ());
    assert!(fixed.is_err());
    assert_eq!(fixed, general);
}
