//! A planar TDOA fix for a tag at a known height, with the stations at their own heights: the
//! range differences are differences of slant ranges, not of ranges in the plane.

use nalgebra::{DMatrix, DVector, SVector, Vector2};

use super::chan;
use crate::error::{PositioningError, Result};
use crate::fix::Fix2;
use crate::linalg::{covariance_inverse, solve_spd};
use crate::multilateration::validate::MIN_RELATIVE_THICKNESS;
use crate::multilateration::{levenberg_marquardt, variance_factor, GaussNewtonOptions, Model, NormalEquations};

/// The planar maximum-likelihood TDOA fix of a tag at height `height_m` from stations at their
/// own heights `(x, y, z)`.
///
/// Treating such range differences as planar ones (dropping the heights) is wrong by up to the
/// height difference per station, which in a room is larger than the noise and can throw
/// Chan's closed form thousands of kilometres off. Here the model is exact, with
/// `Δz_i = z_i − height_m` and `ρ_i(p) = √(‖p − s_i‖² + Δz_i²)` for `p = (x, y)`:
/// ```text
/// h_i(p) = ρ_i(p) − ρ_ref(p)
/// J_i    = (p − s_i)ᵀ/ρ_i − (p − s_ref)ᵀ/ρ_ref
/// Q⁻¹ = L Lᵀ,  ẽ = Lᵀ (r − h(p)),  J̃ = Lᵀ J        (whitening)
/// minimise ‖ẽ‖² by Levenberg–Marquardt (the engine of multilateration::gauss_newton)
/// χ² = ‖ẽ‖²,  σ̂₀² = max(1, χ²/(n − 1 − 2))
/// P = σ̂₀² (J̃ᵀ J̃)⁻¹ at the solution
/// ```
/// The iteration starts from the lowest-cost of: Chan's planar fix(es) of the stations'
/// projections (an approximation that ignores the heights), the projected centroid of the
/// stations, and the centroid pulled towards each station in turn; it then keeps the
/// lowest-cost minimum.
///
/// Two stations at one `(x, y)` and different heights are fine here (their slant ranges
/// differ); the fix needs three distinct projected positions not on one line, like any planar
/// TDOA fix.
///
/// # Units
/// Stations, height, range differences and the fix in m; `Q` and the covariance in m².
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than 3 stations;
/// - [`PositioningError::InvalidParameter`] (`reference`) for a reference index `≥ n`;
/// - [`PositioningError::DimensionMismatch`] unless there are `n − 1` range differences and
///   `Q` is `(n − 1) × (n − 1)`;
/// - [`PositioningError::NonFiniteEntry`] / [`PositioningError::NonFinite`] for a NaN/∞
///   station coordinate, range difference or height;
/// - [`PositioningError::NotPositiveDefinite`] or [`PositioningError::InvalidParameter`] for
///   a bad `Q`;
/// - [`PositioningError::DegenerateGeometry`] when `J̃ᵀJ̃` is singular at every start's
///   minimum (e.g. collinear projected stations) or the iteration reaches a station;
/// - [`PositioningError::DidNotConverge`] when no start converges;
/// - [`PositioningError::ImplausibleFix`] / [`PositioningError::NotPositiveDefinite`] for a
///   minimum that fails [`Fix2::check_plausible`] (range differences no position near the
///   stations explains).
///
/// # Example
/// ```
/// use nalgebra::{DMatrix, Vector2, Vector3};
/// use rtls_positioning::tdoa::{planar_at_height, range_differences_at};
/// // UWB anchors at 2.5–3 m, a tag at 1.0 m
/// let anchors = [[0.0, 0.0, 3.0], [20.0, 0.0, 2.5], [20.0, 15.0, 3.0], [0.0, 15.0, 2.5]];
/// let tag = Vector3::new(6.0, 4.0, 1.0);
/// let r = range_differences_at(&anchors, 0, &tag)?; // slant-range differences
/// let fix = planar_at_height(&anchors, 0, &r, &(DMatrix::identity(3, 3) * 0.01), 1.0)?;
/// assert!((fix.position - Vector2::new(6.0, 4.0)).norm() < 1e-6);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// W. H. Foy, "Position-location solutions by Taylor-series estimation", *IEEE Trans. AES*
/// 12(2), 1976; D. J. Torrieri, "Statistical theory of passive location systems", *IEEE Trans.
/// AES* 20(2), 1984 (the ML TDOA fix and its covariance); P. J. G. Teunissen, *Adjustment
/// Theory*, 2000, §4.4 (variance factor).
pub fn planar_at_height(
    stations_m: &[[f64; 3]],
    reference: usize,
    range_differences_m: &[f64],
    covariance_m2: &DMatrix<f64>,
    height_m: f64,
) -> Result<Fix2> {
    let model = SlantTdoa::new(stations_m, reference, range_differences_m, covariance_m2, height_m)?;
    let options = GaussNewtonOptions {
        max_iterations: 200,
        relative_tolerance: 1e-9,
    };
    let tolerance_m = options.relative_tolerance * model.scale_m.max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, Fix2)> = None;
    let mut last_error = None;
    for start in model.starts(stations_m, reference, range_differences_m, covariance_m2) {
        let attempt = levenberg_marquardt(&model, start, tolerance_m, &options).and_then(|minimum| {
            let fix = model.fix_at(&minimum.position, minimum.normal.cost)?;
            Ok((minimum.normal.cost, fix))
        });
        match attempt {
            Ok((cost, fix)) if best.as_ref().is_none_or(|(c, _)| cost < *c) => best = Some((cost, fix)),
            Ok(_) => {}
            Err(error) => last_error = Some(error),
        }
    }
    let fix = best.map(|(_, fix)| fix).ok_or_else(|| {
        last_error.unwrap_or(PositioningError::DegenerateGeometry {
            reason: "no start of the planar tdoa fix reached a minimum",
        })
    })?;
    let projected: Vec<[f64; 2]> = stations_m.iter().map(|s| [s[0], s[1]]).collect();
    fix.check_plausible(&projected, 0.0)?;
    Ok(fix)
}

/// [`PositioningError::DegenerateGeometry`] unless the projected stations span the plane:
/// `λ_min > MIN_RELATIVE_THICKNESS² λ_max` for their scatter matrix
/// `S = Σ (s_i − c)(s_i − c)ᵀ` (collinear stations leave the tag's side of their line open).
fn require_planar_span(projected: &[Vector2<f64>]) -> Result<()> {
    let n = projected.len() as f64;
    // c = (1/n) Σ s_i
    let centroid = projected.iter().fold(Vector2::zeros(), |acc, s| acc + s) / n;
    // S = Σ (s_i − c)(s_i − c)ᵀ
    let scatter = projected.iter().fold(nalgebra::Matrix2::zeros(), |acc, s| {
        let d = s - centroid;
        acc + d * d.transpose()
    });
    let eigenvalues = scatter.symmetric_eigenvalues();
    let (low, high) = (eigenvalues.min(), eigenvalues.max());
    if high > 0.0 && low > MIN_RELATIVE_THICKNESS * MIN_RELATIVE_THICKNESS * high {
        Ok(())
    } else {
        Err(PositioningError::DegenerateGeometry {
            reason: "the stations' (x, y) positions are collinear (or coincide): the range differences \
                     cannot tell the tag from its mirror image across their line; add a station off the line",
        })
    }
}

/// The whitened slant-range TDOA model in the plane.
struct SlantTdoa {
    /// Projected stations `(x, y)` (m).
    stations_m: Vec<Vector2<f64>>,
    /// `Δz_i²` (m²).
    height_offsets_m2: Vec<f64>,
    reference: usize,
    /// `r_{i,ref}` for `i ≠ ref`, in station order (m).
    differences_m: DVector<f64>,
    /// `Lᵀ` with `Q⁻¹ = L Lᵀ`.
    whitening: DMatrix<f64>,
    /// Largest projected station distance from the reference (m).
    scale_m: f64,
}

impl SlantTdoa {
    fn new(
        stations_m: &[[f64; 3]],
        reference: usize,
        range_differences_m: &[f64],
        covariance_m2: &DMatrix<f64>,
        height_m: f64,
    ) -> Result<Self> {
        super::problem::check_inputs(stations_m, reference, range_differences_m, 3)?;
        let n = stations_m.len();
        if !(range_differences_m.iter().all(|v| v.is_finite()) && height_m.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "range differences or tag height",
            });
        }
        let q_inverse = covariance_inverse(covariance_m2, n - 1, "covariance_m2", "range-difference covariance")?;
        // Q⁻¹ = L Lᵀ
        let whitening = q_inverse
            .cholesky()
            .ok_or(PositioningError::NotPositiveDefinite {
                what: "inverse range-difference covariance",
            })?
            .l()
            .transpose();
        let projected: Vec<Vector2<f64>> = stations_m.iter().map(|s| Vector2::new(s[0], s[1])).collect();
        require_planar_span(&projected)?;
        let scale_m = projected
            .iter()
            .map(|s| (s - projected[reference]).norm())
            .fold(0.0, f64::max);
        if !scale_m.is_finite() {
            return Err(PositioningError::NonFinite {
                what: "station spread (coordinates too large)",
            });
        }
        Ok(Self {
            stations_m: projected,
            // Δz_i² = (z_i − h)²
            height_offsets_m2: stations_m.iter().map(|s| (s[2] - height_m).powi(2)).collect(),
            reference,
            differences_m: DVector::from_column_slice(range_differences_m),
            whitening,
            scale_m,
        })
    }

    /// `ρ_i(p)` and `∂ρ_i/∂p`, or an error at a station's foot with no height offset.
    fn slant(&self, p: &Vector2<f64>, i: usize) -> Result<(f64, Vector2<f64>)> {
        let offset = p - self.stations_m[i];
        // ρ_i = √(‖p − s_i‖² + Δz_i²)
        let rho = (offset.norm_squared() + self.height_offsets_m2[i]).sqrt();
        if rho > f64::EPSILON * self.scale_m && rho.is_finite() {
            Ok((rho, offset / rho))
        } else {
            Err(PositioningError::DegenerateGeometry {
                reason: "the tdoa iterate coincides with a station, where the jacobian is undefined",
            })
        }
    }

    /// `(r − h(p), J)` unwhitened, rows in station order skipping the reference.
    fn residual(&self, p: &Vector2<f64>) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let m = self.stations_m.len() - 1;
        let (rho_ref, u_ref) = self.slant(p, self.reference)?;
        let mut residual = DVector::zeros(m);
        let mut jacobian = DMatrix::zeros(m, 2);
        for (row, i) in (0..self.stations_m.len()).filter(|&i| i != self.reference).enumerate() {
            let (rho, u) = self.slant(p, i)?;
            // e_i = r_i − (ρ_i − ρ_ref)
            residual[row] = self.differences_m[row] - (rho - rho_ref);
            // J_i = ∂ρ_i/∂p − ∂ρ_ref/∂p
            let gradient = u - u_ref;
            jacobian[(row, 0)] = gradient.x;
            jacobian[(row, 1)] = gradient.y;
        }
        Ok((residual, jacobian))
    }

    /// The fix at `p`: `P = σ̂₀² (J̃ᵀJ̃)⁻¹`.
    fn fix_at(&self, p: &Vector2<f64>, chi_square: f64) -> Result<Fix2> {
        let normal = self.normal_equations(p)?;
        let (_, covariance) = solve_spd(
            &normal.information,
            &Vector2::zeros(),
            "the tdoa information matrix Jᵀ Q⁻¹ J is singular at the fix (projected stations collinear \
             with it); add a station off their line",
        )?;
        let factor = variance_factor(chi_square, self.stations_m.len().saturating_sub(3));
        Fix2 {
            position: *p,
            covariance: (covariance + covariance.transpose()) * (0.5 * factor),
        }
        .checked()
    }

    /// Starts: Chan's planar fix(es) of the projections, the projected centroid, and the
    /// centroid moved halfway to each station, ordered by cost (lowest first), at most four.
    fn starts(
        &self,
        stations_m: &[[f64; 3]],
        reference: usize,
        range_differences_m: &[f64],
        covariance_m2: &DMatrix<f64>,
    ) -> Vec<Vector2<f64>> {
        let n = self.stations_m.len() as f64;
        let centroid = self.stations_m.iter().fold(Vector2::zeros(), |acc, s| acc + s) / n;
        let mut candidates = vec![centroid];
        candidates.extend(self.stations_m.iter().map(|s| (centroid + s) * 0.5));
        let planar: Vec<[f64; 2]> = stations_m.iter().map(|s| [s[0], s[1]]).collect();
        if let Ok(solution) = chan(&planar, reference, range_differences_m, covariance_m2) {
            candidates.extend(
                core::iter::once(solution.fix)
                    .chain(solution.alternative)
                    .map(|f| f.position),
            );
        }
        let mut scored: Vec<(f64, Vector2<f64>)> = candidates
            .into_iter()
            .filter_map(|p| self.normal_equations(&p).ok().map(|n| (n.cost, p)))
            .filter(|(cost, _)| cost.is_finite())
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        scored.into_iter().take(4).map(|(_, p)| p).collect()
    }
}

impl Model<2> for SlantTdoa {
    fn normal_equations(&self, p: &SVector<f64, 2>) -> Result<NormalEquations<2>> {
        let (residual, jacobian) = self.residual(p)?;
        // ẽ = Lᵀ e,  J̃ = Lᵀ J
        let whitened_residual = &self.whitening * residual;
        let whitened_jacobian = &self.whitening * jacobian;
        let mut normal = NormalEquations::zero();
        for k in 0..whitened_residual.len() {
            let row = Vector2::new(whitened_jacobian[(k, 0)], whitened_jacobian[(k, 1)]);
            normal.add(whitened_residual[k], &row, 1.0);
        }
        Ok(normal)
    }
}

#[cfg(test)]
#[path = "height_tests.rs"]
mod tests;
