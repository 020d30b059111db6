//! The anonymous multi-target tracker: predict, gate, associate (GNN or JPDA), update, start
//! and retire tracks, one scan at a time.

use std::sync::Arc;

use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::stats::ChiSquareGate;
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::associate::{Decisions, Scan, TrackChange};
use super::detection::{Detection, DetectionKind};
use super::gating::{gate, NearPair};
use super::manoeuvre::{Candidate, Choice, ManoeuvreFallback};
use super::report::{
    AnonymousTrackUpdate, DetectionCounts, DetectionFate, DetectionReport, ScanReport, TrackEvent, TrackEventKind,
};
use super::settings::AnonymousTrackerSettings;
use crate::error::{EngineError, Result};
use crate::lifecycle::{Lifecycle, TrackStatus};

/// One anonymous track: a CV state `[x, vx, y, vy]` and its lifecycle.
#[derive(Debug, Clone, PartialEq)]
pub struct AnonymousTrack {
    id: Arc<str>,
    /// The latest estimate (posterior, or prediction when not updated).
    state: Gaussian<4>,
    /// The posterior of the last update (what a lost track reports).
    last_update: Gaussian<4>,
    lifecycle: Lifecycle,
}

impl AnonymousTrack {
    /// `anon-1`, `anon-2`, … in creation order.
    #[must_use]
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The latest estimate at the last scan time (`[x, vx, y, vy]`, m and m/s).
    #[must_use]
    pub fn state(&self) -> &Gaussian<4> {
        &self.state
    }

    /// The posterior of the last update.
    #[must_use]
    pub fn last_update(&self) -> &Gaussian<4> {
        &self.last_update
    }

    /// The lifecycle status.
    #[must_use]
    pub fn status(&self) -> TrackStatus {
        self.lifecycle.status()
    }
}

/// Tracks any number of targets from detections that carry no identity: position fixes and
/// ranges from known nodes (seed 003's ultrasonic echoes).
///
/// Each scan (one sensor's detections at one time; each target gives at most one detection per
/// scan, so several nodes firing at once are successive scans with the same time stamp):
/// 1. every track is predicted to the scan time (CV model, KF);
/// 2. each detection is gated against each prediction: `d² = νᵀ S⁻¹ ν ≤ χ²_{P_G}(m)`;
/// 3. established tracks (confirmed, coasting, lost) are associated first, then tentative
///    tracks with the detections left over (priority to established tracks: a detection the
///    established track explains must not feed a duplicate started next to it after one
///    detection fell outside the gate). In each stage, tracks and detections sharing gates form
///    clusters, each associated on its own:
///    - GNN: the assignment minimising `Σ (d² + ln |S|)` over assigned pairs plus
///      `c₀ = −2 ln λ − m ln 2π + 2 ln P_D − 2 ln(1 − P_D P_G)` per unassigned detection
///      ([`solve_assignment`](super::solve_assignment)); `d² + ln |S| = −2 ln N(ν; 0, S) − m ln 2π`, so this is the
///      most likely joint event of the JPDA, and a detection is assigned only where its
///      likelihood ratio against clutter exceeds 1;
///    - JPDA: every gated detection updates the track, weighted by its marginal association
///      probability ([`jpda_marginals`](super::jpda_marginals)); a cluster with more than `jpda_max_cluster_tracks`
///      tracks or `jpda_max_joint_events` events is associated by GNN (counted in
///      [`ScanReport::gnn_fallback_clusters`]);
/// 4. fixes update by the KF, ranges by the EKF (`H = [(x − aₓ)/d, 0, (y − a_y)/d, 0]`);
///    A range with a [`FieldOfView`](super::FieldOfView) is gated only against the tracks
///    predicted inside it. With a [`ManoeuvreFallback`](super::ManoeuvreFallback), a range
///    outside every gate then goes to the one established track that can have made it after a
///    manoeuvre (if no gated detection updated that track), its velocity re-opened;
/// 5. a fix no track took starts a tentative track at the fix with zero velocity (velocity
///    σ `initial_velocity_std_mps`), named `anon-<n>` in creation order. **Ranges alone cannot
///    start a track** (a range leaves the position on a circle): an untaken range is reported
///    as [`DetectionFate::UnusedRange`], never dropped silently. Under JPDA a detection inside
///    any gate is weighed into that cluster's tracks, so only fixes outside every gate start
///    tracks;
/// 6. the [`Lifecycle`] of each track moves on: updated tracks (JPDA: detection probability
///    `1 − β₀ ≥ ½`) count towards M-of-N confirmation or resume; the others coast, are lost
///    (reporting their last updated state) and deleted after the timeouts.
///
/// Tracks of targets whose start is known are seeded, confirmed, with
/// [`AnonymousTracker::seed_track`]; [`AnonymousTracker::predict_tracks`] looks ahead without
/// changing them.
///
/// Seed 003's limit ① — several robots in one grid cell could not be told apart — is what the
/// association removes: once tracks exist (from fixes, or seeded), each anonymous range goes to
/// the track it fits. Seed 003's reproduction (`rtls repro wsn-ekf`, "ours") runs on this
/// tracker: seeded robots, each firing instant's echoes one scan, sonar sectors as fields of
/// view, the manoeuvre fallback on.
///
/// # Errors
/// [`AnonymousTracker::new`] rejects invalid settings; [`AnonymousTracker::process_scan`]
/// returns an error, and leaves the tracker as it was, for a scan time that is not finite or
/// earlier than the previous scan, or when a filter step fails numerically.
///
/// # Example
/// Two targets 1 m apart moving at 0.2 m/s: fixes every 0.5 s start and confirm two tracks,
/// then one node's two anonymous ranges update them.
/// ```
/// use rtls_engine::association::{AnonymousTracker, AnonymousTrackerSettings, Detection, DetectionFate};
/// use rtls_engine::lifecycle::TrackStatus;
/// let truth = |t: f64| [[0.2 * t, 0.0], [1.0 + 0.2 * t, 1.0]];
/// let mut tracker = AnonymousTracker::new(AnonymousTrackerSettings::default())?;
/// let cov = [[0.01, 0.0], [0.0, 0.01]];
/// for k in 0..4 {
///     let t = 0.5 * k as f64;
///     let [a, b] = truth(t);
///     let report = tracker.process_scan(t, &[Detection::fix(a, cov)?, Detection::fix(b, cov)?])?;
///     assert_eq!(report.updates.len(), 2);
/// }
/// assert!(tracker.tracks().iter().all(|t| t.status() == TrackStatus::Confirmed));
/// let node = [3.0, 0.0];
/// let range = |p: [f64; 2]| (p[0] - node[0]).hypot(p[1] - node[1]);
/// let [a, b] = truth(2.0);
/// // the ranges arrive in any order and carry no identity
/// let ranges = [Detection::range(node, range(b), 0.0004)?, Detection::range(node, range(a), 0.0004)?];
/// let report = tracker.process_scan(2.0, &ranges)?;
/// assert_eq!(report.counts.assigned, 2);
/// assert_eq!(report.detections[0].fate, DetectionFate::Assigned { track: "anon-2".into() });
/// assert_eq!(tracker.tracks()[0].id(), "anon-1");
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Y. Bar-Shalom, T. E. Fortmann, *Tracking and Data Association*, 1988 (gating, GNN, JPDA);
/// S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, 1999, §6
/// (assignment cost as a log-likelihood ratio) and §3.2 (M-of-N); R. Jonker, A. Volgenant,
/// 1987 (assignment); seed 003 eq. (6)–(8) and its limit ①.
#[derive(Debug, Clone)]
pub struct AnonymousTracker {
    settings: AnonymousTrackerSettings,
    motion: ConstantVelocity,
    /// `χ²_{P_G}(1)`, `χ²_{P_G}(2)`.
    gates: [f64; 2],
    tracks: Vec<AnonymousTrack>,
    next_id: u64,
    last_scan_s: Option<f64>,
}

impl AnonymousTracker {
    /// A tracker with no tracks.
    ///
    /// # Errors
    /// The errors of [`AnonymousTrackerSettings::validate`].
    pub fn new(settings: AnonymousTrackerSettings) -> Result<Self> {
        settings.validate()?;
        let sigma_a = settings.acceleration_noise_std_mps2;
        let noise = match settings.acceleration_psd_m2ps3 {
            Some(q) => ProcessNoise::continuous(q),
            None => ProcessNoise::discrete(sigma_a * sigma_a, NoiseGain::kinematic()),
        };
        let motion = ConstantVelocity::new(noise)?;
        let gate = ChiSquareGate::new(settings.gate_probability)?;
        Ok(Self {
            settings,
            motion,
            gates: [gate.threshold(1)?, gate.threshold(2)?],
            tracks: Vec::new(),
            next_id: 1,
            last_scan_s: None,
        })
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &AnonymousTrackerSettings {
        &self.settings
    }

    /// The live tracks, in creation order.
    #[must_use]
    pub fn tracks(&self) -> &[AnonymousTrack] {
        &self.tracks
    }

    /// Processes one scan of `detections` taken at `time_s` (s): see the type documentation.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`time_s`) for a non-finite time or one before the
    /// previous scan; [`EngineError::Estimation`] when a filter step fails. The tracker is
    /// unchanged after an error.
    pub fn process_scan(&mut self, time_s: f64, detections: &[Detection]) -> Result<ScanReport> {
        if !time_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "a scan time must be finite",
            });
        }
        if self.last_scan_s.is_some_and(|last| time_s < last) {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "time went backwards: scans must come in time order",
            });
        }
        let kf = KalmanFilter::default();
        let priors = self
            .tracks
            .iter()
            .map(|track| kf.predict(&track.state, &self.motion, time_s))
            .collect::<rtls_estimation::Result<Vec<_>>>()?;
        let margin_m = self.settings.manoeuvre.map_or(0.0, |m| m.margin_m);
        let gating = gate(&priors, detections, self.gates, margin_m);
        let mut gated_tracks = vec![0usize; detections.len()];
        for pair in &gating.pairs {
            gated_tracks[pair.detection] += 1;
        }

        // Work out every change before touching the tracks, so an error leaves them as they were.
        let ids: Vec<Arc<str>> = self.tracks.iter().map(|track| Arc::clone(&track.id)).collect();
        let established: Vec<bool> = self
            .tracks
            .iter()
            .map(|t| t.status() != TrackStatus::Tentative)
            .collect();
        let scan = Scan {
            settings: &self.settings,
            priors: &priors,
            ids: &ids,
            established: &established,
            pairs: &gating.pairs,
            detections,
        };
        let mut decisions = Decisions {
            changes: vec![None; priors.len()],
            fates: vec![None; detections.len()],
        };
        let cluster_counts = scan.associate(&mut decisions)?;
        let manoeuvres = match &self.settings.manoeuvre {
            Some(fallback) => {
                let last_update_s: Vec<f64> = self.tracks.iter().map(|t| t.lifecycle.last_update_s()).collect();
                let ungated = Ungated {
                    fallback,
                    time_s,
                    priors: &priors,
                    ids: &ids,
                    established: &established,
                    last_update_s: &last_update_s,
                    gated_tracks: &gated_tracks,
                    near: &gating.near,
                    detections,
                };
                ungated.fall_back(&mut decisions)?
            }
            None => ManoeuvreCounts::default(),
        };
        let Decisions { changes, fates } = decisions;

        // Untaken fixes start tracks; untaken ranges are reported.
        let mut started: Vec<AnonymousTrack> = Vec::new();
        let mut next_id = self.next_id;
        let mut reports: Vec<DetectionReport> = Vec::with_capacity(detections.len());
        for ((detection, fate), gated_tracks) in detections.iter().zip(fates).zip(gated_tracks) {
            let fate = match (fate, detection.kind()) {
                (Some(fate), _) => fate,
                (
                    None,
                    DetectionKind::Fix {
                        position_m,
                        covariance_m2,
                    },
                ) => {
                    let track = self.start_track(next_id, time_s, *position_m, *covariance_m2)?;
                    next_id += 1;
                    let id = Arc::clone(&track.id);
                    started.push(track);
                    DetectionFate::StartedTrack { track: id }
                }
                (None, DetectionKind::Range { .. }) => DetectionFate::UnusedRange,
            };
            reports.push(DetectionReport { gated_tracks, fate });
        }

        // Apply. The lifecycle calls cannot fail here: the time was checked above and deleted
        // tracks are removed at the end of every scan.
        let mut events = Vec::new();
        let mut updated = vec![false; priors.len()];
        for ((track, prior), (change, updated)) in self
            .tracks
            .iter_mut()
            .zip(priors)
            .zip(changes.into_iter().zip(updated.iter_mut()))
        {
            let event = match change {
                Some(change) => {
                    track.state = change.state;
                    if change.detected {
                        track.last_update = change.state;
                        *updated = true;
                        track.lifecycle.update(time_s)?
                    } else {
                        track.lifecycle.tick(time_s)?
                    }
                }
                None => {
                    track.state = prior;
                    track.lifecycle.tick(time_s)?
                }
            };
            if let Some(event) = event {
                events.push(TrackEvent {
                    track: Arc::clone(&track.id),
                    kind: TrackEventKind::Lifecycle(event),
                });
            }
        }
        let mut was_updated: Vec<bool> = self
            .tracks
            .iter()
            .zip(updated)
            .filter(|(track, _)| track.status() != TrackStatus::Deleted)
            .map(|(_, updated)| updated)
            .collect();
        self.tracks.retain(|track| track.status() != TrackStatus::Deleted);
        for track in started {
            events.push(TrackEvent {
                track: Arc::clone(&track.id),
                kind: TrackEventKind::Started,
            });
            self.tracks.push(track);
            was_updated.push(true);
        }
        self.next_id = next_id;
        self.last_scan_s = Some(time_s);

        let updates = self
            .tracks
            .iter()
            .zip(&was_updated)
            .map(|(track, &updated)| AnonymousTrackUpdate {
                track: Arc::clone(&track.id),
                state: if track.status() == TrackStatus::Lost {
                    track.last_update
                } else {
                    track.state
                },
                status: track.status(),
                predicted: !updated,
            })
            .collect();
        Ok(ScanReport {
            time_s,
            updates,
            events,
            counts: DetectionCounts::of(&reports),
            detections: reports,
            clusters: cluster_counts.clusters,
            gnn_fallback_clusters: cluster_counts.gnn_fallbacks,
            singular_pairs: gating.singular_pairs,
            manoeuvre_assigned: manoeuvres.assigned,
            manoeuvre_ambiguous: manoeuvres.ambiguous,
        })
    }

    /// Starts a confirmed track `id` at a known `state` (`[x, vx, y, vy]` at its time,
    /// m and m/s): a target whose start is known (robots placed at known positions, a track
    /// handed over by another tracker), which ranges alone could not start. The track is
    /// confirmed at once (no M-of-N), then coasts, is lost and deleted like any other; it is
    /// associated like any established track. The tracker's clock moves to the state's time:
    /// later scans must not be earlier.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `id` for an empty id, one in use by a live
    /// track or one of the form `anon-…` (reserved for tracks the tracker starts), or `time_s`
    /// for a state earlier than the last scan. The tracker is unchanged after an error.
    ///
    /// # Example
    /// Two robots at known starts; an anonymous range from a node updates the one it fits.
    /// ```
    /// use rtls_engine::association::{AnonymousTracker, AnonymousTrackerSettings, Detection, DetectionFate};
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// let p0 = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.01, 0.01, 0.01, 0.01));
    /// let mut tracker = AnonymousTracker::new(AnonymousTrackerSettings::default())?;
    /// tracker.seed_track("robot-0", Gaussian::new(Vector::<4>::new(1.0, 0.0, 1.0, 0.0), p0, 0.0)?)?;
    /// tracker.seed_track("robot-1", Gaussian::new(Vector::<4>::new(3.0, 0.0, 1.0, 0.0), p0, 0.0)?)?;
    /// assert!(tracker.seed_track("robot-1", Gaussian::new(Vector::<4>::zeros(), p0, 0.0)?).is_err());
    /// let report = tracker.process_scan(0.1, &[Detection::range([4.0, 1.0], 1.01, 0.0009)?])?;
    /// assert_eq!(report.detections[0].fate, DetectionFate::Assigned { track: "robot-1".into() });
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn seed_track(&mut self, id: impl Into<Arc<str>>, state: Gaussian<4>) -> Result<()> {
        let id: Arc<str> = id.into();
        if id.is_empty() || id.starts_with("anon-") || self.tracks.iter().any(|t| t.id == id) {
            return Err(EngineError::InvalidParameter {
                name: "id",
                reason: "a seeded track needs a non-empty id not in use and not of the form anon-<n> \
                         (reserved for the tracks the tracker starts)",
            });
        }
        let time_s = state.time_s();
        if self.last_scan_s.is_some_and(|last| time_s < last) {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "time went backwards: a seeded state must not be earlier than the last scan",
            });
        }
        let lifecycle = Lifecycle::confirmed(self.settings.lifecycle, time_s)?;
        self.tracks.push(AnonymousTrack {
            id,
            state,
            last_update: state,
            lifecycle,
        });
        self.last_scan_s = Some(self.last_scan_s.map_or(time_s, |last| last.max(time_s)));
        Ok(())
    }

    /// Every live track's state predicted to `time_s` (s), in track order, by the tracker's
    /// CV model; the tracker is unchanged (a look ahead, e.g. to schedule the next
    /// measurements).
    ///
    /// # Errors
    /// [`EngineError::Estimation`] for a time before a track's state (earlier than the last
    /// scan) or a non-finite time.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::association::{AnonymousTracker, AnonymousTrackerSettings};
    /// use rtls_estimation::{Gaussian, Matrix, Vector};
    /// let mut tracker = AnonymousTracker::new(AnonymousTrackerSettings::default())?;
    /// let p0 = Matrix::<4>::identity() * 0.01;
    /// tracker.seed_track("a", Gaussian::new(Vector::<4>::new(1.0, 0.5, 2.0, 0.0), p0, 0.0)?)?;
    /// let ahead = tracker.predict_tracks(2.0)?;
    /// assert!((ahead[0].mean()[0] - 2.0).abs() < 1e-12); // x + vx t
    /// assert_eq!(tracker.tracks()[0].state().time_s(), 0.0);
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn predict_tracks(&self, time_s: f64) -> Result<Vec<Gaussian<4>>> {
        let kf = KalmanFilter::default();
        Ok(self
            .tracks
            .iter()
            .map(|track| kf.predict(&track.state, &self.motion, time_s))
            .collect::<rtls_estimation::Result<Vec<_>>>()?)
    }

    /// The time of the last scan (or of the latest seeded state), s; `None` before either.
    #[must_use]
    pub fn last_scan_s(&self) -> Option<f64> {
        self.last_scan_s
    }
}

/// What the manoeuvre fallback of a scan reads.
struct Ungated<'a> {
    fallback: &'a ManoeuvreFallback,
    time_s: f64,
    priors: &'a [Gaussian<4>],
    ids: &'a [Arc<str>],
    established: &'a [bool],
    last_update_s: &'a [f64],
    /// Per detection, the number of tracks whose gate it passed.
    gated_tracks: &'a [usize],
    near: &'a [NearPair],
    detections: &'a [Detection],
}

/// How many ranges the manoeuvre fallback gave to a track, and how many it found ambiguous.
#[derive(Debug, Clone, Copy, Default)]
struct ManoeuvreCounts {
    assigned: usize,
    ambiguous: usize,
}

impl Ungated<'_> {
    /// The manoeuvre fallback ([`ManoeuvreFallback`]) after the gated association: each range
    /// outside every gate goes to the one established track that can have made it, if that
    /// track took no gated detection in this scan; of several such ranges a track takes the
    /// one of least `d² + ln |S|`.
    ///
    /// # Errors
    /// A failed filter update.
    fn fall_back(&self, out: &mut Decisions) -> Result<ManoeuvreCounts> {
        let mut counts = ManoeuvreCounts::default();
        // (cost, detection, track) of every range the fallback may give to a track
        let mut proposals: Vec<(f64, usize, usize)> = Vec::new();
        let mut start = 0;
        while start < self.near.len() {
            let d = self.near[start].detection;
            let end = start + self.near[start..].iter().take_while(|p| p.detection == d).count();
            if self.gated_tracks[d] == 0 && out.fates[d].is_none() {
                let candidates: Vec<Candidate> = self.near[start..end]
                    .iter()
                    .filter(|p| self.established[p.track])
                    .map(|p| Candidate {
                        track: p.track,
                        innovation_abs_m: p.innovation_abs_m,
                        variance_m2: p.variance_m2,
                        last_update_s: self.last_update_s[p.track],
                        cost: p.score.cost(),
                    })
                    .collect();
                match self.fallback.choose(&candidates, self.time_s) {
                    Choice::Candidate(k) => proposals.push((candidates[k].cost, d, candidates[k].track)),
                    Choice::Ambiguous => counts.ambiguous += 1,
                    Choice::Nobody => {}
                }
            }
            start = end;
        }
        // each free track takes its cheapest proposal (ties: the earlier detection)
        proposals.sort_by(|a, b| a.2.cmp(&b.2).then(a.0.total_cmp(&b.0)).then(a.1.cmp(&b.1)));
        let mut last_track = None;
        for (_, d, t) in proposals {
            if last_track == Some(t) || out.changes[t].is_some() {
                continue;
            }
            last_track = Some(t);
            // P⁻ += diag(0, σ_m², 0, σ_m²), then the range update
            let opened = self.fallback.open_velocity(&self.priors[t])?;
            let posterior = self.detections[d].update(&opened)?;
            out.changes[t] = Some(TrackChange {
                state: posterior.state,
                detected: true,
            });
            out.fates[d] = Some(DetectionFate::Manoeuvre {
                track: Arc::clone(&self.ids[t]),
            });
            counts.assigned += 1;
        }
        Ok(counts)
    }
}

impl AnonymousTracker {
    /// A new track `anon-<number>` from a fix: `x₀ = [zₓ, 0, z_y, 0]`,
    /// `P₀ = [[Rₓₓ, 0, Rₓᵧ, 0], [0, σ_v², 0, 0], [Rᵧₓ, 0, Rᵧᵧ, 0], [0, 0, 0, σ_v²]]`.
    fn start_track(
        &self,
        number: u64,
        time_s: f64,
        position_m: [f64; 2],
        covariance_m2: [[f64; 2]; 2],
    ) -> Result<AnonymousTrack> {
        let velocity_variance = self.settings.initial_velocity_std_mps * self.settings.initial_velocity_std_mps;
        let mean = Vector::<4>::new(position_m[0], 0.0, position_m[1], 0.0);
        let mut covariance = Matrix::<4>::zeros();
        for (i, row) in [0, 2].into_iter().enumerate() {
            for (j, column) in [0, 2].into_iter().enumerate() {
                covariance[(row, column)] = covariance_m2[i][j];
            }
        }
        covariance[(1, 1)] = velocity_variance;
        covariance[(3, 3)] = velocity_variance;
        let state = Gaussian::new(mean, covariance, time_s)?;
        Ok(AnonymousTrack {
            id: format!("anon-{number}").into(),
            state,
            last_update: state,
            lifecycle: Lifecycle::start(self.settings.lifecycle, time_s)?,
        })
    }
}
