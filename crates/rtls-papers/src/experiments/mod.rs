//! The paper reproductions behind `rtls repro`: each experiment reads its scenario files
//! (TOML under `crates/rtls-papers/scenarios/`, embedded in the library so the defaults need no files), runs its
//! seeded Monte Carlo in parallel and returns an [`ExperimentReport`].
//!
//! | experiment | paper | scenario files |
//! | --- | --- | --- |
//! | `mekf` | seed 000 (ME-KF, mine personnel) | `000-mine-walk.toml`, `000-table-1.toml` |
//! | `ukf-uwb` | seed 001 (UKF over TOA + RSS) | `001-cv.toml`, `001-turn.toml` |
//! | `lwknn` | seed 002 (L-WKNN + accelerometer KF) | `002-field.toml`, `002-table-2.toml`, `002-noise-sweep.toml`, `002-model-order.toml` |
//! | `wsn-ekf` | seed 003 (single-range EKF, node scheduling) | `003-test-bed.toml` |
//! | `vdkf` | seed 004 (VD-KF, TDOA + odometry) | `004-vehicle.toml` |

use serde::de::DeserializeOwned;

use crate::error::{Result, SimError};
use crate::report::ExperimentReport;
use rtls_sim::montecarlo::Progress;

mod common;
pub mod lwknn;
pub mod mekf;
mod template;
pub mod ukf_uwb;
pub mod vdkf;
pub mod wsn_ekf;

/// A scenario file: its name (as listed in the table above) and its TOML text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioSource {
    /// File name, e.g. `001-cv.toml`.
    pub name: String,
    /// TOML text.
    pub text: String,
}

/// Monte Carlo settings shared by every experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReproOptions {
    /// Runs per configuration (the papers use 50 or 100).
    pub runs: usize,
    /// Base seed; run `i` uses [`rtls_sim::montecarlo::run_seed`]`(seed, i)`.
    pub seed: u64,
}

/// Parses `source` as the scenario type `T`, rejecting unknown keys.
///
/// # Errors
/// [`SimError::Scenario`] naming the file, with the parser's line, column and key.
///
/// # Example
/// ```
/// use rtls_papers::experiments::{parse_scenario, ScenarioSource};
/// #[derive(Debug, serde::Deserialize)]
/// #[serde(deny_unknown_fields)]
/// struct S { runs: usize }
/// let bad = ScenarioSource { name: "x.toml".into(), text: "runs = 5\nspeed = 2".into() };
/// let err = parse_scenario::<S>(&bad).unwrap_err().to_string();
/// assert!(err.contains("x.toml") && err.contains("speed") && err.contains("line 2"), "{err}");
/// ```
pub fn parse_scenario<T: DeserializeOwned>(source: &ScenarioSource) -> Result<T> {
    toml::from_str(&source.text).map_err(|e| SimError::Scenario {
        file: source.name.clone(),
        reason: e.to_string().trim_end().replace('\n', " "),
    })
}

/// The source called `name` among `sources`.
///
/// # Errors
/// [`SimError::Scenario`] if it is missing.
pub fn find_source<'a>(sources: &'a [ScenarioSource], name: &str) -> Result<&'a ScenarioSource> {
    sources
        .iter()
        .find(|s| s.name == name)
        .ok_or_else(|| SimError::Scenario {
            file: name.to_string(),
            reason: "the experiment needs this scenario file and it was not given".to_string(),
        })
}

/// The scenario files shipped in `crates/rtls-papers/scenarios/`, embedded at compile time.
const EMBEDDED: &[(&str, &str)] = &[
    ("000-mine-walk.toml", include_str!("../../scenarios/000-mine-walk.toml")),
    ("000-table-1.toml", include_str!("../../scenarios/000-table-1.toml")),
    ("001-cv.toml", include_str!("../../scenarios/001-cv.toml")),
    ("001-turn.toml", include_str!("../../scenarios/001-turn.toml")),
    ("002-field.toml", include_str!("../../scenarios/002-field.toml")),
    ("002-table-2.toml", include_str!("../../scenarios/002-table-2.toml")),
    (
        "002-noise-sweep.toml",
        include_str!("../../scenarios/002-noise-sweep.toml"),
    ),
    (
        "002-model-order.toml",
        include_str!("../../scenarios/002-model-order.toml"),
    ),
    ("003-test-bed.toml", include_str!("../../scenarios/003-test-bed.toml")),
    ("004-vehicle.toml", include_str!("../../scenarios/004-vehicle.toml")),
];

/// One of the five paper reproductions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExperimentId {
    /// Seed 000: ME-KF on a mine walk, PEL, error rates, Table 1 re-evaluated.
    Mekf,
    /// Seed 001: UKF vs EKF over joint UWB TOA + RSS, CV and coordinated-turn scenarios.
    UkfUwb,
    /// Seed 002: L-WKNN fingerprinting with accelerometer-aided Kalman tracking.
    Lwknn,
    /// Seed 003: multi-robot ultrasonic tracking with single-range EKF and node scheduling.
    WsnEkf,
    /// Seed 004: variable-dimension KF fusing cellular TDOA with odometry.
    Vdkf,
}

impl ExperimentId {
    /// All experiments, in paper order.
    pub const ALL: [Self; 5] = [Self::Mekf, Self::UkfUwb, Self::Lwknn, Self::WsnEkf, Self::Vdkf];

    /// The command-line name.
    ///
    /// # Example
    /// ```
    /// use rtls_papers::experiments::ExperimentId;
    /// assert_eq!(ExperimentId::UkfUwb.name(), "ukf-uwb");
    /// assert_eq!(ExperimentId::from_name("wsn-ekf"), Some(ExperimentId::WsnEkf));
    /// ```
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Mekf => "mekf",
            Self::UkfUwb => "ukf-uwb",
            Self::Lwknn => "lwknn",
            Self::WsnEkf => "wsn-ekf",
            Self::Vdkf => "vdkf",
        }
    }

    /// The experiment with command-line name `name`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Its scenario files' names.
    #[must_use]
    pub fn scenario_files(self) -> &'static [&'static str] {
        match self {
            Self::Mekf => &["000-mine-walk.toml", "000-table-1.toml"],
            Self::UkfUwb => &["001-cv.toml", "001-turn.toml"],
            Self::Lwknn => &[
                "002-field.toml",
                "002-table-2.toml",
                "002-noise-sweep.toml",
                "002-model-order.toml",
            ],
            Self::WsnEkf => &["003-test-bed.toml"],
            Self::Vdkf => &["004-vehicle.toml"],
        }
    }

    /// Run `run` of base seed `seed` of the experiment's main scenario as files — the site, the
    /// records and the truth that its "ours" row runs the engine's tracker on (what
    /// `rtls sim <experiment>` writes). `None` for an experiment whose "ours" row does not run
    /// the engine on a recording yet.
    ///
    /// # Errors
    /// [`SimError::Scenario`] for a missing or malformed scenario file; the simulation's errors.
    pub fn recording(
        self,
        sources: &[ScenarioSource],
        seed: u64,
        run: usize,
    ) -> Option<Result<crate::recording::Recording>> {
        match self {
            Self::Mekf => Some(mekf::recording(sources, seed, run)),
            Self::UkfUwb => Some(ukf_uwb::recording(sources, seed, run)),
            Self::Lwknn => Some(lwknn::recording(sources, seed, run)),
            Self::Vdkf => Some(vdkf::recording(sources, seed, run)),
            Self::WsnEkf => None,
        }
    }

    /// Its scenario files as shipped (embedded at compile time).
    #[must_use]
    pub fn embedded_scenarios(self) -> Vec<ScenarioSource> {
        self.scenario_files()
            .iter()
            .filter_map(|name| EMBEDDED.iter().find(|(n, _)| n == name))
            .map(|(name, text)| ScenarioSource {
                name: (*name).to_string(),
                text: (*text).to_string(),
            })
            .collect()
    }

    /// How many progress units (Monte Carlo runs over all configurations) [`Self::reproduce`]
    /// will report.
    ///
    /// # Errors
    /// As [`Self::reproduce`] for unreadable scenarios.
    pub fn work_units(self, sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
        match self {
            Self::Mekf => mekf::work_units(sources, options),
            Self::UkfUwb => ukf_uwb::work_units(sources, options),
            Self::Lwknn => lwknn::work_units(sources, options),
            Self::WsnEkf => wsn_ekf::work_units(sources, options),
            Self::Vdkf => vdkf::work_units(sources, options),
        }
    }

    /// Runs the experiment on `sources` and returns its report.
    ///
    /// # Errors
    /// [`SimError::Scenario`] for a missing or malformed scenario file; any simulation error.
    pub fn reproduce(
        self,
        sources: &[ScenarioSource],
        options: &ReproOptions,
        progress: Progress<'_>,
    ) -> Result<ExperimentReport> {
        if options.runs == 0 {
            return Err(SimError::InvalidParameter {
                name: "runs",
                reason: "a reproduction needs at least one Monte Carlo run",
            });
        }
        let mut report = match self {
            Self::Mekf => mekf::reproduce(sources, options, progress),
            Self::UkfUwb => ukf_uwb::reproduce(sources, options, progress),
            Self::Lwknn => lwknn::reproduce(sources, options, progress),
            Self::WsnEkf => wsn_ekf::reproduce(sources, options, progress),
            Self::Vdkf => vdkf::reproduce(sources, options, progress),
        }?;
        report.scenarios = self
            .scenario_files()
            .iter()
            .map(|s| format!("crates/rtls-papers/scenarios/{s}"))
            .collect();
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scenario_file_is_embedded() {
        for id in ExperimentId::ALL {
            assert_eq!(
                id.embedded_scenarios().len(),
                id.scenario_files().len(),
                "{}",
                id.name()
            );
        }
        assert!(find_source(&[], "x.toml").is_err());
    }
}
