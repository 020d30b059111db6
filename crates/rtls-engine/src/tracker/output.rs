//! What the tracker reports: track updates and events, and their JSON Lines form.

use super::noise::Innovations;
use std::sync::Arc;

use serde_json::{json, Map, Value};

use crate::lifecycle::{LifecycleEvent, TrackStatus};
use crate::zones::ZoneEvent;

/// What produced a track update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum UpdateSource {
    /// A position fix: solved from an epoch's anchor measurements (fix-then-filter), from a
    /// fingerprint scan, or a `fix` record.
    Fix,
    /// Raw anchor measurements (ranges, RSSI, TDOA) in the tightly coupled filter.
    Anchors,
    /// A velocity or odometry measurement.
    Velocity,
    /// No measurement: the prediction while the track coasts (seed 000's gap filling).
    Prediction,
}

impl UpdateSource {
    /// The name written in the `source` field.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Fix => "fix",
            Self::Anchors => "anchors",
            Self::Velocity => "velocity",
            Self::Prediction => "prediction",
        }
    }
}

/// One reported track state.
///
/// # Units
/// Time in s, positions in m, velocities in m/s, the position covariance in m² (row-major
/// `D × D`, `D` = [`TrackUpdate::dimensions`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackUpdate {
    /// Time of the state, s.
    pub time_s: f64,
    /// Tag id.
    pub tag: Arc<str>,
    /// Tracked dimensions `D` (2 or 3).
    pub dimensions: usize,
    /// Position `[x, y, z]`, m (`z` is the configured tag height, or 0, in 2-D).
    pub position_m: [f64; 3],
    /// Velocity `[vx, vy, vz]`, m/s (`vz` = 0 in 2-D).
    pub velocity_mps: [f64; 3],
    /// Position covariance, `D × D` row-major in the first `D²` entries, m².
    pub position_covariance_m2: [f64; 9],
    /// `true` when no measurement supports this time: the prediction of a coasting track.
    pub predicted: bool,
    /// The track's status after this update.
    pub status: TrackStatus,
    /// What produced it.
    pub source: UpdateSource,
    /// Under `motion_model = "imm"` (or "ct"): the most probable motion mode ("CV", "CA", "CT").
    pub mode: Option<&'static str>,
    /// `true` when this update replaces one already reported for the same or a later time:
    /// a late record was re-filtered (`tracker.rewind_horizon_s`), or a record with the time
    /// of an update already published arrived after it.
    pub revised: bool,
    /// `true` when the state was smoothed over the later measurements of its track
    /// ([`super::Smoother`], `rtls track --smooth`): not what a live tracker knew at the time.
    pub smoothed: bool,
}

/// The name of a track status as written in JSON.
#[must_use]
pub fn status_name(status: TrackStatus) -> &'static str {
    match status {
        TrackStatus::Tentative => "tentative",
        TrackStatus::Confirmed => "confirmed",
        TrackStatus::Coasting => "coasting",
        TrackStatus::Lost => "lost",
        TrackStatus::Deleted => "deleted",
    }
}

fn lifecycle_name(event: LifecycleEvent) -> &'static str {
    match event {
        LifecycleEvent::Confirmed => "confirmed",
        LifecycleEvent::StartedCoasting => "started-coasting",
        LifecycleEvent::Resumed => "resumed",
        LifecycleEvent::Lost => "lost",
        LifecycleEvent::Recovered => "recovered",
        LifecycleEvent::Deleted => "deleted",
        LifecycleEvent::Jumped => "jumped",
        LifecycleEvent::Alternating => "alternating",
    }
}

impl TrackUpdate {
    /// The update as one JSON object on one line:
    /// `{"t","tag","x","y"[,"z"],"vx","vy"[,"vz"],"cov":[D² entries],"predicted","status","source"[,"mode"][,"revised"][,"smoothed"]}`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::lifecycle::TrackStatus;
    /// use rtls_engine::tracker::{TrackUpdate, UpdateSource};
    /// let update = TrackUpdate {
    ///     time_s: 2.0, tag: "w1".into(), dimensions: 2,
    ///     position_m: [1.0, 2.0, 0.0], velocity_mps: [0.5, 0.0, 0.0],
    ///     position_covariance_m2: [0.04, 0.0, 0.0, 0.04, 0.0, 0.0, 0.0, 0.0, 0.0],
    ///     predicted: false, status: TrackStatus::Confirmed, source: UpdateSource::Fix,
    ///     mode: None, revised: false, smoothed: false,
    /// };
    /// let value: serde_json::Value = serde_json::from_str(&update.to_json_line()).unwrap();
    /// assert_eq!(value["cov"].as_array().unwrap().len(), 4);
    /// assert!(value.get("z").is_none());
    /// ```
    #[must_use]
    pub fn to_json_line(&self) -> String {
        let d = self.dimensions;
        // written straight from the fields, keys in the order a JSON object map sorts them
        // (as the other lines of a track file): no map is built per update, the server's hot path
        let line = TrackLine {
            cov: &self.position_covariance_m2[..d * d],
            mode: self.mode,
            predicted: self.predicted,
            revised: self.revised.then_some(true),
            smoothed: self.smoothed.then_some(true),
            source: self.source.name(),
            status: status_name(self.status),
            t: self.time_s,
            tag: &self.tag,
            vx: self.velocity_mps[0],
            vy: self.velocity_mps[1],
            vz: (d == 3).then_some(self.velocity_mps[2]),
            x: self.position_m[0],
            y: self.position_m[1],
            z: (d == 3).then_some(self.position_m[2]),
        };
        serde_json::to_string(&line).unwrap_or_else(|error| unreachable!("a track line always serialises: {error}"))
    }
}

/// A track-file line as written ([`TrackUpdate::to_json_line`]); non-finite numbers are `null`.
#[derive(serde::Serialize)]
struct TrackLine<'a> {
    cov: &'a [f64],
    #[serde(skip_serializing_if = "Option::is_none")]
    mode: Option<&'static str>,
    predicted: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    revised: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    smoothed: Option<bool>,
    source: &'static str,
    status: &'static str,
    t: f64,
    tag: &'a str,
    vx: f64,
    vy: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    vz: Option<f64>,
    x: f64,
    y: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    z: Option<f64>,
}

/// The keys every track-file line starts with: `t`, `tag`, `x`, `y` and, in 3-D, `z`.
fn located(time_s: f64, tag: &str, dimensions: usize, position_m: &[f64; 3]) -> Map<String, Value> {
    let mut object = Map::new();
    object.insert("t".into(), json!(time_s));
    object.insert("tag".into(), json!(tag));
    object.insert("x".into(), json!(position_m[0]));
    object.insert("y".into(), json!(position_m[1]));
    if dimensions == 3 {
        object.insert("z".into(), json!(position_m[2]));
    }
    object
}

/// A raw position fix of the fix-then-filter pipeline, before the filter (for evaluation).
#[derive(Debug, Clone, PartialEq)]
pub struct RawFix {
    /// Time of the fix, s.
    pub time_s: f64,
    /// Tag id.
    pub tag: Arc<str>,
    /// Dimensions (2 or 3).
    pub dimensions: usize,
    /// Position, m (`z` = 0 in 2-D).
    pub position_m: [f64; 3],
    /// Covariance, `D × D` row-major in the first `D²` entries, m².
    pub covariance_m2: [f64; 9],
    /// How an epoch fix was made (`gauss-newton`, `gauss-newton-from-centroid`,
    /// `weighted-centroid`, `tdoa`, `pseudorange`); `None` for other fixes (fingerprints).
    pub method: Option<&'static str>,
}

impl RawFix {
    /// The fix as a JSON line in the track-file shape (`t`, `tag`, `x`, `y`[, `z`], `cov`,
    /// `predicted: false`, `source: "raw-fix"`, and `method` when known), so `rtls eval` reads
    /// it like a track file.
    #[must_use]
    pub fn to_json_line(&self) -> String {
        let d = self.dimensions;
        let mut object = located(self.time_s, &self.tag, d, &self.position_m);
        object.insert("cov".into(), json!(&self.covariance_m2[..d * d]));
        object.insert("predicted".into(), json!(false));
        object.insert("source".into(), json!("raw-fix"));
        if let Some(method) = self.method {
            object.insert("method".into(), json!(method));
        }
        Value::Object(object).to_string()
    }
}

/// Something worth reporting besides a track update.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// Zone enter / exit / dwell.
    Zone(ZoneEvent),
    /// A track changed status (confirmed, coasting, lost with its last position, deleted, …).
    Lifecycle {
        /// Tag id.
        tag: Arc<str>,
        /// Time, s.
        time_s: f64,
        /// What happened.
        event: LifecycleEvent,
        /// The track's position at that moment (the last estimate when lost), m.
        position_m: [f64; 3],
    },
    /// Seed 000's predictive alarm: the tag's predicted path enters a hazard zone (or an area
    /// without a working reader) within the horizon.
    HazardPredicted {
        /// Tag id.
        tag: Arc<str>,
        /// Zone id.
        zone: String,
        /// Time the alarm was raised, s.
        time_s: f64,
        /// Predicted time until the entry probability first reaches the threshold, s.
        time_to_entry_s: f64,
        /// The entry probability at that time.
        probability: f64,
    },
    /// A predictive alarm no longer holds (the prediction no longer enters the zone).
    HazardCleared {
        /// Tag id.
        tag: Arc<str>,
        /// Zone id.
        zone: String,
        /// Time, s.
        time_s: f64,
    },
    /// A tag entered a zone in which no listed reader works: it is not covered there.
    NoCoverage {
        /// Tag id.
        tag: Arc<str>,
        /// Zone id.
        zone: String,
        /// Time, s.
        time_s: f64,
    },
    /// Under `motion_model = "imm"`: another motion mode became the most probable one (a
    /// manoeuvre began or ended).
    ModelSwitch {
        /// Tag id.
        tag: Arc<str>,
        /// Time, s.
        time_s: f64,
        /// The mode reported until now.
        from: &'static str,
        /// The mode reported from now on.
        to: &'static str,
        /// Its probability `μ`.
        probability: f64,
    },
    /// `[scheduling]` (seed 003): a track's readers for the next cycle changed — its task
    /// nodes and, near a cell border, the neighbouring cell's monitors. Only these need wake.
    Schedule {
        /// Tag id.
        tag: Arc<str>,
        /// Time, s.
        time_s: f64,
        /// Task nodes (reader ids), nearest first.
        task_nodes: Vec<Arc<str>>,
        /// Edge monitors (reader ids) that are not task nodes.
        monitors: Vec<Arc<str>>,
    },
    /// A record arrived later than the re-ordering window allows; it was not applied.
    Late {
        /// Tag id.
        tag: Arc<str>,
        /// The record's time, s.
        time_s: f64,
        /// The record's kind.
        kind: &'static str,
        /// How far behind the newest record it was, s.
        lateness_s: f64,
    },
    /// A measurement was not applied, and why (unknown or broken reader, outside the
    /// validation gate, no radio map, an epoch that could not be solved, a failed update).
    Rejected {
        /// Tag id.
        tag: Arc<str>,
        /// The measurement's time, s.
        time_s: f64,
        /// The measurement's kind.
        kind: &'static str,
        /// Why.
        reason: String,
    },
}

impl Event {
    /// The event's time, s.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::tracker::Event;
    /// let event = Event::NoCoverage { tag: "m7".into(), zone: "collapse".into(), time_s: 12.0 };
    /// assert_eq!(event.time_s(), 12.0);
    /// ```
    #[must_use]
    pub fn time_s(&self) -> f64 {
        match self {
            Self::Zone(zone_event) => zone_event.time_s(),
            Self::Lifecycle { time_s, .. }
            | Self::HazardPredicted { time_s, .. }
            | Self::HazardCleared { time_s, .. }
            | Self::NoCoverage { time_s, .. }
            | Self::ModelSwitch { time_s, .. }
            | Self::Schedule { time_s, .. }
            | Self::Late { time_s, .. }
            | Self::Rejected { time_s, .. } => *time_s,
        }
    }

    /// The event as one JSON line with a `type` field: `zone-enter`, `zone-exit`, `zone-dwell`,
    /// `lifecycle`, `hazard-predicted`, `hazard-cleared`, `no-coverage`, `model-switch`,
    /// `schedule`, `late`, `rejected`.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::tracker::Event;
    /// let event = Event::NoCoverage { tag: "m7".into(), zone: "collapse".into(), time_s: 12.0 };
    /// let value: serde_json::Value = serde_json::from_str(&event.to_json_line()).unwrap();
    /// assert_eq!(value["type"], "no-coverage");
    /// ```
    #[must_use]
    pub fn to_json_line(&self) -> String {
        let value = match self {
            Self::Zone(ZoneEvent::Enter { tag, zone, time_s }) => {
                json!({"type": "zone-enter", "t": time_s, "tag": tag, "zone": zone})
            }
            Self::Zone(ZoneEvent::Exit { tag, zone, time_s }) => {
                json!({"type": "zone-exit", "t": time_s, "tag": tag, "zone": zone})
            }
            Self::Zone(ZoneEvent::Dwell {
                tag,
                zone,
                time_s,
                dwell_s,
            }) => json!({"type": "zone-dwell", "t": time_s, "tag": tag, "zone": zone, "dwell_s": dwell_s}),
            Self::Lifecycle {
                tag,
                time_s,
                event,
                position_m,
            } => json!({"type": "lifecycle", "t": time_s, "tag": &**tag, "event": lifecycle_name(*event),
                        "x": position_m[0], "y": position_m[1], "z": position_m[2]}),
            Self::HazardPredicted {
                tag,
                zone,
                time_s,
                time_to_entry_s,
                probability,
            } => json!({"type": "hazard-predicted", "t": time_s, "tag": &**tag, "zone": zone,
                        "time_to_entry_s": time_to_entry_s, "probability": probability}),
            Self::HazardCleared { tag, zone, time_s } => {
                json!({"type": "hazard-cleared", "t": time_s, "tag": &**tag, "zone": zone})
            }
            Self::NoCoverage { tag, zone, time_s } => {
                json!({"type": "no-coverage", "t": time_s, "tag": &**tag, "zone": zone})
            }
            Self::Schedule {
                tag,
                time_s,
                task_nodes,
                monitors,
            } => {
                let task_nodes: Vec<&str> = task_nodes.iter().map(|n| &**n).collect();
                let monitors: Vec<&str> = monitors.iter().map(|n| &**n).collect();
                json!({"type": "schedule", "t": time_s, "tag": &**tag, "task_nodes": task_nodes,
                       "monitors": monitors})
            }
            Self::ModelSwitch {
                tag,
                time_s,
                from,
                to,
                probability,
            } => {
                json!({"type": "model-switch", "t": time_s, "tag": &**tag, "from": from, "to": to,
                       "probability": probability})
            }
            Self::Late {
                tag,
                time_s,
                kind,
                lateness_s,
            } => json!({"type": "late", "t": time_s, "tag": &**tag, "kind": kind, "lateness_s": lateness_s}),
            Self::Rejected {
                tag,
                time_s,
                kind,
                reason,
            } => json!({"type": "rejected", "t": time_s, "tag": &**tag, "kind": kind, "reason": reason}),
        };
        value.to_string()
    }
}

/// What one call into the tracker produced, in time order of processing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Output {
    /// Track updates.
    pub updates: Vec<TrackUpdate>,
    /// Events.
    pub events: Vec<Event>,
    /// Raw fixes of the fix-then-filter pipeline (before filtering).
    pub fixes: Vec<RawFix>,
    /// Innovation totals per measurement class of the updates computed since the last
    /// [`Output::clear`] (a consumer that clears adds them up with [`Innovations::merge`]).
    pub innovations: Innovations,
    /// The whole filtered state behind each track update, for a smoother
    /// ([`super::Smoother`]); `None` (nothing kept, nothing copied) unless the output was
    /// made by [`Output::keeping_states`].
    pub states: Option<Vec<ReportedState>>,
}

/// The whole filtered state (CV layout `[x, vx, y, vy(, z, vz)]`) behind one track update of
/// an [`Output`], kept for the smoother ([`super::Smoother`]).
///
/// # Units
/// Means in m and m/s, covariance entries in m², m²/s and m²/s².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReportedState {
    /// Index of its update in [`Output::updates`].
    pub update: usize,
    /// Which start of the track it descends from: every (re)start of a track from a fix (its
    /// first, a re-acquisition, a jump) begins a new segment, and a smoother does not cross
    /// one.
    pub segment: u64,
    /// The mean, first `N` entries (`N` = 2 × the update's
    /// [`dimensions`](TrackUpdate::dimensions)).
    pub mean: [f64; 6],
    /// The covariance, `N × N` in the first `N²` entries (symmetric: row- and column-major
    /// agree).
    pub covariance: [f64; 36],
    /// What the measurements since the track's previous reported state added, in information
    /// form: `J = P⁺⁻¹ − P⁻⁻¹` (`N × N` in the first `N²` entries; 0 for a prediction or a
    /// track's first state) …
    pub information: [f64; 36],
    /// … and `j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻` (first `N` entries), summed over those updates.
    pub information_vector: [f64; 6],
    /// Whether one of those updates told more than `information` says (one correlated with
    /// states outside the CV layout — a speed whose heading's drift is considered, a range
    /// whose offset is —, one predicted with an accelerometer's control input, or the IMM's
    /// mixture), or a constraint moved the state since (silent readers, the corridors, the
    /// speed limit).
    pub partial_information: bool,
    /// A track whose motion model has the turn rate as a state (`motion_model = "ct"`): its
    /// whole state `[x, vx, y, vy, ω]`, so the smoother's backward pass follows the turn.
    pub turn: Option<TurnState>,
}

/// The whole state of a coordinated-turn track, `[x, vx, y, vy, ω]` (m, m/s, rad/s), and its
/// covariance (5 × 5, symmetric).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnState {
    /// The mean.
    pub mean: [f64; 5],
    /// The covariance (row- and column-major agree).
    pub covariance: [f64; 25],
}

impl TurnState {
    /// The single coordinated-turn mode of `modes`, when that is what they are.
    pub(super) fn of(modes: Option<&rtls_estimation::imm::ImmState>) -> Option<Self> {
        let [estimate] = modes?.estimates() else {
            return None;
        };
        (estimate.mean.len() == 5 && estimate.covariance.len() == 25).then(|| {
            let mut turn = Self {
                mean: [0.0; 5],
                covariance: [0.0; 25],
            };
            turn.mean.copy_from_slice(estimate.mean.as_slice());
            turn.covariance.copy_from_slice(estimate.covariance.as_slice());
            turn
        })
    }
}

impl Output {
    /// An empty output that also keeps the whole state behind each track update
    /// ([`Output::states`]), for [`super::Smoother`].
    #[must_use]
    pub fn keeping_states() -> Self {
        Self {
            states: Some(Vec::new()),
            ..Self::default()
        }
    }

    /// Empties all lists, keeping their capacity (and whether states are kept), and zeroes
    /// the innovation totals.
    pub fn clear(&mut self) {
        self.updates.clear();
        self.events.clear();
        self.fixes.clear();
        if let Some(states) = self.states.as_mut() {
            states.clear();
        }
        self.innovations = Innovations::default();
    }

    /// `true` when nothing was produced.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.updates.is_empty() && self.events.is_empty() && self.fixes.is_empty()
    }
}

/// An epoch's raw fix, naming the solver's method.
pub(super) fn epoch_raw_fix(
    tag: &Arc<str>,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
    method: &'static str,
) -> RawFix {
    RawFix {
        method: Some(method),
        ..raw_fix(tag, time_s, position, covariance)
    }
}

pub(super) fn raw_fix(tag: &Arc<str>, time_s: f64, position: &[f64], covariance: &[f64]) -> RawFix {
    let mut position_m = [0.0; 3];
    position_m[..position.len()].copy_from_slice(position);
    let mut covariance_m2 = [0.0; 9];
    covariance_m2[..covariance.len()].copy_from_slice(covariance);
    RawFix {
        time_s,
        tag: Arc::clone(tag),
        dimensions: position.len(),
        position_m,
        covariance_m2,
        method: None,
    }
}
