//! The metrics and tables of the `ukf-uwb` report: paper | ours | bound for every number the
//! paper gives, the pooled RMSE of every tracker with its √PCRB, consistency, the NLOS
//! extension, and the variants of scenario 1.

use super::analysis::{ScenarioAnalysis, TrackerSummary};
use super::config::{ReportSettings, Variant};
use crate::report::{Metric, Table};
use crate::reproduction::seed_001::Seed001Filter;

/// The numbers seed 001 reports for scenario 1 (§3.1, Fig. 3 and 4), m.
#[derive(Debug, Clone, Copy)]
pub(super) struct PaperValues {
    /// UKF mean |x error| ≈ 0.1 m.
    pub(super) ukf_mean_x_m: f64,
    /// UKF mean |y error| ≈ 0.2 m.
    pub(super) ukf_mean_y_m: f64,
    /// UKF RMSE 0.27–0.53 m.
    pub(super) ukf_rmse_m: [f64; 2],
    /// EKF RMSE 0.30–0.67 m.
    pub(super) ekf_rmse_m: [f64; 2],
}

/// Seed 001 §3.1: "平均误差为 0.1 m 左右", "Y 方向上的位置平均误差在 0.2 m 左右",
/// "UKF算法的RMSE为0.27~0.53 m,而EKF算法的RMSE的平均值则为0.30 m~0.67 m".
pub(super) const PAPER: PaperValues = PaperValues {
    ukf_mean_x_m: 0.1,
    ukf_mean_y_m: 0.2,
    ukf_rmse_m: [0.27, 0.53],
    ekf_rmse_m: [0.30, 0.67],
};

/// A variant of scenario 1 and its analysis.
#[derive(Debug, Clone)]
pub(super) struct VariantResult {
    /// The variant as configured.
    pub(super) variant: Variant,
    /// Its runs, analysed.
    pub(super) analysis: ScenarioAnalysis,
}

/// The metrics of one scenario; `scenario` is the name prefix ("CV", "turn"), `paper` the
/// paper's values where it gives any.
pub(super) fn scenario_metrics(
    scenario: &str,
    settings: &ReportSettings,
    analysis: &ScenarioAnalysis,
    paper: Option<&PaperValues>,
) -> Vec<Metric> {
    let after = format!("after {} s", settings.converged_after_s);
    let ukf = &analysis.trackers[Seed001Filter::Ukf.index()];
    let ekf = &analysis.trackers[Seed001Filter::Ekf.index()];
    let bound = &analysis.bound;
    let with_paper = |metric: Metric, value: Option<f64>| match value {
        Some(v) => metric.paper(v),
        None => metric,
    };
    let mut metrics = vec![
        with_paper(
            Metric::new(
                format!("{scenario}: UKF mean |x error| {after}"),
                "m",
                evaluated_mean(&ukf.mean_abs_error[0], analysis.first_epoch),
            ),
            paper.map(|p| p.ukf_mean_x_m),
        ),
        with_paper(
            Metric::new(
                format!("{scenario}: UKF mean |y error| {after}"),
                "m",
                evaluated_mean(&ukf.mean_abs_error[2], analysis.first_epoch),
            ),
            paper.map(|p| p.ukf_mean_y_m),
        ),
        Metric::new(
            format!(
                "{scenario}: UKF share of |x error| < {} m {after}",
                settings.x_error_threshold_m
            ),
            "%",
            100.0 * ukf.share_x_below,
        ),
    ];
    for (tracker, values) in [(ukf, paper.map(|p| p.ukf_rmse_m)), (ekf, paper.map(|p| p.ekf_rmse_m))] {
        let name = short_name(tracker);
        metrics.push(with_paper(
            Metric::new(
                format!("{scenario}: {name} per-epoch RMSE, min {after}"),
                "m",
                tracker.min_rmse_m,
            )
            .bound(bound.min_m),
            values.map(|v| v[0]),
        ));
        metrics.push(with_paper(
            Metric::new(
                format!("{scenario}: {name} per-epoch RMSE, max {after}"),
                "m",
                tracker.max_rmse_m,
            )
            .bound(bound.max_m),
            values.map(|v| v[1]),
        ));
    }
    for tracker in &analysis.trackers {
        metrics.push(
            Metric::new(
                format!("{scenario}: {} pooled RMSE {after}", tracker.name),
                "m",
                tracker.pooled_rmse_m,
            )
            .bound(bound.pooled_m),
        );
    }
    metrics.push(Metric::new(
        format!("{scenario}: UKF / EKF pooled RMSE"),
        "",
        ratio(ukf.pooled_rmse_m, ekf.pooled_rmse_m),
    ));
    let best = &analysis.trackers[analysis.best];
    metrics.push(
        Metric::new(
            format!("{scenario}: our best ({}) pooled RMSE {after}", best.name),
            "m",
            best.pooled_rmse_m,
        )
        .bound(bound.pooled_m),
    );
    metrics.push(
        Metric::new(
            format!("{scenario}: TOA-RSS fix RMSE {after}"),
            "m",
            analysis.fixes.rmse_m,
        )
        .bound(analysis.fixes.crb_m),
    );
    metrics.push(Metric::new(
        format!("{scenario}: √PCRB pooled {after}, TOA ranges only"),
        "m",
        analysis.toa_bound_pooled_m,
    ));
    metrics.push(Metric::new(
        format!("{scenario}: RSS share of the position information"),
        "%",
        100.0 * analysis.rss_information_share,
    ));
    for tracker in [ukf, ekf] {
        let name = short_name(tracker);
        metrics.push(Metric::new(
            format!("{scenario}: {name} mean NEES {after} (consistent: 4)"),
            "",
            tracker.mean_nees,
        ));
        if let Some(nis) = tracker.mean_nis {
            metrics.push(Metric::new(
                format!(
                    "{scenario}: {name} mean NIS {after} (consistent: {})",
                    analysis.measurement_dim
                ),
                "",
                nis,
            ));
        }
    }
    for tracker in analysis.trackers.iter().filter(|t| t.nees_dof == 2) {
        metrics.push(Metric::new(
            format!(
                "{scenario}: {} mean position NEES {after} (consistent: 2)",
                tracker.name
            ),
            "",
            tracker.mean_nees,
        ));
    }
    if let Some(nlos) = &analysis.nlos {
        metrics.push(Metric::new(
            format!("{scenario}+NLOS: share of NLOS ranges"),
            "%",
            100.0 * nlos.nlos_share,
        ));
        for tracker in [&nlos.ukf, &nlos.robust, &nlos.robust_los] {
            metrics.push(
                Metric::new(
                    format!("{scenario}+NLOS: {} pooled RMSE {after}", tracker.name),
                    "m",
                    tracker.pooled_rmse_m,
                )
                .bound(bound.pooled_m),
            );
        }
        metrics.push(Metric::new(
            format!("{scenario}+NLOS: ranges refused by the engine UKF's gate"),
            "%",
            100.0 * nlos.robust.downweighted_share,
        ));
    }
    metrics
}

/// The per-tracker table of one scenario (with the NLOS trackers when run).
pub(super) fn tracker_table(title: &str, settings: &ReportSettings, analysis: &ScenarioAnalysis) -> Table {
    let header = [
        "tracker",
        "pooled RMSE (m)",
        "RMSE / √PCRB",
        "per-epoch RMSE min–max (m)",
        "mean NEES (dof)",
        "NEES in 95 % interval",
        "mean NIS",
        "NIS in 95 % interval",
        "lost tracks",
    ];
    let mut trackers: Vec<&TrackerSummary> = analysis.trackers.iter().collect();
    if let Some(nlos) = &analysis.nlos {
        trackers.extend([&nlos.ukf, &nlos.robust, &nlos.robust_los]);
    }
    let rows = trackers
        .iter()
        .map(|t| {
            vec![
                t.name.clone(),
                format!("{:.3}", t.pooled_rmse_m),
                format!("{:.2}", ratio(t.pooled_rmse_m, analysis.bound.pooled_m)),
                format!("{:.3}–{:.3}", t.min_rmse_m, t.max_rmse_m),
                format!("{:.2} ({})", t.mean_nees, t.nees_dof),
                format!("{:.0} %", 100.0 * t.nees_inside),
                t.mean_nis.map_or_else(|| "—".to_string(), |v| format!("{v:.2}")),
                t.nis_inside
                    .map_or_else(|| "—".to_string(), |v| format!("{:.0} %", 100.0 * v)),
                format!("{} / {}", t.lost_tracks, analysis.runs),
            ]
        })
        .collect();
    Table {
        title: format!(
            "{title}: trackers over {} runs, epochs after {} s (√PCRB pooled {:.3} m; 95 % intervals: NEES of [x, vx, y, vy] (dof 4, the paper's filters) [{:.2}, {:.2}], NEES of the position (dof 2, the engine's track updates carry the position covariance) [{:.2}, {:.2}], NIS [{:.2}, {:.2}], none for the engine, which updates one reading at a time; a track is lost when its last error exceeds {} m)",
            analysis.runs,
            settings.converged_after_s,
            analysis.bound.pooled_m,
            analysis.nees_interval.lower,
            analysis.nees_interval.upper,
            analysis.position_nees_interval.lower,
            analysis.position_nees_interval.upper,
            analysis.nis_interval.lower,
            analysis.nis_interval.upper,
            settings.lost_track_error_m,
        ),
        header: header.iter().map(|h| (*h).to_string()).collect(),
        rows,
    }
}

/// The variants table: the base scenario first, then each variant.
pub(super) fn variant_table(base: &ScenarioAnalysis, variants: &[VariantResult]) -> Table {
    let row = |name: &str, change: &str, a: &ScenarioAnalysis| {
        let ukf = &a.trackers[Seed001Filter::Ukf.index()];
        let ekf = &a.trackers[Seed001Filter::Ekf.index()];
        vec![
            name.to_string(),
            change.to_string(),
            format!("{:.3}", ukf.pooled_rmse_m),
            format!("{:.3}", ekf.pooled_rmse_m),
            format!("{:.3}", ratio(ukf.pooled_rmse_m, ekf.pooled_rmse_m)),
            format!("{:.3}", a.bound.pooled_m),
            format!("{} / {}", ukf.lost_tracks, ekf.lost_tracks),
        ]
    };
    let mut rows = vec![row("scenario 1", "as configured", base)];
    rows.extend(
        variants
            .iter()
            .map(|v| row(&v.variant.name, &v.variant.change, &v.analysis)),
    );
    Table {
        title: format!(
            "Scenario 1 variants (same {} run seeds, line of sight): where could a UKF with α = 0.01 beat the EKF?",
            base.runs
        ),
        header: [
            "variant",
            "change",
            "UKF pooled RMSE (m)",
            "EKF pooled RMSE (m)",
            "UKF / EKF",
            "√PCRB (m)",
            "lost tracks UKF / EKF",
        ]
        .iter()
        .map(|h| (*h).to_string())
        .collect(),
        rows,
    }
}

/// "UKF" or "EKF" for the paper's two trackers, the full label otherwise.
pub(super) fn short_name(tracker: &TrackerSummary) -> &str {
    tracker.name.split(' ').next().unwrap_or(&tracker.name)
}

/// `a / b`, 0 when `b` is not positive (never NaN).
pub(super) fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        0.0
    }
}

/// Mean of `values[first..]` (0 for none).
pub(super) fn evaluated_mean(values: &[f64], first: usize) -> f64 {
    let tail = &values[first.min(values.len())..];
    tail.iter().sum::<f64>() / tail.len().max(1) as f64
}
