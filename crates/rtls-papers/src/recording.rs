//! A simulated recording — a site file, the measurement records and the truth, exactly what
//! `rtls sim <scenario> --out DIR` writes and `rtls track` / `rtls eval` read — and the
//! engine's tracker run on it.
//!
//! Every "ours" row of `rtls repro` is computed this way: the experiment turns its seeded
//! scenario into a [`Recording`], [`Recording::track`] runs [`rtls_engine::tracker::Tracker`]
//! (the same code path as `rtls track` and `rtls serve`) and the experiment scores the
//! [`Tracked`] updates against the truth. There is one tracking loop in the workspace.
//!
//! # Example
//! ```
//! use rtls_engine::record::{Measurement, Record};
//! use rtls_engine::evaluation::TruthSample;
//! use rtls_papers::recording::Recording;
//!
//! let site = r#"
//! readers = [ { id = "A", position_m = [0.0, 0.0], technology = "uwb" } ]
//! [tracker]
//! pipeline = "fix-then-filter"
//! filter = "kf"
//! initiation = { confirm_updates = 1, within_s = 1.0 }
//! "#;
//! let fix = Measurement::Fix { position_m: vec![1.0, 2.0], covariance_m2: vec![0.25, 0.0, 0.0, 0.25] };
//! let records = (0..5)
//!     .map(|k| Record { time_s: f64::from(k), tag: "t1".into(), measurement: fix.clone() })
//!     .collect();
//! let truth = (0..5).map(|k| TruthSample { has_z: true, line: 0, time_s: f64::from(k), tag: "t1".into(), position_m: [1.0, 2.0, 0.0] }).collect();
//! let recording = Recording { site_toml: site.to_string(), records, truth };
//! let tracked = recording.track()?;
//! let at = tracked.latest_at("t1", &[4.0]);
//! assert!((at[0].unwrap().position_m[0] - 1.0).abs() < 1e-9);
//! assert!(recording.truth_csv().starts_with("t,tag,x,y,z\n0,t1,1,2,0\n"));
//! # Ok::<(), rtls_papers::SimError>(())
//! ```

use std::fmt::Write as _;

use rtls_engine::evaluation::TruthSample;
use rtls_engine::record::{to_json_line, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Event, Output, TrackUpdate, Tracker};

use crate::error::{Result, SimError};

/// The file name a recording's site is parsed under (errors name it).
pub const SITE_FILE: &str = "site.toml";

/// The end of a `[tracker]` table for a reproduction scored once a second on a known start: a
/// track is confirmed by its first update, coasts 10 s, lives 600 s, records are taken in
/// order (no re-ordering window), one update per second, no negative information, and no
/// adaptive noise (the paper's noise is the filter's). It closes the table with
/// `[tracker.adaptive_noise]`; subtables may follow.
pub(crate) const SCORED_EACH_SECOND: &str = "initiation = { confirm_updates = 1, within_s = 1.0 }
coast_timeout_s = 10.0
delete_timeout_s = 600.0
reorder_window_s = 0.0
output_interval_s = 1.0
negative_information = false
[tracker.adaptive_noise]
enabled = false
correlation_s = 0.0
";

/// A scenario as files: the site, the records a deployment would send, and the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// The site file (TOML, the format of `examples/site.toml`).
    pub site_toml: String,
    /// The measurement records in arrival order.
    pub records: Vec<Record>,
    /// The truth, in time order.
    pub truth: Vec<TruthSample>,
}

/// What the engine's tracker made of a recording.
#[derive(Debug, Clone)]
pub struct Tracked {
    /// Every track update, in output order.
    pub updates: Vec<TrackUpdate>,
    /// Every event (lifecycle, rejected records, model switches, …).
    pub events: Vec<Event>,
    /// Records the tracker refused as input errors: index into [`Recording::records`] and
    /// the message.
    pub refused: Vec<(usize, String)>,
}

impl Recording {
    /// The site, parsed and validated as `rtls track` does.
    ///
    /// # Errors
    /// [`SimError::Scenario`] naming [`SITE_FILE`] with the loader's message.
    pub fn site(&self) -> Result<Site> {
        Site::from_toml_str(&self.site_toml, SITE_FILE).map_err(|e| SimError::Scenario {
            file: SITE_FILE.to_string(),
            reason: e.to_string(),
        })
    }

    /// Runs [`Tracker`] over every record in order and finishes it (the `rtls track` loop,
    /// without the file reading).
    ///
    /// # Errors
    /// The site's errors ([`Recording::site`]); a tracker that cannot be built or finished.
    /// A record the tracker refuses is not an error: it is listed in [`Tracked::refused`].
    pub fn track(&self) -> Result<Tracked> {
        let site = self.site()?;
        let mut tracker = Tracker::new(&site).map_err(SimError::from_engine)?;
        let mut output = Output::default();
        let mut refused = Vec::new();
        for (index, record) in self.records.iter().enumerate() {
            if let Err(error) = tracker.push(record.clone(), &mut output) {
                refused.push((index, error.to_string()));
            }
        }
        tracker.finish(&mut output).map_err(SimError::from_engine)?;
        Ok(Tracked {
            updates: output.updates,
            events: output.events,
            refused,
        })
    }

    /// The records as JSON Lines, the input of `rtls track --input`.
    #[must_use]
    pub fn measurements_jsonl(&self) -> String {
        let mut text = String::new();
        for record in &self.records {
            text.push_str(&to_json_line(record));
            text.push('\n');
        }
        text
    }

    /// The truth as CSV `t,tag,x,y,z`, the input of `rtls eval --truth`.
    #[must_use]
    pub fn truth_csv(&self) -> String {
        let mut text = String::from("t,tag,x,y,z\n");
        for row in &self.truth {
            let [x, y, z] = row.position_m;
            // writing into a String cannot fail; no height: an empty z, as `rtls eval` reads it
            let _ = if row.has_z {
                writeln!(text, "{},{},{x},{y},{z}", row.time_s, row.tag)
            } else {
                writeln!(text, "{},{},{x},{y},", row.time_s, row.tag)
            };
        }
        text
    }
}

impl Tracked {
    /// For each of `times_s`, the latest update of `tag` whose time is at or before it (what a
    /// control room shows at that time), `None` before the tag's first update.
    ///
    /// Updates are taken in output order; `times_s` need not be sorted.
    #[must_use]
    pub fn latest_at(&self, tag: &str, times_s: &[f64]) -> Vec<Option<&TrackUpdate>> {
        let mut own: Vec<&TrackUpdate> = self.updates.iter().filter(|u| &*u.tag == tag).collect();
        // stable: of equal times the later output (the revised state) wins below
        own.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        times_s
            .iter()
            .map(|&t| {
                // a state stamped a microsecond after t is the epoch of t (float noise)
                let after = own.partition_point(|u| u.time_s <= t + 1e-6);
                after.checked_sub(1).map(|i| own[i])
            })
            .collect()
    }
}
