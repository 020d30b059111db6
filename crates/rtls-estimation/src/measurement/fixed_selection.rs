//! A measurement of `M` selected state components with sizes known at compile time: the
//! position fix (or velocity) of a constant-velocity track, updated without heap allocation
//! by [`KalmanFilter::update_fixed`](crate::filter::KalmanFilter::update_fixed).

use nalgebra::{SMatrix, SVector};

use super::noise_covariance::checked_covariance;
use super::position::check_indices;
use crate::error::Result;
use crate::gaussian::Vector;

/// `z = H x + v` with row `r` of `H` the unit row selecting state index `indices[r]`, and
/// `v ~ N(0, R)`: [`ComponentSelection`](super::ComponentSelection) with a fixed number of
/// components `M` (1, 2 or 3 for a position fix), so `H`, `R`, `S` and `K` live on the stack.
///
/// # Units
/// Those of the selected state components (m for positions, m/s for velocities); `R` in their
/// squares.
///
/// # Example
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use rtls_estimation::measurement::FixedSelection;
/// use rtls_estimation::Vector;
/// // x and y of a 2-D constant-velocity state [x, vx, y, vy], σ = 0.2 m
/// let fix = FixedSelection::<4, 2>::new([0, 2], Matrix2::identity() * 0.04)?;
/// assert_eq!(fix.predict(&Vector::<4>::new(1.0, 0.5, 2.0, -0.5)), Vector2::new(1.0, 2.0));
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 000, measurement `Z = H X + V` with `H` picking x, y, z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedSelection<const N: usize, const M: usize> {
    indices: [usize; M],
    noise: SMatrix<f64, M, M>,
}

impl<const N: usize, const M: usize> FixedSelection<N, M> {
    /// Measures the state components `indices` (in that order) with noise covariance `noise`,
    /// checked and symmetrised as [`NoiseCovariance::full`](super::NoiseCovariance::full) does.
    ///
    /// # Errors
    /// First the noise's, as [`NoiseCovariance::full`](super::NoiseCovariance::full) (an empty
    /// `R` when `M` is 0); then [`EstimationError::InvalidParameter`](crate::EstimationError::InvalidParameter) naming `indices` if an
    /// index is not below `N` or an index repeats (the errors and order of
    /// `NoiseCovariance::full` followed by `ComponentSelection::new`).
    pub fn new(indices: [usize; M], noise: SMatrix<f64, M, M>) -> Result<Self> {
        let noise = checked_covariance(noise)?;
        check_indices::<N>(&indices)?;
        Ok(Self { indices, noise })
    }

    /// The selected state indices, in measurement order.
    #[must_use]
    pub fn indices(&self) -> &[usize; M] {
        &self.indices
    }

    /// `R`, symmetric positive definite.
    #[must_use]
    pub fn noise(&self) -> &SMatrix<f64, M, M> {
        &self.noise
    }

    /// `ẑ = H x`: the selected components of `x`.
    #[must_use]
    pub fn predict(&self, x: &Vector<N>) -> SVector<f64, M> {
        SVector::<f64, M>::from_fn(|r, _| x[self.indices[r]])
    }
}
