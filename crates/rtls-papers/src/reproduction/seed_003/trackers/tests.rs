//! Tests of the three trackers.

use super::super::schedule::Request;
use super::*;
use rtls_estimation::motion::ProcessNoise;
use rtls_estimation::{Matrix, Vector};
use rtls_sim::sensors::ultrasonic::Aim;

fn settings() -> TrackerSettings {
    TrackerSettings {
        motion: ConstantVelocity::new(ProcessNoise::continuous(0.05)).unwrap(),
        range_variance_m2: 0.03 * 0.03,
        gate: ChiSquareGate::new(0.99).unwrap(),
        sector_margin_rad: 10f64.to_radians(),
        manoeuvre_margin_m: 0.5,
        manoeuvre_velocity_std_mps: 0.5,
        manoeuvre_speed_change_mps: 1.0,
    }
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
    let mut paper = Tracker::Ekf {
        tracks: tracks.clone(),
        associate: false,
    };
    let outcome = paper.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert_eq!(outcome.used_by, vec![Some(0)]);
    let mut ours = Tracker::Ekf {
        tracks,
        associate: true,
    };
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert_eq!(outcome.used_by, vec![Some(1)]);
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
    let tracks = vec![track(1.0, 1.0), track(1.0, 1.04)];
    let a = 1.0f64.hypot(1.02);
    let b = 1.0f64.hypot(1.0);
    let obs = [
        observation(0, 0, 0, 0.1, Some((a, 1))),
        observation(1, 3, 3, 0.1, Some((b, 0))),
    ];
    let mut ours = Tracker::Ekf {
        tracks,
        associate: true,
    };
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &obs).unwrap();
    assert!(outcome.used_by.iter().all(Option::is_some));
    assert_ne!(outcome.used_by[0], outcome.used_by[1]);
}

/// (assigned echoes, total cost) of an assignment; `None` if two echoes share a track.
fn score(candidates: &[Vec<(usize, f64)>], assignment: &[Option<usize>]) -> Option<(usize, f64)> {
    let mut used = Vec::new();
    let mut cost = 0.0;
    for (echo, choice) in candidates.iter().zip(assignment) {
        if let Some(c) = choice {
            let (track, c_cost) = echo[*c];
            if used.contains(&track) {
                return None;
            }
            used.push(track);
            cost += c_cost;
        }
    }
    Some((used.len(), cost))
}

/// The best score by enumerating every assignment (independent of the solver).
fn brute_force(candidates: &[Vec<(usize, f64)>]) -> (usize, f64) {
    let mut best = (0, 0.0);
    let mut choice = vec![0usize; candidates.len()];
    loop {
        let assignment: Vec<Option<usize>> = choice.iter().map(|&c| c.checked_sub(1)).collect();
        if let Some((n, cost)) = score(candidates, &assignment) {
            if n > best.0 || (n == best.0 && cost < best.1) {
                best = (n, cost);
            }
        }
        // next choice: each echo takes nothing (0) or candidate c − 1
        let mut e = 0;
        loop {
            if e == choice.len() {
                return best;
            }
            choice[e] += 1;
            if choice[e] <= candidates[e].len() {
                break;
            }
            choice[e] = 0;
            e += 1;
        }
    }
}

#[test]
fn the_assignment_assigns_the_most_echoes_then_the_least_cost() {
    // echo 0 prefers track 0 (−5) over track 1 (an ungated 10⁶); echo 1 can only be track 0:
    // both assigned beats the cheaper single assignment
    let candidates = vec![vec![(0, -5.0), (1, 1e6)], vec![(0, 3.0)]];
    assert_eq!(best_assignment(&candidates, 2).unwrap(), vec![Some(1), Some(0)]);
    // with a free track 2 for echo 1, the cheap pairing wins
    let candidates = vec![vec![(0, -5.0), (1, 1e6)], vec![(0, 3.0), (2, 4.0)]];
    assert_eq!(best_assignment(&candidates, 3).unwrap(), vec![Some(0), Some(1)]);
    // no candidates: nothing assigned
    assert_eq!(best_assignment(&[vec![], vec![]], 3).unwrap(), vec![None, None]);
}

#[test]
fn the_assignment_matches_exhaustive_search() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..500 {
        let echoes = rng.gen_range(1..=5);
        let tracks = rng.gen_range(1..=4);
        let mut candidates: Vec<Vec<(usize, f64)>> = vec![Vec::new(); echoes];
        for echo in &mut candidates {
            for t in 0..tracks {
                if rng.gen_bool(0.6) {
                    // gated costs νᵀS⁻¹ν + ln|S| (ln|S| ≈ −7), some ungated (+10⁶)
                    let ungated = if rng.gen_bool(0.2) { 1e6 } else { 0.0 };
                    echo.push((t, rng.gen_range(-8.0..2.0) + ungated));
                }
            }
        }
        let assignment = best_assignment(&candidates, tracks).unwrap();
        let (n, cost) = score(&candidates, &assignment).expect("each track at most once");
        let (best_n, best_cost) = brute_force(&candidates);
        assert_eq!(n, best_n, "{candidates:?}");
        assert!((cost - best_cost).abs() < 1e-6, "{cost} vs {best_cost}: {candidates:?}");
    }
}

#[test]
fn an_echo_two_tracks_could_explain_goes_to_the_one_that_can_have_drifted_that_far() {
    // both tracks predict 1.044 m from node 0 and the echo says 1.494 m: outside both gates
    // (√S ≈ 0.06 m for the fresh track, 0.14 m a second later), within the 0.5 m manoeuvre
    // margin of both. Track 0 was updated 0.05 s ago (it can be 3 √S + 1 m/s × 0.05 s ≈ 0.22 m
    // off), track 1 a second ago: track 1 takes it.
    let p = Matrix::<4>::from_diagonal(&Vector::<4>::new(0.0025, 1e-4, 0.0025, 1e-4));
    let at = |x: f64, y: f64, time_s: f64| Gaussian::new(Vector::<4>::new(x, 0.0, y, 0.0), p, time_s).unwrap();
    let r = 1.0f64.hypot(0.3);
    let y1 = 0.53;
    let x1 = (r * r - y1 * y1).sqrt();
    let echo = [observation(0, 0, 0, 1.0, Some((r + 0.45, 1)))];
    let mut ours = Tracker::Ekf {
        tracks: vec![at(1.0, 0.3, 0.95), at(x1, y1, 0.0)],
        associate: true,
    };
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &echo).unwrap();
    assert_eq!(
        (outcome.used_by[0], outcome.sole_candidate, outcome.ambiguous),
        (Some(1), 1, 0)
    );
    // both updated long ago: either may have manoeuvred, the echo is dropped as ambiguous
    let mut ours = Tracker::Ekf {
        tracks: vec![at(1.0, 0.3, 0.0), at(x1, y1, 0.0)],
        associate: true,
    };
    let outcome = ours.process(&settings(), &SonarRing::srf08(), &NODES, &echo).unwrap();
    assert_eq!((outcome.used_by[0], outcome.ambiguous, outcome.gated_out), (None, 1, 1));
}
