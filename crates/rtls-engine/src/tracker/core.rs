//! The per-tag tracks of one state size (`N = 4`: 2-D CV, `N = 6`: 3-D CV) and what happens to
//! them on a record and on a clock tick.

use std::collections::HashMap;
use std::sync::Arc;

use super::alarms::position_of;
use super::anchors::{AnchorReading, Anchors};
use super::epoch::{anchor_reading, close_due_epoch, raw_fix};
use super::output::{Event, Output, UpdateSource};
use super::report::{clear_alarms, coast, report, track_update};
use super::update::{fix_update, velocity_update};
use crate::error::Result;
use crate::lifecycle::{Lifecycle, LifecycleEvent, LifecycleSettings, TrackStatus};
use crate::radio_map::RadioMap;
use crate::record::Measurement;
use crate::site::{AlarmSettings, Pipeline, TrackerSettings};
use crate::zones::{Zone, ZoneMonitor};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter};
use rtls_estimation::imm::ImmState;
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::Gaussian;

use super::modes::Manoeuvres;
use super::noise::NoiseScales;
use super::schedule::{Scheduling, TrackSchedule};
use rtls_estimation::adaptive::AdaptiveNoise;

/// An accelerometer sample drives the prediction (zero-order hold) for at most this long, s.
pub(super) const ACCELERATION_HOLD_S: f64 = 1.0;

/// Everything the tracks share: settings, anchors, models, filters, alarm zones.
#[derive(Debug, Clone)]
pub(crate) struct Shared {
    pub(crate) settings: TrackerSettings,
    pub(crate) alarms: AlarmSettings,
    pub(crate) lifecycle: LifecycleSettings,
    pub(crate) anchors: Anchors,
    pub(crate) radio_map: Option<RadioMap>,
    /// CV with white-acceleration noise `q = σ_a²`.
    pub(crate) motion: ConstantVelocity,
    /// The same model driven by a measured acceleration `u`.
    pub(crate) aided_motion: ConstantVelocity,
    pub(crate) kf: KalmanFilter,
    pub(crate) ekf: ExtendedKalmanFilter,
    pub(crate) ukf: UnscentedKalmanFilter,
    /// `χ²` gate thresholds for 1, 2 and 3 degrees of freedom (index = dof − 1).
    pub(crate) gates: [f64; 3],
    pub(crate) tag_height_m: f64,
    /// Hazard zones and zones without a working reader, checked by the predictive alarm.
    pub(crate) alarm_zones: Vec<Zone>,
    /// Ids of the zones whose listed readers are all broken.
    pub(crate) no_coverage_zones: Vec<String>,
    /// The interacting multiple models of `motion_model = "imm"`.
    pub(crate) manoeuvres: Option<Arc<Manoeuvres>>,
    /// Seed 003's adaptive node scheduling (`[scheduling]`).
    pub(crate) scheduling: Option<Arc<Scheduling>>,
    /// Adaptive measurement noise (`[tracker.adaptive_noise]`); `None` when disabled.
    pub(crate) adaptive: Option<AdaptiveNoise>,
}

/// One tag's track: its state (a value it owns), lifecycle and pending work.
#[derive(Debug, Clone)]
pub(crate) struct Track<const N: usize> {
    pub(super) tag: Arc<str>,
    /// The filtered state; `None` until the first fix.
    pub(super) state: Option<Gaussian<N>>,
    pub(super) lifecycle: Option<Lifecycle>,
    /// Fix-then-filter: the open epoch's readings; tightly coupled: readings waiting to
    /// initialise the track.
    pub(super) epoch: Vec<(f64, AnchorReading)>,
    pub(super) epoch_start_s: f64,
    /// Last accelerometer sample `(t, a)`.
    pub(super) acceleration: Option<(f64, [f64; 3])>,
    /// An update not yet reported, and what produced it.
    pub(super) unreported: Option<UpdateSource>,
    pub(super) last_output_s: f64,
    /// Alarm zones with a raised predictive alarm.
    pub(super) alarmed: Vec<bool>,
    /// The state frozen when the track was lost (its last position is kept and reported).
    pub(super) lost_state: Option<Gaussian<N>>,
    /// Under the IMM: the modes the state combines.
    pub(super) modes: Option<ImmState>,
    /// Under the IMM: the reported (most probable) mode's index.
    pub(super) mode: usize,
    /// Under `[scheduling]`: the track's task nodes and last reported firing set.
    pub(super) schedule: TrackSchedule,
    /// Adaptive measurement-noise scales, per measurement class.
    pub(super) noise: NoiseScales,
    /// Running share of gated updates that fell outside the gate (exponential, ~20 updates).
    pub(super) rejection_rate: f64,
    /// Gated updates since the track (re)started.
    pub(super) gated_updates: u32,
}

impl<const N: usize> Track<N> {
    pub(super) fn new(tag: Arc<str>, alarm_zones: usize) -> Self {
        Self {
            tag,
            state: None,
            lifecycle: None,
            epoch: Vec::new(),
            epoch_start_s: f64::NEG_INFINITY,
            acceleration: None,
            unreported: None,
            last_output_s: f64::NEG_INFINITY,
            alarmed: vec![false; alarm_zones],
            lost_state: None,
            modes: None,
            mode: 0,
            schedule: TrackSchedule::default(),
            noise: NoiseScales::default(),
            rejection_rate: 0.0,
            gated_updates: 0,
        }
    }

    pub(super) fn status(&self) -> Option<TrackStatus> {
        self.lifecycle.as_ref().map(Lifecycle::status)
    }

    pub(super) fn is_lost(&self) -> bool {
        self.status() == Some(TrackStatus::Lost)
    }
}

/// All tracks of one state size.
#[derive(Debug, Clone)]
pub(crate) struct Core<const N: usize> {
    pub(crate) shared: Shared,
    index: HashMap<Arc<str>, usize>,
    tracks: Vec<Track<N>>,
    pub(crate) monitor: ZoneMonitor,
}

/// Fix-then-filter: whether the track's open epoch holds readings from before `now_s`. Its fix
/// will carry the epoch's last reading time, so ticking the track at `now_s` first would put
/// the fix's update behind the tick (time going backwards for the lifecycle).
fn holds_earlier_readings<const N: usize>(shared: &Shared, track: &Track<N>, now_s: f64) -> bool {
    shared.settings.pipeline == Pipeline::FixThenFilter && track.epoch.last().is_some_and(|&(t, _)| t < now_s)
}

/// Tracked dimensions of a CV state of size `N`.
pub(super) const fn dimensions<const N: usize>() -> usize {
    N / 2
}

pub(super) fn rejected(tag: &Arc<str>, time_s: f64, kind: &'static str, reason: String) -> Event {
    Event::Rejected {
        tag: Arc::clone(tag),
        time_s,
        kind,
        reason,
    }
}

impl<const N: usize> Core<N> {
    pub(crate) fn new(shared: Shared, monitor: ZoneMonitor) -> Self {
        Self {
            shared,
            index: HashMap::new(),
            tracks: Vec::new(),
            monitor,
        }
    }

    pub(crate) fn track_count(&self) -> usize {
        self.tracks.len()
    }

    pub(crate) fn status(&self, tag: &str) -> Option<TrackStatus> {
        self.index.get(tag).and_then(|&i| self.tracks[i].status())
    }

    /// Applies one in-order record.
    pub(crate) fn apply(&mut self, time_s: f64, tag: &str, measurement: &Measurement, out: &mut Output) -> Result<()> {
        let index = match self.index.get(tag) {
            Some(&i) => i,
            None => {
                let tag: Arc<str> = Arc::from(tag);
                self.tracks
                    .push(Track::new(Arc::clone(&tag), self.shared.alarm_zones.len()));
                self.index.insert(tag, self.tracks.len() - 1);
                self.tracks.len() - 1
            }
        };
        let track = &mut self.tracks[index];
        let shared = &self.shared;
        // a later time closes the previous time's work: report it first
        if track.state.as_ref().is_some_and(|s| time_s > s.time_s()) && track.unreported.is_some() {
            report(shared, track, &mut self.monitor, out)?;
        }
        match measurement {
            Measurement::Range { .. } | Measurement::Rssi { .. } | Measurement::Tdoa { .. } => {
                let reading = match shared.anchors.resolve(measurement) {
                    Ok(Some(reading)) => reading,
                    Ok(None) => return Ok(()),
                    Err(reason) => {
                        out.events
                            .push(rejected(&track.tag, time_s, measurement.kind(), reason));
                        return Ok(());
                    }
                };
                anchor_reading(shared, track, time_s, reading, measurement.kind(), out)?;
            }
            Measurement::Fix {
                position_m,
                covariance_m2,
            } => {
                let k = position_m.len();
                if k < dimensions::<N>() {
                    let reason = format!("a {k}-D fix cannot update a {}-D track", dimensions::<N>());
                    out.events.push(rejected(&track.tag, time_s, "fix", reason));
                } else {
                    // the tracked axes: the leading D × D block
                    let d = dimensions::<N>();
                    let covariance: Vec<f64> = (0..d * d).map(|i| covariance_m2[(i / d) * k + i % d]).collect();
                    fix_update(shared, track, time_s, &position_m[..d], &covariance, "fix", out)?;
                }
            }
            Measurement::RssiVector { readings } => match &shared.radio_map {
                None => {
                    let reason = "no fingerprint radio map is loaded (site [fingerprints])".to_string();
                    out.events.push(rejected(&track.tag, time_s, "rssi_vector", reason));
                }
                Some(map) => match map.locate(readings) {
                    Ok(fix) => {
                        let c = fix.covariance_m2;
                        let covariance = [c[0][0], c[0][1], c[1][0], c[1][1]];
                        out.fixes
                            .push(raw_fix(&track.tag, time_s, &fix.position_m, &covariance));
                        fix_update(shared, track, time_s, &fix.position_m, &covariance, "rssi_vector", out)?;
                    }
                    Err(error) => {
                        let reason = format!("fingerprint fix failed: {error}");
                        out.events.push(rejected(&track.tag, time_s, "rssi_vector", reason));
                    }
                },
            },
            Measurement::Velocity {
                velocity_mps,
                covariance_m2ps2,
            } => {
                let k = velocity_mps.len().min(dimensions::<N>());
                let covariance: Vec<f64> = match covariance_m2ps2 {
                    Some(c) => (0..k * k).map(|i| c[(i / k) * velocity_mps.len() + i % k]).collect(),
                    None => {
                        let reason = "a velocity needs `covariance_m2ps2`".to_string();
                        out.events.push(rejected(&track.tag, time_s, "velocity", reason));
                        return Ok(());
                    }
                };
                velocity_update(shared, track, time_s, &velocity_mps[..k], &covariance, "velocity", out)?;
            }
            Measurement::Odometry {
                speed_mps,
                heading_rad,
                speed_std_mps,
                heading_std_rad,
            } => {
                let (Some(speed_std), Some(heading_std)) = (speed_std_mps, heading_std_rad) else {
                    let reason = "odometry needs `speed_std_mps` and `heading_std_rad`".to_string();
                    out.events.push(rejected(&track.tag, time_s, "odometry", reason));
                    return Ok(());
                };
                // v = s [cos θ, sin θ]ᵀ, Σ_v = J diag(σ_s², σ_θ²) Jᵀ, J = [[cos θ, −s sin θ], [sin θ, s cos θ]]
                let (sin, cos) = heading_rad.sin_cos();
                let (vs, vh) = (speed_std * speed_std, heading_std * heading_std);
                let s = *speed_mps;
                let cxx = cos * cos * vs + s * s * sin * sin * vh;
                let cyy = sin * sin * vs + s * s * cos * cos * vh;
                let cxy = sin * cos * vs - s * s * sin * cos * vh;
                let covariance = [cxx.max(1e-9), cxy, cxy, cyy.max(1e-9)];
                velocity_update(shared, track, time_s, &[s * cos, s * sin], &covariance, "odometry", out)?;
            }
            Measurement::Accelerometer { .. } if shared.manoeuvres.is_some() => {
                let reason = "accelerometer control input is not used with motion_model = \"imm\" (the CA and CT \
                              modes estimate the acceleration)"
                    .to_string();
                out.events.push(rejected(&track.tag, time_s, "accelerometer", reason));
            }
            Measurement::Accelerometer { acceleration_mps2, .. } => {
                let mut a = [0.0; 3];
                for (axis, value) in acceleration_mps2.iter().enumerate().take(3) {
                    a[axis] = *value;
                }
                track.acceleration = Some((time_s, a));
            }
        }
        Ok(())
    }

    /// The periodic clock tick at `now_s`: closes due epochs, reports pending updates, advances
    /// lifecycles, outputs coasting predictions, deletes dead tracks.
    pub(crate) fn tick(&mut self, now_s: f64, out: &mut Output) -> Result<()> {
        let shared = &self.shared;
        let interval_s = shared.settings.output_interval_s;
        let mut deleted = false;
        for track in &mut self.tracks {
            close_due_epoch(shared, track, now_s, out)?;
            if track.unreported.is_some() && track.state.as_ref().is_some_and(|s| s.time_s() < now_s) {
                report(shared, track, &mut self.monitor, out)?;
            }
            if holds_earlier_readings(shared, track, now_s) {
                // its fix will be dated before this tick: the lifecycle and the coasting output
                // wait for it (the epoch closes by the first tick after its window)
                continue;
            }
            let Some(lifecycle) = track.lifecycle.as_mut() else {
                continue;
            };
            let silence_s = now_s - lifecycle.last_update_s();
            // a track coasts once an update is overdue by more than the output interval
            if silence_s > interval_s || lifecycle.status() == TrackStatus::Tentative {
                if let Some(event) = lifecycle.tick(now_s)? {
                    let position_m = match (event, track.state.as_ref()) {
                        (LifecycleEvent::Lost, Some(state)) => {
                            // keep the last estimated position (where the tag was last seen)
                            let frozen = *state;
                            let position_m = position_of(&frozen, shared.tag_height_m).0;
                            track.lost_state = Some(frozen);
                            position_m
                        }
                        (_, Some(state)) => position_of(state, shared.tag_height_m).0,
                        (_, None) => [0.0; 3],
                    };
                    out.events.push(Event::Lifecycle {
                        tag: Arc::clone(&track.tag),
                        time_s: now_s,
                        event,
                        position_m,
                    });
                    if event == LifecycleEvent::Deleted {
                        for zone_event in self.monitor.remove_tag(&track.tag, now_s)? {
                            out.events.push(Event::Zone(zone_event));
                        }
                        clear_alarms(shared, track, now_s, out);
                        deleted = true;
                        continue;
                    }
                }
            }
            if now_s - track.last_output_s >= interval_s {
                match track.status() {
                    Some(TrackStatus::Coasting) => coast(shared, track, now_s, &mut self.monitor, out)?,
                    Some(TrackStatus::Lost) => {
                        // the last position, frozen, reported as lost
                        if let Some(frozen) = &track.lost_state {
                            let mut update =
                                track_update(shared, track, frozen, true, TrackStatus::Lost, UpdateSource::Prediction);
                            update.time_s = now_s;
                            out.updates.push(update);
                            track.last_output_s = now_s;
                        }
                    }
                    _ => {}
                }
            }
        }
        if deleted {
            self.tracks.retain(|t| t.status() != Some(TrackStatus::Deleted));
            self.index = self
                .tracks
                .iter()
                .enumerate()
                .map(|(i, t)| (Arc::clone(&t.tag), i))
                .collect();
        }
        Ok(())
    }

    /// End of input: closes every epoch and reports every pending update.
    pub(crate) fn flush(&mut self, out: &mut Output) -> Result<()> {
        for track in &mut self.tracks {
            close_due_epoch(&self.shared, track, f64::INFINITY, out)?;
            if track.unreported.is_some() {
                report(&self.shared, track, &mut self.monitor, out)?;
            }
        }
        Ok(())
    }
}
