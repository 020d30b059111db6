//! A slant range to an anchor at another height, projected onto the horizontal plane of the
//! tag, with its variance propagated.

use crate::error::{PositioningError, Result};

/// A horizontal range (m) and its variance (m²): the slant range of an anchor `Δz` above (or
/// below) the tag projected onto the tag's plane.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::HorizontalRange;
/// let h = HorizontalRange { range_m: 4.0, variance_m2: 0.0156 };
/// assert!((h.std_m() - 0.1249).abs() < 1e-4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HorizontalRange {
    /// `h = √(r² − Δz²)` (m), 0 when `r ≤ |Δz|`; the slant range itself when `Δz = 0`
    /// (then negative ranges pass through unchanged).
    pub range_m: f64,
    /// `σ_h²` (m²), finite and at least `σ_r²`.
    pub variance_m2: f64,
}

impl HorizontalRange {
    /// `σ_h` (m).
    #[must_use]
    pub fn std_m(&self) -> f64 {
        self.variance_m2.sqrt()
    }
}

/// Projects a slant range `r` (variance `σ_r²`) to an anchor `Δz` above or below the tag onto
/// the tag's horizontal plane, for planar (2-D) multilateration.
///
/// ```text
/// r⁺ = max(r, |Δz|)                       (the true slant range is at least |Δz|)
/// h  = √(r² − Δz²) if r > |Δz|, else 0
/// h_f = √(r⁺ σ_r)                         floor: the spread of h when the true h is 0
/// σ_h = σ_r · max(1, r⁺ / max(h, h_f))    delta method, dh/dr = r/h
/// ```
/// The delta method `σ_h = σ_r r/h` follows from `h² = r² − Δz²`; it diverges as `h → 0`,
/// where the linearisation fails. There `h² ≈ 2 r (r − |Δz|)` is roughly `2 r e` for a range
/// error `e`, so the horizontal range spreads over about `√(r σ_r)`: the floor `h_f` keeps
/// `σ_h` at that honest, finite level (and equal to it for `r ≤ |Δz|`, including negative
/// ranges, which say the tag is close to the anchor's foot). `σ_h ≥ σ_r` always: projecting
/// never adds precision. With `Δz = 0` the range and variance pass through unchanged.
///
/// # Units
/// Ranges and heights in m, variances in m².
///
/// # Errors
/// [`PositioningError::NonFinite`] for a NaN/∞ input;
/// [`PositioningError::InvalidParameter`] (`variance_m2`) for a variance `≤ 0`.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::horizontal_range;
/// // an anchor 3 m above the tag, slant range 5 m, σ_r = 0.1 m: h = 4 m, σ_h = 0.1 · 5/4
/// let h = horizontal_range(5.0, 0.01, 3.0)?;
/// assert!((h.range_m - 4.0).abs() < 1e-12 && (h.std_m() - 0.125).abs() < 1e-12);
/// // a range shorter than the height difference: h = 0 with a finite σ_h = √(r⁺ σ_r)
/// let h = horizontal_range(2.9, 0.01, 3.0)?;
/// assert_eq!(h.range_m, 0.0);
/// assert!((h.std_m() - (3.0_f64 * 0.1).sqrt()).abs() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// G. W. Oehlert, "A note on the delta method", *The American Statistician* 46(1), 1992
/// (first-order propagation `σ_h = |dh/dr| σ_r` and where it fails).
pub fn horizontal_range(range_m: f64, variance_m2: f64, height_difference_m: f64) -> Result<HorizontalRange> {
    if !(range_m.is_finite() && variance_m2.is_finite() && height_difference_m.is_finite()) {
        return Err(PositioningError::NonFinite {
            what: "slant range, its variance or the height difference",
        });
    }
    if variance_m2 <= 0.0 {
        return Err(PositioningError::InvalidParameter {
            name: "variance_m2",
            reason: "the range variance must be strictly positive",
        });
    }
    let dz = height_difference_m.abs();
    if dz == 0.0 {
        return Ok(HorizontalRange { range_m, variance_m2 });
    }
    let sigma_r = variance_m2.sqrt();
    // r⁺ = max(r, |Δz|)
    let slant = range_m.max(dz);
    // h = √(r² − Δz²) for r > |Δz|, else 0
    let horizontal = if range_m > dz {
        ((range_m - dz) * (range_m + dz)).sqrt()
    } else {
        0.0
    };
    // h_f = √(r⁺ σ_r)
    let floor = (slant * sigma_r).sqrt();
    // σ_h = σ_r · max(1, r⁺ / max(h, h_f))
    let sigma_h = sigma_r * (slant / horizontal.max(floor)).max(1.0);
    let variance = sigma_h * sigma_h;
    if horizontal.is_finite() && variance.is_finite() {
        Ok(HorizontalRange {
            range_m: horizontal,
            variance_m2: variance,
        })
    } else {
        Err(PositioningError::NonFinite {
            what: "horizontal range (inputs too large)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delta_method_away_from_the_foot_and_finite_at_it() {
        // σ_h = σ_r r / h
        let h = horizontal_range(10.0, 0.04, 6.0).unwrap();
        assert!((h.range_m - 8.0).abs() < 1e-12);
        assert!((h.std_m() - 0.2 * 10.0 / 8.0).abs() < 1e-12);
        // exactly at the height difference, below it, zero and negative: h = 0, σ_h finite
        for r in [6.0, 5.0, 0.0, -0.4] {
            let h = horizontal_range(r, 0.04, 6.0).unwrap();
            assert_eq!(h.range_m, 0.0, "{r}");
            assert!((h.std_m() - (6.0_f64 * 0.2).sqrt()).abs() < 1e-12, "{r}");
        }
        // continuous through the floor: just above |Δz| the floor takes over, no jump to ∞
        let near = horizontal_range(6.0 + 1e-9, 0.04, 6.0).unwrap();
        assert!(near.std_m() <= (6.0_f64 * 0.2).sqrt() + 1e-9);
        // never more precise than the slant range
        let tiny = horizontal_range(0.01, 1.0, 0.005).unwrap();
        assert!(tiny.variance_m2 >= 1.0);
    }

    #[test]
    fn no_height_difference_passes_through_and_errors() {
        assert_eq!(
            horizontal_range(-0.3, 0.01, 0.0).unwrap(),
            HorizontalRange {
                range_m: -0.3,
                variance_m2: 0.01
            }
        );
        assert!(matches!(
            horizontal_range(f64::NAN, 0.01, 1.0),
            Err(PositioningError::NonFinite { .. })
        ));
        assert!(matches!(
            horizontal_range(1.0, 0.0, 1.0),
            Err(PositioningError::InvalidParameter { .. })
        ));
        assert!(matches!(
            horizontal_range(1e300, 1e308, 0.99e300),
            Err(PositioningError::NonFinite { .. })
        ));
    }
}
