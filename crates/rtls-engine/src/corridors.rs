//! The site's map of corridors — a mine's drifts, a factory's aisles, a hospital's hallways — as
//! plan centrelines with a half-width, and the geometry the tracker asks of it: the nearest
//! corridor segment to an estimate, whether a junction (a bend or a meeting of corridors) is
//! near, and whether the straight line between two points stays inside the corridors (radio
//! line of sight underground, where rock stops a reader from hearing a tag in the next drift).
//!
//! A corridor may give the height of its centreline at each point (a decline's walking line):
//! the height at `s` along a segment is interpolated linearly between its ends.
//!
//! A corridor is a polyline `[a₀, a₁, …]` (plan `x, y`, m). Each segment `aₖ → aₖ₊₁` has the
//! unit direction `u = (aₖ₊₁ − aₖ)/‖aₖ₊₁ − aₖ‖` and the normal `n = (−u_y, u_x)`. For a point `p`
//! its along-track coordinate is `s = u·(p − aₖ)` and its lateral offset `e = n·(p − aₖ)`.
//!
//! Junctions are the interior vertices of every polyline (bends) and every point where a
//! segment of one corridor meets a segment of another (crossings, and T-junctions where a
//! corridor ends on another one within its half-width). A corridor end that is not a junction
//! is a dead end.
//!
//! # Example
//! ```
//! use rtls_engine::corridors::CorridorMap;
//! use rtls_engine::site::Corridor;
//! // an L: east along y = 0, then north along x = 100
//! let map = CorridorMap::new(&[Corridor {
//!     id: "drift".into(),
//!     points_m: vec![[0.0, 0.0], [100.0, 0.0], [100.0, 50.0]],
//!     heights_m: Some(vec![0.0, -1.0, -1.0]), // a 1 % decline, then level
//!     half_width_m: 2.0,
//! }]);
//! let nearest = map.nearest([40.0, 1.5]).unwrap();
//! assert!((nearest.lateral_m - 1.5).abs() < 1e-12);
//! assert!((nearest.height_m.unwrap() + 0.4).abs() < 1e-12);
//! assert!(map.junction_within([98.0, 1.0], 5.0));
//! assert!(map.line_of_sight([10.0, 0.0], [90.0, 0.0]));
//! assert!(!map.line_of_sight([50.0, 0.0], [100.0, 40.0])); // through the rock inside the L
//! ```
//!
//! # References
//! D. Simon, "Kalman filtering with state constraints: a survey of linear and nonlinear
//! algorithms", *IET Control Theory & Applications* 4(8), 2010 (constraints as
//! pseudo-measurements); seed 000 §3 (tracking inside a mine's tunnels).

use crate::site::Corridor;

/// One straight piece of a corridor's centreline.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    /// Start `aₖ`, m.
    start_m: [f64; 2],
    /// Unit direction `u`.
    direction: [f64; 2],
    /// `‖aₖ₊₁ − aₖ‖`, m.
    length_m: f64,
    /// The corridor's half-width, m.
    half_width_m: f64,
    /// Heights of the centreline at the start and the end (`heights_m`), m.
    heights_m: Option<[f64; 2]>,
    /// Index of the corridor it belongs to.
    corridor: usize,
    /// Whether the segment's start is a dead end of its corridor.
    dead_start: bool,
    /// Whether the segment's end is a dead end of its corridor.
    dead_end: bool,
}

impl Segment {
    fn end_m(&self) -> [f64; 2] {
        [
            self.start_m[0] + self.length_m * self.direction[0],
            self.start_m[1] + self.length_m * self.direction[1],
        ]
    }

    /// `(s, e)`: along-track coordinate and lateral offset of `p`, m.
    fn coordinates(&self, p: [f64; 2]) -> (f64, f64) {
        let d = [p[0] - self.start_m[0], p[1] - self.start_m[1]];
        // s = u·(p − a), e = n·(p − a), n = (−u_y, u_x)
        (
            self.direction[0] * d[0] + self.direction[1] * d[1],
            -self.direction[1] * d[0] + self.direction[0] * d[1],
        )
    }

    /// Distance from `p` to the segment, m.
    fn distance_m(&self, p: [f64; 2]) -> f64 {
        let (s, e) = self.coordinates(p);
        let beyond = if s < 0.0 {
            -s
        } else if s > self.length_m {
            s - self.length_m
        } else {
            0.0
        };
        beyond.hypot(e)
    }
}

/// Where an estimate lies relative to its nearest corridor segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearestSegment {
    /// A point of the centreline (the segment's start), m.
    pub origin_m: [f64; 2],
    /// The segment's unit direction `u`.
    pub direction: [f64; 2],
    /// The unit normal `n = (−u_y, u_x)`.
    pub normal: [f64; 2],
    /// Lateral offset `e = n·(p − a)`, m.
    pub lateral_m: f64,
    /// Along-track coordinate `s = u·(p − a)`, m.
    pub along_m: f64,
    /// The segment's length, m.
    pub length_m: f64,
    /// The corridor's half-width, m.
    pub half_width_m: f64,
    /// The centreline's height at the point nearest the estimate (`h = h₀ + clamp(s/L, 0, 1)
    /// (h₁ − h₀)`), m, when the corridor has `heights_m`.
    pub height_m: Option<f64>,
    /// Index of the corridor in the site's list.
    pub corridor: usize,
    /// The segment's start is a dead end (the estimate may not pass it).
    pub dead_start: bool,
    /// The segment's end is a dead end.
    pub dead_end: bool,
}

/// The corridors of a site, ready for the tracker's questions.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CorridorMap {
    segments: Vec<Segment>,
    junctions_m: Vec<[f64; 2]>,
}

/// `true` when `p` lies on segment `seg` within `tolerance_m` (laterally and along it).
fn touches(seg: &Segment, p: [f64; 2], tolerance_m: f64) -> bool {
    seg.distance_m(p) <= tolerance_m
}

/// Intersection point of two segments, if they cross (parallel segments never do here).
fn crossing(a: &Segment, b: &Segment) -> Option<[f64; 2]> {
    // a + t·u = b + r·v  →  t = ((b − a) × v) / (u × v)
    let cross = |p: [f64; 2], q: [f64; 2]| p[0] * q[1] - p[1] * q[0];
    let denominator = cross(a.direction, b.direction);
    if denominator.abs() < 1e-12 {
        return None;
    }
    let w = [b.start_m[0] - a.start_m[0], b.start_m[1] - a.start_m[1]];
    let t = cross(w, b.direction) / denominator;
    let r = cross(w, a.direction) / denominator;
    ((0.0..=a.length_m).contains(&t) && (0.0..=b.length_m).contains(&r))
        .then(|| [a.start_m[0] + t * a.direction[0], a.start_m[1] + t * a.direction[1]])
}

impl CorridorMap {
    /// The map of `corridors`. Degenerate segments (two equal consecutive points) are skipped;
    /// the site loader refuses them, so this only matters for corridors built in code.
    #[must_use]
    pub fn new(corridors: &[Corridor]) -> Self {
        let mut segments = Vec::new();
        let mut junctions_m = Vec::new();
        for (index, corridor) in corridors.iter().enumerate() {
            let points = &corridor.points_m;
            for (k, pair) in points.windows(2).enumerate() {
                let d = [pair[1][0] - pair[0][0], pair[1][1] - pair[0][1]];
                let length_m = d[0].hypot(d[1]);
                if length_m.is_nan() || length_m <= 0.0 {
                    continue;
                }
                segments.push(Segment {
                    start_m: pair[0],
                    direction: [d[0] / length_m, d[1] / length_m],
                    length_m,
                    half_width_m: corridor.half_width_m,
                    heights_m: corridor
                        .heights_m
                        .as_ref()
                        .and_then(|h| Some([*h.get(k)?, *h.get(k + 1)?])),
                    corridor: index,
                    dead_start: k == 0,
                    dead_end: k + 2 == points.len(),
                });
            }
            // bends
            if points.len() > 2 {
                junctions_m.extend_from_slice(&points[1..points.len() - 1]);
            }
        }
        // crossings and T-junctions between corridors
        for i in 0..segments.len() {
            for j in i + 1..segments.len() {
                let (a, b) = (segments[i], segments[j]);
                if a.corridor == b.corridor {
                    continue;
                }
                if let Some(point) = crossing(&a, &b) {
                    junctions_m.push(point);
                }
                for (seg, other, at_start) in [(i, &b, true), (i, &b, false), (j, &a, true), (j, &a, false)] {
                    let s = &segments[seg];
                    let (dead, end) = if at_start {
                        (s.dead_start, s.start_m)
                    } else {
                        (s.dead_end, s.end_m())
                    };
                    if dead && touches(other, end, s.half_width_m.max(other.half_width_m)) {
                        junctions_m.push(end);
                        if at_start {
                            segments[seg].dead_start = false;
                        } else {
                            segments[seg].dead_end = false;
                        }
                    }
                }
            }
        }
        Self { segments, junctions_m }
    }

    /// Whether the map has no corridor.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.segments.is_empty()
    }

    /// The segment nearest to `p` (plan, m), or `None` for an empty map.
    #[must_use]
    pub fn nearest(&self, p: [f64; 2]) -> Option<NearestSegment> {
        let seg = self
            .segments
            .iter()
            .min_by(|a, b| a.distance_m(p).total_cmp(&b.distance_m(p)))?;
        let (along_m, lateral_m) = seg.coordinates(p);
        Some(NearestSegment {
            origin_m: seg.start_m,
            direction: seg.direction,
            normal: [-seg.direction[1], seg.direction[0]],
            lateral_m,
            along_m,
            length_m: seg.length_m,
            half_width_m: seg.half_width_m,
            // h = h₀ + clamp(s/L, 0, 1)·(h₁ − h₀)
            height_m: seg
                .heights_m
                .map(|[h0, h1]| h0 + (along_m / seg.length_m).clamp(0.0, 1.0) * (h1 - h0)),
            corridor: seg.corridor,
            dead_start: seg.dead_start,
            dead_end: seg.dead_end,
        })
    }

    /// The point of a corridor centreline within `radius_m` of `p` that the most of `readers`
    /// see ([`CorridorMap::line_of_sight`]), the nearest to `p` among equals; `None` when no
    /// centreline comes that near.
    ///
    /// Candidates are `p`'s foot on each segment, `a + clamp(u·(p − a), 0, L) u`: where a fix
    /// made of readings heard through the corridors can lie. On a map of `S` segments it costs
    /// `S` candidates, each `readers` lines of sight.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::corridors::CorridorMap;
    /// use rtls_engine::site::Corridor;
    /// let drift = |id: &str, y: f64| Corridor {
    ///     id: id.into(), points_m: vec![[0.0, y], [100.0, y]], heights_m: None, half_width_m: 2.0,
    /// };
    /// // two parallel drifts 10 m apart; a fix between them, nearer the lower one, of readings
    /// // heard by two readers of the upper one
    /// let map = CorridorMap::new(&[drift("lower", 0.0), drift("upper", 10.0)]);
    /// let point = map.visible_point_near([50.0, 4.0], &[[40.0, 10.0], [60.0, 10.0]], 20.0).unwrap();
    /// assert_eq!(point, [50.0, 10.0]);
    /// ```
    #[must_use]
    pub fn visible_point_near(&self, p: [f64; 2], readers: &[[f64; 2]], radius_m: f64) -> Option<[f64; 2]> {
        let mut best: Option<(usize, f64, [f64; 2])> = None;
        for segment in &self.segments {
            if segment.distance_m(p) > radius_m {
                continue;
            }
            // foot of p: a + clamp(s, 0, L) u
            let (along_m, _) = segment.coordinates(p);
            let along_m = along_m.clamp(0.0, segment.length_m);
            let foot = [
                segment.start_m[0] + along_m * segment.direction[0],
                segment.start_m[1] + along_m * segment.direction[1],
            ];
            let seen = readers.iter().filter(|&&r| self.line_of_sight(foot, r)).count();
            let distance_m = (foot[0] - p[0]).hypot(foot[1] - p[1]);
            if best.is_none_or(|(most, nearest_m, _)| seen > most || (seen == most && distance_m < nearest_m)) {
                best = Some((seen, distance_m, foot));
            }
        }
        best.map(|(_, _, foot)| foot)
    }

    /// Whether a junction (a bend, a crossing, a T) lies within `radius_m` of `p`.
    #[must_use]
    pub fn junction_within(&self, p: [f64; 2], radius_m: f64) -> bool {
        self.junctions_m
            .iter()
            .any(|j| (j[0] - p[0]).hypot(j[1] - p[1]) <= radius_m)
    }

    /// The junctions (bends, crossings, T-junctions), m.
    #[must_use]
    pub fn junctions_m(&self) -> &[[f64; 2]] {
        &self.junctions_m
    }

    /// Whether the straight line from `a` to `b` stays inside the corridors: every point
    /// strictly between them (sampled at a quarter of the narrowest half-width) lies within
    /// some corridor's half-width of its centreline. The ends themselves are not tested, so a
    /// reader on a wall and an estimate just outside one still see each other. An empty map
    /// sees everything.
    #[must_use]
    pub fn line_of_sight(&self, a: [f64; 2], b: [f64; 2]) -> bool {
        let Some(narrowest_m) = self.segments.iter().map(|s| s.half_width_m).reduce(f64::min) else {
            return true;
        };
        let length_m = (b[0] - a[0]).hypot(b[1] - a[1]);
        let steps = (length_m / (0.25 * narrowest_m)).ceil().clamp(1.0, 1e5) as usize;
        (1..steps).all(|k| {
            let t = k as f64 / steps as f64;
            let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            self.segments.iter().any(|s| s.distance_m(p) <= s.half_width_m)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corridor(id: &str, points_m: Vec<[f64; 2]>) -> Corridor {
        Corridor {
            id: id.into(),
            points_m,
            heights_m: None,
            half_width_m: 2.5,
        }
    }

    /// Two parallel drifts 40 m apart joined by a cross-cut at x = 300.
    fn mine() -> CorridorMap {
        CorridorMap::new(&[
            corridor("d0", vec![[0.0, 0.0], [600.0, 0.0]]),
            corridor("d1", vec![[0.0, 40.0], [600.0, 40.0]]),
            corridor("x", vec![[300.0, 0.0], [300.0, 40.0]]),
        ])
    }

    #[test]
    fn crossings_and_t_junctions_are_junctions_and_free_ends_are_dead_ends() {
        let map = mine();
        // the cross-cut ends on both drifts: two T-junctions (found from each side)
        assert!(map.junction_within([300.0, 0.0], 0.1));
        assert!(map.junction_within([300.0, 40.0], 0.1));
        assert!(!map.junction_within([150.0, 0.0], 10.0));
        let west = map.nearest([-3.0, 0.5]).unwrap();
        assert!(west.dead_start && west.dead_end && west.along_m < 0.0);
        let cut = map.nearest([300.5, 20.0]).unwrap();
        assert!(!cut.dead_start && !cut.dead_end);
        assert!((cut.lateral_m + 0.5).abs() < 1e-12, "{}", cut.lateral_m);
        // an X crossing in the middle of two corridors
        let cross = CorridorMap::new(&[
            corridor("a", vec![[-10.0, 0.0], [10.0, 0.0]]),
            corridor("b", vec![[0.0, -10.0], [0.0, 10.0]]),
        ]);
        assert!(cross.junction_within([0.0, 0.0], 1e-9));
        assert_eq!(cross.junctions_m().len(), 1);
    }

    #[test]
    fn the_nearest_segment_gives_signed_lateral_and_along_track_coordinates() {
        let map = mine();
        let n = map.nearest([100.0, 38.0]).unwrap();
        assert_eq!(n.corridor, 1);
        assert!((n.lateral_m + 2.0).abs() < 1e-12 && (n.along_m - 100.0).abs() < 1e-12);
        assert!(CorridorMap::default().nearest([0.0, 0.0]).is_none());
    }

    #[test]
    fn line_of_sight_follows_the_corridors_not_the_rock() {
        let map = mine();
        assert!(map.line_of_sight([10.0, 0.0], [200.0, 2.5]));
        // between the drifts through 35 m of rock
        assert!(!map.line_of_sight([100.0, 0.0], [100.0, 40.0]));
        // down the cross-cut
        assert!(map.line_of_sight([300.0, 1.0], [300.0, 39.0]));
        // diagonal from one drift into the cross-cut leaves the tunnels
        assert!(!map.line_of_sight([250.0, 0.0], [300.0, 30.0]));
        assert!(CorridorMap::default().line_of_sight([0.0, 0.0], [1e3, 1e3]));
    }
}
