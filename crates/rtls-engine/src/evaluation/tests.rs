//! Statistics against hand-computed values; interpolation, 2-D/3-D errors and unmatched counts
//! against hand-worked cases.

use super::statistics::percentile;
use super::{
    evaluate, ErrorStatistics, EvaluationSettings, TrackSample, TruthSample, Unmatched, TRACKS_SOURCE, TRUTH_SOURCE,
};
use crate::EngineError;

fn truth(tag: &str, time_s: f64, position_m: &[f64], line: usize) -> TruthSample {
    TruthSample {
        time_s,
        tag: tag.into(),
        position_m: [position_m[0], position_m[1], position_m.get(2).copied().unwrap_or(0.0)],
        has_z: position_m.len() == 3,
        line,
    }
}

fn track(tag: &str, time_s: f64, position_m: &[f64], predicted: bool, line: usize) -> TrackSample {
    TrackSample {
        time_s,
        tag: tag.into(),
        position_m: [position_m[0], position_m[1], position_m.get(2).copied().unwrap_or(0.0)],
        has_z: position_m.len() == 3,
        predicted,
        covariance_m2: None,
        line,
    }
}

fn settings(max_gap_s: f64, skip_initial_s: f64, include_predicted: bool, dimensions: usize) -> EvaluationSettings {
    EvaluationSettings {
        max_gap_s,
        skip_initial_s,
        include_predicted,
        dimensions,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + b.abs())
}

fn parse_error(error: EngineError) -> (String, usize, String, String) {
    let message = error.to_string();
    match error {
        EngineError::Parse { file, line, field, .. } => (file, line, field, message),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn statistics_match_hand_values() {
    // sorted: 1 2 3 4 10; Σe = 20, Σe² = 130
    let stats = ErrorStatistics::from_errors(&[4.0, 10.0, 1.0, 3.0, 2.0]).unwrap();
    assert_eq!(stats.count, 5);
    assert!(close(stats.mean_m, 4.0));
    assert!(close(stats.rmse_m, 26f64.sqrt()));
    assert!(close(stats.median_m, 3.0));
    assert!(close(stats.p90_m, 7.6)); // h = 3.6: 4 + 0.6·6
    assert!(close(stats.p95_m, 8.8)); // h = 3.8: 4 + 0.8·6
    assert_eq!(stats.max_m, 10.0);

    // even count: 1 2 3 4
    let stats = ErrorStatistics::from_errors(&[1.0, 2.0, 3.0, 4.0]).unwrap();
    assert!(close(stats.median_m, 2.5)); // h = 1.5
    assert!(close(stats.p90_m, 3.7)); // h = 2.7
    assert!(close(stats.p95_m, 3.85)); // h = 2.85
    assert!(close(stats.rmse_m, 7.5f64.sqrt())); // 30 / 4

    let one = ErrorStatistics::from_errors(&[0.7]).unwrap();
    assert_eq!(
        (one.count, one.median_m, one.p95_m, one.max_m, one.mean_m),
        (1, 0.7, 0.7, 0.7, 0.7)
    );
}

#[test]
fn percentile_type_7_end_points_and_ties() {
    let sorted = [0.0, 1.0, 1.0, 5.0];
    assert_eq!(percentile(&sorted, 0.0), 0.0);
    assert_eq!(percentile(&sorted, 1.0), 5.0);
    assert!(close(percentile(&sorted, 0.5), 1.0));
    assert!(close(percentile(&sorted, 0.25), 0.75)); // h = 0.75
    assert!(close(percentile(&sorted, 0.9), 3.8)); // h = 2.7: 1 + 0.7·4
}

#[test]
fn statistics_refuse_empty_and_invalid_errors() {
    for errors in [&[][..], &[1.0, -0.5], &[f64::NAN], &[f64::INFINITY]] {
        match ErrorStatistics::from_errors(errors) {
            Err(EngineError::InvalidParameter { name: "errors_m", .. }) => {}
            other => panic!("{errors:?}: {other:?}"),
        }
    }
}

#[test]
fn truth_is_interpolated_linearly_between_bracketing_samples() {
    // truth of `a` from (0, 0) at 0 s to (10, 20) at 1 s, given out of order
    let truth = [truth("a", 1.0, &[10.0, 20.0], 3), truth("a", 0.0, &[0.0, 0.0], 2)];
    let tracks = [
        track("a", 0.25, &[2.8, 5.4], false, 1), // truth (2.5, 5): error |(0.3, 0.4)| = 0.5
        track("a", 0.75, &[7.5, 15.0], false, 2), // truth (7.5, 15): error 0
        track("a", 1.0, &[10.0, 21.0], false, 3), // exactly at a truth sample: error 1
        track("a", 0.1, &[1.0, 2.0, 7.0], false, 4), // z ignored in 2-D: error 0
    ];
    let evaluation = evaluate(&truth, &tracks, &settings(1.0, 0.0, false, 2)).unwrap();
    let overall = &evaluation.overall;
    assert_eq!(overall.count, 4);
    assert!(close(overall.mean_m, 1.5 / 4.0));
    assert!(close(overall.rmse_m, (1.25f64 / 4.0).sqrt()));
    assert!(close(overall.median_m, 0.25)); // sorted 0 0 0.5 1
    assert!(close(overall.max_m, 1.0));
    assert_eq!(evaluation.per_tag.len(), 1);
    assert_eq!(evaluation.per_tag[0], ("a".to_string(), overall.clone()));
    assert_eq!(evaluation.unmatched, Unmatched::default());
    assert!(evaluation.unmatched_per_tag.is_empty());
}

#[test]
fn three_dimensions_use_z_and_two_dimensions_ignore_it() {
    let truth = [
        truth("a", 0.0, &[0.0, 0.0, 0.0], 2),
        truth("a", 2.0, &[0.0, 0.0, 4.0], 3),
    ];
    // at 0.5 s the truth is (0, 0, 1): difference (1, 2, 2)
    let tracks = [track("a", 0.5, &[1.0, 2.0, 3.0], false, 1)];
    let three = evaluate(&truth, &tracks, &settings(2.0, 0.0, false, 3)).unwrap();
    assert!(close(three.overall.rmse_m, 3.0));
    let two = evaluate(&truth, &tracks, &settings(2.0, 0.0, false, 2)).unwrap();
    assert!(close(two.overall.rmse_m, 5f64.sqrt()));
}

#[test]
fn three_dimensions_name_the_sample_without_z() {
    let truth_2d_end = [truth("a", 0.0, &[0.0, 0.0, 0.0], 2), truth("a", 1.0, &[1.0, 0.0], 3)];
    // the track sample has no z
    let flat_track = [track("a", 0.5, &[0.5, 0.0], false, 7)];
    let (file, line, field, message) =
        parse_error(evaluate(&truth_2d_end, &flat_track, &settings(1.0, 0.0, false, 3)).unwrap_err());
    assert_eq!((file.as_str(), line, field.as_str()), (TRACKS_SOURCE, 7, "z"));
    assert!(message.contains("tag `a`") && message.contains("2-D"), "{message}");
    // the upper truth sample has no z
    let tall_track = [track("a", 0.5, &[0.5, 0.0, 0.0], false, 7)];
    let (file, line, field, message) =
        parse_error(evaluate(&truth_2d_end, &tall_track, &settings(1.0, 0.0, false, 3)).unwrap_err());
    assert_eq!((file.as_str(), line, field.as_str()), (TRUTH_SOURCE, 3, "z"));
    assert!(message.contains("tracks line 7"), "{message}");
    // at the exact time of the 3-D truth sample only that sample is needed
    let at_start = [track("a", 0.0, &[0.0, 0.0, 0.25], false, 1)];
    let evaluation = evaluate(&truth_2d_end, &at_start, &settings(1.0, 0.0, false, 3)).unwrap();
    assert!(close(evaluation.overall.max_m, 0.25));
    // 2-D needs no z anywhere
    assert!(evaluate(&truth_2d_end, &flat_track, &settings(1.0, 0.0, false, 2)).is_ok());
}

#[test]
fn unmatched_samples_are_counted_by_reason() {
    let truth = [
        truth("a", 0.0, &[0.0, 0.0], 2),
        truth("a", 0.5, &[5.0, 0.0], 3),
        truth("a", 1.0, &[10.0, 0.0], 4),
        truth("a", 3.0, &[10.0, 0.0], 5), // 2 s gap before this one
        truth("a", 3.5, &[10.0, 5.0], 6),
    ];
    let tracks = [
        track("a", -1.0, &[0.0, 0.0], false, 1), // a's first sample: in the skipped 0.2 s
        track("a", -0.5, &[0.0, 0.0], false, 2), // before the truth
        track("a", 0.25, &[2.5, 0.1], false, 3), // error 0.1
        track("a", 0.75, &[7.5, 0.0], true, 4),  // predicted, error 0 when included
        track("a", 2.0, &[10.0, 0.0], false, 5), // truth gap
        track("a", 3.25, &[10.0, 2.2], false, 6), // truth (10, 2.5): error 0.3
        track("a", 4.0, &[10.0, 5.0], false, 7), // after the truth
        track("a", 0.5, &[5.0, 0.6], true, 8),   // predicted, error 0.6 when included
        track("b", 0.0, &[0.0, 0.0], false, 9),  // b's first sample: skipped
        track("b", 1.0, &[0.0, 0.0], false, 10), // b has no truth
    ];
    let evaluation = evaluate(&truth, &tracks, &settings(0.5, 0.2, false, 2)).unwrap();
    let expected = Unmatched {
        predicted_excluded: 2,
        initial_skipped: 2,
        tag_not_in_truth: 1,
        outside_truth_span: 2,
        truth_gap: 1,
    };
    assert_eq!(evaluation.unmatched, expected);
    assert_eq!(evaluation.overall.count + evaluation.unmatched.total(), tracks.len());
    assert_eq!(evaluation.overall.count, 2);
    assert!(close(evaluation.overall.max_m, 0.3));
    assert!(close(evaluation.overall.mean_m, 0.2));
    assert_eq!(
        evaluation
            .per_tag
            .iter()
            .map(|(tag, _)| tag.as_str())
            .collect::<Vec<_>>(),
        ["a"]
    );
    assert_eq!(
        evaluation.unmatched_per_tag,
        [
            (
                "a".to_string(),
                Unmatched {
                    predicted_excluded: 2,
                    initial_skipped: 1,
                    tag_not_in_truth: 0,
                    outside_truth_span: 2,
                    truth_gap: 1
                }
            ),
            (
                "b".to_string(),
                Unmatched {
                    initial_skipped: 1,
                    tag_not_in_truth: 1,
                    ..Unmatched::default()
                }
            ),
        ]
    );

    // predicted samples scored when asked: 0.1, 0, 0.3, 0.6
    let with_predicted = evaluate(&truth, &tracks, &settings(0.5, 0.2, true, 2)).unwrap();
    assert_eq!(with_predicted.overall.count, 4);
    assert_eq!(with_predicted.unmatched.predicted_excluded, 0);
    assert!(close(with_predicted.overall.mean_m, 0.25));
    assert!(close(with_predicted.overall.max_m, 0.6));

    // a wider gap allowance scores the sample at 2 s (truth (10, 0): error 0)
    let wide = evaluate(&truth, &tracks, &settings(2.0, 0.2, false, 2)).unwrap();
    assert_eq!((wide.overall.count, wide.unmatched.truth_gap), (3, 0));
}

#[test]
fn gap_limit_is_inclusive_and_zero_means_exact_times_only() {
    let truth = [truth("a", 0.0, &[0.0, 0.0], 2), truth("a", 0.5, &[1.0, 0.0], 3)];
    let tracks = [
        track("a", 0.25, &[0.5, 0.0], false, 1),
        track("a", 0.5, &[1.0, 0.0], false, 2),
    ];
    let inclusive = evaluate(&truth, &tracks, &settings(0.5, 0.0, false, 2)).unwrap();
    assert_eq!(inclusive.overall.count, 2);
    let exact = evaluate(&truth, &tracks, &settings(0.0, 0.0, false, 2)).unwrap();
    assert_eq!((exact.overall.count, exact.unmatched.truth_gap), (1, 1));
    let unlimited = evaluate(&truth, &tracks, &settings(f64::INFINITY, 0.0, false, 2)).unwrap();
    assert_eq!(unlimited.overall.count, 2);
}

#[test]
fn per_tag_statistics_are_separate_and_sorted() {
    let truth = [
        truth("zeta", 0.0, &[0.0, 0.0], 2),
        truth("zeta", 1.0, &[0.0, 0.0], 3),
        truth("alpha", 0.0, &[5.0, 5.0], 4),
        truth("alpha", 1.0, &[5.0, 5.0], 5),
    ];
    let tracks = [
        track("zeta", 0.5, &[3.0, 4.0], false, 1),
        track("alpha", 0.5, &[5.0, 6.0], false, 2),
        track("alpha", 0.6, &[5.0, 8.0], false, 3),
    ];
    let evaluation = evaluate(&truth, &tracks, &settings(1.0, 0.0, false, 2)).unwrap();
    let tags: Vec<_> = evaluation
        .per_tag
        .iter()
        .map(|(tag, stats)| (tag.as_str(), stats.count))
        .collect();
    assert_eq!(tags, [("alpha", 2), ("zeta", 1)]);
    assert!(close(evaluation.per_tag[0].1.mean_m, 2.0)); // errors 1 and 3
    assert!(close(evaluation.per_tag[1].1.rmse_m, 5.0));
    assert!(close(evaluation.overall.mean_m, 3.0)); // 1, 3, 5
}

#[test]
fn nothing_scored_is_an_error_with_the_counts() {
    let truth = [truth("a", 0.0, &[0.0, 0.0], 2), truth("a", 1.0, &[0.0, 0.0], 3)];
    let tracks = [
        track("b", 0.5, &[0.0, 0.0], false, 1),
        track("a", 0.5, &[0.0, 0.0], true, 2),
        track("a", 5.0, &[0.0, 0.0], false, 3),
    ];
    let (file, line, _, message) = parse_error(evaluate(&truth, &tracks, &settings(1.0, 0.0, false, 2)).unwrap_err());
    assert_eq!((file.as_str(), line), (TRACKS_SOURCE, 0));
    for needle in [
        "of 3 samples",
        "1 predicted",
        "1 of tags without truth",
        "1 outside the truth's time span",
        "0 in truth gaps",
    ] {
        assert!(message.contains(needle), "{needle}: {message}");
    }
    let (_, _, _, empty) = parse_error(evaluate(&truth, &[], &EvaluationSettings::default()).unwrap_err());
    assert!(empty.contains("of 0 samples"), "{empty}");
}

#[test]
fn bad_settings_and_samples_are_refused() {
    let truth = [truth("a", 0.0, &[0.0, 0.0], 2), truth("a", 1.0, &[0.0, 0.0], 3)];
    let tracks = [track("a", 0.5, &[0.0, 0.0], false, 1)];
    for (settings, expected) in [
        (settings(1.0, 0.0, false, 1), "dimensions"),
        (settings(1.0, 0.0, false, 4), "dimensions"),
        (settings(f64::NAN, 0.0, false, 2), "max_gap_s"),
        (settings(-0.1, 0.0, false, 2), "max_gap_s"),
        (settings(1.0, -1.0, false, 2), "skip_initial_s"),
        (settings(1.0, f64::INFINITY, false, 2), "skip_initial_s"),
    ] {
        match evaluate(&truth, &tracks, &settings) {
            Err(EngineError::InvalidParameter { name, .. }) => assert_eq!(name, expected),
            other => panic!("{settings:?}: {other:?}"),
        }
    }
    let mut bad_track = tracks[0].clone();
    bad_track.position_m[1] = f64::NAN;
    let (file, line, field, _) =
        parse_error(evaluate(&truth, &[bad_track], &EvaluationSettings::default()).unwrap_err());
    assert_eq!((file.as_str(), line, field.as_str()), (TRACKS_SOURCE, 1, "y"));
    let mut bad_truth = truth.clone();
    bad_truth[1].time_s = f64::INFINITY;
    let (file, line, field, _) =
        parse_error(evaluate(&bad_truth, &tracks, &EvaluationSettings::default()).unwrap_err());
    assert_eq!((file.as_str(), line, field.as_str()), (TRUTH_SOURCE, 3, "t"));
    // conflicting truth at one time, built in code
    let conflicting = [
        truth[0].clone(),
        truth[1].clone(),
        self::truth("a", 1.0, &[0.0, 1.0], 9),
    ];
    let (file, line, field, message) =
        parse_error(evaluate(&conflicting, &tracks, &EvaluationSettings::default()).unwrap_err());
    assert_eq!((file.as_str(), line, field.as_str()), (TRUTH_SOURCE, 9, "y"));
    assert!(message.contains("line 3"), "{message}");
}
