//! The interacting multiple model (IMM) estimator across motion models of different state
//! size.
//!
//! - [`StateLayout`] says what each state entry means (position, velocity, acceleration per
//!   axis, turn rate); [`convert`] maps an estimate between layouts explicitly.
//! - [`ImmMode`] is one mode: a layout, a motion model, a measurement model and a KF, EKF or
//!   UKF ([`FilterMode`]), so a 4-state CV KF, a 6-state CA KF and a 5-state coordinated-turn
//!   EKF or UKF mix in one estimator.
//! - [`ModeTransitions`] is the Markov chain; [`InteractingMultipleModel`] runs the cycle and
//!   exposes the mode probabilities.
//!
//! FilterPy's and Stone Soup's IMMs require every mode to share one state vector; here the
//! conversions make different sizes first-class (Granström, Willett, Bar-Shalom 2015).

mod filter;
mod layout;
mod mode;
mod transitions;

pub use filter::{ImmState, ImmUpdate, InteractingMultipleModel};
pub use layout::{convert, Axis, Component, Fill, StateLayout};
pub use mode::{ComponentObservation, FilterMode, ImmMode, ModeEstimate, ModeUpdate};
pub use transitions::ModeTransitions;
