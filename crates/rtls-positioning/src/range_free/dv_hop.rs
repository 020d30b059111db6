//! DV-Hop (Niculescu & Nath): range-free positioning in a multi-hop network from hop counts
//! to anchors (seed 000's range-free baseline).

use std::collections::VecDeque;

use crate::error::{PositioningError, Result};
use crate::fix::Fix;
use crate::multilateration::validate::{self, point};
use crate::multilateration::{
    gauss_newton, weighted_linear_least_squares, GaussNewtonOptions, Initial, ReferenceAnchor,
};

/// Floor of the per-hop distance standard deviation, as a fraction of the mean hop size
/// (used only when the anchors' own hop distances fit their hop sizes exactly).
const MIN_HOP_STD_FRACTION: f64 = 0.05;

/// Options of [`DvHop::locate`].
///
/// # Example
/// ```
/// use rtls_positioning::range_free::DvHopOptions;
/// let closed_form_only = DvHopOptions { refine: false, ..DvHopOptions::default() };
/// assert!(DvHopOptions::default().refine && !closed_form_only.refine);
/// ```
///
/// # References
/// Niculescu & Nath (2003) (trilateration step); Foy (1976) (Gauss–Newton refinement).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DvHopOptions {
    /// Refine the linear least-squares fix by weighted Gauss–Newton
    /// ([`crate::multilateration::gauss_newton`]); default `true`.
    pub refine: bool,
    /// Iteration limit and tolerance of the refinement.
    pub solver: GaussNewtonOptions,
}

impl Default for DvHopOptions {
    fn default() -> Self {
        Self {
            refine: true,
            solver: GaussNewtonOptions::default(),
        }
    }
}

/// A network prepared for DV-Hop: hop counts from every anchor, per-anchor hop sizes and the
/// per-hop distance variance. Build once per topology, then [`DvHop::locate`] any node.
///
/// The network has `n` nodes; anchors are the nodes with a surveyed position, unknown nodes
/// have none. Links are undirected (radio connectivity).
/// ```text
/// h_kj = BFS hop count from anchor k to node j
/// c_k  = Σ_{l ≠ k} ‖a_k − a_l‖ / Σ_{l ≠ k} h_kl            hop size of anchor k (m/hop), l reachable
/// σ_h² = Σ_k Σ_{l ≠ k} (‖a_k − a_l‖ − c_k h_kl)² / Σ_k Σ_{l ≠ k} h_kl   per-hop distance variance
///        (floored at (0.05 · mean c_k)²)
/// node j:  k* = the anchor with the fewest hops (lowest index on ties)
///          d_jk = h_kj · c_k*,   var d_jk = h_kj σ_h²    for every reachable anchor k
///          p_j = weighted linear LS of (a_k, d_jk), optionally refined by Gauss–Newton
/// ```
/// The variance model (independent per-hop errors, calibrated from the anchors' own hop
/// distances) only weights the fit and scales the reported covariance; DV-Hop errors are in
/// truth correlated (every distance of a node uses the same hop size) and biased where the
/// network is anisotropic (holes, borders), so treat the covariance as indicative and
/// calibrate it ([`crate::calibrate_fix_noise`]) before feeding a tracker.
///
/// # Units
/// Positions and the fix in m; hop sizes in m per hop; variances in m².
///
/// # Example
/// ```
/// use rtls_positioning::range_free::{DvHop, DvHopOptions};
/// // three anchors and two unknown nodes: 0 – 3 – 1, 0 – 4 – 2, 3 – 4
/// let positions = [Some([0.0, 0.0]), Some([12.0, 0.0]), Some([0.0, 12.0]), None, None];
/// let edges = [(0, 3), (3, 1), (0, 4), (4, 2), (3, 4)];
/// let network = DvHop::new(&positions, &edges)?;
/// assert_eq!(network.hops(1, 2), Some(3)); // 1 – 3 – 4 – 2
/// assert_eq!(network.hop_size_m(0), Some(6.0)); // (12 + 12) / (2 + 2)
/// let fix = network.locate(3, &DvHopOptions { refine: false, ..DvHopOptions::default() })?;
/// assert!((fix.position.x - 6.0).abs() < 1e-9 && (fix.position.y - 1.5).abs() < 1e-9);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// D. Niculescu, B. Nath, "DV based positioning in ad hoc networks", *Telecommunication
/// Systems* 22(1–4), 2003 (DV-Hop: hop counts, the anchors' average hop size — the
/// "correction" — distance estimates and trilateration); D. Niculescu, B. Nath, "Ad hoc positioning system (APS)",
/// *IEEE GLOBECOM* 2001. Seed 000 (DV-Hop as the range-free baseline).
#[derive(Debug, Clone, PartialEq)]
pub struct DvHop<const D: usize> {
    /// Node index of each anchor, ascending.
    anchors: Vec<usize>,
    /// Surveyed position of each anchor (m), in the order of `anchors`.
    anchor_positions_m: Vec<[f64; D]>,
    /// `hops[k][j]`: hop count from anchor `k` (slot in `anchors`) to node `j`; `None` when
    /// unreachable.
    hops: Vec<Vec<Option<u32>>>,
    /// `c_k` (m/hop).
    hop_sizes_m: Vec<f64>,
    /// `σ_h²` (m² per hop).
    hop_variance_m2: f64,
}

impl<const D: usize> DvHop<D> {
    /// Prepares a network: validates it, counts hops from every anchor by breadth-first search
    /// and computes the hop sizes.
    ///
    /// `positions_m[j]` is `Some(position)` for an anchor and `None` for an unknown node;
    /// `edges` are undirected links `(i, j)` between node indices (duplicates and self-loops
    /// are harmless). Cost `O(A (n + |edges|))` for `A` anchors.
    ///
    /// # Errors
    /// - [`PositioningError::Underdetermined`] for fewer than `D + 1` anchors;
    /// - [`PositioningError::NonFiniteEntry`] (row = node, column = axis) for a NaN/∞ anchor
    ///   position;
    /// - [`PositioningError::DuplicateAnchors`] (node indices) for two anchors at one position;
    /// - [`PositioningError::InvalidParameter`] (`edges`) for a link naming a node index
    ///   `≥ n`;
    /// - [`PositioningError::NodeUnderdetermined`] (`anchors: 0, needed: 1`) for an anchor
    ///   that reaches no other anchor, whose hop size is undefined.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::DvHop;
    /// use rtls_positioning::PositioningError;
    /// let positions = [Some([0.0, 0.0]), Some([10.0, 0.0]), Some([0.0, 10.0]), None];
    /// // anchor 2 has no link
    /// let error = DvHop::new(&positions, &[(0, 3), (3, 1)]).unwrap_err();
    /// assert_eq!(error, PositioningError::NodeUnderdetermined { node: 2, anchors: 0, needed: 1 });
    /// ```
    ///
    /// # References
    /// Niculescu & Nath (2003).
    pub fn new(positions_m: &[Option<[f64; D]>], edges: &[(usize, usize)]) -> Result<Self> {
        let n = positions_m.len();
        let anchors: Vec<usize> = (0..n).filter(|&j| positions_m[j].is_some()).collect();
        let anchor_positions_m: Vec<[f64; D]> = positions_m.iter().flatten().copied().collect();
        // anchor table checks, errors reported with node indices
        validate::anchors(&anchor_positions_m, D + 1, false).map_err(|error| match error {
            PositioningError::NonFiniteEntry { row, column, .. } => PositioningError::NonFiniteEntry {
                what: "node positions (row = node, column = axis)",
                row: anchors[row],
                column,
            },
            PositioningError::DuplicateAnchors { first, second } => PositioningError::DuplicateAnchors {
                first: anchors[first],
                second: anchors[second],
            },
            other => other,
        })?;
        let adjacency = Adjacency::new(n, edges)?;
        // h_kj by breadth-first search from each anchor
        let hops: Vec<Vec<Option<u32>>> = anchors.iter().map(|&k| adjacency.hop_counts(k)).collect();
        // c_k = Σ_l ‖a_k − a_l‖ / Σ_l h_kl over the other reachable anchors
        let mut hop_sizes_m = Vec::with_capacity(anchors.len());
        for (k, a_k) in anchor_positions_m.iter().enumerate() {
            let (mut distance_m, mut hop_total) = (0.0, 0u64);
            for (l, a_l) in anchor_positions_m.iter().enumerate() {
                if let (true, Some(h)) = (l != k, hops[k][anchors[l]]) {
                    distance_m += (point(a_k) - point(a_l)).norm();
                    hop_total += u64::from(h);
                }
            }
            if hop_total == 0 {
                return Err(PositioningError::NodeUnderdetermined {
                    node: anchors[k],
                    anchors: 0,
                    needed: 1,
                });
            }
            hop_sizes_m.push(distance_m / hop_total as f64);
        }
        // σ_h² = Σ (‖a_k − a_l‖ − c_k h_kl)² / Σ h_kl
        let (mut squared_m2, mut hop_total) = (0.0, 0u64);
        for (k, a_k) in anchor_positions_m.iter().enumerate() {
            for (l, a_l) in anchor_positions_m.iter().enumerate() {
                if let (true, Some(h)) = (l != k, hops[k][anchors[l]]) {
                    let error_m = (point(a_k) - point(a_l)).norm() - hop_sizes_m[k] * f64::from(h);
                    squared_m2 += error_m * error_m;
                    hop_total += u64::from(h);
                }
            }
        }
        let mean_hop_m = hop_sizes_m.iter().sum::<f64>() / hop_sizes_m.len() as f64;
        let floor_m = MIN_HOP_STD_FRACTION * mean_hop_m;
        let hop_variance_m2 = (squared_m2 / hop_total as f64).max(floor_m * floor_m);
        if !(hop_variance_m2.is_finite() && hop_variance_m2 > 0.0) {
            return Err(PositioningError::NonFinite {
                what: "dv-hop hop sizes",
            });
        }
        Ok(Self {
            anchors,
            anchor_positions_m,
            hops,
            hop_sizes_m,
            hop_variance_m2,
        })
    }

    /// Node indices of the anchors, ascending.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::DvHop;
    /// let positions = [None, Some([0.0, 0.0]), Some([4.0, 0.0]), Some([0.0, 4.0])];
    /// let network = DvHop::new(&positions, &[(0, 1), (0, 2), (0, 3)])?;
    /// assert_eq!(network.anchors(), &[1, 2, 3]);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[must_use]
    pub fn anchors(&self) -> &[usize] {
        &self.anchors
    }

    /// Hop count from anchor node `anchor` to node `node`; `None` when `node` is unreachable,
    /// `anchor` is not an anchor, or either index is out of range.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::DvHop;
    /// let positions = [None, Some([0.0, 0.0]), Some([4.0, 0.0]), Some([0.0, 4.0])];
    /// let network = DvHop::new(&positions, &[(0, 1), (0, 2), (0, 3)])?;
    /// assert_eq!(network.hops(1, 0), Some(1));
    /// assert_eq!(network.hops(1, 2), Some(2));
    /// assert_eq!(network.hops(0, 2), None); // node 0 is not an anchor
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[must_use]
    pub fn hops(&self, anchor: usize, node: usize) -> Option<u32> {
        let slot = self.anchors.binary_search(&anchor).ok()?;
        self.hops[slot].get(node).copied().flatten()
    }

    /// Hop size `c_k` (m/hop) of anchor node `anchor`; `None` if it is not an anchor.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::DvHop;
    /// let positions = [None, Some([0.0, 0.0]), Some([4.0, 0.0]), Some([0.0, 4.0])];
    /// let network = DvHop::new(&positions, &[(0, 1), (0, 2), (0, 3)])?;
    /// assert_eq!(network.hop_size_m(1), Some(2.0)); // (4 + 4) / (2 + 2)
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Niculescu & Nath (2003) (the anchors' correction `c_i`).
    #[must_use]
    pub fn hop_size_m(&self, anchor: usize) -> Option<f64> {
        let slot = self.anchors.binary_search(&anchor).ok()?;
        Some(self.hop_sizes_m[slot])
    }

    /// The per-hop distance variance `σ_h²` (m²) calibrated from the anchors (see [`DvHop`]).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::DvHop;
    /// let positions = [None, Some([0.0, 0.0]), Some([4.0, 0.0]), Some([0.0, 4.0])];
    /// let network = DvHop::new(&positions, &[(0, 1), (0, 2), (0, 3)])?;
    /// assert!(network.hop_variance_m2() > 0.0);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    #[must_use]
    pub fn hop_variance_m2(&self) -> f64 {
        self.hop_variance_m2
    }

    /// The DV-Hop fix of unknown node `node` (see [`DvHop`] for the equations).
    ///
    /// # Errors
    /// - [`PositioningError::InvalidParameter`] (`node`) for an index `≥ n` or an anchor;
    /// - [`PositioningError::NodeUnderdetermined`] when the node reaches fewer than `D + 1`
    ///   anchors;
    /// - [`PositioningError::DegenerateGeometry`] when the anchors it reaches are collinear
    ///   (2-D) / coplanar (3-D);
    /// - the solver errors of [`crate::multilateration::gauss_newton`] (with `refine`) or
    ///   [`crate::multilateration::weighted_linear_least_squares`].
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::{DvHop, DvHopOptions};
    /// use rtls_positioning::PositioningError;
    /// // node 4 hangs off node 3 alone and still reaches all three anchors; node 5 is isolated
    /// let positions = [Some([0.0, 0.0]), Some([10.0, 0.0]), Some([0.0, 10.0]), None, None, None];
    /// let network = DvHop::new(&positions, &[(0, 3), (1, 3), (2, 3), (3, 4)])?;
    /// assert!(network.locate(4, &DvHopOptions::default()).is_ok());
    /// assert_eq!(
    ///     network.locate(5, &DvHopOptions::default()).unwrap_err(),
    ///     PositioningError::NodeUnderdetermined { node: 5, anchors: 0, needed: 3 }
    /// );
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Niculescu & Nath (2003).
    pub fn locate(&self, node: usize, options: &DvHopOptions) -> Result<Fix<D>> {
        let node_count = self.hops.first().map_or(0, Vec::len);
        if node >= node_count {
            return Err(PositioningError::InvalidParameter {
                name: "node",
                reason: "the node index must be below the number of nodes",
            });
        }
        if self.anchors.binary_search(&node).is_ok() {
            return Err(PositioningError::InvalidParameter {
                name: "node",
                reason: "the node is an anchor: its position is surveyed, not estimated",
            });
        }
        // reachable anchors and their hop counts
        let reached: Vec<(usize, u32)> = self
            .hops
            .iter()
            .enumerate()
            .filter_map(|(k, hops)| hops[node].map(|h| (k, h)))
            .collect();
        if reached.len() < D + 1 {
            return Err(PositioningError::NodeUnderdetermined {
                node,
                anchors: reached.len(),
                needed: D + 1,
            });
        }
        // k* = the anchor with the fewest hops (first on ties)
        let nearest = reached.iter().min_by_key(|&&(k, h)| (h, k)).map_or(0, |&(k, _)| k);
        let hop_size_m = self.hop_sizes_m[nearest];
        // d_k = h_k c_k*,  var d_k = h_k σ_h²
        let anchors_m: Vec<[f64; D]> = reached.iter().map(|&(k, _)| self.anchor_positions_m[k]).collect();
        let distances_m: Vec<f64> = reached.iter().map(|&(_, h)| f64::from(h) * hop_size_m).collect();
        let variances_m2: Vec<f64> = reached
            .iter()
            .map(|&(_, h)| f64::from(h) * self.hop_variance_m2)
            .collect();
        if options.refine {
            gauss_newton(
                &anchors_m,
                &distances_m,
                &variances_m2,
                Initial::Linear,
                &options.solver,
            )
            .map(|s| s.fix)
        } else {
            weighted_linear_least_squares(&anchors_m, &distances_m, &variances_m2, ReferenceAnchor::NearestRange)
        }
    }

    /// The fix of every unknown node, in node order, each with its own result (a node that
    /// reaches too few anchors does not prevent the others).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::range_free::{DvHop, DvHopOptions};
    /// let positions = [Some([0.0, 0.0]), Some([12.0, 0.0]), Some([0.0, 12.0]), None, None];
    /// let network = DvHop::new(&positions, &[(0, 3), (3, 1), (0, 4), (4, 2), (3, 4)])?;
    /// let fixes = network.locate_all(&DvHopOptions::default());
    /// assert_eq!(fixes.iter().map(|(node, _)| *node).collect::<Vec<_>>(), [3, 4]);
    /// assert!(fixes.iter().all(|(_, fix)| fix.is_ok()));
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// Niculescu & Nath (2003).
    #[must_use]
    pub fn locate_all(&self, options: &DvHopOptions) -> Vec<(usize, Result<Fix<D>>)> {
        let node_count = self.hops.first().map_or(0, Vec::len);
        (0..node_count)
            .filter(|node| self.anchors.binary_search(node).is_err())
            .map(|node| (node, self.locate(node, options)))
            .collect()
    }
}

/// The links of a unit-disk radio model: every pair of nodes at most `radio_range_m` apart,
/// as `(i, j)` with `i < j` in lexicographic order. `O(n²)`; for simulations.
///
/// # Units
/// Positions and range in m.
///
/// # Errors
/// [`PositioningError::NonFiniteEntry`] (row = node, column = axis) for a NaN/∞ position;
/// [`PositioningError::InvalidParameter`] (`radio_range_m`) unless the range is finite and
/// positive.
///
/// # Example
/// ```
/// use rtls_positioning::range_free::unit_disk_edges;
/// let edges = unit_disk_edges(&[[0.0, 0.0], [3.0, 0.0], [10.0, 0.0]], 5.0)?;
/// assert_eq!(edges, [(0, 1)]);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// B. N. Clark, C. J. Colbourn, D. S. Johnson, "Unit disk graphs", *Discrete Mathematics*
/// 86(1–3), 1990; Niculescu & Nath (2003) (simulated isotropic deployments).
pub fn unit_disk_edges<const D: usize>(positions_m: &[[f64; D]], radio_range_m: f64) -> Result<Vec<(usize, usize)>> {
    if !(radio_range_m.is_finite() && radio_range_m > 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "radio_range_m",
            reason: "the radio range must be finite and positive",
        });
    }
    for (row, p) in positions_m.iter().enumerate() {
        if let Some(column) = p.iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: "node positions (row = node, column = axis)",
                row,
                column,
            });
        }
    }
    let mut edges = Vec::new();
    for i in 0..positions_m.len() {
        for j in i + 1..positions_m.len() {
            // ‖p_i − p_j‖ ≤ R
            if (point(&positions_m[i]) - point(&positions_m[j])).norm() <= radio_range_m {
                edges.push((i, j));
            }
        }
    }
    Ok(edges)
}

/// Undirected adjacency in compressed-row form.
struct Adjacency {
    /// `neighbours[offsets[j]..offsets[j + 1]]` are node `j`'s neighbours.
    offsets: Vec<usize>,
    neighbours: Vec<usize>,
}

impl Adjacency {
    /// # Errors
    /// [`PositioningError::InvalidParameter`] (`edges`) for an index `≥ n`.
    fn new(n: usize, edges: &[(usize, usize)]) -> Result<Self> {
        if edges.iter().any(|&(i, j)| i >= n || j >= n) {
            return Err(PositioningError::InvalidParameter {
                name: "edges",
                reason: "a link names a node index that is not below the number of nodes",
            });
        }
        let mut degree = vec![0usize; n];
        for &(i, j) in edges.iter().filter(|(i, j)| i != j) {
            degree[i] += 1;
            degree[j] += 1;
        }
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for d in &degree {
            offsets.push(offsets.last().copied().unwrap_or(0) + d);
        }
        let mut fill = offsets.clone();
        let mut neighbours = vec![0usize; offsets[n]];
        for &(i, j) in edges.iter().filter(|(i, j)| i != j) {
            neighbours[fill[i]] = j;
            fill[i] += 1;
            neighbours[fill[j]] = i;
            fill[j] += 1;
        }
        Ok(Self { offsets, neighbours })
    }

    /// Hop counts from `source` to every node (breadth-first search); `None` if unreachable.
    fn hop_counts(&self, source: usize) -> Vec<Option<u32>> {
        let n = self.offsets.len() - 1;
        let mut hops = vec![None; n];
        hops[source] = Some(0u32);
        let mut queue = VecDeque::from([source]);
        while let Some(j) = queue.pop_front() {
            let next = hops[j].map_or(0, |h| h.saturating_add(1));
            for &k in &self.neighbours[self.offsets[j]..self.offsets[j + 1]] {
                if hops[k].is_none() {
                    hops[k] = Some(next);
                    queue.push_back(k);
                }
            }
        }
        hops
    }
}

#[cfg(test)]
#[path = "dv_hop_tests.rs"]
mod tests;
