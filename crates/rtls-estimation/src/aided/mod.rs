//! Sensor-aided tracking: on-tag accelerometers (seed 002) and odometry (seed 004).
//!
//! - [`PrintedAccelerometerModel`]: seed 002's first- and second-order dead-reckoning models
//!   with the accumulating `Q(k)`, as printed; [`TextbookAccelerometerModel`]: state
//!   `[x, vx, y, vy]`, the accelerometer as control input, its noise propagated into `Q`.
//! - [`OdometryErrorModel`]: speed + heading with speed error, heading noise and heading drift,
//!   turned into a velocity measurement ([`position_velocity_observation`], seed 004 eq. (9))
//!   or a control input ([`OdometryDeadReckoning`]); [`odometry_velocity`]: one record's
//!   speed and heading with their standard deviations as a positive definite velocity
//!   measurement (standstill included).
//! - [`HeadingModel`]: a heading channel `[ψ, b_g, δ]` driven by a yaw rate, with the gyro's
//!   bias and an odometer heading's offset estimated against heading references.

mod accelerometer;
mod heading;
mod odometry;
mod odometry_covariance;

pub use accelerometer::{
    AccelerometerSample, DeadReckoning, ModelOrder, PositionStep, PrintedAccelerometerModel, TextbookAccelerometerModel,
};
pub use heading::{HeadingModel, HeadingState};
pub use odometry::{
    position_velocity_observation, HeadingBias, HeadingBiasEstimator, OdometryDeadReckoning, OdometryErrorModel,
    OdometryReading,
};
pub use odometry_covariance::{odometry_velocity, ODOMETRY_VELOCITY_FLOOR_MPS};
