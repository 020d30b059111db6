//! Association of one cluster: GNN by linear assignment, JPDA by exact enumeration.

use std::sync::Arc;

use rtls_estimation::Gaussian;

use super::assignment::{solve_assignment, CostMatrix};
use super::detection::{Detection, DetectionKind};
use super::gating::{clusters, Cluster, GatedPair};
use super::jpda::{combine, jpda_marginals, JpdaOutcome};
use super::report::DetectionFate;
use super::settings::{AnonymousTrackerSettings, Association};
use crate::error::Result;

/// How a scan changes one existing track.
#[derive(Debug, Clone, Copy)]
pub(super) struct TrackChange {
    /// The new estimate.
    pub(super) state: Gaussian<4>,
    /// Counts as an update for the lifecycle.
    pub(super) detected: bool,
}

/// What the association of a scan reads.
pub(super) struct Scan<'a> {
    pub(super) settings: &'a AnonymousTrackerSettings,
    /// Predicted state of each track.
    pub(super) priors: &'a [Gaussian<4>],
    /// Id of each track.
    pub(super) ids: &'a [Arc<str>],
    /// Whether each track is established (confirmed, coasting or lost) rather than tentative.
    pub(super) established: &'a [bool],
    /// Every gated pair of the scan.
    pub(super) pairs: &'a [GatedPair],
    pub(super) detections: &'a [Detection],
}

/// How the clusters of a scan were associated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct ClusterCounts {
    /// Clusters of both stages.
    pub(super) clusters: usize,
    /// JPDA clusters associated by GNN instead.
    pub(super) gnn_fallbacks: usize,
}

/// What the association of a scan writes: one entry per track and per detection.
pub(super) struct Decisions {
    pub(super) changes: Vec<Option<TrackChange>>,
    pub(super) fates: Vec<Option<DetectionFate>>,
}

impl Scan<'_> {
    /// Associates the scan in two stages, established tracks first (they have priority over
    /// tentative ones, so a detection the established track explains does not feed a duplicate
    /// track started next to it): stage 1 clusters the gated pairs of established tracks;
    /// stage 2 the pairs of tentative tracks with the detections stage 1 left unused.
    ///
    /// # Errors
    /// A failed filter update or mixture.
    pub(super) fn associate(&self, out: &mut Decisions) -> Result<ClusterCounts> {
        let mut counts = ClusterCounts::default();
        let first: Vec<GatedPair> = self
            .pairs
            .iter()
            .filter(|p| self.established[p.track])
            .copied()
            .collect();
        self.associate_stage(&first, out, &mut counts)?;
        let second: Vec<GatedPair> = self
            .pairs
            .iter()
            .filter(|p| !self.established[p.track] && out.fates[p.detection].is_none())
            .copied()
            .collect();
        self.associate_stage(&second, out, &mut counts)?;
        Ok(counts)
    }

    /// One stage: clusters of `pairs`, each by JPDA (within the caps) or GNN.
    fn associate_stage(&self, pairs: &[GatedPair], out: &mut Decisions, counts: &mut ClusterCounts) -> Result<()> {
        let jpda = self.settings.association == Association::Jpda;
        for cluster in clusters(pairs, self.priors.len(), self.detections.len()) {
            counts.clusters += 1;
            let handled = jpda
                && cluster.tracks.len() <= self.settings.jpda_max_cluster_tracks
                && self.jpda(&cluster, pairs, out)?;
            if !handled {
                counts.gnn_fallbacks += usize::from(jpda);
                self.gnn(&cluster, pairs, out)?;
            }
        }
        Ok(())
    }

    /// `λ` of a detection's kind.
    fn clutter_density(&self, detection: &Detection) -> f64 {
        match detection.kind() {
            DetectionKind::Fix { .. } => self.settings.fix_clutter_density_per_m2,
            DetectionKind::Range { .. } => self.settings.range_clutter_density_per_m,
        }
    }

    /// GNN on one cluster: rows are its detections, columns its tracks, pair cost `d² + ln |S|`,
    /// non-assignment cost `c₀` of the detection's kind; assigned pairs are filtered.
    ///
    /// # Errors
    /// A failed filter update.
    fn gnn(&self, cluster: &Cluster, pairs: &[GatedPair], out: &mut Decisions) -> Result<()> {
        let mut costs = CostMatrix::forbidden(cluster.detections.len(), cluster.tracks.len())?;
        for &k in &cluster.pairs {
            let pair = &pairs[k];
            let (row, column) = local(cluster, pair);
            costs.set(row, column, pair.score.cost())?;
        }
        let unassigned: Vec<f64> = cluster
            .detections
            .iter()
            .map(|&d| {
                let detection = &self.detections[d];
                self.settings
                    .non_assignment_cost(detection.dim(), self.clutter_density(detection))
            })
            .collect();
        let best = solve_assignment(&costs, &unassigned)?;
        for (row, column) in best.row_to_column.iter().enumerate() {
            let Some(column) = column else { continue };
            let (d, t) = (cluster.detections[row], cluster.tracks[*column]);
            let posterior = self.detections[d].update(&self.priors[t])?;
            out.changes[t] = Some(TrackChange {
                state: posterior.state,
                detected: true,
            });
            out.fates[d] = Some(DetectionFate::Assigned {
                track: Arc::clone(&self.ids[t]),
            });
        }
        Ok(())
    }

    /// JPDA on one cluster; `false` (nothing written) when it has more joint events than
    /// `jpda_max_joint_events`.
    ///
    /// # Errors
    /// A failed filter update or mixture.
    fn jpda(&self, cluster: &Cluster, pairs: &[GatedPair], out: &mut Decisions) -> Result<bool> {
        let settings = self.settings;
        let ln_detect = settings.detection_probability.ln();
        // ln L_td = ln P_D − ln λ_d + ln N(ν_td; 0, S_td), per cluster track, detections local
        let mut options: Vec<Vec<(usize, f64)>> = vec![Vec::new(); cluster.tracks.len()];
        for &k in &cluster.pairs {
            let pair = &pairs[k];
            let (row, column) = local(cluster, pair);
            let detection = &self.detections[pair.detection];
            let ln_ratio =
                ln_detect - self.clutter_density(detection).ln() + pair.score.log_likelihood(detection.dim());
            options[column].push((row, ln_ratio));
        }
        let marginals = match jpda_marginals(&options, settings.ln_miss(), settings.jpda_max_joint_events)? {
            JpdaOutcome::Marginals(marginals) => marginals,
            JpdaOutcome::TooManyEvents { .. } => return Ok(false),
        };
        let mut weights: Vec<Vec<(Arc<str>, f64)>> = vec![Vec::new(); cluster.detections.len()];
        let mut changes = Vec::with_capacity(cluster.tracks.len());
        for (column, &t) in cluster.tracks.iter().enumerate() {
            let prior = &self.priors[t];
            let mut posteriors = Vec::with_capacity(marginals.association[column].len());
            for &(row, beta) in &marginals.association[column] {
                let d = cluster.detections[row];
                posteriors.push((beta, self.detections[d].update(prior)?.state));
                weights[row].push((Arc::clone(&self.ids[t]), beta));
            }
            let miss = marginals.miss[column];
            changes.push((
                t,
                TrackChange {
                    state: combine(prior, miss, &posteriors)?,
                    detected: miss <= 0.5,
                },
            ));
        }
        for (t, change) in changes {
            out.changes[t] = Some(change);
        }
        for (row, tracks) in weights.into_iter().enumerate() {
            out.fates[cluster.detections[row]] = Some(DetectionFate::Weighted { tracks });
        }
        Ok(true)
    }
}

/// The (row, column) of a gated pair in its cluster's detection and track lists.
fn local(cluster: &Cluster, pair: &GatedPair) -> (usize, usize) {
    // both lists are sorted and contain the pair's members (built from the same pairs)
    let row = cluster.detections.partition_point(|&d| d < pair.detection);
    let column = cluster.tracks.partition_point(|&t| t < pair.track);
    debug_assert_eq!(cluster.detections.get(row), Some(&pair.detection));
    debug_assert_eq!(cluster.tracks.get(column), Some(&pair.track));
    (row, column)
}
