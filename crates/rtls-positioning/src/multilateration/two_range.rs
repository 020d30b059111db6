//! The two-range fix in the plane (seed 003's "two-point" baseline): the intersections of two
//! range circles, with the ambiguity resolved by a prior.

use nalgebra::{DMatrix, Matrix2, Vector2};

use super::validate;
#[cfg(any(doc, test))]
use crate::error::PositioningError;
use crate::error::Result;
use crate::fix::Fix2;
use crate::linalg::{covariance_inverse, solve_spd};

/// Relative tolerance of tangency: `|h²| ≤ TANGENT_TOLERANCE · max(d, r₁, r₂)²`.
const TANGENT_TOLERANCE: f64 = 1e-12;

/// How the two range circles meet.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::CircleIntersection;
/// assert_ne!(CircleIntersection::Crossing, CircleIntersection::Apart);
/// ```
///
/// # References
/// P. Bourke, "Circles and spheres: intersection of two circles", 1997
/// (paulbourke.net/geometry/circlesphere).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CircleIntersection {
    /// Two intersection points, mirror images across the line of the anchors: ambiguous.
    Crossing,
    /// The circles touch (within round-off): one point, on the line of the anchors.
    Tangent,
    /// The circles miss each other, each outside the other (`r₁ + r₂ < d`: ranges too short,
    /// e.g. noise): the fix is the best point on the line of the anchors.
    Apart,
    /// One circle lies inside the other (`|r₁ − r₂| > d`): the fix is the best point on the
    /// line of the anchors, beyond the anchor with the shorter range.
    Nested,
}

/// The result of [`two_range`]: the chosen fix and both candidates.
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use rtls_positioning::multilateration::two_range;
/// use rtls_positioning::Fix2;
/// let anchors = [[0.0, 0.0], [8.0, 0.0]];
/// let ranges = [5.0, 5.0]; // intersections (4, 3) and (4, −3)
/// let prior = Fix2 { position: Vector2::new(3.0, -2.0), covariance: Matrix2::identity() };
/// let solution = two_range(&anchors, &ranges, &[0.01; 2], Some(&prior))?;
/// assert_eq!(solution.chosen, 1);
/// assert!((solution.fix.position - Vector2::new(4.0, -3.0)).norm() < 1e-12);
/// assert!((solution.candidates[0].position - Vector2::new(4.0, 3.0)).norm() < 1e-12);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 003 (two-point least-squares positioning when only two ranges are available).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoRangeSolution {
    /// The chosen candidate, `candidates[chosen]`.
    pub fix: Fix2,
    /// The candidates: `[left, right]` of the directed line from anchor 0 to anchor 1 when
    /// the circles cross; two copies of the one point otherwise.
    pub candidates: [Fix2; 2],
    /// Index of the chosen candidate (0 without a prior or when the circles do not cross).
    pub chosen: usize,
    /// How the circles meet.
    pub intersection: CircleIntersection,
}

/// The position from two ranges in the plane: the intersections of the circles
/// `‖p − a₀‖ = r₀`, `‖p − a₁‖ = r₁`, the ambiguity resolved by a prior.
///
/// With `d = ‖a₁ − a₀‖`, `e = (a₁ − a₀)/d` and `n = (−e_y, e_x)` (left of `a₀ → a₁`):
/// ```text
/// x = (r₀² − r₁² + d²) / (2d)          distance along e from a₀ to the chord
/// h² = r₀² − x²                          squared half-chord
/// h² > 0:  p± = a₀ + x e ± h n           two candidates (Crossing)
/// ```
/// **Choice** — with a prior `(μ, P)` (a tracker's prediction or the previous fix) the
/// candidate with the smaller Mahalanobis distance `(p − μ)ᵀ P⁻¹ (p − μ)` is chosen; without
/// one, the left candidate (index 0), and the caller must treat the fix as ambiguous.
///
/// **Covariance of a crossing** — the first-order covariance from the 2 × 2 Jacobian
/// `J = [u₀ᵀ; u₁ᵀ]`, `u_i = (p − a_i)/‖p − a_i‖`: `P = (Jᵀ W J)⁻¹ = J⁻¹ diag(σ₀², σ₁²) J⁻ᵀ`.
/// It grows without bound as the circles approach tangency (`J` becomes singular).
///
/// **Tangent or missing circles** (`h² ≤ 0`, noise with the tag near the line of the
/// anchors) — the fix is the weighted least-squares point on the line of the anchors,
/// `p = a₀ + t e`, which is then the global minimiser of `Σ (r_i − ‖p − a_i‖)²/σ_i²`:
/// ```text
/// t = (w₀ s₀ r₀ + w₁ (s₁ r₁ + d)) / (w₀ + w₁),  s₀ = sign t, s₁ = sign(t − d), w = 1/σ²
///                                            (the best of the three segments of the line)
/// σ_∥² = 1 / (w₀ + w₁)                                          along the line
/// σ_⊥² = 2 (√(A² + B) − A) / B                                   across it, where
/// A = −Σ w_i e_i / ℓ_i ≥ 0,  B = Σ w_i / ℓ_i²,  e_i = r_i − ℓ_i,  ℓ_i = max(‖p − a_i‖, σ_i)
/// P = σ_∥² e eᵀ + σ_⊥² n nᵀ
/// ```
/// Across the line the ranges change only to second order (`‖p + h n − a_i‖ ≈ ℓ_i +
/// h²/(2ℓ_i)`), so the cost grows as `A h² + B h⁴/4`; `σ_⊥` is the offset where it has grown
/// by 1 (the one-sigma contour, `1/√A` when the quadratic term dominates, `(4/B)^¼` at exact
/// tangency). Both candidates are then that one point.
///
/// # Units
/// Anchors, ranges and the fix in m; variances and covariances in m².
///
/// # Errors
/// - [`PositioningError::NonFiniteEntry`] for a NaN/∞ anchor coordinate, range or variance;
///   [`PositioningError::NonFinite`] for a NaN/∞ prior;
/// - [`PositioningError::InvalidParameter`] for a negative range, a variance `≤ 0`, or an
///   asymmetric prior covariance (`prior`);
/// - [`PositioningError::NotPositiveDefinite`] for a prior covariance that is not positive
///   definite;
/// - [`PositioningError::DuplicateAnchors`] when the anchors coincide (then the circles are
///   concentric: no point or a whole circle);
/// - [`PositioningError::NonFinite`] if the result would not be finite.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::{two_range, CircleIntersection};
/// // ranges too short for the circles to meet (noise): the best point between the anchors
/// let solution = two_range(&[[0.0, 0.0], [10.0, 0.0]], &[4.0, 5.0], &[1.0, 1.0], None)?;
/// assert_eq!(solution.intersection, CircleIntersection::Apart);
/// assert!((solution.fix.position - Vector2::new(4.5, 0.0)).norm() < 1e-12);
/// assert!(solution.fix.covariance[(1, 1)] > solution.fix.covariance[(0, 0)]);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 003 (two-point LS baseline; the EKF's predicted position as the prior); Bourke (1997)
/// (circle–circle intersection); P. C. Mahalanobis, "On the generalised distance in
/// statistics", 1936.
pub fn two_range(
    anchors_m: &[[f64; 2]; 2],
    ranges_m: &[f64; 2],
    variances_m2: &[f64; 2],
    prior: Option<&Fix2>,
) -> Result<TwoRangeSolution> {
    validate::anchors(anchors_m, 2, false)?;
    validate::ranges(ranges_m, 2, "ranges_m", "ranges (one per anchor)")?;
    validate::variances(variances_m2, 2, "variances_m2", "range variances (one per anchor)")?;
    let prior_information = prior.map(prior_inverse).transpose()?;

    let a0 = Vector2::from(anchors_m[0]);
    let a1 = Vector2::from(anchors_m[1]);
    let [r0, r1] = *ranges_m;
    let weights = variances_m2.map(|v| 1.0 / v);
    // d = ‖a₁ − a₀‖,  e = (a₁ − a₀)/d,  n = (−e_y, e_x)
    let d = (a1 - a0).norm();
    let e = (a1 - a0) / d;
    let n = Vector2::new(-e.y, e.x);
    // x = (r₀² − r₁² + d²)/(2d),  h² = r₀² − x²
    let x = (r0 * r0 - r1 * r1 + d * d) / (2.0 * d);
    let h2 = r0 * r0 - x * x;
    let scale = d.max(r0).max(r1);

    if h2 > TANGENT_TOLERANCE * scale * scale {
        // p± = a₀ + x e ± h n
        let h = h2.sqrt();
        let points = [a0 + e * x + n * h, a0 + e * x - n * h];
        let crossing = |p: &Vector2<f64>| crossing_covariance(p, &[a0, a1], &weights);
        if let (Ok(c0), Ok(c1)) = (crossing(&points[0]), crossing(&points[1])) {
            let candidates = [
                Fix2 {
                    position: points[0],
                    covariance: c0,
                }
                .checked()?,
                Fix2 {
                    position: points[1],
                    covariance: c1,
                }
                .checked()?,
            ];
            // choose by Mahalanobis distance (p − μ)ᵀ P⁻¹ (p − μ) to the prior
            let chosen = match (prior, prior_information) {
                (Some(prior), Some(information)) => {
                    let distance = |p: &Vector2<f64>| {
                        let v = p - prior.position;
                        v.dot(&(information * v))
                    };
                    usize::from(distance(&points[1]) < distance(&points[0]))
                }
                _ => 0,
            };
            return Ok(TwoRangeSolution {
                fix: candidates[chosen],
                candidates,
                chosen,
                intersection: CircleIntersection::Crossing,
            });
        }
        // J numerically singular: so close to tangent that the line treatment applies
    }
    let intersection = if h2 >= -TANGENT_TOLERANCE * scale * scale {
        CircleIntersection::Tangent
    } else if r0 + r1 < d {
        CircleIntersection::Apart
    } else {
        CircleIntersection::Nested
    };
    let fix = on_the_line(a0, e, n, d, ranges_m, variances_m2)?;
    Ok(TwoRangeSolution {
        fix,
        candidates: [fix, fix],
        chosen: 0,
        intersection,
    })
}

/// `P⁻¹` of a prior, validated.
fn prior_inverse(prior: &Fix2) -> Result<Matrix2<f64>> {
    validate::finite_point(&prior.position, "prior position")?;
    let covariance = DMatrix::from_column_slice(2, 2, prior.covariance.as_slice());
    let inverse = covariance_inverse(&covariance, 2, "prior", "prior covariance")?;
    Ok(Matrix2::new(
        inverse[(0, 0)],
        inverse[(0, 1)],
        inverse[(1, 0)],
        inverse[(1, 1)],
    ))
}

/// `(Jᵀ W J)⁻¹` at a crossing point.
fn crossing_covariance(p: &Vector2<f64>, anchors: &[Vector2<f64>; 2], weights: &[f64; 2]) -> Result<Matrix2<f64>> {
    // JᵀWJ = Σ w_i u_i u_iᵀ,  u_i = (p − a_i)/‖p − a_i‖
    let mut information = Matrix2::zeros();
    for (a, w) in anchors.iter().zip(weights) {
        let offset = p - a;
        let distance = offset.norm();
        if distance <= 0.0 {
            return Err(validate::AT_ANCHOR);
        }
        let u = offset / distance;
        information += u * u.transpose() * *w;
    }
    let (_, covariance) = solve_spd(
        &information,
        &Vector2::zeros(),
        "the two-range jacobian is singular (circles nearly tangent)",
    )?;
    Ok((covariance + covariance.transpose()) * 0.5)
}

/// The weighted LS point on the line `a₀ + t e` and its covariance (see [`two_range`]).
fn on_the_line(
    a0: Vector2<f64>,
    e: Vector2<f64>,
    n: Vector2<f64>,
    d: f64,
    ranges_m: &[f64; 2],
    variances_m2: &[f64; 2],
) -> Result<Fix2> {
    let [r0, r1] = *ranges_m;
    let [w0, w1] = variances_m2.map(|v| 1.0 / v);
    // cost(t) = w₀ (r₀ − |t|)² + w₁ (r₁ − |t − d|)²
    let cost = |t: f64| w0 * (r0 - t.abs()).powi(2) + w1 * (r1 - (t - d).abs()).powi(2);
    // per segment (s₀, s₁) = (sign t, sign(t − d)): t = (w₀ s₀ r₀ + w₁ (s₁ r₁ + d))/(w₀ + w₁),
    // clamped to the segment
    let segments = [
        (-1.0, -1.0, f64::NEG_INFINITY, 0.0),
        (1.0, -1.0, 0.0, d),
        (1.0, 1.0, d, f64::INFINITY),
    ];
    let t = segments
        .iter()
        .map(|&(s0, s1, low, high)| ((w0 * s0 * r0 + w1 * (s1 * r1 + d)) / (w0 + w1)).clamp(low, high))
        .fold((0.0, f64::INFINITY), |best, t| {
            let c = cost(t);
            if c < best.1 {
                (t, c)
            } else {
                best
            }
        })
        .0;
    let p = a0 + e * t;
    // σ_∥² = 1/(w₀ + w₁)
    let along_m2 = 1.0 / (w0 + w1);
    // ℓ_i = max(‖p − a_i‖, σ_i),  e_i = r_i − ‖p − a_i‖
    let lengths = [t.abs(), (t - d).abs()];
    let (mut a, mut b) = (0.0, 0.0);
    for (((length, r), w), v) in lengths.iter().zip(ranges_m).zip([w0, w1]).zip(variances_m2) {
        let l = length.max(v.sqrt());
        // A = −Σ w_i e_i/ℓ_i,  B = Σ w_i/ℓ_i²
        a -= w * (r - length) / l;
        b += w / (l * l);
    }
    let a = a.max(0.0);
    // σ_⊥² = 2 (√(A² + B) − A)/B  (written as 2/(√(A² + B) + A) to avoid cancellation)
    let across_m2 = 2.0 / ((a * a + b).sqrt() + a);
    // P = σ_∥² e eᵀ + σ_⊥² n nᵀ
    let covariance = e * e.transpose() * along_m2 + n * n.transpose() * across_m2;
    Fix2 {
        position: p,
        covariance,
    }
    .checked()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior_at(x: f64, y: f64) -> Fix2 {
        Fix2 {
            position: Vector2::new(x, y),
            covariance: Matrix2::identity() * 4.0,
        }
    }

    #[test]
    fn the_prior_picks_the_nearer_intersection() {
        let anchors = [[1.0, 1.0], [9.0, 7.0]]; // d = 10, e = (0.8, 0.6)
        let truth_left = Vector2::new(1.0, 1.0) + Vector2::new(0.8, 0.6) * 6.0 + Vector2::new(-0.6, 0.8) * 3.0;
        let r = [
            (truth_left - Vector2::from(anchors[0])).norm(),
            (truth_left - Vector2::from(anchors[1])).norm(),
        ];
        let mirror = Vector2::new(1.0, 1.0) + Vector2::new(0.8, 0.6) * 6.0 - Vector2::new(-0.6, 0.8) * 3.0;
        for (prior, expected, index) in [
            (prior_at(truth_left.x + 1.0, truth_left.y - 0.5), truth_left, 0),
            (prior_at(mirror.x - 1.0, mirror.y + 0.5), mirror, 1),
        ] {
            let s = two_range(&anchors, &r, &[0.04, 0.09], Some(&prior)).unwrap();
            assert_eq!(s.intersection, CircleIntersection::Crossing);
            assert_eq!(s.chosen, index);
            assert!((s.fix.position - expected).norm() < 1e-12);
        }
        // a tie (candidates (4, ±3) equally far from the prior) goes to the left one
        let s = two_range(
            &[[0.0, 0.0], [8.0, 0.0]],
            &[5.0, 5.0],
            &[0.01, 0.01],
            Some(&prior_at(4.0, 0.0)),
        )
        .unwrap();
        assert_eq!(s.chosen, 0);
        // a correlated prior: (4, 3) is nearer in metres, (4, −3) in Mahalanobis distance
        // (P = 100 along (1, −1)/√2, 0.1 along (1, 1)/√2)
        let correlated = Fix2 {
            position: Vector2::new(1.0, 0.5),
            covariance: Matrix2::new(50.05, -49.95, -49.95, 50.05),
        };
        let s = two_range(&[[0.0, 0.0], [8.0, 0.0]], &[5.0, 5.0], &[0.01, 0.01], Some(&correlated)).unwrap();
        assert!((s.fix.position - Vector2::new(4.0, -3.0)).norm() < 1e-12);
        assert_eq!(s.chosen, 1);
    }

    #[test]
    fn crossing_covariance_is_the_first_order_one() {
        // a right-angle crossing: u₀ ⊥ u₁, so P = σ₀² u₀u₀ᵀ + σ₁² u₁u₁ᵀ
        let anchors = [[0.0, 0.0], [10.0, 0.0]];
        let p = Vector2::new(3.6, 4.8); // r₀ = 6, r₁ = 8, u₀ ⊥ u₁
        let s = two_range(&anchors, &[6.0, 8.0], &[0.04, 0.25], Some(&prior_at(3.0, 5.0))).unwrap();
        assert!((s.fix.position - p).norm() < 1e-12);
        let u0 = p / 6.0;
        let u1 = (p - Vector2::new(10.0, 0.0)) / 8.0;
        let expected = u0 * u0.transpose() * 0.04 + u1 * u1.transpose() * 0.25;
        assert!((s.fix.covariance - expected).amax() < 1e-12);
    }

    #[test]
    fn tangent_and_missing_circles_give_the_point_on_the_line() {
        let anchors = [[0.0, 0.0], [10.0, 0.0]];
        // externally tangent at (4, 0)
        let s = two_range(&anchors, &[4.0, 6.0], &[0.01, 0.01], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Tangent);
        assert!((s.fix.position - Vector2::new(4.0, 0.0)).norm() < 1e-12);
        assert_eq!(s.candidates[0], s.candidates[1]);
        // σ_∥² = 1/(w₀ + w₁) = 0.005; σ_⊥² = 2/√B, B = 100/16 + 100/36
        assert!((s.fix.covariance[(0, 0)] - 0.005).abs() < 1e-12);
        let b: f64 = 100.0 / 16.0 + 100.0 / 36.0;
        assert!((s.fix.covariance[(1, 1)] - 2.0 / b.sqrt()).abs() < 1e-12);
        assert!(s.fix.covariance[(0, 1)].abs() < 1e-15);
        // internally tangent at (12, 0)
        let s = two_range(&anchors, &[12.0, 2.0], &[0.01, 0.01], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Tangent);
        assert!((s.fix.position - Vector2::new(12.0, 0.0)).norm() < 1e-12);
        // apart, unequal weights: t = (w₀ r₀ + w₁ (d − r₁))/(w₀ + w₁)
        let s = two_range(&anchors, &[3.0, 5.0], &[1.0, 4.0], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Apart);
        let t = (3.0 + 0.25 * 5.0) / 1.25;
        assert!((s.fix.position - Vector2::new(t, 0.0)).norm() < 1e-12);
        // nested: r₀ = 15 > d + r₁ = 13 → beyond anchor 1: t = (w₀ r₀ + w₁ (r₁ + d))/(w₀ + w₁)
        let s = two_range(&anchors, &[15.0, 3.0], &[1.0, 1.0], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Nested);
        assert!((s.fix.position - Vector2::new(14.0, 0.0)).norm() < 1e-12);
        // nested the other way: r₁ = 15 > d + r₀ → beyond anchor 0
        let s = two_range(&anchors, &[3.0, 15.0], &[1.0, 1.0], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Nested);
        assert!((s.fix.position - Vector2::new(-4.0, 0.0)).norm() < 1e-12);
        // the point on the line is the 2-D minimum of the cost: a grid search agrees
        let cost =
            |p: Vector2<f64>| (3.0 - p.norm()).powi(2) + 0.25 * (5.0 - (p - Vector2::new(10.0, 0.0)).norm()).powi(2);
        let best = s_min_on_grid(cost);
        assert!((best - Vector2::new(t, 0.0)).norm() < 0.02);
    }

    fn s_min_on_grid(cost: impl Fn(Vector2<f64>) -> f64) -> Vector2<f64> {
        let mut best = (Vector2::zeros(), f64::INFINITY);
        for i in -200..=600 {
            for j in -200..=200 {
                let p = Vector2::new(i as f64 * 0.02, j as f64 * 0.02);
                let c = cost(p);
                if c < best.1 {
                    best = (p, c);
                }
            }
        }
        best.0
    }

    #[test]
    fn errors() {
        let anchors = [[0.0, 0.0], [10.0, 0.0]];
        assert_eq!(
            two_range(&[[1.0, 1.0], [1.0, 1.0]], &[3.0, 3.0], &[1.0, 1.0], None).unwrap_err(),
            PositioningError::DuplicateAnchors { first: 0, second: 1 }
        );
        assert!(matches!(
            two_range(&[[1.0, f64::NAN], [1.0, 1.0]], &[3.0, 3.0], &[1.0, 1.0], None),
            Err(PositioningError::NonFiniteEntry { row: 0, column: 1, .. })
        ));
        assert!(matches!(
            two_range(&anchors, &[3.0, -3.0], &[1.0, 1.0], None),
            Err(PositioningError::InvalidParameter { name: "ranges_m", .. })
        ));
        assert!(matches!(
            two_range(&anchors, &[3.0, 3.0], &[1.0, 0.0], None),
            Err(PositioningError::InvalidParameter {
                name: "variances_m2",
                ..
            })
        ));
        let indefinite = Fix2 {
            position: Vector2::new(1.0, 1.0),
            covariance: Matrix2::new(1.0, 2.0, 2.0, 1.0),
        };
        assert!(matches!(
            two_range(&anchors, &[6.0, 6.0], &[1.0, 1.0], Some(&indefinite)),
            Err(PositioningError::NotPositiveDefinite { .. })
        ));
        let nan_prior = Fix2 {
            position: Vector2::new(f64::NAN, 1.0),
            covariance: Matrix2::identity(),
        };
        assert!(matches!(
            two_range(&anchors, &[6.0, 6.0], &[1.0, 1.0], Some(&nan_prior)),
            Err(PositioningError::NonFinite { .. })
        ));
        // a zero range at an anchor: tangent when the other range reaches it
        let s = two_range(&anchors, &[0.0, 10.0], &[0.01, 0.01], None).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Tangent);
        assert!(s.fix.position.norm() < 1e-12);
        assert!(s.fix.covariance.iter().all(|v| v.is_finite()));
    }
}
