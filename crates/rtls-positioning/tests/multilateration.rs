//! Conformance of the multilateration solvers: exact recovery on random noise-free geometries
//! (2-D and 3-D), seeded Monte Carlo of the reported covariances (NEES against the χ² interval,
//! GN against the Cramér–Rao bound), agreement with brute-force grid searches, and the typed
//! errors of every degenerate input.

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_positioning::multilateration::{
    gauss_newton, gdop, linear_least_squares, toa_rss, two_range, weighted_linear_least_squares, CircleIntersection,
    GaussNewtonOptions, Initial, RangeObservation, ReferenceAnchor, RssObservation,
};
use rtls_positioning::pathloss::{LogDistance, PathLossModel};
use rtls_positioning::{Fix2, PositioningError, Result};

fn distances<const D: usize>(anchors: &[[f64; D]], p: &SVector<f64, D>) -> Vec<f64> {
    anchors.iter().map(|a| (p - SVector::from(*a)).norm()).collect()
}

/// `(JᵀWJ)⁻¹` at `p` for ranges with variances `v` (the Cramér–Rao bound of TOA).
fn range_crb<const D: usize>(anchors: &[[f64; D]], v: &[f64], p: &SVector<f64, D>) -> SMatrix<f64, D, D> {
    let info = anchors
        .iter()
        .zip(v)
        .fold(SMatrix::<f64, D, D>::zeros(), |acc, (a, v)| {
            let u = (p - SVector::from(*a)).normalize();
            acc + u * u.transpose() / *v
        });
    info.try_inverse().unwrap()
}

/// The 99 % Monte-Carlo interval of the mean of `trials` χ²_D samples (normal approximation).
fn nees_interval(dimension: usize, trials: usize) -> (f64, f64) {
    let d = dimension as f64;
    let half = 2.576 * (2.0 * d / trials as f64).sqrt();
    (d - half, d + half)
}

/// Random anchors (between D+1 and 10) and a truth in a 50 m box (truth up to 5 m outside
/// it), rejecting geometries whose GDOP at the truth exceeds `GDOP_CAP`.
const GDOP_CAP: f64 = 8.0;

fn random_case<const D: usize>(rng: &mut ChaCha8Rng) -> (Vec<[f64; D]>, SVector<f64, D>) {
    loop {
        let n = rng.gen_range(D + 1..=10);
        let anchors: Vec<[f64; D]> = (0..n)
            .map(|_| core::array::from_fn(|_| rng.gen_range(0.0..50.0)))
            .collect();
        let truth = SVector::<f64, D>::from_fn(|_, _| rng.gen_range(-5.0..55.0));
        if matches!(gdop(&anchors, &truth), Ok(g) if g < GDOP_CAP) {
            return (anchors, truth);
        }
    }
}

fn recovers_on_random_geometries<const D: usize>(seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let model = LogDistance::new(-40.0, 2.0, 1.0, 2.0).unwrap();
    let options = GaussNewtonOptions::default();
    let geometries = 250;
    for case in 0..geometries {
        let (anchors, truth) = random_case::<D>(&mut rng);
        let r = distances(&anchors, &truth);
        let v: Vec<f64> = (0..anchors.len()).map(|_| rng.gen_range(0.01..1.0)).collect();
        let tolerance = 1e-6 * (1.0 + truth.norm());
        let check = |name: &str, p: &SVector<f64, D>| {
            assert!((p - truth).norm() < tolerance, "case {case} {name}: {p} vs {truth}");
        };
        // the linear fix is exact only for consistent ranges, and may be ill-conditioned where
        // the GN fix is not: it must either be exact or report degenerate geometry
        match linear_least_squares(&anchors, &r, ReferenceAnchor::NearestRange) {
            Ok(p) => check("lls", &p),
            Err(PositioningError::DegenerateGeometry { .. }) => {}
            Err(e) => panic!("case {case} lls: {e}"),
        }
        check(
            "wlls",
            &weighted_linear_least_squares(&anchors, &r, &v, ReferenceAnchor::Index(0))
                .unwrap()
                .position,
        );
        let gn = gauss_newton(&anchors, &r, &v, Initial::Linear, &options).unwrap();
        check("gn", &gn.fix.position);
        assert!(gn.chi_square < 1e-12, "case {case}: χ² = {}", gn.chi_square);
        assert!((gn.gdop - gdop(&anchors, &truth).unwrap()).abs() < 1e-6 * gn.gdop);
        // from a guess 2 m off, as a tracker would start it
        let guess = truth + SVector::<f64, D>::from_fn(|_, _| rng.gen_range(-1.2..1.2));
        check(
            "gn guess",
            &gauss_newton(&anchors, &r, &v, Initial::Guess(guess), &options)
                .unwrap()
                .fix
                .position,
        );
        // TOA + RSS, every anchor both
        let ranges: Vec<RangeObservation> = r
            .iter()
            .enumerate()
            .map(|(anchor, &range_m)| RangeObservation {
                anchor,
                range_m,
                variance_m2: v[anchor],
            })
            .collect();
        let rss: Vec<RssObservation<'_>> = r
            .iter()
            .enumerate()
            .map(|(anchor, &d)| RssObservation {
                anchor,
                rssi_dbm: model.mean_rssi_dbm(d),
                model: &model,
            })
            .collect();
        check(
            "toa+rss",
            &toa_rss(&anchors, &ranges, &rss, Initial::Linear, &options)
                .unwrap()
                .fix
                .position,
        );
    }
}

#[test]
fn every_solver_recovers_the_truth_on_random_2d_geometries() {
    recovers_on_random_geometries::<2>(2000);
    // the two-range fix: the prior at the truth picks it
    let mut rng = ChaCha8Rng::seed_from_u64(2001);
    let mut crossing = 0;
    while crossing < 250 {
        let anchors: [[f64; 2]; 2] = core::array::from_fn(|_| core::array::from_fn(|_| rng.gen_range(0.0..50.0)));
        let truth = Vector2::new(rng.gen_range(-5.0..55.0), rng.gen_range(-5.0..55.0));
        if !matches!(gdop(&anchors, &truth), Ok(g) if g < GDOP_CAP) {
            continue;
        }
        let r = distances(&anchors, &truth);
        let prior = Fix2 {
            position: truth,
            covariance: Matrix2::identity(),
        };
        let s = two_range(&anchors, &[r[0], r[1]], &[0.01, 0.04], Some(&prior)).unwrap();
        assert_eq!(s.intersection, CircleIntersection::Crossing);
        assert!((s.fix.position - truth).norm() < 1e-6 * (1.0 + truth.norm()));
        crossing += 1;
    }
}

#[test]
fn every_solver_recovers_the_truth_on_random_3d_geometries() {
    recovers_on_random_geometries::<3>(3000);
}

/// Monte-Carlo NEES of fixes against the truth: `(p̂ − p)ᵀ P⁻¹ (p̂ − p)`.
fn nees<const D: usize>(position: &SVector<f64, D>, covariance: &SMatrix<f64, D, D>, truth: &SVector<f64, D>) -> f64 {
    let e = position - truth;
    e.dot(&(covariance.try_inverse().unwrap() * e))
}

fn gauss_newton_consistency<const D: usize>(anchors: &[[f64; D]], truth: SVector<f64, D>, sigmas: &[f64], seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let v: Vec<f64> = sigmas.iter().map(|s| s * s).collect();
    let crb = range_crb(anchors, &v, &truth);
    let clean = distances(anchors, &truth);
    let trials = 2000;
    let (mut gn_nees, mut lls_nees, mut scaled_nees) = (0.0, 0.0, 0.0);
    let mut scatter = SMatrix::<f64, D, D>::zeros();
    let (mut worst_covariance_error, mut mean_covariance_error) = (0.0_f64, 0.0);
    for _ in 0..trials {
        let r: Vec<f64> = clean
            .iter()
            .zip(sigmas)
            .map(|(d, s)| d + Normal::new(0.0, *s).unwrap().sample(&mut rng))
            .collect();
        let gn = gauss_newton(anchors, &r, &v, Initial::Linear, &GaussNewtonOptions::default()).unwrap();
        // (JᵀWJ)⁻¹ before the a-posteriori variance factor: the CRB-consistent covariance
        let a_priori = gn.fix.covariance / gn.variance_factor;
        assert!(gn.variance_factor >= 1.0);
        gn_nees += nees(&gn.fix.position, &a_priori, &truth);
        scaled_nees += nees(&gn.fix.position, &gn.fix.covariance, &truth);
        let e = gn.fix.position - truth;
        scatter += e * e.transpose();
        let covariance_error = (a_priori - crb).norm() / crb.norm();
        worst_covariance_error = worst_covariance_error.max(covariance_error);
        mean_covariance_error += covariance_error / trials as f64;
        let lls = weighted_linear_least_squares(anchors, &r, &v, ReferenceAnchor::NearestRange).unwrap();
        lls_nees += nees(&lls.position, &lls.covariance, &truth);
    }
    let (low, high) = nees_interval(D, trials);
    let gn_mean = gn_nees / trials as f64;
    let lls_mean = lls_nees / trials as f64;
    eprintln!("mean NEES: GN {gn_mean}, WLLS {lls_mean}; interval [{low}, {high}]");
    assert!(
        (low..high).contains(&gn_mean),
        "GN mean NEES {gn_mean} outside [{low}, {high}]"
    );
    // the reported covariance σ̂₀² (JᵀWJ)⁻¹ is conservative: never inflates the NEES
    let scaled_mean = scaled_nees / trials as f64;
    assert!(scaled_mean <= gn_mean && scaled_mean < high, "{scaled_mean}");
    assert!(
        (low..high).contains(&lls_mean),
        "WLLS mean NEES {lls_mean} outside [{low}, {high}]"
    );
    // the reported covariance (JᵀWJ)⁻¹ at the fix is the CRB at the truth, to first order
    // (it moves with the fix: most along a weak direction)
    assert!(
        mean_covariance_error < 0.05,
        "reported vs CRB: mean {mean_covariance_error}"
    );
    assert!(
        worst_covariance_error < 0.3,
        "reported vs CRB: worst {worst_covariance_error}"
    );
    // and the fixes scatter as the CRB says
    let empirical = scatter / trials as f64;
    let ratio = empirical.trace() / crb.trace();
    eprintln!(
        "empirical / CRB trace {ratio}, reported vs CRB mean {mean_covariance_error}, worst {worst_covariance_error}"
    );
    assert!((0.9..1.1).contains(&ratio), "empirical / CRB trace = {ratio}");
}

#[test]
fn gauss_newton_covariance_is_consistent_2d() {
    // seed 003 test bed (m), ultrasonic ranging σ = 1–3 cm
    let anchors = [[0.0, 0.0], [4.0, 0.0], [0.0, 6.0], [4.0, 6.0], [2.0, 3.0], [0.0, 3.0]];
    gauss_newton_consistency(
        &anchors,
        Vector2::new(1.3, 2.2),
        &[0.01, 0.02, 0.03, 0.01, 0.02, 0.015],
        77,
    );
    // outside the hull (GDOP ≈ 2.7)
    gauss_newton_consistency(&anchors[..4], Vector2::new(6.0, 8.0), &[0.02; 4], 78);
}

#[test]
fn gauss_newton_covariance_is_consistent_3d() {
    let anchors = [
        [0.0, 0.0, 3.0],
        [20.0, 0.0, 2.5],
        [0.0, 15.0, 3.0],
        [20.0, 15.0, 0.5],
        [10.0, 7.0, 0.2],
    ];
    // indoor: anchors between 0.2 m and 3 m high, so height is the weak direction and the
    // first-order covariance holds only at small noise (σ ≤ 2 cm here; at 5–10 cm the
    // fixes' height scatters ~10 % beyond it, mean NEES ≈ 3.35)
    gauss_newton_consistency(
        &anchors,
        SVector::from([6.0, 9.0, 1.5]),
        &[0.01, 0.02, 0.01, 0.015, 0.02],
        79,
    );
}

#[test]
fn toa_rss_covariance_is_consistent_and_never_larger_than_toa_alone() {
    let mut rng = ChaCha8Rng::seed_from_u64(2004);
    let model = LogDistance::new(-45.0, 2.0, 1.0, 0.5).unwrap();
    let anchors = [[0.0, 0.0], [12.0, 0.0], [0.0, 10.0], [12.0, 10.0]];
    let truth = Vector2::new(4.0, 6.5);
    let sigma_r = 0.3;
    let clean = distances(&anchors, &truth);
    let range_noise = Normal::new(0.0, sigma_r).unwrap();
    let rss_noise = Normal::new(0.0, model.shadowing_std_db()).unwrap();
    let options = GaussNewtonOptions::default();
    let trials = 2000;
    let mut sum = 0.0;
    for _ in 0..trials {
        let ranges: Vec<RangeObservation> = clean
            .iter()
            .enumerate()
            .map(|(anchor, d)| RangeObservation {
                anchor,
                range_m: d + range_noise.sample(&mut rng),
                variance_m2: sigma_r * sigma_r,
            })
            .collect();
        let rss: Vec<RssObservation<'_>> = clean
            .iter()
            .enumerate()
            .map(|(anchor, d)| RssObservation {
                anchor,
                rssi_dbm: model.mean_rssi_dbm(*d) + rss_noise.sample(&mut rng),
                model: &model,
            })
            .collect();
        let joint = toa_rss(&anchors, &ranges, &rss, Initial::Linear, &options).unwrap();
        // before the a-posteriori variance factor
        sum += nees(
            &joint.fix.position,
            &(joint.fix.covariance / joint.variance_factor),
            &truth,
        );
    }
    let (low, high) = nees_interval(2, trials);
    let mean = sum / trials as f64;
    eprintln!("TOA+RSS mean NEES {mean}");
    assert!(
        (low..high).contains(&mean),
        "TOA+RSS mean NEES {mean} outside [{low}, {high}]"
    );

    // information adds: on noise-free data at random positions, P_toa − P_joint ⪰ 0
    for _ in 0..200 {
        let p = Vector2::new(rng.gen_range(-5.0..17.0), rng.gen_range(-5.0..15.0));
        let d = distances(&anchors, &p);
        let ranges: Vec<RangeObservation> = (0..4)
            .map(|anchor| RangeObservation {
                anchor,
                range_m: d[anchor],
                variance_m2: 0.09,
            })
            .collect();
        let rss: Vec<RssObservation<'_>> = (0..4)
            .map(|anchor| RssObservation {
                anchor,
                rssi_dbm: model.mean_rssi_dbm(d[anchor]),
                model: &model,
            })
            .collect();
        let (Ok(toa), Ok(joint)) = (
            toa_rss(&anchors, &ranges, &[], Initial::Linear, &options),
            toa_rss(&anchors, &ranges, &rss, Initial::Linear, &options),
        ) else {
            continue; // p at an anchor
        };
        assert!((joint.fix.position - p).norm() < 1e-6);
        let difference = toa.fix.covariance - joint.fix.covariance;
        assert!(
            difference.symmetric_eigenvalues().min() >= -1e-12 * toa.fix.covariance.amax(),
            "{difference}"
        );
    }
}

/// Brute-force minimiser of `cost` over a square grid (coarse, then fine around the best).
fn grid_minimum(cost: impl Fn(Vector2<f64>) -> f64, low: f64, high: f64) -> Vector2<f64> {
    let search = |centre: Vector2<f64>, half: f64, step: f64| {
        let steps = (2.0 * half / step).round() as i64;
        let mut best = (centre, f64::INFINITY);
        for i in 0..=steps {
            for j in 0..=steps {
                let p = centre + Vector2::new(i as f64 * step - half, j as f64 * step - half);
                let c = cost(p);
                if c < best.1 {
                    best = (p, c);
                }
            }
        }
        best.0
    };
    let centre = Vector2::repeat(0.5 * (low + high));
    let coarse = search(centre, 0.5 * (high - low), 0.05);
    search(coarse, 0.1, 0.0005)
}

#[test]
fn linear_and_gauss_newton_fixes_agree_with_a_grid_search() {
    let anchors = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
    // noisy ranges of a tag at (3, 4)
    let r = [5.3, 8.0, 6.5, 9.4];
    let v = [0.04, 0.09, 0.01, 0.25];
    // LLS minimises the algebraic cost Σ (a'_iᵀ p' − b_i)² with the nearest anchor as reference
    let reference = 0;
    let algebraic = |p: Vector2<f64>| {
        (1..4)
            .map(|i| {
                let a = Vector2::from(anchors[i]) - Vector2::from(anchors[reference]);
                let b = 0.5 * (a.norm_squared() - r[i] * r[i] + r[reference] * r[reference]);
                (a.dot(&p) - b).powi(2)
            })
            .sum::<f64>()
    };
    let lls = linear_least_squares(&anchors, &r, ReferenceAnchor::NearestRange).unwrap();
    let grid = grid_minimum(algebraic, 0.0, 10.0);
    assert!((lls - grid).norm() < 1e-3, "lls {lls} vs grid {grid}");
    // GN minimises the ML cost Σ (r_i − ‖p − a_i‖)²/σ_i²
    let ml = |p: Vector2<f64>| {
        (0..4)
            .map(|i| (r[i] - (p - Vector2::from(anchors[i])).norm()).powi(2) / v[i])
            .sum::<f64>()
    };
    let gn = gauss_newton(&anchors, &r, &v, Initial::Linear, &GaussNewtonOptions::default()).unwrap();
    let grid = grid_minimum(ml, 0.0, 10.0);
    assert!(
        (gn.fix.position - grid).norm() < 1e-3,
        "gn {} vs grid {grid}",
        gn.fix.position
    );
    assert!((gn.chi_square - ml(gn.fix.position)).abs() < 1e-9);
    assert!(ml(gn.fix.position) <= ml(lls));
}

#[test]
fn every_degenerate_input_is_a_typed_error() {
    let options = GaussNewtonOptions::default();
    let square = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
    let r = [5.0, 8.0, 7.0, 9.0];
    let v = [0.1; 4];
    let collinear = [[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0]];
    let duplicate = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 0.0]];
    let nan = [[0.0, 0.0], [10.0, 0.0], [0.0, f64::NAN], [10.0, 10.0]];
    let toa = |a: &[[f64; 2]], r: &[f64], v: &[f64]| -> Result<()> {
        let ranges: Vec<RangeObservation> = (0..r.len())
            .map(|i| RangeObservation {
                anchor: i,
                range_m: r[i],
                variance_m2: v[i],
            })
            .collect();
        toa_rss(a, &ranges, &[], Initial::Linear, &options).map(|_| ())
    };
    type Solver<'a> = Box<dyn Fn(&[[f64; 2]], &[f64], &[f64]) -> Result<()> + 'a>;
    let solvers: [(&str, Solver<'_>); 4] = [
        (
            "lls",
            Box::new(|a, r, _| linear_least_squares(a, r, ReferenceAnchor::default()).map(|_| ())),
        ),
        (
            "wlls",
            Box::new(|a, r, v| weighted_linear_least_squares(a, r, v, ReferenceAnchor::default()).map(|_| ())),
        ),
        (
            "gn",
            Box::new(|a, r, v| gauss_newton(a, r, v, Initial::Linear, &options).map(|_| ())),
        ),
        ("toa+rss", Box::new(toa)),
    ];
    for (name, solve) in &solvers {
        assert!(solve(&square, &r, &v).is_ok(), "{name}");
        if *name == "gn" {
            // a negative range is a measurement (Wi-Fi FTM close to an anchor), not an error
            assert!(solve(&square, &[5.0, 8.0, -0.2, 9.0], &v).is_ok(), "{name}");
        } else {
            assert!(
                matches!(
                    solve(&square, &[5.0, 8.0, -7.0, 9.0], &v),
                    Err(PositioningError::InvalidParameter { .. })
                ),
                "{name}"
            );
        }
        assert_eq!(
            solve(&square[..2], &r[..2], &v[..2]).unwrap_err(),
            PositioningError::Underdetermined { anchors: 2, needed: 3 },
            "{name}"
        );
        assert!(
            matches!(
                solve(&collinear, &r, &v),
                Err(PositioningError::DegenerateGeometry { .. })
            ),
            "{name}"
        );
        assert_eq!(
            solve(&duplicate, &r, &v).unwrap_err(),
            PositioningError::DuplicateAnchors { first: 1, second: 3 },
            "{name}"
        );
        assert!(
            matches!(
                solve(&nan, &r, &v),
                Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
            ),
            "{name}"
        );
        assert!(
            matches!(
                solve(&square, &[5.0, f64::INFINITY, 7.0, 9.0], &v),
                Err(PositioningError::NonFiniteEntry { row: 1, .. })
            ),
            "{name}"
        );
    }
    // variances, lengths
    for (name, solve) in &solvers[1..] {
        assert!(
            matches!(
                solve(&square, &r, &[0.1, 0.0, 0.1, 0.1]),
                Err(PositioningError::InvalidParameter { .. })
            ),
            "{name}"
        );
    }
    for (name, solve) in &solvers[..3] {
        assert!(
            matches!(
                solve(&square, &r[..3], &v),
                Err(PositioningError::DimensionMismatch { .. })
            ),
            "{name}"
        );
    }
    assert!(matches!(
        weighted_linear_least_squares(&square, &r, &v[..3], ReferenceAnchor::default()),
        Err(PositioningError::DimensionMismatch { .. })
    ));
    // 3-D coplanar anchors
    let plane = [[0.0, 0.0, 2.0], [10.0, 0.0, 2.0], [0.0, 10.0, 2.0], [10.0, 10.0, 2.0]];
    assert!(matches!(
        gauss_newton(&plane, &r, &v, Initial::Linear, &options),
        Err(PositioningError::DegenerateGeometry { reason }) if reason.contains("coplanar")
    ));
    // two-range: coincident anchors
    assert_eq!(
        two_range(&[[1.0, 2.0], [1.0, 2.0]], &[1.0, 1.0], &[1.0, 1.0], None).unwrap_err(),
        PositioningError::DuplicateAnchors { first: 0, second: 1 }
    );
    // GDOP at an anchor
    assert!(matches!(
        gdop(&square, &Vector2::new(10.0, 10.0)),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}
