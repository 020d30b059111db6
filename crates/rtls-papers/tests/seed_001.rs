//! Seed 001 end to end through `rtls repro ukf-uwb`: the paper's qualitative claims that we
//! reproduce, our findings where we differ, the √PCRB really bounding every tracker,
//! determinism across calls and thread counts, and scenario errors that name file and field.

use rtls_papers::experiments::{ExperimentId, ReproOptions, ScenarioSource};
use rtls_papers::report::ExperimentReport;
use rtls_sim::montecarlo::Progress;
use rtls_sim::SimError;

const RUNS: usize = 10;
const SEED: u64 = 2026;

fn reproduce(runs: usize, sources: &[ScenarioSource]) -> rtls_sim::Result<ExperimentReport> {
    ExperimentId::UkfUwb.reproduce(sources, &ReproOptions { runs, seed: SEED }, Progress::none())
}

fn report() -> ExperimentReport {
    reproduce(RUNS, &ExperimentId::UkfUwb.embedded_scenarios()).unwrap()
}

fn ours(report: &ExperimentReport, name: &str) -> f64 {
    report
        .metric(name)
        .unwrap_or_else(|| panic!("metric `{name}` missing"))
        .ours
}

#[test]
fn the_papers_claims_that_hold_and_our_findings_where_they_do_not() {
    let r = report();
    for scenario in ["CV", "turn"] {
        let fix = ours(&r, &format!("{scenario}: TOA-RSS fix RMSE after 10 s"));
        for tracker in [
            "UKF (CV)",
            "EKF (CV)",
            "engine UKF (CT, ω estimated)",
            "engine IMM (CV + CT, UKF)",
        ] {
            // paper Fig. 1, 2, 5: filtering the joint measurement beats the single-epoch fixes —
            // on the turn only with a turn model (ours: the CV filters lag behind the fixes)
            let rmse = ours(&r, &format!("{scenario}: {tracker} pooled RMSE after 10 s"));
            if scenario == "turn" && tracker.contains("(CV)") {
                assert!(rmse > fix, "{scenario} {tracker}: {rmse} vs fixes {fix}");
            } else {
                assert!(rmse < 0.85 * fix, "{scenario} {tracker}: {rmse} vs fixes {fix}");
            }
        }
        // ours: with α = 0.01 the UKF is a linearisation: UKF ≈ EKF (the paper claims UKF < EKF)
        let ratio = ours(&r, &format!("{scenario}: UKF / EKF pooled RMSE"));
        assert!((ratio - 1.0).abs() < 0.03, "{scenario}: UKF / EKF = {ratio}");
        // the RSS adds little next to UWB ranges
        assert!(ours(&r, &format!("{scenario}: RSS share of the position information")) < 2.0);
    }
    // paper §3.1: x error mostly within 0.25 m; UKF consistent on its own model
    assert!(ours(&r, "CV: UKF share of |x error| < 0.25 m after 10 s") > 60.0);
    let nees = ours(&r, "CV: UKF mean NEES after 10 s (consistent: 4)");
    assert!((3.0..5.5).contains(&nees), "NEES {nees}");
    // ours: the geometry makes x worse than y (the paper reports the opposite)
    assert!(ours(&r, "CV: UKF mean |x error| after 10 s") > ours(&r, "CV: UKF mean |y error| after 10 s"));
    // scenario 2: modelling the turn beats the paper's CV filters by far
    let cv = ours(&r, "turn: UKF (CV) pooled RMSE after 10 s");
    let ct = ours(&r, "turn: engine UKF (CT, ω estimated) pooled RMSE after 10 s");
    assert!(ct < 0.6 * cv, "turn: CT {ct} vs CV {cv}");
    let best = r.metrics.iter().find(|m| m.name.starts_with("turn: our best")).unwrap();
    assert!(best.ours <= ct + 1e-12 && !best.name.contains("(CV)"), "{}", best.name);
    // NLOS: the biased ranges cost the paper's UKF more than twice its line-of-sight error; the
    // engine's UKF on line-of-sight ranges is as good as the paper's, and its gate refuses NLOS
    // ranges (it has no down-weighting yet: its NLOS row is worse, see the report)
    let los = ours(&r, "CV: UKF (CV) pooled RMSE after 10 s");
    let nlos = ours(&r, "CV+NLOS: UKF (CV), NLOS ranges pooled RMSE after 10 s");
    assert!(nlos > 2.0 * los, "LOS {los}, NLOS {nlos}");
    let engine_los = ours(
        &r,
        "CV+NLOS: engine UKF (CV), line-of-sight ranges pooled RMSE after 10 s",
    );
    assert!(engine_los < 1.1 * los, "engine on LOS {engine_los} vs {los}");
    assert!(ours(&r, "CV+NLOS: ranges refused by the engine UKF's gate") > 5.0);
}

#[test]
fn the_pcrb_bounds_every_tracker() {
    let r = report();
    // a per-epoch RMSE from M runs scatters by about 1/√(2M) relative: allow three of those for
    // per-epoch extremes and for the fixes' single-epoch bound; pooled RMSEs must be above
    let tolerance = 1.0 - 3.0 / (2.0 * RUNS as f64).sqrt();
    let mut checked = 0;
    for m in r.metrics.iter().filter(|m| m.bound.is_some()) {
        let bound = m.bound.unwrap();
        assert!(bound > 0.0 && bound.is_finite(), "{}", m.name);
        if m.name.contains("pooled RMSE") {
            assert!(m.ours >= bound, "{}: {} < √PCRB {}", m.name, m.ours, bound);
        } else {
            assert!(
                m.ours >= tolerance * bound,
                "{}: {} < {} × {}",
                m.name,
                m.ours,
                tolerance,
                bound
            );
        }
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} bounded metrics");
    assert!(r.metrics.iter().all(|m| m.ours.is_finite()));
}

#[test]
fn reports_are_deterministic_across_calls_and_thread_counts() {
    let sources = ExperimentId::UkfUwb.embedded_scenarios();
    let first = reproduce(4, &sources).unwrap();
    assert_eq!(first, reproduce(4, &sources).unwrap());
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| reproduce(4, &sources))
        .unwrap();
    assert_eq!(first, single);
}

#[test]
fn progress_matches_the_work_units_and_figures_are_well_formed() {
    let sources = ExperimentId::UkfUwb.embedded_scenarios();
    let options = ReproOptions { runs: 3, seed: 1 };
    let done = std::sync::atomic::AtomicU64::new(0);
    let tick = |n: u64| {
        done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    };
    let report = ExperimentId::UkfUwb
        .reproduce(&sources, &options, Progress::new(&tick))
        .unwrap();
    assert_eq!(
        done.into_inner(),
        ExperimentId::UkfUwb.work_units(&sources, &options).unwrap()
    );
    assert_eq!(
        report.scenarios,
        vec![
            "crates/rtls-papers/scenarios/001-cv.toml",
            "crates/rtls-papers/scenarios/001-turn.toml"
        ]
    );
    assert!(report.figures.len() >= 12);
    for figure in &report.figures {
        assert!(figure.id.starts_with("ukf-uwb-"), "{}", figure.id);
        assert!(
            figure.x_label.contains('(') && figure.y_label.contains('('),
            "{}",
            figure.id
        );
        for series in &figure.series {
            assert!(!series.points.is_empty() && series.points.len() < 2000, "{}", figure.id);
            assert!(series.points.iter().flatten().all(|v| v.is_finite()), "{}", figure.id);
        }
    }
    assert!(report.notes.len() >= 8);
}

#[test]
fn malformed_scenarios_name_the_file_and_the_field() {
    let embedded = ExperimentId::UkfUwb.embedded_scenarios();
    let broken = |from: &str, to: &str| {
        let mut sources = embedded.clone();
        assert!(sources[0].text.contains(from), "{from}");
        sources[0].text = sources[0].text.replacen(from, to, 1);
        reproduce(2, &sources).unwrap_err().to_string()
    };
    // unknown key
    let err = broken("range_std_m = 0.2", "range_std_m = 0.2\nspeed_mps = 1.0");
    assert!(err.contains("001-cv.toml") && err.contains("speed_mps"), "{err}");
    // bad values
    let err = broken("range_std_m = 0.2", "range_std_m = -0.2");
    assert!(err.contains("001-cv.toml") && err.contains("toa.range_std_m"), "{err}");
    let err = broken("duration_s = 50.0", "duration_s = 50.5");
    assert!(err.contains("truth.duration_s"), "{err}");
    let err = broken("gate_probability = 0.99", "gate_probability = 1.0");
    assert!(err.contains("nlos.gate_probability"), "{err}");
    let err = broken("alpha = 1.0", "alpha = -1.0");
    assert!(err.contains("variants[1].alpha"), "{err}");
    // wrong type
    let err = broken("step_s = 1.0", "step_s = \"one\"");
    assert!(err.contains("001-cv.toml") && err.contains("step_s"), "{err}");
    // missing file
    let err = reproduce(2, &embedded[..1]).unwrap_err().to_string();
    assert!(err.contains("001-turn.toml"), "{err}");
    // zero runs
    assert!(matches!(
        reproduce(0, &embedded),
        Err(SimError::InvalidParameter { name: "runs", .. })
    ));
}
