use super::*;

fn body(id: &str, time_s: f64, x: f64, y: f64, sigma_m: f64) -> Body {
    Body {
        id: id.into(),
        provider_id: format!("tag-{id}"),
        time_s,
        coordinates: vec![x, y],
        floor: 0.0,
        radius_m: 0.5,
        sigma_m,
        exit_tolerance_m: 0.0,
        tolerance_timeout_s: None,
    }
}

fn kinds(transitions: &[Transition]) -> Vec<(CollisionType, &str, &str)> {
    transitions
        .iter()
        .map(|t| (t.kind, t.trigger.id.as_str(), t.other.id.as_str()))
        .collect()
}

#[test]
fn uncertainty_decides_whether_two_trackables_collide() {
    // centres 2 m apart, radii 0.5 m: the discs touch only through k·σ
    let settings = CollisionSettings::default();
    let mut detector = CollisionDetector::new(settings);
    assert!(detector.update(body("a", 0.0, 0.0, 0.0, 0.1)).is_empty());
    // 0.5 + 0.5 + k·(0.1 + 0.1) = 1.49 m < 2 m: apart
    assert!(detector.update(body("b", 0.0, 2.0, 0.0, 0.1)).is_empty());
    // b's σ = 0.3: 1 + k·0.4 = 1.98 m, still apart; σ = 0.32: 1 + k·0.42 = 2.03 m, colliding
    assert!(detector.update(body("b", 0.1, 2.0, 0.0, 0.3)).is_empty());
    let started = detector.update(body("b", 0.2, 2.0, 0.0, 0.32));
    assert_eq!(kinds(&started), vec![(CollisionType::CollisionStart, "b", "a")]);
    let start = &started[0];
    assert!((start.distance_m - 2.0).abs() < 1e-12);
    assert_eq!(start.start_s, 0.2);
    // the overlap's middle lies between the two centres, where b's edge passes a's
    let [x, y] = start.area_m.unwrap();
    let (ea, eb) = (0.5 + K_SIGMA_95 * 0.1, 0.5 + K_SIGMA_95 * 0.32);
    assert!((x - (2.0 - 0.5 * (2.0 - ea + eb))).abs() < 1e-12, "{x}");
    assert_eq!(y, 0.0);
    assert_eq!(detector.collisions(), 1);
}

#[test]
fn start_continue_and_end_are_sent_once_per_transition() {
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    detector.update(body("a", 0.0, 0.0, 0.0, 0.1));
    detector.update(body("b", 0.0, 5.0, 0.0, 0.1));
    let mut seen = Vec::new();
    // b walks to a, stays, walks away; a is updated too
    for step in 0..40 {
        let t = 0.1 * f64::from(step);
        let x = if step < 20 {
            5.0 - 0.25 * f64::from(step)
        } else {
            0.25 * f64::from(step - 20)
        };
        for transition in detector.update(body("b", t, x, 0.0, 0.1)) {
            seen.push((transition.kind, step));
        }
        for transition in detector.update(body("a", t, 0.0, 0.0, 0.1)) {
            seen.push((transition.kind, step));
        }
    }
    let starts: Vec<_> = seen
        .iter()
        .filter(|(k, _)| *k == CollisionType::CollisionStart)
        .collect();
    let ends: Vec<_> = seen.iter().filter(|(k, _)| *k == CollisionType::CollisionEnd).collect();
    assert_eq!(starts.len(), 1, "{seen:?}");
    assert_eq!(ends.len(), 1, "{seen:?}");
    // contact at d < 1.49 m: b reaches 1.25 m at step 15; leaves again at 1.5 m (step 26)
    assert_eq!(starts[0].1, 15);
    assert_eq!(ends[0].1, 26);
    // every update in between of either trackable continues it
    let continuing = seen.iter().filter(|(k, _)| *k == CollisionType::Colliding).count();
    assert_eq!(continuing, 2 * (26 - 15) - 1);
    assert_eq!(detector.collisions(), 0);
}

#[test]
fn exit_tolerance_holds_a_collision_until_the_timeout() {
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    let tolerant = |t, x| Body {
        exit_tolerance_m: 1.0,
        tolerance_timeout_s: Some(0.5),
        ..body("b", t, x, 0.0, 0.1)
    };
    detector.update(body("a", 0.0, 0.0, 0.0, 0.1));
    assert_eq!(detector.update(tolerant(0.0, 1.0)).len(), 1);
    // 1.49 m ≤ 2.0 m < 2.49 m: inside the tolerance band, held
    assert_eq!(detector.update(tolerant(0.2, 2.0))[0].kind, CollisionType::Colliding);
    assert_eq!(detector.update(tolerant(0.4, 2.0))[0].kind, CollisionType::Colliding);
    // 0.5 s after the last contact: released
    let end = detector.update(tolerant(0.5, 2.0));
    assert_eq!(kinds(&end), vec![(CollisionType::CollisionEnd, "b", "a")]);
    assert_eq!(end[0].start_s, 0.0);
    assert_eq!(end[0].area_m, None);
    // and beyond the band at once, without a timeout
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    let held = |t, x| Body {
        exit_tolerance_m: 1.0,
        ..body("b", t, x, 0.0, 0.1)
    };
    detector.update(body("a", 0.0, 0.0, 0.0, 0.1));
    detector.update(held(0.0, 1.0));
    assert_eq!(detector.update(held(9.0, 2.0))[0].kind, CollisionType::Colliding);
    assert_eq!(detector.update(held(9.1, 2.6))[0].kind, CollisionType::CollisionEnd);
}

#[test]
fn floors_uncertain_tracks_removal_and_staleness() {
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    detector.update(body("a", 0.0, 0.0, 0.0, 0.1));
    // another floor: no collision
    assert!(detector
        .update(Body {
            floor: 1.0,
            ..body("b", 0.0, 0.0, 0.0, 0.1)
        })
        .is_empty());
    // too uncertain to judge: nothing starts
    assert!(detector.update(body("c", 0.0, 0.5, 0.0, 20.0)).is_empty());
    // c becomes certain: it starts; uncertain again: held, no event
    assert_eq!(detector.update(body("c", 0.1, 0.5, 0.0, 0.1)).len(), 1);
    assert!(detector.update(body("c", 0.2, 50.0, 0.0, 20.0)).is_empty());
    assert_eq!(detector.collisions(), 1);
    // c's track is lost: its collision ends, c first
    assert_eq!(
        kinds(&detector.remove("c", 0.3)),
        vec![(CollisionType::CollisionEnd, "c", "a")]
    );
    // a pair whose partner goes silent ends when the silence passes stale_after_s
    detector.update(body("d", 1.0, 0.2, 0.0, 0.1));
    assert_eq!(detector.collisions(), 1);
    let later = detector.update(body("e", 40.0, 100.0, 100.0, 0.1));
    assert_eq!(
        later.iter().filter(|t| t.kind == CollisionType::CollisionEnd).count(),
        1,
        "{later:?}"
    );
    assert_eq!(detector.collisions(), 0);
    // only e is left (a, b and d are stale)
    assert_eq!(detector.len(), 1);
}

#[test]
fn an_older_update_of_a_trackable_changes_nothing() {
    let mut detector = CollisionDetector::new(CollisionSettings::default());
    detector.update(body("a", 1.0, 0.0, 0.0, 0.1));
    detector.update(body("b", 1.0, 10.0, 0.0, 0.1));
    // a's other provider reports an older position next to b: ignored
    assert!(detector.update(body("a", 0.5, 10.0, 0.0, 0.1)).is_empty());
    assert_eq!(detector.collisions(), 0);
}

/// The grid finds exactly the pairs a brute-force comparison of every pair finds.
#[test]
fn the_grid_agrees_with_every_pair_compared() {
    let settings = CollisionSettings {
        cell_m: 3.0,
        ..CollisionSettings::default()
    };
    let mut detector = CollisionDetector::new(settings);
    // a deterministic scatter of 200 trackables over 60 × 60 m, with varied σ and radius
    let mut state = 12_345_u64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut bodies = Vec::new();
    for i in 0..200 {
        let b = Body {
            radius_m: 2.0 * next(),
            ..body(&format!("t{i}"), 0.0, 60.0 * next(), 60.0 * next(), 1.5 * next())
        };
        bodies.push(b.clone());
        detector.update(b);
    }
    let extent = |b: &Body| b.radius_m + K_SIGMA_95 * b.sigma_m;
    let mut expected = 0;
    for (i, a) in bodies.iter().enumerate() {
        for b in &bodies[i + 1..] {
            if distance(a.xy(), b.xy()) < extent(a) + extent(b) {
                expected += 1;
            }
        }
    }
    assert!(expected > 10, "the scatter should have collisions: {expected}");
    assert_eq!(detector.collisions(), expected);
}
