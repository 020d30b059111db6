//! Seed 004's experiment: a vehicle tracked by cellular TDOA fixes (Chan, cyclic master) and
//! on-board odometry, comparing raw fixes, a KF on the fixes, the VD-KF fused with the
//! odometry velocity, and an IMM (CV / CA / coordinated turn) on the same data.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_estimation::aided::{
    position_velocity_observation, HeadingBiasEstimator, OdometryErrorModel, OdometryReading as OdometryInput,
};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::imm::{
    ComponentObservation, FilterMode, ImmMode, InteractingMultipleModel, ModeEstimate, ModeTransitions, StateLayout,
};
use rtls_estimation::manoeuvre::{
    LinearObservation, ManoeuvreDetector, ModeSwitch, VariableDimensionFilter, VdMode, VdState,
};
use rtls_estimation::measurement::{ComponentSelection, MeasurementJacobian, NoiseCovariance};
use rtls_estimation::motion::{
    ConstantAcceleration, ConstantVelocity, CoordinatedTurnWithRate, NoiseGain, ProcessNoise,
};
use rtls_estimation::{Gaussian, Matrix, Vector};
use rtls_positioning::tdoa::{chan_taylor, cyclic_reference};
use rtls_positioning::{calibrate_fix_noise, PositioningError};

use crate::error::{Result, SimError};
use rtls_sim::scenarios::seed_004_trajectory;
use rtls_sim::sensors::{OdometrySimulator, TdoaSimulator};
use rtls_sim::trajectory::TruthSample;

/// Everything the seed 004 reproduction can be tuned by; [`Seed004Config::default`] is what
/// the tests, the examples and the README figures use.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed004Config {
    /// Cruise speed (m/s); the paper gives none, we use 10 m/s.
    pub speed_mps: f64,
    /// `σₐ²` of the CV model with seed 004's printed `G = [T/2, 1]ᵀ` ((m/s)² per step: `w` acts as
    /// a velocity increment), used by the KF on fixes and the VD-KF's CV model.
    pub cv_variance: f64,
    /// `σₘ²` of the CA model with `Gᵐ = [T²/4, T/2, 1]ᵀ` ((m/s²)² per step).
    pub ca_variance: f64,
    /// The VD-KF's manoeuvre detector.
    pub detector: ManoeuvreDetector,
    /// Mean sojourn times (s) of the IMM's CV, CA and CT modes.
    pub imm_sojourn_s: [f64; 3],
    /// White acceleration variance of the IMM's CV and CT modes ((m/s²)², kinematic gain).
    pub imm_cv_variance: f64,
    /// Acceleration-increment variance of the IMM's CA mode ((m/s²)², kinematic gain).
    pub imm_ca_variance: f64,
    /// Turn-rate random-walk variance rate of the IMM's CT mode ((rad/s)²/s).
    pub imm_turn_rate_variance: f64,
    /// The cellular TDOA network: stations and timing errors (seed 004: Gaussian 100 ns plus
    /// uniform 0–200 ns NLOS delay).
    pub tdoa: TdoaSimulator,
    /// Number of surveyed points used to calibrate the fix covariance `R` (seed 002's method).
    pub calibration_points: usize,
    /// The simulated odometer (seed 004: speed error 1 m/s, heading drift 20°/h).
    pub odometer: OdometrySimulator,
    /// The odometry error model the filters assume.
    pub odometry_model: OdometryErrorModel,
    /// Estimate the heading drift from the fixes-only track and correct the odometer heading
    /// ([`HeadingBiasEstimator`]); `false` fuses the raw heading with the drift as a growing
    /// variance, as seed 004 does.
    pub estimate_heading_drift: bool,
}

impl Default for Seed004Config {
    fn default() -> Self {
        Self {
            speed_mps: rtls_sim::scenarios::SEED_004_SPEED_MPS,
            cv_variance: 0.01,
            ca_variance: 1e-2,
            detector: ManoeuvreDetector::default(),
            imm_sojourn_s: [200.0, 30.0, 30.0],
            imm_cv_variance: 0.01,
            imm_ca_variance: 0.01,
            imm_turn_rate_variance: 1e-6,
            tdoa: TdoaSimulator::seed_004(),
            calibration_points: 300,
            odometer: OdometrySimulator::default(),
            odometry_model: OdometryErrorModel::seed_004(),
            estimate_heading_drift: true,
        }
    }
}

/// One seeded run of the seed 004 experiment: estimates at every epoch `t = 1, 2, …, 1500 s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed004Run {
    /// The run's seed (every random draw derives from it).
    pub seed: u64,
    /// Truth at each epoch.
    pub truth: Vec<TruthSample>,
    /// Chan TDOA fix at each epoch, `None` when the hyperbolas gave no fix.
    pub fixes: Vec<Option<[f64; 2]>>,
    /// KF (CV) on the fixes alone.
    pub kf: Vec<[f64; 2]>,
    /// VD-KF on the fixes fused with the odometry velocity.
    pub vd: Vec<[f64; 2]>,
    /// The VD-KF's model after each epoch.
    pub vd_modes: Vec<VdMode>,
    /// The VD-KF's model switches.
    pub vd_events: Vec<ModeSwitch>,
    /// IMM (CV / CA / CT) on the same fused observations.
    pub imm: Vec<[f64; 2]>,
    /// IMM mode probabilities `[CV, CA, CT]` after each epoch.
    pub imm_probabilities: Vec<[f64; 3]>,
    /// The calibrated fix covariance `R` (m²) all filters use.
    pub fix_covariance_m2: Matrix2<f64>,
    /// The odometry velocity (m/s) and its covariance ((m/s)²) the fused filters used at each
    /// epoch (heading drift-corrected when configured).
    pub odometry_velocities: Vec<(Vector2<f64>, Matrix2<f64>)>,
}

impl Seed004Run {
    /// The fixes, with epochs without a fix left out, and the truth at those epochs.
    #[must_use]
    pub fn available_fixes(&self) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
        self.fixes
            .iter()
            .zip(&self.truth)
            .filter_map(|(fix, truth)| fix.map(|f| (truth.position_m, f)))
            .unzip()
    }

    /// Truth positions at every epoch.
    #[must_use]
    pub fn truth_positions(&self) -> Vec<[f64; 2]> {
        self.truth.iter().map(|s| s.position_m).collect()
    }
}

/// Runs the seed 004 experiment once with `seed`.
///
/// Per epoch (1 Hz, `t = 1 … 1500 s`): the master station cycles through the four stations
/// (seed 004's "cyclic master"); the three range differences get Gaussian 100 ns plus uniform
/// 0–200 ns errors; Chan's estimator refined by a Taylor (Gauss–Newton ML) step gives the fix
/// (Chan alone scatters by kilometres at this noise on these baselines); the odometer gives speed (σ 1 m/s) and
/// heading (drift ±20°/h, 0.5° noise). The fix covariance `R` is calibrated beforehand from
/// `calibration_points` fixes at surveyed points (seed 002's method, since Chan's own
/// covariance is the Cramér–Rao bound and too small at this noise, see `rtls_positioning`).
/// An epoch without a fix gives the KF a coast and the fused filters a velocity-only update.
///
/// # Errors
/// [`SimError::InvalidParameter`] for a bad configuration; [`SimError::Estimation`] if a
/// filter step fails; [`SimError::Positioning`] for a calibration without enough fixes.
///
/// # References
/// Seed 004 §3 (scenario, noise, 50 runs, compared methods).
pub fn run_seed_004(config: &Seed004Config, seed: u64) -> Result<Seed004Run> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let trajectory = seed_004_trajectory(config.speed_mps)?;
    let truth: Vec<TruthSample> = trajectory.sample(1.0)?.into_iter().skip(1).collect();
    let tdoa = &config.tdoa;
    tdoa.validate()?;
    let stations = tdoa.stations.as_slice();
    let q_tdoa = DMatrix::from_diagonal_element(3, 3, tdoa.range_difference_variance_m2());
    let fix_covariance_m2 = calibrate(tdoa, &q_tdoa, config.calibration_points, &mut rng)?;
    let odometry_model = config.odometry_model;
    let mut odometer = config.odometer.start_run(&mut rng)?;

    // Fixes and odometry for every epoch (the same data for every filter).
    let mut fixes = Vec::with_capacity(truth.len());
    let mut readings = Vec::with_capacity(truth.len());
    for (k, sample) in truth.iter().enumerate() {
        let reference = cyclic_reference(k as u64, stations.len())?;
        let differences = tdoa.measure(sample.position_m, reference, &mut rng)?;
        fixes.push(fix_or_none(chan_taylor(stations, reference, &differences, &q_tdoa))?);
        let reading = odometer.measure(sample, &mut rng)?;
        readings.push(OdometryInput {
            speed_mps: reading.speed_mps,
            heading_rad: reading.heading_rad,
        });
    }

    let first_fix = fixes.iter().flatten().next().copied().ok_or(SimError::EmptyInput {
        what: "seed 004 fixes (every chan fix failed)",
    })?;
    let (v0, rv0) = odometry_model
        .velocity(&readings[0], 0.0)
        .map_err(SimError::estimation(0.0))?;
    let initial = Gaussian::new(
        Vector::<4>::new(first_fix[0], v0[0], first_fix[1], v0[1]),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(
            fix_covariance_m2[(0, 0)],
            rv0[(0, 0)] + 4.0,
            fix_covariance_m2[(1, 1)],
            rv0[(1, 1)] + 4.0,
        )),
        0.0,
    )
    .map_err(SimError::estimation(0.0))?;

    let kf_states = run_kf(config, &truth, &fixes, &fix_covariance_m2, initial)?;
    let kf = kf_states.iter().map(position_of).collect();
    let velocities = odometry_velocities(config, &truth, &readings, &kf_states)?;
    let (vd, vd_modes, vd_events) = run_vd(config, &truth, &fixes, &velocities, &fix_covariance_m2, initial)?;
    let (imm, imm_probabilities) = run_imm(config, &truth, &fixes, &velocities, &fix_covariance_m2, initial)?;
    Ok(Seed004Run {
        seed,
        fixes: fixes.iter().map(|f| f.map(|v| [v[0], v[1]])).collect(),
        truth,
        kf,
        vd,
        vd_modes,
        vd_events,
        imm,
        imm_probabilities,
        fix_covariance_m2,
        odometry_velocities: velocities,
    })
}

/// A fix, or `None` when the noise made the hyperbolas miss (not an error of the input).
fn fix_or_none(result: core::result::Result<rtls_positioning::Fix2, PositioningError>) -> Result<Option<Vector2<f64>>> {
    match result {
        Ok(fix) => Ok(Some(fix.position)),
        Err(
            PositioningError::NoConsistentSolution { .. }
            | PositioningError::DegenerateGeometry { .. }
            | PositioningError::DidNotConverge { .. },
        ) => Ok(None),
        Err(other) => Err(other.into()),
    }
}

/// Seed 002's calibration applied to TDOA: fixes at `points` surveyed positions spread over the
/// track's area, `R` = the sample covariance of their errors.
fn calibrate(tdoa: &TdoaSimulator, q: &DMatrix<f64>, points: usize, rng: &mut ChaCha8Rng) -> Result<Matrix2<f64>> {
    use rand::Rng;
    let mut errors = Vec::with_capacity(points);
    for k in 0..points {
        let p = [rng.gen_range(-1500.0..5000.0), rng.gen_range(-2500.0..2500.0)];
        let reference = cyclic_reference(k as u64, tdoa.stations.len())?;
        let differences = tdoa.measure(p, reference, rng)?;
        if let Some(fix) = fix_or_none(chan_taylor(&tdoa.stations, reference, &differences, q))? {
            errors.push([fix[0] - p[0], fix[1] - p[1]]);
        }
    }
    Ok(calibrate_fix_noise(&errors)?)
}

/// The odometry velocity of every epoch: the heading corrected by the drift estimated against
/// the fixes-only track (or, without estimation, the raw heading with the drift as a variance
/// growing from t = 0, when the heading was aligned).
fn odometry_velocities(
    config: &Seed004Config,
    truth: &[TruthSample],
    readings: &[OdometryInput],
    reference_track: &[Gaussian<4>],
) -> Result<Vec<(Vector2<f64>, Matrix2<f64>)>> {
    let model = config.odometry_model;
    // prior on the drift rate: twice seed 004's 20°/h
    let drift_prior = 2.0 * 20f64.to_radians() / 3600.0;
    let estimator = HeadingBiasEstimator::new(drift_prior, 1e-14, 3.0).map_err(SimError::estimation(0.0))?;
    let mut bias = estimator.start(0.0).map_err(SimError::estimation(0.0))?;
    let heading_variance = model.heading_std_rad() * model.heading_std_rad();
    let mut out = Vec::with_capacity(readings.len());
    for ((sample, reading), track) in truth.iter().zip(readings).zip(reference_track) {
        let t = sample.time_s;
        if !config.estimate_heading_drift {
            out.push(model.velocity(reading, t).map_err(SimError::estimation(t))?);
            continue;
        }
        // correct with the bias known before this epoch's reference, then learn from it
        let (b, var_b) = bias.bias_at(t).map_err(SimError::estimation(t))?;
        out.push(
            model
                .corrected_velocity(reading, b, var_b)
                .map_err(SimError::estimation(t))?,
        );
        let velocity = Vector2::new(track.mean()[1], track.mean()[3]);
        let p = track.covariance();
        let velocity_covariance = Matrix2::new(p[(1, 1)], p[(1, 3)], p[(3, 1)], p[(3, 3)]);
        bias = bias
            .update(
                t,
                reading.heading_rad,
                &velocity,
                &velocity_covariance,
                heading_variance,
            )
            .map_err(SimError::estimation(t))?;
    }
    Ok(out)
}

fn position_of<const N: usize>(x: &Gaussian<N>) -> [f64; 2] {
    [x.mean()[0], x.mean()[2]]
}

fn run_kf(
    config: &Seed004Config,
    truth: &[TruthSample],
    fixes: &[Option<Vector2<f64>>],
    r: &Matrix2<f64>,
    initial: Gaussian<4>,
) -> Result<Vec<Gaussian<4>>> {
    let filter = KalmanFilter::default();
    let cv = ConstantVelocity::new(ProcessNoise::discrete(config.cv_variance, NoiseGain::seed_004_cv()))
        .map_err(SimError::estimation(0.0))?;
    let model = ComponentSelection::<4>::position(2, full_noise(r)?).map_err(SimError::estimation(0.0))?;
    let mut state = initial;
    let mut out = Vec::with_capacity(truth.len());
    for (sample, fix) in truth.iter().zip(fixes) {
        let t = sample.time_s;
        let prior = filter.predict(&state, &cv, t).map_err(SimError::estimation(t))?;
        state = match fix {
            Some(z) => {
                filter
                    .update(&prior, &model, &DVector::from_column_slice(z.as_slice()))
                    .map_err(SimError::estimation(t))?
                    .state
            }
            None => prior,
        };
        out.push(state);
    }
    Ok(out)
}

/// The fused observation of one epoch: `[x, vx, y, vy]` with `H = I₄` (seed 004 eq. (9)), or
/// the velocity alone when there is no fix. `velocity` is the odometry velocity and its
/// covariance, `r` the fix covariance.
///
/// # Errors
/// [`SimError::Estimation`] for a non-positive-definite covariance or non-finite values.
pub fn fused_observation(
    time_s: f64,
    fix: &Option<Vector2<f64>>,
    velocity: &(Vector2<f64>, Matrix2<f64>),
    r: &Matrix2<f64>,
) -> Result<LinearObservation> {
    let (v, rv) = velocity;
    match fix {
        Some(p) => position_velocity_observation(time_s, p, r, v, rv).map_err(SimError::estimation(time_s)),
        None => {
            let mut h = MeasurementJacobian::<4>::zeros(2);
            h[(0, 1)] = 1.0;
            h[(1, 3)] = 1.0;
            LinearObservation::new(time_s, DVector::from_column_slice(v.as_slice()), h, &full_noise(rv)?)
                .map_err(SimError::estimation(time_s))
        }
    }
}

type VdOutput = (Vec<[f64; 2]>, Vec<VdMode>, Vec<ModeSwitch>);
type ImmOutput = (Vec<[f64; 2]>, Vec<[f64; 3]>);

fn run_vd(
    config: &Seed004Config,
    truth: &[TruthSample],
    fixes: &[Option<Vector2<f64>>],
    velocities: &[(Vector2<f64>, Matrix2<f64>)],
    r: &Matrix2<f64>,
    initial: Gaussian<4>,
) -> Result<VdOutput> {
    let vd = VariableDimensionFilter::seed_004(config.cv_variance, config.ca_variance)
        .and_then(|f| f.with_detector(config.detector))
        .map_err(SimError::estimation(0.0))?;
    let mut state: VdState = vd.initial_state(initial);
    let (mut out, mut modes, mut events) = (Vec::new(), Vec::new(), Vec::new());
    for ((sample, fix), velocity) in truth.iter().zip(fixes).zip(velocities) {
        let t = sample.time_s;
        let observation = fused_observation(t, fix, velocity, r)?;
        let step = vd.step(&state, &observation).map_err(SimError::estimation(t))?;
        events.extend(step.event);
        state = step.state;
        out.push(position_of(&state.estimate().position_velocity()));
        modes.push(state.mode());
    }
    Ok((out, modes, events))
}

fn run_imm(
    config: &Seed004Config,
    truth: &[TruthSample],
    fixes: &[Option<Vector2<f64>>],
    velocities: &[(Vector2<f64>, Matrix2<f64>)],
    r: &Matrix2<f64>,
    initial: Gaussian<4>,
) -> Result<ImmOutput> {
    let imm = seed_004_imm(config).map_err(SimError::estimation(0.0))?;
    let mut state = imm
        .initial_state(
            &ModeEstimate::from_gaussian(&initial),
            &StateLayout::cv_2d(),
            1e-4,
            &[0.8, 0.1, 0.1],
            0.0,
        )
        .map_err(SimError::estimation(0.0))?;
    let (mut out, mut probabilities) = (Vec::new(), Vec::new());
    for ((sample, fix), velocity) in truth.iter().zip(fixes).zip(velocities) {
        let t = sample.time_s;
        let prior = imm.predict(&state, t).map_err(SimError::estimation(t))?;
        let observation = ComponentObservation::from_cv_observation(&fused_observation(t, fix, velocity, r)?)
            .map_err(SimError::estimation(t))?;
        state = imm
            .update_components(&prior, &observation)
            .map_err(SimError::estimation(t))?
            .state;
        let (mean, _) = imm
            .combined(&state, &StateLayout::cv_2d())
            .map_err(SimError::estimation(t))?;
        out.push([mean[0], mean[2]]);
        let p = state.probabilities();
        probabilities.push([p[0], p[1], p[2]]);
    }
    Ok((out, probabilities))
}

/// The IMM of the seed 004 comparison: CV (4 states, KF), CA (6 states, KF) and a coordinated
/// turn with the rate as a state (5 states, EKF), switching with the configured sojourn times.
///
/// # Errors
/// [`rtls_estimation::EstimationError::InvalidParameter`] for invalid variances or sojourn times.
pub fn seed_004_imm(config: &Seed004Config) -> rtls_estimation::Result<InteractingMultipleModel> {
    // The modes' own measurement models are unused here (observations arrive as
    // `ComponentObservation`s with per-epoch noise); they describe a position fix.
    let placeholder = NoiseCovariance::isotropic(2, 1.0)?;
    let cv = FilterMode::<4, _, _, _>::new(
        "CV",
        StateLayout::cv_2d(),
        ConstantVelocity::new(ProcessNoise::discrete(config.imm_cv_variance, NoiseGain::kinematic()))?,
        ComponentSelection::<4>::position(2, placeholder.clone())?,
        KalmanFilter::default(),
    )?;
    let ca = FilterMode::<6, _, _, _>::new(
        "CA",
        StateLayout::ca_2d(),
        ConstantAcceleration::new(ProcessNoise::discrete(config.imm_ca_variance, NoiseGain::kinematic()))?,
        ComponentSelection::<6>::position(2, placeholder.clone())?,
        KalmanFilter::default(),
    )?;
    let ct = FilterMode::<5, _, _, _>::new(
        "CT",
        StateLayout::ct_2d(),
        CoordinatedTurnWithRate::new(
            ProcessNoise::discrete(config.imm_cv_variance, NoiseGain::kinematic()),
            config.imm_turn_rate_variance,
        )?,
        ComponentSelection::<5>::position(2, placeholder)?,
        ExtendedKalmanFilter::default(),
    )?;
    let modes: Vec<Box<dyn ImmMode>> = vec![Box::new(cv), Box::new(ca), Box::new(ct)];
    InteractingMultipleModel::new(modes, ModeTransitions::mean_sojourn(config.imm_sojourn_s.to_vec())?)
}

fn full_noise(m: &Matrix2<f64>) -> Result<NoiseCovariance> {
    NoiseCovariance::full(DMatrix::from_column_slice(2, 2, m.as_slice())).map_err(SimError::estimation(0.0))
}
