//! Linear observations of the planar constant-velocity state, kept so that a variable-dimension
//! filter can re-filter them with a larger model.

use nalgebra::{DMatrix, DVector, Dyn};

use crate::error::{EstimationError, Result};
use crate::measurement::{LinearMeasurementModel, MeasurementJacobian, MeasurementModel, NoiseCovariance};
use crate::Vector;

/// One linear measurement of the CV state `[x, vx, y, vy]` at `time_s`: `z = H x + v`,
/// `v ~ N(0, R)`, with `H` of size `m × 4`.
///
/// Seed 004 observes the whole CV state (`H = I₄`): position from the TDOA fix, velocity from
/// speed and heading ([`crate::aided::OdometryErrorModel::velocity`]); a fix without odometry
/// is `H = [[1,0,0,0],[0,0,1,0]]`. In the manoeuvre model `[x, vx, y, vy, ax, ay]` the same
/// observation has `Hᵐ = [H | 0]` (seed 004, `Hᵐ`).
///
/// # Units
/// As the components of `z` (m, m/s); `time_s` in s.
///
/// # Example
/// ```
/// use rtls_estimation::manoeuvre::LinearObservation;
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use nalgebra::DVector;
/// let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 900.0)?)?;
/// let obs = LinearObservation::from_model(3.0, &fix, DVector::from_vec(vec![10.0, 20.0]))?;
/// assert_eq!(obs.dim(), 2);
/// assert!(LinearObservation::from_model(3.0, &fix, DVector::from_vec(vec![1.0])).is_err());
/// // it is its own linear model of the CV state
/// use rtls_estimation::filter::KalmanFilter;
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// let prior = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::identity() * 100.0, 3.0)?;
/// let posterior = KalmanFilter::default().update(&prior, &obs, obs.z())?.state;
/// assert!(posterior.mean()[0] > 0.0);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct LinearObservation {
    time_s: f64,
    z: DVector<f64>,
    matrix: MeasurementJacobian<4>,
    noise: DMatrix<f64>,
}

impl LinearObservation {
    /// An observation `z` at `time_s` with matrix `H` (`m × 4`) and noise `R`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `z`, `H` and `R` disagree on `m`;
    /// [`EstimationError::NonFinite`] for NaN/∞ in `z`, `H` or the time.
    pub fn new(time_s: f64, z: DVector<f64>, matrix: MeasurementJacobian<4>, noise: &NoiseCovariance) -> Result<Self> {
        if !time_s.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "observation time",
            });
        }
        crate::math::ensure_finite(&z, "observation vector")?;
        crate::math::ensure_finite(&matrix, "observation matrix")?;
        if matrix.nrows() != z.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "observation matrix rows",
                expected: z.len(),
                found: matrix.nrows(),
            });
        }
        if noise.dim() != z.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "observation noise covariance",
                expected: z.len(),
                found: noise.dim(),
            });
        }
        Ok(Self {
            time_s,
            z,
            matrix,
            noise: noise.matrix().clone(),
        })
    }

    /// The observation `z` of a linear model of the CV state at `time_s`.
    ///
    /// # Errors
    /// As [`LinearObservation::new`].
    pub fn from_model<H: LinearMeasurementModel<4>>(time_s: f64, model: &H, z: DVector<f64>) -> Result<Self> {
        if z.len() != model.dim() {
            return Err(EstimationError::DimensionMismatch {
                what: "observation vector",
                expected: model.dim(),
                found: z.len(),
            });
        }
        let noise = NoiseCovariance::full(model.noise_covariance().clone())?;
        Self::new(time_s, z, model.matrix().clone(), &noise)
    }

    /// Time stamp (s).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Number of components `m`.
    #[must_use]
    pub fn dim(&self) -> usize {
        self.z.len()
    }

    /// The measured vector `z`.
    #[must_use]
    pub fn z(&self) -> &DVector<f64> {
        &self.z
    }

    /// The noise covariance `R` (`m × m`).
    #[must_use]
    pub fn noise(&self) -> &DMatrix<f64> {
        &self.noise
    }

    /// The model of this observation for an `N`-entry state whose first four entries are the CV
    /// state: `H_N = [H | 0]` (for the CV state itself the observation is its own model).
    pub(crate) fn model<const N: usize>(&self) -> PaddedObservation<N> {
        let mut matrix = MeasurementJacobian::<N>::zeros_generic(Dyn(self.dim()), nalgebra::Const::<N>);
        // H_N = [H | 0]
        matrix.columns_mut(0, 4).copy_from(&self.matrix);
        PaddedObservation {
            matrix,
            noise: self.noise.clone(),
        }
    }
}

/// The observation is its own linear model of the CV state (`H`, `R`), so a KF updates with it
/// directly: `kf.update(&prior, &observation, observation.z())`.
impl MeasurementModel<4> for LinearObservation {
    fn dim(&self) -> usize {
        self.z.len()
    }
    fn predict(&self, x: &Vector<4>) -> Result<DVector<f64>> {
        // ẑ = H x
        Ok(&self.matrix * x)
    }
    fn jacobian(&self, _x: &Vector<4>) -> Result<MeasurementJacobian<4>> {
        Ok(self.matrix.clone())
    }
    fn noise_covariance(&self) -> &DMatrix<f64> {
        &self.noise
    }
}

impl LinearMeasurementModel<4> for LinearObservation {
    fn matrix(&self) -> &MeasurementJacobian<4> {
        &self.matrix
    }
}

/// `z = [H | 0] x + v` over an `N`-entry state.
pub(crate) struct PaddedObservation<const N: usize> {
    matrix: MeasurementJacobian<N>,
    noise: DMatrix<f64>,
}

impl<const N: usize> MeasurementModel<N> for PaddedObservation<N> {
    fn dim(&self) -> usize {
        self.matrix.nrows()
    }
    fn predict(&self, x: &Vector<N>) -> Result<DVector<f64>> {
        Ok(&self.matrix * x)
    }
    fn jacobian(&self, _x: &Vector<N>) -> Result<MeasurementJacobian<N>> {
        Ok(self.matrix.clone())
    }
    fn noise_covariance(&self) -> &DMatrix<f64> {
        &self.noise
    }
}

impl<const N: usize> LinearMeasurementModel<N> for PaddedObservation<N> {
    fn matrix(&self) -> &MeasurementJacobian<N> {
        &self.matrix
    }
}
