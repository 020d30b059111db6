//! Seed 003's test bed: sensor nodes on the corners of a grid of square cells, and robots
//! driving waypoint routes across it.
//!
//! The paper's bed is 4 m × 6 m ((0, 0)–(400, 600) cm) split into 6 cells of 2 m × 2 m; the 12
//! nodes are the 3 × 4 grid of cell corners, so every cell has 4 nodes and inner nodes are
//! shared by 2 or 4 cells. Nodes are numbered row by row from `(0, 0)`, cells likewise.

use crate::error::{finite2, positive, Result, SimError};
use crate::trajectory::{Waypoint, WaypointPath};

/// A rectangular bed `[0, width] × [0, height]` divided into square cells with a node on every
/// cell corner.
///
/// # Units
/// Metres.
///
/// # Example
/// ```
/// use rtls_sim::scenarios::seed_003::TestBed;
/// let bed = TestBed::paper();
/// assert_eq!((bed.nodes_m().len(), bed.cell_count()), (12, 6));
/// assert_eq!(bed.cell_of([3.0, 5.0]), 5);
/// assert_eq!(bed.cell_nodes(5).map(|n| bed.nodes_m()[n]), [[2.0, 4.0], [4.0, 4.0], [2.0, 6.0], [4.0, 6.0]]);
/// // the three nodes of cell 0 nearest to (1.8, 0.5)
/// assert_eq!(bed.nearest_cell_nodes(0, [1.8, 0.5], 3), vec![1, 4, 0]);
/// ```
///
/// # References
/// Seed 003 §1 (12 nodes over 4 m × 6 m, 6 cells of 2 m × 2 m with 4 nodes each).
#[derive(Debug, Clone, PartialEq)]
pub struct TestBed {
    cell_side_m: f64,
    /// Cells along x and y.
    cells: [usize; 2],
    nodes_m: Vec<[f64; 2]>,
}

/// A cell border near a point: the cell on the other side and the two nodes the cells share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NearBorder {
    /// The neighbouring cell across the border.
    pub neighbour: usize,
    /// The two nodes at the ends of the shared border.
    pub shared_nodes: [usize; 2],
}

impl TestBed {
    /// A bed of `width_m × height_m` cut into cells of side `cell_side_m`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`cell_side_m`) unless the width and height are positive
    /// whole multiples of the cell side (to 1e-9 relative), or for more than 10⁴ cells;
    /// [`SimError::NonFinite`] for NaN/∞.
    pub fn new(width_m: f64, height_m: f64, cell_side_m: f64) -> Result<Self> {
        positive(width_m, "width_m", "the bed width must be positive")?;
        positive(height_m, "height_m", "the bed height must be positive")?;
        positive(cell_side_m, "cell_side_m", "the cell side must be positive")?;
        let count = |length: f64| {
            let n = (length / cell_side_m).round();
            ((length / cell_side_m - n).abs() < 1e-9 * n.max(1.0) && (1.0..=1e4).contains(&n)).then_some(n as usize)
        };
        let (Some(nx), Some(ny)) = (count(width_m), count(height_m)) else {
            return Err(SimError::InvalidParameter {
                name: "cell_side_m",
                reason: "the bed's width and height must be whole multiples of the cell side (at most 10⁴ cells)",
            });
        };
        if nx * ny > 10_000 {
            return Err(SimError::InvalidParameter {
                name: "cell_side_m",
                reason: "the bed must have at most 10⁴ cells",
            });
        }
        let nodes_m = (0..=ny)
            .flat_map(|row| (0..=nx).map(move |col| [col as f64 * cell_side_m, row as f64 * cell_side_m]))
            .collect();
        Ok(Self {
            cell_side_m,
            cells: [nx, ny],
            nodes_m,
        })
    }

    /// Seed 003's bed: 4 m × 6 m, cells of 2 m.
    #[must_use]
    pub fn paper() -> Self {
        let side = 2.0;
        let nodes_m = (0..=3)
            .flat_map(|row| (0..=2).map(move |col| [col as f64 * side, row as f64 * side]))
            .collect();
        Self {
            cell_side_m: side,
            cells: [2, 3],
            nodes_m,
        }
    }

    /// Node positions `(x, y)` (m), row by row from `(0, 0)`.
    #[must_use]
    pub fn nodes_m(&self) -> &[[f64; 2]] {
        &self.nodes_m
    }

    /// Width and height of the bed (m).
    #[must_use]
    pub fn size_m(&self) -> [f64; 2] {
        [
            self.cells[0] as f64 * self.cell_side_m,
            self.cells[1] as f64 * self.cell_side_m,
        ]
    }

    /// Cell side (m).
    #[must_use]
    pub fn cell_side_m(&self) -> f64 {
        self.cell_side_m
    }

    /// Number of cells.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.cells[0] * self.cells[1]
    }

    /// The cell holding `point_m` (points outside the bed, or NaN, are clamped into it; a point
    /// on a border belongs to the cell above / to the right of it).
    #[must_use]
    pub fn cell_of(&self, point_m: [f64; 2]) -> usize {
        let [col, row] = self.cell_coordinates(point_m);
        row * self.cells[0] + col
    }

    /// `[column, row]` of the cell holding `point_m` (clamped).
    fn cell_coordinates(&self, point_m: [f64; 2]) -> [usize; 2] {
        let index = |v: f64, n: usize| {
            let k = (v / self.cell_side_m).floor();
            if k.is_nan() || k < 0.0 {
                0
            } else {
                (k as usize).min(n - 1)
            }
        };
        [index(point_m[0], self.cells[0]), index(point_m[1], self.cells[1])]
    }

    /// The four corner nodes of `cell` (clamped to the last cell): lower-left, lower-right,
    /// upper-left, upper-right.
    #[must_use]
    pub fn cell_nodes(&self, cell: usize) -> [usize; 4] {
        let cell = cell.min(self.cell_count() - 1);
        let (col, row) = (cell % self.cells[0], cell / self.cells[0]);
        let stride = self.cells[0] + 1;
        let ll = row * stride + col;
        [ll, ll + 1, ll + stride, ll + stride + 1]
    }

    /// The `k` nodes of `cell` nearest to `point_m`, nearest first (ties by node index).
    #[must_use]
    pub fn nearest_cell_nodes(&self, cell: usize, point_m: [f64; 2], k: usize) -> Vec<usize> {
        let mut nodes: Vec<(f64, usize)> = self
            .cell_nodes(cell)
            .into_iter()
            .map(|n| (distance_m(self.nodes_m[n], point_m), n))
            .collect();
        nodes.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        nodes.into_iter().take(k).map(|(_, n)| n).collect()
    }

    /// The inner borders of `point_m`'s cell that lie within `margin_m` of it (seed 003's edge
    /// zone), with the cells across them; a point near a corner also gets the diagonal cell,
    /// whose shared "border" is the corner node (listed twice).
    #[must_use]
    pub fn nearby_borders(&self, point_m: [f64; 2], margin_m: f64) -> Vec<NearBorder> {
        let [col, row] = self.cell_coordinates(point_m);
        let side = self.cell_side_m;
        let stride = self.cells[0] + 1;
        // −1, 0 or +1: which neighbouring column / row is within the margin
        let step = |v: f64, index: usize, n: usize| -> i64 {
            let low = index as f64 * side;
            if index > 0 && v - low < margin_m {
                -1
            } else if index + 1 < n && low + side - v < margin_m {
                1
            } else {
                0
            }
        };
        let dx = step(point_m[0], col, self.cells[0]);
        let dy = step(point_m[1], row, self.cells[1]);
        let mut borders = Vec::new();
        let node = |c: i64, r: i64| (r as usize) * stride + c as usize;
        let (c, r) = (col as i64, row as i64);
        // corner column / row of the border being approached
        let bx = if dx > 0 { c + 1 } else { c };
        let by = if dy > 0 { r + 1 } else { r };
        let cell = |c: i64, r: i64| (r as usize) * self.cells[0] + c as usize;
        if dx != 0 {
            borders.push(NearBorder {
                neighbour: cell(c + dx, r),
                shared_nodes: [node(bx, r), node(bx, r + 1)],
            });
        }
        if dy != 0 {
            borders.push(NearBorder {
                neighbour: cell(c, r + dy),
                shared_nodes: [node(c, by), node(c + 1, by)],
            });
        }
        if dx != 0 && dy != 0 {
            borders.push(NearBorder {
                neighbour: cell(c + dx, r + dy),
                shared_nodes: [node(bx, by), node(bx, by)],
            });
        }
        borders
    }

    /// Distance from `point_m` to the nearest inner cell border (m); `∞` for a bed of one cell.
    #[must_use]
    pub fn distance_to_inner_border_m(&self, point_m: [f64; 2]) -> f64 {
        let side = self.cell_side_m;
        let nearest = |v: f64, n: usize| {
            (1..n)
                .map(|k| (v - k as f64 * side).abs())
                .fold(f64::INFINITY, f64::min)
        };
        nearest(point_m[0], self.cells[0]).min(nearest(point_m[1], self.cells[1]))
    }

    /// One polyline that draws every cell border (outline, then the inner lines in a
    /// serpentine; some segments are traced twice), for maps.
    #[must_use]
    pub fn grid_polyline_m(&self) -> Vec<[f64; 2]> {
        let [w, h] = self.size_m();
        let side = self.cell_side_m;
        let mut line = vec![[0.0, 0.0], [w, 0.0], [w, h], [0.0, h], [0.0, 0.0]];
        // horizontal lines, alternating direction, starting on the left wall
        for row in 1..self.cells[1] {
            let y = row as f64 * side;
            let (from, to) = if row % 2 == 1 { (0.0, w) } else { (w, 0.0) };
            line.push([from, y]);
            line.push([to, y]);
        }
        // back to the bottom along the wall we ended on, then the vertical lines
        let wall_x = line.last().map_or(0.0, |p| p[0]);
        line.push([wall_x, 0.0]);
        line.push([0.0, 0.0]);
        for col in 1..self.cells[0] {
            let x = col as f64 * side;
            let (from, to) = if col % 2 == 1 { (0.0, h) } else { (h, 0.0) };
            line.push([x, from]);
            line.push([x, to]);
        }
        line
    }
}

/// A planar route at one speed through `points_m` (z = 0), waiting `start_delay_s` before the
/// first leg and `pauses_s[i]` at `points_m[i]` (missing entries: no pause).
///
/// # Errors
/// As [`WaypointPath::new`]; [`SimError::LengthMismatch`] for more pauses than points.
///
/// # Example
/// ```
/// let route = rtls_sim::scenarios::seed_003::planar_route(&[[0.8, 0.7], [3.2, 0.7]], 0.5, 1.0, &[])?;
/// assert!((route.duration_s() - (1.0 + 4.8)).abs() < 1e-12); // 1 s wait, 2.4 m at 0.5 m/s
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 003 §4 (robots at 0.5 m/s).
pub fn planar_route(
    points_m: &[[f64; 2]],
    speed_mps: f64,
    start_delay_s: f64,
    pauses_s: &[f64],
) -> Result<WaypointPath> {
    if pauses_s.len() > points_m.len() {
        return Err(SimError::LengthMismatch {
            what: "route pauses vs waypoints",
            expected: points_m.len(),
            found: pauses_s.len(),
        });
    }
    let waypoints = points_m
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            finite2(p, "route waypoint")?;
            let pause_s = if i == 0 { start_delay_s } else { 0.0 } + pauses_s.get(i).copied().unwrap_or(0.0);
            Ok(Waypoint {
                position_m: [p[0], p[1], 0.0],
                speed_mps,
                pause_s,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    WaypointPath::new(waypoints)
}

/// The time intervals in `[0, duration_s]` during which at least two of `routes` are in the same
/// cell (seed 003's limit ①), sampled every `step_s`: `(start_s, end_s)` pairs.
///
/// # Errors
/// [`SimError::InvalidParameter`] (`step_s`) for a non-positive step; as
/// [`WaypointPath::state_at`] if a route is shorter than `duration_s`.
pub fn shared_cell_intervals(
    bed: &TestBed,
    routes: &[WaypointPath],
    duration_s: f64,
    step_s: f64,
) -> Result<Vec<(f64, f64)>> {
    positive(step_s, "step_s", "the sampling step must be positive")?;
    let steps = (duration_s / step_s).floor() as usize;
    let mut intervals: Vec<(f64, f64)> = Vec::new();
    let mut open: Option<f64> = None;
    for k in 0..=steps {
        let t = (k as f64 * step_s).min(duration_s);
        let mut cells = routes
            .iter()
            .map(|r| r.state_at(t).map(|s| bed.cell_of([s.position_m[0], s.position_m[1]])))
            .collect::<Result<Vec<_>>>()?;
        cells.sort_unstable();
        let shared = cells.windows(2).any(|w| w[0] == w[1]);
        match (shared, open) {
            (true, None) => open = Some(t),
            (false, Some(start)) => {
                intervals.push((start, t));
                open = None;
            }
            _ => {}
        }
    }
    if let Some(start) = open {
        intervals.push((start, duration_s));
    }
    Ok(intervals)
}

fn distance_m(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_bed_matches_its_general_construction() {
        let bed = TestBed::paper();
        assert_eq!(TestBed::new(4.0, 6.0, 2.0).unwrap(), bed);
        assert_eq!(bed.nodes_m()[11], [4.0, 6.0]);
        assert_eq!(bed.size_m(), [4.0, 6.0]);
        // every cell's corners are 2 m apart and the cell holds its own centre
        for cell in 0..6 {
            let [ll, lr, ul, ur] = bed.cell_nodes(cell).map(|n| bed.nodes_m()[n]);
            assert_eq!(
                (lr[0] - ll[0], ul[1] - ll[1], ur),
                (2.0, 2.0, [ll[0] + 2.0, ll[1] + 2.0])
            );
            assert_eq!(bed.cell_of([ll[0] + 1.0, ll[1] + 1.0]), cell);
        }
        assert_eq!(bed.cell_of([-5.0, 99.0]), 4);
        assert_eq!(bed.cell_of([f64::NAN, 0.0]), 0);
        assert!(TestBed::new(4.0, 5.0, 2.0).is_err());
        assert!(TestBed::new(4.0, 6.0, 0.0).is_err());
    }

    #[test]
    fn edge_zones_name_the_neighbour_and_the_shared_nodes() {
        let bed = TestBed::paper();
        // cell 0, 0.1 m left of x = 2: neighbour cell 1, shared nodes (2,0) and (2,2)
        assert_eq!(
            bed.nearby_borders([1.9, 1.0], 0.3),
            vec![NearBorder {
                neighbour: 1,
                shared_nodes: [1, 4]
            }]
        );
        // cell 3 near its lower border y = 2 and left border x = 2: cells 2, 1 and 0
        let near = bed.nearby_borders([2.1, 2.2], 0.3);
        let neighbours: Vec<usize> = near.iter().map(|b| b.neighbour).collect();
        assert_eq!(neighbours, vec![2, 1, 0]);
        assert_eq!(near[2].shared_nodes, [4, 4]);
        // the outer walls are not borders; the middle of a cell is in no edge zone
        assert!(bed.nearby_borders([0.1, 0.1], 0.3).is_empty());
        assert!(bed.nearby_borders([1.0, 3.0], 0.3).is_empty());
        assert!((bed.distance_to_inner_border_m([1.0, 3.7]) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn the_grid_polyline_covers_every_border() {
        let bed = TestBed::paper();
        let line = bed.grid_polyline_m();
        let on_line = |p: [f64; 2]| {
            line.windows(2).any(|w| {
                let (a, b) = (w[0], w[1]);
                let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
                let within = (p[0] - a[0]) * (p[0] - b[0]) <= 1e-12 && (p[1] - a[1]) * (p[1] - b[1]) <= 1e-12;
                cross.abs() < 1e-12 && within
            })
        };
        for p in [[2.0, 1.0], [2.0, 5.0], [1.0, 2.0], [3.0, 4.0], [4.0, 3.0], [1.0, 6.0]] {
            assert!(on_line(p), "{p:?}");
        }
    }

    #[test]
    fn shared_cells_are_found() {
        let bed = TestBed::paper();
        let a = planar_route(&[[0.5, 1.0], [3.5, 1.0]], 0.5, 0.0, &[]).unwrap();
        // b drives into cell 1 and waits there; a joins it at t = 3 s
        let b = planar_route(&[[3.5, 0.5], [2.5, 0.5]], 0.5, 0.0, &[0.0, 5.0]).unwrap();
        let intervals = shared_cell_intervals(&bed, &[a, b], 6.0, 0.1).unwrap();
        assert_eq!(intervals.len(), 1, "{intervals:?}");
        let (start, end) = intervals[0];
        assert!((start - 3.0).abs() < 0.11 && end == 6.0, "{intervals:?}");
        assert!(planar_route(&[[0.0, 0.0]], 0.5, 0.0, &[]).is_err());
        assert!(planar_route(&[[0.0, 0.0], [1.0, 0.0]], 0.5, 0.0, &[0.0, 0.0, 1.0]).is_err());
    }
}
