//! `scenarios/004-vehicle.toml` and its conversion into a [`Seed004Config`].

use rtls_estimation::aided::OdometryErrorModel;
use rtls_estimation::manoeuvre::{ManoeuvreDetector, Threshold};
use serde::Deserialize;

use super::FILE;
use crate::error::{Result, SimError};
use crate::reproduction::Seed004Config;
use rtls_sim::sensors::{OdometrySimulator, TdoaSimulator};

/// `scenarios/004-vehicle.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleScenario {
    /// Cruise speed, m/s.
    pub speed_mps: f64,
    /// Base stations `[x, y]`, m.
    pub stations_m: Vec<[f64; 2]>,
    /// TDOA timing errors.
    pub tdoa: TdoaSection,
    /// On-board speed and heading sensors.
    pub odometer: OdometerSection,
    /// Filter tuning.
    pub filters: FilterSection,
}

/// `[tdoa]`: timing errors of one range difference.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TdoaSection {
    /// Gaussian part, ns (1σ).
    pub gaussian_std_ns: f64,
    /// Upper end of the uniform NLOS delay, ns.
    pub nlos_uniform_max_ns: f64,
}

/// `[odometer]`: the speed and heading sensors.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdometerSection {
    /// Speed error, m/s (1σ).
    pub speed_std_mps: f64,
    /// Heading drift rate, °/h (sign random per run).
    pub heading_drift_deg_per_h: f64,
    /// White heading error, ° (1σ).
    pub heading_noise_std_deg: f64,
}

/// `[filters]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterSection {
    /// CV `σ_a²` with the printed `G`, (m/s)² per step.
    pub cv_variance: f64,
    /// CA `σ_m²`, (m/s²)² per step.
    pub ca_variance: f64,
    /// Surveyed points for the fix-covariance calibration.
    pub calibration_points: usize,
    /// Estimate and remove the heading drift.
    pub estimate_heading_drift: bool,
    /// The VD-KF's manoeuvre detector.
    pub detector: DetectorSection,
}

/// `[filters.detector]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorSection {
    /// `α` of `μ(k) = α μ(k−1) + νᵀS⁻¹ν`.
    pub fading_factor: f64,
    /// χ² quantile of the onset threshold.
    pub onset_probability: f64,
    /// Steps of the exit test.
    pub exit_window_steps: usize,
    /// χ² quantile of the exit threshold.
    pub exit_probability: f64,
    /// Prior std of the acceleration at the onset, m/s².
    pub onset_acceleration_std_mps2: f64,
}

fn scenario_error(section: &str, error: impl std::fmt::Display) -> SimError {
    SimError::Scenario {
        file: FILE.to_string(),
        reason: format!("{section}: {error}"),
    }
}

impl VehicleScenario {
    /// The run configuration, with every value checked.
    ///
    /// # Errors
    /// [`SimError::Scenario`] naming the section and field that is out of range.
    pub fn config(&self) -> Result<Seed004Config> {
        let mut tdoa = TdoaSimulator::new(&self.stations_m).map_err(|e| scenario_error("stations_m", e))?;
        tdoa.gaussian_std_s = self.tdoa.gaussian_std_ns / 1e9;
        tdoa.nlos_uniform_max_s = self.tdoa.nlos_uniform_max_ns / 1e9;
        tdoa.validate().map_err(|e| scenario_error("[tdoa]", e))?;
        let odometer = OdometrySimulator {
            speed_std_mps: self.odometer.speed_std_mps,
            heading_drift_rad_per_s: self.odometer.heading_drift_deg_per_h.to_radians() / 3600.0,
            heading_noise_std_rad: self.odometer.heading_noise_std_deg.to_radians(),
        };
        let odometry_model = OdometryErrorModel::new(
            odometer.speed_std_mps,
            odometer.heading_noise_std_rad,
            odometer.heading_drift_rad_per_s,
        )
        .map_err(|e| scenario_error("[odometer]", e))?;
        let d = self.filters.detector;
        let detector = ManoeuvreDetector {
            fading_factor: d.fading_factor,
            onset: Threshold::ChiSquare {
                probability: d.onset_probability,
            },
            exit_window_steps: d.exit_window_steps,
            exit: Threshold::ChiSquare {
                probability: d.exit_probability,
            },
            onset_acceleration_std_mps2: d.onset_acceleration_std_mps2,
        };
        detector
            .validate()
            .map_err(|e| scenario_error("[filters.detector]", e))?;
        for (name, value) in [
            ("speed_mps", self.speed_mps),
            ("[filters] cv_variance", self.filters.cv_variance),
            ("[filters] ca_variance", self.filters.ca_variance),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(scenario_error(name, "must be a finite number > 0"));
            }
        }
        if self.filters.calibration_points < 10 {
            return Err(scenario_error(
                "[filters] calibration_points",
                "at least 10 points are needed to estimate a 2 × 2 covariance",
            ));
        }
        Ok(Seed004Config {
            speed_mps: self.speed_mps,
            cv_variance: self.filters.cv_variance,
            ca_variance: self.filters.ca_variance,
            detector,
            tdoa,
            calibration_points: self.filters.calibration_points,
            odometer,
            odometry_model,
            estimate_heading_drift: self.filters.estimate_heading_drift,
        })
    }
}
