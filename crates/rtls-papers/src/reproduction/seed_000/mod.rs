//! Seed 000's experiment, one seeded run: a miner walks through a mine section, the readers
//! hear his tag (or not), the reader layer computes RSSI and DV-Hop fixes, and the manager
//! layer tracks him with the paper's ME-KF (a 3-D CV Kalman filter on the RSSI fixes, `T = 1 s`,
//! `Q = R = 5`, as printed) and with ours: the engine's tracker on the readers' records
//! ([`seed_000_recording`], settings [`OursConfig`]: an EKF on the raw RSSI with negative
//! information and the tunnel map).
//!
//! Both trackers report a position at every epoch: with no fix (no detection) they report
//! their prediction, so their percentage of empty locations is 0 (seed 000 Table 2).

mod engine;
mod models;

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_estimation::filter::{CovarianceUpdate, KalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};
use rtls_positioning::multilateration::GaussNewtonOptions;
use rtls_positioning::range_free::DvHopOptions;

use crate::error::{finite, non_negative, positive, Result, SimError};
use rtls_sim::scenarios::seed_000::MineLayout;
use rtls_sim::sensors::readers::{DvHopNetwork, ReaderLayer, ReaderRadio, RssiFix};
use rtls_sim::trajectory::{PathSample, WaypointPath};

pub use engine::{seed_000_recording, site_toml, InnovationSum, OursConfig, TrackerCounts, TAG};
pub use models::{
    detected_information, expected_information, MapSpread, PedestrianCv, PositionConstraint, POSITION_INDICES,
};

/// Iteration limit of the RSSI and DV-Hop Gauss–Newton fixes. In a tunnel the readers span only the wall
/// spacing across and the mounting heights vertically, so the cost has a long, flat valley
/// across the tunnel and the solver needs up to a few hundred steps (measured: all of 220
/// noisy 5-reader fixes converged within 500).
pub const GN_MAX_ITERATIONS: usize = 1000;

/// Step tolerance of the RSSI fix relative to the readers' spread: 10⁻⁴ of a ~25 m spread is
/// millimetres, far below the metres of RSSI error (the library default, 10⁻¹⁰, makes the
/// solver crawl along the valley for thousands of steps).
pub const GN_RELATIVE_TOLERANCE: f64 = 1e-4;

/// The state every tracker starts from: the walker is at the mine entrance at `t = 0`.
///
/// # Units
/// m, m/s, m², (m/s)².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerPrior {
    /// Mean position `[x, y, z]`, m.
    pub position_m: [f64; 3],
    /// Mean velocity `[vx, vy, vz]`, m/s.
    pub velocity_mps: [f64; 3],
    /// Variance of each position component, m².
    pub position_variance_m2: f64,
    /// Variance of each velocity component, (m/s)².
    pub velocity_variance_m2s2: f64,
}

impl TrackerPrior {
    /// The prior as a Gaussian state `[x, vx, y, vy, z, vz]` at `time_s`.
    ///
    /// # Errors
    /// [`SimError::Estimation`] for NaN/∞ or negative variances.
    ///
    /// # Example
    /// ```
    /// use rtls_papers::reproduction::seed_000::TrackerPrior;
    /// let prior = TrackerPrior { position_m: [0.0; 3], velocity_mps: [1.0, 0.0, 0.0], position_variance_m2: 1.0, velocity_variance_m2s2: 2.25 };
    /// let x0 = prior.gaussian(0.0)?;
    /// assert_eq!((x0.mean()[1], x0.covariance()[(1, 1)]), (1.0, 2.25));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    pub fn gaussian(&self, time_s: f64) -> Result<Gaussian<6>> {
        let mut mean = Vector::<6>::zeros();
        let mut covariance = Matrix::<6>::zeros();
        for axis in 0..3 {
            mean[2 * axis] = self.position_m[axis];
            mean[2 * axis + 1] = self.velocity_mps[axis];
            covariance[(2 * axis, 2 * axis)] = self.position_variance_m2;
            covariance[(2 * axis + 1, 2 * axis + 1)] = self.velocity_variance_m2s2;
        }
        Gaussian::new(mean, covariance, time_s).map_err(SimError::estimation(time_s))
    }
}

/// Seed 000's ME-KF as printed: CV model with `Q = σ_w² I₃` through `C = [T²/2, T]ᵀ` per axis,
/// position fixes with `R = σ_v² I₃`, the simple covariance update `P = (I − K H) P⁻` (eq. 20).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MekfConfig {
    /// `σ_w²` ((m/s²)², paper: 5).
    pub process_variance: f64,
    /// `σ_v²` (m², paper: 5).
    pub measurement_variance: f64,
}

/// Everything a run needs, built once per scenario: the readers, the DV-Hop network, the truth
/// at every epoch, the excess radio loss from each epoch's true position to each reader, and
/// the expected information the PCRB needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed000Setup {
    /// The reader layer (readers and radio).
    pub layer: ReaderLayer,
    /// DV-Hop over the working readers.
    pub dv_hop: DvHopNetwork,
    /// The mine layout (our tracker reads the map).
    pub layout: MineLayout,
    /// Truth at `t = T, 2T, …` (the tracker prior is at `t = 0`).
    pub epochs: Vec<PathSample>,
    /// `excess_loss_db[k][i]`: extra loss from the truth at epoch `k` to reader `i`, dB.
    pub excess_loss_db: Vec<Vec<f64>>,
    /// Whether the truth is in a danger zone at each epoch.
    pub in_zone: Vec<bool>,
    /// Expected Fisher information about the state at each epoch's truth (6 × 6): the censored
    /// RSSI of every working reader plus the tunnel map ([`expected_information`]).
    pub information: Vec<DMatrix<f64>>,
    /// The naive information of the readers that hear the tag only ([`detected_information`]).
    pub detected_information: Vec<DMatrix<f64>>,
    /// How far below the readers' centroid the RSSI solver starts, m.
    pub guess_below_m: f64,
    /// RSSI solver options.
    pub solver: GaussNewtonOptions,
    /// The trackers' prior at `t = 0`.
    pub prior: TrackerPrior,
    /// The ME-KF.
    pub mekf: MekfConfig,
    /// Our tracker's settings.
    pub ours: OursConfig,
}

/// How the construction of a [`Seed000Setup`] is parametrised besides the layout and the walk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetupOptions {
    /// Epoch period `T`, s.
    pub period_s: f64,
    /// Reader-to-reader radio range of the DV-Hop network, m.
    pub link_range_m: f64,
    /// How far below the readers' centroid the RSSI solver starts, m.
    pub guess_below_m: f64,
    /// The trackers' prior.
    pub prior: TrackerPrior,
    /// The ME-KF.
    pub mekf: MekfConfig,
    /// Our tracker.
    pub ours: OursConfig,
}

impl Seed000Setup {
    /// Samples the walk at `t = T, 2T, …`, computes the radio losses and the information along
    /// it, and builds the reader layer and the DV-Hop network of `layout`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a bad period, range or variance, or a walk shorter
    /// than two epochs; the errors of [`ReaderLayer::new`] and [`DvHopNetwork::new`] (e.g. a
    /// reader network with an isolated reader).
    pub fn new(layout: &MineLayout, radio: ReaderRadio, path: &WaypointPath, options: &SetupOptions) -> Result<Self> {
        positive(options.period_s, "period_s", "the epoch period must be positive")?;
        positive(
            options.link_range_m,
            "link_range_m",
            "the reader link range must be positive",
        )?;
        finite(options.guess_below_m, "guess_below_m")?;
        for v in [options.mekf.process_variance, options.mekf.measurement_variance] {
            positive(v, "mekf", "the ME-KF variances must be positive")?;
        }
        positive(
            options.ours.max_speed_mps,
            "max_speed_mps",
            "the speed limit must be positive",
        )?;
        non_negative(
            options.ours.junction_radius_m,
            "junction_radius_m",
            "the junction radius must not be negative",
        )?;
        let epochs: Vec<PathSample> = path.sample(options.period_s)?.into_iter().skip(1).collect();
        if epochs.len() < 2 {
            return Err(SimError::InvalidParameter {
                name: "walk",
                reason: "the walk must last at least two epochs",
            });
        }
        let layer = ReaderLayer::new(layout.readers().to_vec(), radio)?;
        let solver = GaussNewtonOptions {
            max_iterations: GN_MAX_ITERATIONS,
            relative_tolerance: GN_RELATIVE_TOLERANCE,
        };
        let dv_hop = DvHopNetwork::new(
            &layer,
            &layout.reader_links(options.link_range_m),
            DvHopOptions { refine: true, solver },
        )?;
        let excess_loss_db: Vec<Vec<f64>> = epochs.iter().map(|s| layout.excess_loss_db(s.position_m)).collect();
        let mut information = Vec::with_capacity(epochs.len());
        let mut detected = Vec::with_capacity(epochs.len());
        for (sample, excess) in epochs.iter().zip(&excess_loss_db) {
            let map = &options.ours.map;
            information.push(expected_information(&layer, layout, map, sample.position_m, excess)?);
            detected.push(detected_information(&layer, sample.position_m, excess)?);
        }
        Ok(Self {
            in_zone: epochs.iter().map(|s| layout.in_danger_zone(s.position_m)).collect(),
            excess_loss_db,
            information,
            detected_information: detected,
            layout: layout.clone(),
            layer,
            dv_hop,
            epochs,
            guess_below_m: options.guess_below_m,
            solver,
            prior: options.prior,
            mekf: options.mekf,
            ours: options.ours,
        })
    }

    /// Truth positions at every epoch.
    #[must_use]
    pub fn truth_m(&self) -> Vec<[f64; 3]> {
        self.epochs.iter().map(|s| s.position_m).collect()
    }
}

/// A tracker's state mean `[x, vx, y, vy, z, vz]` after an epoch.
pub type TrackState = [f64; 6];

/// The position `[x, y, z]` of a track state.
#[must_use]
pub fn position_of(state: &TrackState) -> [f64; 3] {
    [state[0], state[2], state[4]]
}

/// The CV extrapolation `p + h v` of a track state `h` seconds ahead: the mean of the
/// tracker's `h`-step prediction.
///
/// # Example
/// ```
/// use rtls_papers::reproduction::seed_000::extrapolate;
/// assert_eq!(extrapolate(&[1.0, 0.5, 2.0, 0.0, 3.0, -0.1], 2.0), [2.0, 2.0, 2.8]);
/// ```
#[must_use]
pub fn extrapolate(state: &TrackState, horizon_s: f64) -> [f64; 3] {
    [
        state[0] + horizon_s * state[1],
        state[2] + horizon_s * state[3],
        state[4] + horizon_s * state[5],
    ]
}

/// One seeded run: what each method reported at each epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed000Run {
    /// The run's seed.
    pub seed: u64,
    /// Readers that heard the tag at each epoch.
    pub heard: Vec<usize>,
    /// RSSI fix at each epoch (`None`: empty location).
    pub rssi: Vec<Option<RssiFix>>,
    /// DV-Hop fix at each epoch (`None`: empty location or no solution).
    pub dv_hop: Vec<Option<[f64; 3]>>,
    /// ME-KF state after each epoch.
    pub mekf: Vec<TrackState>,
    /// The engine's state after each epoch (its latest update at the epoch's time).
    pub ours: Vec<TrackState>,
    /// The engine's decisions.
    pub counts: TrackerCounts,
    /// Per reader: the RSSI residuals against our estimates (for the obstacle analysis).
    pub innovations: Vec<InnovationSum>,
}

/// Runs seed 000 once with `seed` (every random draw — the shadowing — comes from it): the
/// reader layer's fixes, the ME-KF on them, and the engine on the readers' records.
///
/// # Errors
/// [`SimError::Estimation`] if an ME-KF step fails numerically; the errors of the reader layer
/// and of the engine's tracker.
pub fn run_seed_000(setup: &Seed000Setup, seed: u64) -> Result<Seed000Run> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let estimation = |e| SimError::Estimation { time_s: 0.0, source: e };
    // ME-KF: F, C Q Cᵀ with Q = σ_w² I₃; H picks x, y, z; R = σ_v² I₃
    let cv = ConstantVelocity::new(ProcessNoise::discrete(
        setup.mekf.process_variance,
        NoiseGain::kinematic(),
    ))
    .map_err(estimation)?;
    let fix_model = ComponentSelection::<6>::position(
        3,
        NoiseCovariance::isotropic(3, setup.mekf.measurement_variance).map_err(estimation)?,
    )
    .map_err(estimation)?;
    let kf = KalmanFilter::new(CovarianceUpdate::Simple);
    let n = setup.epochs.len();
    let (mut detections, mut rssi, mut dv_hop) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    let mut mekf = Vec::with_capacity(n);
    let mut mekf_state = setup.prior.gaussian(0.0)?;
    for (truth, excess_db) in setup.epochs.iter().zip(&setup.excess_loss_db) {
        let t = truth.time_s;
        let heard = setup.layer.detect(truth.position_m, excess_db, &mut rng)?;
        let fix = setup.layer.rssi_fix(&heard, setup.guess_below_m, &setup.solver)?;
        dv_hop.push(setup.dv_hop.locate(&heard)?);
        // ME-KF: predict (eq. 21–22), update with the fix (eq. 23–25) or coast
        let prior = kf.predict(&mekf_state, &cv, t).map_err(SimError::estimation(t))?;
        mekf_state = match &fix {
            Some(f) => {
                let z = DVector::from_column_slice(&f.position_m);
                kf.update(&prior, &fix_model, &z)
                    .map_err(SimError::estimation(t))?
                    .state
            }
            None => prior,
        };
        detections.push(heard);
        rssi.push(fix);
        mekf.push(state_array(&mekf_state));
    }
    let recording = engine::recording(setup, &detections);
    let (ours, counts, innovations) = engine::ours(setup, &recording, &detections)?;
    Ok(Seed000Run {
        seed,
        heard: detections.iter().map(Vec::len).collect(),
        rssi,
        dv_hop,
        mekf,
        ours,
        counts,
        innovations,
    })
}

fn state_array(state: &Gaussian<6>) -> TrackState {
    let m = state.mean();
    [m[0], m[1], m[2], m[3], m[4], m[5]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prior_and_extrapolation() {
        let prior = TrackerPrior {
            position_m: [1.0, 2.0, 3.0],
            velocity_mps: [0.5, 0.0, -0.1],
            position_variance_m2: 1.0,
            velocity_variance_m2s2: 2.0,
        };
        let g = prior.gaussian(0.0).unwrap();
        assert_eq!((g.mean()[2], g.covariance()[(3, 3)]), (2.0, 2.0));
        let s = state_array(&g);
        assert_eq!(position_of(&s), [1.0, 2.0, 3.0]);
        assert_eq!(extrapolate(&s, 2.0), [2.0, 2.0, 2.8]);
        let bad = TrackerPrior {
            position_variance_m2: -1.0,
            ..prior
        };
        assert!(bad.gaussian(0.0).is_err());
    }
}
