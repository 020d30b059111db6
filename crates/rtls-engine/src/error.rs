//! The one error type of the engine crate.

/// Why the engine could not read an input or process a record.
///
/// Messages are lowercase and name the cause and, for text inputs, the file, line and field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EngineError {
    /// A text input (record file, site file) is malformed or inconsistent (the field is the
    /// key path, e.g. `readers[3].position_m`).
    #[error("{file}:{line}: field `{field}`: {reason}")]
    Parse {
        /// File name as given by the caller (e.g. `input.jsonl`).
        file: String,
        /// 1-based line number (0 when the parser cannot tell).
        line: usize,
        /// The offending field (`-` for the record as a whole).
        field: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// A text input could not be read (an I/O error, not its content): the records after
    /// `line` are unknown, so a caller stops rather than skipping them.
    #[error("{file}: read error after line {line}: {reason}")]
    Read {
        /// File name as given by the caller.
        file: String,
        /// The last line read (1-based; 0 before the first).
        line: usize,
        /// The I/O error.
        reason: String,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// What is wrong and what is allowed.
        reason: &'static str,
    },
    /// A tracker's checkpoint ([`crate::tracker::TrackerState`]) does not fit the tracker it
    /// was to be restored into (another layout, or inconsistent content).
    #[error("checkpoint not restored: {0}")]
    Checkpoint(String),
    /// A filter step failed.
    #[error("estimation failed: {0}")]
    Estimation(#[from] rtls_estimation::EstimationError),
    /// A positioning solver was given bad input.
    #[error("positioning failed: {0}")]
    Positioning(#[from] rtls_positioning::PositioningError),
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, EngineError>;
