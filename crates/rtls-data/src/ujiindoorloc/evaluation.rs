//! Scoring a fingerprint method on UJIIndoorLoc's validation set: building and floor hit
//! rates, 2-D error statistics, and the neighbour agreement of two methods.

use rtls_positioning::fingerprint::FingerprintFix;
use rtls_positioning::PositioningError;

use super::Fingerprint;

/// The scores of one fingerprint method on a set of labelled queries.
///
/// Hit rates are over **all** queries (a query the method could not locate counts as a miss);
/// error statistics are over the located queries, in the dataset's EPSG:3857 metres (see the
/// [module docs](super)). Failures are listed, never dropped.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Queries scored.
    pub queries: usize,
    /// Fraction of queries whose voted building is right.
    pub building_hit_rate: f64,
    /// Fraction of queries whose voted building and floor are right.
    pub floor_hit_rate: f64,
    /// Mean 2-D error (m) over the located queries.
    pub mean_error_m: f64,
    /// Median 2-D error (m).
    pub median_error_m: f64,
    /// 75th percentile of the 2-D error (m).
    pub p75_error_m: f64,
    /// 95th percentile of the 2-D error (m).
    pub p95_error_m: f64,
    /// `(query index, error)` of every query the method could not locate.
    pub failures: Vec<(usize, PositioningError)>,
}

/// One method's outcome on every query, in query order.
pub type Outcomes = Vec<Result<FingerprintFix, PositioningError>>;

/// Runs `locate` on every query (once), in order.
///
/// # Example
/// ```
/// use rtls_data::ujiindoorloc::{locate_all, Fingerprint};
/// use rtls_positioning::PositioningError;
/// let q = Fingerprint {
///     readings_dbm: vec![], position_m: [0.0, 0.0], floor: 0, building: 0,
///     space_id: 0, relative_position: 1, user_id: 0, phone_id: 0, timestamp_s: 0,
/// };
/// let outcomes = locate_all(&[q], |_| Err(PositioningError::NoCommonAnchors));
/// assert_eq!(outcomes, vec![Err(PositioningError::NoCommonAnchors)]);
/// ```
pub fn locate_all(
    queries: &[Fingerprint],
    locate: impl Fn(&[Option<f64>]) -> Result<FingerprintFix, PositioningError>,
) -> Outcomes {
    queries.iter().map(|q| locate(&q.query())).collect()
}

/// Scores outcomes ([`locate_all`]) against the queries' labels.
///
/// # Errors
/// A method's error on a query is recorded in [`Evaluation::failures`], not returned; the
/// function fails only if nothing was located (no queries, every query failed, or fewer
/// outcomes than queries): [`PositioningError::TooFewSamples`].
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use rtls_data::ujiindoorloc::{locate_all, score, Fingerprint};
/// use rtls_positioning::{fingerprint::FingerprintFix, Fix2};
/// let q = Fingerprint {
///     readings_dbm: vec![(0, -50.0)], position_m: [3.0, 4.0], floor: 1, building: 0,
///     space_id: 0, relative_position: 1, user_id: 0, phone_id: 0, timestamp_s: 0,
/// };
/// let origin = |_: &[Option<f64>]| Ok(FingerprintFix {
///     fix: Fix2 { position: Vector2::zeros(), covariance: Matrix2::zeros() },
///     neighbours: vec![], building: Some(0), floor: Some(2),
/// });
/// let queries = [q];
/// let e = score(&queries, &locate_all(&queries, origin))?;
/// assert_eq!((e.mean_error_m, e.building_hit_rate, e.floor_hit_rate), (5.0, 1.0, 0.0));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
pub fn score(
    queries: &[Fingerprint],
    outcomes: &[Result<FingerprintFix, PositioningError>],
) -> Result<Evaluation, PositioningError> {
    if outcomes.len() != queries.len() {
        return Err(PositioningError::TooFewSamples {
            found: outcomes.len(),
            needed: queries.len(),
        });
    }
    let mut errors_m = Vec::with_capacity(queries.len());
    let (mut building_hits, mut floor_hits) = (0usize, 0usize);
    let mut failures = Vec::new();
    for (k, (query, outcome)) in queries.iter().zip(outcomes).enumerate() {
        match outcome {
            Ok(result) => {
                let building_hit = result.building == Some(query.building);
                building_hits += usize::from(building_hit);
                floor_hits += usize::from(building_hit && result.floor == Some(query.floor));
                // e = ‖x̂ − x‖
                let dx = result.fix.position.x - query.position_m[0];
                let dy = result.fix.position.y - query.position_m[1];
                errors_m.push(dx.hypot(dy));
            }
            Err(error) => failures.push((k, error.clone())),
        }
    }
    if errors_m.is_empty() {
        return Err(PositioningError::TooFewSamples { found: 0, needed: 1 });
    }
    errors_m.sort_unstable_by(f64::total_cmp);
    let n = queries.len() as f64;
    Ok(Evaluation {
        queries: queries.len(),
        building_hit_rate: building_hits as f64 / n,
        floor_hit_rate: floor_hits as f64 / n,
        mean_error_m: errors_m.iter().sum::<f64>() / errors_m.len() as f64,
        median_error_m: percentile(&errors_m, 0.5),
        p75_error_m: percentile(&errors_m, 0.75),
        p95_error_m: percentile(&errors_m, 0.95),
        failures,
    })
}

/// [`locate_all`] then [`score`].
///
/// # Errors
/// As [`score`].
pub fn evaluate(
    queries: &[Fingerprint],
    locate: impl Fn(&[Option<f64>]) -> Result<FingerprintFix, PositioningError>,
) -> Result<Evaluation, PositioningError> {
    score(queries, &locate_all(queries, locate))
}

/// Fraction of queries on which two methods' outcomes choose the same neighbours (as sets,
/// by reference point); a query on which either fails counts as a disagreement unless both
/// fail with the same error. Outcomes beyond the shorter list count as disagreements.
///
/// # Example
/// ```
/// use rtls_data::ujiindoorloc::neighbour_agreement;
/// use rtls_positioning::PositioningError;
/// let failed = vec![Err(PositioningError::NoCommonAnchors)];
/// assert_eq!(neighbour_agreement(&failed, &failed), 1.0);
/// ```
#[must_use]
pub fn neighbour_agreement(
    first: &[Result<FingerprintFix, PositioningError>],
    second: &[Result<FingerprintFix, PositioningError>],
) -> f64 {
    let chosen = |result: &FingerprintFix| {
        let mut set: Vec<usize> = result.neighbours.iter().map(|n| n.reference_point).collect();
        set.sort_unstable();
        set
    };
    let same = first
        .iter()
        .zip(second)
        .filter(|(a, b)| match (a, b) {
            (Ok(a), Ok(b)) => chosen(a) == chosen(b),
            (Err(a), Err(b)) => a == b,
            _ => false,
        })
        .count();
    same as f64 / first.len().max(second.len()).max(1) as f64
}

/// Nearest-rank percentile of sorted values (`p` in [0, 1]).
fn percentile(sorted: &[f64], p: f64) -> f64 {
    let rank = (p * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(percentile(&v, 0.5), 2.0);
        assert_eq!(percentile(&v, 0.75), 3.0);
        assert_eq!(percentile(&v, 0.95), 4.0);
        assert_eq!(percentile(&v, 0.0), 1.0);
    }
}
