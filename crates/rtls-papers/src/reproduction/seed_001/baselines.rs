//! The trackers of a seed 001 run: the paper's UKF and an EKF on the CV model, UKF and EKF on
//! the coordinated turn with the rate as a state, and an IMM of a CV and a CT UKF.

use rtls_estimation::filter::{ExtendedKalmanFilter, GaussianFilter, UnscentedKalmanFilter};
use rtls_estimation::imm::{FilterMode, ImmMode, InteractingMultipleModel, ModeEstimate, ModeTransitions, StateLayout};
use rtls_estimation::measurement::Stacked;
use rtls_estimation::motion::{ConstantVelocity, CoordinatedTurnWithRate};
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::{FilterTrack, JointMeasurement, RunData, Seed001Config, Seed001Filter};
use crate::error::{finite, Result, SimError};

/// The trackers of [`Seed001Filter::ALL`], in order.
pub(super) fn run_trackers(
    config: &Seed001Config,
    joint: &JointMeasurement,
    initial: &Gaussian<4>,
    data: &RunData<'_>,
) -> Result<[FilterTrack; Seed001Filter::COUNT]> {
    let cv = ConstantVelocity::new(config.truth.process_noise()).map_err(SimError::estimation(0.0))?;
    let ct = CoordinatedTurnWithRate::new(config.truth.process_noise(), config.turn_rate_noise_std_rad_s2.powi(2))
        .map_err(SimError::estimation(0.0))?;
    let ukf = UnscentedKalmanFilter::new(config.sigma_points);
    let ekf = ExtendedKalmanFilter::default();
    // [x, vx, y, vy, ω] with ω ~ N(0, σ_ω₀²)
    let mut mean5 = Vector::<5>::zeros();
    let mut cov5 = Matrix::<5>::zeros();
    mean5.fixed_rows_mut::<4>(0).copy_from(initial.mean());
    cov5.fixed_view_mut::<4, 4>(0, 0).copy_from(initial.covariance());
    cov5[(4, 4)] = config.turn_rate_prior_std_rad_s.powi(2);
    let initial5 = Gaussian::new(mean5, cov5, 0.0).map_err(SimError::estimation(0.0))?;
    let joint5 = Stacked::new::<5>(joint.first().clone(), joint.second().clone());
    let imm = imm(config, cv, ct, joint, &joint5)?;
    Ok([
        run_filter(&ukf, &cv, joint, *initial, data)?,
        run_filter(&ekf, &cv, joint, *initial, data)?,
        run_filter(&ukf, &ct, &joint5, initial5, data)?,
        run_filter(&ekf, &ct, &joint5, initial5, data)?,
        run_imm(&imm, config, initial, data)?,
    ])
}

/// The IMM of a CV UKF and a CT (rate estimated) UKF with mean sojourn times
/// [`Seed001Config::imm_sojourn_s`].
fn imm(
    config: &Seed001Config,
    cv: ConstantVelocity,
    ct: CoordinatedTurnWithRate,
    joint: &JointMeasurement,
    joint5: &JointMeasurement,
) -> Result<InteractingMultipleModel> {
    let ukf = UnscentedKalmanFilter::new(config.sigma_points);
    let cv_mode = FilterMode::<4, _, _, _>::new("CV", StateLayout::cv_2d(), cv, joint.clone(), ukf);
    let ct_mode = FilterMode::<5, _, _, _>::new("CT", StateLayout::ct_2d(), ct, joint5.clone(), ukf);
    let modes: Vec<Box<dyn ImmMode>> = vec![
        Box::new(cv_mode.map_err(SimError::estimation(0.0))?),
        Box::new(ct_mode.map_err(SimError::estimation(0.0))?),
    ];
    ModeTransitions::mean_sojourn(config.imm_sojourn_s.to_vec())
        .and_then(|transitions| InteractingMultipleModel::new(modes, transitions))
        .map_err(SimError::estimation(0.0))
}

/// The IMM over every epoch, started with equal mode probabilities and the CT mode's turn rate
/// at 0 with the CT filters' prior; output the moment-matched `[x, vx, y, vy]`.
fn run_imm(
    imm: &InteractingMultipleModel,
    config: &Seed001Config,
    initial: &Gaussian<4>,
    data: &RunData<'_>,
) -> Result<FilterTrack> {
    let layout = StateLayout::cv_2d();
    let mut state = imm
        .initial_state(
            &ModeEstimate::from_gaussian(initial),
            &layout,
            config.turn_rate_prior_std_rad_s.powi(2),
            &[0.5, 0.5],
            0.0,
        )
        .map_err(SimError::estimation(0.0))?;
    let mut track = FilterTrack::with_capacity(data.truth.len());
    for ((&t, z), truth) in data.times_s.iter().zip(data.measurements).zip(data.truth) {
        let prior = imm.predict(&state, t).map_err(SimError::estimation(t))?;
        let updated = imm.update(&prior, z).map_err(SimError::estimation(t))?;
        state = updated.state;
        // x̂ = Σⱼ μⱼ x̂ⱼ,  P = Σⱼ μⱼ [Pⱼ + (x̂ⱼ − x̂)(·)ᵀ]  in the CV layout
        let (mean, covariance) = imm.combined(&state, &layout).map_err(SimError::estimation(t))?;
        let combined = Gaussian::new(
            Vector::<4>::from_column_slice(mean.as_slice()),
            Matrix::<4>::from_column_slice(covariance.as_slice()),
            t,
        )
        .map_err(SimError::estimation(t))?;
        let nis = updated
            .nis
            .get(state.most_probable_mode())
            .copied()
            .ok_or(SimError::EmptyInput { what: "IMM mode NIS" })?;
        track.record(&combined, truth, nis, t)?;
    }
    Ok(track)
}

/// Predict–update over every epoch with one filter.
pub(super) fn run_filter<const N: usize, M, H, F>(
    filter: &F,
    motion: &M,
    measurement: &H,
    initial: Gaussian<N>,
    data: &RunData<'_>,
) -> Result<FilterTrack>
where
    F: GaussianFilter<N, M, H>,
{
    let mut state = initial;
    let mut track = FilterTrack::with_capacity(data.truth.len());
    for ((&t, z), truth) in data.times_s.iter().zip(data.measurements).zip(data.truth) {
        let prior = filter.predict(&state, motion, t).map_err(SimError::estimation(t))?;
        let updated = filter.update(&prior, measurement, z).map_err(SimError::estimation(t))?;
        state = updated.state;
        track.record(&state, truth, updated.nis, t)?;
    }
    Ok(track)
}

impl FilterTrack {
    pub(super) fn with_capacity(epochs: usize) -> Self {
        Self {
            estimates: Vec::with_capacity(epochs),
            nees: Vec::with_capacity(epochs),
            nis: Vec::with_capacity(epochs),
            downweighted_ranges: 0,
        }
    }

    /// Appends the estimate, its NEES against `truth` (on `[x, vx, y, vy]`) and the NIS.
    pub(super) fn record<const N: usize>(
        &mut self,
        state: &Gaussian<N>,
        truth: &[f64; 4],
        nis: f64,
        t: f64,
    ) -> Result<()> {
        let mean = state.mean();
        // the [x, vx, y, vy] marginal (the first four entries of every layout used here)
        let marginal = Gaussian::new(
            Vector::<4>::from_fn(|i, _| mean[i]),
            Matrix::<4>::from_fn(|i, j| state.covariance()[(i, j)]),
            t,
        )
        .map_err(SimError::estimation(t))?;
        let nees = marginal
            .nees(&Vector::<4>::from(*truth))
            .map_err(SimError::estimation(t))?;
        self.estimates.push([mean[0], mean[1], mean[2], mean[3]]);
        self.nees.push(finite(nees, "NEES")?);
        self.nis.push(finite(nis, "NIS")?);
        Ok(())
    }
}
