//! Seed 000's mine section: tunnels as polylines of their walking line, readers mounted on the
//! tunnel walls, a reader broken by a collapse, the danger zone around it, the rockfall that
//! blocks radio into it, and the radio visibility between two points through the tunnels.
//!
//! Radio at 2.4 GHz does not cross rock: a tag and a reader hear each other in line of sight
//! along the tunnels, and around a corner or through a pillar only with a large extra loss
//! ([`MineLayout::excess_loss_db`]). This is why mines put readers at every junction, and why
//! a broken reader behind a rockfall leaves a coverage hole.
//!
//! # Units
//! Positions in m (`z` up, the mine entrance at the origin), losses in dB.

mod walking_line;

pub use walking_line::WalkingLine;

use crate::error::{finite, positive, Result, SimError};
use crate::sensors::readers::{distance_m, Reader, ReaderStatus};

/// Readers are mounted this far inside the rock wall (m), so their antenna lies in the tunnel.
pub const WALL_INSET_M: f64 = 0.2;

/// Spacing of the points at which a line of sight is checked against the tunnels (m).
const SIGHT_STEP_M: f64 = 0.25;

/// Slack on the tunnel half-width when checking a line of sight (m): the wall's roughness.
const SIGHT_SLACK_M: f64 = 0.05;

/// A tunnel (decline, drift, cross-cut) as the polyline of its walking line (the height at
/// which tags are worn), with its half-width.
///
/// # Example
/// ```
/// use rtls_sim::scenarios::seed_000::Tunnel;
/// let drift = Tunnel::new("drift", vec![[0.0, 0.0, 0.0], [30.0, 40.0, -1.0]], 2.0)?;
/// let (point, direction) = drift.point_at(25.0)?;
/// assert!((point[0] - 15.0).abs() < 0.01 && (direction[1] - 0.8).abs() < 1e-3);
/// assert!(drift.plan_distance_m([3.0, 4.0]) < 1e-12);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Tunnel {
    name: String,
    centreline_m: Vec<[f64; 3]>,
    half_width_m: f64,
    /// Cumulative 3-D length at each vertex (m).
    chainage_m: Vec<f64>,
}

impl Tunnel {
    /// A tunnel through `centreline_m` (at least two distinct vertices) of half-width
    /// `half_width_m`.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for fewer than two vertices; [`SimError::NonFinite`] for NaN/∞;
    /// [`SimError::InvalidParameter`] for a non-positive width or two equal consecutive vertices.
    pub fn new(name: impl Into<String>, centreline_m: Vec<[f64; 3]>, half_width_m: f64) -> Result<Self> {
        if centreline_m.len() < 2 {
            return Err(SimError::EmptyInput {
                what: "tunnel centreline (needs at least two vertices)",
            });
        }
        positive(half_width_m, "half_width_m", "a tunnel needs a positive half-width")?;
        let mut chainage_m = vec![0.0];
        for pair in centreline_m.windows(2) {
            for c in pair[1].iter().chain(&pair[0]) {
                finite(*c, "tunnel vertex")?;
            }
            let length = distance_m(pair[0], pair[1]);
            if plan_length(pair[0], pair[1]) < 1e-9 {
                return Err(SimError::InvalidParameter {
                    name: "centreline_m",
                    reason: "consecutive tunnel vertices must differ in plan (no vertical shafts)",
                });
            }
            chainage_m.push(chainage_m[chainage_m.len() - 1] + length);
        }
        Ok(Self {
            name: name.into(),
            centreline_m,
            half_width_m,
            chainage_m,
        })
    }

    /// Name.
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Vertices of the walking line, m.
    #[must_use]
    pub fn centreline_m(&self) -> &[[f64; 3]] {
        &self.centreline_m
    }

    /// Half-width, m.
    #[must_use]
    pub fn half_width_m(&self) -> f64 {
        self.half_width_m
    }

    /// Length along the walking line, m.
    #[must_use]
    pub fn length_m(&self) -> f64 {
        self.chainage_m[self.chainage_m.len() - 1]
    }

    /// The point at `chainage_m` along the walking line and the unit plan direction of travel
    /// there.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`chainage_m`) outside `[0, length]`.
    pub fn point_at(&self, chainage_m: f64) -> Result<([f64; 3], [f64; 2])> {
        finite(chainage_m, "chainage")?;
        if !(0.0..=self.length_m()).contains(&chainage_m) {
            return Err(SimError::InvalidParameter {
                name: "chainage_m",
                reason: "the chainage must lie between 0 and the tunnel's length",
            });
        }
        let leg = self
            .chainage_m
            .partition_point(|&c| c <= chainage_m)
            .clamp(1, self.centreline_m.len() - 1)
            - 1;
        let (a, b) = (self.centreline_m[leg], self.centreline_m[leg + 1]);
        // u = (s − s_a)/(s_b − s_a) along the leg
        let u = (chainage_m - self.chainage_m[leg]) / (self.chainage_m[leg + 1] - self.chainage_m[leg]);
        let point = [
            a[0] + u * (b[0] - a[0]),
            a[1] + u * (b[1] - a[1]),
            a[2] + u * (b[2] - a[2]),
        ];
        let plan = plan_length(a, b);
        Ok((point, [(b[0] - a[0]) / plan, (b[1] - a[1]) / plan]))
    }

    /// Distance in plan from `point_m` to the walking line, m.
    #[must_use]
    pub fn plan_distance_m(&self, point_m: [f64; 2]) -> f64 {
        self.centreline_m
            .windows(2)
            .map(|pair| segment_distance(point_m, [pair[0][0], pair[0][1]], [pair[1][0], pair[1][1]]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Which wall a reader hangs on, looking along increasing chainage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Wall {
    /// Left of the direction of travel.
    Left,
    /// Right of the direction of travel.
    Right,
}

/// An axis-aligned area in plan (`min_m ≤ (x, y) ≤ max_m`), any height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanBox {
    /// Lower corner `(x, y)`, m.
    pub min_m: [f64; 2],
    /// Upper corner `(x, y)`, m.
    pub max_m: [f64; 2],
}

impl PlanBox {
    /// Whether `point_m` lies in the box (in plan).
    #[must_use]
    pub fn contains(&self, point_m: [f64; 3]) -> bool {
        (self.min_m[0]..=self.max_m[0]).contains(&point_m[0]) && (self.min_m[1]..=self.max_m[1]).contains(&point_m[1])
    }

    /// The outline `min → … → min` for drawing.
    #[must_use]
    pub fn outline(&self) -> Vec<[f64; 2]> {
        let ([x0, y0], [x1, y1]) = (self.min_m, self.max_m);
        vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]
    }
}

/// A danger zone (e.g. a collapsed area): entering it raises an alarm.
#[derive(Debug, Clone, PartialEq)]
pub struct DangerZone {
    /// Label.
    pub name: String,
    /// Its area in plan.
    pub area: PlanBox,
}

/// A wall of debris (a rockfall) across a tunnel, in plan: radio crossing it loses `loss_db`.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstruction {
    /// Label.
    pub name: String,
    /// One end `(x, y)`, m.
    pub from_m: [f64; 2],
    /// Other end `(x, y)`, m.
    pub to_m: [f64; 2],
    /// Loss of a path crossing it, dB.
    pub loss_db: f64,
}

/// Seed 000's mine section: tunnels, readers, danger zones and rockfalls, with the radio
/// visibility between points.
///
/// # Example
/// ```
/// use rtls_sim::scenarios::seed_000::{MineLayout, Tunnel};
/// let l = vec![
///     Tunnel::new("east", vec![[0.0, 0.0, 0.0], [40.0, 0.0, 0.0]], 2.0)?,
///     Tunnel::new("north", vec![[40.0, 0.0, 0.0], [40.0, 40.0, 0.0]], 2.0)?,
/// ];
/// let mine = MineLayout::new(l, Vec::new(), Vec::new(), Vec::new(), 25.0)?;
/// assert!(mine.line_of_sight([0.0, 0.0, 0.0], [40.0, 1.0, 1.0]));
/// assert!(!mine.line_of_sight([20.0, 0.0, 0.0], [40.0, 20.0, 0.0])); // through the pillar
/// assert_eq!(mine.path_loss_db([20.0, 0.0, 0.0], [40.0, 20.0, 0.0]), 25.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 §3.3 and Fig. 2 (readers along the roadways, a reader broken by a collapse, a
/// danger zone without coverage); A. E. Forooshani, S. Bashir, D. G. Michelson, S. Noghanian,
/// "A survey of wireless communications and propagation modeling in underground mines",
/// *IEEE Communications Surveys & Tutorials* 15(4), 2013 (tunnels guide 2.4 GHz radio; corners
/// and rock add tens of dB).
#[derive(Debug, Clone, PartialEq)]
pub struct MineLayout {
    tunnels: Vec<Tunnel>,
    readers: Vec<Reader>,
    zones: Vec<DangerZone>,
    obstructions: Vec<Obstruction>,
    nlos_loss_db: f64,
}

impl MineLayout {
    /// A layout; `nlos_loss_db` is the extra loss of a path that leaves the tunnels (around a
    /// corner, through a pillar).
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] without tunnels; [`SimError::InvalidParameter`] for a negative
    /// loss, an empty zone, a degenerate obstruction or a reader outside every tunnel.
    pub fn new(
        tunnels: Vec<Tunnel>,
        readers: Vec<Reader>,
        zones: Vec<DangerZone>,
        obstructions: Vec<Obstruction>,
        nlos_loss_db: f64,
    ) -> Result<Self> {
        if tunnels.is_empty() {
            return Err(SimError::EmptyInput { what: "tunnels" });
        }
        let reason = "the loss must be finite and ≥ 0 dB";
        crate::error::non_negative(nlos_loss_db, "nlos_loss_db", reason)?;
        for zone in &zones {
            if !(zone.area.min_m[0] < zone.area.max_m[0] && zone.area.min_m[1] < zone.area.max_m[1]) {
                return Err(SimError::InvalidParameter {
                    name: "danger_zones",
                    reason: "a zone needs min_m < max_m on both axes",
                });
            }
        }
        for o in &obstructions {
            crate::error::non_negative(o.loss_db, "loss_db", reason)?;
            if plan_length([o.from_m[0], o.from_m[1], 0.0], [o.to_m[0], o.to_m[1], 0.0]) < 1e-9 {
                return Err(SimError::InvalidParameter {
                    name: "obstructions",
                    reason: "an obstruction needs two distinct ends",
                });
            }
        }
        let layout = Self {
            tunnels,
            readers,
            zones,
            obstructions,
            nlos_loss_db,
        };
        if layout.readers.iter().any(|r| !layout.inside_tunnels(r.position_m)) {
            return Err(SimError::InvalidParameter {
                name: "readers",
                reason: "every reader must be mounted inside a tunnel",
            });
        }
        Ok(layout)
    }

    /// The reader at `chainage_m` of `tunnel` on `wall`, `height_m` above the walking line.
    ///
    /// # Errors
    /// As [`Tunnel::point_at`]; [`SimError::InvalidParameter`] (`height_m`) for NaN/∞.
    pub fn mount(tunnel: &Tunnel, chainage_m: f64, wall: Wall, height_m: f64) -> Result<[f64; 3]> {
        finite(height_m, "reader height")?;
        let (point, [dx, dy]) = tunnel.point_at(chainage_m)?;
        // left normal of the direction (dx, dy) is (−dy, dx)
        let side = match wall {
            Wall::Left => 1.0,
            Wall::Right => -1.0,
        };
        let offset = side * (tunnel.half_width_m - WALL_INSET_M).max(0.0);
        Ok([point[0] - dy * offset, point[1] + dx * offset, point[2] + height_m])
    }

    /// The tunnels.
    #[must_use]
    pub fn tunnels(&self) -> &[Tunnel] {
        &self.tunnels
    }

    /// The readers.
    #[must_use]
    pub fn readers(&self) -> &[Reader] {
        &self.readers
    }

    /// The danger zones.
    #[must_use]
    pub fn zones(&self) -> &[DangerZone] {
        &self.zones
    }

    /// The rockfalls.
    #[must_use]
    pub fn obstructions(&self) -> &[Obstruction] {
        &self.obstructions
    }

    /// Whether `point_m` lies inside some tunnel (in plan).
    #[must_use]
    pub fn inside_tunnels(&self, point_m: [f64; 3]) -> bool {
        let p = [point_m[0], point_m[1]];
        self.tunnels
            .iter()
            .any(|t| t.plan_distance_m(p) <= t.half_width_m + SIGHT_SLACK_M)
    }

    /// Whether `point_m` lies in any danger zone.
    #[must_use]
    pub fn in_danger_zone(&self, point_m: [f64; 3]) -> bool {
        self.zones.iter().any(|z| z.area.contains(point_m))
    }

    /// Whether the straight path `a → b` stays inside the tunnels (checked in plan every
    /// 0.25 m).
    #[must_use]
    pub fn line_of_sight(&self, a_m: [f64; 3], b_m: [f64; 3]) -> bool {
        let steps = (plan_length(a_m, b_m) / SIGHT_STEP_M).ceil().max(1.0) as usize;
        (0..=steps).all(|k| {
            let u = k as f64 / steps as f64;
            // p = a + u (b − a)
            self.inside_tunnels([a_m[0] + u * (b_m[0] - a_m[0]), a_m[1] + u * (b_m[1] - a_m[1]), 0.0])
        })
    }

    /// Extra loss of the radio path `a → b` beyond the log-distance law, dB: `nlos_loss_db` if
    /// it leaves the tunnels, plus the loss of every rockfall it crosses.
    #[must_use]
    pub fn path_loss_db(&self, a_m: [f64; 3], b_m: [f64; 3]) -> f64 {
        let walls = if self.line_of_sight(a_m, b_m) {
            0.0
        } else {
            self.nlos_loss_db
        };
        let debris: f64 = self
            .obstructions
            .iter()
            .filter(|o| segments_cross([a_m[0], a_m[1]], [b_m[0], b_m[1]], o.from_m, o.to_m))
            .map(|o| o.loss_db)
            .sum();
        walls + debris
    }

    /// [`Self::path_loss_db`] from `tag_m` to every reader, in reader order.
    #[must_use]
    pub fn excess_loss_db(&self, tag_m: [f64; 3]) -> Vec<f64> {
        self.readers
            .iter()
            .map(|r| self.path_loss_db(tag_m, r.position_m))
            .collect()
    }

    /// Reader pairs that can talk directly: both working, within `range_m` of each other and
    /// with no excess loss between them (line of sight, no rockfall). Pairs `(i, j)`, `i < j`.
    #[must_use]
    pub fn reader_links(&self, range_m: f64) -> Vec<(usize, usize)> {
        let mut links = Vec::new();
        for i in 0..self.readers.len() {
            for j in i + 1..self.readers.len() {
                let (a, b) = (&self.readers[i], &self.readers[j]);
                if a.status == ReaderStatus::Working
                    && b.status == ReaderStatus::Working
                    && distance_m(a.position_m, b.position_m) <= range_m
                    && self.path_loss_db(a.position_m, b.position_m) == 0.0
                {
                    links.push((i, j));
                }
            }
        }
        links
    }
}

/// Plan length of `a → b`, m.
pub(super) fn plan_length(a: [f64; 3], b: [f64; 3]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Distance from `p` to the segment `a → b` in the plane.
pub(super) fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    // u = clamp(((p − a)·(b − a)) / |b − a|², 0, 1)
    let u = if length2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - u * dx).hypot(p[1] - a[1] - u * dy)
}

/// Whether the segments `p → q` and `r → s` cross (proper intersection or touching).
fn segments_cross(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> bool {
    // orientation of (a, b, c): sign of (b − a) × (c − a)
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let (d1, d2) = (orient(r, s, p), orient(r, s, q));
    let (d3, d4) = (orient(p, q, r), orient(p, q, s));
    d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && !(d1 == 0.0 && d2 == 0.0)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    pub(super) fn l_mine() -> MineLayout {
        let tunnels = vec![
            Tunnel::new("east", vec![[0.0, 0.0, 0.0], [40.0, 0.0, -1.0]], 2.0).unwrap(),
            Tunnel::new("north", vec![[40.0, 0.0, -1.0], [40.0, 40.0, -1.0]], 2.0).unwrap(),
        ];
        let reader = |position_m, status| Reader {
            name: String::new(),
            position_m,
            status,
            obstacle_loss_db: 0.0,
        };
        let readers = vec![
            reader(
                MineLayout::mount(&tunnels[0], 5.0, Wall::Left, 1.0).unwrap(),
                ReaderStatus::Working,
            ),
            reader(
                MineLayout::mount(&tunnels[0], 20.0, Wall::Right, 1.0).unwrap(),
                ReaderStatus::Working,
            ),
            reader(
                MineLayout::mount(&tunnels[1], 30.0, Wall::Left, 1.0).unwrap(),
                ReaderStatus::Broken,
            ),
        ];
        let zone = DangerZone {
            name: "collapse".into(),
            area: PlanBox {
                min_m: [38.0, 25.0],
                max_m: [42.0, 40.0],
            },
        };
        let debris = Obstruction {
            name: "rockfall".into(),
            from_m: [37.5, 25.0],
            to_m: [42.5, 25.0],
            loss_db: 30.0,
        };
        MineLayout::new(tunnels, readers, vec![zone], vec![debris], 25.0).unwrap()
    }

    #[test]
    fn readers_hang_on_the_walls_and_sight_follows_the_tunnels() {
        let mine = l_mine();
        // left of +x is +y: 1.8 m from the walking line, 1 m above it
        let r0 = mine.readers()[0].position_m;
        assert!((r0[0] - 5.0).abs() < 1e-2 && (r0[1] - 1.8).abs() < 1e-9 && r0[2] > 0.8);
        assert!((mine.readers()[1].position_m[1] + 1.8).abs() < 1e-9);
        // along the east drift: line of sight; into the north drift past the corner: none
        assert!(mine.line_of_sight(r0, [39.0, 0.0, -1.0]));
        assert!(!mine.line_of_sight(r0, [40.0, 15.0, -1.0]));
        assert_eq!(mine.path_loss_db(r0, [40.0, 15.0, -1.0]), 25.0);
        // the rockfall adds its loss on top, the corner path does not cross it
        assert_eq!(mine.path_loss_db([40.0, 20.0, -1.0], [40.0, 30.0, -1.0]), 30.0);
        // the broken reader round the corner is out of sight
        assert_eq!(mine.excess_loss_db([10.0, 0.0, 0.0]), vec![0.0, 0.0, 25.0]);
        assert!(mine.in_danger_zone([40.0, 30.0, 0.0]) && !mine.in_danger_zone([40.0, 20.0, 0.0]));
        // readers 0 and 1 talk; the broken one never
        assert_eq!(mine.reader_links(20.0), vec![(0, 1)]);
        assert!(mine.reader_links(10.0).is_empty());
    }

    #[test]
    fn chainage_and_crossings() {
        let t = Tunnel::new("t", vec![[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [3.0, 10.0, 0.0]], 1.0).unwrap();
        assert!((t.length_m() - 11.0).abs() < 1e-12);
        let (p, d) = t.point_at(8.0).unwrap();
        assert!((p[1] - 7.0).abs() < 1e-12 && d == [0.0, 1.0]);
        assert!(t.point_at(11.5).is_err());
        assert!(segments_cross([0.0, 0.0], [2.0, 2.0], [0.0, 2.0], [2.0, 0.0]));
        assert!(!segments_cross([0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]));
        assert!((segment_distance([1.0, 5.0], [0.0, 0.0], [2.0, 0.0]) - 5.0).abs() < 1e-12);
    }

    #[test]
    fn bad_layouts_are_errors() {
        assert!(Tunnel::new("t", vec![[0.0; 3]], 1.0).is_err());
        assert!(Tunnel::new("t", vec![[0.0; 3], [0.0, 0.0, 5.0]], 1.0).is_err());
        assert!(Tunnel::new("t", vec![[0.0; 3], [1.0, 0.0, 0.0]], 0.0).is_err());
        let t = Tunnel::new("t", vec![[0.0; 3], [10.0, 0.0, 0.0]], 1.0).unwrap();
        assert!(MineLayout::new(Vec::new(), Vec::new(), Vec::new(), Vec::new(), 20.0).is_err());
        assert!(MineLayout::new(vec![t.clone()], Vec::new(), Vec::new(), Vec::new(), -1.0).is_err());
        let outside = Reader {
            name: String::new(),
            position_m: [5.0, 9.0, 0.0],
            status: ReaderStatus::Working,
            obstacle_loss_db: 0.0,
        };
        assert!(MineLayout::new(vec![t], vec![outside], Vec::new(), Vec::new(), 20.0).is_err());
    }
}
