//! Conformance against FilterPy 2.0.0: every step's state and covariance must agree to 1e-9
//! (relative). The vectors come from `tests/golden/generate.py` (see `tests/golden/README.md`);
//! regenerate with `python3 crates/rtls-estimation/tests/golden/generate.py`.

use nalgebra::{DVector, SMatrix, SVector};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters, UnscentedKalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::stats::{chi_square_cdf, chi_square_quantile};
use rtls_estimation::{Gaussian, Matrix, Vector};
use serde::Deserialize;

const TOLERANCE: f64 = 1e-9;

#[derive(Deserialize)]
struct Golden {
    filterpy_version: String,
    scenarios: std::collections::BTreeMap<String, Scenario>,
    chi2: Vec<Chi2Ppf>,
    chi2_cdf: Vec<Chi2Cdf>,
}

#[derive(Deserialize)]
struct Chi2Ppf {
    p: f64,
    dof: f64,
    ppf: f64,
}

#[derive(Deserialize)]
struct Chi2Cdf {
    x: f64,
    dof: f64,
    cdf: f64,
}

#[derive(Deserialize)]
#[allow(non_snake_case)]
struct Scenario {
    x0: Vec<f64>,
    P0: Vec<Vec<f64>>,
    sigma2: f64,
    #[serde(default)]
    anchors: Vec<[f64; 2]>,
    #[serde(default)]
    R: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    range_variance: Option<f64>,
    #[serde(default)]
    ukf: Option<UkfParams>,
    steps: Vec<Step>,
    #[serde(default)]
    smoothed_x: Vec<Vec<f64>>,
    #[serde(default)]
    smoothed_P: Vec<Vec<Vec<f64>>>,
}

#[derive(Deserialize)]
struct UkfParams {
    alpha: f64,
    beta: f64,
    kappa: f64,
}

#[derive(Deserialize)]
#[allow(non_snake_case)]
struct Step {
    t: f64,
    z: Option<Vec<f64>>,
    #[serde(default)]
    anchor_indices: Vec<usize>,
    prior_x: Vec<f64>,
    prior_P: Vec<Vec<f64>>,
    posterior_x: Vec<f64>,
    posterior_P: Vec<Vec<f64>>,
    innovation: Option<Vec<f64>>,
    S: Option<Vec<Vec<f64>>>,
}

fn load() -> Golden {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/filterpy_vectors.json");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let golden: Golden = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(golden.filterpy_version, "2.0.0");
    golden
}

fn vector(v: &[f64]) -> Vector<4> {
    SVector::<f64, 4>::from_row_slice(v)
}

fn matrix(rows: &[Vec<f64>]) -> Matrix<4> {
    SMatrix::<f64, 4, 4>::from_fn(|i, j| rows[i][j])
}

fn dmatrix(rows: &[Vec<f64>]) -> nalgebra::DMatrix<f64> {
    nalgebra::DMatrix::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

/// Relative agreement: `|a − b| ≤ tol · max(1, max|b|)` entry-wise over the whole object.
fn assert_close<'a>(
    ours: impl IntoIterator<Item = &'a f64>,
    reference: impl IntoIterator<Item = &'a f64> + Clone,
    what: &str,
) {
    let scale = reference.clone().into_iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    for (i, (a, b)) in ours.into_iter().zip(reference).enumerate() {
        assert!(
            (a - b).abs() <= TOLERANCE * scale,
            "{what}[{i}]: ours {a} vs FilterPy {b} (scale {scale})"
        );
    }
}

fn flat(rows: &[Vec<f64>]) -> Vec<f64> {
    // FilterPy writes row-major; nalgebra iterates column-major, so compare transposed order.
    let n = rows.len();
    let m = rows[0].len();
    (0..m).flat_map(|j| (0..n).map(move |i| rows[i][j])).collect()
}

fn initial(s: &Scenario) -> Gaussian<4> {
    Gaussian::new(vector(&s.x0), matrix(&s.P0), 0.0).unwrap()
}

fn check_step(k: usize, name: &str, prior: &Gaussian<4>, posterior: &Gaussian<4>, step: &Step) {
    assert_close(prior.mean().iter(), &step.prior_x, &format!("{name} step {k} prior x"));
    assert_close(
        prior.covariance().iter(),
        &flat(&step.prior_P),
        &format!("{name} step {k} prior P"),
    );
    assert_close(
        posterior.mean().iter(),
        &step.posterior_x,
        &format!("{name} step {k} posterior x"),
    );
    assert_close(
        posterior.covariance().iter(),
        &flat(&step.posterior_P),
        &format!("{name} step {k} posterior P"),
    );
}

fn check_smoothed(name: &str, ours: &[Gaussian<4>], s: &Scenario) {
    assert_eq!(ours.len(), s.smoothed_x.len(), "{name}: smoothed length");
    for (k, g) in ours.iter().enumerate() {
        assert_close(g.mean().iter(), &s.smoothed_x[k], &format!("{name} smoothed x {k}"));
        assert_close(
            g.covariance().iter(),
            &flat(&s.smoothed_P[k]),
            &format!("{name} smoothed P {k}"),
        );
    }
}

fn motion(s: &Scenario) -> ConstantVelocity {
    ConstantVelocity::new(ProcessNoise::discrete(s.sigma2, NoiseGain::kinematic())).unwrap()
}

#[test]
fn kf_position_and_rts_match_filterpy() {
    let golden = load();
    let s = &golden.scenarios["kf_position"];
    let kf = KalmanFilter::default();
    let motion = motion(s);
    let fixes =
        ComponentSelection::<4>::position(2, NoiseCovariance::full(dmatrix(s.R.as_ref().unwrap())).unwrap()).unwrap();
    let mut state = initial(s);
    let mut filtered = Vec::new();
    let mut updates = 0;
    for (k, step) in s.steps.iter().enumerate() {
        let prior = kf.predict(&state, &motion, step.t).unwrap();
        state = match &step.z {
            Some(z) => {
                updates += 1;
                let updated = kf.update(&prior, &fixes, &DVector::from_row_slice(z)).unwrap();
                assert_close(
                    updated.innovation.iter(),
                    step.innovation.as_ref().unwrap(),
                    &format!("kf step {k} innovation"),
                );
                assert_close(
                    updated.innovation_covariance.iter(),
                    &flat(step.S.as_ref().unwrap()),
                    &format!("kf step {k} S"),
                );
                updated.state
            }
            None => prior,
        };
        check_step(k, "kf_position", &prior, &state, step);
        filtered.push(state);
    }
    assert!(
        updates > 30 && updates < s.steps.len(),
        "scenario must mix updates and coasting"
    );
    check_smoothed("kf_position", &kf.smooth(&filtered, &motion).unwrap(), s);
}

#[test]
fn ekf_ranges_with_changing_anchor_sets_match_filterpy() {
    let golden = load();
    let s = &golden.scenarios["ekf_range"];
    let ekf = ExtendedKalmanFilter::default();
    let motion = motion(s);
    let mut state = initial(s);
    let mut sizes = std::collections::BTreeSet::new();
    for (k, step) in s.steps.iter().enumerate() {
        let prior = ekf.predict(&state, &motion, step.t).unwrap();
        state = match &step.z {
            Some(z) => {
                let anchors: Vec<[f64; 2]> = step.anchor_indices.iter().map(|&i| s.anchors[i]).collect();
                sizes.insert(anchors.len());
                let noise = NoiseCovariance::isotropic(anchors.len(), s.range_variance.unwrap()).unwrap();
                let ranges = Ranges::planar(&anchors, noise).unwrap();
                let updated = ekf.update(&prior, &ranges, &DVector::from_row_slice(z)).unwrap();
                assert_close(
                    updated.innovation.iter(),
                    step.innovation.as_ref().unwrap(),
                    &format!("ekf step {k} innovation"),
                );
                updated.state
            }
            None => prior,
        };
        check_step(k, "ekf_range", &prior, &state, step);
    }
    assert!(
        sizes.len() >= 3,
        "the anchor set must change size across updates: {sizes:?}"
    );
}

fn run_ukf(name: &str) {
    let golden = load();
    let s = &golden.scenarios[name];
    let p = s.ukf.as_ref().unwrap();
    let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::new(p.alpha, p.beta, p.kappa).unwrap());
    let motion = motion(s);
    let noise = NoiseCovariance::isotropic(s.anchors.len(), s.range_variance.unwrap()).unwrap();
    let ranges = Ranges::planar(&s.anchors, noise).unwrap();
    let mut state = initial(s);
    let mut filtered = Vec::new();
    for (k, step) in s.steps.iter().enumerate() {
        let prior = ukf.predict(&state, &motion, step.t).unwrap();
        state = match &step.z {
            Some(z) => {
                let updated = ukf.update(&prior, &ranges, &DVector::from_row_slice(z)).unwrap();
                assert_close(
                    updated.innovation.iter(),
                    step.innovation.as_ref().unwrap(),
                    &format!("{name} step {k} innovation"),
                );
                assert_close(
                    updated.innovation_covariance.iter(),
                    &flat(step.S.as_ref().unwrap()),
                    &format!("{name} step {k} S"),
                );
                updated.state
            }
            None => prior,
        };
        check_step(k, name, &prior, &state, step);
        filtered.push(state);
    }
    check_smoothed(name, &ukf.smooth(&filtered, &motion).unwrap(), s);
}

#[test]
fn ukf_ranges_seed_001_parameters_match_filterpy() {
    run_ukf("ukf_range_001");
}

#[test]
fn ukf_ranges_wide_spread_match_filterpy() {
    run_ukf("ukf_range_wide");
}

#[test]
fn chi_square_quantiles_and_cdf_match_scipy() {
    let golden = load();
    assert!(golden.chi2.len() > 50);
    for row in &golden.chi2 {
        let ours = chi_square_quantile(row.p, row.dof).unwrap();
        assert!(
            (ours - row.ppf).abs() <= 1e-9 * row.ppf.abs().max(1e-3),
            "ppf({}, {}): {ours} vs {}",
            row.p,
            row.dof,
            row.ppf
        );
    }
    for row in &golden.chi2_cdf {
        let ours = chi_square_cdf(row.x, row.dof).unwrap();
        assert!(
            (ours - row.cdf).abs() <= 1e-10,
            "cdf({}, {}): {ours} vs {}",
            row.x,
            row.dof,
            row.cdf
        );
    }
}
