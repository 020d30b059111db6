//! "Ours" in seed 001: the run as a [`Recording`] — the site file a user would write from the
//! sensor specifications, the range and RSSI records the two base stations would send, the
//! truth — tracked by the engine's [`Tracker`](rtls_engine::tracker::Tracker) (the code path of
//! `rtls track` and `rtls serve`), and its updates scored at the run's epochs.

use std::fmt::Write as _;

use nalgebra::DVector;
use rtls_engine::record::{Measurement, Record};
use rtls_engine::tracker::Event;
use rtls_estimation::measurement::BreakpointForm;

use super::{FilterTrack, Seed001Config};
use crate::error::{finite, Result, SimError};
use crate::recording::{Recording, Tracked};
use rtls_engine::evaluation::TruthSample;

/// The tag id of the recordings.
pub const SEED_001_TAG: &str = "tag-1";

/// The engine's `[tracker]` for a seed 001 recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Seed001Engine {
    /// `motion_model = "ct"`, `filter = "ukf"`: the coordinated turn with the rate as a state.
    TurnUkf,
    /// `motion_model = "ct"`, `filter = "ekf"`.
    TurnEkf,
    /// `motion_model = "imm"`, `modes = ["cv", "ct"]`, `filter = "ukf"`.
    Imm,
    /// `motion_model = "cv"`, `filter = "ukf"`: the paper's model in the engine, whose
    /// validation gate and adaptive noise are its defence against NLOS ranges.
    CvUkf,
}

/// Which ranges the records carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seed001Ranges {
    /// The line-of-sight ranges every tracker sees.
    LineOfSight,
    /// The same ranges with the NLOS biases of [`super::Seed001Nlos`] added.
    Nlos,
}

/// Seed 001's run `seed` as a recording for the engine's UKF on the coordinated turn
/// ([`Seed001Engine::TurnUkf`]) on line-of-sight ranges: see [`seed_001_recording_with`].
///
/// # Errors
/// As [`seed_001_recording_with`].
///
/// # Example
/// ```
/// use rtls_papers::reproduction::seed_001::{seed_001_recording, Seed001Config};
/// use rtls_sim::scenarios::seed_001::{Seed001Motion, Seed001Truth};
/// let config = Seed001Config::new(Seed001Truth::paper(Seed001Motion::ConstantVelocity, 0.02)?)?;
/// let recording = seed_001_recording(&config, 1)?;
/// assert_eq!(recording.truth.len(), 50);
/// // an enrolment fix and velocity, then two ranges and two RSSI per epoch
/// assert_eq!(recording.records.len(), 2 + 4 * 50);
/// let tracked = recording.track()?;
/// assert!(tracked.refused.is_empty());
/// # Ok::<(), rtls_papers::SimError>(())
/// ```
pub fn seed_001_recording(config: &Seed001Config, seed: u64) -> Result<Recording> {
    seed_001_recording_with(config, seed, Seed001Engine::TurnUkf, Seed001Ranges::LineOfSight)
}

/// Seed 001's run `seed` as files, with the same truth, initial estimate and measurement noise
/// as the baselines of [`super::run_seed_001`] (common random numbers):
///
/// - the site: each base station a UWB reader with `radio.range` (`range_std_m` = σ, no bias)
///   and `radio.path_loss` (the RSS law as a received power for a 0 dBm transmitter,
///   `reference_power_dbm = −P0` at `d0`, `exponent = n`, `shadowing_std_db = σ_s`);
///   `[tracker]` tightly coupled with `engine`'s motion model and filter, the white
///   acceleration σ_ω of the scenario, and for the turn the scenario's turn-rate prior and
///   noise and IMM sojourn times; everything else at the engine's defaults;
/// - the records: at `t = 0` an enrolment `fix` and `velocity` (the initial estimate
///   `x̂₀ ~ N(x₀, P₀)` every baseline starts from, with `P₀`), then per epoch a `range` and an
///   `rssi` record per station (RSSI = −path loss);
/// - the truth at every epoch.
///
/// # Errors
/// [`SimError::InvalidParameter`] for an RSS law the site format cannot express (the engine's
/// readers have one-slope log-distance laws: the continuous breakpoint law with one exponent
/// is one, the printed form is not); [`SimError::InvalidParameter`] for NLOS ranges without an
/// NLOS configuration; the simulation's errors.
pub fn seed_001_recording_with(
    config: &Seed001Config,
    seed: u64,
    engine: Seed001Engine,
    ranges: Seed001Ranges,
) -> Result<Recording> {
    let data = super::simulate(config, seed)?;
    let measurements = match ranges {
        Seed001Ranges::LineOfSight => &data.measurements,
        Seed001Ranges::Nlos => {
            &data
                .nlos
                .as_ref()
                .ok_or(SimError::InvalidParameter {
                    name: "ranges",
                    reason: "NLOS ranges need an NLOS configuration (`nlos`)",
                })?
                .measurements
        }
    };
    Ok(Recording {
        site_toml: site_toml(config, engine)?,
        records: records(config, &data.initial, &data.times_s, measurements)?,
        truth: data
            .times_s
            .iter()
            .zip(&data.truth)
            .map(|(&t, s)| TruthSample {
                has_z: false,
                line: 0,
                time_s: t,
                tag: SEED_001_TAG.to_string(),
                position_m: [s[0], s[2], 0.0],
            })
            .collect(),
    })
}

/// The reader id of station `i`.
fn station_id(i: usize) -> String {
    format!("BS{}", i + 1)
}

/// The site file of a seed 001 recording.
fn site_toml(config: &Seed001Config, engine: Seed001Engine) -> Result<String> {
    let law = &config.rss_law;
    if law.form() != BreakpointForm::Continuous || law.far_exponent() != law.exponent() {
        return Err(SimError::InvalidParameter {
            name: "rss_law",
            reason: "the engine's readers have one-slope log-distance laws: only the continuous breakpoint law \
                     with one exponent on both sides can be written in a site file",
        });
    }
    let mut text = String::from("# Seed 001: two UWB base stations measuring TOA ranges and RSS of one tag.\n");
    for (i, s) in config.stations_m.iter().enumerate() {
        // writing into a String cannot fail
        let _ = write!(
            text,
            "\n[[readers]]\nid = \"{}\"\nposition_m = [{:?}, {:?}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = {:?}, bias_m = 0.0 }}, path_loss = {{ reference_power_dbm = {:?}, \
             exponent = {:?}, shadowing_std_db = {:?}, reference_distance_m = {:?} }} }}\n",
            station_id(i),
            s[0],
            s[1],
            config.range_std_m,
            -law.p0_db(),
            law.exponent(),
            config.shadowing_std_db,
            law.reference_distance_m(),
        );
    }
    let (motion_model, filter) = match engine {
        Seed001Engine::TurnUkf => ("ct", "ukf"),
        Seed001Engine::TurnEkf => ("ct", "ekf"),
        Seed001Engine::Imm => ("imm", "ukf"),
        Seed001Engine::CvUkf => ("cv", "ukf"),
    };
    let _ = write!(
        text,
        "\n[tracker]\npipeline = \"tightly-coupled\"\nmotion_model = \"{motion_model}\"\nfilter = \"{filter}\"\n\
         acceleration_noise_std_mps2 = {:?}\nturn_rate_noise_std_radps2 = {:?}\ninitial_turn_rate_std_radps = {:?}\n",
        config.truth.process_noise_std_mps2.max(1e-6),
        config.turn_rate_noise_std_rad_s2.max(1e-6),
        config.turn_rate_prior_std_rad_s,
    );
    if let (Seed001Engine::CvUkf, Some(nlos)) = (engine, &config.nlos) {
        let _ = writeln!(text, "gate_probability = {:?}", nlos.gate_probability);
    }
    if engine == Seed001Engine::Imm {
        let [cv, ct] = config.imm_sojourn_s;
        let _ = write!(
            text,
            "\n[tracker.imm]\nmodes = [\"cv\", \"ct\"]\ncv_sojourn_s = {cv:?}\nct_sojourn_s = {ct:?}\n\
             ct_turn_rate_noise_std_radps2 = {:?}\n",
            config.turn_rate_noise_std_rad_s2.max(1e-6),
        );
    }
    Ok(text)
}

/// The enrolment records at `t = 0` and the range and RSSI records of every epoch.
fn records(
    config: &Seed001Config,
    initial: &[f64; 4],
    times_s: &[f64],
    measurements: &[DVector<f64>],
) -> Result<Vec<Record>> {
    let stations = config.stations_m.len();
    let record = |time_s: f64, measurement: Measurement| Record {
        time_s,
        tag: SEED_001_TAG.to_string(),
        measurement,
    };
    let (p, v) = (
        config.initial_position_std_m.powi(2),
        config.initial_velocity_std_mps.powi(2),
    );
    let mut out = vec![
        record(
            0.0,
            Measurement::Fix {
                position_m: vec![initial[0], initial[2]],
                covariance_m2: vec![p, 0.0, 0.0, p],
            },
        ),
        record(
            0.0,
            Measurement::Velocity {
                velocity_mps: vec![initial[1], initial[3]],
                covariance_m2ps2: Some(vec![v, 0.0, 0.0, v]),
            },
        ),
    ];
    for (&t, z) in times_s.iter().zip(measurements) {
        for i in 0..stations {
            out.push(record(
                t,
                Measurement::Range {
                    anchor: station_id(i),
                    range_m: z[i],
                    std_m: None,
                    anchor_position_m: None,
                },
            ));
        }
        for i in 0..stations {
            // received power of a 0 dBm transmitter: ρ = −P
            out.push(record(
                t,
                Measurement::Rssi {
                    anchor: station_id(i),
                    rssi_dbm: -z[stations + i],
                },
            ));
        }
    }
    Ok(out)
}

/// The engine's track at each epoch (its latest update at or before it): `[x, vx, y, vy]`, the
/// NEES of the position (`χ²(2)` if consistent: a track update carries the position
/// covariance), no NIS (the engine updates one reading at a time), and the ranges its
/// validation gate refused.
///
/// # Errors
/// [`SimError::EmptyInput`] for an epoch before the track's first update; a non-finite NEES.
pub(super) fn engine_track(tracked: &Tracked, times_s: &[f64], truth: &[[f64; 4]]) -> Result<FilterTrack> {
    let mut track = FilterTrack::with_capacity(times_s.len(), 2);
    for (update, state) in tracked.latest_at(SEED_001_TAG, times_s).into_iter().zip(truth) {
        let update = update.ok_or(SimError::EmptyInput {
            what: "engine track update at a seed 001 epoch",
        })?;
        let [x, y, _] = update.position_m;
        let [vx, vy, _] = update.velocity_mps;
        // NEES = eᵀ P⁻¹ e over the position, P = [[a, b], [b, c]]
        let (ex, ey) = (x - state[0], y - state[2]);
        let c = &update.position_covariance_m2;
        let (a, b, d) = (c[0], c[1], c[3]);
        let det = a * d - b * b;
        if det.is_nan() || det <= 0.0 {
            return Err(SimError::NonFinite {
                what: "engine position covariance (not positive definite)",
            });
        }
        let nees = (d * ex * ex - 2.0 * b * ex * ey + a * ey * ey) / det;
        track.estimates.push([x, vx, y, vy]);
        track.nees.push(finite(nees, "NEES")?);
    }
    track.downweighted_ranges = tracked
        .events
        .iter()
        .filter(|e| matches!(e, Event::Rejected { kind: "range", .. }))
        .count();
    Ok(track)
}
