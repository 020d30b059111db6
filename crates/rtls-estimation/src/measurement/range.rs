//! Ranges to fixed anchors (TOA, UWB two-way ranging, ultrasonic time of flight), and the
//! anchor geometry shared by the range-type models (ranges, RSS, TDOA).

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::{MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;
use crate::math::sqrt;

/// Below this tag–anchor distance (m) the direction `(p − a)/d` is undefined.
pub(super) const MIN_DISTANCE_M: f64 = 1e-9;

/// State indices of the x, y, z positions (`2i` for axis `i`).
pub(super) const POSITION_INDICES: [usize; 3] = [0, 2, 4];

/// Checks and lifts planar anchors `(x, y)` to `(x, y, 0)`.
pub(super) fn planar_anchors(anchors: &[[f64; 2]]) -> Result<Vec<[f64; 3]>> {
    let lifted: Vec<[f64; 3]> = anchors.iter().map(|&[x, y]| [x, y, 0.0]).collect();
    spatial_anchors(&lifted)
}

/// Checks spatial anchors: at least one, all coordinates finite.
pub(super) fn spatial_anchors(anchors: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
    if anchors.is_empty() {
        return Err(EstimationError::InvalidParameter {
            name: "anchors",
            reason: "give at least one anchor",
        });
    }
    if anchors.iter().flatten().any(|c| !c.is_finite()) {
        return Err(EstimationError::NonFinite {
            what: "anchor coordinates",
        });
    }
    Ok(anchors.to_vec())
}

/// Checks that `noise` has `expected` components.
pub(super) fn check_noise_dim(noise: &NoiseCovariance, expected: usize) -> Result<()> {
    if noise.dim() == expected {
        Ok(())
    } else {
        Err(EstimationError::DimensionMismatch {
            what: "measurement noise covariance",
            expected,
            found: noise.dim(),
        })
    }
}

/// The tag position `p = (x[0], x[2], x[4])` (`x[4]` replaced by 0 for planar models).
///
/// Planar models need `N ≥ 4` (`[x, vx, y, vy]`), spatial ones `N ≥ 6` (`[x, vx, y, vy, z, vz]`).
pub(super) fn position_of<const N: usize>(x: &Vector<N>, spatial: bool) -> Result<[f64; 3]> {
    let needed = if spatial { 6 } else { 4 };
    if N < needed {
        return Err(EstimationError::DimensionMismatch {
            what: "state size (position/velocity pairs on every axis of the anchors)",
            expected: needed,
            found: N,
        });
    }
    let z = if spatial { x[POSITION_INDICES[2]] } else { 0.0 };
    Ok([x[POSITION_INDICES[0]], x[POSITION_INDICES[1]], z])
}

/// The offset `δ = p − a` from an anchor to the tag and its length `d = ‖δ‖` (m).
pub(super) fn offset(p: &[f64; 3], a: &[f64; 3]) -> ([f64; 3], f64) {
    // δ = p − a
    let delta = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    // d = √(δₓ² + δᵧ² + δ_z²)
    let distance_m = sqrt(delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]);
    (delta, distance_m)
}

/// `SingularMeasurement` for `model` when the tag is within `1e-9` m of an anchor.
pub(super) fn ensure_separated(distance_m: f64, model: &'static str) -> Result<()> {
    if distance_m.is_nan() || distance_m < MIN_DISTANCE_M {
        return Err(EstimationError::SingularMeasurement {
            model,
            reason: "the tag position coincides with an anchor (closer than 1e-9 m), \
                     where the direction to it is undefined",
        });
    }
    Ok(())
}

/// The unit vector `u = (p − a)/d`, or `SingularMeasurement` when `d < 1e-9` m.
pub(super) fn unit_vector(delta: &[f64; 3], distance_m: f64, model: &'static str) -> Result<[f64; 3]> {
    ensure_separated(distance_m, model)?;
    // u = δ / d
    Ok([delta[0] / distance_m, delta[1] / distance_m, delta[2] / distance_m])
}

/// Writes the position gradient `g` into row `row` of `H` (columns 0, 2 and, if spatial, 4).
pub(super) fn set_position_row<const N: usize>(
    h: &mut MeasurementJacobian<N>,
    row: usize,
    gradient: &[f64; 3],
    spatial: bool,
) {
    let axes = if spatial { 3 } else { 2 };
    for (axis, &g) in gradient.iter().enumerate().take(axes) {
        h[(row, POSITION_INDICES[axis])] = g;
    }
}

/// Ranges from the tag to fixed anchors: `rᵢ = ‖p − aᵢ‖ + vᵢ`, one component per anchor.
///
/// `p` is the tag position (state indices 0, 2 and, for spatial models, 4); `aᵢ` the anchor
/// positions. The Jacobian row of anchor `i` is the unit vector `(p − aᵢ)ᵀ/dᵢ` at the position
/// indices and 0 elsewhere. A single anchor is seed 003's single-observation EKF measurement;
/// several anchors give seed 001's TOA vector `z_TOA = [d₁ … d_k]ᵀ + a`.
///
/// Build one value per epoch over the anchors that answered (construction is cheap).
///
/// # Units
/// Anchors, positions and ranges in metres; `R` in m².
///
/// # Errors
/// [`MeasurementModel::predict`] and [`MeasurementModel::jacobian`] return
/// [`EstimationError::DimensionMismatch`] if the state is too small for the anchors (planar
/// needs `N ≥ 4`, spatial `N ≥ 6`); the Jacobian returns
/// [`EstimationError::SingularMeasurement`] (model `"ranges"`) when the tag is within `1e-9` m
/// of an anchor (the range itself is then defined, ≈ 0).
///
/// # Example
/// ```
/// use rtls_estimation::measurement::{MeasurementModel, NoiseCovariance, Ranges};
/// use rtls_estimation::Vector;
/// // Seed 001 scenario 1: base stations at (2, 2) and (20, 40) m, σ = 0.1 m.
/// let toa = Ranges::planar(&[[2.0, 2.0], [20.0, 40.0]], NoiseCovariance::isotropic(2, 0.01)?)?;
/// let x = Vector::<4>::new(5.0, 0.1, 6.0, 0.5); // [x, vx, y, vy]
/// let z = toa.predict(&x)?;
/// assert!((z[0] - 5.0).abs() < 1e-12); // ‖(3, 4)‖
/// let h = toa.jacobian(&x)?;
/// assert!((h[(0, 0)] - 0.6).abs() < 1e-12 && (h[(0, 2)] - 0.8).abs() < 1e-12);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 001, §2.1: `r_TOA = d_k + a_k`, `d_k = √((x − x_BS)² + (y − y_BS)²)`; seed 003,
/// eq. (6) (range) and eq. (8) (`H = [h₁₁, 0, h₁₃, 0]`, `h₁₁ = (x − xₐ)/d`, `h₁₃ = (y − yₐ)/d`).
#[derive(Debug, Clone, PartialEq)]
pub struct Ranges {
    anchors_m: Vec<[f64; 3]>,
    spatial: bool,
    noise: NoiseCovariance,
}

impl Ranges {
    /// Ranges to anchors in the plane (`(x, y)` in m), measured from the state's x and y
    /// (indices 0 and 2); `noise` has one component per anchor.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for an empty anchor list;
    /// [`EstimationError::NonFinite`] for a NaN/∞ coordinate;
    /// [`EstimationError::DimensionMismatch`] if `noise.dim()` is not the number of anchors.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{NoiseCovariance, Ranges};
    /// // Seed 003: one ultrasonic range per cycle to the scheduled node at (400, 600) cm.
    /// let sonar = Ranges::planar(&[[4.0, 6.0]], NoiseCovariance::isotropic(1, 0.0004)?)?;
    /// assert_eq!(sonar.anchors(), &[[4.0, 6.0, 0.0]]);
    /// assert!(Ranges::planar(&[], NoiseCovariance::isotropic(1, 1.0)?).is_err());
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 003, eq. (6)–(8).
    pub fn planar(anchors: &[[f64; 2]], noise: NoiseCovariance) -> Result<Self> {
        let anchors_m = planar_anchors(anchors)?;
        check_noise_dim(&noise, anchors_m.len())?;
        Ok(Self {
            anchors_m,
            spatial: false,
            noise,
        })
    }

    /// Ranges to anchors in space (`(x, y, z)` in m), measured from the state's x, y, z
    /// (indices 0, 2, 4; the state needs `N ≥ 6`).
    ///
    /// # Errors
    /// As [`Ranges::planar`].
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{MeasurementModel, NoiseCovariance, Ranges};
    /// use rtls_estimation::Vector;
    /// let uwb = Ranges::spatial(&[[0.0, 0.0, 3.0]], NoiseCovariance::isotropic(1, 0.01)?)?;
    /// let x = Vector::<6>::from_column_slice(&[4.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    /// assert!((uwb.predict(&x)?[0] - 5.0).abs() < 1e-12); // ‖(4, 0, −3)‖
    /// assert!(uwb.predict(&Vector::<4>::zeros()).is_err()); // a 2-D state has no z
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn spatial(anchors: &[[f64; 3]], noise: NoiseCovariance) -> Result<Self> {
        let anchors_m = spatial_anchors(anchors)?;
        check_noise_dim(&noise, anchors_m.len())?;
        Ok(Self {
            anchors_m,
            spatial: true,
            noise,
        })
    }

    /// Anchor positions `(x, y, z)` in m, in measurement order (`z = 0` for planar models).
    #[inline]
    #[must_use]
    pub fn anchors(&self) -> &[[f64; 3]] {
        &self.anchors_m
    }

    /// Whether the model is spatial (3-D) rather than planar.
    #[inline]
    #[must_use]
    pub fn is_spatial(&self) -> bool {
        self.spatial
    }

    /// The measurement noise covariance.
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }
}

impl<const N: usize> MeasurementModel<N> for Ranges {
    #[inline]
    fn dim(&self) -> usize {
        self.anchors_m.len()
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        let p = position_of(x, self.spatial)?;
        // rᵢ = ‖p − aᵢ‖
        Ok(DVector::from_iterator(
            self.anchors_m.len(),
            self.anchors_m.iter().map(|a| offset(&p, a).1),
        ))
    }

    fn jacobian(&self, x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        let p = position_of(x, self.spatial)?;
        let mut h = MeasurementJacobian::<N>::zeros(self.anchors_m.len());
        for (row, a) in self.anchors_m.iter().enumerate() {
            let (delta, distance_m) = offset(&p, a);
            // ∂rᵢ/∂p = (p − aᵢ)ᵀ / dᵢ
            let u = unit_vector(&delta, distance_m, "ranges")?;
            set_position_row(&mut h, row, &u, self.spatial);
        }
        Ok(h)
    }

    #[inline]
    fn noise_covariance(&self) -> &DMatrix<f64> {
        self.noise.matrix()
    }

    fn residuals(&self, points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
        super::subtract_from_columns(points, mean)
    }
}

/// Shared test helpers: finite-difference Jacobian checks and reproducible test states.
#[cfg(test)]
pub(super) mod testing {
    use alloc::vec::Vec;

    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::super::MeasurementModel;
    use crate::gaussian::Vector;

    /// Central-difference step.
    const STEP: f64 = 1e-6;
    /// Relative tolerance (absolute below 1).
    const TOLERANCE: f64 = 1e-6;

    /// `count` reproducible states with entries uniform in `[−scale, scale]`.
    pub(crate) fn random_states<const N: usize>(seed: u64, count: usize, scale: f64) -> Vec<Vector<N>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..count)
            .map(|_| Vector::<N>::from_fn(|_, _| rng.gen_range(-scale..scale)))
            .collect()
    }

    /// Asserts that the analytic Jacobian equals central finite differences
    /// `(h(x + εeⱼ) ⊖ h(x − εeⱼ)) / 2ε` (⊖ = the model's residual, so angles wrap).
    pub(crate) fn assert_jacobian_matches_finite_differences<const N: usize, M: MeasurementModel<N>>(
        model: &M,
        x: &Vector<N>,
    ) {
        let analytic = model.jacobian(x).expect("analytic jacobian");
        assert_eq!(analytic.nrows(), model.dim());
        for j in 0..N {
            let mut plus = *x;
            let mut minus = *x;
            plus[j] += STEP;
            minus[j] -= STEP;
            let difference = model.residual(&model.predict(&plus).unwrap(), &model.predict(&minus).unwrap());
            for i in 0..model.dim() {
                let numeric = difference[i] / (2.0 * STEP);
                let exact = analytic[(i, j)];
                assert!(
                    (numeric - exact).abs() <= TOLERANCE * exact.abs().max(1.0),
                    "H[{i}, {j}] = {exact}, finite differences give {numeric} at x = {x:?}"
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{assert_jacobian_matches_finite_differences, random_states};
    use super::*;

    fn noise(dim: usize) -> NoiseCovariance {
        NoiseCovariance::isotropic(dim, 0.01).unwrap()
    }

    #[test]
    fn planar_ranges_and_jacobian_match_seed_003() {
        let model = Ranges::planar(&[[2.0, 2.0], [20.0, 40.0]], noise(2)).unwrap();
        let x = Vector::<4>::new(5.0, 0.7, 6.0, -0.3);
        let z = model.predict(&x).unwrap();
        assert!((z[0] - 5.0).abs() < 1e-12);
        assert!((z[1] - sqrt(15.0 * 15.0 + 34.0 * 34.0)).abs() < 1e-12);
        let h = model.jacobian(&x).unwrap();
        // H = [h₁₁, 0, h₁₃, 0], h₁₁ = (x − xₐ)/d, h₁₃ = (y − yₐ)/d
        assert_eq!(h.nrows(), 2);
        assert!((h[(0, 0)] - 0.6).abs() < 1e-12);
        assert!((h[(0, 2)] - 0.8).abs() < 1e-12);
        assert_eq!(h[(0, 1)], 0.0);
        assert_eq!(h[(0, 3)], 0.0);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let anchors = [[0.0, 0.0], [10.0, 0.0], [3.0, 8.0], [-4.0, 5.0]];
        let planar = Ranges::planar(&anchors, noise(4)).unwrap();
        for x in random_states::<4>(1, 20, 20.0) {
            assert_jacobian_matches_finite_differences(&planar, &x);
        }
        // The same planar model on a CA state [x, vx, y, vy, ax, ay].
        for x in random_states::<6>(2, 10, 20.0) {
            assert_jacobian_matches_finite_differences(&planar, &x);
        }
        let spatial = Ranges::spatial(&[[0.0, 0.0, 3.0], [10.0, 1.0, 2.5], [4.0, 9.0, 0.0]], noise(3)).unwrap();
        for x in random_states::<6>(3, 20, 20.0) {
            assert_jacobian_matches_finite_differences(&spatial, &x);
        }
        for x in random_states::<9>(4, 10, 20.0) {
            assert_jacobian_matches_finite_differences(&spatial, &x);
        }
    }

    #[test]
    fn jacobian_at_an_anchor_is_an_error_not_nan() {
        let model = Ranges::planar(&[[1.0, 2.0], [5.0, 5.0]], noise(2)).unwrap();
        let x = Vector::<4>::new(1.0, 3.0, 2.0, -1.0);
        assert!(matches!(
            model.jacobian(&x),
            Err(EstimationError::SingularMeasurement { model: "ranges", .. })
        ));
        // The range itself is defined there.
        assert_eq!(model.predict(&x).unwrap()[0], 0.0);
        let near = Vector::<4>::new(1.0 + 1e-10, 0.0, 2.0, 0.0);
        assert!(model.jacobian(&near).is_err());
    }

    #[test]
    fn spatial_ranges_need_a_3d_state() {
        let model = Ranges::spatial(&[[0.0, 0.0, 3.0]], noise(1)).unwrap();
        assert!(matches!(
            model.predict(&Vector::<4>::zeros()),
            Err(EstimationError::DimensionMismatch {
                expected: 6,
                found: 4,
                ..
            })
        ));
        assert!(matches!(
            MeasurementModel::<5>::jacobian(&model, &Vector::<5>::zeros()),
            Err(EstimationError::DimensionMismatch {
                expected: 6,
                found: 5,
                ..
            })
        ));
        let planar = Ranges::planar(&[[0.0, 0.0]], noise(1)).unwrap();
        assert!(matches!(
            planar.predict(&Vector::<2>::zeros()),
            Err(EstimationError::DimensionMismatch {
                expected: 4,
                found: 2,
                ..
            })
        ));
        let x = Vector::<6>::from_column_slice(&[4.0, 9.0, 0.0, 9.0, 0.0, 9.0]);
        assert!((model.predict(&x).unwrap()[0] - 5.0).abs() < 1e-12);
        let h = model.jacobian(&x).unwrap();
        assert!((h[(0, 0)] - 0.8).abs() < 1e-12);
        assert!((h[(0, 4)] + 0.6).abs() < 1e-12);
    }

    #[test]
    fn bad_constructors_are_rejected() {
        assert!(matches!(
            Ranges::planar(&[], noise(1)),
            Err(EstimationError::InvalidParameter { name: "anchors", .. })
        ));
        assert!(matches!(
            Ranges::spatial(&[[0.0, f64::NAN, 0.0]], noise(1)),
            Err(EstimationError::NonFinite {
                what: "anchor coordinates"
            })
        ));
        assert!(matches!(
            Ranges::planar(&[[0.0, 0.0], [1.0, f64::INFINITY]], noise(2)),
            Err(EstimationError::NonFinite { .. })
        ));
        assert_eq!(
            Ranges::planar(&[[0.0, 0.0], [1.0, 1.0]], noise(3)),
            Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: 2,
                found: 3
            })
        );
    }
}
