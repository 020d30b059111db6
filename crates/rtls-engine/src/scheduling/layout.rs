//! The sensor layout a scheduler works on: nodes with positions, and rectangular cells, each
//! listing the nodes that serve it (seed 003: a grid of 2 m cells with a node on every corner,
//! so neighbouring cells share the nodes of their common border).

use crate::{EngineError, Result};

/// Tolerance for "touching" and "overlapping" cells (m).
const TOUCH_TOLERANCE_M: f64 = 1e-9;

/// A sensor node.
///
/// # Units
/// Metres (site frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Unique id (as in the site file or the measurement records).
    pub id: String,
    /// Position `[x, y]` (m).
    pub position_m: [f64; 2],
}

/// A rectangular cell `[min_x, max_x) × [min_y, max_y)` and the nodes that serve it.
///
/// # Units
/// Metres (site frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Lower-left corner `[x, y]` (m).
    pub min_m: [f64; 2],
    /// Upper-right corner `[x, y]` (m), above `min_m` on both axes.
    pub max_m: [f64; 2],
    /// Indices (into the layout's nodes) of the nodes serving the cell: at least one.
    pub nodes: Vec<usize>,
}

impl Cell {
    /// Chebyshev distance from `point_m` to the closed rectangle, `max(gap_x, gap_y)` (m): 0
    /// inside or on the border.
    #[must_use]
    pub fn chebyshev_gap_m(&self, point_m: [f64; 2]) -> f64 {
        // gap per axis: how far the point lies outside [min, max]
        let gap = |axis: usize| {
            (self.min_m[axis] - point_m[axis])
                .max(point_m[axis] - self.max_m[axis])
                .max(0.0)
        };
        gap(0).max(gap(1))
    }

    /// Euclidean distance from `point_m` to the closed rectangle (m): 0 inside or on the border.
    #[must_use]
    pub fn distance_m(&self, point_m: [f64; 2]) -> f64 {
        let gap = |axis: usize| {
            (self.min_m[axis] - point_m[axis])
                .max(point_m[axis] - self.max_m[axis])
                .max(0.0)
        };
        gap(0).hypot(gap(1))
    }

    /// Whether `point_m` lies in the half-open rectangle `[min, max)` on both axes.
    #[must_use]
    pub fn contains(&self, point_m: [f64; 2]) -> bool {
        (0..2).all(|a| point_m[a] >= self.min_m[a] && point_m[a] < self.max_m[a])
    }
}

/// A neighbouring cell whose border lies within the edge margin of a point (seed 003's edge
/// zone), with the nodes that monitor the crossing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NearCell {
    /// The neighbouring cell.
    pub cell: usize,
    /// The monitoring nodes: the nodes both cells share (the ends of a shared border, or the
    /// shared corner node of a diagonal neighbour); for cells that share no node, the two nodes
    /// of the neighbour nearest to the point.
    pub monitors: Vec<usize>,
}

/// Nodes and rectangular cells.
///
/// Cells must not overlap (interiors disjoint); two cells are *neighbours* when their closed
/// rectangles touch (a common border or corner), and a border between neighbours is an *inner*
/// border.
///
/// # Example
/// ```
/// use rtls_engine::scheduling::Layout;
/// // seed 003's bed: 4 m × 6 m, cells of 2 m, nodes on the 3 × 4 corners
/// let bed = Layout::grid(4.0, 6.0, 2.0)?;
/// assert_eq!((bed.nodes().len(), bed.cells().len()), (12, 6));
/// assert_eq!(bed.cell_of([3.0, 5.0]), Some(5));
/// // the three nodes of cell 0 nearest to (1.8, 0.5): (2, 0), (2, 2), (0, 0)
/// assert_eq!(bed.nearest_cell_nodes(0, [1.8, 0.5], 3), vec![1, 4, 0]);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Seed 003 §1 (12 nodes over 4 m × 6 m, 6 cells of 2 m × 2 m with 4 nodes each), §3.2 (edge
/// monitoring).
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    nodes: Vec<Node>,
    cells: Vec<Cell>,
    /// Neighbours of each cell, ascending.
    neighbours: Vec<Vec<usize>>,
}

fn invalid(name: &'static str, reason: &'static str) -> EngineError {
    EngineError::InvalidParameter { name, reason }
}

impl Layout {
    /// A layout of `nodes` and `cells`.
    ///
    /// O(cells²) to find the neighbours and check for overlaps.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming the field: `nodes` (none, a duplicate id, a
    /// non-finite position), `cells` (none, a rectangle that is not finite or has no area, two
    /// cells that overlap), `cells.nodes` (a cell without nodes, or a node index out of range).
    pub fn new(nodes: Vec<Node>, cells: Vec<Cell>) -> Result<Self> {
        if nodes.is_empty() {
            return Err(invalid("nodes", "a layout needs at least one node"));
        }
        if nodes.iter().any(|n| !n.position_m.iter().all(|v| v.is_finite())) {
            return Err(invalid("nodes", "node positions must be finite"));
        }
        let mut ids: Vec<&str> = nodes.iter().map(|n| n.id.as_str()).collect();
        ids.sort_unstable();
        if ids.windows(2).any(|w| w[0] == w[1]) {
            return Err(invalid("nodes", "node ids must be unique"));
        }
        if cells.is_empty() {
            return Err(invalid("cells", "a layout needs at least one cell"));
        }
        for cell in &cells {
            let finite = cell.min_m.iter().chain(&cell.max_m).all(|v| v.is_finite());
            if !finite || cell.max_m[0] <= cell.min_m[0] || cell.max_m[1] <= cell.min_m[1] {
                return Err(invalid(
                    "cells",
                    "a cell must be a finite rectangle with max_m above min_m on both axes",
                ));
            }
            if cell.nodes.is_empty() {
                return Err(invalid("cells.nodes", "every cell needs at least one node"));
            }
            if cell.nodes.iter().any(|&n| n >= nodes.len()) {
                return Err(invalid("cells.nodes", "a cell lists a node index beyond the node list"));
            }
        }
        let mut neighbours = vec![Vec::new(); cells.len()];
        for i in 0..cells.len() {
            for j in i + 1..cells.len() {
                let (a, b) = (&cells[i], &cells[j]);
                // overlap of the two rectangles per axis (negative: a gap)
                let overlap = |axis: usize| a.max_m[axis].min(b.max_m[axis]) - a.min_m[axis].max(b.min_m[axis]);
                let (ox, oy) = (overlap(0), overlap(1));
                if ox > TOUCH_TOLERANCE_M && oy > TOUCH_TOLERANCE_M {
                    return Err(invalid("cells", "cells must not overlap"));
                }
                if ox >= -TOUCH_TOLERANCE_M && oy >= -TOUCH_TOLERANCE_M {
                    neighbours[i].push(j);
                    neighbours[j].push(i);
                }
            }
        }
        Ok(Self {
            nodes,
            cells,
            neighbours,
        })
    }

    /// A `width_m × height_m` bed cut into square cells of side `cell_side_m` with a node on
    /// every cell corner: nodes numbered row by row from `(0, 0)` (ids `"n0"`, `"n1"`, …), cells
    /// likewise, each cell listing its corners lower-left, lower-right, upper-left, upper-right.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`cell_side_m`) unless the width and height are
    /// positive, finite, whole multiples of the cell side (to 1e-9 relative) with at most 10⁴
    /// cells.
    pub fn grid(width_m: f64, height_m: f64, cell_side_m: f64) -> Result<Self> {
        let count = |length: f64| {
            let n = (length / cell_side_m).round();
            let whole = (length / cell_side_m - n).abs() < 1e-9 * n.max(1.0);
            (length.is_finite() && cell_side_m.is_finite() && cell_side_m > 0.0 && whole && (1.0..=1e4).contains(&n))
                .then_some(n as usize)
        };
        let (Some(nx), Some(ny)) = (count(width_m), count(height_m)) else {
            return Err(invalid(
                "cell_side_m",
                "the bed's width and height must be positive whole multiples of a positive cell side",
            ));
        };
        if nx * ny > 10_000 {
            return Err(invalid("cell_side_m", "a grid must have at most 10⁴ cells"));
        }
        let stride = nx + 1;
        let nodes = (0..=ny)
            .flat_map(|row| (0..=nx).map(move |col| (row, col)))
            .map(|(row, col)| Node {
                id: format!("n{}", row * stride + col),
                position_m: [col as f64 * cell_side_m, row as f64 * cell_side_m],
            })
            .collect();
        let cells = (0..ny)
            .flat_map(|row| (0..nx).map(move |col| (row, col)))
            .map(|(row, col)| {
                let ll = row * stride + col;
                Cell {
                    min_m: [col as f64 * cell_side_m, row as f64 * cell_side_m],
                    max_m: [(col + 1) as f64 * cell_side_m, (row + 1) as f64 * cell_side_m],
                    nodes: vec![ll, ll + 1, ll + stride, ll + stride + 1],
                }
            })
            .collect();
        Self::new(nodes, cells)
    }

    /// The nodes.
    #[must_use]
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The cells.
    #[must_use]
    pub fn cells(&self) -> &[Cell] {
        &self.cells
    }

    /// The neighbours of `cell` (cells whose rectangles touch it), ascending; empty for an
    /// unknown cell.
    #[must_use]
    pub fn neighbours(&self, cell: usize) -> &[usize] {
        self.neighbours.get(cell).map_or(&[], Vec::as_slice)
    }

    /// Position of `node` (m), `None` for an unknown node.
    #[must_use]
    pub fn node_position_m(&self, node: usize) -> Option<[f64; 2]> {
        self.nodes.get(node).map(|n| n.position_m)
    }

    /// The cell holding `point_m`: the one whose half-open rectangle contains it (a point on an
    /// inner border belongs to the cell above / to the right of it), else — outside every cell —
    /// the nearest cell (lowest index on a tie). `None` only for a non-finite point.
    ///
    /// O(cells).
    #[must_use]
    pub fn cell_of(&self, point_m: [f64; 2]) -> Option<usize> {
        if !point_m.iter().all(|v| v.is_finite()) {
            return None;
        }
        if let Some(inside) = self.cells.iter().position(|c| c.contains(point_m)) {
            return Some(inside);
        }
        let mut best: Option<(f64, usize)> = None;
        for (i, cell) in self.cells.iter().enumerate() {
            let d = cell.distance_m(point_m);
            if best.is_none_or(|(b, _)| d < b) {
                best = Some((d, i));
            }
        }
        best.map(|(_, i)| i)
    }

    /// The `k` nodes of `cell` nearest to `point_m`, nearest first (ties by node index); all of
    /// them when the cell has fewer; empty for an unknown cell.
    #[must_use]
    pub fn nearest_cell_nodes(&self, cell: usize, point_m: [f64; 2], k: usize) -> Vec<usize> {
        let Some(cell) = self.cells.get(cell) else {
            return Vec::new();
        };
        let mut nodes = cell.nodes.clone();
        self.sort_by_distance(&mut nodes, point_m);
        nodes.dedup();
        nodes.truncate(k);
        nodes
    }

    /// Sorts `nodes` nearest to `point_m` first (ties by node index; unknown nodes last).
    pub fn sort_by_distance(&self, nodes: &mut [usize], point_m: [f64; 2]) {
        let distance = |n: usize| {
            self.node_position_m(n)
                .map_or(f64::INFINITY, |a| (a[0] - point_m[0]).hypot(a[1] - point_m[1]))
        };
        nodes.sort_by(|&a, &b| distance(a).total_cmp(&distance(b)).then(a.cmp(&b)));
    }

    /// Seed 003's edge zone: the neighbours of `cell` whose rectangle lies within `margin_m` of
    /// `point_m` (Chebyshev distance below the margin: for a side neighbour, the distance to the
    /// common border; for a diagonal neighbour, both distances), each with its monitoring nodes.
    /// Empty for an unknown cell.
    #[must_use]
    pub fn near_cells(&self, cell: usize, point_m: [f64; 2], margin_m: f64) -> Vec<NearCell> {
        let Some(own) = self.cells.get(cell) else {
            return Vec::new();
        };
        self.neighbours(cell)
            .iter()
            .filter(|&&n| self.cells[n].chebyshev_gap_m(point_m) < margin_m)
            .map(|&n| {
                let other = &self.cells[n];
                let mut monitors: Vec<usize> = own.nodes.iter().copied().filter(|m| other.nodes.contains(m)).collect();
                if monitors.is_empty() {
                    monitors = self.nearest_cell_nodes(n, point_m, 2);
                }
                monitors.sort_unstable();
                monitors.dedup();
                NearCell { cell: n, monitors }
            })
            .collect()
    }

    /// Distance from `point_m` to the nearest inner border of its cell (m): the least Euclidean
    /// distance to a neighbouring cell's rectangle; `∞` for a cell without neighbours or a
    /// non-finite point.
    #[must_use]
    pub fn distance_to_inner_border_m(&self, point_m: [f64; 2]) -> f64 {
        let Some(cell) = self.cell_of(point_m) else {
            return f64::INFINITY;
        };
        self.neighbours(cell)
            .iter()
            .map(|&n| self.cells[n].distance_m(point_m))
            .fold(f64::INFINITY, f64::min)
    }
}
