//! A range fix that is always made when the geometry allows one: co-located anchors merged,
//! Gauss–Newton / Levenberg–Marquardt from several starts, and a weighted centroid with an
//! honest covariance as the last resort, each outcome named.

use nalgebra::{SMatrix, SVector};

use super::gauss_newton::gauss_newton;
use super::solver::{variance_factor, GaussNewtonFix, GaussNewtonOptions, Initial};
use super::validate::{self, point, COINCIDENCE_TOLERANCE};
use crate::error::{PositioningError, Result};
use crate::fix::Fix;

/// Where the Gauss–Newton iteration of [`multilaterate`] started.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::{FixMethod, Start};
/// assert_eq!(FixMethod::GaussNewton(Start::Centroid).name(), "gauss-newton-from-centroid");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// The caller's guess (a track's prediction).
    Guess,
    /// The weighted linear least-squares fix.
    Linear,
    /// The weighted centroid of the anchors (after the other starts failed).
    Centroid,
}

/// How [`multilaterate`] made its fix: a caller reports anything but the first choice.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::{FixMethod, Start};
/// assert!(!FixMethod::GaussNewton(Start::Linear).is_fallback());
/// assert!(FixMethod::WeightedCentroid.is_fallback());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixMethod {
    /// The maximum-likelihood fix, reached from the named start.
    GaussNewton(Start),
    /// Every Gauss–Newton start failed: the anchors' weighted centroid with the covariance of
    /// a uniform position in the disc (ball) the ranges allow.
    WeightedCentroid,
}

impl FixMethod {
    /// A stable kebab-case name for reports: `gauss-newton` (from the guess or the linear
    /// fix), `gauss-newton-from-centroid`, `weighted-centroid`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::GaussNewton(Start::Guess | Start::Linear) => "gauss-newton",
            Self::GaussNewton(Start::Centroid) => "gauss-newton-from-centroid",
            Self::WeightedCentroid => "weighted-centroid",
        }
    }

    /// `true` unless the fix is Gauss–Newton from the guess or the linear start.
    #[must_use]
    pub const fn is_fallback(self) -> bool {
        !matches!(self, Self::GaussNewton(Start::Guess | Start::Linear))
    }
}

/// The result of [`multilaterate`].
#[derive(Debug, Clone, PartialEq)]
pub struct RangeFix<const D: usize> {
    /// The fix: finite, covariance symmetric positive definite, plausible (see
    /// [`Fix::check_plausible`]).
    pub fix: Fix<D>,
    /// How it was made.
    pub method: FixMethod,
    /// The Gauss–Newton diagnostics over all measurements (χ² including the scatter of
    /// merged co-located anchors); `None` for the centroid fallback.
    pub solution: Option<GaussNewtonFix<D>>,
    /// Why each earlier attempt failed, in order (empty when the first start succeeded).
    pub failures: Vec<PositioningError>,
    /// Distinct anchor positions used (co-located anchors count once).
    pub distinct_anchors: usize,
}

/// A range fix that does not give up while the geometry allows one.
///
/// 1. Anchors at one position (within `1e-9 ×` the anchors' scale; e.g. two anchors on one
///    mast, projected to the plane) are merged: their ranges `r_k` with weights
///    `w_k = 1/σ_k²` become `r̄ = Σ w_k r_k / Σ w_k` with variance `1/Σ w_k`. The
///    least-squares cost is unchanged up to the constant `Σ w_k (r_k − r̄)²`, which is added to
///    `χ²`, so the fix is the same maximum-likelihood fix.
/// 2. [`gauss_newton`] (Levenberg–Marquardt damped, with `options`) from the guess if one is
///    given, else from the weighted linear fix; then from the weighted centroid
///    `c_w = Σ w_i a_i / Σ w_i`, `w_i = 1/(max(r_i, 0) + σ_i)²`. A result must pass
///    [`Fix::check_plausible`] with reach `max(r_i + 3σ_i)`.
/// 3. If every start fails, the weighted centroid with the covariance of a position uniform in
///    the smallest ball the ranges allow around it:
///    ```text
///    R = min_i (‖a_i − c_w‖ + max(r_i, 0) + 3σ_i)
///    P = R² / (D + 2) · I          (per-axis variance of a uniform D-ball of radius R)
///    ```
///
/// The covariance of a Gauss–Newton fix is `σ̂₀² (JᵀWJ)⁻¹` with the a-posteriori variance
/// factor over all measurements (`σ̂₀² = max(1, χ²/(m − D))`, see [`gauss_newton`]).
///
/// Negative ranges are accepted (see [`gauss_newton`]).
///
/// # Units
/// Anchors, ranges, the guess and the fix in m; variances and the covariance in m².
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than `D + 1` distinct anchor positions
///   (`D` with a guess), `anchors` counting distinct positions;
/// - [`PositioningError::DegenerateGeometry`] for collinear (2-D) / coplanar (3-D) anchors
///   without a guess (the mirror ambiguity needs one);
/// - [`PositioningError::DimensionMismatch`], [`PositioningError::NonFiniteEntry`],
///   [`PositioningError::NonFinite`], [`PositioningError::InvalidParameter`] for malformed
///   inputs (as [`gauss_newton`]).
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::{multilaterate, FixMethod, GaussNewtonOptions, Start};
/// // two anchors on one mast (same x, y in the plane) and two more
/// let anchors = [[0.0, 0.0], [0.0, 0.0], [20.0, 0.0], [0.0, 15.0]];
/// let truth = Vector2::new(6.0, 4.0);
/// let ranges: Vec<f64> = anchors.iter().map(|a| (truth - Vector2::from(*a)).norm()).collect();
/// let fix = multilaterate(&anchors, &ranges, &[0.01; 4], None, &GaussNewtonOptions::default())?;
/// assert_eq!(fix.method, FixMethod::GaussNewton(Start::Linear));
/// assert_eq!(fix.distinct_anchors, 3);
/// assert!((fix.fix.position - truth).norm() < 1e-6);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Madsen, Nielsen & Tingleff (2004), §3.2 (Levenberg–Marquardt); J. Blumenthal et al.,
/// "Weighted centroid localization in Zigbee-based sensor networks", *IEEE WISP* 2007 (the
/// centroid fallback); P. J. G. Teunissen, *Adjustment Theory*, 2000, §4.4 (variance factor).
pub fn multilaterate<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges_m: &[f64],
    variances_m2: &[f64],
    guess_m: Option<SVector<f64, D>>,
    options: &GaussNewtonOptions,
) -> Result<RangeFix<D>> {
    options.validate()?;
    let n = anchors_m.len();
    // finite anchors; co-located ones are merged below
    match validate::anchors(anchors_m, 0, false) {
        Ok(_) | Err(PositioningError::DuplicateAnchors { .. }) => {}
        Err(other) => return Err(other),
    }
    validate::signed_ranges(ranges_m, n, "ranges (one per anchor)")?;
    validate::variances(variances_m2, n, "variances_m2", "range variances (one per anchor)")?;
    if let Some(guess) = &guess_m {
        validate::finite_point(guess, "initial position")?;
    }
    let merged = merge(anchors_m, ranges_m, variances_m2)?;
    let distinct = merged.anchors_m.len();
    let needed = if guess_m.is_some() { D } else { D + 1 };
    if distinct < needed {
        return Err(PositioningError::Underdetermined {
            anchors: distinct,
            needed,
        });
    }
    if guess_m.is_none() {
        // collinear / coplanar anchors without a guess: the mirror ambiguity cannot be resolved
        validate::anchors(&merged.anchors_m, D + 1, true)?;
    }
    // reach = max (r_i + 3σ_i)
    let reach_m = ranges_m
        .iter()
        .zip(variances_m2)
        .map(|(r, v)| r + 3.0 * v.sqrt())
        .fold(0.0, f64::max);
    let centroid = weighted_centroid(&merged);
    let first = match guess_m {
        Some(guess) => (Start::Guess, Initial::Guess(guess)),
        None => (Start::Linear, Initial::Linear),
    };
    let mut failures = Vec::new();
    for (start, initial) in [first, (Start::Centroid, Initial::Guess(centroid))] {
        let attempt = gauss_newton(
            &merged.anchors_m,
            &merged.ranges_m,
            &merged.variances_m2,
            initial,
            options,
        )
        .and_then(|solution| rescale(solution, merged.scatter, n))
        .and_then(|solution| {
            solution.fix.check_plausible(anchors_m, reach_m)?;
            Ok(solution)
        });
        match attempt {
            Ok(solution) => {
                return Ok(RangeFix {
                    fix: solution.fix,
                    method: FixMethod::GaussNewton(start),
                    solution: Some(solution),
                    failures,
                    distinct_anchors: distinct,
                })
            }
            Err(error) => failures.push(error),
        }
    }
    let fix = centroid_fix(&merged, centroid)?;
    fix.check_plausible(anchors_m, reach_m)?;
    Ok(RangeFix {
        fix,
        method: FixMethod::WeightedCentroid,
        solution: None,
        failures,
        distinct_anchors: distinct,
    })
}

/// Anchors with co-located ones merged.
struct Merged<const D: usize> {
    anchors_m: Vec<[f64; D]>,
    ranges_m: Vec<f64>,
    variances_m2: Vec<f64>,
    /// `Σ w_k (r_k − r̄)²` over the merged groups (unitless).
    scatter: f64,
}

/// Merges anchors closer than `COINCIDENCE_TOLERANCE ×` their scale (inverse-variance means).
fn merge<const D: usize>(anchors_m: &[[f64; D]], ranges_m: &[f64], variances_m2: &[f64]) -> Result<Merged<D>> {
    // scale = max(spread, largest |coordinate|), as validate::anchors
    let magnitude_m = anchors_m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    let n = anchors_m.len() as f64;
    let mean = anchors_m
        .iter()
        .fold(SVector::<f64, D>::zeros(), |acc, a| acc + point(a))
        / n.max(1.0);
    let spread_m = anchors_m.iter().map(|a| (point(a) - mean).norm()).fold(0.0, f64::max);
    let tolerance_m = COINCIDENCE_TOLERANCE * spread_m.max(magnitude_m);
    // groups of indices at one position, in first-seen order
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, a) in anchors_m.iter().enumerate() {
        match groups
            .iter_mut()
            .find(|g| (point(&anchors_m[g[0]]) - point(a)).norm() <= tolerance_m)
        {
            Some(group) => group.push(i),
            None => groups.push(vec![i]),
        }
    }
    let mut merged = Merged {
        anchors_m: Vec::with_capacity(groups.len()),
        ranges_m: Vec::with_capacity(groups.len()),
        variances_m2: Vec::with_capacity(groups.len()),
        scatter: 0.0,
    };
    for group in &groups {
        // W = Σ w_k,  r̄ = Σ w_k r_k / W
        let weight: f64 = group.iter().map(|&k| 1.0 / variances_m2[k]).sum();
        let mean_m = group.iter().map(|&k| ranges_m[k] / variances_m2[k]).sum::<f64>() / weight;
        // scatter += Σ w_k (r_k − r̄)²
        merged.scatter += group
            .iter()
            .map(|&k| (ranges_m[k] - mean_m).powi(2) / variances_m2[k])
            .sum::<f64>();
        merged.anchors_m.push(anchors_m[group[0]]);
        merged.ranges_m.push(mean_m);
        merged.variances_m2.push(1.0 / weight);
    }
    if merged
        .ranges_m
        .iter()
        .chain(&merged.variances_m2)
        .all(|v| v.is_finite())
        && merged.scatter.is_finite()
    {
        Ok(merged)
    } else {
        Err(PositioningError::NonFinite {
            what: "merged ranges of co-located anchors",
        })
    }
}

/// Recomputes χ², dof and the variance factor over all `measurements` (adding the merged
/// groups' scatter) and rescales the covariance accordingly.
fn rescale<const D: usize>(
    mut solution: GaussNewtonFix<D>,
    scatter: f64,
    measurements: usize,
) -> Result<GaussNewtonFix<D>> {
    // χ² = χ²_merged + Σ w_k (r_k − r̄)²,  dof = m − D
    let chi_square = solution.chi_square + scatter;
    let degrees_of_freedom = measurements.saturating_sub(D);
    let factor = variance_factor(chi_square, degrees_of_freedom);
    // P = σ̂₀² (JᵀWJ)⁻¹ = (σ̂₀² / σ̂₀²_merged) P_merged
    solution.fix.covariance *= factor / solution.variance_factor;
    solution.chi_square = chi_square;
    solution.degrees_of_freedom = degrees_of_freedom;
    solution.variance_factor = factor;
    solution.fix = solution.fix.checked()?;
    Ok(solution)
}

/// `c_w = Σ w_i a_i / Σ w_i` with `w_i = 1/(max(r_i, 0) + σ_i)²`.
fn weighted_centroid<const D: usize>(merged: &Merged<D>) -> SVector<f64, D> {
    let mut total = 0.0;
    let mut sum = SVector::<f64, D>::zeros();
    for ((a, r), v) in merged.anchors_m.iter().zip(&merged.ranges_m).zip(&merged.variances_m2) {
        // w_i = 1/(r⁺ + σ)²
        let w = (r.max(0.0) + v.sqrt()).powi(-2);
        sum += point(a) * w;
        total += w;
    }
    let centroid = sum / total;
    if centroid.iter().all(|v| v.is_finite()) {
        centroid
    } else {
        // weights under- or overflowed: the plain centroid
        merged.anchors_m.iter().fold(SVector::zeros(), |acc, a| acc + point(a)) / merged.anchors_m.len() as f64
    }
}

/// The centroid fallback: `R = min_i (‖a_i − c‖ + r_i⁺ + 3σ_i)`, `P = R²/(D + 2) I`.
fn centroid_fix<const D: usize>(merged: &Merged<D>, centroid: SVector<f64, D>) -> Result<Fix<D>> {
    let radius_m = merged
        .anchors_m
        .iter()
        .zip(&merged.ranges_m)
        .zip(&merged.variances_m2)
        .map(|((a, r), v)| (point(a) - centroid).norm() + r.max(0.0) + 3.0 * v.sqrt())
        .fold(f64::INFINITY, f64::min);
    // P = R² / (D + 2) · I
    let covariance = SMatrix::<f64, D, D>::identity() * (radius_m * radius_m / (D as f64 + 2.0));
    Fix {
        position: centroid,
        covariance,
    }
    .checked()
}

#[cfg(test)]
#[path = "robust_tests.rs"]
mod tests;
