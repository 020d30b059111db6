//! Which tracks a clock tick visits: those given a record since the last tick, and those whose
//! wake time ([`super::tick::wake_s`]: the first tick that can change a track no record
//! reaches) has come. A tick over 100 000 quiet confirmed tracks then touches none of them,
//! instead of loading each one's first cache lines to find nothing to do.
//!
//! The tracks to visit are a bit set over track indices, visited in index order, so a tick's
//! outputs come in the order a walk over every track gives. Future wake times wait in a timer
//! wheel of buckets one tick period wide (`BTreeMap` from bucket to indices); a track whose
//! wake time moves leaves its old entry behind, and an entry is live only while its bucket is
//! the track's current one ([`DueTracks::slot`]), so stale entries are dropped when their
//! bucket comes up.
//!
//! Visiting a track that is not due is always allowed (its tick changes nothing), so whatever
//! cannot be followed cheaply — a deletion re-indexing the tracks, a checkpoint restored, the
//! end of input — marks every track.

use std::collections::BTreeMap;

/// No live wheel entry (see [`DueTracks::slot`]).
const NO_SLOT: i64 = i64::MIN;

/// The tracks the next tick visits, and when the others wake (see the
/// [module documentation](self)).
#[derive(Debug, Clone)]
pub(super) struct DueTracks {
    /// Bit `i`: track `i` is visited by the next tick.
    due: Vec<u64>,
    /// Each track's wake time, s (`f64::INFINITY`: none).
    wake_s: Vec<f64>,
    /// The wheel bucket of each track's live entry, [`NO_SLOT`] without one.
    slot: Vec<i64>,
    /// Future wake times: bucket (`⌊wake / width⌋`) → track indices.
    wheel: BTreeMap<i64, Vec<u32>>,
    /// A bucket's width, s (the tick period; any positive width is correct).
    width_s: f64,
    /// The due indices of the tick under way (kept for its capacity).
    visiting: Vec<usize>,
}

impl DueTracks {
    /// An empty schedule whose wheel buckets are `width_s` wide (a non-positive or non-finite
    /// width is taken as 1 s).
    pub(super) fn new(width_s: f64) -> Self {
        Self {
            due: Vec::new(),
            wake_s: Vec::new(),
            slot: Vec::new(),
            wheel: BTreeMap::new(),
            width_s: if width_s.is_finite() && width_s > 0.0 {
                width_s
            } else {
                1.0
            },
            visiting: Vec::new(),
        }
    }

    fn bucket(&self, time_s: f64) -> i64 {
        // (saturating: far times share the end buckets, which is only early, never late)
        (time_s / self.width_s).floor() as i64
    }

    /// Room for `tracks` tracks (a new track starts unscheduled: mark it).
    fn grow(&mut self, tracks: usize) {
        if self.wake_s.len() < tracks {
            self.wake_s.resize(tracks, f64::INFINITY);
            self.slot.resize(tracks, NO_SLOT);
            self.due.resize(tracks.div_ceil(64), 0);
        }
    }

    /// Track `index` is visited by the next tick (it was given a record).
    pub(super) fn mark(&mut self, index: usize) {
        self.grow(index + 1);
        self.due[index / 64] |= 1 << (index % 64);
    }

    /// Every one of `tracks` tracks is visited by the next tick, and nothing else is scheduled
    /// (after a re-indexing, a restore or a flush).
    pub(super) fn mark_all(&mut self, tracks: usize) {
        self.wheel.clear();
        self.wake_s.clear();
        self.slot.clear();
        self.due.clear();
        self.grow(tracks);
        self.due.fill(u64::MAX);
        if !tracks.is_multiple_of(64) {
            if let Some(last) = self.due.last_mut() {
                *last = (1 << (tracks % 64)) - 1;
            }
        }
    }

    /// The indices of the tracks the tick at `now_s` visits, in increasing order, among the
    /// first `tracks`: those marked, and those whose wake time is at or before `now_s`. Each is
    /// unmarked; give every one its new wake time ([`Self::schedule`]) after its tick, and
    /// hand the list back ([`Self::done`]).
    pub(super) fn take_due(&mut self, now_s: f64, tracks: usize) -> Vec<usize> {
        self.grow(tracks);
        let now = self.bucket(now_s);
        if self.wheel.first_key_value().is_some_and(|(&first, _)| first <= now) {
            let later = self.wheel.split_off(&now.saturating_add(1));
            let come = std::mem::replace(&mut self.wheel, later);
            for (bucket, indices) in come {
                for index in indices {
                    let i = index as usize;
                    if i >= tracks || self.slot[i] != bucket {
                        continue; // stale: the track moved to another bucket (or is gone)
                    }
                    if self.wake_s[i] <= now_s {
                        self.slot[i] = NO_SLOT;
                        self.due[i / 64] |= 1 << (i % 64);
                    } else {
                        // in the bucket of `now_s` but later within it
                        self.wheel.entry(bucket).or_default().push(index);
                    }
                }
            }
        }
        let mut visiting = std::mem::take(&mut self.visiting);
        visiting.clear();
        for (w, word) in self.due.iter_mut().enumerate() {
            let mut bits = std::mem::take(word);
            while bits != 0 {
                let i = w * 64 + bits.trailing_zeros() as usize;
                if i < tracks {
                    visiting.push(i);
                }
                bits &= bits - 1;
            }
        }
        visiting
    }

    /// Hands back the list [`Self::take_due`] gave (its capacity is reused).
    pub(super) fn done(&mut self, visiting: Vec<usize>) {
        self.visiting = visiting;
    }

    /// Track `index`'s wake time after its tick (see [`super::tick::wake_s`]): the next tick
    /// visits it when `wake_s` is `-∞`; a finite time waits in the wheel; `+∞` waits for a
    /// record.
    pub(super) fn schedule(&mut self, index: usize, wake_s: f64) {
        self.grow(index + 1);
        self.wake_s[index] = wake_s;
        if wake_s == f64::NEG_INFINITY {
            self.due[index / 64] |= 1 << (index % 64);
        } else if wake_s.is_finite() {
            let bucket = self.bucket(wake_s);
            if self.slot[index] != bucket {
                self.slot[index] = bucket;
                // u32 indices: the wheel's entries stay small (4 G tracks is beyond any tracker)
                self.wheel.entry(bucket).or_default().push(index as u32);
            }
        } else {
            self.slot[index] = NO_SLOT;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marked_and_woken_tracks_are_visited_in_order_once() {
        let mut due = DueTracks::new(0.5);
        due.mark(130);
        due.mark(3);
        due.mark(3);
        let first = due.take_due(0.0, 200);
        assert_eq!(first, vec![3, 130]);
        due.done(first);
        due.schedule(3, 1.2);
        due.schedule(130, f64::INFINITY);
        due.schedule(7, f64::NEG_INFINITY);
        due.schedule(9, 1.0);
        // 9 moves to a later bucket: its old entry is stale
        due.schedule(9, 2.6);
        assert_eq!(due.take_due(0.5, 200), vec![7]);
        // 3 wakes at 1.2, within the bucket [1.0, 1.5): not yet at 1.0
        assert_eq!(due.take_due(1.0, 200), Vec::<usize>::new());
        assert_eq!(due.take_due(1.2, 200), vec![3]);
        assert_eq!(due.take_due(2.0, 200), Vec::<usize>::new());
        assert_eq!(due.take_due(3.0, 200), vec![9]);
        assert_eq!(due.take_due(10.0, 200), Vec::<usize>::new());
    }

    #[test]
    fn marking_all_visits_every_track_and_forgets_the_wheel() {
        let mut due = DueTracks::new(0.5);
        due.schedule(2, 1.0);
        due.mark_all(70);
        assert_eq!(due.take_due(0.0, 70), (0..70).collect::<Vec<_>>());
        assert_eq!(due.take_due(5.0, 70), Vec::<usize>::new());
        // tracks beyond the count (deleted) are not visited
        due.mark_all(64);
        due.mark(100);
        assert_eq!(due.take_due(0.0, 64).len(), 64);
    }
}
