//! A track's recent history, for re-filtering a late record (`tracker.rewind_horizon_s`).
//!
//! Each track keeps the inputs it was given over the horizon — its records, and the clock
//! ticks that changed it — and copies of itself taken every quarter horizon before an input.
//! A record older than the track's newest input restores the newest copy taken at or before
//! the record's time and re-applies the inputs after it with the late record in its place
//! (a stable merge: inputs of equal time keep their arrival order). Replaying the same inputs
//! through the same code gives the state the track would have had with the records in order.
//!
//! Memory: per track, the inputs of one horizon plus one snapshot interval, and up to five
//! copies of the track.

use std::collections::VecDeque;

use super::track::Track;
use crate::record::Measurement;

/// What a track was given.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) enum Input {
    /// A record of the tag.
    Record(Measurement),
    /// A clock tick that changed the track (coasting, an epoch's deadline, its lifecycle).
    Tick,
}

/// The track before the input at `input_index` (counted since the track began), whose time is
/// `time_s`.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Snapshot<const N: usize> {
    input_index: u64,
    time_s: f64,
    track: Track<N>,
}

/// A track's inputs over the horizon and the copies of it to rewind to.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct History<const N: usize> {
    /// `(time, input)` in time order; the first has index `first_index`.
    inputs: VecDeque<(f64, Input)>,
    first_index: u64,
    snapshots: VecDeque<Snapshot<N>>,
    /// Time of the newest input, s (−∞ before any).
    newest_s: f64,
}

impl<const N: usize> History<N> {
    /// The history of a new track: its first copy is the track before any input, so a record
    /// older than the one that started it (within the horizon) still rewinds.
    pub(super) fn new(track: &Track<N>) -> Self {
        Self {
            inputs: VecDeque::new(),
            first_index: 0,
            snapshots: VecDeque::from([Snapshot {
                input_index: 0,
                time_s: f64::NEG_INFINITY,
                track: track.clone(),
            }]),
            newest_s: f64::NEG_INFINITY,
        }
    }
}

/// Where a rewind starts: the track to restore and the inputs to re-apply, in order.
pub(super) struct Rewind<const N: usize> {
    pub(super) track: Track<N>,
    pub(super) inputs: Vec<(f64, Input)>,
}

impl<const N: usize> History<N> {
    /// Time of the newest input, s (−∞ before any).
    pub(super) fn newest_s(&self) -> f64 {
        self.newest_s
    }

    /// Whether an input at `time_s` is to be preceded by a copy of the track: the newest copy
    /// is a quarter `horizon_s` old (or there is none).
    pub(super) fn copy_due(&self, time_s: f64, horizon_s: f64) -> bool {
        self.snapshots
            .back()
            .is_none_or(|s| time_s - s.time_s >= horizon_s / 4.0)
    }

    /// Records `input` after a copy of the track taken now, whatever the interval: the start
    /// of an epoch that may close early, which a straggling reading rewinds to.
    pub(super) fn push_with_copy(&mut self, time_s: f64, input: Input, copy: Track<N>, horizon_s: f64) {
        if self.snapshots.back().is_some_and(|s| s.time_s == time_s) {
            // a copy at this time already precedes every input of this time
            return self.push(time_s, input, None, horizon_s);
        }
        self.snapshots.push_back(Snapshot {
            input_index: self.first_index + self.inputs.len() as u64,
            time_s,
            track: copy,
        });
        self.push(time_s, input, None, horizon_s);
    }

    /// Records `input` at `time_s` (not before [`Self::newest_s`]), after `copy` — the track
    /// before the input — when [`Self::copy_due`]; then forgets what the horizon no longer
    /// needs.
    pub(super) fn push(&mut self, time_s: f64, input: Input, copy: Option<Track<N>>, horizon_s: f64) {
        debug_assert!(time_s >= self.newest_s, "inputs are recorded in time order");
        if let Some(track) = copy.filter(|_| self.copy_due(time_s, horizon_s)) {
            self.snapshots.push_back(Snapshot {
                input_index: self.first_index + self.inputs.len() as u64,
                time_s,
                track,
            });
        }
        self.inputs.push_back((time_s, input));
        self.newest_s = time_s;
        // a record at newest − horizon needs a copy at or before it: keep the newest such copy
        while self.snapshots.len() >= 2 && self.snapshots[1].time_s <= self.newest_s - horizon_s {
            self.snapshots.pop_front();
        }
        if let Some(oldest) = self.snapshots.front() {
            while self.first_index < oldest.input_index {
                self.inputs.pop_front();
                self.first_index += 1;
            }
        }
    }

    /// Whether the newest input is a record (not a tick).
    pub(super) fn last_is_record(&self) -> bool {
        matches!(self.inputs.back(), Some((_, Input::Record(_))))
    }

    /// Whether a tick at `time_s` is to be preceded by a copy of the track: one is due, or
    /// the tick is the first after a record and may change the track (`may_change`, asked
    /// only then; see [`Self::push_tick`]).
    pub(super) fn copy_before_tick(&self, time_s: f64, horizon_s: f64, may_change: impl FnOnce() -> bool) -> bool {
        self.copy_due(time_s, horizon_s) || (self.last_is_record() && may_change())
    }

    /// Records a tick at `time_s` that changed the track, after `copy` — the track before
    /// the tick. The first tick after a record keeps its copy, dated at that record's time
    /// (the copy holds every input up to it and none after): a record that arrives between
    /// the two — another sender's records moved the clock past it — restores that copy and
    /// re-applies the ticks only, not every record since the last periodic copy. Other
    /// ticks keep `copy` only when one is due, as [`Self::push`] does.
    pub(super) fn push_tick(&mut self, time_s: f64, copy: Option<Track<N>>, horizon_s: f64) {
        match copy {
            Some(track) if self.last_is_record() => {
                self.snapshots.push_back(Snapshot {
                    input_index: self.first_index + self.inputs.len() as u64,
                    time_s: self.newest_s,
                    track,
                });
                self.push(time_s, Input::Tick, None, horizon_s);
            }
            copy => self.push(time_s, Input::Tick, copy, horizon_s),
        }
    }

    /// Rewinds for a record at `time_s`: the newest copy taken at or before it, and the inputs
    /// since that copy (which the history forgets: re-applying them records them again).
    /// `None` when the history holds no copy that old (the record is beyond the horizon).
    pub(super) fn rewind(&mut self, time_s: f64) -> Option<Rewind<N>> {
        let position = self.snapshots.iter().rposition(|s| s.time_s <= time_s)?;
        let snapshot = self.snapshots.drain(position..).next()?;
        let keep = usize::try_from(snapshot.input_index - self.first_index).unwrap_or(usize::MAX);
        let inputs: Vec<(f64, Input)> = self.inputs.drain(keep.min(self.inputs.len())..).collect();
        // every input before the copy is at or before its time
        self.newest_s = self.inputs.back().map_or(f64::NEG_INFINITY, |(t, _)| *t);
        Some(Rewind {
            track: snapshot.track,
            inputs,
        })
    }
}
