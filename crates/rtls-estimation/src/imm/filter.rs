//! The interacting multiple model (IMM) estimator over modes of different state size.

use alloc::boxed::Box;
use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use super::layout::{check_estimate, convert, Fill, StateLayout};
use super::mode::{ComponentObservation, ImmMode, ModeEstimate, ModeUpdate};
use super::transitions::ModeTransitions;
use crate::error::{EstimationError, Result};

/// The IMM state a track owns: one estimate per mode (in the mode's layout), the mode
/// probabilities `μⱼ` and the time stamp.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ImmState {
    estimates: Vec<ModeEstimate>,
    probabilities: Vec<f64>,
    time_s: f64,
}

impl ImmState {
    /// The mode-conditioned estimates, in mode order.
    #[must_use]
    pub fn estimates(&self) -> &[ModeEstimate] {
        &self.estimates
    }

    /// The mode-conditioned estimates, to change in place (a known control input added to one
    /// mode's prediction, a state component bounded with [`ModeEstimate::bound_component`]);
    /// the probabilities and the time stay as they are.
    #[must_use]
    pub fn estimates_mut(&mut self) -> &mut [ModeEstimate] {
        &mut self.estimates
    }

    /// The mode probabilities `μⱼ` (sum to 1): posterior after an update, predicted `c̄ⱼ` after
    /// a prediction.
    #[must_use]
    pub fn probabilities(&self) -> &[f64] {
        &self.probabilities
    }

    /// Time stamp (s).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The index of the most probable mode.
    #[must_use]
    pub fn most_probable_mode(&self) -> usize {
        let mut best = 0;
        for (j, p) in self.probabilities.iter().enumerate() {
            if *p > self.probabilities[best] {
                best = j;
            }
        }
        best
    }
}

/// An IMM update: the new state and each mode's likelihood and NIS.
#[derive(Debug, Clone, PartialEq)]
pub struct ImmUpdate {
    /// The posterior IMM state.
    pub state: ImmState,
    /// `ln Λⱼ` per mode.
    pub log_likelihoods: Vec<f64>,
    /// `νⱼᵀ Sⱼ⁻¹ νⱼ` per mode.
    pub nis: Vec<f64>,
}

/// The interacting multiple model estimator with Markov switching among modes of different
/// state dimension (e.g. CV `[x, vx, y, vy]`, CA `[x, vx, y, vy, ax, ay]` and a coordinated
/// turn `[x, vx, y, vy, ω]`), each run by its own KF, EKF or UKF.
///
/// One cycle (Bar-Shalom et al. 2001, §11.6.6), with `conv_{i→j}` the explicit layout
/// conversion of [`convert`] (components mode `i` lacks are filled from mode `j`'s own
/// estimate; components mode `j` lacks are marginalised out):
/// ```text
/// c̄ⱼ    = Σᵢ pᵢⱼ μᵢ                                       predicted mode probability
/// μᵢ|ⱼ  = pᵢⱼ μᵢ / c̄ⱼ                                     mixing probabilities
/// x⁰ⱼ   = Σᵢ μᵢ|ⱼ conv_{i→j}(x̂ᵢ)                           mixed mean
/// P⁰ⱼ   = Σᵢ μᵢ|ⱼ [conv(Pᵢ) + (conv(x̂ᵢ) − x⁰ⱼ)(·)ᵀ]         mixed covariance
/// x⁻ⱼ, P⁻ⱼ = mode j's prediction of (x⁰ⱼ, P⁰ⱼ)
/// Λⱼ    = N(νⱼ; 0, Sⱼ)                                      mode-matched update
/// μⱼ    = Λⱼ c̄ⱼ / Σₗ Λₗ c̄ₗ                                  (in the log domain)
/// ```
/// [`InteractingMultipleModel::predict`] performs the mixing and the mode-matched predictions
/// (its state carries `c̄ⱼ` as probabilities, so coasting through a gap is repeated
/// predictions); [`InteractingMultipleModel::update`] the mode-matched updates and the mode
/// probabilities; [`InteractingMultipleModel::combined`] the moment-matched output in any
/// layout.
///
/// # Errors
/// Steps return [`EstimationError`] values: time going backwards, a mode filter's numerical
/// failure, or every mode assigning the measurement zero likelihood.
///
/// # Example
/// ```
/// use rtls_estimation::filter::KalmanFilter;
/// use rtls_estimation::imm::{FilterMode, InteractingMultipleModel, ModeEstimate, ModeTransitions, StateLayout};
/// use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
/// use rtls_estimation::motion::{ConstantAcceleration, ConstantVelocity, NoiseGain, ProcessNoise};
/// use nalgebra::{DMatrix, DVector};
///
/// let r = NoiseCovariance::isotropic(2, 1.0)?;
/// let cv = FilterMode::<4, _, _, _>::new("CV", StateLayout::cv_2d(),
///     ConstantVelocity::new(ProcessNoise::discrete(1e-4, NoiseGain::kinematic()))?,
///     ComponentSelection::<4>::position(2, r.clone())?, KalmanFilter::default())?;
/// let ca = FilterMode::<6, _, _, _>::new("CA", StateLayout::ca_2d(),
///     ConstantAcceleration::new(ProcessNoise::discrete(1e-2, NoiseGain::kinematic()))?,
///     ComponentSelection::<6>::position(2, r)?, KalmanFilter::default())?;
/// let imm = InteractingMultipleModel::new(
///     vec![Box::new(cv), Box::new(ca)],
///     ModeTransitions::per_step(DMatrix::from_row_slice(2, 2, &[0.95, 0.05, 0.05, 0.95]))?,
/// )?;
/// let start = ModeEstimate { mean: DVector::zeros(4), covariance: DMatrix::identity(4, 4) * 10.0 };
/// let mut state = imm.initial_state(&start, &StateLayout::cv_2d(), 1.0, &[0.5, 0.5], 0.0)?;
/// // A target accelerating at 1 m/s² along x: the CA mode takes over.
/// for k in 1..=15 {
///     let t = k as f64;
///     let prior = imm.predict(&state, t)?;
///     state = imm.update(&prior, &DVector::from_vec(vec![0.5 * t * t, 0.0]))?.state;
/// }
/// assert!(state.probabilities()[1] > 0.9);
/// let (mean, _) = imm.combined(&state, &StateLayout::ca_2d())?;
/// assert!((mean[4] - 1.0).abs() < 0.3 * 1.0 / state.probabilities()[1]);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// H. A. P. Blom, Y. Bar-Shalom, "The interacting multiple model algorithm for systems with
/// Markovian switching coefficients", *IEEE Trans. Automatic Control* 33(8), 1988;
/// Bar-Shalom, Li, Kirubarajan (2001), §11.6.6; K. Granström, P. Willett, Y. Bar-Shalom,
/// "Systematic approach to IMM mixing for unequal dimension states", *IEEE TAES* 51(4), 2015.
pub struct InteractingMultipleModel {
    modes: Vec<Box<dyn ImmMode>>,
    transitions: ModeTransitions,
}

impl core::fmt::Debug for InteractingMultipleModel {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let names: Vec<&str> = self.modes.iter().map(|m| m.name()).collect();
        f.debug_struct("InteractingMultipleModel")
            .field("modes", &names)
            .field("transitions", &self.transitions)
            .finish()
    }
}

impl InteractingMultipleModel {
    /// An IMM over `modes` switching by `transitions`.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `transitions` is not for `modes.len()` modes;
    /// [`EstimationError::InvalidParameter`] for no mode. One mode (with the transition matrix
    /// `[1]`) is allowed: mixing is then the identity and the IMM is that mode's filter, so a
    /// user of the IMM can run a single model through the same code.
    pub fn new(modes: Vec<Box<dyn ImmMode>>, transitions: ModeTransitions) -> Result<Self> {
        if modes.is_empty() {
            return Err(EstimationError::InvalidParameter {
                name: "modes",
                reason: "an IMM needs at least one mode",
            });
        }
        if transitions.modes() != modes.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "mode transition matrix",
                expected: modes.len(),
                found: transitions.modes(),
            });
        }
        Ok(Self { modes, transitions })
    }

    /// The modes, in order.
    #[must_use]
    pub fn modes(&self) -> &[Box<dyn ImmMode>] {
        &self.modes
    }

    /// An initial state from one estimate in `layout` (e.g. [`ModeEstimate::from_gaussian`] of a
    /// CV track's state): each mode gets the
    /// shared components, and components `layout` lacks get mean 0 and variance
    /// `missing_variance` (e.g. an acceleration or turn-rate prior).
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] for sizes that do not match `layout` or a
    /// probability list that does not have one entry per mode;
    /// [`EstimationError::InvalidParameter`] if the probabilities are negative or do not sum
    /// to 1, or `missing_variance` is negative or not finite.
    pub fn initial_state(
        &self,
        estimate: &ModeEstimate,
        layout: &StateLayout,
        missing_variance: f64,
        probabilities: &[f64],
        time_s: f64,
    ) -> Result<ImmState> {
        if !missing_variance.is_finite() || missing_variance < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "missing_variance",
                reason: "must be finite and non-negative",
            });
        }
        let estimates = self
            .modes
            .iter()
            .map(|mode| {
                let n = mode.layout().len();
                let fill_mean = DVector::zeros(n);
                let fill_cov = DMatrix::from_diagonal_element(n, n, missing_variance);
                let (m, p) = convert(
                    &estimate.mean,
                    &estimate.covariance,
                    layout,
                    mode.layout(),
                    Fill::From {
                        mean: &fill_mean,
                        covariance: &fill_cov,
                    },
                )?;
                Ok(ModeEstimate { mean: m, covariance: p })
            })
            .collect::<Result<Vec<_>>>()?;
        self.state(estimates, probabilities.to_vec(), time_s)
    }

    /// An IMM state from explicit per-mode estimates.
    ///
    /// # Errors
    /// As [`InteractingMultipleModel::initial_state`]; [`EstimationError::NonFinite`] for a
    /// NaN/∞ entry or time.
    pub fn state(&self, estimates: Vec<ModeEstimate>, probabilities: Vec<f64>, time_s: f64) -> Result<ImmState> {
        for (what, found) in [
            ("IMM mode estimates", estimates.len()),
            ("IMM mode probabilities", probabilities.len()),
        ] {
            if found != self.modes.len() {
                return Err(EstimationError::DimensionMismatch {
                    what,
                    expected: self.modes.len(),
                    found,
                });
            }
        }
        for (estimate, mode) in estimates.iter().zip(&self.modes) {
            check_estimate(
                &estimate.mean,
                &estimate.covariance,
                mode.layout().len(),
                "IMM mode estimate",
            )?;
            crate::math::ensure_finite(&estimate.mean, "IMM mode estimate")?;
            crate::math::ensure_finite(&estimate.covariance, "IMM mode estimate")?;
        }
        if probabilities.iter().any(|p| !p.is_finite() || *p < 0.0)
            || (probabilities.iter().sum::<f64>() - 1.0).abs() > 1e-9
        {
            return Err(EstimationError::InvalidParameter {
                name: "mode probabilities",
                reason: "must be non-negative and sum to 1",
            });
        }
        if !time_s.is_finite() {
            return Err(EstimationError::NonFinite { what: "IMM state time" });
        }
        Ok(ImmState {
            estimates,
            probabilities,
            time_s,
        })
    }

    /// Interaction (mixing) and mode-matched prediction to `to_time_s`; the returned state's
    /// probabilities are the predicted `c̄ⱼ`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`] if `to_time_s` precedes the state; a mode's
    /// prediction errors.
    pub fn predict(&self, state: &ImmState, to_time_s: f64) -> Result<ImmState> {
        let dt_s = to_time_s - state.time_s;
        if dt_s.is_nan() || dt_s < 0.0 {
            return Err(EstimationError::TimeWentBackwards {
                state_time_s: state.time_s,
                requested_time_s: to_time_s,
            });
        }
        let pi = self.transitions.matrix(dt_s)?;
        let modes = self.modes.len();
        // c̄ⱼ = Σᵢ pᵢⱼ μᵢ
        let c_bar: Vec<f64> = (0..modes)
            .map(|j| (0..modes).map(|i| pi[(i, j)] * state.probabilities[i]).sum())
            .collect();
        let mut estimates = Vec::with_capacity(modes);
        for (j, mode) in self.modes.iter().enumerate() {
            let mixed = self.mix_into(state, &pi, &c_bar, j)?;
            estimates.push(mode.predict(&mixed, state.time_s, to_time_s)?);
        }
        Ok(ImmState {
            estimates,
            probabilities: normalised(c_bar)?,
            time_s: to_time_s,
        })
    }

    /// The mixed initial condition `(x⁰ⱼ, P⁰ⱼ)` of mode `j`.
    fn mix_into(&self, state: &ImmState, pi: &DMatrix<f64>, c_bar: &[f64], j: usize) -> Result<ModeEstimate> {
        let target = &self.modes[j];
        let own = &state.estimates[j];
        if c_bar[j] <= f64::MIN_POSITIVE {
            // Mode j is unreachable this step: its mixed estimate is its own.
            return Ok(own.clone());
        }
        let n = target.layout().len();
        let fill = Fill::From {
            mean: &own.mean,
            covariance: &own.covariance,
        };
        let mut converted = Vec::with_capacity(self.modes.len());
        for (i, source) in self.modes.iter().enumerate() {
            // μᵢ|ⱼ = pᵢⱼ μᵢ / c̄ⱼ
            let weight = pi[(i, j)] * state.probabilities[i] / c_bar[j];
            if weight == 0.0 {
                continue;
            }
            let estimate = &state.estimates[i];
            let (m, p) = if i == j {
                (estimate.mean.clone(), estimate.covariance.clone())
            } else {
                convert(
                    &estimate.mean,
                    &estimate.covariance,
                    source.layout(),
                    target.layout(),
                    fill,
                )?
            };
            converted.push((weight, m, p));
        }
        // x⁰ⱼ = Σᵢ μᵢ|ⱼ conv(x̂ᵢ),  P⁰ⱼ = Σᵢ μᵢ|ⱼ [conv(Pᵢ) + (conv(x̂ᵢ) − x⁰ⱼ)(·)ᵀ]
        let (mean, covariance) = moment_match(n, &converted);
        Ok(ModeEstimate { mean, covariance })
    }

    /// Mode-matched updates with measurement `z` and the posterior mode probabilities
    /// `μⱼ = Λⱼ c̄ⱼ / Σₗ Λₗ c̄ₗ`, computed in the log domain.
    ///
    /// # Errors
    /// A mode's update errors; [`EstimationError::NonFinite`] if every mode gives the
    /// measurement zero likelihood (underflow even in the log domain).
    pub fn update(&self, prior: &ImmState, z: &DVector<f64>) -> Result<ImmUpdate> {
        self.update_with(prior, |mode, estimate| mode.update(estimate, prior.time_s, z))
    }

    /// As [`InteractingMultipleModel::update`], with a direct observation of layout components
    /// (see [`ComponentObservation`]) that every mode maps onto its own state.
    ///
    /// # Errors
    /// As [`InteractingMultipleModel::update`], plus [`EstimationError::InvalidParameter`] if a
    /// mode lacks an observed component.
    pub fn update_components(&self, prior: &ImmState, observation: &ComponentObservation) -> Result<ImmUpdate> {
        self.update_with(prior, |mode, estimate| {
            mode.update_components(estimate, prior.time_s, observation)
        })
    }

    /// As [`InteractingMultipleModel::update`], with the mode-matched update supplied by the
    /// caller: `update_mode(mode, prior estimate)` returns the mode's posterior, `ln Λⱼ` and
    /// NIS. For measurements whose model changes with every call (one range to whichever
    /// anchor answered, in the mode's own layout), where [`ImmMode::update`]'s fixed model
    /// does not fit.
    ///
    /// # Errors
    /// The errors `update_mode` returns; [`EstimationError::NonFinite`] if every mode gives the
    /// measurement zero likelihood.
    pub fn update_with(
        &self,
        prior: &ImmState,
        update_mode: impl Fn(&dyn ImmMode, &ModeEstimate) -> Result<ModeUpdate>,
    ) -> Result<ImmUpdate> {
        let mut estimates = Vec::with_capacity(self.modes.len());
        let mut log_likelihoods = Vec::with_capacity(self.modes.len());
        let mut nis = Vec::with_capacity(self.modes.len());
        for (mode, estimate) in self.modes.iter().zip(&prior.estimates) {
            let update = update_mode(mode.as_ref(), estimate)?;
            estimates.push(update.estimate);
            log_likelihoods.push(update.log_likelihood);
            nis.push(update.nis);
        }
        // ln(Λⱼ c̄ⱼ), then μⱼ = exp(ln(Λⱼ c̄ⱼ) − max) / Σ exp(·)
        let log_weights: Vec<f64> = log_likelihoods
            .iter()
            .zip(&prior.probabilities)
            .map(|(ll, c)| ll + crate::math::ln(*c))
            .collect();
        let max = log_weights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "IMM mode likelihoods (every mode rejects the measurement)",
            });
        }
        let weights: Vec<f64> = log_weights.iter().map(|lw| crate::math::exp(lw - max)).collect();
        Ok(ImmUpdate {
            state: ImmState {
                estimates,
                probabilities: normalised(weights)?,
                time_s: prior.time_s,
            },
            log_likelihoods,
            nis,
        })
    }

    /// The moment-matched combined estimate in `layout`:
    /// `x̂ = Σⱼ μⱼ conv(x̂ⱼ)`, `P = Σⱼ μⱼ [conv(Pⱼ) + (conv(x̂ⱼ) − x̂)(·)ᵀ]`, where a component a
    /// mode lacks counts as the value that mode asserts: zero, with zero variance (a CV mode's
    /// acceleration, a straight-line mode's turn rate).
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] if `state` does not belong to this IMM.
    pub fn combined(&self, state: &ImmState, layout: &StateLayout) -> Result<(DVector<f64>, DMatrix<f64>)> {
        if state.estimates.len() != self.modes.len() {
            return Err(EstimationError::DimensionMismatch {
                what: "IMM state modes",
                expected: self.modes.len(),
                found: state.estimates.len(),
            });
        }
        let mut converted = Vec::with_capacity(self.modes.len());
        for ((mode, estimate), &mu) in self.modes.iter().zip(&state.estimates).zip(&state.probabilities) {
            let (m, p) = convert(&estimate.mean, &estimate.covariance, mode.layout(), layout, Fill::Zero)?;
            converted.push((mu, m, p));
        }
        // x̂ = Σⱼ μⱼ conv(x̂ⱼ),  P = Σⱼ μⱼ [conv(Pⱼ) + (conv(x̂ⱼ) − x̂)(·)ᵀ]
        let (mean, covariance) = moment_match(layout.len(), &converted);
        Ok((mean, covariance))
    }
}

/// `wⱼ / Σ w`.
fn normalised(mut weights: Vec<f64>) -> Result<Vec<f64>> {
    let total: f64 = weights.iter().sum();
    if !total.is_finite() || total <= 0.0 {
        return Err(EstimationError::NonFinite {
            what: "IMM mode probabilities",
        });
    }
    for w in &mut weights {
        *w /= total;
    }
    Ok(weights)
}

/// The moment-matched Gaussian of a mixture `Σ wᵢ N(mᵢ, Pᵢ)` (weights summing to 1) in an
/// `n`-entry layout, shared by IMM mixing and the combined output:
/// ```text
/// x = Σ wᵢ mᵢ
/// P = Σ wᵢ [Pᵢ + (mᵢ − x)(mᵢ − x)ᵀ]
/// ```
fn moment_match(n: usize, components: &[(f64, DVector<f64>, DMatrix<f64>)]) -> (DVector<f64>, DMatrix<f64>) {
    let mut mean = DVector::zeros(n);
    for (weight, m, _) in components {
        // x += wᵢ mᵢ
        mean.axpy(*weight, m, 1.0);
    }
    let mut covariance = DMatrix::zeros(n, n);
    for (weight, m, p) in components {
        // P += wᵢ [Pᵢ + (mᵢ − x)(mᵢ − x)ᵀ]
        let d = m - &mean;
        covariance += p * *weight;
        covariance.ger(*weight, &d, &d, 1.0);
    }
    crate::math::symmetrize(&mut covariance);
    (mean, covariance)
}
