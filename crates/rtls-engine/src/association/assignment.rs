//! Rectangular linear assignment with forbidden pairs and a price for leaving a row unassigned:
//! the shortest-augmenting-path (Hungarian / Jonker–Volgenant) algorithm on `f64` costs.
//!
//! # Problem
//! Rows `i = 0..n` (detections), columns `j = 0..m` (tracks), costs `cᵢⱼ` with `cᵢⱼ = +∞` for
//! a forbidden pair, and a non-assignment cost `c₀ᵢ` per row. Find `xᵢⱼ ∈ {0, 1}` minimising
//! ```text
//! Σᵢⱼ cᵢⱼ xᵢⱼ + Σᵢ c₀ᵢ (1 − Σⱼ xᵢⱼ)
//! subject to  Σⱼ xᵢⱼ ≤ 1 (each row at most one column),  Σᵢ xᵢⱼ ≤ 1 (each column at most one row).
//! ```
//! # Method
//! The problem is an `n × (m + n)` assignment in which every row must be assigned: row `i` may
//! take column `m + i` (its own "unassigned" column) at cost `c₀ᵢ`; the other `n − 1` extra
//! columns are forbidden to it. These columns are implicit (never stored). Every row then has a
//! feasible choice, so a complete row assignment always exists.
//!
//! Rows are added one at a time; each addition is a Dijkstra search for the shortest
//! augmenting path in the reduced costs `c̄ᵢⱼ = cᵢⱼ − uᵢ − vⱼ ≥ 0` with dual potentials `u`
//! (rows) and `v` (columns). After the search the potentials are shifted by the path lengths
//! `δ`, which keeps `c̄ ≥ 0` on every pair and `c̄ = 0` on assigned pairs (complementary
//! slackness), so the final assignment is optimal. Each search costs `O(n (m + n))`, the whole
//! solve `O(n² (m + n))`, i.e. `O(n³)` for square problems. Forbidden pairs (`+∞`) never enter a
//! path.
//!
//! # References
//! - H. W. Kuhn, "The Hungarian method for the assignment problem", *Naval Research Logistics
//!   Quarterly* 2, 83–97, 1955.
//! - R. Jonker, A. Volgenant, "A shortest augmenting path algorithm for dense and sparse linear
//!   assignment problems", *Computing* 38, 325–340, 1987.
//! - D. F. Crouse, "On implementing 2D rectangular assignment algorithms", *IEEE Trans.
//!   Aerospace and Electronic Systems* 52(4), 1679–1696, 2016 (the rectangular form and the
//!   dummy-column treatment of non-assignment).

use crate::error::{EngineError, Result};

/// A dense `rows × columns` cost matrix, row-major; `+∞` marks a forbidden pair.
///
/// # Invariants
/// No entry is NaN or `−∞` (checked by every constructor and setter).
///
/// # Example
/// ```
/// use rtls_engine::association::CostMatrix;
/// let mut costs = CostMatrix::forbidden(2, 3)?;
/// costs.set(0, 1, 4.5)?;
/// assert_eq!(costs.get(0, 1), Some(4.5));
/// assert_eq!(costs.get(1, 1), Some(f64::INFINITY));
/// assert!(costs.set(0, 0, f64::NAN).is_err());
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct CostMatrix {
    rows: usize,
    columns: usize,
    costs: Vec<f64>,
}

impl CostMatrix {
    /// A matrix from row-major `costs` (`rows · columns` entries).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `costs` if the length is not `rows · columns`
    /// or an entry is NaN or `−∞`.
    pub fn new(rows: usize, columns: usize, costs: Vec<f64>) -> Result<Self> {
        if Some(costs.len()) != rows.checked_mul(columns) {
            return Err(EngineError::InvalidParameter {
                name: "costs",
                reason: "give rows · columns entries, row-major",
            });
        }
        costs.iter().try_for_each(|&c| check_cost(c))?;
        Ok(Self { rows, columns, costs })
    }

    /// A matrix in which every pair is forbidden (`+∞`); allow pairs with [`CostMatrix::set`].
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `costs` if `rows · columns` overflows.
    pub fn forbidden(rows: usize, columns: usize) -> Result<Self> {
        let len = rows.checked_mul(columns).ok_or(EngineError::InvalidParameter {
            name: "costs",
            reason: "rows · columns overflows",
        })?;
        Ok(Self {
            rows,
            columns,
            costs: vec![f64::INFINITY; len],
        })
    }

    /// Sets the cost of pair (`row`, `column`) (`+∞` forbids it).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `row` or `column` when out of range, `costs`
    /// for NaN or `−∞`.
    pub fn set(&mut self, row: usize, column: usize, cost: f64) -> Result<()> {
        let index = self.index(row, column)?;
        check_cost(cost)?;
        self.costs[index] = cost;
        Ok(())
    }

    /// The cost of pair (`row`, `column`), or `None` outside the matrix.
    #[must_use]
    pub fn get(&self, row: usize, column: usize) -> Option<f64> {
        self.index(row, column).ok().map(|i| self.costs[i])
    }

    /// Number of rows.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    #[must_use]
    pub fn columns(&self) -> usize {
        self.columns
    }

    fn index(&self, row: usize, column: usize) -> Result<usize> {
        if row >= self.rows {
            return Err(EngineError::InvalidParameter {
                name: "row",
                reason: "the row index is outside the cost matrix",
            });
        }
        if column >= self.columns {
            return Err(EngineError::InvalidParameter {
                name: "column",
                reason: "the column index is outside the cost matrix",
            });
        }
        Ok(row * self.columns + column)
    }
}

fn check_cost(cost: f64) -> Result<()> {
    if cost.is_nan() || cost == f64::NEG_INFINITY {
        Err(EngineError::InvalidParameter {
            name: "costs",
            reason: "a cost must be finite, or +∞ for a forbidden pair (not NaN or −∞)",
        })
    } else {
        Ok(())
    }
}

/// An optimal assignment.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// For each row, its column, or `None` when the row is left unassigned.
    pub row_to_column: Vec<Option<usize>>,
    /// For each column, its row, or `None` when no row took it.
    pub column_to_row: Vec<Option<usize>>,
    /// `Σ cᵢⱼ` over assigned pairs plus `Σ c₀ᵢ` over unassigned rows.
    pub total_cost: f64,
}

/// Solves the rectangular assignment problem with non-assignment costs (module docs give the
/// problem and the method): each row takes at most one column, each column at most one row;
/// row `i` left unassigned costs `non_assignment_costs[i]`.
///
/// Ties between optimal assignments are broken deterministically (by the order rows are
/// added).
///
/// # Errors
/// [`EngineError::InvalidParameter`] naming `non_assignment_costs` if its length is not the
/// number of rows or an entry is not finite.
///
/// # Example
/// Two detections, two tracks: detection 1 is close to track 0 only; detection 0 could go to
/// either, but is cheaper left unassigned than given to track 1 (cost 9 > 5).
/// ```
/// use rtls_engine::association::{solve_assignment, CostMatrix};
/// let inf = f64::INFINITY;
/// let costs = CostMatrix::new(2, 2, vec![2.0, 9.0,
///                                         1.0, inf])?;
/// let best = solve_assignment(&costs, &[5.0, 5.0])?;
/// assert_eq!(best.row_to_column, vec![None, Some(0)]);
/// assert_eq!(best.column_to_row, vec![Some(1), None]);
/// assert_eq!(best.total_cost, 5.0 + 1.0);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Kuhn (1955); Jonker & Volgenant (1987); Crouse (2016), see the module documentation.
pub fn solve_assignment(costs: &CostMatrix, non_assignment_costs: &[f64]) -> Result<Assignment> {
    let n = costs.rows;
    let m = costs.columns;
    if non_assignment_costs.len() != n {
        return Err(EngineError::InvalidParameter {
            name: "non_assignment_costs",
            reason: "give one non-assignment cost per row",
        });
    }
    if non_assignment_costs.iter().any(|c| !c.is_finite()) {
        return Err(EngineError::InvalidParameter {
            name: "non_assignment_costs",
            reason: "a non-assignment cost must be finite",
        });
    }
    // Columns 1..=m are real, m+1..=m+n the implicit unassigned columns; index 0 is the
    // virtual column the search starts from. Rows are 1-based too (0 = "no row").
    let width = m + n;
    // c(i, j) for 1-based i, j.
    let cost = |i: usize, j: usize| -> f64 {
        if j <= m {
            costs.costs[(i - 1) * m + (j - 1)]
        } else if j - m == i {
            non_assignment_costs[i - 1]
        } else {
            f64::INFINITY
        }
    };
    let mut u = vec![0.0; n + 1]; // row potentials
    let mut v = vec![0.0; width + 1]; // column potentials
    let mut row_of = vec![0usize; width + 1]; // p[j]: the row holding column j (0 = free)
    let mut way = vec![0usize; width + 1]; // predecessor column on the shortest path
    let mut min_reduced = vec![f64::INFINITY; width + 1];
    let mut used = vec![false; width + 1];
    for i in 1..=n {
        // Dijkstra from row i over the reduced costs c̄ᵢⱼ = cᵢⱼ − uᵢ − vⱼ.
        row_of[0] = i;
        let mut j0 = 0;
        min_reduced.fill(f64::INFINITY);
        used.fill(false);
        loop {
            used[j0] = true;
            let i0 = row_of[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0;
            for j in 1..=width {
                if used[j] {
                    continue;
                }
                let c = cost(i0, j);
                if c < f64::INFINITY {
                    // c̄ = c − u[i0] − v[j]
                    let reduced = c - u[i0] - v[j];
                    if reduced < min_reduced[j] {
                        min_reduced[j] = reduced;
                        way[j] = j0;
                    }
                }
                if min_reduced[j] < delta {
                    delta = min_reduced[j];
                    j1 = j;
                }
            }
            // Row i's own unassigned column is always reachable, so δ is finite.
            debug_assert!(delta.is_finite());
            if !delta.is_finite() {
                return Err(EngineError::InvalidParameter {
                    name: "costs",
                    reason: "no feasible assignment (costs too large: keep them far below 1e300)",
                });
            }
            // Shift the potentials by δ: reduced costs stay ≥ 0, tree edges stay tight.
            for j in 0..=width {
                if used[j] {
                    u[row_of[j]] += delta;
                    v[j] -= delta;
                } else {
                    min_reduced[j] -= delta;
                }
            }
            j0 = j1;
            if row_of[j0] == 0 {
                break;
            }
        }
        // Augment along the path back to the virtual column 0.
        while j0 != 0 {
            let j1 = way[j0];
            row_of[j0] = row_of[j1];
            j0 = j1;
        }
    }
    let mut row_to_column = vec![None; n];
    let mut column_to_row = vec![None; m];
    let mut total_cost = 0.0;
    for j in 1..=width {
        let i = row_of[j];
        if i == 0 {
            continue;
        }
        total_cost += cost(i, j);
        if j <= m {
            row_to_column[i - 1] = Some(j - 1);
            column_to_row[j - 1] = Some(i - 1);
        }
    }
    Ok(Assignment {
        row_to_column,
        column_to_row,
        total_cost,
    })
}
