//! Tests of the pseudorange solver: noise-free truth, the minimum against a brute-force grid,
//! the covariance against Monte Carlo scatter, fault exclusion, the clock prior and errors.

use nalgebra::{DMatrix, DVector, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;

/// GPS orbit radius, m.
const ORBIT_RADIUS_M: f64 = 26_560e3;

fn frame() -> LocalFrame {
    LocalFrame::new(Geodetic {
        latitude_deg: 47.37,
        longitude_deg: 8.54,
        height_m: 420.0,
    })
    .unwrap()
}

/// A satellite on the orbit sphere seen from the frame's origin at (azimuth, elevation), ECEF.
fn satellite(frame: &LocalFrame, azimuth_deg: f64, elevation_deg: f64) -> Vector3<f64> {
    let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let u_enu = Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
    let u = frame.rotation().transpose() * u_enu;
    let r0 = frame.origin_ecef_m();
    // ‖r₀ + d u‖ = R  ⇒  d = −r₀·u + √((r₀·u)² − ‖r₀‖² + R²)
    let ru = r0.dot(&u);
    let d = -ru + (ru * ru - r0.norm_squared() + ORBIT_RADIUS_M * ORBIT_RADIUS_M).sqrt();
    r0 + u * d
}

/// Eight satellites spread over the sky.
fn constellation(frame: &LocalFrame) -> Vec<Vector3<f64>> {
    [
        (10.0, 75.0),
        (60.0, 35.0),
        (120.0, 20.0),
        (170.0, 50.0),
        (220.0, 15.0),
        (260.0, 40.0),
        (310.0, 25.0),
        (350.0, 12.0),
    ]
    .iter()
    .map(|&(az, el)| satellite(frame, az, el))
    .collect()
}

/// Exact pseudoranges (Sagnac included) from the ENU point `truth` with clock bias `bias_m`.
fn observe(
    frame: &LocalFrame,
    satellites: &[Vector3<f64>],
    truth: &Vector3<f64>,
    bias_m: f64,
    sigma_m: f64,
) -> Vec<Pseudorange> {
    let receiver = frame.ecef_from_enu(truth);
    satellites
        .iter()
        .map(|s| Pseudorange {
            satellite_ecef_m: [s[0], s[1], s[2]],
            pseudorange_m: (earth_rotation_correction(s, &receiver).unwrap() - receiver).norm() + bias_m,
            variance_m2: sigma_m * sigma_m,
        })
        .collect()
}

/// `χ²(x, b)` evaluated independently of the solver.
fn cost(frame: &LocalFrame, observations: &[Pseudorange], enu: &Vector3<f64>, bias_m: f64) -> f64 {
    let receiver = frame.ecef_from_enu(enu);
    observations
        .iter()
        .map(|o| {
            let s = earth_rotation_correction(&Vector3::from(o.satellite_ecef_m), &receiver).unwrap();
            let e = o.pseudorange_m - (s - receiver).norm() - bias_m;
            e * e / o.variance_m2
        })
        .sum()
}

#[test]
fn noise_free_truth_is_recovered_to_a_millimetre() {
    let frame = frame();
    let satellites = constellation(&frame);
    for (truth, bias) in [
        (Vector3::new(0.0, 0.0, 0.0), 0.0),
        (Vector3::new(350.0, -820.0, 12.0), 3.0e5),
        (Vector3::new(-4000.0, 2500.0, -30.0), -1.2e6),
    ] {
        let observations = observe(&frame, &satellites, &truth, bias, 3.0);
        let s = pseudorange_fix(&frame, &observations, &PseudorangeOptions::default()).unwrap();
        assert!((s.fix.position - truth).norm() < 1e-3, "{:?}", s.fix.position - truth);
        assert!((s.clock_bias_m - bias).abs() < 1e-3);
        assert!(s.chi_square < 1e-6 && s.excluded.is_empty());
        assert_eq!((s.degrees_of_freedom, s.integrity), (4, Integrity::Passed));
        assert!(s.residuals_m.iter().all(|r| r.abs() < 1e-3));
        // P = σ² (HᵀH)⁻¹ for equal σ: tr P = σ² GDOP²
        let dop = s.dop.unwrap();
        assert!((s.covariance_m2.trace() - 9.0 * dop.gdop * dop.gdop).abs() < 1e-6 * s.covariance_m2.trace());
        assert!(dop.pdop < dop.gdop && dop.hdop < dop.pdop && dop.vdop.unwrap() > 0.0 && dop.tdop > 0.0);
        // at the known height: the planar solver
        let planar =
            pseudorange_fix_at_height(&frame, &observations, truth[2], &PseudorangeOptions::default()).unwrap();
        assert!((planar.fix.position - truth.xy()).norm() < 1e-3);
        assert!((planar.clock_bias_m - bias).abs() < 1e-3);
        assert_eq!(planar.degrees_of_freedom, 5);
        assert!(planar.dop.unwrap().vdop.is_none());
    }
}

#[test]
fn the_solution_is_the_minimum_of_a_brute_force_grid() {
    let frame = frame();
    let satellites = constellation(&frame);
    let truth = Vector3::new(40.0, 25.0, 3.0);
    let mut observations = observe(&frame, &satellites, &truth, 1000.0, 3.0);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let noise = Normal::new(0.0, 3.0).unwrap();
    for o in &mut observations {
        o.pseudorange_m += noise.sample(&mut rng);
    }
    let options = PseudorangeOptions {
        exclude_faults: false,
        ..PseudorangeOptions::default()
    };
    let s = pseudorange_fix(&frame, &observations, &options).unwrap();
    let best = cost(&frame, &observations, &s.fix.position, s.clock_bias_m);
    assert!((best - s.chi_square).abs() < 1e-9 * best.max(1.0));
    // a 9⁴ grid of ±2σ about the solution (σ from the covariance): nothing lower
    let sd: Vec<f64> = (0..4).map(|i| s.covariance_m2[(i, i)].sqrt()).collect();
    let mut lowest = f64::INFINITY;
    for i in -4..=4 {
        for j in -4..=4 {
            for k in -4..=4 {
                for l in -4..=4 {
                    let step = |n: i32, axis: usize| f64::from(n) * 0.5 * sd[axis];
                    let p = s.fix.position + Vector3::new(step(i, 0), step(j, 1), step(k, 2));
                    let c = cost(&frame, &observations, &p, s.clock_bias_m + step(l, 3));
                    assert!(c >= best - 1e-9 * best, "grid point {i} {j} {k} {l}: {c} < {best}");
                    lowest = lowest.min(c);
                }
            }
        }
    }
    assert!((lowest - best).abs() < 1e-9 * best);
}

#[test]
fn the_covariance_matches_monte_carlo_scatter() {
    let frame = frame();
    let satellites = constellation(&frame);
    let truth = Vector3::new(100.0, -60.0, 1.5);
    let clean = observe(&frame, &satellites, &truth, 2.0e4, 3.0);
    let options = PseudorangeOptions {
        exclude_faults: false,
        ..PseudorangeOptions::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let noise = Normal::new(0.0, 3.0).unwrap();
    let trials = 2000;
    let mut errors = Vec::with_capacity(trials);
    let mut predicted = DMatrix::zeros(4, 4);
    for _ in 0..trials {
        let mut observations = clean.clone();
        for o in &mut observations {
            o.pseudorange_m += noise.sample(&mut rng);
        }
        let s = pseudorange_fix(&frame, &observations, &options).unwrap();
        let e = s.fix.position - truth;
        errors.push(DVector::from_vec(vec![e[0], e[1], e[2], s.clock_bias_m - 2.0e4]));
        // the a-priori covariance (HᵀWH)⁻¹, without the a-posteriori factor
        predicted = s.covariance_m2 / s.variance_factor;
    }
    let mean = errors.iter().fold(DVector::zeros(4), |acc, e| acc + e) / trials as f64;
    let scatter = errors.iter().fold(DMatrix::zeros(4, 4), |acc, e| {
        acc + (e - &mean) * (e - &mean).transpose()
    }) / (trials as f64 - 1.0);
    for i in 0..4 {
        // a sample variance of 2000 draws has a relative standard error of √(2/1999) ≈ 3.2 %
        let ratio = scatter[(i, i)] / predicted[(i, i)];
        println!(
            "axis {i}: sample/predicted variance {ratio:.3}, mean error {:.3} m",
            mean[i]
        );
        assert!((ratio - 1.0).abs() < 0.1, "axis {i}: sample/predicted variance {ratio}");
        // unbiased: the mean error within 4 standard errors
        assert!(
            mean[i].abs() < 4.0 * (predicted[(i, i)] / trials as f64).sqrt(),
            "axis {i}: bias {}",
            mean[i]
        );
    }
    // the correlations (height and clock are strongly correlated) match too
    let correlation = |m: &DMatrix<f64>| m[(2, 3)] / (m[(2, 2)] * m[(3, 3)]).sqrt();
    assert!((correlation(&scatter) - correlation(&predicted)).abs() < 0.05);
}

#[test]
fn a_multipath_outlier_is_excluded() {
    let frame = frame();
    let satellites = constellation(&frame);
    let truth = Vector3::new(-30.0, 80.0, 2.0);
    let mut observations = observe(&frame, &satellites, &truth, 5.0e4, 3.0);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 3.0).unwrap();
    for o in &mut observations {
        o.pseudorange_m += noise.sample(&mut rng);
    }
    observations[3].pseudorange_m += 100.0;
    let s = pseudorange_fix(&frame, &observations, &PseudorangeOptions::default()).unwrap();
    println!(
        "outlier: excluded {:?}, residual {:.1} m, error {:.2} m, chi2 {:.2} (dof {})",
        s.excluded,
        s.residuals_m[3],
        (s.fix.position - truth).norm(),
        s.chi_square,
        s.degrees_of_freedom
    );
    assert_eq!(s.excluded, [3]);
    assert_eq!(s.integrity, Integrity::Passed);
    assert_eq!(s.degrees_of_freedom, 3);
    assert!(s.residuals_m[3] > 60.0, "{}", s.residuals_m[3]);
    assert!((s.fix.position - truth).norm() < 25.0);
    // without exclusion the fault stays, flagged, and the covariance is inflated
    let kept = pseudorange_fix(
        &frame,
        &observations,
        &PseudorangeOptions {
            exclude_faults: false,
            ..PseudorangeOptions::default()
        },
    )
    .unwrap();
    assert_eq!(kept.integrity, Integrity::Failed);
    assert!(kept.variance_factor > 10.0 && kept.excluded.is_empty());
}

#[test]
fn a_clock_prior_makes_three_satellites_enough() {
    let frame = frame();
    let satellites: Vec<Vector3<f64>> = constellation(&frame)[..3].to_vec();
    let truth = Vector3::new(15.0, -5.0, 1.0);
    let observations = observe(&frame, &satellites, &truth, 3.0e5, 3.0);
    assert_eq!(
        pseudorange_fix(&frame, &observations, &PseudorangeOptions::default()).unwrap_err(),
        PositioningError::Underdetermined { anchors: 3, needed: 4 }
    );
    let options = PseudorangeOptions {
        clock_prior: Some(ClockPrior {
            mean_m: 3.0e5,
            variance_m2: 4.0,
        }),
        ..PseudorangeOptions::default()
    };
    let s = pseudorange_fix(&frame, &observations, &options).unwrap();
    assert!((s.fix.position - truth).norm() < 1e-3);
    assert_eq!((s.degrees_of_freedom, s.integrity), (0, Integrity::Untestable));
    assert!(s.dop.is_none());
    assert!(s.clock_variance_m2 <= 4.0);
    // at a known height two satellites and the prior suffice
    let planar = pseudorange_fix_at_height(&frame, &observations[..2], 1.0, &options).unwrap();
    assert!((planar.fix.position - truth.xy()).norm() < 1e-3);
    assert_eq!(
        pseudorange_fix_at_height(&frame, &observations[..1], 1.0, &options).unwrap_err(),
        PositioningError::Underdetermined { anchors: 1, needed: 2 }
    );
}

#[test]
fn invalid_inputs_are_errors() {
    let frame = frame();
    let satellites = constellation(&frame);
    let good = observe(&frame, &satellites, &Vector3::zeros(), 0.0, 3.0);
    let options = PseudorangeOptions::default();
    let mut bad = good.clone();
    bad[2].satellite_ecef_m[1] = f64::NAN;
    assert!(matches!(
        pseudorange_fix(&frame, &bad, &options),
        Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
    ));
    let mut bad = good.clone();
    bad[0].variance_m2 = 0.0;
    assert!(matches!(
        pseudorange_fix(&frame, &bad, &options),
        Err(PositioningError::InvalidParameter {
            name: "variance_m2",
            ..
        })
    ));
    let bad_prior = PseudorangeOptions {
        clock_prior: Some(ClockPrior {
            mean_m: 0.0,
            variance_m2: -1.0,
        }),
        ..options
    };
    assert!(pseudorange_fix(&frame, &good, &bad_prior).is_err());
    let bad_probability = PseudorangeOptions {
        false_alarm_probability: 1.0,
        ..options
    };
    assert!(pseudorange_fix(&frame, &good, &bad_probability).is_err());
    assert!(pseudorange_fix_at_height(&frame, &good, f64::NAN, &options).is_err());
    // four satellites at one position: the geometry is singular
    let same: Vec<Pseudorange> = (0..4).map(|_| good[0]).collect();
    assert!(matches!(
        pseudorange_fix(&frame, &same, &options),
        Err(PositioningError::DegenerateGeometry { .. })
    ));
}

#[test]
fn the_sagnac_correction_is_a_rotation_by_the_transit_angle() {
    let receiver = Vector3::new(WGS84_A_M, 0.0, 0.0);
    let satellite = Vector3::new(15_600e3, 7_540e3, 20_140e3);
    let rotated = earth_rotation_correction(&satellite, &receiver).unwrap();
    let theta = EARTH_ROTATION_RATE_RADPS * (satellite - receiver).norm() / SPEED_OF_LIGHT_MPS;
    // the arc ω_E τ ‖s_xy‖, about 99 m here; z unchanged
    assert!(((rotated - satellite).norm() - theta * satellite.xy().norm()).abs() < 1e-6);
    assert_eq!(rotated[2], satellite[2]);
    // it moves the satellite westwards (the Earth turned east under the signal)
    assert!(rotated.xy().perp(&satellite.xy()) > 0.0);
    assert!(earth_rotation_correction(&Vector3::new(f64::NAN, 0.0, 0.0), &receiver).is_err());
}
