//! Unit tests of the survey: residuals of hand-made cases, Welford against two passes, the flag
//! rule on synthetic populations, the correction table, and the CSV round trip and errors.

use super::stats::median_and_mad;
use super::*;
use crate::evaluation::{parse_track_lines, TrackSample};
use crate::record::{AnchorReading, Measurement, Record};
use crate::site::Site;

/// Three readers at 2.5 m height (two with a path-loss law, one with a range bias), one
/// without radio parameters, one broken; 2-D tracking at a tag height of 1 m.
const SITE: &str = r#"
readers = [
  { id = "A", position_m = [0.0, 0.0, 2.5], technology = "uwb", radio = { range = { range_std_m = 0.1, bias_m = 0.2 } } },
  { id = "B", position_m = [30.0, 0.0, 2.5], technology = "ble", radio = { path_loss = { reference_power_dbm = -45.0, exponent = 2.5, shadowing_std_db = 4.0, reference_distance_m = 2.0 } } },
  { id = "C", position_m = [0.0, 20.0, 2.5], technology = "ble" },
  { id = "D", position_m = [30.0, 20.0, 2.5], technology = "ble", working = false },
]
[tracker]
pipeline = "tightly-coupled"
motion_model = "cv"
filter = "ekf"
acceleration_noise_std_mps2 = 0.5
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 5.0
delete_timeout_s = 60.0
reorder_window_s = 0.0
tag_height_m = 1.0
"#;

fn site() -> Site {
    Site::from_toml_str(SITE, "site.toml").unwrap()
}

/// Tag `w`: (10, 5) at t = 10, (20, 5) at t = 11, a predicted (50, 50) at t = 11.5, (20, 15)
/// at t = 12, then a 5 s gap to (20, 15) at t = 17.
fn tracks() -> Vec<TrackSample> {
    parse_track_lines(
        "{\"t\": 10, \"tag\": \"w\", \"x\": 10, \"y\": 5}\n\
         {\"t\": 11, \"tag\": \"w\", \"x\": 20, \"y\": 5}\n\
         {\"t\": 11.5, \"tag\": \"w\", \"x\": 50, \"y\": 50, \"predicted\": true}\n\
         {\"t\": 12, \"tag\": \"w\", \"x\": 20, \"y\": 15}\n\
         {\"t\": 17, \"tag\": \"w\", \"x\": 20, \"y\": 15}\n",
        "tracks.jsonl",
    )
    .unwrap()
}

fn record(time_s: f64, measurement: Measurement) -> Record {
    Record {
        time_s,
        tag: "w".into(),
        measurement,
    }
}

fn rssi(anchor: &str, rssi_dbm: f64) -> Measurement {
    Measurement::Rssi {
        anchor: anchor.into(),
        rssi_dbm,
    }
}

fn range(anchor: &str, range_m: f64) -> Measurement {
    Measurement::Range {
        anchor: anchor.into(),
        range_m,
        std_m: None,
        anchor_position_m: None,
    }
}

fn settings() -> SurveySettings {
    SurveySettings {
        skip_initial_s: 0.0,
        ..SurveySettings::default()
    }
}

#[test]
fn residuals_of_hand_made_ranges_and_rssi_use_the_slant_distance_and_interpolate() {
    let records = [
        // t = 10.5: halfway, p = (15, 5, 1); to A: √(225 + 25 + 2.25) = √252.25
        record(10.5, range("A", 17.0)),
        // t = 11.25 (the predicted sample at 11.5 is ignored): p = (20, 7.5, 1); to B:
        // √(100 + 56.25 + 2.25) = √158.5, law −45 − 25 log₁₀(d / 2)
        record(11.25, rssi("B", -70.0)),
        // exactly at an update: p = (20, 15, 1)
        record(
            12.0,
            Measurement::RssiVector {
                readings: vec![
                    AnchorReading {
                        anchor: "B".into(),
                        rssi_dbm: -66.0,
                    },
                    AnchorReading {
                        anchor: "C".into(),
                        rssi_dbm: -60.0,
                    },
                ],
            },
        ),
    ];
    let found = residuals(&site(), &records, &tracks(), &settings()).unwrap();
    // (r − b) − d
    let d_a = 252.25f64.sqrt();
    assert!((found.residuals[0].value - (17.0 - 0.2 - d_a)).abs() < 1e-12);
    assert_eq!(found.residuals[0].position_m, [15.0, 5.0, 1.0]);
    assert!((found.residuals[0].distance_m - d_a).abs() < 1e-12);
    assert_eq!(found.residuals[0].kind, ResidualKind::Range);
    // ρ − (P₀ − 10 n log₁₀(d / d₀))
    let d_b = 158.5f64.sqrt();
    assert!((found.residuals[1].value - (-70.0 - (-45.0 - 25.0 * (d_b / 2.0).log10()))).abs() < 1e-12);
    assert_eq!(found.residuals[1].position_m, [20.0, 7.5, 1.0]);
    let d_b = (100.0f64 + 225.0 + 2.25).sqrt();
    assert!((found.residuals[2].value - (-66.0 - (-45.0 - 25.0 * (d_b / 2.0).log10()))).abs() < 1e-12);
    assert_eq!(found.residuals.len(), 3);
    // C has no path-loss law: counted, not dropped
    assert_eq!(
        found.unmatched,
        Unmatched {
            no_path_loss: 1,
            ..Unmatched::default()
        }
    );
}

#[test]
fn every_measurement_without_a_residual_is_counted_under_its_reason() {
    let records = [
        record(
            10.5,
            Measurement::Fix {
                position_m: vec![1.0, 2.0],
                covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
            },
        ),
        record(
            10.5,
            Measurement::Tdoa {
                anchor: "A".into(),
                reference: "B".into(),
                range_difference_m: 1.0,
                std_m: None,
            },
        ),
        record(10.5, rssi("Z", -60.0)),
        record(10.5, rssi("D", -60.0)),
        record(10.5, rssi("C", -60.0)),
        Record {
            tag: "nobody".into(),
            ..record(10.5, rssi("B", -60.0))
        },
        record(9.0, rssi("B", -60.0)),
        record(17.5, rssi("B", -60.0)),
        record(14.0, rssi("B", -60.0)),
        // with a 1 s initial skip: t = 10.5 is skipped
        record(10.5, range("A", 10.0)),
    ];
    let skip = SurveySettings {
        skip_initial_s: 1.0,
        ..settings()
    };
    let found = residuals(&site(), &records, &tracks(), &skip).unwrap();
    assert!(found.residuals.is_empty());
    let expected = Unmatched {
        not_anchor_measurement: 1,
        tdoa: 1,
        unknown_reader: 1,
        broken_reader: 1,
        no_path_loss: 1,
        no_track: 1,
        initial_skipped: 1,
        outside_track: 2,
        track_gap: 1,
    };
    assert_eq!(found.unmatched, expected);
    assert_eq!(found.unmatched.total(), records.len());
    // the gap is 5 s: allowed with max_gap_s = 5
    let wide = SurveySettings {
        max_gap_s: 5.0,
        ..settings()
    };
    let found = residuals(&site(), &[record(14.0, rssi("B", -60.0))], &tracks(), &wide).unwrap();
    assert_eq!(found.residuals.len(), 1);
}

#[test]
fn bad_records_tracks_and_settings_are_errors() {
    let bad = record(10.5, rssi("B", f64::NAN));
    let error = residuals(&site(), &[record(10.5, rssi("B", -60.0)), bad], &tracks(), &settings()).unwrap_err();
    assert!(error.to_string().starts_with("records:2: field `rssi_dbm`"), "{error}");
    let mut samples = tracks();
    samples[1].position_m[1] = f64::INFINITY;
    let error = residuals(&site(), &[], &samples, &settings()).unwrap_err();
    assert!(error.to_string().starts_with("tracks:2: field `y`"), "{error}");
    let zero = SurveySettings {
        min_count: 1,
        ..settings()
    };
    assert!(matches!(
        residuals(&site(), &[], &tracks(), &zero),
        Err(EngineError::InvalidParameter { name: "min_count", .. })
    ));
    let bands = SurveySettings {
        distance_band_m: Some(-1.0),
        ..settings()
    };
    assert!(bands.validate().is_err());
}

#[test]
fn welford_matches_the_two_pass_formulas_even_far_from_zero() {
    // values around 10⁹ with a spread of ~1: Σx² − n x̄² would lose every digit
    let values: Vec<f64> = (0..1000).map(|k| 1e9 + ((k * 7919) % 1000) as f64 / 500.0).collect();
    let mut stats = RunningStats::default();
    assert_eq!((stats.mean(), stats.std()), (None, None));
    for &v in &values {
        stats.push(v);
    }
    // two passes: x̄ = Σx / n, s² = Σ(x − x̄)² / (n − 1)
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    assert_eq!(stats.count(), 1000);
    assert!((stats.mean().unwrap() - mean).abs() < 1e-6);
    assert!(
        (stats.variance().unwrap() - variance).abs() < 1e-6 * variance,
        "{variance}"
    );
    // the one-pass textbook formula (Σx² − n x̄²) / (n − 1) loses every digit here
    let naive = (values.iter().map(|v| v * v).sum::<f64>() - n * mean * mean) / (n - 1.0);
    assert!((naive - variance).abs() > 10.0 * variance, "{naive}");
    let mut one = RunningStats::default();
    one.push(3.0);
    assert_eq!((one.mean(), one.variance()), (Some(3.0), None));
}

/// `count` residuals of `reader` in cell `cell` (10 m cells), alternating `bias ± spread`, at
/// 12 m from the reader.
pub(super) fn residuals_in(
    cell: [i64; 2],
    reader: &str,
    kind: ResidualKind,
    bias: f64,
    spread: f64,
    count: usize,
) -> Vec<Residual> {
    (0..count)
        .map(|k| Residual {
            time_s: k as f64,
            tag: "t".into(),
            reader: reader.into(),
            kind,
            position_m: [cell[0] as f64 * 10.0 + 5.0, cell[1] as f64 * 10.0 + 5.0, 0.0],
            distance_m: 12.0,
            value: bias + if k % 2 == 0 { spread } else { -spread },
        })
        .collect()
}

/// 20 RSSI cells of reader `R` with biases −0.9 … +1.0 dB, spread 2 dB; and the extra cells.
pub(super) fn population(extra: &[([i64; 2], f64, f64)]) -> Vec<Residual> {
    let mut all = Vec::new();
    for k in 0..20 {
        all.extend(residuals_in(
            [k, 0],
            "R",
            ResidualKind::Rssi,
            -0.9 + 0.1 * k as f64,
            2.0,
            50,
        ));
    }
    for &(cell, bias, spread) in extra {
        all.extend(residuals_in(cell, "R", ResidualKind::Rssi, bias, spread, 50));
    }
    all
}

#[test]
fn the_flag_rule_needs_the_robust_z_the_effect_and_the_count() {
    let residuals = population(&[
        ([0, 1], -6.0, 2.0), // attenuated: flagged
        ([1, 1], -2.0, 2.0), // below the minimum effect (3 dB): not flagged
        ([2, 1], 6.0, 2.0),  // stronger than expected: not an obstacle
        ([3, 1], 0.0, 9.0),  // abnormal spread: flagged only with flag_spread
    ]);
    let mut few = residuals_in([4, 1], "R", ResidualKind::Rssi, -9.0, 1.0, 49); // below min_count
    few.extend(residuals);
    let settings = SurveySettings::default();
    let map = SurveyMap::build(&few, &settings).unwrap();
    let entry = |cell: [i64; 2]| map.cells().iter().find(|e| e.cell == cell).unwrap().summary;
    // independent computation of z for the attenuated cell
    let biases: Vec<f64> = map
        .cells()
        .iter()
        .filter(|e| e.summary.count >= 50)
        .map(|e| e.summary.bias)
        .collect();
    let (m, mad) = median_and_mad(&biases).unwrap();
    let scale = (1.482_602_218_505_602 * mad).max(3.0 / 3.5);
    assert!((entry([0, 1]).z.unwrap() - (-6.0 - m) / scale).abs() < 1e-9);
    assert!(entry([0, 1]).degraded.bias && entry([0, 1]).degraded.any());
    assert!(!entry([1, 1]).degraded.any() && !entry([2, 1]).degraded.any());
    assert!(entry([2, 1]).z.unwrap() > 3.5); // significant, but in the wrong direction
    assert!(entry([3, 1]).spread_z.unwrap() > 3.5 && !entry([3, 1]).degraded.any());
    assert_eq!(entry([4, 1]).z, None);
    assert!(!entry([4, 1]).degraded.any());
    let flagged: Vec<[i64; 2]> = map.flagged_cells().iter().map(|e| e.cell).collect();
    assert_eq!(flagged, [[0, 1]]);
    // the reader: flagged through its cell, not by its own (diluted) bias
    let reader = &map.readers()[0];
    assert_eq!(reader.flagged_cells, 1);
    assert!(reader.summary.degraded.cells && !reader.summary.degraded.bias);
    assert_eq!(reader.summary.degraded.name(), "cells");

    let spread = SurveySettings {
        flag_spread: true,
        ..settings
    };
    let map = SurveyMap::build(&few[49..], &spread).unwrap();
    let mut flagged: Vec<[i64; 2]> = map.flagged_cells().iter().map(|e| e.cell).collect();
    flagged.sort_unstable();
    assert_eq!(flagged, [[0, 1], [3, 1]]);
}

#[test]
fn ranges_are_flagged_for_excess_path_and_small_populations_are_not_scored() {
    let mut all = Vec::new();
    for k in 0..8 {
        all.extend(residuals_in([k, 0], "U", ResidualKind::Range, 0.01 * k as f64, 0.1, 50));
    }
    all.extend(residuals_in([0, 1], "U", ResidualKind::Range, 1.2, 0.1, 50)); // NLOS
    all.extend(residuals_in([1, 1], "U", ResidualKind::Range, -1.2, 0.1, 50)); // short: not NLOS
    let map = SurveyMap::build(&all, &SurveySettings::default()).unwrap();
    let flagged: Vec<[i64; 2]> = map.flagged_cells().iter().map(|e| e.cell).collect();
    assert_eq!(flagged, [[0, 1]]);
    // four entries are no population
    let map = SurveyMap::build(&all[..200], &SurveySettings::default()).unwrap();
    assert!(map.cells().iter().all(|e| e.summary.z.is_none()));
    // readers: 6 of them, one with a bias over all its links
    let mut all = Vec::new();
    for (k, bias) in [0.1, -0.2, 0.0, 0.3, -0.1, -5.0].into_iter().enumerate() {
        all.extend(residuals_in(
            [k as i64, 0],
            &format!("R{k}"),
            ResidualKind::Rssi,
            bias,
            1.0,
            50,
        ));
    }
    let map = SurveyMap::build(&all, &SurveySettings::default()).unwrap();
    let flagged: Vec<&str> = map.flagged_readers().iter().map(|e| e.reader.as_str()).collect();
    assert_eq!(flagged, ["R5"]);
    assert!(map.flagged_readers()[0].summary.degraded.bias);
}

#[test]
fn distance_bands_compare_cells_with_cells_as_far_from_their_reader() {
    // 20 far cells (45 m) biased upwards by the detection threshold (+4 dB), 10 near ones
    // (12 m) around 0 dB, and a near cell attenuated by 4 dB
    let mut all = Vec::new();
    for k in 0..20 {
        let mut far = residuals_in([k, 5], "R", ResidualKind::Rssi, 4.0 + 0.05 * k as f64, 1.0, 50);
        far.iter_mut().for_each(|r| r.distance_m = 45.0);
        all.append(&mut far);
    }
    for k in 0..10 {
        all.extend(residuals_in(
            [k, 0],
            "R",
            ResidualKind::Rssi,
            0.1 * k as f64 - 0.5,
            1.0,
            50,
        ));
    }
    all.extend(residuals_in([0, 1], "R", ResidualKind::Rssi, -4.0, 1.0, 50));
    let banded = SurveyMap::build(&all, &SurveySettings::default()).unwrap();
    assert_eq!(
        banded.flagged_cells().iter().map(|e| e.cell).collect::<Vec<_>>(),
        [[0, 1]]
    );
    let one = SurveySettings {
        distance_band_m: None,
        ..SurveySettings::default()
    };
    let unbanded = SurveyMap::build(&all, &one).unwrap();
    // among all cells the median is a far cell's (≈ 4 dB): every near cell sits ≥ 3.6 dB below
    assert_eq!(unbanded.flagged_cells().len(), 11);
}

#[test]
fn corrections_fall_back_from_the_cell_to_the_reader_and_leave_other_records_alone() {
    let mut all = population(&[([0, 1], -6.0, 2.0)]);
    all.extend(residuals_in([5, 1], "R", ResidualKind::Rssi, -8.0, 1.0, 10)); // too few
    let map = SurveyMap::build(&all, &SurveySettings::default()).unwrap();
    let correction = map.correction("R", ResidualKind::Rssi, [5.0, 15.0]).unwrap();
    assert_eq!((correction.bias, correction.source), (-6.0, CorrectionSource::Cell));
    // unflagged cells and the unflagged reader give nothing by default …
    assert_eq!(map.correction("R", ResidualKind::Rssi, [15.0, 5.0]), None);
    assert_eq!(map.correction("R", ResidualKind::Range, [5.0, 15.0]), None);
    assert_eq!(map.correction("Q", ResidualKind::Rssi, [5.0, 15.0]), None);
    // … and everything with enough residuals when asked
    let all_settings = SurveySettings {
        correct_unflagged: true,
        ..SurveySettings::default()
    };
    let map_all = SurveyMap::build(&all, &all_settings).unwrap();
    let cell = map_all.correction("R", ResidualKind::Rssi, [15.0, 5.0]).unwrap();
    assert!((cell.bias - -0.8).abs() < 1e-12 && cell.source == CorrectionSource::Cell);
    let reader = map_all.correction("R", ResidualKind::Rssi, [55.0, 15.0]).unwrap();
    assert_eq!((reader.source, reader.count), (CorrectionSource::Reader, 1060));

    // records: RSSI and RSSI vectors get ρ − b, ranges max(r − b, 0), others unchanged
    let at = [5.0, 15.0];
    let corrected = map.correct_record(&record(1.0, rssi("R", -70.0)), at);
    assert_eq!(corrected.measurement, rssi("R", -64.0));
    let scan = Measurement::RssiVector {
        readings: vec![
            AnchorReading {
                anchor: "R".into(),
                rssi_dbm: -70.0,
            },
            AnchorReading {
                anchor: "Q".into(),
                rssi_dbm: -75.0,
            },
        ],
    };
    let corrected = map.correct_record(&record(1.0, scan), at);
    let Measurement::RssiVector { readings } = corrected.measurement else {
        panic!("a vector stays a vector")
    };
    assert_eq!((readings[0].rssi_dbm, readings[1].rssi_dbm), (-64.0, -75.0));
    let ranges: Vec<Residual> = (0..8)
        .flat_map(|k| residuals_in([k, 0], "U", ResidualKind::Range, 0.0, 0.1, 50))
        .chain(residuals_in([0, 1], "U", ResidualKind::Range, 2.0, 0.1, 50))
        .collect();
    let range_map = SurveyMap::build(&ranges, &SurveySettings::default()).unwrap();
    let short = range_map.correct_record(&record(1.0, range("U", 1.5)), at);
    assert_eq!(short.measurement, range("U", 0.0));
    let long = range_map.correct_record(&record(1.0, range("U", 7.5)), at);
    assert_eq!(long.measurement, range("U", 5.5));
    let fix = record(
        1.0,
        Measurement::Fix {
            position_m: vec![1.0, 2.0],
            covariance_m2: vec![1.0, 0.0, 0.0, 1.0],
        },
    );
    assert_eq!(range_map.correct_record(&fix, at), fix);
}

#[test]
fn degradation_names_round_trip() {
    for bits in 0..8u8 {
        let d = Degradation {
            bias: bits & 1 != 0,
            spread: bits & 2 != 0,
            cells: bits & 4 != 0,
        };
        assert_eq!(Degradation::from_name(&d.name()), Some(d));
    }
    assert_eq!(Degradation::from_name("spread+bias"), None);
    assert_eq!(ResidualKind::from_name("rssi"), Some(ResidualKind::Rssi));
    assert_eq!(ResidualKind::from_name("tdoa"), None);
}
