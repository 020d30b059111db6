//! `motion_model = "imm"`: the tracker's interacting multiple models — by default a quiet
//! constant velocity, a constant acceleration and (in 2-D) a coordinated turn with the turn rate
//! as a state, or the set `[tracker.imm] modes` names — and the most probable mode, whose
//! changes are reported as `model-switch` events. `motion_model = "ct"` is the coordinated turn
//! alone, run as an IMM of one mode (mixing one mode is the identity: the plain filter).
//!
//! The track keeps its CV-layout state `[x, vx, y, vy(, z, vz)]` as the moment-matched
//! combination of the modes (so reporting, gating, zones and alarms are unchanged) and the
//! [`ImmState`] beside it. Fixes and velocities update every mode through
//! [`ComponentObservation`]s; a single anchor reading (tightly coupled) updates every mode in
//! that mode's own layout, since only the position enters the measurement: by a sigma-point
//! step under `filter = "ukf"`, else by an EKF step.
//!
//! # References
//! H. A. P. Blom, Y. Bar-Shalom, "The interacting multiple model algorithm for systems with
//! Markovian switching coefficients", *IEEE Trans. Automatic Control* 33(8), 1988;
//! Bar-Shalom, Li, Kirubarajan (2001), §11.6.6–§11.7; seed 004 (manoeuvre detection, the
//! problem the IMM solves without a detector's delay).

use nalgebra::{DMatrix, DVector};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters, UnscentedKalmanFilter};
use rtls_estimation::imm::{
    Axis, Component, ComponentObservation, FilterMode, ImmMode, ImmState, InteractingMultipleModel, ModeEstimate,
    ModeTransitions, ModeUpdate, StateLayout,
};
use rtls_estimation::measurement::{ComponentSelection, MeasurementJacobian, MeasurementModel, NoiseCovariance};
use rtls_estimation::motion::{ConstantAcceleration, ConstantVelocity, CoordinatedTurnWithRate, ProcessNoise};
use rtls_estimation::{EstimationError, Gaussian, Matrix, Vector};

use super::models::AnchorMeasurement;
use crate::error::{EngineError, Result};
use crate::site::{FilterKind, ImmModeKind, MotionModelKind, TrackerSettings};

/// Prior variance of the accelerations a CV estimate lacks when the modes start ((m/s²)², i.e.
/// σ = 1 m/s²); the turn rate's is `tracker.initial_turn_rate_std_radps²`.
const MISSING_VARIANCE: f64 = 1.0;

/// The largest turn rate the coordinated-turn mode may hold, rad/s: half a turn per second.
/// A walking person turns a corner at about 1 rad/s and a mine vehicle at well under 0.5 rad/s;
/// a rate beyond this is not a manoeuvre but the mode drifting where the position does not
/// observe `ω` (coasting, straight motion), and it is clamped (see
/// [`ModeEstimate::bound_component`]).
pub(crate) const MAX_TURN_RATE_RAD_S: f64 = core::f64::consts::PI;

/// The IMM of the tracker and what it needs to report modes.
#[derive(Debug)]
pub(crate) struct Manoeuvres {
    imm: InteractingMultipleModel,
    /// The track's CV layout: `[x, vx, y, vy]` or `[x, vx, y, vy, z, vz]`.
    layout: StateLayout,
    names: Vec<&'static str>,
    initial_probabilities: Vec<f64>,
    switch_probability: f64,
    /// `filter = "ukf"`: anchor readings update every mode by a sigma-point step; else by an
    /// EKF step.
    ukf: Option<UnscentedKalmanFilter>,
    /// `σ_ω₀²` of a new track's turn rate, (rad/s)².
    initial_turn_rate_variance: f64,
    /// The coordinated turn when it is the only mode (`motion_model = "ct"`): the model a
    /// smoother of these tracks runs backwards.
    sole_turn: Option<CoordinatedTurnWithRate>,
}

impl Manoeuvres {
    /// The coordinated turn when it is the only mode (`motion_model = "ct"`), else `None`.
    pub(crate) fn sole_turn(&self) -> Option<CoordinatedTurnWithRate> {
        self.sole_turn
    }

    /// The modes of `motion_model = "imm"` (`[tracker.imm] modes`; by default CV, CA and, in
    /// 2-D, CT) or the coordinated turn alone (`motion_model = "ct"`, an IMM of one mode, which
    /// is the plain filter). CV uses `tracker.imm.cv_acceleration_noise_std_mps2` (by default
    /// `tracker.acceleration_noise_std_mps2`), CA a white jerk, CT the CV noise plus a white
    /// turn acceleration; Markov switching with the configured mean sojourn times. A track
    /// starts with 80 % in the first mode and the rest shared equally. The CT mode predicts with
    /// the configured filter (`"ukf"`: sigma points through the turn; else the EKF).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for a coordinated turn in 3-D or a motion model without
    /// modes; [`EstimationError`] for noise or sojourn settings the models reject.
    pub(crate) fn new(settings: &TrackerSettings) -> Result<Self> {
        let imm = settings.imm;
        let planar = settings.dimensions != 3;
        let (kinds, cv_noise, ct_rate_noise) = match settings.motion_model {
            MotionModelKind::Ct => (
                vec![ImmModeKind::Ct],
                settings.acceleration_noise_std_mps2,
                settings.turn_rate_noise_std_radps2,
            ),
            MotionModelKind::Imm => (
                imm.modes.map_or_else(
                    || {
                        if planar {
                            vec![ImmModeKind::Cv, ImmModeKind::Ca, ImmModeKind::Ct]
                        } else {
                            vec![ImmModeKind::Cv, ImmModeKind::Ca]
                        }
                    },
                    |set| set.modes(),
                ),
                settings.imm_cv_acceleration_noise_std_mps2(),
                imm.ct_turn_rate_noise_std_radps2,
            ),
            MotionModelKind::Cv | MotionModelKind::Ca | MotionModelKind::RandomWalk => {
                return Err(EngineError::InvalidParameter {
                    name: "tracker.motion_model",
                    reason: "only \"imm\" and \"ct\" run as motion modes",
                })
            }
        };
        if !planar && kinds.contains(&ImmModeKind::Ct) {
            return Err(EngineError::InvalidParameter {
                name: "tracker.imm.modes",
                reason: "the coordinated turn is a 2-D model: track in 2-D or leave it out",
            });
        }
        // q = σ² (continuous white-noise spectral densities)
        let cv_noise = ProcessNoise::continuous(cv_noise.powi(2));
        let ca_noise = ProcessNoise::continuous(imm.ca_jerk_noise_std_mps3.powi(2));
        let axes = if planar { 2 } else { 3 };
        // the modes' own measurement models are unused: observations arrive with their noise
        let placeholder = NoiseCovariance::isotropic(axes, 1.0)?;
        let ukf = UnscentedKalmanFilter::new(SigmaPointParameters::default());
        let mut modes: Vec<Box<dyn ImmMode>> = Vec::with_capacity(kinds.len());
        let mut sojourn_s = Vec::with_capacity(kinds.len());
        let mut sole_turn = None;
        for kind in &kinds {
            let name = kind.name();
            let mode: Box<dyn ImmMode> = match (kind, planar) {
                (ImmModeKind::Cv, true) => Box::new(FilterMode::<4, _, _, _>::new(
                    name,
                    StateLayout::cv_2d(),
                    ConstantVelocity::new(cv_noise)?,
                    ComponentSelection::<4>::position(2, placeholder.clone())?,
                    KalmanFilter::default(),
                )?),
                (ImmModeKind::Cv, false) => Box::new(FilterMode::<6, _, _, _>::new(
                    name,
                    StateLayout::cv_3d(),
                    ConstantVelocity::new(cv_noise)?,
                    ComponentSelection::<6>::position(3, placeholder.clone())?,
                    KalmanFilter::default(),
                )?),
                (ImmModeKind::Ca, true) => Box::new(FilterMode::<6, _, _, _>::new(
                    name,
                    StateLayout::ca_2d(),
                    ConstantAcceleration::new(ca_noise)?,
                    ComponentSelection::<6>::position(2, placeholder.clone())?,
                    KalmanFilter::default(),
                )?),
                (ImmModeKind::Ca, false) => Box::new(FilterMode::<9, _, _, _>::new(
                    name,
                    StateLayout::ca_3d(),
                    ConstantAcceleration::new(ca_noise)?,
                    ComponentSelection::<9>::position(3, placeholder.clone())?,
                    KalmanFilter::default(),
                )?),
                (ImmModeKind::Ct, _) => {
                    let motion = CoordinatedTurnWithRate::new(cv_noise, ct_rate_noise.powi(2))?;
                    if kinds.len() == 1 {
                        sole_turn = Some(motion);
                    }
                    let selection = ComponentSelection::<5>::position(2, placeholder.clone())?;
                    if settings.filter == FilterKind::Ukf {
                        Box::new(FilterMode::<5, _, _, _>::new(
                            name,
                            StateLayout::ct_2d(),
                            motion,
                            selection,
                            ukf,
                        )?)
                    } else {
                        Box::new(FilterMode::<5, _, _, _>::new(
                            name,
                            StateLayout::ct_2d(),
                            motion,
                            selection,
                            ExtendedKalmanFilter::default(),
                        )?)
                    }
                }
            };
            modes.push(mode);
            sojourn_s.push(match kind {
                ImmModeKind::Cv => imm.cv_sojourn_s,
                ImmModeKind::Ca => imm.ca_sojourn_s,
                ImmModeKind::Ct => imm.ct_sojourn_s,
            });
        }
        // 80 % in the first mode, the rest shared (one mode: 1)
        let others = kinds.len().saturating_sub(1);
        let initial_probabilities = (0..kinds.len())
            .map(|i| match (i, others) {
                (_, 0) => 1.0,
                (0, _) => 0.8,
                _ => 0.2 / others as f64,
            })
            .collect();
        Ok(Self {
            // one mode stays in itself: Π = [1]
            imm: InteractingMultipleModel::new(
                modes,
                if sojourn_s.len() == 1 {
                    ModeTransitions::per_step(DMatrix::identity(1, 1))?
                } else {
                    ModeTransitions::mean_sojourn(sojourn_s)?
                },
            )?,
            layout: if planar {
                StateLayout::cv_2d()
            } else {
                StateLayout::cv_3d()
            },
            names: kinds.iter().map(|k| k.name()).collect(),
            initial_probabilities,
            switch_probability: imm.switch_probability,
            ukf: (settings.filter == FilterKind::Ukf).then_some(ukf),
            initial_turn_rate_variance: settings.initial_turn_rate_std_radps.powi(2),
            sole_turn,
        })
    }

    /// The name of mode `index` ("CV", "CA", "CT").
    pub(crate) fn name(&self, index: usize) -> &'static str {
        self.names.get(index).copied().unwrap_or("?")
    }

    /// The modes started from a CV state: shared components copied, accelerations
    /// `N(0, MISSING_VARIANCE)`, the turn rate `N(0, tracker.initial_turn_rate_std_radps²)`.
    ///
    /// # Errors
    /// [`EstimationError`] if the state does not fit the layout.
    pub(crate) fn start<const N: usize>(&self, state: &Gaussian<N>) -> rtls_estimation::Result<ImmState> {
        let mut modes = self.imm.initial_state(
            &ModeEstimate::from_gaussian(state),
            &self.layout,
            MISSING_VARIANCE,
            &self.initial_probabilities,
            state.time_s(),
        )?;
        // the turn rate's own prior, ω ~ N(0, σ_ω₀²) (uncorrelated: the fill is diagonal)
        for (mode, estimate) in self.imm.modes().iter().zip(modes.estimates_mut()) {
            if let Some(i) = mode.layout().index_of(Component::TurnRate) {
                estimate.covariance[(i, i)] = self.initial_turn_rate_variance;
            }
        }
        Ok(modes)
    }

    /// Mixing and mode-matched prediction to `time_s`.
    ///
    /// # Errors
    /// [`EstimationError::TimeWentBackwards`]; a mode's prediction errors.
    pub(crate) fn predict(&self, modes: &ImmState, time_s: f64) -> rtls_estimation::Result<ImmState> {
        self.bounded(self.imm.predict(modes, time_s)?)
    }

    /// [`Manoeuvres::predict`] with a measured acceleration `u` (m/s², one entry per axis) held
    /// over the step as the CV mode's control input, as the single CV model uses it: for a
    /// linear model the control enters the mean only,
    /// ```text
    /// x⁻_CV = F x⁰_CV + B u,   B_axis = [T²/2, T]ᵀ,   P⁻_CV = F P⁰_CV Fᵀ + Q
    /// ```
    /// so it is added to the CV mode's mode-matched prediction. The CA and CT modes keep
    /// estimating the acceleration themselves (an accelerometer is not a measurement in their
    /// likelihoods, which would make the modes' likelihoods incomparable).
    ///
    /// # Errors
    /// As [`Manoeuvres::predict`].
    pub(crate) fn predict_with_control(
        &self,
        modes: &ImmState,
        time_s: f64,
        u: &[f64],
    ) -> rtls_estimation::Result<ImmState> {
        let dt = time_s - modes.time_s();
        let mut predicted = self.imm.predict(modes, time_s)?;
        if let Some(cv) = predicted.estimates_mut().first_mut() {
            for (axis, a) in u.iter().enumerate().take(self.layout.len() / 2) {
                // B_axis u = [T²/2, T]ᵀ u
                cv.mean[2 * axis] += 0.5 * dt * dt * a;
                cv.mean[2 * axis + 1] += dt * a;
            }
        }
        self.bounded(predicted)
    }

    /// The modes with the coordinated turn's rate inside ±[`MAX_TURN_RATE_RAD_S`].
    fn bounded(&self, mut modes: ImmState) -> rtls_estimation::Result<ImmState> {
        for (mode, estimate) in self.imm.modes().iter().zip(modes.estimates_mut()) {
            if let Some(index) = mode.layout().index_of(Component::TurnRate) {
                estimate.bound_component(index, MAX_TURN_RATE_RAD_S)?;
            }
        }
        Ok(modes)
    }

    /// Each mode's state layout, in mode order.
    pub(crate) fn modes_layouts(&self) -> Vec<&StateLayout> {
        self.imm.modes().iter().map(|m| m.layout()).collect()
    }

    /// The moment-matched CV state `x̂ = Σⱼ μⱼ x̂ⱼ`, `P = Σⱼ μⱼ [Pⱼ + (x̂ⱼ − x̂)(·)ᵀ]`.
    ///
    /// # Errors
    /// [`EstimationError`] for a non-finite or asymmetric combination.
    pub(crate) fn combined<const N: usize>(&self, modes: &ImmState) -> rtls_estimation::Result<Gaussian<N>> {
        let (mean, covariance) = self.imm.combined(modes, &self.layout)?;
        Gaussian::new(
            Vector::<N>::from_column_slice(mean.as_slice()),
            Matrix::<N>::from_column_slice(covariance.as_slice()),
            modes.time_s(),
        )
    }

    /// Every mode updated with a direct observation `value` (row-major `covariance`) of the CV
    /// state's entries `indices` (positions `2i`, velocities `2i + 1`).
    ///
    /// # Errors
    /// [`EstimationError`] for a bad covariance or a failed mode update.
    pub(crate) fn update_components(
        &self,
        prior: &ImmState,
        indices: &[usize],
        value: &[f64],
        covariance: &[f64],
    ) -> rtls_estimation::Result<ImmState> {
        let k = indices.len();
        let components: Vec<Component> = indices.iter().map(|&i| self.layout.components()[i]).collect();
        let observation = ComponentObservation::new(
            components,
            DVector::from_column_slice(value),
            NoiseCovariance::full(DMatrix::from_row_slice(k, k, covariance))?,
        )?;
        self.bounded(self.imm.update_components(prior, &observation)?.state)
    }

    /// Every mode updated with one anchor reading `z` in its own layout: by a sigma-point step
    /// under `filter = "ukf"`, else by an EKF step.
    ///
    /// # Errors
    /// [`EstimationError`] at an anchor (undefined direction), for a non-positive innovation
    /// variance, or if every mode rejects the reading.
    pub(crate) fn update_anchor(
        &self,
        prior: &ImmState,
        model: &AnchorMeasurement,
        z: f64,
    ) -> rtls_estimation::Result<ImmState> {
        let time_s = prior.time_s();
        self.bounded(
            self.imm
                .update_with(prior, |mode, estimate| match &self.ukf {
                    Some(ukf) => sigma_point_update(ukf, mode.layout(), estimate, model, z, time_s),
                    None => scalar_update(mode.layout(), estimate, model, z),
                })?
                .state,
        )
    }

    /// The mode to report after `modes`, given the one reported so far: the most probable
    /// mode once its probability reaches `switch_probability` (anti-flap), else `current`.
    pub(crate) fn reported_mode(&self, modes: &ImmState, current: usize) -> usize {
        let best = modes.most_probable_mode();
        if best != current && modes.probabilities()[best] >= self.switch_probability {
            best
        } else {
            current
        }
    }
}

/// One scalar EKF update of a mode estimate in `layout` with an anchor reading:
/// ```text
/// p      = position entries of x (z = tag height in 2-D)
/// H      = ∂h/∂p on the position entries, 0 elsewhere          (1 × n)
/// ν      = z − h(p)
/// S      = H P Hᵀ + R
/// K      = P Hᵀ / S
/// x⁺     = x + K ν
/// P⁺     = (I − K H) P (I − K H)ᵀ + K R Kᵀ                      (Joseph form)
/// ln Λ   = −½ (ln 2πS + ν² / S)
/// ```
fn scalar_update(
    layout: &StateLayout,
    estimate: &ModeEstimate,
    model: &AnchorMeasurement,
    z: f64,
) -> rtls_estimation::Result<ModeUpdate> {
    let n = layout.len();
    let indices = [Axis::X, Axis::Y, Axis::Z].map(|axis| layout.index_of(Component::Position(axis)));
    let mut p = [0.0, 0.0, model.tag_height_m()];
    for (axis, index) in indices.iter().enumerate() {
        if let Some(i) = index {
            p[axis] = estimate.mean[*i];
        }
    }
    let gradient = model.gradient(&p)?;
    // H = ∂h/∂p on the position entries
    let mut h = DVector::<f64>::zeros(n);
    for (axis, index) in indices.iter().enumerate() {
        if let Some(i) = index {
            h[*i] = gradient[axis];
        }
    }
    let r = model.variance();
    // ν = z − h(p)
    let innovation = z - model.value(&p);
    // P Hᵀ, S = H P Hᵀ + R
    let ph = &estimate.covariance * &h;
    let s = h.dot(&ph) + r;
    if !s.is_finite() || s <= 0.0 {
        return Err(EstimationError::NonFinite {
            what: "innovation variance of an anchor reading (IMM mode)",
        });
    }
    // K = P Hᵀ / S
    let gain = ph / s;
    // x⁺ = x + K ν
    let mean = &estimate.mean + &gain * innovation;
    // P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ
    let i_kh = DMatrix::<f64>::identity(n, n) - &gain * h.transpose();
    let mut covariance = &i_kh * &estimate.covariance * i_kh.transpose() + &gain * gain.transpose() * r;
    covariance = (&covariance + covariance.transpose()) * 0.5;
    let nis = innovation * innovation / s;
    Ok(ModeUpdate {
        estimate: ModeEstimate { mean, covariance },
        // ln Λ = −½ (ln 2πS + ν²/S)
        log_likelihood: -0.5 * ((2.0 * core::f64::consts::PI * s).ln() + nis),
        nis,
    })
}

/// One anchor reading seen from a mode state: `h` of the entries `indices` that hold the
/// position `[x, y(, z)]` in the mode's layout (`z` = the tag height when the layout has none).
struct LayoutAnchor<'a> {
    model: &'a AnchorMeasurement,
    indices: [Option<usize>; 3],
}

impl LayoutAnchor<'_> {
    fn position(&self, x: &[f64]) -> [f64; 3] {
        let mut p = [0.0, 0.0, self.model.tag_height_m()];
        for (axis, index) in self.indices.iter().enumerate() {
            if let Some(i) = index {
                p[axis] = x[*i];
            }
        }
        p
    }
}

impl<const N: usize> MeasurementModel<N> for LayoutAnchor<'_> {
    fn dim(&self) -> usize {
        1
    }

    fn predict(&self, x: &Vector<N>) -> rtls_estimation::Result<DVector<f64>> {
        Ok(DVector::from_element(1, self.model.value(&self.position(x.as_slice()))))
    }

    fn jacobian(&self, x: &Vector<N>) -> rtls_estimation::Result<MeasurementJacobian<N>> {
        let gradient = self.model.gradient(&self.position(x.as_slice()))?;
        let mut h = MeasurementJacobian::<N>::zeros(1);
        for (axis, index) in self.indices.iter().enumerate() {
            if let Some(i) = index {
                h[(0, *i)] = gradient[axis];
            }
        }
        Ok(h)
    }

    fn noise_covariance(&self) -> &DMatrix<f64> {
        MeasurementModel::<N>::noise_covariance(self.model)
    }
}

/// One sigma-point (UKF) update of a mode estimate in `layout` with an anchor reading: the
/// tracker's UKF step in the mode's own state (sigma points of all `n` entries, `h` of their
/// position entries), and the mode likelihood `ln Λ = −½ (ln 2π + ln S + ν²/S)`.
fn sigma_point_update(
    ukf: &UnscentedKalmanFilter,
    layout: &StateLayout,
    estimate: &ModeEstimate,
    model: &AnchorMeasurement,
    z: f64,
    time_s: f64,
) -> rtls_estimation::Result<ModeUpdate> {
    fn update<const N: usize>(
        ukf: &UnscentedKalmanFilter,
        anchor: &LayoutAnchor<'_>,
        estimate: &ModeEstimate,
        z: f64,
        time_s: f64,
    ) -> rtls_estimation::Result<ModeUpdate> {
        let prior = estimate.to_gaussian::<N>(time_s)?;
        let updated = ukf.update(&prior, anchor, &DVector::from_element(1, z))?;
        Ok(ModeUpdate {
            estimate: ModeEstimate::from_gaussian(&updated.state),
            log_likelihood: updated.log_likelihood(),
            nis: updated.nis,
        })
    }
    let anchor = LayoutAnchor {
        model,
        indices: [Axis::X, Axis::Y, Axis::Z].map(|axis| layout.index_of(Component::Position(axis))),
    };
    match layout.len() {
        4 => update::<4>(ukf, &anchor, estimate, z, time_s),
        5 => update::<5>(ukf, &anchor, estimate, z, time_s),
        6 => update::<6>(ukf, &anchor, estimate, z, time_s),
        9 => update::<9>(ukf, &anchor, estimate, z, time_s),
        _ => Err(EstimationError::DimensionMismatch {
            what: "IMM mode layout for a sigma-point anchor update",
            expected: 9,
            found: layout.len(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::models::AnchorLaw;
    use rtls_estimation::filter::ExtendedKalmanFilter;

    #[test]
    fn a_mode_update_in_the_cv_layout_matches_the_ekf() {
        // the scalar update in the CV layout must equal the tracker's EKF on the same model
        let model = AnchorMeasurement::new([1.0, 2.0, 2.5], 1.0, AnchorLaw::Range, 0.04);
        let mean = Vector::<4>::new(4.0, 0.3, 6.0, -0.2);
        let covariance = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.5, 0.2, 0.4, 0.3));
        let prior = Gaussian::new(mean, covariance, 0.0).unwrap();
        let z = DVector::from_element(1, 5.3);
        let reference = ExtendedKalmanFilter::default().update(&prior, &model, &z).unwrap();
        let update = scalar_update(&StateLayout::cv_2d(), &ModeEstimate::from_gaussian(&prior), &model, 5.3).unwrap();
        for i in 0..4 {
            assert!((update.estimate.mean[i] - reference.state.mean()[i]).abs() < 1e-12);
            for j in 0..4 {
                assert!((update.estimate.covariance[(i, j)] - reference.state.covariance()[(i, j)]).abs() < 1e-12);
            }
        }
        assert!((update.nis - reference.nis).abs() < 1e-12);
    }

    #[test]
    fn the_turn_rate_stays_within_its_physical_bound() {
        let text = crate::tracker::tests::site_text("tightly-coupled", "ekf", "")
            .replace("motion_model = \"cv\"", "motion_model = \"imm\"");
        let site = crate::site::Site::from_toml_str(&text, "imm.toml").unwrap();
        let manoeuvres = Manoeuvres::new(&site.tracker).unwrap();
        let start = Gaussian::new(Vector::<4>::new(5.0, 1.0, 5.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
        let mut modes = manoeuvres.start(&start).unwrap();
        // a CT estimate that has drifted to 40 rad/s with a (20 rad/s)² variance
        let ct = &mut modes.estimates_mut()[2];
        ct.mean[4] = 40.0;
        ct.covariance[(4, 4)] = 400.0;
        ct.covariance[(0, 4)] = 3.0;
        ct.covariance[(4, 0)] = 3.0;
        for predicted in [
            manoeuvres.predict(&modes, 0.5).unwrap(),
            manoeuvres.predict_with_control(&modes, 0.5, &[0.2, 0.0]).unwrap(),
        ] {
            let ct = &predicted.estimates()[2];
            assert!(ct.mean[4].abs() <= MAX_TURN_RATE_RAD_S, "{}", ct.mean[4]);
            assert!(ct.covariance[(4, 4)] <= MAX_TURN_RATE_RAD_S.powi(2) * (1.0 + 1e-12));
            assert!(ct.covariance.clone().cholesky().is_some());
        }
    }

    #[test]
    fn the_accelerometer_moves_only_the_cv_modes_prediction() {
        let text = crate::tracker::tests::site_text("tightly-coupled", "ekf", "")
            .replace("motion_model = \"cv\"", "motion_model = \"imm\"");
        let site = crate::site::Site::from_toml_str(&text, "imm.toml").unwrap();
        let manoeuvres = Manoeuvres::new(&site.tracker).unwrap();
        let start = Gaussian::new(Vector::<4>::new(5.0, 1.0, 5.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
        let modes = manoeuvres.start(&start).unwrap();
        let free = manoeuvres.predict(&modes, 2.0).unwrap();
        let driven = manoeuvres.predict_with_control(&modes, 2.0, &[0.5, -0.25]).unwrap();
        // CV: x += T²/2 u, v += T u (T = 2 s); covariances unchanged
        let (f, d) = (&free.estimates()[0], &driven.estimates()[0]);
        let expected = [2.0 * 0.5, 2.0 * 0.5, 2.0 * -0.25, 2.0 * -0.25];
        for (i, shift) in expected.iter().enumerate() {
            assert!((d.mean[i] - f.mean[i] - shift).abs() < 1e-12, "entry {i}");
        }
        assert_eq!(d.covariance, f.covariance);
        // CA and CT are not driven
        assert_eq!(driven.estimates()[1], free.estimates()[1]);
        assert_eq!(driven.estimates()[2], free.estimates()[2]);
    }

    #[test]
    fn a_mode_update_leaves_entries_without_correlation_to_the_position_alone() {
        // CT layout [x, vx, y, vy, ω]: ω uncorrelated with the position is not updated
        let model = AnchorMeasurement::new([0.0, 0.0, 0.0], 0.0, AnchorLaw::Range, 0.01);
        let estimate = ModeEstimate {
            mean: DVector::from_vec(vec![3.0, 1.0, 4.0, 0.0, 0.1]),
            covariance: DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 1.0, 1.0, 1.0, 0.5])),
        };
        let update = scalar_update(&StateLayout::ct_2d(), &estimate, &model, 5.5).unwrap();
        assert_eq!(update.estimate.mean[4], 0.1);
        assert_eq!(update.estimate.covariance[(4, 4)], 0.5);
        // the range 5 → 5.5 pushes the position outwards along (3, 4)/5
        assert!(update.estimate.mean[0] > 3.0 && update.estimate.mean[2] > 4.0);
    }
}
