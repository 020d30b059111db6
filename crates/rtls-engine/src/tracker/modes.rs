//! `motion_model = "imm"`: the tracker's interacting multiple models — a quiet constant
//! velocity, a constant acceleration and (in 2-D) a coordinated turn with the turn rate as a
//! state — and the most probable mode, whose changes are reported as `model-switch` events.
//!
//! The track keeps its CV-layout state `[x, vx, y, vy(, z, vz)]` as the moment-matched
//! combination of the modes (so reporting, gating, zones and alarms are unchanged) and the
//! [`ImmState`] beside it. Fixes and velocities update every mode through
//! [`ComponentObservation`]s; a single anchor reading (tightly coupled) updates every mode by
//! an EKF step in that mode's own layout, since only the position enters the measurement.
//!
//! # References
//! H. A. P. Blom, Y. Bar-Shalom, "The interacting multiple model algorithm for systems with
//! Markovian switching coefficients", *IEEE Trans. Automatic Control* 33(8), 1988;
//! Bar-Shalom, Li, Kirubarajan (2001), §11.6.6–§11.7; seed 004 (manoeuvre detection, the
//! problem the IMM solves without a detector's delay).

use nalgebra::{DMatrix, DVector};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::imm::{
    Axis, Component, ComponentObservation, FilterMode, ImmMode, ImmState, InteractingMultipleModel, ModeEstimate,
    ModeTransitions, ModeUpdate, StateLayout,
};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantAcceleration, ConstantVelocity, CoordinatedTurnWithRate, ProcessNoise};
use rtls_estimation::{EstimationError, Gaussian, Matrix, Vector};

use super::models::AnchorMeasurement;
use crate::site::TrackerSettings;

/// Prior variance of the components a CV estimate lacks when the modes start: accelerations
/// ((m/s²)², i.e. σ = 1 m/s²) and the turn rate ((rad/s)², σ = 1 rad/s).
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
}

impl Manoeuvres {
    /// The modes for a `dimensions`-D track: CV (`tracker.imm.cv_acceleration_noise_std_mps2`,
    /// by default `tracker.acceleration_noise_std_mps2`), CA
    /// (white jerk) and, in 2-D, a coordinated turn; Markov switching with the configured mean
    /// sojourn times; start with 80 % CV (2-D: 10 % each manoeuvre mode; 3-D: 20 % CA).
    ///
    /// # Errors
    /// [`EstimationError`] for noise or sojourn settings the models reject.
    pub(crate) fn new(settings: &TrackerSettings) -> rtls_estimation::Result<Self> {
        let imm = settings.imm;
        // q = σ² (continuous white-noise spectral densities)
        let cv_noise = ProcessNoise::continuous(settings.imm_cv_acceleration_noise_std_mps2().powi(2));
        let ca_noise = ProcessNoise::continuous(imm.ca_jerk_noise_std_mps3.powi(2));
        let planar = settings.dimensions != 3;
        let axes = if planar { 2 } else { 3 };
        // the modes' own measurement models are unused: observations arrive with their noise
        let placeholder = NoiseCovariance::isotropic(axes, 1.0)?;
        let (modes, layout, names, sojourn_s, initial_probabilities): (Vec<Box<dyn ImmMode>>, _, _, _, _) = if planar {
            let cv = FilterMode::<4, _, _, _>::new(
                "CV",
                StateLayout::cv_2d(),
                ConstantVelocity::new(cv_noise)?,
                ComponentSelection::<4>::position(2, placeholder.clone())?,
                KalmanFilter::default(),
            )?;
            let ca = FilterMode::<6, _, _, _>::new(
                "CA",
                StateLayout::ca_2d(),
                ConstantAcceleration::new(ca_noise)?,
                ComponentSelection::<6>::position(2, placeholder.clone())?,
                KalmanFilter::default(),
            )?;
            let ct = FilterMode::<5, _, _, _>::new(
                "CT",
                StateLayout::ct_2d(),
                CoordinatedTurnWithRate::new(cv_noise, imm.ct_turn_rate_noise_std_radps2.powi(2))?,
                ComponentSelection::<5>::position(2, placeholder)?,
                ExtendedKalmanFilter::default(),
            )?;
            (
                vec![Box::new(cv), Box::new(ca), Box::new(ct)],
                StateLayout::cv_2d(),
                vec!["CV", "CA", "CT"],
                vec![imm.cv_sojourn_s, imm.ca_sojourn_s, imm.ct_sojourn_s],
                vec![0.8, 0.1, 0.1],
            )
        } else {
            let cv = FilterMode::<6, _, _, _>::new(
                "CV",
                StateLayout::cv_3d(),
                ConstantVelocity::new(cv_noise)?,
                ComponentSelection::<6>::position(3, placeholder.clone())?,
                KalmanFilter::default(),
            )?;
            let ca = FilterMode::<9, _, _, _>::new(
                "CA",
                StateLayout::ca_3d(),
                ConstantAcceleration::new(ca_noise)?,
                ComponentSelection::<9>::position(3, placeholder)?,
                KalmanFilter::default(),
            )?;
            (
                vec![Box::new(cv), Box::new(ca)],
                StateLayout::cv_3d(),
                vec!["CV", "CA"],
                vec![imm.cv_sojourn_s, imm.ca_sojourn_s],
                vec![0.8, 0.2],
            )
        };
        Ok(Self {
            imm: InteractingMultipleModel::new(modes, ModeTransitions::mean_sojourn(sojourn_s)?)?,
            layout,
            names,
            initial_probabilities,
            switch_probability: imm.switch_probability,
        })
    }

    /// The name of mode `index` ("CV", "CA", "CT").
    pub(crate) fn name(&self, index: usize) -> &'static str {
        self.names.get(index).copied().unwrap_or("?")
    }

    /// The modes started from a CV state: shared components copied, accelerations and the
    /// turn rate `N(0, MISSING_VARIANCE)`.
    ///
    /// # Errors
    /// [`EstimationError`] if the state does not fit the layout.
    pub(crate) fn start<const N: usize>(&self, state: &Gaussian<N>) -> rtls_estimation::Result<ImmState> {
        self.imm.initial_state(
            &ModeEstimate::from_gaussian(state),
            &self.layout,
            MISSING_VARIANCE,
            &self.initial_probabilities,
            state.time_s(),
        )
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

    /// Every mode updated with one anchor reading `z` by an EKF step in its own layout.
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
        self.bounded(
            self.imm
                .update_with(prior, |mode, estimate| scalar_update(mode.layout(), estimate, model, z))?
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
