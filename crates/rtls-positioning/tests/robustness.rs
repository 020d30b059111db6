//! Property tests: random anchor sets (1–12 anchors; co-located, duplicated, collinear, far
//! away) and random measurements (negative, zero, huge) never make a solver panic or return a
//! NaN/∞: every result is an error value or a finite fix with a finite, symmetric
//! positive-definite covariance (and, for the fixes a tracker uses, a plausible position).

use nalgebra::{DMatrix, SMatrix, SVector, Vector2};
use proptest::prelude::*;
use rtls_positioning::multilateration::{gauss_newton, multilaterate, GaussNewtonOptions, Initial};
use rtls_positioning::tdoa::{chan_taylor, planar_at_height};
use rtls_positioning::Fix;

/// An anchor: `(kind, x, y, z, earlier)`; kind 0 duplicates and kind 1 shares `(x, y)` with
/// the anchor `earlier mod i`, kind 2 lies on the line y = 0, kind 3 is far away.
type AnchorSpec = (u8, f64, f64, f64, usize);

fn anchors(specs: &[AnchorSpec]) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::with_capacity(specs.len());
    for (i, &(kind, x, y, z, earlier)) in specs.iter().enumerate() {
        let anchor = match kind {
            0 if i > 0 => out[earlier % i],
            1 if i > 0 => {
                let p = out[earlier % i];
                [p[0], p[1], z]
            }
            2 => [x, 0.0, 2.5],
            3 => [x * 3e4, y * 3e4, z * 100.0],
            _ => [x, y, z],
        };
        out.push(anchor);
    }
    out
}

fn anchor_spec() -> impl Strategy<Value = AnchorSpec> {
    (0u8..6, -30.0..30.0f64, -30.0..30.0f64, -5.0..5.0f64, 0usize..12)
}

/// Negative, zero, huge or ordinary.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![-5.0..0.0f64, Just(0.0), 1e5..1e9f64, 0.0..60.0f64]
}

fn variance() -> impl Strategy<Value = f64> {
    (-6.0..2.0f64).prop_map(|e| 10f64.powf(e))
}

fn assert_sound<const D: usize>(fix: &Fix<D>) {
    assert!(fix.position.iter().all(|v| v.is_finite()), "{fix:?}");
    let p: SMatrix<f64, D, D> = fix.covariance;
    assert!(p.iter().all(|v| v.is_finite()), "{fix:?}");
    assert!((p - p.transpose()).amax() <= 1e-9 * p.amax(), "{fix:?}");
    assert!(p.cholesky().is_some(), "{fix:?}");
}

fn planar(anchors: &[[f64; 3]]) -> Vec<[f64; 2]> {
    anchors.iter().map(|a| [a[0], a[1]]).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn range_solvers_give_sound_fixes_or_errors(
        specs in prop::collection::vec(anchor_spec(), 1..=12),
        measurements in prop::collection::vec((value(), variance()), 12),
        guess in prop::option::of((-40.0..40.0f64, -40.0..40.0f64)),
        three in any::<bool>(),
    ) {
        let anchors = anchors(&specs);
        let n = anchors.len();
        let ranges: Vec<f64> = measurements[..n].iter().map(|m| m.0).collect();
        let variances: Vec<f64> = measurements[..n].iter().map(|m| m.1).collect();
        let reach = ranges.iter().zip(&variances).map(|(r, v)| r + 3.0 * v.sqrt()).fold(0.0, f64::max);
        let options = GaussNewtonOptions::default();
        if three {
            let guess = guess.map(|(x, y)| SVector::<f64, 3>::new(x, y, 1.0));
            if let Ok(fix) = multilaterate(&anchors, &ranges, &variances, guess, &options) {
                assert_sound(&fix.fix);
                prop_assert!(fix.fix.check_plausible(&anchors, reach).is_ok());
            }
            let initial = guess.map_or(Initial::Linear, Initial::Guess);
            if let Ok(solution) = gauss_newton(&anchors, &ranges, &variances, initial, &options) {
                assert_sound(&solution.fix);
                prop_assert!(solution.chi_square.is_finite() && solution.variance_factor >= 1.0);
            }
        } else {
            let anchors = planar(&anchors);
            let guess = guess.map(|(x, y)| Vector2::new(x, y));
            if let Ok(fix) = multilaterate(&anchors, &ranges, &variances, guess, &options) {
                assert_sound(&fix.fix);
                prop_assert!(fix.fix.check_plausible(&anchors, reach).is_ok());
            }
            let initial = guess.map_or(Initial::Linear, Initial::Guess);
            if let Ok(solution) = gauss_newton(&anchors, &ranges, &variances, initial, &options) {
                assert_sound(&solution.fix);
                prop_assert!(solution.chi_square.is_finite() && solution.variance_factor >= 1.0);
            }
        }
    }

    #[test]
    fn tdoa_solvers_give_sound_fixes_or_errors(
        specs in prop::collection::vec(anchor_spec(), 1..=12),
        measurements in prop::collection::vec((value(), value(), variance()), 11),
        reference in 0usize..12,
        height in -2.0..4.0f64,
    ) {
        let anchors = anchors(&specs);
        let n = anchors.len();
        let reference = reference % n;
        let differences: Vec<f64> = measurements[..n - 1].iter().map(|m| m.0 - m.1).collect();
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(n - 1, measurements[..n - 1].iter().map(|m| m.2)));
        if let Ok(fix) = planar_at_height(&anchors, reference, &differences, &q, height) {
            assert_sound(&fix);
            prop_assert!(fix.check_plausible(&planar(&anchors), 0.0).is_ok());
        }
        if let Ok(fix) = chan_taylor(&anchors, reference, &differences, &q) {
            assert_sound(&fix);
        }
        if let Ok(fix) = chan_taylor(&planar(&anchors), reference, &differences, &q) {
            assert_sound(&fix);
        }
    }
}
