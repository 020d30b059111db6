//! The per-tag tracks of one state size (`N = 4`: 2-D CV, `N = 6`: 3-D CV) and what happens to
//! them on a record and on a clock tick.

use std::sync::Arc;

use super::aided::HeldAcceleration;
use super::direct::direct_measurement;
use super::divergence::{reset, reset_if_diverged};
use super::due::DueTracks;
use super::epoch::{anchor_reading, close_due_epoch, opens_epoch, straggles};
use super::gnss::{close_due_gnss_epoch, pseudorange};
use super::output::{Event, Output};
use super::range_bias::RangeOffset;
use super::report::report;
use super::tag_index::TagIndex;
use super::tick::{likely_to_change, tick_one, wake_s, TickMark};
use crate::error::{EngineError, Result};
use crate::lifecycle::TrackStatus;
use crate::record::Measurement;
use crate::zones::{Zone, ZoneKind, ZoneMonitor};
use rtls_estimation::{EstimationError, Gaussian};

use super::constraints::close_epoch_if_due;
use super::rewind::{History, Input};
use super::track::{rejected, Shared, Track};

#[cfg(test)]
thread_local! {
    /// Tests: every tick visits every track, the due schedule's reference
    /// (`tests_due_ticks`).
    pub(super) static TICK_EVERY_TRACK: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// All tracks of one state size.
#[derive(Debug, Clone)]
pub(crate) struct Core<const N: usize> {
    pub(crate) shared: Shared,
    pub(super) index: TagIndex,
    pub(super) tracks: Vec<Track<N>>,
    /// Each track's recent inputs and copies, for re-filtering a late record (empty and
    /// unused when `rewind_horizon_s` is 0); indexed as `tracks`.
    pub(super) histories: Vec<History<N>>,
    /// Tracks given a record since the last [`Self::report_pending`] (indices, may repeat):
    /// the only ones that can have an update pending, so a report does not walk every track.
    pub(super) touched: Vec<usize>,
    /// The tracks the next tick visits, and when the others wake ([`DueTracks`]).
    pub(super) due: DueTracks,
    pub(crate) monitor: ZoneMonitor,
    /// Tracks this core has created (restored ones included): the next track's creation
    /// number, which numbers its segments ([`Track::new`]).
    pub(super) tracks_created: u64,
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
        let due = DueTracks::new(shared.settings.output_interval_s / 2.0);
        Self {
            shared,
            index: TagIndex::default(),
            tracks: Vec::new(),
            histories: Vec::new(),
            touched: Vec::new(),
            due,
            monitor,
            tracks_created: 0,
        }
    }

    pub(crate) fn track_count(&self) -> usize {
        self.tracks.len()
    }

    /// The range offsets each track has learnt (`[tracker.range_bias]`): tag, anchor id,
    /// offset (m) and its standard deviation (m), by tag then anchor.
    pub(crate) fn range_offsets(&self) -> Vec<RangeOffset> {
        let mut offsets: Vec<RangeOffset> = self
            .tracks
            .iter()
            .flat_map(|track| {
                track
                    .range_bias
                    .estimates()
                    .map(|(anchor, offset_m, std_m)| RangeOffset {
                        tag: track.tag.to_string(),
                        anchor: self.shared.anchors.get(anchor).id.clone(),
                        offset_m,
                        std_m,
                    })
            })
            .collect();
        offsets.sort_by(|a, b| (&a.tag, &a.anchor).cmp(&(&b.tag, &b.anchor)));
        offsets
    }

    /// The heading channel of `tag`'s track (tests).
    #[cfg(test)]
    pub(crate) fn heading_state(&self, tag: &str) -> Option<rtls_estimation::aided::HeadingState> {
        self.index
            .get(tag, &self.tracks)
            .and_then(|i| self.tracks[i].heading.state().copied())
    }

    pub(crate) fn status(&self, tag: &str) -> Option<TrackStatus> {
        self.index.get(tag, &self.tracks).and_then(|i| self.tracks[i].status())
    }

    /// Applies one record of `tag`. One record never aborts the run: a failure while applying
    /// it is reported as a `rejected` event naming the error, and a track it leaves diverged
    /// (see [`divergence`](super::divergence)) restarts from its next fix.
    ///
    /// With `rewind_horizon_s` > 0 a record older than its track's newest input is re-filtered
    /// ([`Self::refilter`]); without, the caller passes records in time order.
    ///
    /// # Errors
    /// None today; the `Result` is kept for failures that concern the whole tracker.
    pub(crate) fn apply(&mut self, time_s: f64, tag: &str, measurement: &Measurement, out: &mut Output) -> Result<()> {
        let index = match self.index.get(tag, &self.tracks) {
            Some(i) => i,
            None => {
                let track = Track::new(Arc::from(tag), self.shared.alarm_zones.len(), self.tracks_created);
                self.tracks_created += 1;
                if self.shared.settings.rewind_horizon_s > 0.0 {
                    self.histories.push(History::new(&track));
                }
                self.tracks.push(track);
                self.index.push(&self.tracks);
                self.tracks.len() - 1
            }
        };
        self.touched.push(index);
        self.due.mark(index);
        if self.touched.len() > 2 * self.tracks.len() + 64 {
            // a caller that never reports (a file run) keeps it to a list of the tracks
            self.touched.sort_unstable();
            self.touched.dedup();
        }
        let horizon_s = self.shared.settings.rewind_horizon_s;
        if horizon_s > 0.0 {
            let track = &mut self.tracks[index];
            let anchor_reading = matches!(
                measurement,
                Measurement::Range { .. } | Measurement::Rssi { .. } | Measurement::Tdoa { .. }
            );
            // only after an early close can a reading straggle: resolving its reader (which the
            // record's application does again) is needed then only
            let straggler = if anchor_reading && track.early_closed_s.is_some() {
                let reading = self.shared.anchors.resolve(measurement).ok().flatten();
                reading.and_then(|r| straggles(&self.shared, track, time_s, &r))
            } else {
                None
            };
            if let Some(start_s) = straggler {
                // the epoch it belongs to closed without it: re-solve that epoch with it,
                // closing it at its deadline this time
                return self.refilter(index, time_s, measurement, Some(start_s), out);
            }
            if time_s < self.histories[index].newest_s() {
                return self.refilter(index, time_s, measurement, None, out);
            }
            let history = &mut self.histories[index];
            let input = Input::Record(measurement.clone());
            if anchor_reading && opens_epoch(&self.shared, track, time_s) && !track.expected_readers.is_empty() {
                // an epoch that may close early: a straggler rewinds to its start
                history.push_with_copy(time_s, input, track.clone(), horizon_s);
            } else {
                let copy = history.copy_due(time_s, horizon_s).then(|| track.clone());
                history.push(time_s, input, copy, horizon_s);
            }
        }
        apply_to_track(
            &self.shared,
            &mut self.tracks[index],
            &mut self.monitor,
            time_s,
            measurement,
            out,
        );
        Ok(())
    }

    /// A record older than its track's newest input: the track rewinds to its newest copy at or
    /// before the record and re-applies what followed with the record in its place. Updates the
    /// replay produces from the record's time on are output, flagged `revised` where they
    /// replace ones already out; what it produces before the record's time repeats what was
    /// output, and its events (zones, alarms, lifecycle) are not repeated — those already out
    /// stand, and the alarms the control room was told of stay raised. A record older than the
    /// history reaches is reported [`Event::Late`].
    ///
    /// `reopen_epoch_s`: the start of an epoch closed early that the record belongs to (a
    /// straggler); in the replay that epoch closes at its deadline, holding the record.
    fn refilter(
        &mut self,
        index: usize,
        time_s: f64,
        measurement: &Measurement,
        reopen_epoch_s: Option<f64>,
        out: &mut Output,
    ) -> Result<()> {
        let horizon_s = self.shared.settings.rewind_horizon_s;
        let newest_s = self.histories[index].newest_s();
        let Some(rewind) = self.histories[index].rewind(time_s) else {
            out.events.push(Event::Late {
                tag: Arc::clone(&self.tracks[index].tag),
                time_s,
                kind: measurement.kind(),
                lateness_s: newest_s - time_s,
            });
            return Ok(());
        };
        // what the control room has been told: the revisions are judged against it
        let told_reported_s = self.tracks[index].last_reported_s;
        let told_alarms = self.tracks[index].alarmed.clone();
        self.tracks[index] = rewind.track;
        self.tracks[index].last_reported_s = told_reported_s;
        if reopen_epoch_s.is_some() {
            self.tracks[index].held_open_epoch_s = reopen_epoch_s;
        }
        let mut inputs = rewind.inputs;
        // after every input of the same or an earlier time (those arrived first)
        let at = inputs.partition_point(|(t, _)| *t <= time_s);
        inputs.insert(at, (time_s, Input::Record(measurement.clone())));
        let (updates_before, events_before) = (out.updates.len(), out.events.len());
        let mut deleted = false;
        for (input_s, input) in inputs {
            let track = &mut self.tracks[index];
            let history = &mut self.histories[index];
            match &input {
                Input::Record(m) => {
                    let copy = history.copy_due(input_s, horizon_s).then(|| track.clone());
                    history.push(input_s, input.clone(), copy, horizon_s);
                    apply_to_track(&self.shared, track, &mut self.monitor, input_s, m, out);
                }
                Input::Tick => {
                    // a recorded tick changed the track: the first after records keeps a copy
                    let copy = history
                        .copy_before_tick(input_s, horizon_s, || true)
                        .then(|| track.clone());
                    history.push_tick(input_s, copy, horizon_s);
                    deleted |= tick_one(&self.shared, track, &mut self.monitor, input_s, out);
                }
            }
        }
        let track = &mut self.tracks[index];
        if track.alarmed.len() == told_alarms.len() {
            track.alarmed = told_alarms;
        }
        // the replay before the late record repeats the updates that were output
        let replayed = out.updates.split_off(updates_before);
        out.updates.extend(
            replayed
                .into_iter()
                .filter(|u| u.time_s >= time_s || u.time_s > told_reported_s),
        );
        // events: the late record's rejection, and the zones and alarms of positions reported
        // for the first time; the rest repeat what the records said when they were applied
        let kind = measurement.kind();
        let replayed = out.events.split_off(events_before);
        out.events.extend(replayed.into_iter().filter(|e| match e {
            Event::Rejected { time_s: t, kind: k, .. } => *t == time_s && *k == kind,
            Event::Zone(_) | Event::HazardPredicted { .. } | Event::HazardCleared { .. } | Event::NoCoverage { .. } => {
                e.time_s() > told_reported_s
            }
            _ => false,
        }));
        if deleted {
            self.forget_deleted();
        }
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
        let horizon_s = shared.settings.rewind_horizon_s;
        let mut deleted = false;
        // the tracks this tick can change, in index order: the rest keep as they are
        let visiting = self.due.take_due(now_s, self.tracks.len());
        #[cfg(test)]
        let visiting = if TICK_EVERY_TRACK.with(std::cell::Cell::get) {
            (0..self.tracks.len()).collect()
        } else {
            visiting
        };
        for &index in &visiting {
            let track = &mut self.tracks[index];
            if horizon_s <= 0.0 {
                deleted |= tick_one(shared, track, &mut self.monitor, now_s, out);
            } else {
                let history = &mut self.histories[index];
                if history.newest_s() <= now_s {
                    // a tick that changed the track is an input to re-apply if a late record
                    // rewinds it; one that changed nothing (the usual case) is not, so a
                    // record of another tag that overtook this one does not force a rewind
                    // (a late record re-filtered past this tick: its replay ran the ticks it
                    // needed)
                    let before = TickMark::of(track, now_s);
                    let copy = history
                        .copy_before_tick(now_s, horizon_s, || likely_to_change(shared, track, now_s))
                        .then(|| track.clone());
                    deleted |= tick_one(shared, track, &mut self.monitor, now_s, out);
                    if TickMark::of(track, now_s) != before {
                        history.push_tick(now_s, copy, horizon_s);
                    }
                }
            }
            self.due.schedule(index, wake_s(shared, track));
        }
        self.due.done(visiting);
        if deleted {
            self.forget_deleted();
        }
        Ok(())
    }

    /// Drops deleted tracks (and their histories) and re-indexes the rest.
    fn forget_deleted(&mut self) {
        let keep: Vec<bool> = self
            .tracks
            .iter()
            .map(|t| t.status() != Some(TrackStatus::Deleted))
            .collect();
        let mut k = 0;
        self.tracks.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        if !self.histories.is_empty() {
            let mut k = 0;
            self.histories.retain(|_| {
                k += 1;
                keep[k - 1]
            });
        }
        self.index = TagIndex::of_distinct(&self.tracks);
        // the indices moved: the tracks with an update pending, anew (deletions are rare)
        self.touched = (0..self.tracks.len())
            .filter(|&i| self.tracks[i].unreported.is_some())
            .collect();
        self.due.mark_all(self.tracks.len());
    }

    /// Reports every track's pending update now, instead of when the tag's next record or the
    /// next tick closes its time: a live server calls this after each batch of records so an
    /// update leaves as soon as it is produced. A record of the same time arriving afterwards
    /// updates the track again, and that update is flagged `revised`.
    ///
    /// # Errors
    /// None today; a track whose report fails is reset and reported (`rejected`, kind `track`).
    pub(crate) fn report_pending(&mut self, out: &mut Output) -> Result<()> {
        for index in std::mem::take(&mut self.touched) {
            let track = &mut self.tracks[index];
            if track.unreported.is_none() {
                continue;
            }
            if let Err(error) = report(&self.shared, track, &mut self.monitor, out) {
                let time_s = track.state.as_ref().map_or(track.epoch_start_s, Gaussian::time_s);
                reset(track, time_s, "track", &format!("{error}"), out);
            }
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
        // epochs closed and updates reported: every track's wake time may have moved
        self.due.mark_all(self.tracks.len());
        Ok(())
    }
}

/// One record applied to one track: its failure is reported (`rejected`, naming the error),
/// a numerical failure of the track's own state restarts it, and a diverged track restarts.
fn apply_to_track<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    time_s: f64,
    measurement: &Measurement,
    out: &mut Output,
) {
    let kind = measurement.kind();
    if let Err(error) = apply_record(shared, track, monitor, time_s, measurement, out) {
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
