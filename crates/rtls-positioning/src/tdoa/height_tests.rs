//! Tests of [`super::planar_at_height`].

use nalgebra::{DMatrix, Vector2, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::tdoa::{chan_taylor, range_differences_at};

/// Four anchors at 2.5–3 m on a 20 m × 15 m room and one low one.
const ANCHORS: [[f64; 3]; 5] = [
    [0.0, 0.0, 3.0],
    [20.0, 0.0, 2.5],
    [20.0, 15.0, 3.0],
    [0.0, 15.0, 2.5],
    [10.0, 7.0, 0.3],
];

#[test]
fn slant_differences_give_the_planar_fix_that_ignoring_heights_misses() {
    let tag = Vector3::new(3.0, 12.0, 1.0);
    let r = range_differences_at(&ANCHORS, 0, &tag).unwrap();
    let q = DMatrix::identity(4, 4) * 1e-4;
    let fix = planar_at_height(&ANCHORS, 0, &r, &q, 1.0).unwrap();
    assert!((fix.position - Vector2::new(3.0, 12.0)).norm() < 1e-6);
    assert!(fix.check_plausible(&ANCHORS.map(|a| [a[0], a[1]]), 0.0).is_ok());
    // the old way: the same differences treated as planar, heights dropped
    let planar = ANCHORS.map(|a| [a[0], a[1]]);
    match chan_taylor(&planar, 0, &r, &q) {
        Ok(f) => assert!((f.position - Vector2::new(3.0, 12.0)).norm() > 0.1, "{}", f.position),
        Err(error) => assert!(!error.to_string().is_empty()),
    }
}

#[test]
fn anchors_sharing_x_y_at_different_heights_are_usable() {
    // a mast with anchors at 0.5 m and 4 m at the origin, and two more
    let stations = [[0.0, 0.0, 0.5], [0.0, 0.0, 4.0], [15.0, 0.0, 3.0], [0.0, 12.0, 3.0]];
    let tag = Vector3::new(5.0, 4.0, 1.2);
    let r = range_differences_at(&stations, 2, &tag).unwrap();
    let fix = planar_at_height(&stations, 2, &r, &(DMatrix::identity(3, 3) * 1e-4), 1.2).unwrap();
    assert!((fix.position - Vector2::new(5.0, 4.0)).norm() < 1e-6);
    assert!(fix.covariance.cholesky().is_some());
}

#[test]
fn noisy_fixes_scatter_like_their_covariance() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let sigma = 0.1;
    let noise = Normal::new(0.0, sigma).unwrap();
    let tag = Vector3::new(12.0, 5.0, 1.0);
    let exact = range_differences_at(&ANCHORS, 1, &tag).unwrap();
    // independent TOA errors differenced: Q = σ² (I + 1 1ᵀ)
    let q = (DMatrix::identity(4, 4) + DMatrix::from_element(4, 4, 1.0)) * (sigma * sigma);
    let (mut nees, runs) = (0.0, 300);
    for _ in 0..runs {
        let e_ref = noise.sample(&mut rng);
        let r: Vec<f64> = exact.iter().map(|d| d + noise.sample(&mut rng) - e_ref).collect();
        let fix = planar_at_height(&ANCHORS, 1, &r, &q, 1.0).unwrap();
        let error = fix.position - Vector2::new(12.0, 5.0);
        nees += error.dot(&(fix.covariance.try_inverse().unwrap() * error));
    }
    // E[NEES] = 2 with exact covariances; the variance factor only inflates (≤ 2)
    let mean = nees / f64::from(runs);
    assert!((1.0..2.4).contains(&mean), "{mean}");
}

#[test]
fn errors_are_typed() {
    let q = DMatrix::identity(4, 4);
    let r = [0.0; 4];
    assert_eq!(
        planar_at_height(&ANCHORS[..2], 0, &r[..1], &DMatrix::identity(1, 1), 1.0).unwrap_err(),
        PositioningError::Underdetermined { anchors: 2, needed: 3 }
    );
    assert!(matches!(
        planar_at_height(&ANCHORS, 5, &r, &q, 1.0),
        Err(PositioningError::InvalidParameter { name: "reference", .. })
    ));
    assert!(matches!(
        planar_at_height(&ANCHORS, 0, &r[..3], &q, 1.0),
        Err(PositioningError::DimensionMismatch { .. })
    ));
    assert!(matches!(
        planar_at_height(&ANCHORS, 0, &r, &q, f64::NAN),
        Err(PositioningError::NonFinite { .. })
    ));
    assert!(planar_at_height(&ANCHORS, 0, &r, &(-q), 1.0).is_err());
    // collinear projected stations: mirror-ambiguous, refused
    let line = [[0.0, 0.0, 3.0], [10.0, 0.0, 2.0], [20.0, 0.0, 3.0]];
    assert!(matches!(
        planar_at_height(&line, 0, &[1.0, 2.0], &DMatrix::identity(2, 2), 1.0),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}
