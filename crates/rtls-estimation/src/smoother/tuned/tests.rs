use super::*;
use crate::filter::KalmanFilter;
use crate::motion::{ConstantVelocity, ProcessNoise};
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A fix of `position` with isotropic variance `r` as an information step.
fn fix_step(time_s: f64, position: [f64; 2], r: f64) -> InformationStep<4> {
    InformationStep {
        time_s,
        information: Matrix::<4>::from_diagonal(&Vector::<4>::new(1.0 / r, 0.0, 1.0 / r, 0.0)),
        information_vector: Vector::<4>::new(position[0] / r, 0.0, position[1] / r, 0.0),
    }
}

fn start_at(position: [f64; 2], r: f64) -> Gaussian<4> {
    Gaussian::new(
        Vector::<4>::new(position[0], 0.0, position[1], 0.0),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(r, 4.0, r, 4.0)),
        0.0,
    )
    .expect("start")
}

/// A walker turning on a 20 m circle at 1 m/s, fixes every `dt_s` with errors of variance
/// `r` that persist (AR(1) with correlation time `tau_s`; 0: white).
fn walk(count: usize, dt_s: f64, r: f64, tau_s: f64, seed: u64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phi = if tau_s > 0.0 { (-dt_s / tau_s).exp() } else { 0.0 };
    let innovation = Normal::new(0.0, (r * (1.0 - phi * phi)).sqrt()).expect("normal");
    let start = Normal::new(0.0, r.sqrt()).expect("normal");
    let mut error = [start.sample(&mut rng), start.sample(&mut rng)];
    let mut truth = Vec::new();
    let mut fixes = Vec::new();
    for k in 0..count {
        let angle = k as f64 * dt_s / 20.0;
        let p = [20.0 * angle.cos(), 20.0 * angle.sin()];
        for e in &mut error {
            // e ← φ e + w
            *e = phi * *e + innovation.sample(&mut rng);
        }
        truth.push(p);
        fixes.push([p[0] + error[0], p[1] + error[1]]);
    }
    (truth, fixes)
}

fn rmse(truth: &[[f64; 2]], states: &[Gaussian<4>]) -> f64 {
    let sum: f64 = truth
        .iter()
        .zip(states)
        .map(|(t, s)| (s.mean()[0] - t[0]).powi(2) + (s.mean()[2] - t[1]).powi(2))
        .sum();
    (sum / truth.len() as f64).sqrt()
}

/// With `q` and `c = 1` fixed, the forward pass over fix information is the KF's predict and
/// update of the fixes themselves (the update golden-tested against FilterPy).
#[test]
fn the_forward_pass_over_fix_information_is_the_kalman_filter_of_the_fixes() {
    let (_, fixes) = walk(40, 0.5, 0.25, 0.0, 3);
    let r = 0.25;
    let start = start_at(fixes[0], r);
    let steps: Vec<_> = fixes
        .iter()
        .enumerate()
        .map(|(k, p)| fix_step(k as f64 * 0.5, *p, r))
        .collect();
    let (_, filtered) = forward(&start, &prepare_all(&steps), 0.5, 1.0, true).expect("forward");

    let kf = KalmanFilter::default();
    let motion = ConstantVelocity::new(ProcessNoise::continuous(0.5)).expect("cv");
    let fix_model = crate::measurement::ComponentSelection::<4>::position(
        2,
        crate::measurement::NoiseCovariance::isotropic(2, r).expect("R"),
    )
    .expect("H");
    let mut state = start;
    let mut reference = vec![start];
    for (k, p) in fixes.iter().enumerate().skip(1) {
        let prior = kf.predict(&state, &motion, k as f64 * 0.5).expect("predict");
        state = kf
            .update(&prior, &fix_model, &DVector::from_vec(vec![p[0], p[1]]))
            .expect("update")
            .state;
        reference.push(state);
    }
    for (k, (ours, theirs)) in filtered.iter().zip(&reference).enumerate() {
        let mean_error = (ours.mean() - theirs.mean()).norm();
        let covariance_error = (ours.covariance() - theirs.covariance()).norm();
        assert!(
            mean_error < 1e-9 && covariance_error < 1e-9,
            "step {k}: {mean_error:e}, {covariance_error:e}"
        );
    }
}

/// Every step prepared, the first's information ignored (it is in the start).
fn prepare_all(steps: &[InformationStep<4>]) -> Vec<Prepared<4>> {
    steps.iter().enumerate().map(|(k, s)| prepare(s, k == 0)).collect()
}

/// A steady walk (a 20 m circle at 1 m/s: 0.05 m/s² of acceleration) tracked with the
/// tracker's q = 1 m²/s³: the fit chooses a smaller q, and its smoother beats the RTS smoother
/// of the tracker's model and the raw fixes.
#[test]
fn a_steady_walk_is_fitted_a_smaller_q_and_smoothed_better_than_the_tracker_model() {
    let (r, dt_s) = (1.0, 0.5);
    for seed in 0..4 {
        let (truth, fixes) = walk(300, dt_s, r, 0.0, seed);
        let start = start_at(fixes[0], r);
        let steps: Vec<_> = fixes
            .iter()
            .enumerate()
            .map(|(k, p)| fix_step(k as f64 * dt_s, *p, r))
            .collect();
        let tuned = tuned_smooth(&start, &steps, 1.0).expect("tuned");
        assert!(tuned.fit.acceleration_psd_m2ps3 < 0.1, "seed {seed}: {:?}", tuned.fit);
        let (_, filtered) = forward(&start, &prepare_all(&steps), 1.0, 1.0, true).expect("forward");
        let motion = ConstantVelocity::new(ProcessNoise::continuous(1.0)).expect("cv");
        let plain = KalmanFilter::default().smooth(&filtered, &motion).expect("smooth");
        let raw: Vec<_> = fixes.iter().map(|p| start_at(*p, r)).collect();
        let (raw, plain, tuned) = (rmse(&truth, &raw), rmse(&truth, &plain), rmse(&truth, &tuned.smoothed));
        assert!(
            tuned < 0.8 * plain,
            "seed {seed}: tuned {tuned:.3} m, plain {plain:.3} m"
        );
        assert!(tuned < 0.5 * raw, "seed {seed}: tuned {tuned:.3} m, raw {raw:.3} m");
    }
}

/// Fixes whose errors are twice the variance they state: the fit scales the noise up.
#[test]
fn understated_noise_is_fitted_a_larger_scale() {
    let (truth_r, stated_r, dt_s) = (2.0, 1.0, 0.5);
    let (_, fixes) = walk(400, dt_s, truth_r, 0.0, 11);
    let start = start_at(fixes[0], stated_r);
    let steps: Vec<_> = fixes
        .iter()
        .enumerate()
        .map(|(k, p)| fix_step(k as f64 * dt_s, *p, stated_r))
        .collect();
    let tuned = tuned_smooth(&start, &steps, 1.0).expect("tuned");
    assert!(tuned.fit.noise_scale >= 1.4, "{:?}", tuned.fit);
}

/// A range (rank-one information) and a fix at one time add up to their sum.
#[test]
fn sequential_updates_add_their_information() {
    let prior = start_at([0.0, 0.0], 1.0);
    let mid = Gaussian::new(
        Vector::<4>::new(0.5, 0.0, 0.0, 0.0),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(0.5, 4.0, 1.0, 4.0)),
        0.0,
    )
    .expect("mid");
    let last = Gaussian::new(
        Vector::<4>::new(0.5, 0.0, 0.25, 0.0),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(0.5, 4.0, 0.5, 4.0)),
        0.0,
    )
    .expect("last");
    let mut total = InformationStep::between(&prior, &mid).expect("first");
    total.add(&InformationStep::between(&mid, &last).expect("second"));
    let whole = InformationStep::between(&prior, &last).expect("whole");
    assert!((total.information - whole.information).norm() < 1e-12);
    assert!((total.information_vector - whole.information_vector).norm() < 1e-12);
}

#[test]
fn an_empty_segment_and_time_going_backwards_are_errors() {
    let start = start_at([0.0, 0.0], 1.0);
    assert!(tuned_smooth::<4>(&start, &[], 1.0).is_err());
    let steps = [fix_step(1.0, [0.0, 0.0], 1.0), fix_step(0.5, [0.0, 0.0], 1.0)];
    assert!(matches!(
        tuned_smooth(&start, &steps, 1.0),
        Err(EstimationError::TimeWentBackwards { .. })
    ));
}
