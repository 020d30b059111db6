//! Simulated sensors: cellular TDOA and odometry (seed 004), accelerometer and RSSI (seed 002),
//! mine readers with shadowed RSSI, sensitivity and broken readers (seed 000, [`readers`]), UWB
//! TOA with NLOS bias and UWB RSS (seed 001, [`uwb`]), ultrasonic sonar rings (seed 003,
//! [`ultrasonic`]).
//!
//! Every simulator takes its randomness as `rng: &mut impl rand::Rng`, so a seeded generator
//! (e.g. `rand_chacha::ChaCha8Rng::seed_from_u64`) reproduces a run exactly.

pub mod readers;
pub mod ultrasonic;
pub mod uwb;

mod accelerometer;
mod odometry;
mod rssi;
mod tdoa;

pub use accelerometer::{AccelerometerNoise, AccelerometerReading, AccelerometerSimulator};
pub use odometry::{
    OdometryReading, OdometryRun, OdometrySimulator, SEED_004_HEADING_DRIFT_RAD_PER_S, SEED_004_HEADING_NOISE_STD_RAD,
};
pub use rssi::{fingerprint_means, LogDistanceRadio};
pub use tdoa::{TdoaSimulator, SPEED_OF_LIGHT_MPS};
