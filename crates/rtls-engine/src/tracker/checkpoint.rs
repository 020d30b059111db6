//! A tracker's state as a value: what a cluster node stores so that a partition it gives up
//! (or loses with the node) resumes elsewhere from that state plus the records after it,
//! instead of from the tracks' priors.
//!
//! The state is every track (filter state, lifecycle, IMM modes, heading channel, learnt range
//! offsets, adaptive noise scales, open epochs), the tracks' rewind histories, the zone
//! memberships, the re-ordering window's held records and the clocks. The site's models
//! (motion and measurement models, anchors, zones, settings) are not part of it: the tracker
//! it is restored into brings its own, built from the site. The anonymous detections'
//! multi-target front end is not part of it either; its tracks start again after a restore.

use serde::{Deserialize, Serialize};

use super::core::Core;
use super::rewind::History;
use super::tag_index::TagIndex;
use super::track::Track;
use crate::error::{EngineError, Result};
use crate::record::{Reorderer, TimeGate};
use crate::zones::monitor::Memberships;

/// Everything a [`super::Tracker`] has learnt from its records, as a value that serialises
/// (serde) and restores into a tracker of the same site ([`super::Tracker::state`],
/// [`super::Tracker::restore`]).
///
/// Its encoding is serde's data model; a format that keeps non-finite floats (the state holds
/// −∞ for "never" and NaN for "not yet"), e.g. CBOR, is needed: JSON turns them into `null`.
///
/// # Example
/// ```
/// use rtls_engine::record::parse_json_line;
/// use rtls_engine::site::Site;
/// use rtls_engine::tracker::{Output, Tracker};
/// let site = Site::from_toml_str(r#"
///     readers = [
///       { id = "A", position_m = [0.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.0 } } },
///       { id = "B", position_m = [20.0, 0.0], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.0 } } },
///     ]
///     [tracker]
///     pipeline = "fix-then-filter"
///     reorder_window_s = 0.0
/// "#, "site.toml")?;
/// let mut tracker = Tracker::new(&site)?;
/// let mut out = Output::default();
/// for t in [1.0, 2.0, 3.0] {
///     let fix = format!(r#"{{"t": {t}, "tag": "T1", "kind": "fix", "position_m": [1.0, 2.0], "covariance_m2": [0.09, 0, 0, 0.09]}}"#);
///     tracker.push(parse_json_line(&fix, "in.jsonl", 1)?, &mut out)?;
/// }
/// assert_eq!(tracker.track_count(), 1);
/// let mut resumed = Tracker::new(&site)?;
/// resumed.restore(tracker.state())?;
/// assert_eq!(resumed.track_count(), 1);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrackerState {
    pub(super) tracks: TracksState,
    pub(super) time_gate: TimeGate,
    pub(super) reorderer: Reorderer,
    pub(super) next_tick_s: Option<f64>,
    pub(super) now_s: f64,
}

/// The tracks of a 2-D (`[x, y, vx, vy]`) or a 3-D site.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) enum TracksState {
    Planar(CoreState<4>),
    Spatial(CoreState<6>),
}

/// One state size's tracks, with what their per-zone flags refer to.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct CoreState<const N: usize> {
    tracks: Vec<Track<N>>,
    /// Empty when the tracker kept none (`rewind_horizon_s` = 0).
    histories: Vec<History<N>>,
    /// The alarm zones each track's `alarmed` flags are indexed by.
    alarm_zone_ids: Vec<String>,
    memberships: Memberships,
    /// The core's count of tracks created, so a track created after the restore does not
    /// number its segments as a deleted one did (0 in a checkpoint from before it was kept:
    /// the restore then counts from the restored tracks' creation numbers).
    #[serde(default)]
    tracks_created: u64,
}

impl<const N: usize> Core<N> {
    /// This core's tracks as a value (see [`TrackerState`]).
    pub(super) fn state(&self) -> CoreState<N> {
        CoreState {
            tracks: self.tracks.clone(),
            histories: self.histories.clone(),
            alarm_zone_ids: self.shared.alarm_zones.iter().map(|zone| zone.id.clone()).collect(),
            memberships: self.monitor.memberships(),
            tracks_created: self.tracks_created,
        }
    }

    /// Replaces the tracks with a checkpoint's. Alarm flags and zone memberships follow their
    /// zone's id (a zone the checkpoint did not know starts clear). Histories are kept when
    /// this tracker rewinds (a track without one starts a fresh one), dropped when it does not.
    ///
    /// # Errors
    /// [`EngineError::Checkpoint`] when a history or a track's flags do not match its tracks,
    /// or a tag appears twice; the tracks are unchanged then.
    pub(super) fn restore(&mut self, state: CoreState<N>) -> Result<()> {
        let CoreState {
            mut tracks,
            histories,
            alarm_zone_ids,
            memberships,
            tracks_created,
        } = state;
        if !histories.is_empty() && histories.len() != tracks.len() {
            return Err(EngineError::Checkpoint(format!(
                "{} histories for {} tracks",
                histories.len(),
                tracks.len()
            )));
        }
        let index =
            TagIndex::of(&tracks).map_err(|tag| EngineError::Checkpoint(format!("the tag {tag} appears twice")))?;
        for track in &tracks {
            if track.alarmed.len() != alarm_zone_ids.len() {
                return Err(EngineError::Checkpoint(format!(
                    "the track of {} has {} alarm flags for {} alarm zones",
                    track.tag,
                    track.alarmed.len(),
                    alarm_zone_ids.len()
                )));
            }
        }
        let mut monitor = self.monitor.clone();
        monitor.restore_memberships(memberships)?;
        // each track's alarm flags follow their zone's id
        let positions: Vec<Option<usize>> = self
            .shared
            .alarm_zones
            .iter()
            .map(|zone| alarm_zone_ids.iter().position(|id| *id == zone.id))
            .collect();
        for track in &mut tracks {
            track.alarmed = positions
                .iter()
                .map(|old| old.is_some_and(|i| track.alarmed[i]))
                .collect();
        }
        self.histories = if self.shared.settings.rewind_horizon_s <= 0.0 {
            Vec::new()
        } else if histories.is_empty() {
            tracks.iter().map(History::new).collect()
        } else {
            histories
        };
        // never below a restored track's creation number (segment = creation << 32 | restarts)
        self.tracks_created = tracks
            .iter()
            .map(|track| (track.segment >> 32) + 1)
            .fold(tracks_created, u64::max);
        self.tracks = tracks;
        self.index = index;
        self.touched.clear();
        self.due.mark_all(self.tracks.len());
        self.monitor = monitor;
        Ok(())
    }
}

impl super::Tracker {
    /// What the tracker has learnt, as a value to store ([`TrackerState`]). The anonymous
    /// detections' tracks are not part of it.
    #[must_use]
    pub fn state(&self) -> TrackerState {
        TrackerState {
            tracks: match &self.tracks {
                super::Tracks::Planar(core) => TracksState::Planar(core.state()),
                super::Tracks::Spatial(core) => TracksState::Spatial(core.state()),
            },
            time_gate: self.time_gate.clone(),
            reorderer: self.reorderer.clone(),
            next_tick_s: self.next_tick_s,
            now_s: self.now_s,
        }
    }

    /// Continues from `state`, taken from a tracker of the same site ([`Self::state`]): its
    /// tracks replace this tracker's, with this tracker's models and settings (re-ordering
    /// window, time gate, zones: alarm flags and memberships follow their zone's id). The
    /// records after the state's are then pushed as usual.
    ///
    /// # Errors
    /// [`EngineError::Checkpoint`] for a state of the other dimension (2-D against 3-D) or an
    /// inconsistent one; the tracker is unchanged then.
    pub fn restore(&mut self, state: TrackerState) -> Result<()> {
        if !state.now_s.is_finite() && state.now_s != f64::NEG_INFINITY {
            return Err(EngineError::Checkpoint(format!("the clock is {}", state.now_s)));
        }
        match (&mut self.tracks, state.tracks) {
            (super::Tracks::Planar(core), TracksState::Planar(tracks)) => core.restore(tracks)?,
            (super::Tracks::Spatial(core), TracksState::Spatial(tracks)) => core.restore(tracks)?,
            (super::Tracks::Planar(_), TracksState::Spatial(_)) => {
                return Err(EngineError::Checkpoint("3-D tracks for a 2-D site".into()))
            }
            (super::Tracks::Spatial(_), TracksState::Planar(_)) => {
                return Err(EngineError::Checkpoint("2-D tracks for a 3-D site".into()))
            }
        }
        self.time_gate.resume(state.time_gate);
        self.reorderer.resume(state.reorderer);
        self.next_tick_s = state.next_tick_s;
        self.now_s = state.now_s;
        Ok(())
    }
}
