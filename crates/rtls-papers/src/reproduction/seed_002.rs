//! Seed 002's experiment: L-WKNN fingerprint fixes over a 100 m × 100 m site, tracked with the
//! accelerometer as control input by the paper's first- and second-order models (as printed,
//! the baselines, built here from rtls-estimation types) and by ours: the textbook `[p, v]`
//! model in the engine's tracker (`rtls_engine::tracker::Tracker`), run on the same data
//! written as a [`Recording`] ([`seed_002_recording`]).

use std::fmt::Write as _;

use nalgebra::{DVector, Matrix2, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_engine::evaluation::TruthSample;
use rtls_engine::record::{Measurement, Record};
use rtls_estimation::aided::{AccelerometerSample, DeadReckoning, ModelOrder, PrintedAccelerometerModel};
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::Gaussian;
use rtls_positioning::fingerprint::{
    FingerprintDatabase, FingerprintFix, FingerprintIndex, Knn, LocalWknn, SignalSpace,
};

use crate::error::{Result, SimError};
use crate::recording::Recording;
use rtls_sim::scenarios::{seed_002_manoeuvre_then_cruise, seed_002_trajectory, GridSite};
use rtls_sim::sensors::{fingerprint_means, AccelerometerNoise, AccelerometerSimulator};

/// Which of seed 002's trajectories.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seed002Trajectory {
    /// Fig. 1: 100 samples at 1 s with varying acceleration.
    Tracking,
    /// Fig. 5/6: 80 samples, varying acceleration for 55 s, then constant velocity.
    ManoeuvreThenCruise,
}

/// Parameters of the seed 002 reproduction; [`Seed002Config::default`] is Table 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed002Config {
    /// The trajectory.
    pub trajectory: Seed002Trajectory,
    /// Online RSSI noise variance `σ_p²` (dB²; Table 1: 16).
    pub rssi_variance_db2: f64,
    /// Fingerprint noise variance `σ²` (dB²; Table 1: 1).
    pub fingerprint_variance_db2: f64,
    /// L-WKNN parameters (Table 1: `N_k = 4`, radius 20 m, `n = 4`).
    pub locator: LocalWknn,
    /// Observation noise `U = diag(U_x, U_y)` (m²; Table 1: 1.5 and 2).
    pub fix_variance_m2: [f64; 2],
    /// Accelerometer noise (Table 1: 0.01 m/s²; §2(3): 10 % of the reading).
    pub accelerometer: AccelerometerNoise,
    /// Extra white-acceleration variance of the textbook model ((m/s²)²): the square of the
    /// engine's `aided_acceleration_noise_std_mps2` (a continuous white acceleration of this
    /// PSD, m²/s³, on top of the samples' noise); 0 = the accelerometer's own noise only.
    pub textbook_extra_variance_m2ps4: f64,
    /// The site: anchors, reference-point grid and radio (Table 1: [`GridSite::seed_002`]).
    pub site: GridSite,
}

impl Default for Seed002Config {
    fn default() -> Self {
        Self {
            trajectory: Seed002Trajectory::Tracking,
            rssi_variance_db2: 16.0,
            fingerprint_variance_db2: 1.0,
            locator: LocalWknn {
                strongest_anchors: 4,
                radius_m: 20.0,
                knn: Knn::wknn(4),
            },
            fix_variance_m2: [1.5, 2.0],
            accelerometer: AccelerometerNoise::SEED_002_ABSOLUTE,
            textbook_extra_variance_m2ps4: 0.0,
            site: GridSite::seed_002(),
        }
    }
}

impl Seed002Config {
    /// The first- vs second-order comparison of §2(3): the 80-sample trajectory with
    /// accelerometer noise 10 % of the reading.
    #[must_use]
    pub fn model_order_comparison() -> Self {
        Self {
            trajectory: Seed002Trajectory::ManoeuvreThenCruise,
            accelerometer: AccelerometerNoise::SEED_002_PROPORTIONAL,
            ..Self::default()
        }
    }
}

/// One seeded run: positions at `t = 1, 2, …` s.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed002Run {
    /// The run's seed.
    pub seed: u64,
    /// Truth.
    pub truth: Vec<[f64; 2]>,
    /// L-WKNN fixes.
    pub fixes: Vec<[f64; 2]>,
    /// First-order model as printed (eq. (6)–(9)).
    pub first_order: Vec<[f64; 2]>,
    /// Second-order model as printed (eq. (6), (9)–(11)).
    pub second_order: Vec<[f64; 2]>,
    /// Ours: the textbook model (state `[p, v]`, accelerometer as control input) in the
    /// engine's tracker on [`seed_002_recording`] of the same data, its update at each epoch.
    pub textbook: Vec<[f64; 2]>,
    /// The engine's position NEES `eᵀ P⁻¹ e` at each epoch (2 on average if consistent).
    pub textbook_nees: Vec<f64>,
    /// Whether L-WKNN chose the same neighbours as global WKNN (same `n`) at each epoch.
    pub same_neighbours_as_wknn: Vec<bool>,
}

/// The tag id of the node in [`seed_002_recording`].
pub const SEED_002_TAG: &str = "node";

/// Runs seed 002's experiment once with `seed`.
///
/// The fingerprint database holds one noisy (`σ²`) RSSI vector per reference point of the
/// 10 m grid; every second the node's RSSI (`σ_p²`) gives an L-WKNN fix, and its
/// accelerometer the mean acceleration over the last second. The printed models start at the
/// known initial position with zero covariance (`Q(0) = 0`, §1.2) and observe the fixes with
/// `U`; ours is the engine's tracker on [`seed_002_recording`] of the same fixes and samples.
///
/// # Errors
/// [`SimError::Positioning`] if the locator fails; [`SimError::Estimation`] if a filter step
/// fails; the simulators' parameter errors; the engine's errors for a site it refuses, and
/// [`SimError::EmptyInput`] if it gave no update by some epoch.
///
/// # References
/// Seed 002 §1–§2, Table 1, Fig. 1 and Fig. 5–6.
pub fn run_seed_002(config: &Seed002Config, seed: u64) -> Result<Seed002Run> {
    let (mut run, recording) = simulate(config, seed)?;
    let tracked = recording.track()?;
    let times: Vec<f64> = recording.truth.iter().map(|row| row.time_s).collect();
    for (update, truth) in tracked.latest_at(SEED_002_TAG, &times).into_iter().zip(&run.truth) {
        let u = update.ok_or(SimError::EmptyInput {
            what: "seed 002 engine state at an epoch (no track update yet)",
        })?;
        let position = [u.position_m[0], u.position_m[1]];
        // D × D row-major in the first D² entries
        let (p, d) = (&u.position_covariance_m2, u.dimensions);
        let covariance = Matrix2::new(p[0], p[1], p[d], p[d + 1]);
        let error = Vector2::new(position[0] - truth[0], position[1] - truth[1]);
        // eᵀ P⁻¹ e
        let nees = covariance
            .try_inverse()
            .map(|inverse| (error.transpose() * inverse * error)[0])
            .ok_or(SimError::EmptyInput {
                what: "seed 002 engine covariance (singular)",
            })?;
        run.textbook.push(position);
        run.textbook_nees.push(nees);
    }
    Ok(run)
}

/// Seed 002's run `seed` as a [`Recording`]: the site file a user would write from the
/// sensors' specifications, the records the node would send, and the truth.
/// [`run_seed_002`] tracks it with the engine for the "ours" row.
///
/// - **Readers**: the 25 anchors (their RSSI is turned into fixes on the node's side).
/// - **Records**: at `t = 0` an enrolment `fix` at the known start (σ 1 cm) and a `velocity`
///   of 0 (σ 1 cm/s): the node starts at rest at a surveyed point, as the printed models
///   assume (`x(0)` known, `v(0) = 0`, `Q(0) = 0`); then every second an `accelerometer`
///   record (the mean acceleration over the last second, with the filter's `ε` as its std;
///   with noise proportional to the reading, the larger axis's) and the L-WKNN `fix` with
///   the calibrated covariance `U`.
/// - **Tracker**: fix-then-filter, the CV model as a KF driven by the accelerometer, with no
///   noise beyond the samples' own (`aided_acceleration_noise_std_mps2` = the configured
///   extra, 0 in the paper's comparison): seed 002's textbook `[p, v]` model. Every fix is
///   taken (`U` is the paper's calibration; an L-WKNN error far outside it is still the only
///   position there is), at the stated noise (no adaptive scaling).
///
/// # Errors
/// As [`run_seed_002`].
pub fn seed_002_recording(config: &Seed002Config, seed: u64) -> Result<Recording> {
    Ok(simulate(config, seed)?.1)
}

/// One seeded run: the fixes, the printed models' estimates and the recording for the engine
/// (`textbook` left empty).
fn simulate(config: &Seed002Config, seed: u64) -> Result<(Seed002Run, Recording)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let trajectory = match config.trajectory {
        Seed002Trajectory::Tracking => seed_002_trajectory()?,
        Seed002Trajectory::ManoeuvreThenCruise => seed_002_manoeuvre_then_cruise()?,
    };
    config.site.validate()?;
    let radio = config.site.radio;
    let anchors = config.site.anchors_m();
    let reference_points = config.site.reference_points_m();
    let rows = fingerprint_means(
        &anchors,
        &reference_points,
        &radio,
        config.fingerprint_variance_db2,
        1,
        &mut rng,
    )?;
    let database = FingerprintDatabase::new(reference_points, anchors.clone(), rows)?;
    // seed 002's signal space: Euclidean distance on dBm (every anchor is heard)
    let index = FingerprintIndex::new(database, SignalSpace::default())?;
    let locator = config.locator.build(&index)?;
    let accelerometer = AccelerometerSimulator {
        noise: config.accelerometer,
    };
    let samples = trajectory.sample(1.0)?;
    let readings = accelerometer.measure_trajectory(&trajectory, 1.0, &mut rng)?;

    let kf = KalmanFilter::default();
    let u = NoiseCovariance::diagonal(&config.fix_variance_m2).map_err(SimError::estimation(0.0))?;
    let fix2 = ComponentSelection::<2>::new(&[0, 1], u).map_err(SimError::estimation(0.0))?;
    let start = samples[0].position_m;
    // known initial position, at rest: zero covariance
    let mut first = Gaussian::new(Vector2::from(start), Matrix2::zeros(), 0.0).map_err(SimError::estimation(0.0))?;
    let mut second = first;
    let (mut dr_first, mut dr_second) = (DeadReckoning::at_rest(), DeadReckoning::at_rest());
    let printed_first = PrintedAccelerometerModel::new(ModelOrder::First);
    let printed_second = PrintedAccelerometerModel::new(ModelOrder::Second);
    let [ux, uy] = config.fix_variance_m2;
    let mut records = enrolment(start);

    let mut run = Seed002Run {
        seed,
        truth: Vec::new(),
        fixes: Vec::new(),
        first_order: Vec::new(),
        second_order: Vec::new(),
        textbook: Vec::new(),
        textbook_nees: Vec::new(),
        same_neighbours_as_wknn: Vec::new(),
    };
    for (truth, reading) in samples.iter().skip(1).zip(&readings) {
        let t = truth.time_s;
        let rssi: Vec<Option<f64>> = radio
            .measure(&anchors, truth.position_m, config.rssi_variance_db2, &mut rng)?
            .into_iter()
            .map(Some)
            .collect();
        let local = locator.locate(&rssi)?;
        let global = config.locator.knn.locate(&index, &rssi)?;
        let fix = local.fix.position;
        let z = DVector::from_column_slice(fix.as_slice());
        // the filter's ε: what a real filter knows — the configured std, or 10 % of the reading
        let std = config.accelerometer.filter_std_mps2(reading.acceleration_mps2);
        let sample = AccelerometerSample::new(reading.acceleration_mps2, [std[0] * std[0], std[1] * std[1]])
            .map_err(SimError::estimation(t))?;
        let step = |state: &Gaussian<2>, model: &PrintedAccelerometerModel, dr: &DeadReckoning| {
            let (position_step, next) = model.advance(dr, &sample, 1.0)?;
            let prior = kf.predict_with_control(state, &position_step, &position_step.control(), t)?;
            Ok::<_, rtls_estimation::EstimationError>((kf.update(&prior, &fix2, &z)?.state, next))
        };
        (first, dr_first) = step(&first, &printed_first, &dr_first).map_err(SimError::estimation(t))?;
        (second, dr_second) = step(&second, &printed_second, &dr_second).map_err(SimError::estimation(t))?;
        // the engine's records of this second: the sample over it, then the fix at its end
        records.push(node_record(
            t,
            Measurement::Accelerometer {
                acceleration_mps2: reading.acceleration_mps2.to_vec(),
                std_mps2: Some(std[0].max(std[1])),
            },
        ));
        records.push(node_record(
            t,
            Measurement::Fix {
                position_m: vec![fix[0], fix[1]],
                covariance_m2: vec![ux, 0.0, 0.0, uy],
            },
        ));

        run.truth.push(truth.position_m);
        run.fixes.push([fix[0], fix[1]]);
        run.same_neighbours_as_wknn.push(same_neighbours(&local, &global));
        run.first_order.push([first.mean()[0], first.mean()[1]]);
        run.second_order.push([second.mean()[0], second.mean()[1]]);
    }
    let truth = samples
        .iter()
        .skip(1)
        .map(|s| TruthSample {
            time_s: s.time_s,
            tag: SEED_002_TAG.to_string(),
            position_m: [s.position_m[0], s.position_m[1], 0.0],
            // a plan scenario: no height
            has_z: false,
            line: 0,
        })
        .collect();
    let recording = Recording {
        site_toml: site_toml(config),
        records,
        truth,
    };
    Ok((run, recording))
}

/// A record of the node.
fn node_record(time_s: f64, measurement: Measurement) -> Record {
    Record {
        time_s,
        tag: SEED_002_TAG.to_string(),
        measurement,
    }
}

/// The enrolment at `t = 0`: the surveyed start (σ 1 cm) and the node at rest (σ 1 cm/s).
fn enrolment(start_m: [f64; 2]) -> Vec<Record> {
    const ENROLMENT_STD_M: f64 = 0.01;
    const ENROLMENT_SPEED_STD_MPS: f64 = 0.01;
    let p = ENROLMENT_STD_M * ENROLMENT_STD_M;
    let v = ENROLMENT_SPEED_STD_MPS * ENROLMENT_SPEED_STD_MPS;
    vec![
        node_record(
            0.0,
            Measurement::Fix {
                position_m: start_m.to_vec(),
                covariance_m2: vec![p, 0.0, 0.0, p],
            },
        ),
        node_record(
            0.0,
            Measurement::Velocity {
                velocity_mps: vec![0.0, 0.0],
                covariance_m2ps2: Some(vec![v, 0.0, 0.0, v]),
            },
        ),
    ]
}

/// The site file of [`seed_002_recording`] (see there for the choices).
fn site_toml(config: &Seed002Config) -> String {
    let mut site = String::from("name = \"Seed 002: 100 m field, 25 anchors, L-WKNN fixes and an accelerometer\"\n");
    for (i, [x, y]) in config.site.anchors_m().iter().enumerate() {
        // writing into a String cannot fail
        let _ = writeln!(
            site,
            "[[readers]]\nid = \"A{}\"\nposition_m = [{x:?}, {y:?}]\ntechnology = \"wifi\"",
            i + 1
        );
    }
    let _ = write!(
        site,
        "[tracker]\n\
         pipeline = \"fix-then-filter\"\n\
         motion_model = \"cv\"\n\
         filter = \"kf\"\n\
         aided_acceleration_noise_std_mps2 = {:?}\n\
         gate_probability = 0.999999999\n\
         {}",
        config.textbook_extra_variance_m2ps4.sqrt(),
        crate::recording::SCORED_EACH_SECOND,
    );
    site
}

/// Whether two fixes averaged the same set of reference points (seed 002: "L-WKNN finds the same
/// neighbours as global WKNN").
fn same_neighbours(a: &FingerprintFix, b: &FingerprintFix) -> bool {
    let set = |fix: &FingerprintFix| {
        let mut points: Vec<usize> = fix.neighbours.iter().map(|n| n.reference_point).collect();
        points.sort_unstable();
        points
    };
    set(a) == set(b)
}
