//! One track's clock tick ([`tick_one`]: due epochs closed, the pending update reported, the
//! lifecycle advanced, coasting and lost outputs) and the earliest tick that can change a
//! track which no record reaches first ([`wake_s`]), so a tick visits only the tracks that are
//! due (see [`super::due`]).

use std::sync::Arc;

use super::alarms::position_of;
use super::constraints::close_epoch_if_due;
use super::divergence::{divergence, reset, reset_if_diverged};
use super::epoch::close_due_epoch;
use super::output::{Event, Output, UpdateSource};
use super::report::{clear_alarms, coast, report, track_update};
use super::step::predict;
use super::track::{Shared, Track};
use crate::error::Result;
use crate::lifecycle::{LifecycleEvent, TrackStatus};
use crate::site::Pipeline;
use crate::zones::ZoneMonitor;
use rtls_estimation::Gaussian;

/// Whether the track's open fix-then-filter epoch or GNSS epoch (either pipeline) holds readings
/// from before `now_s`. Its fix will be dated at its readings' mean time (GNSS: at their time),
/// before `now_s` unless every reading is at `now_s` (readings come in time order), so ticking
/// the track at `now_s` first would put the fix's update behind the tick (time going backwards
/// for the lifecycle and the state).
fn holds_earlier_readings<const N: usize>(shared: &Shared, track: &Track<N>, now_s: f64) -> bool {
    (shared.settings.pipeline == Pipeline::FixThenFilter && track.epoch.first().is_some_and(|&(t, _)| t < now_s))
        || track.gnss.holds_readings_before(now_s)
}

/// One track's clock tick at `now_s`; a failure restarts the track. `true` when the track was
/// deleted.
pub(super) fn tick_one<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    now_s: f64,
    out: &mut Output,
) -> bool {
    match tick_track(shared, track, monitor, now_s, out) {
        Ok(gone) => gone,
        Err(error) => {
            reset(track, now_s, "track", &format!("{error}"), out);
            false
        }
    }
}

/// What a clock tick can change in a track besides reporting its pending update: its state's
/// time or presence, its lifecycle, its open epochs and held records, its coasting output.
#[derive(Debug, PartialEq)]
pub(super) struct TickMark {
    state_s: Option<f64>,
    status: Option<TrackStatus>,
    epoch: usize,
    deferred: usize,
    output_at_tick: bool,
    gnss_pending: bool,
}

impl TickMark {
    pub(super) fn of<const N: usize>(track: &Track<N>, now_s: f64) -> Self {
        Self {
            state_s: track.state.as_ref().map(Gaussian::time_s),
            status: track.status(),
            epoch: track.epoch.len(),
            deferred: track.deferred.len(),
            // a coasting or lost output is dated at the tick (a report, at its state's time)
            output_at_tick: track.last_output_s >= now_s,
            gnss_pending: track.gnss.holds_readings_before(f64::INFINITY),
        }
    }
}

/// Whether a tick at `now_s` is likely to change the track (what [`TickMark`] detects): it
/// holds an open epoch, deferred records or GNSS readings, is tentative, or has been silent
/// longer than the output interval (it coasts, is lost or deleted). A hint for taking a copy
/// of the track before the tick ([`super::rewind::History::push_tick`]); nothing depends on
/// it being right.
pub(super) fn likely_to_change<const N: usize>(shared: &Shared, track: &Track<N>, now_s: f64) -> bool {
    !track.epoch.is_empty()
        || !track.deferred.is_empty()
        || track.gnss.holds_readings_before(f64::INFINITY)
        || track.lifecycle.as_ref().is_some_and(|lifecycle| {
            lifecycle.status() == TrackStatus::Tentative
                || now_s - lifecycle.last_update_s() > shared.settings.output_interval_s
        })
}

/// One track's part of [`Core::tick`](super::core::Core::tick); returns `true` when the track was deleted.
fn tick_track<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    now_s: f64,
    out: &mut Output,
) -> Result<bool> {
    let interval_s = shared.settings.output_interval_s;
    close_due_epoch(shared, track, now_s, out)?;
    close_epoch_if_due(shared, track, now_s, out)?;
    if reset_if_diverged(&shared.bounds, track, now_s, "epoch", out) {
        return Ok(false);
    }
    if track.unreported.is_some() && track.state.as_ref().is_some_and(|s| s.time_s() < now_s) {
        report(shared, track, monitor, out)?;
    }
    if holds_earlier_readings(shared, track, now_s) {
        // its fix will be dated before this tick: the lifecycle and the coasting output
        // wait for it (the epoch closes by the first tick after its window)
        return Ok(false);
    }
    let Some(lifecycle) = track.lifecycle.as_mut() else {
        return Ok(false);
    };
    let silence_s = now_s - lifecycle.last_update_s();
    // a track coasts once an update is overdue by more than the output interval
    if silence_s > interval_s || lifecycle.status() == TrackStatus::Tentative {
        if let Some(event) = lifecycle.tick(now_s)? {
            let position_m = match (event, track.state.as_ref()) {
                (LifecycleEvent::Lost, Some(state)) => {
                    // keep the last estimated position (where the tag was last seen)
                    let frozen = *state;
                    let position_m = position_of(&frozen, shared.tag_height_m).0;
                    track.lost_state = Some(Box::new(frozen));
                    position_m
                }
                (_, Some(state)) => position_of(state, shared.tag_height_m).0,
                (_, None) => [0.0; 3],
            };
            out.events.push(Event::Lifecycle {
                tag: Arc::clone(&track.tag),
                time_s: now_s,
                event,
                position_m,
            });
            if event == LifecycleEvent::Deleted {
                for zone_event in monitor.remove_tag(&track.tag, now_s)? {
                    out.events.push(Event::Zone(zone_event));
                }
                clear_alarms(shared, track, now_s, out);
                return Ok(true);
            }
        }
    }
    if now_s - track.last_output_s >= interval_s {
        match track.status() {
            Some(TrackStatus::Coasting) => coast_if_sound(shared, track, now_s, monitor, out)?,
            Some(TrackStatus::Lost) => {
                // the last position, frozen, reported as lost
                if let Some(frozen) = &track.lost_state {
                    let mut update =
                        track_update(shared, track, frozen, true, TrackStatus::Lost, UpdateSource::Prediction);
                    update.time_s = now_s;
                    update.revised = now_s <= track.last_reported_s;
                    out.updates.push(update);
                    track.last_output_s = now_s;
                    track.last_reported_s = track.last_reported_s.max(now_s);
                }
            }
            _ => {}
        }
    }
    Ok(false)
}

/// Outputs the coasting prediction of `track` at `now_s`, unless it has diverged: then the
/// track is reported and reset, and nothing is output.
fn coast_if_sound<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    // no reader heard the tag: every reader that should have is evidence where it is not
    super::constraints::coast(shared, track, now_s)?;
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let prior = predict(shared, track, state, now_s)?;
    match divergence(&shared.bounds, &prior.state, prior.modes.as_ref()) {
        Some(reason) => {
            reset(track, now_s, "track", &format!("coasting prediction: {reason}"), out);
            Ok(())
        }
        // the prediction just checked is the one output
        None => coast(shared, track, (&prior.state, prior.modes.as_ref()), now_s, monitor, out),
    }
}

/// The earliest tick time from which [`tick_one`] can do anything to `track` (output, event or
/// change of the track) when no record, flush or restore reaches the track first:
/// `f64::NEG_INFINITY` for a track every tick can change, `f64::INFINITY` for one no tick
/// changes. A tick at `now_s` < this leaves the track as it is, so skipping it changes nothing.
///
/// Mirrors [`tick_track`]'s conditions, conservatively:
/// - open epochs, held direct measurements and open GNSS epochs close on ticks, and the
///   constraints' epochs (negative information) on their deadlines: every tick;
/// - a pending update is reported by the first tick after its state's time;
/// - a tentative, coasting or lost track's lifecycle and outputs advance on every tick;
/// - a confirmed track is left alone until its silence exceeds the output interval
///   (`now − last update > interval`, so from `last update + interval` on); its state was
///   checked for divergence when it last changed, and the check gives the same answer until
///   it changes again.
pub(super) fn wake_s<const N: usize>(shared: &Shared, track: &Track<N>) -> f64 {
    if shared.constraints.is_some()
        || !track.epoch.is_empty()
        || !track.deferred.is_empty()
        || track.gnss.holds_readings_before(f64::INFINITY)
    {
        return f64::NEG_INFINITY;
    }
    let report_s = match (&track.unreported, &track.state) {
        (Some(_), Some(state)) => state.time_s(),
        _ => f64::INFINITY,
    };
    let Some(lifecycle) = track.lifecycle.as_ref() else {
        return report_s;
    };
    match lifecycle.status() {
        TrackStatus::Confirmed => report_s.min(lifecycle.last_update_s() + shared.settings.output_interval_s),
        TrackStatus::Tentative | TrackStatus::Coasting | TrackStatus::Lost | TrackStatus::Deleted => f64::NEG_INFINITY,
    }
}
