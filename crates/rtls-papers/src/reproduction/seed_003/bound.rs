//! The posterior Cramér–Rao bound of one robot's position over a seed 003 run, under two
//! dynamics: the trackers' CV model, or the robot's true manoeuvres.

use nalgebra::DMatrix;
use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel};
use rtls_estimation::Matrix;

use crate::error::Result;
use rtls_sim::pcrb::{measurement_information, posterior_crb, PcrbStep};
use rtls_sim::trajectory::WaypointPath;

/// The dynamics a bound assumes between two events.
#[derive(Debug, Clone, Copy)]
pub(crate) enum BoundDynamics<'a> {
    /// The trackers' model: CV with continuous white acceleration (`F(dt)`, `Q(dt)`). It bounds
    /// estimators of trajectories drawn from that model; on the robots' exactly straight legs
    /// an estimator can beat it.
    TrackerModel(&'a ConstantVelocity),
    /// The robot's route: constant velocity on every leg (`Q = 0`), and at every change of
    /// velocity `Δv` (a turn, a stop, a start) the velocity re-opened by
    /// `Q = |Δv|² diag(0, 1, 0, 1)` — the PCRB conditional on the true manoeuvre times, a
    /// lower bound for any estimator that does not know them.
    TrueManoeuvres(&'a WaypointPath),
}

impl BoundDynamics<'_> {
    /// `(F, Q)` from `from_s` to `to_s`.
    fn step(&self, from_s: f64, to_s: f64) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
        let dt_s = (to_s - from_s).max(0.0);
        let cv = |m: &ConstantVelocity| {
            (
                DMatrix::from_column_slice(4, 4, LinearMotionModel::<4>::transition_matrix(m, dt_s).as_slice()),
                DMatrix::from_column_slice(4, 4, LinearMotionModel::<4>::process_noise_matrix(m, dt_s).as_slice()),
            )
        };
        match self {
            Self::TrackerModel(model) => Ok(cv(model)),
            Self::TrueManoeuvres(route) => {
                // F = CV(dt); Q = |Δv|² on both velocities if the velocity changed in between
                let mut transition = DMatrix::identity(4, 4);
                transition[(0, 1)] = dt_s;
                transition[(2, 3)] = dt_s;
                let (a, b) = (route.state_at(from_s)?.velocity_mps, route.state_at(to_s)?.velocity_mps);
                let jump_mps2 = (b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2);
                let mut noise = DMatrix::zeros(4, 4);
                noise[(1, 1)] = jump_mps2;
                noise[(3, 3)] = jump_mps2;
                Ok((transition, noise))
            }
        }
    }
}

/// A range to a node that truly came from the robot: when, from where, and the robot's true
/// position then.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RangeEvent {
    /// Firing time (s).
    pub time_s: f64,
    /// The firing node (m).
    pub node_m: [f64; 2],
    /// The robot's true position at the firing (m).
    pub truth_m: [f64; 2],
}

/// The bound `B₀₀ + B₂₂` on the position MSE (m²) at each of `epochs_s` (ascending), for the
/// dynamics `dynamics`, the prior `prior` (the trackers' `P₀`) and the ranges `events` (ascending),
/// each of variance `range_variance_m2` and information `Hᵀ R⁻¹ H`,
/// `H = [(x − xa)/d, 0, (y − ya)/d, 0]` at the true position. A range at the same time as an
/// epoch counts before it.
///
/// # Errors
/// As [`posterior_crb`] and [`measurement_information`]; as [`WaypointPath::state_at`].
pub(crate) fn position_bound_m2(
    dynamics: BoundDynamics<'_>,
    prior: &Matrix<4>,
    range_variance_m2: f64,
    events: &[RangeEvent],
    epochs_s: &[f64],
) -> Result<Vec<f64>> {
    let r = DMatrix::from_element(1, 1, range_variance_m2);
    let zero = DMatrix::zeros(4, 4);
    let mut steps = Vec::with_capacity(events.len() + epochs_s.len());
    let mut is_epoch = Vec::with_capacity(steps.capacity());
    let (mut e, mut k, mut time_s) = (0, 0, 0.0);
    while k < epochs_s.len() {
        let take_event = e < events.len() && events[e].time_s <= epochs_s[k];
        let (next_s, information) = if take_event {
            let RangeEvent {
                time_s,
                node_m,
                truth_m,
            } = events[e];
            e += 1;
            // u = (p − a)/d, H = [uₓ, 0, u_y, 0]
            let d = (truth_m[0] - node_m[0]).hypot(truth_m[1] - node_m[1]);
            let information = if d > 1e-9 {
                let h = DMatrix::from_row_slice(
                    1,
                    4,
                    &[(truth_m[0] - node_m[0]) / d, 0.0, (truth_m[1] - node_m[1]) / d, 0.0],
                );
                // J_z = Hᵀ R⁻¹ H
                measurement_information(&h, &r)?
            } else {
                zero.clone()
            };
            (time_s, information)
        } else {
            k += 1;
            (epochs_s[k - 1], zero.clone())
        };
        let (transition, process_noise) = dynamics.step(time_s, next_s.max(time_s))?;
        time_s = next_s.max(time_s);
        steps.push(PcrbStep {
            transition,
            process_noise,
            measurement_information: information,
        });
        is_epoch.push(!take_event);
    }
    let bounds = posterior_crb(&DMatrix::from_column_slice(4, 4, prior.as_slice()), steps)?;
    Ok(bounds
        .iter()
        .zip(&is_epoch)
        .filter(|(_, &epoch)| epoch)
        // position MSE bound: B₀₀ + B₂₂
        .map(|(b, _)| (b[(0, 0)] + b[(2, 2)]).max(0.0))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_estimation::motion::ProcessNoise;
    use rtls_estimation::Vector;

    #[test]
    fn ranges_shrink_the_bound_and_silence_grows_it() {
        let motion = ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap();
        let prior = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.01, 0.04, 0.01, 0.04));
        let truth = [1.0, 1.0];
        let events: Vec<RangeEvent> = (0..30)
            .map(|k| RangeEvent {
                time_s: 0.1 * k as f64,
                node_m: [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]][k % 3],
                truth_m: truth,
            })
            .collect();
        let model = BoundDynamics::TrackerModel(&motion);
        let bounds = position_bound_m2(model, &prior, 0.0009, &events, &[0.0, 1.0, 2.9, 6.0]).unwrap();
        assert_eq!(bounds.len(), 4);
        // one range at t = 0 already informs one direction: below the prior's 0.02
        assert!(bounds[0] < 0.02);
        assert!(bounds[1] < bounds[0] && bounds[2] < bounds[0], "{bounds:?}");
        // 3 s without ranges: the bound grows again
        assert!(bounds[3] > bounds[2]);
        // no ranges at all: the prior, propagated
        let silent = position_bound_m2(model, &prior, 0.0009, &[], &[0.0]).unwrap();
        assert!((silent[0] - 0.02).abs() < 1e-12);
    }

    #[test]
    fn true_manoeuvres_bound_a_straight_leg_below_the_model_and_reopen_at_a_turn() {
        let motion = ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap();
        let prior = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.01, 0.04, 0.01, 0.04));
        // 4 s east at 0.5 m/s, then 4 s north
        let route =
            rtls_sim::scenarios::seed_003::planar_route(&[[0.5, 1.0], [2.5, 1.0], [2.5, 3.0]], 0.5, 0.0, &[]).unwrap();
        let nodes = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0], [4.0, 4.0]];
        let events: Vec<RangeEvent> = (0..80)
            .map(|k| {
                let t = 0.1 * k as f64;
                let p = route.state_at(t).unwrap().position_m;
                RangeEvent {
                    time_s: t,
                    node_m: nodes[k % 4],
                    truth_m: [p[0], p[1]],
                }
            })
            .collect();
        let epochs = [3.9, 4.05, 4.5, 7.9];
        let model = position_bound_m2(BoundDynamics::TrackerModel(&motion), &prior, 0.0009, &events, &epochs).unwrap();
        let truth = position_bound_m2(BoundDynamics::TrueManoeuvres(&route), &prior, 0.0009, &events, &epochs).unwrap();
        // on the straight leg the truth-conditioned bound is far below the model's
        assert!(truth[0] < 0.25 * model[0], "{truth:?} vs {model:?}");
        // the turn at 4 s re-opens the velocity: the bound rises after it, then falls again
        assert!(truth[2] > truth[0] && truth[3] < truth[2], "{truth:?}");
    }
}
