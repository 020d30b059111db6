//! Seeded Monte Carlo consistency: with the true model, the average NEES over independent runs
//! stays inside its 95 % chi-square interval (Bar-Shalom, Li, Kirubarajan 2001, §5.4.2).

use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters, UnscentedKalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, MeasurementModel, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::stats::average_consistency_interval;
use rtls_estimation::{Gaussian, Matrix, Vector};

const RUNS: usize = 200;
const STEPS: usize = 40;
const SEED: u64 = 20_261_121;
const SIGMA_W2: f64 = 0.2;

/// Simulates one truth trajectory of the 2-D CV model with discrete white-noise acceleration.
fn truth(rng: &mut ChaCha8Rng, dts: &[f64]) -> Vec<Vector<4>> {
    let accel = Normal::new(0.0, SIGMA_W2.sqrt()).unwrap();
    let mut x = Vector::<4>::new(0.0, 1.0, 0.0, 0.5);
    let mut out = Vec::new();
    for &dt in dts {
        let (ax, ay) = (accel.sample(rng), accel.sample(rng));
        // x ← F x + G w,  G = [dt²/2, dt]
        x = Vector::<4>::new(
            x[0] + dt * x[1] + 0.5 * dt * dt * ax,
            x[1] + dt * ax,
            x[2] + dt * x[3] + 0.5 * dt * dt * ay,
            x[3] + dt * ay,
        );
        out.push(x);
    }
    out
}

enum Which {
    Kf,
    Ekf,
    Ukf,
}

/// Runs `RUNS` seeded trials; returns the average NEES at each step.
fn average_nees(which: Which) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let motion = ConstantVelocity::new(ProcessNoise::discrete(SIGMA_W2, NoiseGain::kinematic())).unwrap();
    let fix_variance = [1.0, 2.0];
    let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&fix_variance).unwrap()).unwrap();
    let anchors = [[-30.0, -20.0], [40.0, -25.0], [5.0, 45.0]];
    let range_variance = 0.05;
    let ranges = Ranges::planar(&anchors, NoiseCovariance::isotropic(3, range_variance).unwrap()).unwrap();
    let p0 = Matrix::<4>::from_diagonal(&Vector::<4>::new(4.0, 1.0, 4.0, 1.0));
    let mut sums = vec![0.0; STEPS];
    for _ in 0..RUNS {
        let dts: Vec<f64> = (0..STEPS).map(|k| 0.5 + 0.25 * (k % 5) as f64).collect();
        let xs = truth(&mut rng, &dts);
        // x̂₀ ~ N(x₀, P₀): draw the initial estimate consistently with its covariance.
        let l = p0.cholesky().unwrap().unpack();
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let e = Vector::<4>::from_fn(|_, _| n01.sample(&mut rng));
        let mut state = Gaussian::new(Vector::<4>::new(0.0, 1.0, 0.0, 0.5) + l * e, p0, 0.0).unwrap();
        let mut t = 0.0;
        for (k, (&dt, x)) in dts.iter().zip(&xs).enumerate() {
            t += dt;
            state = match which {
                Which::Kf => {
                    let kf = KalmanFilter::default();
                    let z = DVector::from_row_slice(&[
                        x[0] + Normal::new(0.0, fix_variance[0].sqrt()).unwrap().sample(&mut rng),
                        x[2] + Normal::new(0.0, fix_variance[1].sqrt()).unwrap().sample(&mut rng),
                    ]);
                    kf.update(&kf.predict(&state, &motion, t).unwrap(), &fixes, &z)
                        .unwrap()
                        .state
                }
                Which::Ekf | Which::Ukf => {
                    let noise = Normal::new(0.0, range_variance.sqrt()).unwrap();
                    let mut z = ranges.predict(x).unwrap();
                    z.iter_mut().for_each(|r| *r += noise.sample(&mut rng));
                    if matches!(which, Which::Ekf) {
                        let ekf = ExtendedKalmanFilter::default();
                        ekf.update(&ekf.predict(&state, &motion, t).unwrap(), &ranges, &z)
                            .unwrap()
                            .state
                    } else {
                        let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::default());
                        ukf.update(&ukf.predict(&state, &motion, t).unwrap(), &ranges, &z)
                            .unwrap()
                            .state
                    }
                }
            };
            sums[k] += state.nees(x).unwrap();
        }
    }
    sums.iter().map(|s| s / RUNS as f64).collect()
}

fn check(name: &str, anees: &[f64]) {
    let interval = average_consistency_interval(4, RUNS, 0.95).unwrap();
    let inside = anees.iter().filter(|&&a| interval.contains(a)).count();
    let overall = anees.iter().sum::<f64>() / anees.len() as f64;
    // 95 % of the steps should fall inside; allow a little sampling slack (≥ 85 %).
    assert!(
        inside as f64 >= 0.85 * anees.len() as f64,
        "{name}: only {inside}/{} steps inside [{:.3}, {:.3}]; ANEES = {anees:?}",
        anees.len(),
        interval.lower,
        interval.upper
    );
    assert!(
        interval.contains(*anees.last().unwrap()),
        "{name}: final ANEES {} outside {interval:?}",
        anees.last().unwrap()
    );
    assert!(
        (overall - 4.0).abs() < 0.4,
        "{name}: mean ANEES {overall} far from the state dimension 4"
    );
}

#[test]
fn kf_average_nees_is_consistent() {
    check("kf", &average_nees(Which::Kf));
}

#[test]
fn ekf_average_nees_is_consistent_with_ranges() {
    check("ekf", &average_nees(Which::Ekf));
}

#[test]
fn ukf_average_nees_is_consistent_with_ranges() {
    check("ukf", &average_nees(Which::Ukf));
}

#[test]
fn an_overconfident_filter_fails_the_test() {
    // Same data, but the filter believes the process noise is 50× smaller: the check must see it.
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let motion = ConstantVelocity::new(ProcessNoise::discrete(SIGMA_W2 / 50.0, NoiseGain::kinematic())).unwrap();
    let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&[1.0, 2.0]).unwrap()).unwrap();
    let kf = KalmanFilter::default();
    let dts = vec![1.0; STEPS];
    let mut final_sum = 0.0;
    for _ in 0..RUNS {
        let xs = truth(&mut rng, &dts);
        let mut state = Gaussian::new(Vector::<4>::new(0.0, 1.0, 0.0, 0.5), Matrix::<4>::identity(), 0.0).unwrap();
        for (k, x) in xs.iter().enumerate() {
            let z = DVector::from_row_slice(&[
                x[0] + Normal::new(0.0, 1.0).unwrap().sample(&mut rng),
                x[2] + Normal::new(0.0, 2.0f64.sqrt()).unwrap().sample(&mut rng),
            ]);
            state = kf
                .update(&kf.predict(&state, &motion, (k + 1) as f64).unwrap(), &fixes, &z)
                .unwrap()
                .state;
        }
        final_sum += state.nees(xs.last().unwrap()).unwrap();
    }
    let interval = average_consistency_interval(4, RUNS, 0.95).unwrap();
    assert!(
        final_sum / RUNS as f64 > interval.upper,
        "overconfident filter not detected: {}",
        final_sum / RUNS as f64
    );
}
