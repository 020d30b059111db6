//! What one scan of the anonymous tracker reports.

use std::sync::Arc;

use rtls_estimation::Gaussian;

use crate::lifecycle::{LifecycleEvent, TrackStatus};

/// The state of one track after a scan.
///
/// # Units
/// `state` is `[x, vx, y, vy]` in m and m/s, covariance in m², m²/s, m²/s²; its `time_s` is
/// the scan time, except for a lost track, which reports its last updated state (its own time).
#[derive(Debug, Clone, PartialEq)]
pub struct AnonymousTrackUpdate {
    /// `anon-1`, `anon-2`, … in creation order.
    pub track: Arc<str>,
    /// The estimate.
    pub state: Gaussian<4>,
    /// The status after the scan.
    pub status: TrackStatus,
    /// `true` when no detection updated the track in this scan (GNN: none assigned; JPDA: the
    /// probability that it was detected was below ½): the state is a prediction.
    pub predicted: bool,
}

/// What happened to a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackEventKind {
    /// A fix nobody took started the track (tentative, or confirmed at once when `M = 1`).
    Started,
    /// A lifecycle transition (confirmed, coasting, resumed, lost, recovered, deleted).
    Lifecycle(LifecycleEvent),
}

/// A track event of a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackEvent {
    /// The track.
    pub track: Arc<str>,
    /// What happened.
    pub kind: TrackEventKind,
}

/// What became of one detection.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectionFate {
    /// GNN (or JPDA's GNN fallback) gave it to this track.
    Assigned {
        /// The track it updated.
        track: Arc<str>,
    },
    /// JPDA weighed it into the update of each of these tracks with probability `β`
    /// (`1 − Σ β` is the probability that it is clutter).
    Weighted {
        /// `(track, β)` for every track whose gate it fell in.
        tracks: Vec<(Arc<str>, f64)>,
    },
    /// A range outside every gate that the manoeuvre fallback gave to the one track that can
    /// have made it, its velocity re-opened ([`ManoeuvreFallback`](super::ManoeuvreFallback)).
    Manoeuvre {
        /// The track it updated.
        track: Arc<str>,
    },
    /// A fix no track took: it started this (tentative) track.
    StartedTrack {
        /// The new track.
        track: Arc<str>,
    },
    /// A range no track took. Ranges cannot start a track (one range leaves the position on a
    /// circle), so it is counted here, never dropped silently.
    UnusedRange,
}

/// One detection's gating and fate, in the order of the scan's detections.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectionReport {
    /// Number of tracks whose χ² gate it passed (0 = gated out by every track).
    pub gated_tracks: usize,
    /// What became of it.
    pub fate: DetectionFate,
}

/// How the detections of a scan were used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DetectionCounts {
    /// Detections in the scan.
    pub total: usize,
    /// Used to update tracks ([`DetectionFate::Assigned`], [`DetectionFate::Weighted`] or
    /// [`DetectionFate::Manoeuvre`]).
    pub assigned: usize,
    /// Not used by any track: `total − assigned` (new tracks and unused ranges).
    pub unassigned: usize,
    /// Outside the gate of every track (a subset of the unassigned ones).
    pub gated_out: usize,
    /// Fixes that started a track.
    pub started_tracks: usize,
    /// Ranges no track took.
    pub unused_ranges: usize,
}

/// The output of one scan.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScanReport {
    /// The scan time, s.
    pub time_s: f64,
    /// One update per track alive after the scan, in creation order (deleted tracks are only in
    /// `events`).
    pub updates: Vec<AnonymousTrackUpdate>,
    /// Track events in track order (starts after the lifecycle events of existing tracks).
    pub events: Vec<TrackEvent>,
    /// One report per detection, in scan order.
    pub detections: Vec<DetectionReport>,
    /// Counts derived from `detections`.
    pub counts: DetectionCounts,
    /// Clusters (connected groups of tracks and detections sharing gates) in this scan, both
    /// stages (established tracks, then tentative tracks) together.
    pub clusters: usize,
    /// JPDA only: clusters associated by GNN instead, because they had more tracks than
    /// `jpda_max_cluster_tracks` or more joint events than `jpda_max_joint_events`.
    pub gnn_fallback_clusters: usize,
    /// Track–range pairs whose innovation covariance was undefined (the track on the node):
    /// treated as outside the gate.
    pub singular_pairs: usize,
    /// Ranges outside every gate given to a track by the manoeuvre fallback
    /// ([`DetectionFate::Manoeuvre`]); 0 without the fallback.
    pub manoeuvre_assigned: usize,
    /// Ranges outside every gate that several tracks could have made after a manoeuvre, with
    /// not exactly one that can have drifted that far: unused, since which track manoeuvred is
    /// unknown; 0 without the fallback.
    pub manoeuvre_ambiguous: usize,
}

impl DetectionCounts {
    /// Counts the fates of `reports`.
    pub(crate) fn of(reports: &[DetectionReport]) -> Self {
        let mut counts = Self {
            total: reports.len(),
            ..Self::default()
        };
        for report in reports {
            match report.fate {
                DetectionFate::Assigned { .. } | DetectionFate::Weighted { .. } | DetectionFate::Manoeuvre { .. } => {
                    counts.assigned += 1;
                }
                DetectionFate::StartedTrack { .. } => counts.started_tracks += 1,
                DetectionFate::UnusedRange => counts.unused_ranges += 1,
            }
            if report.gated_tracks == 0 {
                counts.gated_out += 1;
            }
        }
        counts.unassigned = counts.total - counts.assigned;
        counts
    }
}
