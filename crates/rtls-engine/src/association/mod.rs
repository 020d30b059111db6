//! Anonymous multi-target association: tracking several targets from detections that carry no
//! identity — position fixes and ranges from known nodes (seed 003's ultrasonic echoes).
//!
//! Components, each usable on its own:
//! - [`solve_assignment`] on a [`CostMatrix`] — rectangular linear assignment with forbidden
//!   pairs and a price for leaving a row unassigned (Hungarian / Jonker–Volgenant, `O(n³)`);
//! - [`jpda_marginals`] — exact joint probabilistic data association weights of a cluster;
//! - [`AnonymousTracker`] — CV tracks `[x, vx, y, vy]` fed scan by scan: χ² gating on the NIS,
//!   GNN or JPDA per cluster, KF updates for fixes and EKF updates for ranges, track start from
//!   unassigned fixes or from known states ([`AnonymousTracker::seed_track`]) and the
//!   [`Lifecycle`](crate::lifecycle::Lifecycle) (M-of-N confirmation, coasting, lost, deletion)
//!   for every track;
//! - [`FieldOfView`] — the sector of a directional ranging sensor: only tracks predicted inside
//!   it are candidates for its range;
//! - [`ManoeuvreFallback`] — a range outside every gate that only one track can have made goes
//!   to that track, its velocity re-opened (off by default).
//!
//! # Cost and likelihood
//! For a detection `z` of dimension `m` and a predicted track with innovation `ν`, innovation
//! covariance `S`, `d² = νᵀ S⁻¹ ν` and `−2 ln N(ν; 0, S) = d² + ln |S| + m ln 2π`. The GNN pair
//! cost is `d² + ln |S|`; leaving a detection unassigned costs
//! `c₀ = −2 ln λ − m ln 2π + 2 ln P_D − 2 ln(1 − P_D P_G)`, so the minimum-cost assignment is
//! the most likely joint event of the JPDA model (`P_D` detection, `P_G` gate probability,
//! `λ` clutter density).
//!
//! # References
//! - Y. Bar-Shalom, T. E. Fortmann, *Tracking and Data Association*, Academic Press, 1988.
//! - H. W. Kuhn, "The Hungarian method for the assignment problem", 1955; R. Jonker,
//!   A. Volgenant, "A shortest augmenting path algorithm for dense and sparse linear assignment
//!   problems", *Computing* 38, 1987.
//! - Seed 003 (single-range EKF, 2 m × 2 m grid cells of ultrasonic nodes), limit ①: several
//!   targets in one cell cannot be located. Tracks started from fixes keep their identity on
//!   anonymous ranges here.

mod assignment;
mod associate;
mod detection;
mod field_of_view;
mod gating;
mod jpda;
mod manoeuvre;
mod report;
mod settings;
mod tracker;

#[cfg(test)]
mod assignment_tests;
#[cfg(test)]
mod jpda_tests;
#[cfg(test)]
mod scenario_tests;
#[cfg(test)]
mod seeded_tests;
#[cfg(test)]
mod test_support;
#[cfg(test)]
mod tracker_tests;

pub use assignment::{solve_assignment, Assignment, CostMatrix};
pub use detection::{Detection, DetectionKind};
pub use field_of_view::FieldOfView;
pub use jpda::{jpda_marginals, JpdaMarginals, JpdaOutcome};
pub use manoeuvre::ManoeuvreFallback;
pub use report::{
    AnonymousTrackUpdate, DetectionCounts, DetectionFate, DetectionReport, ScanReport, TrackEvent, TrackEventKind,
};
pub use settings::{AnonymousTrackerSettings, Association};
pub use tracker::{AnonymousTrack, AnonymousTracker};
