//! Reduces each seed 003 run to the sums the report needs, and adds them up over runs in run
//! order (so the totals do not depend on the thread count).

use rtls_engine::scheduling::EnergyLedger;

use crate::error::{Result, SimError};
use crate::reproduction::seed_003::{ClockStats, RunCounters, Seed003Run};
use rtls_sim::scenarios::seed_003::TestBed;
use rtls_sim::trajectory::WaypointPath;

use super::scenario::Evaluation;

/// Width of the error-over-time bins (s).
pub(crate) const BIN_S: f64 = 0.5;

/// `Σ e²`, `Σ b²` and the count over a set of (robot, epoch) pairs: the RMSE and its PCRB bound
/// pooled over the same epochs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SquareSums {
    /// Σ squared position errors (m²).
    pub error_m2: f64,
    /// Σ PCRB position bounds conditional on the true manoeuvres (m²).
    pub bound_m2: f64,
    /// Σ PCRB position bounds under the trackers' CV model (m²).
    pub model_bound_m2: f64,
    /// Number of (robot, epoch) pairs.
    pub count: usize,
}

impl SquareSums {
    fn add(&mut self, error_m2: f64, [bound_m2, model_bound_m2]: [f64; 2]) {
        self.error_m2 += error_m2;
        self.bound_m2 += bound_m2;
        self.model_bound_m2 += model_bound_m2;
        self.count += 1;
    }

    fn merge(&mut self, other: &Self) {
        self.error_m2 += other.error_m2;
        self.bound_m2 += other.bound_m2;
        self.model_bound_m2 += other.model_bound_m2;
        self.count += other.count;
    }

    /// `√(Σ e² / n)` (m), 0 for no epochs.
    pub fn rmse_m(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.error_m2 / self.count as f64).sqrt()
        }
    }

    /// `√(Σ b² / n)` (m): the pooled √PCRB (true manoeuvres), 0 for no epochs.
    pub fn bound_m(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.bound_m2 / self.count as f64).sqrt()
        }
    }

    /// The pooled √PCRB under the trackers' CV model (m), 0 for no epochs.
    pub fn model_bound_m(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.model_bound_m2 / self.count as f64).sqrt()
        }
    }
}

/// A robot whose track was nearer another robot's truth in the swap window: where and when
/// it first was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SwapEvent {
    /// The run's seed.
    pub seed: u64,
    /// The robot.
    pub robot: usize,
    /// Time of the first such epoch (s).
    pub time_s: f64,
    /// The robot's true position then (m).
    pub truth_m: [f64; 2],
    /// Its error then (m).
    pub error_m: f64,
    /// Whether the robot stood still then (its true speed below 1 mm/s).
    pub standing: bool,
    /// Whether the track was back within the tracked error at the end of the run.
    pub recovered: bool,
}

/// What the report needs from runs of one method (one run, or the sum over runs).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct MethodTotals {
    /// Every epoch.
    pub all: SquareSums,
    /// Epochs before the first shared-cell episode (the paper's regime: one robot per cell).
    pub before: SquareSums,
    /// Epochs before the first shared-cell episode whose truth lies within the border band of
    /// an inner cell border.
    pub border: SquareSums,
    /// (robot, epoch) pairs with the robot in a cell shared with another robot.
    pub shared: SquareSums,
    /// Per robot.
    pub per_robot: Vec<SquareSums>,
    /// Per time bin of [`BIN_S`].
    pub bins: Vec<SquareSums>,
    /// Every position error (m), for the CDF.
    pub errors_m: Vec<f64>,
    /// Path length near borders before the first shared-cell episode: `[estimated, true]` (m)
    /// over consecutive epochs both in the band.
    pub border_path_m: [f64; 2],
    /// Robots whose track was nearer another robot's truth (and off by more than the tracked
    /// error) at some epoch of the swap window.
    pub swaps: usize,
    /// Each of those swaps.
    pub swap_events: Vec<SwapEvent>,
    /// Robots tracked (fraction of errors below the tracked error ≥ the tracked fraction).
    pub tracked: usize,
    /// Echoes used for the wrong robot during the shared-cell episodes.
    pub shared_wrong: usize,
    /// Counters summed.
    pub counters: RunCounters,
    /// Σ latencies (s) and their count.
    pub latency: (f64, usize),
    /// Σ simulated time covered by the counters (s).
    pub simulated_s: f64,
    /// Σ sonars fired (a dual-sonar firing counts 2).
    pub sonar_firings: usize,
    /// Every node's radio and sonar on-time, scheduled and all on (`None` before any run).
    pub energy: Option<EnergyLedger>,
    /// Time-stamp and range errors from the nodes' clocks.
    pub clock: ClockStats,
    /// Runs added.
    pub runs: usize,
}

/// What is fixed across runs: the bed, the evaluation settings, the shared-cell episodes.
#[derive(Debug, Clone)]
pub(crate) struct Context<'a> {
    /// The bed.
    pub bed: &'a TestBed,
    /// Evaluation settings.
    pub evaluation: &'a Evaluation,
    /// Intervals in which two robots share a cell (truth), s.
    pub shared_intervals: &'a [(f64, f64)],
    /// Time bins of the error-over-time figure.
    pub bins: usize,
    /// The robots' routes (true motion).
    pub routes: &'a [WaypointPath],
}

impl MethodTotals {
    /// The sums of one run.
    pub fn from_run(run: &Seed003Run, context: &Context<'_>) -> Self {
        let robots = run.epochs.first().map_or(0, |e| e.truth_m.len());
        let evaluation = context.evaluation;
        let mut totals = Self {
            per_robot: vec![SquareSums::default(); robots],
            bins: vec![SquareSums::default(); context.bins],
            runs: 1,
            counters: run.counters,
            simulated_s: run.end_s,
            latency: (run.latencies_s.iter().sum(), run.latencies_s.len()),
            sonar_firings: run.firings.iter().map(|f| f.aim.count).sum(),
            energy: Some(run.energy.clone()),
            clock: run.clock,
            ..Self::default()
        };
        let swap_window = match (context.shared_intervals.first(), context.shared_intervals.last()) {
            (Some(first), Some(last)) => Some((first.0, last.1 + evaluation.swap_window_s)),
            _ => None,
        };
        let episode_s = context.shared_intervals.first().map_or(f64::INFINITY, |i| i.0);
        let mut within = vec![0usize; robots];
        let mut swapped = vec![false; robots];
        for (k, epoch) in run.epochs.iter().enumerate() {
            let cells: Vec<usize> = epoch.truth_m.iter().map(|&p| context.bed.cell_of(p)).collect();
            let bin = ((epoch.time_s / BIN_S) as usize).min(context.bins.saturating_sub(1));
            for i in 0..robots {
                let (truth, estimate) = (epoch.truth_m[i], epoch.estimate_m[i]);
                let bound = [epoch.bound_m2[i], epoch.model_bound_m2[i]];
                let error_m = distance(truth, estimate);
                let e2 = error_m * error_m;
                totals.all.add(e2, bound);
                totals.per_robot[i].add(e2, bound);
                if let Some(b) = totals.bins.get_mut(bin) {
                    b.add(e2, bound);
                }
                totals.errors_m.push(error_m);
                within[i] += usize::from(error_m < evaluation.tracked_error_m);
                let before = epoch.time_s < episode_s;
                if before {
                    totals.before.add(e2, bound);
                }
                if before && context.bed.distance_to_inner_border_m(truth) <= evaluation.border_band_m {
                    totals.border.add(e2, bound);
                    // zig-zag: path length of consecutive epochs inside the band
                    if let Some(previous) = k.checked_sub(1).map(|j| &run.epochs[j]) {
                        if context.bed.distance_to_inner_border_m(previous.truth_m[i]) <= evaluation.border_band_m {
                            totals.border_path_m[0] += distance(previous.estimate_m[i], estimate);
                            totals.border_path_m[1] += distance(previous.truth_m[i], truth);
                        }
                    }
                }
                if (0..robots).any(|j| j != i && cells[j] == cells[i]) {
                    totals.shared.add(e2, bound);
                }
                let in_window = swap_window.is_some_and(|(from, to)| (from..=to).contains(&epoch.time_s));
                if in_window
                    && error_m > evaluation.tracked_error_m
                    && !swapped[i]
                    && (0..robots).any(|j| j != i && distance(epoch.truth_m[j], estimate) < error_m)
                {
                    swapped[i] = true;
                    let standing = context
                        .routes
                        .get(i)
                        .and_then(|r| r.state_at(epoch.time_s).ok())
                        .is_some_and(|s| s.velocity_mps[0].hypot(s.velocity_mps[1]) < 1e-3);
                    let recovered = run
                        .epochs
                        .last()
                        .is_some_and(|e| distance(e.truth_m[i], e.estimate_m[i]) < evaluation.tracked_error_m);
                    totals.swap_events.push(SwapEvent {
                        seed: run.seed,
                        robot: i,
                        time_s: epoch.time_s,
                        truth_m: truth,
                        error_m,
                        standing,
                        recovered,
                    });
                }
            }
        }
        let epochs = run.epochs.len().max(1) as f64;
        totals.tracked = within
            .iter()
            .filter(|&&n| n as f64 / epochs >= evaluation.tracked_fraction)
            .count();
        totals.swaps = swapped.iter().filter(|&&s| s).count();
        totals.shared_wrong = run
            .firings
            .iter()
            .filter(|f| {
                context
                    .shared_intervals
                    .iter()
                    .any(|&(a, b)| (a..=b).contains(&f.time_s))
            })
            .filter(|f| matches!((f.echo, f.used_by), (Some(echo), Some(robot)) if echo.source != robot))
            .count();
        totals
    }

    /// Adds another run's (or total's) sums.
    ///
    /// # Errors
    /// [`crate::SimError::InvalidParameter`] (`other`) when the energy ledgers cover different
    /// nodes or energy models (runs of different configurations).
    pub fn merge(&mut self, other: &Self) -> Result<()> {
        match (&mut self.energy, &other.energy) {
            (Some(mine), Some(theirs)) => mine.merge(theirs).map_err(SimError::from_engine)?,
            (None, Some(theirs)) => self.energy = Some(theirs.clone()),
            (_, None) => {}
        }
        self.clock.merge(&other.clock);
        self.all.merge(&other.all);
        self.before.merge(&other.before);
        self.border.merge(&other.border);
        self.shared.merge(&other.shared);
        if self.per_robot.len() < other.per_robot.len() {
            self.per_robot.resize(other.per_robot.len(), SquareSums::default());
        }
        for (a, b) in self.per_robot.iter_mut().zip(&other.per_robot) {
            a.merge(b);
        }
        if self.bins.len() < other.bins.len() {
            self.bins.resize(other.bins.len(), SquareSums::default());
        }
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            a.merge(b);
        }
        self.errors_m.extend_from_slice(&other.errors_m);
        self.border_path_m[0] += other.border_path_m[0];
        self.border_path_m[1] += other.border_path_m[1];
        self.swaps += other.swaps;
        self.swap_events.extend_from_slice(&other.swap_events);
        self.tracked += other.tracked;
        self.shared_wrong += other.shared_wrong;
        let (c, o) = (&mut self.counters, &other.counters);
        c.cycles += o.cycles;
        c.schedule_decisions += o.schedule_decisions;
        c.schedule_accepted += o.schedule_accepted;
        c.schedule_changes += o.schedule_changes;
        c.awake_node_cycles += o.awake_node_cycles;
        c.firings += o.firings;
        c.echoes += o.echoes;
        c.foreign_echoes += o.foreign_echoes;
        c.used += o.used;
        c.wrong_associations += o.wrong_associations;
        c.gated_out += o.gated_out;
        c.sole_candidate += o.sole_candidate;
        c.ambiguous += o.ambiguous;
        for k in 0..3 {
            c.ls_fixes[k] += o.ls_fixes[k];
        }
        c.singular_updates += o.singular_updates;
        self.latency.0 += other.latency.0;
        self.latency.1 += other.latency.1;
        self.simulated_s += other.simulated_s;
        self.sonar_firings += other.sonar_firings;
        self.runs += other.runs;
        Ok(())
    }

    /// Per-run mean of a sum.
    pub fn per_run_f64(&self, sum: f64) -> f64 {
        sum / self.runs.max(1) as f64
    }

    /// Per-run mean of a count.
    pub fn per_run(&self, count: usize) -> f64 {
        count as f64 / self.runs.max(1) as f64
    }

    /// Path-length excess near borders, `(estimated / true − 1) · 100` (%).
    pub fn border_path_excess_percent(&self) -> f64 {
        if self.border_path_m[1] > 0.0 {
            (self.border_path_m[0] / self.border_path_m[1] - 1.0) * 100.0
        } else {
            0.0
        }
    }

    /// Mean latency (s).
    pub fn mean_latency_s(&self) -> f64 {
        self.latency.0 / self.latency.1.max(1) as f64
    }

    /// Mean cycle period (s).
    pub fn mean_cycle_s(&self) -> f64 {
        self.simulated_s / self.counters.cycles.max(1) as f64
    }

    /// Rate of `count` events over the simulated time (1/s).
    pub fn rate_per_s(&self, count: usize) -> f64 {
        if self.simulated_s > 0.0 {
            count as f64 / self.simulated_s
        } else {
            0.0
        }
    }

    /// `100 · part / whole` (%), 0 for an empty whole.
    pub fn percent(part: usize, whole: usize) -> f64 {
        if whole == 0 {
            0.0
        } else {
            100.0 * part as f64 / whole as f64
        }
    }
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}
