//! χ² gating of every detection against every predicted track, kept sparse by a sweep over the
//! tracks sorted by x, and the clusters (connected components) of the gating graph.

use super::detection::{track_half_width_m, Detection, PairScore};
use rtls_estimation::Gaussian;

/// Tracks whose x half-width exceeds this many times the median are checked against every
/// detection instead of widening every detection's window (a lost track's growing covariance
/// must not make the search dense for all).
const WIDE_TRACK_FACTOR: f64 = 3.0;

/// A detection inside a track's gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GatedPair {
    /// Index into the scan's detections.
    pub(crate) detection: usize,
    /// Index into the tracks.
    pub(crate) track: usize,
    /// Its `d²` and `ln |S|`.
    pub(crate) score: PairScore,
}

/// The gated pairs of a scan.
#[derive(Debug, Clone, Default)]
pub(crate) struct Gating {
    /// Every pair with `d² ≤ χ²_{P_G}(m)`, sorted by (detection, track).
    pub(crate) pairs: Vec<GatedPair>,
    /// Pairs whose `S` was undefined (a track on the node of a range): treated as outside the
    /// gate, counted.
    pub(crate) singular_pairs: usize,
    /// With a manoeuvre margin `m`: every range–track pair in view, outside the gate, with
    /// `|ν| ≤ m`, sorted by (detection, track).
    pub(crate) near: Vec<NearPair>,
}

/// A range outside a track's gate but within the manoeuvre margin of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NearPair {
    /// Index into the scan's detections.
    pub(crate) detection: usize,
    /// Index into the tracks.
    pub(crate) track: usize,
    /// `|ν| = |r − d̂|`, m.
    pub(crate) innovation_abs_m: f64,
    /// `S`, m².
    pub(crate) variance_m2: f64,
    /// Its `d²` and `ln |S|`.
    pub(crate) score: PairScore,
}

/// Gates every detection against every prior. `gates[m − 1]` is `χ²_{P_G}(m)` for `m = 1, 2`.
/// A range with a field of view is gated only against the tracks in view
/// ([`FieldOfView`](super::FieldOfView)). With a manoeuvre margin `m > 0`, the in-view ranges
/// outside a track's gate with `|ν| ≤ m` are kept in [`Gating::near`].
///
/// The exact test `d² ≤ γ` runs only on pairs whose track x lies in the detection's window
/// ([`Detection::x_window`]), a necessary condition, so the result equals the dense check.
pub(crate) fn gate(priors: &[Gaussian<4>], detections: &[Detection], gates: [f64; 2], margin_m: f64) -> Gating {
    let mut gating = Gating::default();
    if priors.is_empty() || detections.is_empty() {
        return gating;
    }
    let widest_gate = gates[0].max(gates[1]);
    let widths: Vec<f64> = priors.iter().map(|p| track_half_width_m(p, widest_gate)).collect();
    let mut sorted_widths = widths.clone();
    sorted_widths.sort_by(f64::total_cmp);
    let cap = WIDE_TRACK_FACTOR * sorted_widths[sorted_widths.len() / 2];
    // Narrow tracks sorted by x; wide ones checked for every detection.
    let mut narrow: Vec<(f64, usize)> = Vec::with_capacity(priors.len());
    let mut wide: Vec<usize> = Vec::new();
    let mut narrow_width = 0.0f64;
    for (t, (prior, &w)) in priors.iter().zip(&widths).enumerate() {
        if w <= cap {
            narrow.push((prior.mean()[0], t));
            narrow_width = narrow_width.max(w);
        } else {
            wide.push(t);
        }
    }
    narrow.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut candidates: Vec<usize> = Vec::new();
    for (d, detection) in detections.iter().enumerate() {
        let gate = gates[detection.dim() - 1];
        let (lo, hi) = detection.x_window(gate, narrow_width, margin_m);
        candidates.clear();
        let start = narrow.partition_point(|&(x, _)| x < lo);
        candidates.extend(narrow[start..].iter().take_while(|&&(x, _)| x <= hi).map(|&(_, t)| t));
        candidates.extend_from_slice(&wide);
        candidates.sort_unstable();
        for &t in &candidates {
            let prior = &priors[t];
            match detection.in_view(prior) {
                Some(false) => continue,
                None => {
                    gating.singular_pairs += 1;
                    continue;
                }
                Some(true) => {}
            }
            match detection.score(prior) {
                Some(score) if score.nis <= gate => gating.pairs.push(GatedPair {
                    detection: d,
                    track: t,
                    score,
                }),
                Some(score) if margin_m > 0.0 => {
                    if let Some((innovation_abs_m, variance_m2)) = detection.range_innovation(prior) {
                        // |ν| = |r − d̂| ≤ m
                        if innovation_abs_m <= margin_m {
                            gating.near.push(NearPair {
                                detection: d,
                                track: t,
                                innovation_abs_m,
                                variance_m2,
                                score,
                            });
                        }
                    }
                }
                Some(_) => {}
                None => gating.singular_pairs += 1,
            }
        }
    }
    gating
}

/// A connected component of the gating graph: tracks and detections linked by gated pairs.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Cluster {
    /// Track indices, ascending.
    pub(crate) tracks: Vec<usize>,
    /// Detection indices, ascending.
    pub(crate) detections: Vec<usize>,
    /// Indices into [`Gating::pairs`].
    pub(crate) pairs: Vec<usize>,
}

/// The clusters of the gated pairs (each with at least one pair), ordered by their first
/// detection. Tracks and detections without a gated pair belong to no cluster.
pub(crate) fn clusters(pairs: &[GatedPair], tracks: usize, detections: usize) -> Vec<Cluster> {
    // Union–find over nodes 0..tracks (tracks) and tracks..tracks+detections (detections).
    let mut parent: Vec<usize> = (0..tracks + detections).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for pair in pairs {
        let a = find(&mut parent, pair.track);
        let b = find(&mut parent, tracks + pair.detection);
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut index_of_root = vec![usize::MAX; tracks + detections];
    let mut out: Vec<Cluster> = Vec::new();
    for (k, pair) in pairs.iter().enumerate() {
        let root = find(&mut parent, pair.track);
        if index_of_root[root] == usize::MAX {
            index_of_root[root] = out.len();
            out.push(Cluster::default());
        }
        let cluster = &mut out[index_of_root[root]];
        cluster.pairs.push(k);
        cluster.tracks.push(pair.track);
        cluster.detections.push(pair.detection);
    }
    for cluster in &mut out {
        cluster.tracks.sort_unstable();
        cluster.tracks.dedup();
        cluster.detections.sort_unstable();
        cluster.detections.dedup();
    }
    out
}
