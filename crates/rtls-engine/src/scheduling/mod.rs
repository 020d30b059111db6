//! Adaptive sensor scheduling (seed 003): which nodes of a cell-structured sensor network
//! measure each track next cycle, when they fire and report under the dual tokens, and what the
//! schedule costs in energy against keeping every node awake.
//!
//! A pure library, independent of any simulator: positions in, node indices and times out.
//!
//! - [`Layout`] — nodes and rectangular cells, each with its nodes; the cell of a point, the
//!   nearest nodes of a cell, the neighbouring cells within an edge margin (with their
//!   monitoring nodes).
//! - [`TaskScheduler`] — per track, from its predicted position: the 2–3 nearest nodes of the
//!   predicted cell as candidate task nodes, seed 003's acceptance rule against the current
//!   ones, edge monitoring near inner borders ([`TaskDecision`]).
//! - [`TokenTiming`] — work tokens (one ranging node per cell at a time, cells in parallel) and
//!   the communication token (one transmitter on the shared channel): each firing's time and
//!   its report's arrival, and the cycle's length ([`CycleTimetable`]).
//! - [`EnergyLedger`] — per node radio and sonar on-time and energy, scheduled against all
//!   nodes on ([`EnergyModel`], [`PowerModel`] with CC2420 / SRF08 datasheet figures).
//!
//! # Example
//! ```
//! use rtls_engine::scheduling::{FiringRequest, Layout, TaskScheduler, TokenTiming};
//! let bed = Layout::grid(4.0, 6.0, 2.0)?;
//! let scheduler = TaskScheduler::new(2, 0.3)?;
//! // two tracks: one mid-cell, one 0.15 m from the corner (2, 4) of cell 2
//! let mut current = vec![scheduler.initial(&bed, [1.0, 1.0])?, scheduler.initial(&bed, [1.85, 3.85])?];
//! let decisions = scheduler.plan(&bed, &mut current, &[[1.05, 1.0], [1.85, 3.85]])?;
//! // the second keeps its two task nodes; node 6, shared with the cell above, monitors the edge
//! assert_eq!((decisions[1].task_nodes.clone(), decisions[1].monitors.clone()), (vec![7, 4], vec![6]));
//! let requests: Vec<FiringRequest> = decisions
//!     .iter()
//!     .flat_map(|d| d.firing_nodes.iter().map(|&node| FiringRequest { node, cell: d.cell }))
//!     .collect();
//! let cycle = TokenTiming::new(0.065, 0.010)?.cycle(0.0, &requests)?;
//! assert_eq!(cycle.firings.len(), requests.len());
//! # Ok::<(), rtls_engine::EngineError>(())
//! ```
//!
//! # References
//! Xiahou, Yan, Ye, Yu, Wu, *Multi-target tracking based on Kalman filter and WSN*, Acta
//! Scientiarum Naturalium Universitatis Sunyatseni 53 (2), 2014: §3.1 dual tokens and clock
//! sync, §3.2 edge monitoring, §3.4 EKF-based adaptive node scheduling.

mod energy;
mod layout;
mod tasks;
mod tokens;

pub use energy::{EnergyLedger, EnergyModel, EnergyTotals, NodeUsage, PowerModel};
pub use layout::{Cell, Layout, NearCell, Node};
pub use tasks::{TaskDecision, TaskScheduler};
pub use tokens::{CycleTimetable, FiringRequest, TimedFiring, TokenTiming};

#[cfg(test)]
mod tests;
