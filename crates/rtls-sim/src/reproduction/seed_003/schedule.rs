//! Seed 003's adaptive node scheduling (§3.4), edge monitoring (§3.2) and the dual tokens
//! (§3.1): which nodes measure a robot next cycle, when each sonar fires, and when its report
//! reaches the base station.

use crate::scenarios::seed_003::TestBed;
use crate::sensors::ultrasonic::{Aim, SonarRing};

/// One sonar firing requested for a robot in a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Request {
    /// The robot the firing is meant for.
    pub robot: usize,
    /// The firing node.
    pub node: usize,
    /// The sonar(s) aimed at the robot's predicted position.
    pub aim: Aim,
    /// The cell whose work token the firing holds (the robot's predicted cell).
    pub cell: usize,
}

/// A request with its time on the work-token and communication-token schedules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Timed {
    /// The request.
    pub request: Request,
    /// Firing time (s).
    pub time_s: f64,
    /// Arrival of the node's report at the base station (s).
    pub arrival_s: f64,
}

/// The task nodes of every robot, updated each cycle by seed 003's acceptance rule.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scheduler {
    /// Current task nodes per robot (without edge monitors).
    current: Vec<Vec<usize>>,
    /// Task nodes per robot and cycle (2 or 3 in the paper).
    task_nodes: usize,
    /// Distance to an inner border within which the border's nodes also measure (m).
    edge_margin_m: f64,
    /// A predicted bearing this close to a sector edge fires both adjacent sonars (rad).
    aim_margin_rad: f64,
}

/// What one cycle's scheduling decided.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Plan {
    /// Firings in request order (robot by robot, nearest node first).
    pub requests: Vec<Request>,
    /// Robots whose predicted task nodes were accepted this cycle.
    pub accepted: usize,
    /// Robots whose accepted task nodes differ from the previous ones.
    pub changed: usize,
}

impl Scheduler {
    /// Task nodes from the initial position estimates: the nearest nodes of each one's cell.
    pub fn new(
        bed: &TestBed,
        initial_m: &[[f64; 2]],
        task_nodes: usize,
        edge_margin_m: f64,
        aim_margin_rad: f64,
    ) -> Self {
        let current = initial_m
            .iter()
            .map(|&p| bed.nearest_cell_nodes(bed.cell_of(p), p, task_nodes))
            .collect();
        Self {
            current,
            task_nodes,
            edge_margin_m,
            aim_margin_rad,
        }
    }

    /// Next cycle's firings from the predicted positions `predicted_m` (one per robot).
    ///
    /// Per robot (seed 003 §3.4): the proposal is the `task_nodes` nodes of the predicted cell
    /// nearest to the prediction; it is accepted if more of its nodes coincide with the current
    /// task nodes than differ from them, else the current nodes measure again. Edge monitoring
    /// (§3.2): while the prediction lies within `edge_margin_m` of an inner border, the nodes at
    /// the ends of that border measure too. Each firing node aims the sonar whose sector holds
    /// the predicted bearing, and its neighbour too when the bearing is near their common edge.
    pub fn plan(&mut self, bed: &TestBed, sonar: &SonarRing, predicted_m: &[[f64; 2]]) -> Plan {
        let mut requests = Vec::new();
        let (mut accepted, mut changed) = (0, 0);
        for (robot, (&p, current)) in predicted_m.iter().zip(self.current.iter_mut()).enumerate() {
            let cell = bed.cell_of(p);
            let proposal = bed.nearest_cell_nodes(cell, p, self.task_nodes);
            // same = |proposal ∩ current|, different = |proposal \ current|
            let same = proposal.iter().filter(|n| current.contains(n)).count();
            let different = proposal.len() - same;
            if same > different {
                accepted += 1;
                if same < current.len().max(proposal.len()) {
                    changed += 1;
                }
                *current = proposal;
            }
            let mut nodes = current.clone();
            for border in bed.nearby_borders(p, self.edge_margin_m) {
                nodes.extend(border.shared_nodes);
            }
            nodes.sort_unstable();
            nodes.dedup();
            // nearest node first
            let distance = |n: usize| {
                let a = bed.nodes_m()[n];
                (a[0] - p[0]).hypot(a[1] - p[1])
            };
            nodes.sort_by(|&a, &b| distance(a).total_cmp(&distance(b)).then(a.cmp(&b)));
            requests.extend(nodes.into_iter().map(|node| Request {
                robot,
                node,
                aim: sonar.aim_at(bed.nodes_m()[node], p, self.aim_margin_rad),
                cell,
            }));
        }
        Plan {
            requests,
            accepted,
            changed,
        }
    }
}

/// Work-token slots: each request goes to the earliest slot in which neither its cell's token
/// nor its node is taken (one sonar per cell at a time; one sonar per node at a time). Slot `s`
/// fires at `start_s + s · ranging_slot_s`.
///
/// Communication token (TDMA on the single channel): reports are sent in firing order, each
/// when its ranging has ended and the channel is free, taking `comm_slot_s`.
///
/// Returns the timed requests sorted by firing time (then request order).
pub(crate) fn timetable(requests: &[Request], start_s: f64, ranging_slot_s: f64, comm_slot_s: f64) -> Vec<Timed> {
    // (cell, node) pairs already firing in each slot
    let mut slots: Vec<Vec<(usize, usize)>> = Vec::new();
    let mut slotted: Vec<(usize, Request)> = Vec::with_capacity(requests.len());
    for &request in requests {
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
        slotted.push((slot, request));
    }
    // firing order: by slot, then request order (stable sort)
    slotted.sort_by_key(|&(slot, _)| slot);
    let mut channel_free_s = start_s;
    slotted
        .into_iter()
        .map(|(slot, request)| {
            // t_f = t₀ + s · T_ranging
            let time_s = start_s + slot as f64 * ranging_slot_s;
            // the report is ready when the ranging ends and goes out when the token reaches it
            let send_s = (time_s + ranging_slot_s).max(channel_free_s);
            channel_free_s = send_s + comm_slot_s;
            Timed {
                request,
                time_s,
                arrival_s: channel_free_s,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predictions_are_accepted_only_when_most_nodes_coincide() {
        let bed = TestBed::paper();
        let sonar = SonarRing::srf08();
        // robot in cell 0's lower left: nodes 0, 1 and 3
        let mut scheduler = Scheduler::new(&bed, &[[0.9, 0.5]], 3, 0.3, 0.0);
        let before = scheduler.current[0].clone();
        assert_eq!(before.len(), 3);
        // small move: same cell, same nearest nodes
        assert_eq!(before, vec![0, 1, 3]);
        let plan = scheduler.plan(&bed, &sonar, &[[0.95, 0.5]]);
        assert_eq!((plan.accepted, plan.changed), (1, 0));
        // crossing x = 1: node 4 replaces node 3, two of three coincide: accepted, changed
        let plan = scheduler.plan(&bed, &sonar, &[[1.1, 0.5]]);
        assert_eq!((plan.accepted, plan.changed), (1, 1));
        assert_eq!(scheduler.current[0], vec![1, 0, 4]);
        let before = scheduler.current[0].clone();
        // a prediction two cells away shares no node with the current ones: rejected, the
        // current nodes measure again
        let plan = scheduler.plan(&bed, &sonar, &[[1.0, 5.0]]);
        assert_eq!(plan.accepted, 0);
        assert_eq!(scheduler.current[0], before);
        let nodes: Vec<usize> = plan.requests.iter().map(|r| r.node).collect();
        assert_eq!(nodes.len(), 3);
        assert!(nodes.iter().all(|n| before.contains(n)));
    }

    #[test]
    fn edge_monitoring_adds_the_border_nodes() {
        let bed = TestBed::paper();
        let sonar = SonarRing::srf08();
        // inside cell 0 near its upper right: task nodes 4 (2,2), 3 (0,2), 1 (2,0)
        let mut scheduler = Scheduler::new(&bed, &[[1.5, 1.6]], 3, 0.3, 0.0);
        let plan = scheduler.plan(&bed, &sonar, &[[1.85, 1.6]]);
        let nodes: Vec<usize> = plan.requests.iter().map(|r| r.node).collect();
        // the border x = 2 (nodes 1 and 4) is monitored; nearest node first
        assert!(nodes.contains(&1) && nodes.contains(&4), "{nodes:?}");
        assert_eq!(nodes[0], 4);
        // each firing aims at the robot
        for r in &plan.requests {
            assert!(sonar.in_aim(bed.nodes_m()[r.node], r.aim, [1.85, 1.6], 0.0));
        }
    }

    #[test]
    fn tokens_serialise_a_cell_and_a_node_and_the_channel() {
        let request = |robot, node, cell| Request {
            robot,
            node,
            aim: Aim::single(0),
            cell,
        };
        // robots 0 and 1 share cell 0; robot 2 is in cell 5 but shares node 4 with robot 0
        let requests = [
            request(0, 0, 0),
            request(0, 4, 0),
            request(1, 1, 0),
            request(2, 4, 5),
            request(2, 8, 5),
        ];
        let timed = timetable(&requests, 10.0, 0.065, 0.01);
        let slot_of = |i: usize| {
            let t = timed.iter().find(|t| t.request == requests[i]).unwrap().time_s;
            ((t - 10.0) / 0.065).round() as usize
        };
        // cell 0 fires once per slot, in request order
        assert_eq!([slot_of(0), slot_of(1), slot_of(2)], [0, 1, 2]);
        // cell 5 runs in parallel; node 4 is free in slot 0 (it fires for robot 0 in slot 1)
        assert_eq!([slot_of(3), slot_of(4)], [0, 1]);
        // sorted by firing time, reports one at a time on the channel
        assert!(timed.windows(2).all(|w| w[0].time_s <= w[1].time_s));
        for w in timed.windows(2) {
            assert!(w[1].arrival_s >= w[0].arrival_s + 0.01 - 1e-12);
        }
        for t in &timed {
            assert!(t.arrival_s >= t.time_s + 0.065 + 0.01 - 1e-12);
        }
    }
}
