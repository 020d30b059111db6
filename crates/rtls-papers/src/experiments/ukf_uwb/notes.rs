//! The notes of the `ukf-uwb` report: the setup, the errata, what can be compared with the
//! paper, and an explanation of every difference, with every number taken from the runs; the
//! prose is in `templates/ukf-uwb.md`.

use rtls_estimation::measurement::BreakpointForm;

use super::analysis::ScenarioAnalysis;
use super::config::Scenario;
use super::metrics::{evaluated_mean, ratio, VariantResult, PAPER};
use crate::experiments::common::fmt;
use crate::experiments::template::{files::UKF_UWB as T, render};
use crate::reproduction::seed_001::Seed001Filter;
use rtls_sim::scenarios::seed_001::Seed001Motion;

/// Everything the notes draw on.
pub(super) struct NoteInputs<'a> {
    /// Scenario 1 as configured.
    pub(super) cv: &'a Scenario,
    /// Scenario 2 as configured.
    pub(super) turn: &'a Scenario,
    /// Scenario 1's analysis.
    pub(super) cv_analysis: &'a ScenarioAnalysis,
    /// Scenario 2's analysis.
    pub(super) turn_analysis: &'a ScenarioAnalysis,
    /// The variants of scenario 1.
    pub(super) variants: &'a [VariantResult],
    /// Base seed.
    pub(super) seed: u64,
}

/// The notes, in reading order.
pub(super) fn notes(inputs: &NoteInputs<'_>) -> Vec<String> {
    let mut notes = vec![
        setup(inputs),
        errata(inputs),
        comparable(inputs),
        ukf_versus_ekf(inputs),
    ];
    notes.push(variants(inputs));
    notes.push(axes(inputs));
    notes.push(rss(inputs));
    notes.push(before_ukf(inputs));
    notes.push(consistency(inputs));
    notes.push(turn(inputs));
    if let Some(n) = nlos(inputs) {
        notes.push(n);
    }
    notes.push(best_versus_headline(inputs));
    notes
}

fn pooled(a: &ScenarioAnalysis, filter: Seed001Filter) -> f64 {
    a.trackers[filter.index()].pooled_rmse_m
}

fn setup(inputs: &NoteInputs<'_>) -> String {
    let c = &inputs.cv.config;
    let law = &c.rss_law;
    let omega = match inputs.turn.config.truth.motion {
        Seed001Motion::CoordinatedTurn { turn_rate_rad_s } => turn_rate_rad_s,
        Seed001Motion::ConstantVelocity => 0.0,
    };
    // fraction of a full circle turned over the run: |ω| T / 2π
    let turns = omega.abs() * inputs.turn.config.truth.duration_s / std::f64::consts::TAU;
    render!(
        T,
        "setup",
        stations_m = format!("{:?}", c.stations_m),
        initial_state = format!("{:?}", c.truth.initial_state),
        duration_s = c.truth.duration_s,
        step_s = c.truth.step_s,
        process_noise_std_mps2 = c.truth.process_noise_std_mps2,
        turn_rate_rad_s = fmt(omega, 4),
        turns = fmt(turns, 2),
        turn_duration_s = inputs.turn.config.truth.duration_s,
        range_std_m = c.range_std_m,
        shadowing_std_db = c.shadowing_std_db,
        p0_db = law.p0_db(),
        d0_m = law.reference_distance_m(),
        exponent = law.exponent(),
        breakpoint_m = law.breakpoint_m(),
        alpha = c.sigma_points.alpha,
        beta = c.sigma_points.beta,
        kappa = c.sigma_points.kappa,
        initial_position_std_m = c.initial_position_std_m,
        initial_velocity_std_mps = c.initial_velocity_std_mps,
        runs = inputs.cv_analysis.runs,
        seed = inputs.seed,
    )
}

fn errata(inputs: &NoteInputs<'_>) -> String {
    let law = &inputs.cv.config.rss_law;
    // the printed far branch adds 10 n lg(d_b/d0) again
    let jump_db = 10.0 * law.far_exponent() * (law.breakpoint_m() / law.reference_distance_m()).log10();
    let printed = inputs.variants.iter().find(|v| v.variant.change.contains("as printed"));
    let printed_text = printed.map_or(String::new(), |v| {
        let a = &v.analysis;
        let text = render!(
            T,
            "errata-printed-variant",
            variant = v.variant.name,
            ukf_rmse_m = fmt(pooled(a, Seed001Filter::Ukf), 3),
            ekf_rmse_m = fmt(pooled(a, Seed001Filter::Ekf), 3),
            continuous_ukf_rmse_m = fmt(pooled(inputs.cv_analysis, Seed001Filter::Ukf), 3),
            continuous_ekf_rmse_m = fmt(pooled(inputs.cv_analysis, Seed001Filter::Ekf), 3),
            breakpoint_m = law.breakpoint_m(),
            rss_share_percent = fmt(100.0 * inputs.cv_analysis.rss_information_share, 1),
        );
        format!(" {text}")
    });
    render!(
        T,
        "errata",
        jump_db = fmt(jump_db, 1),
        breakpoint_m = law.breakpoint_m(),
        // the scenario file's names of the two forms
        form = match law.form() {
            BreakpointForm::Continuous => "continuous",
            BreakpointForm::AsPrinted => "as printed",
        },
        exponent = law.exponent(),
        printed_variant = printed_text,
    )
}

fn comparable(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let ukf = &a.trackers[Seed001Filter::Ukf.index()];
    let ekf = &a.trackers[Seed001Filter::Ekf.index()];
    let t = inputs.turn_analysis;
    render!(
        T,
        "comparable",
        cv_ratio = fmt(ratio(ukf.pooled_rmse_m, ekf.pooled_rmse_m), 3),
        turn_ratio = fmt(ratio(pooled(t, Seed001Filter::Ukf), pooled(t, Seed001Filter::Ekf)), 3),
        ukf_to_bound = fmt(ratio(ukf.pooled_rmse_m, a.bound.pooled_m), 2),
        ekf_to_bound = fmt(ratio(ekf.pooled_rmse_m, a.bound.pooled_m), 2),
        bound_m = fmt(a.bound.pooled_m, 3),
        converged_after_s = inputs.cv.report.converged_after_s,
        ukf_min_m = fmt(ukf.min_rmse_m, 3),
        ukf_max_m = fmt(ukf.max_rmse_m, 3),
        paper_ukf_min_m = PAPER.ukf_rmse_m[0],
        paper_ukf_max_m = PAPER.ukf_rmse_m[1],
        ekf_min_m = fmt(ekf.min_rmse_m, 3),
        ekf_max_m = fmt(ekf.max_rmse_m, 3),
        paper_ekf_min_m = PAPER.ekf_rmse_m[0],
        paper_ekf_max_m = PAPER.ekf_rmse_m[1],
        bound_min_m = fmt(a.bound.min_m, 3),
        bound_max_m = fmt(a.bound.max_m, 3),
    )
}

fn ukf_versus_ekf(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let c = &inputs.cv.config;
    let ukf = &a.trackers[Seed001Filter::Ukf.index()];
    let ekf = &a.trackers[Seed001Filter::Ekf.index()];
    let max_difference = ukf
        .rmse_per_epoch_m
        .iter()
        .zip(&ekf.rmse_per_epoch_m)
        .map(|(u, e)| (u - e).abs())
        .fold(0.0, f64::max);
    let r = ratio(ukf.pooled_rmse_m, ekf.pooled_rmse_m);
    let verdict = if (r - 1.0).abs() < 0.02 {
        render!(T, "ukf-versus-ekf-equal")
    } else if r < 1.0 {
        render!(T, "ukf-versus-ekf-ukf-ahead", percent = fmt(100.0 * (1.0 - r), 1))
    } else {
        render!(T, "ukf-versus-ekf-ekf-ahead", percent = fmt(100.0 * (r - 1.0), 1))
    };
    // sigma points at ±√(n + λ) = ±α √n prior standard deviations (n = 4)
    let spread = c.sigma_points.alpha * 2.0;
    // a range curves by σ_p²/(2d): the largest prior spread (P₀) at the closest approach
    let prior_position_m = c.initial_position_std_m;
    let closest_m = a.closest_station_m;
    let curvature_m = prior_position_m * prior_position_m / (2.0 * closest_m);
    let ct_ukf = pooled(a, Seed001Filter::UkfTurnRate);
    let ct_ekf = pooled(a, Seed001Filter::EkfTurnRate);
    let lost = |f: Seed001Filter| a.trackers[f.index()].lost_tracks;
    let offset_cm = 100.0 * spread * c.initial_position_std_m;
    render!(
        T,
        "ukf-versus-ekf",
        verdict = verdict,
        ukf_rmse_m = fmt(ukf.pooled_rmse_m, 3),
        ekf_rmse_m = fmt(ekf.pooled_rmse_m, 3),
        max_difference_m = fmt(max_difference, 3),
        alpha = c.sigma_points.alpha,
        spread = fmt(spread, 2),
        offset_cm = fmt(offset_cm, 0),
        curvature_m = fmt(curvature_m, 3),
        prior_position_m = fmt(prior_position_m, 2),
        closest_m = fmt(closest_m, 1),
        range_std_m = c.range_std_m,
        ct_ukf_m = fmt(ct_ukf, 3),
        ct_ekf_m = fmt(ct_ekf, 3),
        ct_ratio = fmt(ratio(ct_ukf, ct_ekf), 3),
        ct_ukf_lost = lost(Seed001Filter::UkfTurnRate),
        ct_ekf_lost = lost(Seed001Filter::EkfTurnRate),
    )
}

fn variants(inputs: &NoteInputs<'_>) -> String {
    if inputs.variants.is_empty() {
        return render!(T, "variants-none");
    }
    let mut parts = Vec::new();
    let (mut lost_ukf, mut lost_ekf) = (0, 0);
    let mut largest = (0.0f64, String::new());
    for v in inputs.variants {
        let a = &v.analysis;
        let ukf = &a.trackers[Seed001Filter::Ukf.index()];
        let ekf = &a.trackers[Seed001Filter::Ekf.index()];
        let r = ratio(ukf.pooled_rmse_m, ekf.pooled_rmse_m);
        lost_ukf += ukf.lost_tracks;
        lost_ekf += ekf.lost_tracks;
        if (r - 1.0).abs() > (largest.0 - 1.0).abs() {
            largest = (r, v.variant.name.clone());
        }
        parts.push(render!(
            T,
            "variants-item",
            name = v.variant.name,
            change = v.variant.change,
            ratio = fmt(r, 3),
            ukf_lost = ukf.lost_tracks,
            ekf_lost = ekf.lost_tracks,
        ));
    }
    let without_losses: Vec<f64> = inputs
        .variants
        .iter()
        .filter(|v| v.analysis.trackers.iter().take(2).all(|t| t.lost_tracks == 0))
        .map(|v| {
            ratio(
                pooled(&v.analysis, Seed001Filter::Ukf),
                pooled(&v.analysis, Seed001Filter::Ekf),
            )
        })
        .collect();
    let spread_without = without_losses.iter().map(|r| (r - 1.0).abs()).fold(0.0, f64::max);
    // the paper's gap: 1 − UKF/EKF at both ends of its ranges
    let gap = [
        1.0 - PAPER.ukf_rmse_m[0] / PAPER.ekf_rmse_m[0],
        1.0 - PAPER.ukf_rmse_m[1] / PAPER.ekf_rmse_m[1],
    ];
    let conclusion = if spread_without < 0.05 {
        "variants-no-systematic-gap"
    } else {
        "variants-some-systematic-gap"
    };
    render!(
        T,
        "variants",
        items = parts.join("; "),
        spread_percent = fmt(100.0 * spread_without, 1),
        lost_ukf = lost_ukf,
        lost_ekf = lost_ekf,
        largest_ratio = fmt(largest.0, 3),
        largest_variant = largest.1,
        paper_gap_low_percent = fmt(100.0 * gap[0], 0),
        paper_gap_high_percent = fmt(100.0 * gap[1], 0),
        conclusion = render!(T, conclusion),
    )
}

fn axes(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let ukf = &a.trackers[Seed001Filter::Ukf.index()];
    let (mx, my) = (
        evaluated_mean(&ukf.mean_abs_error[0], a.first_epoch),
        evaluated_mean(&ukf.mean_abs_error[2], a.first_epoch),
    );
    let [bx, by] = a.bound.axis_m;
    let geometry = if bx > by {
        render!(T, "axes-bound-larger-in-x", ratio = fmt(ratio(bx, by), 1))
    } else {
        render!(T, "axes-bound-not-larger-in-x", bx_m = fmt(bx, 3), by_m = fmt(by, 3))
    };
    render!(
        T,
        "axes",
        paper_x_m = PAPER.ukf_mean_x_m,
        paper_y_m = PAPER.ukf_mean_y_m,
        mean_x_m = fmt(mx, 3),
        mean_y_m = fmt(my, 3),
        converged_after_s = inputs.cv.report.converged_after_s,
        start_to_baseline_m = fmt(a.start_to_baseline_m, 1),
        bx_m = fmt(bx, 3),
        by_m = fmt(by, 3),
        geometry = geometry,
    )
}

fn rss(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let c = &inputs.cv.config;
    // a path loss with shadowing σ_s is worth a range of σ_d = d σ_s ln 10 / (10 n)
    let per_metre = c.shadowing_std_db * std::f64::consts::LN_10 / (10.0 * c.rss_law.exponent());
    render!(
        T,
        "rss",
        rss_share_percent = fmt(100.0 * a.rss_information_share, 1),
        shadowing_std_db = c.shadowing_std_db,
        exponent = c.rss_law.exponent(),
        per_metre = fmt(per_metre, 3),
        at_10_m = fmt(per_metre * 10.0, 1),
        at_30_m = fmt(per_metre * 30.0, 1),
        range_std_m = c.range_std_m,
        toa_bound_m = fmt(a.toa_bound_pooled_m, 4),
        bound_m = fmt(a.bound.pooled_m, 4),
    )
}

fn before_ukf(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let ukf = &a.trackers[Seed001Filter::Ukf.index()];
    let speed_error = 0.5
        * (evaluated_mean(&ukf.mean_abs_error[1], a.first_epoch)
            + evaluated_mean(&ukf.mean_abs_error[3], a.first_epoch));
    let total = a.runs * a.times_s.len();
    render!(
        T,
        "before-ukf",
        fixes_rmse_m = fmt(a.fixes.rmse_m, 3),
        converged_after_s = inputs.cv.report.converged_after_s,
        fixes_crb_m = fmt(a.fixes.crb_m, 3),
        failures = a.fixes.failures,
        total = total,
        fixes_rmse_rounded_m = fmt(a.fixes.rmse_m, 2),
        speed_error_mps = fmt(speed_error, 3),
    )
}

fn consistency(inputs: &NoteInputs<'_>) -> String {
    let describe = |a: &ScenarioAnalysis, filter: Seed001Filter| {
        let t = &a.trackers[filter.index()];
        match (t.mean_nis, t.nis_inside) {
            (Some(nis), Some(nis_inside)) => render!(
                T,
                "consistency-tracker",
                name = t.name,
                nees = fmt(t.mean_nees, 2),
                nees_inside_percent = fmt(100.0 * t.nees_inside, 0),
                nis = fmt(nis, 2),
                nis_inside_percent = fmt(100.0 * nis_inside, 0),
            ),
            _ => render!(
                T,
                "consistency-engine-tracker",
                name = t.name,
                nees = fmt(t.mean_nees, 2),
                nees_inside_percent = fmt(100.0 * t.nees_inside, 0),
                nees_lower = fmt(t.nees_interval.lower, 2),
                nees_upper = fmt(t.nees_interval.upper, 2),
            ),
        }
    };
    let a = inputs.cv_analysis;
    let t = inputs.turn_analysis;
    render!(
        T,
        "consistency",
        runs = a.runs,
        nees_lower = fmt(a.nees_interval.lower, 2),
        nees_upper = fmt(a.nees_interval.upper, 2),
        measurement_dim = a.measurement_dim,
        nis_lower = fmt(a.nis_interval.lower, 2),
        nis_upper = fmt(a.nis_interval.upper, 2),
        cv_ukf = describe(a, Seed001Filter::Ukf),
        cv_ekf = describe(a, Seed001Filter::Ekf),
        turn_ukf = describe(t, Seed001Filter::Ukf),
        turn_ekf = describe(t, Seed001Filter::Ekf),
        turn_ct_ukf = describe(t, Seed001Filter::UkfTurnRate),
        turn_consistency = turn_consistency(t),
    )
}

/// Why the CV filters are (in)consistent on the turn, from the numbers.
fn turn_consistency(t: &ScenarioAnalysis) -> String {
    let cv = &t.trackers[Seed001Filter::Ukf.index()];
    let ct = &t.trackers[Seed001Filter::UkfTurnRate.index()];
    if cv.mean_nees > t.nees_interval.upper {
        let restored = if ct.nees_interval.contains(ct.mean_nees) {
            "turn-consistency-restored"
        } else {
            "turn-consistency-reduced"
        };
        render!(
            T,
            "turn-consistency-overconfident",
            nees = fmt(cv.mean_nees, 1),
            nees_upper = fmt(t.nees_interval.upper, 2),
            restored = render!(T, restored),
        )
    } else {
        render!(T, "turn-consistency-fine")
    }
}

fn turn(inputs: &NoteInputs<'_>) -> String {
    let t = inputs.turn_analysis;
    let r = ratio(pooled(t, Seed001Filter::Ukf), pooled(t, Seed001Filter::Ekf));
    let claim = if r < 0.98 {
        "turn-claim-holds"
    } else if r <= 1.02 {
        "turn-claim-equal"
    } else {
        "turn-claim-worse"
    };
    let best = &t.trackers[t.best];
    let cv_rmse = pooled(t, Seed001Filter::Ukf).max(pooled(t, Seed001Filter::Ekf));
    let fixes = if cv_rmse > t.fixes.rmse_m {
        render!(T, "turn-fixes-worse", fixes_rmse_m = fmt(t.fixes.rmse_m, 3))
    } else {
        format!(
            " {}",
            render!(T, "turn-fixes-better", fixes_rmse_m = fmt(t.fixes.rmse_m, 3))
        )
    };
    render!(
        T,
        "turn",
        ukf_rmse_m = fmt(pooled(t, Seed001Filter::Ukf), 3),
        ekf_rmse_m = fmt(pooled(t, Seed001Filter::Ekf), 3),
        bound_m = fmt(t.bound.pooled_m, 3),
        fixes = fixes,
        claim = render!(T, claim, ratio = fmt(r, 3)),
        ct_ukf_m = fmt(pooled(t, Seed001Filter::UkfTurnRate), 3),
        ct_ekf_m = fmt(pooled(t, Seed001Filter::EkfTurnRate), 3),
        ct_ratio = fmt(ratio(pooled(t, Seed001Filter::UkfTurnRate), t.bound.pooled_m), 2),
        imm_m = fmt(pooled(t, Seed001Filter::Imm), 3),
        cv_imm_m = fmt(pooled(inputs.cv_analysis, Seed001Filter::Imm), 3),
        cv_ukf_m = fmt(pooled(inputs.cv_analysis, Seed001Filter::Ukf), 3),
        best = best.name,
        best_m = fmt(best.pooled_rmse_m, 3),
    )
}

fn nlos(inputs: &NoteInputs<'_>) -> Option<String> {
    let a = inputs.cv_analysis;
    let n = a.nlos.as_ref()?;
    let setting = inputs.cv.config.nlos.as_ref()?;
    Some(render!(
        T,
        "nlos",
        nlos_percent = fmt(100.0 * n.nlos_share, 1),
        probability = setting.bias.probability,
        mean_bias_m = setting.bias.mean_bias_m,
        bias_all_m = fmt(n.mean_bias_m, 3),
        ukf_rmse_m = fmt(pooled(a, Seed001Filter::Ukf), 3),
        nlos_ukf_rmse_m = fmt(n.ukf.pooled_rmse_m, 3),
        gate_probability = setting.gate_probability,
        robust_rmse_m = fmt(n.robust.pooled_rmse_m, 3),
        downweighted_percent = fmt(100.0 * n.robust.downweighted_share, 1),
        robust_los_rmse_m = fmt(n.robust_los.pooled_rmse_m, 3),
        los_bound_m = fmt(a.bound.pooled_m, 3),
    ))
}

fn best_versus_headline(inputs: &NoteInputs<'_>) -> String {
    let a = inputs.cv_analysis;
    let best = &a.trackers[a.best];
    let ekf = &a.trackers[Seed001Filter::Ekf.index()];
    let ukf = &a.trackers[Seed001Filter::Ukf.index()];
    let tie = if a.best != Seed001Filter::Ukf.index() {
        let behind = render!(
            T,
            "best-ukf-behind",
            percent = fmt(100.0 * (ratio(ukf.pooled_rmse_m, best.pooled_rmse_m) - 1.0), 1),
        );
        format!(" {behind}")
    } else {
        String::new()
    };
    let beats = best.max_rmse_m < PAPER.ukf_rmse_m[1] && best.min_rmse_m < PAPER.ukf_rmse_m[0];
    let verdict = if beats {
        "best-below-paper"
    } else {
        "best-not-below-paper"
    };
    render!(
        T,
        "best",
        paper_ukf_min_m = PAPER.ukf_rmse_m[0],
        paper_ukf_max_m = PAPER.ukf_rmse_m[1],
        best = best.name,
        tie = tie,
        best_min_m = fmt(best.min_rmse_m, 3),
        best_max_m = fmt(best.max_rmse_m, 3),
        converged_after_s = inputs.cv.report.converged_after_s,
        best_rmse_m = fmt(best.pooled_rmse_m, 3),
        verdict = render!(T, verdict),
        best_ratio = fmt(ratio(best.pooled_rmse_m, a.bound.pooled_m), 2),
        best_margin_percent = fmt(100.0 * (ratio(best.pooled_rmse_m, a.bound.pooled_m) - 1.0).max(0.0), 0),
        ekf_ratio = fmt(ratio(ekf.pooled_rmse_m, a.bound.pooled_m), 2),
        ekf_margin_percent = fmt(100.0 * (1.0 - ratio(a.bound.pooled_m, ekf.pooled_rmse_m)).max(0.0), 0),
        paper_gap_low_percent = fmt(100.0 * (1.0 - PAPER.ukf_rmse_m[0] / PAPER.ekf_rmse_m[0]), 0),
        paper_gap_high_percent = fmt(100.0 * (1.0 - PAPER.ukf_rmse_m[1] / PAPER.ekf_rmse_m[1]), 0),
    )
}
