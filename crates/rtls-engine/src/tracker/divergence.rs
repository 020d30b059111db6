//! Numerical divergence of a track: a state that is no longer an estimate of where the tag is.
//!
//! A filter whose state or covariance has become non-finite, whose position covariance has
//! grown beyond [`MAX_POSITION_VARIANCE_M2`], or whose position has left the site by more than
//! [`MAX_DISTANCE_FROM_SITE_M`] would go on outputting (and feeding zones and alarms with)
//! nonsense. Such a track is reported as a `rejected` event whose reason starts with
//! `track diverged` and restarts from its next fix; its lifecycle goes on (a restarted track is
//! not a new tag).

use nalgebra::DMatrix;
use rtls_estimation::imm::ImmState;
use rtls_estimation::Gaussian;

use super::bounds::SiteBounds;
use super::output::Output;
use super::track::{dimensions, rejected, Track};

/// The largest trace of a track's position covariance, m²: a 10 km standard deviation, far
/// beyond any site and any honest coast (a CV track coasting 600 s at σ_a = 1 m/s² reaches
/// `q T³/3 ≈ 7.2·10⁷ m²` per axis, below this).
pub(super) const MAX_POSITION_VARIANCE_M2: f64 = 1.0e8;

/// The farthest a track's position may be from the box around the site's readers, m.
pub(super) const MAX_DISTANCE_FROM_SITE_M: f64 = 10_000.0;

/// Why `state` (and, under the IMM, its `modes`) has diverged, or `None` when it is sound.
pub(super) fn divergence<const N: usize>(
    bounds: &SiteBounds,
    state: &Gaussian<N>,
    modes: Option<&ImmState>,
) -> Option<String> {
    let d = dimensions::<N>();
    let (mean, covariance) = (state.mean(), state.covariance());
    if mean.iter().chain(covariance.iter()).any(|x| !x.is_finite()) {
        return Some("non-finite state or covariance".to_string());
    }
    if let Some(modes) = modes {
        let finite = |m: &DMatrix<f64>| m.iter().all(|x| x.is_finite());
        if modes
            .estimates()
            .iter()
            .any(|e| !e.mean.iter().all(|x| x.is_finite()) || !finite(&e.covariance))
        {
            return Some("non-finite motion-mode estimate".to_string());
        }
    }
    // tr P_pos = Σ P[2i, 2i]
    let trace: f64 = (0..d).map(|i| covariance[(2 * i, 2 * i)]).sum();
    if trace > MAX_POSITION_VARIANCE_M2 {
        return Some(format!(
            "position covariance trace {trace:.3e} m² beyond {MAX_POSITION_VARIANCE_M2:.0e} m²"
        ));
    }
    let mut position = [0.0; 3];
    for (i, x) in position.iter_mut().enumerate().take(d) {
        *x = mean[2 * i];
    }
    match bounds.distance_m(&position, d) {
        Some(distance) if distance > MAX_DISTANCE_FROM_SITE_M => Some(format!(
            "position {distance:.3e} m outside the readers' box, beyond {MAX_DISTANCE_FROM_SITE_M:.0} m"
        )),
        _ => None,
    }
}

/// Checks `track`'s state; a diverged track is reported (`kind` names what revealed it) and
/// forgets its state and motion modes, so it restarts from its next fix.
///
/// Returns `true` when the track was reset.
pub(super) fn reset_if_diverged<const N: usize>(
    bounds: &SiteBounds,
    track: &mut Track<N>,
    time_s: f64,
    kind: &'static str,
    out: &mut Output,
) -> bool {
    let Some(reason) = track
        .state
        .as_ref()
        .and_then(|state| divergence(bounds, state, track.modes.as_ref()))
    else {
        return false;
    };
    reset(track, time_s, kind, &reason, out);
    true
}

/// Forgets `track`'s state (reporting `reason`): it restarts from its next fix.
pub(super) fn reset<const N: usize>(
    track: &mut Track<N>,
    time_s: f64,
    kind: &'static str,
    reason: &str,
    out: &mut Output,
) {
    let reason = format!("track diverged: {reason}; it restarts from its next fix");
    out.events.push(rejected(&track.tag, time_s, kind, reason));
    track.state = None;
    track.heading_cross = None;
    track.offset_cross = None;
    track.modes = None;
    track.lost_state = None;
    track.unreported = None;
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_estimation::{Matrix, Vector};

    fn bounds() -> SiteBounds {
        SiteBounds {
            extent_m: Some(([0.0, 0.0, 0.0], [20.0, 20.0, 3.0])),
        }
    }

    #[test]
    fn sound_states_pass_and_each_bound_is_named() {
        let sound = Gaussian::new(Vector::<4>::new(10.0, 1.0, 5.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
        assert_eq!(divergence(&bounds(), &sound, None), None);
        let wide = Gaussian::new(Vector::<4>::zeros(), Matrix::<4>::identity() * 6.0e7, 0.0).unwrap();
        assert!(divergence(&bounds(), &wide, None).unwrap().contains("covariance trace"));
        let far = Gaussian::new(Vector::<4>::new(2.5e121, 0.0, 0.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
        assert!(divergence(&bounds(), &far, None)
            .unwrap()
            .contains("outside the readers' box"));
        // 9 km out is still a (distant) estimate; without readers positions are not checked
        let distant = Gaussian::new(Vector::<4>::new(9_020.0, 0.0, 0.0, 0.0), Matrix::<4>::identity(), 0.0).unwrap();
        assert_eq!(divergence(&bounds(), &distant, None), None);
        assert_eq!(divergence(&SiteBounds { extent_m: None }, &far, None), None);
    }
}
