//! The one error type of the simulation crate.

/// Why a scenario, a simulated sensor or a metric could not be computed.
///
/// Every bad parameter or input is reported through this type; no function of the crate panics
/// on user input or returns a NaN. Messages are lowercase and name the cause and the fix.
///
/// # Example
/// ```
/// use rtls_sim::{SimError, Trajectory};
/// let err = Trajectory::builder([0.0, 0.0], [1.0, 0.0]).constant_velocity(-1.0).build().unwrap_err();
/// assert!(matches!(err, SimError::InvalidParameter { name: "duration_s", .. }));
/// assert!(err.to_string().starts_with("invalid parameter `duration_s`"));
/// ```
///
/// # References
/// STYLE.md, "Errors": one `thiserror` enum per library crate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A parameter is outside its valid range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name as in the function signature or struct field.
        name: &'static str,
        /// What is wrong with it and what is allowed.
        reason: &'static str,
    },
    /// An input contains NaN or infinity.
    #[error("{what} contains a non-finite value (NaN or infinity): pass finite numbers only")]
    NonFinite {
        /// Which input, e.g. "start position".
        what: &'static str,
    },
    /// An input that must hold at least one element is empty.
    #[error("{what} is empty: pass at least one element")]
    EmptyInput {
        /// Which input, e.g. "errors".
        what: &'static str,
    },
    /// Two inputs that must have the same length do not.
    #[error("length mismatch in {what}: expected {expected}, found {found}; pass inputs of equal length")]
    LengthMismatch {
        /// What was being compared, e.g. "estimates vs truth".
        what: &'static str,
        /// Length required.
        expected: usize,
        /// Length supplied.
        found: usize,
    },
    /// A filter step failed (numerical failure or bad input to `rtls-estimation`).
    #[error("estimation failed at t = {time_s} s: {source}")]
    Estimation {
        /// Simulation time of the failing step (s).
        time_s: f64,
        /// The filter's error.
        source: rtls_estimation::EstimationError,
    },
    /// A scenario file could not be read as its experiment's parameters.
    #[error("scenario `{file}`: {reason}")]
    Scenario {
        /// The scenario file's name (e.g. `scenarios/001-cv.toml`).
        file: String,
        /// What is wrong, with line, column and key where the parser knows them.
        reason: String,
    },
    /// A positioning algorithm was given bad input (as opposed to a fix that is simply
    /// unavailable this epoch, which a reproduction counts and coasts through).
    #[error("positioning failed: {0}")]
    Positioning(#[from] rtls_positioning::PositioningError),
}

impl SimError {
    /// Wraps a filter error with the simulation time it happened at.
    pub fn estimation(time_s: f64) -> impl FnOnce(rtls_estimation::EstimationError) -> Self {
        move |source| Self::Estimation { time_s, source }
    }

    /// The simulation's error for an engine error: the engine's libraries used by the
    /// simulators (scheduling layouts, energy ledgers) report bad parameters only, which keep
    /// their name and reason; a positioning error stays one; any other kind is passed on with
    /// its message as a [`SimError::Scenario`] of file `(rtls-engine)`.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::EngineError;
    /// use rtls_sim::SimError;
    /// let e = SimError::from_engine(EngineError::InvalidParameter { name: "cell_side_m", reason: "must be positive" });
    /// assert_eq!(e, SimError::InvalidParameter { name: "cell_side_m", reason: "must be positive" });
    /// ```
    #[must_use]
    pub fn from_engine(error: rtls_engine::EngineError) -> Self {
        use rtls_engine::EngineError;
        match error {
            EngineError::InvalidParameter { name, reason } => Self::InvalidParameter { name, reason },
            EngineError::Positioning(e) => Self::Positioning(e),
            other => Self::Scenario {
                file: "(rtls-engine)".to_string(),
                reason: other.to_string(),
            },
        }
    }
}

/// Result alias of this crate: `Result<T, SimError>`.
///
/// # Example
/// ```
/// fn speed() -> rtls_sim::Result<f64> {
///     Ok(rtls_sim::seed_004_trajectory(10.0)?.state_at(0.0)?.speed_mps())
/// }
/// assert_eq!(speed(), Ok(10.0));
/// ```
///
/// # References
/// STYLE.md, "Errors".
pub type Result<T> = core::result::Result<T, SimError>;

/// Checks that `value` is finite.
pub fn finite(value: f64, what: &'static str) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(SimError::NonFinite { what })
    }
}

/// Checks that both components of `value` are finite.
pub fn finite2(value: [f64; 2], what: &'static str) -> Result<[f64; 2]> {
    finite(value[0], what)?;
    finite(value[1], what)?;
    Ok(value)
}

/// Checks that `value` is finite and strictly positive.
pub fn positive(value: f64, name: &'static str, reason: &'static str) -> Result<f64> {
    finite(value, name)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(SimError::InvalidParameter { name, reason })
    }
}

/// Checks that `value` is finite and not negative.
pub fn non_negative(value: f64, name: &'static str, reason: &'static str) -> Result<f64> {
    finite(value, name)?;
    if value >= 0.0 {
        Ok(value)
    } else {
        Err(SimError::InvalidParameter { name, reason })
    }
}
