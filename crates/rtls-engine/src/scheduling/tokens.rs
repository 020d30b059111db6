//! Seed 003's dual tokens (§3.1, §2.2–§2.3): the work token lets one node of a cell fire its
//! sonar at a time (cells fire in parallel), the communication token lets one node transmit at
//! a time on the single shared channel (TDMA). Together they fix when each firing happens and
//! when its report reaches the base station.

use crate::{EngineError, Result};

/// The slot lengths of the two tokens.
///
/// # Units
/// Seconds.
///
/// # Example
/// ```
/// use rtls_engine::scheduling::{FiringRequest, TokenTiming};
/// let timing = TokenTiming::new(0.065, 0.010)?;
/// // two nodes of cell 0 and one of cell 1
/// let requests = [
///     FiringRequest { node: 0, cell: 0 },
///     FiringRequest { node: 1, cell: 0 },
///     FiringRequest { node: 5, cell: 1 },
/// ];
/// let cycle = timing.cycle(10.0, &requests)?;
/// // token broadcast 10.000–10.010; slot 0: nodes 0 and 5, slot 1: node 1
/// let fired: Vec<(usize, f64)> = cycle.firings.iter().map(|f| (f.node, f.time_s)).collect();
/// for ((node, t), (expected_node, expected_t)) in fired.into_iter().zip([(0, 10.01), (5, 10.01), (1, 10.075)]) {
///     assert!(node == expected_node && (t - expected_t).abs() < 1e-12);
/// }
/// // reports one at a time: 10.075–10.085, 10.085–10.095, 10.140–10.150
/// assert!((cycle.end_s - 10.15).abs() < 1e-12);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TokenTiming {
    /// Time one firing holds its cell's work token: the ping, the echo window and the decay of
    /// late echoes (SRF08: 65 ms per ranging), s.
    pub ranging_slot_s: f64,
    /// One message on the shared channel — the token broadcast or one node's report — s.
    pub comm_slot_s: f64,
}

/// One firing to schedule: the node and the cell whose work token it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FiringRequest {
    /// The firing node.
    pub node: usize,
    /// The cell whose work token the firing holds.
    pub cell: usize,
}

/// A request with its place on the two token schedules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedFiring {
    /// Index of the request in the slice given to [`TokenTiming::cycle`].
    pub request: usize,
    /// The firing node.
    pub node: usize,
    /// The cell whose work token it holds.
    pub cell: usize,
    /// Work-token slot (0 first).
    pub slot: usize,
    /// Firing time (s).
    pub time_s: f64,
    /// Arrival of the node's report at the base station (s): the end of its communication slot,
    /// which starts at `arrival_s − comm_slot_s`.
    pub arrival_s: f64,
}

/// One cycle on the token schedules: the token broadcast, the firings and the reports.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleTimetable {
    /// Start of the cycle: the token broadcast begins (s).
    pub start_s: f64,
    /// End of the token broadcast: the first firings (s).
    pub broadcast_end_s: f64,
    /// The firings sorted by firing time (then request order).
    pub firings: Vec<TimedFiring>,
    /// End of the cycle: the last report is in (the broadcast's end without firings), s. The
    /// next cycle starts here.
    pub end_s: f64,
    /// The communication slot (s), so that the reports' slots can be recovered.
    pub comm_slot_s: f64,
}

impl TokenTiming {
    /// Token timing with the given slots.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`ranging_slot_s`, `comm_slot_s`) for a slot that is
    /// not positive and finite.
    pub fn new(ranging_slot_s: f64, comm_slot_s: f64) -> Result<Self> {
        let timing = Self {
            ranging_slot_s,
            comm_slot_s,
        };
        timing.validate()?;
        Ok(timing)
    }

    /// Checks the slots.
    ///
    /// # Errors
    /// As [`TokenTiming::new`].
    pub fn validate(&self) -> Result<()> {
        if !(self.ranging_slot_s.is_finite() && self.ranging_slot_s > 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "ranging_slot_s",
                reason: "the ranging slot must be a positive, finite time",
            });
        }
        if !(self.comm_slot_s.is_finite() && self.comm_slot_s > 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "comm_slot_s",
                reason: "the communication slot must be a positive, finite time",
            });
        }
        Ok(())
    }

    /// The cycle that starts at `start_s` with `requests` (in priority order):
    ///
    /// 1. the base broadcasts the tokens: `[start_s, start_s + T_c]`;
    /// 2. work tokens: each request goes to the earliest slot in which neither its cell's token
    ///    nor its node is taken (one sonar per cell and per node at a time); slot `s` fires at
    ///    `t_f = start_s + T_c + s · T_r`;
    /// 3. communication token: reports go out in firing order, each when its ranging has ended
    ///    and the channel is free, `send = max(t_f + T_r, channel free)`, and arrive `T_c` later.
    ///
    /// # Errors
    /// As [`TokenTiming::validate`]; [`EngineError::InvalidParameter`] (`start_s`) for a
    /// non-finite start.
    pub fn cycle(&self, start_s: f64, requests: &[FiringRequest]) -> Result<CycleTimetable> {
        self.validate()?;
        if !start_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "start_s",
                reason: "the cycle start must be a finite time",
            });
        }
        let broadcast_end_s = start_s + self.comm_slot_s;
        // (cell, node) pairs already firing in each slot
        let mut slots: Vec<Vec<(usize, usize)>> = Vec::new();
        let mut slotted: Vec<(usize, usize)> = Vec::with_capacity(requests.len());
        for (index, request) in requests.iter().enumerate() {
            let free = |taken: &Vec<(usize, usize)>| {
                taken
                    .iter()
                    .all(|&(cell, node)| cell != request.cell && node != request.node)
            };
            let slot = match slots.iter().position(free) {
                Some(s) => s,
                None => {
                    slots.push(Vec::new());
                    slots.len() - 1
                }
            };
            slots[slot].push((request.cell, request.node));
            slotted.push((slot, index));
        }
        // firing order: by slot, then request order (stable sort)
        slotted.sort_by_key(|&(slot, _)| slot);
        let mut channel_free_s = broadcast_end_s;
        let firings: Vec<TimedFiring> = slotted
            .into_iter()
            .map(|(slot, index)| {
                // t_f = t₀ + T_c + s · T_r
                let time_s = broadcast_end_s + slot as f64 * self.ranging_slot_s;
                // the report is ready when the ranging ends and goes out when the token reaches it
                let send_s = (time_s + self.ranging_slot_s).max(channel_free_s);
                channel_free_s = send_s + self.comm_slot_s;
                TimedFiring {
                    request: index,
                    node: requests[index].node,
                    cell: requests[index].cell,
                    slot,
                    time_s,
                    arrival_s: channel_free_s,
                }
            })
            .collect();
        let end_s = firings.iter().map(|f| f.arrival_s).fold(broadcast_end_s, f64::max);
        Ok(CycleTimetable {
            start_s,
            broadcast_end_s,
            firings,
            end_s,
            comm_slot_s: self.comm_slot_s,
        })
    }
}
