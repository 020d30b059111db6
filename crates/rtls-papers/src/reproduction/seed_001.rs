//! Seed 001's experiment, one seeded run: a tag tracked by two UWB base stations from the
//! joint measurement `z = [z_TOA; z_RSS]`, by the paper's UKF (α = 0.01, β = 2, κ = 0) and an
//! EKF on the constant-velocity model, and by the coordinated-turn model with the turn rate as
//! a state (what the field uses for turning targets); the single-epoch TOA-RSS fixes (the
//! paper's "before UKF"); the NEES/NIS of every filter; the measurement information at the true
//! states for the posterior Cramér–Rao bound; and, optionally, the same run with NLOS-biased
//! ranges for a plain and a robust (one-sided NIS-gated, down-weighting) UKF.

mod measurements;
mod nlos;
mod trackers;

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rtls_estimation::filter::SigmaPointParameters;
use rtls_estimation::imm::ModeTransitions;
use rtls_estimation::measurement::{BreakpointPathLoss, NoiseCovariance, Ranges, RssPathLoss, Stacked};
use rtls_estimation::stats::ChiSquareGate;
use rtls_estimation::{Gaussian, Matrix, Vector};

use crate::error::{finite, non_negative, positive, Result, SimError};
use measurements::{information_at_truth, joint_fixes};
use nlos::run_nlos;
use rtls_sim::scenarios::seed_001::{Seed001Truth, SEED_001_STATIONS};
use rtls_sim::sensors::uwb::{NlosBias, UwbRssSimulator, UwbToaSimulator};
use trackers::run_trackers;

/// The joint TOA + RSS measurement model: ranges to every station, then path losses.
pub type JointMeasurement = Stacked<Ranges, RssPathLoss<BreakpointPathLoss>>;

/// The NLOS extension: ranges biased by [`NlosBias`], tracked by the plain UKF and by a robust
/// UKF that down-weights ranges whose one-sided normalised innovation exceeds a χ²(1) gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed001Nlos {
    /// The bias added to every range.
    pub bias: NlosBias,
    /// Gate probability `P_G` of the robust UKF: a range longer than predicted by more than
    /// `√γ` innovation standard deviations, `γ = χ²_{P_G}(1)`, is down-weighted.
    pub gate_probability: f64,
}

/// Everything a seed 001 run is configured by (the scenario files `001-cv.toml` and
/// `001-turn.toml` are parsed into this).
///
/// # Units
/// m, m/s, s, dB; `σ_ω` in m/s², turn-rate prior in rad/s, turn-rate noise in rad/s².
#[derive(Debug, Clone, PartialEq)]
pub struct Seed001Config {
    /// Truth motion, initial state, duration, step and `σ_ω`.
    pub truth: Seed001Truth,
    /// Base stations, m.
    pub stations_m: Vec<[f64; 2]>,
    /// `σ`: TOA ranging noise, m.
    pub range_std_m: f64,
    /// The mean path-loss law of the RSS (truth and filters), dB.
    pub rss_law: BreakpointPathLoss,
    /// `σ_s`: shadowing, dB.
    pub shadowing_std_db: f64,
    /// Sigma-point parameters of the UKFs (seed 001: α = 0.01, β = 2, κ = 0).
    pub sigma_points: SigmaPointParameters,
    /// Standard deviation of the initial position estimate per axis, m (`P₀`).
    pub initial_position_std_m: f64,
    /// Standard deviation of the initial velocity estimate per axis, m/s (`P₀`).
    pub initial_velocity_std_mps: f64,
    /// Prior standard deviation of the turn rate of the CT filters (mean 0), rad/s.
    pub turn_rate_prior_std_rad_s: f64,
    /// Standard deviation of the white turn-rate acceleration of the CT filters, rad/s².
    pub turn_rate_noise_std_rad_s2: f64,
    /// Mean sojourn times of the IMM's CV and CT modes, s.
    pub imm_sojourn_s: [f64; 2],
    /// The NLOS extension, if run.
    pub nlos: Option<Seed001Nlos>,
}

impl Seed001Config {
    /// The values of the shipped scenario files for `truth`: two stations at
    /// [`SEED_001_STATIONS`], `σ = 0.2` m, continuous breakpoint law with `P0 = 48.7` dB at
    /// `d₀ = 1` m, `n = 2`, `d_b = 10` m, `σ_s = 2` dB, seed 001's sigma points, `P₀` of 0.5 m and
    /// 0.3 m/s per axis, CT prior 0.2 rad/s and noise 0.01 rad/s², IMM sojourn times 20 s, no
    /// NLOS (the reasons are given in `scenarios/001-cv.toml`).
    ///
    /// # Errors
    /// As [`Seed001Config::validate`].
    ///
    /// # Example
    /// ```
    /// use rtls_papers::reproduction::seed_001::{run_seed_001, Seed001Config};
    /// use rtls_sim::scenarios::seed_001::{Seed001Motion, Seed001Truth};
    /// let config = Seed001Config::new(Seed001Truth::paper(Seed001Motion::ConstantVelocity, 0.02)?)?;
    /// let run = run_seed_001(&config, 1)?;
    /// assert_eq!(run.truth.len(), 50);
    /// assert_eq!(run.tracks.len(), 5);
    /// # Ok::<(), rtls_sim::SimError>(())
    /// ```
    pub fn new(truth: Seed001Truth) -> Result<Self> {
        let config = Self {
            truth,
            stations_m: SEED_001_STATIONS.to_vec(),
            range_std_m: 0.2,
            rss_law: BreakpointPathLoss::new(
                48.7,
                1.0,
                2.0,
                10.0,
                rtls_estimation::measurement::BreakpointForm::Continuous,
            )
            .map_err(SimError::estimation(0.0))?,
            shadowing_std_db: 2.0,
            sigma_points: SigmaPointParameters::seed_001(),
            initial_position_std_m: 0.5,
            initial_velocity_std_mps: 0.3,
            turn_rate_prior_std_rad_s: 0.2,
            turn_rate_noise_std_rad_s2: 0.01,
            imm_sojourn_s: [20.0, 20.0],
            nlos: None,
        };
        config.validate()?;
        Ok(config)
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] / [`SimError::NonFinite`] naming the field; the errors of
    /// [`Seed001Truth::validate`] and [`NlosBias::validate`].
    pub fn validate(&self) -> Result<()> {
        self.truth.validate()?;
        if self.stations_m.len() < 2 {
            return Err(SimError::InvalidParameter {
                name: "stations_m",
                reason: "a planar track from ranges needs at least two base stations",
            });
        }
        for s in &self.stations_m {
            crate::error::finite2(*s, "base station")?;
        }
        positive(self.range_std_m, "range_std_m", "the TOA noise must be positive")?;
        positive(
            self.shadowing_std_db,
            "shadowing_std_db",
            "the shadowing must be positive",
        )?;
        positive(
            self.initial_position_std_m,
            "initial_position_std_m",
            "the initial position uncertainty must be positive",
        )?;
        positive(
            self.initial_velocity_std_mps,
            "initial_velocity_std_mps",
            "the initial velocity uncertainty must be positive",
        )?;
        positive(
            self.turn_rate_prior_std_rad_s,
            "turn_rate_prior_std_rad_s",
            "the turn-rate prior must be positive",
        )?;
        non_negative(
            self.turn_rate_noise_std_rad_s2,
            "turn_rate_noise_std_rad_s2",
            "the turn-rate noise must not be negative",
        )?;
        ModeTransitions::mean_sojourn(self.imm_sojourn_s.to_vec()).map_err(SimError::estimation(0.0))?;
        SigmaPointParameters::new(self.sigma_points.alpha, self.sigma_points.beta, self.sigma_points.kappa)
            .and_then(|p| p.weights(4))
            .map_err(SimError::estimation(0.0))?;
        if let Some(nlos) = &self.nlos {
            nlos.bias.validate()?;
            finite(nlos.gate_probability, "gate probability")?;
            ChiSquareGate::new(nlos.gate_probability).map_err(SimError::estimation(0.0))?;
        }
        Ok(())
    }

    /// `P₀ = diag(σ_p², σ_v², σ_p², σ_v²)`: the filters' initial covariance and the PCRB's prior.
    #[must_use]
    pub fn initial_covariance(&self) -> Matrix<4> {
        let (p, v) = (
            self.initial_position_std_m.powi(2),
            self.initial_velocity_std_mps.powi(2),
        );
        Matrix::<4>::from_diagonal(&Vector::<4>::new(p, v, p, v))
    }

    /// The joint measurement model `[ranges; path losses]` with `R = blockdiag(σ² I, σ_s² I)`.
    ///
    /// # Errors
    /// [`SimError::Estimation`] for invalid noise (validated configs never fail).
    pub fn joint_measurement(&self) -> Result<JointMeasurement> {
        Ok(Stacked::new::<4>(
            self.ranges(self.range_std_m.powi(2))?,
            self.rss_model()?,
        ))
    }

    fn ranges(&self, variance_m2: f64) -> Result<Ranges> {
        let n = self.stations_m.len();
        NoiseCovariance::isotropic(n, variance_m2)
            .and_then(|r| Ranges::planar(&self.stations_m, r))
            .map_err(SimError::estimation(0.0))
    }

    fn rss_model(&self) -> Result<RssPathLoss<BreakpointPathLoss>> {
        let n = self.stations_m.len();
        NoiseCovariance::isotropic(n, self.shadowing_std_db.powi(2))
            .and_then(|r| RssPathLoss::planar(self.rss_law, &self.stations_m, r))
            .map_err(SimError::estimation(0.0))
    }
}

/// The trackers every run compares, in the order of [`Seed001Run::tracks`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Seed001Filter {
    /// The paper's UKF on the CV model.
    Ukf,
    /// The paper's EKF on the CV model.
    Ekf,
    /// UKF on the coordinated turn with the rate as a fifth state.
    UkfTurnRate,
    /// EKF on the coordinated turn with the rate as a fifth state.
    EkfTurnRate,
    /// IMM of a CV UKF and a CT (rate estimated) UKF.
    Imm,
}

impl Seed001Filter {
    /// Number of trackers.
    pub const COUNT: usize = 5;

    /// All trackers, in run order.
    pub const ALL: [Self; Self::COUNT] = [Self::Ukf, Self::Ekf, Self::UkfTurnRate, Self::EkfTurnRate, Self::Imm];

    /// A label for reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Ukf => "UKF (CV)",
            Self::Ekf => "EKF (CV)",
            Self::UkfTurnRate => "UKF (CT, ω estimated)",
            Self::EkfTurnRate => "EKF (CT, ω estimated)",
            Self::Imm => "IMM (CV + CT UKFs)",
        }
    }

    /// Position in [`Seed001Run::tracks`] and [`Seed001Filter::ALL`] (below [`Seed001Filter::COUNT`]).
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            Self::Ukf => 0,
            Self::Ekf => 1,
            Self::UkfTurnRate => 2,
            Self::EkfTurnRate => 3,
            Self::Imm => 4,
        }
    }
}

/// One tracker's output over a run, one entry per epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterTrack {
    /// Posterior mean `[x, vx, y, vy]` (m, m/s).
    pub estimates: Vec<[f64; 4]>,
    /// NEES of `[x, vx, y, vy]` (the marginal for the 5-state CT filters), `χ²(4)` if consistent.
    pub nees: Vec<f64>,
    /// NIS of the joint measurement, `χ²(m)` if consistent (`m` = 2 × stations); for the IMM,
    /// the NIS of the mode most probable after the update.
    pub nis: Vec<f64>,
    /// Ranges the robust UKF down-weighted (0 for the other trackers).
    pub downweighted_ranges: usize,
}

/// The NLOS part of a run: the same truth and Gaussian noise, ranges biased.
#[derive(Debug, Clone, PartialEq)]
pub struct NlosRun {
    /// Fraction of ranges that were NLOS.
    pub nlos_fraction: f64,
    /// Mean bias over all ranges, m.
    pub mean_bias_m: f64,
    /// The paper's UKF on the biased ranges.
    pub ukf: FilterTrack,
    /// The robust UKF on the biased ranges.
    pub robust: FilterTrack,
    /// The robust UKF on the line-of-sight ranges (the price of robustness).
    pub robust_los: FilterTrack,
}

/// One seeded run of seed 001.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed001Run {
    /// The run's seed.
    pub seed: u64,
    /// Epoch times, s.
    pub times_s: Vec<f64>,
    /// True `[x, vx, y, vy]` at each epoch.
    pub truth: Vec<[f64; 4]>,
    /// Single-epoch joint TOA-RSS fix (Gauss–Newton from the previous fix), `None` if it failed.
    pub fixes: Vec<Option<[f64; 2]>>,
    /// One track per [`Seed001Filter::ALL`] entry, in that order.
    pub tracks: [FilterTrack; Seed001Filter::COUNT],
    /// `Hᵀ R⁻¹ H` of the joint measurement at the true state, per epoch (4 × 4).
    pub information: Vec<DMatrix<f64>>,
    /// The same for the TOA ranges alone.
    pub toa_information: Vec<DMatrix<f64>>,
    /// The NLOS extension, if configured.
    pub nlos: Option<NlosRun>,
}

impl Seed001Run {
    /// The track of `filter`.
    #[must_use]
    pub fn track(&self, filter: Seed001Filter) -> &FilterTrack {
        &self.tracks[filter.index()]
    }
}

/// Runs seed 001 once with `seed`.
///
/// Random streams: stream 0 of `ChaCha8Rng::seed_from_u64(seed)` draws the truth (two normals
/// per epoch), then the initial estimate error (four normals), then per epoch the ranges (one
/// normal per station) and the path losses (one normal per station); stream 1 draws the NLOS
/// biases, so the line-of-sight results do not depend on whether NLOS is configured, and
/// every tracker sees the same data (common random numbers).
///
/// # Errors
/// As [`Seed001Config::validate`]; [`SimError::Estimation`] if a filter step fails (e.g. the
/// estimate lands on a station).
///
/// # References
/// Seed 001 §2–§3.
pub fn run_seed_001(config: &Seed001Config, seed: u64) -> Result<Seed001Run> {
    config.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = config.truth.simulate(&mut rng)?;
    let times_s = config.truth.times_s();
    // x̂₀ = x₀ + √P₀ n
    let x0 = config.truth.initial_state;
    let stds = [
        config.initial_position_std_m,
        config.initial_velocity_std_mps,
        config.initial_position_std_m,
        config.initial_velocity_std_mps,
    ];
    let mut initial_mean = Vector::<4>::from(x0);
    for (m, s) in initial_mean.iter_mut().zip(stds) {
        *m += s * rand::Rng::sample::<f64, _>(&mut rng, StandardNormal);
    }
    let initial = Gaussian::new(initial_mean, config.initial_covariance(), 0.0).map_err(SimError::estimation(0.0))?;

    // Measurements: the same data for every tracker.
    let toa = UwbToaSimulator::new(&config.stations_m, config.range_std_m)?;
    let rss = UwbRssSimulator::new(&config.stations_m, config.rss_law, config.shadowing_std_db)?;
    let stations = config.stations_m.len();
    let mut measurements = Vec::with_capacity(truth.len());
    for state in &truth {
        let position = [state[0], state[2]];
        let ranges = toa.measure(position, &mut rng)?.ranges_m;
        let losses = rss.measure(position, &mut rng)?;
        measurements.push(DVector::from_iterator(2 * stations, ranges.into_iter().chain(losses)));
    }

    let joint = config.joint_measurement()?;
    let data = RunData {
        times_s: &times_s,
        truth: &truth,
        measurements: &measurements,
    };
    let tracks = run_trackers(config, &joint, &initial, &data)?;
    let fixes = joint_fixes(config, &measurements)?;
    let (information, toa_information) = information_at_truth(config, &joint, &truth)?;
    let nlos = match &config.nlos {
        Some(nlos) => Some(run_nlos(config, nlos, &joint, &initial, &data, seed)?),
        None => None,
    };
    Ok(Seed001Run {
        seed,
        times_s,
        truth,
        fixes,
        tracks,
        information,
        toa_information,
        nlos,
    })
}

/// The per-run data every tracker reads.
struct RunData<'a> {
    times_s: &'a [f64],
    truth: &'a [[f64; 4]],
    measurements: &'a [DVector<f64>],
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_sim::scenarios::seed_001::{Seed001Motion, Seed001Truth};

    fn config(nlos: bool) -> Seed001Config {
        let mut config =
            Seed001Config::new(Seed001Truth::paper(Seed001Motion::ConstantVelocity, 0.02).unwrap()).unwrap();
        if nlos {
            config.nlos = Some(Seed001Nlos {
                bias: NlosBias::new(0.2, 1.0).unwrap(),
                gate_probability: 0.99,
            });
        }
        config
    }

    #[test]
    fn a_run_is_deterministic_and_nlos_does_not_change_the_los_part() {
        let plain = run_seed_001(&config(false), 11).unwrap();
        assert_eq!(plain, run_seed_001(&config(false), 11).unwrap());
        let with_nlos = run_seed_001(&config(true), 11).unwrap();
        assert_eq!(plain.tracks, with_nlos.tracks);
        assert_eq!(plain.truth, with_nlos.truth);
        let nlos = with_nlos.nlos.unwrap();
        assert!(
            nlos.nlos_fraction > 0.05 && nlos.nlos_fraction < 0.4,
            "{}",
            nlos.nlos_fraction
        );
        assert_ne!(nlos.ukf.estimates, plain.track(Seed001Filter::Ukf).estimates);
    }

    #[test]
    fn trackers_follow_the_truth_and_fixes_exist() {
        let run = run_seed_001(&config(false), 3).unwrap();
        for filter in Seed001Filter::ALL {
            let track = run.track(filter);
            let last = track.estimates[49];
            let truth = run.truth[49];
            let error = (last[0] - truth[0]).hypot(last[2] - truth[2]);
            assert!(error < 2.0, "{}: {error}", filter.name());
            assert!(track.nees.iter().all(|v| v.is_finite() && *v >= 0.0));
        }
        assert!(run.fixes.iter().filter(|f| f.is_some()).count() >= 45);
        // the joint information exceeds the TOA information (RSS adds a little)
        for (j, jt) in run.information.iter().zip(&run.toa_information) {
            assert!(j.trace() > jt.trace());
        }
    }

    #[test]
    fn robust_ukf_downweights_only_with_nlos() {
        let run = run_seed_001(&config(true), 5).unwrap();
        let nlos = run.nlos.unwrap();
        assert!(nlos.robust.downweighted_ranges > 0);
        assert!(nlos.robust.downweighted_ranges >= nlos.robust_los.downweighted_ranges);
        assert_eq!(nlos.ukf.downweighted_ranges, 0);
    }

    #[test]
    fn invalid_configs_are_rejected() {
        let mut bad = config(false);
        bad.range_std_m = 0.0;
        assert!(run_seed_001(&bad, 1).is_err());
        let mut bad = config(false);
        bad.stations_m.pop();
        assert!(bad.validate().is_err());
        let mut bad = config(true);
        if let Some(n) = bad.nlos.as_mut() {
            n.gate_probability = 1.0;
        }
        assert!(bad.validate().is_err());
        let mut bad = config(false);
        bad.sigma_points.kappa = -10.0;
        assert!(bad.validate().is_err());
    }
}
