//! `[tracker.consistency]`: the test of each track's own consistency from the corrections its
//! updates make, and the covariance inflation when it fails
//! ([`rtls_estimation::adaptive::corrections`]).

use serde::Deserialize;

/// `[tracker.consistency]`: each track sums the position corrections `K ν` of its tightly
/// coupled updates (ranges, RSSI, range differences; not fixes, whose positioning stage's
/// errors often persist unseen, e.g. a fingerprint snapped to its reference points) over
/// a window and tests the sum against the covariance the filter expects it to have (`Σ K S Kᵀ`,
/// a `χ²` test); when the estimate keeps being pulled one way by more than its covariance
/// admits, the track's covariance is multiplied by the ratio of the observed to the expected
/// statistic, so the next measurements correct it at the rate its real error asks for and its
/// ellipses hold the truth as often as they claim: a motion model lagging a manoeuvre, a track
/// started from a biased fix and held by a tight velocity. On a simulated vehicle turning
/// under a `σ_a` forty times too small the RMSE fell 2.8 → 0.29 m and the 95 % ellipses held
/// the truth 37 → 65 % of the time (`tracker::tests_consistency`); errors that its readings
/// themselves do not reveal (the labyrinth recording's, docs/EVALUATION.md) it cannot see. Not
/// applied under the IMM, whose modes keep their own covariances.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConsistencySettings {
    /// Whether tracks test their corrections and inflate their covariance. Default true.
    pub enabled: bool,
    /// The window the corrections are summed over, s (0.1 to 3600): long enough to see a pull
    /// that persists, short enough to act on it while it lasts. Default 1.
    pub window_s: f64,
    /// The probability that a consistent track's window passes the test (0.5 to 0.999 999):
    /// `1 − probability` of a consistent track's windows are inflated needlessly (for one
    /// window). Default 0.99.
    pub probability: f64,
    /// The largest inflation of one window, a multiple of the covariance (1 to 1e6). Default
    /// 100 (σ × 10).
    pub max_inflation: f64,
}

impl Default for ConsistencySettings {
    fn default() -> Self {
        Self {
            enabled: true,
            window_s: 1.0,
            probability: 0.99,
            max_inflation: 100.0,
        }
    }
}
