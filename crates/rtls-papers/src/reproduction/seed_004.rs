//! Seed 004's experiment: a vehicle tracked by cellular TDOA fixes (Chan, cyclic master) and
//! on-board odometry, comparing raw fixes, a KF on the fixes and the VD-KF fused with the
//! odometry velocity (the paper's methods, built here from rtls-estimation types) with ours:
//! the engine's tracker (`rtls_engine::tracker::Tracker`, an IMM over CV / CA / coordinated
//! turn with its heading channel) run on the same data written as a [`Recording`]
//! ([`seed_004_recording`]).

use std::fmt::Write as _;

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_engine::record::{Measurement, Record};
use rtls_estimation::aided::{
    position_velocity_observation, HeadingBiasEstimator, OdometryErrorModel, OdometryReading as OdometryInput,
};
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::manoeuvre::{
    LinearObservation, ManoeuvreDetector, ModeSwitch, VariableDimensionFilter, VdMode, VdState,
};
use rtls_estimation::measurement::{ComponentSelection, MeasurementJacobian, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};
use rtls_positioning::tdoa::{chan_taylor, cyclic_reference};
use rtls_positioning::{calibrate_fix_noise, PositioningError};

use crate::error::{Result, SimError};
use crate::recording::Recording;
use rtls_sim::scenarios::seed_004_trajectory;
use rtls_sim::sensors::{OdometryReading, OdometrySimulator, TdoaSimulator};
use rtls_sim::trajectory::TruthSample;

/// The tag id of the vehicle in [`seed_004_recording`].
pub const SEED_004_TAG: &str = "vehicle";

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
    /// Ours: the engine's tracker on [`seed_004_recording`] of the same data, its latest
    /// state at each epoch (`None` before the track's first update).
    pub engine: Vec<Option<EngineEstimate>>,
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

    /// The engine's position at every epoch.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] if the engine had no state at some epoch (it reports one from
    /// the first epoch on; a missing one would leave that epoch unscored).
    pub fn engine_positions(&self) -> Result<Vec<[f64; 2]>> {
        self.engine
            .iter()
            .map(|e| {
                e.as_ref().map(|e| e.position_m).ok_or(SimError::EmptyInput {
                    what: "seed 004 engine state at an epoch (no track update yet)",
                })
            })
            .collect()
    }
}

/// The engine's state of the vehicle at one epoch (the latest [`TrackUpdate`] at or before
/// it).
///
/// [`TrackUpdate`]: rtls_engine::tracker::TrackUpdate
#[derive(Debug, Clone, PartialEq)]
pub struct EngineEstimate {
    /// Position `[x, y]`, m.
    pub position_m: [f64; 2],
    /// Position covariance `[P_xx, P_xy, P_yy]`, m².
    pub covariance_m2: [f64; 3],
    /// The IMM's most probable mode (`"CV"`, `"CA"`, `"CT"`).
    pub mode: Option<&'static str>,
}

/// The sensor data of one seeded run, shared by the baselines and the engine's recording.
struct Sensed {
    truth: Vec<TruthSample>,
    /// Per epoch: the reference station and the range differences of the other stations
    /// (station order, reference left out), m.
    differences: Vec<(usize, Vec<f64>)>,
    /// The odometer's reading at each epoch.
    readings: Vec<OdometryReading>,
    /// The fix covariance calibrated at surveyed points (the baselines' `R`).
    fix_covariance_m2: Matrix2<f64>,
}

/// Simulates one run: calibration fixes, then per epoch (1 Hz, `t = 1 … 1500 s`) the range
/// differences with the master station cycling through the four stations (seed 004's "cyclic
/// master") and an odometer reading. Every random draw comes from `seed`.
fn sense(config: &Seed004Config, seed: u64) -> Result<Sensed> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let trajectory = seed_004_trajectory(config.speed_mps)?;
    let truth: Vec<TruthSample> = trajectory.sample(1.0)?.into_iter().skip(1).collect();
    let tdoa = &config.tdoa;
    tdoa.validate()?;
    let q_tdoa = DMatrix::from_diagonal_element(3, 3, tdoa.range_difference_variance_m2());
    let fix_covariance_m2 = calibrate(tdoa, &q_tdoa, config.calibration_points, &mut rng)?;
    let mut odometer = config.odometer.start_run(&mut rng)?;
    let mut differences = Vec::with_capacity(truth.len());
    let mut readings = Vec::with_capacity(truth.len());
    for (k, sample) in truth.iter().enumerate() {
        let reference = cyclic_reference(k as u64, tdoa.stations.len())?;
        differences.push((reference, tdoa.measure(sample.position_m, reference, &mut rng)?));
        readings.push(odometer.measure(sample, &mut rng)?);
    }
    Ok(Sensed {
        truth,
        differences,
        readings,
        fix_covariance_m2,
    })
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
/// Ours is the engine's tracker on [`seed_004_recording`] of the same range differences and
/// odometer readings.
///
/// # Errors
/// [`SimError::InvalidParameter`] for a bad configuration; [`SimError::Estimation`] if a
/// filter step fails; [`SimError::Positioning`] for a calibration without enough fixes;
/// the engine's errors for a site it refuses.
///
/// # References
/// Seed 004 §3 (scenario, noise, 50 runs, compared methods).
pub fn run_seed_004(config: &Seed004Config, seed: u64) -> Result<Seed004Run> {
    let sensed = sense(config, seed)?;
    let Sensed {
        truth,
        differences,
        readings: odometer_readings,
        fix_covariance_m2,
    } = &sensed;
    let tdoa = &config.tdoa;
    let stations = tdoa.stations.as_slice();
    let q_tdoa = DMatrix::from_diagonal_element(3, 3, tdoa.range_difference_variance_m2());
    let odometry_model = config.odometry_model;

    // Fixes and odometry for every epoch (the same data for every filter).
    let mut fixes = Vec::with_capacity(truth.len());
    for (reference, z) in differences {
        fixes.push(fix_or_none(chan_taylor(stations, *reference, z, &q_tdoa))?);
    }
    let readings: Vec<OdometryInput> = odometer_readings
        .iter()
        .map(|r| OdometryInput {
            speed_mps: r.speed_mps,
            heading_rad: r.heading_rad,
        })
        .collect();

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

    let kf_states = run_kf(config, truth, &fixes, fix_covariance_m2, initial)?;
    let kf = kf_states.iter().map(position_of).collect();
    let velocities = odometry_velocities(config, truth, &readings, &kf_states)?;
    let (vd, vd_modes, vd_events) = run_vd(config, truth, &fixes, &velocities, fix_covariance_m2, initial)?;
    let engine = track_with_engine(&recording_of(config, &sensed)?)?;
    Ok(Seed004Run {
        seed,
        fixes: fixes.iter().map(|f| f.map(|v| [v[0], v[1]])).collect(),
        truth: sensed.truth,
        kf,
        vd,
        vd_modes,
        vd_events,
        engine,
        fix_covariance_m2: sensed.fix_covariance_m2,
        odometry_velocities: velocities,
    })
}

/// The engine's latest state at every epoch of the recording's truth.
fn track_with_engine(recording: &Recording) -> Result<Vec<Option<EngineEstimate>>> {
    let tracked = recording.track()?;
    let times: Vec<f64> = recording.truth.iter().map(|row| row.time_s).collect();
    Ok(tracked
        .latest_at(SEED_004_TAG, &times)
        .into_iter()
        .map(|update| {
            update.map(|u| {
                // D × D row-major in the first D² entries
                let (p, d) = (&u.position_covariance_m2, u.dimensions);
                EngineEstimate {
                    position_m: [u.position_m[0], u.position_m[1]],
                    covariance_m2: [p[0], p[1], p[d + 1]],
                    mode: u.mode,
                }
            })
        })
        .collect())
}

/// Seed 004's run `seed` as a [`Recording`]: the site file a user at this site would write from
/// the sensors' specifications, the records the network and the vehicle would send, and the
/// truth. [`run_seed_004`] tracks it with the engine for the "ours" row.
///
/// - **Readers**: the four base stations (`technology = "cellular"`). The simulator puts an
///   independent error on each range difference, Gaussian `σ_g` plus a uniform NLOS delay
///   `U(0, u_max)`: variance `c²(σ_g² + u_max²/12)`. The engine takes a TDOA's variance as the
///   sum of its two readers' `range_std_m²`, so each reader gets `range_std_m = σ_Δr/√2`.
/// - **Records**: per epoch three `tdoa` records (anchor against the epoch's master station)
///   and one `odometry` record with speed, heading and their specified 1σ (speed 1 m/s, the
///   white heading error); an odometer does not report negative speeds, so the simulator's
///   noisy speed is clipped at 0 (at a standstill).
/// - **Tracker**: `platform = "vehicle"` (IMM: CV, CA, coordinated turn), tightly coupled (each
///   range difference updates the filter: no fix is needed for an epoch, and no calibration),
///   the heading channel with the odometer's drift (`[tracker.heading]`).
///
/// # Errors
/// As [`run_seed_004`].
pub fn seed_004_recording(config: &Seed004Config, seed: u64) -> Result<Recording> {
    recording_of(config, &sense(config, seed)?)
}

fn recording_of(config: &Seed004Config, sensed: &Sensed) -> Result<Recording> {
    let names = station_names(config.tdoa.stations.len());
    let speed_std_mps = config.odometer.speed_std_mps;
    let heading_std_rad = config.odometer.heading_noise_std_rad;
    let mut records = Vec::with_capacity(4 * sensed.truth.len());
    for ((sample, (reference, z)), reading) in sensed.truth.iter().zip(&sensed.differences).zip(&sensed.readings) {
        let anchors = (0..names.len()).filter(|i| i != reference);
        for (anchor, range_difference_m) in anchors.zip(z) {
            records.push(Record {
                time_s: sample.time_s,
                tag: SEED_004_TAG.to_string(),
                measurement: Measurement::Tdoa {
                    anchor: names[anchor].clone(),
                    reference: names[*reference].clone(),
                    range_difference_m: *range_difference_m,
                    std_m: None,
                },
            });
        }
        records.push(Record {
            time_s: sample.time_s,
            tag: SEED_004_TAG.to_string(),
            measurement: Measurement::Odometry {
                // an odometer reads no negative speed
                speed_mps: reading.speed_mps.max(0.0),
                heading_rad: Some(reading.heading_rad),
                speed_std_mps: Some(speed_std_mps),
                heading_std_rad: Some(heading_std_rad),
            },
        });
    }
    let truth = sensed
        .truth
        .iter()
        .map(|s| rtls_engine::evaluation::TruthSample {
            time_s: s.time_s,
            tag: SEED_004_TAG.to_string(),
            position_m: [s.position_m[0], s.position_m[1], 0.0],
            // a plan scenario: no height
            has_z: false,
            line: 0,
        })
        .collect();
    Ok(Recording {
        site_toml: site_toml(config),
        records,
        truth,
    })
}

fn station_names(count: usize) -> Vec<String> {
    (1..=count).map(|i| format!("S{i}")).collect()
}

/// The site file of [`seed_004_recording`], every value from the sensors' specifications:
///
/// - reader `range_std_m = σ_Δr/√2` with `σ_Δr² = c²(σ_g² + u_max²/12)` (see
///   [`seed_004_recording`]);
/// - `[tracker.heading]`: the odometer heading's offset starts at its white error (the
///   heading sensor is aligned at the start) and drifts; the engine models the drift as a
///   random walk, written as the drift per hour spread over an hour,
///   `√q_δ = δ̇ · 3600 s / √3600 s` (20°/h → 0.0058 rad/√s, the convention of
///   `examples/site.toml`); without a gyro the heading's changes come from the odometer's
///   successive headings, whose difference has the std `√2 σ_ψ` per second
///   (`gyro_noise_std_radps`);
/// - `[tracker.adaptive_noise]` off and no error correlation: the simulator's errors are white
///   with the stated variances.
fn site_toml(config: &Seed004Config) -> String {
    let tdoa = &config.tdoa;
    let odometer = &config.odometer;
    // σ_Δr/√2 per reader, so that σ_a² + σ_b² = σ_Δr²
    let reader_std_m = (tdoa.range_difference_variance_m2() / 2.0).sqrt();
    let mut site = String::from("name = \"Seed 004: cellular TDOA network and a vehicle with odometry\"\n");
    for (name, [x, y]) in station_names(tdoa.stations.len()).iter().zip(&tdoa.stations) {
        // writing into a String cannot fail
        let _ = writeln!(
            site,
            "[[readers]]\nid = \"{name}\"\nposition_m = [{x:?}, {y:?}]\ntechnology = \"cellular\"\n\
             radio = {{ range = {{ range_std_m = {reader_std_m:?}, bias_m = 0.0 }} }}"
        );
    }
    // √q_δ = δ̇ · 3600 / √3600, at least the engine's smallest (a drift-free heading sensor)
    let drift = (odometer.heading_drift_rad_per_s * 3600f64.sqrt()).max(1e-7);
    // the difference of two headings with white error σ_ψ, over 1 s
    let heading_rate_std = 2f64.sqrt() * odometer.heading_noise_std_rad;
    let offset_std = odometer.heading_noise_std_rad;
    let scored = crate::recording::SCORED_EACH_SECOND;
    let _ = write!(
        site,
        "[tracker]\n\
         platform = \"vehicle\"\n\
         pipeline = \"tightly-coupled\"\n\
         filter = \"ekf\"\n\
         {scored}\
         [tracker.heading]\n\
         gyro_noise_std_radps = {heading_rate_std:?}\n\
         odometer_drift_rad_per_sqrt_s = {drift:?}\n\
         odometer_offset_std_rad = {offset_std:?}\n"
    );
    site
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

fn full_noise(m: &Matrix2<f64>) -> Result<NoiseCovariance> {
    NoiseCovariance::full(DMatrix::from_column_slice(2, 2, m.as_slice())).map_err(SimError::estimation(0.0))
}
