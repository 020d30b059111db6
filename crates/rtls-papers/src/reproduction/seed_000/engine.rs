//! Our tracker for seed 000 is the engine's: [`seed_000_recording`] writes the mine walk as a
//! site file (the readers with their path-loss law and sensitivity, the tunnels as
//! `[[corridors]]` with their walking lines' heights, the `[tracker]` settings of
//! [`OursConfig`]) and the RSSI records the readers send, and
//! [`rtls_engine::tracker::Tracker`] tracks the walker on them — the same code as `rtls track`
//! and `rtls serve`. Per epoch the engine runs
//!
//! ```text
//! predict                 x⁻ = F x̂,  P⁻ = F P Fᵀ + Q                      (3-D CV, σ_a)
//! for each reader heard   ν = ρᵢ − μ(‖p⁻ − rᵢ‖),  applied if ν²/S ≤ χ²₁(P_G)   (tightly coupled)
//! at the epoch's close    the surest silent reader as z = S (negative information), the
//!                         tunnel map (lateral 0 ± σ_lat away from junctions, height on the
//!                         walking line ± σ_vert, back at a dead end), |v_xy| ≤ v_max, and a
//!                         restart at the epoch's fix when most readers heard cannot see the
//!                         estimate through the tunnels (the wrong branch)
//! ```
//!
//! The walker enters past the entrance reader: the recording starts with a position fix at the
//! entrance at `t = 0` with the prior's σ (what a check-in gate reports), which starts the track.
//!
//! # References
//! W. Koch, "On exploiting 'negative' sensor evidence for target tracking and sensor data
//! fusion", *Information Fusion* 8(1), 2007; D. Simon, "Kalman filtering with state
//! constraints", *IET Control Theory & Applications* 4(8), 2010; Y. Bar-Shalom, X. R. Li,
//! T. Kirubarajan, *Estimation with Applications to Tracking and Navigation*, Wiley 2001, §5.4.

use std::fmt::Write as _;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtls_engine::record::{Measurement, Record};
use rtls_engine::tracker::{Event, TrackUpdate};
use rtls_positioning::pathloss::PathLossModel;

use super::models::{MapSpread, PedestrianCv};
use super::{Seed000Setup, TrackState};
use crate::error::Result;
use crate::recording::{Recording, Tracked};
use rtls_engine::evaluation::TruthSample;
use rtls_sim::sensors::readers::{distance_m, Detection, ReaderStatus};

/// The walker's tag id in the recording.
pub const TAG: &str = "miner";

/// Our tracker's settings, written into the recording's `[tracker]` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OursConfig {
    /// The pedestrian CV model: its horizontal σ is the engine's white acceleration (the
    /// engine's CV is isotropic; the height is held by the map's vertical part), and the
    /// PCRB's motion model.
    pub motion: PedestrianCv,
    /// Probability of the engine's χ² validation gate.
    pub gate_probability: f64,
    /// The tunnel map: `σ_lat` and `σ_vert` of `[tracker.map]`.
    pub map: MapSpread,
    /// Largest plan speed of a walker, m/s (`max_speed_mps`).
    pub max_speed_mps: f64,
    /// Within this plan distance of a junction the lateral constraint is not applied, m.
    pub junction_radius_m: f64,
}

/// Counts of the engine's decisions over a run, from its events.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrackerCounts {
    /// RSSI records applied.
    pub accepted: usize,
    /// RSSI records outside the validation gate.
    pub rejected: usize,
    /// Restarts: at the epoch's fix from the wrong tunnel, or after a failed or diverged step.
    pub reinitialised: usize,
}

/// Running sum of one reader's RSSI residuals against our estimate (measured − expected at the
/// estimate of the epoch), dB.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InnovationSum {
    /// `Σ (ρ − μ(‖p̂ − r‖))`, dB.
    pub sum_db: f64,
    /// Number of residuals.
    pub count: usize,
}

/// The mine walk of `setup` as a site file, the readers' records and the truth, with the
/// shadowing of run `seed` (the same draws as [`super::run_seed_000`]): what
/// `rtls sim mekf --out DIR` writes.
///
/// # Errors
/// The reader layer's errors.
pub fn seed_000_recording(setup: &Seed000Setup, seed: u64) -> Result<Recording> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut detections = Vec::with_capacity(setup.epochs.len());
    for (truth, excess_db) in setup.epochs.iter().zip(&setup.excess_loss_db) {
        detections.push(setup.layer.detect(truth.position_m, excess_db, &mut rng)?);
    }
    Ok(recording(setup, &detections))
}

/// The recording of `detections` (one list per epoch of `setup`).
pub(super) fn recording(setup: &Seed000Setup, detections: &[Vec<Detection>]) -> Recording {
    let readers = setup.layer.readers();
    let p0 = setup.prior.position_m;
    let v0 = setup.prior.position_variance_m2;
    let mut records = vec![Record {
        time_s: 0.0,
        tag: TAG.into(),
        measurement: Measurement::Fix {
            position_m: p0.to_vec(),
            covariance_m2: vec![v0, 0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0, v0],
        },
    }];
    for (truth, heard) in setup.epochs.iter().zip(detections) {
        records.extend(heard.iter().map(|d| Record {
            time_s: truth.time_s,
            tag: TAG.into(),
            measurement: Measurement::Rssi {
                anchor: readers[d.reader].name.clone(),
                rssi_dbm: d.rssi_dbm,
            },
        }));
    }
    let truth = std::iter::once(TruthSample {
        has_z: true,
        line: 0,
        time_s: 0.0,
        tag: TAG.into(),
        position_m: p0,
    })
    .chain(setup.epochs.iter().map(|s| TruthSample {
        has_z: true,
        line: 0,
        time_s: s.time_s,
        tag: TAG.into(),
        position_m: s.position_m,
    }))
    .collect();
    Recording {
        site_toml: site_toml(setup),
        records,
        truth,
    }
}

/// The site file: readers, tunnels and our tracker's settings.
#[must_use]
pub fn site_toml(setup: &Seed000Setup) -> String {
    let radio = setup.layer.radio();
    let law = radio.law();
    let o = &setup.ours;
    let mut text = String::from(
        "# Seed 000's mine walk (rtls-papers): readers on the tunnel walls, the tunnels' walking lines,\n\
         # and the tracker of `rtls repro mekf`'s \"ours\" row.\nname = \"Seed 000 mine walk\"\n",
    );
    // writing into a String cannot fail
    for reader in setup.layer.readers() {
        let [x, y, z] = reader.position_m;
        let _ = write!(
            text,
            "\n[[readers]]\nid = {:?}\nposition_m = [{x:?}, {y:?}, {z:?}]\ntechnology = \"rfid\"\nworking = {}\n\
             radio = {{ path_loss = {{ reference_power_dbm = {:?}, exponent = {:?}, shadowing_std_db = {:?}, \
             reference_distance_m = {:?} }}, sensitivity_dbm = {:?} }}\n",
            reader.name,
            reader.status == ReaderStatus::Working,
            law.reference_rssi_dbm(),
            law.exponent(),
            law.shadowing_std_db(),
            law.reference_distance_m(),
            radio.sensitivity_dbm(),
        );
    }
    for tunnel in setup.layout.tunnels() {
        let points: Vec<String> = tunnel
            .centreline_m()
            .iter()
            .map(|p| format!("[{:?}, {:?}]", p[0], p[1]))
            .collect();
        let heights: Vec<String> = tunnel.centreline_m().iter().map(|p| format!("{:?}", p[2])).collect();
        let _ = write!(
            text,
            "\n[[corridors]]\nid = {:?}\npoints_m = [{}]\nheights_m = [{}]\nhalf_width_m = {:?}\n",
            tunnel.name(),
            points.join(", "),
            heights.join(", "),
            tunnel.half_width_m(),
        );
    }
    let prior_speed_std_mps = setup.prior.velocity_variance_m2s2.sqrt();
    let _ = write!(
        text,
        "\n[tracker]\nplatform = \"walker\"\npipeline = \"tightly-coupled\"\nmotion_model = \"cv\"\nfilter = \"ekf\"\n\
         dimensions = 3\nacceleration_noise_std_mps2 = {:?}\ngate_probability = {:?}\n\
         initiation = {{ confirm_updates = 1, within_s = 1.0 }}\ncoast_timeout_s = 60.0\ndelete_timeout_s = 600.0\n\
         reorder_window_s = 0.0\ninitial_speed_std_mps = {prior_speed_std_mps:?}\nmax_speed_mps = {:?}\n\
         [tracker.map]\nlateral_std_m = {:?}\nvertical_std_m = {:?}\njunction_radius_m = {:?}\n",
        o.motion.horizontal_std_mps2(),
        o.gate_probability,
        o.max_speed_mps,
        o.map.lateral_std_m,
        o.map.vertical_std_m,
        o.junction_radius_m,
    );
    text
}

/// Our states at `setup`'s epochs from the engine's updates, the engine's decisions, and each
/// reader's RSSI residuals against them.
///
/// # Errors
/// The recording's ([`Recording::track`]).
pub(super) fn ours(
    setup: &Seed000Setup,
    recording: &Recording,
    detections: &[Vec<Detection>],
) -> Result<(Vec<TrackState>, TrackerCounts, Vec<InnovationSum>)> {
    let tracked = recording.track()?;
    let times: Vec<f64> = setup.epochs.iter().map(|s| s.time_s).collect();
    let prior = [
        setup.prior.position_m[0],
        setup.prior.velocity_mps[0],
        setup.prior.position_m[1],
        setup.prior.velocity_mps[1],
        setup.prior.position_m[2],
        setup.prior.velocity_mps[2],
    ];
    let states: Vec<TrackState> = tracked
        .latest_at(TAG, &times)
        .into_iter()
        .map(|u| u.map_or(prior, state_of))
        .collect();
    let law = setup.layer.radio().law();
    let readers = setup.layer.readers();
    let mut innovations = vec![InnovationSum::default(); readers.len()];
    for (state, heard) in states.iter().zip(detections) {
        let p = [state[0], state[2], state[4]];
        for d in heard {
            // ν = ρ − μ(‖p̂ − r‖)
            let expected_dbm = law.mean_rssi_dbm(distance_m(p, readers[d.reader].position_m));
            innovations[d.reader].sum_db += d.rssi_dbm - expected_dbm;
            innovations[d.reader].count += 1;
        }
    }
    Ok((states, counts(&tracked, recording), innovations))
}

/// `[x, vx, y, vy, z, vz]` of an update.
fn state_of(update: &TrackUpdate) -> TrackState {
    let [x, y, z] = update.position_m;
    let [vx, vy, vz] = update.velocity_mps;
    [x, vx, y, vy, z, vz]
}

/// The engine's decisions on the RSSI records, from its events.
fn counts(tracked: &Tracked, recording: &Recording) -> TrackerCounts {
    let rssi = recording
        .records
        .iter()
        .filter(|r| matches!(r.measurement, Measurement::Rssi { .. }))
        .count();
    let mut counts = TrackerCounts::default();
    for event in &tracked.events {
        match event {
            Event::Rejected { kind, .. } if *kind == "rssi" => counts.rejected += 1,
            Event::Rejected { reason, .. } if reason.contains("restart") => counts.reinitialised += 1,
            _ => {}
        }
    }
    counts.accepted = rssi - counts.rejected;
    counts
}
