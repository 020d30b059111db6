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
    /// A fix far outside the anchors that produced it (a wrong local minimum, a model that
    /// does not fit the site, e.g. anchor heights ignored): refused rather than used.
    #[error(
        "implausible fix: {distance_m:.1} m from the anchors' centroid, beyond the limit of {limit_m:.1} m \
         (a few times the anchors' extent plus the measured reach); the measurements or the anchor \
         coordinates are inconsistent"
    )]
    ImplausibleFix {
        /// Distance of the fix from the anchors' centroid (m).
        distance_m: f64,
        /// The largest plausible distance (m).
        limit_m: f64,
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
    /// A node of a multi-hop network (DV-Hop) reaches too few anchors through the network
    /// graph to be located, or, for an anchor, no other anchor (so its hop size is undefined).
    #[error(
        "network node {node} reaches {anchors} anchors other than itself through the graph, at least {needed} \
         needed; add radio links or anchors near it, or leave the node unlocated"
    )]
    NodeUnderdetermined {
        /// Index of the node in the network (0-based).
        node: usize,
        /// Anchors (other than the node itself) it reaches.
        anchors: usize,
        /// Minimum needed (`D + 1` for an unknown node, 1 for an anchor).
        needed: usize,
    },
    /// A fingerprint reading names an anchor index the survey does not have.
    #[error("fingerprint row {row} has a reading of anchor {anchor}, but the survey has {anchors} anchors (0-based)")]
    AnchorOutOfRange {
        /// Reference point (row, 0-based).
        row: usize,
        /// Anchor index given.
        anchor: usize,
        /// Anchors in the survey.
        anchors: usize,
    },
    /// One fingerprint row lists the same anchor twice.
    #[error("fingerprint row {row} lists anchor {column} twice; merge the readings (e.g. average them) first")]
    DuplicateReading {
        /// Reference point (row, 0-based).
        row: usize,
        /// The repeated anchor (column).
        column: usize,
    },
    /// A heard RSSI reading is weaker than the signal representation's floor.
    #[error(
        "{what} [row {row}, column {column}] = {rssi_dbm} dBm is below the representation floor {floor_dbm} dBm; \
         lower floor_dbm to the receivers' weakest reading"
    )]
    RssiBelowFloor {
        /// Which table, e.g. "fingerprint rssi (row = reference point, column = anchor)".
        what: &'static str,
        /// Row (reference point; 0 for a query).
        row: usize,
        /// Column (anchor).
        column: usize,
        /// The reading (dBm).
        rssi_dbm: f64,
        /// The floor (dBm).
        floor_dbm: f64,
    },
    /// No candidate reference point hears any anchor the query hears, so signal space says
    /// nothing about where the query is.
    #[error(
        "no fingerprint match: no candidate reference point hears any of the query's anchors; \
         the receiver is outside the surveyed area or hears only unsurveyed anchors"
    )]
    NoFingerprintMatch,
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, PositioningError>;
