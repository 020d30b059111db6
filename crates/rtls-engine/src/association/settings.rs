//! Settings of the anonymous multi-target tracker, and the association costs they imply.

use serde::Deserialize;

use super::manoeuvre::ManoeuvreFallback;
use crate::error::{EngineError, Result};
use crate::lifecycle::LifecycleSettings;

/// How detections are shared out among tracks at each scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Association {
    /// Global nearest neighbour: the single most likely assignment (each detection to at most
    /// one track, each track at most one detection), solved exactly per cluster by
    /// [`solve_assignment`](super::solve_assignment).
    Gnn,
    /// Joint probabilistic data association: every track is updated with all detections in its
    /// gate, weighted by the marginal probability of each joint association event; exact
    /// enumeration per cluster, GNN beyond the caps.
    Jpda,
}

/// Settings of [`AnonymousTracker`](super::AnonymousTracker).
///
/// # Units
/// Accelerations in m/s², velocities in m/s, clutter densities in false detections per scan
/// per m² (fixes) or per metre of range (ranges), probabilities in `(0, 1)`.
///
/// # Example
/// ```
/// use rtls_engine::association::{Association, AnonymousTrackerSettings};
/// let jpda = AnonymousTrackerSettings { association: Association::Jpda, ..Default::default() };
/// assert!(jpda.validate().is_ok());
/// let bad = AnonymousTrackerSettings { detection_probability: 0.0, ..Default::default() };
/// assert!(bad.validate().unwrap_err().to_string().contains("detection_probability"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnonymousTrackerSettings {
    /// GNN or JPDA.
    pub association: Association,
    /// `σ_a` (m/s²) of the constant-velocity model's white acceleration (discrete, kinematic
    /// gain `G = [dt²/2, dt]ᵀ` per axis). Unused when `acceleration_psd_m2ps3` is set.
    pub acceleration_noise_std_mps2: f64,
    /// `q` (m²/s³): when set, the CV model's process noise is continuous white acceleration of
    /// this power spectral density per axis, `Q = q [[dt³/3, dt²/2], [dt²/2, dt]]`, instead of
    /// the discrete `σ_a` model (a continuous model predicts the same in one step or in many,
    /// so scans may come at any spacing). `None` (the default): the discrete model. Set in code
    /// only (not read from a site file).
    #[serde(skip)]
    pub acceleration_psd_m2ps3: Option<f64>,
    /// `σ_v` (m/s): standard deviation of each velocity component of a new track (which starts
    /// at the fix with zero velocity).
    pub initial_velocity_std_mps: f64,
    /// `P_G`: the χ² gate keeps a detection of a track when `d² = νᵀ S⁻¹ ν ≤ χ²_{P_G}(m)`.
    pub gate_probability: f64,
    /// `P_D`: probability that a target yields a detection in a scan.
    pub detection_probability: f64,
    /// `λ` of position fixes: expected false fixes per scan per m² (clutter and new targets).
    pub fix_clutter_density_per_m2: f64,
    /// `λ` of ranges: expected false ranges per scan per metre of range.
    pub range_clutter_density_per_m: f64,
    /// M-of-N confirmation, coasting, lost and deletion timeouts.
    pub lifecycle: LifecycleSettings,
    /// JPDA: clusters with more tracks than this are associated by GNN (reported).
    pub jpda_max_cluster_tracks: usize,
    /// JPDA: a cluster whose joint events exceed this number is associated by GNN (reported).
    pub jpda_max_joint_events: usize,
    /// The manoeuvre fallback for ranges outside every gate ([`ManoeuvreFallback`]); `None`
    /// (the default): such ranges are unused. Set in code only (not read from a site file).
    #[serde(skip)]
    pub manoeuvre: Option<ManoeuvreFallback>,
}

impl Default for AnonymousTrackerSettings {
    /// GNN; `σ_a` = 0.5 m/s² (people and slow robots, seed 003's 0.5 m/s robots); `σ_v` = 1 m/s;
    /// `P_G` = 0.99; `P_D` = 0.9; `λ` = 10⁻³ false fixes per m² and 10⁻² false ranges per m per
    /// scan; confirmation after 3 updates within 3 s, coasting up to 5 s, deletion after 30 s
    /// (an anonymous track cannot be recognised again once lost, so it is not kept for long);
    /// JPDA exact up to 8 tracks and 10⁵ joint events per cluster; discrete process noise and
    /// no manoeuvre fallback.
    fn default() -> Self {
        Self {
            association: Association::Gnn,
            acceleration_noise_std_mps2: 0.5,
            initial_velocity_std_mps: 1.0,
            gate_probability: 0.99,
            detection_probability: 0.9,
            fix_clutter_density_per_m2: 1e-3,
            range_clutter_density_per_m: 1e-2,
            lifecycle: LifecycleSettings {
                confirm_updates: 3,
                confirm_window_s: 3.0,
                coast_timeout_s: 5.0,
                delete_timeout_s: 30.0,
            },
            jpda_max_cluster_tracks: 8,
            jpda_max_joint_events: 100_000,
            acceleration_psd_m2ps3: None,
            manoeuvre: None,
        }
    }
}

/// Largest accepted `jpda_max_cluster_tracks`: exact enumeration over more tracks is hopeless.
pub(crate) const MAX_JPDA_CLUSTER_TRACKS: usize = 64;

impl AnonymousTrackerSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming the field: a non-finite or non-positive
    /// standard deviation or clutter density, `gate_probability` not in `(0, 1)`,
    /// `detection_probability` not in `(0, 1]`, `jpda_max_cluster_tracks` not in `1..=64`,
    /// `jpda_max_joint_events = 0`, an `acceleration_psd_m2ps3` that is not finite and > 0, a
    /// manoeuvre field (`manoeuvre.…`) or a lifecycle field (`lifecycle.…`) its own validation
    /// rejects.
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [
            ("acceleration_noise_std_mps2", self.acceleration_noise_std_mps2),
            ("initial_velocity_std_mps", self.initial_velocity_std_mps),
            ("fix_clutter_density_per_m2", self.fix_clutter_density_per_m2),
            ("range_clutter_density_per_m", self.range_clutter_density_per_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(EngineError::InvalidParameter {
                    name,
                    reason: "must be finite and > 0",
                });
            }
        }
        if !(self.gate_probability > 0.0 && self.gate_probability < 1.0) {
            return Err(EngineError::InvalidParameter {
                name: "gate_probability",
                reason: "must be strictly between 0 and 1 (e.g. 0.99)",
            });
        }
        if !(self.detection_probability > 0.0 && self.detection_probability <= 1.0) {
            return Err(EngineError::InvalidParameter {
                name: "detection_probability",
                reason: "must be in (0, 1]",
            });
        }
        if !(1..=MAX_JPDA_CLUSTER_TRACKS).contains(&self.jpda_max_cluster_tracks) {
            return Err(EngineError::InvalidParameter {
                name: "jpda_max_cluster_tracks",
                reason: "must be between 1 and 64 (exact enumeration beyond that is hopeless)",
            });
        }
        if let Some(q) = self.acceleration_psd_m2ps3 {
            if !(q.is_finite() && q > 0.0) {
                return Err(EngineError::InvalidParameter {
                    name: "acceleration_psd_m2ps3",
                    reason: "must be finite and > 0",
                });
            }
        }
        if let Some(manoeuvre) = &self.manoeuvre {
            manoeuvre.validate()?;
        }
        if self.jpda_max_joint_events == 0 {
            return Err(EngineError::InvalidParameter {
                name: "jpda_max_joint_events",
                reason: "must be at least 1",
            });
        }
        self.lifecycle.validate().map_err(|error| match error {
            EngineError::InvalidParameter { name, reason } => EngineError::InvalidParameter {
                name: lifecycle_field(name),
                reason,
            },
            other => other,
        })
    }

    /// `ln(1 − P_D P_G)`: the log-weight of a track that is not detected in a scan (its target
    /// was missed, or its detection fell outside the gate).
    pub(crate) fn ln_miss(&self) -> f64 {
        (1.0 - self.detection_probability * self.gate_probability).ln()
    }

    /// The cost of leaving a detection of dimension `dim` with clutter density `density`
    /// unassigned, on the scale of the pair cost `d² + ln |S|`:
    /// ```text
    /// c₀ = −2 ln λ − m ln 2π + 2 ln P_D − 2 ln(1 − P_D P_G)
    /// ```
    /// A pair is worth assigning iff `d² + ln |S| < c₀`, i.e. iff its likelihood ratio
    /// `P_D N(ν; 0, S) / (λ (1 − P_D P_G))` exceeds 1 (module documentation).
    pub(crate) fn non_assignment_cost(&self, dim: usize, density: f64) -> f64 {
        -2.0 * density.ln() - dim as f64 * std::f64::consts::TAU.ln() + 2.0 * self.detection_probability.ln()
            - 2.0 * self.ln_miss()
    }
}

/// The key path of a lifecycle field.
fn lifecycle_field(name: &'static str) -> &'static str {
    match name {
        "confirm_updates" => "lifecycle.confirm_updates",
        "confirm_window_s" => "lifecycle.confirm_window_s",
        "coast_timeout_s" => "lifecycle.coast_timeout_s",
        "delete_timeout_s" => "lifecycle.delete_timeout_s",
        other => other,
    }
}
