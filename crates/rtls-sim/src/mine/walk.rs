//! How a miner moves: the seed 000 scenario's patrol (back and forth between two limits, in
//! closed form) and the endless feed's roaming (walk, rest, change drift through the
//! cross-cut, walk into the collapse when sent there), leg by leg.

use std::collections::VecDeque;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::{MineLayout, RoamingSettings};

/// A miner walking back and forth along a drift at a constant speed, forever.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Patrol {
    /// y of the drift's centreline plus the miner's lateral offset, m.
    pub y_m: f64,
    /// x at time 0, m.
    pub start_x_m: f64,
    pub speed_mps: f64,
    /// He turns back at these, m.
    pub limits_m: [f64; 2],
    /// Heading east (`true`) or west at time 0.
    pub eastward: bool,
}

impl Patrol {
    /// Position at `t_s` (s after the start), m.
    pub fn position_m(&self, t_s: f64) -> [f64; 2] {
        // unfold the bouncing walk: distance travelled along a 2L-periodic track
        let [a, b] = self.limits_m;
        let length = b - a;
        let unfolded = if self.eastward {
            self.start_x_m - a + self.speed_mps * t_s
        } else {
            2.0 * length - (self.start_x_m - a) + self.speed_mps * t_s
        };
        let phase = unfolded.rem_euclid(2.0 * length);
        let x = if phase <= length {
            a + phase
        } else {
            b - (phase - length)
        };
        [x, self.y_m]
    }
}

/// Which tunnel a leg runs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tunnel {
    /// A drift, by index: the leg's coordinate is x.
    Drift(usize),
    /// The cross-cut: the leg's coordinate is y.
    CrossCut,
}

/// One stretch of a miner's day: from one point of a tunnel to another at constant speed (or
/// standing still, when both are equal), between two times.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leg {
    tunnel: Tunnel,
    /// Coordinate along the tunnel at `start_s` and `end_s`, m.
    from_m: f64,
    to_m: f64,
    /// s after the simulation's start.
    start_s: f64,
    end_s: f64,
}

impl Leg {
    /// Coordinate along the tunnel at `t_s`, m (held at the ends outside the leg's times).
    fn along_m(&self, t_s: f64) -> f64 {
        if self.end_s <= self.start_s {
            return self.to_m;
        }
        let fraction = ((t_s - self.start_s) / (self.end_s - self.start_s)).clamp(0.0, 1.0);
        self.from_m + (self.to_m - self.from_m) * fraction
    }
}

/// What a miner does next.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Plan {
    /// Walk along `tunnel` to `to_m`.
    Walk { tunnel: Tunnel, to_m: f64 },
    /// Stand still.
    Rest { duration_s: f64 },
}

/// A miner roaming the drifts, with his own random stream (so his walk does not depend on how
/// often the simulation is stepped).
#[derive(Debug, Clone)]
pub(super) struct Roamer {
    lateral_m: f64,
    speed_mps: f64,
    leg: Leg,
    plans: VecDeque<Plan>,
    /// Heading into (or inside, or walking out of) the collapse.
    approaching: bool,
    /// The last activity was a rest (the next one is a walk, so nobody idles for long).
    rested: bool,
    rng: ChaCha8Rng,
}

impl Roamer {
    /// A miner standing on `drift` at `x_m` at time 0, who first walks into the collapse if
    /// `approach` and otherwise starts roaming.
    pub fn new(
        layout: &MineLayout,
        settings: &RoamingSettings,
        start: (usize, f64),
        lateral_m: f64,
        speed_mps: f64,
        approach: bool,
        rng: ChaCha8Rng,
    ) -> Self {
        let (drift, x_m) = start;
        let mut roamer = Self {
            lateral_m,
            speed_mps,
            leg: Leg {
                tunnel: Tunnel::Drift(drift),
                from_m: x_m,
                to_m: x_m,
                start_s: 0.0,
                end_s: 0.0,
            },
            plans: VecDeque::new(),
            approaching: false,
            rested: false,
            rng,
        };
        if approach {
            roamer.plan_approach(layout, settings);
        }
        roamer
    }

    /// Whether he is heading into, inside or walking out of the collapse.
    pub fn approaching(&self) -> bool {
        self.approaching
    }

    /// Position at `t_s`, which must be covered by the current leg (after [`Self::advance`]
    /// to at least `t_s`), m.
    pub fn position_m(&self, layout: &MineLayout, t_s: f64) -> [f64; 2] {
        self.point_m(layout, self.leg.tunnel, self.leg.along_m(t_s))
    }

    /// Lays out his legs up to `t_s` (s after the start), planning new activities as the old
    /// ones end.
    pub fn advance(&mut self, layout: &MineLayout, settings: &RoamingSettings, t_s: f64) {
        while self.leg.end_s < t_s {
            let plan = match self.plans.pop_front() {
                Some(plan) => plan,
                None => {
                    self.plan_activity(layout, settings);
                    match self.plans.pop_front() {
                        Some(plan) => plan,
                        // plan_activity always plans something; stand still a second otherwise
                        None => Plan::Rest { duration_s: 1.0 },
                    }
                }
            };
            let start_s = self.leg.end_s;
            let here_m = self.point_m(layout, self.leg.tunnel, self.leg.to_m);
            self.leg = match plan {
                Plan::Rest { duration_s } => Leg {
                    from_m: self.leg.to_m,
                    start_s,
                    end_s: start_s + duration_s,
                    ..self.leg
                },
                Plan::Walk { tunnel, to_m } => {
                    // turning into another tunnel at a junction: the same point, measured
                    // along the new tunnel
                    let from_m = match tunnel {
                        Tunnel::Drift(_) => here_m[0],
                        Tunnel::CrossCut => here_m[1],
                    };
                    Leg {
                        tunnel,
                        from_m,
                        to_m,
                        start_s,
                        end_s: start_s + (to_m - from_m).abs() / self.speed_mps,
                    }
                }
            };
        }
    }

    /// Sends him into the collapse from wherever he is at `t_s` (he must have been advanced
    /// to `t_s`): his current leg stops there and his plans are replaced.
    pub fn send_into_collapse(&mut self, layout: &MineLayout, settings: &RoamingSettings, t_s: f64) {
        let along_m = self.leg.along_m(t_s);
        self.leg.to_m = along_m;
        self.leg.end_s = t_s.max(self.leg.start_s);
        if self.leg.end_s <= self.leg.start_s {
            self.leg.from_m = along_m;
        }
        self.plan_approach(layout, settings);
    }

    /// The point at `along_m` of `tunnel`, offset by his lateral position, m.
    fn point_m(&self, layout: &MineLayout, tunnel: Tunnel, along_m: f64) -> [f64; 2] {
        match tunnel {
            Tunnel::Drift(drift) => [along_m, layout.drifts[drift].y_m + self.lateral_m],
            Tunnel::CrossCut => [layout.cross_cut.x_m + self.lateral_m, along_m],
        }
    }

    /// Where the current leg ends: tunnel and coordinate along it.
    fn end_place(&self) -> (Tunnel, f64) {
        (self.leg.tunnel, self.leg.to_m)
    }

    /// Replaces his plans with: walk to a point inside the collapse, linger, walk back out west.
    fn plan_approach(&mut self, layout: &MineLayout, settings: &RoamingSettings) {
        self.plans.clear();
        self.approaching = true;
        self.rested = false;
        let collapse = &layout.collapse;
        let [west, east] = collapse.x_range_m;
        let depth_m = uniform(&mut self.rng, [west + 5.0, east - 5.0]);
        self.plan_route(layout, collapse.drift, depth_m);
        let duration_s = uniform(&mut self.rng, settings.collapse_linger_s);
        self.plans.push_back(Plan::Rest { duration_s });
        let walkable_east_m = layout.drifts[collapse.drift].walkable_x_m[1];
        let walkable_west_m = layout.drifts[collapse.drift].walkable_x_m[0];
        let out_m = uniform(
            &mut self.rng,
            [(walkable_east_m - 150.0).max(walkable_west_m), walkable_east_m],
        );
        self.plans.push_back(Plan::Walk {
            tunnel: Tunnel::Drift(collapse.drift),
            to_m: out_m,
        });
    }

    /// Plans his next activity: a rest (never two in a row), a walk to another drift through the
    /// cross-cut, or a walk along his drift (turning back short of its ends).
    fn plan_activity(&mut self, layout: &MineLayout, settings: &RoamingSettings) {
        self.approaching = false;
        let (tunnel, along_m) = self.end_place();
        let drift = match tunnel {
            Tunnel::Drift(drift) => drift,
            Tunnel::CrossCut => {
                // only after an interrupted route: go to any drift
                let drift = self.rng.gen_range(0..layout.drifts.len());
                let x_m = uniform(&mut self.rng, layout.drifts[drift].walkable_x_m);
                self.plan_route(layout, drift, x_m);
                return;
            }
        };
        if !self.rested && self.rng.gen_bool(settings.rest_probability) {
            self.rested = true;
            let duration_s = uniform(&mut self.rng, settings.rest_duration_s);
            self.plans.push_back(Plan::Rest { duration_s });
            return;
        }
        self.rested = false;
        if layout.drifts.len() > 1 && self.rng.gen_bool(settings.drift_change_probability) {
            // any other drift, uniformly
            let mut other = self.rng.gen_range(0..layout.drifts.len() - 1);
            if other >= drift {
                other += 1;
            }
            let x_m = uniform(&mut self.rng, layout.drifts[other].walkable_x_m);
            self.plan_route(layout, other, x_m);
            return;
        }
        let [west, east] = layout.drifts[drift].walkable_x_m;
        let (room_west_m, room_east_m) = ((along_m - west).max(0.0), (east - along_m).max(0.0));
        let min_m = settings.min_walk_m;
        let eastward = match (room_west_m >= min_m, room_east_m >= min_m) {
            (true, true) => self.rng.gen_bool(0.5),
            (false, true) => true,
            (true, false) => false,
            // a drift shorter than two walks: to the farther end
            (false, false) => room_east_m > room_west_m,
        };
        let room_m = if eastward { room_east_m } else { room_west_m };
        let distance_m = uniform(&mut self.rng, [min_m.min(room_m), room_m]);
        let to_m = if eastward {
            along_m + distance_m
        } else {
            along_m - distance_m
        };
        self.plans.push_back(Plan::Walk {
            tunnel: Tunnel::Drift(drift),
            to_m: to_m.clamp(west, east),
        });
    }

    /// Appends the walks from where his plans end to `x_m` on `drift`, through the cross-cut
    /// when the drift is another one. Turns happen where his lateral offset meets the other
    /// tunnel's, so his path is continuous.
    fn plan_route(&mut self, layout: &MineLayout, drift: usize, x_m: f64) {
        let (tunnel, _) = self
            .plans
            .iter()
            .rev()
            .find_map(|plan| match plan {
                Plan::Walk { tunnel, to_m } => Some((*tunnel, *to_m)),
                Plan::Rest { .. } => None,
            })
            .unwrap_or_else(|| self.end_place());
        let junction_x_m = layout.cross_cut.x_m + self.lateral_m;
        let junction_y_m = layout.drifts[drift].y_m + self.lateral_m;
        match tunnel {
            Tunnel::Drift(current) if current == drift => {}
            Tunnel::Drift(_) => {
                self.plans.push_back(Plan::Walk {
                    tunnel,
                    to_m: junction_x_m,
                });
                self.plans.push_back(Plan::Walk {
                    tunnel: Tunnel::CrossCut,
                    to_m: junction_y_m,
                });
            }
            Tunnel::CrossCut => self.plans.push_back(Plan::Walk {
                tunnel: Tunnel::CrossCut,
                to_m: junction_y_m,
            }),
        }
        self.plans.push_back(Plan::Walk {
            tunnel: Tunnel::Drift(drift),
            to_m: x_m,
        });
    }
}

/// A uniform draw from `[lo, hi)`, or `lo` when the range is empty (no panic).
pub(super) fn uniform(rng: &mut impl Rng, [lo, hi]: [f64; 2]) -> f64 {
    if lo < hi {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}
