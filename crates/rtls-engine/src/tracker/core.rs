//! The per-tag tracks of one state size (`N = 4`: 2-D CV, `N = 6`: 3-D CV) and what happens to
//! them on a record and on a clock tick.

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, SVector};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter, Updated};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::alarms::{position_of, predict_entries};
use super::anchors::{AnchorReading, Anchors};
use super::models::{AnchorLaw, AnchorMeasurement};
use super::output::{Event, Output, RawFix, TrackUpdate, UpdateSource};
use super::solve::solve_epoch;
use crate::error::Result;
use crate::lifecycle::{Lifecycle, LifecycleEvent, LifecycleSettings, TrackStatus};
use crate::radio_map::RadioMap;
use crate::record::Measurement;
use crate::site::{AlarmSettings, FilterKind, Pipeline, TrackerSettings};
use crate::zones::{Zone, ZoneEvent, ZoneMonitor};

/// An accelerometer sample drives the prediction (zero-order hold) for at most this long, s.
const ACCELERATION_HOLD_S: f64 = 1.0;

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
}

/// One tag's track: its state (a value it owns), lifecycle and pending work.
#[derive(Debug, Clone)]
pub(crate) struct Track<const N: usize> {
    tag: Arc<str>,
    /// The filtered state; `None` until the first fix.
    state: Option<Gaussian<N>>,
    lifecycle: Option<Lifecycle>,
    /// Fix-then-filter: the open epoch's readings; tightly coupled: readings waiting to
    /// initialise the track.
    epoch: Vec<(f64, AnchorReading)>,
    epoch_start_s: f64,
    /// Last accelerometer sample `(t, a)`.
    acceleration: Option<(f64, [f64; 3])>,
    /// An update not yet reported, and what produced it.
    unreported: Option<UpdateSource>,
    last_output_s: f64,
    /// Alarm zones with a raised predictive alarm.
    alarmed: Vec<bool>,
    /// The state frozen when the track was lost (its last position is kept and reported).
    lost_state: Option<Gaussian<N>>,
}

impl<const N: usize> Track<N> {
    fn new(tag: Arc<str>, alarm_zones: usize) -> Self {
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
        }
    }

    fn status(&self) -> Option<TrackStatus> {
        self.lifecycle.as_ref().map(Lifecycle::status)
    }

    fn is_lost(&self) -> bool {
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

/// Tracked dimensions of a CV state of size `N`.
const fn dimensions<const N: usize>() -> usize {
    N / 2
}

fn rejected(tag: &Arc<str>, time_s: f64, kind: &'static str, reason: String) -> Event {
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
                            let mut update = track_update(
                                shared,
                                &track.tag,
                                frozen,
                                true,
                                TrackStatus::Lost,
                                UpdateSource::Prediction,
                            );
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

/// A range / RSSI / TDOA reading: into the open epoch (fix-then-filter, or a track still
/// initialising) or straight into the filter (tightly coupled).
fn anchor_reading<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let coupled = shared.settings.pipeline == Pipeline::TightlyCoupled;
    if coupled && track.state.is_some() && !track.is_lost() {
        return coupled_update(shared, track, time_s, reading, kind, out);
    }
    if coupled {
        // (re-)initialising: a lost track's prior is too stale to linearise about, so like a
        // new one it waits for a fix; keep the readings of the confirmation window and try
        expire_initial_readings(shared, track, time_s, kind, out);
        track.epoch.push((time_s, reading));
        let readings: Vec<AnchorReading> = track.epoch.iter().map(|(_, r)| *r).collect();
        if let Ok(fixes) = solve::<N>(shared, &readings, None) {
            track.epoch.clear();
            for (position, covariance) in fixes {
                out.fixes.push(raw_fix(&track.tag, time_s, &position, &covariance));
                fix_update(shared, track, time_s, &position, &covariance, "epoch", out)?;
            }
        }
        return Ok(());
    }
    if !track.epoch.is_empty() && time_s - track.epoch_start_s > shared.settings.epoch_s {
        close_epoch(shared, track, out)?;
    }
    if track.epoch.is_empty() {
        track.epoch_start_s = time_s;
    }
    track.epoch.push((time_s, reading));
    Ok(())
}

/// A fix as `(position, row-major covariance)` on the tracked axes.
type FlatFix = (Vec<f64>, Vec<f64>);

/// Solves readings into fixes `(position, row-major covariance)` on the tracked axes.
fn solve<const N: usize>(
    shared: &Shared,
    readings: &[AnchorReading],
    guess: Option<&Gaussian<N>>,
) -> std::result::Result<Vec<FlatFix>, String> {
    fn flatten<const D: usize>(fix: &rtls_positioning::Fix<D>) -> (Vec<f64>, Vec<f64>) {
        (
            fix.position.iter().copied().collect(),
            fix.covariance.transpose().iter().copied().collect(),
        )
    }
    let tag_height_m = shared.tag_height_m;
    if dimensions::<N>() == 3 {
        let guess = guess.map(|g| SVector::<f64, 3>::new(g.mean()[0], g.mean()[2], g.mean()[4]));
        Ok(solve_epoch::<3>(&shared.anchors, readings, tag_height_m, guess)?
            .iter()
            .map(flatten)
            .collect())
    } else {
        let guess = guess.map(|g| SVector::<f64, 2>::new(g.mean()[0], g.mean()[2]));
        Ok(solve_epoch::<2>(&shared.anchors, readings, tag_height_m, guess)?
            .iter()
            .map(flatten)
            .collect())
    }
}

/// Closes the open epoch if `now_s` is past its window (fix-then-filter only).
fn close_due_epoch<const N: usize>(shared: &Shared, track: &mut Track<N>, now_s: f64, out: &mut Output) -> Result<()> {
    if shared.settings.pipeline == Pipeline::FixThenFilter
        && !track.epoch.is_empty()
        && now_s - track.epoch_start_s > shared.settings.epoch_s
    {
        close_epoch(shared, track, out)?;
    }
    if shared.settings.pipeline == Pipeline::TightlyCoupled {
        expire_initial_readings(shared, track, now_s, "epoch", out);
    }
    Ok(())
}

/// Tightly coupled, a track (re)initialising: readings older than the confirmation window are
/// dropped from its buffer and reported.
fn expire_initial_readings<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    kind: &'static str,
    out: &mut Output,
) {
    let window_s = shared.settings.initiation.within_s;
    // the buffer is in time order
    let expired = track.epoch.iter().take_while(|(t, _)| now_s - t > window_s).count();
    if expired > 0 {
        let reason = format!("{expired} reading(s) expired before enough anchors could initialise the track");
        out.events.push(rejected(&track.tag, now_s, kind, reason));
        track.epoch.drain(..expired);
    }
}

/// Solves the epoch into fixes and applies them at the epoch's last time.
fn close_epoch<const N: usize>(shared: &Shared, track: &mut Track<N>, out: &mut Output) -> Result<()> {
    let epoch = std::mem::take(&mut track.epoch);
    let Some(&(time_s, _)) = epoch.last() else {
        return Ok(());
    };
    let readings: Vec<AnchorReading> = epoch.iter().map(|(_, r)| *r).collect();
    // a lost track's state is too stale to start the solver from
    let guess = track.state.as_ref().filter(|_| !track.is_lost());
    match solve::<N>(shared, &readings, guess) {
        Ok(fixes) => {
            for (position, covariance) in fixes {
                out.fixes.push(raw_fix(&track.tag, time_s, &position, &covariance));
                fix_update(shared, track, time_s, &position, &covariance, "epoch", out)?;
            }
        }
        Err(reason) => out.events.push(rejected(&track.tag, time_s, "epoch", reason)),
    }
    Ok(())
}

fn raw_fix(tag: &Arc<str>, time_s: f64, position: &[f64], covariance: &[f64]) -> RawFix {
    let mut position_m = [0.0; 3];
    position_m[..position.len()].copy_from_slice(position);
    let mut covariance_m2 = [0.0; 9];
    covariance_m2[..covariance.len()].copy_from_slice(covariance);
    RawFix {
        time_s,
        tag: Arc::clone(tag),
        dimensions: position.len(),
        position_m,
        covariance_m2,
    }
}

/// `x⁻ = F x̂ (+ B a)`, `P⁻ = F P Fᵀ + Q` to `time_s`, with a recent accelerometer sample as
/// the control input (seed 002's acceleration-driven prediction).
fn predict<const N: usize>(shared: &Shared, track: &Track<N>, state: &Gaussian<N>, time_s: f64) -> Result<Gaussian<N>> {
    match track.acceleration {
        Some((t, a)) if time_s - t <= ACCELERATION_HOLD_S => {
            let u = DVector::from_iterator(dimensions::<N>(), a.iter().copied().take(dimensions::<N>()));
            Ok(shared
                .kf
                .predict_with_control(state, &shared.aided_motion, &u, time_s)?)
        }
        _ => Ok(shared.kf.predict(state, &shared.motion, time_s)?),
    }
}

/// Accepts an update unless the track is confirmed and the NIS is outside the χ² gate; then
/// advances the lifecycle.
fn accept<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    updated: Updated<N>,
    kind: &'static str,
    source: UpdateSource,
    out: &mut Output,
) -> Result<()> {
    let time_s = updated.state.time_s();
    let dof = updated.measurement_dim().clamp(1, 3);
    let gated = matches!(track.status(), Some(TrackStatus::Confirmed | TrackStatus::Coasting));
    if gated && updated.nis > shared.gates[dof - 1] {
        let reason = format!(
            "outside the χ²({dof}) validation gate: NIS {:.2} > {:.2}",
            updated.nis,
            shared.gates[dof - 1]
        );
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(());
    }
    let position_m = position_of(&updated.state, shared.tag_height_m).0;
    track.state = Some(updated.state);
    track.lost_state = None;
    if let Some(event) = track
        .lifecycle
        .as_mut()
        .map(|l| l.update(time_s))
        .transpose()?
        .flatten()
    {
        out.events.push(Event::Lifecycle {
            tag: Arc::clone(&track.tag),
            time_s,
            event,
            position_m,
        });
    }
    track.unreported = Some(source);
    Ok(())
}

/// A position fix: starts the track, or updates it (`H` selects the position components).
fn fix_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let k = position.len();
    let Some(state) = track.state.as_ref().filter(|_| !track.is_lost()) else {
        // a new track, or a lost one whose prior is too stale to update
        return start_from_fix(shared, track, time_s, position, covariance, kind, out);
    };
    let indices: Vec<usize> = (0..k).map(|i| 2 * i).collect();
    let prior = predict(shared, track, state, time_s)?;
    component_update(
        shared,
        track,
        prior,
        &indices,
        position,
        covariance,
        kind,
        UpdateSource::Fix,
        out,
    )
}

/// (Re)starts a track at a fix: `x₀ = [p, 0]`, `P₀ = diag(Σ_fix, σ_v² I)`; a lost track
/// recovers, a new one starts its lifecycle.
fn start_from_fix<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let k = position.len();
    let mut mean = Vector::<N>::zeros();
    let mut p0 = Matrix::<N>::zeros();
    let speed_variance = shared.settings.initial_speed_std_mps.powi(2);
    for i in 0..dimensions::<N>() {
        p0[(2 * i + 1, 2 * i + 1)] = speed_variance;
        if i < k {
            mean[2 * i] = position[i];
            for j in 0..k {
                p0[(2 * i, 2 * j)] = covariance[i * k + j];
            }
        } else {
            // an axis the fix does not give (a 2-D fingerprint fix in a 3-D track)
            mean[2 * i] = shared.tag_height_m;
            p0[(2 * i, 2 * i)] = 100.0;
        }
    }
    let state = match Gaussian::new(mean, p0, time_s) {
        Ok(state) => state,
        Err(error) => {
            let reason = format!("cannot start a track from this fix: {error}");
            out.events.push(rejected(&track.tag, time_s, kind, reason));
            return Ok(());
        }
    };
    let position_m = position_of(&state, shared.tag_height_m).0;
    track.state = Some(state);
    track.lost_state = None;
    track.unreported = Some(UpdateSource::Fix);
    match track.lifecycle.as_mut() {
        None => track.lifecycle = Some(Lifecycle::start(shared.lifecycle, time_s)?),
        Some(lifecycle) => {
            if let Some(event) = lifecycle.update(time_s)? {
                out.events.push(Event::Lifecycle {
                    tag: Arc::clone(&track.tag),
                    time_s,
                    event,
                    position_m,
                });
            }
        }
    }
    Ok(())
}

/// A linear update of state components `indices` with `value` and its row-major covariance;
/// a failed update is reported, not applied.
#[allow(clippy::too_many_arguments)]
fn component_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    prior: Gaussian<N>,
    indices: &[usize],
    value: &[f64],
    covariance: &[f64],
    kind: &'static str,
    source: UpdateSource,
    out: &mut Output,
) -> Result<()> {
    let k = indices.len();
    let result = NoiseCovariance::full(DMatrix::from_row_slice(k, k, covariance))
        .and_then(|noise| ComponentSelection::<N>::new(indices, noise))
        .and_then(|model| shared.kf.update(&prior, &model, &DVector::from_column_slice(value)));
    match result {
        Ok(updated) => accept(shared, track, updated, kind, source, out),
        Err(error) => {
            let reason = format!("{} update failed: {error}", source.name());
            out.events.push(rejected(&track.tag, prior.time_s(), kind, reason));
            Ok(())
        }
    }
}

/// A velocity measurement of the first `k` axes.
fn velocity_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    velocity: &[f64],
    covariance: &[f64],
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(state) = track.state.as_ref().filter(|_| !track.is_lost()) else {
        let reason =
            "no track (or a lost one): a velocity cannot start or recover it (it needs a position)".to_string();
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        return Ok(());
    };
    let indices: Vec<usize> = (0..velocity.len()).map(|i| 2 * i + 1).collect();
    let prior = predict(shared, track, state, time_s)?;
    component_update(
        shared,
        track,
        prior,
        &indices,
        velocity,
        covariance,
        kind,
        UpdateSource::Velocity,
        out,
    )
}

/// Tightly coupled: one range / RSSI / TDOA straight into the EKF or UKF (seed 003's
/// one-observation update).
fn coupled_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let (model, z) = match reading {
        AnchorReading::Range {
            anchor,
            range_m,
            variance_m2,
        } => (
            AnchorMeasurement::new(
                shared.anchors.get(anchor).position_m,
                shared.tag_height_m,
                AnchorLaw::Range,
                variance_m2,
            ),
            range_m,
        ),
        AnchorReading::Rssi {
            anchor,
            rssi_dbm,
            law: [p0, d0, n, _],
            variance_db2,
        } => {
            let law = AnchorLaw::LogDistance {
                reference_power_dbm: p0,
                reference_distance_m: d0,
                exponent: n,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    variance_db2,
                ),
                rssi_dbm,
            )
        }
        AnchorReading::Tdoa {
            anchor,
            reference,
            range_difference_m,
            variance_m2,
        } => {
            let law = AnchorLaw::RangeDifference {
                reference_m: shared.anchors.get(reference).position_m,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    variance_m2,
                ),
                range_difference_m,
            )
        }
    };
    let prior = predict(shared, track, state, time_s)?;
    let z = DVector::from_element(1, z);
    let result = match shared.settings.filter {
        FilterKind::Ukf => shared.ukf.update(&prior, &model, &z),
        FilterKind::Ekf | FilterKind::Kf => shared.ekf.update(&prior, &model, &z),
    };
    match result {
        Ok(updated) => accept(shared, track, updated, kind, UpdateSource::Anchors, out),
        Err(error) => {
            out.events.push(rejected(
                &track.tag,
                time_s,
                kind,
                format!("filter update failed: {error}"),
            ));
            Ok(())
        }
    }
}

fn track_update<const N: usize>(
    shared: &Shared,
    tag: &Arc<str>,
    state: &Gaussian<N>,
    predicted: bool,
    status: TrackStatus,
    source: UpdateSource,
) -> TrackUpdate {
    let d = dimensions::<N>();
    let (position_m, covariance) = position_of(state, shared.tag_height_m);
    let mut velocity_mps = [0.0; 3];
    for (axis, v) in velocity_mps.iter_mut().enumerate().take(d) {
        *v = state.mean()[2 * axis + 1];
    }
    let mut position_covariance_m2 = [0.0; 9];
    position_covariance_m2[..d * d].copy_from_slice(&covariance);
    TrackUpdate {
        time_s: state.time_s(),
        tag: Arc::clone(tag),
        dimensions: d,
        position_m,
        velocity_mps,
        position_covariance_m2,
        predicted,
        status,
        source,
    }
}

/// Reports the track's latest update, then its zones and alarms.
fn report<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let (Some(source), Some(state), Some(status)) = (track.unreported.take(), track.state, track.status()) else {
        return Ok(());
    };
    out.updates
        .push(track_update(shared, &track.tag, &state, false, status, source));
    track.last_output_s = state.time_s();
    if matches!(status, TrackStatus::Confirmed | TrackStatus::Coasting) {
        zones_and_alarms(shared, track, &state, monitor, out)?;
    }
    Ok(())
}

/// A coasting track's prediction at `now_s`, flagged as predicted (seed 000's gap filling).
fn coast<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let predicted = predict(shared, track, state, now_s)?;
    out.updates.push(track_update(
        shared,
        &track.tag,
        &predicted,
        true,
        TrackStatus::Coasting,
        UpdateSource::Prediction,
    ));
    track.last_output_s = now_s;
    zones_and_alarms(shared, track, &predicted, monitor, out)
}

/// Zone events for the state's position, then the predictive alarms.
fn zones_and_alarms<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    state: &Gaussian<N>,
    monitor: &mut ZoneMonitor,
    out: &mut Output,
) -> Result<()> {
    let (position_m, _) = position_of(state, shared.tag_height_m);
    for zone_event in monitor.update(&track.tag, state.time_s(), position_m)? {
        if let ZoneEvent::Enter { zone, time_s, .. } = &zone_event {
            if shared.no_coverage_zones.iter().any(|z| z == zone) {
                out.events.push(Event::NoCoverage {
                    tag: Arc::clone(&track.tag),
                    zone: zone.clone(),
                    time_s: *time_s,
                });
            }
        }
        out.events.push(Event::Zone(zone_event));
    }
    if shared.alarm_zones.is_empty() {
        return Ok(());
    }
    let inside: Vec<bool> = shared.alarm_zones.iter().map(|z| z.contains(position_m)).collect();
    let entries = predict_entries(
        state,
        &shared.motion,
        &shared.alarm_zones,
        &inside,
        &shared.alarms,
        shared.tag_height_m,
    )?;
    for (index, zone) in shared.alarm_zones.iter().enumerate() {
        let entry = entries.iter().find(|e| e.zone == index);
        match (entry, track.alarmed[index], inside[index]) {
            (Some(entry), false, _) => {
                track.alarmed[index] = true;
                out.events.push(Event::HazardPredicted {
                    tag: Arc::clone(&track.tag),
                    zone: zone.id.clone(),
                    time_s: state.time_s(),
                    time_to_entry_s: entry.time_to_entry_s,
                    probability: entry.probability,
                });
            }
            // inside: the zone-enter event takes over; the alarm stays raised until the tag
            // is out and no longer heading in
            (None, true, false) => {
                track.alarmed[index] = false;
                out.events.push(Event::HazardCleared {
                    tag: Arc::clone(&track.tag),
                    zone: zone.id.clone(),
                    time_s: state.time_s(),
                });
            }
            _ => {}
        }
    }
    Ok(())
}

/// Clears every raised alarm of a deleted track.
fn clear_alarms<const N: usize>(shared: &Shared, track: &mut Track<N>, now_s: f64, out: &mut Output) {
    for (index, zone) in shared.alarm_zones.iter().enumerate() {
        if std::mem::take(&mut track.alarmed[index]) {
            out.events.push(Event::HazardCleared {
                tag: Arc::clone(&track.tag),
                zone: zone.id.clone(),
                time_s: now_s,
            });
        }
    }
}
