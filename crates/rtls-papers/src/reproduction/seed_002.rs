//! Seed 002's experiment: L-WKNN fingerprint fixes over a 100 m × 100 m site, tracked with the
//! accelerometer as control input by the paper's first- and second-order models (as printed)
//! and by the textbook `[p, v]` model, all on the same seeded data.

use nalgebra::{DVector, Matrix2, Matrix4, Vector2, Vector4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_estimation::aided::{
    AccelerometerSample, DeadReckoning, ModelOrder, PrintedAccelerometerModel, TextbookAccelerometerModel,
};
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::Gaussian;
use rtls_positioning::fingerprint::{
    FingerprintDatabase, FingerprintFix, FingerprintIndex, Knn, LocalWknn, SignalSpace,
};

use crate::error::{Result, SimError};
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
    /// Extra white-acceleration variance of the textbook model ((m/s²)²); 0 = accelerometer only.
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
    /// Textbook model: state `[p, v]`, accelerometer as control input.
    pub textbook: Vec<[f64; 2]>,
    /// Whether L-WKNN chose the same neighbours as global WKNN (same `n`) at each epoch.
    pub same_neighbours_as_wknn: Vec<bool>,
}

/// Runs seed 002's experiment once with `seed`.
///
/// The fingerprint database holds one noisy (`σ²`) RSSI vector per reference point of the
/// 10 m grid; every second the node's RSSI (`σ_p²`) gives an L-WKNN fix, and its
/// accelerometer the mean acceleration over the last second. The filters start at the known
/// initial position with zero covariance (`Q(0) = 0`, §1.2) and observe the fixes with `U`.
///
/// # Errors
/// [`SimError::Positioning`] if the locator fails; [`SimError::Estimation`] if a filter step
/// fails; the simulators' parameter errors.
///
/// # References
/// Seed 002 §1–§2, Table 1, Fig. 1 and Fig. 5–6.
pub fn run_seed_002(config: &Seed002Config, seed: u64) -> Result<Seed002Run> {
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
    let fix2 = ComponentSelection::<2>::new(&[0, 1], u.clone()).map_err(SimError::estimation(0.0))?;
    let fix4 = ComponentSelection::<4>::position(2, u).map_err(SimError::estimation(0.0))?;
    let start = samples[0].position_m;
    // known initial position, at rest: zero covariance
    let mut first = Gaussian::new(Vector2::from(start), Matrix2::zeros(), 0.0).map_err(SimError::estimation(0.0))?;
    let mut second = first;
    let mut textbook = Gaussian::new(Vector4::new(start[0], 0.0, start[1], 0.0), Matrix4::zeros(), 0.0)
        .map_err(SimError::estimation(0.0))?;
    let (mut dr_first, mut dr_second) = (DeadReckoning::at_rest(), DeadReckoning::at_rest());
    let printed_first = PrintedAccelerometerModel::new(ModelOrder::First);
    let printed_second = PrintedAccelerometerModel::new(ModelOrder::Second);
    let textbook_model =
        TextbookAccelerometerModel::new(config.textbook_extra_variance_m2ps4).map_err(SimError::estimation(0.0))?;

    let mut run = Seed002Run {
        seed,
        truth: Vec::new(),
        fixes: Vec::new(),
        first_order: Vec::new(),
        second_order: Vec::new(),
        textbook: Vec::new(),
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
        let model = textbook_model.for_sample(&sample);
        let a = DVector::from_column_slice(&reading.acceleration_mps2);
        let prior = kf
            .predict_with_control(&textbook, &model, &a, t)
            .map_err(SimError::estimation(t))?;
        textbook = kf.update(&prior, &fix4, &z).map_err(SimError::estimation(t))?.state;

        run.truth.push(truth.position_m);
        run.fixes.push([fix[0], fix[1]]);
        run.same_neighbours_as_wknn.push(same_neighbours(&local, &global));
        run.first_order.push([first.mean()[0], first.mean()[1]]);
        run.second_order.push([second.mean()[0], second.mean()[1]]);
        run.textbook.push([textbook.mean()[0], textbook.mean()[2]]);
    }
    Ok(run)
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
