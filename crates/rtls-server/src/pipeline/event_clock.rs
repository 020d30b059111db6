//! Where a partition's live clock may move its tracker: the wall clock, but never ahead of the
//! records still on their way.
//!
//! With `pipeline.live_clock` the wall clock (minus the lag, [`super::clock_lag`]) moves the trackers while no
//! records come, so silent tags coast and are lost. Under a backlog upstream of the partition
//! (publishers with many unacknowledged payloads in flight, an ingest log catching up after a
//! stall) the records that arrive are seconds old; a partition whose queue empties for a
//! moment would move its tracker to the wall clock, and every record of the backlog after it
//! would be older than its track — beyond the rewind horizon, reported `late` and not tracked
//! (the 6 000-tag soak of 2026-11-28: records 13.6 s behind the clock, every one of them late).
//!
//! The clock therefore follows event time: from the newest record the partition has taken, it
//! runs on at the wall clock's rate, capped by the wall clock, and the lag applies to both:
//!
//! ```text
//! target = min(t_wall,  t_newest + (t_wall − t_wall at which t_newest was taken)) − lag
//! ```
//!
//! When records keep coming this stays behind their own time (the trackers are driven by them
//! anyway), by the lag: a record delivered a little later than the one before it (jitter in
//! the path) is not overtaken. When every tag falls silent the clock runs on from the last
//! record, so tracks coast and are lost `coast_timeout_s` after it, as they would on a prompt
//! stream. Without any record it is the wall clock minus the lag.

use std::time::Instant;

/// The newest record time a partition has taken and when it took it.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct EventClock {
    newest: Option<(f64, Instant)>,
}

impl EventClock {
    /// Notes a record of time `time_s` (s) taken now.
    pub(super) fn observe(&mut self, time_s: f64) {
        if !time_s.is_finite() {
            return;
        }
        match self.newest {
            Some((newest_s, _)) if newest_s >= time_s => {}
            _ => self.newest = Some((time_s, Instant::now())),
        }
    }

    /// The time the live clock may move the tracker to (s): the module's `target` at wall
    /// time `wall_s` with lag `lag_s`.
    pub(super) fn target_s(&self, wall_s: f64, lag_s: f64) -> f64 {
        let event_s = match self.newest {
            Some((newest_s, taken)) => wall_s.min(newest_s + taken.elapsed().as_secs_f64()),
            None => wall_s,
        };
        event_s - lag_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_records_the_clock_is_the_wall_clock_minus_the_lag() {
        assert_eq!(EventClock::default().target_s(1000.0, 2.0), 998.0);
    }

    #[test]
    fn a_backlog_holds_the_clock_at_its_records_time() {
        let mut clock = EventClock::default();
        // records 16 s old (a backlog upstream): the clock stays the lag behind them, not at
        // wall − 2 s
        clock.observe(984.0);
        let target = clock.target_s(1000.0, 2.0);
        assert!((982.0..982.5).contains(&target), "{target}");
        // an older record does not move it back
        clock.observe(980.0);
        assert!(clock.target_s(1000.0, 2.0) >= 982.0);
    }

    #[test]
    fn prompt_records_keep_the_clock_the_lag_behind_them_and_the_wall() {
        let mut clock = EventClock::default();
        clock.observe(999.9);
        let target = clock.target_s(1000.0, 2.0);
        assert!((997.9..=998.0).contains(&target), "{target}");
        // a record stamped ahead of the wall clock does not move the clock ahead of it
        clock.observe(1005.0);
        assert_eq!(clock.target_s(1000.0, 2.0), 998.0);
    }

    #[test]
    fn after_the_newest_record_the_clock_runs_at_the_wall_clocks_rate() {
        let mut clock = EventClock::default();
        clock.observe(900.0);
        std::thread::sleep(std::time::Duration::from_millis(60));
        let target = clock.target_s(1000.0, 2.0);
        assert!((898.05..899.0).contains(&target), "{target}");
    }

    #[test]
    fn a_non_finite_time_is_ignored() {
        let mut clock = EventClock::default();
        clock.observe(f64::NAN);
        assert_eq!(clock.target_s(1000.0, 2.0), 998.0);
    }
}
