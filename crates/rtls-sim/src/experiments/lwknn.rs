//! Placeholder until the reproduction lands.

use super::{ReproOptions, ScenarioSource};
use crate::error::{Result, SimError};
use crate::montecarlo::Progress;
use crate::report::ExperimentReport;

/// Progress units of [`reproduce`].
///
/// # Errors
/// Never yet.
pub fn work_units(_sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    Ok(options.runs as u64)
}

/// Runs the reproduction.
///
/// # Errors
/// Always, until implemented.
pub fn reproduce(_sources: &[ScenarioSource], _options: &ReproOptions, _progress: Progress<'_>) -> Result<ExperimentReport> {
    Err(SimError::EmptyInput { what: "implementation" })
}
