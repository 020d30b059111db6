//! Zone event tests: anti-flap, one enter and one exit per real crossing, dwell, head counts,
//! order, errors.

use super::*;
use crate::zones::ZoneKind;

fn square(id: &str, x0: f64) -> Zone {
    Zone {
        id: id.into(),
        name: id.into(),
        kind: ZoneKind::Hazard,
        readers: vec![],
        shape: Shape::Polygon {
            vertices_m: vec![[x0, 0.0], [x0 + 10.0, 0.0], [x0 + 10.0, 10.0], [x0, 10.0]],
            floor: None,
            z_range_m: Some([0.0, 3.0]),
        },
    }
}

fn monitor(tolerance_m: f64, delay_s: f64) -> ZoneMonitor {
    ZoneMonitor::new(vec![square("z", 0.0)], AntiFlap { tolerance_m, delay_s }).unwrap()
}

fn kinds(events: &[ZoneEvent]) -> Vec<&'static str> {
    events
        .iter()
        .map(|e| match e {
            ZoneEvent::Enter { .. } => "enter",
            ZoneEvent::Exit { .. } => "exit",
            ZoneEvent::Dwell { .. } => "dwell",
        })
        .collect()
}

#[test]
fn wobbling_within_half_the_tolerance_does_not_flap() {
    let mut m = monitor(1.0, 0.0);
    let mut events = Vec::new();
    // border at x = 0; the tag wobbles x = ±0.5 m for 100 s
    for k in 0..100 {
        let x = if k % 2 == 0 { 0.5 } else { -0.5 };
        events.extend(m.update("t", f64::from(k), [x, 5.0, 1.0]).unwrap());
    }
    assert!(events.is_empty(), "{events:?}");
    // now inside for real, then wobble on the border again: stays inside, no exit
    events.extend(m.update("t", 100.0, [5.0, 5.0, 1.0]).unwrap());
    for k in 101..200 {
        let x = if k % 2 == 0 { 0.5 } else { -0.5 };
        events.extend(m.update("t", f64::from(k), [x, 5.0, 1.0]).unwrap());
    }
    assert_eq!(kinds(&events), ["enter"]);
    assert_eq!(m.head_count("z"), 1);
}

#[test]
fn a_real_crossing_gives_exactly_one_enter_and_one_exit() {
    let mut m = monitor(1.0, 2.0);
    let mut events = Vec::new();
    // walk along +x at 1 m/s from x = −20 to x = 30, with ±0.4 m noise
    for k in 0..=50 {
        let noise = if k % 2 == 0 { 0.4 } else { -0.4 };
        let x = -20.0 + f64::from(k) + noise;
        events.extend(m.update("t", f64::from(k), [x, 5.0, 1.0]).unwrap());
    }
    assert_eq!(kinds(&events), ["enter", "exit"]);
    // clearly inside (x ≥ 1 m) from t = 22 (x = 2.4; at t = 21, x = 0.6): confirmed 2 s later
    assert_eq!(events[0].time_s(), 24.0);
    assert_eq!(events[0].tag(), "t");
    assert_eq!(events[0].zone(), "z");
    // clearly outside (x ≥ 11 m) from t = 32 (x = 12.4; at t = 31, x = 10.6): confirmed at 34
    assert_eq!(events[1].time_s(), 34.0);
    assert_eq!(m.head_count("z"), 0);
}

#[test]
fn a_short_visit_shorter_than_the_delay_gives_no_event() {
    let mut m = monitor(0.0, 5.0);
    let mut events = Vec::new();
    for (t, x) in [(0.0, -5.0), (1.0, 5.0), (3.0, 5.0), (4.0, -5.0), (20.0, -5.0)] {
        events.extend(m.update("t", t, [x, 5.0, 1.0]).unwrap());
    }
    assert!(events.is_empty());
}

#[test]
fn dwell_reports_come_once_per_interval() {
    let mut m = monitor(0.0, 0.0).with_dwell_interval_s(10.0).unwrap();
    let mut events = Vec::new();
    for t in 0..=35 {
        events.extend(m.update("t", f64::from(t), [5.0, 5.0, 1.0]).unwrap());
    }
    assert_eq!(kinds(&events), ["enter", "dwell", "dwell", "dwell"]);
    let dwell: Vec<(f64, f64)> = events[1..]
        .iter()
        .map(|e| match e {
            ZoneEvent::Dwell { time_s, dwell_s, .. } => (*time_s, *dwell_s),
            _ => unreachable!(),
        })
        .collect();
    assert_eq!(dwell, [(10.0, 10.0), (20.0, 20.0), (30.0, 30.0)]);
    // a long gap gives one report, not a burst
    let late = m.update("t", 100.0, [5.0, 5.0, 1.0]).unwrap();
    assert_eq!(kinds(&late), ["dwell"]);
    assert!(m.update("t", 105.0, [5.0, 5.0, 1.0]).unwrap().is_empty());
    assert_eq!(kinds(&m.update("t", 110.0, [5.0, 5.0, 1.0]).unwrap()), ["dwell"]);
}

#[test]
fn head_counts_and_occupants_follow_the_tags() {
    let zones = vec![square("b", 20.0), square("a", 0.0)];
    let mut m = ZoneMonitor::new(
        zones,
        AntiFlap {
            tolerance_m: 0.0,
            delay_s: 0.0,
        },
    )
    .unwrap();
    assert_eq!(m.zones()[0].id, "a");
    m.update("t2", 0.0, [5.0, 5.0, 1.0]).unwrap();
    m.update("t1", 0.0, [5.0, 5.0, 1.0]).unwrap();
    m.update("t3", 0.0, [25.0, 5.0, 1.0]).unwrap();
    m.update("t4", 0.0, [15.0, 5.0, 1.0]).unwrap();
    assert_eq!((m.head_count("a"), m.head_count("b"), m.head_count("c")), (2, 1, 0));
    assert_eq!(m.occupants("a"), ["t1", "t2"]);
    m.update("t1", 1.0, [25.0, 5.0, 1.0]).unwrap();
    assert_eq!((m.head_count("a"), m.head_count("b")), (1, 2));
    assert_eq!(kinds(&m.remove_tag("t3", 2.0).unwrap()), ["exit"]);
    assert!(m.remove_tag("unknown", 2.0).unwrap().is_empty());
    assert_eq!(m.head_count("b"), 1);
    assert!(m.occupants("nowhere").is_empty());
}

#[test]
fn events_of_one_update_come_in_zone_id_order() {
    // two overlapping zones given out of order
    let zones = vec![square("z2", 0.0), square("z1", 5.0)];
    let mut m = ZoneMonitor::new(
        zones,
        AntiFlap {
            tolerance_m: 0.0,
            delay_s: 0.0,
        },
    )
    .unwrap();
    let events = m.update("t", 0.0, [7.0, 5.0, 1.0]).unwrap();
    let order: Vec<&str> = events.iter().map(ZoneEvent::zone).collect();
    assert_eq!(order, ["z1", "z2"]);
    let exits = m.update("t", 1.0, [50.0, 5.0, 1.0]).unwrap();
    assert_eq!(exits.iter().map(ZoneEvent::zone).collect::<Vec<_>>(), ["z1", "z2"]);
    assert_eq!(kinds(&exits), ["exit", "exit"]);
}

#[test]
fn height_range_counts_for_events() {
    let mut m = monitor(0.0, 0.0);
    assert!(m.update("t", 0.0, [5.0, 5.0, 10.0]).unwrap().is_empty()); // above the zone
    assert_eq!(kinds(&m.update("t", 1.0, [5.0, 5.0, 1.0]).unwrap()), ["enter"]);
}

#[test]
fn bad_inputs_are_errors_and_leave_the_state_alone() {
    let mut m = monitor(0.0, 0.0);
    m.update("t", 5.0, [5.0, 5.0, 1.0]).unwrap();
    let name = |r: Result<Vec<ZoneEvent>>| match r {
        Err(EngineError::InvalidParameter { name, .. }) => name,
        other => panic!("{other:?}"),
    };
    assert_eq!(name(m.update("t", 4.0, [50.0, 5.0, 1.0])), "time_s");
    assert_eq!(name(m.update("t", f64::NAN, [5.0, 5.0, 1.0])), "time_s");
    assert_eq!(name(m.update("t", 6.0, [f64::INFINITY, 5.0, 1.0])), "position_m");
    assert_eq!(name(m.remove_tag("t", f64::NAN)), "time_s");
    assert_eq!(m.head_count("z"), 1);
    // same time stamp is fine
    assert!(m.update("t", 5.0, [5.0, 5.0, 1.0]).unwrap().is_empty());
}

#[test]
fn construction_errors_name_the_problem() {
    let flap = AntiFlap {
        tolerance_m: 0.0,
        delay_s: 0.0,
    };
    let field = |r: Result<ZoneMonitor>| match r {
        Err(EngineError::Parse { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(
        field(ZoneMonitor::new(vec![square("a", 0.0), square("a", 1.0)], flap)),
        "zones[1].id"
    );
    let mut unresolved = square("a", 0.0);
    if let Shape::Polygon { floor, z_range_m, .. } = &mut unresolved.shape {
        *floor = Some("L1".into());
        *z_range_m = None;
    }
    assert_eq!(field(ZoneMonitor::new(vec![unresolved], flap)), "zones[0].shape.floor");
    let mut bad = square("a", 0.0);
    if let Shape::Polygon { vertices_m, .. } = &mut bad.shape {
        vertices_m.truncate(2);
    }
    assert_eq!(field(ZoneMonitor::new(vec![bad], flap)), "zones[0].shape.vertices_m");
    for bad_flap in [
        AntiFlap {
            tolerance_m: -0.1,
            delay_s: 0.0,
        },
        AntiFlap {
            tolerance_m: 0.0,
            delay_s: f64::INFINITY,
        },
    ] {
        assert!(matches!(
            ZoneMonitor::new(vec![], bad_flap),
            Err(EngineError::InvalidParameter { .. })
        ));
    }
    let m = ZoneMonitor::new(vec![], flap).unwrap();
    assert!(m.clone().with_dwell_interval_s(f64::NAN).is_err());
    assert!(m.with_dwell_interval_s(-1.0).is_err());
}
