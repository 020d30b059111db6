//! Paper reproductions: the experiments of the seed papers, seeded and end to end (truth,
//! simulated sensors, positioning, filters), returning every estimate so tests, examples and
//! docs compute their figures from the same runs.

pub mod seed_000;
pub mod seed_001;
pub mod seed_003;

pub mod seed_002;
pub mod seed_004;

pub use seed_002::{run_seed_002, Seed002Config, Seed002Run, Seed002Trajectory};
pub use seed_004::{
    fused_observation, run_seed_004, seed_004_recording, EngineEstimate, Seed004Config, Seed004Run, SEED_004_TAG,
};
