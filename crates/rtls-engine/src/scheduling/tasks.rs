//! Seed 003's adaptive node scheduling (§3.4) with edge monitoring (§3.2): which nodes measure a
//! track next cycle, from its predicted position.

use super::layout::Layout;
use crate::{EngineError, Result};

/// The scheduling strategy: how many task nodes a track gets and how wide the edge zone is.
///
/// Immutable and shared by every track; each track owns its current task nodes (a
/// `Vec<usize>` of node indices, as returned by [`TaskScheduler::initial`] and updated by
/// [`TaskScheduler::decide`]).
///
/// # Example
/// ```
/// use rtls_engine::scheduling::{Layout, TaskScheduler};
/// let bed = Layout::grid(4.0, 6.0, 2.0)?;
/// let scheduler = TaskScheduler::new(3, 0.3)?;
/// let mut current = scheduler.initial(&bed, [0.9, 0.5])?;
/// assert_eq!(current, vec![0, 1, 3]);
/// // the robot crosses x = 1: node 4 replaces node 3, two of three nodes coincide → accepted
/// let decision = scheduler.decide(&bed, &current, [1.1, 0.5])?;
/// assert!(decision.accepted && decision.changed);
/// current = decision.task_nodes.clone();
/// assert_eq!(current, vec![1, 0, 4]);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Seed 003 §3.4: "from the predicted position, the two or three nearest nodes of the grid
/// become next cycle's task nodes; the prediction is accepted if more of them coincide with the
/// current task nodes than differ, else the current ones measure again"; §3.2 edge monitoring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskScheduler {
    task_nodes: usize,
    edge_margin_m: f64,
    /// Hand a track over to a neighbouring cell that shares none of its nodes (see
    /// [`TaskScheduler::with_neighbour_handover`]); off: seed 003's rule as printed.
    neighbour_handover: bool,
}

/// One track's scheduling decision for the next cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskDecision {
    /// The predicted cell (whose work token the track's firings hold).
    pub cell: usize,
    /// The proposal: the task-node count's nearest nodes of the predicted cell, nearest first.
    pub proposal: Vec<usize>,
    /// Whether the proposal was accepted (more of its nodes coincide with the current task
    /// nodes than differ).
    pub accepted: bool,
    /// Whether the accepted proposal differs, as a set, from the previous task nodes.
    pub changed: bool,
    /// The track's task nodes after the decision: the proposal if accepted, else the previous
    /// ones. Store them as the track's current task nodes.
    pub task_nodes: Vec<usize>,
    /// Edge monitors that are not task nodes: the monitoring nodes of every neighbouring cell
    /// within the edge margin of the prediction, ascending.
    pub monitors: Vec<usize>,
    /// Every node that fires for the track this cycle (task nodes and monitors), nearest to the
    /// prediction first (ties by node index).
    pub firing_nodes: Vec<usize>,
}

impl TaskScheduler {
    /// `task_nodes` per track and cycle (seed 003: 2 or 3), and the edge zone `edge_margin_m`
    /// (m): within it of an inner border, the border's nodes measure too.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for `task_nodes` = 0 or a negative or non-finite
    /// `edge_margin_m`.
    pub fn new(task_nodes: usize, edge_margin_m: f64) -> Result<Self> {
        if task_nodes == 0 {
            return Err(EngineError::InvalidParameter {
                name: "task_nodes",
                reason: "a track needs at least one task node",
            });
        }
        if !(edge_margin_m.is_finite() && edge_margin_m >= 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "edge_margin_m",
                reason: "the edge margin must be a finite distance ≥ 0",
            });
        }
        Ok(Self {
            task_nodes,
            edge_margin_m,
            neighbour_handover: false,
        })
    }

    /// The same scheduler with a handover for layouts whose neighbouring cells share no node:
    /// a prediction in a neighbour of the current nodes' cell that holds none of them is
    /// accepted (those nodes cannot measure the track there, and seed 003's rule alone would
    /// keep them for ever); a jump further away is still refused. Seed 003's bed shares its
    /// border nodes, so its reproduction keeps the rule as printed.
    #[must_use]
    pub fn with_neighbour_handover(self) -> Self {
        Self {
            neighbour_handover: true,
            ..self
        }
    }

    /// Task nodes per track.
    #[must_use]
    pub fn task_nodes(&self) -> usize {
        self.task_nodes
    }

    /// The edge margin (m).
    #[must_use]
    pub fn edge_margin_m(&self) -> f64 {
        self.edge_margin_m
    }

    /// A new track's task nodes: the nearest nodes of the cell holding `position_m`.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`position_m`) for a non-finite position.
    pub fn initial(&self, layout: &Layout, position_m: [f64; 2]) -> Result<Vec<usize>> {
        let cell = cell_of(layout, position_m)?;
        Ok(layout.nearest_cell_nodes(cell, position_m, self.task_nodes))
    }

    /// Next cycle's nodes for a track with task nodes `current` and predicted position
    /// `predicted_m`.
    ///
    /// The proposal is the `task_nodes` nodes of the predicted cell nearest to the prediction;
    /// with `same = |proposal ∩ current|` and `different = |proposal \ current|` it is accepted
    /// iff `same > different`, so a jump of the estimate is not followed (and, with
    /// [`TaskScheduler::with_neighbour_handover`], also on a move into a neighbouring cell that
    /// shares none of the current nodes). Edge monitoring
    /// adds the monitors of every neighbouring cell within the margin ([`Layout::near_cells`])
    /// to the firing nodes.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`position_m`) for a non-finite prediction.
    pub fn decide(&self, layout: &Layout, current: &[usize], predicted_m: [f64; 2]) -> Result<TaskDecision> {
        let cell = cell_of(layout, predicted_m)?;
        let proposal = layout.nearest_cell_nodes(cell, predicted_m, self.task_nodes);
        // same = |proposal ∩ current|, different = |proposal \ current|
        let same = proposal.iter().filter(|n| current.contains(n)).count();
        let different = proposal.len() - same;
        // a move from the current nodes' cell into a neighbour that shares none of them
        let nodes_of = |c: usize| &layout.cells()[c].nodes;
        let unreachable_neighbour = self.neighbour_handover
            && !current.is_empty()
            && !current.iter().any(|n| nodes_of(cell).contains(n))
            && layout
                .neighbours(cell)
                .iter()
                .any(|&c| current.iter().all(|n| nodes_of(c).contains(n)));
        let accepted = same > different || unreachable_neighbour;
        let changed = accepted && same < current.len().max(proposal.len());
        let task_nodes = if accepted { proposal.clone() } else { current.to_vec() };
        let mut monitors: Vec<usize> = layout
            .near_cells(cell, predicted_m, self.edge_margin_m)
            .into_iter()
            .flat_map(|near| near.monitors)
            .filter(|n| !task_nodes.contains(n))
            .collect();
        monitors.sort_unstable();
        monitors.dedup();
        let mut firing_nodes: Vec<usize> = task_nodes.iter().chain(&monitors).copied().collect();
        firing_nodes.sort_unstable();
        firing_nodes.dedup();
        layout.sort_by_distance(&mut firing_nodes, predicted_m);
        Ok(TaskDecision {
            cell,
            proposal,
            accepted,
            changed,
            task_nodes,
            monitors,
            firing_nodes,
        })
    }

    /// [`TaskScheduler::decide`] for every track, storing each decision's task nodes in
    /// `current` (one entry per track, in the order of `predicted_m`).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`predicted_m`) when the two slices differ in length;
    /// as [`TaskScheduler::decide`] (then `current` is left unchanged).
    pub fn plan(
        &self,
        layout: &Layout,
        current: &mut [Vec<usize>],
        predicted_m: &[[f64; 2]],
    ) -> Result<Vec<TaskDecision>> {
        if current.len() != predicted_m.len() {
            return Err(EngineError::InvalidParameter {
                name: "predicted_m",
                reason: "one predicted position per track's current task nodes is needed",
            });
        }
        let decisions = current
            .iter()
            .zip(predicted_m)
            .map(|(nodes, &p)| self.decide(layout, nodes, p))
            .collect::<Result<Vec<_>>>()?;
        for (nodes, decision) in current.iter_mut().zip(&decisions) {
            nodes.clone_from(&decision.task_nodes);
        }
        Ok(decisions)
    }
}

fn cell_of(layout: &Layout, point_m: [f64; 2]) -> Result<usize> {
    layout.cell_of(point_m).ok_or(EngineError::InvalidParameter {
        name: "position_m",
        reason: "a track position must be finite to schedule its nodes",
    })
}
