//! Our tracker for seed 000: an EKF on the raw RSSI of whichever readers heard the tag (one is
//! enough, so there are no empty epochs), with a pedestrian CV model, a per-reader χ² gate, the
//! tunnel map as a pseudo-measurement, the walking speed limit, and re-initialisation from the
//! RSSI fix when the track has lost the tag.
//!
//! The steps of an epoch are listed on [`OursConfig`].

use nalgebra::{DVector, Matrix3, Vector3};
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter};
use rtls_estimation::measurement::{LogDistancePathLoss, MeasurementModel, NoiseCovariance, RssPathLoss};
use rtls_estimation::stats::ChiSquareGate;
use rtls_estimation::{Gaussian, Matrix, Vector};

use super::models::{MapSpread, PedestrianCv, PositionConstraint, POSITION_INDICES};
use crate::error::{Result, SimError};
use rtls_sim::scenarios::seed_000::MineLayout;
use rtls_sim::sensors::readers::{Detection, ReaderLayer, ReaderStatus, RssiFix};

/// Our tracker's parameters. Per epoch the tracker runs
///
/// ```text
/// predict                     x⁻ = F x̂,  P⁻ = F P Fᵀ + Q                  (pedestrian CV)
/// for each reader i heard     ν = ρᵢ − μ(‖p⁻ − rᵢ‖),  S = H P Hᵀ + σ_X²,   apply if ν²/S ≤ χ²₁(P_G)
/// for each silent reader j    if μ(‖p − rⱼ‖) − L_map > S: update with ρⱼ = S   (negative information)
/// map                         lateral offset 0 ± σ_lat (not near a junction), height on the
///                             walking line ± σ_vert, back at a dead end if past it
/// speed                       |v_xy| ≤ v_max                            (estimate projection)
/// re-initialise               at the RSSI fix after K epochs in which the gate rejected RSSI
///                             and the fix lay outside the track's χ²₃ gate
/// ```
///
/// # References
/// Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
/// Navigation*, Wiley 2001, §5.4 and §6.3 (gating, white-noise acceleration);
/// W. Koch, "On exploiting 'negative' sensor evidence for target tracking and sensor data
/// fusion", *Information Fusion* 8(1), 2007 (silent sensors as information); D. Simon,
/// "Kalman filtering with state constraints", *IET Control Theory & Applications* 4(8), 2010
/// (map and speed constraints).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OursConfig {
    /// The pedestrian CV model.
    pub motion: PedestrianCv,
    /// Per-reader gate on the scalar NIS (`χ²₁` quantile).
    pub gate: ChiSquareGate,
    /// After this many consecutive epochs whose every RSSI was gated out, the next such epoch is
    /// applied ungated.
    pub reacquire_after: usize,
    /// The tunnel map as a pseudo-measurement every epoch.
    pub map: MapSpread,
    /// Largest plan speed of a walker, m/s.
    pub max_speed_mps: f64,
    /// Per-axis error of an RSSI fix assumed by the re-initialisation gate, m.
    pub fix_std_m: f64,
    /// Gate (`χ²₃` quantile) on the distance between the track and the RSSI fix.
    pub reinit_gate: ChiSquareGate,
    /// Consecutive epochs in which RSSI was gated out and the fix lay outside that gate, after
    /// which the track restarts at the fix.
    pub reinit_after: usize,
    /// Within this plan distance of a junction or bend the lateral map constraint is not
    /// applied (which leg the walker takes is for the RSSI to tell), m.
    pub junction_radius_m: f64,
}

/// Counts of our tracker's decisions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrackerCounts {
    /// RSSI values applied after passing the gate.
    pub accepted: usize,
    /// RSSI values rejected by the gate.
    pub rejected: usize,
    /// RSSI values applied ungated to re-acquire a track that rejected everything.
    pub forced: usize,
    /// Re-initialisations from the RSSI fix.
    pub reinitialised: usize,
    /// Epochs whose speed was projected down to the limit.
    pub speed_limited: usize,
    /// Silent readers applied as negative information.
    pub silent: usize,
}

/// Running sum of one reader's RSSI innovations (measured − predicted), dB.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InnovationSum {
    /// `Σ ν`, dB.
    pub sum_db: f64,
    /// Number of innovations.
    pub count: usize,
}

/// The tracker of one run: its filters, models and memory between epochs.
pub(super) struct Ours<'a> {
    config: OursConfig,
    ekf: ExtendedKalmanFilter,
    kf: KalmanFilter,
    law: LogDistancePathLoss,
    noise: NoiseCovariance,
    layer: &'a ReaderLayer,
    layout: &'a MineLayout,
    /// Consecutive epochs with every RSSI gated out.
    all_rejected: usize,
    /// Consecutive epochs with the fix outside the track's gate.
    inconsistent: usize,
    /// Decisions so far.
    pub(super) counts: TrackerCounts,
    /// Innovations per reader so far.
    pub(super) innovations: Vec<InnovationSum>,
}

impl<'a> Ours<'a> {
    /// A tracker for `layer` on `layout`.
    ///
    /// # Errors
    /// [`SimError::Estimation`] for an unusable radio law.
    pub(super) fn new(config: OursConfig, layer: &'a ReaderLayer, layout: &'a MineLayout) -> Result<Self> {
        let law = layer.radio().law();
        let estimation = SimError::estimation(0.0);
        let mean_law = LogDistancePathLoss::new(law.reference_rssi_dbm(), law.reference_distance_m(), law.exponent())
            .map_err(estimation)?;
        let noise = NoiseCovariance::isotropic(1, law.shadowing_std_db().powi(2).max(1e-9))
            .map_err(SimError::estimation(0.0))?;
        Ok(Self {
            config,
            ekf: ExtendedKalmanFilter::default(),
            kf: KalmanFilter::default(),
            law: mean_law,
            noise,
            layer,
            layout,
            all_rejected: 0,
            inconsistent: 0,
            counts: TrackerCounts::default(),
            innovations: vec![InnovationSum::default(); layer.readers().len()],
        })
    }

    /// One epoch at `time_s` with the detections and the reader layer's RSSI fix.
    ///
    /// # Errors
    /// [`SimError::Estimation`] if a filter step fails.
    pub(super) fn step(
        &mut self,
        state: &Gaussian<6>,
        time_s: f64,
        detections: &[Detection],
        fix: Option<&RssiFix>,
    ) -> Result<Gaussian<6>> {
        let prior = self
            .ekf
            .predict(state, &self.config.motion, time_s)
            .map_err(SimError::estimation(time_s))?;
        let rejected_before = self.counts.rejected;
        let (mut state, accepted) = self.rssi(prior, detections, true)?;
        let rejected_now = self.counts.rejected > rejected_before;
        if !detections.is_empty() && accepted == 0 {
            self.all_rejected += 1;
            if self.all_rejected >= self.config.reacquire_after {
                // re-acquire: apply this epoch's RSSI without the gate
                state = self.rssi(prior, detections, false)?.0;
                self.all_rejected = 0;
            }
        } else if accepted > 0 {
            self.all_rejected = 0;
        }
        state = self.silence(state, detections)?;
        state = self.map(state)?;
        state = self.limit_speed(state)?;
        if let Some(f) = fix {
            // lost: the gate rejected RSSI and the reader layer's fix disagrees with the track
            if rejected_now && self.fix_is_inconsistent(&state, f)? {
                self.inconsistent += 1;
            } else {
                self.inconsistent = 0;
            }
            if self.inconsistent >= self.config.reinit_after {
                state = self.map(self.restart(f, time_s)?)?;
                self.inconsistent = 0;
                self.counts.reinitialised += 1;
            }
        }
        Ok(state)
    }

    /// Sequential scalar EKF updates with the RSSI of each reader heard; with `gated`, a value
    /// whose NIS exceeds the gate is skipped. Returns the state and the number applied.
    fn rssi(&mut self, prior: Gaussian<6>, detections: &[Detection], gated: bool) -> Result<(Gaussian<6>, usize)> {
        let t = prior.time_s();
        let mut state = prior;
        let mut applied = 0;
        for d in detections {
            let reader = self
                .layer
                .readers()
                .get(d.reader)
                .ok_or(SimError::InvalidParameter {
                    name: "detections",
                    reason: "a detection names a reader index outside the layer",
                })?
                .position_m;
            let model =
                RssPathLoss::spatial(self.law, &[reader], self.noise.clone()).map_err(SimError::estimation(t))?;
            // ν = ρ − h(x⁻), S = H P⁻ Hᵀ + R, NIS = ν²/S
            let updated = self
                .ekf
                .update(&state, &model, &DVector::from_element(1, d.rssi_dbm))
                .map_err(SimError::estimation(t))?;
            if gated {
                let sum = &mut self.innovations[d.reader];
                sum.sum_db += updated.innovation[0];
                sum.count += 1;
                if !self
                    .config
                    .gate
                    .accepts(updated.nis, 1)
                    .map_err(SimError::estimation(t))?
                {
                    self.counts.rejected += 1;
                    continue;
                }
                self.counts.accepted += 1;
            } else {
                self.counts.forced += 1;
            }
            state = updated.state;
            applied += 1;
        }
        Ok((state, applied))
    }

    /// Negative information: a working reader that did not hear the tag although, from the
    /// estimate, it should have (mean power above the sensitivity, after the map's wall and
    /// rockfall losses) says the tag is farther away. It is applied as the pseudo-measurement
    /// `ρ = S` (the most the reader could have received unheard), `R = σ_X²`, pushing the estimate
    /// back to where the silence is expected; a silence that is expected changes nothing.
    fn silence(&mut self, mut state: Gaussian<6>, detections: &[Detection]) -> Result<Gaussian<6>> {
        let t = state.time_s();
        let sensitivity_dbm = self.layer.radio().sensitivity_dbm();
        for (i, reader) in self.layer.readers().iter().enumerate() {
            if reader.status == ReaderStatus::Broken || detections.iter().any(|d| d.reader == i) {
                continue;
            }
            let m = state.mean();
            let position = [m[0], m[2], m[4]];
            // ŷ = μ(d) − L_map
            let walls_db = self.layout.path_loss_db(position, reader.position_m);
            let model = RssPathLoss::spatial(self.law, &[reader.position_m], self.noise.clone())
                .map_err(SimError::estimation(t))?;
            let predicted = model.predict(m).map_err(SimError::estimation(t))?[0] - walls_db;
            if predicted <= sensitivity_dbm {
                continue;
            }
            // ν = (S + L_map) − μ(d) = S − ŷ < 0
            state = self
                .ekf
                .update(&state, &model, &DVector::from_element(1, sensitivity_dbm + walls_db))
                .map_err(SimError::estimation(t))?
                .state;
            self.counts.silent += 1;
        }
        Ok(state)
    }

    /// The map: the walking line of the nearest leg (lateral — except near a junction — and
    /// vertical), and the leg's dead end if the estimate lies past it.
    fn map(&self, state: Gaussian<6>) -> Result<Gaussian<6>> {
        let t = state.time_s();
        let m = state.mean();
        let position = [m[0], m[2], m[4]];
        let Some(line) = self.layout.nearest_walking_line(position) else {
            return Ok(state);
        };
        let near_junction = line
            .distance_to_junction_m(position)
            .is_some_and(|d| d < self.config.junction_radius_m);
        let mut state = if near_junction {
            let (c, r) = line.vertical();
            let (vertical, z) = PositionConstraint::new(&[(c, r, self.config.map.vertical_std_m)])?;
            self.kf
                .update(&state, &vertical, &z)
                .map_err(SimError::estimation(t))?
                .state
        } else {
            let (model, z) = PositionConstraint::tunnel(&line, &self.config.map)?;
            self.kf
                .update(&state, &model, &z)
                .map_err(SimError::estimation(t))?
                .state
        };
        if let Some((c, r)) = line.overshoot(position) {
            // d · p = end, σ = σ_lat
            let (end, z) = PositionConstraint::new(&[(c, r, self.config.map.lateral_std_m)])?;
            state = self.kf.update(&state, &end, &z).map_err(SimError::estimation(t))?.state;
        }
        Ok(state)
    }

    /// `v_xy ← v_xy · v_max/|v_xy|` when faster than a walker (the covariance is kept).
    fn limit_speed(&mut self, state: Gaussian<6>) -> Result<Gaussian<6>> {
        let mut mean = *state.mean();
        let speed = mean[1].hypot(mean[3]);
        if speed <= self.config.max_speed_mps {
            return Ok(state);
        }
        self.counts.speed_limited += 1;
        let scale = self.config.max_speed_mps / speed;
        mean[1] *= scale;
        mean[3] *= scale;
        Gaussian::new(mean, *state.covariance(), state.time_s()).map_err(SimError::estimation(state.time_s()))
    }

    /// Whether `(f − p)ᵀ (P_pp + σ_f² I)⁻¹ (f − p)` exceeds the χ²₃ gate.
    fn fix_is_inconsistent(&self, state: &Gaussian<6>, fix: &RssiFix) -> Result<bool> {
        let t = state.time_s();
        let m = state.mean();
        let p = state.covariance();
        let mut s = Matrix3::<f64>::identity() * self.config.fix_std_m.powi(2);
        let mut d = Vector3::zeros();
        for (a, &ia) in POSITION_INDICES.iter().enumerate() {
            d[a] = fix.position_m[a] - m[ia];
            for (b, &ib) in POSITION_INDICES.iter().enumerate() {
                // S = P_pp + σ_f² I
                s[(a, b)] += p[(ia, ib)];
            }
        }
        let distance2 = s.cholesky().map_or(f64::INFINITY, |c| d.dot(&c.solve(&d)));
        Ok(!self
            .config
            .reinit_gate
            .accepts(distance2, 3)
            .map_err(SimError::estimation(t))?)
    }

    /// A fresh track at the fix, at rest: position variance `σ_f²`, velocity variance
    /// `(v_max/2)²` per axis.
    fn restart(&self, fix: &RssiFix, time_s: f64) -> Result<Gaussian<6>> {
        let mut mean = Vector::<6>::zeros();
        let mut covariance = Matrix::<6>::zeros();
        for (a, &i) in POSITION_INDICES.iter().enumerate() {
            mean[i] = fix.position_m[a];
            covariance[(i, i)] = self.config.fix_std_m.powi(2);
            covariance[(i + 1, i + 1)] = (self.config.max_speed_mps / 2.0).powi(2);
        }
        Gaussian::new(mean, covariance, time_s).map_err(SimError::estimation(time_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_positioning::pathloss::{LogDistance, PathLossModel};
    use rtls_sim::scenarios::seed_000::Tunnel;
    use rtls_sim::sensors::readers::distance_m;
    use rtls_sim::sensors::readers::{Reader, ReaderRadio};

    fn fixture() -> (ReaderLayer, MineLayout, OursConfig) {
        let tunnel = Tunnel::new("drift", vec![[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]], 2.0).unwrap();
        let reader = |x: f64| Reader {
            name: format!("R{x}"),
            position_m: [x, 1.8, 1.0],
            status: ReaderStatus::Working,
            obstacle_loss_db: 0.0,
        };
        let readers = vec![reader(20.0), reader(80.0)];
        let radio = ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0).unwrap(), -85.0).unwrap();
        let layer = ReaderLayer::new(readers.clone(), radio).unwrap();
        let layout = MineLayout::new(vec![tunnel], readers, Vec::new(), Vec::new(), 25.0).unwrap();
        let config = OursConfig {
            motion: PedestrianCv::new(0.25, 0.0025).unwrap(),
            gate: ChiSquareGate::new(0.99).unwrap(),
            reacquire_after: 2,
            map: MapSpread {
                lateral_std_m: 1.0,
                vertical_std_m: 0.1,
            },
            max_speed_mps: 2.0,
            fix_std_m: 4.0,
            reinit_gate: ChiSquareGate::new(0.95).unwrap(),
            reinit_after: 2,
            junction_radius_m: 6.0,
        };
        (layer, layout, config)
    }

    fn state(position: [f64; 3], velocity: [f64; 3], variance: f64) -> Gaussian<6> {
        let mut mean = Vector::<6>::zeros();
        for (a, &i) in POSITION_INDICES.iter().enumerate() {
            mean[i] = position[a];
            mean[i + 1] = velocity[a];
        }
        Gaussian::new(mean, Matrix::<6>::identity() * variance, 1.0).unwrap()
    }

    /// A reader that should have heard the tag (4 m away) but did not pushes the estimate away;
    /// a reader that could not have heard it (60 m away) changes nothing.
    #[test]
    fn silence_pushes_the_estimate_away_only_when_the_reader_should_have_heard() {
        let (layer, layout, config) = fixture();
        let mut ours = Ours::new(config, &layer, &layout).unwrap();
        let near = state([24.0, 0.0, 0.0], [0.0; 3], 25.0);
        let after = ours.silence(near, &[]).unwrap();
        assert!(after.mean()[0] > 24.5, "moved to {}", after.mean()[0]);
        assert_eq!(ours.counts.silent, 1);
        let far = state([50.0, 0.0, 0.0], [0.0; 3], 25.0);
        assert_eq!(ours.silence(far, &[]).unwrap(), far);
        // a reader that did hear the tag is not silent
        let heard = [Detection {
            reader: 0,
            rssi_dbm: -70.0,
        }];
        assert_eq!(ours.silence(near, &heard).unwrap().mean()[0], 24.0);
    }

    /// The map pulls a drifting estimate back to the walking line and back from a dead end;
    /// the speed is held at the walking limit.
    #[test]
    fn map_and_speed_constraints_hold_the_track_to_the_tunnel() {
        let (layer, layout, config) = fixture();
        let mut ours = Ours::new(config, &layer, &layout).unwrap();
        // P = 4, σ_lat² = 1: the 3 m lateral offset shrinks to 3 · 1/(4 + 1); σ_vert² = 0.01
        let off = ours.map(state([50.0, 3.0, 0.5], [0.0; 3], 4.0)).unwrap();
        assert!((off.mean()[2] - 0.6).abs() < 1e-9, "{:?}", off.mean());
        assert!((off.mean()[4] - 0.5 * 0.01 / 4.01).abs() < 1e-9, "{:?}", off.mean());
        let beyond = ours.map(state([104.0, 0.0, 0.0], [0.0; 3], 4.0)).unwrap();
        assert!(beyond.mean()[0] < 101.0, "{:?}", beyond.mean());
        let fast = ours.limit_speed(state([50.0, 0.0, 0.0], [3.0, 4.0, 0.0], 1.0)).unwrap();
        assert!((fast.mean()[1].hypot(fast.mean()[3]) - 2.0).abs() < 1e-12);
        assert_eq!(ours.counts.speed_limited, 1);
    }

    /// A track far from every consistent position restarts at the RSSI fix after the configured
    /// number of inconsistent epochs.
    #[test]
    fn a_lost_track_restarts_at_the_fix() {
        let (layer, layout, config) = fixture();
        let mut ours = Ours::new(config, &layer, &layout).unwrap();
        let law = layer.radio().law();
        // the tag is 2 m from reader 0; the track believes it is at x = 60
        let rssi = law.mean_rssi_dbm(distance_m([20.0, 0.0, 0.0], [20.0, 1.8, 1.0]));
        let detections = [Detection {
            reader: 0,
            rssi_dbm: rssi,
        }];
        let fix = RssiFix {
            position_m: [20.0, 0.0, 0.0],
            kind: rtls_sim::sensors::readers::RssiFixKind::Centroid,
        };
        let mut track = state([60.0, 0.0, 0.0], [0.0; 3], 0.5);
        for t in 2..6 {
            track = ours.step(&track, t as f64, &detections, Some(&fix)).unwrap();
        }
        assert!(ours.counts.reinitialised >= 1, "{:?}", ours.counts);
        assert!((track.mean()[0] - 20.0).abs() < 5.0, "{:?}", track.mean());
    }
}
