//! Seed 003's experiment: robots driving across a wireless sensor network of ultrasonic nodes,
//! tracked by least-squares multilateration (the paper's baseline), the paper's
//! single-observation EKF, or ours, the engine's multi-target tracker with data association
//! ([`rtls_engine::association::AnonymousTracker`]) — each in closed loop with the
//! paper's adaptive node scheduling, edge monitoring and dual-token timing.
//!
//! One call of [`run_seed_003`] simulates one method for one seed, cycle by cycle:
//! 1. the base station broadcasts the tokens (one communication slot); the broadcast also
//!    re-syncs the nodes' clocks (or, as in the paper, only the first one does);
//! 2. each robot's task nodes are scheduled from the tracker's predicted position by the
//!    engine's [`rtls_engine::scheduling::TaskScheduler`] (acceptance rule and edge
//!    monitoring), each firing node aiming its sonar(s) at the prediction;
//! 3. the work tokens order the firings (one sonar per cell and per node at a time, each
//!    firing a ranging slot) and each sonar hears the nearest reflecting robot in its sector;
//!    the node stamps the range with its own clock and counts the time of flight on it;
//! 4. the communication token brings the reports to the base one at a time (TDMA); the engine's
//!    [`rtls_engine::scheduling::EnergyLedger`] books every node's radio and sonar on-time;
//! 5. the tracker processes the echoes in firing order at their time stamps (ours: the echoes
//!    of one firing instant as one scan of the engine's tracker); the estimates are
//!    evaluated at the cycle's last firing; the next cycle starts when the last report is in.

mod bound;
mod clock;
mod config;
mod schedule;
mod trackers;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rtls_engine::scheduling::{CycleTimetable, EnergyLedger};
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::{Gaussian, Matrix, Vector};

pub use self::clock::ClockConfig;
pub use self::config::{EnergyConfig, SchedulingConfig, Seed003Config, TrackerConfig};
pub use rtls_engine::scheduling::TokenTiming;

use self::bound::{position_bound_m2, BoundDynamics, RangeEvent};
use self::clock::NodeClocks;
use self::schedule::{timetable, Scheduler};
use self::trackers::{Observation, Tracker, TrackerSettings};
use crate::error::{Result, SimError};
use rtls_sim::sensors::ultrasonic::{Aim, Echo};

/// The position estimator under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Least-squares multilateration per cycle (Gauss–Newton with ≥ 3 ranges, two-range fix
    /// with 2), scheduling from the last fix — seed 003's baseline (§2.4).
    LeastSquares,
    /// The paper's single-observation EKF: each echo updates the robot its sonar was aimed at
    /// (§3.3).
    PaperEkf,
    /// Ours: the engine's multi-target tracker
    /// ([`AnonymousTracker`](rtls_engine::association::AnonymousTracker)) — the same CV EKF per
    /// robot, each echo assigned to the track it matches (χ² gate, global nearest neighbour,
    /// sonar sectors as fields of view, the manoeuvre fallback), unmatched echoes dropped.
    AssociatedEkf,
}

impl Method {
    /// The three methods, baseline first.
    pub const ALL: [Self; 3] = [Self::LeastSquares, Self::PaperEkf, Self::AssociatedEkf];

    /// A short label for reports.
    ///
    /// # Example
    /// ```
    /// use rtls_papers::reproduction::seed_003::Method;
    /// assert_eq!(Method::PaperEkf.label(), "paper EKF");
    /// ```
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::LeastSquares => "LS",
            Self::PaperEkf => "paper EKF",
            Self::AssociatedEkf => "ours (EKF + GNN)",
        }
    }
}

/// The estimates at one evaluation epoch (a cycle's last firing).
#[derive(Debug, Clone, PartialEq)]
pub struct Epoch {
    /// Time (s).
    pub time_s: f64,
    /// True position of each robot (m).
    pub truth_m: Vec<[f64; 2]>,
    /// The method's position estimate of each robot (m): the EKF mean predicted to this time,
    /// or the latest LS fix.
    pub estimate_m: Vec<[f64; 2]>,
    /// The posterior Cramér–Rao bound on each robot's position MSE (m²) for this run's echoes,
    /// conditional on the robot's true manoeuvres (see [`run_seed_003`]).
    pub bound_m2: Vec<f64>,
    /// The same bound under the trackers' CV model instead (not a strict bound on straight legs).
    pub model_bound_m2: Vec<f64>,
}

/// One sonar firing of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FiringRecord {
    /// Firing time (s).
    pub time_s: f64,
    /// The firing's time stamp by the firing node's clock (s).
    pub stamp_s: f64,
    /// Arrival of the node's report at the base station (s).
    pub arrival_s: f64,
    /// The robot the firing was scheduled for.
    pub robot: usize,
    /// The firing node.
    pub node: usize,
    /// The sonar(s) fired.
    pub aim: Aim,
    /// The echo, if one was accepted (its `source` is the robot that truly reflected it).
    pub echo: Option<Echo>,
    /// The robot whose estimate used the echo, if any.
    pub used_by: Option<usize>,
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RunCounters {
    /// Cycles completed.
    pub cycles: usize,
    /// Scheduling decisions (robots × cycles).
    pub schedule_decisions: usize,
    /// Decisions whose predicted task nodes were accepted.
    pub schedule_accepted: usize,
    /// Accepted decisions that changed the task nodes.
    pub schedule_changes: usize,
    /// Σ over cycles of the nodes awake (firing at least once) in the cycle.
    pub awake_node_cycles: usize,
    /// Sonar firings.
    pub firings: usize,
    /// Firings that returned an accepted echo.
    pub echoes: usize,
    /// Echoes reflected by another robot than the one the sonar was aimed at.
    pub foreign_echoes: usize,
    /// Echoes used by an estimate.
    pub used: usize,
    /// Echoes used for another robot than the one that reflected them.
    pub wrong_associations: usize,
    /// Echoes the association gate dropped (ours).
    pub gated_out: usize,
    /// Echoes outside every gate given to the only track in the beam (ours).
    pub sole_candidate: usize,
    /// Echoes outside every gate that several tracks could have made after a manoeuvre,
    /// dropped because which one manoeuvred is unknown (ours).
    pub ambiguous: usize,
    /// LS fixes from ≥ 3 ranges, from 2 ranges, and robot-cycles without a fix.
    pub ls_fixes: [usize; 3],
    /// EKF updates skipped because a track sat on the firing node.
    pub singular_updates: usize,
}

/// The clock errors a run's measurements carried.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClockStats {
    /// Σ squared time-stamp errors over the firings (s²).
    pub stamp_error_sum_sq_s2: f64,
    /// Largest |time-stamp error| (s).
    pub stamp_error_max_s: f64,
    /// Firings stamped.
    pub stamps: usize,
    /// Largest |range error| from counting the time of flight on the node's clock, `|δ| r` (m).
    pub range_bias_max_m: f64,
}

impl ClockStats {
    /// RMS time-stamp error (s), 0 without stamps.
    #[must_use]
    pub fn rms_stamp_error_s(&self) -> f64 {
        if self.stamps == 0 {
            0.0
        } else {
            (self.stamp_error_sum_sq_s2 / self.stamps as f64).sqrt()
        }
    }

    /// Adds another run's statistics.
    pub fn merge(&mut self, other: &Self) {
        self.stamp_error_sum_sq_s2 += other.stamp_error_sum_sq_s2;
        self.stamp_error_max_s = self.stamp_error_max_s.max(other.stamp_error_max_s);
        self.stamps += other.stamps;
        self.range_bias_max_m = self.range_bias_max_m.max(other.range_bias_max_m);
    }
}

/// One seeded run of one method.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed003Run {
    /// The run's seed.
    pub seed: u64,
    /// The method.
    pub method: Method,
    /// Estimates at every cycle's last firing.
    pub epochs: Vec<Epoch>,
    /// Every firing, in firing order.
    pub firings: Vec<FiringRecord>,
    /// Counters.
    pub counters: RunCounters,
    /// Latency (s) from firing to estimate: per EKF update, or per LS fix (see the method).
    pub latencies_s: Vec<f64>,
    /// Start time of each cycle (s).
    pub cycle_starts_s: Vec<f64>,
    /// End of the last completed cycle (s): the time span the counters cover.
    pub end_s: f64,
    /// Every node's radio and sonar on-time, scheduled and with all nodes on, over the
    /// completed cycles.
    pub energy: EnergyLedger,
    /// The clock errors of the time stamps and ranges.
    pub clock: ClockStats,
}

/// Runs `method` on `config` with all randomness drawn from `seed` (initial estimates first, so
/// every method starts from the same estimates for the same seed).
///
/// Each epoch carries the PCRB of every robot's position from the trackers' `P₀` and the range
/// information at the robot's true position of every echo returned by a firing scheduled for
/// it (as if it were its echo, whoever reflected it) and of every other echo it truly reflected
/// — perfect association of the echoes the method's schedule produced — under two dynamics:
/// the robot's true manoeuvres (`bound_m2`: constant velocity on each leg, the velocity
/// re-opened by `|Δv|²` at each turn, stop or start; a lower bound for any estimator that does
/// not know the manoeuvre times) and the trackers' CV model (`model_bound_m2`: white
/// acceleration of PSD `q`, which an estimator can beat on the exactly straight legs).
///
/// # Errors
/// As [`Seed003Config::validate`]; [`SimError::Estimation`] if a filter step fails
/// numerically; as [`rtls_sim::pcrb::posterior_crb`].
///
/// # Example
/// ```
/// use rtls_papers::reproduction::seed_003::{run_seed_003, Method, Seed003Config};
/// use rtls_sim::scenarios::seed_003::planar_route;
/// let route = planar_route(&[[0.8, 0.7], [3.2, 0.7]], 0.5, 0.0, &[])?;
/// let config = Seed003Config::paper(vec![route], 4.0)?;
/// let run = run_seed_003(&config, Method::PaperEkf, 7)?;
/// let last = run.epochs.last().expect("cycles ran");
/// let error_m = (last.estimate_m[0][0] - last.truth_m[0][0]).hypot(last.estimate_m[0][1] - last.truth_m[0][1]);
/// assert!(error_m < 0.2 && error_m >= 0.0);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 003 §3.1–§3.4 (dual tokens, edge monitoring, single-observation EKF, adaptive
/// scheduling), §2.4 (LS baseline), §5 limit ① (robots sharing a cell).
pub fn run_seed_003(config: &Seed003Config, method: Method, seed: u64) -> Result<Seed003Run> {
    config.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let motion = config.motion()?;
    let p0 = config.initial_covariance();
    let settings = TrackerSettings {
        motion,
        acceleration_psd_m2ps3: config.tracker.acceleration_psd_m2ps3,
        range_variance_m2: config.sonar.range_noise_std_m.powi(2),
        gate_probability: config.tracker.gate_probability,
        sector_margin_rad: config.tracker.sector_margin_deg.to_radians(),
        manoeuvre_margin_m: config.tracker.manoeuvre_margin_m,
        manoeuvre_velocity_std_mps: config.tracker.manoeuvre_velocity_std_mps,
        manoeuvre_speed_change_mps: config.tracker.manoeuvre_speed_change_mps,
    };
    let truth_at = |t: f64| -> Result<Vec<[f64; 2]>> {
        config
            .robots
            .iter()
            .map(|r| r.state_at(t).map(|s| [s.position_m[0], s.position_m[1]]))
            .collect()
    };
    // x₀ ~ N(truth(0), P₀), drawn first for every method
    let mut initial = Vec::with_capacity(config.robots.len());
    for route in &config.robots {
        let s = route.state_at(0.0)?;
        let truth = [s.position_m[0], s.velocity_mps[0], s.position_m[1], s.velocity_mps[1]];
        let mean = Vector::<4>::from_fn(|i, _| {
            let z: f64 = StandardNormal.sample(&mut rng);
            truth[i] + p0[(i, i)].sqrt() * z
        });
        initial.push(Gaussian::new(mean, p0, 0.0).map_err(SimError::estimation(0.0))?);
    }
    let initial_m: Vec<[f64; 2]> = initial.iter().map(trackers::position).collect();
    let mut tracker = match method {
        Method::LeastSquares => Tracker::LeastSquares(initial_m.clone()),
        Method::PaperEkf => Tracker::PaperEkf(initial),
        Method::AssociatedEkf => Tracker::engine(&settings, &config.sonar, &initial)?,
    };
    let bed = &config.bed;
    let mut scheduler = Scheduler::new(
        bed,
        &initial_m,
        config.task_scheduler()?,
        config.scheduling.dual_sonar_margin_deg.to_radians(),
    )?;
    // the clocks draw from their own stream, so that they leave the measurement noise alone
    let mut clock_rng = ChaCha8Rng::seed_from_u64(seed);
    clock_rng.set_stream(1);
    let mut clocks = NodeClocks::new(bed.nodes_m().len(), &config.clock, &mut clock_rng)?;
    let mut run = Seed003Run {
        seed,
        method,
        epochs: Vec::new(),
        firings: Vec::new(),
        counters: RunCounters::default(),
        latencies_s: Vec::new(),
        cycle_starts_s: Vec::new(),
        end_s: 0.0,
        energy: EnergyLedger::new(bed.nodes_m().len(), config.energy.model(&config.sonar))
            .map_err(SimError::from_engine)?,
        clock: ClockStats::default(),
    };
    let mut cycle_start_s = 0.0;
    loop {
        // 1. token broadcast; the firings start when it has been sent
        let fire_start_s = cycle_start_s + config.timing.comm_slot_s;
        // 2. scheduling from the predicted positions
        let predicted = tracker.positions_at(&settings, fire_start_s)?;
        let plan = scheduler.plan(bed, &config.sonar, &predicted)?;
        // 3.–4. work tokens and communication token
        let (cycle, timed) = timetable(&config.timing, cycle_start_s, &plan.requests)?;
        let Some(last) = timed.last() else {
            return Err(SimError::EmptyInput {
                what: "firings of a cycle",
            });
        };
        let last_fire_s = last.time_s;
        if last_fire_s > config.duration_s {
            break;
        }
        // the broadcast syncs the clocks: every cycle, or only the first (the paper)
        if run.counters.cycles == 0 || config.clock.resync_every_cycle {
            clocks.sync(cycle.broadcast_end_s, &mut clock_rng);
        }
        run.cycle_starts_s.push(cycle_start_s);
        let mut observations = Vec::with_capacity(timed.len());
        for t in timed {
            let targets = truth_at(t.time_s)?;
            let node = t.request.node;
            let echo = config
                .sonar
                .fire(bed.nodes_m()[node], t.request.aim, &targets, &mut rng)?;
            // the node's clock: the stamp is off by e(t), the time of flight is scaled by 1 + δ
            let error_s = clocks.error_s(node, t.time_s);
            let rate = clocks.rate(node);
            let echo = echo.map(|e| Echo {
                range_m: e.range_m * rate,
                time_of_flight_s: e.time_of_flight_s * rate,
                source: e.source,
            });
            let c = &mut run.clock;
            c.stamp_error_sum_sq_s2 += error_s * error_s;
            c.stamp_error_max_s = c.stamp_error_max_s.max(error_s.abs());
            c.stamps += 1;
            if let Some(e) = echo {
                c.range_bias_max_m = c.range_bias_max_m.max((e.range_m - e.range_m / rate).abs());
            }
            observations.push(Observation {
                timed: t,
                stamp_s: t.time_s + error_s,
                echo,
            });
        }
        // 5. the tracker, then the evaluation at the last firing
        let outcome = tracker.process(&settings, &config.sonar, bed.nodes_m(), &observations)?;
        let estimate_m = tracker.positions_at(&settings, last_fire_s)?;
        run.epochs.push(Epoch {
            time_s: last_fire_s,
            truth_m: truth_at(last_fire_s)?,
            estimate_m,
            bound_m2: Vec::new(),
            model_bound_m2: Vec::new(),
        });
        count_cycle(&mut run, config.robots.len(), &plan, &cycle, &observations, &outcome)?;
        cycle_start_s = cycle.end_s;
        run.end_s = cycle.end_s;
    }
    attach_bounds(&mut run, config, &motion, &p0)?;
    Ok(run)
}

/// Adds one cycle's firings, counters and energy to the run.
fn count_cycle(
    run: &mut Seed003Run,
    robots: usize,
    plan: &schedule::Plan,
    cycle: &CycleTimetable,
    observations: &[Observation],
    outcome: &trackers::CycleOutcome,
) -> Result<()> {
    // the observations are in the cycle's firing order
    let sonars: Vec<usize> = observations.iter().map(|o| o.timed.request.aim.count).collect();
    run.energy.record_cycle(cycle, &sonars).map_err(SimError::from_engine)?;
    let c = &mut run.counters;
    c.cycles += 1;
    c.schedule_decisions += robots;
    c.schedule_accepted += plan.accepted;
    c.schedule_changes += plan.changed;
    let mut awake: Vec<usize> = plan.requests.iter().map(|r| r.node).collect();
    awake.sort_unstable();
    awake.dedup();
    c.awake_node_cycles += awake.len();
    c.gated_out += outcome.gated_out;
    c.sole_candidate += outcome.sole_candidate;
    c.ambiguous += outcome.ambiguous;
    c.singular_updates += outcome.singular;
    for k in 0..3 {
        c.ls_fixes[k] += outcome.ls_fixes[k];
    }
    for (o, &used_by) in observations.iter().zip(&outcome.used_by) {
        c.firings += 1;
        if let Some(echo) = o.echo {
            c.echoes += 1;
            c.foreign_echoes += usize::from(echo.source != o.timed.request.robot);
            if let Some(robot) = used_by {
                c.used += 1;
                c.wrong_associations += usize::from(echo.source != robot);
            }
        }
        run.firings.push(FiringRecord {
            time_s: o.timed.time_s,
            stamp_s: o.stamp_s,
            arrival_s: o.timed.arrival_s,
            robot: o.timed.request.robot,
            node: o.timed.request.node,
            aim: o.timed.request.aim,
            echo: o.echo,
            used_by,
        });
    }
    run.latencies_s.extend_from_slice(&outcome.latencies_s);
    Ok(())
}

/// Fills every epoch's PCRB. Robot `i` gets the information `Hᵀ R⁻¹ H` at its true position of
/// every range the method scheduled for it that returned an echo — as if that echo were `i`'s,
/// whoever reflected it — and of every other echo `i` truly reflected. Perfect association of
/// the echoes the schedule produced: a lower bound for any estimator that uses this schedule's
/// echoes.
fn attach_bounds(
    run: &mut Seed003Run,
    config: &Seed003Config,
    motion: &ConstantVelocity,
    p0: &Matrix<4>,
) -> Result<()> {
    let epochs_s: Vec<f64> = run.epochs.iter().map(|e| e.time_s).collect();
    let variance = config.sonar.range_noise_std_m.powi(2);
    for (robot, route) in config.robots.iter().enumerate() {
        let events = run
            .firings
            .iter()
            .filter(|f| f.echo.is_some_and(|e| f.robot == robot || e.source == robot))
            .map(|f| {
                let s = route.state_at(f.time_s)?;
                Ok(RangeEvent {
                    time_s: f.time_s,
                    node_m: config.bed.nodes_m()[f.node],
                    truth_m: [s.position_m[0], s.position_m[1]],
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let truth = position_bound_m2(BoundDynamics::TrueManoeuvres(route), p0, variance, &events, &epochs_s)?;
        let model = position_bound_m2(BoundDynamics::TrackerModel(motion), p0, variance, &events, &epochs_s)?;
        for ((epoch, b), m) in run.epochs.iter_mut().zip(truth).zip(model) {
            epoch.bound_m2.push(b);
            epoch.model_bound_m2.push(m);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
