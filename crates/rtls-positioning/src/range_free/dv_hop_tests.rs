use nalgebra::{Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// The hand-computed network:
/// ```text
/// A0 (0, 0) – 3 – A1 (12, 0)
///   |         |
///   4 ––––––––┘
///   |
/// A2 (0, 12)
/// ```
/// links 0–3, 3–1, 0–4, 4–2, 3–4.
fn hand_network() -> DvHop<2> {
    let positions = [Some([0.0, 0.0]), Some([12.0, 0.0]), Some([0.0, 12.0]), None, None];
    DvHop::new(&positions, &[(0, 3), (3, 1), (0, 4), (4, 2), (3, 4)]).unwrap()
}

#[test]
fn hand_computed_hops_hop_sizes_and_fixes() {
    let network = hand_network();
    assert_eq!(network.anchors(), &[0, 1, 2]);
    // hop counts by hand
    let table = [
        [Some(0), Some(2), Some(2), Some(1), Some(1)], // from A0
        [Some(2), Some(0), Some(3), Some(1), Some(2)], // from A1
        [Some(2), Some(3), Some(0), Some(2), Some(1)], // from A2
    ];
    for (anchor, row) in table.iter().enumerate() {
        for (node, expected) in row.iter().enumerate() {
            assert_eq!(network.hops(anchor, node), *expected, "anchor {anchor}, node {node}");
        }
    }
    assert_eq!(network.hops(3, 0), None);
    assert_eq!(network.hops(0, 9), None);
    // c_0 = (12 + 12)/(2 + 2) = 6;  c_1 = c_2 = (12 + 12√2)/(2 + 3)
    assert_eq!(network.hop_size_m(0), Some(6.0));
    let c1 = (12.0 + 12.0 * 2.0_f64.sqrt()) / 5.0;
    assert!((network.hop_size_m(1).unwrap() - c1).abs() < 1e-12);
    assert!((network.hop_size_m(2).unwrap() - c1).abs() < 1e-12);
    assert_eq!(network.hop_size_m(3), None);
    // σ_h² = Σ e²/Σ h: pairs from A1 and A2 miss by ±(12 − 2 c_1), ±(12√2 − 3 c_1); A0's fit
    let e_short: f64 = 12.0 - 2.0 * c1;
    let e_long: f64 = 12.0 * 2.0_f64.sqrt() - 3.0 * c1;
    let pooled = 2.0 * (e_short * e_short + e_long * e_long) / 14.0;
    let floor = (0.05 * (6.0 + 2.0 * c1) / 3.0_f64).powi(2);
    assert!((network.hop_variance_m2() - pooled.max(floor)).abs() < 1e-12);
    // node 3: nearest anchors A0 and A1 (1 hop) → A0 (lowest index), c = 6: d = (6, 6, 12)
    // reference A0: 12 x = ½(144 − 36 + 36) → x = 6;  12 y = ½(144 − 144 + 36) → y = 1.5
    let linear = DvHopOptions {
        refine: false,
        ..DvHopOptions::default()
    };
    let fix3 = network.locate(3, &linear).unwrap();
    assert!((fix3.position - Vector2::new(6.0, 1.5)).norm() < 1e-9);
    // node 4 by symmetry: (1.5, 6)
    let fix4 = network.locate(4, &linear).unwrap();
    assert!((fix4.position - Vector2::new(1.5, 6.0)).norm() < 1e-9);
    // refined: the weighted ML fit of d = (6, 6, 12) with variances (1, 1, 2) σ_h²: gradient 0
    let refined = network.locate(3, &DvHopOptions::default()).unwrap();
    let anchors = [[0.0, 0.0], [12.0, 0.0], [0.0, 12.0]];
    let (d, w) = ([6.0, 6.0, 12.0], [1.0, 1.0, 0.5]);
    let gradient = anchors.iter().enumerate().fold(Vector2::zeros(), |g, (i, a)| {
        let offset = refined.position - Vector2::from(*a);
        g + offset / offset.norm() * (w[i] * (d[i] - offset.norm()))
    });
    assert!(gradient.norm() < 1e-9, "{gradient}");
    assert!((refined.position - fix3.position).norm() > 0.1);
    assert!(refined.covariance.iter().all(|v| v.is_finite()));
    // locate_all lists the unknown nodes in order
    let all = network.locate_all(&linear);
    assert_eq!(all.len(), 2);
    assert_eq!(all[0].0, 3);
    assert_eq!(all[1].1.as_ref().unwrap().position, fix4.position);
}

/// Uniform random deployment (Niculescu & Nath's isotropic case): mean error a fraction of
/// the radio range.
fn random_deployment<const D: usize>(
    seed: u64,
    nodes: usize,
    anchors: usize,
    side_m: f64,
    radio_m: f64,
) -> (f64, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth: Vec<[f64; D]> = (0..nodes)
        .map(|_| core::array::from_fn(|_| rng.gen::<f64>() * side_m))
        .collect();
    let positions: Vec<Option<[f64; D]>> = truth
        .iter()
        .enumerate()
        .map(|(j, p)| (j < anchors).then_some(*p))
        .collect();
    let edges = unit_disk_edges(&truth, radio_m).unwrap();
    let network = DvHop::new(&positions, &edges).unwrap();
    let (mut sum_m, mut located) = (0.0, 0);
    for (node, fix) in network.locate_all(&DvHopOptions::default()) {
        if let Ok(fix) = fix {
            sum_m += (fix.position - point(&truth[node])).norm();
            located += 1;
        }
    }
    (sum_m / located as f64, located)
}

#[test]
fn random_uniform_deployments_locate_within_a_fraction_of_the_radio_range() {
    // 2-D: 300 nodes on 100 m × 100 m, 30 anchors, radio range 15 m
    let radio_m = 15.0;
    let (mean_m, located) = random_deployment::<2>(2003, 300, 30, 100.0, radio_m);
    eprintln!("2-D: {located} located, mean error {mean_m:.2} m (radio range {radio_m} m)");
    assert_eq!(located, 270);
    assert!(mean_m < 0.3 * radio_m, "2-D mean error {mean_m} m");
    // 3-D: 400 nodes in a 60 m cube, 40 anchors, radio range 18 m
    let (mean_m, located) = random_deployment::<3>(2004, 400, 40, 60.0, 18.0);
    eprintln!("3-D: {located} located, mean error {mean_m:.2} m (radio range 18 m)");
    assert_eq!(located, 360);
    assert!(mean_m < 0.3 * 18.0, "3-D mean error {mean_m} m");
}

#[test]
fn degenerate_networks_are_errors() {
    let three = [Some([0.0, 0.0]), Some([10.0, 0.0]), Some([0.0, 10.0])];
    // fewer than D + 1 anchors
    assert_eq!(
        DvHop::<2>::new(&[Some([0.0, 0.0]), Some([1.0, 0.0]), None], &[(0, 2), (1, 2)]).unwrap_err(),
        PositioningError::Underdetermined { anchors: 2, needed: 3 }
    );
    // non-finite anchor, reported by node index
    let nan = [None, Some([0.0, 0.0]), Some([1.0, f64::NAN]), Some([0.0, 1.0])];
    assert!(matches!(
        DvHop::new(&nan, &[]),
        Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
    ));
    // duplicate anchors, by node index
    let duplicate = [Some([0.0, 0.0]), None, Some([5.0, 0.0]), Some([0.0, 0.0])];
    assert_eq!(
        DvHop::new(&duplicate, &[]).unwrap_err(),
        PositioningError::DuplicateAnchors { first: 0, second: 3 }
    );
    // a link to a node that does not exist
    assert!(matches!(
        DvHop::new(&three, &[(0, 1), (1, 3)]),
        Err(PositioningError::InvalidParameter { name: "edges", .. })
    ));
    // an anchor reaching no other anchor
    assert_eq!(
        DvHop::new(&three, &[(0, 1)]).unwrap_err(),
        PositioningError::NodeUnderdetermined {
            node: 2,
            anchors: 0,
            needed: 1
        }
    );
    // node queries
    let network = hand_network();
    let options = DvHopOptions::default();
    assert!(matches!(
        network.locate(0, &options),
        Err(PositioningError::InvalidParameter { name: "node", .. })
    ));
    assert!(matches!(
        network.locate(5, &options),
        Err(PositioningError::InvalidParameter { name: "node", .. })
    ));
    // a node that reaches two anchors only (a separate component with anchors 3 and 4)
    let split = [
        Some([0.0, 0.0]),
        Some([10.0, 0.0]),
        Some([0.0, 10.0]),
        Some([50.0, 50.0]),
        Some([60.0, 50.0]),
        None,
        None,
    ];
    let network = DvHop::new(&split, &[(0, 1), (1, 2), (3, 6), (6, 4), (0, 5)]).unwrap();
    assert_eq!(
        network.locate(6, &options).unwrap_err(),
        PositioningError::NodeUnderdetermined {
            node: 6,
            anchors: 2,
            needed: 3
        }
    );
    assert!(network.locate(5, &options).is_ok());
    // the anchors a node reaches are collinear
    let collinear = [Some([0.0, 0.0]), Some([10.0, 0.0]), Some([20.0, 0.0]), None];
    let network = DvHop::new(&collinear, &[(0, 3), (1, 3), (2, 3)]).unwrap();
    assert!(matches!(
        network.locate(3, &options),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
    // unit-disk helper errors
    assert!(matches!(
        unit_disk_edges(&[[0.0, 0.0]], 0.0),
        Err(PositioningError::InvalidParameter {
            name: "radio_range_m",
            ..
        })
    ));
    assert!(matches!(
        unit_disk_edges(&[[0.0, 0.0], [f64::NAN, 0.0]], 1.0),
        Err(PositioningError::NonFiniteEntry { row: 1, column: 0, .. })
    ));
}

#[test]
fn three_dimensional_hand_network() {
    // four anchors on a tetrahedron-like frame, one unknown node linked to all: 1 hop each
    let positions = [
        Some([0.0, 0.0, 0.0]),
        Some([10.0, 0.0, 0.0]),
        Some([0.0, 10.0, 0.0]),
        Some([0.0, 0.0, 10.0]),
        None,
    ];
    let edges = [(0, 4), (1, 4), (2, 4), (3, 4)];
    let network = DvHop::new(&positions, &edges).unwrap();
    // every anchor pair is 2 hops apart: c_0 = 30/6 = 5, c_k = (10 + 2·10√2)/6 for k ≥ 1
    assert_eq!(network.hop_size_m(0), Some(5.0));
    let ck = (10.0 + 20.0 * 2.0_f64.sqrt()) / 6.0;
    assert!((network.hop_size_m(3).unwrap() - ck).abs() < 1e-12);
    // node 4: all at 1 hop, nearest = A0 (c = 5): equidistant (5) from the four anchors
    let fix = network
        .locate(
            4,
            &DvHopOptions {
                refine: false,
                ..DvHopOptions::default()
            },
        )
        .unwrap();
    // reference A0: 10 x = ½(100 − 25 + 25) → x = 5, likewise y = z = 5
    assert!((fix.position - Vector3::new(5.0, 5.0, 5.0)).norm() < 1e-9);
}
