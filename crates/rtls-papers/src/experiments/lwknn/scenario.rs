//! The four seed 002 scenario files and their conversion into [`Seed002Config`]s.

use rtls_positioning::fingerprint::{Knn, LocalWknn};
use serde::Deserialize;

use crate::error::{Result, SimError};
use crate::reproduction::{Seed002Config, Seed002Trajectory};
use rtls_sim::scenarios::GridSite;
use rtls_sim::sensors::{AccelerometerNoise, LogDistanceRadio};

pub(super) const FIELD: &str = "002-field.toml";
pub(super) const TABLE_2: &str = "002-table-2.toml";
pub(super) const NOISE_SWEEP: &str = "002-noise-sweep.toml";
pub(super) const MODEL_ORDER: &str = "002-model-order.toml";

/// `trajectory = "tracking" | "manoeuvre-then-cruise"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrajectoryName {
    /// Fig. 1: 100 samples.
    Tracking,
    /// Fig. 5–6: 80 samples.
    ManoeuvreThenCruise,
}

impl From<TrajectoryName> for Seed002Trajectory {
    fn from(name: TrajectoryName) -> Self {
        match name {
            TrajectoryName::Tracking => Self::Tracking,
            TrajectoryName::ManoeuvreThenCruise => Self::ManoeuvreThenCruise,
        }
    }
}

/// `[accelerometer]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum AccelerometerSection {
    /// White noise of a fixed std, m/s².
    Absolute {
        /// Std, m/s².
        std_mps2: f64,
    },
    /// White noise proportional to the reading.
    Proportional {
        /// Std as a fraction of the reading.
        fraction: f64,
    },
}

impl From<AccelerometerSection> for AccelerometerNoise {
    fn from(section: AccelerometerSection) -> Self {
        match section {
            AccelerometerSection::Absolute { std_mps2 } => Self::Absolute { std_mps2 },
            AccelerometerSection::Proportional { fraction } => Self::ProportionalToReading { fraction },
        }
    }
}

/// `[site]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSection {
    /// Field width, m.
    pub width_m: f64,
    /// Field height, m.
    pub height_m: f64,
    /// Anchor grid spacing, m.
    pub anchor_spacing_m: f64,
    /// Reference-point grid spacing, m.
    pub reference_spacing_m: f64,
}

/// `[radio]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadioSection {
    /// `ρ_T`, dBm at 1 m.
    pub reference_power_dbm: f64,
    /// `η`.
    pub exponent: f64,
    /// Distance clamp, m.
    pub min_distance_m: f64,
}

/// `[locator]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocatorSection {
    /// `N_k`.
    pub strongest_anchors: usize,
    /// Candidate radius, m.
    pub radius_m: f64,
    /// `n`.
    pub neighbours: usize,
}

impl LocatorSection {
    pub(super) fn locator(&self) -> LocalWknn {
        LocalWknn {
            strongest_anchors: self.strongest_anchors,
            radius_m: self.radius_m,
            knn: Knn::wknn(self.neighbours),
        }
    }
}

/// `[paper]` of `002-field.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldPaper {
    /// L-WKNN mean error bound quoted ("below"), m.
    pub lwknn_mean_error_m: f64,
    /// Second-order KF mean error, m.
    pub second_order_mean_error_m: f64,
    /// 90th percentile of the error "with this algorithm" (read as the tracked output), m.
    pub p90_error_m: f64,
    /// Share of epochs where L-WKNN and WKNN agree, %.
    pub same_neighbours_percent: f64,
}

/// `002-field.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldScenario {
    /// Which trajectory.
    pub trajectory: TrajectoryName,
    /// `σ_p²`, dB².
    pub rssi_variance_db2: f64,
    /// `σ²` of the survey, dB².
    pub fingerprint_variance_db2: f64,
    /// `U`, m².
    pub fix_variance_m2: [f64; 2],
    /// Textbook model's extra white acceleration, (m/s²)².
    pub textbook_extra_variance_m2ps4: f64,
    /// The field.
    pub site: SiteSection,
    /// The radio.
    pub radio: RadioSection,
    /// L-WKNN.
    pub locator: LocatorSection,
    /// The accelerometer.
    pub accelerometer: AccelerometerSection,
    /// The paper's figures.
    pub paper: FieldPaper,
}

/// One column of Table 2.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table2Row {
    /// `N_k`.
    pub strongest_anchors: usize,
    /// Radius, m.
    pub radius_m: f64,
    /// `n`.
    pub neighbours: usize,
    /// The paper's `e`, m.
    pub paper_mean_error_m: f64,
    /// The paper's `σ_MSE`, m.
    pub paper_std_m: f64,
}

/// `002-table-2.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table2Scenario {
    /// The columns of Table 2.
    pub rows: Vec<Table2Row>,
}

/// `002-noise-sweep.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseSweepScenario {
    /// The `σ_p²` values, dB².
    pub rssi_variance_db2: Vec<f64>,
    /// The paper's second-order error at every swept noise, m.
    pub paper_second_order_mean_error_m: f64,
}

/// `[paper]` of `002-model-order.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelOrderPaper {
    /// First-order mean error, m.
    pub first_order_mean_error_m: f64,
    /// Second-order mean error, m.
    pub second_order_mean_error_m: f64,
}

/// `002-model-order.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelOrderScenario {
    /// Which trajectory.
    pub trajectory: TrajectoryName,
    /// The accelerometer.
    pub accelerometer: AccelerometerSection,
    /// The paper's figures.
    pub paper: ModelOrderPaper,
}

pub(super) fn scenario_error(file: &str, field: &str, reason: impl std::fmt::Display) -> SimError {
    SimError::Scenario {
        file: file.to_string(),
        reason: format!("{field}: {reason}"),
    }
}

fn check_positive(file: &str, field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(scenario_error(file, field, "must be a finite number > 0"))
    }
}

/// Checks a locator's parameters.
pub(super) fn check_locator(file: &str, field: &str, strongest: usize, radius_m: f64, neighbours: usize) -> Result<()> {
    if strongest == 0 || neighbours == 0 {
        return Err(scenario_error(
            file,
            field,
            "strongest_anchors and neighbours must be at least 1",
        ));
    }
    check_positive(file, &format!("{field} radius_m"), radius_m)
}

/// Checks an accelerometer section.
pub(super) fn check_accelerometer(file: &str, section: AccelerometerSection) -> Result<()> {
    match section {
        AccelerometerSection::Absolute { std_mps2 } if std_mps2.is_finite() && std_mps2 >= 0.0 => Ok(()),
        AccelerometerSection::Proportional { fraction } if fraction.is_finite() && fraction >= 0.0 => Ok(()),
        _ => Err(scenario_error(
            file,
            "[accelerometer]",
            "the noise must be a finite number ≥ 0",
        )),
    }
}

impl FieldScenario {
    /// The base configuration, every value checked.
    ///
    /// # Errors
    /// [`SimError::Scenario`] naming the field that is out of range.
    pub fn config(&self) -> Result<Seed002Config> {
        check_positive(FIELD, "rssi_variance_db2", self.rssi_variance_db2)?;
        check_positive(FIELD, "fingerprint_variance_db2", self.fingerprint_variance_db2)?;
        check_positive(FIELD, "fix_variance_m2[0]", self.fix_variance_m2[0])?;
        check_positive(FIELD, "fix_variance_m2[1]", self.fix_variance_m2[1])?;
        if !(self.textbook_extra_variance_m2ps4.is_finite() && self.textbook_extra_variance_m2ps4 >= 0.0) {
            return Err(scenario_error(
                FIELD,
                "textbook_extra_variance_m2ps4",
                "must be finite and ≥ 0",
            ));
        }
        check_positive(FIELD, "[radio] exponent", self.radio.exponent)?;
        check_positive(FIELD, "[radio] min_distance_m", self.radio.min_distance_m)?;
        if !self.radio.reference_power_dbm.is_finite() {
            return Err(scenario_error(FIELD, "[radio] reference_power_dbm", "must be finite"));
        }
        check_locator(
            FIELD,
            "[locator]",
            self.locator.strongest_anchors,
            self.locator.radius_m,
            self.locator.neighbours,
        )?;
        check_accelerometer(FIELD, self.accelerometer)?;
        let site = GridSite {
            width_m: self.site.width_m,
            height_m: self.site.height_m,
            anchor_spacing_m: self.site.anchor_spacing_m,
            reference_spacing_m: self.site.reference_spacing_m,
            sensitivity_dbm: GridSite::seed_002().sensitivity_dbm,
            radio: LogDistanceRadio {
                reference_power_dbm: self.radio.reference_power_dbm,
                exponent: self.radio.exponent,
                min_distance_m: self.radio.min_distance_m,
            },
        };
        site.validate().map_err(|e| scenario_error(FIELD, "[site]", e))?;
        Ok(Seed002Config {
            trajectory: self.trajectory.into(),
            rssi_variance_db2: self.rssi_variance_db2,
            fingerprint_variance_db2: self.fingerprint_variance_db2,
            locator: self.locator.locator(),
            fix_variance_m2: self.fix_variance_m2,
            accelerometer: self.accelerometer.into(),
            textbook_extra_variance_m2ps4: self.textbook_extra_variance_m2ps4,
            site,
        })
    }
}
