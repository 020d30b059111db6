//! Reader health: when each reader was last heard and how many records name it per second, so a
//! control room sees a silent reader (seed 000's broken reader) before its tags go dark.
//!
//! A reader is heard when a valid record names it: the anchor of a range, RSSI or TDOA
//! (and the TDOA's reference), or a reading of a fingerprint scan. The rate is the count over
//! the last completed window of [`RATE_WINDOW_MS`].
//!
//! Each reader's row also carries what the tracks have learnt of its range offset
//! (`[tracker.range_bias]`): the partitions post their trackers' offsets at most once per
//! [`OFFSET_PUBLISH_PERIOD`], and the row summarises them over the tags that learnt one.

use std::collections::HashMap;
use std::sync::RwLock;
use std::time::Duration;

use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::AnchorOffsetSummary;
use serde::Serialize;

/// The window over which a reader's record rate is counted, ms.
pub const RATE_WINDOW_MS: i64 = 10_000;

/// A reader that has been heard is silent after this many of its mean record intervals
/// without a record (and never sooner than [`MIN_SILENCE_MS`]): a reader in a busy drift that
/// stops is flagged within a minute, one at a dead end that hears a miner now and then is not.
pub const SILENT_AFTER_INTERVALS: f64 = 10.0;

/// The shortest silence that flags a reader, ms.
pub const MIN_SILENCE_MS: i64 = 60_000;

/// A partition posts its trackers' learnt range offsets at most this often.
pub const OFFSET_PUBLISH_PERIOD: Duration = Duration::from_secs(1);

/// What the health of one reader looks like in `GET /api/v1/readers`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReaderHealth {
    /// The reader's id.
    pub id: String,
    /// Its position in the site, m.
    pub position_m: Vec<f64>,
    /// `false` when the site marks it broken (`working = false`).
    pub working_in_site: bool,
    /// When a record last named it, ms since the Unix epoch (server clock); `None`: never.
    pub last_heard_ms: Option<i64>,
    /// Records naming it per second over the last completed window.
    pub rate_hz: f64,
    /// Records naming it since the server started.
    pub records: u64,
    /// `ok`, `silent` (heard before, not for [`SILENT_AFTER_INTERVALS`] of its intervals),
    /// `never-heard`, or `not-in-site` (records name a reader the site does not list).
    pub status: &'static str,
    /// The range offset the tracks have learnt for it; `None` before any has (or with
    /// `[tracker.range_bias] enabled = false`, or for a reader that gives no ranges).
    pub range_offset: Option<AnchorOffsetSummary>,
}

#[derive(Debug, Clone, Default)]
struct Counter {
    last_heard_ms: i64,
    records: u64,
    window_start_ms: i64,
    window_count: u64,
    rate_hz: f64,
}

impl Counter {
    fn heard(&mut self, now_ms: i64) {
        if self.records == 0 {
            self.window_start_ms = now_ms;
        }
        self.roll(now_ms);
        self.records += 1;
        self.window_count += 1;
        self.last_heard_ms = now_ms;
    }

    /// Closes the window when it is over: rate = count / window length.
    fn roll(&mut self, now_ms: i64) {
        let elapsed_ms = now_ms - self.window_start_ms;
        if elapsed_ms >= RATE_WINDOW_MS {
            // a window with no record since it ended reads as 0
            self.rate_hz = if elapsed_ms >= 2 * RATE_WINDOW_MS {
                0.0
            } else {
                self.window_count as f64 * 1000.0 / elapsed_ms as f64
            };
            self.window_start_ms = now_ms;
            self.window_count = 0;
        }
    }
}

/// Per-reader counters, written at ingest and read by the API.
#[derive(Debug)]
pub struct ReaderMonitor {
    site_readers: Vec<(String, Vec<f64>, bool)>,
    counters: RwLock<HashMap<String, Counter>>,
    started_ms: i64,
    /// Each partition's trackers' learnt range offsets, summarised per reader, as last posted.
    offsets: RwLock<Vec<HashMap<String, AnchorOffsetSummary>>>,
}

impl ReaderMonitor {
    /// A monitor for the site's readers, started at `now_ms`.
    #[must_use]
    pub fn new(site: &Site, now_ms: i64) -> Self {
        Self {
            site_readers: site
                .readers
                .iter()
                .map(|r| (r.id.clone(), r.position_m.clone(), r.working))
                .collect(),
            counters: RwLock::new(HashMap::new()),
            started_ms: now_ms,
            offsets: RwLock::new(Vec::new()),
        }
    }

    /// Replaces what partition `partition` has learnt of the readers' range offsets (its
    /// tracker's offsets summarised per reader, [`AnchorOffsetSummary::by_anchor`]).
    pub fn learnt_offsets(&self, partition: usize, summaries: Vec<AnchorOffsetSummary>) {
        let Ok(mut all) = self.offsets.write() else {
            return;
        };
        if all.len() <= partition {
            all.resize_with(partition + 1, HashMap::new);
        }
        all[partition] = summaries.into_iter().map(|s| (s.anchor.clone(), s)).collect();
    }

    /// The partitions' summaries of `reader` merged (each partition tracks its own tags).
    fn offset_of(&self, reader: &str) -> Option<AnchorOffsetSummary> {
        let all = self.offsets.read().ok()?;
        let mut parts = all.iter().filter_map(|partition| partition.get(reader));
        let mut merged = parts.next()?.clone();
        for part in parts {
            merged.merge(part);
        }
        Some(merged)
    }

    /// Notes the readers that accepted records name, received at `now_ms`.
    pub fn heard<'a>(&self, records: impl IntoIterator<Item = &'a Record>, now_ms: i64) {
        let Ok(mut counters) = self.counters.write() else {
            return;
        };
        for record in records {
            for_each_reader(&record.measurement, |reader| {
                if let Some(counter) = counters.get_mut(reader) {
                    counter.heard(now_ms);
                } else {
                    let mut counter = Counter::default();
                    counter.heard(now_ms);
                    counters.insert(reader.to_string(), counter);
                }
            });
        }
    }

    /// How many times each reader is named by `records` (for a cluster's other nodes, which
    /// apply it with [`ReaderMonitor::heard_counts`]).
    #[must_use]
    pub fn counts<'a>(records: impl IntoIterator<Item = &'a Record>) -> Vec<(String, u64)> {
        let mut counts: HashMap<String, u64> = HashMap::new();
        for record in records {
            for_each_reader(&record.measurement, |reader| {
                *counts.entry(reader.to_string()).or_default() += 1;
            });
        }
        counts.into_iter().collect()
    }

    /// Notes readers heard `count` times each at `now_ms` (another node of a cluster received
    /// their records).
    pub fn heard_counts(&self, counts: &[(String, u64)], now_ms: i64) {
        let Ok(mut counters) = self.counters.write() else {
            return;
        };
        for (reader, count) in counts {
            let counter = counters.entry(reader.clone()).or_default();
            for _ in 0..*count {
                counter.heard(now_ms);
            }
        }
    }

    /// Every reader of the site, then any reader records named that the site lacks, at `now_ms`.
    #[must_use]
    pub fn health(&self, now_ms: i64) -> Vec<ReaderHealth> {
        let mut counters = self.counters.read().map(|c| c.clone()).unwrap_or_default();
        let mut rows: Vec<ReaderHealth> = self
            .site_readers
            .iter()
            .map(|(id, position_m, working)| {
                let counter = counters.remove(id);
                let mut health = row(id, position_m.clone(), *working, counter, now_ms, self.started_ms, true);
                health.range_offset = self.offset_of(id);
                health
            })
            .collect();
        let mut strangers: Vec<_> = counters.into_iter().collect();
        strangers.sort_by(|a, b| a.0.cmp(&b.0));
        rows.extend(
            strangers
                .into_iter()
                .map(|(id, counter)| row(&id, Vec::new(), true, Some(counter), now_ms, self.started_ms, false)),
        );
        rows
    }
}

fn row(
    id: &str,
    position_m: Vec<f64>,
    working_in_site: bool,
    counter: Option<Counter>,
    now_ms: i64,
    started_ms: i64,
    in_site: bool,
) -> ReaderHealth {
    let (last_heard_ms, rate_hz, records, status) = match counter {
        None => (None, 0.0, 0, "never-heard"),
        Some(mut counter) => {
            counter.roll(now_ms);
            // mean interval since the first record; silence is judged against it
            let span_ms = (counter.last_heard_ms - started_ms).max(1) as f64;
            let interval_ms = span_ms / counter.records.max(1) as f64;
            let silence_limit_ms = (SILENT_AFTER_INTERVALS * interval_ms).max(MIN_SILENCE_MS as f64);
            let silent = (now_ms - counter.last_heard_ms) as f64 > silence_limit_ms;
            let status = match (in_site, silent) {
                (false, _) => "not-in-site",
                (true, true) => "silent",
                (true, false) => "ok",
            };
            (Some(counter.last_heard_ms), counter.rate_hz, counter.records, status)
        }
    };
    ReaderHealth {
        id: id.to_string(),
        position_m,
        working_in_site,
        last_heard_ms,
        rate_hz,
        records,
        status,
        range_offset: None,
    }
}

/// Calls `f` with every reader a measurement names.
fn for_each_reader(measurement: &Measurement, mut f: impl FnMut(&str)) {
    match measurement {
        Measurement::Range { anchor, .. } | Measurement::Rssi { anchor, .. } => f(anchor),
        Measurement::Tdoa { anchor, reference, .. } => {
            f(anchor);
            f(reference);
        }
        Measurement::RssiVector { readings } => readings.iter().for_each(|r| f(&r.anchor)),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn site() -> Site {
        Site::from_toml_str(
            r#"
[[readers]]
id = "R1"
position_m = [0.0, 0.0]
technology = "uwb"
[[readers]]
id = "R2"
position_m = [10.0, 0.0]
technology = "uwb"
[tracker]
"#,
            "site.toml",
        )
        .unwrap()
    }

    fn range(anchor: &str) -> Record {
        rtls_engine::record::parse_json_line(
            &format!(r#"{{"t":1.0,"tag":"T","kind":"range","anchor":"{anchor}","range_m":3.0,"std_m":0.1}}"#),
            "test",
            1,
        )
        .unwrap()
    }

    #[test]
    fn a_reader_that_stops_reporting_is_flagged_silent_and_one_never_heard_says_so() {
        let monitor = ReaderMonitor::new(&site(), 0);
        let r1 = range("R1");
        // R1 at 2 Hz for 20 s
        for k in 0..40 {
            monitor.heard([&r1], k * 500);
        }
        let now = monitor.health(20_000);
        assert_eq!(now[0].status, "ok");
        assert!((now[0].rate_hz - 2.0).abs() < 0.25, "rate {}", now[0].rate_hz);
        assert_eq!(now[0].records, 40);
        assert_eq!(now[1].status, "never-heard");
        // 80 s later, nothing (more than a minute and ten of its intervals): silent, and its
        // rate reads 0 after two windows
        assert_eq!(monitor.health(50_000)[0].status, "ok");
        let later = monitor.health(100_000);
        assert_eq!(later[0].status, "silent");
        assert_eq!(later[0].rate_hz, 0.0);
    }

    #[test]
    fn a_reader_the_site_does_not_list_is_reported_as_such() {
        let monitor = ReaderMonitor::new(&site(), 0);
        monitor.heard([&range("R9")], 100);
        let rows = monitor.health(200);
        assert_eq!(rows.len(), 3);
        assert_eq!(rows[2].id, "R9");
        assert_eq!(rows[2].status, "not-in-site");
    }
}
