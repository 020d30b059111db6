//! Simulation helpers of the association tests: noisy detections and identity-swap counting.

use std::sync::Arc;

use rand::Rng;
use rand_distr::{Distribution, Normal};

use super::{AnonymousTrackerSettings, Association, Detection, ScanReport};
use crate::lifecycle::{LifecycleSettings, TrackStatus};

/// Test settings: `σ_a` = 0.5 m/s², `σ_v` = 1 m/s, `P_G` = 0.99, `P_D` = 0.9, the given
/// lifecycle.
pub(super) fn settings(association: Association, lifecycle: LifecycleSettings) -> AnonymousTrackerSettings {
    AnonymousTrackerSettings {
        association,
        lifecycle,
        ..AnonymousTrackerSettings::default()
    }
}

/// Lifecycle: confirm after `m` updates within `window_s`, coast `coast_s`, delete `delete_s`.
pub(super) fn lifecycle(m: u32, window_s: f64, coast_s: f64, delete_s: f64) -> LifecycleSettings {
    LifecycleSettings {
        confirm_updates: m,
        confirm_window_s: window_s,
        coast_timeout_s: coast_s,
        delete_timeout_s: delete_s,
    }
}

/// A fix of `truth` with independent `N(0, σ²)` errors on x and y, reported with `R = σ² I`.
pub(super) fn noisy_fix(rng: &mut impl Rng, truth: [f64; 2], sigma_m: f64) -> Detection {
    let noise = Normal::new(0.0, sigma_m).unwrap();
    let variance = sigma_m * sigma_m;
    Detection::fix(
        [truth[0] + noise.sample(rng), truth[1] + noise.sample(rng)],
        [[variance, 0.0], [0.0, variance]],
    )
    .unwrap()
}

/// A range from `node` to `truth` with `N(0, σ²)` error (clamped at 0).
pub(super) fn noisy_range(rng: &mut impl Rng, node: [f64; 2], truth: [f64; 2], sigma_m: f64) -> Detection {
    let noise = Normal::new(0.0, sigma_m).unwrap();
    let range = ((truth[0] - node[0]).hypot(truth[1] - node[1]) + noise.sample(rng)).max(0.0);
    Detection::range(node, range, sigma_m * sigma_m).unwrap()
}

/// Follows which track each true target is matched to: after every scan, the nearest
/// confirmed or coasting track within `radius_m` of each target. A change of that track id is
/// an identity swap; a scan without a match is counted as unmatched.
#[derive(Debug)]
pub(super) struct IdentityFollower {
    radius_m: f64,
    /// The track each target was last matched to.
    pub(super) ids: Vec<Option<Arc<str>>>,
    /// Changes of a target's track.
    pub(super) swaps: usize,
    /// (target, scan) pairs without a track within the radius.
    pub(super) unmatched: usize,
    /// Squared position errors of matched scans, m².
    pub(super) squared_errors_m2: Vec<f64>,
    /// Every track id ever matched to a target.
    pub(super) matched_ids: std::collections::BTreeSet<Arc<str>>,
}

impl IdentityFollower {
    pub(super) fn new(targets: usize, radius_m: f64) -> Self {
        Self {
            radius_m,
            ids: vec![None; targets],
            swaps: 0,
            unmatched: 0,
            squared_errors_m2: Vec::new(),
            matched_ids: std::collections::BTreeSet::new(),
        }
    }

    pub(super) fn observe(&mut self, report: &ScanReport, truths: &[[f64; 2]]) {
        for (target, truth) in truths.iter().enumerate() {
            let nearest = report
                .updates
                .iter()
                .filter(|u| matches!(u.status, TrackStatus::Confirmed | TrackStatus::Coasting))
                .map(|u| {
                    let m = u.state.mean();
                    ((m[0] - truth[0]).powi(2) + (m[2] - truth[1]).powi(2), &u.track)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match nearest {
                Some((e2, id)) if e2 <= self.radius_m * self.radius_m => {
                    if self.ids[target].as_ref().is_some_and(|last| last != id) {
                        self.swaps += 1;
                    }
                    self.ids[target] = Some(Arc::clone(id));
                    self.matched_ids.insert(Arc::clone(id));
                    self.squared_errors_m2.push(e2);
                }
                _ => self.unmatched += 1,
            }
        }
    }

    /// Root mean square of the matched position errors, m.
    pub(super) fn rmse_m(&self) -> f64 {
        (self.squared_errors_m2.iter().sum::<f64>() / self.squared_errors_m2.len() as f64).sqrt()
    }
}

/// Brute force over every map detection → {clutter, track 0, …, track T−1} (`(T+1)^D` maps),
/// keeping those where no track takes two detections and every pair is gated:
/// `w(θ) = Π L_td · Π_{t undetected} miss`. Returns (β_t0, β_td as a T × D table, events).
pub(super) fn brute_force_jpda(
    ratio: &[Vec<Option<f64>>],
    detections: usize,
    miss: f64,
) -> (Vec<f64>, Vec<Vec<f64>>, usize) {
    let tracks = ratio.len();
    let mut miss_weight = vec![0.0; tracks];
    let mut pair_weight = vec![vec![0.0; detections]; tracks];
    let mut total = 0.0;
    let mut events = 0;
    let maps = (tracks + 1).pow(detections as u32);
    'maps: for code in 0..maps {
        // digit d of `code` in base T+1: 0 = clutter, t + 1 = track t
        let mut owner = vec![None; detections];
        let mut rest = code;
        for slot in owner.iter_mut() {
            let digit = rest % (tracks + 1);
            rest /= tracks + 1;
            *slot = digit.checked_sub(1);
        }
        let mut weight = 1.0;
        let mut detected = vec![false; tracks];
        for (d, o) in owner.iter().enumerate() {
            if let Some(t) = *o {
                let Some(l) = ratio[t][d] else { continue 'maps };
                if detected[t] {
                    continue 'maps;
                }
                detected[t] = true;
                weight *= l;
            }
        }
        for &was in &detected {
            if !was {
                weight *= miss;
            }
        }
        events += 1;
        total += weight;
        for t in 0..tracks {
            if !detected[t] {
                miss_weight[t] += weight;
            }
        }
        for (d, o) in owner.iter().enumerate() {
            if let Some(t) = *o {
                pair_weight[t][d] += weight;
            }
        }
    }
    (
        miss_weight.iter().map(|w| w / total).collect(),
        pair_weight
            .iter()
            .map(|row| row.iter().map(|w| w / total).collect())
            .collect(),
        events,
    )
}
