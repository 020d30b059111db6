//! Dilution of precision of range (TOA) geometry: GDOP, HDOP and VDOP maps.

use nalgebra::{SMatrix, SVector};

use super::validate::{self, unit_from};
use crate::error::{PositioningError, Result};
use crate::linalg::solve_spd;

/// Dilution of precision of range measurements at one position.
///
/// All three are unitless: the factor by which a range standard deviation `σ` (m) becomes a
/// position standard deviation, `σ_pos = DOP · σ`, for equal, independent range errors.
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use rtls_positioning::multilateration::dilution_of_precision;
/// // a regular octahedron around the point: JᵀJ = 2 I
/// let anchors = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
/// let dop = dilution_of_precision(&anchors, &Vector3::zeros())?;
/// assert!((dop.gdop - 1.5_f64.sqrt()).abs() < 1e-12);
/// assert!((dop.hdop - 1.0).abs() < 1e-12);
/// assert!((dop.vdop.unwrap() - 0.5_f64.sqrt()).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// E. D. Kaplan, C. J. Hegarty, *Understanding GPS/GNSS*, 3rd ed., §11.2 (DOP; without a clock
/// unknown, the GDOP here is GNSS's PDOP).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dop {
    /// Geometric DOP `√tr G`, `G = (UᵀU)⁻¹` (all axes).
    pub gdop: f64,
    /// Horizontal DOP `√(G_xx + G_yy)` (the first two axes; equal to `gdop` in 2-D).
    pub hdop: f64,
    /// Vertical DOP `√(Σ_{k ≥ 2} G_kk)` in 3-D; `None` in 1-D and 2-D.
    pub vdop: Option<f64>,
}

/// Geometric dilution of precision of range measurements from `anchors_m` at `position_m`.
///
/// With the unit line-of-sight vectors `u_i = (p − a_i)/‖p − a_i‖` as the rows of `U`
/// (the range Jacobian), `G = (UᵀU)⁻¹` and `GDOP = √tr G`. For equal independent range errors
/// of standard deviation `σ`, the least-squares position covariance is `σ² G`, so
/// `DRMS = GDOP · σ`. Evaluate it over a grid to draw a GDOP map (see the example).
///
/// Closed forms: `N` anchors evenly spaced on a circle around `p` give `UᵀU = (N/2) I` and
/// `GDOP = √(4/N)`; a regular polyhedron around `p` in 3-D gives `UᵀU = (N/3) I` and
/// `GDOP = √(9/N)`.
///
/// # Units
/// Anchors and position in m; the result is unitless.
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than `D` anchors;
/// - [`PositioningError::NonFiniteEntry`] / [`PositioningError::NonFinite`] for a NaN/∞ anchor
///   or position;
/// - [`PositioningError::DuplicateAnchors`] for two anchors at one position;
/// - [`PositioningError::DegenerateGeometry`] where `UᵀU` is singular (the position on the line
///   through two anchors in 2-D, or at an anchor).
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::gdop;
/// // four anchors around the point: GDOP = √(4/4) = 1
/// let anchors = [[10.0, 0.0], [0.0, 10.0], [-10.0, 0.0], [0.0, -10.0]];
/// assert!((gdop(&anchors, &Vector2::zeros())? - 1.0).abs() < 1e-12);
/// // a coarse GDOP map of a 20 m × 20 m room with anchors in three corners
/// let corners = [[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]];
/// let map: Vec<Vec<Option<f64>>> = (0..5)
///     .map(|i| (0..5).map(|j| gdop(&corners, &Vector2::new(2.5 + 5.0 * i as f64, 2.5 + 5.0 * j as f64)).ok()).collect())
///     .collect();
/// assert!(map.iter().flatten().all(|g| g.is_some_and(|g| g >= (4.0_f64 / 3.0).sqrt())));
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Kaplan & Hegarty, *Understanding GPS/GNSS*, §11.2; N. Levanon, "Lowest GDOP in 2-D
/// scenarios", *IEE Proc. Radar, Sonar Navig.* 147(3), 2000 (`√(4/N)` for `N` anchors evenly
/// around the point).
pub fn gdop<const D: usize>(anchors_m: &[[f64; D]], position_m: &SVector<f64, D>) -> Result<f64> {
    dilution_of_precision(anchors_m, position_m).map(|dop| dop.gdop)
}

/// GDOP, HDOP and (in 3-D) VDOP at `position_m`; see [`gdop`] for the definitions.
///
/// # Errors
/// As [`gdop`].
///
/// # Example
/// ```
/// use nalgebra::Vector3;
/// use rtls_positioning::multilateration::dilution_of_precision;
/// // anchors only on the ceiling (z = 3 m) over a tag at 1 m: height is poorly determined
/// let anchors = [[0.0, 0.0, 3.0], [10.0, 0.0, 3.0], [0.0, 10.0, 3.0], [10.0, 10.0, 3.0]];
/// let dop = dilution_of_precision(&anchors, &Vector3::new(5.0, 5.0, 1.0))?;
/// assert!(dop.vdop.unwrap() > dop.hdop);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Kaplan & Hegarty, *Understanding GPS/GNSS*, §11.2.
pub fn dilution_of_precision<const D: usize>(anchors_m: &[[f64; D]], position_m: &SVector<f64, D>) -> Result<Dop> {
    let scale = validate::anchors(anchors_m, D, false)?;
    validate::finite_point(position_m, "position")?;
    dop_at(anchors_m.iter(), position_m, scale.coincidence_m)
}

/// DOP from the anchors in `anchors_m` at `p` (inputs already validated).
pub(crate) fn dop_at<'a, const D: usize>(
    anchors_m: impl Iterator<Item = &'a [f64; D]>,
    p: &SVector<f64, D>,
    coincidence_m: f64,
) -> Result<Dop> {
    // UᵀU = Σ u_i u_iᵀ
    let mut geometry = SMatrix::<f64, D, D>::zeros();
    for a in anchors_m {
        let (u, _) = unit_from(p, a, coincidence_m)?;
        geometry += u * u.transpose();
    }
    // G = (UᵀU)⁻¹
    let (_, g) = solve_spd(
        &geometry,
        &SVector::zeros(),
        "the line-of-sight matrix UᵀU is singular at this position (on the line through the anchors)",
    )?;
    let diagonal = g.diagonal();
    // GDOP = √tr G,  HDOP = √(G_xx + G_yy),  VDOP = √(Σ_{k≥2} G_kk)
    let gdop = diagonal.sum().sqrt();
    let hdop = diagonal.iter().take(2).sum::<f64>().sqrt();
    let vdop = (D >= 3).then(|| diagonal.iter().skip(2).sum::<f64>().sqrt());
    if gdop.is_finite() && hdop.is_finite() {
        Ok(Dop { gdop, hdop, vdop })
    } else {
        Err(PositioningError::NonFinite {
            what: "dilution of precision",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn gdop_matches_the_closed_forms() {
        // N evenly spaced on a circle (any radius, any phase): GDOP = √(4/N)
        for n in 3..=12 {
            let anchors: Vec<[f64; 2]> = (0..n)
                .map(|k| {
                    let angle = 0.3 + k as f64 * core::f64::consts::TAU / n as f64;
                    [5.0 + 7.0 * angle.cos(), -2.0 + 7.0 * angle.sin()]
                })
                .collect();
            let value = gdop(&anchors, &Vector2::new(5.0, -2.0)).unwrap();
            assert!((value - (4.0 / n as f64).sqrt()).abs() < 1e-12, "n = {n}: {value}");
        }
        // regular tetrahedron (N = 4) and octahedron (N = 6): GDOP = √(9/N)
        let s = 1.0 / 3.0_f64.sqrt();
        let tetrahedron = [[s, s, s], [s, -s, -s], [-s, s, -s], [-s, -s, s]];
        let octahedron = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let scaled = |anchors: &[[f64; 3]]| -> Vec<[f64; 3]> {
            anchors
                .iter()
                .map(|a| [3.0 + 20.0 * a[0], 1.0 + 20.0 * a[1], 2.0 + 20.0 * a[2]])
                .collect()
        };
        let centre = Vector3::new(3.0, 1.0, 2.0);
        let dop = dilution_of_precision(&scaled(&tetrahedron), &centre).unwrap();
        assert!((dop.gdop - 1.5).abs() < 1e-12);
        // G = (3/4) I: HDOP = √1.5, VDOP = √0.75
        assert!((dop.hdop - 1.5_f64.sqrt()).abs() < 1e-12);
        assert!((dop.vdop.unwrap() - 0.75_f64.sqrt()).abs() < 1e-12);
        let value = gdop(&scaled(&octahedron), &centre).unwrap();
        assert!((value - 1.5_f64.sqrt()).abs() < 1e-12);
        // in 2-D hdop = gdop and there is no vdop
        let dop2 = dilution_of_precision(&[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]], &Vector2::zeros()).unwrap();
        assert_eq!(dop2.hdop, dop2.gdop);
        assert_eq!(dop2.vdop, None);
    }

    #[test]
    fn gdop_errors() {
        let anchors = [[0.0, 0.0], [10.0, 0.0]];
        // two anchors: fine off their line, singular on it, undefined at an anchor
        assert!(gdop(&anchors, &Vector2::new(5.0, 5.0)).is_ok());
        assert!(matches!(
            gdop(&anchors, &Vector2::new(20.0, 0.0)),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert!(matches!(
            gdop(&anchors, &Vector2::new(0.0, 0.0)),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert_eq!(
            gdop(&anchors[..1], &Vector2::new(5.0, 5.0)).unwrap_err(),
            PositioningError::Underdetermined { anchors: 1, needed: 2 }
        );
        assert_eq!(
            gdop(&[[0.0, 0.0], [0.0, 0.0]], &Vector2::new(5.0, 5.0)).unwrap_err(),
            PositioningError::DuplicateAnchors { first: 0, second: 1 }
        );
        assert!(matches!(
            gdop(&anchors, &Vector2::new(f64::NAN, 5.0)),
            Err(PositioningError::NonFinite { .. })
        ));
        assert!(matches!(
            gdop(&[[0.0, 0.0], [f64::INFINITY, 0.0]], &Vector2::new(1.0, 5.0)),
            Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
        ));
    }
}
