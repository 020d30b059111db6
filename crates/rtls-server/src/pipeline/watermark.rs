//! A partition's watermark: the record time up to which every tag still being heard has
//! delivered (`rtls_engine::tracker::Tracker::set_watermark`).
//!
//! Each tag's records come through some sender — a gateway, an MQTT publisher — with that
//! sender's delay. A tag's *offset* is its newest record's time less the wall time at which
//! that record arrived (−delay); at wall time `w` the tag has delivered up to `w + offset`.
//! Over the tags heard within [`ACTIVE`]:
//!
//! ```text
//! W = w + min over active tags of offset,   ignoring offsets below max offset − horizon
//! ```
//!
//! — the slowest sender's position in record time. A tag whose records are more than the
//! rewind horizon behind the others' is ignored (its records are late anyway; waiting for it
//! would hold every track's ticks for nothing), and the tracker never lets its ticks lag the
//! newest record by more than the horizon. A tag no longer heard leaves the minimum after
//! [`ACTIVE`]; until then its term runs on at the wall clock's rate from its last record, so a
//! tag falling silent holds nothing back. Clock offsets between senders count as delays (a
//! gateway whose clock runs 1 s behind is, in record time, a sender 1 s late).

use std::collections::HashMap;
use std::time::{Duration, Instant};

/// A tag not heard for this long (wall time) no longer holds the watermark.
pub(super) const ACTIVE: Duration = Duration::from_secs(5);

/// How often the tags are scanned again (forgetting silent ones, leaving out hopeless ones);
/// in between, a record that lowers a tag's offset lowers the watermark at once, and one that
/// raises it waits for the scan — the watermark is then a little behind, never ahead.
const RESCAN: Duration = Duration::from_millis(50);

/// A tag's newest record time, that less the wall time of its arrival, and when it was heard.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    newest_s: f64,
    offset_s: f64,
    heard: Instant,
}

/// The partition's tags' arrivals (see the module).
#[derive(Debug)]
pub(super) struct Watermark {
    tags: HashMap<String, Arrival>,
    /// The slowest offset as of the last scan, lowered by records since (+∞: no tag).
    slowest_offset_s: f64,
    /// When the tags were last scanned.
    scanned: Option<Instant>,
}

impl Default for Watermark {
    fn default() -> Self {
        Self {
            tags: HashMap::new(),
            slowest_offset_s: f64::INFINITY,
            scanned: None,
        }
    }
}

impl Watermark {
    /// Notes a record of `tag` at `time_s` (s) arriving at wall time `wall_s` (s), `heard` now.
    /// A record older than the tag's newest keeps the tag's offset (it says nothing of how
    /// far the tag has delivered) but counts as heard.
    pub(super) fn observe(&mut self, tag: &str, time_s: f64, wall_s: f64, heard: Instant) {
        if !time_s.is_finite() {
            return;
        }
        // offset = t_newest − w at its arrival (a sender falling further behind lowers it)
        let offset_s = time_s - wall_s;
        self.slowest_offset_s = self.slowest_offset_s.min(offset_s);
        match self.tags.get_mut(tag) {
            Some(arrival) => {
                if time_s > arrival.newest_s {
                    arrival.newest_s = time_s;
                    arrival.offset_s = offset_s;
                }
                arrival.heard = arrival.heard.max(heard);
            }
            None => {
                let arrival = Arrival {
                    newest_s: time_s,
                    offset_s,
                    heard,
                };
                self.tags.insert(tag.to_string(), arrival);
            }
        }
    }

    /// The watermark at wall time `wall_s` (s) and `now`, or `None` when no tag has been
    /// heard within [`ACTIVE`]. `horizon_s`: the tracker's rewind horizon. Scans the tags
    /// (forgetting those not heard within [`ACTIVE`]) at most every [`RESCAN`]; a batch
    /// costs one hash lookup per record otherwise.
    pub(super) fn watermark_s(&mut self, wall_s: f64, now: Instant, horizon_s: f64) -> Option<f64> {
        if self
            .scanned
            .is_none_or(|at| now.saturating_duration_since(at) >= RESCAN)
        {
            self.scanned = Some(now);
            self.tags
                .retain(|_, a| now.saturating_duration_since(a.heard) <= ACTIVE);
            let newest_offset_s = self.tags.values().map(|a| a.offset_s).fold(f64::NEG_INFINITY, f64::max);
            self.slowest_offset_s = self
                .tags
                .values()
                .map(|a| a.offset_s)
                .filter(|&offset_s| offset_s >= newest_offset_s - horizon_s)
                .fold(f64::INFINITY, f64::min);
        }
        // W = w + min offset
        self.slowest_offset_s
            .is_finite()
            .then_some(wall_s + self.slowest_offset_s)
    }

    /// How many tags hold the watermark (heard within [`ACTIVE`] at the last
    /// [`Self::watermark_s`]).
    #[cfg(test)]
    fn active(&self) -> usize {
        self.tags.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slowest_active_sender_sets_the_watermark() {
        let mut marks = Watermark::default();
        let start = Instant::now();
        // scans k apart
        let at = |k: u32| start + RESCAN * k;
        // at wall 1000: a prompt tag's record of 999.98, a slow sender's of 998.5
        marks.observe("prompt", 999.98, 1000.0, at(0));
        marks.observe("slow", 998.5, 1000.0, at(0));
        let w = marks.watermark_s(1000.2, at(0), 2.0).unwrap();
        assert!((w - 998.7).abs() < 1e-9, "{w}");
        // the slow tag's newer record moves it up, at the next scan (until then it stays
        // behind: never ahead)
        marks.observe("slow", 999.0, 1000.3, at(0));
        let w = marks.watermark_s(1000.3, at(0), 2.0).unwrap();
        assert!((w - 998.8).abs() < 1e-9, "{w}");
        let w = marks.watermark_s(1000.3, at(1), 2.0).unwrap();
        assert!((w - 999.0).abs() < 1e-9, "{w}");
        // an older record of a tag does not move it back
        marks.observe("slow", 997.0, 1000.3, at(2));
        assert!((marks.watermark_s(1000.3, at(2), 2.0).unwrap() - 999.0).abs() < 1e-9);
        // a sender falling further behind: its newer record, 1.8 s old on arrival, lowers it
        // at once, between scans
        marks.observe("slow", 999.1, 1000.9, at(2));
        let w = marks.watermark_s(1000.9, at(2), 2.0).unwrap();
        assert!((w - 999.1).abs() < 1e-9, "{w}");
    }

    #[test]
    fn a_sender_beyond_the_horizon_holds_nothing() {
        let mut marks = Watermark::default();
        let now = Instant::now();
        marks.observe("prompt", 1000.0, 1000.0, now);
        marks.observe("hopeless", 990.0, 1000.0, now);
        assert_eq!(marks.watermark_s(1000.0, now, 2.0), Some(1000.0));
    }

    #[test]
    fn a_tag_no_longer_heard_leaves_the_watermark() {
        let mut marks = Watermark::default();
        let start = Instant::now();
        marks.observe("slow", 998.0, 1000.0, start);
        marks.observe("prompt", 1000.0, 1000.0, start + ACTIVE);
        // within ACTIVE the silent tag still counts, running on at the wall clock's rate
        let w = marks.watermark_s(1005.0, start + ACTIVE, 2.0).unwrap();
        assert!((w - 1003.0).abs() < 1e-9, "{w}");
        assert_eq!(marks.active(), 2);
        let later = start + ACTIVE + RESCAN;
        assert_eq!(marks.watermark_s(1005.0, later, 2.0), Some(1005.0));
        assert_eq!(marks.active(), 1);
        // nobody heard: no watermark
        assert_eq!(marks.watermark_s(1020.0, later + ACTIVE + ACTIVE, 2.0), None);
    }

    #[test]
    fn a_non_finite_time_is_ignored() {
        let mut marks = Watermark::default();
        marks.observe("x", f64::NAN, 1000.0, Instant::now());
        assert_eq!(marks.watermark_s(1000.0, Instant::now(), 2.0), None);
    }
}
