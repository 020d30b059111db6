//! The paper experiments report the simulation's error type: every failure of an experiment
//! is a bad scenario file or parameter, or a failure of the simulation, positioning or filter
//! step it runs, which [`SimError`] already names (file and field for scenarios, simulation
//! time for filters).

pub use rtls_sim::{Result, SimError};

pub(crate) use rtls_sim::validate::{finite, finite2, non_negative, positive};
