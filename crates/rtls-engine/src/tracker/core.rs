//! The per-tag tracks of one state size (`N = 4`: 2-D CV, `N = 6`: 3-D CV) and what happens to
//! them on a record and on a clock tick.

use std::collections::HashMap;
use std::sync::Arc;

use super::aided::HeldAcceleration;
use super::alarms::position_of;
use super::direct::direct_measurement;
use super::divergence::{divergence, reset, reset_if_diverged};
use super::epoch::{anchor_reading, close_due_epoch};
use super::gnss::{close_due_gnss_epoch, pseudorange};
use super::output::{Event, Output, UpdateSource};
use super::report::{clear_alarms, coast, report, track_update};
use super::update::predict;
use crate::error::{EngineError, Result};
use crate::lifecycle::{LifecycleEvent, TrackStatus};
use crate::record::Measurement;
use crate::site::Pipeline;
use crate::zones::{Zone, ZoneKind, ZoneMonitor};
use rtls_estimation::{EstimationError, Gaussian};

use super::constraints::close_epoch_if_due;
use super::track::{rejected, Shared, Track};

/// All tracks of one state size.
#[derive(Debug, Clone)]
pub(crate) struct Core<const N: usize> {
    pub(crate) shared: Shared,
    index: HashMap<Arc<str>, usize>,
    tracks: Vec<Track<N>>,
    pub(crate) monitor: ZoneMonitor,
}

/// Whether the track's open fix-then-filter epoch or GNSS epoch (either pipeline) holds readings
/// from before `now_s`. Its fix will carry the epoch's last reading time, so ticking the track
/// at `now_s` first would put the fix's update behind the tick (time going backwards for the
/// lifecycle).
fn holds_earlier_readings<const N: usize>(shared: &Shared, track: &Track<N>, now_s: f64) -> bool {
    (shared.settings.pipeline == Pipeline::FixThenFilter && track.epoch.last().is_some_and(|&(t, _)| t < now_s))
        || track.gnss.holds_readings_before(now_s)
}

impl<const N: usize> Core<N> {
    /// See [`super::Tracker::replace_zones`].
    pub(crate) fn replace_zones(&mut self, zones: Vec<Zone>) -> Result<()> {
        let alarm_zones: Vec<Zone> = zones
            .iter()
            .filter(|z| z.kind == ZoneKind::Hazard || self.shared.no_coverage_zones.contains(&z.id))
            .cloned()
            .collect();
        self.monitor.replace_zones(zones)?;
        // each track's alarm flags follow their zone's id
        let old_ids: Vec<String> = self.shared.alarm_zones.iter().map(|z| z.id.clone()).collect();
        for track in &mut self.tracks {
            track.alarmed = alarm_zones
                .iter()
                .map(|zone| {
                    old_ids
                        .iter()
                        .position(|id| *id == zone.id)
                        .is_some_and(|i| track.alarmed.get(i).copied().unwrap_or(false))
                })
                .collect();
        }
        self.shared.alarm_zones = alarm_zones;
        Ok(())
    }

    pub(crate) fn new(shared: Shared, monitor: ZoneMonitor) -> Self {
        Self {
            shared,
            index: HashMap::new(),
            tracks: Vec::new(),
            monitor,
        }
    }

    pub(crate) fn track_count(&self) -> usize {
        self.tracks.len()
    }

    /// The heading channel of `tag`'s track (tests).
    #[cfg(test)]
    pub(crate) fn heading_state(&self, tag: &str) -> Option<rtls_estimation::aided::HeadingState> {
        self.index
            .get(tag)
            .and_then(|&i| self.tracks[i].heading.state().copied())
    }

    pub(crate) fn status(&self, tag: &str) -> Option<TrackStatus> {
        self.index.get(tag).and_then(|&i| self.tracks[i].status())
    }

    /// Applies one in-order record. One record never aborts the run: a failure while applying
    /// it is reported as a `rejected` event naming the error, and a track it leaves diverged
    /// (see [`divergence`](super::divergence)) restarts from its next fix.
    ///
    /// # Errors
    /// None today; the `Result` is kept for failures that concern the whole tracker.
    pub(crate) fn apply(&mut self, time_s: f64, tag: &str, measurement: &Measurement, out: &mut Output) -> Result<()> {
        let index = match self.index.get(tag) {
            Some(&i) => i,
            None => {
                let tag: Arc<str> = Arc::from(tag);
                self.tracks
                    .push(Track::new(Arc::clone(&tag), self.shared.alarm_zones.len()));
                self.index.insert(tag, self.tracks.len() - 1);
                self.tracks.len() - 1
            }
        };
        let track = &mut self.tracks[index];
        let shared = &self.shared;
        let kind = measurement.kind();
        if let Err(error) = apply_record(shared, track, &mut self.monitor, time_s, measurement, out) {
            let numerical = matches!(&error, EngineError::Estimation(e)
                if !matches!(e, EstimationError::TimeWentBackwards { .. }));
            if numerical && track.state.is_some() {
                // the track's own state failed (its prediction or combination): start afresh
                reset(track, time_s, kind, &format!("{error}"), out);
            } else {
                let reason = format!("not applied: {error}");
                out.events.push(rejected(&track.tag, time_s, kind, reason));
            }
        }
        reset_if_diverged(&shared.bounds, track, time_s, kind, out);
        Ok(())
    }

    /// The periodic clock tick at `now_s`: closes due epochs, reports pending updates, advances
    /// lifecycles, outputs coasting predictions, deletes dead tracks. A track whose tick fails
    /// or whose coasting prediction diverges is reported (`rejected`, kind `track`) and
    /// restarts from its next fix; the other tracks tick on.
    ///
    /// # Errors
    /// None today; the `Result` is kept for failures that concern the whole tracker.
    pub(crate) fn tick(&mut self, now_s: f64, out: &mut Output) -> Result<()> {
        let shared = &self.shared;
        let mut deleted = false;
        for track in &mut self.tracks {
            match tick_track(shared, track, &mut self.monitor, now_s, out) {
                Ok(gone) => deleted |= gone,
                Err(error) => reset(track, now_s, "track", &format!("{error}"), out),
            }
        }
        if deleted {
            self.tracks.retain(|t| t.status() != Some(TrackStatus::Deleted));
            self.index = self
                .tracks
                .iter()
                .enumerate()
                .map(|(i, t)| (Arc::clone(&t.tag), i))
                .collect();
        }
        Ok(())
    }

    /// End of input: closes every epoch and reports every pending update.
    pub(crate) fn flush(&mut self, out: &mut Output) -> Result<()> {
        for track in &mut self.tracks {
            let flushed = close_due_epoch(&self.shared, track, f64::INFINITY, out)
                .and_then(|()| close_epoch_if_due(&self.shared, track, f64::INFINITY, out))
                .and_then(|()| {
                    if reset_if_diverged(&self.shared.bounds, track, track.epoch_start_s, "epoch", out) {
                        return Ok(());
                    }
                    match track.unreported {
                        Some(_) => report(&self.shared, track, &mut self.monitor, out),
                        None => Ok(()),
                    }
                });
            if let Err(error) = flushed {
                let time_s = track.state.as_ref().map_or(track.epoch_start_s, Gaussian::time_s);
                reset(track, time_s, "track", &format!("{error}"), out);
            }
        }
        Ok(())
    }
}

/// What [`Core::apply`] does with one record; its errors are the record's.
fn apply_record<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    time_s: f64,
    measurement: &Measurement,
    out: &mut Output,
) -> Result<()> {
    // a record beyond the open GNSS epoch's window closes it (its fix is dated before this record)
    close_due_gnss_epoch(shared, track, time_s, out)?;
    if shared.constraints.is_some() {
        // the epoch this record closes: its fix first (fix-then-filter), then what the
        // readers that stayed silent, the map and the speed limit say about it
        close_due_epoch(shared, track, time_s, out)?;
        close_epoch_if_due(shared, track, time_s, out)?;
    }
    // a later time closes the previous time's work: report it first
    if track.state.as_ref().is_some_and(|s| time_s > s.time_s()) && track.unreported.is_some() {
        report(shared, track, monitor, out)?;
    }
    match measurement {
        Measurement::Range { .. } | Measurement::Rssi { .. } | Measurement::Tdoa { .. } => {
            let reading = match shared.anchors.resolve(measurement) {
                Ok(Some(reading)) => reading,
                Ok(None) => {
                    if shared.constraints.is_some() {
                        track.hearing.heard(time_s, None);
                    }
                    return Ok(());
                }
                Err(reason) => {
                    out.events
                        .push(rejected(&track.tag, time_s, measurement.kind(), reason));
                    return Ok(());
                }
            };
            if shared.constraints.is_some() {
                // the epoch's readers, for its close (nothing to keep without constraints)
                track.hearing.heard(time_s, Some(reading));
            }
            anchor_reading(shared, track, time_s, reading, measurement.kind(), out)
        }
        // the control input of the CV model (and of the IMM's CV mode) for the next
        // predictions, up to ACCELERATION_HOLD_S
        Measurement::Accelerometer {
            acceleration_mps2,
            std_mps2,
        } => {
            let mut a = [0.0; 3];
            for (axis, value) in acceleration_mps2.iter().enumerate().take(3) {
                a[axis] = *value;
            }
            track.acceleration = Some(HeldAcceleration {
                time_s,
                acceleration_mps2: a,
                std_mps2: std_mps2.unwrap_or(0.0),
            });
            Ok(())
        }
        Measurement::Pseudorange { .. } => pseudorange(shared, track, time_s, measurement, out),
        _ => direct_measurement(shared, track, time_s, measurement, out),
    }
}

/// One track's part of [`Core::tick`]; returns `true` when the track was deleted.
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
                    track.lost_state = Some(frozen);
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
                    out.updates.push(update);
                    track.last_output_s = now_s;
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
        None => coast(shared, track, now_s, monitor, out),
    }
}
