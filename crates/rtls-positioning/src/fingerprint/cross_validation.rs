//! Leave-one-out cross-validation of KNN / WKNN over its own map, and the fix-noise floor
//! calibrated from it so that the reported covariance's 95 % ellipse holds 95 % of the errors.

use nalgebra::{Matrix2, Vector2};

use super::index::FingerprintIndex;
use super::knn::{nearest_weighted, Knn};
use crate::error::{PositioningError, Result};

/// Fewest distinct reference positions for a leave-one-out estimate: with two, leaving one out
/// leaves a single place, and every "fix" is that place.
pub const MIN_DISTINCT_POSITIONS: usize = 3;

/// Fewest located leave-one-out queries from which [`LeaveOneOut::floor_variance_m2`] fits a
/// floor (with three, the 95 % quantile is the largest of them: conservative, not a fit).
pub const MIN_LOCATED: usize = 3;

/// One reference point located by the rest of the map.
///
/// # Units
/// `error_m` in m, `spread_m2` in m².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaveOneOutSample {
    /// The reference point used as the query.
    pub reference_point: usize,
    /// `e = x̂ − P_l`: the fix from the rest of the map minus the point's surveyed position.
    pub error_m: Vector2<f64>,
    /// The fix's neighbour spread `C = Σ w (P_j − x̂)(P_j − x̂)ᵀ` ([`super::FingerprintFix`]).
    pub spread_m2: Matrix2<f64>,
}

/// The leave-one-out errors of a matcher over its own map ([`Knn::leave_one_out`]) and the
/// fix-noise floor they call for.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, Knn, SignalSpace};
/// // a 5 × 5 grid, 4 m apart, two anchors at opposite corners; ρ = −40 lg d
/// let anchors = vec![[0.0, 0.0], [16.0, 16.0]];
/// let points: Vec<[f64; 2]> = (0..25).map(|k| [4.0 * (k % 5) as f64, 4.0 * (k / 5) as f64]).collect();
/// let rssi = points
///     .iter()
///     .map(|p| anchors.iter().map(|a: &[f64; 2]| -40.0 * (p[0] - a[0]).hypot(p[1] - a[1]).max(1.0).log10()).collect())
///     .collect();
/// let index = FingerprintIndex::new(FingerprintDatabase::new(points, anchors, rssi)?, SignalSpace::default())?;
/// let loo = Knn::wknn(3).leave_one_out(&index, 1000)?;
/// assert_eq!(loo.samples().len(), 25);
/// let floor = loo.floor_variance_m2(0.95)?.expect("25 located points");
/// // 95 % of the leave-one-out errors lie inside their 95 % ellipse
/// assert!(loo.inside_share(floor, 0.95)? >= 0.95);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct LeaveOneOut {
    samples: Vec<LeaveOneOutSample>,
    queried: usize,
}

impl Knn {
    /// Locates reference points of `index` with the rest of the map: for each queried point
    /// `l`, its own represented fingerprint is the query and the candidates are the reference
    /// points **at another place** — every row at the same position, floor and building as `l`
    /// is left out with it, so that repeated scans of one spot (UJIIndoorLoc has ~20 per spot)
    /// cannot match each other and hide the map's real resolution.
    ///
    /// At most `max_queries` points are queried: all of them when the map is no larger, else
    /// the evenly strided subsample `l_i = ⌊i n / max_queries⌋`, `i = 0 … max_queries − 1`
    /// (deterministic). Each query is compared with the rows that hear one of its anchors (the
    /// only ones KNN could choose), found through a per-anchor list of rows: the work is at
    /// most `max_queries · n` signal-space distances, much less on a multi-building map.
    ///
    /// A map with fewer than [`MIN_DISTINCT_POSITIONS`] distinct positions gives no samples;
    /// a query that shares no heard anchor with the rest of the map, or whose fix overflows,
    /// is skipped (counted in [`LeaveOneOut::queried`] but not in the samples).
    ///
    /// Leave-one-out errors estimate the error of a scan taken **at a surveyed point**, with
    /// that point's neighbourhood one reference point sparser and with the map's own
    /// fingerprints (averages, one device) as queries. The first makes them pessimistic, the
    /// second optimistic against live scans from other devices months later.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`neighbours`, `power`, `max_queries` = 0).
    ///
    /// # Example
    /// See [`LeaveOneOut`].
    ///
    /// # References
    /// T. Hastie, R. Tibshirani, J. Friedman, *The Elements of Statistical Learning*, 2nd ed.,
    /// §7.10 (cross-validation); Torres-Sospedra et al., "UJIIndoorLoc", IPIN 2014 (repeated
    /// scans per reference location).
    pub fn leave_one_out(&self, index: &FingerprintIndex, max_queries: usize) -> Result<LeaveOneOut> {
        self.validate()?;
        if max_queries == 0 {
            return Err(PositioningError::InvalidParameter {
                name: "max_queries",
                reason: "at least one reference point must be queried",
            });
        }
        let database = index.database();
        let n = database.reference_point_count();
        let (place, distinct_positions) = places(index);
        if distinct_positions < MIN_DISTINCT_POSITIONS {
            return Ok(LeaveOneOut {
                samples: Vec::new(),
                queried: 0,
            });
        }
        // the rows that hear each anchor: only they can share an anchor with a query (the
        // others are no candidates of KNN), so a multi-building map is not scanned whole
        let mut hearing: Vec<Vec<usize>> = vec![Vec::new(); database.anchor_count()];
        for l in 0..n {
            for &(anchor, _) in index.represented_row(l) {
                hearing[anchor as usize].push(l);
            }
        }
        let queries = n.min(max_queries);
        let mut samples = Vec::with_capacity(queries);
        let mut seen = vec![usize::MAX; n];
        let mut candidates = Vec::new();
        for i in 0..queries {
            // l_i = ⌊i n / m⌋ (every point when m ≥ n)
            let l = i * n / queries;
            let query = index.represented_row(l);
            // rows at another place that hear one of the query's anchors
            candidates.clear();
            for &(anchor, _) in query {
                for &j in &hearing[anchor as usize] {
                    if seen[j] != i && place[j] != place[l] {
                        seen[j] = i;
                        candidates.push(j);
                    }
                }
            }
            match nearest_weighted(index, candidates.iter().copied(), query, self) {
                Ok(found) => {
                    let p = database.reference_points_m()[l];
                    samples.push(LeaveOneOutSample {
                        reference_point: l,
                        // e = x̂ − P_l
                        error_m: found.fix.position - Vector2::new(p[0], p[1]),
                        spread_m2: found.fix.covariance,
                    });
                }
                // no anchor shared with the rest of the map, or a fix beyond f64 (coordinates
                // near 1e308 m): no error to learn from
                Err(
                    PositioningError::NoFingerprintMatch
                    | PositioningError::NoCandidates
                    | PositioningError::NonFinite { .. },
                ) => {}
                Err(other) => return Err(other),
            }
        }
        Ok(LeaveOneOut {
            samples,
            queried: queries,
        })
    }
}

impl LeaveOneOut {
    /// The located queries, in reference-point order.
    #[must_use]
    pub fn samples(&self) -> &[LeaveOneOutSample] {
        &self.samples
    }

    /// Reference points queried (located or not).
    #[must_use]
    pub fn queried(&self) -> usize {
        self.queried
    }

    /// `√(Σ |e_l|² / S)` over the located queries (m); `None` without any.
    ///
    /// # Errors
    /// [`PositioningError::NonFinite`] if the sum overflows (errors beyond ~1e154 m).
    pub fn rmse_m(&self) -> Result<Option<f64>> {
        if self.samples.is_empty() {
            return Ok(None);
        }
        let total: f64 = self.samples.iter().map(|s| s.error_m.norm_squared()).sum();
        // RMSE = √(Σ |e|² / S)
        finite((total / self.samples.len() as f64).sqrt(), "leave-one-out rmse").map(Some)
    }

    /// The variance floor `σ_f²` (m²) to add to every fix's spread, `P_l = C_l + σ_f² I`, so
    /// that a share `probability` of the leave-one-out errors lies inside its own
    /// `probability` ellipse: `e_lᵀ P_l⁻¹ e_l ≤ γ` with `γ = χ²₂(p) = −2 ln(1 − p)` (5.99 for
    /// 95 %).
    ///
    /// Each error enters its ellipse at the smallest `s_l ≥ 0` with
    /// `e_lᵀ (C_l + s_l I)⁻¹ e_l ≤ γ` (the left side decreases in `s`). By
    /// `(C + sI)⁻¹ = (adj C + sI) / (det C + s tr C + s²)` that is the larger root of
    /// `γ s² + (γ tr C − |e|²) s + (γ det C − eᵀ adj(C) e) = 0`, or 0 when it is negative
    /// (for `C = 0`: `s_l = |e_l|² / γ`). Then `σ_f² = s_(⌈pS⌉)`, the `⌈pS⌉`-th smallest of
    /// the `S` values, and exactly the errors with `s_l ≤ σ_f²` are inside.
    ///
    /// Why a coverage fit and not mean NEES = 2: fingerprint errors are heavy-tailed (a
    /// symmetric corridor, a wrong floor's neighbours), and the mean of `eᵀP⁻¹e` is set by
    /// its few largest terms; matching it would widen every ellipse to pay for them. The
    /// quantile fit is what the 95 % ellipse promises, ignores the last 5 % (the tracker's
    /// gate handles those), and equals the mean-NEES fit when the errors are Gaussian.
    ///
    /// `None` with fewer than [`MIN_LOCATED`] located queries.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`probability`) unless `0 < p < 1`;
    /// [`PositioningError::NonFinite`] if the quadratic overflows (errors or spreads beyond
    /// ~1e100 m).
    ///
    /// # Example
    /// See [`LeaveOneOut`].
    ///
    /// # References
    /// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    /// Navigation*, Wiley 2001, §5.4.2 (NEES, χ² ellipses).
    pub fn floor_variance_m2(&self, probability: f64) -> Result<Option<f64>> {
        let gamma = chi_square_2(probability)?;
        if self.samples.len() < MIN_LOCATED {
            return Ok(None);
        }
        let mut entry: Vec<f64> = self
            .samples
            .iter()
            .map(|s| entry_variance(&s.error_m, &s.spread_m2, gamma))
            .collect();
        entry.sort_unstable_by(f64::total_cmp);
        // σ_f² = s_(⌈pS⌉)
        let rank = (probability * entry.len() as f64).ceil() as usize;
        finite(entry[rank.clamp(1, entry.len()) - 1], "leave-one-out variance floor").map(Some)
    }

    /// Mean NEES `(1/S) Σ e_lᵀ (C_l + σ² I)⁻¹ e_l` with the floor `σ² = floor_variance_m2`
    /// (2 when consistent in 2-D); `None` without samples.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`floor_variance_m2`) unless positive and finite;
    /// [`PositioningError::NonFinite`] if a term overflows.
    pub fn mean_nees(&self, floor_variance_m2: f64) -> Result<Option<f64>> {
        check_floor(floor_variance_m2)?;
        if self.samples.is_empty() {
            return Ok(None);
        }
        let total: f64 = self
            .samples
            .iter()
            .map(|s| nees(&s.error_m, &s.spread_m2, floor_variance_m2))
            .sum();
        finite(total / self.samples.len() as f64, "leave-one-out mean nees").map(Some)
    }

    /// Share of the samples inside their `probability` ellipse with the floor
    /// `σ² = floor_variance_m2`: `e_lᵀ (C_l + σ² I)⁻¹ e_l ≤ −2 ln(1 − p)`; 0 without samples.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`probability`, `floor_variance_m2`);
    /// [`PositioningError::NonFinite`] if a NEES overflows to NaN.
    pub fn inside_share(&self, floor_variance_m2: f64, probability: f64) -> Result<f64> {
        let gamma = chi_square_2(probability)?;
        check_floor(floor_variance_m2)?;
        if self.samples.is_empty() {
            return Ok(0.0);
        }
        let mut inside = 0;
        for s in &self.samples {
            let q = finite(nees(&s.error_m, &s.spread_m2, floor_variance_m2), "leave-one-out nees")?;
            inside += usize::from(q <= gamma);
        }
        Ok(inside as f64 / self.samples.len() as f64)
    }
}

/// `value`, or [`PositioningError::NonFinite`] naming `what`.
fn finite(value: f64, what: &'static str) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PositioningError::NonFinite { what })
    }
}

/// `χ²₂(p) = −2 ln(1 − p)`, the `p` quantile of the χ² distribution with 2 degrees of freedom.
fn chi_square_2(probability: f64) -> Result<f64> {
    if !(probability > 0.0 && probability < 1.0) {
        return Err(PositioningError::InvalidParameter {
            name: "probability",
            reason: "the ellipse probability must lie strictly between 0 and 1",
        });
    }
    // γ = −2 ln(1 − p)
    Ok(-2.0 * (-probability).ln_1p())
}

fn check_floor(floor_variance_m2: f64) -> Result<()> {
    if floor_variance_m2.is_finite() && floor_variance_m2 > 0.0 {
        Ok(())
    } else {
        Err(PositioningError::InvalidParameter {
            name: "floor_variance_m2",
            reason: "the variance floor must be positive and finite (the covariance must be invertible)",
        })
    }
}

/// `eᵀ (C + s I)⁻¹ e` for `s > 0`, as `(eᵀ adj(C) e + s |e|²) / (det C + s tr C + s²)`.
fn nees(e: &Vector2<f64>, c: &Matrix2<f64>, s: f64) -> f64 {
    // eᵀ adj(C) e, adj C = [[c₁₁, −c₀₁], [−c₁₀, c₀₀]]
    let adjugate = e.x * e.x * c[(1, 1)] - e.x * e.y * (c[(0, 1)] + c[(1, 0)]) + e.y * e.y * c[(0, 0)];
    // det(C + sI) = det C + s tr C + s²
    let determinant = c.determinant() + s * c.trace() + s * s;
    (adjugate + s * e.norm_squared()) / determinant
}

/// The smallest `s ≥ 0` with `eᵀ (C + s I)⁻¹ e ≤ γ`: the larger root of
/// `γ s² + (γ tr C − |e|²) s + (γ det C − eᵀ adj(C) e)`, or 0.
fn entry_variance(e: &Vector2<f64>, c: &Matrix2<f64>, gamma: f64) -> f64 {
    let adjugate = e.x * e.x * c[(1, 1)] - e.x * e.y * (c[(0, 1)] + c[(1, 0)]) + e.y * e.y * c[(0, 0)];
    // a s² + b s + c₀ = 0
    let a = gamma;
    let b = gamma * c.trace() - e.norm_squared();
    let c0 = gamma * c.determinant() - adjugate;
    // Δ = b² − 4 a c₀ (negative: the quadratic is positive everywhere, e is always inside)
    let discriminant = b * b - 4.0 * a * c0;
    if discriminant < 0.0 {
        return 0.0;
    }
    // the larger root without cancellation: (−b + √Δ)/(2a) for b ≤ 0, 2c₀/(−b − √Δ) for b > 0
    let root = if b <= 0.0 {
        (-b + discriminant.sqrt()) / (2.0 * a)
    } else {
        2.0 * c0 / (-b - discriminant.sqrt())
    };
    root.max(0.0)
}

/// A place id per reference point (equal for rows at one position, floor and building) and the
/// number of distinct positions.
fn places(index: &FingerprintIndex) -> (Vec<usize>, usize) {
    let database = index.database();
    let points = database.reference_points_m();
    let key = |l: usize| (points[l], database.floor(l), database.building(l));
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_unstable_by(|&i, &j| {
        let (a, b) = (key(i), key(j));
        a.0[0]
            .total_cmp(&b.0[0])
            .then(a.0[1].total_cmp(&b.0[1]))
            .then(a.1.cmp(&b.1))
            .then(a.2.cmp(&b.2))
    });
    let mut place = vec![0; points.len()];
    let (mut id, mut positions) = (0, 0);
    for (rank, &l) in order.iter().enumerate() {
        if rank > 0 {
            let previous = order[rank - 1];
            if key(previous) != key(l) {
                id += 1;
            }
            if points[previous] != points[l] {
                positions += 1;
            }
        } else {
            positions = 1;
        }
        place[l] = id;
    }
    (place, positions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fingerprint::{FingerprintDatabase, SignalSpace, Survey};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// 9 anchors on a 3 × 3 grid over a 30 m × 30 m room; `ρ = −40 − 30 lg(max(d, 1 m))` dBm.
    fn anchors() -> Vec<[f64; 2]> {
        (0..9).map(|k| [15.0 * (k % 3) as f64, 15.0 * (k / 3) as f64]).collect()
    }

    /// One scan at `p`: the path loss plus independent shadowing of `σ` dB per anchor.
    fn scan(p: [f64; 2], shadowing: &Normal<f64>, rng: &mut ChaCha8Rng) -> Vec<f64> {
        anchors()
            .iter()
            .map(|a| -40.0 - 30.0 * (p[0] - a[0]).hypot(p[1] - a[1]).max(1.0).log10() + shadowing.sample(rng))
            .collect()
    }

    /// A dense map: one scan per point of a 1 m grid (961 points), shadowing 4 dB.
    fn dense_map(rng: &mut ChaCha8Rng) -> FingerprintIndex {
        let shadowing = Normal::new(0.0, 4.0).unwrap();
        let points: Vec<[f64; 2]> = (0..961).map(|k| [(k % 31) as f64, (k / 31) as f64]).collect();
        let rssi = points.iter().map(|&p| scan(p, &shadowing, rng)).collect();
        let db = FingerprintDatabase::new(points, anchors(), rssi).unwrap();
        FingerprintIndex::new(db, SignalSpace::default()).unwrap()
    }

    /// `eᵀ (C + s I)⁻¹ e` over independent scans at uniformly random points, and the share
    /// inside the 95 % ellipse.
    fn test_scans(index: &FingerprintIndex, knn: &Knn, s: f64, rng: &mut ChaCha8Rng) -> (f64, f64, f64) {
        let shadowing = Normal::new(0.0, 4.0).unwrap();
        let gamma = chi_square_2(0.95).unwrap();
        let (mut total, mut inside, mut squares) = (0.0, 0_u32, 0.0);
        let count = 400;
        for _ in 0..count {
            let truth = [rng.gen_range(0.0..30.0), rng.gen_range(0.0..30.0)];
            let query: Vec<Option<f64>> = scan(truth, &shadowing, rng).into_iter().map(Some).collect();
            let fix = knn.locate(index, &query).unwrap().fix;
            let e = fix.position - Vector2::new(truth[0], truth[1]);
            let q = nees(&e, &fix.covariance, s);
            total += q;
            inside += u32::from(q <= gamma);
            squares += e.norm_squared();
        }
        let n = f64::from(count);
        (total / n, f64::from(inside) / n, (squares / n).sqrt())
    }

    #[test]
    fn the_calibrated_floor_is_consistent_on_independent_scans_and_the_spacing_floor_is_not() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let index = dense_map(&mut rng);
        let knn = Knn::wknn(3);
        let loo = knn.leave_one_out(&index, 2000).unwrap();
        assert_eq!((loo.queried(), loo.samples().len()), (961, 961));
        let fitted = loo.floor_variance_m2(0.95).unwrap().unwrap();
        // on its own samples: 95 % inside, by construction
        let share = loo.inside_share(fitted, 0.95).unwrap();
        assert!((0.95..0.952).contains(&share), "{share}");
        // independent scans at random points: mean NEES near 2, ~95 % inside
        let (nees, inside, rmse) = test_scans(&index, &knn, fitted, &mut rng);
        assert!(
            (1.3..3.0).contains(&nees),
            "NEES {nees}, σ_f {} m, RMSE {rmse} m",
            fitted.sqrt()
        );
        assert!((0.9..0.99).contains(&inside), "{inside}");
        // the leave-one-out RMSE estimates the live RMSE within 25 %
        let loo_rmse = loo.rmse_m().unwrap().unwrap();
        assert!((loo_rmse / rmse - 1.0).abs() < 0.25, "{loo_rmse} {rmse}");
        // the old floor, s²/12 with s = 1 m: far over (the ellipses are much too small)
        let (old_nees, old_inside, _) = test_scans(&index, &knn, 1.0 / 12.0, &mut rng);
        assert!(old_nees > 10.0 && old_inside < 0.7, "{old_nees} {old_inside}");
    }

    #[test]
    fn rows_at_one_place_leave_together() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let index = dense_map(&mut rng);
        let db = index.database();
        // every row three times: a leaky leave-one-out would match the copies exactly
        let rows: Vec<usize> = (0..db.reference_point_count()).flat_map(|l| [l; 3]).collect();
        let tripled = FingerprintDatabase::from_survey(Survey {
            reference_points_m: rows.iter().map(|&l| db.reference_points_m()[l]).collect(),
            anchor_count: db.anchor_count(),
            anchors_m: Some(db.anchors_m().to_vec()),
            readings_dbm: rows
                .iter()
                .map(|&l| {
                    db.readings_dbm(l)
                        .unwrap()
                        .iter()
                        .map(|&(x, v)| (x as usize, v))
                        .collect()
                })
                .collect(),
            ..Survey::default()
        })
        .unwrap();
        let tripled = FingerprintIndex::new(tripled, SignalSpace::default()).unwrap();
        // k = 1: the nearest other place, whichever copy of it — the same errors as the map
        let once = Knn::wknn(1).leave_one_out(&index, 10_000).unwrap();
        let thrice = Knn::wknn(1).leave_one_out(&tripled, 10_000).unwrap();
        assert_eq!(thrice.samples().len(), 3 * once.samples().len());
        for (i, sample) in thrice.samples().iter().enumerate() {
            assert_eq!(sample.error_m, once.samples()[i / 3].error_m);
        }
        // k = 3: no query finds itself
        let loo = Knn::wknn(3).leave_one_out(&tripled, 10_000).unwrap();
        assert!(loo.samples().iter().all(|s| s.error_m.norm() > 0.0));
        // the same position on another floor is another place, and stays a candidate
        let two_floors = FingerprintDatabase::from_survey(Survey {
            reference_points_m: vec![[0.0, 0.0], [0.0, 0.0], [5.0, 0.0], [10.0, 0.0]],
            floors: Some(vec![0, 1, 0, 0]),
            anchor_count: 1,
            readings_dbm: vec![vec![(0, -50.0)], vec![(0, -51.0)], vec![(0, -70.0)], vec![(0, -90.0)]],
            ..Survey::default()
        })
        .unwrap();
        let two_floors = FingerprintIndex::new(two_floors, SignalSpace::default()).unwrap();
        let loo = Knn::wknn(1).leave_one_out(&two_floors, 10).unwrap();
        assert_eq!(loo.samples()[0].error_m, Vector2::zeros());
    }

    #[test]
    fn subsampling_is_even_and_deterministic() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let index = dense_map(&mut rng);
        let loo = Knn::wknn(3).leave_one_out(&index, 100).unwrap();
        assert_eq!(loo.queried(), 100);
        let queried: Vec<usize> = loo.samples().iter().map(|s| s.reference_point).collect();
        let expected: Vec<usize> = (0..100).map(|i| i * 961 / 100).collect();
        assert_eq!(queried, expected);
        assert_eq!(loo, Knn::wknn(3).leave_one_out(&index, 100).unwrap());
        assert!(matches!(
            Knn::wknn(3).leave_one_out(&index, 0),
            Err(PositioningError::InvalidParameter {
                name: "max_queries",
                ..
            })
        ));
    }

    #[test]
    fn fewer_than_three_positions_give_no_floor() {
        // two positions, many rows each (and a third row on another floor at one of them)
        let db = FingerprintDatabase::from_survey(Survey {
            reference_points_m: vec![[0.0, 0.0], [0.0, 0.0], [4.0, 0.0], [4.0, 0.0], [0.0, 0.0]],
            floors: Some(vec![0, 0, 0, 0, 1]),
            anchor_count: 2,
            readings_dbm: vec![
                vec![(0, -40.0), (1, -70.0)],
                vec![(0, -41.0), (1, -71.0)],
                vec![(0, -70.0), (1, -40.0)],
                vec![(0, -69.0), (1, -41.0)],
                vec![(0, -60.0)],
            ],
            ..Survey::default()
        })
        .unwrap();
        let index = FingerprintIndex::new(db, SignalSpace::default()).unwrap();
        let loo = Knn::wknn(3).leave_one_out(&index, 10).unwrap();
        assert_eq!((loo.queried(), loo.samples().len()), (0, 0));
        assert_eq!(loo.floor_variance_m2(0.95), Ok(None));
        assert_eq!(loo.rmse_m(), Ok(None));
        // one position
        let db = FingerprintDatabase::new(vec![[1.0, 1.0]], vec![[0.0, 0.0]], vec![vec![-50.0]]).unwrap();
        let index = FingerprintIndex::new(db, SignalSpace::default()).unwrap();
        assert!(Knn::wknn(3).leave_one_out(&index, 10).unwrap().samples().is_empty());
    }

    /// `eᵀ (C + sI)⁻¹ e` by nalgebra's inverse.
    fn nees_by_inverse(e: &Vector2<f64>, c: &Matrix2<f64>, s: f64) -> f64 {
        let p = c + Matrix2::identity() * s;
        (e.transpose() * p.try_inverse().unwrap() * e)[(0, 0)]
    }

    #[test]
    fn nees_by_the_adjugate_equals_nees_by_the_inverse() {
        let e = Vector2::new(3.0, -1.5);
        for c in [
            Matrix2::zeros(),
            Matrix2::new(4.0, 1.0, 1.0, 2.0),
            Matrix2::new(9.0, 0.0, 0.0, 0.0),
        ] {
            for s in [0.01, 1.0, 37.0] {
                let (a, b) = (nees(&e, &c, s), nees_by_inverse(&e, &c, s));
                assert!((a - b).abs() <= 1e-12 * b, "{a} {b}");
            }
        }
    }

    #[test]
    fn the_entry_variance_is_where_the_nees_crosses_gamma() {
        let gamma = chi_square_2(0.95).unwrap();
        assert!((gamma - 5.991_464_547_107_979).abs() < 1e-12);
        // C = 0: s = |e|²/γ
        let e = Vector2::new(3.0, 4.0);
        assert!((entry_variance(&e, &Matrix2::zeros(), gamma) - 25.0 / gamma).abs() < 1e-12);
        // inside already: 0
        assert_eq!(
            entry_variance(&Vector2::new(0.1, 0.0), &Matrix2::identity(), gamma),
            0.0
        );
        assert_eq!(entry_variance(&Vector2::zeros(), &Matrix2::zeros(), gamma), 0.0);
        // against bisection on the NEES, for spreads of several shapes (singular too)
        for (e, c) in [
            (Vector2::new(10.0, -2.0), Matrix2::new(4.0, 1.0, 1.0, 2.0)),
            (Vector2::new(0.0, 7.0), Matrix2::new(50.0, 0.0, 0.0, 0.0)),
            (Vector2::new(5.0, 5.0), Matrix2::new(1.0, -0.99, -0.99, 1.0)),
            (Vector2::new(1e-3, 2e-3), Matrix2::new(1e-8, 0.0, 0.0, 1e-8)),
        ] {
            let (mut lo, mut hi) = (0.0_f64, 1e6_f64);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if nees(&e, &c, mid) > gamma {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let s = entry_variance(&e, &c, gamma);
            assert!((s - hi).abs() <= 1e-9 * hi.max(1e-12), "{s} {hi}");
            assert!((nees(&e, &c, s) - gamma).abs() < 1e-9);
        }
    }

    #[test]
    fn probability_and_floor_are_checked() {
        let loo = LeaveOneOut {
            samples: Vec::new(),
            queried: 0,
        };
        for p in [0.0, 1.0, f64::NAN, -0.5] {
            assert!(matches!(
                loo.floor_variance_m2(p),
                Err(PositioningError::InvalidParameter {
                    name: "probability",
                    ..
                })
            ));
        }
        for s in [0.0, -1.0, f64::INFINITY, f64::NAN] {
            assert!(matches!(
                loo.mean_nees(s),
                Err(PositioningError::InvalidParameter {
                    name: "floor_variance_m2",
                    ..
                })
            ));
        }
        assert_eq!(loo.floor_variance_m2(0.95), Ok(None));
        assert_eq!(loo.mean_nees(1.0), Ok(None));
        assert_eq!(loo.rmse_m(), Ok(None));
    }
}
