//! The live feed: miners walking the mine and the RSSI scans the readers report, stepped to
//! any time.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rtls_engine::record::{Measurement, Record};

use super::walk::{uniform, Patrol, Roamer};
use super::MineLayout;
use crate::error::{Result, SimError};

/// The scenario's patrol limits for the miners who walk into the collapse: from west of it to
/// well east of it and back, m.
const PATROL_THROUGH_COLLAPSE_M: [f64; 2] = [250.0, 560.0];

/// How the miners move.
#[derive(Debug, Clone, PartialEq)]
pub enum WalkModel {
    /// Seed 000's test scenario: every miner walks back and forth between two fixed limits of
    /// his drift at a constant speed, forever; the entering miners' limits straddle the
    /// collapse (250–560 m), so they walk through it once per round trip.
    Patrol,
    /// The endless demo feed: miners walk, rest, turn back, change drift through the
    /// cross-cut, and from time to time one is sent into the collapse.
    Roaming(RoamingSettings),
}

/// The roaming miners' habits.
#[derive(Debug, Clone, PartialEq)]
pub struct RoamingSettings {
    /// Probability that a miner rests when he finishes a walk (never twice in a row), in `[0, 1]`.
    pub rest_probability: f64,
    /// A rest lasts uniformly `[min, max]` s (`0 < min ≤ max`).
    pub rest_duration_s: [f64; 2],
    /// Probability that a walk goes to another drift (through the cross-cut), in `[0, 1]`.
    pub drift_change_probability: f64,
    /// A walk along a drift covers at least this, m (`> 0`), unless the drift is shorter.
    pub min_walk_m: f64,
    /// Every this many seconds a miner, chosen at random among those not already heading in,
    /// is sent into the collapse (he walks there through the cross-cut, which can take several
    /// minutes); `None` sends nobody after the initial entering miners.
    pub collapse_approach_period_s: Option<f64>,
    /// Inside the collapse a miner lingers uniformly `[min, max]` s before walking back out
    /// west (`0 < min ≤ max`).
    pub collapse_linger_s: [f64; 2],
}

impl Default for RoamingSettings {
    /// Rests 30 % of the time for 5–60 s, a drift change on 30 % of the walks, walks of at
    /// least 20 m, a miner sent into the collapse every 2 minutes, lingering 5–20 s.
    fn default() -> Self {
        Self {
            rest_probability: 0.3,
            rest_duration_s: [5.0, 60.0],
            drift_change_probability: 0.3,
            min_walk_m: 20.0,
            collapse_approach_period_s: Some(120.0),
            collapse_linger_s: [5.0, 20.0],
        }
    }
}

/// What to simulate on a [`MineLayout`].
///
/// # Examples
/// ```
/// use rtls_sim::mine::{MineConfig, WalkModel};
/// let demo = MineConfig { miners: 50, start_time_s: 1.7e9, ..MineConfig::default() };
/// assert!(matches!(demo.walk, WalkModel::Roaming(_)));
/// assert_eq!(MineConfig::seed000_scenario().miners, 600);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MineConfig {
    /// Number of miners, tagged `miner-000`, `miner-001`, …
    pub miners: usize,
    /// The first this many miners start on the collapsed drift 60–140 m west of the collapse
    /// heading east into it (`≤ miners`).
    pub entering_miners: usize,
    /// Seed of every random draw (walks, scan phases, shadowing).
    pub seed: u64,
    /// Time of the simulation's start on the records' clock, s (e.g. Unix time); record times
    /// are `start_time_s + t`.
    pub start_time_s: f64,
    /// Each miner walks at a constant speed drawn uniformly from `[min, max)`, m/s.
    pub speed_range_mps: [f64; 2],
    /// How the miners move.
    pub walk: WalkModel,
}

impl MineConfig {
    /// Seed 000's scenario exactly as the mine test has always run it: 600 miners, 30 of them
    /// entering the collapse, seed 2026, start at 0 s, speeds 0.8–1.5 m/s, patrol walks.
    #[must_use]
    pub fn seed000_scenario() -> Self {
        Self {
            miners: 600,
            entering_miners: 30,
            seed: 2026,
            start_time_s: 0.0,
            speed_range_mps: [0.8, 1.5],
            walk: WalkModel::Patrol,
        }
    }
}

impl Default for MineConfig {
    /// The demo: 600 roaming miners, 10 of them entering the collapse at the start and one
    /// more every 2 minutes, seed 2026, start at 0 s (set `start_time_s` to now for a live feed).
    fn default() -> Self {
        Self {
            entering_miners: 10,
            walk: WalkModel::Roaming(RoamingSettings::default()),
            ..Self::seed000_scenario()
        }
    }
}

/// A miner's motion.
#[derive(Debug, Clone)]
enum Walker {
    Patrol(Patrol),
    Roaming(Box<Roamer>),
}

/// A simulated mine producing RSSI scans as a live, endless, deterministic feed.
///
/// Every miner is scanned once per second, at his own phase within the second; each working
/// reader within [`super::MineRadio::max_range_m`] draws a shadowed RSSI and reports it if it
/// reaches the sensitivity; a miner inside the collapse is heard by nobody. [`Self::step`]
/// advances to a time and returns the scans since the previous step, in time order. The
/// records do not depend on how the time is cut into steps.
///
/// # Examples
/// ```
/// use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation};
/// let config = MineConfig { miners: 5, entering_miners: 1, start_time_s: 1000.0, ..MineConfig::default() };
/// let mut mine = MineSimulation::new(MineLayout::seed000(), config)?;
/// let records = mine.step(1002.0);
/// assert!(records.iter().all(|r| r.time_s > 1000.0 && r.time_s <= 1002.0));
/// for tag in ["miner-000", "miner-004"] {
///     assert!(records.iter().any(|r| r.tag == tag));
/// }
/// assert!(mine.step(1001.0).is_empty()); // not after the last step
/// assert_eq!(mine.truth().count(), 5);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
#[derive(Debug, Clone)]
pub struct MineSimulation {
    layout: MineLayout,
    config: MineConfig,
    tags: Vec<String>,
    walkers: Vec<Walker>,
    /// Each miner's scan phase within a second, s in `[0, 1)`.
    phases_s: Vec<f64>,
    shadowing: Normal<f64>,
    /// Draws the shadowing (and, at the start, the miners' speeds, offsets and phases).
    rng: ChaCha8Rng,
    /// Chooses the miners sent into the collapse.
    scheduler_rng: ChaCha8Rng,
    /// The time reached, s after the start.
    now_s: f64,
    /// The second whose scans are in `batch`.
    second: u64,
    /// The scans of `second` as (time after the start, miner), in time order, and how many of
    /// them were done.
    batch: Vec<(f64, usize)>,
    batch_done: usize,
    /// How many collapse approaches were scheduled.
    approaches: u64,
}

impl MineSimulation {
    /// The miners of `config` placed on `layout` at `config.start_time_s`.
    ///
    /// # Errors
    /// The layout's [`MineLayout::validate`] errors; [`SimError::InvalidParameter`] for no
    /// miners, more entering miners than miners, a speed range that is not `0 < min ≤ max`, a non-finite
    /// start time, probabilities outside `[0, 1]`, durations that are not `0 < min ≤ max`, a
    /// non-positive minimum walk or approach period.
    pub fn new(layout: MineLayout, config: MineConfig) -> Result<Self> {
        layout.validate()?;
        validate(&config)?;
        let shadowing = Normal::new(0.0, layout.radio.shadowing_std_db).map_err(|_| SimError::InvalidParameter {
            name: "radio.shadowing_std_db",
            reason: "must be finite and ≥ 0",
        })?;
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        // the draws in seed 000's order: per miner speed, lateral offset, start, direction;
        // then the scan phases
        let collapse_drift = layout.collapse.drift;
        let starts: Vec<(f64, f64, usize, f64, bool)> = (0..config.miners)
            .map(|i| {
                let speed_mps = rng.gen_range(config.speed_range_mps[0]..config.speed_range_mps[1]);
                let lateral_m = rng.gen_range(-1.5..1.5);
                if i < config.entering_miners {
                    let x_m = uniform(&mut rng, layout.collapse.approach_start_x_m);
                    (speed_mps, lateral_m, collapse_drift, x_m, true)
                } else {
                    let drift = i % layout.drifts.len();
                    let x_m = uniform(&mut rng, layout.drifts[drift].walkable_x_m);
                    (speed_mps, lateral_m, drift, x_m, rng.gen_bool(0.5))
                }
            })
            .collect();
        let phases_s: Vec<f64> = (0..config.miners).map(|_| rng.gen_range(0.0..1.0)).collect();
        let walkers = starts
            .into_iter()
            .enumerate()
            .map(|(i, (speed_mps, lateral_m, drift, x_m, eastward))| {
                let entering = i < config.entering_miners;
                match &config.walk {
                    WalkModel::Patrol => Walker::Patrol(Patrol {
                        y_m: layout.drifts[drift].y_m + lateral_m,
                        start_x_m: x_m,
                        speed_mps,
                        limits_m: if entering {
                            PATROL_THROUGH_COLLAPSE_M
                        } else {
                            layout.drifts[drift].walkable_x_m
                        },
                        eastward,
                    }),
                    WalkModel::Roaming(settings) => {
                        // his own stream of the seed: his walk does not depend on the others'
                        let mut miner_rng = ChaCha8Rng::seed_from_u64(config.seed);
                        miner_rng.set_stream(i as u64 + 1);
                        Walker::Roaming(Box::new(Roamer::new(
                            &layout,
                            settings,
                            (drift, x_m),
                            lateral_m,
                            speed_mps,
                            entering,
                            miner_rng,
                        )))
                    }
                }
            })
            .collect();
        let mut scheduler_rng = ChaCha8Rng::seed_from_u64(config.seed);
        scheduler_rng.set_stream(u64::MAX);
        Ok(Self {
            tags: (0..config.miners).map(|i| format!("miner-{i:03}")).collect(),
            walkers,
            phases_s,
            shadowing,
            rng,
            scheduler_rng,
            now_s: 0.0,
            second: 0,
            batch: Vec::new(),
            batch_done: 0,
            approaches: 0,
            layout,
            config,
        })
    }

    /// The layout simulated.
    #[must_use]
    pub fn layout(&self) -> &MineLayout {
        &self.layout
    }

    /// The configuration simulated.
    #[must_use]
    pub fn config(&self) -> &MineConfig {
        &self.config
    }

    /// The time reached on the records' clock, s (`start_time_s` before the first step).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.config.start_time_s + self.now_s
    }

    /// Advances every miner to `until_time_s` (on the records' clock, e.g. Unix seconds) and
    /// returns the scans made since the previous step (times in `(previous, until_time_s]`), in
    /// time order. A time not after the previous one (or not finite) returns nothing and
    /// changes nothing.
    ///
    /// The feed is endless, and the same for a seed however the time is cut into steps. A
    /// step over a long time returns all of its scans (about 4 records per miner per second
    /// with seed 000's radio), so call it regularly, with `start_time_s` on the same clock; a
    /// caller that fell far behind (a suspended machine) can start a new simulation at its
    /// current time instead.
    pub fn step(&mut self, until_time_s: f64) -> Vec<Record> {
        let until_s = until_time_s - self.config.start_time_s;
        if !until_s.is_finite() || until_s <= self.now_s {
            return Vec::new();
        }
        let mut records = Vec::new();
        loop {
            if self.batch_done == self.batch.len() {
                self.start_batch();
            }
            let (t_s, miner) = self.batch[self.batch_done];
            if t_s > until_s {
                break;
            }
            self.send_miners_until(t_s);
            self.scan(miner, t_s, &mut records);
            self.batch_done += 1;
        }
        self.send_miners_until(until_s);
        if let WalkModel::Roaming(settings) = &self.config.walk {
            for walker in &mut self.walkers {
                if let Walker::Roaming(roamer) = walker {
                    roamer.advance(&self.layout, settings, until_s);
                }
            }
        }
        self.now_s = until_s;
        records
    }

    /// Every miner's tag and true position `[x, y]` (m) at [`Self::time_s`], in miner order.
    pub fn truth(&self) -> impl Iterator<Item = (&str, [f64; 2])> + '_ {
        self.walkers
            .iter()
            .zip(&self.tags)
            .map(|(walker, tag)| (tag.as_str(), self.position_m(walker, self.now_s)))
    }

    /// The scans of the next second, in time order (ties in miner order).
    fn start_batch(&mut self) {
        if !self.batch.is_empty() {
            self.second += 1;
        }
        let second = self.second as f64;
        self.batch = self
            .phases_s
            .iter()
            .enumerate()
            .map(|(i, phase)| (second + phase, i))
            .collect();
        self.batch.sort_by(|a, b| a.0.total_cmp(&b.0));
        self.batch_done = 0;
    }

    /// Position of `walker` at `t_s`, which the walker must have been advanced to.
    fn position_m(&self, walker: &Walker, t_s: f64) -> [f64; 2] {
        match walker {
            Walker::Patrol(patrol) => patrol.position_m(t_s),
            Walker::Roaming(roamer) => roamer.position_m(&self.layout, t_s),
        }
    }

    /// Sends a miner into the collapse at every approach time up to `t_s`.
    fn send_miners_until(&mut self, t_s: f64) {
        let WalkModel::Roaming(settings) = &self.config.walk else {
            return;
        };
        let Some(period_s) = settings.collapse_approach_period_s else {
            return;
        };
        loop {
            let approach_s = (self.approaches + 1) as f64 * period_s;
            if approach_s > t_s {
                return;
            }
            self.approaches += 1;
            let mut candidates = Vec::new();
            for (i, walker) in self.walkers.iter_mut().enumerate() {
                if let Walker::Roaming(roamer) = walker {
                    roamer.advance(&self.layout, settings, approach_s);
                    if !roamer.approaching() {
                        candidates.push(i);
                    }
                }
            }
            if candidates.is_empty() {
                continue;
            }
            let chosen = candidates[self.scheduler_rng.gen_range(0..candidates.len())];
            if let Walker::Roaming(roamer) = &mut self.walkers[chosen] {
                roamer.send_into_collapse(&self.layout, settings, approach_s);
            }
        }
    }

    /// One scan of `miner` at `t_s`: every working reader in range draws its RSSI
    /// `ρ = P₀ − 10 η log₁₀ max(d, d_min) + X` and reports it if `ρ ≥ ρ_min`; nothing from
    /// inside the collapse.
    fn scan(&mut self, miner: usize, t_s: f64, records: &mut Vec<Record>) {
        if let (Walker::Roaming(roamer), WalkModel::Roaming(settings)) = (&mut self.walkers[miner], &self.config.walk) {
            roamer.advance(&self.layout, settings, t_s);
        }
        let [x, y] = self.position_m(&self.walkers[miner], t_s);
        if self.layout.in_collapse([x, y]) {
            return;
        }
        let radio = &self.layout.radio;
        let time_s = self.config.start_time_s + t_s;
        for reader in self.layout.readers.iter().filter(|r| r.working) {
            let [rx, ry] = reader.position_m;
            let distance_m = ((x - rx).powi(2) + (y - ry).powi(2)).sqrt();
            if distance_m > radio.max_range_m {
                continue;
            }
            // ρ = P₀ − 10 η log₁₀ max(d, d_min) + X
            let rssi_dbm = radio.reference_power_dbm
                - 10.0 * radio.exponent * distance_m.max(radio.min_distance_m).log10()
                + self.shadowing.sample(&mut self.rng);
            if rssi_dbm >= radio.sensitivity_dbm {
                records.push(Record {
                    time_s,
                    tag: self.tags[miner].clone(),
                    measurement: Measurement::Rssi {
                        anchor: reader.id.clone(),
                        rssi_dbm,
                    },
                });
            }
        }
    }
}

/// Checks a configuration's own rules (the layout is checked separately).
fn validate(config: &MineConfig) -> Result<()> {
    let invalid = |name, reason| Err(SimError::InvalidParameter { name, reason });
    if config.miners == 0 {
        return invalid("miners", "must be at least 1");
    }
    if config.entering_miners > config.miners {
        return invalid("entering_miners", "must not exceed miners");
    }
    if !config.start_time_s.is_finite() {
        return Err(SimError::NonFinite { what: "start_time_s" });
    }
    let [slow, fast] = config.speed_range_mps;
    if !(slow.is_finite() && fast.is_finite() && 0.0 < slow && slow < fast) {
        return invalid("speed_range_mps", "must be [min, max) with 0 < min < max, m/s");
    }
    let WalkModel::Roaming(settings) = &config.walk else {
        return Ok(());
    };
    let probability = |p: f64| (0.0..=1.0).contains(&p);
    if !probability(settings.rest_probability) {
        return invalid("rest_probability", "must be in [0, 1]");
    }
    if !probability(settings.drift_change_probability) {
        return invalid("drift_change_probability", "must be in [0, 1]");
    }
    let durations = |[lo, hi]: [f64; 2]| lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi;
    if !durations(settings.rest_duration_s) {
        return invalid("rest_duration_s", "must be [min, max] with 0 < min ≤ max, s");
    }
    if !durations(settings.collapse_linger_s) {
        return invalid("collapse_linger_s", "must be [min, max] with 0 < min ≤ max, s");
    }
    if !(settings.min_walk_m.is_finite() && settings.min_walk_m > 0.0) {
        return invalid("min_walk_m", "must be finite and > 0, m");
    }
    if let Some(period_s) = settings.collapse_approach_period_s {
        if !(period_s.is_finite() && period_s > 0.0) {
            return invalid("collapse_approach_period_s", "must be finite and > 0, s");
        }
    }
    Ok(())
}
