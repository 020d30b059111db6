//! How an SQLite connection waits for another connection's write lock.

use std::time::Duration;

/// How long a statement waits for another connection's lock before failing (ms).
pub(super) const BUSY_TIMEOUT_MS: u64 = 5_000;

/// The first wait for another connection's lock (µs); each retry doubles it up to
/// [`BUSY_MAX_SLEEP_US`].
const BUSY_FIRST_SLEEP_US: u64 = 20;
/// The longest single wait for another connection's lock (µs).
const BUSY_MAX_SLEEP_US: u64 = 1_000;

/// Waits for another connection's write lock: 20 µs, doubling to 1 ms, then 1 ms at a time,
/// for [`BUSY_TIMEOUT_MS`] in all; `false` (the statement fails with `SQLITE_BUSY`) after.
///
/// The ingest log and the output thread write to one file, so one waits whenever the other
/// commits. SQLite's own busy timeout sleeps 1, 2, 5, 10, 15, 20, 25 … ms, so a lock held for
/// 1.1 ms cost the waiter 3 ms, and one held a little over 3 ms cost 8 ms, on the path from a
/// record to its acknowledgement and its track update.
pub(super) fn wait_for_lock(retries_so_far: i32) -> bool {
    match lock_wait_us(u64::try_from(retries_so_far).unwrap_or(0)) {
        Some(sleep_us) => {
            std::thread::sleep(Duration::from_micros(sleep_us));
            true
        }
        None => false,
    }
}

/// The wait before retry `retries` (µs): min(20 µs · 2ⁿ, 1 ms); `None` once the waits before
/// it add up to [`BUSY_TIMEOUT_MS`].
fn lock_wait_us(retries: u64) -> Option<u64> {
    // the doubling reaches 1 ms after 6 retries (20 + 40 + … + 640 = 1 260 µs in all)
    const DOUBLING: u64 = 6;
    let waited_us = if retries <= DOUBLING {
        BUSY_FIRST_SLEEP_US * ((1 << retries) - 1)
    } else {
        BUSY_FIRST_SLEEP_US * ((1 << DOUBLING) - 1) + (retries - DOUBLING) * BUSY_MAX_SLEEP_US
    };
    (waited_us < BUSY_TIMEOUT_MS * 1_000).then(|| (BUSY_FIRST_SLEEP_US << retries.min(DOUBLING)).min(BUSY_MAX_SLEEP_US))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lock_waits_start_at_20_us_double_to_1_ms_and_stop_after_5_s() {
        assert_eq!(lock_wait_us(0), Some(20));
        assert_eq!(lock_wait_us(1), Some(40));
        assert_eq!(lock_wait_us(5), Some(640));
        assert_eq!(lock_wait_us(6), Some(1_000));
        assert_eq!(lock_wait_us(100), Some(1_000));
        let mut waited_us = 0;
        let mut retries = 0;
        while let Some(wait_us) = lock_wait_us(retries) {
            waited_us += wait_us;
            retries += 1;
        }
        // gives up once the waits reach the timeout, not before and not much after
        assert!(waited_us >= BUSY_TIMEOUT_MS * 1_000, "{waited_us} µs");
        assert!(waited_us <= BUSY_TIMEOUT_MS * 1_000 + 1_000, "{waited_us} µs");
    }
}
