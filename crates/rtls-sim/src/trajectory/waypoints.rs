//! Waypoint paths in 3-D: straight legs between surveyed points walked at a speed per leg, with
//! optional pauses — how people walk along mine tunnels (seed 000) and how robots follow
//! routes across a test bed (seed 003).

use serde::Deserialize;

use crate::error::{finite, positive, Result, SimError};

/// One waypoint: where to go, how fast to walk the leg that ends here, and how long to stand
/// there on arrival.
///
/// # Units
/// `position_m` in m (`[x, y, z]`), `speed_mps` in m/s, `pause_s` in s.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    /// Position `[x, y, z]`, m.
    pub position_m: [f64; 3],
    /// Speed along the leg that ends at this waypoint, m/s (ignored for the first waypoint).
    #[serde(default)]
    pub speed_mps: f64,
    /// Time standing at this waypoint after arriving, s.
    #[serde(default)]
    pub pause_s: f64,
}

/// The true 3-D state on a waypoint path at one instant.
///
/// # Units
/// s, m, m/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSample {
    /// Time since the start, s.
    pub time_s: f64,
    /// Position `[x, y, z]`, m.
    pub position_m: [f64; 3],
    /// Velocity `[vx, vy, vz]`, m/s (zero while pausing).
    pub velocity_mps: [f64; 3],
}

/// A path through waypoints at constant speed per leg (velocity jumps at the corners, as a
/// walker turning into a cross-cut).
///
/// # Example
/// ```
/// use rtls_sim::trajectory::{Waypoint, WaypointPath};
/// let path = WaypointPath::new(vec![
///     Waypoint { position_m: [0.0, 0.0, 0.0], speed_mps: 0.0, pause_s: 0.0 },
///     Waypoint { position_m: [3.0, 4.0, 0.0], speed_mps: 1.0, pause_s: 2.0 },
///     Waypoint { position_m: [3.0, 4.0, 1.0], speed_mps: 0.5, pause_s: 0.0 },
/// ])?;
/// assert_eq!(path.duration_s(), 5.0 + 2.0 + 2.0);
/// let s = path.state_at(2.5)?;
/// assert!((s.position_m[0] - 1.5).abs() < 1e-12 && (s.velocity_mps[1] - 0.8).abs() < 1e-12);
/// assert_eq!(path.state_at(6.0)?.velocity_mps, [0.0; 3]); // pausing
/// assert_eq!(path.sample(1.0)?.len(), 10);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 §5.1 (miners walk at 0.9–1.5 m/s in x and y, z follows the road); seed 003 §4
/// (robots at 0.5 m/s).
#[derive(Debug, Clone, PartialEq)]
pub struct WaypointPath {
    waypoints: Vec<Waypoint>,
    /// Start time of each leg's motion (s), one per leg.
    leg_start_s: Vec<f64>,
    /// Duration of each leg's motion (s).
    leg_duration_s: Vec<f64>,
    duration_s: f64,
}

impl WaypointPath {
    /// A path through `waypoints` (at least two).
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for fewer than two waypoints; [`SimError::NonFinite`] for NaN/∞;
    /// [`SimError::InvalidParameter`] (`speed_mps`) for a leg with a non-positive speed,
    /// (`pause_s`) for a negative pause.
    pub fn new(waypoints: Vec<Waypoint>) -> Result<Self> {
        if waypoints.len() < 2 {
            return Err(SimError::EmptyInput {
                what: "waypoint path legs (needs at least two waypoints)",
            });
        }
        let mut leg_start_s = Vec::with_capacity(waypoints.len() - 1);
        let mut leg_duration_s = Vec::with_capacity(waypoints.len() - 1);
        let mut time_s = 0.0;
        for w in &waypoints {
            for c in w.position_m {
                finite(c, "waypoint position")?;
            }
            finite(w.pause_s, "waypoint pause")?;
            if w.pause_s < 0.0 {
                return Err(SimError::InvalidParameter {
                    name: "pause_s",
                    reason: "a pause must not be negative",
                });
            }
        }
        time_s += waypoints[0].pause_s;
        for pair in waypoints.windows(2) {
            let speed = positive(pair[1].speed_mps, "speed_mps", "every leg needs a positive speed")?;
            let length = distance(pair[0].position_m, pair[1].position_m);
            leg_start_s.push(time_s);
            leg_duration_s.push(length / speed);
            time_s += length / speed + pair[1].pause_s;
        }
        Ok(Self {
            waypoints,
            leg_start_s,
            leg_duration_s,
            duration_s: time_s,
        })
    }

    /// Total time from the start to the end of the last pause, s.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// The waypoints.
    #[must_use]
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// The state at `time_s ∈ [0, duration]`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`time_s`) outside the path's time span;
    /// [`SimError::NonFinite`] for NaN.
    pub fn state_at(&self, time_s: f64) -> Result<PathSample> {
        finite(time_s, "time")?;
        if !(0.0..=self.duration_s * (1.0 + 1e-12) + 1e-12).contains(&time_s) {
            return Err(SimError::InvalidParameter {
                name: "time_s",
                reason: "the time is outside the waypoint path's duration",
            });
        }
        // the last leg that has started by time_s
        let leg = self
            .leg_start_s
            .partition_point(|&start| start <= time_s)
            .saturating_sub(1);
        let (from, to) = (self.waypoints[leg].position_m, self.waypoints[leg + 1].position_m);
        let duration = self.leg_duration_s[leg];
        let tau = time_s - self.leg_start_s[leg];
        if tau < 0.0 {
            // pausing at the first waypoint
            return Ok(PathSample {
                time_s,
                position_m: from,
                velocity_mps: [0.0; 3],
            });
        }
        if tau >= duration * (1.0 - 1e-12) {
            // pausing at the end of the leg
            return Ok(PathSample {
                time_s,
                position_m: to,
                velocity_mps: [0.0; 3],
            });
        }
        let mut position_m = [0.0; 3];
        let mut velocity_mps = [0.0; 3];
        for i in 0..3 {
            // v = (p₁ − p₀)/T, p = p₀ + v τ
            velocity_mps[i] = (to[i] - from[i]) / duration;
            position_m[i] = from[i] + velocity_mps[i] * tau;
        }
        Ok(PathSample {
            time_s,
            position_m,
            velocity_mps,
        })
    }

    /// States at `t = 0, dt, 2dt, …` up to the duration.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`dt_s`) for a non-positive step or one giving more than
    /// 10⁸ samples.
    pub fn sample(&self, dt_s: f64) -> Result<Vec<PathSample>> {
        positive(dt_s, "dt_s", "the sampling step must be positive")?;
        let count = (self.duration_s / dt_s * (1.0 + 1e-12)).floor();
        if count > 1.0e8 {
            return Err(SimError::InvalidParameter {
                name: "dt_s",
                reason: "the sampling step gives more than 10⁸ samples",
            });
        }
        (0..=count as usize)
            .map(|k| self.state_at((k as f64 * dt_s).min(self.duration_s)))
            .collect()
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(p: [f64; 3], speed: f64, pause: f64) -> Waypoint {
        Waypoint {
            position_m: p,
            speed_mps: speed,
            pause_s: pause,
        }
    }

    #[test]
    fn positions_are_continuous_and_speeds_match_the_legs() {
        let path = WaypointPath::new(vec![
            wp([0.0, 0.0, 0.0], 0.0, 1.0),
            wp([10.0, 0.0, -1.0], 1.2, 0.0),
            wp([10.0, 8.0, -1.0], 0.9, 3.0),
            wp([0.0, 8.0, 0.0], 1.5, 0.0),
        ])
        .unwrap();
        let samples = path.sample(0.1).unwrap();
        for pair in samples.windows(2) {
            let step = distance(pair[0].position_m, pair[1].position_m);
            assert!(step <= 1.5 * 0.1 + 1e-9, "jump of {step} m at {}", pair[0].time_s);
        }
        let s = path.state_at(5.0).unwrap();
        let speed = s.velocity_mps.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((speed - 1.2).abs() < 1e-12);
        assert_eq!(path.state_at(path.duration_s()).unwrap().position_m, [0.0, 8.0, 0.0]);
        assert_eq!(path.state_at(0.5).unwrap().position_m, [0.0, 0.0, 0.0]);
    }

    #[test]
    fn bad_paths_are_errors() {
        assert!(WaypointPath::new(vec![wp([0.0; 3], 1.0, 0.0)]).is_err());
        assert!(WaypointPath::new(vec![wp([0.0; 3], 1.0, 0.0), wp([1.0, 0.0, 0.0], 0.0, 0.0)]).is_err());
        assert!(WaypointPath::new(vec![wp([0.0; 3], 1.0, -1.0), wp([1.0, 0.0, 0.0], 1.0, 0.0)]).is_err());
        assert!(WaypointPath::new(vec![wp([f64::NAN, 0.0, 0.0], 1.0, 0.0), wp([1.0, 0.0, 0.0], 1.0, 0.0)]).is_err());
        let path = WaypointPath::new(vec![wp([0.0; 3], 1.0, 0.0), wp([1.0, 0.0, 0.0], 1.0, 0.0)]).unwrap();
        assert!(path.state_at(2.0).is_err());
        assert!(path.sample(0.0).is_err());
    }
}
