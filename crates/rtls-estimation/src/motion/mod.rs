//! Motion (transition) models: how a state evolves over a time step `dt`.
//!
//! A model is an immutable strategy. Linear models implement [`LinearMotionModel`] (the
//! transition matrix `F(dt)` and process noise `Q(dt)`); every linear model is automatically a
//! [`MotionModel`], the interface the EKF, UKF and smoothers use, which nonlinear models (the
//! coordinated turn with the rate as a state) implement directly.
//!
//! State layouts (per-axis position/velocity pairs first, as in the papers):
//! - constant velocity, `D` axes: `[x, vx, y, vy, z, vz]` truncated to `N = 2D`;
//! - constant acceleration, `D` axes: `[x, vx, y, vy, …, ax, ay, …]` (`N = 3D`), seed 004's
//!   order, so the CV state is the first `2D` entries of the CA state;
//! - coordinated turn: `[x, vx, y, vy]`, and `[x, vx, y, vy, ω]` with the rate as a state.

use nalgebra::{Const, Dyn, OMatrix};

use crate::gaussian::{Matrix, Vector};

mod constant_acceleration;
mod constant_velocity;
mod coordinated_turn;
mod noise;
mod random_walk;

pub use constant_acceleration::ConstantAcceleration;
pub use constant_velocity::ConstantVelocity;
pub use coordinated_turn::{CoordinatedTurn, CoordinatedTurnWithRate};
pub use noise::{GainTerm, NoiseGain, ProcessNoise};
pub use random_walk::RandomWalk;

/// Control-input gain `B(dt)`: `N` rows, one column per control component.
pub type ControlGain<const N: usize> = OMatrix<f64, Const<N>, Dyn>;

/// A linear motion model `x(t+dt) = F(dt) x(t) + B(dt) u + w`, `w ~ N(0, Q(dt))`.
///
/// # References
/// Seed 000, eq. (16)–(17) (`X⁻ = A X + B U`, `P⁻ = A P Aᵀ + C Q Cᵀ`).
pub trait LinearMotionModel<const N: usize> {
    /// Transition matrix `F(dt)` for a step of `dt_s` seconds.
    fn transition_matrix(&self, dt_s: f64) -> Matrix<N>;
    /// Process noise covariance `Q(dt)` accumulated over a step of `dt_s` seconds.
    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<N>;
    /// Control gain `B(dt)` (`N × p`), or `None` if the model takes no control input.
    fn control_matrix(&self, _dt_s: f64) -> Option<ControlGain<N>> {
        None
    }
}

/// A (possibly nonlinear) motion model `x(t+dt) = f(x(t), dt) + B(dt) u + w`,
/// `w ~ N(0, Q(x, dt))`, with its Jacobian `F = ∂f/∂x`.
pub trait MotionModel<const N: usize> {
    /// Propagated state `f(x, dt)` (without control input or noise).
    fn transition(&self, x: &Vector<N>, dt_s: f64) -> Vector<N>;
    /// Jacobian `F = ∂f/∂x` evaluated at `x`.
    fn transition_jacobian(&self, x: &Vector<N>, dt_s: f64) -> Matrix<N>;
    /// Process noise covariance `Q(x, dt)`.
    fn process_noise(&self, x: &Vector<N>, dt_s: f64) -> Matrix<N>;
    /// Control gain `B(dt)` (`N × p`), or `None` if the model takes no control input.
    fn control_gain(&self, _dt_s: f64) -> Option<ControlGain<N>> {
        None
    }
}

impl<const N: usize, T: LinearMotionModel<N>> MotionModel<N> for T {
    #[inline]
    fn transition(&self, x: &Vector<N>, dt_s: f64) -> Vector<N> {
        // x⁻ = F x
        self.transition_matrix(dt_s) * x
    }
    #[inline]
    fn transition_jacobian(&self, _x: &Vector<N>, dt_s: f64) -> Matrix<N> {
        self.transition_matrix(dt_s)
    }
    #[inline]
    fn process_noise(&self, _x: &Vector<N>, dt_s: f64) -> Matrix<N> {
        self.process_noise_matrix(dt_s)
    }
    #[inline]
    fn control_gain(&self, dt_s: f64) -> Option<ControlGain<N>> {
        self.control_matrix(dt_s)
    }
}
