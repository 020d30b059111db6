//! Reporting a track: its updates, coasting predictions, zone events and predictive alarms.

use std::sync::Arc;

use rtls_estimation::smoother::InformationStep;
use rtls_estimation::Gaussian;

use super::alarms::{position_of, predict_entries};
use super::output::{Event, Output, ReportedState, TrackUpdate, TurnState, UpdateSource};
use super::track::{dimensions, Shared, Track};
use crate::error::Result;
use crate::lifecycle::TrackStatus;
use crate::zones::{ZoneEvent, ZoneMonitor};

pub(super) fn track_update<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    state: &Gaussian<N>,
    predicted: bool,
    status: TrackStatus,
    source: UpdateSource,
) -> TrackUpdate {
    let d = dimensions::<N>();
    let (position_m, position_covariance_m2) = position_of(state, shared.tag_height_m);
    let mut velocity_mps = [0.0; 3];
    for (axis, v) in velocity_mps.iter_mut().enumerate().take(d) {
        *v = state.mean()[2 * axis + 1];
    }
    TrackUpdate {
        time_s: state.time_s(),
        tag: Arc::clone(&track.tag),
        dimensions: d,
        position_m,
        velocity_mps,
        position_covariance_m2,
        predicted,
        status,
        source,
        mode: shared.manoeuvres.as_ref().map(|m| m.name(track.mode)),
        revised: state.time_s() <= track.last_reported_s,
        smoothed: false,
    }
}

/// Appends `update` to the output and, when the output keeps states
/// ([`Output::keeping_states`]), the whole `state` behind it with what its measurements added
/// (`information`: none for a prediction).
fn push_update<const N: usize>(
    out: &mut Output,
    update: TrackUpdate,
    state: &Gaussian<N>,
    segment: u64,
    (information, partial_information): (Option<InformationStep<N>>, bool),
    turn: Option<TurnState>,
) {
    if let Some(states) = out.states.as_mut() {
        let mut kept = ReportedState {
            update: out.updates.len(),
            segment,
            mean: [0.0; 6],
            covariance: [0.0; 36],
            information: [0.0; 36],
            information_vector: [0.0; 6],
            partial_information,
            turn,
        };
        kept.mean[..N].copy_from_slice(state.mean().as_slice());
        // (column-major storage of a symmetric matrix: its row-major entries too)
        kept.covariance[..N * N].copy_from_slice(state.covariance().as_slice());
        if let Some(information) = information {
            kept.information[..N * N].copy_from_slice(information.information.as_slice());
            kept.information_vector[..N].copy_from_slice(information.information_vector.as_slice());
        }
        states.push(kept);
    }
    out.updates.push(update);
}

/// The coordinated turn's whole state behind an update, when the output keeps states.
fn kept_turn(out: &Output, modes: Option<&rtls_estimation::imm::ImmState>) -> Option<TurnState> {
    out.states.as_ref().and_then(|_| TurnState::of(modes))
}

/// Reports the track's latest update, then its zones and alarms.
pub(super) fn report<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let (Some(source), Some(state), Some(status)) = (track.unreported.take(), track.state, track.status()) else {
        return Ok(());
    };
    let turn = kept_turn(out, track.modes.as_ref());
    push_update(
        out,
        track_update(shared, track, &state, false, status, source),
        &state,
        track.segment,
        track.take_information(),
        turn,
    );
    track.last_output_s = state.time_s();
    track.last_reported_s = track.last_reported_s.max(state.time_s());
    if matches!(status, TrackStatus::Confirmed | TrackStatus::Coasting) {
        zones_and_alarms(shared, track, &state, monitor, out)?;
    }
    Ok(())
}

/// Outputs `predicted`, a coasting track's prediction at `now_s`, flagged as predicted (seed
/// 000's gap filling).
pub(super) fn coast<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    (predicted, predicted_modes): (&Gaussian<N>, Option<&rtls_estimation::imm::ImmState>),
    now_s: f64,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let update = track_update(
        shared,
        track,
        predicted,
        true,
        TrackStatus::Coasting,
        UpdateSource::Prediction,
    );
    let turn = kept_turn(out, predicted_modes);
    push_update(out, update, predicted, track.segment, (None, false), turn);
    track.last_output_s = now_s;
    track.last_reported_s = track.last_reported_s.max(now_s);
    zones_and_alarms(shared, track, predicted, monitor, out)
}

/// Zone events for the state's position, then the predictive alarms.
pub(super) fn zones_and_alarms<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    state: &Gaussian<N>,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let (position_m, _) = position_of(state, shared.tag_height_m);
    // a revision of a time before the zones' latest position for the tag (a re-filtered late
    // record): the zones have been decided on newer positions, and stand
    // (only a revision can be behind: the monitor is not asked on the usual, newer report)
    let zones_behind =
        track.last_reported_s > state.time_s() && monitor.last_time_s(&track.tag).is_some_and(|t| state.time_s() < t);
    let zone_events = if zones_behind {
        Vec::new()
    } else {
        monitor.update(&track.tag, state.time_s(), position_m)?
    };
    for zone_event in zone_events {
        if let ZoneEvent::Enter { zone, time_s, .. } = &zone_event {
            if shared.no_coverage_zones.iter().any(|z| z == zone) {
                out.events.push(Event::NoCoverage {
                    tag: Arc::clone(&track.tag),
                    zone: zone.clone(),
                    time_s: *time_s,
                });
            }
        }
        out.events.push(Event::Zone(zone_event));
    }
    if let Some(scheduling) = &shared.scheduling {
        let x = state.mean();
        scheduling.update(
            &track.tag,
            &mut track.schedule,
            state.time_s(),
            [x[0], x[2]],
            [x[1], x[3]],
            out,
        )?;
    }
    if shared.alarm_zones.is_empty() {
        return Ok(());
    }
    let inside: Vec<bool> = shared.alarm_zones.iter().map(|z| z.contains(position_m)).collect();
    let entries = predict_entries(
        state,
        &shared.motion,
        &shared.alarm_zones,
        &inside,
        &shared.alarms,
        shared.tag_height_m,
    )?;
    for (index, zone) in shared.alarm_zones.iter().enumerate() {
        let entry = entries.iter().find(|e| e.zone == index);
        match (entry, track.alarmed[index], inside[index]) {
            (Some(entry), false, _) => {
                track.alarmed[index] = true;
                out.events.push(Event::HazardPredicted {
                    tag: Arc::clone(&track.tag),
                    zone: zone.id.clone(),
                    time_s: state.time_s(),
                    time_to_entry_s: entry.time_to_entry_s,
                    probability: entry.probability,
                });
            }
            // inside: the zone-enter event takes over; the alarm stays raised until the tag
            // is out and no longer heading in
            (None, true, false) => {
                track.alarmed[index] = false;
                out.events.push(Event::HazardCleared {
                    tag: Arc::clone(&track.tag),
                    zone: zone.id.clone(),
                    time_s: state.time_s(),
                });
            }
            _ => {}
        }
    }
    Ok(())
}

/// Clears every raised alarm of a deleted track.
pub(super) fn clear_alarms<const N: usize>(shared: &Shared, track: &mut Track<N>, now_s: f64, out: &mut Output) {
    for (index, zone) in shared.alarm_zones.iter().enumerate() {
        if std::mem::take(&mut track.alarmed[index]) {
            out.events.push(Event::HazardCleared {
                tag: Arc::clone(&track.tag),
                zone: zone.id.clone(),
                time_s: now_s,
            });
        }
    }
}
