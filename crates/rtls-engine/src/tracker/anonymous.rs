//! Anonymous detections in the tracker: records whose tag is [`ANONYMOUS_TAG`] (`"*"`) — ranges
//! from a reader or position fixes that carry no identity, like seed 003's ultrasonic echoes —
//! go to the multi-target [`AnonymousTracker`] (gating, GNN or JPDA, M-of-N initiation,
//! deletion) instead of a per-tag track. Its tracks are reported as track updates whose tag is
//! the track id (`anon-1`, `anon-2`, …); confirmed and coasting ones feed the zone monitor
//! (zone events, head counts) like named tags, but not the predictive alarms.
//!
//! Scans: the detections of one time stamp form one scan per reader (one sonar hears each
//! target at most once), and the fixes of one time stamp one scan. A scan is processed when a
//! later record arrives, at a tick or at the end of input; between scans the tracker coasts
//! the tracks with an empty scan every `output_interval_s`, so they are predicted, lost and
//! deleted like named tracks.

use std::sync::Arc;

use super::anchors::{AnchorReading, Anchors};
use super::output::{Event, Output, TrackUpdate, UpdateSource};
use crate::association::{
    AnonymousTracker, AnonymousTrackerSettings, Detection, DetectionFate, ScanReport, TrackEventKind,
};
use crate::error::Result;
use crate::record::Measurement;

/// The tag of a record that carries no identity.
pub const ANONYMOUS_TAG: &str = "*";

/// What one pending detection came from: a reader's range (its anchor index) or a fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum ScanKey {
    Reader(usize),
    Fixes,
}

/// The anonymous tracker and the detections of the time stamp being collected.
#[derive(Debug, Clone)]
pub(crate) struct AnonymousFront {
    tracker: AnonymousTracker,
    tag: Arc<str>,
    /// The height reported for the planar tracks, m.
    tag_height_m: f64,
    pending: Vec<(ScanKey, Detection)>,
    pending_time_s: f64,
    last_scan_s: f64,
}

impl AnonymousFront {
    pub(crate) fn new(settings: AnonymousTrackerSettings, tag_height_m: f64) -> Result<Self> {
        Ok(Self {
            tracker: AnonymousTracker::new(settings)?,
            tag: Arc::from(ANONYMOUS_TAG),
            tag_height_m,
            pending: Vec::new(),
            pending_time_s: f64::NEG_INFINITY,
            last_scan_s: f64::NEG_INFINITY,
        })
    }

    /// One anonymous record: a range (planar: the slant range projected to the tag height) or
    /// a fix; any other kind is rejected with the reason.
    pub(crate) fn push(
        &mut self,
        anchors: &Anchors,
        time_s: f64,
        measurement: &Measurement,
        out: &mut Output,
    ) -> Result<()> {
        if time_s > self.pending_time_s {
            self.flush(out)?;
            self.pending_time_s = time_s;
        }
        let kind = measurement.kind();
        let detection = match measurement {
            Measurement::Range { .. } => match anchors.resolve(measurement) {
                Ok(Some(AnchorReading::Range {
                    anchor,
                    position_m: a,
                    range_m,
                    variance_m2,
                })) => {
                    // planar range: √(r² − (a_z − h)²)
                    let dz = a[2] - self.tag_height_m;
                    // a negative range (Wi-Fi FTM/RTT next to the responder) is about 0
                    let range_m = range_m.max(0.0);
                    let planar_squared = range_m * range_m - dz * dz;
                    if planar_squared < 0.0 {
                        let reason = format!(
                            "a range of {range_m:.3} m is shorter than the reader's height above the tag ({:.3} m)",
                            dz.abs()
                        );
                        out.events.push(self.rejected(time_s, kind, reason));
                        return Ok(());
                    }
                    Detection::range([a[0], a[1]], planar_squared.sqrt(), variance_m2)
                        .map(|d| (ScanKey::Reader(anchor), d))
                }
                Ok(_) => return Ok(()),
                Err(reason) => {
                    out.events.push(self.rejected(time_s, kind, reason));
                    return Ok(());
                }
            },
            Measurement::Fix {
                position_m,
                covariance_m2,
            } if position_m.len() >= 2 => {
                let k = position_m.len();
                let c = |i: usize, j: usize| covariance_m2[i * k + j];
                Detection::fix([position_m[0], position_m[1]], [[c(0, 0), c(0, 1)], [c(1, 0), c(1, 1)]])
                    .map(|d| (ScanKey::Fixes, d))
            }
            _ => {
                let reason =
                    format!("an anonymous (tag \"{ANONYMOUS_TAG}\") record must be a range or a fix, not a {kind}");
                out.events.push(self.rejected(time_s, kind, reason));
                return Ok(());
            }
        };
        match detection {
            Ok(entry) => self.pending.push(entry),
            Err(error) => out.events.push(self.rejected(time_s, kind, error.to_string())),
        }
        Ok(())
    }

    /// The clock at `now_s`: a due scan is processed; without detections for
    /// `output_interval_s` the tracks are advanced by an empty scan (coasting, lost, deleted).
    pub(crate) fn tick(&mut self, now_s: f64, output_interval_s: f64, out: &mut Output) -> Result<()> {
        if now_s > self.pending_time_s {
            self.flush(out)?;
        }
        if !self.tracker.tracks().is_empty() && now_s - self.last_scan_s >= output_interval_s {
            let report = self.tracker.process_scan(now_s, &[])?;
            self.last_scan_s = now_s;
            self.report(&report, out);
        }
        Ok(())
    }

    /// Processes the collected detections, one scan per reader and one for the fixes.
    pub(crate) fn flush(&mut self, out: &mut Output) -> Result<()> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let mut pending = std::mem::take(&mut self.pending);
        pending.sort_by_key(|(key, _)| *key);
        let time_s = self.pending_time_s;
        let mut start = 0;
        while start < pending.len() {
            let key = pending[start].0;
            let end = start + pending[start..].iter().take_while(|(k, _)| *k == key).count();
            let scan: Vec<Detection> = pending[start..end].iter().map(|(_, d)| *d).collect();
            let report = self.tracker.process_scan(time_s, &scan)?;
            self.report(&report, out);
            start = end;
        }
        self.last_scan_s = time_s;
        Ok(())
    }

    fn rejected(&self, time_s: f64, kind: &'static str, reason: String) -> Event {
        Event::Rejected {
            tag: Arc::clone(&self.tag),
            time_s,
            kind,
            reason,
        }
    }

    /// A scan's track updates, lifecycle events, and its ranges that no track could use.
    fn report(&self, report: &ScanReport, out: &mut Output) {
        for update in &report.updates {
            let mean = update.state.mean();
            let p = update.state.covariance();
            out.updates.push(TrackUpdate {
                time_s: update.state.time_s(),
                tag: Arc::clone(&update.track),
                dimensions: 2,
                position_m: [mean[0], mean[2], self.tag_height_m],
                velocity_mps: [mean[1], mean[3], 0.0],
                position_covariance_m2: [p[(0, 0)], p[(0, 2)], p[(2, 0)], p[(2, 2)], 0.0, 0.0, 0.0, 0.0, 0.0],
                predicted: update.predicted,
                status: update.status,
                source: if update.predicted {
                    UpdateSource::Prediction
                } else {
                    UpdateSource::Anchors
                },
                mode: None,
                revised: false,
                smoothed: false,
            });
        }
        for event in &report.events {
            if let TrackEventKind::Lifecycle(lifecycle) = event.kind {
                let position_m = self
                    .tracker
                    .tracks()
                    .iter()
                    .find(|t| t.id() == &*event.track)
                    .map_or([0.0, 0.0, self.tag_height_m], |t| {
                        [t.state().mean()[0], t.state().mean()[2], self.tag_height_m]
                    });
                out.events.push(Event::Lifecycle {
                    tag: Arc::clone(&event.track),
                    time_s: report.time_s,
                    event: lifecycle,
                    position_m,
                });
            }
        }
        let unused = report
            .detections
            .iter()
            .filter(|d| matches!(d.fate, DetectionFate::UnusedRange))
            .count();
        if unused > 0 {
            let reason = format!(
                "{unused} anonymous range(s) matched no track (a range alone cannot start one: send fixes first)"
            );
            out.events.push(self.rejected(report.time_s, "range", reason));
        }
    }
}
