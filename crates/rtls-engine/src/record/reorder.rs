//! Re-ordering of records that arrive out of time order (network and reader-buffer delays).

use std::collections::BTreeMap;

use super::Record;
use crate::error::{EngineError, Result};

/// A record leaving a [`Reorderer`].
#[derive(Debug, Clone, PartialEq)]
pub enum Emitted {
    /// Released in time order: not earlier than any record released before it.
    InOrder(Record),
    /// Arrived after a later record had already been released; passed on at once, never
    /// dropped, so that the caller can apply it (e.g. by re-filtering) or count it.
    Late {
        /// The record.
        record: Record,
        /// How far it is behind the last released time stamp, s (> 0).
        lateness_s: f64,
    },
}

impl Emitted {
    /// The record, in order or late.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::{Emitted, Measurement, Record};
    ///
    /// let record = Record { time_s: 1.0, tag: "a".into(), measurement: Measurement::Rssi { anchor: "R".into(), rssi_dbm: -60.0 } };
    /// assert_eq!(Emitted::InOrder(record.clone()).record(), &record);
    /// ```
    #[must_use]
    pub fn record(&self) -> &Record {
        match self {
            Self::InOrder(record) | Self::Late { record, .. } => record,
        }
    }
}

/// Puts records back in time order within a window, across all tags.
///
/// Each pushed record is held until a record at least `window_s` newer has been seen, then
/// released in time order (equal time stamps keep their arrival order, so the output is
/// deterministic). A record older than the last released time stamp can no longer be put in
/// place: it is emitted at once as [`Emitted::Late`] with its lateness. [`Reorderer::finish`]
/// releases everything still held. With `window_s = 0` records pass straight through and the
/// re-orderer only checks the order.
///
/// # Units
/// `window_s` and all times in seconds.
///
/// # Examples
/// ```
/// use rtls_engine::record::{Emitted, Measurement, Record, Reorderer};
///
/// let at = |time_s: f64| Record { time_s, tag: "a".into(), measurement: Measurement::Rssi { anchor: "R".into(), rssi_dbm: -60.0 } };
/// let mut reorderer = Reorderer::new(1.0).unwrap();
/// assert!(reorderer.push(at(2.0)).unwrap().is_empty());
/// assert!(reorderer.push(at(1.5)).unwrap().is_empty());
/// // 3.0 − 1.0 = 2.0: both held records are released, in time order.
/// let out = reorderer.push(at(3.0)).unwrap();
/// assert_eq!(out, vec![Emitted::InOrder(at(1.5)), Emitted::InOrder(at(2.0))]);
/// // 1.0 is behind the last released 2.0: reported late, not dropped.
/// assert_eq!(reorderer.push(at(1.0)).unwrap(), vec![Emitted::Late { record: at(1.0), lateness_s: 1.0 }]);
/// assert_eq!(reorderer.finish(), vec![Emitted::InOrder(at(3.0))]);
/// ```
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Reorderer {
    window_s: f64,
    /// Held records by (time, arrival number).
    held: BTreeMap<(TimeKey, u64), Record>,
    arrivals: u64,
    newest_s: Option<f64>,
    last_released_s: Option<f64>,
}

/// A finite time stamp, totally ordered.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct TimeKey(f64);

impl Eq for TimeKey {}

impl PartialOrd for TimeKey {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for TimeKey {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

impl Reorderer {
    /// Continues from `earlier`'s held records and clocks (a tracker's checkpoint), with this
    /// re-ordering window.
    pub(crate) fn resume(&mut self, earlier: Reorderer) {
        self.held = earlier.held;
        self.arrivals = earlier.arrivals;
        self.newest_s = earlier.newest_s;
        self.last_released_s = earlier.last_released_s;
    }

    /// A re-orderer that holds records for up to `window_s` of newer data.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] if `window_s` is negative or not finite.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::Reorderer;
    ///
    /// assert!(Reorderer::new(0.5).is_ok());
    /// assert!(Reorderer::new(-1.0).is_err());
    /// ```
    pub fn new(window_s: f64) -> Result<Self> {
        if !(window_s.is_finite() && window_s >= 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "window_s",
                reason: "must be finite and ≥ 0 s",
            });
        }
        Ok(Self {
            window_s,
            held: BTreeMap::new(),
            arrivals: 0,
            newest_s: None,
            last_released_s: None,
        })
    }

    /// The window, s.
    ///
    /// # Examples
    /// ```
    /// assert_eq!(rtls_engine::record::Reorderer::new(2.0).unwrap().window_s(), 2.0);
    /// ```
    #[must_use]
    pub fn window_s(&self) -> f64 {
        self.window_s
    }

    /// How many records are held, waiting for newer data.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::{Measurement, Record, Reorderer};
    ///
    /// let mut reorderer = Reorderer::new(5.0).unwrap();
    /// let record = Record { time_s: 1.0, tag: "a".into(), measurement: Measurement::Rssi { anchor: "R".into(), rssi_dbm: -60.0 } };
    /// reorderer.push(record).unwrap();
    /// assert_eq!(reorderer.held(), 1);
    /// ```
    #[must_use]
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// Takes one record; returns the records now released: the late record itself if it is older
    /// than the last released time stamp, otherwise every held record at or before
    /// `newest − window_s`, in time order.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] if the record's time is not finite (parsed records
    /// always are); the re-orderer is unchanged.
    ///
    /// # Examples
    /// See [`Reorderer`].
    pub fn push(&mut self, record: Record) -> Result<Vec<Emitted>> {
        let mut released = Vec::new();
        self.push_into(record, &mut released)?;
        Ok(released)
    }

    /// [`Reorderer::push`], appending the released records to `released` (a caller's buffer,
    /// so a record that passes straight through allocates nothing).
    ///
    /// # Errors
    /// As [`Reorderer::push`].
    pub(crate) fn push_into(&mut self, record: Record, released: &mut Vec<Emitted>) -> Result<()> {
        let time_s = record.time_s;
        if !time_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "must be a finite time stamp",
            });
        }
        if let Some(last_s) = self.last_released_s.filter(|&last_s| time_s < last_s) {
            released.push(Emitted::Late {
                record,
                lateness_s: last_s - time_s,
            });
            return Ok(());
        }
        let newest_s = self.newest_s.map_or(time_s, |n| n.max(time_s));
        if self.held.is_empty() && time_s <= newest_s - self.window_s {
            // nothing held and the record is due at once (no window, or a record that old):
            // it alone is released, as it would be through the map
            self.arrivals += 1;
            self.newest_s = Some(newest_s);
            self.last_released_s = Some(time_s);
            released.push(Emitted::InOrder(record));
            return Ok(());
        }
        self.held.insert((TimeKey(time_s), self.arrivals), record);
        self.arrivals += 1;
        self.newest_s = Some(newest_s);
        self.release_into(newest_s - self.window_s, released);
        Ok(())
    }

    /// Releases the held records at or before `clock_s − window_s`, in time order: a live
    /// clock (`clock_s`, on the records' time base) says no record older than that can still
    /// arrive in time, so the last records of a tag that falls silent are not held for ever.
    /// Records older than the released ones stay late, as after [`Reorderer::push`].
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::record::{Measurement, Record, Reorderer};
    ///
    /// let mut reorderer = Reorderer::new(1.0).unwrap();
    /// let record = Record { time_s: 10.0, tag: "a".into(), measurement: Measurement::Rssi { anchor: "R".into(), rssi_dbm: -60.0 } };
    /// assert!(reorderer.push(record).unwrap().is_empty());
    /// assert!(reorderer.release_until(10.5).is_empty()); // 10 > 10.5 − 1
    /// assert_eq!(reorderer.release_until(11.0).len(), 1);
    /// ```
    pub fn release_until(&mut self, clock_s: f64) -> Vec<Emitted> {
        if !clock_s.is_finite() {
            return Vec::new();
        }
        self.release_up_to(clock_s - self.window_s)
    }

    /// Releases every held record, in time order (end of input).
    ///
    /// Later pushes still compare with the last released time stamp.
    ///
    /// # Examples
    /// See [`Reorderer`].
    pub fn finish(&mut self) -> Vec<Emitted> {
        self.release_up_to(f64::INFINITY)
    }

    fn release_up_to(&mut self, cutoff_s: f64) -> Vec<Emitted> {
        let mut released = Vec::new();
        self.release_into(cutoff_s, &mut released);
        released
    }

    fn release_into(&mut self, cutoff_s: f64, released: &mut Vec<Emitted>) {
        while let Some(entry) = self.held.first_entry() {
            if entry.key().0 .0 > cutoff_s {
                break;
            }
            let record = entry.remove();
            self.last_released_s = Some(record.time_s);
            released.push(Emitted::InOrder(record));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Measurement;

    fn at(time_s: f64, tag: &str) -> Record {
        Record {
            time_s,
            tag: tag.into(),
            measurement: Measurement::Rssi {
                anchor: "R1".into(),
                rssi_dbm: -60.0,
            },
        }
    }

    fn times(emitted: &[Emitted]) -> Vec<f64> {
        emitted.iter().map(|e| e.record().time_s).collect()
    }

    /// A deterministic shuffle: each record displaced by less than the window.
    #[test]
    fn shuffled_within_the_window_comes_out_sorted() {
        let window_s = 1.0;
        let mut input: Vec<f64> = (0..200).map(|i| f64::from(i) * 0.1).collect();
        // Swap neighbours in blocks of up to 9 steps (0.9 s < window).
        let mut state = 12_345_u64;
        for start in (0..input.len()).step_by(9) {
            let end = (start + 9).min(input.len());
            for i in (start + 1..end).rev() {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let j = start + usize::try_from(state >> 33).unwrap() % (i - start + 1);
                input.swap(i, j);
            }
        }
        let mut reorderer = Reorderer::new(window_s).unwrap();
        let mut output = Vec::new();
        for &t in &input {
            output.extend(reorderer.push(at(t, "a")).unwrap());
        }
        output.extend(reorderer.finish());
        assert!(output.iter().all(|e| matches!(e, Emitted::InOrder(_))));
        let mut sorted = input.clone();
        sorted.sort_by(f64::total_cmp);
        assert_ne!(input, sorted, "the test input must be shuffled");
        assert_eq!(times(&output), sorted);
        assert_eq!(reorderer.held(), 0);
    }

    #[test]
    fn late_records_are_reported_with_their_lateness() {
        let mut reorderer = Reorderer::new(0.5).unwrap();
        assert!(reorderer.push(at(10.0, "a")).unwrap().is_empty());
        assert_eq!(times(&reorderer.push(at(11.0, "a")).unwrap()), vec![10.0]);
        let late = reorderer.push(at(9.75, "b")).unwrap();
        assert_eq!(
            late,
            vec![Emitted::Late {
                record: at(9.75, "b"),
                lateness_s: 0.25
            }]
        );
        // Still behind after the flush: reported, never dropped.
        assert_eq!(times(&reorderer.finish()), vec![11.0]);
        assert!(
            matches!(reorderer.push(at(10.5, "c")).unwrap()[..], [Emitted::Late { lateness_s, .. }] if lateness_s == 0.5)
        );
    }

    #[test]
    fn a_record_at_the_last_released_time_is_in_order() {
        let mut reorderer = Reorderer::new(0.0).unwrap();
        reorderer.push(at(5.0, "a")).unwrap();
        assert_eq!(
            reorderer.push(at(5.0, "b")).unwrap(),
            vec![Emitted::InOrder(at(5.0, "b"))]
        );
    }

    #[test]
    fn window_zero_passes_through_and_checks_order() {
        let mut reorderer = Reorderer::new(0.0).unwrap();
        assert_eq!(
            reorderer.push(at(1.0, "a")).unwrap(),
            vec![Emitted::InOrder(at(1.0, "a"))]
        );
        assert_eq!(
            reorderer.push(at(2.0, "a")).unwrap(),
            vec![Emitted::InOrder(at(2.0, "a"))]
        );
        assert_eq!(
            reorderer.push(at(1.5, "a")).unwrap(),
            vec![Emitted::Late {
                record: at(1.5, "a"),
                lateness_s: 0.5
            }]
        );
        assert_eq!(reorderer.held(), 0);
        assert!(reorderer.finish().is_empty());
    }

    #[test]
    fn ties_keep_arrival_order() {
        let mut reorderer = Reorderer::new(1.0).unwrap();
        for tag in ["c", "a", "b"] {
            assert!(reorderer.push(at(3.0, tag)).unwrap().is_empty());
        }
        reorderer.push(at(2.5, "z")).unwrap();
        let out = reorderer.finish();
        let tags: Vec<&str> = out.iter().map(|e| e.record().tag.as_str()).collect();
        assert_eq!(tags, ["z", "c", "a", "b"]);
    }

    #[test]
    fn release_happens_exactly_at_the_window_edge() {
        let mut reorderer = Reorderer::new(2.0).unwrap();
        reorderer.push(at(1.0, "a")).unwrap();
        assert!(reorderer.push(at(2.999, "a")).unwrap().is_empty());
        assert_eq!(times(&reorderer.push(at(3.0, "a")).unwrap()), vec![1.0]);
    }

    #[test]
    fn invalid_window_and_time_are_errors() {
        for window_s in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                Reorderer::new(window_s),
                Err(EngineError::InvalidParameter { name: "window_s", .. })
            ));
        }
        let mut reorderer = Reorderer::new(1.0).unwrap();
        let error = reorderer.push(at(f64::NAN, "a")).unwrap_err();
        assert!(matches!(error, EngineError::InvalidParameter { name: "time_s", .. }));
        assert_eq!(reorderer.held(), 0);
    }
}
