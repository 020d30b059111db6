//! Input validation shared by the multilateration solvers (anchors, ranges, variances), and
//! the geometric primitives they share (unit vectors, coincidence tolerances).
//!
//! Every check returns the typed error the crate documents; nothing here panics.

use nalgebra::{SMatrix, SVector};

use crate::error::{PositioningError, Result};

/// Two points closer than `COINCIDENCE_TOLERANCE × scale` (scale = the larger of the anchors'
/// spread and their largest coordinate magnitude) count as one point.
pub(crate) const COINCIDENCE_TOLERANCE: f64 = 1e-9;

/// Anchors whose thinnest extent is below `MIN_RELATIVE_THICKNESS ×` their widest extent are
/// collinear (2-D) or coplanar (3-D): `λ_min / λ_max < MIN_RELATIVE_THICKNESS²` for the
/// eigenvalues of their scatter matrix.
pub(crate) const MIN_RELATIVE_THICKNESS: f64 = 1e-6;

/// The anchor table's row/column description used in [`PositioningError::NonFiniteEntry`].
pub(crate) const ANCHORS_WHAT: &str = "anchor positions (row = anchor, column = axis)";

/// `[f64; D]` → `SVector<f64, D>`.
#[inline]
pub(crate) fn point<const D: usize>(a: &[f64; D]) -> SVector<f64, D> {
    SVector::from(*a)
}

/// Length scales of a validated anchor set.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AnchorScale {
    /// Largest anchor distance from the anchors' centroid (m): the length scale of relative
    /// step tolerances.
    pub(crate) spread_m: f64,
    /// Distance below which two points coincide (m).
    pub(crate) coincidence_m: f64,
}

/// The reason of [`PositioningError::DegenerateGeometry`] for anchors that do not span `D`
/// dimensions.
pub(crate) const fn flat_reason(dimension: usize) -> &'static str {
    match dimension {
        2 => {
            "the anchors are collinear (or nearly so), so a range fix is mirror-ambiguous across their \
             line; move an anchor off the line, add one, or start from a prior guess"
        }
        3 => {
            "the anchors are coplanar (or nearly so), so a range fix is mirror-ambiguous across their \
             plane; move an anchor off the plane, add one, or start from a prior guess"
        }
        _ => "the anchors do not span the space of the fix; spread them out or add anchors",
    }
}

/// Validates an anchor table: at least `needed` anchors, all finite, no two at one position,
/// and (if `full_rank`) spanning all `D` dimensions.
///
/// # Errors
/// [`PositioningError::InvalidParameter`] (`D`) for `D = 0`;
/// [`PositioningError::Underdetermined`]; [`PositioningError::NonFiniteEntry`] (row = anchor,
/// column = axis); [`PositioningError::DuplicateAnchors`] (the first pair found, in index
/// order); [`PositioningError::DegenerateGeometry`] (collinear / coplanar).
pub(crate) fn anchors<const D: usize>(anchors_m: &[[f64; D]], needed: usize, full_rank: bool) -> Result<AnchorScale> {
    if D == 0 {
        return Err(PositioningError::InvalidParameter {
            name: "D",
            reason: "a fix needs at least one dimension",
        });
    }
    let n = anchors_m.len();
    if n < needed {
        return Err(PositioningError::Underdetermined { anchors: n, needed });
    }
    for (row, a) in anchors_m.iter().enumerate() {
        if let Some(column) = a.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: ANCHORS_WHAT,
                row,
                column,
            });
        }
    }
    if n == 0 {
        return Ok(AnchorScale {
            spread_m: 0.0,
            coincidence_m: 0.0,
        });
    }
    // c = (1/N) Σ a_i
    let centroid = anchors_m
        .iter()
        .fold(SVector::<f64, D>::zeros(), |acc, a| acc + point(a))
        / n as f64;
    // spread = max ‖a_i − c‖,  magnitude = max |a_ik|
    let spread_m = anchors_m
        .iter()
        .map(|a| (point(a) - centroid).norm())
        .fold(0.0, f64::max);
    let magnitude_m = anchors_m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    let coincidence_m = COINCIDENCE_TOLERANCE * spread_m.max(magnitude_m);
    for first in 0..n {
        for second in first + 1..n {
            if (point(&anchors_m[first]) - point(&anchors_m[second])).norm() <= coincidence_m {
                return Err(PositioningError::DuplicateAnchors { first, second });
            }
        }
    }
    if full_rank {
        // S = Σ (a_i − c)(a_i − c)ᵀ
        let scatter = anchors_m.iter().fold(SMatrix::<f64, D, D>::zeros(), |acc, a| {
            let d = point(a) - centroid;
            acc + d * d.transpose()
        });
        // κ_F = ‖S‖_F ‖S⁻¹‖_F ≥ λ_max / λ_min  (rotation invariant, within a factor D of it)
        let degenerate = PositioningError::DegenerateGeometry { reason: flat_reason(D) };
        let inverse = scatter.cholesky().ok_or(degenerate.clone())?.inverse();
        let condition = scatter.norm() * inverse.norm();
        if !(condition.is_finite() && condition * MIN_RELATIVE_THICKNESS * MIN_RELATIVE_THICKNESS <= 1.0) {
            return Err(degenerate);
        }
    }
    Ok(AnchorScale {
        spread_m,
        coincidence_m,
    })
}

/// Validates a per-anchor vector of non-negative values (ranges): length `n`, finite,
/// `≥ 0`.
///
/// # Errors
/// [`PositioningError::DimensionMismatch`], [`PositioningError::NonFiniteEntry`]
/// (row = anchor, column 0), [`PositioningError::InvalidParameter`] (`name`).
pub(crate) fn ranges(ranges_m: &[f64], n: usize, name: &'static str, what: &'static str) -> Result<()> {
    per_anchor(ranges_m, n, what)?;
    if ranges_m.iter().any(|&r| r < 0.0) {
        return Err(PositioningError::InvalidParameter {
            name,
            reason: "ranges must be non-negative",
        });
    }
    Ok(())
}

/// Validates a per-anchor vector of signed ranges: length `n`, finite. Negative values are
/// accepted: a range is a noisy measurement `r = d + e`, and for a tag close to an anchor the
/// error `e` can exceed `d` (Wi-Fi FTM / RTT and UWB with a calibrated bias both report
/// negative ranges there); the least-squares cost handles them as it handles any other value.
///
/// # Errors
/// [`PositioningError::DimensionMismatch`], [`PositioningError::NonFiniteEntry`]
/// (row = anchor, column 0).
pub(crate) fn signed_ranges(ranges_m: &[f64], n: usize, what: &'static str) -> Result<()> {
    per_anchor(ranges_m, n, what)
}

/// Validates a per-anchor vector of variances: length `n`, finite, `> 0`.
///
/// # Errors
/// [`PositioningError::DimensionMismatch`], [`PositioningError::NonFiniteEntry`]
/// (row = anchor, column 0), [`PositioningError::InvalidParameter`] (`name`).
pub(crate) fn variances(variances_m2: &[f64], n: usize, name: &'static str, what: &'static str) -> Result<()> {
    per_anchor(variances_m2, n, what)?;
    if variances_m2.iter().any(|&v| v <= 0.0) {
        return Err(PositioningError::InvalidParameter {
            name,
            reason: "every variance must be strictly positive",
        });
    }
    Ok(())
}

/// Length `n` and finite entries.
fn per_anchor(values: &[f64], n: usize, what: &'static str) -> Result<()> {
    if values.len() != n {
        return Err(PositioningError::DimensionMismatch {
            what,
            expected: n,
            found: values.len(),
        });
    }
    if let Some(row) = values.iter().position(|v| !v.is_finite()) {
        return Err(PositioningError::NonFiniteEntry { what, row, column: 0 });
    }
    Ok(())
}

/// A finite position (initial guess, evaluation point).
///
/// # Errors
/// [`PositioningError::NonFinite`] (`what`).
pub(crate) fn finite_point<const D: usize>(p: &SVector<f64, D>, what: &'static str) -> Result<()> {
    if p.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(PositioningError::NonFinite { what })
    }
}

/// The error of a position at an anchor, where the range Jacobian `(p − a)ᵀ/‖p − a‖` is
/// undefined.
pub(crate) const AT_ANCHOR: PositioningError = PositioningError::DegenerateGeometry {
    reason: "the position coincides with an anchor, where the range jacobian is undefined; \
             start from another guess or drop that anchor's measurement",
};

/// `(u, d)` with `d = ‖p − a‖` and `u = (p − a)/d`, or [`AT_ANCHOR`] when `d ≤ floor_m`.
#[inline]
pub(crate) fn unit_from<const D: usize>(
    p: &SVector<f64, D>,
    a: &[f64; D],
    floor_m: f64,
) -> Result<(SVector<f64, D>, f64)> {
    let offset = p - point(a);
    let distance_m = offset.norm();
    if distance_m > floor_m && distance_m.is_finite() {
        Ok((offset / distance_m, distance_m))
    } else {
        Err(AT_ANCHOR)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchor_checks() {
        let square = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
        let scale = anchors(&square, 3, true).unwrap();
        assert!((scale.spread_m - 50.0_f64.sqrt()).abs() < 1e-12);
        assert_eq!(
            anchors(&square[..2], 3, true).unwrap_err(),
            PositioningError::Underdetermined { anchors: 2, needed: 3 }
        );
        assert!(matches!(
            anchors(&[[0.0, 0.0], [1.0, f64::NAN], [2.0, 5.0]], 3, true),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 1, .. })
        ));
        assert_eq!(
            anchors(&[[0.0, 0.0], [1.0, 1.0], [3.0, 5.0], [1.0, 1.0]], 3, true).unwrap_err(),
            PositioningError::DuplicateAnchors { first: 1, second: 3 }
        );
        // collinear along a diagonal (not axis aligned): rotation-invariant test
        let diagonal = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [5.0, 5.0]];
        assert!(matches!(
            anchors(&diagonal, 3, true),
            Err(PositioningError::DegenerateGeometry { reason }) if reason.contains("collinear")
        ));
        assert!(anchors(&diagonal, 3, false).is_ok());
        // nearly collinear: 1e-8 off a 10 m line
        assert!(anchors(&[[0.0, 0.0], [10.0, 0.0], [5.0, 1e-8]], 3, true).is_err());
        assert!(anchors(&[[0.0, 0.0], [10.0, 0.0], [5.0, 1e-3]], 3, true).is_ok());
        let plane = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0]];
        assert!(matches!(
            anchors(&plane, 4, true),
            Err(PositioningError::DegenerateGeometry { reason }) if reason.contains("coplanar")
        ));
        let empty: [[f64; 0]; 3] = [[], [], []];
        assert!(matches!(
            anchors(&empty, 1, true),
            Err(PositioningError::InvalidParameter { name: "D", .. })
        ));
    }

    #[test]
    fn vector_checks() {
        assert!(ranges(&[1.0, 0.0], 2, "r", "r").is_ok());
        assert!(matches!(
            ranges(&[1.0], 2, "r", "r"),
            Err(PositioningError::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
        assert!(matches!(
            ranges(&[1.0, f64::INFINITY], 2, "r", "r"),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
        ));
        assert!(matches!(
            ranges(&[1.0, -1.0], 2, "r", "r"),
            Err(PositioningError::InvalidParameter { name: "r", .. })
        ));
        assert!(signed_ranges(&[1.0, -1.0], 2, "r").is_ok());
        assert!(signed_ranges(&[1.0, f64::NAN], 2, "r").is_err());
        assert!(matches!(
            variances(&[1.0, 0.0], 2, "v", "v"),
            Err(PositioningError::InvalidParameter { name: "v", .. })
        ));
        let p = SVector::<f64, 2>::new(1.0, 1.0);
        assert_eq!(unit_from(&p, &[1.0, 1.0], 1e-9).unwrap_err(), AT_ANCHOR);
        let (u, d) = unit_from(&p, &[4.0, 5.0], 1e-9).unwrap();
        assert_eq!(d, 5.0);
        assert!((u - SVector::<f64, 2>::new(-0.6, -0.8)).norm() < 1e-15);
    }
}
