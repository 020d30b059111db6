//! The one error type of the positioning crate.

/// Why a position fix could not be computed.
///
/// Every numerical failure is reported through this type: no function of the crate panics on
/// user input or returns a NaN. Messages are lowercase and name the cause and the usual remedy.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PositioningError {
    /// Fewer anchors (stations) than the method needs.
    #[error("underdetermined: {anchors} anchors given, at least {needed} needed; add anchors or use another method")]
    Underdetermined {
        /// Anchors supplied.
        anchors: usize,
        /// Minimum the method needs.
        needed: usize,
    },
    /// The anchor geometry (or the geometry of anchors and fix) does not determine a position.
    #[error("degenerate geometry: {reason}")]
    DegenerateGeometry {
        /// What is degenerate and what to do, e.g. "stations are collinear; …".
        reason: &'static str,
    },
    /// Two anchors share one position, so they add no geometry (and make differenced equations
    /// singular).
    #[error("anchors {first} and {second} are at the same position; remove the duplicate or fix its coordinates")]
    DuplicateAnchors {
        /// Index of the first anchor (0-based).
        first: usize,
        /// Index of the second anchor at the same position.
        second: usize,
    },
    /// An input or a result contains NaN or infinity.
    #[error("{what} contains a non-finite value (nan or infinity); check the input data")]
    NonFinite {
        /// Which quantity, e.g. "range differences" or "position estimate".
        what: &'static str,
    },
    /// One entry of a table (row `row`, column `column`) is NaN or infinity.
    #[error("{what} [row {row}, column {column}] is not finite (nan or infinity); fix or remove that entry")]
    NonFiniteEntry {
        /// Which table, e.g. "fingerprint rssi (row = reference point, column = anchor)".
        what: &'static str,
        /// Row index (0-based).
        row: usize,
        /// Column index (0-based).
        column: usize,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name as in the signature or struct field.
        name: &'static str,
        /// What is wrong and what is allowed.
        reason: &'static str,
    },
    /// Two inputs that must agree in size do not.
    #[error("dimension mismatch in {what}: expected {expected}, found {found}")]
    DimensionMismatch {
        /// What was checked, e.g. "range differences".
        what: &'static str,
        /// Size required.
        expected: usize,
        /// Size supplied.
        found: usize,
    },
    /// One row of a table has the wrong length.
    #[error("{what}: row {row} has {found} values, expected {expected} (one per column)")]
    RowLength {
        /// Which table, e.g. "fingerprint rssi".
        what: &'static str,
        /// Offending row (0-based).
        row: usize,
        /// Required length.
        expected: usize,
        /// Supplied length.
        found: usize,
    },
    /// A covariance that must be symmetric positive definite is not.
    #[error("{what} is not symmetric positive definite (cholesky factorisation failed); check the noise model")]
    NotPositiveDefinite {
        /// Which matrix, e.g. "range-difference covariance".
        what: &'static str,
    },
    /// The measurements admit no position consistent with the model (e.g. hyperbolas that do
    /// not intersect because of noise).
    #[error("no consistent solution: {reason}")]
    NoConsistentSolution {
        /// Why and what to do.
        reason: &'static str,
    },
    /// An iterative solver did not converge within its iteration limit.
    #[error(
        "the iterative solver did not converge in {iterations} iterations; check the geometry and the initial guess"
    )]
    DidNotConverge {
        /// Iterations performed.
        iterations: usize,
    },
    /// A fingerprint query hears no anchor, so it cannot be compared with any reference point.
    #[error(
        "the fingerprint query shares no heard anchor with the database (every value is None); \
         wait for a measurement that hears at least one anchor"
    )]
    NoCommonAnchors,
    /// The local search of L-WKNN found no reference point near the strongest anchors.
    #[error(
        "no reference point lies within radius_m of the strongest anchors; \
         increase radius_m or strongest_anchors, or check the anchor positions"
    )]
    NoCandidates,
    /// A fingerprint database with no reference points or no anchors.
    #[error("the fingerprint database is empty (no reference points or no anchors); survey the site first")]
    EmptyDatabase,
    /// Too few samples for a statistic (e.g. a sample covariance needs two).
    #[error("too few samples: {found} given, at least {needed} needed; measure at more known points")]
    TooFewSamples {
        /// Samples supplied.
        found: usize,
        /// Minimum needed.
        needed: usize,
    },
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, PositioningError>;
