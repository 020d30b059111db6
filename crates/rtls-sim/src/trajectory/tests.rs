//! Tests of the exact trajectory integration.

use core::f64::consts::{FRAC_PI_2, PI};

use proptest::prelude::*;

use super::*;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

#[test]
fn turn_is_an_exact_circular_arc() {
    // Left turn from heading +x: centre at (0, R), R = v/ω = 10 / 0.05 = 200 m.
    let (v, w, duration) = (10.0, 0.05, 40.0);
    let radius = v / w;
    let track = Trajectory::builder([0.0, 0.0], [v, 0.0])
        .turn(duration, w)
        .build()
        .unwrap();
    for s in track.sample(0.5).unwrap() {
        let theta = w * s.time_s;
        assert!(
            close(s.speed_mps(), v, 1e-12),
            "speed {} at {}",
            s.speed_mps(),
            s.time_s
        );
        let r = norm([s.position_m[0], s.position_m[1] - radius]);
        assert!(close(r, radius, 1e-9), "radius {r} at {}", s.time_s);
        // closed form: p = (R sin θ, R (1 − cos θ)), v = v (cos θ, sin θ)
        assert!(close(s.position_m[0], radius * theta.sin(), 1e-9));
        assert!(close(s.position_m[1], radius * (1.0 - theta.cos()), 1e-9));
        assert!(close(s.velocity_mps[1], v * theta.sin(), 1e-12));
        // centripetal acceleration: magnitude v ω, pointing at the centre
        assert!(close(norm(s.acceleration_mps2), v * w, 1e-12));
        let to_centre = [-s.position_m[0], radius - s.position_m[1]];
        let dot = s.acceleration_mps2[0] * to_centre[0] + s.acceleration_mps2[1] * to_centre[1];
        assert!(
            close(dot, v * w * radius, 1e-6),
            "acceleration not centripetal at {}",
            s.time_s
        );
    }
    let end = track.state_at(duration).unwrap();
    assert!(close(end.position_m[0], 200.0 * 2f64.sin(), 1e-9));
    assert!(close(end.position_m[1], 200.0 * (1.0 - 2f64.cos()), 1e-9));
}

#[test]
fn right_turn_curves_clockwise() {
    // ω < 0 from heading +y: centre at (R, 0); a half circle ends at (2R, 0) heading −y.
    let w = -PI / 20.0;
    let track = Trajectory::builder([0.0, 0.0], [0.0, 5.0])
        .turn(20.0, w)
        .build()
        .unwrap();
    let radius = 5.0 / w.abs();
    let end = track.state_at(20.0).unwrap();
    assert!(close(end.position_m[0], 2.0 * radius, 1e-9) && close(end.position_m[1], 0.0, 1e-9));
    assert!(close(end.velocity_mps[1], -5.0, 1e-12));
}

#[test]
fn zero_turn_rate_is_a_straight_line() {
    let turn = Trajectory::builder([1.0, 2.0], [3.0, -4.0])
        .turn(7.0, 0.0)
        .build()
        .unwrap();
    let line = Trajectory::builder([1.0, 2.0], [3.0, -4.0])
        .constant_velocity(7.0)
        .build()
        .unwrap();
    assert_eq!(turn.sample(1.0).unwrap(), line.sample(1.0).unwrap());
}

#[test]
fn tiny_turn_rate_matches_a_straight_line_without_cancellation() {
    // (1 − cos θ)/ω via 2 sin²(θ/2)/ω stays accurate as ω → 0.
    let w = 1e-12;
    let end = Trajectory::builder([0.0, 0.0], [10.0, 0.0])
        .turn(100.0, w)
        .build()
        .unwrap()
        .state_at(100.0)
        .unwrap();
    assert!(close(end.position_m[0], 1000.0, 1e-9));
    // lateral offset ≈ v ω τ²/2 = 5e-8 m
    assert!(close(end.position_m[1], 10.0 * w * 100.0 * 100.0 / 2.0, 1e-15));
}

#[test]
fn constant_acceleration_matches_closed_form() {
    let track = Trajectory::builder([1.0, -2.0], [0.5, 1.0])
        .constant_acceleration(6.0, [0.2, -0.1])
        .build()
        .unwrap();
    let s = track.state_at(6.0).unwrap();
    // p = p₀ + v₀ τ + a τ²/2 = (1 + 3 + 3.6, −2 + 6 − 1.8)
    assert!(close(s.position_m[0], 7.6, 1e-12) && close(s.position_m[1], 2.2, 1e-12));
    // v = v₀ + a τ = (1.7, 0.4)
    assert!(close(s.velocity_mps[0], 1.7, 1e-12) && close(s.velocity_mps[1], 0.4, 1e-12));
    assert_eq!(s.acceleration_mps2, [0.2, -0.1]);
}

#[test]
fn segment_boundaries_are_right_continuous() {
    let track = Trajectory::builder([0.0, 0.0], [2.0, 0.0])
        .constant_velocity(5.0)
        .stop(5.0)
        .set_velocity([0.0, 1.0])
        .constant_velocity(5.0)
        .build()
        .unwrap();
    // at the instant of the stop the vehicle is already at rest
    assert_eq!(track.state_at(5.0).unwrap().velocity_mps, [0.0, 0.0]);
    // at the restart the new velocity holds
    assert_eq!(track.state_at(10.0).unwrap().velocity_mps, [0.0, 1.0]);
    // just before the stop it still moves
    assert_eq!(track.state_at(4.999).unwrap().velocity_mps, [2.0, 0.0]);
    // the end is the last segment's end state
    let end = track.state_at(15.0).unwrap();
    assert_eq!((end.position_m, end.velocity_mps), ([10.0, 5.0], [0.0, 1.0]));
    // sample() agrees with state_at() at every grid point, boundaries included
    for s in track.sample(0.5).unwrap() {
        assert_eq!(s, track.state_at(s.time_s).unwrap());
    }
}

#[test]
fn sample_times_are_multiples_of_dt_and_include_the_end() {
    let track = Trajectory::builder([0.0, 0.0], [1.0, 0.0])
        .constant_velocity(1500.0)
        .build()
        .unwrap();
    let samples = track.sample(0.1).unwrap();
    assert_eq!(samples.len(), 15_001);
    for (k, s) in samples.iter().enumerate() {
        assert_eq!(s.time_s, (k as f64 * 0.1).min(1500.0));
    }
    assert_eq!(samples.last().unwrap().time_s, 1500.0);
}

#[test]
fn mean_acceleration_integrates_across_segments_and_skips_impulses() {
    let track = Trajectory::builder([0.0, 0.0], [0.0, 0.0])
        .constant_acceleration(2.0, [1.0, 0.0])
        .stop(1.0) // the jump from 2 m/s to 0 is an impulse: not integrated
        .set_velocity([0.0, 3.0])
        .turn(1.0, FRAC_PI_2)
        .build()
        .unwrap();
    // ∫₀² a dt = (2, 0) over 2 s
    assert_eq!(track.mean_acceleration(0.0, 2.0).unwrap(), [1.0, 0.0]);
    // over [1, 3]: 1 s of (1, 0), 1 s stopped → (0.5, 0)
    assert_eq!(track.mean_acceleration(1.0, 3.0).unwrap(), [0.5, 0.0]);
    // quarter turn: Δv = (−3, 0) − (0, 3) over 1 s
    let a = track.mean_acceleration(3.0, 4.0).unwrap();
    assert!(close(a[0], -3.0, 1e-12) && close(a[1], -3.0, 1e-12));
}

#[test]
fn bad_parameters_are_errors() {
    let b = || Trajectory::builder([0.0, 0.0], [1.0, 0.0]);
    let invalid = |r: Result<Trajectory>| matches!(r, Err(SimError::InvalidParameter { name: "duration_s", .. }));
    assert!(invalid(b().constant_velocity(-1.0).build()));
    assert!(invalid(b().stop(0.0).build()));
    assert!(invalid(b().turn(-5.0, 0.1).build()));
    assert!(invalid(b().constant_acceleration(-0.5, [0.0, 0.0]).build()));
    assert!(matches!(
        b().constant_velocity(f64::NAN).build(),
        Err(SimError::NonFinite { .. })
    ));
    assert!(matches!(
        b().constant_velocity(f64::INFINITY).build(),
        Err(SimError::NonFinite { .. })
    ));
    assert!(matches!(
        b().turn(1.0, f64::NAN).build(),
        Err(SimError::NonFinite { .. })
    ));
    assert!(matches!(
        b().constant_acceleration(1.0, [0.0, f64::NAN]).build(),
        Err(SimError::NonFinite { .. })
    ));
    assert!(matches!(
        b().set_velocity([f64::NAN, 0.0]).constant_velocity(1.0).build(),
        Err(SimError::NonFinite { .. })
    ));
    assert!(matches!(
        Trajectory::builder([0.0, 0.0], [f64::INFINITY, 0.0])
            .constant_velocity(1.0)
            .build(),
        Err(SimError::NonFinite { what: "start velocity" })
    ));
    assert!(matches!(b().build(), Err(SimError::EmptyInput { .. })));
    assert!(matches!(
        b().set_velocity([1.0, 1.0]).build(),
        Err(SimError::EmptyInput { .. })
    ));
    // the first error wins, later valid steps do not hide it
    assert!(invalid(
        b().constant_velocity(-1.0)
            .turn(1.0, f64::NAN)
            .constant_velocity(1.0)
            .build()
    ));

    let track = b().constant_velocity(10.0).build().unwrap();
    assert!(matches!(
        track.state_at(-0.1),
        Err(SimError::InvalidParameter { name: "time_s", .. })
    ));
    assert!(matches!(
        track.state_at(10.1),
        Err(SimError::InvalidParameter { name: "time_s", .. })
    ));
    assert!(matches!(track.state_at(f64::NAN), Err(SimError::NonFinite { .. })));
    assert!(matches!(
        track.sample(0.0),
        Err(SimError::InvalidParameter { name: "dt_s", .. })
    ));
    assert!(matches!(
        track.sample(-1.0),
        Err(SimError::InvalidParameter { name: "dt_s", .. })
    ));
    assert!(matches!(track.sample(f64::NAN), Err(SimError::NonFinite { .. })));
    assert!(matches!(
        track.sample(1e-12),
        Err(SimError::InvalidParameter { name: "dt_s", .. })
    ));
    assert!(matches!(
        track.mean_acceleration(5.0, 5.0),
        Err(SimError::InvalidParameter { name: "to_s", .. })
    ));
    assert!(matches!(
        track.mean_acceleration(6.0, 5.0),
        Err(SimError::InvalidParameter { name: "to_s", .. })
    ));
    assert!(matches!(
        track.mean_acceleration(0.0, 11.0),
        Err(SimError::InvalidParameter { .. })
    ));
}

#[test]
fn heading_is_undefined_at_rest() {
    let track = Trajectory::builder([0.0, 0.0], [0.0, -3.0])
        .constant_velocity(1.0)
        .stop(1.0)
        .build()
        .unwrap();
    assert_eq!(track.state_at(0.5).unwrap().heading_rad(), Some(-FRAC_PI_2));
    assert_eq!(track.state_at(1.5).unwrap().heading_rad(), None);
}

proptest! {
    #[test]
    fn turns_keep_speed_and_radius(
        vx in -30.0..30.0f64,
        vy in -30.0..30.0f64,
        rate in prop_oneof![-0.5..-1e-3f64, 1e-3..0.5f64],
        duration in 0.1..200.0f64,
    ) {
        let speed = vx.hypot(vy);
        prop_assume!(speed > 0.1);
        let track = Trajectory::builder([100.0, -50.0], [vx, vy]).turn(duration, rate).build().unwrap();
        // centre c = p₀ + (1/ω) [−vy, vx]
        let centre = [100.0 - vy / rate, -50.0 + vx / rate];
        let radius = speed / rate.abs();
        for t in [0.0, 0.3 * duration, duration] {
            let s = track.state_at(t).unwrap();
            prop_assert!(close(s.speed_mps(), speed, 1e-9 * speed));
            let r = norm([s.position_m[0] - centre[0], s.position_m[1] - centre[1]]);
            prop_assert!(close(r, radius, 1e-9 * radius.max(1.0)));
            // the velocity has rotated by ω t
            let turned = s.velocity_mps[1].atan2(s.velocity_mps[0]) - vy.atan2(vx);
            prop_assert!(close(rtls_estimation::wrap_angle(turned - rate * t), 0.0, 1e-9));
        }
    }

    #[test]
    fn constant_acceleration_steps_compose(
        a in prop::collection::vec((-1.0..1.0f64, -1.0..1.0f64), 1..20),
    ) {
        // p(k) = p(k−1) + v(k−1) Δt + a(k) Δt²/2 exactly, the paper's second-order model
        let mut builder = Trajectory::builder([0.0, 0.0], [0.0, 0.0]);
        for &(ax, ay) in &a {
            builder = builder.constant_acceleration(1.0, [ax, ay]);
        }
        let samples = builder.build().unwrap().sample(1.0).unwrap();
        prop_assert_eq!(samples.len(), a.len() + 1);
        for (k, &(ax, ay)) in a.iter().enumerate() {
            let (prev, next) = (samples[k], samples[k + 1]);
            prop_assert!(close(next.position_m[0], prev.position_m[0] + prev.velocity_mps[0] + ax / 2.0, 1e-12));
            prop_assert!(close(next.position_m[1], prev.position_m[1] + prev.velocity_mps[1] + ay / 2.0, 1e-12));
            prop_assert!(close(next.velocity_mps[0], prev.velocity_mps[0] + ax, 1e-12));
        }
    }
}
