//! Rate-limited logging: a warning about something that may repeat thousands of times a second
//! (a gateway's malformed datagrams, an unreachable NATS server) is logged at most once per
//! period, with how many occurrences went unlogged since. The metrics count every one.

use std::time::{Duration, Instant};

/// How often a repeated warning of one source is logged at most.
pub const LOG_PERIOD: Duration = Duration::from_secs(10);

/// Decides whether an occurrence is logged: the first one, then the first after each
/// its period (`LogLimiter::new`); counts the others.
#[derive(Debug, Clone)]
pub struct LogLimiter {
    period: Duration,
    last: Option<Instant>,
    unlogged: u64,
}

impl Default for LogLimiter {
    fn default() -> Self {
        Self::new(LOG_PERIOD)
    }
}

impl LogLimiter {
    /// A limiter logging at most once per `period`.
    #[must_use]
    pub fn new(period: Duration) -> Self {
        Self {
            period,
            last: None,
            unlogged: 0,
        }
    }

    /// Notes one occurrence: `Some(n)` when it is to be logged, `n` counting it and the
    /// occurrences not logged since the last logged one; `None` when it is only counted.
    #[must_use]
    pub fn occurred(&mut self) -> Option<u64> {
        self.occurred_many(1)
    }

    /// Notes `count` occurrences at once (a burst counted together), as
    /// [`LogLimiter::occurred`].
    #[must_use]
    pub fn occurred_many(&mut self, count: u64) -> Option<u64> {
        self.unlogged += count;
        if self.last.is_none_or(|at| at.elapsed() >= self.period) {
            self.last = Some(Instant::now());
            let count = self.unlogged;
            self.unlogged = 0;
            Some(count)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_occurrence_is_logged_and_the_rest_counted_until_the_period_passes() {
        let mut limiter = LogLimiter::new(Duration::from_millis(50));
        assert_eq!(limiter.occurred(), Some(1));
        assert_eq!(limiter.occurred(), None);
        assert_eq!(limiter.occurred(), None);
        std::thread::sleep(Duration::from_millis(60));
        assert_eq!(limiter.occurred(), Some(3), "the two unlogged and this one");
        assert_eq!(limiter.occurred(), None);
        std::thread::sleep(Duration::from_millis(60));
        assert_eq!(limiter.occurred_many(5), Some(6));
    }
}
