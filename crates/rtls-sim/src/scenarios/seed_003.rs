//! Seed 003's test bed: sensor nodes on the corners of a grid of square cells, and robots
//! driving waypoint routes across it.
//!
//! The paper's bed is 4 m × 6 m ((0, 0)–(400, 600) cm) split into 6 cells of 2 m × 2 m; the 12
//! nodes are the 3 × 4 grid of cell corners, so every cell has 4 nodes and inner nodes are
//! shared by 2 or 4 cells. Nodes are numbered row by row from `(0, 0)`, cells likewise. The
//! geometry the scheduler needs (cell of a point, nearest nodes of a cell, edge zones) is the
//! engine's [`Layout`]; [`TestBed`] adds what the simulation and its figures need on a grid.

use rtls_engine::scheduling::Layout;

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
/// let bed = TestBed::paper()?;
/// assert_eq!((bed.nodes_m().len(), bed.cell_count()), (12, 6));
/// assert_eq!(bed.cell_of([3.0, 5.0]), 5);
/// let corners: Vec<[f64; 2]> = bed.cell_nodes(5).iter().map(|&n| bed.nodes_m()[n]).collect();
/// assert_eq!(corners, vec![[2.0, 4.0], [4.0, 4.0], [2.0, 6.0], [4.0, 6.0]]);
/// // the three nodes of cell 0 nearest to (1.8, 0.5)
/// assert_eq!(bed.layout().nearest_cell_nodes(0, [1.8, 0.5], 3), vec![1, 4, 0]);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 003 §1 (12 nodes over 4 m × 6 m, 6 cells of 2 m × 2 m with 4 nodes each).
#[derive(Debug, Clone, PartialEq)]
pub struct TestBed {
    cell_side_m: f64,
    /// Cells along x and y.
    cells: [usize; 2],
    layout: Layout,
    /// The layout's node positions, in node order.
    nodes_m: Vec<[f64; 2]>,
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
        let layout = Layout::grid(width_m, height_m, cell_side_m).map_err(SimError::from_engine)?;
        let cells = [
            (width_m / cell_side_m).round() as usize,
            (height_m / cell_side_m).round() as usize,
        ];
        let nodes_m = layout.nodes().iter().map(|n| n.position_m).collect();
        Ok(Self {
            cell_side_m,
            cells,
            layout,
            nodes_m,
        })
    }

    /// Seed 003's bed: 4 m × 6 m, cells of 2 m.
    ///
    /// # Errors
    /// None in practice (the paper's bed is a valid grid); as [`TestBed::new`].
    pub fn paper() -> Result<Self> {
        Self::new(4.0, 6.0, 2.0)
    }

    /// The engine's layout of the bed: nodes, cells, neighbours and edge zones.
    #[must_use]
    pub fn layout(&self) -> &Layout {
        &self.layout
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

    /// The cell holding `point_m` ([`Layout::cell_of`]: a point on a border belongs to the cell
    /// above / to the right of it, a point outside the bed to the nearest cell); 0 for NaN.
    #[must_use]
    pub fn cell_of(&self, point_m: [f64; 2]) -> usize {
        self.layout.cell_of(point_m).unwrap_or(0)
    }

    /// The corner nodes of `cell`: lower-left, lower-right, upper-left, upper-right (empty for
    /// an unknown cell).
    #[must_use]
    pub fn cell_nodes(&self, cell: usize) -> &[usize] {
        self.layout.cells().get(cell).map_or(&[], |c| c.nodes.as_slice())
    }

    /// Distance from `point_m` to the nearest inner cell border (m); `∞` for a bed of one cell.
    #[must_use]
    pub fn distance_to_inner_border_m(&self, point_m: [f64; 2]) -> f64 {
        self.layout.distance_to_inner_border_m(point_m)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_bed_is_the_engine_grid() {
        let bed = TestBed::paper().unwrap();
        assert_eq!(TestBed::new(4.0, 6.0, 2.0).unwrap(), bed);
        assert_eq!(bed.layout(), &Layout::grid(4.0, 6.0, 2.0).unwrap());
        assert_eq!(bed.nodes_m()[11], [4.0, 6.0]);
        assert_eq!(bed.size_m(), [4.0, 6.0]);
        // every cell's corners are 2 m apart and the cell holds its own centre
        for cell in 0..6 {
            let corners: Vec<[f64; 2]> = bed.cell_nodes(cell).iter().map(|&n| bed.nodes_m()[n]).collect();
            let [ll, lr, ul, ur] = [corners[0], corners[1], corners[2], corners[3]];
            assert_eq!(
                (lr[0] - ll[0], ul[1] - ll[1], ur),
                (2.0, 2.0, [ll[0] + 2.0, ll[1] + 2.0])
            );
            assert_eq!(bed.cell_of([ll[0] + 1.0, ll[1] + 1.0]), cell);
        }
        assert_eq!(bed.cell_of([-5.0, 99.0]), 4);
        assert_eq!(bed.cell_of([f64::NAN, 0.0]), 0);
        assert!(bed.cell_nodes(6).is_empty());
        assert!((bed.distance_to_inner_border_m([1.0, 3.7]) - 0.3).abs() < 1e-12);
        assert!(TestBed::new(4.0, 5.0, 2.0).is_err());
        assert!(TestBed::new(4.0, 6.0, 0.0).is_err());
    }

    #[test]
    fn the_grid_polyline_covers_every_border() {
        let bed = TestBed::paper().unwrap();
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
        let bed = TestBed::paper().unwrap();
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
