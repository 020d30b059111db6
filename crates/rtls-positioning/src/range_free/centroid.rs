//! Centroid and weighted-centroid localisation: the tag is placed at the (weighted) mean of the
//! anchors that hear it. Seed 000 names centroid among its range-free baselines.

use nalgebra::{SMatrix, SVector};

use crate::error::{PositioningError, Result};
use crate::fix::Fix;

/// The table name of anchor positions in [`PositioningError::NonFiniteEntry`].
const ANCHOR_TABLE: &str = "anchor positions (row = anchor, column = axis)";

/// Centroid localisation: the mean of the positions of the `N` anchors that hear the tag,
/// in the plane (`D = 2`) or in space (`D = 3`).
///
/// ```text
/// p = (1/N) Σ a_i
/// C = (1/N) Σ (a_i − p)(a_i − p)ᵀ            the anchors' spread
/// P = C / N                                    reported covariance
/// ```
///
/// **What the covariance means.** `P` is the covariance of the mean of `N` points drawn from
/// a distribution with the anchors' spread `C`: a geometric statement of how much the
/// anchors disagree, shrinking as more anchors hear the tag. It is **not calibrated**: the
/// centroid's real error is mostly a bias set by where the tag sits relative to the anchors
/// and by the radio range (a tag heard by one anchor gets `P = 0`, a tag at the edge of the
/// site is pulled inwards), not a random error that averages out. Before feeding centroid
/// fixes to a Kalman filter, measure their error at surveyed points with
/// [`crate::calibrate_fix_noise`].
///
/// # Units
/// Anchor positions and the fix in m, covariance in m².
///
/// # Errors
/// [`PositioningError::Underdetermined`] for no anchor;
/// [`PositioningError::NonFiniteEntry`] (row = anchor, column = axis) for a NaN/∞ coordinate;
/// [`PositioningError::NonFinite`] if the result overflows.
///
/// # Example
/// ```
/// use rtls_positioning::range_free::centroid;
/// let heard = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
/// let fix = centroid(&heard)?;
/// assert_eq!(fix.position, nalgebra::Vector2::new(5.0, 5.0));
/// assert_eq!(fix.covariance[(0, 0)], 25.0 / 4.0); // spread 25 m² over 4 anchors
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// N. Bulusu, J. Heidemann, D. Estrin, "GPS-less low-cost outdoor localization for very small
/// devices", *IEEE Personal Communications* 7(5), 2000 (centroid localisation); seed 000
/// (baselines).
pub fn centroid<const D: usize>(anchors_m: &[[f64; D]]) -> Result<Fix<D>> {
    check_anchors(anchors_m)?;
    weighted_fix(anchors_m, &vec![1.0; anchors_m.len()])
}

/// Weighted centroid localisation: `p = Σ w_i a_i / Σ w_i`, with weights from
/// [`rssi_weights`], [`range_weights`] or the caller.
///
/// ```text
/// w̃_i = w_i / max_j w_j                        (scale-free: avoids overflow)
/// p = Σ w̃_i a_i / Σ w̃_i
/// C_w = Σ w̃_i (a_i − p)(a_i − p)ᵀ / Σ w̃_i      weighted spread
/// N_eff = (Σ w̃_i)² / Σ w̃_i²                   effective number of anchors (Kish)
/// P = C_w / N_eff
/// ```
/// With equal weights this is [`centroid`]. The covariance has the same meaning and the same
/// caveat (not calibrated) as there.
///
/// # Units
/// Anchor positions and the fix in m, covariance in m²; weights dimensionless.
///
/// # Errors
/// As [`centroid`]; [`PositioningError::DimensionMismatch`] unless there is one weight per
/// anchor; [`PositioningError::NonFiniteEntry`] (row = anchor) for a NaN/∞ weight;
/// [`PositioningError::InvalidParameter`] (`weights`) for a negative weight or when every
/// weight is zero.
///
/// # Example
/// ```
/// use rtls_positioning::range_free::weighted_centroid;
/// let heard = [[0.0, 0.0], [10.0, 0.0]];
/// let fix = weighted_centroid(&heard, &[3.0, 1.0])?;
/// assert_eq!(fix.position.x, 2.5);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// J. Blumenthal, R. Grossmann, F. Golatowski, D. Timmermann, "Weighted centroid localization
/// in Zigbee-based sensor networks", *IEEE Int. Symp. on Intelligent Signal Processing
/// (WISP)*, 2007, eq. (2) (`P_i = Σ w_ij B_j / Σ w_ij`); L. Kish, *Survey Sampling*, 1965
/// (effective sample size).
pub fn weighted_centroid<const D: usize>(anchors_m: &[[f64; D]], weights: &[f64]) -> Result<Fix<D>> {
    check_anchors(anchors_m)?;
    if weights.len() != anchors_m.len() {
        return Err(PositioningError::DimensionMismatch {
            what: "weights (one per anchor)",
            expected: anchors_m.len(),
            found: weights.len(),
        });
    }
    if let Some(row) = weights.iter().position(|w| !w.is_finite()) {
        return Err(PositioningError::NonFiniteEntry {
            what: "weights (row = anchor)",
            row,
            column: 0,
        });
    }
    if weights.iter().any(|&w| w < 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "weights",
            reason: "centroid weights must be non-negative",
        });
    }
    // w̃_i = w_i / max_j w_j
    let largest = weights.iter().copied().fold(0.0, f64::max);
    if largest <= 0.0 {
        return Err(PositioningError::InvalidParameter {
            name: "weights",
            reason: "every weight is zero (or underflowed to zero): at least one anchor must carry weight",
        });
    }
    let scaled: Vec<f64> = weights.iter().map(|w| w / largest).collect();
    weighted_fix(anchors_m, &scaled)
}

/// Weights from received power: `w_i = 10^(ρ_i / (10 g))`, i.e. the received power in mW to
/// the power `1/g` (`g > 0`, the degree; larger `g` flattens the weights).
///
/// Returned normalised to the strongest anchor, `w_i = 10^((ρ_i − ρ_max) / (10 g))` (the
/// centroid does not depend on a common factor, and the strongest weight is 1, so the weights
/// cannot all underflow).
///
/// Under a log-distance law `ρ = ρ_T − 10 η lg d`, `10^(ρ/(10 g)) ∝ d^(−η/g)`: this is
/// Blumenthal et al.'s `w = 1/d^{g_B}` ([`range_weights`]) with `g_B = η / g`, without
/// inverting the law. With seed 002's `η = 4`, `g = 4` gives `w ∝ 1/d`.
///
/// # Units
/// `rssi_dbm` in dBm; `degree` dimensionless.
///
/// # Errors
/// [`PositioningError::Underdetermined`] for no reading;
/// [`PositioningError::InvalidParameter`] (`degree`) unless `g` is finite and positive;
/// [`PositioningError::NonFiniteEntry`] (row = anchor) for a NaN/∞ reading.
///
/// # Example
/// ```
/// use rtls_positioning::range_free::{rssi_weights, weighted_centroid};
/// let w = rssi_weights(&[-50.0, -60.0, -70.0], 1.0)?;
/// assert_eq!(w[0], 1.0);
/// assert!((w[1] - 0.1).abs() < 1e-15 && (w[2] - 0.01).abs() < 1e-15);
/// let fix = weighted_centroid(&[[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]], &w)?;
/// assert!(fix.position.x < 1.0); // pulled to the strongest anchor
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Blumenthal et al. (2007), eq. (3) (`w_ij = 1/(d_ij)^g`); seed 002 eq. (1) (log-distance law).
pub fn rssi_weights(rssi_dbm: &[f64], degree: f64) -> Result<Vec<f64>> {
    check_degree(degree)?;
    check_readings(rssi_dbm, "rssi_dbm (row = anchor)")?;
    let strongest_dbm = rssi_dbm.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // w_i = 10^((ρ_i − ρ_max) / (10 g))
    Ok(rssi_dbm
        .iter()
        .map(|rho| 10f64.powf((rho - strongest_dbm) / (10.0 * degree)))
        .collect())
}

/// Weights from ranges: `w_i = 1/d_i^g` (`g > 0`, the degree; larger `g` favours the nearest
/// anchors more).
///
/// Returned normalised to the nearest anchor, `w_i = (d_min / d_i)^g`. A zero range means the
/// tag is at that anchor (the limit `g → ∞` of the weights): the anchors at range 0 get
/// weight 1 and all others 0.
///
/// # Units
/// `ranges_m` in m; `degree` dimensionless.
///
/// # Errors
/// [`PositioningError::Underdetermined`] for no range;
/// [`PositioningError::InvalidParameter`] (`degree`) unless `g` is finite and positive,
/// (`ranges_m`) for a negative range (clamp noisy negative ranges to 0 first);
/// [`PositioningError::NonFiniteEntry`] (row = anchor) for a NaN/∞ range.
///
/// # Example
/// ```
/// use rtls_positioning::range_free::range_weights;
/// let w = range_weights(&[2.0, 4.0, 8.0], 1.0)?;
/// assert_eq!(w, vec![1.0, 0.5, 0.25]);
/// assert_eq!(range_weights(&[0.0, 4.0], 2.0)?, vec![1.0, 0.0]);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Blumenthal et al. (2007), eq. (3).
pub fn range_weights(ranges_m: &[f64], degree: f64) -> Result<Vec<f64>> {
    check_degree(degree)?;
    check_readings(ranges_m, "ranges_m (row = anchor)")?;
    if ranges_m.iter().any(|&d| d < 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "ranges_m",
            reason: "ranges must be non-negative; clamp noisy negative ranges to 0 first",
        });
    }
    let nearest_m = ranges_m.iter().copied().fold(f64::INFINITY, f64::min);
    if nearest_m == 0.0 {
        // the tag is at the anchor(s) with zero range
        return Ok(ranges_m.iter().map(|&d| if d == 0.0 { 1.0 } else { 0.0 }).collect());
    }
    // w_i = (d_min / d_i)^g
    Ok(ranges_m.iter().map(|d| (nearest_m / d).powf(degree)).collect())
}

/// [`weighted_centroid`] with [`rssi_weights`]: `w_i = 10^(ρ_i / (10 g))`.
///
/// # Errors
/// Those of [`rssi_weights`] and [`weighted_centroid`] (`DimensionMismatch` unless there is one
/// reading per anchor).
///
/// # Example
/// ```
/// use rtls_positioning::range_free::rssi_weighted_centroid;
/// let fix = rssi_weighted_centroid(&[[0.0, 0.0, 2.0], [10.0, 0.0, 2.0]], &[-40.0, -40.0], 2.0)?;
/// assert_eq!(fix.position, nalgebra::Vector3::new(5.0, 0.0, 2.0));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Blumenthal et al. (2007).
pub fn rssi_weighted_centroid<const D: usize>(anchors_m: &[[f64; D]], rssi_dbm: &[f64], degree: f64) -> Result<Fix<D>> {
    check_anchors(anchors_m)?;
    weighted_centroid(anchors_m, &rssi_weights(rssi_dbm, degree)?)
}

/// [`weighted_centroid`] with [`range_weights`]: `w_i = 1/d_i^g`.
///
/// # Errors
/// Those of [`range_weights`] and [`weighted_centroid`].
///
/// # Example
/// ```
/// use rtls_positioning::range_free::range_weighted_centroid;
/// let fix = range_weighted_centroid(&[[0.0, 0.0], [12.0, 0.0]], &[3.0, 9.0], 1.0)?;
/// assert!((fix.position.x - 3.0).abs() < 1e-12); // weights 1 and 1/3
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Blumenthal et al. (2007).
pub fn range_weighted_centroid<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    degree: f64,
) -> Result<Fix<D>> {
    check_anchors(anchors_m)?;
    weighted_centroid(anchors_m, &range_weights(ranges_m, degree)?)
}

/// `p`, `C_w / N_eff` for validated anchors and non-negative weights with maximum 1.
fn weighted_fix<const D: usize>(anchors_m: &[[f64; D]], weights: &[f64]) -> Result<Fix<D>> {
    let point = |a: &[f64; D]| SVector::<f64, D>::from(*a);
    // W = Σ w_i,  p = Σ w_i a_i / W
    let total: f64 = weights.iter().sum();
    let position = anchors_m
        .iter()
        .zip(weights)
        .fold(SVector::<f64, D>::zeros(), |acc, (a, w)| acc + point(a) * *w)
        / total;
    // C_w = Σ w_i (a_i − p)(a_i − p)ᵀ / W
    let spread = anchors_m
        .iter()
        .zip(weights)
        .fold(SMatrix::<f64, D, D>::zeros(), |acc, (a, w)| {
            let e = point(a) - position;
            acc + e * e.transpose() * *w
        })
        / total;
    // N_eff = W² / Σ w_i²
    let effective = total * total / weights.iter().map(|w| w * w).sum::<f64>();
    Fix {
        position,
        // P = C_w / N_eff
        covariance: spread / effective,
    }
    .checked()
}

/// At least one anchor, all coordinates finite.
fn check_anchors<const D: usize>(anchors_m: &[[f64; D]]) -> Result<()> {
    const { assert!(D > 0, "a centroid needs at least one spatial dimension") };
    if anchors_m.is_empty() {
        return Err(PositioningError::Underdetermined { anchors: 0, needed: 1 });
    }
    for (row, a) in anchors_m.iter().enumerate() {
        if let Some(column) = a.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: ANCHOR_TABLE,
                row,
                column,
            });
        }
    }
    Ok(())
}

/// A finite, positive weighting degree.
fn check_degree(degree: f64) -> Result<()> {
    if degree.is_finite() && degree > 0.0 {
        Ok(())
    } else {
        Err(PositioningError::InvalidParameter {
            name: "degree",
            reason: "the weighting degree must be finite and positive (typically 1–4)",
        })
    }
}

/// At least one reading, all finite.
fn check_readings(values: &[f64], what: &'static str) -> Result<()> {
    if values.is_empty() {
        return Err(PositioningError::Underdetermined { anchors: 0, needed: 1 });
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(row) => Err(PositioningError::NonFiniteEntry { what, row, column: 0 }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

    #[test]
    fn centroid_is_the_mean_and_its_covariance_the_spread_over_n() {
        let anchors = [[0.0, 0.0], [6.0, 0.0], [6.0, 3.0], [0.0, 3.0], [3.0, 9.0]];
        let fix = centroid(&anchors).unwrap();
        assert!((fix.position - Vector2::new(3.0, 3.0)).norm() < 1e-12);
        // C = (1/5) Σ e eᵀ, e = (−3,−3), (3,−3), (3,0), (−3,0), (0,6)
        let spread = Matrix2::new(36.0, 0.0, 0.0, 54.0) / 5.0;
        assert!((fix.covariance - spread / 5.0).amax() < 1e-12);
        // in space
        let cube: Vec<[f64; 3]> = (0..8)
            .map(|k| [f64::from(k & 1), f64::from((k >> 1) & 1), f64::from(k >> 2)])
            .collect();
        let fix = centroid(&cube).unwrap();
        assert!((fix.position - Vector3::repeat(0.5)).norm() < 1e-12);
        assert!((fix.covariance - Matrix3::identity() * (0.25 / 8.0)).amax() < 1e-12);
        // one anchor: the anchor itself, zero covariance (documented: not calibrated)
        let fix = centroid(&[[4.0, -2.0, 1.0]]).unwrap();
        assert_eq!(fix.position, Vector3::new(4.0, -2.0, 1.0));
        assert_eq!(fix.covariance, Matrix3::zeros());
        // far from the origin: no loss of precision in the spread
        let shifted: Vec<[f64; 2]> = anchors.iter().map(|a| [a[0] + 4.0e6, a[1] - 3.0e6]).collect();
        let moved = centroid(&shifted).unwrap();
        assert!((moved.covariance - spread / 5.0).amax() < 1e-6);
    }

    #[test]
    fn weighted_centroid_matches_the_plain_one_for_equal_weights_and_is_scale_free() {
        let anchors = [[0.0, 0.0], [6.0, 0.0], [6.0, 3.0], [0.0, 3.0], [3.0, 9.0]];
        let plain = centroid(&anchors).unwrap();
        for w in [1.0, 1e-300, 7.5, 1e300] {
            let weighted = weighted_centroid(&anchors, &[w; 5]).unwrap();
            assert!((weighted.position - plain.position).norm() < 1e-12);
            assert!((weighted.covariance - plain.covariance).amax() < 1e-12);
        }
        // hand computation: weights (1, 1, 2, 0, 0) → p = (4.5, 1.5)
        let fix = weighted_centroid(&anchors, &[1.0, 1.0, 2.0, 0.0, 0.0]).unwrap();
        assert!((fix.position - Vector2::new(4.5, 1.5)).norm() < 1e-12);
        // C_w = [(1)(20.25, 6.75; 6.75, 2.25) + (1)(2.25, −2.25; −2.25, 2.25) + (2)(2.25, 2.25; 2.25, 2.25)] / 4
        let spread = Matrix2::new(27.0, 9.0, 9.0, 9.0) / 4.0;
        // N_eff = 16 / 6
        assert!((fix.covariance - spread * (6.0 / 16.0)).amax() < 1e-12);
        // all weight on one anchor
        let fix = weighted_centroid(&anchors, &[0.0, 0.0, 0.0, 0.0, 2.0]).unwrap();
        assert_eq!(fix.position, Vector2::new(3.0, 9.0));
        assert_eq!(fix.covariance, Matrix2::zeros());
    }

    #[test]
    fn rssi_and_range_weights_agree_under_a_log_distance_law() {
        // noise-free ρ = −40 − 10 η lg d; with g = η the rssi weights are 1/d (range degree 1)
        let anchors = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0], [10.0, 30.0]];
        let tag = Vector2::new(4.0, 6.0);
        let eta = 3.0;
        let ranges: Vec<f64> = anchors.iter().map(|a| (Vector2::from(*a) - tag).norm()).collect();
        let rssi: Vec<f64> = ranges.iter().map(|d| -40.0 - 10.0 * eta * d.log10()).collect();
        let by_rssi = rssi_weighted_centroid(&anchors, &rssi, eta).unwrap();
        let by_range = range_weighted_centroid(&anchors, &ranges, 1.0).unwrap();
        assert!((by_rssi.position - by_range.position).norm() < 1e-9);
        assert!((by_rssi.covariance - by_range.covariance).amax() < 1e-9);
        // a common rssi offset changes nothing
        let offset: Vec<f64> = rssi.iter().map(|r| r - 37.0).collect();
        let shifted = rssi_weighted_centroid(&anchors, &offset, eta).unwrap();
        assert!((shifted.position - by_rssi.position).norm() < 1e-12);
        // weighting pulls the fix towards the tag, and more so with a higher range degree
        let plain = centroid(&anchors).unwrap();
        let sharper = range_weighted_centroid(&anchors, &ranges, 3.0).unwrap();
        let error = |f: &Fix<2>| (f.position - tag).norm();
        assert!(error(&by_range) < error(&plain));
        assert!(error(&sharper) < error(&by_range));
        // very weak readings do not underflow: the strongest weight is 1
        let w = rssi_weights(&[-3000.0, -7000.0], 1.0).unwrap();
        assert_eq!(w, vec![1.0, 0.0]);
        assert!(weighted_centroid(&anchors[..2], &w).is_ok());
    }

    #[test]
    fn zero_ranges_put_the_tag_at_those_anchors() {
        let anchors = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        let fix = range_weighted_centroid(&anchors, &[5.0, 0.0, 7.0], 2.0).unwrap();
        assert_eq!(fix.position, Vector2::new(10.0, 0.0));
        let fix = range_weighted_centroid(&anchors, &[0.0, 0.0, 7.0], 2.0).unwrap();
        assert_eq!(fix.position, Vector2::new(5.0, 0.0));
    }

    #[test]
    fn error_paths() {
        let empty: [[f64; 2]; 0] = [];
        assert_eq!(
            centroid(&empty),
            Err(PositioningError::Underdetermined { anchors: 0, needed: 1 })
        );
        assert_eq!(
            weighted_centroid(&empty, &[]),
            Err(PositioningError::Underdetermined { anchors: 0, needed: 1 })
        );
        assert!(matches!(
            rssi_weights(&[], 1.0),
            Err(PositioningError::Underdetermined { .. })
        ));
        assert!(matches!(
            range_weights(&[], 1.0),
            Err(PositioningError::Underdetermined { .. })
        ));
        let anchors = [[0.0, 0.0, 0.0], [1.0, f64::NAN, 0.0]];
        assert!(matches!(
            centroid(&anchors),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 1, .. })
        ));
        let anchors = [[0.0, 0.0], [10.0, 0.0]];
        assert!(matches!(
            weighted_centroid(&anchors, &[1.0]),
            Err(PositioningError::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
        assert!(matches!(
            rssi_weighted_centroid(&anchors, &[-40.0, -50.0, -60.0], 1.0),
            Err(PositioningError::DimensionMismatch { .. })
        ));
        assert!(matches!(
            weighted_centroid(&anchors, &[1.0, f64::NAN]),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
        ));
        assert!(matches!(
            weighted_centroid(&anchors, &[f64::INFINITY, 1.0]),
            Err(PositioningError::NonFiniteEntry { row: 0, .. })
        ));
        assert!(matches!(
            weighted_centroid(&anchors, &[1.0, -0.5]),
            Err(PositioningError::InvalidParameter { name: "weights", .. })
        ));
        assert!(matches!(
            weighted_centroid(&anchors, &[0.0, 0.0]),
            Err(PositioningError::InvalidParameter { name: "weights", .. })
        ));
        assert!(matches!(
            rssi_weights(&[-40.0, f64::NAN], 1.0),
            Err(PositioningError::NonFiniteEntry { row: 1, .. })
        ));
        assert!(matches!(
            range_weights(&[3.0, f64::INFINITY], 1.0),
            Err(PositioningError::NonFiniteEntry { row: 1, .. })
        ));
        assert!(matches!(
            range_weights(&[3.0, -0.1], 1.0),
            Err(PositioningError::InvalidParameter { name: "ranges_m", .. })
        ));
        for degree in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                rssi_weights(&[-40.0], degree),
                Err(PositioningError::InvalidParameter { name: "degree", .. })
            ));
            assert!(matches!(
                range_weights(&[4.0], degree),
                Err(PositioningError::InvalidParameter { name: "degree", .. })
            ));
        }
        // coordinates so large that the spread overflows
        assert!(matches!(
            centroid(&[[1e300, 0.0], [-1e300, 0.0]]),
            Err(PositioningError::NonFinite { .. })
        ));
    }
}
