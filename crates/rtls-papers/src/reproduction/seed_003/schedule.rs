//! The simulation's side of seed 003's scheduling: the engine's [`TaskScheduler`] picks each
//! robot's nodes (acceptance rule, edge monitoring) and its [`TokenTiming`] times them (dual
//! tokens); this module adds what the engine does not know — which sonars of a node to aim at
//! the prediction — and keeps each firing's robot.

use rtls_engine::scheduling::{CycleTimetable, FiringRequest, TaskScheduler, TokenTiming};

use crate::error::{Result, SimError};
use rtls_sim::scenarios::seed_003::TestBed;
use rtls_sim::sensors::ultrasonic::{Aim, SonarRing};

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

/// The task nodes of every robot, updated each cycle by the engine's scheduler.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scheduler {
    /// The engine's strategy (task-node count, edge margin).
    strategy: TaskScheduler,
    /// Current task nodes per robot (without edge monitors).
    current: Vec<Vec<usize>>,
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
    ///
    /// # Errors
    /// [`crate::SimError::InvalidParameter`] (`position_m`) for a non-finite estimate.
    pub fn new(bed: &TestBed, initial_m: &[[f64; 2]], strategy: TaskScheduler, aim_margin_rad: f64) -> Result<Self> {
        let current = initial_m
            .iter()
            .map(|&p| strategy.initial(bed.layout(), p).map_err(SimError::from_engine))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            strategy,
            current,
            aim_margin_rad,
        })
    }

    /// Next cycle's firings from the predicted positions `predicted_m` (one per robot): the
    /// engine's decision per robot ([`TaskScheduler::plan`]), each firing node aiming the sonar
    /// whose sector holds the predicted bearing, and its neighbour too when the bearing is near
    /// their common edge.
    ///
    /// # Errors
    /// As [`TaskScheduler::plan`] (a non-finite prediction, or not one per robot).
    pub fn plan(&mut self, bed: &TestBed, sonar: &SonarRing, predicted_m: &[[f64; 2]]) -> Result<Plan> {
        let decisions = self
            .strategy
            .plan(bed.layout(), &mut self.current, predicted_m)
            .map_err(SimError::from_engine)?;
        let mut requests = Vec::new();
        for (robot, (decision, &p)) in decisions.iter().zip(predicted_m).enumerate() {
            requests.extend(decision.firing_nodes.iter().map(|&node| Request {
                robot,
                node,
                aim: sonar.aim_at(bed.nodes_m()[node], p, self.aim_margin_rad),
                cell: decision.cell,
            }));
        }
        Ok(Plan {
            requests,
            accepted: decisions.iter().filter(|d| d.accepted).count(),
            changed: decisions.iter().filter(|d| d.changed).count(),
        })
    }

    /// The current task nodes of `robot` (empty for an unknown robot).
    #[cfg(test)]
    pub fn current(&self, robot: usize) -> &[usize] {
        self.current.get(robot).map_or(&[], Vec::as_slice)
    }
}

/// The cycle starting at `start_s` on the engine's token schedules ([`TokenTiming::cycle`]),
/// and the requests with their firing and arrival times, sorted by firing time (then request
/// order).
///
/// # Errors
/// As [`TokenTiming::cycle`].
pub(crate) fn timetable(
    timing: &TokenTiming,
    start_s: f64,
    requests: &[Request],
) -> Result<(CycleTimetable, Vec<Timed>)> {
    let firing_requests: Vec<FiringRequest> = requests
        .iter()
        .map(|r| FiringRequest {
            node: r.node,
            cell: r.cell,
        })
        .collect();
    let cycle = timing.cycle(start_s, &firing_requests).map_err(SimError::from_engine)?;
    let timed = cycle
        .firings
        .iter()
        .map(|f| Timed {
            request: requests[f.request],
            time_s: f.time_s,
            arrival_s: f.arrival_s,
        })
        .collect();
    Ok((cycle, timed))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_follows_the_engine_and_aims_at_the_prediction() {
        let bed = TestBed::paper().unwrap();
        let sonar = SonarRing::srf08();
        let strategy = TaskScheduler::new(3, 0.3).unwrap();
        let mut scheduler = Scheduler::new(&bed, &[[0.9, 0.5], [1.5, 1.6]], strategy, 0.0).unwrap();
        assert_eq!(scheduler.current(0), &[0, 1, 3]);
        // robot 0 crosses x = 1 (node 4 replaces node 3); robot 1 nears the border x = 2
        let plan = scheduler.plan(&bed, &sonar, &[[1.1, 0.5], [1.85, 1.6]]).unwrap();
        assert_eq!((plan.accepted, plan.changed), (2, 1));
        assert_eq!(scheduler.current(0), &[1, 0, 4]);
        let nodes = |robot: usize| -> Vec<usize> {
            plan.requests
                .iter()
                .filter(|r| r.robot == robot)
                .map(|r| r.node)
                .collect()
        };
        assert_eq!(nodes(0), vec![1, 0, 4]);
        // robot 1: (2,2) 0.43 m, (2,0) 1.61 m, (0,2) 1.89 m — the border's nodes 1 and 4 fire
        assert_eq!(nodes(1), vec![4, 1, 3]);
        for r in &plan.requests {
            let p = if r.robot == 0 { [1.1, 0.5] } else { [1.85, 1.6] };
            assert!(sonar.in_aim(bed.nodes_m()[r.node], r.aim, p, 0.0), "{r:?}");
            assert_eq!(r.cell, 0);
        }
        // a NaN prediction is an error, not a panic
        assert!(scheduler.plan(&bed, &sonar, &[[f64::NAN, 0.5], [1.0, 1.0]]).is_err());
    }

    #[test]
    fn the_timetable_keeps_each_firings_robot_and_aim() {
        let request = |robot, node, cell| Request {
            robot,
            node,
            aim: Aim::single(robot),
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
        let timing = TokenTiming::new(0.065, 0.01).unwrap();
        let (cycle, timed) = timetable(&timing, 10.0, &requests).unwrap();
        assert_eq!(timed.len(), 5);
        // the engine's order: slot 0 (requests 0, 3), slot 1 (1, 4), slot 2 (2)
        let order: Vec<Request> = timed.iter().map(|t| t.request).collect();
        assert_eq!(
            order,
            vec![requests[0], requests[3], requests[1], requests[4], requests[2]]
        );
        for (t, f) in timed.iter().zip(&cycle.firings) {
            assert_eq!((t.time_s, t.arrival_s), (f.time_s, f.arrival_s));
        }
        assert!((cycle.end_s - 10.215).abs() < 1e-12);
    }
}
