//! The seed papers' scenarios: truth trajectories, site layouts and the choices we made where
//! a paper is silent.

pub mod seed_000;
pub mod seed_001;
pub mod seed_003;

mod grid_site;
mod seed_002;
mod seed_004;

pub use grid_site::GridSite;
pub use seed_002::{
    seed_002_acceleration_profile, seed_002_manoeuvre_then_cruise, seed_002_reference_points,
    seed_002_step_acceleration, seed_002_trajectory, SEED_002_ANCHORS, SEED_002_AREA_SIDE_M, SEED_002_MANOEUVRE_END_S,
    SEED_002_MANOEUVRE_SAMPLES, SEED_002_SAMPLES, SEED_002_START_M,
};
pub use seed_004::{
    seed_004_phase_at, seed_004_phases, seed_004_trajectory, MotionPhase, SEED_004_DURATION_S, SEED_004_SPEED_MPS,
    SEED_004_START_M, SEED_004_STATIONS, SEED_004_TURN_RATE_RAD_S,
};
