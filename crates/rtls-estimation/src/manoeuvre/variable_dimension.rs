//! Seed 004's variable-dimension Kalman filter: CV `[x, vx, y, vy]` ↔ CA `[x, vx, y, vy, ax, ay]`
//! with fading-memory manoeuvre detection and re-filtering from the manoeuvre's onset.

use alloc::collections::VecDeque;
use alloc::sync::Arc;

use nalgebra::{Matrix2, Vector2};

use super::detector::ManoeuvreDetector;
use super::observation::LinearObservation;
use crate::error::{EstimationError, Result};
use crate::filter::KalmanFilter;
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::motion::{ConstantAcceleration, ConstantVelocity, NoiseGain, ProcessNoise};

/// Which model the variable-dimension filter is running.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VdMode {
    /// Low order, non-manoeuvring: constant velocity `[x, vx, y, vy]`.
    ConstantVelocity,
    /// High order, manoeuvring: constant acceleration `[x, vx, y, vy, ax, ay]`.
    ConstantAcceleration,
}

/// The estimate in the current model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VdEstimate {
    /// CV state `[x, vx, y, vy]`.
    ConstantVelocity(Gaussian<4>),
    /// CA state `[x, vx, y, vy, ax, ay]`.
    ConstantAcceleration(Gaussian<6>),
}

impl VdEstimate {
    /// The model in use.
    #[must_use]
    pub fn mode(&self) -> VdMode {
        match self {
            Self::ConstantVelocity(_) => VdMode::ConstantVelocity,
            Self::ConstantAcceleration(_) => VdMode::ConstantAcceleration,
        }
    }

    /// The `[x, vx, y, vy]` marginal (the CA state's first four entries).
    #[must_use]
    pub fn position_velocity(&self) -> Gaussian<4> {
        match self {
            Self::ConstantVelocity(x) => *x,
            Self::ConstantAcceleration(x) => cv_marginal(x),
        }
    }

    /// Time stamp (s).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        match self {
            Self::ConstantVelocity(x) => x.time_s(),
            Self::ConstantAcceleration(x) => x.time_s(),
        }
    }
}

/// The state a track owns: the estimate, the detector's statistics, and (in CV) the last
/// `Δ + 1` observations with the estimate before each, for re-filtering at an onset. The
/// observations are shared (`Arc`), so stepping a state does not copy them.
#[derive(Debug, Clone, PartialEq)]
pub struct VdState {
    estimate: VdEstimate,
    fading_statistic: f64,
    history: VecDeque<(Gaussian<4>, Arc<LinearObservation>)>,
    significance: VecDeque<f64>,
}

impl VdState {
    /// A state in `estimate`'s model with the detector reset (after a start or a switch).
    fn reset(estimate: VdEstimate) -> Self {
        Self {
            estimate,
            fading_statistic: 0.0,
            history: VecDeque::new(),
            significance: VecDeque::new(),
        }
    }

    /// The current estimate.
    #[must_use]
    pub fn estimate(&self) -> &VdEstimate {
        &self.estimate
    }

    /// The current model.
    #[must_use]
    pub fn mode(&self) -> VdMode {
        self.estimate.mode()
    }

    /// `μ(k)` (0 while in CA).
    #[must_use]
    pub fn fading_statistic(&self) -> f64 {
        self.fading_statistic
    }

    /// `Uₐ(k)` over the steps of the exit window seen so far (0 while in CV).
    #[must_use]
    pub fn acceleration_significance(&self) -> f64 {
        self.significance.iter().sum()
    }
}

/// A model switch, reported with its time and the statistic that caused it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModeSwitch {
    /// Time of the observation at which the switch was decided (s).
    pub time_s: f64,
    /// The model switched to.
    pub to: VdMode,
    /// `μ(k)` for a switch to CA, `Uₐ(k)` for a switch to CV.
    pub statistic: f64,
    /// The threshold it crossed.
    pub threshold: f64,
    /// For a switch to CA: the time of the first re-filtered observation, where the
    /// acceleration is assumed to have begun (`Δ` steps back); for a switch to CV: `time_s`.
    pub onset_time_s: f64,
}

/// The result of one step: the new state, the observation's NIS under the model the step began
/// in, and the model switch if one happened.
#[derive(Debug, Clone, PartialEq)]
pub struct VdStep {
    /// The new state.
    pub state: VdState,
    /// `νᵀ S⁻¹ ν` of the observation under the model the step began in.
    pub nis: f64,
    /// The model switch decided at this step, if any.
    pub event: Option<ModeSwitch>,
}

/// Seed 004's variable-dimension Kalman filter (VD-KF).
///
/// The filter runs the low-order CV model while the target is not manoeuvring, and the
/// high-order CA model while it is:
/// ```text
/// CV:  X(k+1) = Φ X(k) + G W(k),     X = [x, vx, y, vy]             (seed 004 eq. (8))
/// CA:  Xᵐ(k+1) = Φᵐ Xᵐ(k) + Gᵐ Wᵐ(k), Xᵐ = [x, vx, y, vy, ax, ay]   (eq. (10))
/// Z(k) = H X(k) + V(k),  Hᵐ = [H | 0]                                (eq. (9))
/// ```
/// In CV, [`ManoeuvreDetector`] accumulates `μ(k) = α μ(k−1) + νᵀ S⁻¹ ν`. When `μ(k) ≥ Th`
/// the target is taken to have started accelerating `Δ` steps ago: the CA filter is started
/// from the CV estimate before the oldest of the last `Δ + 1` stored observations (the
/// accelerations get mean 0 and variance `σₐ₀²`), and those observations are re-filtered with
/// the CA model up to now. (Seed 004 prints the onset as step `k − α − 1`; with `Δ = (1−α)⁻¹`
/// defined just before, `k − Δ − 1` is meant: that is Bar-Shalom and Birmiwal's rule.) In CA,
/// the acceleration's significance `Uₐ` over the last `p` steps is tested; when it falls below
/// its threshold the filter drops the accelerations (marginalises) and returns to CV.
///
/// The filter is an immutable strategy; [`VdState`] is the value a track owns.
///
/// # Errors
/// Steps return [`EstimationError`]s: time going backwards, observation size mismatches,
/// non-finite values, a non-positive-definite innovation or acceleration covariance.
///
/// # Example
/// ```
/// use rtls_estimation::manoeuvre::{LinearObservation, VariableDimensionFilter, VdMode};
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// use nalgebra::DVector;
///
/// let vd = VariableDimensionFilter::seed_004(1e-4, 1e-3)?;
/// let fixes = ComponentSelection::<4>::position(2, NoiseCovariance::isotropic(2, 1.0)?)?;
/// let mut state = vd.initial_state(Gaussian::new(
///     Vector::<4>::new(0.0, 10.0, 0.0, 0.0), Matrix::<4>::identity(), 0.0)?);
/// let mut switched_at = None;
/// for k in 1..=40 {
///     let t = k as f64;
///     // 10 m/s along x, then from t = 20 s a 2 m/s² acceleration along y.
///     let y = if t > 20.0 { (t - 20.0).powi(2) } else { 0.0 };
///     let obs = LinearObservation::from_model(t, &fixes, DVector::from_vec(vec![10.0 * t, y]))?;
///     let step = vd.step(&state, &obs)?;
///     if let Some(event) = step.event {
///         if event.to == VdMode::ConstantAcceleration && switched_at.is_none() {
///             switched_at = Some(event.time_s);
///         }
///     }
///     state = step.state;
/// }
/// let t = switched_at.expect("the manoeuvre is detected");
/// assert!(t > 20.0 && t <= 23.0);
/// assert_eq!(state.mode(), VdMode::ConstantAcceleration);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Seed 004 §1–§2, eq. (8)–(13); Y. Bar-Shalom, K. Birmiwal, "Variable dimension filter for
/// maneuvering target tracking", *IEEE Trans. AES* 18(5), 1982; Bar-Shalom, Li, Kirubarajan
/// (2001), §11.4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VariableDimensionFilter {
    quiescent: ConstantVelocity,
    manoeuvring: ConstantAcceleration,
    detector: ManoeuvreDetector,
    filter: KalmanFilter,
    /// `Th` for `m = 1..=CACHED_DIMS` (χ² quantiles are iterative; computed once).
    onset_thresholds: [f64; CACHED_DIMS],
    /// The exit threshold for a planar acceleration.
    exit_threshold: f64,
}

/// Measurement sizes whose onset threshold is precomputed.
const CACHED_DIMS: usize = 8;

impl VariableDimensionFilter {
    /// A VD-KF with the given CV and CA models and detector.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for invalid detector parameters.
    pub fn new(
        quiescent: ConstantVelocity,
        manoeuvring: ConstantAcceleration,
        detector: ManoeuvreDetector,
    ) -> Result<Self> {
        detector.validate()?;
        let mut onset_thresholds = [0.0; CACHED_DIMS];
        for (i, th) in onset_thresholds.iter_mut().enumerate() {
            *th = detector.onset_threshold(i + 1)?;
        }
        Ok(Self {
            quiescent,
            manoeuvring,
            detector,
            filter: KalmanFilter::default(),
            onset_thresholds,
            exit_threshold: detector.exit_threshold(2)?,
        })
    }

    /// Seed 004's models as printed: CV with `G = [T/2, 1]ᵀ` per axis and `Q = σₐ² I`
    /// (`cv_variance`), CA with `Gᵐ = [T²/4, T/2, 1]ᵀ` and `Qᵐ = σₘ² I` (`ca_variance`), and the
    /// default detector.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a negative or non-finite variance.
    pub fn seed_004(cv_variance: f64, ca_variance: f64) -> Result<Self> {
        Self::new(
            ConstantVelocity::new(ProcessNoise::discrete(cv_variance, NoiseGain::seed_004_cv()))?,
            ConstantAcceleration::new(ProcessNoise::discrete(ca_variance, NoiseGain::seed_004_ca()))?,
            ManoeuvreDetector::default(),
        )
    }

    /// The same filter with another detector.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for invalid detector parameters.
    pub fn with_detector(self, detector: ManoeuvreDetector) -> Result<Self> {
        Self::new(self.quiescent, self.manoeuvring, detector)
    }

    /// `Th` for an observation of `m` components (cached for small `m`).
    fn onset_threshold(&self, m: usize) -> Result<f64> {
        match self.onset_thresholds.get(m.wrapping_sub(1)) {
            Some(&th) => Ok(th),
            None => self.detector.onset_threshold(m),
        }
    }

    /// The detector.
    #[must_use]
    pub fn detector(&self) -> &ManoeuvreDetector {
        &self.detector
    }

    /// A state starting in the CV model from `initial`.
    #[must_use]
    pub fn initial_state(&self, initial: Gaussian<4>) -> VdState {
        VdState::reset(VdEstimate::ConstantVelocity(initial))
    }

    /// Predicts the estimate to `to_time_s` in the current model (coasting without an
    /// observation); the detector statistics are unchanged.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if `to_time_s` precedes the state.
    pub fn predict(&self, state: &VdState, to_time_s: f64) -> Result<VdState> {
        let estimate = match &state.estimate {
            VdEstimate::ConstantVelocity(x) => {
                VdEstimate::ConstantVelocity(self.filter.predict(x, &self.quiescent, to_time_s)?)
            }
            VdEstimate::ConstantAcceleration(x) => {
                VdEstimate::ConstantAcceleration(self.filter.predict(x, &self.manoeuvring, to_time_s)?)
            }
        };
        Ok(VdState {
            estimate,
            ..state.clone()
        })
    }

    /// One cycle with `observation`: predict to its time, update, and run the manoeuvre
    /// detector (onset in CV, exit in CA).
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] for an observation older than the state; the KF's
    /// update errors; [`EstimationError::NotPositiveDefinite`] if the acceleration covariance
    /// cannot be inverted for the significance test.
    pub fn step(&self, state: &VdState, observation: &LinearObservation) -> Result<VdStep> {
        match &state.estimate {
            VdEstimate::ConstantVelocity(x) => self.step_quiescent(state, x, observation),
            VdEstimate::ConstantAcceleration(x) => self.step_manoeuvring(state, x, observation),
        }
    }

    fn step_quiescent(&self, state: &VdState, x: &Gaussian<4>, observation: &LinearObservation) -> Result<VdStep> {
        let prior = self.filter.predict(x, &self.quiescent, observation.time_s())?;
        let updated = self.filter.update(&prior, observation, observation.z())?;
        // μ(k) = α μ(k−1) + νᵀ S⁻¹ ν
        let mu = self.detector.fading_factor * state.fading_statistic + updated.nis;
        let mut history = state.history.clone();
        history.push_back((*x, Arc::new(observation.clone())));
        // keep the last Δ + 1 observations: the onset is Δ steps back from this one
        while history.len() > self.detector.window_steps() + 1 {
            history.pop_front();
        }
        let threshold = self.onset_threshold(observation.dim())?;
        if mu < threshold {
            return Ok(VdStep {
                state: VdState {
                    estimate: VdEstimate::ConstantVelocity(updated.state),
                    fading_statistic: mu,
                    history,
                    significance: VecDeque::new(),
                },
                nis: updated.nis,
                event: None,
            });
        }
        // Manoeuvre: start CA from the estimate before the oldest stored observation, with
        // â = 0, Pₐ = σₐ₀² I, and re-filter the stored observations.
        let (start, first) = history.front().ok_or(EstimationError::InvalidParameter {
            name: "history",
            reason: "the onset window is empty",
        })?;
        let onset_time_s = first.time_s();
        let mut ca = augment(start, self.detector.onset_acceleration_std_mps2);
        for (_, stored) in &history {
            let ca_prior = self.filter.predict(&ca, &self.manoeuvring, stored.time_s())?;
            ca = self.filter.update(&ca_prior, &stored.model::<6>(), stored.z())?.state;
        }
        Ok(VdStep {
            state: VdState::reset(VdEstimate::ConstantAcceleration(ca)),
            nis: updated.nis,
            event: Some(ModeSwitch {
                time_s: observation.time_s(),
                to: VdMode::ConstantAcceleration,
                statistic: mu,
                threshold,
                onset_time_s,
            }),
        })
    }

    fn step_manoeuvring(&self, state: &VdState, x: &Gaussian<6>, observation: &LinearObservation) -> Result<VdStep> {
        let prior = self.filter.predict(x, &self.manoeuvring, observation.time_s())?;
        let updated = self.filter.update(&prior, &observation.model::<6>(), observation.z())?;
        let posterior = updated.state;
        // â, Pₐ: the acceleration block of the CA posterior
        let a_hat: Vector2<f64> = posterior.mean().fixed_rows::<2>(4).into_owned();
        let p_a: Matrix2<f64> = posterior.covariance().fixed_view::<2, 2>(4, 4).into_owned();
        // δₐ = âᵀ Pₐ⁻¹ â
        let chol = p_a.cholesky().ok_or(EstimationError::NotPositiveDefinite {
            what: "acceleration covariance Pₐ",
        })?;
        let delta_a = a_hat.dot(&chol.solve(&a_hat));
        let mut significance = state.significance.clone();
        significance.push_back(delta_a);
        while significance.len() > self.detector.exit_window_steps {
            significance.pop_front();
        }
        // Uₐ = Σ over the last p steps of δₐ
        let u_a: f64 = significance.iter().sum();
        let threshold = self.exit_threshold;
        if significance.len() == self.detector.exit_window_steps && u_a < threshold {
            return Ok(VdStep {
                state: VdState::reset(VdEstimate::ConstantVelocity(cv_marginal(&posterior))),
                nis: updated.nis,
                event: Some(ModeSwitch {
                    time_s: observation.time_s(),
                    to: VdMode::ConstantVelocity,
                    statistic: u_a,
                    threshold,
                    onset_time_s: observation.time_s(),
                }),
            });
        }
        Ok(VdStep {
            state: VdState {
                estimate: VdEstimate::ConstantAcceleration(posterior),
                fading_statistic: 0.0,
                history: VecDeque::new(),
                significance,
            },
            nis: updated.nis,
            event: None,
        })
    }
}

/// `[x, vx, y, vy] ↦ [x, vx, y, vy, 0, 0]` with `Pₐ = σₐ₀² I` and no cross-covariance.
fn augment(x: &Gaussian<4>, acceleration_std_mps2: f64) -> Gaussian<6> {
    let mut mean = Vector::<6>::zeros();
    mean.fixed_rows_mut::<4>(0).copy_from(x.mean());
    let mut covariance = Matrix::<6>::zeros();
    covariance.fixed_view_mut::<4, 4>(0, 0).copy_from(x.covariance());
    let variance = acceleration_std_mps2 * acceleration_std_mps2;
    covariance[(4, 4)] = variance;
    covariance[(5, 5)] = variance;
    Gaussian::from_parts_unchecked(mean, covariance, x.time_s())
}

/// The `[x, vx, y, vy]` marginal of a CA state.
fn cv_marginal(x: &Gaussian<6>) -> Gaussian<4> {
    Gaussian::from_parts_unchecked(
        x.mean().fixed_rows::<4>(0).into_owned(),
        x.covariance().fixed_view::<4, 4>(0, 0).into_owned(),
        x.time_s(),
    )
}
