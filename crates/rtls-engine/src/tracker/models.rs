//! Single-anchor measurement models of the tightly coupled pipeline, for a CV state
//! `[x, vx, y, vy(, z, vz)]` in 2-D (`N = 4`) or 3-D (`N = 6`).
//!
//! In 2-D the tag is at a known height `h` (`tracker.tag_height_m`) and anchors may sit at
//! other heights, so every model uses the slant distance
//! `d = √((x − aₓ)² + (y − a_y)² + (h − a_z)²)`; in 3-D `d = ‖p − a‖`.

use nalgebra::{DMatrix, DVector};
use rtls_estimation::measurement::{MeasurementJacobian, MeasurementModel};
use rtls_estimation::{EstimationError, Vector};

/// Positions of `x`, `y`(, `z`) in the CV state.
const POSITION_INDICES: [usize; 3] = [0, 2, 4];

/// Below this distance the direction to an anchor is undefined.
const MIN_DISTANCE_M: f64 = 1e-6;

/// The tag position implied by a state: `[x, y, z]`, with `z = h` in 2-D.
fn tag_position<const N: usize>(x: &Vector<N>, tag_height_m: f64) -> [f64; 3] {
    if N >= 6 {
        [x[0], x[2], x[4]]
    } else {
        [x[0], x[2], tag_height_m]
    }
}

/// `(p − a, ‖p − a‖)`.
fn offset(p: &[f64; 3], a: &[f64; 3]) -> ([f64; 3], f64) {
    let delta = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    (
        delta,
        (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt(),
    )
}

/// The unit vector `(p − a)/d` on the tracked axes, or an error at the anchor itself.
fn unit(delta: &[f64; 3], distance_m: f64, model: &'static str) -> rtls_estimation::Result<[f64; 3]> {
    if distance_m.is_nan() || distance_m < MIN_DISTANCE_M {
        return Err(EstimationError::SingularMeasurement {
            model,
            reason: "the tag position coincides with an anchor, where the direction to it is undefined",
        });
    }
    // u = (p − a) / d
    Ok([delta[0] / distance_m, delta[1] / distance_m, delta[2] / distance_m])
}

/// A `1 × N` Jacobian with `gradient` on the position columns.
fn position_row<const N: usize>(gradient: &[f64; 3]) -> MeasurementJacobian<N> {
    let mut h = MeasurementJacobian::<N>::zeros(1);
    let axes = if N >= 6 { 3 } else { 2 };
    for (axis, &g) in gradient.iter().enumerate().take(axes) {
        h[(0, POSITION_INDICES[axis])] = g;
    }
    h
}

/// What one anchor measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum AnchorLaw {
    /// Range `r = d + v` (m).
    Range,
    /// Received power `ρ = ρ₀ − 10 n log₁₀(d / d₀) + v` (dBm).
    LogDistance {
        /// `ρ₀`, dBm at `d₀`.
        reference_power_dbm: f64,
        /// `d₀`, m.
        reference_distance_m: f64,
        /// `n`.
        exponent: f64,
    },
    /// Range difference `Δr = ‖p − a‖ − ‖p − b‖ + v` (m) to a second (reference) anchor `b`.
    RangeDifference {
        /// The reference anchor `b`, m.
        reference_m: [f64; 3],
    },
    /// Signed offset `e = n·(p − a) + v` (m) of the tag from a line or plane through the
    /// "anchor" `a` with unit normal `n`: a map constraint as a pseudo-measurement.
    Offset {
        /// The unit normal `n`.
        normal: [f64; 3],
    },
}

/// One scalar anchor measurement as a [`MeasurementModel`] (seed 003's one-observation EKF
/// update, seed 001's TOA / RSS and seed 004's TDOA components).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AnchorMeasurement {
    anchor_m: [f64; 3],
    tag_height_m: f64,
    law: AnchorLaw,
    variance: DMatrix<f64>,
}

impl AnchorMeasurement {
    /// The model of a measurement from `anchor_m` with variance `variance` (unit², > 0).
    pub(crate) fn new(anchor_m: [f64; 3], tag_height_m: f64, law: AnchorLaw, variance: f64) -> Self {
        Self {
            anchor_m,
            tag_height_m,
            law,
            variance: DMatrix::from_element(1, 1, variance),
        }
    }
}

impl AnchorMeasurement {
    /// The tag height used for a planar state, m.
    pub(crate) fn tag_height_m(&self) -> f64 {
        self.tag_height_m
    }

    /// The measurement variance `R`, unit².
    pub(crate) fn variance(&self) -> f64 {
        self.variance[(0, 0)]
    }

    /// `h(p)` at the tag position `p = [x, y, z]`, m.
    pub(crate) fn value(&self, p: &[f64; 3]) -> f64 {
        let (_, d) = offset(p, &self.anchor_m);
        match self.law {
            // h = d
            AnchorLaw::Range => d,
            // h = ρ₀ − 10 n log₁₀(max(d, d_min) / d₀)
            AnchorLaw::LogDistance {
                reference_power_dbm,
                reference_distance_m,
                exponent,
            } => reference_power_dbm - 10.0 * exponent * (d.max(MIN_DISTANCE_M) / reference_distance_m).log10(),
            // h = ‖p − a‖ − ‖p − b‖
            AnchorLaw::RangeDifference { reference_m } => d - offset(p, &reference_m).1,
            // h = n·(p − a)
            AnchorLaw::Offset { normal } => {
                let (delta, _) = offset(p, &self.anchor_m);
                normal[0] * delta[0] + normal[1] * delta[1] + normal[2] * delta[2]
            }
        }
    }

    /// `∂h/∂p` at the tag position `p = [x, y, z]`.
    ///
    /// # Errors
    /// [`EstimationError::SingularMeasurement`] at an anchor, where the direction is undefined.
    pub(crate) fn gradient(&self, p: &[f64; 3]) -> rtls_estimation::Result<[f64; 3]> {
        // ∂(n·(p − a))/∂p = nᵀ, defined everywhere
        if let AnchorLaw::Offset { normal } = self.law {
            return Ok(normal);
        }
        let (delta, d) = offset(p, &self.anchor_m);
        let u = unit(&delta, d, "anchor measurement")?;
        Ok(match self.law {
            // ∂d/∂p = (p − a)ᵀ / d
            AnchorLaw::Range => u,
            // ∂ρ/∂p = −10 n / (ln 10 · d) · (p − a)ᵀ / d
            AnchorLaw::LogDistance { exponent, .. } => {
                let scale = -10.0 * exponent / (core::f64::consts::LN_10 * d);
                [scale * u[0], scale * u[1], scale * u[2]]
            }
            // ∂Δr/∂p = (p − a)ᵀ/‖p − a‖ − (p − b)ᵀ/‖p − b‖
            AnchorLaw::RangeDifference { reference_m } => {
                let (delta_b, d_b) = offset(p, &reference_m);
                let w = unit(&delta_b, d_b, "anchor measurement")?;
                [u[0] - w[0], u[1] - w[1], u[2] - w[2]]
            }
            AnchorLaw::Offset { normal } => normal,
        })
    }
}

impl<const N: usize> MeasurementModel<N> for AnchorMeasurement {
    fn dim(&self) -> usize {
        1
    }

    fn predict(&self, x: &Vector<N>) -> rtls_estimation::Result<DVector<f64>> {
        let p = tag_position(x, self.tag_height_m);
        Ok(DVector::from_element(1, self.value(&p)))
    }

    fn jacobian(&self, x: &Vector<N>) -> rtls_estimation::Result<MeasurementJacobian<N>> {
        let p = tag_position(x, self.tag_height_m);
        Ok(position_row::<N>(&self.gradient(&p)?))
    }

    fn noise_covariance(&self) -> &DMatrix<f64> {
        &self.variance
    }

    fn residuals(&self, points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
        rtls_estimation::measurement::subtract_from_columns(points, mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central-difference Jacobian of `h` (independent of the analytic one).
    fn numeric_jacobian<const N: usize>(model: &AnchorMeasurement, x: &Vector<N>) -> Vec<f64> {
        let step = 1e-6;
        (0..N)
            .map(|j| {
                let mut plus = *x;
                let mut minus = *x;
                plus[j] += step;
                minus[j] -= step;
                let hp = MeasurementModel::<N>::predict(model, &plus).unwrap()[0];
                let hm = MeasurementModel::<N>::predict(model, &minus).unwrap()[0];
                (hp - hm) / (2.0 * step)
            })
            .collect()
    }

    fn laws() -> [AnchorLaw; 4] {
        [
            AnchorLaw::Range,
            AnchorLaw::LogDistance {
                reference_power_dbm: -59.0,
                reference_distance_m: 1.0,
                exponent: 2.3,
            },
            AnchorLaw::RangeDifference {
                reference_m: [-4.0, 7.0, 3.0],
            },
            AnchorLaw::Offset {
                normal: [0.6, -0.8, 0.0],
            },
        ]
    }

    #[test]
    fn planar_models_use_the_slant_distance_at_the_tag_height() {
        // anchor 2.5 m up, tag at 1 m: Δz = 1.5; planar offset (3, 4) → d = √(25 + 2.25)
        let model = AnchorMeasurement::new([1.0, 2.0, 2.5], 1.0, AnchorLaw::Range, 0.01);
        let x = Vector::<4>::new(4.0, 0.3, 6.0, -0.2);
        let h = MeasurementModel::<4>::predict(&model, &x).unwrap()[0];
        assert!((h - 27.25f64.sqrt()).abs() < 1e-12);
        let rss = AnchorMeasurement::new([1.0, 2.0, 2.5], 1.0, laws()[1], 16.0);
        let h = MeasurementModel::<4>::predict(&rss, &x).unwrap()[0];
        assert!((h - (-59.0 - 23.0 * 27.25f64.sqrt().log10())).abs() < 1e-12);
    }

    #[test]
    fn analytic_jacobians_match_central_differences_in_2d_and_3d() {
        for law in laws() {
            let model = AnchorMeasurement::new([1.0, 2.0, 2.5], 0.8, law, 1.0);
            let x4 = Vector::<4>::new(4.0, 0.3, 6.0, -0.2);
            let analytic = MeasurementModel::<4>::jacobian(&model, &x4).unwrap();
            for (j, numeric) in numeric_jacobian(&model, &x4).into_iter().enumerate() {
                assert!((analytic[(0, j)] - numeric).abs() < 1e-6, "{law:?} column {j}");
            }
            let x6 = Vector::<6>::from_column_slice(&[4.0, 0.3, 6.0, -0.2, 0.5, 0.1]);
            let analytic = MeasurementModel::<6>::jacobian(&model, &x6).unwrap();
            for (j, numeric) in numeric_jacobian(&model, &x6).into_iter().enumerate() {
                assert!((analytic[(0, j)] - numeric).abs() < 1e-6, "{law:?} column {j}");
            }
        }
    }

    #[test]
    fn the_jacobian_at_the_anchor_is_an_error_not_a_nan() {
        let model = AnchorMeasurement::new([1.0, 2.0, 0.0], 0.0, AnchorLaw::Range, 1.0);
        let x = Vector::<4>::new(1.0, 0.0, 2.0, 0.0);
        assert!(matches!(
            MeasurementModel::<4>::jacobian(&model, &x),
            Err(EstimationError::SingularMeasurement { .. })
        ));
    }
}
