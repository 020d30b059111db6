//! IMM modes: a motion model, a measurement model and a Kalman-type filter of any state size,
//! behind one object-safe interface on dynamically sized estimates.

use alloc::string::String;

use core::marker::PhantomData;

use nalgebra::{DMatrix, DVector};

use super::layout::{check_estimate, Component, StateLayout};
use crate::error::{EstimationError, Result};
use crate::filter::GaussianFilter;
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::measurement::{ComponentSelection, NoiseCovariance};

/// A mode-conditioned estimate in its mode's [`StateLayout`] (the size varies between modes).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ModeEstimate {
    /// Mean, one entry per layout component.
    pub mean: DVector<f64>,
    /// Covariance (symmetric positive semi-definite).
    pub covariance: DMatrix<f64>,
}

impl ModeEstimate {
    /// Keeps entry `index` physically plausible: a mean beyond `±max_abs` is clamped to it,
    /// and a variance beyond `max_abs²` is brought down to it by scaling the entry's row and
    /// column,
    /// ```text
    /// x̂ᵢ  ← clamp(x̂ᵢ, −m, m)
    /// k   = min(1, m / √Pᵢᵢ)
    /// P   ← D P D,   D = diag(1, …, k (at i), …, 1)
    /// ```
    /// which keeps `P` symmetric positive semi-definite (a congruence) and the other entries'
    /// variances unchanged. Used for a turn rate `ω`, which the position observes only through
    /// the curvature of the track: while a track coasts or its motion is straight, nothing
    /// holds `ω` and a coordinated-turn mode can drift to rates no target has.
    ///
    /// Returns `true` when anything changed.
    ///
    /// # Units
    /// Those of the entry (`max_abs` in rad/s for a turn rate).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for an `index` outside the estimate or a
    /// `max_abs` that is not positive and finite.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::imm::ModeEstimate;
    /// use nalgebra::{DMatrix, DVector};
    /// let mut estimate = ModeEstimate {
    ///     mean: DVector::from_vec(vec![1.0, 40.0]),
    ///     covariance: DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 100.0]),
    /// };
    /// assert!(estimate.bound_component(1, 2.0)?);
    /// assert_eq!(estimate.mean[1], 2.0);
    /// assert!((estimate.covariance[(1, 1)] - 4.0).abs() < 1e-12);
    /// assert!((estimate.covariance[(0, 1)] - 0.4).abs() < 1e-12);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn bound_component(&mut self, index: usize, max_abs: f64) -> Result<bool> {
        if index >= self.mean.len() || index >= self.covariance.nrows() {
            return Err(EstimationError::InvalidParameter {
                name: "index",
                reason: "the bounded entry must be inside the estimate",
            });
        }
        if !(max_abs.is_finite() && max_abs > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "max_abs",
                reason: "the bound must be positive and finite",
            });
        }
        let mut changed = false;
        // x̂ᵢ ← clamp(x̂ᵢ, −m, m)
        let clamped = self.mean[index].clamp(-max_abs, max_abs);
        if clamped != self.mean[index] {
            self.mean[index] = clamped;
            changed = true;
        }
        let variance = self.covariance[(index, index)];
        if variance > max_abs * max_abs {
            // k = m / √Pᵢᵢ; P ← D P D
            let k = max_abs / crate::math::sqrt(variance);
            self.covariance.row_mut(index).scale_mut(k);
            self.covariance.column_mut(index).scale_mut(k);
            changed = true;
        }
        Ok(changed)
    }

    /// The estimate of a statically sized [`Gaussian`] (its time is kept by the IMM state).
    #[must_use]
    pub fn from_gaussian<const N: usize>(state: &Gaussian<N>) -> Self {
        Self {
            mean: DVector::from_column_slice(state.mean().as_slice()),
            covariance: DMatrix::from_column_slice(N, N, state.covariance().as_slice()),
        }
    }

    /// The statically sized [`Gaussian`] at `time_s`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if the estimate does not have `N` entries; the
    /// errors of [`Gaussian::new`] for non-finite or asymmetric values.
    pub fn to_gaussian<const N: usize>(&self, time_s: f64) -> Result<Gaussian<N>> {
        check_estimate(&self.mean, &self.covariance, N, "mode estimate")?;
        Gaussian::new(
            Vector::<N>::from_column_slice(self.mean.as_slice()),
            Matrix::<N>::from_column_slice(self.covariance.as_slice()),
            time_s,
        )
    }
}

/// The result of a mode-matched measurement update.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeUpdate {
    /// The mode-conditioned posterior.
    pub estimate: ModeEstimate,
    /// `ln Λⱼ = ln N(ν; 0, S)`: the measurement log-likelihood under this mode.
    pub log_likelihood: f64,
    /// `νᵀ S⁻¹ ν` under this mode.
    pub nis: f64,
}

/// One mode of an interacting multiple model filter: a state layout, a prediction and a
/// measurement update. Object safe, so modes of different state sizes and filter kinds live
/// in one `Vec<Box<dyn ImmMode>>`. `Send + Sync`, so one IMM serves tracks on many threads.
///
/// [`FilterMode`] implements it for any motion model, measurement model and KF/EKF/UKF.
pub trait ImmMode: Send + Sync {
    /// A short name for reports ("CV", "CA", "CT").
    fn name(&self) -> &str;
    /// The meaning of each state entry.
    fn layout(&self) -> &StateLayout;
    /// Mode-matched prediction from `from_time_s` to `to_time_s`.
    ///
    /// # Errors
    /// The filter's prediction errors.
    fn predict(&self, estimate: &ModeEstimate, from_time_s: f64, to_time_s: f64) -> Result<ModeEstimate>;
    /// Mode-matched update with measurement `z` at `time_s`.
    ///
    /// # Errors
    /// The filter's update errors.
    fn update(&self, prior: &ModeEstimate, time_s: f64, z: &DVector<f64>) -> Result<ModeUpdate>;
    /// Mode-matched update with a direct observation of layout components (a position fix, a
    /// velocity from odometry) whose noise may change every epoch.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if the mode's layout lacks an observed component;
    /// the filter's update errors.
    fn update_components(
        &self,
        prior: &ModeEstimate,
        time_s: f64,
        observation: &ComponentObservation,
    ) -> Result<ModeUpdate>;
}

/// A direct, linear observation of named state components, `z = x[components] + v`,
/// `v ~ N(0, R)`: every IMM mode whose layout has the components can use it, whatever its
/// state size, and `R` may change every epoch (e.g. a TDOA fix's covariance).
///
/// # Example
/// ```
/// use rtls_estimation::imm::{Axis, Component, ComponentObservation};
/// use rtls_estimation::measurement::NoiseCovariance;
/// use nalgebra::DVector;
/// let fix = ComponentObservation::new(
///     vec![Component::Position(Axis::X), Component::Position(Axis::Y)],
///     DVector::from_vec(vec![12.0, -3.0]),
///     NoiseCovariance::isotropic(2, 900.0)?,
/// )?;
/// assert_eq!(fix.components().len(), 2);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentObservation {
    components: alloc::vec::Vec<Component>,
    z: DVector<f64>,
    noise: NoiseCovariance,
}

impl ComponentObservation {
    /// An observation `z` of `components` with noise `noise`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `z`, `components` and `noise` disagree in size;
    /// [`EstimationError::NonFinite`] for NaN/∞ in `z`.
    pub fn new(components: alloc::vec::Vec<Component>, z: DVector<f64>, noise: NoiseCovariance) -> Result<Self> {
        if components.len() != z.len() || noise.dim() != z.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "component observation",
                expected: components.len(),
                found: if noise.dim() != z.len() { noise.dim() } else { z.len() },
            });
        }
        crate::math::ensure_finite(&z, "component observation")?;
        Ok(Self { components, z, noise })
    }

    /// The same observation of a planar CV state ([`StateLayout::cv_2d`]) whose matrix rows each
    /// select one state entry (a fix, a velocity, or both, as seed 004's `H = I₄`).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if a row of `H` is not a unit selection row;
    /// [`EstimationError::InvalidParameter`] from [`NoiseCovariance::full`].
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::imm::{Axis, Component, ComponentObservation};
    /// use rtls_estimation::manoeuvre::LinearObservation;
    /// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
    /// use nalgebra::DVector;
    /// let fix = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 9.0)?)?;
    /// let obs = LinearObservation::from_model(1.0, &fix, DVector::from_vec(vec![3.0, 4.0]))?;
    /// let components = ComponentObservation::from_cv_observation(&obs)?;
    /// assert_eq!(components.components(), &[Component::Position(Axis::X), Component::Position(Axis::Y)]);
    /// # Ok::<(), rtls_estimation::EstimationError>(())
    /// ```
    pub fn from_cv_observation(observation: &crate::manoeuvre::LinearObservation) -> Result<Self> {
        use crate::measurement::LinearMeasurementModel;
        let layout = StateLayout::cv_2d();
        let h = observation.matrix();
        let components = h
            .row_iter()
            .map(|row| {
                let ones: alloc::vec::Vec<usize> = (0..4).filter(|&c| row[c] == 1.0).collect();
                let zeros = (0..4).filter(|&c| row[c] == 0.0).count();
                match (ones.as_slice(), zeros) {
                    ([c], 3) => Ok(layout.components()[*c]),
                    _ => Err(EstimationError::InvalidParameter {
                        name: "observation matrix",
                        reason: "every row must select exactly one state entry (a single 1, zeros elsewhere)",
                    }),
                }
            })
            .collect::<Result<alloc::vec::Vec<_>>>()?;
        Self::new(
            components,
            observation.z().clone(),
            NoiseCovariance::full(observation.noise().clone())?,
        )
    }

    /// The observed components.
    #[must_use]
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// The measured values.
    #[must_use]
    pub fn z(&self) -> &DVector<f64> {
        &self.z
    }

    /// The noise covariance.
    #[must_use]
    pub fn noise(&self) -> &NoiseCovariance {
        &self.noise
    }
}

/// An [`ImmMode`] made of a motion model `M`, a measurement model `H` and a filter `F`
/// ([`crate::filter::KalmanFilter`], [`crate::filter::ExtendedKalmanFilter`] or
/// [`crate::filter::UnscentedKalmanFilter`]) on an `N`-entry state described by a layout.
///
/// # Example
/// ```
/// use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
/// use rtls_estimation::imm::{FilterMode, ImmMode, StateLayout};
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use rtls_estimation::motion::{ConstantVelocity, CoordinatedTurnWithRate, NoiseGain, ProcessNoise};
/// let fixes4 = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 25.0)?)?;
/// let fixes5 = ComponentSelection::<5>::position(2, NoiseCovariance::isotropic(2, 25.0)?)?;
/// let cv = FilterMode::<4, _, _, _>::new(
///     "CV",
///     StateLayout::cv_2d(),
///     ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic()))?,
///     fixes4,
///     KalmanFilter::default(),
/// )?;
/// let ct = FilterMode::<5, _, _, _>::new(
///     "CT",
///     StateLayout::ct_2d(),
///     CoordinatedTurnWithRate::new(ProcessNoise::discrete(0.01, NoiseGain::kinematic()), 1e-4)?,
///     fixes5,
///     ExtendedKalmanFilter::default(),
/// )?;
/// let modes: Vec<Box<dyn ImmMode>> = vec![Box::new(cv), Box::new(ct)];
/// assert_eq!(modes[1].layout().len(), 5);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone)]
pub struct FilterMode<const N: usize, M, H, F> {
    name: String,
    layout: StateLayout,
    motion: M,
    measurement: H,
    filter: F,
    _state: PhantomData<[f64; N]>,
}

impl<const N: usize, M, H, F: GaussianFilter<N, M, H>> FilterMode<N, M, H, F> {
    /// A mode named `name` over states described by `layout`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `layout` does not have `N` components.
    pub fn new(name: &str, layout: StateLayout, motion: M, measurement: H, filter: F) -> Result<Self> {
        if layout.len() != N {
            return Err(EstimationError::DimensionMismatch {
                what: "mode state layout",
                expected: N,
                found: layout.len(),
            });
        }
        Ok(Self {
            name: String::from(name),
            layout,
            motion,
            measurement,
            filter,
            _state: PhantomData,
        })
    }

    /// The motion model.
    #[must_use]
    pub fn motion(&self) -> &M {
        &self.motion
    }

    /// The measurement model.
    #[must_use]
    pub fn measurement(&self) -> &H {
        &self.measurement
    }
}

impl<const N: usize, M, H, F> ImmMode for FilterMode<N, M, H, F>
where
    M: Send + Sync,
    H: Send + Sync,
    F: GaussianFilter<N, M, H> + GaussianFilter<N, M, ComponentSelection<N>> + Send + Sync,
{
    fn name(&self) -> &str {
        &self.name
    }

    fn layout(&self) -> &StateLayout {
        &self.layout
    }

    fn predict(&self, estimate: &ModeEstimate, from_time_s: f64, to_time_s: f64) -> Result<ModeEstimate> {
        let state = estimate.to_gaussian::<N>(from_time_s)?;
        let prior = GaussianFilter::<N, M, H>::predict(&self.filter, &state, &self.motion, to_time_s)?;
        Ok(ModeEstimate::from_gaussian(&prior))
    }

    fn update(&self, prior: &ModeEstimate, time_s: f64, z: &DVector<f64>) -> Result<ModeUpdate> {
        let state = prior.to_gaussian::<N>(time_s)?;
        let updated = GaussianFilter::<N, M, H>::update(&self.filter, &state, &self.measurement, z)?;
        Ok(ModeUpdate {
            estimate: ModeEstimate::from_gaussian(&updated.state),
            log_likelihood: updated.log_likelihood(),
            nis: updated.nis,
        })
    }

    fn update_components(
        &self,
        prior: &ModeEstimate,
        time_s: f64,
        observation: &ComponentObservation,
    ) -> Result<ModeUpdate> {
        let indices = observation
            .components()
            .iter()
            .map(|&c| {
                self.layout.index_of(c).ok_or(EstimationError::InvalidParameter {
                    name: "component observation",
                    reason: "an IMM mode's state layout lacks an observed component",
                })
            })
            .collect::<Result<alloc::vec::Vec<usize>>>()?;
        let model = ComponentSelection::<N>::new(&indices, observation.noise().clone())?;
        let state = prior.to_gaussian::<N>(time_s)?;
        let updated =
            GaussianFilter::<N, M, ComponentSelection<N>>::update(&self.filter, &state, &model, observation.z())?;
        Ok(ModeUpdate {
            estimate: ModeEstimate::from_gaussian(&updated.state),
            log_likelihood: updated.log_likelihood(),
            nis: updated.nis,
        })
    }
}
