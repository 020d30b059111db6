//! Geometry tests: concave polygons, height ranges, boxes, validation, segment entry.

use super::*;

fn polygon(vertices_m: Vec<[f64; 2]>, z_range_m: Option<[f64; 2]>) -> Zone {
    Zone {
        id: "p".into(),
        name: "polygon".into(),
        kind: ZoneKind::Restricted,
        readers: vec![],
        shape: Shape::Polygon {
            vertices_m,
            floor: None,
            z_range_m,
        },
    }
}

fn boxed(min_m: [f64; 3], max_m: [f64; 3]) -> Zone {
    Zone {
        id: "b".into(),
        name: "box".into(),
        kind: ZoneKind::Hazard,
        readers: vec![],
        shape: Shape::Box { min_m, max_m },
    }
}

/// A U shape: 0 ≤ x ≤ 6, 0 ≤ y ≤ 6 minus the notch 2 < x < 4, y > 2.
fn u_shape(z: Option<[f64; 2]>) -> Zone {
    polygon(
        vec![
            [0.0, 0.0],
            [6.0, 0.0],
            [6.0, 6.0],
            [4.0, 6.0],
            [4.0, 2.0],
            [2.0, 2.0],
            [2.0, 6.0],
            [0.0, 6.0],
        ],
        z,
    )
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

#[test]
fn concave_polygon_contains_and_distances() {
    let u = u_shape(None);
    u.validate().unwrap();
    assert!(u.contains([1.0, 5.0, 0.0]));
    assert!(u.contains([5.0, 5.0, -100.0])); // no height range: every height
    assert!(!u.contains([3.0, 5.0, 0.0])); // the notch
    assert!(u.contains([3.0, 2.0, 0.0])); // on the boundary
    assert!(close(u.signed_distance_m([3.0, 5.0, 0.0]), 1.0)); // 1 m from both arms
    assert!(close(u.signed_distance_m([1.0, 5.0, 0.0]), -1.0)); // 1 m from three walls of the arm
    assert!(close(u.signed_distance_m([3.0, 1.0, 0.0]), -1.0));
    assert!(close(u.signed_distance_m([9.0, 10.0, 0.0]), 5.0)); // to the corner (6, 6)
                                                                // the same shape in clockwise order gives the same answers
    let mut cw = u.clone();
    if let Shape::Polygon { vertices_m, .. } = &mut cw.shape {
        vertices_m.reverse();
    }
    cw.validate().unwrap();
    for p in [[3.0, 5.0, 0.0], [1.0, 5.0, 0.0], [9.0, 10.0, 0.0], [3.0, 1.0, 0.0]] {
        assert!(close(u.signed_distance_m(p), cw.signed_distance_m(p)));
    }
}

#[test]
fn height_range_combines_with_the_plan_distance() {
    let u = u_shape(Some([0.0, 3.0]));
    assert!(u.contains([1.0, 1.0, 2.0]));
    assert!(!u.contains([1.0, 1.0, 3.5]));
    assert!(!u.contains([1.0, 1.0, -0.1]));
    // inside: the nearer of the walls (1 m away) and the ceiling
    assert!(close(u.signed_distance_m([1.0, 1.0, 2.5]), -0.5));
    assert!(close(u.signed_distance_m([1.0, 1.0, 1.5]), -1.0));
    // above, inside in plan: only the height counts
    assert!(close(u.signed_distance_m([1.0, 1.0, 5.0]), 2.0));
    // outside in plan and in height: Euclidean to the edge
    assert!(close(u.signed_distance_m([9.0, 1.0, 7.0]), 5.0));
    // outside in plan, inside in height: the plan distance
    assert!(close(u.signed_distance_m([9.0, 1.0, 1.0]), 3.0));
}

#[test]
fn box_distances_inside_outside_and_at_corners() {
    let b = boxed([0.0, 0.0, 0.0], [4.0, 2.0, 6.0]);
    b.validate().unwrap();
    assert!(close(b.signed_distance_m([2.0, 1.0, 3.0]), -1.0));
    assert!(close(b.signed_distance_m([2.0, 0.25, 3.0]), -0.25));
    assert!(close(b.signed_distance_m([7.0, 6.0, 3.0]), 5.0));
    assert!(close(b.signed_distance_m([4.0, 1.0, 3.0]), 0.0));
    assert!(b.contains([4.0, 1.0, 3.0]));
    assert!(!b.contains([2.0, 1.0, 6.01]));
}

#[test]
fn segment_entry_finds_the_first_contact() {
    let u = u_shape(Some([0.0, 3.0]));
    // along y = 5 from x = −4: enters the left arm at x = 0 (s = 0.2 of a 20 m step)
    assert!(close(u.segment_entry([-4.0, 5.0, 1.0], [16.0, 5.0, 1.0]).unwrap(), 0.2));
    // starting inside the notch's opening and walking up the notch: never inside
    assert_eq!(u.segment_entry([3.0, 2.5, 1.0], [3.0, 9.0, 1.0]), None);
    // starting inside: 0
    assert_eq!(u.segment_entry([1.0, 1.0, 1.0], [1.0, 1.0, 9.0]), Some(0.0));
    // passing above the zone
    assert_eq!(u.segment_entry([-4.0, 5.0, 5.0], [16.0, 5.0, 5.0]), None);
    // descending onto it: enters at the ceiling (z = 3 at s = 0.5)
    assert!(close(u.segment_entry([1.0, 1.0, 5.0], [1.0, 1.0, 1.0]).unwrap(), 0.5));
    // sliding along an edge counts as contact
    assert!(close(u.segment_entry([-2.0, 0.0, 1.0], [2.0, 0.0, 1.0]).unwrap(), 0.5));
    assert!(u.segment_enters([3.0, 9.0, 1.0], [3.0, 1.0, 1.0]));
    // a stationary tag outside
    assert_eq!(u.segment_entry([9.0, 9.0, 1.0], [9.0, 9.0, 1.0]), None);

    let b = boxed([10.0, -1.0, 0.0], [12.0, 1.0, 3.0]);
    assert!(close(b.segment_entry([0.0, 0.0, 1.0], [20.0, 0.0, 1.0]).unwrap(), 0.5));
    assert_eq!(b.segment_entry([0.0, 0.0, 1.0], [9.0, 0.0, 1.0]), None);
    assert_eq!(b.segment_entry([0.0, 0.0, 5.0], [20.0, 0.0, 5.0]), None);
    assert_eq!(b.segment_entry([11.0, 0.0, 1.0], [30.0, 0.0, 1.0]), Some(0.0));
    assert!(b.segment_enters([11.0, -5.0, 2.0], [11.0, 5.0, 2.0]));
}

fn invalid_field(zone: &Zone) -> String {
    match zone.validate() {
        Err(EngineError::Parse { field, reason, .. }) => {
            assert!(reason.starts_with("zone `"), "{reason}");
            field
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn invalid_polygons_are_rejected_with_the_field() {
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [1.0, 0.0]], None)),
        "shape.vertices_m"
    );
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [1.0, f64::NAN], [0.0, 1.0]], None)),
        "shape.vertices_m[1]"
    );
    // closed by repeating the first vertex
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]], None)),
        "shape.vertices_m[3]"
    );
    // bow tie
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]], None)),
        "shape.vertices_m"
    );
    // a vertex touching a non-adjacent edge
    assert_eq!(
        invalid_field(&polygon(
            vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [2.0, 0.0], [0.0, 4.0]],
            None
        )),
        "shape.vertices_m"
    );
    // a spike folding back on itself
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [4.0, 0.0], [2.0, 0.0], [2.0, 3.0]], None)),
        "shape.vertices_m"
    );
    // collinear
    assert_eq!(
        invalid_field(&polygon(vec![[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], None)),
        "shape.vertices_m"
    );
    let square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    assert_eq!(
        invalid_field(&polygon(square.clone(), Some([3.0, 3.0]))),
        "shape.z_range_m"
    );
    assert_eq!(
        invalid_field(&polygon(square.clone(), Some([f64::NAN, 3.0]))),
        "shape.z_range_m"
    );
    assert!(polygon(square, Some([0.0, 3.0])).validate().is_ok());
}

#[test]
fn invalid_boxes_are_rejected_with_the_field() {
    assert_eq!(invalid_field(&boxed([0.0, 0.0, f64::NAN], [1.0; 3])), "shape.min_m");
    assert_eq!(
        invalid_field(&boxed([0.0; 3], [1.0, f64::INFINITY, 1.0])),
        "shape.max_m"
    );
    assert_eq!(invalid_field(&boxed([0.0; 3], [1.0, 1.0, 0.0])), "shape.max_m");
}

#[test]
fn zones_deserialize_from_toml() {
    let zone: Zone = toml::from_str(
        r#"
        id = "z"
        name = "Zone"
        kind = "area-of-interest"
        shape = { type = "polygon", vertices_m = [[0, 0], [1, 0], [0, 1]], z_range_m = [0, 2] }
        "#,
    )
    .unwrap();
    assert_eq!(zone.kind, ZoneKind::AreaOfInterest);
    assert!(zone.contains([0.2, 0.2, 1.0]));
    let unknown = toml::from_str::<Zone>(
        r#"
        id = "z"
        name = "Zone"
        kind = "hazard"
        shape = { type = "box", min_m = [0, 0, 0], max_m = [1, 1, 1], colour = "red" }
        "#,
    );
    assert!(unknown.unwrap_err().to_string().contains("colour"));
}
