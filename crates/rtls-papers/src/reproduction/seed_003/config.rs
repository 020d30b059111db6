//! The configuration of a seed 003 run: token timing, scheduling, tracker tuning, clocks,
//! energy, and the whole run's [`Seed003Config`].

use rtls_engine::scheduling::{EnergyModel, PowerModel, TaskScheduler, TokenTiming};
use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
use rtls_estimation::{Matrix, Vector};

use super::clock::ClockConfig;
use crate::error::{positive, Result, SimError};
use rtls_sim::scenarios::seed_003::TestBed;
use rtls_sim::sensors::ultrasonic::SonarRing;
use rtls_sim::trajectory::WaypointPath;

/// What the energy accounting assumes beyond the sonar's echo window.
///
/// # References
/// See [`PowerModel`] (CC2420 and SRF08 datasheet figures).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyConfig {
    /// Power draws of the radio and of a ranging sonar (W).
    pub power: PowerModel,
    /// Length of one ping (s): SRF08, 8 cycles at 40 kHz = 0.2 ms.
    pub sonar_ping_s: f64,
    /// Sonars every node fires per cycle in the all-nodes-on reference.
    pub all_on_sonars_per_node: usize,
}

impl EnergyConfig {
    /// The engine's energy model with `sonar`'s echo window: a fired sonar is on for the ping
    /// plus the window.
    #[must_use]
    pub fn model(&self, sonar: &SonarRing) -> EnergyModel {
        EnergyModel {
            power: self.power,
            sonar_ping_s: self.sonar_ping_s,
            echo_window_s: sonar.echo_window_s,
            all_on_sonars_per_node: self.all_on_sonars_per_node,
        }
    }
}

/// Node scheduling (seed 003 §3.2 and §3.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchedulingConfig {
    /// Task nodes per robot and cycle (the paper: 2 or 3), 1–4.
    pub task_nodes: usize,
    /// Edge zone: within this distance of an inner border the border's nodes also measure (m).
    pub edge_margin_m: f64,
    /// A firing node fires both adjacent sonars when the predicted bearing lies within this
    /// angle of the edge between their sectors (deg).
    pub dual_sonar_margin_deg: f64,
}

/// The EKFs' tuning, shared by the paper's EKF and ours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// Power spectral density `q` of the CV model's white acceleration (m²/s³): continuous
    /// noise, integrated exactly over the irregular steps between firings.
    pub acceleration_psd_m2ps3: f64,
    /// Initial position uncertainty per axis (m): tracks start at the truth plus this noise.
    pub initial_position_std_m: f64,
    /// Initial velocity uncertainty per axis (m/s).
    pub initial_velocity_std_mps: f64,
    /// Probability of the χ²(1) association gate (ours), in (0, 1).
    pub gate_probability: f64,
    /// Association: a track is a candidate for an echo if its prediction lies in the sonar's
    /// sector widened by this angle on each side (deg).
    pub sector_margin_deg: f64,
    /// Association: an echo outside every gate goes to the only candidate whose predicted range
    /// is within this distance of it (a manoeuvre), m.
    pub manoeuvre_margin_m: f64,
    /// Association: the velocity uncertainty per axis re-opened on a track found manoeuvring
    /// (m/s).
    pub manoeuvre_velocity_std_mps: f64,
    /// Association: the largest velocity change `|Δv|` a robot makes (m/s; a reversal at speed
    /// `v` is `2 v`). When an echo outside every gate is within the manoeuvre margin of several
    /// tracks, a track can only have made it if its range innovation is within
    /// `3 √S + |Δv| · (t − t_last update)`; if exactly one can, it takes the echo.
    pub manoeuvre_speed_change_mps: f64,
}

/// Everything one seed 003 run needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed003Config {
    /// The bed and its nodes.
    pub bed: TestBed,
    /// Each node's sonars.
    pub sonar: SonarRing,
    /// Token timing.
    pub timing: TokenTiming,
    /// Scheduling.
    pub scheduling: SchedulingConfig,
    /// EKF tuning.
    pub tracker: TrackerConfig,
    /// The nodes' clocks and their sync.
    pub clock: ClockConfig,
    /// Energy accounting.
    pub energy: EnergyConfig,
    /// One route per robot (z ignored), each at least `duration_s` long.
    pub robots: Vec<WaypointPath>,
    /// Simulated time (s).
    pub duration_s: f64,
}

impl Seed003Config {
    /// Checks the configuration.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad field; [`SimError::EmptyInput`]
    /// without robots; [`SimError::NonFinite`] for NaN/∞.
    pub fn validate(&self) -> Result<()> {
        self.sonar.validate()?;
        self.timing.validate().map_err(SimError::from_engine)?;
        if !(1..=4).contains(&self.scheduling.task_nodes) {
            return Err(SimError::InvalidParameter {
                name: "task_nodes",
                reason: "a robot needs 1 to 4 task nodes of its cell",
            });
        }
        crate::error::non_negative(
            self.scheduling.edge_margin_m,
            "edge_margin_m",
            "the edge margin must not be negative",
        )?;
        self.clock.validate()?;
        self.energy
            .model(&self.sonar)
            .validate()
            .map_err(SimError::from_engine)?;
        crate::error::non_negative(
            self.scheduling.dual_sonar_margin_deg,
            "dual_sonar_margin_deg",
            "the dual-sonar margin must not be negative",
        )?;
        let t = &self.tracker;
        crate::error::non_negative(
            t.acceleration_psd_m2ps3,
            "acceleration_psd_m2ps3",
            "q must not be negative",
        )?;
        positive(
            t.initial_position_std_m,
            "initial_position_std_m",
            "the initial uncertainty must be positive",
        )?;
        positive(
            t.initial_velocity_std_mps,
            "initial_velocity_std_mps",
            "the initial uncertainty must be positive",
        )?;
        crate::error::finite(t.gate_probability, "gate_probability")?;
        if !(t.gate_probability > 0.0 && t.gate_probability < 1.0) {
            return Err(SimError::InvalidParameter {
                name: "gate_probability",
                reason: "the gate probability must lie in (0, 1)",
            });
        }
        crate::error::non_negative(
            t.sector_margin_deg,
            "sector_margin_deg",
            "the sector margin must not be negative",
        )?;
        crate::error::non_negative(
            t.manoeuvre_margin_m,
            "manoeuvre_margin_m",
            "the manoeuvre margin must not be negative",
        )?;
        crate::error::non_negative(
            t.manoeuvre_velocity_std_mps,
            "manoeuvre_velocity_std_mps",
            "the re-opened velocity uncertainty must not be negative",
        )?;
        crate::error::non_negative(
            t.manoeuvre_speed_change_mps,
            "manoeuvre_speed_change_mps",
            "the largest velocity change must not be negative",
        )?;
        positive(self.duration_s, "duration_s", "the simulated time must be positive")?;
        if self.robots.is_empty() {
            return Err(SimError::EmptyInput { what: "robots" });
        }
        if self.robots.iter().any(|r| r.duration_s() < self.duration_s) {
            return Err(SimError::InvalidParameter {
                name: "duration_s",
                reason: "every robot route must last at least the simulated time",
            });
        }
        Ok(())
    }

    /// The engine's task scheduler for this configuration.
    ///
    /// # Errors
    /// As [`TaskScheduler::new`] (a zero task-node count or a bad edge margin).
    pub fn task_scheduler(&self) -> Result<TaskScheduler> {
        TaskScheduler::new(self.scheduling.task_nodes, self.scheduling.edge_margin_m).map_err(SimError::from_engine)
    }

    /// The trackers' motion model (CV, continuous white acceleration of PSD `q`).
    ///
    /// # Errors
    /// [`SimError::Estimation`] for an invalid `q`.
    pub fn motion(&self) -> Result<ConstantVelocity> {
        ConstantVelocity::new(ProcessNoise::continuous(self.tracker.acceleration_psd_m2ps3))
            .map_err(SimError::estimation(0.0))
    }

    /// The trackers' initial covariance `P₀ = diag(σ_p², σ_v², σ_p², σ_v²)`.
    #[must_use]
    pub fn initial_covariance(&self) -> Matrix<4> {
        let (p, v) = (
            self.tracker.initial_position_std_m.powi(2),
            self.tracker.initial_velocity_std_mps.powi(2),
        );
        Matrix::<4>::from_diagonal(&Vector::<4>::new(p, v, p, v))
    }
}

impl Seed003Config {
    /// The paper's bed with `robots` driving for `duration_s`, and our choices for what the
    /// paper leaves open — the values of `scenarios/003-test-bed.toml`, where each is
    /// justified: SRF08 sonars ([`SonarRing::srf08`]), 65 ms ranging slot, 10 ms
    /// communication slot, 3 task nodes, 0.3 m edge margin, both sonars within 10° of a sector
    /// edge, `q` = 0.02 m²/s³, `P₀` = diag(0.1², 0.2², 0.1², 0.2²), 99 % gate, 10° sector
    /// margin, 0.75 m manoeuvre margin, 0.5 m/s re-opened velocity; clocks drifting by
    /// σ = 20 ppm with a 0.1 ms sync jitter, re-synced every cycle; a CC2420 radio and SRF08
    /// sonars ([`PowerModel::cc2420_srf08`]), 0.2 ms pings, 6 sonars per node when all are on.
    ///
    /// # Errors
    /// As [`Seed003Config::validate`].
    ///
    /// # References
    /// Seed 003 §1 (bed, nodes, sonars), §3.1–§3.4 (tokens, edge monitoring, EKF, scheduling).
    pub fn paper(robots: Vec<WaypointPath>, duration_s: f64) -> Result<Self> {
        let config = Self {
            bed: TestBed::paper()?,
            sonar: SonarRing::srf08(),
            timing: TokenTiming {
                ranging_slot_s: 0.065,
                comm_slot_s: 0.01,
            },
            scheduling: SchedulingConfig {
                task_nodes: 3,
                edge_margin_m: 0.3,
                dual_sonar_margin_deg: 10.0,
            },
            tracker: TrackerConfig {
                acceleration_psd_m2ps3: 0.02,
                initial_position_std_m: 0.1,
                initial_velocity_std_mps: 0.2,
                gate_probability: 0.99,
                sector_margin_deg: 10.0,
                manoeuvre_margin_m: 0.75,
                manoeuvre_velocity_std_mps: 0.5,
                manoeuvre_speed_change_mps: 1.0,
            },
            clock: ClockConfig {
                drift_std_ppm: 20.0,
                sync_jitter_std_s: 1e-4,
                resync_every_cycle: true,
            },
            energy: EnergyConfig {
                power: PowerModel::cc2420_srf08(),
                sonar_ping_s: 0.0002,
                all_on_sonars_per_node: 6,
            },
            robots,
            duration_s,
        };
        config.validate()?;
        Ok(config)
    }
}
