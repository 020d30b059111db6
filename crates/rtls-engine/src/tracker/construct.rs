//! Building a [`Tracker`] from a site: its settings, models, filters, gates and zones.

use std::sync::Arc;

use super::range_bias::OffsetModel;
use rtls_estimation::adaptive::corrections::CorrectionTest;
use rtls_estimation::adaptive::correlation::ErrorCorrelation;
use rtls_estimation::adaptive::AdaptiveNoise;
use rtls_estimation::aided::HeadingModel;
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, SigmaPointParameters, UnscentedKalmanFilter};
use rtls_estimation::motion::{ConstantVelocity, ProcessNoise};
use rtls_estimation::stats::chi_square_quantile;

use super::anchors::Anchors;
use super::anonymous::AnonymousFront;
use super::core::Core;
use super::modes::Manoeuvres;
use super::schedule::Scheduling;
use super::track::Shared;
use super::{bounds, constraint_model, Tracker, Tracks};
use crate::error::{EngineError, Result};
use crate::record::{Reorderer, TimeGate};
use crate::site::{MotionModelKind, Site};
use crate::zones::ZoneKind;

impl Tracker {
    /// A tracker for `site` (its readers, zones, `[tracker]`, `[zone_events]` and `[alarms]`).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for a motion model other than `cv` (the tracker's
    /// measurement models assume the CV state `[x, vx, y, vy(, z, vz)]`), or settings the
    /// lifecycle or zone monitor reject.
    pub fn new(site: &Site) -> Result<Self> {
        let settings = site.tracker;
        let manoeuvres = match settings.motion_model {
            MotionModelKind::Cv => None,
            MotionModelKind::Imm | MotionModelKind::Ct => Some(Arc::new(Manoeuvres::new(&settings)?)),
            MotionModelKind::Ca | MotionModelKind::RandomWalk => {
                return Err(EngineError::InvalidParameter {
                    name: "tracker.motion_model",
                    reason: "the tracker runs the constant-velocity model (\"cv\"), the coordinated turn \
                             (\"ct\") or the interacting multiple models (\"imm\", which can include a \
                             constant acceleration); a lone \"ca\" or \"random-walk\" is available in \
                             rtls-estimation but not wired into the tracker",
                });
            }
        };
        let lifecycle = settings.lifecycle();
        lifecycle.validate()?;
        // q = σ_a² (continuous white acceleration)
        let noise = ProcessNoise::continuous(settings.acceleration_noise_std_mps2.powi(2));
        let motion = ConstantVelocity::new(noise)?;
        let mut gates = [0.0; 3];
        let mut check_run_gates = [0.0; 3];
        for (dof, (gate, run_gate)) in gates.iter_mut().zip(&mut check_run_gates).enumerate() {
            *gate = chi_square_quantile(settings.gate_probability, (dof + 1) as f64)?;
            // a run of check fixes: χ²(k · CHECK_RUN)
            *run_gate = chi_square_quantile(settings.gate_probability, ((dof + 1) * super::check::CHECK_RUN) as f64)?;
        }
        let no_coverage_zones: Vec<String> = site
            .zones
            .iter()
            .filter(|z| !z.readers.is_empty() && z.readers.iter().all(|r| site.reader(r).is_some_and(|r| !r.working)))
            .map(|z| z.id.clone())
            .collect();
        let alarm_zones = site
            .zones
            .iter()
            .filter(|z| z.kind == ZoneKind::Hazard || no_coverage_zones.contains(&z.id))
            .cloned()
            .collect();

        let anchors = Anchors::new(site);
        let shadows = site
            .zones
            .iter()
            .filter(|z| no_coverage_zones.contains(&z.id))
            .cloned()
            .collect();
        let constraints = constraint_model::Constraints::new(site, &anchors, shadows);
        let shared = Shared {
            settings,
            alarms: site.alarms,
            lifecycle,
            anchors,
            radio_map: None,
            motion,
            // the accelerometer-driven model: the residual noise σ_r (absent: σ_a)
            aided_motion: match settings.aided_acceleration_noise_std_mps2 {
                Some(sigma) => ConstantVelocity::new(ProcessNoise::continuous(sigma * sigma))?,
                None => motion,
            }
            .with_acceleration_input(),
            kf: KalmanFilter::default(),
            ekf: ExtendedKalmanFilter::default(),
            ukf: UnscentedKalmanFilter::new(SigmaPointParameters::default()),
            gates,
            check_run_gates,
            tag_height_m: settings.tag_height_m.unwrap_or(0.0),
            alarm_zones,
            no_coverage_zones,
            manoeuvres,
            scheduling: Scheduling::new(site)?.map(Arc::new),
            adaptive: if settings.adaptive_noise.enabled {
                Some(AdaptiveNoise::new(
                    settings.adaptive_noise.memory_s,
                    settings.adaptive_noise.max_scale,
                )?)
            } else {
                None
            },
            error_correlation: if settings.adaptive_noise.correlation_from_innovations {
                Some(ErrorCorrelation::new(settings.adaptive_noise.memory_s)?)
            } else {
                None
            },
            bounds: bounds::SiteBounds::new(site),
            heading_model: HeadingModel::new(
                settings.heading.gyro_bias_std_radps,
                settings.heading.gyro_bias_random_walk_radps_per_sqrt_s,
                settings.heading.heading_random_walk_rad_per_sqrt_s,
                settings.heading.odometer_drift_rad_per_sqrt_s,
                settings.heading.odometer_offset_std_rad,
            )?,
            range_bias: if settings.range_bias.enabled {
                Some(OffsetModel::new(&settings.range_bias, site)?)
            } else {
                None
            },
            consistency: if settings.consistency.enabled {
                Some(CorrectionTest::new(
                    settings.consistency.window_s,
                    settings.consistency.probability,
                    settings.consistency.max_inflation,
                )?)
            } else {
                None
            },
            frame: site.frame.map(|f| f.local_frame()).transpose()?,
            constraints,
        };
        let monitor = site.zone_monitor()?;
        let tracks = if settings.dimensions == 3 {
            Tracks::Spatial(Core::new(shared, monitor))
        } else {
            Tracks::Planar(Core::new(shared, monitor))
        };
        let anonymous = match site.anonymous {
            Some(anonymous) => Some(AnonymousFront::new(anonymous, settings.tag_height_m.unwrap_or(0.0))?),
            None => None,
        };
        Ok(Self {
            tracks,
            anonymous,
            time_gate: TimeGate::new(settings.max_time_jump_s)?,
            reorderer: Reorderer::new(settings.reorder_window_s)?,
            next_tick_s: None,
            output_interval_s: settings.output_interval_s,
            rewind_horizon_s: settings.rewind_horizon_s,
            now_s: f64::NEG_INFINITY,
            watermark_s: None,
            released: Vec::new(),
        })
    }
}
