//! Piecewise construction of a [`Trajectory`] from motion segments.

use super::segment::{Motion, Segment};
use super::Trajectory;
use crate::error::{finite, finite2, positive, Result, SimError};

/// Builds a [`Trajectory`] segment by segment, each integrated exactly in closed form.
///
/// Start with [`Trajectory::builder`], chain segments, finish with
/// [`TrajectoryBuilder::build`]. Segments are contiguous in time: each starts where the previous
/// one ended, at the position and velocity it ended with. The builder records the first bad
/// parameter and [`TrajectoryBuilder::build`] returns it, so chains need no `?` per step.
///
/// | method | motion on `[t₀, t₀ + T]` (`τ = t − t₀`) |
/// | --- | --- |
/// | [`constant_velocity`](Self::constant_velocity) | `p = p₀ + v₀ τ` |
/// | [`stop`](Self::stop) | `v = 0` from `t₀` on (instantly), `p = p₀` |
/// | [`set_velocity`](Self::set_velocity) | `v₀ ← v` instantly, no time passes |
/// | [`turn`](Self::turn) | `v = R(ωτ) v₀`, `p = p₀ + [[S, −C], [C, S]] v₀`, `S = sin ωτ/ω`, `C = (1 − cos ωτ)/ω` |
/// | [`constant_acceleration`](Self::constant_acceleration) | `v = v₀ + a τ`, `p = p₀ + v₀ τ + a τ²/2` |
///
/// # Units
/// Positions in m, velocities in m/s, accelerations in m/s², durations in s, turn rates in
/// rad/s (counter-clockwise, i.e. to the left, is positive).
///
/// # Errors
/// [`TrajectoryBuilder::build`] returns the first error any step met:
/// [`SimError::NonFinite`] for a NaN/∞ start state, velocity, rate or acceleration;
/// [`SimError::InvalidParameter`] (`duration_s`) for a duration that is not strictly positive;
/// [`SimError::EmptyInput`] when no segment that takes time was added.
///
/// # Example
/// ```
/// use rtls_sim::Trajectory;
/// let track = Trajectory::builder([0.0, 0.0], [2.0, 0.0])
///     .constant_velocity(10.0) // to (20, 0)
///     .stop(5.0)
///     .set_velocity([0.0, 1.0])
///     .constant_acceleration(4.0, [0.0, 0.5]) // 4 m + ½·0.5·16 m = 8 m along +y
///     .build()?;
/// let end = track.state_at(track.duration_s())?;
/// assert_eq!(track.duration_s(), 19.0);
/// assert!((end.position_m[0] - 20.0).abs() < 1e-12 && (end.position_m[1] - 8.0).abs() < 1e-12);
/// assert!((end.velocity_mps[1] - 3.0).abs() < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
/// Navigation*, Wiley 2001, §11.7 (coordinated turn); seed 004 §3 (the piecewise scenario).
#[derive(Debug, Clone)]
#[must_use = "a builder does nothing until `build` is called"]
pub struct TrajectoryBuilder {
    time_s: f64,
    position_m: [f64; 2],
    velocity_mps: [f64; 2],
    segments: Vec<Segment>,
    error: Option<SimError>,
}

impl TrajectoryBuilder {
    /// A builder at `t = 0` with the given start state (see [`Trajectory::builder`]).
    pub(super) fn new(start_position_m: [f64; 2], start_velocity_mps: [f64; 2]) -> Self {
        let error = finite2(start_position_m, "start position")
            .and_then(|_| finite2(start_velocity_mps, "start velocity"))
            .err();
        Self {
            time_s: 0.0,
            position_m: start_position_m,
            velocity_mps: start_velocity_mps,
            segments: Vec::new(),
            error,
        }
    }

    /// Moves on at the current velocity for `duration_s` seconds: `p(τ) = p₀ + v₀ τ`.
    ///
    /// # Errors
    /// Recorded for [`TrajectoryBuilder::build`]: [`SimError::InvalidParameter`] unless
    /// `duration_s` is finite and `> 0`.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([1.0, 2.0], [3.0, -1.0]).constant_velocity(2.0).build()?;
    /// assert_eq!(track.state_at(2.0)?.position_m, [7.0, 0.0]);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (0–400 s and 450–900 s legs).
    pub fn constant_velocity(self, duration_s: f64) -> Self {
        self.push(duration_s, Motion::ConstantVelocity)
    }

    /// Stops instantly and stays at the current position for `duration_s` seconds (`v = 0`);
    /// the following segment starts at rest, so restart with
    /// [`set_velocity`](Self::set_velocity) or [`constant_acceleration`](Self::constant_acceleration).
    ///
    /// # Errors
    /// As [`constant_velocity`](Self::constant_velocity).
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([5.0, 5.0], [1.0, 0.0]).stop(3.0).build()?;
    /// let s = track.state_at(3.0)?;
    /// assert_eq!((s.position_m, s.velocity_mps), ([5.0, 5.0], [0.0, 0.0]));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (400–450 s, stopped).
    pub fn stop(mut self, duration_s: f64) -> Self {
        if self.error.is_none() {
            self.velocity_mps = [0.0, 0.0];
        }
        self.push(duration_s, Motion::Stopped)
    }

    /// Changes the velocity instantly to `velocity_mps = [vx, vy]` (m/s); no time passes.
    ///
    /// # Errors
    /// Recorded for [`TrajectoryBuilder::build`]: [`SimError::NonFinite`] for a NaN/∞ component.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// let track = Trajectory::builder([0.0, 0.0], [0.0, 0.0])
    ///     .set_velocity([0.0, 2.0])
    ///     .constant_velocity(1.0)
    ///     .build()?;
    /// assert_eq!(track.state_at(1.0)?.position_m, [0.0, 2.0]);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (the restart at 450 s).
    pub fn set_velocity(mut self, velocity_mps: [f64; 2]) -> Self {
        if self.error.is_none() {
            match finite2(velocity_mps, "velocity") {
                Ok(v) => self.velocity_mps = v,
                Err(e) => self.error = Some(e),
            }
        }
        self
    }

    /// A coordinated turn for `duration_s` seconds at constant speed and turn rate
    /// `turn_rate_rad_s` (`ω`, positive = left / counter-clockwise): an exact circular arc of
    /// radius `|v|/|ω|`.
    ///
    /// `v(τ) = R(ωτ) v₀`, `p(τ) = p₀ + [[S, −C], [C, S]] v₀` with `S = sin(ωτ)/ω`,
    /// `C = (1 − cos ωτ)/ω`; the acceleration is centripetal, `a = ω × v = ω [−v_y, v_x]`.
    /// `ω = 0` is a straight line.
    ///
    /// # Errors
    /// As [`constant_velocity`](Self::constant_velocity); [`SimError::NonFinite`] for a NaN/∞
    /// rate.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// // A quarter circle of radius 10 m: from heading +x to heading +y.
    /// let w = std::f64::consts::FRAC_PI_2 / 10.0;
    /// let track = Trajectory::builder([0.0, 0.0], [10.0 * w, 0.0]).turn(10.0, w).build()?;
    /// let end = track.state_at(10.0)?;
    /// assert!((end.position_m[0] - 10.0).abs() < 1e-12 && (end.position_m[1] - 10.0).abs() < 1e-12);
    /// assert!(end.velocity_mps[0].abs() < 1e-12);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Bar-Shalom, Li, Kirubarajan (2001) §11.7.2; seed 004 §3 (900–1000 s turn); seed 001
    /// scenario 2.
    pub fn turn(self, duration_s: f64, turn_rate_rad_s: f64) -> Self {
        match finite(turn_rate_rad_s, "turn rate") {
            Ok(w) => self.push(duration_s, Motion::Turn { rate_rad_s: w }),
            Err(e) => self.fail(e),
        }
    }

    /// Constant acceleration `acceleration_mps2 = [ax, ay]` for `duration_s` seconds:
    /// `v(τ) = v₀ + a τ`, `p(τ) = p₀ + v₀ τ + a τ²/2`.
    ///
    /// Repeating it with one value per 1 s step builds a piecewise-constant acceleration
    /// profile (seed 002).
    ///
    /// # Errors
    /// As [`constant_velocity`](Self::constant_velocity); [`SimError::NonFinite`] for a NaN/∞
    /// component.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::Trajectory;
    /// // Brake from 10 m/s to rest in 5 s: 25 m.
    /// let track = Trajectory::builder([0.0, 0.0], [10.0, 0.0])
    ///     .constant_acceleration(5.0, [-2.0, 0.0])
    ///     .build()?;
    /// let end = track.state_at(5.0)?;
    /// assert_eq!((end.position_m[0], end.velocity_mps[0]), (25.0, 0.0));
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    ///
    /// # References
    /// Seed 004 §3 (1000–1500 s deceleration); seed 002 §1.2 (acceleration constant over each
    /// sampling interval).
    pub fn constant_acceleration(self, duration_s: f64, acceleration_mps2: [f64; 2]) -> Self {
        match finite2(acceleration_mps2, "acceleration") {
            Ok(a) => self.push(duration_s, Motion::ConstantAcceleration { acceleration_mps2: a }),
            Err(e) => self.fail(e),
        }
    }

    /// Finishes the trajectory.
    ///
    /// # Errors
    /// The first error recorded by any step (see [`TrajectoryBuilder`]); [`SimError::EmptyInput`]
    /// if no segment that takes time was added.
    ///
    /// # Example
    /// ```
    /// use rtls_sim::{SimError, Trajectory};
    /// assert!(matches!(
    ///     Trajectory::builder([0.0, 0.0], [1.0, 0.0]).build(),
    ///     Err(SimError::EmptyInput { .. })
    /// ));
    /// assert!(matches!(
    ///     Trajectory::builder([f64::NAN, 0.0], [1.0, 0.0]).constant_velocity(1.0).build(),
    ///     Err(SimError::NonFinite { .. })
    /// ));
    /// ```
    ///
    /// # References
    /// STYLE.md, "Errors": bad parameters are errors, never panics.
    pub fn build(self) -> Result<Trajectory> {
        if let Some(error) = self.error {
            return Err(error);
        }
        if self.segments.is_empty() {
            return Err(SimError::EmptyInput {
                what: "trajectory segments",
            });
        }
        Ok(Trajectory {
            segments: self.segments,
        })
    }

    /// Appends a segment that starts at the builder's current time and state.
    fn push(mut self, duration_s: f64, motion: Motion) -> Self {
        if self.error.is_some() {
            return self;
        }
        if let Err(e) = positive(duration_s, "duration_s", "a segment duration must be finite and > 0 s") {
            return self.fail(e);
        }
        let segment = Segment {
            start_s: self.time_s,
            duration_s,
            start_position_m: self.position_m,
            start_velocity_mps: self.velocity_mps,
            motion,
        };
        let end = segment.end_state();
        self.time_s = segment.end_s();
        self.position_m = end.position_m;
        self.velocity_mps = end.velocity_mps;
        self.segments.push(segment);
        self
    }

    /// Records `error` unless an earlier one is already recorded.
    fn fail(mut self, error: SimError) -> Self {
        if self.error.is_none() {
            self.error = Some(error);
        }
        self
    }
}
