//! Admission of records at ingest: a record whose time cannot be the present of a live site is
//! refused before it is stored, with the reason, so it never reaches a tracker.
//!
//! The parser already refuses times beyond ±10¹¹ s (milliseconds, microseconds or nanoseconds
//! since the epoch; `rtls_engine::record::implausible_time`). A live server also knows the
//! present: with the wall clock driving the trackers (`pipeline.live_clock`), a record more than
//! `pipeline.max_record_lead_s` ahead of the server's clock (a reader whose clock is wrong) or
//! more than `pipeline.max_record_age_s` behind it (a relative clock, a reader replaying a
//! week-old buffer) cannot be tracked as live data and is refused at ingest.

/// The plausible window of record times around the server clock, s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeWindow {
    /// How far behind the server clock a record may be (s, > 0).
    pub max_age_s: f64,
    /// How far ahead of the server clock a record may be (s, > 0).
    pub max_lead_s: f64,
}

impl TimeWindow {
    /// Why a record at `time_s` (Unix s) is outside the window around `now_s` (Unix s); `None`
    /// when it is inside.
    ///
    /// ```text
    /// now − max_age ≤ t ≤ now + max_lead
    /// ```
    ///
    /// # Examples
    /// ```
    /// use rtls_server::pipeline::TimeWindow;
    ///
    /// let window = TimeWindow { max_age_s: 86_400.0, max_lead_s: 60.0 };
    /// let now = 1.8e9;
    /// assert!(window.refusal(now - 3.0, now).is_none());
    /// assert!(window.refusal(now + 3_600.0, now).unwrap().contains("ahead of the server clock"));
    /// assert!(window.refusal(12.5, now).unwrap().contains("relative clock"));
    /// ```
    #[must_use]
    pub fn refusal(&self, time_s: f64, now_s: f64) -> Option<String> {
        let ahead_s = time_s - now_s;
        if ahead_s > self.max_lead_s {
            return Some(format!(
                "{time_s} s is {ahead_s:.0} s ahead of the server clock (Unix {now_s:.0} s; at most \
                 pipeline.max_record_lead_s = {} s): is the reader's clock set (NTP)?",
                self.max_lead_s
            ));
        }
        let behind_s = -ahead_s;
        if behind_s > self.max_age_s {
            // Unix time in 2001 was 1e9 s: anything below it is a clock with another origin
            let hint = if time_s < 1e9 {
                "a relative clock (seconds since the reader started)? A live server needs Unix \
                 seconds; replay recorded data with `rtls serve --data-clock`"
            } else {
                "a buffer replayed long after? Replay old records with `rtls serve --data-clock`"
            };
            return Some(format!(
                "{time_s} s is {behind_s:.0} s behind the server clock (Unix {now_s:.0} s; at most \
                 pipeline.max_record_age_s = {} s): {hint}",
                self.max_age_s
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::TimeWindow;

    const WINDOW: TimeWindow = TimeWindow {
        max_age_s: 86_400.0,
        max_lead_s: 60.0,
    };
    const NOW: f64 = 1_795_000_000.0;

    #[test]
    fn the_window_is_inclusive_and_refuses_beyond_it() {
        assert!(WINDOW.refusal(NOW + 60.0, NOW).is_none());
        assert!(WINDOW.refusal(NOW - 86_400.0, NOW).is_none());
        assert!(WINDOW.refusal(NOW, NOW).is_none());
        let ahead = WINDOW.refusal(NOW + 61.0, NOW).expect("ahead");
        assert!(ahead.contains("61 s ahead"), "{ahead}");
        assert!(ahead.contains("max_record_lead_s = 60"), "{ahead}");
        let old = WINDOW.refusal(NOW - 90_000.0, NOW).expect("old");
        assert!(old.contains("90000 s behind"), "{old}");
        assert!(old.contains("--data-clock"), "{old}");
    }

    #[test]
    fn unit_confusions_that_pass_the_parser_are_named() {
        // deciseconds since the epoch parse (< 1e11) but are centuries ahead
        let deci = WINDOW.refusal(NOW * 10.0, NOW).expect("deciseconds");
        assert!(deci.contains("ahead of the server clock"), "{deci}");
        // a reader counting seconds since it booted
        let relative = WINDOW.refusal(3_600.0, NOW).expect("relative");
        assert!(relative.contains("relative clock"), "{relative}");
    }
}
