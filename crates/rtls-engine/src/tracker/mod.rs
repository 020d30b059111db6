//! The manager layer's tracker: records in, track updates and events out, for any number of
//! tags, deterministic and synchronous (no threads, no clock: time comes from the records).
//!
//! # Pipelines (`tracker.pipeline` in the site file)
//! - **fix-then-filter** (seed 000): a tag's range / RSSI / TDOA readings within `epoch_s` (or,
//!   without it, those of one time stamp, or of one round of readers that report one at a
//!   time: [`AUTO_EPOCH_MAX_S`]) are solved into a fix dated at their mean time (weighted
//!   Gauss–Newton multilateration with covariance; Chan + Taylor for TDOA) which a linear KF on
//!   a CV state smooths.
//! - **tightly coupled** (seeds 001, 003, 004): each raw reading updates an EKF or UKF directly,
//!   one scalar measurement at a time (seed 003's one-observation update), with the slant
//!   distance to anchors at other heights. A new track starts from a fix of its first readings
//!   (waiting up to 1 s for readings whose fix is surer than the anchors' spread and, when the
//!   first anchors lie on one line, for one off it); every second a confirmed track checks
//!   itself against a fix of the readings it took and jumps to such fixes when they agree with
//!   each other outside its gate (`check`).
//!
//! In both, `fix` records and fingerprint scans (`rssi_vector`, located in the site's radio map)
//! update the position, `velocity` and `odometry` (speed + heading) the velocity, and an
//! `accelerometer` sample drives the prediction for up to 1 s (seed 002). A range may carry its
//! anchor's position (`anchor_position_m`, a moving anchor).
//!
//! # Heading (`[tracker.heading]`)
//! Each track keeps a heading channel — heading, gyro bias, odometer heading offset
//! ([`rtls_estimation::aided::HeadingModel`]). `yaw_rate`, `odometry_increment` and body-frame
//! `imu` samples drive it; odometry headings and the course over ground (chords between the
//! track's positions after fixes) align it and calibrate the biases; a speed without a heading
//! (`odometry` without `heading_rad`, an increment's distance) becomes a velocity along it.
//!
//! GNSS `pseudorange` records are solved per epoch in both pipelines: a pseudorange carries the
//! receiver clock bias, common to every satellite of the epoch and unknown, so one alone cannot
//! update the filter without the clock state. A tag's pseudoranges of one epoch (equal time
//! stamps, or within `epoch_s`) are solved together for position and clock bias in the site's
//! ENU frame about `[frame] origin` (with fault exclusion), and the fix updates the track like a
//! position fix (raw fix method `pseudorange`); each track keeps a receiver clock filter
//! (bias and drift) whose prediction is the solver's prior, so three satellites (two at a known
//! height) still give a fix. The model is documented in the tracker's `gnss` module and in [`rtls_positioning::gnss`].
//!
//! # Motion models (`tracker.motion_model`)
//! - **cv**: constant velocity with white acceleration `σ_a` (seed 000).
//! - **ct** (2-D): a coordinated turn with the turn rate as a state, `[x, vx, y, vy, ω]`, its
//!   rate driven by a white turn acceleration (`turn_rate_noise_std_radps2`); run as an IMM of
//!   this one mode (which is the plain filter), so its reported state is the `[x, vx, y, vy]`
//!   marginal and every update names the mode "CT".
//! - **imm**: interacting multiple models (`[tracker.imm]`): by default a quiet CV, a constant
//!   acceleration and, in 2-D, a coordinated turn with the rate as a state (`modes` picks any
//!   set of them), switching as a Markov chain. The track's reported state is the modes'
//!   moment-matched combination; every
//!   update names the most probable mode (`mode`), and [`Event::ModelSwitch`] reports when it
//!   changes (anti-flap: the new mode needs `switch_probability`). Anchor readings update each
//!   mode in its own layout by a sigma-point step under `filter = "ukf"`, else by an EKF step,
//!   and the coordinated turn predicts with the configured filter; an accelerometer sample is the CV mode's control
//!   input, as for the single CV model (the CA and CT modes estimate the acceleration
//!   themselves). The turn rate is kept within ±π rad/s (half a turn per second): beyond
//!   that the CT mode is drifting where the position does not observe it, not turning.
//!
//! # Time, order and output
//! Records pass a re-ordering window (`reorder_window_s`); later ones are reported as
//! [`Event::Late`], never applied silently out of order — unless `rewind_horizon_s` > 0: then a
//! record up to that much older than its track's newest input is re-filtered (the track
//! rewinds to a stored copy and re-applies what followed; revised updates are flagged), so a
//! live server can run without a window. [`Tracker::report_pending`] reports updates at once. A track's update is reported once all
//! readings of its time stamp are in (when a later record of the tag arrives, or at the next
//! tick). The tracker ticks every half `output_interval_s` of record time, in time order with
//! the records: the ticks before a record's time run before it is applied (so a tag's outputs do
//! not depend on other tags' records), and a fix-then-filter track whose open epoch holds
//! earlier readings is ticked once its fix is in. A track whose update is overdue by more than
//! `output_interval_s` coasts, outputting its prediction every `output_interval_s`, flagged
//! `predicted`, with its growing covariance (seed 000's gap filling, so the position-equipment
//! loss rate PEL is 0); after `coast_timeout_s` of silence it is lost and keeps reporting its
//! last estimated position (status `lost`); after `delete_timeout_s` it is deleted.
//!
//! # Zones and alarms
//! Confirmed and coasting positions feed the zone monitor (enter / exit / dwell with anti-flap).
//! Each reported state is predicted over `alarms.horizon_s`; when the probability of being
//! inside a hazard zone (or a zone whose readers are all broken) reaches
//! `alarms.entry_probability`, [`Event::HazardPredicted`] carries the expected time to entry
//! (seed 000's predictive alarm); entering a zone without a working reader gives
//! [`Event::NoCoverage`].
//!
//! In fix-then-filter, a fix, fingerprint scan, velocity or odometry record that arrives while
//! the tag's epoch is open is held and applied in time order with the epoch's fix (which is
//! dated at its readings' mean time) when the epoch closes.
//!
//! # Errors
//! A measurement that cannot be used (unknown or broken reader, no noise level, outside the
//! gate, an epoch without enough anchors, a failed update) is reported as [`Event::Rejected`]
//! with the reason; [`Tracker::check_record`] lets a file reader turn unknown reader ids into
//! errors naming the file, line and field first. One record never aborts the run: any failure
//! while applying it is a rejected event naming the error. A track whose state or covariance
//! becomes non-finite, whose position covariance trace exceeds (10 km)², or whose position
//! leaves the readers' box by more than 10 km has diverged: a rejected event whose reason
//! starts with `track diverged` (kind `track` when a clock tick finds it) reports it, and the
//! track restarts from its next fix. `Err` is returned only for settings the tracker cannot
//! run with and for a non-finite time through the API.
//!
//! # Example
//! ```
//! use rtls_engine::record::{Measurement, Record};
//! use rtls_engine::site::Site;
//! use rtls_engine::tracker::{Output, Tracker};
//! let site = Site::from_toml_str(r#"
//!     readers = [
//!       { id = "A", position_m = [0.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.0 } } },
//!       { id = "B", position_m = [20.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.0 } } },
//!       { id = "C", position_m = [0.0, 20.0], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.0 } } },
//!     ]
//!     [tracker]
//!     pipeline = "tightly-coupled"
//!     motion_model = "cv"
//!     filter = "ekf"
//!     acceleration_noise_std_mps2 = 0.5
//!     gate_probability = 0.999
//!     initiation = { confirm_updates = 3, within_s = 5.0 }
//!     coast_timeout_s = 5.0
//!     delete_timeout_s = 60.0
//!     reorder_window_s = 0.0
//! "#, "site.toml")?;
//! let mut tracker = Tracker::new(&site)?;
//! let mut out = Output::default();
//! let truth = [5.0, 5.0];
//! for k in 0..30 {
//!     let t = k as f64 * 0.1;
//!     let anchor = ["A", "B", "C"][k % 3];
//!     let a = site.reader(anchor).unwrap().position_xyz_m();
//!     let range_m = ((truth[0] - a[0]).powi(2) + (truth[1] - a[1]).powi(2)).sqrt();
//!     let record = Record { time_s: t, tag: "w1".into(),
//!                           measurement: Measurement::Range { anchor: anchor.into(), range_m, std_m: None, anchor_position_m: None } };
//!     tracker.push(record, &mut out)?;
//! }
//! tracker.finish(&mut out)?;
//! let last = out.updates.last().unwrap();
//! assert!((last.position_m[0] - 5.0).abs() < 0.05 && (last.position_m[1] - 5.0).abs() < 0.05);
//! # Ok::<(), rtls_engine::EngineError>(())
//! ```
//!
//! # References
//! Seed 000 (manager layer, ME-KF gap filling, predictive danger-zone alarms); seed 003
//! (single-observation EKF); seed 001 (UKF on UWB ranges); seed 004 and Blom & Bar-Shalom
//! (1988) (manoeuvres, IMM); Bar-Shalom, Li & Kirubarajan,
//! *Estimation with Applications to Tracking and Navigation*, 2001, §5.4 (validation gates).

mod aided;
mod alarms;
mod anchors;
mod anonymous;
mod bounds;
mod check;
mod checkpoint;
mod clock;
mod consider;
mod constraint_model;
mod constraints;
mod construct;
mod core;
mod coupled;
mod direct;
mod divergence;
mod due;
mod epoch;
mod gnss;
mod gnss_state;
mod heading;
mod heading_cross;
mod heading_state;
mod jump;
mod jump_state;
pub(crate) mod models;
mod modes;
mod noise;
mod offset_cross;
mod outcome;
mod output;
mod range_bias;
mod readings_fix;
mod report;
mod rewind;
mod schedule;
mod smoothing;
mod solve;
mod step;
mod tag_index;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_anonymous;
#[cfg(test)]
mod tests_check;
#[cfg(test)]
mod tests_checkpoint;
#[cfg(test)]
mod tests_consistency;
#[cfg(test)]
mod tests_constraints;
#[cfg(test)]
mod tests_correlation;
#[cfg(test)]
mod tests_due_ticks;
#[cfg(test)]
mod tests_fixed_path;
#[cfg(test)]
mod tests_gnss;
#[cfg(test)]
mod tests_heading;
#[cfg(test)]
mod tests_imm;
#[cfg(test)]
mod tests_jump;
#[cfg(test)]
mod tests_range_bias;
#[cfg(test)]
mod tests_rewind;
#[cfg(test)]
mod tests_robust;
#[cfg(test)]
mod tests_schedule;
#[cfg(test)]
mod tests_smoothing;
#[cfg(test)]
mod tests_timing;
#[cfg(test)]
mod tests_watermark;
mod tick;
mod track;
mod update;

pub use anonymous::ANONYMOUS_TAG;
pub use checkpoint::TrackerState;
pub use epoch::AUTO_EPOCH_MAX_S;
pub use noise::{InnovationTotals, Innovations, NoiseClass};
pub use output::{status_name, Event, Output, RawFix, ReportedState, TrackUpdate, TurnState, UpdateSource};
pub use range_bias::{AnchorOffsetSummary, RangeOffset};
pub use rtls_estimation::smoother::NoiseFit;
pub(crate) use schedule::scheduling_layout;
pub use smoothing::{SegmentFit, SmoothedTracks, Smoother, SmoothingFailure, FIT_STATES_MIN};

use self::anonymous::AnonymousFront;
use self::core::Core;
use self::track::Shared;
use crate::error::{EngineError, Result};
use crate::lifecycle::{LifecycleEvent, TrackStatus};
use crate::radio_map::RadioMap;
use crate::record::{Emitted, Record, Reorderer, TimeGate};
use crate::zones::Zone;

/// Ticks run to catch up after a silence of the whole input, at most: after a longer silence
/// (or when a tick step is lost in rounding) the tick grid restarts at the record's time, so
/// one record never costs more than this many ticks.
const MAX_CATCH_UP_TICKS: f64 = 100_000.0;

/// Which ticks [`Tracker::run_ticks`] runs relative to a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TicksDue {
    /// Those strictly before it: due before a record at that time is applied.
    Before,
    /// Those before it and at it.
    Through,
}

/// The tracks of a 2-D or a 3-D site.
#[derive(Debug, Clone)]
enum Tracks {
    Planar(Core<4>),
    Spatial(Core<6>),
}

/// Tracks every tag of a site from its measurement records.
///
/// See the [module documentation](self) for the pipelines, timing and events.
#[derive(Debug, Clone)]
pub struct Tracker {
    tracks: Tracks,
    /// Records with tag [`ANONYMOUS_TAG`], when the site has an `[anonymous]` section.
    anonymous: Option<AnonymousFront>,
    /// Refuses records whose time jumps beyond `max_time_jump_s` (before they move any clock).
    time_gate: TimeGate,
    reorderer: Reorderer,
    next_tick_s: Option<f64>,
    output_interval_s: f64,
    rewind_horizon_s: f64,
    now_s: f64,
    /// The caller's watermark ([`Tracker::set_watermark`]), s.
    watermark_s: Option<f64>,
    /// [`Tracker::push`]'s buffer of the records the re-ordering window releases (empty
    /// between calls).
    released: Vec<Emitted>,
}

impl Tracker {
    /// The heading channel of `tag`'s track (tests).
    #[cfg(test)]
    pub(crate) fn heading_state(&self, tag: &str) -> Option<rtls_estimation::aided::HeadingState> {
        match &self.tracks {
            Tracks::Planar(core) => core.heading_state(tag),
            Tracks::Spatial(core) => core.heading_state(tag),
        }
    }

    /// Adds the fingerprint radio map that `rssi_vector` records are located in.
    #[must_use]
    pub fn with_radio_map(mut self, radio_map: RadioMap) -> Self {
        self.shared_mut().radio_map = Some(radio_map);
        self
    }

    fn shared(&self) -> &Shared {
        match &self.tracks {
            Tracks::Planar(core) => &core.shared,
            Tracks::Spatial(core) => &core.shared,
        }
    }

    fn shared_mut(&mut self) -> &mut Shared {
        match &mut self.tracks {
            Tracks::Planar(core) => &mut core.shared,
            Tracks::Spatial(core) => &mut core.shared,
        }
    }

    /// Checks a record against the site before it is pushed: every reader id it names must be
    /// a reader of the site.
    ///
    /// # Errors
    /// [`EngineError::Parse`] naming `file`, `line` and the field (`anchor`, `reference`,
    /// `readings[i].anchor`).
    pub fn check_record(&self, record: &Record, file: &str, line: usize) -> Result<()> {
        self.shared()
            .anchors
            .check_ids(&record.measurement)
            .map_err(|(field, reason)| EngineError::Parse {
                file: file.to_string(),
                line,
                field,
                reason,
            })
    }

    /// Pushes one record; what it (and the records it releases from the re-ordering window)
    /// produced is appended to `out`.
    ///
    /// A record whose time is not plausible (not finite, beyond
    /// ±[`MAX_ABS_TIME_S`](crate::record::MAX_ABS_TIME_S)) or jumps more than
    /// `tracker.max_time_jump_s` ahead of the newest record ([`TimeGate`]) is refused: an
    /// [`Event::Rejected`] with the reason, at the newest accepted time (0 before any).
    ///
    /// # Errors
    /// A non-finite or implausible time is a [`Event::Rejected`] (see `max_time_jump_s`);
    /// failures of the anonymous detections' front end are errors. A record that cannot be
    /// applied to a tag's track is a [`Event::Rejected`], not an error.
    pub fn push(&mut self, record: Record, out: &mut Output) -> Result<()> {
        if let Err(reason) = self.time_gate.check(record.time_s) {
            out.events.push(Event::Rejected {
                tag: record.tag.as_str().into(),
                time_s: self.time_gate.newest_s().unwrap_or(0.0),
                kind: record.measurement.kind(),
                reason,
            });
            return Ok(());
        }
        // (the buffer is the tracker's, so a record that passes straight through allocates
        // nothing)
        let mut released = std::mem::take(&mut self.released);
        let result = self
            .reorderer
            .push_into(record, &mut released)
            .and_then(|()| released.drain(..).try_for_each(|emitted| self.emitted(emitted, out)));
        released.clear();
        self.released = released;
        result
    }

    fn emitted(&mut self, emitted: Emitted, out: &mut Output) -> Result<()> {
        let rewinds = self.rewind_horizon_s > 0.0;
        match emitted {
            // behind the clock or the window: its track re-filters it (or reports it late)
            Emitted::InOrder(record) | Emitted::Late { record, .. }
                if rewinds && record.tag != ANONYMOUS_TAG && record.time_s < self.now_s =>
            {
                self.apply(&record, out)
            }
            // the live clock ticked past it (it arrived after the window had closed on it)
            Emitted::InOrder(record) if record.time_s < self.now_s => {
                out.events.push(Event::Late {
                    tag: record.tag.as_str().into(),
                    time_s: record.time_s,
                    kind: record.measurement.kind(),
                    lateness_s: self.now_s - record.time_s,
                });
                Ok(())
            }
            Emitted::InOrder(record) => self.apply(&record, out),
            Emitted::Late { record, lateness_s } => {
                out.events.push(Event::Late {
                    tag: record.tag.as_str().into(),
                    time_s: record.time_s,
                    kind: record.measurement.kind(),
                    lateness_s,
                });
                Ok(())
            }
        }
    }

    /// Applies one in-order record: first the ticks due before its time, then the record, then
    /// a tick at its time if one is due.
    fn apply(&mut self, record: &Record, out: &mut Output) -> Result<()> {
        // a tick at τ must see every track as of τ: the ticks between the previous record and
        // this one come first, or a track this record updates (or starts) would be ticked at
        // an earlier time after its update (its lifecycle's time would go backwards)
        self.run_ticks(record.time_s, TicksDue::Before, out)?;
        if record.tag == ANONYMOUS_TAG {
            let shared = match &self.tracks {
                Tracks::Planar(core) => &core.shared,
                Tracks::Spatial(core) => &core.shared,
            };
            match (&mut self.anonymous, &self.tracks) {
                (Some(front), Tracks::Planar(_)) => {
                    let mark = (out.updates.len(), out.events.len());
                    front.push(&shared.anchors, record.time_s, &record.measurement, out)?;
                    anonymous_zones(&mut self.tracks, out, mark)?;
                }
                (front, _) => out.events.push(Event::Rejected {
                    tag: ANONYMOUS_TAG.into(),
                    time_s: record.time_s,
                    kind: record.measurement.kind(),
                    reason: if front.is_some() {
                        "anonymous detections are tracked in 2-D only (tracker.dimensions = 2)".into()
                    } else {
                        "an anonymous (tag \"*\") record needs an [anonymous] section in the site".into()
                    },
                }),
            }
            self.now_s = self.now_s.max(record.time_s);
            return self.run_ticks(self.now_s, TicksDue::Through, out);
        }
        match &mut self.tracks {
            Tracks::Planar(core) => core.apply(record.time_s, &record.tag, &record.measurement, out)?,
            Tracks::Spatial(core) => core.apply(record.time_s, &record.tag, &record.measurement, out)?,
        }
        self.now_s = self.now_s.max(record.time_s);
        self.run_ticks(self.now_s, TicksDue::Through, out)
    }

    /// Reports every track's pending update now (see the module's *Time, order and output*):
    /// a live server calls it after each batch so updates leave when produced.
    ///
    /// # Errors
    /// None today.
    pub fn report_pending(&mut self, out: &mut Output) -> Result<()> {
        match &mut self.tracks {
            Tracks::Planar(core) => core.report_pending(out),
            Tracks::Spatial(core) => core.report_pending(out),
        }
    }

    /// End of input: releases the re-ordering window, closes open epochs and reports every
    /// pending update.
    ///
    /// # Errors
    /// As [`Tracker::push`].
    pub fn finish(&mut self, out: &mut Output) -> Result<()> {
        for emitted in self.reorderer.finish() {
            self.emitted(emitted, out)?;
        }
        if let Some(front) = &mut self.anonymous {
            let mark = (out.updates.len(), out.events.len());
            front.flush(out)?;
            anonymous_zones(&mut self.tracks, out, mark)?;
        }
        match &mut self.tracks {
            Tracks::Planar(core) => core.flush(out),
            Tracks::Spatial(core) => core.flush(out),
        }
    }

    /// A smoother for this tracker's track updates ([`Smoother`]): the site's CV model (and,
    /// with `motion_model = "ct"`, its coordinated turn) and tag height. Feed it outputs made
    /// by [`Output::keeping_states`].
    #[must_use]
    pub fn smoother(&self) -> Smoother {
        let shared = self.shared();
        Smoother::new(
            shared.kf,
            shared.motion,
            shared.settings.acceleration_noise_std_mps2.powi(2),
            shared.tag_height_m,
        )
        // the tracker's own coordinated turn, the very model its tracks were predicted with
        .with_turn(shared.manoeuvres.as_ref().and_then(|m| m.sole_turn()))
    }

    /// The anchors' range offsets the tracks have learnt (`[tracker.range_bias]`), by tag then
    /// anchor: what a site file's `radio.range.bias_m` would need on top of its value for
    /// that tag. Empty when the estimation is off or no range was used.
    #[must_use]
    pub fn range_offsets(&self) -> Vec<RangeOffset> {
        match &self.tracks {
            Tracks::Planar(core) => core.range_offsets(),
            Tracks::Spatial(core) => core.range_offsets(),
        }
    }

    /// Number of live (not deleted) tracks.
    #[must_use]
    pub fn track_count(&self) -> usize {
        match &self.tracks {
            Tracks::Planar(core) => core.track_count(),
            Tracks::Spatial(core) => core.track_count(),
        }
    }

    /// The status of `tag`'s track, `None` when there is none (or it has no state yet).
    #[must_use]
    pub fn status(&self, tag: &str) -> Option<TrackStatus> {
        match &self.tracks {
            Tracks::Planar(core) => core.status(tag),
            Tracks::Spatial(core) => core.status(tag),
        }
    }

    /// Tags currently inside zone `zone_id` (confirmed entries).
    #[must_use]
    pub fn head_count(&self, zone_id: &str) -> usize {
        match &self.tracks {
            Tracks::Planar(core) => core.monitor.head_count(zone_id),
            Tracks::Spatial(core) => core.monitor.head_count(zone_id),
        }
    }

    /// Replaces the site's zones while tracking (the control room's zone editor): the zone
    /// monitor keeps each tag's state in zones whose id stays ([`crate::zones::ZoneMonitor::replace_zones`]),
    /// and the predictive alarm watches the new hazard zones (plus the site's zones without
    /// coverage that remain), each track keeping its alarm state in zones whose id stays.
    ///
    /// # Errors
    /// As [`crate::zones::ZoneMonitor::new`] for an invalid zone (a polygon's `floor` must already be resolved
    /// into `z_range_m`); the tracker is unchanged on error.
    pub fn replace_zones(&mut self, zones: Vec<Zone>) -> Result<()> {
        match &mut self.tracks {
            Tracks::Planar(core) => core.replace_zones(zones),
            Tracks::Spatial(core) => core.replace_zones(zones),
        }
    }

    /// The tags inside zone `zone_id` (confirmed entries), sorted; empty for an unknown zone.
    #[must_use]
    pub fn occupants(&self, zone_id: &str) -> Vec<&str> {
        match &self.tracks {
            Tracks::Planar(core) => core.monitor.occupants(zone_id),
            Tracks::Spatial(core) => core.monitor.occupants(zone_id),
        }
    }
}

/// Zone events and head counts for the anonymous tracks' updates appended to `out` since
/// `mark` (updates, events): confirmed and coasting positions enter the zone monitor like a
/// named tag's, and a deleted anonymous track leaves its zones.
fn anonymous_zones(tracks: &mut Tracks, out: &mut Output, mark: (usize, usize)) -> Result<()> {
    let Tracks::Planar(core) = tracks else {
        return Ok(());
    };
    let mut zone_events = Vec::new();
    for update in &out.updates[mark.0..] {
        if matches!(update.status, TrackStatus::Confirmed | TrackStatus::Coasting) {
            for event in core.monitor.update(&update.tag, update.time_s, update.position_m)? {
                zone_events.push(Event::Zone(event));
            }
        }
    }
    for event in &out.events[mark.1..] {
        if let Event::Lifecycle {
            tag,
            time_s,
            event: LifecycleEvent::Deleted,
            ..
        } = event
        {
            for zone_event in core.monitor.remove_tag(tag, *time_s)? {
                zone_events.push(Event::Zone(zone_event));
            }
        }
    }
    out.events.extend(zone_events);
    Ok(())
}
