//! Per-track adaptive measurement noise (`[tracker.adaptive_noise]`): one scale `λ ≥ 1` per
//! measurement class, applied to the stated noise before an update and re-estimated from the
//! update's innovation afterwards ([`rtls_estimation::adaptive`]).

use rtls_estimation::adaptive::correlation::{CorrelationEstimate, ErrorCorrelation};
use rtls_estimation::adaptive::{AdaptiveNoise, NoiseScale};

use super::outcome::UpdateOutcome;
use crate::site::AdaptiveNoiseSettings;

/// Measurement classes that keep separate noise scales: their errors come from different
/// physics, so one being worse than stated says nothing about the others.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NoiseClass {
    /// Tightly coupled ranges.
    Range,
    /// Tightly coupled RSSI.
    Rssi,
    /// Tightly coupled range differences.
    Tdoa,
    /// Position fixes: epoch fixes of fix-then-filter (but those solved from RSSI alone) and
    /// `fix` records.
    Fix,
    /// Fix-then-filter epoch fixes solved from RSSI readings alone (path-loss multilateration).
    RssiFix,
    /// Fingerprint fixes (`rssi_vector` scans located in the radio map).
    Fingerprint,
    /// Velocity and odometry.
    Velocity,
}

impl NoiseClass {
    /// Number of classes.
    pub const COUNT: usize = 7;

    /// Every class, in index order.
    pub const ALL: [Self; Self::COUNT] = [
        Self::Range,
        Self::Rssi,
        Self::Tdoa,
        Self::Fix,
        Self::RssiFix,
        Self::Fingerprint,
        Self::Velocity,
    ];

    /// The class's name in summaries: `range`, `rssi`, `tdoa`, `fix`, `rssi-fix`, `fingerprint`,
    /// `velocity`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Range => "range",
            Self::Rssi => "rssi",
            Self::Tdoa => "tdoa",
            Self::Fix => "fix",
            Self::RssiFix => "rssi-fix",
            Self::Fingerprint => "fingerprint",
            Self::Velocity => "velocity",
        }
    }

    /// The class of a component update, by the record kind that produced it (the `kind` the
    /// tracker names in events: `rssi_vector` is a fingerprint; `velocity` / `odometry` a
    /// velocity; every other position update a fix).
    /// The correlation time of the class's errors, s: `rssi_correlation_s` for fixes made of
    /// received signal strength (fixes solved from RSSI alone, fingerprint scans),
    /// `rssi_reading_correlation_s` for single RSSI readings, `correlation_s` for everything
    /// else (see [`AdaptiveNoiseSettings`]).
    pub(super) fn correlation_s(self, settings: &AdaptiveNoiseSettings) -> f64 {
        match self {
            Self::RssiFix | Self::Fingerprint => settings.rssi_correlation_s,
            Self::Rssi => settings.rssi_reading_correlation_s,
            Self::Range | Self::Tdoa | Self::Fix | Self::Velocity => settings.correlation_s,
        }
    }

    pub(super) fn of_component_kind(kind: &str, is_velocity: bool) -> Self {
        match (kind, is_velocity) {
            (_, true) => Self::Velocity,
            ("rssi_vector", false) => Self::Fingerprint,
            _ => Self::Fix,
        }
    }
}

/// Where a measurement comes from, for its error correlation in time: one reader's readings
/// of one class, or a whole class of component measurements (fixes, velocities).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(super) struct Source {
    pub(super) class: NoiseClass,
    /// The reader's index for anchor readings; `usize::MAX` for a class-wide source.
    pub(super) anchor: usize,
}

/// A track's noise scales, one per [`NoiseClass`], the time of each class's last update and of
/// each source's last measurement (a value the track owns).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct NoiseScales {
    scales: [NoiseScale; NoiseClass::COUNT],
    last_update_s: [f64; NoiseClass::COUNT],
    /// Each source's last measurement and error correlation, a handful per track.
    sources: Vec<SourceHistory>,
}

/// One source's time of its last measurement, s, and its innovations' correlation.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct SourceHistory {
    source: Source,
    last_s: f64,
    correlation: CorrelationEstimate,
}

impl Default for NoiseScales {
    fn default() -> Self {
        Self {
            scales: [NoiseScale::default(); NoiseClass::COUNT],
            last_update_s: [f64::NAN; NoiseClass::COUNT],
            sources: Vec::new(),
        }
    }
}

impl NoiseScales {
    /// The inflation `c = max(1, 2 τ_c / Δt, (1 + ρ̂)/(1 − ρ̂))` of a measurement's stated
    /// variance for errors correlated over `τ_c` (`correlation_s`), `Δt` after the same source's
    /// previous one, or with the lag-one correlation `ρ̂` the source's innovations showed
    /// (when `measured` is given: [`ErrorCorrelation`]); and records this one's time. The
    /// first term is `1` for a source's first measurement or `τ_c = 0`.
    ///
    /// A filter treats successive measurements as independent, so `n` of them within `τ_c`
    /// shrink its covariance `n` times although their errors, moving together, average out far
    /// less. Over a window `T ≫ τ_c` the mean of errors with correlation time `τ_c` has the
    /// variance `σ² · 2τ_c / T`, where independent samples every `Δt` would give `σ² Δt / T`:
    /// inflating each variance by `2τ_c / Δt` gives the filter the information the window
    /// really holds (the equivalent white noise of a Gauss–Markov error; Gelb, *Applied Optimal
    /// Estimation*, 1974, §3.8 and §4.6).
    pub(super) fn correlation_inflation(
        &mut self,
        source: Source,
        time_s: f64,
        correlation_s: f64,
        measured: Option<&ErrorCorrelation>,
    ) -> f64 {
        let (previous, from_innovations) = match self.sources.iter_mut().find(|h| h.source == source) {
            Some(history) => (
                Some(std::mem::replace(&mut history.last_s, time_s)),
                // (1 + ρ̂)/(1 − ρ̂)
                measured.map_or(1.0, |strategy| strategy.inflation(&history.correlation)),
            ),
            None => {
                self.sources.push(SourceHistory {
                    source,
                    last_s: time_s,
                    correlation: CorrelationEstimate::default(),
                });
                (None, 1.0)
            }
        };
        let from_time = match previous {
            // c = max(1, 2 τ_c / Δt); simultaneous readings of one source count as one interval
            Some(previous_s) if correlation_s > 0.0 => {
                let elapsed_s = (time_s - previous_s).max(1e-3);
                (2.0 * correlation_s / elapsed_s).max(1.0)
            }
            _ => 1.0,
        };
        from_time.max(from_innovations)
    }

    /// Adds an update's innovation to its source's correlation estimate: the normalised
    /// components `uᵢ = νᵢ / √Sᵢᵢ`. Innovations the estimator refuses (non-finite) are left out.
    pub(super) fn observe_correlation<const N: usize>(
        &mut self,
        measured: Option<&ErrorCorrelation>,
        source: Source,
        updated: &impl UpdateOutcome<N>,
    ) {
        let Some(strategy) = measured else {
            return;
        };
        let Some(history) = self.sources.iter_mut().find(|h| h.source == source) else {
            return;
        };
        let mut normalised = [0.0; 2];
        let m = updated.measurement_dim().min(2);
        for (i, u) in normalised.iter_mut().enumerate().take(m) {
            // uᵢ = νᵢ / √Sᵢᵢ
            *u = updated.innovation(i) / updated.innovation_variance(i).sqrt();
        }
        if let Ok(next) = strategy.observe(&history.correlation, updated.state().time_s(), &normalised[..m]) {
            history.correlation = next;
        }
    }

    /// `λ` of `class` (1 while adaptation is off or nothing was observed).
    pub(super) fn scale(&self, class: NoiseClass) -> f64 {
        self.scales[class as usize].scale()
    }

    /// Re-estimates `class`'s scale from an update computed with `λR`, given the stated `R`
    /// (row-major `m × m`) and the gate `γ` innovations are clipped to. An update whose numbers
    /// the estimator refuses (it already passed the filter's own checks) leaves the scale as it
    /// was.
    pub(super) fn observe<const N: usize>(
        &mut self,
        adaptive: Option<&AdaptiveNoise>,
        class: NoiseClass,
        updated: &impl UpdateOutcome<N>,
        stated_noise: &[f64],
        gate: f64,
    ) {
        let Some(adaptive) = adaptive else {
            return;
        };
        let m = updated.measurement_dim();
        if stated_noise.len() != m * m {
            return;
        }
        let index = class as usize;
        let time_s = updated.state().time_s();
        // Δt since the class's previous update (NaN before the first: the running mean rules)
        let elapsed_s = time_s - self.last_update_s[index];
        let slot = &mut self.scales[index];
        if let Ok(next) = updated.observe_noise(adaptive, slot, elapsed_s, stated_noise, gate) {
            *slot = next;
            self.last_update_s[index] = time_s;
        }
    }
}

/// Running totals of one class's innovations over a run: how well the stated (and adapted)
/// noise explains what the filter saw. A consistent filter has a mean NIS per degree of
/// freedom near 1.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InnovationTotals {
    /// Updates computed (accepted or gated out).
    pub updates: u64,
    /// `Σ m`, the measurement components.
    pub dof: u64,
    /// `Σ NIS` (each clipped at its validation gate, so one wild outlier does not dominate).
    pub nis: f64,
    /// `Σ ln N(ν; 0, S) = −½ Σ (NIS + ln |S| + m ln 2π)` with the clipped NIS: the innovation
    /// log-likelihood that `rtls tune` maximises.
    pub log_likelihood: f64,
    /// `Σ λ`, the adaptive noise scale in force at each update.
    pub noise_scale: f64,
}

impl InnovationTotals {
    /// Adds one update with the given NIS, `ln |S|`, `m` and clip gate, under scale `λ`.
    pub(super) fn add(&mut self, nis: f64, log_det_s: f64, m: usize, gate: f64, scale: f64) {
        let nis = nis.min(gate);
        self.updates += 1;
        self.dof += m as u64;
        self.nis += nis;
        // ln N(ν; 0, S) = −½ (νᵀS⁻¹ν + ln|S| + m ln 2π)
        self.log_likelihood -= 0.5 * (nis + log_det_s + m as f64 * (2.0 * core::f64::consts::PI).ln());
        self.noise_scale += scale;
    }

    /// Mean NIS per degree of freedom (`None` before any update).
    #[must_use]
    pub fn mean_nis_per_dof(&self) -> Option<f64> {
        (self.dof > 0).then(|| self.nis / self.dof as f64)
    }

    /// Mean adaptive noise scale `λ` (`None` before any update).
    #[must_use]
    pub fn mean_noise_scale(&self) -> Option<f64> {
        (self.updates > 0).then(|| self.noise_scale / self.updates as f64)
    }

    /// Adds another run's totals.
    pub fn merge(&mut self, other: &Self) {
        self.updates += other.updates;
        self.dof += other.dof;
        self.nis += other.nis;
        self.log_likelihood += other.log_likelihood;
        self.noise_scale += other.noise_scale;
    }
}

/// [`InnovationTotals`] per [`NoiseClass`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Innovations(pub [InnovationTotals; NoiseClass::COUNT]);

impl Innovations {
    /// The totals of `class`.
    #[must_use]
    pub fn of(&self, class: NoiseClass) -> &InnovationTotals {
        &self.0[class as usize]
    }

    /// Records one update of `class` computed with noise scale `scale`.
    pub(super) fn record<const N: usize>(
        &mut self,
        class: NoiseClass,
        updated: &impl UpdateOutcome<N>,
        gate: f64,
        scale: f64,
    ) {
        self.0[class as usize].add(
            updated.nis(),
            updated.log_det_innovation_covariance(),
            updated.measurement_dim(),
            gate,
            scale,
        );
    }

    /// The total innovation log-likelihood over every class.
    #[must_use]
    pub fn log_likelihood(&self) -> f64 {
        self.0.iter().map(|t| t.log_likelihood).sum()
    }

    /// Adds another run's totals.
    pub fn merge(&mut self, other: &Self) {
        for (mine, theirs) in self.0.iter_mut().zip(&other.0) {
            mine.merge(theirs);
        }
    }
}
