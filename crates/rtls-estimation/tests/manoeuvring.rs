//! The variable-dimension filter and the IMM on synthetic manoeuvres: the re-filtering rule,
//! the detector's false-alarm rate, and mode probabilities across models of different size.

use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter};
use rtls_estimation::imm::{
    Axis, Component, ComponentObservation, FilterMode, ImmMode, InteractingMultipleModel, ModeEstimate,
    ModeTransitions, StateLayout,
};
use rtls_estimation::manoeuvre::{LinearObservation, ManoeuvreDetector, Threshold, VariableDimensionFilter, VdMode};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{
    ConstantAcceleration, ConstantVelocity, CoordinatedTurnWithRate, NoiseGain, ProcessNoise,
};
use rtls_estimation::{Gaussian, Matrix, Vector};

/// Truth of a planar target: 60 s straight at 10 m/s along x, a 30 s left turn at 0.05 rad/s,
/// 40 s straight, 25 s accelerating at 0.8 m/s² along its heading, 30 s straight.
fn truth() -> Vec<(f64, [f64; 4], &'static str)> {
    let mut out = Vec::new();
    let (mut x, mut y, mut vx, mut vy) = (0.0_f64, 0.0_f64, 10.0_f64, 0.0_f64);
    let dt = 1.0;
    for k in 1..=185 {
        let t = k as f64;
        let phase = match k {
            1..=60 => "cv",
            61..=90 => "turn",
            91..=130 => "cv",
            131..=155 => "accel",
            _ => "cv",
        };
        match phase {
            "turn" => {
                // exact coordinated turn over dt
                let w: f64 = 0.05;
                let (s, c) = (w * dt).sin_cos();
                let (nvx, nvy) = (c * vx - s * vy, s * vx + c * vy);
                x += (s * vx - (1.0 - c) * vy) / w;
                y += ((1.0 - c) * vx + s * vy) / w;
                vx = nvx;
                vy = nvy;
            }
            "accel" => {
                let speed = vx.hypot(vy);
                let (ax, ay) = (0.8 * vx / speed, 0.8 * vy / speed);
                x += vx * dt + 0.5 * ax * dt * dt;
                y += vy * dt + 0.5 * ay * dt * dt;
                vx += ax * dt;
                vy += ay * dt;
            }
            _ => {
                x += vx * dt;
                y += vy * dt;
            }
        }
        out.push((t, [x, vx, y, vy], phase));
    }
    out
}

fn noisy_fixes(seed: u64, std_m: f64) -> Vec<(f64, [f64; 2], &'static str, [f64; 4])> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, std_m).unwrap();
    truth()
        .into_iter()
        .map(|(t, s, phase)| {
            (
                t,
                [s[0] + noise.sample(&mut rng), s[2] + noise.sample(&mut rng)],
                phase,
                s,
            )
        })
        .collect()
}

fn initial() -> Gaussian<4> {
    Gaussian::new(
        Vector::<4>::new(0.0, 10.0, 0.0, 0.0),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(25.0, 4.0, 25.0, 4.0)),
        0.0,
    )
    .unwrap()
}

/// At the onset the CA state must equal a CA Kalman filter started from the CV estimate before
/// the window (accelerations N(0, σₐ₀²)) and run over the stored observations.
#[test]
fn onset_refilters_the_window_with_the_ca_model() {
    let detector = ManoeuvreDetector {
        onset: Threshold::Fixed(1e-6), // fire at the first step whose window is full
        ..ManoeuvreDetector::default()
    };
    let cv = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::seed_004_cv())).unwrap();
    let ca = ConstantAcceleration::new(ProcessNoise::discrete(0.05, NoiseGain::seed_004_ca())).unwrap();
    let vd = VariableDimensionFilter::new(cv, ca, detector).unwrap();
    let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 4.0).unwrap()).unwrap();
    let data = noisy_fixes(7, 2.0);
    let observations: Vec<LinearObservation> = data
        .iter()
        .map(|(t, z, _, _)| LinearObservation::from_model(*t, &fixes, DVector::from_vec(z.to_vec())).unwrap())
        .collect();
    // The threshold fires at the first step: the window holds one observation.
    let state = vd.initial_state(initial());
    let step = vd.step(&state, &observations[0]).unwrap();
    let event = step.event.expect("a fixed threshold of 1e-6 fires at once");
    assert_eq!(event.to, VdMode::ConstantAcceleration);
    assert_eq!(event.onset_time_s, observations[0].time_s());

    // Now a longer window: fire only at step 10 by raising the threshold until then.
    let window = vd.detector().window_steps();
    let quiet = vd
        .with_detector(ManoeuvreDetector {
            onset: Threshold::Fixed(f64::MAX),
            ..detector
        })
        .unwrap();
    let mut state = vd.initial_state(initial());
    let mut before = Vec::new();
    for obs in &observations[..9] {
        before.push(*state.estimate());
        state = quiet.step(&state, obs).unwrap().state;
    }
    before.push(*state.estimate());
    let switched = vd.step(&state, &observations[9]).unwrap();
    let event = switched.event.unwrap();
    // the window is Δ + 1 = 6 observations: 4..=9 (0-based), started from the estimate before 4
    let first = 9 - window;
    assert_eq!(event.onset_time_s, observations[first].time_s());
    let start = before[first].position_velocity();
    let mut mean = Vector::<6>::zeros();
    mean.fixed_rows_mut::<4>(0).copy_from(start.mean());
    let mut cov = Matrix::<6>::zeros();
    cov.fixed_view_mut::<4, 4>(0, 0).copy_from(start.covariance());
    cov[(4, 4)] = 1.0;
    cov[(5, 5)] = 1.0;
    let mut reference = Gaussian::new(mean, cov, start.time_s()).unwrap();
    let kf = KalmanFilter::default();
    let fixes6 = ComponentSelection::<6>::position(2, NoiseCovariance::isotropic(2, 4.0).unwrap()).unwrap();
    for (t, z, _, _) in &data[first..=9] {
        let prior = kf.predict(&reference, &ca, *t).unwrap();
        reference = kf
            .update(&prior, &fixes6, &DVector::from_vec(z.to_vec()))
            .unwrap()
            .state;
    }
    match switched.state.estimate() {
        rtls_estimation::manoeuvre::VdEstimate::ConstantAcceleration(ours) => {
            assert!((ours.mean() - reference.mean()).amax() < 1e-9);
            assert!((ours.covariance() - reference.covariance()).amax() < 1e-9);
        }
        other => panic!("expected CA, got {other:?}"),
    }
}

/// With no manoeuvre, `μ(k) ≥ Th` must happen at about the designed 1 % of steps: the
/// moment-matched χ² threshold is calibrated (Bar-Shalom's χ²(mΔ) would give far fewer).
#[test]
fn onset_threshold_false_alarm_rate_is_as_designed() {
    let detector = ManoeuvreDetector::default();
    let q = 0.01;
    let cv = ConstantVelocity::new(ProcessNoise::discrete(q, NoiseGain::kinematic())).unwrap();
    let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 4.0).unwrap()).unwrap();
    let kf = KalmanFilter::default();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let accel = Normal::new(0.0, q.sqrt()).unwrap();
    let meas = Normal::new(0.0, 2.0).unwrap();
    let th = detector.onset_threshold(2).unwrap();
    let (mut exceed, mut steps) = (0usize, 0usize);
    for _run in 0..40 {
        let mut truth = [0.0, 1.0, 0.0, -0.5];
        let mut state = initial();
        let mut mu = 0.0;
        for k in 1..=1000 {
            // truth: discrete white-noise acceleration, exactly the filter's model
            for axis in 0..2 {
                let a = accel.sample(&mut rng);
                truth[2 * axis] += truth[2 * axis + 1] + 0.5 * a;
                truth[2 * axis + 1] += a;
            }
            let z = DVector::from_vec(vec![truth[0] + meas.sample(&mut rng), truth[2] + meas.sample(&mut rng)]);
            let prior = kf.predict(&state, &cv, k as f64).unwrap();
            let up = kf.update(&prior, &fixes, &z).unwrap();
            state = up.state;
            mu = detector.fading_factor * mu + up.nis;
            if k > 50 {
                steps += 1;
                exceed += usize::from(mu >= th);
            }
        }
    }
    let rate = exceed as f64 / steps as f64;
    assert!((0.004..0.02).contains(&rate), "false-alarm rate {rate} (designed 0.01)");
}

fn imm_cv_ca_ct(ct_filter_is_ukf: bool) -> InteractingMultipleModel {
    let r = NoiseCovariance::isotropic(2, 9.0).unwrap();
    let cv = FilterMode::<4, _, _, _>::new(
        "CV",
        StateLayout::cv_2d(),
        ConstantVelocity::new(ProcessNoise::discrete(0.005, NoiseGain::kinematic())).unwrap(),
        ComponentSelection::<4>::position(2, r.clone()).unwrap(),
        KalmanFilter::default(),
    )
    .unwrap();
    let ca = FilterMode::<6, _, _, _>::new(
        "CA",
        StateLayout::ca_2d(),
        ConstantAcceleration::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic())).unwrap(),
        ComponentSelection::<6>::position(2, r.clone()).unwrap(),
        KalmanFilter::default(),
    )
    .unwrap();
    let ct_model = CoordinatedTurnWithRate::new(ProcessNoise::discrete(0.005, NoiseGain::kinematic()), 1e-5).unwrap();
    let ct_fix = ComponentSelection::<5>::position(2, r).unwrap();
    let ct: Box<dyn ImmMode> = if ct_filter_is_ukf {
        Box::new(
            FilterMode::<5, _, _, _>::new(
                "CT",
                StateLayout::ct_2d(),
                ct_model,
                ct_fix,
                UnscentedKalmanFilter::default(),
            )
            .unwrap(),
        )
    } else {
        Box::new(
            FilterMode::<5, _, _, _>::new(
                "CT",
                StateLayout::ct_2d(),
                ct_model,
                ct_fix,
                ExtendedKalmanFilter::default(),
            )
            .unwrap(),
        )
    };
    InteractingMultipleModel::new(
        vec![Box::new(cv), Box::new(ca), ct],
        ModeTransitions::mean_sojourn(vec![60.0, 15.0, 20.0]).unwrap(),
    )
    .unwrap()
}

/// CV (4 states, KF), CA (6, KF) and CT (5, EKF or UKF) mixed in one IMM: the turn mode wins
/// the turn, the CA mode the acceleration, the CV mode the straight legs.
#[test]
fn imm_mode_probabilities_follow_turn_and_acceleration() {
    for ukf in [false, true] {
        let imm = imm_cv_ca_ct(ukf);
        let mut mean_probability = std::collections::HashMap::<&str, ([f64; 3], usize)>::new();
        for seed in 0..10 {
            let data = noisy_fixes(100 + seed, 3.0);
            let init = initial();
            let mut state = imm
                .initial_state(
                    &ModeEstimate::from_gaussian(&init),
                    &StateLayout::cv_2d(),
                    0.01,
                    &[0.8, 0.1, 0.1],
                    0.0,
                )
                .unwrap();
            for (t, z, phase, _) in &data {
                let prior = imm.predict(&state, *t).unwrap();
                state = imm.update(&prior, &DVector::from_vec(z.to_vec())).unwrap().state;
                // score the settled part of each phase (skip its first 8 s)
                let settled = data
                    .iter()
                    .filter(|d| d.2 == *phase && d.0 <= *t && d.0 > *t - 8.0)
                    .count()
                    >= 8;
                if settled {
                    let entry = mean_probability.entry(phase).or_insert(([0.0; 3], 0));
                    for j in 0..3 {
                        entry.0[j] += state.probabilities()[j];
                    }
                    entry.1 += 1;
                }
            }
        }
        let mean = |phase: &str| {
            let (sum, n) = mean_probability[phase];
            [sum[0] / n as f64, sum[1] / n as f64, sum[2] / n as f64]
        };
        let (cv, turn, accel) = (mean("cv"), mean("turn"), mean("accel"));
        let filter = if ukf { "UKF" } else { "EKF" };
        assert!(cv[0] > 0.5, "{filter}: P(CV) on straight legs {cv:?}");
        eprintln!(
            "{filter}: mean mode probabilities [CV, CA, CT]: straight {cv:?}, turn {turn:?}, accelerating {accel:?}"
        );
        // In the turn CT is the most probable mode (CA, which can also bend a track, second).
        assert!(
            turn[2] > turn[0] && turn[2] > turn[1] && turn[2] > 3.0 * cv[2],
            "{filter}: P(CT) in the turn {turn:?} vs straight {cv:?}"
        );
        assert!(
            accel[1] > accel[0] && accel[1] > accel[2] && accel[1] > 3.0 * cv[1],
            "{filter}: P(CA) accelerating {accel:?} vs straight {cv:?}"
        );
    }
}

/// A component observation with the same noise as a mode's fixed model gives the same update.
#[test]
fn component_observation_equals_the_fixed_model_update() {
    let imm = imm_cv_ca_ct(false);
    let init = initial();
    let state = imm
        .initial_state(
            &ModeEstimate::from_gaussian(&init),
            &StateLayout::cv_2d(),
            0.01,
            &[0.6, 0.2, 0.2],
            0.0,
        )
        .unwrap();
    let prior = imm.predict(&state, 1.0).unwrap();
    let z = DVector::from_vec(vec![11.0, -1.0]);
    let fixed = imm.update(&prior, &z).unwrap();
    let observation = ComponentObservation::new(
        vec![Component::Position(Axis::X), Component::Position(Axis::Y)],
        z,
        NoiseCovariance::isotropic(2, 9.0).unwrap(),
    )
    .unwrap();
    let by_components = imm.update_components(&prior, &observation).unwrap();
    assert_eq!(fixed, by_components);
    // A component no mode has is an error, not a silent skip.
    let bad = ComponentObservation::new(
        vec![Component::Position(Axis::Z)],
        DVector::from_vec(vec![1.0]),
        NoiseCovariance::isotropic(1, 1.0).unwrap(),
    )
    .unwrap();
    assert!(imm.update_components(&prior, &bad).is_err());

    // A CV observation converts only when every row selects one state entry.
    let mut h = rtls_estimation::measurement::MeasurementJacobian::<4>::zeros(1);
    h[(0, 0)] = 1.0;
    h[(0, 2)] = 1.0; // x + y: not a component
    let summed = LinearObservation::new(
        1.0,
        DVector::from_vec(vec![3.0]),
        h,
        &NoiseCovariance::isotropic(1, 1.0).unwrap(),
    )
    .unwrap();
    assert!(matches!(
        ComponentObservation::from_cv_observation(&summed),
        Err(rtls_estimation::EstimationError::InvalidParameter {
            name: "observation matrix",
            ..
        })
    ));
    // A state with the wrong number of probabilities names what is wrong.
    let estimates = state.estimates().to_vec();
    assert!(matches!(
        imm.state(estimates, vec![1.0], 0.0),
        Err(rtls_estimation::EstimationError::DimensionMismatch {
            what: "IMM mode probabilities",
            expected: 3,
            found: 1
        })
    ));
}
