//! Energy accounting of a scheduled sensor network against the same network with every node
//! awake: per node radio on-time (token reception, own reports, idle listening) and sonar
//! on-time, in seconds and joules.
//!
//! # Model
//! Per cycle (a [`CycleTimetable`]: token broadcast `[t₀, t_b]`, firings, last report at `t_e`):
//!
//! **Scheduled** (seed 003: only task nodes wake):
//! - every node's radio receives the token broadcast (it also carries the clock sync):
//!   `t_b − t₀` of receive time, whether the node is tasked or not;
//! - a node that fires this cycle stays awake from `t_b` until its last report has been sent:
//!   it transmits for `T_c` per report and listens (idle, waiting for the tokens) for the rest of
//!   that span; each fired sonar is on for the ping plus the echo window;
//! - every other node sleeps after the broadcast: radio and sonars off.
//!
//! **All nodes on** (the reference, for the same cycles): every node is awake for the whole
//! cycle `[t₀, t_e]` — it listens except while it transmits one report of `T_c` — and fires
//! `all_on_sonars_per_node` sonars once (a node that does not know where the target is scans
//! every sector). The reference keeps the scheduled cycle lengths although more firings would
//! lengthen its cycles, so its energy — and the saving — is understated.
//!
//! Not counted: sleep draw (CC2420 power-down 20 µA), the microcontroller, the SRF08's standby
//! draw while powered but not ranging (3 mA), packet retransmissions.

use super::tokens::CycleTimetable;
use crate::{EngineError, Result};

/// Power draw of a node's radio and of one sonar while ranging.
///
/// # Units
/// Watts.
///
/// # References
/// Chipcon/TI, *CC2420 datasheet* (SWRS041): RX 18.8 mA, TX 17.4 mA at 0 dBm — the radio of
/// seed 003's MPR2400 (MICAz) motes, powered by 2 × AA cells (3.0 V); Devantech, *SRF08 Ultra
/// sonic range finder — technical specification*: 5 V, 15 mA typical while ranging, 3 mA standby,
/// an 8-cycle 40 kHz burst.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerModel {
    /// Radio receiving or listening idle (W).
    pub radio_rx_w: f64,
    /// Radio transmitting (W).
    pub radio_tx_w: f64,
    /// One sonar while it pings and listens for the echo (W).
    pub sonar_w: f64,
}

impl PowerModel {
    /// A CC2420 radio at 3.0 V (RX 18.8 mA → 56.4 mW, TX at 0 dBm 17.4 mA → 52.2 mW) and SRF08
    /// sonars at 5 V (15 mA → 75 mW while ranging).
    ///
    /// # Example
    /// ```
    /// let p = rtls_engine::scheduling::PowerModel::cc2420_srf08();
    /// assert!((p.radio_rx_w - 0.0564).abs() < 1e-12 && (p.sonar_w - 0.075).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn cc2420_srf08() -> Self {
        Self {
            // 18.8 mA × 3.0 V, 17.4 mA × 3.0 V, 15 mA × 5 V
            radio_rx_w: 0.0564,
            radio_tx_w: 0.0522,
            sonar_w: 0.075,
        }
    }
}

/// What the ledger counts: the powers, the sonar's on-time per firing, and the reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyModel {
    /// Power draws.
    pub power: PowerModel,
    /// Length of one ping (s): SRF08, 8 cycles at 40 kHz = 0.2 ms.
    pub sonar_ping_s: f64,
    /// The echo window a fired sonar listens for (s).
    pub echo_window_s: f64,
    /// Sonars every node fires per cycle in the all-nodes-on reference (≥ 1).
    pub all_on_sonars_per_node: usize,
}

impl EnergyModel {
    /// Checks the model.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming the field: a power, the ping or the echo window
    /// that is negative or not finite, or `all_on_sonars_per_node` = 0.
    pub fn validate(&self) -> Result<()> {
        let checks: [(f64, &'static str); 5] = [
            (self.power.radio_rx_w, "radio_rx_w"),
            (self.power.radio_tx_w, "radio_tx_w"),
            (self.power.sonar_w, "sonar_w"),
            (self.sonar_ping_s, "sonar_ping_s"),
            (self.echo_window_s, "echo_window_s"),
        ];
        for (value, name) in checks {
            if !(value.is_finite() && value >= 0.0) {
                return Err(EngineError::InvalidParameter {
                    name,
                    reason: "powers and times must be finite and ≥ 0",
                });
            }
        }
        if self.all_on_sonars_per_node == 0 {
            return Err(EngineError::InvalidParameter {
                name: "all_on_sonars_per_node",
                reason: "a node of the all-on reference fires at least one sonar per cycle",
            });
        }
        Ok(())
    }

    /// On-time of one fired sonar: ping plus echo window (s).
    #[must_use]
    pub fn sonar_on_per_firing_s(&self) -> f64 {
        self.sonar_ping_s + self.echo_window_s
    }
}

/// One node's on-times and counts over the recorded cycles.
///
/// # Units
/// Seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NodeUsage {
    /// Radio receiving or listening (s).
    pub radio_rx_s: f64,
    /// Radio transmitting (s).
    pub radio_tx_s: f64,
    /// Sonars on, summed over the node's sonars (s).
    pub sonar_on_s: f64,
    /// Cycles in which the node was awake after the token broadcast.
    pub awake_cycles: usize,
    /// Reports the node sent.
    pub reports: usize,
    /// Sonars the node fired (two fired together count 2).
    pub sonars_fired: usize,
}

impl NodeUsage {
    /// Radio on-time, receive plus transmit (s).
    #[must_use]
    pub fn radio_on_s(&self) -> f64 {
        self.radio_rx_s + self.radio_tx_s
    }

    /// Radio energy `t_rx P_rx + t_tx P_tx` (J).
    #[must_use]
    pub fn radio_j(&self, power: &PowerModel) -> f64 {
        self.radio_rx_s * power.radio_rx_w + self.radio_tx_s * power.radio_tx_w
    }

    /// Sonar energy `t_sonar P_sonar` (J).
    #[must_use]
    pub fn sonar_j(&self, power: &PowerModel) -> f64 {
        self.sonar_on_s * power.sonar_w
    }

    /// Radio plus sonar energy (J).
    #[must_use]
    pub fn total_j(&self, power: &PowerModel) -> f64 {
        self.radio_j(power) + self.sonar_j(power)
    }

    /// Adds `other`'s on-times and counts.
    pub fn add(&mut self, other: &Self) {
        self.radio_rx_s += other.radio_rx_s;
        self.radio_tx_s += other.radio_tx_s;
        self.sonar_on_s += other.sonar_on_s;
        self.awake_cycles += other.awake_cycles;
        self.reports += other.reports;
        self.sonars_fired += other.sonars_fired;
    }
}

/// Per-node on-times of the scheduled network and of the all-nodes-on reference over the same
/// cycles (see the module docs for the model).
///
/// # Example
/// ```
/// use rtls_engine::scheduling::{EnergyLedger, EnergyModel, FiringRequest, PowerModel, TokenTiming};
/// let model = EnergyModel {
///     power: PowerModel::cc2420_srf08(),
///     sonar_ping_s: 0.0002,
///     echo_window_s: 0.0175,
///     all_on_sonars_per_node: 6,
/// };
/// let mut ledger = EnergyLedger::new(4, model)?;
/// // node 2 fires one sonar: broadcast 0–10 ms, firing at 10 ms, report 75–85 ms
/// let cycle = TokenTiming::new(0.065, 0.010)?.cycle(0.0, &[FiringRequest { node: 2, cell: 0 }])?;
/// ledger.record_cycle(&cycle, &[1])?;
/// let node = ledger.scheduled()[2];
/// assert!((node.radio_tx_s - 0.010).abs() < 1e-12 && (node.radio_rx_s - 0.075).abs() < 1e-12);
/// assert!((ledger.scheduled()[0].radio_rx_s - 0.010).abs() < 1e-12); // the broadcast only
/// assert!(ledger.totals().energy_saving_percent() > 50.0);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct EnergyLedger {
    model: EnergyModel,
    scheduled: Vec<NodeUsage>,
    all_on: Vec<NodeUsage>,
    cycles: usize,
    duration_s: f64,
}

/// Network totals of a ledger, scheduled and all nodes on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyTotals {
    /// The scheduled network, summed over nodes.
    pub scheduled: NodeUsage,
    /// The all-nodes-on reference, summed over nodes.
    pub all_on: NodeUsage,
    /// The powers, to turn on-times into joules.
    pub power: PowerModel,
}

impl EnergyTotals {
    /// Saving of radio on-time, `100 (1 − scheduled / all-on)` (%); 0 without reference time.
    #[must_use]
    pub fn radio_time_saving_percent(&self) -> f64 {
        saving_percent(self.scheduled.radio_on_s(), self.all_on.radio_on_s())
    }

    /// Saving of sonar on-time (%).
    #[must_use]
    pub fn sonar_time_saving_percent(&self) -> f64 {
        saving_percent(self.scheduled.sonar_on_s, self.all_on.sonar_on_s)
    }

    /// Saving of radio plus sonar energy (%).
    #[must_use]
    pub fn energy_saving_percent(&self) -> f64 {
        saving_percent(self.scheduled.total_j(&self.power), self.all_on.total_j(&self.power))
    }
}

fn saving_percent(scheduled: f64, reference: f64) -> f64 {
    if reference > 0.0 {
        100.0 * (1.0 - scheduled / reference)
    } else {
        0.0
    }
}

impl EnergyLedger {
    /// An empty ledger for `nodes` nodes.
    ///
    /// # Errors
    /// As [`EnergyModel::validate`].
    pub fn new(nodes: usize, model: EnergyModel) -> Result<Self> {
        model.validate()?;
        Ok(Self {
            model,
            scheduled: vec![NodeUsage::default(); nodes],
            all_on: vec![NodeUsage::default(); nodes],
            cycles: 0,
            duration_s: 0.0,
        })
    }

    /// Adds one cycle; `sonars_fired[i]` is the number of sonars of `cycle.firings[i]`.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`]: `sonars_fired` (not one entry per firing), `node` (a
    /// firing node beyond the ledger's nodes), `cycle` (a cycle that ends before it starts or
    /// whose times are not finite). The ledger is unchanged on error.
    pub fn record_cycle(&mut self, cycle: &CycleTimetable, sonars_fired: &[usize]) -> Result<()> {
        if sonars_fired.len() != cycle.firings.len() {
            return Err(EngineError::InvalidParameter {
                name: "sonars_fired",
                reason: "one sonar count per firing of the cycle is needed",
            });
        }
        if cycle.firings.iter().any(|f| f.node >= self.scheduled.len()) {
            return Err(EngineError::InvalidParameter {
                name: "node",
                reason: "a firing node lies beyond the ledger's nodes",
            });
        }
        let times_ok = [cycle.start_s, cycle.broadcast_end_s, cycle.end_s, cycle.comm_slot_s]
            .iter()
            .all(|t| t.is_finite())
            && cycle.start_s <= cycle.broadcast_end_s
            && cycle.broadcast_end_s <= cycle.end_s;
        if !times_ok {
            return Err(EngineError::InvalidParameter {
                name: "cycle",
                reason: "a cycle's times must be finite and in order",
            });
        }
        let on_per_sonar_s = self.model.sonar_on_per_firing_s();
        let broadcast_s = cycle.broadcast_end_s - cycle.start_s;
        let cycle_s = cycle.end_s - cycle.start_s;
        // per node: (reports, last report's arrival, sonars fired)
        let mut activity: Vec<(usize, f64, usize)> = vec![(0, cycle.broadcast_end_s, 0); self.scheduled.len()];
        for (firing, &sonars) in cycle.firings.iter().zip(sonars_fired) {
            let a = &mut activity[firing.node];
            a.0 += 1;
            a.1 = a.1.max(firing.arrival_s);
            a.2 += sonars;
        }
        for (node, (scheduled, all_on)) in self.scheduled.iter_mut().zip(&mut self.all_on).enumerate() {
            let (reports, last_arrival_s, sonars) = activity[node];
            // everyone hears the token broadcast
            scheduled.radio_rx_s += broadcast_s;
            if reports > 0 {
                // awake from the broadcast's end until its last report is sent
                let tx_s = reports as f64 * cycle.comm_slot_s;
                let awake_s = last_arrival_s - cycle.broadcast_end_s;
                scheduled.radio_tx_s += tx_s;
                scheduled.radio_rx_s += (awake_s - tx_s).max(0.0);
                scheduled.sonar_on_s += sonars as f64 * on_per_sonar_s;
                scheduled.awake_cycles += 1;
                scheduled.reports += reports;
                scheduled.sonars_fired += sonars;
            }
            // all on: awake the whole cycle, one report, every sonar once
            let tx_s = cycle.comm_slot_s.min(cycle_s);
            all_on.radio_tx_s += tx_s;
            all_on.radio_rx_s += cycle_s - tx_s;
            all_on.sonar_on_s += self.model.all_on_sonars_per_node as f64 * on_per_sonar_s;
            all_on.awake_cycles += 1;
            all_on.reports += 1;
            all_on.sonars_fired += self.model.all_on_sonars_per_node;
        }
        self.cycles += 1;
        self.duration_s += cycle_s;
        Ok(())
    }

    /// Adds another ledger's cycles (e.g. another Monte Carlo run).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`other`) for a ledger with another node count or
    /// model.
    pub fn merge(&mut self, other: &Self) -> Result<()> {
        if other.scheduled.len() != self.scheduled.len() || other.model != self.model {
            return Err(EngineError::InvalidParameter {
                name: "other",
                reason: "only ledgers of the same nodes and energy model can be merged",
            });
        }
        for (a, b) in self.scheduled.iter_mut().zip(&other.scheduled) {
            a.add(b);
        }
        for (a, b) in self.all_on.iter_mut().zip(&other.all_on) {
            a.add(b);
        }
        self.cycles += other.cycles;
        self.duration_s += other.duration_s;
        Ok(())
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &EnergyModel {
        &self.model
    }

    /// Per node, the scheduled network.
    #[must_use]
    pub fn scheduled(&self) -> &[NodeUsage] {
        &self.scheduled
    }

    /// Per node, the all-nodes-on reference.
    #[must_use]
    pub fn all_on(&self) -> &[NodeUsage] {
        &self.all_on
    }

    /// Cycles recorded.
    #[must_use]
    pub fn cycles(&self) -> usize {
        self.cycles
    }

    /// Time covered by the recorded cycles (s).
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// Network totals.
    #[must_use]
    pub fn totals(&self) -> EnergyTotals {
        let sum = |usage: &[NodeUsage]| {
            usage.iter().fold(NodeUsage::default(), |mut acc, u| {
                acc.add(u);
                acc
            })
        };
        EnergyTotals {
            scheduled: sum(&self.scheduled),
            all_on: sum(&self.all_on),
            power: self.model.power,
        }
    }
}
