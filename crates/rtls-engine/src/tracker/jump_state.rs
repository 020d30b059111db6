//! A track's jump hypothesis as a value the track owns (its logic is [`super::jump`]).

use rtls_estimation::Gaussian;

/// Fixes that left the track's gate and agree with each other under the motion model.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct JumpHypothesis<const N: usize> {
    /// The hypothesis's filtered state (a new track's, updated by its fixes).
    pub(super) state: Gaussian<N>,
    /// Fixes it holds.
    pub(super) fixes: u32,
    /// Time of its first fix, s.
    pub(super) first_s: f64,
}
