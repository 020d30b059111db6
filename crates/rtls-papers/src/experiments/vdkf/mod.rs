//! `rtls repro vdkf`: seed 004's vehicle run — raw cellular TDOA fixes, a KF on the fixes, the
//! variable-dimension KF fused with odometry, and ours: the engine's tracker (IMM, tightly
//! coupled TDOA, odometry through its heading channel) on the same data as a recording — with
//! per-phase errors, manoeuvre detection, the engine's NEES and the PCRB.

use nalgebra::{DMatrix, Vector4};
use rtls_estimation::aided::{OdometryErrorModel, OdometryReading as OdometryInput};
use rtls_estimation::manoeuvre::VdMode;
use rtls_estimation::measurement::{MeasurementModel, NoiseCovariance, Tdoa};
use rtls_estimation::motion::{ConstantVelocity, LinearMotionModel, NoiseGain, ProcessNoise};
use rtls_estimation::stats::{average_consistency_interval, ConsistencyInterval};
use rtls_positioning::tdoa::cyclic_reference;

use super::common::{cdf_series, decimate, dynamic, fmt, pooled_rmse, rmse_over_time, squared_errors};
use super::template::{files::VDKF as T, render};
use super::{find_source, parse_scenario, ReproOptions, ScenarioSource};
use crate::error::{Result, SimError};
use crate::report::{ExperimentReport, Figure, Metric, Series, SeriesStyle, Table};
use crate::reproduction::{run_seed_004, Seed004Config, Seed004Run};
use rtls_sim::metrics::average_over_runs;
use rtls_sim::montecarlo::{monte_carlo, Progress};
use rtls_sim::pcrb::{measurement_information, pooled_rmse_bound, posterior_crb, rmse_bound, PcrbStep};
use rtls_sim::scenarios::{seed_004_phases, seed_004_trajectory, MotionPhase};

mod scenario;

pub use scenario::{DetectorSection, FilterSection, OdometerSection, TdoaSection, VehicleScenario};

const FILE: &str = "004-vehicle.toml";

/// The metric of ours: the engine's tracker on the recording.
pub const IMM_METRIC: &str = "RMSE: IMM CV/CA/CT on TDOA + odometry, engine tracker (ours)";

/// Confidence of the NEES interval.
const NEES_CONFIDENCE: f64 = 0.95;

/// Progress units: one per run.
///
/// # Errors
/// [`SimError::Scenario`] if the scenario is missing or malformed.
pub fn work_units(sources: &[ScenarioSource], options: &ReproOptions) -> Result<u64> {
    parse_scenario::<VehicleScenario>(find_source(sources, FILE)?)?.config()?;
    // the configuration as shipped and the paper's raw-heading fusion
    Ok(2 * options.runs as u64)
}

/// Squared errors of one run, per estimator.
struct RunErrors {
    /// `None` where there was no fix.
    fixes: Vec<Option<f64>>,
    kf: Vec<f64>,
    vd: Vec<f64>,
    /// Ours: the engine's tracker.
    imm: Vec<f64>,
    /// The engine's position NEES `eᵀ P⁻¹ e` at each epoch.
    imm_nees: Vec<f64>,
}

fn run_errors(run: &Seed004Run) -> Result<RunErrors> {
    let truth = run.truth_positions();
    let fixes = run
        .fixes
        .iter()
        .zip(&truth)
        .map(|(fix, t)| fix.map(|f| (f[0] - t[0]).powi(2) + (f[1] - t[1]).powi(2)))
        .collect();
    let imm_nees = run
        .engine
        .iter()
        .zip(&truth)
        .map(|(estimate, t)| {
            let estimate = estimate.as_ref().ok_or(SimError::EmptyInput {
                what: "seed 004 engine state at an epoch (no track update yet)",
            })?;
            position_nees(estimate.position_m, estimate.covariance_m2, *t)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(RunErrors {
        fixes,
        kf: squared_errors(&truth, &run.kf)?,
        vd: squared_errors(&truth, &run.vd)?,
        imm: squared_errors(&truth, &run.engine_positions()?)?,
        imm_nees,
    })
}

/// `eᵀ P⁻¹ e` of a 2-D position estimate with covariance `[P_xx, P_xy, P_yy]`.
fn position_nees(estimate: [f64; 2], covariance: [f64; 3], truth: [f64; 2]) -> Result<f64> {
    let (ex, ey) = (estimate[0] - truth[0], estimate[1] - truth[1]);
    let [pxx, pxy, pyy] = covariance;
    // P⁻¹ = [[P_yy, −P_xy], [−P_xy, P_xx]] / det P
    let det = pxx * pyy - pxy * pxy;
    if !(det.is_finite() && det > 0.0 && pxx > 0.0) {
        return Err(SimError::InvalidParameter {
            name: "engine position covariance",
            reason: "must be symmetric positive definite",
        });
    }
    Ok((pyy * ex * ex - 2.0 * pxy * ex * ey + pxx * ey * ey) / det)
}

/// The PCRB of the `[x, vx, y, vy]` state along the (deterministic) truth: CV dynamics with the
/// KF's `Q`; per epoch the information of the three range differences (cyclic reference, the
/// Gaussian of the same variance) plus that of the odometry velocity without drift.
fn bound(config: &Seed004Config, run: &Seed004Run) -> Result<Vec<DMatrix<f64>>> {
    let cv = ConstantVelocity::new(ProcessNoise::discrete(config.cv_variance, NoiseGain::seed_004_cv()))
        .map_err(SimError::estimation(0.0))?;
    let transition = dynamic(&LinearMotionModel::<4>::transition_matrix(&cv, 1.0));
    let process_noise = dynamic(&LinearMotionModel::<4>::process_noise_matrix(&cv, 1.0));
    let stations = &config.tdoa.stations;
    let variance = config.tdoa.range_difference_variance_m2();
    let velocity_model = OdometryErrorModel::new(
        config.odometer.speed_std_mps,
        config.odometry_model.heading_std_rad(),
        0.0,
    )
    .map_err(SimError::estimation(0.0))?;
    let velocity_selection = DMatrix::from_row_slice(2, 4, &[0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let mut steps = Vec::with_capacity(run.truth.len());
    let mut heading_rad = 0.0;
    for (k, sample) in run.truth.iter().enumerate() {
        let t = sample.time_s;
        let x = Vector4::new(
            sample.position_m[0],
            sample.velocity_mps[0],
            sample.position_m[1],
            sample.velocity_mps[1],
        );
        let reference = cyclic_reference(k as u64, stations.len())?;
        let tdoa = Tdoa::planar(
            stations,
            reference,
            NoiseCovariance::isotropic(stations.len() - 1, variance).map_err(SimError::estimation(t))?,
        )
        .map_err(SimError::estimation(t))?;
        let h = tdoa.jacobian(&x).map_err(SimError::estimation(t))?;
        let h = DMatrix::from_column_slice(h.nrows(), 4, h.as_slice());
        let mut information = measurement_information(&h, MeasurementModel::<4>::noise_covariance(&tdoa))?;
        heading_rad = sample.heading_rad().unwrap_or(heading_rad);
        let reading = OdometryInput {
            speed_mps: sample.speed_mps(),
            heading_rad,
        };
        let (_, r_v) = velocity_model.velocity(&reading, t).map_err(SimError::estimation(t))?;
        information += measurement_information(&velocity_selection, &dynamic::<2, 2>(&r_v))?;
        steps.push(PcrbStep {
            transition: transition.clone(),
            process_noise: process_noise.clone(),
            measurement_information: information,
        });
    }
    // no prior knowledge of the start: a vague prior (10 km, 100 m/s)
    let prior = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1e8, 1e4, 1e8, 1e4]));
    posterior_crb(&prior, steps)
}

/// Run `run` of base seed `seed` of the vehicle scenario as files: the site, the records and the
/// truth its "ours" row tracks (`rtls sim vdkf` writes them).
///
/// # Errors
/// [`crate::SimError::Scenario`] for a missing or malformed scenario file; the simulation's
/// errors.
pub fn recording(sources: &[ScenarioSource], seed: u64, run: usize) -> Result<crate::recording::Recording> {
    let config = parse_scenario::<VehicleScenario>(find_source(sources, FILE)?)?.config()?;
    crate::reproduction::seed_004::seed_004_recording(&config, rtls_sim::montecarlo::run_seed(seed, run))
}

/// Runs the reproduction.
///
/// # Errors
/// [`SimError::Scenario`] for a bad scenario; any simulation error.
pub fn reproduce(
    sources: &[ScenarioSource],
    options: &ReproOptions,
    progress: Progress<'_>,
) -> Result<ExperimentReport> {
    let config = parse_scenario::<VehicleScenario>(find_source(sources, FILE)?)?.config()?;
    let runs = monte_carlo(options.runs, options.seed, progress, |seed| run_seed_004(&config, seed))?;
    let errors = runs.iter().map(run_errors).collect::<Result<Vec<_>>>()?;
    // the paper's fusion: the raw, drifting heading with the drift as a growing variance
    let as_paper = Seed004Config {
        estimate_heading_drift: false,
        ..config.clone()
    };
    let paper_runs = monte_carlo(options.runs, options.seed, progress, |seed| {
        run_seed_004(&as_paper, seed)
    })?;
    let paper_vd = paper_runs
        .iter()
        .map(|run| squared_errors(&run.truth_positions(), &run.vd))
        .collect::<Result<Vec<_>>>()?;
    let first = &runs[0];
    let bounds = bound(&config, first)?;
    let epochs = first.truth.len();

    let kf: Vec<Vec<f64>> = errors.iter().map(|e| e.kf.clone()).collect();
    let vd: Vec<Vec<f64>> = errors.iter().map(|e| e.vd.clone()).collect();
    let imm: Vec<Vec<f64>> = errors.iter().map(|e| e.imm.clone()).collect();
    // the engine's consistency: the run-averaged position NEES per epoch against its interval
    let nees_interval =
        average_consistency_interval(2, runs.len(), NEES_CONFIDENCE).map_err(SimError::estimation(0.0))?;
    let nees_per_epoch = average_over_runs(&errors.iter().map(|e| e.imm_nees.clone()).collect::<Vec<_>>())?;
    let mean_nees = nees_per_epoch.iter().sum::<f64>() / nees_per_epoch.len().max(1) as f64;
    let nees_inside = 100.0 * nees_per_epoch.iter().filter(|v| nees_interval.contains(**v)).count() as f64
        / nees_per_epoch.len().max(1) as f64;
    let fixes: Vec<Vec<f64>> = errors
        .iter()
        .map(|e| e.fixes.iter().flatten().copied().collect())
        .collect();
    let fix_count: usize = fixes.iter().map(Vec::len).sum();
    let availability = 100.0 * fix_count as f64 / (epochs * runs.len()) as f64;
    let bound_all = pooled_rmse_bound(&bounds, &[0, 2])?;
    let (rmse_fix, rmse_kf, rmse_raw, rmse_vd, rmse_imm) = (
        pooled_rmse(&fixes)?,
        pooled_rmse(&kf)?,
        pooled_rmse(&paper_vd)?,
        pooled_rmse(&vd)?,
        pooled_rmse(&imm)?,
    );

    let mut report = ExperimentReport::new(
        "vdkf",
        "Seed 004 — variable-dimension KF fusing cellular TDOA with odometry",
        options.runs,
        options.seed,
    );
    report.metrics = vec![
        Metric::new("TDOA fix availability (Chan + Taylor)", "%", availability),
        Metric::new("RMSE: raw TDOA fixes", "m", rmse_fix),
        Metric::new("RMSE: KF (CV) on fixes", "m", rmse_kf).bound(bound_all),
        Metric::new("RMSE: VD-KF, raw drifting heading (as the paper)", "m", rmse_raw).bound(bound_all),
        Metric::new("RMSE: VD-KF, heading drift estimated", "m", rmse_vd).bound(bound_all),
        Metric::new(IMM_METRIC, "m", rmse_imm).bound(bound_all),
        Metric::new("Mean NEES, position, engine (2 if consistent)", "", mean_nees),
        Metric::new(
            "Epochs whose run-averaged NEES is in its 95 % interval, engine",
            "%",
            nees_inside,
        ),
        Metric::new(
            "RMSE ratio VD-KF (drift estimated) / KF (paper: VD-KF better, < 1)",
            "",
            rmse_vd / rmse_kf,
        ),
    ];

    // per-phase RMSE, and the paper's claim that fusion is slightly worse on quiet legs
    let phases = seed_004_phases();
    let mut rows = Vec::new();
    for (start, end, phase) in phases {
        let range = (start as usize).min(epochs)..(end as usize).min(epochs);
        let slice = |all: &[Vec<f64>]| all.iter().map(|r| r[range.clone()].to_vec()).collect::<Vec<_>>();
        let b = pooled_rmse_bound(&bounds[range.clone()], &[0, 2])?;
        rows.push(vec![
            format!("{start:.0}–{end:.0} s {}", phase_name(phase)),
            fmt(pooled_rmse(&slice(&kf))?, 1),
            fmt(pooled_rmse(&slice(&paper_vd))?, 1),
            fmt(pooled_rmse(&slice(&vd))?, 1),
            fmt(pooled_rmse(&slice(&imm))?, 1),
            fmt(b, 1),
        ]);
    }
    report.tables.push(Table {
        title: "RMSE per motion phase (m), pooled over runs".to_string(),
        header: [
            "phase",
            "KF on fixes",
            "VD-KF, raw heading",
            "VD-KF, drift estimated",
            "IMM, engine (ours)",
            "√PCRB",
        ]
        .map(String::from)
        .to_vec(),
        rows,
    });

    // manoeuvre detection by the VD-KF
    let detected = |onset_s: f64, window_s: f64| {
        let hits = runs
            .iter()
            .filter(|run| {
                run.vd_events.iter().any(|e| {
                    e.to == VdMode::ConstantAcceleration && e.time_s >= onset_s && e.time_s <= onset_s + window_s
                })
            })
            .count();
        100.0 * hits as f64 / runs.len() as f64
    };
    report.metrics.push(Metric::new(
        "VD-KF detects the stop within 5 s",
        "%",
        detected(400.0, 5.0),
    ));
    report.metrics.push(Metric::new(
        "VD-KF detects the start within 5 s",
        "%",
        detected(450.0, 5.0),
    ));
    report.metrics.push(Metric::new(
        "VD-KF detects the turn within 20 s",
        "%",
        detected(900.0, 20.0),
    ));
    let cv_share = {
        let mut in_cv = 0usize;
        let mut total = 0usize;
        for run in &runs {
            for (sample, mode) in run.truth.iter().zip(&run.vd_modes) {
                if (20.0..400.0).contains(&sample.time_s) || (470.0..900.0).contains(&sample.time_s) {
                    total += 1;
                    in_cv += usize::from(*mode == VdMode::ConstantVelocity);
                }
            }
        }
        100.0 * in_cv as f64 / total.max(1) as f64
    };
    report
        .metrics
        .push(Metric::new("VD-KF in CV on straight legs", "%", cv_share));

    report.figures = figures(first, &errors, &bounds)?;
    let phase = |all: &[Vec<f64>], from: usize, to: usize| {
        pooled_rmse(
            &all.iter()
                .map(|r| r[from.min(epochs)..to.min(epochs)].to_vec())
                .collect::<Vec<_>>(),
        )
    };
    let findings = Findings {
        fixes: rmse_fix,
        raw: rmse_raw,
        quiet_kf: phase(&kf, 0, 400)?,
        quiet_raw: phase(&paper_vd, 0, 400)?,
        quiet_estimated: phase(&vd, 0, 400)?,
        late_raw: phase(&paper_vd, 1000, 1500)?,
        late_estimated: phase(&vd, 1000, 1500)?,
    };
    let consistency = Consistency {
        mean_nees,
        nees_inside,
        interval: nees_interval,
    };
    report.notes = notes(
        &config,
        &report,
        &findings,
        &consistency,
        [rmse_kf, rmse_vd, rmse_imm, bound_all],
    )?;
    Ok(report)
}

fn phase_name(phase: MotionPhase) -> &'static str {
    match phase {
        MotionPhase::ConstantVelocity => "cruise",
        MotionPhase::Stopped => "stopped",
        MotionPhase::Turn => "turn",
        MotionPhase::Decelerating => "deceleration",
    }
}

fn figures(first: &Seed004Run, errors: &[RunErrors], bounds: &[DMatrix<f64>]) -> Result<Vec<Figure>> {
    let truth = first.truth_positions();
    let line = |label: &str, points: &[[f64; 2]]| Series::new(label, SeriesStyle::Line, decimate(points.to_vec(), 750));
    let trajectory = Figure::new(
        "vdkf-trajectory",
        "Seed 004 run 0: truth, TDOA fixes, KF, VD-KF and IMM (cf. the paper's Fig. 4–5)",
        "x (m)",
        "y (m)",
    )
    .equal_aspect()
    .with(Series::new(
        "TDOA fixes",
        SeriesStyle::Points,
        decimate(first.fixes.iter().flatten().copied().collect(), 500),
    ))
    .with(line("truth", &truth))
    .with(line("KF on fixes", &first.kf))
    .with(line("VD-KF + odometry", &first.vd))
    .with(line("IMM, engine (ours)", &first.engine_positions()?));

    let over_time =
        |label: &str, style: SeriesStyle, values: &[f64]| Series::over_index(label, style, 1.0, 1.0, values);
    let per_run = |pick: fn(&RunErrors) -> &Vec<f64>| errors.iter().map(|e| pick(e).clone()).collect::<Vec<_>>();
    // fixes: RMSE over the runs that had a fix at each epoch (epochs where none had one are left out)
    let fix_rmse: Vec<[f64; 2]> = (0..truth.len())
        .filter_map(|k| {
            let available: Vec<f64> = errors.iter().filter_map(|e| e.fixes[k]).collect();
            (!available.is_empty()).then(|| {
                [
                    (k + 1) as f64,
                    (available.iter().sum::<f64>() / available.len() as f64).sqrt(),
                ]
            })
        })
        .collect();
    let bound_over_time = bounds
        .iter()
        .map(|b| rmse_bound(b, &[0, 2]))
        .collect::<Result<Vec<_>>>()?;
    let rmse = Figure::new(
        "vdkf-rmse",
        "Seed 004: RMSE over time over the runs (cf. Fig. 6), with the √PCRB",
        "time (s)",
        "RMSE (m)",
    )
    .with(Series::new("TDOA fixes", SeriesStyle::Points, fix_rmse))
    .with(over_time(
        "KF on fixes",
        SeriesStyle::Line,
        &rmse_over_time(&per_run(|e| &e.kf))?,
    ))
    .with(over_time(
        "VD-KF + odometry",
        SeriesStyle::Line,
        &rmse_over_time(&per_run(|e| &e.vd))?,
    ))
    .with(over_time(
        "IMM, engine (ours)",
        SeriesStyle::Line,
        &rmse_over_time(&per_run(|e| &e.imm))?,
    ))
    .with(over_time("√PCRB", SeriesStyle::Dashed, &bound_over_time));

    let all = |pick: fn(&RunErrors) -> &Vec<f64>| {
        errors
            .iter()
            .flat_map(|e| pick(e).iter().map(|v| v.sqrt()))
            .collect::<Vec<_>>()
    };
    let fixes: Vec<f64> = errors
        .iter()
        .flat_map(|e| e.fixes.iter().flatten().map(|v| v.sqrt()))
        .collect();
    let cdf = Figure::new(
        "vdkf-cdf",
        "Seed 004: CDF of the position error, all runs",
        "error (m)",
        "P(error ≤ e)",
    )
    .with(cdf_series("TDOA fixes", &fixes)?)
    .with(cdf_series("KF on fixes", &all(|e| &e.kf))?)
    .with(cdf_series("VD-KF + odometry", &all(|e| &e.vd))?)
    .with(cdf_series("IMM, engine (ours)", &all(|e| &e.imm))?);

    // the engine reports its most probable mode; drawn at 1 (CV), 2 (CA), 3 (CT)
    let engine_mode: Vec<f64> = first
        .engine
        .iter()
        .map(|e| match e.as_ref().and_then(|e| e.mode) {
            Some("CV") => 1.0,
            Some("CA") => 2.0,
            Some("CT") => 3.0,
            _ => 0.0,
        })
        .collect();
    let modes = Figure::new(
        "vdkf-modes",
        "Seed 004 run 0: the engine IMM's most probable mode (1 = CV, 2 = CA, 3 = CT) and the VD-KF's model (1 = CA)",
        "time (s)",
        "mode",
    )
    .with(over_time("engine IMM mode", SeriesStyle::Line, &engine_mode))
    .with(over_time(
        "VD-KF in CA",
        SeriesStyle::Dashed,
        &first
            .vd_modes
            .iter()
            .map(|m| f64::from(u8::from(*m == VdMode::ConstantAcceleration)))
            .collect::<Vec<_>>(),
    ));
    Ok(vec![trajectory, rmse, cdf, modes])
}

/// Per-phase figures quoted in the notes, m.
struct Findings {
    fixes: f64,
    raw: f64,
    quiet_kf: f64,
    quiet_raw: f64,
    quiet_estimated: f64,
    late_raw: f64,
    late_estimated: f64,
}

/// The engine's NEES over the runs.
struct Consistency {
    mean_nees: f64,
    nees_inside: f64,
    interval: ConsistencyInterval,
}

fn notes(
    config: &Seed004Config,
    report: &ExperimentReport,
    findings: &Findings,
    consistency: &Consistency,
    [rmse_kf, rmse_vd, rmse_imm, bound_all]: [f64; 4],
) -> Result<Vec<String>> {
    let trajectory = seed_004_trajectory(config.speed_mps)?;
    let stations = config
        .tdoa
        .stations
        .iter()
        .map(|s| format!("({:.0}, {:.0})", s[0], s[1]))
        .collect::<Vec<_>>()
        .join(", ");
    let manoeuvre_percent = |name: &str| report.metric(name).map_or(0.0, |m| m.ours);
    Ok(vec![
        render!(
            T,
            "setup",
            duration_s = fmt(trajectory.duration_s(), 0),
            speed_mps = config.speed_mps,
            stations = stations,
            gaussian_ns = fmt(config.tdoa.gaussian_std_s * 1e9, 0),
            nlos_max_ns = fmt(config.tdoa.nlos_uniform_max_s * 1e9, 0),
            calibration_points = config.calibration_points,
            odometer_speed_std_mps = config.odometer.speed_std_mps,
            filter_settings = render!(
                T,
                "filter-settings",
                cv_variance = config.cv_variance,
                ca_variance = config.ca_variance
            ),
        ),
        render!(
            T,
            "paper-and-ours",
            raw_rmse_m = fmt(findings.raw, 1),
            kf_rmse_m = fmt(rmse_kf, 1),
            raw_verdict = render!(
                T,
                if findings.raw > rmse_kf {
                    "raw-worse"
                } else {
                    "raw-better"
                }
            ),
            fixes_rmse_m = fmt(findings.fixes, 1),
            estimated_rmse_m = fmt(rmse_vd, 1),
            estimated_to_kf = fmt(rmse_vd / rmse_kf, 2),
            quiet_kf_m = fmt(findings.quiet_kf, 1),
            quiet_raw_m = fmt(findings.quiet_raw, 1),
            quiet_estimated_m = fmt(findings.quiet_estimated, 1),
            late_raw_m = fmt(findings.late_raw, 1),
            late_estimated_m = fmt(findings.late_estimated, 1),
        ),
        render!(
            T,
            "best",
            imm_rmse_m = fmt(rmse_imm, 1),
            vd_rmse_m = fmt(rmse_vd, 1),
            imm_verdict = render!(
                T,
                if rmse_imm < rmse_vd {
                    "engine-better"
                } else {
                    "engine-worse"
                }
            ),
            mean_nees = fmt(consistency.mean_nees, 2),
            nees_lower = fmt(consistency.interval.lower, 2),
            nees_upper = fmt(consistency.interval.upper, 2),
            nees_inside = fmt(consistency.nees_inside, 0),
        ),
        render!(
            T,
            "pcrb",
            bound_m = fmt(bound_all, 1),
            vd_ratio = fmt(rmse_vd / bound_all, 1),
            imm_ratio = fmt(rmse_imm / bound_all, 2),
        ),
        render!(
            T,
            "manoeuvres",
            stop_percent = fmt(manoeuvre_percent("VD-KF detects the stop within 5 s"), 0),
            start_percent = fmt(manoeuvre_percent("VD-KF detects the start within 5 s"), 0),
            turn_percent = fmt(manoeuvre_percent("VD-KF detects the turn within 20 s"), 0),
            cv_percent = fmt(manoeuvre_percent("VD-KF in CV on straight legs"), 1),
        ),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn source(text: &str) -> Vec<ScenarioSource> {
        vec![ScenarioSource {
            name: FILE.into(),
            text: text.into(),
        }]
    }

    #[test]
    fn the_shipped_scenario_is_the_default_configuration() {
        let shipped = super::super::ExperimentId::Vdkf.embedded_scenarios();
        let config = parse_scenario::<VehicleScenario>(&shipped[0])
            .unwrap()
            .config()
            .unwrap();
        assert_eq!(config, Seed004Config::default());
    }

    #[test]
    fn bad_scenarios_name_the_file_and_field() {
        let shipped = &super::super::ExperimentId::Vdkf.embedded_scenarios()[0].text;
        let unknown = shipped.replace("speed_mps = 10.0", "speed_mps = 10.0\nsped = 3");
        let err = work_units(&source(&unknown), &ReproOptions { runs: 1, seed: 0 })
            .unwrap_err()
            .to_string();
        assert!(err.contains(FILE) && err.contains("sped"), "{err}");
        let negative = shipped.replace("gaussian_std_ns = 100.0", "gaussian_std_ns = -100.0");
        let err = work_units(&source(&negative), &ReproOptions { runs: 1, seed: 0 })
            .unwrap_err()
            .to_string();
        assert!(err.contains("[tdoa]") && err.contains("gaussian_std_s"), "{err}");
        let zero = shipped.replace("cv_variance = 0.01\n# CA", "cv_variance = 0.0\n# CA");
        assert_ne!(&zero, shipped);
        let err = work_units(&source(&zero), &ReproOptions { runs: 1, seed: 0 })
            .unwrap_err()
            .to_string();
        assert!(err.contains("cv_variance"), "{err}");
    }
}
