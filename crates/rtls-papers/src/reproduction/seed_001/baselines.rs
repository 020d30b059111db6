//! The paper's own trackers, as printed: its UKF (α = 0.01, β = 2, κ = 0) and an EKF on the CV
//! model over the joint measurement `z = [z_TOA; z_RSS]`. They are the baselines "ours" (the
//! engine's tracker, [`super::engine`]) is compared with, built from rtls-estimation's filters
//! exactly as the paper describes them.

use rtls_estimation::filter::GaussianFilter;
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::{FilterTrack, RunData};
use crate::error::{finite, Result, SimError};

/// Predict–update over every epoch with one of the paper's filters.
pub(super) fn run_baseline<const N: usize, M, H, F>(
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
    let mut track = FilterTrack::with_capacity(data.truth.len(), 4);
    for ((&t, z), truth) in data.times_s.iter().zip(data.measurements).zip(data.truth) {
        let prior = filter.predict(&state, motion, t).map_err(SimError::estimation(t))?;
        let updated = filter.update(&prior, measurement, z).map_err(SimError::estimation(t))?;
        state = updated.state;
        track.record(&state, truth, updated.nis, t)?;
    }
    Ok(track)
}

impl FilterTrack {
    /// An empty track whose NEES has `nees_dof` degrees of freedom.
    pub(super) fn with_capacity(epochs: usize, nees_dof: usize) -> Self {
        Self {
            estimates: Vec::with_capacity(epochs),
            nees: Vec::with_capacity(epochs),
            nees_dof,
            nis: Vec::with_capacity(epochs),
            downweighted_ranges: 0,
        }
    }

    /// Appends the estimate, its NEES against `truth` (on `[x, vx, y, vy]`) and the NIS.
    fn record<const N: usize>(&mut self, state: &Gaussian<N>, truth: &[f64; 4], nis: f64, t: f64) -> Result<()> {
        let mean = state.mean();
        // the [x, vx, y, vy] marginal (the first four entries)
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
