//! Manoeuvring targets: seed 004's variable-dimension Kalman filter (CV ↔ CA) with
//! fading-memory manoeuvre detection, re-filtering from the manoeuvre's onset and a
//! significance test to return to CV. For Markov switching among several models see
//! [`crate::imm`].

mod detector;
mod observation;
mod variable_dimension;

pub use detector::{ManoeuvreDetector, Threshold};
pub use observation::LinearObservation;
pub use variable_dimension::{ModeSwitch, VariableDimensionFilter, VdEstimate, VdMode, VdState, VdStep};
