//! Planar truth trajectories, integrated exactly in closed form.
//!
//! A [`Trajectory`] is a chain of segments (constant velocity, stop, coordinated turn, constant
//! acceleration) built with [`Trajectory::builder`]; it is evaluated at any time with
//! [`Trajectory::state_at`] and sampled on a grid with [`Trajectory::sample`]. No Euler steps:
//! every position is the closed-form solution of its segment's motion law.

mod builder;
mod segment;
#[cfg(test)]
mod tests;
mod waypoints;

pub use builder::TrajectoryBuilder;
pub use waypoints::{PathSample, Waypoint, WaypointPath};

use crate::error::{finite, positive, Result, SimError};
use segment::{Kinematics, Segment};

/// Speed (m/s) at or below which a target counts as standing still and its heading is
/// undefined ([`TruthSample::heading_rad`] returns `None`).
///
/// The same threshold as `rtls_estimation::measurement::SpeedHeading`, which refuses to
/// linearise the heading below it.
///
/// # Example
/// ```
/// assert_eq!(rtls_sim::MIN_MOVING_SPEED_MPS, 1e-9);
/// ```
///
/// # References
/// Seed 004 §3 (400–450 s: the vehicle stands still and has no direction of motion).
pub const MIN_MOVING_SPEED_MPS: f64 = 1.0e-9;

/// Most samples [`Trajectory::sample`] will produce (guards against a tiny `dt_s`).
const MAX_SAMPLES: f64 = 1.0e8;

/// Relative slack when deciding whether the end time lies on the sampling grid.
const GRID_SLACK: f64 = 1.0e-9;

/// The true planar state of a target at one instant.
///
/// # Units
/// `time_s` in s, `position_m` in m, `velocity_mps` in m/s, `acceleration_mps2` in m/s²; all
/// `[x, y]`.
///
/// # Example
/// ```
/// use rtls_sim::Trajectory;
/// let s = Trajectory::builder([0.0, 0.0], [3.0, 4.0]).constant_velocity(1.0).build()?.state_at(0.5)?;
/// assert_eq!(s.position_m, [1.5, 2.0]);
/// assert_eq!(s.speed_mps(), 5.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3 and seed 002 §2 (the truth that the experiments measure).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Time since the trajectory started, s.
    pub time_s: f64,
    /// Position `[x, y]`, m.
    pub position_m: [f64; 2],
    /// Velocity `[vx, vy]`, m/s.
    pub velocity_mps: [f64; 2],
    /// Instantaneous acceleration `[ax, ay]`, m/s² (centripetal `ω × v` in a turn).
    pub acceleration_mps2: [f64; 2],
}

impl TruthSample {
    /// Speed `s = √(vx² + vy²)` in m/s.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::TruthSample;
    /// let s = TruthSample { time_s: 0.0, position_m: [0.0; 2], velocity_mps: [-6.0, 8.0], acceleration_mps2: [0.0; 2] };
    /// assert_eq!(s.speed_mps(), 10.0);
    /// ```
    ///
    /// # References
    /// Seed 004 §1 (speed observed by the odometer).
    #[must_use]
    pub fn speed_mps(&self) -> f64 {
        // s = √(vx² + vy²)
        self.velocity_mps[0].hypot(self.velocity_mps[1])
    }

    /// Heading `ψ = atan2(vy, vx)` in rad (from +x, counter-clockwise), or `None` at rest
    /// (speed `≤ 1e-9` m/s), where the heading is undefined.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::TruthSample;
    /// let mut s = TruthSample { time_s: 0.0, position_m: [0.0; 2], velocity_mps: [0.0, 2.0], acceleration_mps2: [0.0; 2] };
    /// assert_eq!(s.heading_rad(), Some(std::f64::consts::FRAC_PI_2));
    /// s.velocity_mps = [0.0, 0.0];
    /// assert_eq!(s.heading_rad(), None);
    /// ```
    ///
    /// # References
    /// Seed 004 §1 (direction of motion from the local sensors); same convention as
    /// `rtls_estimation::measurement::SpeedHeading`.
    #[must_use]
    pub fn heading_rad(&self) -> Option<f64> {
        if self.speed_mps() <= MIN_MOVING_SPEED_MPS {
            None
        } else {
            // ψ = atan2(vy, vx)
            Some(self.velocity_mps[1].atan2(self.velocity_mps[0]))
        }
    }
}

/// A planar truth trajectory starting at `t = 0`: contiguous segments, each with an exact
/// closed-form motion law (see [`TrajectoryBuilder`]).
///
/// At a segment boundary the state is that of the segment that *starts* there (right
/// continuity: at the instant of a [`stop`](TrajectoryBuilder::stop) the velocity is already 0);
/// at the very end it is the last segment's end state.
///
/// # Units
/// Times in s, positions in m, velocities in m/s, accelerations in m/s².
///
/// # Example
/// ```
/// use rtls_sim::Trajectory;
/// let track = Trajectory::builder([0.0, 0.0], [1.0, 0.0]).constant_velocity(3.0).build()?;
/// let samples = track.sample(1.0)?;
/// assert_eq!(samples.len(), 4); // t = 0, 1, 2, 3
/// assert_eq!(samples[3].position_m, [3.0, 0.0]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 004 §3; seed 002 §2.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    segments: Vec<Segment>,
}

impl Trajectory {
    /// Starts building a trajectory at `t = 0` from `start_position_m` (m) moving at
    /// `start_velocity_mps` (m/s).
    ///
    /// # Errors
    /// None here; a NaN/∞ start state is reported by [`TrajectoryBuilder::build`] as
    /// [`SimError::NonFinite`].
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([-1000.0, 2000.0], [0.0, -10.0]).constant_velocity(400.0).build()?;
    /// assert_eq!(track.state_at(400.0)?.position_m, [-1000.0, -2000.0]);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3.
    pub fn builder(start_position_m: [f64; 2], start_velocity_mps: [f64; 2]) -> TrajectoryBuilder {
        TrajectoryBuilder::new(start_position_m, start_velocity_mps)
    }

    /// Total duration `T` in s (the trajectory spans `[0, T]`).
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([0.0, 0.0], [1.0, 0.0]).constant_velocity(2.0).stop(1.5).build()?;
    /// assert_eq!(track.duration_s(), 3.5);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (1500 s).
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.segments.last().map_or(0.0, Segment::end_s)
    }

    /// The exact true state at `time_s` (`0 ≤ t ≤ T`).
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for a NaN/∞ time; [`SimError::InvalidParameter`] (`time_s`)
    /// outside `[0, T]`.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([0.0, 0.0], [0.0, 0.0]).constant_acceleration(4.0, [1.0, 0.0]).build()?;
    /// let s = track.state_at(2.0)?;
    /// assert_eq!((s.position_m[0], s.velocity_mps[0], s.acceleration_mps2[0]), (2.0, 2.0, 1.0));
    /// assert!(track.state_at(4.5).is_err());
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3; seed 002 §2.
    pub fn state_at(&self, time_s: f64) -> Result<TruthSample> {
        let t = self.check_time(time_s)?;
        let segment = self.segment_at(t);
        Ok(Self::to_sample(t, segment.state(t - segment.start_s)))
    }

    /// Samples the trajectory at `t = 0, dt, 2 dt, …` up to `T` inclusive (the end is included
    /// when `T` is a multiple of `dt` within a relative `1e-9`). Times are computed as `k · dt`,
    /// never accumulated, so they do not drift.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`dt_s`) unless `dt_s` is finite and `> 0`, or if it
    /// would produce more than 10⁸ samples.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([0.0, 0.0], [1.0, 1.0]).constant_velocity(1.0).build()?;
    /// let times: Vec<f64> = track.sample(0.25)?.iter().map(|s| s.time_s).collect();
    /// assert_eq!(times, [0.0, 0.25, 0.5, 0.75, 1.0]);
    /// assert_eq!(track.sample(0.3)?.len(), 4); // 0, 0.3, 0.6, 0.9
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (1 Hz); seed 002 §2 (1 s sampling).
    pub fn sample(&self, dt_s: f64) -> Result<Vec<TruthSample>> {
        let dt_s = positive(dt_s, "dt_s", "the sampling interval must be finite and > 0 s")?;
        let total_s = self.duration_s();
        // K = ⌊T/dt⌋ (with slack so that T on the grid is included)
        let steps = (total_s / dt_s * (1.0 + GRID_SLACK)).floor();
        if steps > MAX_SAMPLES {
            return Err(SimError::InvalidParameter {
                name: "dt_s",
                reason: "the sampling interval gives more than 1e8 samples: use a larger dt_s",
            });
        }
        let steps = steps as usize;
        let mut samples = Vec::with_capacity(steps + 1);
        let mut index = 0;
        for k in 0..=steps {
            // t_k = k dt (clamped to T against rounding)
            let t = (k as f64 * dt_s).min(total_s);
            while index + 1 < self.segments.len() && self.segments[index + 1].start_s <= t {
                index += 1;
            }
            let segment = &self.segments[index];
            samples.push(Self::to_sample(t, segment.state(t - segment.start_s)));
        }
        Ok(samples)
    }

    /// Mean acceleration over `[from_s, to_s]`: `ā = (1/(t₁ − t₀)) ∫ a(t) dt`, in m/s².
    ///
    /// This is what an ideal accelerometer integrating over one sampling interval reports. The
    /// integral runs over the segments' own accelerations; the instantaneous velocity jumps of
    /// [`stop`](TrajectoryBuilder::stop) and [`set_velocity`](TrajectoryBuilder::set_velocity)
    /// (idealised impulses) are not included. For a piecewise-constant profile built from 1 s
    /// [`constant_acceleration`](TrajectoryBuilder::constant_acceleration) steps,
    /// `mean_acceleration(k − 1, k)` is exactly the step's `a(k)`.
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for NaN/∞ times; [`SimError::InvalidParameter`] unless
    /// `0 ≤ from_s < to_s ≤ T`.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([0.0, 0.0], [0.0, 0.0])
    ///     .constant_acceleration(1.0, [0.2, 0.0])
    ///     .constant_acceleration(1.0, [0.0, 0.4])
    ///     .build()?;
    /// assert_eq!(track.mean_acceleration(1.0, 2.0)?, [0.0, 0.4]);
    /// let a = track.mean_acceleration(0.0, 2.0)?;
    /// assert!((a[0] - 0.1).abs() < 1e-15 && (a[1] - 0.2).abs() < 1e-15);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 002 §1.2: `a(k)` is the acceleration sampled at `k`, constant over `(k − 1, k]`.
    pub fn mean_acceleration(&self, from_s: f64, to_s: f64) -> Result<[f64; 2]> {
        let t0 = self.check_time(from_s)?;
        let t1 = self.check_time(to_s)?;
        if t1 <= t0 {
            return Err(SimError::InvalidParameter {
                name: "to_s",
                reason: "the interval must end after it starts",
            });
        }
        let mut delta_v = [0.0, 0.0];
        for segment in &self.segments {
            // overlap [a, b] of the segment with [t₀, t₁]
            let a = t0.max(segment.start_s);
            let b = t1.min(segment.end_s());
            if b > a {
                // ∫ₐᵇ a(t) dt = v(b) − v(a) within the segment (velocity is continuous there)
                let va = segment.state(a - segment.start_s).velocity_mps;
                let vb = segment.state(b - segment.start_s).velocity_mps;
                delta_v = [delta_v[0] + vb[0] - va[0], delta_v[1] + vb[1] - va[1]];
            }
        }
        // ā = Δv / (t₁ − t₀)
        let dt = t1 - t0;
        Ok([delta_v[0] / dt, delta_v[1] / dt])
    }

    /// Checks `0 ≤ t ≤ T`.
    fn check_time(&self, time_s: f64) -> Result<f64> {
        let t = finite(time_s, "time")?;
        if t < 0.0 || t > self.duration_s() {
            return Err(SimError::InvalidParameter {
                name: "time_s",
                reason: "the time lies outside the trajectory: pass 0 ≤ t ≤ duration_s()",
            });
        }
        Ok(t)
    }

    /// The segment whose interval `[start, end)` holds `t` (the last one for `t = T`).
    fn segment_at(&self, t: f64) -> &Segment {
        // index of the last segment starting at or before t (segments are sorted by start)
        let after = self.segments.partition_point(|s| s.start_s <= t);
        let index = after.saturating_sub(1).min(self.segments.len() - 1);
        &self.segments[index]
    }

    /// Wraps segment kinematics as a [`TruthSample`].
    fn to_sample(time_s: f64, k: Kinematics) -> TruthSample {
        TruthSample {
            time_s,
            position_m: k.position_m,
            velocity_mps: k.velocity_mps,
            acceleration_mps2: k.acceleration_mps2,
        }
    }
}
