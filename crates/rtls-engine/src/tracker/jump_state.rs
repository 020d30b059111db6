//! A track's jump hypothesis as a value the track owns (its logic is [`super::jump`]).

use rtls_estimation::Gaussian;

/// The jump hypothesis an in-gate fix last dropped and how many gated-out fixes came back to
/// it since ([`super::jump`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct Alternation<const N: usize> {
    /// The dropped hypothesis (boxed, like the track's own).
    pub(super) departed: Option<Box<JumpHypothesis<N>>>,
    /// Gated-out fixes that fell inside its gate after it was dropped (once the track
    /// switches places, the fixes the place it left took).
    pub(super) returns: u32,
    /// Whether the track reported `alternating`.
    pub(super) reported: bool,
    /// Fixes the track took itself while it held a dropped hypothesis, since the report once
    /// `reported`: with `returns`, the share of the fixes that came from the other place
    /// ([`super::jump::from_departed`]).
    #[serde(default)]
    pub(super) taken: u32,
}

impl<const N: usize> Default for Alternation<N> {
    fn default() -> Self {
        Self {
            departed: None,
            returns: 0,
            reported: false,
            taken: 0,
        }
    }
}

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
