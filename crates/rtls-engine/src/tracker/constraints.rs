//! What a track knows at the end of each epoch beyond its measurements (seed 000's manager
//! layer): which readers did *not* hear the tag (negative information), the corridors the tag
//! cannot leave (the map), and how fast it can move (the speed limit).
//!
//! An epoch opens with a track's first reading or update at `t₀` and closes when a record or a
//! clock tick comes later than `t₀ + tracker.epoch_s`. At the close, on the state at its time:
//!
//! ```text
//! silence   of the working readers j with a sensitivity S_j that did not hear the tag, in line
//!           of sight of the estimate through the corridors, the one with the largest
//!             ŷ_j − S_j,  ŷ_j = ρ₀ − 10 n log₁₀(‖p̂ − r_j‖ / d₀)
//!           if ŷ_j − S_j ≥ σ_X: EKF update with z = S_j, R = σ_X²       (Koch 2007)
//! map       nearest corridor segment (a, u, n); unless a junction is within r_J of p̂:
//!             e = n·(p − a) = 0 ± σ_lat                                 (Simon 2010)
//!           past a dead end a (or b): the mean projected back onto it, u·(p − b) ≤ 0
//!           (estimate projection, P kept)
//! speed     ‖v_xy‖ > v_max  →  v_xy ← v_xy · v_max / ‖v_xy‖             (estimate projection)
//! ```
//!
//! A coasting track (no reader heard the tag at all) gets the silence of every reader and the
//! map at each coasting output: a miner behind a roof fall is where no working reader can hear
//! him, and the estimate goes there instead of drifting on.
//!
//! Zones without coverage (every reader listed for the zone is broken: seed 000's roof fall)
//! shield: an estimate inside one is not expected to be heard by anyone, and a reader whose line
//! to the estimate crosses one is not expected to hear it (the rubble that broke the reader
//! stops its neighbours' radio too).
//!
//! # References
//! W. Koch, "On exploiting 'negative' sensor evidence for target tracking and sensor data
//! fusion", *Information Fusion* 8(1), 2007; D. Simon, "Kalman filtering with state
//! constraints: a survey of linear and nonlinear algorithms", *IET Control Theory &
//! Applications* 4(8), 2010; seed 000 §3 (the mine's manager layer).

use nalgebra::DVector;
use rtls_estimation::imm::{Axis, Component, ImmState};
use rtls_estimation::Gaussian;

use super::alarms::position_of;
use super::constraint_model::Constraints;
use super::models::{AnchorLaw, AnchorMeasurement};
use super::output::epoch_raw_fix;
use super::output::Output;
use super::readings_fix::solve;
use super::step::{carry_cross_covariances, predict, reacquire};
use super::track::rejected;
use super::track::{dimensions, Shared, Track};
use super::update::fix_update;
use crate::error::Result;
use crate::site::FilterKind;

/// Closes the track's epoch if `now_s` is past `t₀ + epoch_s`: applies silence, map and speed
/// to the state at its time. If most of the readers that heard the tag (at least two) have no
/// line of sight through the corridors to the estimate, the estimate is in the wrong corridor (a single-hypothesis track that took the wrong
/// branch at a junction): it restarts at the fix of the epoch's own readings (an event says
/// so), or keeps its state when they give none.
///
/// # Errors
/// A failed filter step (the caller reports it and restarts the track).
pub(super) fn close_epoch_if_due<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    out: &mut Output,
) -> Result<()> {
    let Some(constraints) = shared.constraints.as_ref() else {
        return Ok(());
    };
    let Some(open_s) = track.hearing.open_since_s else {
        return Ok(());
    };
    if now_s - open_s <= shared.settings.epoch_s.unwrap_or(0.0) {
        return Ok(());
    }
    let heard = std::mem::take(&mut track.hearing.heard);
    track.hearing.open_since_s = None;
    let readings = std::mem::take(&mut track.hearing.readings);
    if track.state.is_none() || track.is_lost() {
        return Ok(());
    }
    if let (true, Some(p)) = (constraints.map_enabled, position(shared, track)) {
        let plan = [p[0], p[1]];
        let blocked = heard
            .iter()
            .filter(|&&i| {
                let a = shared.anchors.get(i).position_m;
                !constraints.map.line_of_sight(plan, [a[0], a[1]])
            })
            .count();
        // restart at once: waiting a second epoch (a reader heard round a corner is one epoch's
        // evidence) left the demo mine's miners in the wrong drift (`rtls sim mine` → `rtls
        // track` → `rtls eval`: RMSE 6.30 m against 2.14 m)
        if heard.len() >= 2 && 2 * blocked > heard.len() {
            let time_s = track.state.as_ref().map_or(open_s, Gaussian::time_s);
            let readers: Vec<[f64; 2]> = heard
                .iter()
                .map(|&i| {
                    let a = shared.anchors.get(i).position_m;
                    [a[0], a[1]]
                })
                .collect();
            let fixes = solve::<N>(shared, &readings, None).ok();
            let what = if fixes.is_some() {
                "restarts at the fix of this epoch's readings, moved onto the corridor nearest it that they \
                 can see when one lies within 3σ"
            } else {
                "(its readings give no fix to restart at) moves onto the corridor nearest it that they can \
                 see when one lies within 3σ"
            };
            let reason = format!(
                "{blocked} of the {} readers that heard the tag cannot see the estimate through the corridors: \
                 the track is in the wrong corridor and {what}",
                heard.len()
            );
            out.events.push(rejected(&track.tag, time_s, "epoch", reason));
            match fixes {
                Some(fixes) => {
                    reacquire(track);
                    for (position, covariance, method) in fixes {
                        out.fixes
                            .push(epoch_raw_fix(&track.tag, time_s, &position, &covariance, method));
                        // the fix's readings came through the corridors: start where the readers
                        // that heard them can see, within 3σ of it (a fix between two drifts
                        // sits in the rock, and a start there is refused again next epoch)
                        let d = position.len().min(3);
                        let radius_m = 3.0 * covariance[0].max(covariance[d + 1]).sqrt();
                        let mut start = position.clone();
                        if let Some(foot) = visible_foot(constraints, [position[0], position[1]], &readers, radius_m) {
                            start[..2].copy_from_slice(&foot);
                        }
                        fix_update(shared, track, time_s, &start, &covariance, "epoch", out)?;
                    }
                }
                None => {
                    // no fix: the estimate itself moves there (its covariance kept: projecting
                    // the mean onto the constraint, Simon 2010 §2.3)
                    if let Some(state) = track.state {
                        let p = state.covariance();
                        let radius_m = 3.0 * p[(0, 0)].max(p[(2, 2)]).sqrt();
                        if let Some(foot) = visible_foot(constraints, plan, &readers, radius_m) {
                            let mut mean = *state.mean();
                            mean[0] = foot[0];
                            mean[2] = foot[1];
                            track.state = Some(Gaussian::new(mean, *p, state.time_s())?);
                        }
                    }
                }
            }
            return Ok(());
        }
    }
    constrain(shared, constraints, track, &heard)
}

/// A coasting track at `now_s`: predicted there, then every listening reader's silence, the map
/// and the speed limit.
///
/// # Errors
/// A failed prediction or filter step.
pub(super) fn coast<const N: usize>(shared: &Shared, track: &mut Track<N>, now_s: f64) -> Result<()> {
    let Some(constraints) = shared.constraints.as_ref() else {
        return Ok(());
    };
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    if state.time_s() >= now_s {
        return Ok(());
    }
    let prior = predict(shared, track, state, now_s)?;
    track.state = Some(prior.state);
    if prior.modes.is_some() {
        track.modes = prior.modes;
    }
    constrain(shared, constraints, track, &[])
}

/// Silence, map and speed on the track's state, in that order. A state they changed was told
/// more than the information the track keeps for a smoother (pseudo-measurements and
/// projections are not measurements): it is marked partial, and a smoother runs the site's
/// model over the tracker's states there instead of re-filtering without them.
fn constrain<const N: usize>(
    shared: &Shared,
    constraints: &Constraints,
    track: &mut Track<N>,
    heard: &[usize],
) -> Result<()> {
    let before = track.state;
    silence(shared, constraints, track, heard)?;
    if constraints.map_enabled {
        map(shared, constraints, track)?;
    }
    if let Some(max_speed_mps) = constraints.max_speed_mps {
        limit_speed(shared, track, max_speed_mps)?;
    }
    if track.state != before {
        track.information_partial = true;
    }
    Ok(())
}

/// The tag position `[x, y, z]` of the track's state.
/// The corridor point within `radius_m` (at least 5 m) of `p` that the most of `readers` see
/// ([`crate::corridors::CorridorMap::visible_point_near`]).
fn visible_foot(constraints: &Constraints, p: [f64; 2], readers: &[[f64; 2]], radius_m: f64) -> Option<[f64; 2]> {
    constraints
        .map
        .visible_point_near(p, readers, radius_m.max(MIN_VISIBLE_RADIUS_M))
}

/// The least distance searched for a corridor point the readers see, m.
const MIN_VISIBLE_RADIUS_M: f64 = 5.0;

fn position<const N: usize>(shared: &Shared, track: &Track<N>) -> Option<[f64; 3]> {
    track.state.as_ref().map(|s| position_of(s, shared.tag_height_m).0)
}

/// Negative information: of the listening readers that did not hear the tag, the one that
/// should most surely have heard it (largest `ŷ − S`), if `ŷ − S ≥ σ_X` (it hears a tag there
/// at least 84 % of the time). One per epoch: the silences of neighbouring readers are not
/// independent evidence, and stacking them as independent Gaussian measurements collapses the
/// covariance until real readings are gated out (measured on the demo mine).
fn silence<const N: usize>(
    shared: &Shared,
    constraints: &Constraints,
    track: &mut Track<N>,
    heard: &[usize],
) -> Result<()> {
    let Some(p) = position(shared, track) else {
        return Ok(());
    };
    let mut surest: Option<(f64, &AnchorMeasurement, f64)> = None;
    for (index, sensitivity_dbm, model) in &constraints.listeners {
        if heard.contains(index) {
            continue;
        }
        // ŷ − S, against σ_X: a silence that is not clearly unexpected says little
        let excess_db = model.value(&p) - sensitivity_dbm;
        if excess_db < model.variance().sqrt() || surest.is_some_and(|(e, _, _)| e >= excess_db) {
            continue;
        }
        if !constraints.audible(p, shared.anchors.get(*index).position_m) {
            continue;
        }
        surest = Some((excess_db, model, *sensitivity_dbm));
    }
    match surest {
        // z = S: the most the reader could have received without reporting it
        Some((_, model, sensitivity_dbm)) => pseudo_update(shared, track, model, sensitivity_dbm),
        None => Ok(()),
    }
}

/// The map constraint on the nearest corridor segment.
fn map<const N: usize>(shared: &Shared, constraints: &Constraints, track: &mut Track<N>) -> Result<()> {
    let Some(p) = position(shared, track) else {
        return Ok(());
    };
    let plan = [p[0], p[1]];
    let Some(segment) = constraints.map.nearest(plan) else {
        return Ok(());
    };
    let lateral_std_m = constraints.lateral_std_m.unwrap_or(segment.half_width_m / 3f64.sqrt());
    let variance = lateral_std_m * lateral_std_m;
    let [ax, ay] = segment.origin_m;
    if !constraints.map.junction_within(plan, constraints.junction_radius_m) {
        // e = n·(p − a) = 0 ± σ_lat
        let [nx, ny] = segment.normal;
        let model = AnchorMeasurement::new(
            [ax, ay, p[2]],
            shared.tag_height_m,
            AnchorLaw::Offset { normal: [nx, ny, 0.0] },
            variance,
        );
        pseudo_update(shared, track, &model, 0.0)?;
    }
    if let (Some(height_m), true) = (segment.height_m, dimensions::<N>() == 3) {
        // z − h(s) = 0 ± σ_z: on the corridor's walking line
        let model = AnchorMeasurement::new(
            [ax, ay, height_m],
            shared.tag_height_m,
            AnchorLaw::Offset {
                normal: [0.0, 0.0, 1.0],
            },
            constraints.vertical_std_m * constraints.vertical_std_m,
        );
        pseudo_update(shared, track, &model, 0.0)?;
    }
    let [ux, uy] = segment.direction;
    let end = if segment.dead_start && segment.along_m < 0.0 {
        Some([ax, ay])
    } else if segment.dead_end && segment.along_m > segment.length_m {
        Some([ax + segment.length_m * ux, ay + segment.length_m * uy])
    } else {
        None
    };
    if let Some([ex, ey]) = end {
        // a dead end is an inequality, u·(p − end) ≤ 0 (or ≥ 0 at a start): back onto it
        let outward = if segment.along_m < 0.0 { [-ux, -uy] } else { [ux, uy] };
        project_inside(shared, track, outward, outward[0] * ex + outward[1] * ey)?;
    }
    Ok(())
}

/// Estimate projection onto the half-plane `w·p ≤ d` of a violated inequality constraint
/// (Simon 2010, §2.3, with the weight `W = P⁻¹`):
///
/// ```text
/// x̂ ← x̂ − P hᵀ (h P hᵀ)⁻¹ (h x̂ − d),   h = wᵀ on the position entries;  P unchanged
/// ```
///
/// The covariance stays: a walker at a dead end may be anywhere short of it, and shrinking `P`
/// along the tunnel at every epoch (as an equality pseudo-measurement would) makes the track
/// overconfident until it gates out the readers that hear him walk back. Every IMM mode is
/// projected in its own layout.
fn project_inside<const N: usize>(shared: &Shared, track: &mut Track<N>, w: [f64; 2], d: f64) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let mut mean = *state.mean();
    let covariance = *state.covariance();
    // h = wᵀ on x (index 0) and y (index 2) of [x, vx, y, …]
    let excess = w[0] * mean[0] + w[1] * mean[2] - d;
    let ph: [f64; N] = std::array::from_fn(|i| covariance[(i, 0)] * w[0] + covariance[(i, 2)] * w[1]);
    let hph = w[0] * ph[0] + w[1] * ph[2];
    if excess > 0.0 && hph > 0.0 {
        for (i, phi) in ph.iter().enumerate() {
            mean[i] -= phi * excess / hph;
        }
        track.state = Some(Gaussian::new(mean, covariance, state.time_s())?);
    }
    if let (Some(manoeuvres), Some(modes)) = (shared.manoeuvres.as_ref(), track.modes.as_mut()) {
        for (layout, estimate) in manoeuvres.modes_layouts().into_iter().zip(modes.estimates_mut()) {
            let (Some(ix), Some(iy)) = (
                layout.index_of(Component::Position(Axis::X)),
                layout.index_of(Component::Position(Axis::Y)),
            ) else {
                continue;
            };
            let excess = w[0] * estimate.mean[ix] + w[1] * estimate.mean[iy] - d;
            let ph = estimate.covariance.column(ix) * w[0] + estimate.covariance.column(iy) * w[1];
            let hph = w[0] * ph[ix] + w[1] * ph[iy];
            if excess > 0.0 && hph > 0.0 {
                estimate.mean -= ph * (excess / hph);
            }
        }
    }
    Ok(())
}

/// `v_xy ← v_xy · v_max/‖v_xy‖` on the state and on every IMM mode (covariances kept).
fn limit_speed<const N: usize>(shared: &Shared, track: &mut Track<N>, max_speed_mps: f64) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let mut mean = *state.mean();
    let speed = mean[1].hypot(mean[3]);
    if speed <= max_speed_mps {
        return Ok(());
    }
    let scale = max_speed_mps / speed;
    mean[1] *= scale;
    mean[3] *= scale;
    track.state = Some(Gaussian::new(mean, *state.covariance(), state.time_s())?);
    if let (Some(manoeuvres), Some(modes)) = (shared.manoeuvres.as_ref(), track.modes.as_mut()) {
        limit_mode_speeds(manoeuvres.modes_layouts(), modes, max_speed_mps);
    }
    Ok(())
}

/// The speed limit on each IMM mode's own velocity entries.
fn limit_mode_speeds(layouts: Vec<&rtls_estimation::imm::StateLayout>, modes: &mut ImmState, max_speed_mps: f64) {
    for (layout, estimate) in layouts.into_iter().zip(modes.estimates_mut()) {
        let (Some(ix), Some(iy)) = (
            layout.index_of(Component::Velocity(Axis::X)),
            layout.index_of(Component::Velocity(Axis::Y)),
        ) else {
            continue;
        };
        let speed = estimate.mean[ix].hypot(estimate.mean[iy]);
        if speed > max_speed_mps {
            let scale = max_speed_mps / speed;
            estimate.mean[ix] *= scale;
            estimate.mean[iy] *= scale;
        }
    }
}

/// An ungated update with a pseudo-measurement `z` of `model` (every IMM mode too). Not a
/// measurement: no lifecycle step, no gate, no adaptive-noise statistics.
fn pseudo_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    model: &AnchorMeasurement,
    z: f64,
) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let measured = DVector::from_element(1, z);
    if let (Some(manoeuvres), Some(modes)) = (shared.manoeuvres.as_ref(), track.modes.as_ref()) {
        let posterior = manoeuvres.update_anchor(modes, model, z)?;
        track.state = Some(manoeuvres.combined(&posterior)?);
        track.modes = Some(posterior);
        return Ok(());
    }
    let updated = match shared.settings.filter {
        FilterKind::Ukf => shared.ukf.update(state, model, &measured)?,
        FilterKind::Ekf | FilterKind::Kf => shared.ekf.update(state, model, &measured)?,
    };
    let prior = *state;
    track.state = Some(updated.state);
    // the state's cross-covariances with the heading's and the offsets' errors follow
    carry_cross_covariances(track, &prior)
}
