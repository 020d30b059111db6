//! Linear least-squares multilateration by reference differencing (closed form, any `D`).

use nalgebra::{SMatrix, SVector};

use super::validate::{self, point};
use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::linalg::solve_spd;

/// Which anchor's equation is subtracted from the others in [`linear_least_squares`].
///
/// The unweighted solution depends on the choice; the weighted one
/// ([`weighted_linear_least_squares`]) does not (any full-rank differencing spans the same
/// equations, and generalised least squares is invariant to that), so there it only affects
/// round-off.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::ReferenceAnchor;
/// assert_eq!(ReferenceAnchor::default(), ReferenceAnchor::NearestRange);
/// ```
///
/// # References
/// K. W. Cheung, H. C. So, W.-K. Ma, Y. T. Chan, "Least squares algorithms for time-of-arrival
/// based mobile location", *IEEE Trans. Signal Processing* 52(4), 2004, §III (reference
/// selection in the linearised TOA equations).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReferenceAnchor {
    /// The anchor with the smallest measured range (the first on ties): the most precise
    /// squared range when errors grow with distance, and the usual choice.
    #[default]
    NearestRange,
    /// A given anchor index.
    Index(usize),
}

/// Linear least-squares position from ranges by reference differencing (unweighted).
///
/// Each range gives `‖p − a_i‖² = r_i²`. Subtracting the reference anchor's equation removes
/// the quadratic term `‖p‖²`; in coordinates centred on the reference (`a'_i = a_i − a_r`,
/// `p' = p − a_r`) the `N − 1` remaining equations are linear:
/// ```text
/// 2 (a_i − a_r)ᵀ p = ‖a_i‖² − ‖a_r‖² − r_i² + r_r²    ⇔    a'_iᵀ p' = b_i = ½ (‖a'_i‖² − r_i² + r_r²)
/// p' = (AᵀA)⁻¹ Aᵀ b,   rows of A: a'_iᵀ (i ≠ r),   p = p' + a_r
/// ```
/// The result is exact on noise-free ranges. Under noise it is not the maximum-likelihood
/// fix (the differenced squared ranges have unequal, correlated errors); use
/// [`weighted_linear_least_squares`] for the proper weighting and a covariance, or
/// [`super::gauss_newton`] for the ML fix.
///
/// # Units
/// Anchors, ranges and the position in m.
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than `D + 1` anchors;
/// - [`PositioningError::DimensionMismatch`] unless there is one range per anchor;
/// - [`PositioningError::NonFiniteEntry`] for a NaN/∞ anchor coordinate (row = anchor, column
///   = axis) or range (row = anchor);
/// - [`PositioningError::InvalidParameter`] for a negative range (`ranges_m`) or a reference
///   index out of range (`reference`);
/// - [`PositioningError::DuplicateAnchors`] for two anchors at one position;
/// - [`PositioningError::DegenerateGeometry`] for collinear (2-D) / coplanar (3-D) anchors.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::{linear_least_squares, ReferenceAnchor};
/// let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
/// // tag at (3, 4): ranges 5, √65, √45, √85
/// let ranges = [5.0, 65.0_f64.sqrt(), 45.0_f64.sqrt(), 85.0_f64.sqrt()];
/// let p = linear_least_squares(&anchors, &ranges, ReferenceAnchor::default())?;
/// assert!((p.x - 3.0).abs() < 1e-12 && (p.y - 4.0).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Cheung, So, Ma & Chan (2004), §III (linear LS from differenced squared ranges);
/// I. Güvenç, C.-C. Chong, "A survey on TOA based wireless localization and NLOS mitigation
/// techniques", *IEEE Commun. Surveys & Tutorials* 11(3), 2009, §III (linear least squares);
/// seed 000 (RSSI trilateration baseline) and seed 003 (multi-point LS baseline).
pub fn linear_least_squares<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    reference: ReferenceAnchor,
) -> Result<SVector<f64, D>> {
    validate::anchors(anchors_m, D + 1, true)?;
    validate::ranges(ranges_m, anchors_m.len(), "ranges_m", "ranges (one per anchor)")?;
    let reference = resolve_reference(reference, ranges_m)?;
    solve(anchors_m, ranges_m, None, reference).map(|(p, _)| p)
}

/// Weighted linear least squares from ranges with known variances: the best linear unbiased
/// fix of the differenced equations, with its first-order covariance.
///
/// With range errors of variance `σ_i²` (m²), the squared ranges have variance
/// `v_i = var(r̃_i²) ≈ 4 r_i² σ_i² + 2 σ_i⁴` (exact for Gaussian errors at the true range,
/// evaluated at the measured one; the `2σ⁴` term keeps a zero range usable). The differenced
/// right-hand sides `b_i = ½ (‖a'_i‖² − r_i² + r_r²)` (see [`linear_least_squares`]) share the
/// reference's error, so
/// ```text
/// C = cov(b) = ¼ (V + v_r 1 1ᵀ),   V = diag(v_i), i ≠ r
/// C⁻¹ = 4 (V⁻¹ − V⁻¹ 1 1ᵀ V⁻¹ / s),   s = 1/v_r + Σ 1/v_i          (Sherman–Morrison)
/// AᵀC⁻¹A = 4 (Σ w_i a'_i a'_iᵀ − g gᵀ/s),   w_i = 1/v_i,  g = Σ w_i a'_i
/// AᵀC⁻¹b = 4 (Σ w_i a'_i b_i − g (Σ w_i b_i)/s)
/// p' = (AᵀC⁻¹A)⁻¹ AᵀC⁻¹b,   P = (AᵀC⁻¹A)⁻¹
/// ```
/// `P` is the first-order covariance of this estimator. It is at least the Cramér–Rao bound
/// `(JᵀWJ)⁻¹` (differencing discards the information in the common term): close to it
/// inside the anchors, well above it outside (seed 003's 4 m × 6 m bed with six nodes and
/// equal variances: trace 7–13 % above the bound inside, 40 % above at 2 m outside, 2.6× at
/// 3 m outside); [`super::gauss_newton`] reaches the bound. The result
/// does not depend on `reference` (up to round-off).
///
/// # Units
/// Anchors, ranges and the position in m; variances and the covariance in m².
///
/// # Errors
/// As [`linear_least_squares`], plus [`PositioningError::DimensionMismatch`] /
/// [`PositioningError::NonFiniteEntry`] for the variances and
/// [`PositioningError::InvalidParameter`] (`variances_m2`) for a variance `≤ 0`.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::{weighted_linear_least_squares, ReferenceAnchor};
/// let anchors = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 3.0]];
/// let truth = [2.0, 3.0, 1.0];
/// let ranges: Vec<f64> = anchors
///     .iter()
///     .map(|a: &[f64; 3]| a.iter().zip(&truth).map(|(a, t)| (a - t).powi(2)).sum::<f64>().sqrt())
///     .collect();
/// let fix = weighted_linear_least_squares(&anchors, &ranges, &[0.01; 4], ReferenceAnchor::default())?;
/// assert!((fix.position - nalgebra::Vector3::from(truth)).norm() < 1e-9);
/// assert!(fix.drms_m() > 0.1); // σ = 0.1 m per range
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Cheung, So, Ma & Chan (2004), §III–IV (weighting the linearised TOA equations by the
/// covariance of the squared-range errors); J. Sherman, W. J. Morrison, "Adjustment of an
/// inverse matrix corresponding to a change in one element of a given matrix", *Ann. Math.
/// Statist.* 21(1), 1950.
pub fn weighted_linear_least_squares<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    variances_m2: &[f64],
    reference: ReferenceAnchor,
) -> Result<Fix<D>> {
    validate::anchors(anchors_m, D + 1, true)?;
    let n = anchors_m.len();
    validate::ranges(ranges_m, n, "ranges_m", "ranges (one per anchor)")?;
    validate::variances(variances_m2, n, "variances_m2", "range variances (one per anchor)")?;
    let reference = resolve_reference(reference, ranges_m)?;
    let (position, covariance) = solve(anchors_m, ranges_m, Some(variances_m2), reference)?;
    let covariance = covariance.ok_or(PositioningError::NonFinite {
        what: "linear least-squares covariance",
    })?;
    Fix { position, covariance }.checked()
}

/// The reference anchor's index.
pub(crate) fn resolve_reference(reference: ReferenceAnchor, ranges_m: &[f64]) -> Result<usize> {
    match reference {
        ReferenceAnchor::NearestRange => Ok(ranges_m
            .iter()
            .enumerate()
            .fold(
                (0, f64::INFINITY),
                |best, (i, &r)| if r < best.1 { (i, r) } else { best },
            )
            .0),
        ReferenceAnchor::Index(i) if i < ranges_m.len() => Ok(i),
        ReferenceAnchor::Index(_) => Err(PositioningError::InvalidParameter {
            name: "reference",
            reason: "the reference index must be below the number of anchors",
        }),
    }
}

/// The (weighted) differenced LS solution on validated inputs: `(p, P)`, `P` only when
/// variances are given.
pub(crate) fn solve<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    variances_m2: Option<&[f64]>,
    reference: usize,
) -> Result<(SVector<f64, D>, Option<SMatrix<f64, D, D>>)> {
    const SINGULAR: &str = "the differenced anchor matrix AᵀA is singular (anchors collinear or coplanar)";
    let a_r = point(&anchors_m[reference]);
    let r_r = ranges_m[reference];
    // v = var(r̃²) ≈ 4 r² σ² + 2 σ⁴
    let squared_variance = |i: usize| {
        variances_m2.map(|v| {
            let (r, s2) = (ranges_m[i], v[i]);
            4.0 * r * r * s2 + 2.0 * s2 * s2
        })
    };
    let others = (0..anchors_m.len()).filter(|&i| i != reference);
    // N = Σ w_i a'_i a'_iᵀ, y = Σ w_i a'_i b_i, g = Σ w_i a'_i, h = Σ w_i b_i, s = Σ w_i (+ 1/v_r)
    let mut normal = SMatrix::<f64, D, D>::zeros();
    let mut rhs = SVector::<f64, D>::zeros();
    let mut g = SVector::<f64, D>::zeros();
    let mut h = 0.0;
    let mut s = squared_variance(reference).map_or(0.0, |v_r| 1.0 / v_r);
    for i in others {
        // a'_i = a_i − a_r
        let a = point(&anchors_m[i]) - a_r;
        // b_i = ½ (‖a'_i‖² − r_i² + r_r²)
        let b = 0.5 * (a.norm_squared() - ranges_m[i] * ranges_m[i] + r_r * r_r);
        // w_i = 1/v_i (1 unweighted)
        let w = squared_variance(i).map_or(1.0, |v| 1.0 / v);
        normal += a * a.transpose() * w;
        rhs += a * (w * b);
        g += a * w;
        h += w * b;
        s += w;
    }
    if variances_m2.is_some() {
        // AᵀC⁻¹A = 4 (Σ w a aᵀ − g gᵀ/s),  AᵀC⁻¹b = 4 (Σ w a b − g h/s)
        normal = (normal - g * g.transpose() / s) * 4.0;
        rhs = (rhs - g * (h / s)) * 4.0;
    }
    // p' = N⁻¹ y
    let (centred, inverse) = solve_spd(&normal, &rhs, SINGULAR)?;
    // p = p' + a_r
    let position = centred + a_r;
    validate::finite_point(&position, "linear least-squares position")?;
    Ok((position, variances_m2.map(|_| (inverse + inverse.transpose()) * 0.5)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    fn ranges_to<const D: usize>(anchors: &[[f64; D]], p: &SVector<f64, D>) -> Vec<f64> {
        anchors.iter().map(|a| (p - point(a)).norm()).collect()
    }

    #[test]
    fn exact_on_noise_free_ranges_for_every_reference() {
        let anchors = [[0.0, 0.0], [30.0, 2.0], [4.0, 25.0], [28.0, 31.0], [-5.0, 12.0]];
        let truth = Vector2::new(12.5, 7.25);
        let r = ranges_to(&anchors, &truth);
        for k in 0..anchors.len() {
            let p = linear_least_squares(&anchors, &r, ReferenceAnchor::Index(k)).unwrap();
            assert!((p - truth).norm() < 1e-10);
            let fix = weighted_linear_least_squares(&anchors, &r, &[0.04; 5], ReferenceAnchor::Index(k)).unwrap();
            assert!((fix.position - truth).norm() < 1e-10);
        }
        let anchors3 = [
            [0.0, 0.0, 0.0],
            [20.0, 0.0, 1.0],
            [0.0, 20.0, 2.0],
            [10.0, 10.0, 6.0],
            [20.0, 20.0, 0.5],
        ];
        let truth3 = Vector3::new(7.0, 11.0, 1.2);
        let r3 = ranges_to(&anchors3, &truth3);
        let p3 = linear_least_squares(&anchors3, &r3, ReferenceAnchor::NearestRange).unwrap();
        assert!((p3 - truth3).norm() < 1e-10);
    }

    #[test]
    fn weighted_solution_does_not_depend_on_the_reference() {
        let anchors = [[0.0, 0.0], [30.0, 2.0], [4.0, 25.0], [28.0, 31.0], [-5.0, 12.0]];
        // ranges with arbitrary errors, unequal variances
        let r = [14.1, 18.3, 18.6, 28.2, 18.0];
        let v = [0.01, 0.04, 0.09, 0.02, 0.25];
        let base = weighted_linear_least_squares(&anchors, &r, &v, ReferenceAnchor::Index(0)).unwrap();
        for k in 1..anchors.len() {
            let other = weighted_linear_least_squares(&anchors, &r, &v, ReferenceAnchor::Index(k)).unwrap();
            assert!((other.position - base.position).norm() < 1e-9, "reference {k}");
            assert!((other.covariance - base.covariance).amax() < 1e-9 * base.covariance.amax());
        }
        // while the unweighted solution does depend on it
        let p0 = linear_least_squares(&anchors, &r, ReferenceAnchor::Index(0)).unwrap();
        let p3 = linear_least_squares(&anchors, &r, ReferenceAnchor::Index(3)).unwrap();
        assert!((p0 - p3).norm() > 1e-3);
    }

    #[test]
    fn weighted_covariance_matches_direct_generalised_least_squares() {
        // build A, b, C explicitly and compare with the Sherman–Morrison form
        let anchors = [[1.0, 2.0], [30.0, 2.0], [4.0, 25.0], [28.0, 31.0]];
        let r = [10.0, 20.0, 15.0, 25.0];
        let v = [0.01, 0.04, 0.09, 0.02];
        let reference = 2;
        let fix = weighted_linear_least_squares(&anchors, &r, &v, ReferenceAnchor::Index(reference)).unwrap();
        let var_sq: Vec<f64> = (0..4).map(|i| 4.0 * r[i] * r[i] * v[i] + 2.0 * v[i] * v[i]).collect();
        let others: Vec<usize> = (0..4).filter(|&i| i != reference).collect();
        let ar = Vector2::from(anchors[reference]);
        let a = nalgebra::DMatrix::from_fn(3, 2, |row, col| anchors[others[row]][col] - ar[col]);
        let b = nalgebra::DVector::from_fn(3, |row, _| {
            let i = others[row];
            0.5 * ((Vector2::from(anchors[i]) - ar).norm_squared() - r[i] * r[i] + r[reference] * r[reference])
        });
        let c = nalgebra::DMatrix::from_fn(3, 3, |i, j| {
            0.25 * (var_sq[reference] + if i == j { var_sq[others[i]] } else { 0.0 })
        });
        let ci = c.try_inverse().unwrap();
        let info = a.transpose() * &ci * &a;
        let cov = info.clone().try_inverse().unwrap();
        let p = &cov * a.transpose() * &ci * b;
        assert!((fix.position - (Vector2::new(p[0], p[1]) + ar)).norm() < 1e-9);
        for i in 0..2 {
            for j in 0..2 {
                assert!((fix.covariance[(i, j)] - cov[(i, j)]).abs() < 1e-9 * cov.amax());
            }
        }
    }

    #[test]
    fn nearest_range_picks_the_first_smallest() {
        assert_eq!(
            resolve_reference(ReferenceAnchor::NearestRange, &[3.0, 1.0, 1.0, 2.0]),
            Ok(1)
        );
        assert_eq!(
            resolve_reference(ReferenceAnchor::Index(3), &[3.0, 1.0, 1.0, 2.0]),
            Ok(3)
        );
        assert!(matches!(
            resolve_reference(ReferenceAnchor::Index(4), &[3.0, 1.0, 1.0, 2.0]),
            Err(PositioningError::InvalidParameter { name: "reference", .. })
        ));
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        let r = [5.0, 5.0, 5.0];
        assert_eq!(
            linear_least_squares(&anchors[..2], &r[..2], ReferenceAnchor::default()).unwrap_err(),
            PositioningError::Underdetermined { anchors: 2, needed: 3 }
        );
        assert!(matches!(
            linear_least_squares(&[[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]], &r, ReferenceAnchor::default()),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert_eq!(
            linear_least_squares(&[[0.0, 0.0], [10.0, 0.0], [0.0, 0.0]], &r, ReferenceAnchor::default()).unwrap_err(),
            PositioningError::DuplicateAnchors { first: 0, second: 2 }
        );
        assert!(matches!(
            linear_least_squares(&anchors, &[5.0, 5.0], ReferenceAnchor::default()),
            Err(PositioningError::DimensionMismatch {
                expected: 3,
                found: 2,
                ..
            })
        ));
        assert!(matches!(
            linear_least_squares(&anchors, &[5.0, f64::NAN, 5.0], ReferenceAnchor::default()),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
        ));
        assert!(matches!(
            linear_least_squares(&anchors, &[5.0, -1.0, 5.0], ReferenceAnchor::default()),
            Err(PositioningError::InvalidParameter { name: "ranges_m", .. })
        ));
        assert!(matches!(
            linear_least_squares(&anchors, &r, ReferenceAnchor::Index(3)),
            Err(PositioningError::InvalidParameter { name: "reference", .. })
        ));
        assert!(matches!(
            weighted_linear_least_squares(&anchors, &r, &[1.0, 0.0, 1.0], ReferenceAnchor::default()),
            Err(PositioningError::InvalidParameter {
                name: "variances_m2",
                ..
            })
        ));
        assert!(matches!(
            weighted_linear_least_squares(&anchors, &r, &[1.0, 1.0], ReferenceAnchor::default()),
            Err(PositioningError::DimensionMismatch {
                expected: 3,
                found: 2,
                ..
            })
        ));
        assert!(matches!(
            weighted_linear_least_squares(&anchors, &r, &[1.0, 1.0, f64::INFINITY], ReferenceAnchor::default()),
            Err(PositioningError::NonFiniteEntry { row: 2, column: 0, .. })
        ));
        assert!(matches!(
            linear_least_squares(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]], &[1.0; 4], ReferenceAnchor::default()),
            Err(PositioningError::DegenerateGeometry { reason }) if reason.contains("coplanar")
        ));
    }
}
