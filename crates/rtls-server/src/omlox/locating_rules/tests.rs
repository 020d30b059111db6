use super::*;
use crate::omlox::Point;
use crate::omlox::{Location, ProviderType, Trackable};

fn location(provider_id: &str, kind: ProviderType, accuracy: Option<f64>) -> Location {
    Location {
        position: Point {
            coordinates: vec![1.0, 2.0],
        },
        source: "zone-a".into(),
        provider_type: kind,
        provider_id: provider_id.into(),
        timestamp_generated: None,
        timestamp_sent: None,
        crs: None,
        associated: None,
        accuracy,
        floor: None,
        true_heading: None,
        magnetic_heading: None,
        heading_accuracy: None,
        elevation_ref: None,
        speed: None,
        course: None,
        trackables: None,
        properties: None,
    }
}

fn holds(expression: &str, location: &Location, age_ms: f64) -> bool {
    Expr::parse(expression)
        .unwrap_or_else(|e| panic!("`{expression}`: {e}"))
        .matches(&Subject { location, age_ms })
}

fn uwb(accuracy: f64) -> Location {
    location("tag-1", ProviderType::Uwb, Some(accuracy))
}

#[test]
fn the_spec_example_holds_for_a_close_uwb_fix_only() {
    let rule = "type = 'uwb' AND accuracy < 5";
    assert!(holds(rule, &uwb(0.3), 0.0));
    assert!(!holds(rule, &uwb(5.0), 0.0), "5 is not < 5");
    assert!(!holds(rule, &location("tag-1", ProviderType::Ibeacon, Some(0.3)), 0.0));
}

#[test]
fn and_binds_tighter_than_or() {
    // a OR b AND c = a OR (b AND c): true for a wifi fix however inaccurate
    let wifi = location("w", ProviderType::Wifi, Some(50.0));
    assert!(holds("type = 'wifi' OR type = 'uwb' AND accuracy < 1", &wifi, 0.0));
    // (a OR b) AND c is false for it
    assert!(!holds("(type = 'wifi' OR type = 'uwb') AND accuracy < 1", &wifi, 0.0));
    // b AND c OR a, written the other way round, is the same
    assert!(holds("type = 'uwb' AND accuracy < 1 OR type = 'wifi'", &wifi, 0.0));
}

#[test]
fn not_negates_what_follows_it() {
    let fix = uwb(0.3);
    assert!(!holds("NOT type = 'uwb'", &fix, 0.0));
    assert!(holds("NOT type = 'gps'", &fix, 0.0));
    assert!(holds("NOT NOT type = 'uwb'", &fix, 0.0));
    // NOT takes the comparison, not the conjunction: (NOT a) AND b
    assert!(!holds("NOT type = 'gps' AND accuracy > 1", &fix, 0.0));
    assert!(holds("NOT (type = 'uwb' AND accuracy > 1)", &fix, 0.0));
    // keywords in any case
    assert!(holds("not type = 'gps' and accuracy < 1 Or type = 'gps'", &fix, 0.0));
}

#[test]
fn every_property_and_operator_is_compared() {
    let mut fix = uwb(0.5);
    fix.floor = Some(2.0);
    fix.speed = Some(1.5);
    for (rule, expected) in [
        ("accuracy = 0.5", true),
        ("accuracy == 0.5", true),
        ("accuracy != 0.5", false),
        ("accuracy <> 0.4", true),
        ("accuracy <= 0.5", true),
        ("accuracy >= 0.6", false),
        ("provider_id = 'tag-1'", true),
        ("provider_id != \"tag-1\"", false),
        ("type = 'uwb'", true),
        ("TYPE = 'uwb'", true),
        ("source = 'zone-a'", true),
        ("source = 'zone-b'", false),
        ("floor = 2", true),
        ("floor > 2", false),
        ("floor >= -1", true),
        ("speed > 1", true),
        ("speed < 1.5", false),
        ("timestamp_diff < 500", true),
        ("timestamp_diff >= 250", true),
        ("timestamp_diff > 250", false),
    ] {
        assert_eq!(holds(rule, &fix, 250.0), expected, "{rule}");
    }
}

#[test]
fn a_property_the_location_lacks_makes_its_comparison_false() {
    let bare = location("t", ProviderType::Unknown, None);
    for rule in [
        "accuracy < 100",
        "accuracy >= 0",
        "accuracy != 3",
        "floor = 0",
        "speed < 1e9",
    ] {
        assert!(!holds(rule, &bare, 0.0), "{rule}");
    }
    // and its negation true (two-valued logic, as documented)
    assert!(holds("NOT accuracy > 5", &bare, 0.0));
}

#[test]
fn quotes_of_either_kind_and_doubled_quotes() {
    let fix = location("o'clock", ProviderType::Rfid, None);
    assert!(holds("provider_id = 'o''clock'", &fix, 0.0));
    assert!(holds("provider_id = \"o'clock\"", &fix, 0.0));
}

#[test]
fn bad_syntax_is_refused_with_its_position() {
    for (rule, position, says) in [
        ("accuracy <", 11, "expected a number or quoted text"),
        ("accuracy 5", 10, "expected an operator"),
        ("colour = 'red'", 1, "unknown property `colour`"),
        ("type = 'uwb' AND", 17, "expected a property"),
        ("type = 'uwb' accuracy < 1", 14, "expected AND, OR or the end"),
        ("(type = 'uwb'", 14, "is not closed"),
        ("type = 'uwb", 8, "not closed"),
        ("accuracy < 1 & speed > 2", 14, "unexpected character `&`"),
        ("accuracy < 'near'", 12, "is a number"),
        ("source < 'a'", 10, "compare it with = or !="),
        ("provider_id = 7", 15, "is text"),
        ("type = 'ble'", 8, "is not a provider type"),
        ("accuracy < 1.2.3", 12, "is not a number"),
        ("", 1, "expected a property"),
        ("type = 'uwb')", 13, "unexpected `)`"),
    ] {
        let error = Expr::parse(rule).expect_err(rule);
        assert_eq!(error.position, position, "{rule}: {error}");
        assert!(error.message.contains(says), "{rule}: {error}");
    }
}

#[test]
fn a_rule_set_names_the_rule_that_does_not_parse() {
    let rules = [
        LocatingRule {
            expression: "type = 'uwb'".into(),
            priority: 1.0,
        },
        LocatingRule {
            expression: "accuracy <".into(),
            priority: 2.0,
        },
    ];
    let error = RuleSet::compile(&rules).unwrap_err();
    assert_eq!(error.index, 1);
    assert_eq!(error.error.position, 11);
    assert!(error.to_string().contains("`accuracy <`"), "{error}");
    // kept leniently (a rule set stored before rules were checked), the bad rule is left out
    let stored = Trackable {
        locating_rules: Some(rules.to_vec()),
        ..crate::pipeline::trackables::implicit_trackable("t")
    };
    let lenient = RuleSet::of_stored(&stored);
    assert_eq!(lenient.rules.len(), 1);
}

fn rules(list: &[(&str, f64)]) -> RuleSet {
    let list: Vec<LocatingRule> = list
        .iter()
        .map(|(expression, priority)| LocatingRule {
            expression: (*expression).into(),
            priority: *priority,
        })
        .collect();
    RuleSet::compile(&list).expect("rules")
}

#[test]
fn the_highest_priority_match_is_taken_and_a_location_matching_none_never() {
    let set = rules(&[("type = 'ibeacon'", 1.0), ("type = 'uwb' AND accuracy < 1", 10.0)]);
    let good_uwb = uwb(0.3);
    let poor_uwb = uwb(5.0);
    let ble = location("tag-2", ProviderType::Ibeacon, Some(3.0));
    let candidate = |time_s, location| Candidate { time_s, location };
    // the uwb fix wins though older
    assert_eq!(
        set.select(&[candidate(10.0, &good_uwb), candidate(11.0, &ble)]),
        Some(0)
    );
    // a poor uwb fix matches no rule: the beacon is taken
    assert_eq!(
        set.select(&[candidate(12.0, &poor_uwb), candidate(11.0, &ble)]),
        Some(1)
    );
    // nothing matches: nothing is taken
    assert_eq!(set.select(&[candidate(12.0, &poor_uwb)]), None);
    assert_eq!(set.select(&[]), None);
}

#[test]
fn ties_go_to_the_newest_then_the_most_accurate() {
    let set = rules(&[("accuracy < 10", 5.0)]);
    let (a, b, c) = (uwb(1.0), uwb(2.0), uwb(0.5));
    let candidate = |time_s, location| Candidate { time_s, location };
    assert_eq!(set.select(&[candidate(1.0, &a), candidate(2.0, &b)]), Some(1));
    assert_eq!(
        set.select(&[candidate(2.0, &a), candidate(2.0, &b), candidate(2.0, &c)]),
        Some(2)
    );
}

#[test]
fn timestamp_diff_is_judged_at_the_newest_candidate() {
    // the uwb fix is 3 s older than the beacon's: too old for its rule
    let set = rules(&[
        ("type = 'uwb' AND timestamp_diff < 2000", 10.0),
        ("type = 'ibeacon'", 1.0),
    ]);
    let (fix, ble) = (uwb(0.3), location("b", ProviderType::Ibeacon, Some(3.0)));
    let candidate = |time_s, location| Candidate { time_s, location };
    assert_eq!(set.select(&[candidate(7.0, &fix), candidate(10.0, &ble)]), Some(1));
    assert_eq!(set.select(&[candidate(8.5, &fix), candidate(10.0, &ble)]), Some(0));
}
