//! The crate's error type.

/// What can go wrong in the omlox data model and conversions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServerError {
    /// The ingest body is not a JSON array of objects.
    #[error("request body: {reason}")]
    Body {
        /// What is wrong.
        reason: String,
    },
    /// One element of an ingested array has a bad or missing field.
    #[error("[{index}].{field}: {reason}")]
    InvalidField {
        /// 0-based index in the array.
        index: usize,
        /// The field at fault, with nested paths and indices (`position.coordinates[1]`).
        field: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// A value cannot be expressed in omlox terms (e.g. a non-finite time).
    #[error("{field}: {reason}")]
    Unrepresentable {
        /// The field at fault.
        field: String,
        /// Why, and what would fix it.
        reason: String,
    },
}

/// Result with [`ServerError`].
pub type Result<T> = std::result::Result<T, ServerError>;
