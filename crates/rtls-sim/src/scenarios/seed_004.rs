//! Seed 004: a vehicle tracked by cellular TDOA and on-board odometry.
//!
//! The paper fixes the start point, the phase times and the sensor errors, but not the speed,
//! the turn or the base-station layout; the choices made here are documented on each item.

use core::f64::consts::FRAC_PI_2;

use crate::error::{positive, Result};
use crate::trajectory::Trajectory;

/// Cruise speed of the seed 004 vehicle, m/s (36 km/h).
///
/// The paper gives no speed. 10 m/s is a vehicle in town (the paper's "special vehicles,
/// robots"), slow enough that the 100 ns TDOA error (≈ 30 m) dominates a 1 s step's 10 m of
/// motion, which is the regime where fusing odometry pays off.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_004_SPEED_MPS * 3.6, 36.0);
/// ```
///
/// # References
/// Seed 004 §3 (speed not stated: our choice).
pub const SEED_004_SPEED_MPS: f64 = 10.0;

/// Start position of the seed 004 vehicle, m.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_004_START_M, [-1000.0, 2000.0]);
/// ```
///
/// # References
/// Seed 004 §3: "起始位置为 (−1000, 2000)".
pub const SEED_004_START_M: [f64; 2] = [-1000.0, 2000.0];

/// Duration of the seed 004 scenario, s.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_004_DURATION_S, 1500.0);
/// ```
///
/// # References
/// Seed 004 §3 (0–1500 s).
pub const SEED_004_DURATION_S: f64 = 1500.0;

/// Turn rate of the 900–1000 s turn: a 90° left turn in 100 s, `ω = (π/2)/100` rad/s.
///
/// The paper says only "转弯" (turn). We turn left by 90°, from heading +x to heading +y, at
/// constant speed, so the track bends back inside the station rectangle; with 10 m/s the
/// radius is `v/ω = 2000/π ≈ 636.6` m.
///
/// # Example
/// ```
/// let quarter = rtls_sim::SEED_004_TURN_RATE_RAD_S * 100.0;
/// assert!((quarter - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// ```
///
/// # References
/// Seed 004 §3 (turn direction and angle not stated: our choice).
pub const SEED_004_TURN_RATE_RAD_S: f64 = FRAC_PI_2 / 100.0;

/// The four base stations of seed 004, m: a 9 km × 8 km rectangle around the track.
///
/// The paper says "four observation base stations" and gives no layout. The corners
/// (−3000, −4000), (6000, −4000), (6000, 4000), (−3000, 4000) enclose the whole track (it spans
/// x ∈ [−1000, 4137], y ∈ [−2000, 2000] at the default speed), so Chan's estimator works inside
/// the hull where TDOA geometry is good; a cell radius of a few km is that of an urban macro
/// cell.
///
/// # Example
/// ```
/// let [sw, se, ne, nw] = rtls_sim::SEED_004_STATIONS;
/// assert_eq!((se[0] - sw[0], ne[1] - se[1]), (9000.0, 8000.0));
/// assert_eq!((nw[0], nw[1]), (-3000.0, 4000.0));
/// ```
///
/// # References
/// Seed 004 §3 (layout not stated: our choice); Chan & Ho, *IEEE Trans. SP* 42(8), 1994.
pub const SEED_004_STATIONS: [[f64; 2]; 4] = [
    [-3000.0, -4000.0],
    [6000.0, -4000.0],
    [6000.0, 4000.0],
    [-3000.0, 4000.0],
];

/// The kind of motion in one phase of the seed 004 scenario.
///
/// # Example
/// ```
/// use rtls_sim::{seed_004_phase_at, MotionPhase};
/// assert_eq!(seed_004_phase_at(950.0), Some(MotionPhase::Turn));
/// ```
///
/// # References
/// Seed 004 §3; the variable-dimension filter should be in its CV mode in the
/// [`ConstantVelocity`](MotionPhase::ConstantVelocity) and [`Stopped`](MotionPhase::Stopped)
/// phases and may switch to CA in the others.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotionPhase {
    /// Straight at constant speed.
    ConstantVelocity,
    /// Standing still.
    Stopped,
    /// Coordinated turn at constant speed.
    Turn,
    /// Straight with constant deceleration.
    Decelerating,
}

/// The phases of the seed 004 scenario as `(start_s, end_s, phase)`, in time order.
///
/// | s | phase |
/// | --- | --- |
/// | 0–400 | constant velocity along −y |
/// | 400–450 | stopped |
/// | 450–900 | constant velocity along +x |
/// | 900–1000 | 90° left turn |
/// | 1000–1500 | constant deceleration to rest |
///
/// # Example
/// ```
/// use rtls_sim::{seed_004_phases, MotionPhase};
/// let phases = seed_004_phases();
/// assert_eq!(phases[1], (400.0, 450.0, MotionPhase::Stopped));
/// assert_eq!(phases[4].1, 1500.0);
/// ```
///
/// # References
/// Seed 004 §3.
#[must_use]
pub fn seed_004_phases() -> [(f64, f64, MotionPhase); 5] {
    [
        (0.0, 400.0, MotionPhase::ConstantVelocity),
        (400.0, 450.0, MotionPhase::Stopped),
        (450.0, 900.0, MotionPhase::ConstantVelocity),
        (900.0, 1000.0, MotionPhase::Turn),
        (1000.0, SEED_004_DURATION_S, MotionPhase::Decelerating),
    ]
}

/// The seed 004 phase at `time_s`, or `None` outside `[0, 1500]` s (or for NaN).
///
/// Phases are half-open `[start, end)` (the one starting at a boundary wins, as in
/// [`Trajectory::state_at`]), except that 1500 s belongs to the last phase.
///
/// # Example
/// ```
/// use rtls_sim::{seed_004_phase_at, MotionPhase};
/// assert_eq!(seed_004_phase_at(400.0), Some(MotionPhase::Stopped));
/// assert_eq!(seed_004_phase_at(1500.0), Some(MotionPhase::Decelerating));
/// assert_eq!(seed_004_phase_at(1500.5), None);
/// ```
///
/// # References
/// Seed 004 §3.
#[must_use]
pub fn seed_004_phase_at(time_s: f64) -> Option<MotionPhase> {
    let phases = seed_004_phases();
    phases
        .iter()
        .find(|(start_s, end_s, _)| *start_s <= time_s && time_s < *end_s)
        .or_else(|| phases.last().filter(|(_, end_s, _)| time_s == *end_s))
        .map(|(_, _, phase)| *phase)
}

/// The seed 004 truth trajectory at cruise speed `speed_mps` (m/s; [`SEED_004_SPEED_MPS`] is
/// the documented default).
///
/// From [`SEED_004_START_M`]: 0–400 s along −y at `v`; 400–450 s stopped; 450–900 s along +x at
/// `v`; 900–1000 s a 90° left turn ([`SEED_004_TURN_RATE_RAD_S`], radius `R = v/ω`); 1000–1500 s
/// constant deceleration `d = v/500` along the heading (+y) to rest at exactly 1500 s, covering
/// `v²/(2d) = 250 v` m. At `v = 10` m/s the end point is
/// `(−1000 + 450 v + R, 2000 − 400 v + R + 250 v) ≈ (4136.6, 1136.6)` m.
///
/// # Errors
/// [`SimError::InvalidParameter`](crate::SimError::InvalidParameter) /
/// [`SimError::NonFinite`](crate::SimError::NonFinite) unless `speed_mps` is finite and `> 0`.
///
/// # Example
/// ```
/// use rtls_sim::{seed_004_trajectory, SEED_004_SPEED_MPS};
/// let track = seed_004_trajectory(SEED_004_SPEED_MPS)?;
/// assert_eq!(track.state_at(425.0)?.position_m, [-1000.0, -2000.0]); // stopped
/// let end = track.state_at(1500.0)?;
/// assert!(end.speed_mps() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3 (phase times and start point; speed and turn are our choices).
pub fn seed_004_trajectory(speed_mps: f64) -> Result<Trajectory> {
    let v = positive(speed_mps, "speed_mps", "the cruise speed must be finite and > 0 m/s")?;
    // d = v / 500 s: rest at exactly 1500 s
    let deceleration_mps2 = v / 500.0;
    // heading after the turn ψ = ω · 100 s = π/2 (unit vector [cos ψ, sin ψ] ≈ [0, 1])
    let (sin_psi, cos_psi) = (SEED_004_TURN_RATE_RAD_S * 100.0).sin_cos();
    Trajectory::builder(SEED_004_START_M, [0.0, -v])
        .constant_velocity(400.0)
        .stop(50.0)
        .set_velocity([v, 0.0])
        .constant_velocity(450.0)
        .turn(100.0, SEED_004_TURN_RATE_RAD_S)
        // a = −d [cos ψ, sin ψ]: deceleration along the heading
        .constant_acceleration(500.0, [-deceleration_mps2 * cos_psi, -deceleration_mps2 * sin_psi])
        .build()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SimError;
    use core::f64::consts::PI;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    fn assert_close2(found: [f64; 2], expected: [f64; 2], tol: f64, what: &str) {
        assert!(
            close(found[0], expected[0], tol) && close(found[1], expected[1], tol),
            "{what}: found {found:?}, expected {expected:?}"
        );
    }

    #[test]
    fn waypoints_match_hand_computation() {
        let track = seed_004_trajectory(10.0).unwrap();
        // R = v/ω = 10 / (π/200) = 2000/π ≈ 636.62 m
        let r = 2000.0 / PI;
        assert_eq!(track.duration_s(), 1500.0);
        let at = |t: f64| track.state_at(t).unwrap();
        assert_close2(at(0.0).position_m, [-1000.0, 2000.0], 0.0, "start");
        assert_close2(at(0.0).velocity_mps, [0.0, -10.0], 0.0, "start velocity");
        // 400 s along −y at 10 m/s: y = 2000 − 4000
        assert_close2(at(400.0).position_m, [-1000.0, -2000.0], 1e-9, "stop point");
        assert_close2(at(449.0).velocity_mps, [0.0, 0.0], 0.0, "stopped");
        assert_close2(at(450.0).velocity_mps, [10.0, 0.0], 0.0, "restart");
        // 450 s along +x: x = −1000 + 4500
        assert_close2(at(900.0).position_m, [3500.0, -2000.0], 1e-9, "turn entry");
        // quarter circle to the left: (+R, +R)
        assert_close2(at(1000.0).position_m, [3500.0 + r, -2000.0 + r], 1e-9, "turn exit");
        assert_close2(at(1000.0).velocity_mps, [0.0, 10.0], 1e-12, "turn exit velocity");
        // halfway through the turn: 45° around the centre (3500, −2000 + R)
        let h = r * (PI / 4.0).sin();
        assert_close2(
            at(950.0).position_m,
            [3500.0 + h, -2000.0 + r - r * (PI / 4.0).cos()],
            1e-9,
            "mid turn",
        );
        // deceleration d = 10/500 = 0.02 m/s²: v(1250) = 5, distance v²/(2d) = 2500 m
        assert_close2(at(1250.0).velocity_mps, [0.0, 5.0], 1e-12, "mid deceleration");
        assert_close2(at(1250.0).acceleration_mps2, [0.0, -0.02], 1e-15, "deceleration");
        assert_close2(at(1500.0).position_m, [3500.0 + r, -2000.0 + r + 2500.0], 1e-9, "end");
        assert!(at(1500.0).speed_mps() < 1e-12, "must be at rest at 1500 s");
    }

    #[test]
    fn deceleration_ends_at_rest_after_v_squared_over_two_a() {
        for v in [5.0, 10.0, 20.0] {
            let track = seed_004_trajectory(v).unwrap();
            let start = track.state_at(1000.0).unwrap();
            let end = track.state_at(1500.0).unwrap();
            let a = v / 500.0;
            let distance = (end.position_m[1] - start.position_m[1]).hypot(end.position_m[0] - start.position_m[0]);
            assert!(close(distance, v * v / (2.0 * a), 1e-9), "v = {v}: distance {distance}");
            assert!(end.speed_mps() < 1e-12, "v = {v}: end speed {}", end.speed_mps());
            // still moving a second before the end: it stops at exactly 1500 s, not earlier
            assert!(close(track.state_at(1499.0).unwrap().speed_mps(), a, 1e-12));
        }
    }

    #[test]
    fn phases_describe_the_truth() {
        let (v, w) = (SEED_004_SPEED_MPS, SEED_004_TURN_RATE_RAD_S);
        let track = seed_004_trajectory(v).unwrap();
        let phases = seed_004_phases();
        for pair in phases.windows(2) {
            assert_eq!(pair[0].1, pair[1].0, "phases must be contiguous");
        }
        assert_eq!((phases[0].0, phases[4].1), (0.0, SEED_004_DURATION_S));
        for s in track.sample(1.0).unwrap() {
            let phase = seed_004_phase_at(s.time_s).unwrap();
            let a = s.acceleration_mps2[0].hypot(s.acceleration_mps2[1]);
            let ok = match phase {
                MotionPhase::ConstantVelocity => close(s.speed_mps(), v, 1e-12) && a == 0.0,
                MotionPhase::Stopped => s.speed_mps() == 0.0,
                MotionPhase::Turn => close(s.speed_mps(), v, 1e-9) && close(a, v * w, 1e-12),
                MotionPhase::Decelerating => close(a, v / 500.0, 1e-15),
            };
            assert!(ok, "truth at {} s does not match phase {phase:?}", s.time_s);
        }
        assert_eq!(seed_004_phase_at(-1.0), None);
        assert_eq!(seed_004_phase_at(f64::NAN), None);
    }

    #[test]
    fn every_truth_point_is_inside_the_station_hull() {
        // Stations are counter-clockwise: inside ⇔ every edge cross product is > 0.
        let s = SEED_004_STATIONS;
        for sample in seed_004_trajectory(SEED_004_SPEED_MPS).unwrap().sample(0.5).unwrap() {
            let p = sample.position_m;
            for i in 0..4 {
                let (a, b) = (s[i], s[(i + 1) % 4]);
                let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
                assert!(cross > 0.0, "{p:?} at {} s is outside edge {i}", sample.time_s);
            }
        }
    }

    #[test]
    fn bad_speed_is_an_error() {
        assert!(matches!(
            seed_004_trajectory(0.0),
            Err(SimError::InvalidParameter { name: "speed_mps", .. })
        ));
        assert!(matches!(
            seed_004_trajectory(-10.0),
            Err(SimError::InvalidParameter { .. })
        ));
        assert!(matches!(seed_004_trajectory(f64::NAN), Err(SimError::NonFinite { .. })));
    }
}
