//! How far behind the wall clock a partition's live clock runs: a fixed lag, or one measured
//! from how late the records reach the partition (the default, `pipeline.clock_lag_s = "auto"`).
//!
//! The live clock moves the trackers while no records come (`pipeline/event_clock.rs`), so silent
//! tags coast, are lost and raise alarms in real time, and records held in a site's re-ordering
//! window are released. A record whose time is behind a tick its track already had is re-filtered
//! (within the rewind horizon) or reported late. A record reaching the partition at wall time
//! `w'` with delivery delay `d' = w' − t` is behind a tick of time `w − lag` made at an earlier
//! wall time `w ≤ w'` only if `d' > lag + (w' − w)`; a lag at least the largest delay still to
//! come keeps every record ahead of the ticks. The measured lag is that largest delay, taken
//! over the last [`WINDOW_S`] seconds, with room for jitter:
//!
//! ```text
//! d_max = max over the records of the last WINDOW_S seconds of (w_arrival − t)
//! lag   = clamp(d_max + MARGIN_S + JITTER_SHARE · max(d_max, 0),  MARGIN_S,  MAX_LAG_S)
//! ```
//!
//! Prompt records on a LAN (delays of milliseconds) give a lag of about 0.1 s instead of the
//! former fixed 2 s; a gateway that delivers 1.5 s late gives 1.98 s; a backlog of seconds
//! is held at [`MAX_LAG_S`], the former default (the event clock then keeps the clock behind
//! the backlog's own records). A window without records keeps the last lag. Sender clocks
//! ahead of the server's give negative delays: the lag is then the margin.

use serde::Deserialize;

/// Seconds of arrivals the largest delay is taken over (in whole-second buckets).
pub const WINDOW_S: usize = 10;
/// Room above the largest delay for a record later than any of the window's (s), and the
/// least lag.
pub const MARGIN_S: f64 = 0.1;
/// Share of the largest delay added for jitter (a path that is slow is also uneven).
pub const JITTER_SHARE: f64 = 0.25;
/// The largest measured lag (s): the former fixed default.
pub const MAX_LAG_S: f64 = 2.0;

/// `pipeline.clock_lag_s`: a number of seconds, or `"auto"` (measured).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ClockLag {
    /// Measured from the records' delivery delays (the module's formula).
    #[default]
    Auto,
    /// A fixed lag (s, ≥ 0).
    Fixed(f64),
}

impl<'de> Deserialize<'de> for ClockLag {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Written {
            Seconds(f64),
            Word(String),
        }
        match Written::deserialize(deserializer)? {
            Written::Seconds(seconds) => Ok(Self::Fixed(seconds)),
            Written::Word(word) if word == "auto" => Ok(Self::Auto),
            Written::Word(word) => Err(serde::de::Error::custom(format!(
                "expected a number of seconds or \"auto\", got \"{word}\""
            ))),
        }
    }
}

/// The largest delay of one whole second of arrivals.
#[derive(Debug, Clone, Copy)]
struct Bucket {
    /// The wall second (⌊w⌋) it covers.
    second: i64,
    /// The largest delay of a record arriving in it (s).
    max_delay_s: f64,
}

/// A partition's live-clock lag (see the module).
#[derive(Debug, Clone)]
pub(super) struct LiveClockLag {
    setting: ClockLag,
    /// Arrivals by wall second, a ring of [`WINDOW_S`].
    buckets: [Option<Bucket>; WINDOW_S],
    /// The lag when the window was last not empty.
    last_lag_s: f64,
}

impl LiveClockLag {
    pub(super) fn new(setting: ClockLag) -> Self {
        Self {
            setting,
            buckets: [None; WINDOW_S],
            last_lag_s: MAX_LAG_S,
        }
    }

    /// Notes a batch arriving at wall time `wall_s` whose oldest record is of time `oldest_s`
    /// (s): its largest delay is `wall_s − oldest_s`.
    pub(super) fn observe(&mut self, oldest_s: f64, wall_s: f64) {
        let delay_s = wall_s - oldest_s;
        if !delay_s.is_finite() || self.setting != ClockLag::Auto {
            return;
        }
        let second = wall_s.floor() as i64;
        let slot = &mut self.buckets[second.rem_euclid(WINDOW_S as i64) as usize];
        match slot {
            Some(bucket) if bucket.second == second => bucket.max_delay_s = bucket.max_delay_s.max(delay_s),
            _ => {
                *slot = Some(Bucket {
                    second,
                    max_delay_s: delay_s,
                })
            }
        }
    }

    /// The lag at wall time `wall_s` (s): the fixed one, or the module's formula over the
    /// arrivals of the last [`WINDOW_S`] seconds (the last lag when there were none).
    pub(super) fn lag_s(&mut self, wall_s: f64) -> f64 {
        if let ClockLag::Fixed(seconds) = self.setting {
            return seconds;
        }
        let now = wall_s.floor() as i64;
        // d_max over the buckets still inside the window
        let max_delay_s = self
            .buckets
            .iter()
            .flatten()
            .filter(|bucket| (0..WINDOW_S as i64).contains(&(now - bucket.second)))
            .map(|bucket| bucket.max_delay_s)
            .fold(f64::NEG_INFINITY, f64::max);
        if max_delay_s.is_finite() {
            // lag = clamp(d_max + margin + share · max(d_max, 0), margin, max)
            self.last_lag_s = (max_delay_s + MARGIN_S + JITTER_SHARE * max_delay_s.max(0.0)).clamp(MARGIN_S, MAX_LAG_S);
        }
        self.last_lag_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn auto() -> LiveClockLag {
        LiveClockLag::new(ClockLag::Auto)
    }

    #[test]
    fn prompt_records_give_the_margin_and_a_slow_path_its_delay_with_room() {
        let mut lag = auto();
        // before any record: the former fixed lag
        assert_eq!(lag.lag_s(1000.0), MAX_LAG_S);
        // records 5–20 ms old on arrival
        lag.observe(999.995, 1000.0);
        lag.observe(1000.08, 1000.1);
        let prompt = lag.lag_s(1000.2);
        assert!((prompt - (0.02 + 0.1 + 0.25 * 0.02)).abs() < 1e-9, "{prompt}");
        // a gateway delivering 1.5 s late
        lag.observe(1001.0, 1002.5);
        let slow = lag.lag_s(1002.6);
        assert!((slow - (1.5 + 0.1 + 0.375)).abs() < 1e-9, "{slow}");
    }

    #[test]
    fn the_lag_forgets_a_slow_record_after_the_window_and_keeps_the_last_lag_while_silent() {
        let mut lag = auto();
        lag.observe(998.8, 1000.0);
        assert!((lag.lag_s(1000.0) - 1.6).abs() < 1e-9);
        // prompt records for the next 10 s: the slow record's second is still in the window
        // at 1009.x, not at 1010.x
        for k in 1..=9 {
            let wall = 1000.0 + f64::from(k);
            lag.observe(wall - 0.01, wall);
        }
        assert!(lag.lag_s(1009.5) > 1.0);
        lag.observe(1009.99, 1010.0);
        let prompt = lag.lag_s(1010.5);
        assert!(prompt < 0.12, "{prompt}");
        // silence: the last lag stays
        assert_eq!(lag.lag_s(1100.0), prompt);
    }

    #[test]
    fn a_backlog_is_held_at_the_former_default_and_a_clock_ahead_at_the_margin() {
        let mut lag = auto();
        lag.observe(986.4, 1000.0);
        assert_eq!(lag.lag_s(1000.0), MAX_LAG_S);
        let mut ahead = auto();
        ahead.observe(1003.0, 1000.0);
        assert_eq!(ahead.lag_s(1000.0), MARGIN_S);
        // a non-finite time is ignored
        ahead.observe(f64::NAN, 1000.0);
        assert_eq!(ahead.lag_s(1000.0), MARGIN_S);
    }

    #[test]
    fn a_fixed_lag_is_the_setting() {
        let mut lag = LiveClockLag::new(ClockLag::Fixed(0.5));
        lag.observe(900.0, 1000.0);
        assert_eq!(lag.lag_s(1000.0), 0.5);
    }

    #[test]
    fn the_setting_reads_a_number_or_auto() {
        #[derive(Deserialize)]
        struct Section {
            clock_lag_s: ClockLag,
        }
        let read = |text: &str| toml::from_str::<Section>(text).map(|s| s.clock_lag_s);
        assert_eq!(read("clock_lag_s = 0.5").unwrap(), ClockLag::Fixed(0.5));
        assert_eq!(read("clock_lag_s = 2").unwrap(), ClockLag::Fixed(2.0));
        assert_eq!(read("clock_lag_s = \"auto\"").unwrap(), ClockLag::Auto);
        let err = read("clock_lag_s = \"soon\"").unwrap_err().to_string();
        assert!(err.contains("\"auto\""), "{err}");
    }
}
