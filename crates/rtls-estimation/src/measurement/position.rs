//! Linear measurements that pick state components: position fixes, position + velocity.

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::{LinearMeasurementModel, MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;

/// A measurement of selected state components: `z = H x + v`, where row `r` of `H` is the unit
/// row selecting state index `indices[r]`.
///
/// Covers position fixes from any positioning method (seed 000: `H` picks x, y, z; seed 002:
/// the L-WKNN fix) and seed 004's fused `[x, vx, y, vy]` measurement (`H = I₄`).
///
/// # Units
/// Those of the selected state components (m for positions, m/s for velocities).
///
/// # Example
/// ```
/// use nalgebra::DVector;
/// use rtls_estimation::measurement::{ComponentSelection, MeasurementModel, NoiseCovariance};
/// use rtls_estimation::Vector;
/// // Pick x and y of a 2-D constant-velocity state [x, vx, y, vy].
/// let fix = ComponentSelection::<4>::new(&[0, 2], NoiseCovariance::isotropic(2, 5.0)?)?;
/// let z = fix.predict(&Vector::<4>::new(1.0, 0.5, 2.0, -0.5))?;
/// assert_eq!(z, DVector::from_vec(vec![1.0, 2.0]));
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 000, measurement `Z = H X + V` with `H` picking x, y, z; seed 004, eq. (9), `H = I₄`.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentSelection<const N: usize> {
    indices: Vec<usize>,
    h: MeasurementJacobian<N>,
    noise: NoiseCovariance,
}

impl<const N: usize> ComponentSelection<N> {
    /// Measures the state components `indices` (in that order) with noise covariance `noise`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `indices` is empty, an index is not below `N`
    /// or an index repeats; [`EstimationError::DimensionMismatch`] if `noise.dim()` differs
    /// from `indices.len()`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    /// let r = NoiseCovariance::isotropic(1, 1.0)?;
    /// assert!(ComponentSelection::<4>::new(&[3], r.clone()).is_ok());
    /// assert!(ComponentSelection::<4>::new(&[4], r).is_err()); // index out of the state
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn new(indices: &[usize], noise: NoiseCovariance) -> Result<Self> {
        if indices.is_empty() {
            return Err(EstimationError::InvalidParameter {
                name: "indices",
                reason: "select at least one state component",
            });
        }
        check_indices::<N>(indices)?;
        if noise.dim() != indices.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: indices.len(),
                found: noise.dim(),
            });
        }
        // H[r, indices[r]] = 1, zero elsewhere.
        let mut h = MeasurementJacobian::<N>::zeros(indices.len());
        for (row, &i) in indices.iter().enumerate() {
            h[(row, i)] = 1.0;
        }
        Ok(Self {
            indices: indices.to_vec(),
            h,
            noise,
        })
    }

    /// A position fix on `axes` axes (1, 2 or 3): `z = [x, y, z]` truncated, state indices
    /// `0, 2, 4` (the position of each position/velocity pair).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `axes` is not 1, 2 or 3, or the state is too
    /// small (`N < 2·axes − 1`); [`EstimationError::DimensionMismatch`] if `noise.dim() ≠ axes`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    /// // Seed 000: 3-D fix of [x, vx, y, vy, z, vz], R = σ_v² I₃, σ_v² = 5 m².
    /// let fix = ComponentSelection::<6>::position(3, NoiseCovariance::isotropic(3, 5.0)?)?;
    /// assert_eq!(fix.indices(), &[0, 2, 4]);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 000, measurement matrix `H` picking x, y, z of the CV state.
    pub fn position(axes: usize, noise: NoiseCovariance) -> Result<Self> {
        let axes = Self::axis_count(axes)?;
        // Position of axis i sits at state index 2i.
        let positions: Vec<usize> = (0..axes).map(|axis| 2 * axis).collect();
        Self::new(&positions, noise)
    }

    /// Position and velocity on `axes` axes (1, 2 or 3): `z = [x, vx, y, vy, z, vz]` truncated
    /// to `2·axes` components, state indices `0 .. 2·axes` (seed 004 for `axes = 2`, `H = I₄`).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `axes` is not 1, 2 or 3, or `N < 2·axes`;
    /// [`EstimationError::DimensionMismatch`] if `noise.dim() ≠ 2·axes`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    /// // Seed 004: TDOA position (σ = 50 m) and odometry velocity (σ = 1 m/s) on [x, vx, y, vy].
    /// let r = NoiseCovariance::diagonal(&[2500.0, 1.0, 2500.0, 1.0])?;
    /// let fused = ComponentSelection::<4>::position_velocity(2, r)?;
    /// assert_eq!(fused.indices(), &[0, 1, 2, 3]);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    ///
    /// # References
    /// Seed 004, eq. (9): `Z = H X + V`, `Z = [zx, zvx, zy, zvy]ᵀ`, `H = I₄`.
    pub fn position_velocity(axes: usize, noise: NoiseCovariance) -> Result<Self> {
        let axes = Self::axis_count(axes)?;
        // Position and velocity of axis i sit at 2i and 2i + 1.
        let pairs: Vec<usize> = (0..2 * axes).collect();
        Self::new(&pairs, noise)
    }

    /// The selected state indices, in measurement order.
    #[inline]
    #[must_use]
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// The measurement noise covariance.
    #[inline]
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }

    /// Checks an axis count of 1, 2 or 3.
    fn axis_count(axes: usize) -> Result<usize> {
        if (1..=3).contains(&axes) {
            Ok(axes)
        } else {
            Err(EstimationError::InvalidParameter {
                name: "axes",
                reason: "the number of axes must be 1, 2 or 3",
            })
        }
    }
}

impl<const N: usize> MeasurementModel<N> for ComponentSelection<N> {
    #[inline]
    fn dim(&self) -> usize {
        self.indices.len()
    }

    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        // z = H x, i.e. zᵣ = x[indices[r]]
        Ok(DVector::from_iterator(
            self.indices.len(),
            self.indices.iter().map(|&i| x[i]),
        ))
    }

    fn jacobian(&self, _x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        Ok(self.h.clone())
    }

    #[inline]
    fn noise_covariance(&self) -> &DMatrix<f64> {
        self.noise.matrix()
    }

    fn residuals(&self, points: &DMatrix<f64>, mean: &DVector<f64>) -> DMatrix<f64> {
        super::subtract_from_columns(points, mean)
    }
}

impl<const N: usize> LinearMeasurementModel<N> for ComponentSelection<N> {
    #[inline]
    fn matrix(&self) -> &MeasurementJacobian<N> {
        &self.h
    }
}

/// State indices a measurement selects: each below `N`, none repeated.
///
/// # Errors
/// [`EstimationError::InvalidParameter`] naming `indices`.
pub(crate) fn check_indices<const N: usize>(indices: &[usize]) -> Result<()> {
    if indices.iter().any(|&i| i >= N) {
        return Err(EstimationError::InvalidParameter {
            name: "indices",
            reason: "every index must be below the state dimension N",
        });
    }
    if indices.iter().enumerate().any(|(k, i)| indices[..k].contains(i)) {
        return Err(EstimationError::InvalidParameter {
            name: "indices",
            reason: "an index appears more than once",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(dim: usize) -> NoiseCovariance {
        NoiseCovariance::isotropic(dim, 2.0).unwrap()
    }

    #[test]
    fn position_picks_even_indices_and_h_is_a_selector() {
        let fix = ComponentSelection::<6>::position(3, noise(3)).unwrap();
        assert_eq!(fix.indices(), &[0, 2, 4]);
        let x = Vector::<6>::from_column_slice(&[1.0, 10.0, 2.0, 20.0, 3.0, 30.0]);
        assert_eq!(fix.predict(&x).unwrap(), DVector::from_vec(alloc::vec![1.0, 2.0, 3.0]));
        let h = fix.matrix();
        assert_eq!(h.nrows(), 3);
        assert_eq!(h * x, fix.predict(&x).unwrap());
        assert_eq!(h[(1, 2)], 1.0);
        assert_eq!(h[(1, 1)], 0.0);
        assert_eq!(&fix.jacobian(&x).unwrap(), h);
        assert_eq!(MeasurementModel::<6>::dim(&fix), 3);
        assert_eq!(fix.noise_covariance()[(2, 2)], 2.0);
    }

    #[test]
    fn position_velocity_is_the_identity_on_seed_004_state() {
        let fused = ComponentSelection::<4>::position_velocity(2, noise(4)).unwrap();
        assert_eq!(fused.matrix(), &MeasurementJacobian::<4>::identity(4));
        // On a CA state [x, vx, y, vy, ax, ay] it is seed 004's Hm (first four states).
        let hm = ComponentSelection::<6>::position_velocity(2, noise(4)).unwrap();
        let x = Vector::<6>::from_column_slice(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(
            hm.predict(&x).unwrap(),
            DVector::from_vec(alloc::vec![1.0, 2.0, 3.0, 4.0])
        );
    }

    #[test]
    fn arbitrary_order_is_kept() {
        let sel = ComponentSelection::<4>::new(&[3, 0], noise(2)).unwrap();
        let x = Vector::<4>::new(1.0, 2.0, 3.0, 4.0);
        assert_eq!(sel.predict(&x).unwrap(), DVector::from_vec(alloc::vec![4.0, 1.0]));
        assert_eq!(sel.matrix()[(0, 3)], 1.0);
        assert_eq!(sel.matrix()[(1, 0)], 1.0);
    }

    #[test]
    fn bad_constructors_are_rejected() {
        assert!(matches!(
            ComponentSelection::<4>::new(&[], noise(1)),
            Err(EstimationError::InvalidParameter { name: "indices", .. })
        ));
        assert!(matches!(
            ComponentSelection::<4>::new(&[0, 4], noise(2)),
            Err(EstimationError::InvalidParameter { name: "indices", .. })
        ));
        assert!(matches!(
            ComponentSelection::<4>::new(&[1, 1], noise(2)),
            Err(EstimationError::InvalidParameter { name: "indices", .. })
        ));
        assert_eq!(
            ComponentSelection::<4>::new(&[0, 2], noise(3)),
            Err(EstimationError::DimensionMismatch {
                what: "measurement noise covariance",
                expected: 2,
                found: 3
            })
        );
        assert!(matches!(
            ComponentSelection::<6>::position(0, noise(1)),
            Err(EstimationError::InvalidParameter { name: "axes", .. })
        ));
        assert!(matches!(
            ComponentSelection::<6>::position(4, noise(4)),
            Err(EstimationError::InvalidParameter { name: "axes", .. })
        ));
        // 3 axes need index 4: not in a 4-state.
        assert!(ComponentSelection::<4>::position(3, noise(3)).is_err());
        assert!(ComponentSelection::<4>::position_velocity(3, noise(6)).is_err());
    }
}
