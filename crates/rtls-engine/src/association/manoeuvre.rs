//! The manoeuvre fallback: a range outside every gate that only one track can have made is
//! that track's, which has manoeuvred; its velocity is re-opened before the update.

use rtls_estimation::Gaussian;

use crate::error::{EngineError, Result};

/// How many standard deviations of the predicted range a track's own uncertainty explains in
/// the reachability test `|ν| ≤ 3 √S + |Δv|max (t − t_last)`.
const REACH_SIGMAS: f64 = 3.0;

/// Settings of the manoeuvre fallback of [`AnonymousTracker`](super::AnonymousTracker).
///
/// A χ² gate sized for the constant-velocity model rejects the ranges of a target that has
/// just turned, stopped or started: a 90° turn at 0.5 m/s leaves the CV prediction 10–20 cm off
/// within a third of a second, several σ of a 3 cm sonar. Where every detection comes from a
/// target (no clutter inside the sensor's window, as with seed 003's ultrasonic echoes), such a
/// range is still informative. For each range that passes **no** track's gate, the fallback
/// looks at the established tracks (confirmed, coasting, lost) in its field of view whose range
/// innovation is within the margin, `|ν| = |r − d̂| ≤ m` (*plausible*), and of those the ones
/// that can have drifted that far since their last update (*reachable*),
/// ```text
/// |ν| ≤ 3 √S + |Δv|max (t − t_last update)
/// ```
/// (the CV prediction's error after any velocity change since then). If exactly one track is
/// plausible, or else exactly one is reachable, the range is given to it — after the gated
/// association, so only to a track no gated detection updated in this scan, and to each track at
/// most one such range (the one of least `d² + ln |S|`): a cost above any gated pairing. Its
/// velocity is re-opened first, so that the range can correct a velocity the CV model still
/// holds from before the manoeuvre:
/// ```text
/// P⁻ ← P⁻ + diag(0, σ_m², 0, σ_m²),   then the EKF range update
/// ```
/// Ranges with several plausible tracks and no single reachable one are unused and counted as
/// ambiguous (one of them manoeuvred, which one is unknown): [`ScanReport::manoeuvre_ambiguous`];
/// the ranges given by the fallback are [`DetectionFate::Manoeuvre`] and counted in
/// [`ScanReport::manoeuvre_assigned`]. Fixes outside every gate start tracks as before.
///
/// [`ScanReport::manoeuvre_ambiguous`]: super::ScanReport::manoeuvre_ambiguous
/// [`ScanReport::manoeuvre_assigned`]: super::ScanReport::manoeuvre_assigned
/// [`DetectionFate::Manoeuvre`]: super::DetectionFate::Manoeuvre
///
/// # Units
/// `margin_m` in m, `velocity_std_mps` and `speed_change_mps` in m/s.
///
/// # Errors
/// [`ManoeuvreFallback::validate`] rejects negative or non-finite values.
///
/// # Example
/// ```
/// use rtls_engine::association::{AnonymousTrackerSettings, ManoeuvreFallback};
/// let settings = AnonymousTrackerSettings {
///     manoeuvre: Some(ManoeuvreFallback { margin_m: 0.75, velocity_std_mps: 0.5, speed_change_mps: 1.0 }),
///     ..AnonymousTrackerSettings::default()
/// };
/// assert!(settings.validate().is_ok());
/// ```
///
/// # References
/// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
/// Navigation*, 2001, §11.2 (covariance re-opening on a detected manoeuvre); seed 003 §3.3 (the
/// robots' turns at 0.5 m/s) and its limit ① (robots sharing a cell).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManoeuvreFallback {
    /// `m`: the largest range innovation `|ν|` (m) a manoeuvring track may show.
    pub margin_m: f64,
    /// `σ_m`: the velocity standard deviation per axis (m/s) re-opened on the track.
    pub velocity_std_mps: f64,
    /// `|Δv|max`: the largest velocity change (m/s) a target makes (a reversal at speed `v` is
    /// `2 v`).
    pub speed_change_mps: f64,
}

impl ManoeuvreFallback {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `manoeuvre.margin_m`,
    /// `manoeuvre.velocity_std_mps` or `manoeuvre.speed_change_mps` when negative or not finite.
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [
            ("manoeuvre.margin_m", self.margin_m),
            ("manoeuvre.velocity_std_mps", self.velocity_std_mps),
            ("manoeuvre.speed_change_mps", self.speed_change_mps),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(EngineError::InvalidParameter {
                    name,
                    reason: "must be finite and ≥ 0",
                });
            }
        }
        Ok(())
    }

    /// Which of `candidates` — the plausible tracks (`|ν| ≤ m`) of a range outside every gate
    /// at `time_s` — may take it: the only one, or else the only reachable one.
    pub(crate) fn choose(&self, candidates: &[Candidate], time_s: f64) -> Choice {
        match candidates {
            [] => return Choice::Nobody,
            [_] => return Choice::Candidate(0),
            _ => {}
        }
        // reachable: |ν| ≤ 3 √S + |Δv|max (t − t_last)
        let mut reachable = candidates.iter().enumerate().filter(|(_, c)| {
            let since_update_s = (time_s - c.last_update_s).max(0.0);
            c.innovation_abs_m <= REACH_SIGMAS * c.variance_m2.max(0.0).sqrt() + self.speed_change_mps * since_update_s
        });
        match (reachable.next(), reachable.next()) {
            (Some((only, _)), None) => Choice::Candidate(only),
            _ => Choice::Ambiguous,
        }
    }

    /// `prior` with its velocity re-opened: `P⁻ + diag(0, σ_m², 0, σ_m²)`.
    ///
    /// # Errors
    /// [`EngineError::Estimation`] if the result is not a valid covariance (cannot happen for
    /// a valid prior).
    pub(crate) fn open_velocity(&self, prior: &Gaussian<4>) -> Result<Gaussian<4>> {
        let opened = self.velocity_std_mps * self.velocity_std_mps;
        let mut covariance = *prior.covariance();
        covariance[(1, 1)] += opened;
        covariance[(3, 3)] += opened;
        Ok(Gaussian::new(*prior.mean(), covariance, prior.time_s())?)
    }
}

/// A plausible track for a range outside every gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Candidate {
    /// The track index.
    pub(crate) track: usize,
    /// `|ν| = |r − d̂|`, m.
    pub(crate) innovation_abs_m: f64,
    /// `S`, m².
    pub(crate) variance_m2: f64,
    /// Time of the track's last update, s.
    pub(crate) last_update_s: f64,
    /// The pair's `d² + ln |S|` (before the velocity is re-opened).
    pub(crate) cost: f64,
}

/// The outcome of [`ManoeuvreFallback::choose`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Choice {
    /// No plausible track.
    Nobody,
    /// The one candidate (its index) that can have made the range.
    Candidate(usize),
    /// Several plausible tracks, not exactly one reachable.
    Ambiguous,
}
