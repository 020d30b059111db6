//! The one error type of the estimation crate.

/// Why an estimation step could not produce a valid result.
///
/// Every numerical failure is reported through this type; no function of the crate returns a
/// NaN or panics on bad input. Messages are lowercase and name the cause and the usual remedy.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EstimationError {
    /// The innovation covariance `S = H P Hᵀ + R` could not be Cholesky-factorised.
    #[error(
        "innovation covariance S = H P Hᵀ + R is not positive definite: check that the measurement \
         noise R is positive definite and the state covariance has not collapsed"
    )]
    InnovationNotPositiveDefinite,
    /// A covariance that must be positive definite could not be Cholesky-factorised.
    #[error(
        "{what} is not positive definite (cholesky factorisation failed): \
         check the initial covariance and the process noise"
    )]
    NotPositiveDefinite {
        /// Which matrix failed, e.g. "state covariance".
        what: &'static str,
    },
    /// A step was asked to go to a time earlier than the state's time.
    #[error(
        "time went backwards: the state is at {state_time_s} s but the step asks for {requested_time_s} s; \
         feed measurements in time order or re-filter from an earlier state"
    )]
    TimeWentBackwards {
        /// Time stamp of the state, in seconds.
        state_time_s: f64,
        /// Requested time, in seconds.
        requested_time_s: f64,
    },
    /// Two objects that must agree in size do not.
    #[error("dimension mismatch in {what}: expected {expected}, found {found}")]
    DimensionMismatch {
        /// What was being checked, e.g. "measurement vector".
        what: &'static str,
        /// Size the model requires.
        expected: usize,
        /// Size that was supplied.
        found: usize,
    },
    /// An input or a result contains NaN or infinity.
    #[error("{what} contains a non-finite value (NaN or infinity)")]
    NonFinite {
        /// Which quantity, e.g. "measurement vector" or "posterior covariance".
        what: &'static str,
    },
    /// A model or filter parameter is outside its valid range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name as in the struct field.
        name: &'static str,
        /// What is wrong with it and what is allowed.
        reason: &'static str,
    },
    /// A measurement function is undefined at the given state (e.g. range Jacobian at the anchor).
    #[error("measurement model `{model}` is undefined at this state: {reason}")]
    SingularMeasurement {
        /// Model name.
        model: &'static str,
        /// Why, e.g. "the state coincides with the anchor".
        reason: &'static str,
    },
    /// A control input was given to a motion model that takes none, or of the wrong size.
    #[error("motion model takes no control input: use a model with a control gain B, or predict without control")]
    NoControlInput,
    /// A sequential update was asked for a measurement whose noise components are correlated.
    #[error(
        "sequential update needs a diagonal measurement noise covariance R; \
         decorrelate the measurement or use the batch update"
    )]
    CorrelatedNoise,
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, EstimationError>;
