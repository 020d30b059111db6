//! # rtls-sim
//!
//! Seeded simulation of RTLS scenarios: exact truth trajectories, simulated sensors and
//! accuracy metrics, for the experiments of the seed papers (crate rtls-papers), for the
//! `--demo` mine of `rtls serve` and for testing the filters of `rtls-estimation` and the
//! engine's tracker against a known truth. Numeric only: no I/O, no async, no global
//! randomness (every simulator takes `rng: &mut impl rand::Rng`).
//!
//! ## What this crate owns and may import
//! It owns trajectories, sensor simulators, the seed papers' site layouts and trajectories
//! ([`scenarios`]), metrics, the PCRB, Monte Carlo and the mine simulation. It may import
//! `rtls-estimation`, `rtls-positioning` and `rtls-engine` (records and sites, which the mine
//! writes). The paper experiments and their reports are in rtls-papers, on top of this crate;
//! the server does not depend on it (the binary composes the demo feed).
//!
//! ## Vocabulary
//! - [`trajectory`] — [`Trajectory`] built from segments (constant velocity, stop, coordinated
//!   turn, constant acceleration), each integrated in closed form; [`TruthSample`]s on a grid.
//! - [`scenarios`] — the seed papers' trajectories and site layouts
//!   ([`seed_004_trajectory`], [`SEED_004_STATIONS`], [`seed_002_trajectory`],
//!   [`SEED_002_ANCHORS`], …), with every choice the papers leave open documented.
//! - [`sensors`] — [`TdoaSimulator`] (Gaussian + NLOS uniform timing error),
//!   [`OdometrySimulator`] (speed noise, drifting heading), [`AccelerometerSimulator`]
//!   (absolute or proportional noise), [`LogDistanceRadio`] and [`fingerprint_means`].
//! - [`metrics`] — [`ErrorSummary`] (mean, RMSE, std, median, p90, p95, max),
//!   [`euclidean_errors`], [`axis_rmse`], [`empirical_cdf`], [`percentile`], seed 000's
//!   per-axis error rate and PEL, run-averaged NEES/NIS.
//! - [`pcrb`] — the posterior Cramér–Rao bound (Tichavský's recursion, covariance form).
//! - [`montecarlo`] — seeded parallel Monte Carlo whose results do not depend on the thread count.
//! - [`validate`] — the input checks behind every [`SimError::InvalidParameter`] and
//!   [`SimError::NonFinite`], shared with rtls-papers.
//! - [`mine`] — seed 000's mine at scale (307 readers, 600 miners, a roof fall) as a live,
//!   endless feed of RSSI scans for `rtls serve --demo`, with the site file the tracker needs.
//!
//! ## Example: seed 004 truth, TDOA and odometry
//! ```
//! use rand::SeedableRng;
//! use rtls_sim::{seed_004_trajectory, OdometrySimulator, TdoaSimulator, SEED_004_SPEED_MPS};
//!
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2004);
//! let truth = seed_004_trajectory(SEED_004_SPEED_MPS)?.sample(1.0)?;
//! assert_eq!(truth.len(), 1501);
//! let tdoa = TdoaSimulator::seed_004();
//! let mut odometry = OdometrySimulator::default().start_run(&mut rng)?;
//! for (k, sample) in truth.iter().enumerate() {
//!     // cyclic master station: the reference rotates every epoch
//!     let z = tdoa.measure(sample.position_m, k % 4, &mut rng)?;
//!     let reading = odometry.measure(sample, &mut rng)?;
//!     assert_eq!(z.len(), 3);
//!     assert!(reading.heading_rad.abs() <= std::f64::consts::PI);
//! }
//! # Ok::<(), rtls_sim::SimError>(())
//! ```

mod error;
pub mod metrics;
pub mod mine;
pub mod montecarlo;
pub mod pcrb;
pub mod scenarios;
pub mod sensors;
pub mod trajectory;

/// Input checks shared by the simulators and the paper experiments (crate rtls-papers): each
/// returns its input, or the [`SimError`] that names the parameter and what is allowed.
pub mod validate {
    pub use crate::error::{finite, finite2, non_negative, positive};
}

pub use error::{Result, SimError};
pub use metrics::{axis_rmse, empirical_cdf, euclidean_errors, percentile, ErrorSummary};
pub use scenarios::{
    seed_002_acceleration_profile, seed_002_manoeuvre_then_cruise, seed_002_reference_points,
    seed_002_step_acceleration, seed_002_trajectory, seed_004_phase_at, seed_004_phases, seed_004_trajectory, GridSite,
    MotionPhase, SEED_002_ANCHORS, SEED_002_AREA_SIDE_M, SEED_002_MANOEUVRE_END_S, SEED_002_MANOEUVRE_SAMPLES,
    SEED_002_SAMPLES, SEED_002_START_M, SEED_004_DURATION_S, SEED_004_SPEED_MPS, SEED_004_START_M, SEED_004_STATIONS,
    SEED_004_TURN_RATE_RAD_S,
};
pub use sensors::{
    fingerprint_means, AccelerometerNoise, AccelerometerReading, AccelerometerSimulator, LogDistanceRadio,
    OdometryReading, OdometryRun, OdometrySimulator, TdoaSimulator, SEED_004_HEADING_DRIFT_RAD_PER_S,
    SEED_004_HEADING_NOISE_STD_RAD, SPEED_OF_LIGHT_MPS,
};
pub use trajectory::{Trajectory, TrajectoryBuilder, TruthSample, MIN_MOVING_SPEED_MPS};
