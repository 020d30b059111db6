//! Tests of the three trackers: LS, the paper's EKF and ours through the engine's
//! `AnonymousTracker` (the association logic itself is tested in
//! `rtls-engine/src/association/seeded_tests.rs`).

use super::super::schedule::Request;
use super::*;
use rtls_estimation::motion::ProcessNoise;
use rtls_estimation::{Matrix, Vector};

fn settings() -> TrackerSettings {
    TrackerSettings {
        motion: ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap(),
        acceleration_psd_m2ps3: 0.05,
        range_variance_m2: 0.03 * 0.03,
        gate_probability: 0.99,
        sector_margin_rad: 10f64.to_radians(),
        manoeuvre_margin_m: 0.5,
        manoeuvre_velocity_std_mps: 0.5,
        manoeuvre_speed_change_mps: 1.0,
    }
}

fn ours(tracks: &[Gaussian<4>]) -> Tracker {
    Tracker::engine(&settings(), &SonarRing::srf08(), tracks).unwrap()
}

fn observation(robot: usize, node: usize, sector: usize, time_s: f64, echo: Option<(f64, usize)>) -> Observation {
    Observation {
        timed: Timed {
            request: Request {
                robot,
                node,
                aim: Aim::single(sector),
                cell: 0,
            },
            time_s,
            arrival_s: time_s + 0.1,
        },
        stamp_s: time_s,
        echo: echo.map(|(range_m, source)| Echo {
            range_m,
            time_of_flight_s: 2.0 * range_m / 343.0,
            source,
        }),
    }
}

fn track(x: f64, y: f64) -> Gaussian<4> {
    let p = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.01, 0.01, 0.01, 0.01));
    Gaussian::new(Vector::<4>::new(x, 0.0, y, 0.0), p, 0.0).unwrap()
}

const NODES: [[f64; 2]; 4] = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]];

#[test]
fn least_squares_uses_every_range_of_its_robot() {
    let truth = [1.2, 0.7];
    let range = |n: usize| (NODES[n][0] - truth[0]).hypot(NODES[n][1] - truth[1]);
    let obs: Vec<Observation> = (0..3)
        .map(|n| observation(0, n, 0, 0.1 * n as f64, Some((range(n), 0))))
        .collect();
    let mut ls = Tracker::LeastSquares(vec![[1.0, 1.0]]);
    let outcome = ls.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    let Tracker::LeastSquares(fixes) = &ls else {
        unreachable!()
    };
    assert!((fixes[0][0] - 1.2).abs() < 1e-9 && (fixes[0][1] - 0.7).abs() < 1e-9);
    assert_eq!(outcome.ls_fixes, [1, 0, 0]);
    assert!((outcome.latencies_s[0] - 0.3).abs() < 1e-12);
    // two ranges: the mirror candidate nearer the previous fix
    let mut ls = Tracker::LeastSquares(vec![[1.0, 0.9]]);
    ls.process(&settings(), &SonarRing::srf08(), &NODES, &obs[..2]).unwrap();
    let Tracker::LeastSquares(fixes) = &ls else {
        unreachable!()
    };
    assert!((fixes[0][1] - 0.7).abs() < 1e-9, "{fixes:?}");
}

#[test]
fn the_paper_ekf_takes_a_foreign_echo_and_ours_gives_it_to_its_owner() {
    // robot 0 at (1.5, 0.5), robot 1 at (0.6, 0.3): from node 0 both lie in sector 0 and
    // robot 1 is nearer, so the sonar aimed at robot 0 hears robot 1
    let tracks = vec![track(1.5, 0.5), track(0.6, 0.3)];
    let foreign = 0.6f64.hypot(0.3);
    let obs = [observation(0, 0, 0, 0.1, Some((foreign, 1)))];
    let mut paper = Tracker::PaperEkf(tracks.clone());
    let outcome = paper.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert_eq!(outcome.used_by, vec![Some(0)]);
    let mut ours = ours(&tracks);
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert_eq!(outcome.used_by, vec![Some(1)]);
    assert!((outcome.latencies_s[0] - 0.1).abs() < 1e-12);
    let p = ours.positions_at(&settings(), 0.1).unwrap();
    assert!((p[0][0] - 1.5).abs() < 1e-12, "robot 0 is untouched");
    // an echo matching no track is dropped
    let stray = [observation(0, 0, 0, 0.2, Some((2.9, 5)))];
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &stray).unwrap();
    assert_eq!((outcome.used_by[0], outcome.gated_out), (None, 1));
}

#[test]
fn simultaneous_echoes_are_assigned_jointly() {
    // two echoes at one instant from nodes 0 and 3, both within the gates of both tracks:
    // each track takes at most one of them
    let a = 1.0f64.hypot(1.02);
    let b = 1.0f64.hypot(1.0);
    let obs = [
        observation(0, 0, 0, 0.1, Some((a, 1))),
        observation(1, 3, 3, 0.1, Some((b, 0))),
    ];
    let mut ours = ours(&[track(1.0, 1.0), track(1.0, 1.04)]);
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert!(outcome.used_by.iter().all(Option::is_some));
    assert_ne!(outcome.used_by[0], outcome.used_by[1]);
}

#[test]
fn an_echo_two_tracks_could_explain_goes_to_the_one_that_can_have_drifted_that_far() {
    // both tracks predict 1.044 m from node 0 and the echo says 1.494 m: outside both gates
    // (√S ≈ 0.06 m for the fresh track, 0.14 m a second later), within the 0.5 m manoeuvre
    // margin of both. Robot 1 was updated 0.05 s ago (it can be 3 √S + 1 m/s × 0.05 s ≈ 0.22 m
    // off), robot 0 a second ago: robot 0 takes it, counted as a sole candidate.
    let p = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.0025, 1e-4, 0.0025, 1e-4));
    let at = |x: f64, y: f64, time_s: f64| Gaussian::new(Vector::<4>::new(x, 0.0, y, 0.0), p, time_s).unwrap();
    let r = 1.0f64.hypot(0.3);
    let y0 = 0.53;
    let x0 = (r * r - y0 * y0).sqrt();
    let echo = [observation(0, 0, 0, 1.0, Some((r + 0.45, 0)))];
    let mut tracker = ours(&[at(x0, y0, 0.0), at(1.0, 0.3, 0.95)]);
    let outcome = tracker
        .process(&settings(), &SonarRing::srf08(), &NODES, &echo)
        .unwrap();
    assert_eq!(
        (outcome.used_by[0], outcome.sole_candidate, outcome.ambiguous),
        (Some(0), 1, 0)
    );
    // both updated long ago: either may have manoeuvred, the echo is dropped as ambiguous
    let mut tracker = ours(&[at(x0, y0, 0.0), at(1.0, 0.3, 0.0)]);
    let outcome = tracker
        .process(&settings(), &SonarRing::srf08(), &NODES, &echo)
        .unwrap();
    assert_eq!((outcome.used_by[0], outcome.ambiguous, outcome.gated_out), (None, 1, 1));
}

#[test]
fn a_firings_field_of_view_is_its_sonars_sectors() {
    // the view of one sonar or two adjacent ones (wrapping past sonar 5) holds the same points
    // as SonarRing::in_aim with the same margin, away from the edges
    use rand::{Rng, SeedableRng};
    let ring = SonarRing::srf08();
    let margin_rad = 10f64.to_radians();
    let node: [f64; 2] = [2.0, 2.0];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for aim in [
        Aim::single(0),
        Aim::single(3),
        Aim { first: 2, count: 2 },
        Aim { first: 5, count: 2 },
    ] {
        let view = field_of_view(&ring, aim, margin_rad).unwrap();
        for _ in 0..500 {
            let point: [f64; 2] = [rng.gen_range(-1.0..5.0), rng.gen_range(-1.0..5.0)];
            // skip points within 0.1° of an edge
            let near_edge = (0..=360).step_by(10).any(|edge_deg| {
                let bearing = (point[1] - node[1]).atan2(point[0] - node[0]).to_degrees();
                let offset = (bearing - f64::from(edge_deg)).rem_euclid(360.0);
                !(0.1..=359.9).contains(&offset)
            });
            if near_edge {
                continue;
            }
            assert_eq!(
                view.contains_bearing(node, point),
                ring.in_aim(node, aim, point, margin_rad),
                "{aim:?} {point:?}"
            );
        }
        assert_eq!(view.max_range_m(), ring.max_range_m());
    }
}
