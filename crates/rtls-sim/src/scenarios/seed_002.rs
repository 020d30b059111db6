//! Seed 002: fingerprint (L-WKNN) fixes fused with an accelerometer in a 100 m × 100 m area.
//!
//! The paper shows its trajectory only as figures (Fig. 1, 2, 5), so the profile below is our
//! design; the anchor layout is "25 anchors uniformly" without coordinates, so the grid is ours
//! too. Both choices are documented on each item.

use core::f64::consts::{PI, TAU};

use crate::error::Result;
use crate::trajectory::{Trajectory, TrajectoryBuilder};

/// Side of the seed 002 monitoring area, m (the area is `[0, 100]²`).
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_002_AREA_SIDE_M, 100.0);
/// ```
///
/// # References
/// Seed 002 §2: "100 m × 100 m 的二维监控区域".
pub const SEED_002_AREA_SIDE_M: f64 = 100.0;

/// Start position of the seed 002 node, m (at rest, `v(0) = 0`).
///
/// Our choice: the lower-middle of the area, so that the profile's S-shaped path stays inside
/// `[28, 89] × [25, 88]` m.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_002_START_M, [35.0, 25.0]);
/// ```
///
/// # References
/// Seed 002 §1.2 (`v(0) = 0`); start point not stated: our choice.
pub const SEED_002_START_M: [f64; 2] = [35.0, 25.0];

/// Number of 1 s samples of [`seed_002_trajectory`] (`t = 0, 1, …, 99` s).
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_002_SAMPLES, 100);
/// ```
///
/// # References
/// Seed 002 §2, Fig. 1: "采样间隔为 1 s, 共采集 100 个点".
pub const SEED_002_SAMPLES: usize = 100;

/// Number of 1 s samples of [`seed_002_manoeuvre_then_cruise`] (`t = 0, 1, …, 79` s).
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_002_MANOEUVRE_SAMPLES, 80);
/// ```
///
/// # References
/// Seed 002 §2, Fig. 5/6: "共采集了 80 个采样点".
pub const SEED_002_MANOEUVRE_SAMPLES: usize = 80;

/// Length of the varying-acceleration part of [`seed_002_manoeuvre_then_cruise`], s: the
/// intervals `(k − 1, k]` for `k = 1…55` accelerate, from `k = 56` on the velocity is constant.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::SEED_002_MANOEUVRE_END_S, 55.0);
/// ```
///
/// # References
/// Seed 002 §2: "前 55 s 内 … 具有变化的加速度, 从第 56 s 开始, 节点保持匀速运动".
pub const SEED_002_MANOEUVRE_END_S: f64 = 55.0;

/// The 25 anchors of seed 002, m: a uniform 5 × 5 grid at 10, 30, 50, 70, 90 m on both axes,
/// in row-major order (x fastest).
///
/// The paper says "25 anchors uniformly" without coordinates. A grid with 20 m pitch, offset
/// by half a pitch from the walls, is the uniform layout; it puts every anchor on a reference
/// point of the 10 m fingerprint grid, which is why [`LogDistanceRadio`](crate::LogDistanceRadio)
/// clamps the distance.
///
/// # Example
/// ```
/// use rtls_sim::SEED_002_ANCHORS;
/// assert_eq!(SEED_002_ANCHORS.len(), 25);
/// assert_eq!((SEED_002_ANCHORS[0], SEED_002_ANCHORS[6], SEED_002_ANCHORS[24]), ([10.0, 10.0], [30.0, 30.0], [90.0, 90.0]));
/// ```
///
/// # References
/// Seed 002 §2: "均匀布置了 25 个锚节点" (coordinates not stated: our choice).
pub const SEED_002_ANCHORS: [[f64; 2]; 25] = anchor_grid();

/// Builds the 5 × 5 anchor grid at compile time.
const fn anchor_grid() -> [[f64; 2]; 25] {
    const COORDS_M: [f64; 5] = [10.0, 30.0, 50.0, 70.0, 90.0];
    let mut anchors = [[0.0; 2]; 25];
    let mut i = 0;
    while i < 25 {
        anchors[i] = [COORDS_M[i % 5], COORDS_M[i / 5]];
        i += 1;
    }
    anchors
}

/// The 121 reference points of seed 002, m: the 10 m grid `{0, 10, …, 100}²`, row-major (x
/// fastest).
///
/// # Example
/// ```
/// let rps = rtls_sim::seed_002_reference_points();
/// assert_eq!(rps.len(), 121);
/// assert_eq!((rps[0], rps[11], rps[120]), ([0.0, 0.0], [0.0, 10.0], [100.0, 100.0]));
/// ```
///
/// # References
/// Seed 002 §2: "121 个参考位置点", fingerprint spacing 10 m.
#[must_use]
pub fn seed_002_reference_points() -> Vec<[f64; 2]> {
    (0..11)
        .flat_map(|row| (0..11).map(move |col| [10.0 * f64::from(col), 10.0 * f64::from(row)]))
        .collect()
}

/// The continuous acceleration profile `f(t)` of the seed 002 node, m/s².
///
/// ```text
/// f_x(t) = 0.07 cos(2π t/25 + 3π/4) + 0.13 cos(2π t/50 + 5π/4)
/// f_y(t) = 0.10 sin(2π t/40)
/// ```
/// The node applies the piecewise-constant `a(k) = f(k − ½)` on each interval `(k − 1, k]`
/// (see [`seed_002_step_acceleration`]). The paper shows its profile only as Fig. 2; ours is a
/// smooth sum of sines with the properties the paper's figures show and the area demands:
/// `|a| ≤ 0.22` m/s², speed 0.5–1.8 m/s after the first 10 s, an S-shaped path inside
/// `[28, 89] × [25, 88]` m, and a cruise after 55 s that also stays inside.
///
/// # Example
/// ```
/// let a = rtls_sim::seed_002_acceleration_profile(10.0);
/// assert!((a[1] - 0.10).abs() < 1e-15); // sin(π/2)
/// ```
///
/// # References
/// Seed 002 §2, Fig. 2 (shape only; amplitudes and periods are our design).
#[must_use]
pub fn seed_002_acceleration_profile(time_s: f64) -> [f64; 2] {
    let t = time_s;
    [
        // f_x = 0.07 cos(2πt/25 + 3π/4) + 0.13 cos(2πt/50 + 5π/4)
        0.07 * (TAU * t / 25.0 + 0.75 * PI).cos() + 0.13 * (TAU * t / 50.0 + 1.25 * PI).cos(),
        // f_y = 0.10 sin(2πt/40)
        0.10 * (TAU * t / 40.0).sin(),
    ]
}

/// The acceleration `a(k) = f(k − ½)` (m/s²) the node holds constant over `(k − 1, k]` s,
/// `k = 1, 2, …`.
///
/// Holding it constant over each 1 s interval makes an accelerometer sample taken at `k`
/// exactly the acceleration over `(k − 1, k]`, which is the assumption of both of the paper's
/// models (first order: `v(k) = v(k−1) + a(k)Δt`; second order: `B(k) = v(k−1)Δt + a(k)Δt²/2`),
/// so the two are compared on truth that neither approximates.
///
/// # Example
/// ```
/// use rtls_sim::{seed_002_acceleration_profile, seed_002_step_acceleration};
/// assert_eq!(seed_002_step_acceleration(3), seed_002_acceleration_profile(2.5));
/// ```
///
/// # References
/// Seed 002 §1.2, eqs. (6) and (10).
#[must_use]
pub fn seed_002_step_acceleration(k: usize) -> [f64; 2] {
    // a(k) = f(k − ½)
    seed_002_acceleration_profile(k as f64 - 0.5)
}

/// The seed 002 trajectory of Fig. 1: from rest at [`SEED_002_START_M`], 99 one-second
/// constant-acceleration steps `a(1) … a(99)` ([`seed_002_step_acceleration`]); sample it at
/// 1 s for the paper's 100 points (`t = 0 … 99` s).
///
/// # Errors
/// None in practice (the constants are valid); the builder's [`SimError`](crate::SimError) is
/// passed on.
///
/// # Example
/// ```
/// let samples = rtls_sim::seed_002_trajectory()?.sample(1.0)?;
/// assert_eq!(samples.len(), rtls_sim::SEED_002_SAMPLES);
/// assert_eq!(samples[0].velocity_mps, [0.0, 0.0]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2, Fig. 1 and 2 (trajectory design ours).
pub fn seed_002_trajectory() -> Result<Trajectory> {
    accelerate(SEED_002_SAMPLES - 1).build()
}

/// The seed 002 trajectory of Fig. 5/6: the same steps `a(1) … a(55)` as
/// [`seed_002_trajectory`], then constant velocity from 55 s to 79 s; sample it at 1 s for the
/// paper's 80 points.
///
/// # Errors
/// As [`seed_002_trajectory`].
///
/// # Example
/// ```
/// let track = rtls_sim::seed_002_manoeuvre_then_cruise()?;
/// assert_eq!(track.sample(1.0)?.len(), rtls_sim::SEED_002_MANOEUVRE_SAMPLES);
/// assert_eq!(track.mean_acceleration(60.0, 61.0)?, [0.0, 0.0]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 002 §2 (80 samples; varying acceleration for 55 s, then constant velocity).
pub fn seed_002_manoeuvre_then_cruise() -> Result<Trajectory> {
    let manoeuvre_steps = SEED_002_MANOEUVRE_END_S as usize;
    let cruise_s = (SEED_002_MANOEUVRE_SAMPLES - 1 - manoeuvre_steps) as f64;
    accelerate(manoeuvre_steps).constant_velocity(cruise_s).build()
}

/// A builder from rest at the start with steps `a(1) … a(steps)`.
fn accelerate(steps: usize) -> TrajectoryBuilder {
    (1..=steps).fold(Trajectory::builder(SEED_002_START_M, [0.0, 0.0]), |builder, k| {
        builder.constant_acceleration(1.0, seed_002_step_acceleration(k))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inside(p: [f64; 2]) -> bool {
        (5.0..=95.0).contains(&p[0]) && (5.0..=95.0).contains(&p[1])
    }

    #[test]
    fn trajectories_stay_inside_the_area_with_a_5_m_margin() {
        for track in [
            seed_002_trajectory().unwrap(),
            seed_002_manoeuvre_then_cruise().unwrap(),
        ] {
            // 0.05 s sampling catches excursions between the 1 s samples
            for s in track.sample(0.05).unwrap() {
                assert!(
                    inside(s.position_m),
                    "{:?} at {} s leaves [5, 95]²",
                    s.position_m,
                    s.time_s
                );
            }
        }
    }

    #[test]
    fn sample_counts_and_start_at_rest() {
        let full = seed_002_trajectory().unwrap().sample(1.0).unwrap();
        let cruise = seed_002_manoeuvre_then_cruise().unwrap().sample(1.0).unwrap();
        assert_eq!((full.len(), cruise.len()), (100, 80));
        assert_eq!((full[99].time_s, cruise[79].time_s), (99.0, 79.0));
        assert_eq!(full[0].position_m, SEED_002_START_M);
        assert_eq!(full[0].velocity_mps, [0.0, 0.0]);
    }

    #[test]
    fn profile_has_the_documented_magnitudes() {
        let samples = seed_002_trajectory().unwrap().sample(1.0).unwrap();
        for s in &samples[10..] {
            let v = s.speed_mps();
            assert!((0.5..=2.0).contains(&v), "speed {v} at {} s", s.time_s);
        }
        let peak = (1..100)
            .map(seed_002_step_acceleration)
            .map(|a| a[0].hypot(a[1]))
            .fold(0.0, f64::max);
        assert!((0.15..=0.3).contains(&peak), "peak acceleration {peak}");
    }

    #[test]
    fn accelerometer_interval_is_exactly_the_step_acceleration() {
        let track = seed_002_trajectory().unwrap();
        for k in 1..100 {
            let t = k as f64;
            let a = seed_002_step_acceleration(k);
            let mean = track.mean_acceleration(t - 1.0, t).unwrap();
            assert!(
                (mean[0] - a[0]).abs() < 1e-15 && (mean[1] - a[1]).abs() < 1e-15,
                "k = {k}"
            );
            assert_eq!(track.state_at(t - 0.5).unwrap().acceleration_mps2, a);
        }
    }

    #[test]
    fn manoeuvre_then_cruise_shares_the_first_55_s_then_holds_velocity() {
        let full = seed_002_trajectory().unwrap().sample(1.0).unwrap();
        let cruise = seed_002_manoeuvre_then_cruise().unwrap().sample(1.0).unwrap();
        for k in 0..=55 {
            assert_eq!(full[k].position_m, cruise[k].position_m, "k = {k}");
        }
        let v55 = cruise[55].velocity_mps;
        assert!(v55[0].hypot(v55[1]) > 0.5, "the cruise must move");
        for s in &cruise[56..] {
            assert_eq!(s.velocity_mps, v55);
            assert_eq!(s.acceleration_mps2, [0.0, 0.0]);
        }
        // and the full trajectory keeps accelerating after 55 s
        assert_ne!(full[60].velocity_mps, v55);
    }

    #[test]
    fn layout_is_the_documented_grid() {
        let rps = seed_002_reference_points();
        assert_eq!(rps.len(), 121);
        assert!(rps
            .iter()
            .all(|p| p[0] % 10.0 == 0.0 && p[1] % 10.0 == 0.0 && (0.0..=100.0).contains(&p[0])));
        assert_eq!(SEED_002_ANCHORS.len(), 25);
        for (i, a) in SEED_002_ANCHORS.iter().enumerate() {
            assert_eq!(*a, [10.0 + 20.0 * (i % 5) as f64, 10.0 + 20.0 * (i / 5) as f64]);
            assert!(rps.contains(a), "every anchor sits on a reference point");
        }
    }
}
