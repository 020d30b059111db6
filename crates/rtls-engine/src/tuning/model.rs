//! The error-correlation settings `rtls tune` fits at the chosen `σ_a`: the correlation time of
//! ranges and fixes, learning it from the innovations, and the heading's (see the
//! [module documentation](super)).

use super::{choose, run_candidate, Candidate, TuningSettings, COVERAGE_BAND};
use crate::error::Result;
use crate::evaluation::TruthSample;
use crate::radio_map::RadioMap;
use crate::record::{Measurement, Record};
use crate::site::Site;

/// The error-correlation settings [`tune`](super::tune) tries at the chosen `σ_a`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSettings {
    /// `[tracker.adaptive_noise] correlation_s`, s.
    pub correlation_s: f64,
    /// `[tracker.adaptive_noise] correlation_from_innovations`.
    pub correlation_from_innovations: bool,
    /// `[tracker.heading] heading_error_correlation_s`, s.
    pub heading_error_correlation_s: f64,
}

impl ModelSettings {
    pub(super) fn of(site: &Site) -> Self {
        Self {
            correlation_s: site.tracker.adaptive_noise.correlation_s,
            correlation_from_innovations: site.tracker.adaptive_noise.correlation_from_innovations,
            heading_error_correlation_s: site.tracker.heading.heading_error_correlation_s,
        }
    }

    pub(super) fn apply(self, site: &mut Site) {
        site.tracker.adaptive_noise.correlation_s = self.correlation_s;
        site.tracker.adaptive_noise.correlation_from_innovations = self.correlation_from_innovations;
        site.tracker.heading.heading_error_correlation_s = self.heading_error_correlation_s;
    }
}

/// The error-correlation settings tried (the site's own first) with their runs, and the one
/// chosen.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelChoice {
    /// Each setting tried and how its run did.
    pub tried: Vec<(ModelSettings, Candidate)>,
    /// Index of the chosen one in `tried`.
    pub chosen: usize,
}

impl ModelChoice {
    /// The chosen settings.
    #[must_use]
    pub fn settings(&self) -> ModelSettings {
        self.tried[self.chosen].0
    }
}

/// The heading-error correlation time tried when the recording has speeds, s.
pub const HEADING_CORRELATION_CANDIDATE_S: f64 = 10.0;

/// The error correlation times of ranges and fixes tried besides the site's, s: errors that
/// persist for a second, and for seconds (multipath that moves with a walking tag, a Wi-Fi
/// RTT or GNSS error in one place). The default, 0.25 s, is UWB multipath's.
pub const CORRELATION_CANDIDATES_S: [f64; 2] = [1.0, 3.0];

/// Tries the error-correlation settings at the chosen `σ_a` (see the
/// [module documentation](super)) and leaves the best in `site`.
pub(super) fn choose_model(
    site: &mut Site,
    radio_map: Option<&RadioMap>,
    records: &[Record],
    truth: Option<&[TruthSample]>,
    settings: &TuningSettings,
    chosen: &Candidate,
) -> Result<ModelChoice> {
    let own = ModelSettings::of(site);
    let has_speeds = records.iter().any(|r| {
        matches!(
            r.measurement,
            Measurement::Odometry { .. } | Measurement::OdometryIncrement { .. }
        )
    });
    // with the heading's error considered (not under the IMM) the setting has no effect
    let inflates_headings =
        !site.tracker.heading.consider_heading_error || site.tracker.motion_model == crate::site::MotionModelKind::Imm;
    let headings = if has_speeds && inflates_headings {
        let other = if own.heading_error_correlation_s > 0.0 {
            0.0
        } else {
            HEADING_CORRELATION_CANDIDATE_S
        };
        vec![own.heading_error_correlation_s, other]
    } else {
        vec![own.heading_error_correlation_s]
    };
    let mut correlations = vec![own.correlation_s];
    correlations.extend(CORRELATION_CANDIDATES_S.iter().filter(|&&c| c != own.correlation_s));
    let mut tried = vec![(own, chosen.clone())];
    for correlation_s in correlations {
        for heading_error_correlation_s in headings.iter().copied() {
            for correlation_from_innovations in [own.correlation_from_innovations, !own.correlation_from_innovations] {
                let candidate = ModelSettings {
                    correlation_s,
                    correlation_from_innovations,
                    heading_error_correlation_s,
                };
                if candidate == own {
                    continue;
                }
                let mut trial = site.clone();
                candidate.apply(&mut trial);
                tried.push((candidate, run_candidate(&trial, radio_map, records, truth, settings)?));
            }
        }
    }
    let runs: Vec<Candidate> = tried.iter().map(|(_, c)| c.clone()).collect();
    let best = choose_model_run(&runs).unwrap_or(0);
    tried[best].0.apply(site);
    Ok(ModelChoice { tried, chosen: best })
}

/// The error-correlation run to keep (see the [module documentation](self)): [`choose`]'s,
/// unless truth scored every run and that one's ellipses hold the truth less than 90 % of the
/// time ([`COVERAGE_BAND`]); then, among the runs whose coverage is higher and whose RMSE is
/// within one standard error of its RMSE, the one whose coverage is nearest 95 % (on a tie,
/// the first tried). It never picks narrower ellipses than [`choose`]'s.
///
/// # Example
/// A run at 70 % gives way to one at 94 % within its standard error (in `tuning/tests.rs`:
/// `an_overconfident_least_rmse_run_gives_way_…`).
pub(super) fn choose_model_run(runs: &[Candidate]) -> Option<usize> {
    let best = choose(runs)?;
    let (Some(rmse_m), Some(inside)) = (runs[best].rmse_m, runs[best].inside_95) else {
        return Some(best);
    };
    if inside >= COVERAGE_BAND.0 {
        return Some(best);
    }
    let within_m = rmse_m + runs[best].rmse_standard_error_m.unwrap_or(0.0);
    let miss = |c: &Candidate| c.inside_95.map_or(f64::INFINITY, |i| (i - 0.95).abs());
    let wider = runs.iter().enumerate().filter(|(_, c)| {
        c.updates > 0 && c.rmse_m.is_some_and(|r| r <= within_m) && c.inside_95.is_some_and(|i| i > inside)
    });
    // (any wider run is nearer 95 % than one below 90 %: its coverage is in (that, 1])
    let nearest = wider.min_by(|a, b| miss(a.1).total_cmp(&miss(b.1)));
    Some(nearest.map_or(best, |(i, _)| i))
}
