//! Ultrasonic time-of-flight ranging from a ring of sonars (seed 003's SRF08 nodes).
//!
//! A node carries `n` sonars, sonar `k` covering the bearings `[k·360°/n, k·360°/n + w)` from
//! the +x axis (`w` the sector width: 6 × 60° = 360° on seed 003's nodes). Firing sonar `k`
//! sends a ping; the echo that comes back first is the one of the **nearest** reflecting target
//! inside the sector, and targets carry no identity: whoever is nearest answers. The node
//! accepts the echo only if it arrives within the validity window `T_w` after the ping
//! (`2 r̃ / c ≤ T_w`, i.e. a maximum range `c T_w / 2`), as seed 003 does to reject late,
//! multiply reflected echoes.
//!
//! A firing is aimed ([`Aim`]): one sonar, or two adjacent sonars fired together when the
//! expected target bearing lies near the edge between their sectors (the node then reports the
//! first echo of either, i.e. the nearest reflector in the union of the two sectors).

use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::error::{finite, finite2, positive, Result, SimError};

/// A ring of identical sonars on one node and the physics of their echoes.
///
/// Measurement model of one firing (node `a`, sonar `k`, targets `p_j`):
/// ```text
/// C = { j : bearing(p_j − a) ∈ the aimed sector(s),  d_j = ‖p_j − a‖ ∈ [r_min, c T_w / 2] }
/// j* = argmin_{j ∈ C} d_j                         the first echo is the nearest reflector
/// r̃ = d_{j*} + v,   v ~ N(0, σ²)                  time of flight t = 2 r̃ / c
/// echo accepted  ⇔  detected  and  r̃ ≥ r_min  and  t ≤ T_w,   P(detected) = P_D
/// ```
/// A ping is lost with probability `1 − P_D` (a small robot sometimes returns too weak an
/// echo). The robots are alike, so a farther robot's echo is weaker still: a lost ping is
/// silent rather than answered by a reflector behind the nearest one.
///
/// # Units
/// Positions and ranges in m, angles in degrees (configuration) and radians (bearings), times
/// in s, the speed of sound in m/s.
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_sim::sensors::ultrasonic::{Aim, SonarRing};
/// let ring = SonarRing::srf08();
/// let node = [0.0, 0.0];
/// // two robots in the first sector (0°–60°): the nearer one answers
/// let targets = [[1.5, 0.5], [0.8, 0.3], [-1.0, 0.2]];
/// let aim = ring.aim_at(node, targets[0], 0.0);
/// assert_eq!(aim, Aim::single(0));
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
/// let lossless = SonarRing { detection_probability: 1.0, ..ring };
/// let echo = lossless.fire(node, aim, &targets, &mut rng)?.expect("a robot is in the sector");
/// assert_eq!(echo.source, 1);
/// assert!((echo.range_m - 0.854).abs() < 0.15);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 003 §1 (6 SRF08 sonars of 60° per node, TOF ranging with a time limit) and §5 limit ①
/// (targets in one cell cannot be told apart); Devantech, *SRF08 Ultra sonic range finder —
/// technical specification* (3 cm – 6 m, 65 ms ranging, ≈ 55° beam).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SonarRing {
    /// Sonars per node `n` (≥ 1).
    pub sonars: usize,
    /// Sector width `w` of each sonar (deg), in (0, 360/n].
    pub sector_width_deg: f64,
    /// Standard deviation `σ` of the range noise (m), > 0.
    pub range_noise_std_m: f64,
    /// Shortest measurable range `r_min` (m), ≥ 0.
    pub min_range_m: f64,
    /// Validity window `T_w` after the ping (s), > 0.
    pub echo_window_s: f64,
    /// Probability `P_D` that a target in the sector and in range reflects a usable echo, in (0, 1].
    pub detection_probability: f64,
    /// Speed of sound `c` (m/s), > 0.
    pub speed_of_sound_mps: f64,
}

/// Which sonars of a node fire together: `count` adjacent sonars starting at `first`
/// (`first, first + 1 mod n`).
///
/// # Example
/// ```
/// use rtls_sim::sensors::ultrasonic::{Aim, SonarRing};
/// let ring = SonarRing::srf08();
/// // bearing 58°: within 10° of the edge between sectors 0 and 1, so both fire
/// let p = [58f64.to_radians().cos(), 58f64.to_radians().sin()];
/// assert_eq!(ring.aim_at([0.0, 0.0], p, 10f64.to_radians()), Aim { first: 0, count: 2 });
/// assert_eq!(ring.aim_at([0.0, 0.0], p, 1f64.to_radians()), Aim::single(0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Aim {
    /// The first sonar.
    pub first: usize,
    /// How many adjacent sonars fire (1 or 2).
    pub count: usize,
}

impl Aim {
    /// One sonar.
    #[must_use]
    pub fn single(sonar: usize) -> Self {
        Self { first: sonar, count: 1 }
    }
}

/// One accepted echo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Echo {
    /// Measured range `r̃` (m).
    pub range_m: f64,
    /// Round-trip time of flight `2 r̃ / c` (s).
    pub time_of_flight_s: f64,
    /// Index of the target that reflected it — simulation truth, for evaluation only: the
    /// sensor itself cannot tell targets apart.
    pub source: usize,
}

impl SonarRing {
    /// Seed 003's node: 6 sonars × 60°, σ = 3 cm (SRF08 resolution), `r_min` = 3 cm (SRF08),
    /// a 17.5 ms window (3.0 m at 343 m/s: a cell's diagonal, 2.83 m, plus margin), `P_D` = 0.95,
    /// c = 343 m/s (dry air at 20 °C).
    ///
    /// # Example
    /// ```
    /// let ring = rtls_sim::sensors::ultrasonic::SonarRing::srf08();
    /// assert!((ring.max_range_m() - 3.0).abs() < 0.01);
    /// assert!(ring.validate().is_ok());
    /// ```
    #[must_use]
    pub fn srf08() -> Self {
        Self {
            sonars: 6,
            sector_width_deg: 60.0,
            range_noise_std_m: 0.03,
            min_range_m: 0.03,
            echo_window_s: 0.0175,
            detection_probability: 0.95,
            speed_of_sound_mps: 343.0,
        }
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the field (`sonars`, `sector_width_deg`,
    /// `range_noise_std_m`, `min_range_m`, `echo_window_s`, `detection_probability`,
    /// `speed_of_sound_mps`) when it is outside the range documented on the field, or when the
    /// window's maximum range is not above `min_range_m`; [`SimError::NonFinite`] for NaN/∞.
    pub fn validate(&self) -> Result<()> {
        if self.sonars == 0 {
            return Err(SimError::InvalidParameter {
                name: "sonars",
                reason: "a node needs at least one sonar",
            });
        }
        positive(
            self.sector_width_deg,
            "sector_width_deg",
            "the sector width must be positive",
        )?;
        if self.sector_width_deg * self.sonars as f64 > 360.0 + 1e-9 {
            return Err(SimError::InvalidParameter {
                name: "sector_width_deg",
                reason: "the sectors of one node must not overlap: sonars × width ≤ 360°",
            });
        }
        positive(
            self.range_noise_std_m,
            "range_noise_std_m",
            "the range noise must be positive",
        )?;
        finite(self.min_range_m, "min_range_m")?;
        if self.min_range_m < 0.0 {
            return Err(SimError::InvalidParameter {
                name: "min_range_m",
                reason: "the shortest range must not be negative",
            });
        }
        positive(self.echo_window_s, "echo_window_s", "the echo window must be positive")?;
        positive(
            self.speed_of_sound_mps,
            "speed_of_sound_mps",
            "the speed of sound must be positive",
        )?;
        finite(self.detection_probability, "detection_probability")?;
        if !(self.detection_probability > 0.0 && self.detection_probability <= 1.0) {
            return Err(SimError::InvalidParameter {
                name: "detection_probability",
                reason: "the detection probability must lie in (0, 1]",
            });
        }
        if self.max_range_m() <= self.min_range_m {
            return Err(SimError::InvalidParameter {
                name: "echo_window_s",
                reason: "the window's maximum range c·T_w/2 must exceed min_range_m",
            });
        }
        Ok(())
    }

    /// The longest range accepted by the window, `c T_w / 2` (m).
    #[must_use]
    pub fn max_range_m(&self) -> f64 {
        // r_max = c T_w / 2
        self.speed_of_sound_mps * self.echo_window_s / 2.0
    }

    /// The sonar whose sector holds the bearing from `node_m` to `point_m` (a point on the
    /// node gives sonar 0; a bearing in a gap between narrower sectors gives the sector that
    /// starts before it).
    #[must_use]
    pub fn sector_of(&self, node_m: [f64; 2], point_m: [f64; 2]) -> usize {
        let spacing_rad = std::f64::consts::TAU / self.sonars as f64;
        // k = ⌊θ / (2π/n)⌋, θ ∈ [0, 2π)
        let k = (bearing_rad(node_m, point_m) / spacing_rad).floor();
        if k.is_finite() && k >= 0.0 {
            (k as usize).min(self.sonars - 1)
        } else {
            0
        }
    }

    /// The sonars to fire from `node_m` at a target expected at `point_m`: the one whose sector
    /// holds the bearing, and its neighbour too when the bearing lies within `edge_margin_rad`
    /// of the edge between them (the expectation is uncertain, and a sonar aimed wrong hears
    /// nothing or another target).
    #[must_use]
    pub fn aim_at(&self, node_m: [f64; 2], point_m: [f64; 2], edge_margin_rad: f64) -> Aim {
        let k = self.sector_of(node_m, point_m);
        let spacing_rad = std::f64::consts::TAU / self.sonars as f64;
        // offset of the bearing inside sector k
        let offset = bearing_rad(node_m, point_m) - k as f64 * spacing_rad;
        if self.sonars < 2 {
            Aim::single(k)
        } else if offset < edge_margin_rad {
            Aim {
                first: (k + self.sonars - 1) % self.sonars,
                count: 2,
            }
        } else if offset > self.sector_width_deg.to_radians() - edge_margin_rad {
            Aim { first: k, count: 2 }
        } else {
            Aim::single(k)
        }
    }

    /// Whether `point_m` lies inside the beam of any sonar of `aim` from `node_m`, each sector
    /// widened by `margin_rad` on both sides.
    #[must_use]
    pub fn in_aim(&self, node_m: [f64; 2], aim: Aim, point_m: [f64; 2], margin_rad: f64) -> bool {
        (0..aim.count).any(|i| self.in_sector(node_m, (aim.first + i) % self.sonars, point_m, margin_rad))
    }

    /// Whether `point_m` lies inside sonar `sector`'s beam from `node_m`, widened by
    /// `margin_rad` on both sides.
    #[must_use]
    pub fn in_sector(&self, node_m: [f64; 2], sector: usize, point_m: [f64; 2], margin_rad: f64) -> bool {
        let spacing_rad = std::f64::consts::TAU / self.sonars as f64;
        let width_rad = self.sector_width_deg.to_radians();
        // offset of the bearing from the sector's start, wrapped into [−π, π)
        let start_rad = sector as f64 * spacing_rad;
        let offset = wrap_pi(bearing_rad(node_m, point_m) - start_rad);
        offset >= -margin_rad && offset < width_rad + margin_rad
    }

    /// Fires the sonars of `aim` on the node at `node_m` with targets at `targets_m` and returns
    /// the accepted echo, if any (see the type's model; two sonars fired together answer with
    /// the nearest reflector of both sectors).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`aim`) for a first sonar `≥ n` or a count outside
    /// `1..=n`; as
    /// [`SonarRing::validate`]; [`SimError::NonFinite`] for a NaN/∞ position.
    pub fn fire(&self, node_m: [f64; 2], aim: Aim, targets_m: &[[f64; 2]], rng: &mut impl Rng) -> Result<Option<Echo>> {
        self.validate()?;
        if aim.first >= self.sonars || aim.count == 0 || aim.count > self.sonars {
            return Err(SimError::InvalidParameter {
                name: "aim",
                reason: "the first sonar must be below the number of sonars and the count in 1..=sonars",
            });
        }
        finite2(node_m, "node position")?;
        let max_range_m = self.max_range_m();
        let mut nearest: Option<(usize, f64)> = None;
        for (j, &target) in targets_m.iter().enumerate() {
            finite2(target, "target position")?;
            // d_j = ‖p_j − a‖
            let distance_m = (target[0] - node_m[0]).hypot(target[1] - node_m[1]);
            let candidate =
                self.in_aim(node_m, aim, target, 0.0) && (self.min_range_m..=max_range_m).contains(&distance_m);
            if candidate && nearest.is_none_or(|(_, d)| distance_m < d) {
                nearest = Some((j, distance_m));
            }
        }
        // one detection draw and one noise draw per firing, echo or not, so the random stream
        // does not depend on the geometry
        let detected = rng.gen::<f64>() < self.detection_probability;
        let noise = Normal::new(0.0, self.range_noise_std_m).map_err(|_| SimError::InvalidParameter {
            name: "range_noise_std_m",
            reason: "the range noise must be positive",
        })?;
        let v = noise.sample(rng);
        Ok(nearest.filter(|_| detected).and_then(|(source, distance_m)| {
            // r̃ = d + v, t = 2 r̃ / c
            let range_m = distance_m + v;
            let time_of_flight_s = 2.0 * range_m / self.speed_of_sound_mps;
            (range_m >= self.min_range_m && time_of_flight_s <= self.echo_window_s).then_some(Echo {
                range_m,
                time_of_flight_s,
                source,
            })
        }))
    }
}

/// Bearing of `point_m` seen from `node_m`, in `[0, 2π)` (0 along +x, counter-clockwise).
fn bearing_rad(node_m: [f64; 2], point_m: [f64; 2]) -> f64 {
    // θ = atan2(Δy, Δx) mapped to [0, 2π)
    let theta = (point_m[1] - node_m[1]).atan2(point_m[0] - node_m[0]);
    if theta < 0.0 {
        theta + std::f64::consts::TAU
    } else {
        theta
    }
}

/// `angle` wrapped into `[−π, π)`.
fn wrap_pi(angle_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    (angle_rad + PI).rem_euclid(TAU) - PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn lossless() -> SonarRing {
        SonarRing {
            detection_probability: 1.0,
            ..SonarRing::srf08()
        }
    }

    #[test]
    fn sectors_tile_the_circle() {
        let ring = SonarRing::srf08();
        let node = [2.0, 2.0];
        for (deg, expected) in [
            (10.0, 0),
            (59.0, 0),
            (61.0, 1),
            (179.0, 2),
            (181.0, 3),
            (300.5, 5),
            (359.0, 5),
        ] {
            let theta = f64::to_radians(deg);
            let p = [node[0] + theta.cos(), node[1] + theta.sin()];
            assert_eq!(ring.sector_of(node, p), expected, "{deg}°");
            assert!(ring.in_sector(node, expected, p, 0.0), "{deg}°");
            assert!(!ring.in_sector(node, (expected + 1) % 6, p, 0.0), "{deg}°");
        }
        // 359° is within 2° of sector 0's start
        let p = [
            node[0] + f64::to_radians(359.0).cos(),
            node[1] + f64::to_radians(359.0).sin(),
        ];
        assert!(ring.in_sector(node, 0, p, f64::to_radians(2.0)));
        assert_eq!(ring.sector_of(node, node), 0);
    }

    #[test]
    fn the_nearest_target_in_the_sector_answers_and_others_do_not() {
        let ring = lossless();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let node = [0.0, 0.0];
        // target 0 nearer but in sector 1; target 1 in sector 0; target 2 in sector 0, farther
        let targets = [[0.2, 0.5], [1.0, 0.2], [2.0, 0.5]];
        for _ in 0..50 {
            let echo = ring.fire(node, Aim::single(0), &targets, &mut rng).unwrap().unwrap();
            assert_eq!(echo.source, 1);
            assert!((echo.time_of_flight_s - 2.0 * echo.range_m / 343.0).abs() < 1e-15);
        }
        // nothing in sector 3, and beyond the window's range nothing either
        assert_eq!(ring.fire(node, Aim::single(3), &targets, &mut rng).unwrap(), None);
        assert_eq!(ring.fire(node, Aim::single(0), &[[3.5, 0.5]], &mut rng).unwrap(), None);
        assert_eq!(ring.fire(node, Aim::single(0), &[], &mut rng).unwrap(), None);
        // sonars 0 and 1 together hear target 0 (sector 1), the nearest of both sectors
        let both = Aim { first: 0, count: 2 };
        assert_eq!(ring.fire(node, both, &targets, &mut rng).unwrap().unwrap().source, 0);
        // the pair 5–0 wraps around
        assert!(ring.in_aim(node, Aim { first: 5, count: 2 }, [1.0, 0.1], 0.0));
    }

    #[test]
    fn range_noise_has_the_configured_spread_and_detections_the_configured_rate() {
        let ring = SonarRing {
            detection_probability: 0.8,
            ..SonarRing::srf08()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (mut sum, mut sum_sq, mut hits) = (0.0, 0.0, 0);
        let n = 20_000;
        for _ in 0..n {
            if let Some(echo) = ring.fire([0.0, 0.0], Aim::single(0), &[[1.2, 0.9]], &mut rng).unwrap() {
                let e = echo.range_m - 1.5;
                sum += e;
                sum_sq += e * e;
                hits += 1;
            }
        }
        let mean = sum / hits as f64;
        let std = (sum_sq / hits as f64 - mean * mean).sqrt();
        assert!(mean.abs() < 0.002, "bias {mean}");
        assert!((std - 0.03).abs() < 0.001, "σ {std}");
        assert!((hits as f64 / n as f64 - 0.8).abs() < 0.01);
    }

    #[test]
    fn a_lost_ping_is_silent_even_with_a_robot_behind() {
        let ring = SonarRing {
            detection_probability: 0.5,
            ..SonarRing::srf08()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let echoes: Vec<Option<Echo>> = (0..200)
            .map(|_| {
                ring.fire([0.0, 0.0], Aim::single(0), &[[0.5, 0.1], [1.5, 0.3]], &mut rng)
                    .unwrap()
            })
            .collect();
        assert!(echoes.iter().flatten().all(|e| e.source == 0));
        let silent = echoes.iter().filter(|e| e.is_none()).count();
        assert!((70..130).contains(&silent), "{silent}");
    }

    #[test]
    fn bad_parameters_are_errors() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        assert!(SonarRing::srf08()
            .fire([0.0, 0.0], Aim::single(6), &[], &mut rng)
            .is_err());
        assert!(SonarRing::srf08()
            .fire([0.0, 0.0], Aim { first: 0, count: 0 }, &[], &mut rng)
            .is_err());
        assert!(SonarRing::srf08()
            .fire([f64::NAN, 0.0], Aim::single(0), &[], &mut rng)
            .is_err());
        let bad = [
            SonarRing {
                sonars: 0,
                ..SonarRing::srf08()
            },
            SonarRing {
                sector_width_deg: 70.0,
                ..SonarRing::srf08()
            },
            SonarRing {
                range_noise_std_m: 0.0,
                ..SonarRing::srf08()
            },
            SonarRing {
                min_range_m: -0.1,
                ..SonarRing::srf08()
            },
            SonarRing {
                echo_window_s: 0.0001,
                ..SonarRing::srf08()
            },
            SonarRing {
                detection_probability: 0.0,
                ..SonarRing::srf08()
            },
            SonarRing {
                speed_of_sound_mps: f64::NAN,
                ..SonarRing::srf08()
            },
        ];
        for ring in bad {
            assert!(ring.validate().is_err(), "{ring:?}");
        }
    }
}
