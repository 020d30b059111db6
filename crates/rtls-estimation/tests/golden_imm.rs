//! The IMM against FilterPy 2.0.0's `IMMEstimator` (vectors from `tests/golden/generate_imm.py`).
//!
//! FilterPy's IMM needs every mode to share one state, so these cases mix constant-velocity
//! modes that differ in process noise; mode probabilities, mode-conditioned priors and
//! posteriors and the combined estimate must agree to 1e-9 relative at every step.

use nalgebra::{DMatrix, DVector};
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::imm::{FilterMode, ImmMode, InteractingMultipleModel, ModeEstimate, ModeTransitions, StateLayout};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use serde::Deserialize;

const TOLERANCE: f64 = 1e-9;

#[derive(Deserialize)]
struct Golden {
    filterpy_version: String,
    scenarios: Vec<Scenario>,
}

#[derive(Deserialize)]
#[allow(non_snake_case)]
struct Scenario {
    name: String,
    q: Vec<f64>,
    M: Vec<Vec<f64>>,
    mu0: Vec<f64>,
    R: Vec<Vec<f64>>,
    x0: Vec<f64>,
    P0: Vec<Vec<f64>>,
    steps: Vec<Step>,
}

#[derive(Deserialize)]
#[allow(non_snake_case)]
struct Step {
    z: Vec<f64>,
    mode_prior_x: Vec<Vec<f64>>,
    mode_prior_P: Vec<Vec<Vec<f64>>>,
    mode_x: Vec<Vec<f64>>,
    mode_P: Vec<Vec<Vec<f64>>>,
    mu: Vec<f64>,
    x: Vec<f64>,
    P: Vec<Vec<f64>>,
}

fn dmatrix(rows: &[Vec<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

fn assert_close(ours: &[f64], reference: &[f64], what: &str) {
    assert_eq!(ours.len(), reference.len(), "{what}: length");
    let scale = reference.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    for (i, (a, b)) in ours.iter().zip(reference).enumerate() {
        assert!(
            (a - b).abs() <= TOLERANCE * scale,
            "{what}[{i}]: ours {a} vs FilterPy {b}"
        );
    }
}

fn assert_matrix_close(ours: &DMatrix<f64>, reference: &[Vec<f64>], what: &str) {
    let reference = dmatrix(reference);
    assert_close(ours.as_slice(), reference.as_slice(), what);
}

fn imm_for(s: &Scenario) -> InteractingMultipleModel {
    let r = NoiseCovariance::full(dmatrix(&s.R)).unwrap();
    let modes: Vec<Box<dyn ImmMode>> =
        s.q.iter()
            .enumerate()
            .map(|(i, &q)| {
                let mode = FilterMode::<4, _, _, _>::new(
                    &format!("CV{i}"),
                    StateLayout::cv_2d(),
                    ConstantVelocity::new(ProcessNoise::discrete(q, NoiseGain::kinematic())).unwrap(),
                    ComponentSelection::<4>::position(2, r.clone()).unwrap(),
                    KalmanFilter::default(),
                )
                .unwrap();
                Box::new(mode) as Box<dyn ImmMode>
            })
            .collect();
    InteractingMultipleModel::new(modes, ModeTransitions::per_step(dmatrix(&s.M)).unwrap()).unwrap()
}

#[test]
fn imm_matches_filterpy_imm_estimator() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/imm_vectors.json");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let golden: Golden = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(golden.filterpy_version, "2.0.0");
    assert_eq!(golden.scenarios.len(), 2);
    for s in &golden.scenarios {
        let imm = imm_for(s);
        let estimates =
            s.q.iter()
                .map(|_| ModeEstimate {
                    mean: DVector::from_vec(s.x0.clone()),
                    covariance: dmatrix(&s.P0),
                })
                .collect();
        let mut state = imm.state(estimates, s.mu0.clone(), 0.0).unwrap();
        let mut switched = false;
        for (k, step) in s.steps.iter().enumerate() {
            let name = format!("{} step {}", s.name, k + 1);
            let prior = imm.predict(&state, (k + 1) as f64).unwrap();
            for (j, estimate) in prior.estimates().iter().enumerate() {
                assert_close(
                    estimate.mean.as_slice(),
                    &step.mode_prior_x[j],
                    &format!("{name} prior x[{j}]"),
                );
                assert_matrix_close(
                    &estimate.covariance,
                    &step.mode_prior_P[j],
                    &format!("{name} prior P[{j}]"),
                );
            }
            state = imm.update(&prior, &DVector::from_vec(step.z.clone())).unwrap().state;
            assert_close(state.probabilities(), &step.mu, &format!("{name} mu"));
            for (j, estimate) in state.estimates().iter().enumerate() {
                assert_close(estimate.mean.as_slice(), &step.mode_x[j], &format!("{name} x[{j}]"));
                assert_matrix_close(&estimate.covariance, &step.mode_P[j], &format!("{name} P[{j}]"));
            }
            let (x, p) = imm.combined(&state, &StateLayout::cv_2d()).unwrap();
            assert_close(x.as_slice(), &step.x, &format!("{name} combined x"));
            assert_matrix_close(&p, &step.P, &format!("{name} combined P"));
            switched |= state.most_probable_mode() != 0;
        }
        // The scenario's manoeuvre must actually move the probabilities (the comparison is live).
        assert!(switched, "{}: the high-noise mode never became most probable", s.name);
    }
}
