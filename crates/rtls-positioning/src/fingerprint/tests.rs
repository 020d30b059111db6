//! Tests of KNN, WKNN and L-WKNN: exact matches, the 1/D weighting, absent readings, floor and
//! building votes, L-WKNN = WKNN in the degenerate case (property test), the paper's "same
//! neighbours" claim (seeded), estimated anchors, error paths.

use super::*;
use crate::PositioningError;
use nalgebra::Vector2;
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Seed 002's simulated site: 100 m × 100 m, 25 anchors on a 5 × 5 grid (20 m apart, 10 m
/// from the walls), 121 reference points on a 10 m grid, `ρ = −40 lg(max(d, 1 m))` dBm plus
/// fingerprint noise of variance 1 dB².
fn paper_site(rng: &mut ChaCha8Rng) -> FingerprintDatabase {
    let anchors: Vec<[f64; 2]> = (0..25)
        .map(|k| [10.0 + 20.0 * (k % 5) as f64, 10.0 + 20.0 * (k / 5) as f64])
        .collect();
    let points: Vec<[f64; 2]> = (0..121)
        .map(|k| [10.0 * (k % 11) as f64, 10.0 * (k / 11) as f64])
        .collect();
    let noise = Normal::new(0.0, 1.0).unwrap();
    let rssi = points
        .iter()
        .map(|p| {
            anchors
                .iter()
                .map(|a| path_loss_dbm(p, a) + noise.sample(rng))
                .collect()
        })
        .collect();
    FingerprintDatabase::new(points, anchors, rssi).unwrap()
}

/// The index of a database in seed 002's signal space (Euclidean on dBm).
fn indexed(db: FingerprintDatabase) -> FingerprintIndex {
    FingerprintIndex::new(db, SignalSpace::default()).unwrap()
}

fn anchor(db: &FingerprintDatabase, x: usize) -> [f64; 2] {
    db.anchors_m()[x].unwrap()
}

/// `ρ = ρ_T − 10 η lg d`, `ρ_T = 0 dBm`, `η = 4`, `d ≥ 1 m`.
fn path_loss_dbm(p: &[f64; 2], a: &[f64; 2]) -> f64 {
    let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt().max(1.0);
    -40.0 * d.log10()
}

fn indices(result: &FingerprintFix) -> Vec<usize> {
    result.neighbours.iter().map(|n| n.reference_point).collect()
}

#[test]
fn exact_match_returns_the_reference_point() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let index = indexed(paper_site(&mut rng));
    let db = index.database();
    let locator = LocalWknn::default().build(&index).unwrap();
    for l in [0, 17, 60, 93, 120] {
        let query: Vec<Option<f64>> = db.readings_dbm(l).unwrap().iter().map(|&(_, v)| Some(v)).collect();
        let expected = Vector2::new(db.reference_points_m()[l][0], db.reference_points_m()[l][1]);
        for result in [
            Knn::wknn(4).locate(&index, &query).unwrap(),
            locator.locate(&query).unwrap(),
        ] {
            assert_eq!(result.fix.position, expected, "reference point {l}");
            assert_eq!(result.fix.covariance, nalgebra::Matrix2::zeros());
            assert_eq!(result.neighbours[0].reference_point, l);
            assert_eq!(result.neighbours[0].weight, 1.0);
            assert!(result.neighbours[1..].iter().all(|n| n.weight == 0.0));
        }
    }
}

#[test]
fn two_exact_matches_share_the_weight() {
    let db = FingerprintDatabase::new(
        vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]],
        vec![[0.0, 0.0], [10.0, 10.0]],
        vec![vec![-40.0, -50.0], vec![-40.0, -50.0], vec![-60.0, -45.0]],
    )
    .unwrap();
    let result = Knn::wknn(3).locate(&indexed(db), &[Some(-40.0), Some(-50.0)]).unwrap();
    assert_eq!(result.fix.position, Vector2::new(5.0, 0.0));
    assert_eq!(indices(&result), [0, 1, 2]);
    assert_eq!(result.neighbours[2].weight, 0.0);
    assert_eq!(result.fix.covariance[(0, 0)], 25.0);
}

#[test]
fn inverse_distance_weighting_hand_computed() {
    // One anchor; fingerprints −40, −43, −45, −70 dBm; query −41 dBm: D = 1, 2, 4, 29.
    let db = FingerprintDatabase::new(
        vec![[0.0, 0.0], [7.0, 0.0], [0.0, 14.0], [90.0, 90.0]],
        vec![[0.0, 0.0]],
        vec![vec![-40.0], vec![-43.0], vec![-45.0], vec![-70.0]],
    )
    .unwrap();
    let result = Knn::wknn(3).locate(&indexed(db), &[Some(-41.0)]).unwrap();
    assert_eq!(indices(&result), [0, 1, 2]);
    let distances: Vec<f64> = result.neighbours.iter().map(|n| n.distance).collect();
    assert_eq!(distances, [1.0, 2.0, 4.0]);
    // w ∝ (1, 1/2, 1/4) → (4/7, 2/7, 1/7)
    let weights: Vec<f64> = result.neighbours.iter().map(|n| n.weight).collect();
    for (w, expected) in weights.iter().zip([4.0 / 7.0, 2.0 / 7.0, 1.0 / 7.0]) {
        assert!((w - expected).abs() < 1e-15);
    }
    // x̂ = 4/7 (0,0) + 2/7 (7,0) + 1/7 (0,14) = (2, 2)
    assert!((result.fix.position - Vector2::new(2.0, 2.0)).norm() < 1e-12);
    // spread: xx = (4·4 + 2·25 + 1·4)/7 = 10, xy = (16 − 20 − 24)/7 = −4, yy = (16 + 8 + 144)/7 = 24
    let c = result.fix.covariance;
    assert!((c[(0, 0)] - 10.0).abs() < 1e-12);
    assert!((c[(0, 1)] + 4.0).abs() < 1e-12);
    assert!((c[(1, 0)] + 4.0).abs() < 1e-12);
    assert!((c[(1, 1)] - 24.0).abs() < 1e-12);
    // The paper's printed w = D/ΣD would give (1/7, 2/7, 4/7) → (2, 8): not what we return.
    assert!((result.fix.position - Vector2::new(2.0, 8.0)).norm() > 5.0);
}

#[test]
fn unheard_anchors_count_as_the_floor_on_both_sides() {
    // Reference point 0 does not hear anchor 1; the query does not hear anchor 2.
    let db = FingerprintDatabase::from_survey(Survey {
        reference_points_m: vec![[0.0, 0.0], [10.0, 0.0]],
        anchor_count: 3,
        anchors_m: Some(vec![Some([0.0, 0.0]), Some([10.0, 0.0]), Some([5.0, 5.0])]),
        readings_dbm: vec![vec![(0, -30.0), (2, -90.0)], vec![(0, -60.0), (1, -30.0), (2, -40.0)]],
        ..Survey::default()
    })
    .unwrap();
    let space = SignalSpace {
        representation: SignalRepresentation::Positive { floor_dbm: -100.0 },
        distance: SignalDistance::Euclidean,
    };
    let index = FingerprintIndex::new(db, space).unwrap();
    let result = Knn::wknn(2).locate(&index, &[Some(-33.0), Some(-56.0), None]).unwrap();
    // ψ = ρ + 100, absent = 0.  D_0 = √(3² + 44² + 10²),  D_1 = √(27² + 26² + 60²)
    let d0 = (9.0f64 + 44.0 * 44.0 + 100.0).sqrt();
    let d1 = (27.0f64 * 27.0 + 26.0 * 26.0 + 3600.0).sqrt();
    assert_eq!(indices(&result), [0, 1]);
    assert!((result.neighbours[0].distance - d0).abs() < 1e-12);
    assert!((result.neighbours[1].distance - d1).abs() < 1e-12);
}

#[test]
fn uniform_knn_averages_the_n_nearest_equally() {
    let db = FingerprintDatabase::new(
        vec![[0.0, 0.0], [7.0, 0.0], [0.0, 14.0], [90.0, 90.0]],
        vec![[0.0, 0.0]],
        vec![vec![-40.0], vec![-43.0], vec![-45.0], vec![-70.0]],
    )
    .unwrap();
    let result = Knn::unweighted(3).locate(&indexed(db), &[Some(-41.0)]).unwrap();
    assert_eq!(indices(&result), [0, 1, 2]);
    assert!((result.fix.position - Vector2::new(7.0 / 3.0, 14.0 / 3.0)).norm() < 1e-12);
}

/// Two buildings, two floors each; anchors 0–1 in building 0, 2–3 in building 1.
fn labelled_site() -> FingerprintIndex {
    let survey = Survey {
        reference_points_m: vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [0.0, 0.0],
            [4.0, 0.0],
            [100.0, 0.0],
            [100.0, 0.0],
        ],
        floors: Some(vec![0, 0, 1, 1, 0, 1]),
        buildings: Some(vec![0, 0, 0, 0, 1, 1]),
        anchor_count: 4,
        anchors_m: None,
        readings_dbm: vec![
            vec![(0, -40.0), (1, -75.0)],
            vec![(0, -50.0), (1, -70.0)],
            vec![(0, -70.0), (1, -45.0)],
            vec![(0, -75.0), (1, -50.0)],
            vec![(2, -40.0), (3, -80.0)],
            vec![(2, -80.0), (3, -40.0)],
        ],
    };
    let db = FingerprintDatabase::from_survey(survey)
        .unwrap()
        .with_estimated_anchors(2)
        .unwrap();
    FingerprintIndex::new(db, SignalSpace::powed_sorensen()).unwrap()
}

#[test]
fn building_and_floor_are_weighted_votes_and_the_fix_stays_on_the_voted_floor() {
    let index = labelled_site();
    // Near the floor-1 points of building 0; the third neighbour is on floor 0.
    let query = [Some(-72.0), Some(-47.0), None, None];
    let result = Knn::wknn(3).locate(&index, &query).unwrap();
    assert_eq!(result.building, Some(0));
    assert_eq!(result.floor, Some(1));
    for n in &result.neighbours {
        let on_floor = index.database().floor(n.reference_point) == Some(1);
        assert_eq!(n.weight > 0.0, on_floor, "neighbour {n:?}");
    }
    let total: f64 = result.neighbours.iter().map(|n| n.weight).sum();
    assert!((total - 1.0).abs() < 1e-12);
    // x̂ lies between the floor-1 points (x = 0 and 4), and the floor-0 neighbour is ignored.
    assert!(result.fix.position.x > 0.0 && result.fix.position.x < 4.0);
    // Without the floor restriction the floor-0 neighbour pulls the fix.
    let mixed = Knn {
        same_floor_only: false,
        ..Knn::wknn(3)
    }
    .locate(&index, &query)
    .unwrap();
    assert_eq!(mixed.floor, Some(1));
    assert!(mixed.neighbours.iter().all(|n| n.weight > 0.0));
    // The other building: only reference points 4–5 hear anchors 2 and 3.
    let other = Knn::wknn(3)
        .locate(&index, &[None, None, Some(-78.0), Some(-42.0)])
        .unwrap();
    assert_eq!((other.building, other.floor), (Some(1), Some(1)));
    assert_eq!(indices(&other), [5, 4]);
}

#[test]
fn a_query_hearing_only_unsurveyed_anchors_has_no_match() {
    let index = labelled_site();
    let db = FingerprintDatabase::from_survey(Survey {
        reference_points_m: vec![[0.0, 0.0]],
        anchor_count: 2,
        readings_dbm: vec![vec![(0, -50.0)]],
        ..Survey::default()
    })
    .unwrap();
    let lonely = FingerprintIndex::new(db, SignalSpace::powed_sorensen()).unwrap();
    assert_eq!(
        Knn::wknn(1).locate(&lonely, &[None, Some(-60.0)]),
        Err(PositioningError::NoFingerprintMatch)
    );
    assert!(matches!(
        Knn::wknn(1).locate(&index, &[Some(-120.0), None, None, None]),
        Err(PositioningError::RssiBelowFloor { row: 0, column: 0, .. })
    ));
}

#[test]
fn local_wknn_uses_estimated_anchor_positions() {
    let index = labelled_site();
    // anchor 2 is loudest at reference point 4 (100, 0)
    assert_eq!(index.database().anchors_m()[2], Some([100.0, 0.0]));
    let locator = LocalWknn {
        strongest_anchors: 1,
        radius_m: 10.0,
        knn: Knn::wknn(3),
    }
    .build(&index)
    .unwrap();
    assert_eq!(locator.nearby_reference_points(2), Some(&[4, 5][..]));
    let query = [None, None, Some(-78.0), Some(-42.0)];
    let local = locator.locate(&query).unwrap();
    let global = Knn::wknn(3).locate(&index, &query).unwrap();
    assert_eq!(local, global);
    // no anchor position at all: L-WKNN cannot build
    let db = FingerprintDatabase::from_survey(Survey {
        reference_points_m: vec![[0.0, 0.0]],
        anchor_count: 1,
        readings_dbm: vec![vec![(0, -50.0)]],
        ..Survey::default()
    })
    .unwrap();
    let unknown = FingerprintIndex::new(db, SignalSpace::default()).unwrap();
    assert!(matches!(
        LocalWknn::default().build(&unknown),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}

#[test]
fn fewer_reference_points_than_neighbours_uses_all() {
    let db = FingerprintDatabase::new(
        vec![[0.0, 0.0], [10.0, 0.0]],
        vec![[0.0, 0.0]],
        vec![vec![-30.0], vec![-50.0]],
    )
    .unwrap();
    let result = Knn::wknn(5).locate(&indexed(db), &[Some(-35.0)]).unwrap();
    assert_eq!(indices(&result), [0, 1]);
    // w ∝ (1/5, 1/15) → (3/4, 1/4)
    assert!((result.fix.position.x - 2.5).abs() < 1e-12);
}

#[test]
fn local_wknn_finds_the_global_neighbours_inside_the_grid() {
    // Seed 002 §2: "L-WKNN finds the same neighbours as global WKNN" (N_k = 4, 20 m, n = 4).
    let mut rng = ChaCha8Rng::seed_from_u64(2002);
    let index = indexed(paper_site(&mut rng));
    let db = index.database();
    let locator = LocalWknn::default().build(&index).unwrap();
    let global = Knn::wknn(4);
    let position = rand_distr::Uniform::new(30.0, 70.0);
    let rssi_noise = Normal::new(0.0, 1.0).unwrap();
    let mut candidates_touched = 0;
    for trial in 0..500 {
        let truth = [position.sample(&mut rng), position.sample(&mut rng)];
        let query: Vec<Option<f64>> = db
            .anchors_m()
            .iter()
            .map(|a| Some(path_loss_dbm(&truth, &a.unwrap()) + rssi_noise.sample(&mut rng)))
            .collect();
        let local = locator.locate(&query).unwrap();
        let all = global.locate(&index, &query).unwrap();
        assert_eq!(indices(&local), indices(&all), "trial {trial}, truth {truth:?}");
        assert_eq!(local.fix, all.fix);
        assert!((local.fix.position - Vector2::new(truth[0], truth[1])).norm() < 10.0);
        candidates_touched += strongest_candidate_count(&locator, &query);
    }
    // The local step is what makes it fast: far fewer candidates than 121 reference points.
    assert!(
        candidates_touched < 500 * 40,
        "mean candidates {}",
        candidates_touched / 500
    );
}

/// How many distinct reference points the query's 4 strongest anchors select.
fn strongest_candidate_count(locator: &LocalWknnLocator<'_>, query: &[Option<f64>]) -> usize {
    let mut heard: Vec<(usize, f64)> = query
        .iter()
        .enumerate()
        .filter_map(|(x, v)| v.map(|v| (x, v)))
        .collect();
    heard.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut candidates: Vec<usize> = heard[..4]
        .iter()
        .flat_map(|&(x, _)| locator.nearby_reference_points(x).unwrap().iter().map(|&l| l as usize))
        .collect();
    candidates.sort_unstable();
    candidates.dedup();
    candidates.len()
}

#[test]
fn local_wknn_neighbours_lie_within_the_radius_of_the_strongest_anchors() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let index = indexed(paper_site(&mut rng));
    let db = index.database();
    let params = LocalWknn {
        strongest_anchors: 2,
        radius_m: 15.0,
        knn: Knn::wknn(6),
    };
    let locator = params.build(&index).unwrap();
    let noise = Normal::new(0.0, 4.0).unwrap();
    let position = rand_distr::Uniform::new(0.0, 100.0);
    for _ in 0..200 {
        let truth = [position.sample(&mut rng), position.sample(&mut rng)];
        let query: Vec<Option<f64>> = db
            .anchors_m()
            .iter()
            .map(|a| Some(path_loss_dbm(&truth, &a.unwrap()) + noise.sample(&mut rng)))
            .collect();
        let mut order: Vec<usize> = (0..25).collect();
        order.sort_by(|&a, &b| query[b].unwrap().total_cmp(&query[a].unwrap()).then(a.cmp(&b)));
        let strongest = &order[..2];
        let result = locator.locate(&query).unwrap();
        for n in &result.neighbours {
            let p = db.reference_points_m()[n.reference_point];
            let near = strongest.iter().any(|&x| {
                let a = anchor(db, x);
                ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt() <= 15.0
            });
            assert!(
                near,
                "neighbour {} is not near the strongest anchors",
                n.reference_point
            );
        }
        let total: f64 = result.neighbours.iter().map(|n| n.weight).sum();
        assert!((total - 1.0).abs() < 1e-12);
    }
}

/// A random database (RPs and anchors in a 100 m square, RSSI in [−100, −20] dBm) and a query
/// hearing a random subset of anchors.
fn database_and_query() -> impl Strategy<Value = (FingerprintIndex, Vec<Option<f64>>)> {
    (1usize..40, 1usize..8).prop_flat_map(|(points, anchors)| {
        (
            prop::collection::vec([0.0..100.0f64, 0.0..100.0f64], points),
            prop::collection::vec([0.0..100.0f64, 0.0..100.0f64], anchors),
            prop::collection::vec(prop::collection::vec(-100.0..-20.0f64, anchors), points),
            prop::collection::vec(prop::option::weighted(0.8, -100.0..-20.0f64), anchors),
        )
            .prop_map(|(p, a, rssi, query)| (indexed(FingerprintDatabase::new(p, a, rssi).unwrap()), query))
    })
}

proptest! {
    #[test]
    fn local_wknn_with_all_anchors_and_a_covering_radius_is_wknn(
        (index, query) in database_and_query(),
        neighbours in 1usize..6,
        infinite in any::<bool>(),
    ) {
        let radius_m = if infinite { f64::INFINITY } else { 150.0 }; // the square's diagonal is 141 m
        let knn = Knn::wknn(neighbours);
        let local = LocalWknn { strongest_anchors: index.database().anchor_count(), radius_m, knn }
            .build(&index)
            .unwrap();
        let expected = knn.locate(&index, &query);
        let found = local.locate(&query);
        match (&expected, &found) {
            (Ok(e), Ok(f)) => {
                prop_assert_eq!(indices(e), indices(f));
                prop_assert_eq!(e.fix.position, f.fix.position);
                prop_assert_eq!(e.fix.covariance, f.fix.covariance);
                let total: f64 = f.neighbours.iter().map(|n| n.weight).sum();
                prop_assert!((total - 1.0).abs() < 1e-12);
                prop_assert!(f.fix.covariance.symmetric_eigenvalues().iter().all(|&v| v >= -1e-9));
            }
            (Err(e), Err(f)) => {
                prop_assert_eq!(e, f);
                prop_assert_eq!(e, &PositioningError::NoCommonAnchors);
            }
            _ => prop_assert!(false, "wknn {expected:?} vs l-wknn {found:?}"),
        }
    }
}

#[test]
fn error_paths() {
    let db = FingerprintDatabase::new(
        vec![[0.0, 0.0], [10.0, 0.0]],
        vec![[0.0, 0.0], [100.0, 0.0]],
        vec![vec![-30.0, -70.0], vec![-50.0, -72.0]],
    )
    .unwrap();
    let index = indexed(db);
    let query = [Some(-40.0), Some(-71.0)];
    // parameters
    assert!(matches!(
        Knn::wknn(0).locate(&index, &query),
        Err(PositioningError::InvalidParameter { name: "neighbours", .. })
    ));
    assert!(matches!(
        Knn {
            weighting: Weighting::InverseDistance { power: f64::NAN },
            ..Knn::wknn(2)
        }
        .locate(&index, &query),
        Err(PositioningError::InvalidParameter { name: "power", .. })
    ));
    let base = LocalWknn::default();
    for (params, name) in [
        (
            LocalWknn {
                strongest_anchors: 0,
                ..base
            },
            "strongest_anchors",
        ),
        (
            LocalWknn {
                knn: Knn::wknn(0),
                ..base
            },
            "neighbours",
        ),
        (LocalWknn { radius_m: 0.0, ..base }, "radius_m"),
        (LocalWknn { radius_m: -5.0, ..base }, "radius_m"),
        (
            LocalWknn {
                radius_m: f64::NAN,
                ..base
            },
            "radius_m",
        ),
    ] {
        match params.build(&index) {
            Err(PositioningError::InvalidParameter { name: found, .. }) => assert_eq!(found, name),
            other => panic!("{params:?}: expected InvalidParameter({name}), got {other:?}"),
        }
    }
    let locator = base.build(&index).unwrap();
    // query shape and values
    assert!(matches!(
        Knn::wknn(1).locate(&index, &query[..1]),
        Err(PositioningError::DimensionMismatch {
            expected: 2,
            found: 1,
            ..
        })
    ));
    assert!(matches!(
        locator.locate(&[Some(-40.0), Some(-71.0), None]),
        Err(PositioningError::DimensionMismatch {
            expected: 2,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        locator.locate(&[None, Some(f64::NAN)]),
        Err(PositioningError::NonFiniteEntry { column: 1, .. })
    ));
    assert_eq!(
        Knn::wknn(1).locate(&index, &[None, None]),
        Err(PositioningError::NoCommonAnchors)
    );
    assert_eq!(locator.locate(&[None, None]), Err(PositioningError::NoCommonAnchors));
    // anchor 1 is the strongest heard but no reference point lies within 20 m of it
    assert_eq!(
        locator.locate(&[None, Some(-71.0)]),
        Err(PositioningError::NoCandidates)
    );
    // overflowing distances
    let huge = indexed(FingerprintDatabase::new(vec![[0.0, 0.0]], vec![[0.0, 0.0]], vec![vec![1e200]]).unwrap());
    assert!(matches!(
        Knn::wknn(1).locate(&huge, &[Some(-1e200)]),
        Err(PositioningError::RssiBelowFloor { .. })
    ));
    assert!(matches!(
        Knn::wknn(1).locate(&huge, &[Some(1e100)]),
        Err(PositioningError::NonFinite { .. })
    ));
}
