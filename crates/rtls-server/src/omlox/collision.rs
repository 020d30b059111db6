//! Collisions between trackables, judged from their tracks' positions *and* uncertainty, for
//! the omlox `collision_events` topic.
//!
//! Each trackable is a disc about its newest position whose radius — its *extent* — is
//!
//! ```text
//! extent = radius + k·σ
//! ```
//!
//! where `radius` is the trackable's declared `radius` (m, 0 when it has none) and σ (m) the
//! standard deviation of the track's horizontal position along its major axis
//! (`√λ_max` of the x–y covariance, the omlox `Location.accuracy` our tracks carry). With
//! `k = √χ²₂(0.95) ≈ 2.448` ([`K_SIGMA_95`]) the disc holds the track's 95 % error ellipse —
//! the ellipse the dashboard draws — so it contains the true centre with probability ≥ 95 %.
//! Two trackables on the same floor **collide** when their discs overlap:
//!
//! ```text
//! d < extent_a + extent_b        (d: horizontal centre distance, m; heights are ignored)
//! ```
//!
//! Summing the two `k·σ` (rather than `k·√(σ_a² + σ_b²)`, the test on the difference of two
//! independent Gaussians) is the geometric reading — the regions each trackable may occupy
//! touch — and is the cautious one: it never misses a pair the statistical test would flag.
//!
//! Release follows the spec's trackable settings: a collision ends when the distance reaches
//! `extent_a + extent_b + exit_tolerance` (the larger of the two trackables' `exit_tolerance`,
//! m, default 0), or when it has stayed between the contact distance and that release distance
//! for the smaller of their `tolerance_timeout`s (ms; absent or negative = never). A track
//! whose σ exceeds [`CollisionSettings::max_sigma_m`] is too uncertain to judge: it starts no
//! collision and its ongoing ones are neither continued nor ended until it is judged again.
//! A trackable not updated for [`CollisionSettings::stale_after_s`] (data clock) is forgotten
//! and its collisions end, as do those of a trackable [`CollisionDetector::remove`]d (a lost
//! track).
//!
//! Each pair yields `collision_start` once, `colliding` at every later update of either of the
//! two while they still collide (the spec's MUST), and `collision_end` once.
//!
//! Cost: trackables are kept in a uniform grid of their centres (cells of
//! [`CollisionSettings::cell_m`]); an update looks only at the cells within its extent plus
//! the largest extent present, and at its own ongoing collisions — O(neighbours), not O(n).
//! State is one entry per trackable updated within `stale_after_s` and one per colliding pair.

use std::collections::{HashMap, HashSet};

use super::CollisionType;

/// `√χ²₂(0.95)`: the disc of radius `K_SIGMA_95 · σ_max` holds the 95 % error ellipse.
pub const K_SIGMA_95: f64 = 2.447_746_830_680_816;

/// How collisions are judged (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionSettings {
    /// k: multiples of the track's σ added to the declared radius.
    pub k_sigma: f64,
    /// A track with a larger σ (m) is not judged.
    pub max_sigma_m: f64,
    /// Side of a grid cell (m).
    pub cell_m: f64,
    /// A trackable not updated for this long (s, the records' clock) is forgotten.
    pub stale_after_s: f64,
}

impl Default for CollisionSettings {
    /// `k` = [`K_SIGMA_95`], tracks with σ above 10 m not judged, 10 m cells, forgotten after 30 s.
    fn default() -> Self {
        Self {
            k_sigma: K_SIGMA_95,
            max_sigma_m: 10.0,
            cell_m: 10.0,
            stale_after_s: 30.0,
        }
    }
}

/// A trackable at one update.
///
/// # Units
/// Positions, radius, σ and tolerance in m; times in s (the records' clock); the timeout in s.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// The trackable's id.
    pub id: String,
    /// The location provider (tag) whose update placed it.
    pub provider_id: String,
    /// The update's time.
    pub time_s: f64,
    /// Its position as reported (`[x, y]` or `[x, y, z]`); only `x` and `y` are judged.
    pub coordinates: Vec<f64>,
    /// Logical floor (0 when unknown).
    pub floor: f64,
    /// Declared radius (0 without one).
    pub radius_m: f64,
    /// σ of the horizontal position along its major axis.
    pub sigma_m: f64,
    /// Extra distance before a collision is released.
    pub exit_tolerance_m: f64,
    /// How long a pair may stay within the tolerance band before it is released; `None`: no limit.
    pub tolerance_timeout_s: Option<f64>,
}

impl Body {
    fn xy(&self) -> [f64; 2] {
        [
            self.coordinates.first().copied().unwrap_or(0.0),
            self.coordinates.get(1).copied().unwrap_or(0.0),
        ]
    }
}

/// One of the two trackables of a [`Transition`], as it was judged.
#[derive(Debug, Clone, PartialEq)]
pub struct Side {
    /// The trackable's id.
    pub id: String,
    /// The provider whose update placed it.
    pub provider_id: String,
    /// Its position (as reported).
    pub coordinates: Vec<f64>,
    /// Its floor.
    pub floor: f64,
    /// Its extent `radius + k·σ` (m).
    pub extent_m: f64,
}

/// A pair's collision started, goes on, or ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Transition {
    /// What happened.
    pub kind: CollisionType,
    /// The trackable whose update (or removal) triggered it.
    pub trigger: Side,
    /// The other one.
    pub other: Side,
    /// When the pair started colliding (s).
    pub start_s: f64,
    /// When this happened (s): the triggering update's time.
    pub time_s: f64,
    /// Centre distance (m, horizontal).
    pub distance_m: f64,
    /// The middle of the overlap on the line between the centres (`[x, y]`, m); `None` on an end.
    pub area_m: Option<[f64; 2]>,
}

/// An ongoing collision.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pair {
    start_s: f64,
    /// The last time the two discs overlapped (the tolerance timeout counts from it).
    last_contact_s: f64,
}

#[derive(Debug, Clone)]
struct Tracked {
    body: Body,
    /// Its grid cell while it is judged.
    cell: Option<(i64, i64)>,
    /// The trackables it collides with.
    partners: HashSet<String>,
}

/// Finds collision starts, continuations and ends as trackables are updated (see the module
/// documentation). Synchronous; one instance sees every trackable's updates.
#[derive(Debug, Clone)]
pub struct CollisionDetector {
    settings: CollisionSettings,
    bodies: HashMap<String, Tracked>,
    grid: HashMap<(i64, i64), Vec<String>>,
    /// Ongoing collisions by (smaller id, larger id).
    pairs: HashMap<(String, String), Pair>,
    /// An upper bound of the extents of the judged trackables (m).
    max_extent_m: f64,
    newest_s: f64,
    last_sweep_s: f64,
}

fn key(a: &str, b: &str) -> (String, String) {
    if a <= b {
        (a.to_string(), b.to_string())
    } else {
        (b.to_string(), a.to_string())
    }
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

impl CollisionDetector {
    /// An empty detector.
    #[must_use]
    pub fn new(settings: CollisionSettings) -> Self {
        Self {
            settings,
            bodies: HashMap::new(),
            grid: HashMap::new(),
            pairs: HashMap::new(),
            max_extent_m: 0.0,
            newest_s: f64::NEG_INFINITY,
            last_sweep_s: f64::NEG_INFINITY,
        }
    }

    /// Trackables held (updated within `stale_after_s`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// Whether no trackable is held.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// Ongoing collisions.
    #[must_use]
    pub fn collisions(&self) -> usize {
        self.pairs.len()
    }

    fn extent(&self, body: &Body) -> f64 {
        body.radius_m.max(0.0) + self.settings.k_sigma * body.sigma_m
    }

    fn judged(&self, body: &Body) -> bool {
        body.sigma_m.is_finite()
            && body.sigma_m <= self.settings.max_sigma_m
            && body.coordinates.len() >= 2
            && body.coordinates.iter().all(|c| c.is_finite())
    }

    fn cell_of(&self, xy: [f64; 2]) -> (i64, i64) {
        #[allow(clippy::cast_possible_truncation)] // judged positions are finite site metres
        let cell = |v: f64| (v / self.settings.cell_m).floor() as i64;
        (cell(xy[0]), cell(xy[1]))
    }

    fn side(&self, body: &Body) -> Side {
        Side {
            id: body.id.clone(),
            provider_id: body.provider_id.clone(),
            coordinates: body.coordinates.clone(),
            floor: body.floor,
            extent_m: self.extent(body),
        }
    }

    fn stale(&self, body: &Body) -> bool {
        self.newest_s - body.time_s > self.settings.stale_after_s
    }

    /// Takes a trackable's update; returns the collisions it starts, continues or ends (the
    /// updated trackable first in each). An update older than the trackable's newest (another
    /// of its providers was heard later) changes nothing.
    pub fn update(&mut self, body: Body) -> Vec<Transition> {
        if self.bodies.get(&body.id).is_some_and(|t| t.body.time_s > body.time_s) {
            return Vec::new();
        }
        let time_s = body.time_s;
        self.newest_s = self.newest_s.max(time_s);
        let judged = self.judged(&body);
        let cell = judged.then(|| self.cell_of(body.xy()));
        let extent = self.extent(&body);
        if judged {
            self.max_extent_m = self.max_extent_m.max(extent);
        }
        let id = body.id.clone();
        let old_cell = self.bodies.get(&id).and_then(|t| t.cell);
        if old_cell != cell {
            if let Some(old) = old_cell {
                self.leave_cell(old, &id);
            }
            if let Some(new) = cell {
                self.grid.entry(new).or_default().push(id.clone());
            }
        }
        let partners = match self.bodies.get_mut(&id) {
            Some(tracked) => {
                tracked.body = body;
                tracked.cell = cell;
                tracked.partners.clone()
            }
            None => {
                self.bodies.insert(
                    id.clone(),
                    Tracked {
                        body,
                        cell,
                        partners: HashSet::new(),
                    },
                );
                HashSet::new()
            }
        };
        let mut out = Vec::new();
        for partner in &partners {
            self.judge_ongoing(&id, partner, judged, &mut out);
        }
        if judged {
            self.find_new(&id, extent, &mut out);
        }
        if time_s - self.last_sweep_s >= 1.0 {
            self.sweep(&mut out);
            self.last_sweep_s = time_s;
        }
        out
    }

    /// Forgets a trackable (its track was lost); ends its collisions at `time_s`, it first.
    pub fn remove(&mut self, id: &str, time_s: f64) -> Vec<Transition> {
        let mut out = Vec::new();
        self.forget(id, time_s, &mut out);
        out
    }

    fn leave_cell(&mut self, cell: (i64, i64), id: &str) {
        if let Some(ids) = self.grid.get_mut(&cell) {
            if let Some(i) = ids.iter().position(|x| x == id) {
                ids.swap_remove(i);
            }
            if ids.is_empty() {
                self.grid.remove(&cell);
            }
        }
    }

    /// An ongoing collision of `id` (just updated) with `partner`.
    fn judge_ongoing(&mut self, id: &str, partner: &str, judged: bool, out: &mut Vec<Transition>) {
        let (Some(a), Some(b)) = (self.bodies.get(id), self.bodies.get(partner)) else {
            return;
        };
        let (a, b) = (&a.body, &b.body);
        let pair_key = key(id, partner);
        let Some(pair) = self.pairs.get(&pair_key).copied() else {
            return;
        };
        let d = distance(a.xy(), b.xy());
        let contact = self.extent(a) + self.extent(b);
        let ended = if self.stale(b) || a.floor != b.floor {
            true
        } else if !judged || !self.judged(b) {
            // too uncertain to say either way: the collision stays as it is
            return;
        } else if d < contact {
            false
        } else {
            let tolerance = a.exit_tolerance_m.max(b.exit_tolerance_m).max(0.0);
            let timeout = match (a.tolerance_timeout_s, b.tolerance_timeout_s) {
                (Some(x), Some(y)) => Some(x.min(y)),
                (x, y) => x.or(y),
            };
            d >= contact + tolerance || timeout.is_some_and(|t| a.time_s - pair.last_contact_s >= t)
        };
        let time_s = a.time_s;
        let (trigger, other) = (self.side(a), self.side(b));
        if ended {
            out.push(Transition {
                kind: CollisionType::CollisionEnd,
                trigger,
                other,
                start_s: pair.start_s,
                time_s,
                distance_m: d,
                area_m: None,
            });
            self.end_pair(id, partner);
        } else {
            let area_m = Some(overlap_middle(a.xy(), b.xy(), trigger.extent_m, other.extent_m));
            if d < contact {
                if let Some(p) = self.pairs.get_mut(&pair_key) {
                    p.last_contact_s = time_s;
                }
            }
            out.push(Transition {
                kind: CollisionType::Colliding,
                trigger,
                other,
                start_s: pair.start_s,
                time_s,
                distance_m: d,
                area_m,
            });
        }
    }

    /// New collisions of `id` (judged, with `extent`) with the trackables near it.
    fn find_new(&mut self, id: &str, extent: f64, out: &mut Vec<Transition>) {
        let Some(tracked) = self.bodies.get(id) else {
            return;
        };
        let a = &tracked.body;
        let xy = a.xy();
        let reach = extent + self.max_extent_m;
        let (low, high) = (
            self.cell_of([xy[0] - reach, xy[1] - reach]),
            self.cell_of([xy[0] + reach, xy[1] + reach]),
        );
        let mut started = Vec::new();
        for cx in low.0..=high.0 {
            for cy in low.1..=high.1 {
                let Some(ids) = self.grid.get(&(cx, cy)) else {
                    continue;
                };
                for other in ids {
                    if other == id || tracked.partners.contains(other) {
                        continue;
                    }
                    let Some(b) = self.bodies.get(other).map(|t| &t.body) else {
                        continue;
                    };
                    if self.stale(b) || a.floor != b.floor || !self.judged(b) {
                        continue;
                    }
                    let d = distance(xy, b.xy());
                    let other_extent = self.extent(b);
                    if d < extent + other_extent {
                        started.push(Transition {
                            kind: CollisionType::CollisionStart,
                            trigger: self.side(a),
                            other: self.side(b),
                            start_s: a.time_s,
                            time_s: a.time_s,
                            distance_m: d,
                            area_m: Some(overlap_middle(xy, b.xy(), extent, other_extent)),
                        });
                    }
                }
            }
        }
        for transition in started {
            let pair = Pair {
                start_s: transition.time_s,
                last_contact_s: transition.time_s,
            };
            self.pairs.insert(key(id, &transition.other.id), pair);
            for (one, two) in [(id, transition.other.id.as_str()), (transition.other.id.as_str(), id)] {
                if let Some(t) = self.bodies.get_mut(one) {
                    t.partners.insert(two.to_string());
                }
            }
            out.push(transition);
        }
    }

    fn end_pair(&mut self, a: &str, b: &str) {
        self.pairs.remove(&key(a, b));
        for (one, two) in [(a, b), (b, a)] {
            if let Some(t) = self.bodies.get_mut(one) {
                t.partners.remove(two);
            }
        }
    }

    /// Forgets `id`, ending its collisions at `time_s` (it first).
    fn forget(&mut self, id: &str, time_s: f64, out: &mut Vec<Transition>) {
        let Some(tracked) = self.bodies.get(id) else {
            return;
        };
        let partners: Vec<String> = tracked.partners.iter().cloned().collect();
        for partner in partners {
            let (Some(a), Some(b)) = (self.bodies.get(id), self.bodies.get(&partner)) else {
                continue;
            };
            let start_s = self.pairs.get(&key(id, &partner)).map_or(time_s, |p| p.start_s);
            out.push(Transition {
                kind: CollisionType::CollisionEnd,
                trigger: self.side(&a.body),
                other: self.side(&b.body),
                start_s,
                time_s,
                distance_m: distance(a.body.xy(), b.body.xy()),
                area_m: None,
            });
            self.end_pair(id, &partner);
        }
        if let Some(tracked) = self.bodies.remove(id) {
            if let Some(cell) = tracked.cell {
                self.leave_cell(cell, id);
            }
        }
    }

    /// Forgets the stale trackables and tightens the extent bound.
    fn sweep(&mut self, out: &mut Vec<Transition>) {
        let stale: Vec<String> = self
            .bodies
            .values()
            .filter(|t| self.stale(&t.body))
            .map(|t| t.body.id.clone())
            .collect();
        for id in stale {
            self.forget(&id, self.newest_s, out);
        }
        self.max_extent_m = self
            .bodies
            .values()
            .filter(|t| t.cell.is_some())
            .map(|t| self.extent(&t.body))
            .fold(0.0, f64::max);
    }
}

/// The middle of the overlap of two discs on the line between their centres: the point
/// halfway between `b`'s near edge and `a`'s far edge, seen from `a`.
fn overlap_middle(a: [f64; 2], b: [f64; 2], extent_a: f64, extent_b: f64) -> [f64; 2] {
    let d = distance(a, b);
    if d == 0.0 {
        return a;
    }
    // from a towards b: the overlap spans [d − extent_b, extent_a]
    let along = 0.5 * (d - extent_b + extent_a);
    [a[0] + (b[0] - a[0]) * along / d, a[1] + (b[1] - a[1]) * along / d]
}

#[cfg(test)]
#[path = "collision_tests.rs"]
mod tests;
