//! `ukf-uwb`: seed 001's UKF over joint UWB TOA + RSS, reproduced.
//!
//! Two scenario files: `001-cv.toml` (scenario 1, constant velocity, with the NLOS extension
//! and the variants that explore the UKF-versus-EKF gap) and `001-turn.toml` (scenario 2, a
//! constant-rate turn). Per Monte Carlo run ([`run_seed_001`]): the truth from the motion
//! model with process noise, TOA ranges and path losses from both stations, the single-epoch
//! TOA-RSS fixes, the paper's UKF (α = 0.01, β = 2, κ = 0) and EKF on the CV model (baselines,
//! as printed), ours — the engine's tracker on the run as a recording
//! ([`seed_001_recording`](crate::reproduction::seed_001::seed_001_recording)): UKF and EKF on
//! the coordinated turn with the rate as a state and an IMM of a CV and a CT mode — NEES/NIS,
//! and the measurement information at the truth. The variants run the baselines only. The report gives the paper's numbers beside
//! ours and the √PCRB, the figures of the paper (Fig. 1–8), and notes that explain every
//! difference.
//!
//! # Units
//! Metres, m/s, seconds, dB.
//!
//! # References
//! Yang Qian, Wang Yang, Zhao Hongmei, Cui Guangzhao, "UWB indoor tracking algorithm based on
//! UKF", *Journal of Light Industry* 32(1), 2017 (seed 001); P. Tichavský, C. H. Muravchik,
//! A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time nonlinear filtering", *IEEE
//! Trans. SP* 46(5), 1998.

mod analysis;
mod config;
mod figures;
mod metrics;
mod notes;

use super::{find_source, ReproOptions, ScenarioSource};
use crate::error::Result;
use crate::report::ExperimentReport;
use crate::reproduction::seed_001::{run_seed_001, run_seed_001_baselines, Seed001Config, Seed001Run};
use rtls_sim::montecarlo::{monte_carlo, Progress};

use analysis::{analyse, ScenarioAnalysis};
use config::{ReportSettings, Scenario};
use metrics::{scenario_metrics, tracker_table, variant_table, VariantResult, PAPER};

/// Scenario 1's file.
const CV_FILE: &str = "001-cv.toml";
/// Scenario 2's file.
const TURN_FILE: &str = "001-turn.toml";

/// Progress units of [`reproduce`]: one per Monte Carlo run of scenario 1, scenario 2 and each
/// variant of scenario 1.
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed scenario file.
///
/// # Example
/// ```
/// use rtls_papers::experiments::{ukf_uwb, ExperimentId, ReproOptions};
/// let sources = ExperimentId::UkfUwb.embedded_scenarios();
/// let units = ukf_uwb::work_units(&sources, &ReproOptions { runs: 10, seed: 1 })?;
/// assert!(units >= 20 && units % 10 == 0); // scenario 1, scenario 2 and the variants
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn work_units(sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    let (cv, _) = scenarios(sources)?;
    Ok((options.runs * (2 + cv.variants.len())) as u64)
}

/// Runs the reproduction of seed 001 on `sources` (`001-cv.toml`, `001-turn.toml`).
///
/// # Errors
/// [`crate::SimError::Scenario`] naming the file and the field for a missing or malformed
/// scenario; [`crate::SimError::InvalidParameter`] for zero runs; any simulation error.
///
/// # Example
/// ```
/// use rtls_papers::experiments::{ukf_uwb, ExperimentId, ReproOptions};
/// use rtls_sim::montecarlo::Progress;
/// let sources = ExperimentId::UkfUwb.embedded_scenarios();
/// let report = ukf_uwb::reproduce(&sources, &ReproOptions { runs: 4, seed: 1 }, Progress::none())?;
/// let ukf = report.metric("CV: UKF (CV) pooled RMSE after 10 s").expect("reported");
/// assert!(ukf.ours >= 0.9 * ukf.bound.expect("has a bound"));
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn reproduce(
    sources: &[ScenarioSource],
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<ExperimentReport> {
    let (cv, turn) = scenarios(sources)?;
    let (cv_analysis, cv_run) = run_and_analyse(&cv.config, &cv.report, options, progress)?;
    let (turn_analysis, turn_run) = run_and_analyse(&turn.config, &turn.report, options, progress)?;
    let variants = cv
        .variants
        .iter()
        .map(|variant| {
            let runs = monte_carlo(options.runs, options.seed, progress, |seed| {
                run_seed_001_baselines(&variant.config, seed)
            })?;
            Ok(VariantResult {
                analysis: analyse(&variant.config, &cv.report, &runs)?,
                variant: variant.clone(),
            })
        })
        .collect::<Result<Vec<_>>>()?;

    let mut report = ExperimentReport::new(
        "ukf-uwb",
        "Seed 001: UKF over joint UWB TOA + RSS (Yang et al., 2017)",
        options.runs,
        options.seed,
    );
    report
        .metrics
        .extend(scenario_metrics("CV", &cv.report, &cv_analysis, Some(&PAPER)));
    report
        .metrics
        .extend(scenario_metrics("turn", &turn.report, &turn_analysis, None));
    report.tables = vec![
        tracker_table("Scenario 1 (constant velocity)", &cv.report, &cv_analysis),
        tracker_table("Scenario 2 (turn)", &turn.report, &turn_analysis),
        variant_table(&cv_analysis, &variants),
    ];
    report.figures = figures::scenario_figures(
        "ukf-uwb-cv",
        "Scenario 1 (CV)",
        ("Fig. 5", "Fig. 4"),
        &cv.config,
        &cv_analysis,
        &cv_run,
    );
    report.figures.extend(figures::scenario_figures(
        "ukf-uwb-turn",
        "Scenario 2 (turn)",
        ("Fig. 6", "Fig. 8"),
        &turn.config,
        &turn_analysis,
        &turn_run,
    ));
    report.figures.push(figures::axis_error_figure(
        "ukf-uwb-turn",
        "Scenario 2 (turn)",
        &turn_analysis,
    ));
    report.figures.extend(figures::nlos_figure("ukf-uwb-cv", &cv_analysis));
    report.notes = notes::notes(&notes::NoteInputs {
        cv: &cv,
        turn: &turn,
        cv_analysis: &cv_analysis,
        turn_analysis: &turn_analysis,
        variants: &variants,
        seed: options.seed,
    });
    Ok(report)
}

/// Run `run` of base seed `seed` of the turn scenario as files: the site, the records and the
/// truth its engine rows track (`rtls sim ukf-uwb` writes them).
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed scenario file; the simulation's
/// errors (e.g. a path-loss law a site file cannot express).
pub fn recording(sources: &[ScenarioSource], seed: u64, run: usize) -> Result<crate::recording::Recording> {
    let turn = config::parse(find_source(sources, TURN_FILE)?)?;
    crate::reproduction::seed_001::seed_001_recording(&turn.config, rtls_sim::montecarlo::run_seed(seed, run))
}

/// Both scenario files, parsed and validated.
fn scenarios(sources: &[ScenarioSource]) -> Result<(Scenario, Scenario)> {
    Ok((
        config::parse(find_source(sources, CV_FILE)?)?,
        config::parse(find_source(sources, TURN_FILE)?)?,
    ))
}

/// The Monte Carlo runs of `config` (run seeds from `options`), analysed; also returns run 0
/// for the single-run figures.
fn run_and_analyse(
    config: &Seed001Config,
    settings: &ReportSettings,
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<(ScenarioAnalysis, Seed001Run)> {
    let runs = monte_carlo(options.runs, options.seed, progress, |seed| run_seed_001(config, seed))?;
    let analysis = analyse(config, settings, &runs)?;
    let first = runs
        .into_iter()
        .next()
        .ok_or(crate::SimError::EmptyInput { what: "seed 001 runs" })?;
    Ok((analysis, first))
}
