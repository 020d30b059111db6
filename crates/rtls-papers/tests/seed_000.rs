//! Seed 000 (`rtls repro mekf`) end to end: the mine walk and the Table 1 re-evaluation from the
//! embedded scenarios, with the paper's qualitative claims, the bound, determinism and scenario
//! errors.

use rtls_papers::experiments::{ExperimentId, ReproOptions, ScenarioSource};
use rtls_papers::report::ExperimentReport;
use rtls_sim::montecarlo::Progress;

const OPTIONS: ReproOptions = ReproOptions { runs: 10, seed: 2026 };

fn reproduce(sources: &[ScenarioSource]) -> rtls_sim::Result<ExperimentReport> {
    ExperimentId::Mekf.reproduce(sources, &OPTIONS, Progress::none())
}

fn ours(report: &ExperimentReport, name: &str) -> f64 {
    report
        .metric(name)
        .unwrap_or_else(|| panic!("metric {name:?} missing"))
        .ours
}

/// The embedded scenarios with `from` replaced by `to` in file `file`.
fn edited(file: &str, from: &str, to: &str) -> Vec<ScenarioSource> {
    let mut sources = ExperimentId::Mekf.embedded_scenarios();
    let source = sources.iter_mut().find(|s| s.name == file).expect("embedded file");
    assert!(source.text.contains(from), "{from:?} not in {file}");
    source.text = source.text.replacen(from, to, 1);
    sources
}

/// Paper Table 2 and §5.2–5.3: RSSI and DV-Hop leave empty locations where no reader hears the
/// tag, the ME-KF fills them (PEL 0) and has a lower error rate than the fixes it filters; our
/// tracker beats the ME-KF and the paper's 5 % headline; the obstacle shows in the innovations.
#[test]
fn the_papers_claims_hold_and_our_tracker_beats_the_me_kf() {
    let report = reproduce(&ExperimentId::Mekf.embedded_scenarios()).expect("reproduction");
    let (rssi_pel, dv_hop_pel) = (ours(&report, "RSSI: PEL"), ours(&report, "DV-Hop: PEL"));
    assert!(
        (3.0..=12.0).contains(&rssi_pel),
        "RSSI PEL {rssi_pel} far from the paper's 6.7 %"
    );
    assert!(
        dv_hop_pel >= rssi_pel,
        "DV-Hop locates only heard tags: {dv_hop_pel} < {rssi_pel}"
    );
    assert_eq!((ours(&report, "ME-KF: PEL"), ours(&report, "ours: PEL")), (0.0, 0.0));
    let rate = |m: &str| ours(&report, &format!("{m}: x error rate"));
    assert!(rate("ME-KF") < rate("RSSI") && rate("ME-KF") < rate("DV-Hop"));
    assert!(
        rate("ours") < 5.0,
        "ours {} % vs the paper's ME-KF headline 5 %",
        rate("ours")
    );
    let rmse = |m: &str| ours(&report, &format!("{m}: 3-D RMSE"));
    // the engine (single hypothesis at the junctions: see the report) beats the ME-KF; the
    // removed hand-written tracker did by 60 %
    assert!(
        rmse("ours") < 0.85 * rmse("ME-KF"),
        "ours {} m vs ME-KF {} m",
        rmse("ours"),
        rmse("ME-KF")
    );
    assert!(ours(&report, "ours vs ME-KF: 3-D RMSE reduction") > 15.0);
    // the one-step prediction of our track warns of the entry into the collapsed zone
    assert!(ours(&report, "ours: entries warned in time, one-step prediction") > 0.0);
    assert!(
        ours(&report, "ours: entries warned in time, 5 s look-ahead")
            >= ours(&report, "ME-KF: entries warned in time, 5 s look-ahead")
    );
    // obstacle analysis: the reader behind equipment stands out
    let obstacle = ours(&report, "obstacle analysis: mean RSSI innovation at M3 (8 dB obstacle)");
    let clear = ours(
        &report,
        "obstacle analysis: median mean RSSI innovation of the clear readers",
    );
    assert!(obstacle < clear - 3.0, "obstacle {obstacle} dB vs clear {clear} dB");
}

/// Every RMSE is at or above its √PCRB, which is positive.
#[test]
fn every_rmse_respects_its_bound() {
    let report = reproduce(&ExperimentId::Mekf.embedded_scenarios()).expect("reproduction");
    let bounded: Vec<_> = report.metrics.iter().filter(|m| m.bound.is_some()).collect();
    assert_eq!(bounded.len(), 4, "RSSI, DV-Hop, ME-KF and ours carry a bound");
    for m in bounded {
        let bound = m.bound.unwrap_or_default();
        assert!(
            bound > 0.0 && m.ours >= bound,
            "{}: {} m < √PCRB {} m",
            m.name,
            m.ours,
            bound
        );
    }
}

/// Table 1's printed numbers: the RSSI and DV-Hop error rates are far below the paper's 20 %,
/// 6.7 % is no k/20, and the smallest sample giving it is 15.
#[test]
fn table_1_is_reevaluated_from_its_printed_numbers() {
    let report = reproduce(&ExperimentId::Mekf.embedded_scenarios()).expect("reproduction");
    assert!(ours(&report, "Table 1: RSSI (printed) x error rate") < 10.0);
    assert!(ours(&report, "Table 1: DV-Hop (printed) x error rate") < 10.0);
    let me_kf = ours(&report, "Table 1: ME-KF (printed) x error rate");
    assert!((4.0..7.0).contains(&me_kf), "printed ME-KF x rate {me_kf}");
    assert_eq!(
        ours(&report, "Table 1: PEL closest to 6.7 % possible with 20 samples"),
        5.0
    );
    assert_eq!(ours(&report, "Table 1: fewest samples that give a PEL of 6.7 %"), 15.0);
    assert_eq!(ours(&report, "Table 1: PEL of the printed RSSI column"), 0.0);
    let rows = &report
        .tables
        .iter()
        .find(|t| t.title.starts_with("Table 1 re-evaluated"))
        .expect("table")
        .rows;
    assert_eq!(rows.len(), 4);
}

/// Figures are named after the experiment, labelled with units and small enough to draw;
/// notes quote numbers; nothing is NaN.
#[test]
fn the_report_is_complete_and_finite() {
    let report = reproduce(&ExperimentId::Mekf.embedded_scenarios()).expect("reproduction");
    assert_eq!(
        report.scenarios,
        [
            "crates/rtls-papers/scenarios/000-mine-walk.toml",
            "crates/rtls-papers/scenarios/000-table-1.toml"
        ]
    );
    for id in [
        "mekf-map",
        "mekf-x-error-rate",
        "mekf-x-displacement",
        "mekf-rmse-over-time",
        "mekf-error-cdf",
    ] {
        assert!(report.figures.iter().any(|f| f.id == id), "figure {id} missing");
    }
    for f in &report.figures {
        assert!(f.id.starts_with("mekf-") && f.x_label.contains('(') && f.y_label.contains('('));
        for s in &f.series {
            assert!(
                s.points.len() < 2000,
                "{} / {}: {} points",
                f.id,
                s.label,
                s.points.len()
            );
            assert!(
                s.points.iter().flatten().all(|v| v.is_finite()),
                "{} / {}",
                f.id,
                s.label
            );
        }
    }
    assert!(report.metrics.iter().all(|m| m.ours.is_finite()));
    assert!(report.notes.len() >= 8 && report.notes.iter().all(|n| !n.contains("NaN")));
}

/// Results depend on the seed only: two calls agree, and so does a one-thread pool.
#[test]
fn reproduction_is_deterministic_for_any_thread_count() {
    let sources = ExperimentId::Mekf.embedded_scenarios();
    let first = reproduce(&sources).expect("first");
    assert_eq!(first, reproduce(&sources).expect("second"));
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| reproduce(&sources))
        .expect("one thread");
    assert_eq!(first, single);
    assert_eq!(
        ExperimentId::Mekf.work_units(&sources, &OPTIONS),
        Ok(OPTIONS.runs as u64)
    );
}

/// Unknown keys, bad values and garbled rows are errors naming the file and the field.
#[test]
fn malformed_scenarios_name_the_file_and_the_field() {
    let cases = [
        (
            edited("000-mine-walk.toml", "exponent = 2.5", "exponent = 2.5\ncolour = 3"),
            "000-mine-walk.toml",
            "colour",
        ),
        (
            edited("000-mine-walk.toml", "exponent = 2.5", "exponent = -2.5"),
            "000-mine-walk.toml",
            "radio.exponent",
        ),
        (
            edited("000-mine-walk.toml", "speed_mps = 1.5", "speed_mps = 4.0"),
            "000-mine-walk.toml",
            "walk[1].speed_mps",
        ),
        (
            edited("000-mine-walk.toml", "tunnel = \"cross-cut\"", "tunnel = \"shaft\""),
            "000-mine-walk.toml",
            "readers[12].tunnel",
        ),
        (
            edited("000-table-1.toml", "rssi = [1.5, 1.3, 0.2]", "rssi = [1.5, 1.3]"),
            "000-table-1.toml",
            "rows[0].rssi",
        ),
        (
            edited(
                "000-table-1.toml",
                "[[excluded]]\ntime_s = 15.0",
                "[[excluded]]\ntime_s = 21.0",
            ),
            "000-table-1.toml",
            "rows[14].dv_hop",
        ),
    ];
    for (sources, file, field) in cases {
        let error = reproduce(&sources).expect_err("malformed scenario").to_string();
        assert!(error.contains(file) && error.contains(field), "{error}");
        assert!(ExperimentId::Mekf.work_units(&sources, &OPTIONS).is_err());
    }
    let missing: Vec<_> = ExperimentId::Mekf
        .embedded_scenarios()
        .into_iter()
        .filter(|s| s.name != "000-table-1.toml")
        .collect();
    assert!(reproduce(&missing)
        .expect_err("missing file")
        .to_string()
        .contains("000-table-1.toml"));
}
