//! The scenario files of `ukf-uwb` (`001-cv.toml`, `001-turn.toml`): serde types with
//! `deny_unknown_fields`, validation naming the file and the field, and conversion into the
//! typed [`Seed001Config`].

use rtls_estimation::filter::SigmaPointParameters;
use rtls_estimation::measurement::{BreakpointForm, BreakpointPathLoss};
use serde::Deserialize;

use super::super::{parse_scenario, ScenarioSource};
use crate::error::{Result, SimError};
use crate::reproduction::seed_001::{Seed001Config, Seed001Nlos};
use rtls_sim::scenarios::seed_001::{Seed001Motion, Seed001Truth};
use rtls_sim::sensors::uwb::NlosBias;

/// One scenario file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    site: SiteFile,
    truth: TruthFile,
    toa: ToaFile,
    rss: RssFile,
    filters: FiltersFile,
    report: ReportFile,
    nlos: Option<NlosFile>,
    #[serde(default)]
    variants: Vec<VariantFile>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SiteFile {
    stations_m: Vec<[f64; 2]>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum MotionKind {
    ConstantVelocity,
    CoordinatedTurn,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct TruthFile {
    motion: MotionKind,
    turn_rate_rad_s: Option<f64>,
    initial_state: [f64; 4],
    duration_s: f64,
    step_s: f64,
    process_noise_std_mps2: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToaFile {
    range_std_m: f64,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum FormFile {
    Continuous,
    AsPrinted,
}

impl From<FormFile> for BreakpointForm {
    fn from(form: FormFile) -> Self {
        match form {
            FormFile::Continuous => Self::Continuous,
            FormFile::AsPrinted => Self::AsPrinted,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RssFile {
    reference_loss_db: f64,
    reference_distance_m: f64,
    exponent: f64,
    breakpoint_m: f64,
    form: FormFile,
    shadowing_std_db: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct FiltersFile {
    alpha: f64,
    beta: f64,
    kappa: f64,
    initial_position_std_m: f64,
    initial_velocity_std_mps: f64,
    turn_rate_prior_std_rad_s: f64,
    turn_rate_noise_std_rad_s2: f64,
    imm_sojourn_s: [f64; 2],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReportFile {
    converged_after_s: f64,
    lost_track_error_m: f64,
    x_error_threshold_m: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct NlosFile {
    probability: f64,
    mean_bias_m: f64,
    gate_probability: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct VariantFile {
    name: String,
    form: Option<FormFile>,
    alpha: Option<f64>,
    range_std_m: Option<f64>,
    shadowing_std_db: Option<f64>,
    process_noise_std_mps2: Option<f64>,
    initial_position_std_m: Option<f64>,
}

/// What the report needs besides the simulation: when the filters count as converged, what a
/// lost track is, and the paper's x-error threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ReportSettings {
    /// Epochs with `t > converged_after_s` enter the per-epoch min/max and the pooled RMSE, s.
    pub(super) converged_after_s: f64,
    /// A run whose last position error exceeds this has lost the track, m.
    pub(super) lost_track_error_m: f64,
    /// The paper's "x error mostly within 0.25 m", m.
    pub(super) x_error_threshold_m: f64,
}

/// A variant of the base scenario for the UKF-versus-EKF exploration.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Variant {
    /// Its name in the table.
    pub(super) name: String,
    /// What it changes, e.g. "σ = 1 m, σ_s = 6 dB".
    pub(super) change: String,
    /// The full configuration.
    pub(super) config: Seed001Config,
}

/// A parsed, validated scenario file.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Scenario {
    /// The simulation.
    pub(super) config: Seed001Config,
    /// Reporting settings.
    pub(super) report: ReportSettings,
    /// Variants (only `001-cv.toml` has them).
    pub(super) variants: Vec<Variant>,
}

/// Reads `source` as a seed 001 scenario.
///
/// # Errors
/// [`SimError::Scenario`] naming the file and the field for an unknown key, a missing or
/// mistyped value, or a value outside its range.
pub(super) fn parse(source: &ScenarioSource) -> Result<Scenario> {
    let file: ScenarioFile = parse_scenario(source)?;
    let check = Check { file: &source.name };
    let config = base_config(&file, &check)?;
    let report = ReportSettings {
        converged_after_s: check.non_negative(file.report.converged_after_s, "report.converged_after_s")?,
        lost_track_error_m: check.positive(file.report.lost_track_error_m, "report.lost_track_error_m")?,
        x_error_threshold_m: check.positive(file.report.x_error_threshold_m, "report.x_error_threshold_m")?,
    };
    if report.converged_after_s >= config.truth.duration_s {
        return Err(check.error(
            "report.converged_after_s",
            "must be shorter than truth.duration_s (no epoch would be evaluated)",
        ));
    }
    let variants = file
        .variants
        .iter()
        .enumerate()
        .map(|(i, v)| variant(&config, v, i, &check))
        .collect::<Result<Vec<_>>>()?;
    Ok(Scenario {
        config,
        report,
        variants,
    })
}

/// The base configuration of a file, every field checked.
fn base_config(file: &ScenarioFile, check: &Check<'_>) -> Result<Seed001Config> {
    if file.site.stations_m.len() < 2 {
        return Err(check.error("site.stations_m", "needs at least two base stations"));
    }
    for s in &file.site.stations_m {
        check.finite(s[0], "site.stations_m")?;
        check.finite(s[1], "site.stations_m")?;
    }
    let t = &file.truth;
    let motion = match (t.motion, t.turn_rate_rad_s) {
        (MotionKind::ConstantVelocity, None) => Seed001Motion::ConstantVelocity,
        (MotionKind::ConstantVelocity, Some(_)) => {
            return Err(check.error(
                "truth.turn_rate_rad_s",
                "only a coordinated-turn motion has a turn rate",
            ))
        }
        (MotionKind::CoordinatedTurn, Some(rate)) => {
            check.finite(rate, "truth.turn_rate_rad_s")?;
            if rate == 0.0 {
                return Err(check.error("truth.turn_rate_rad_s", "must not be 0 (use constant-velocity)"));
            }
            Seed001Motion::CoordinatedTurn { turn_rate_rad_s: rate }
        }
        (MotionKind::CoordinatedTurn, None) => {
            return Err(check.error("truth.turn_rate_rad_s", "a coordinated-turn motion needs a turn rate"))
        }
    };
    for v in t.initial_state {
        check.finite(v, "truth.initial_state")?;
    }
    let truth = Seed001Truth {
        motion,
        initial_state: t.initial_state,
        duration_s: check.positive(t.duration_s, "truth.duration_s")?,
        step_s: check.positive(t.step_s, "truth.step_s")?,
        process_noise_std_mps2: check.non_negative(t.process_noise_std_mps2, "truth.process_noise_std_mps2")?,
    };
    truth
        .validate()
        .map_err(|e| check.error("truth.duration_s", &e.to_string()))?;
    let r = &file.rss;
    let rss_law = BreakpointPathLoss::new(
        check.finite(r.reference_loss_db, "rss.reference_loss_db")?,
        check.positive(r.reference_distance_m, "rss.reference_distance_m")?,
        check.positive(r.exponent, "rss.exponent")?,
        check.positive(r.breakpoint_m, "rss.breakpoint_m")?,
        r.form.into(),
    )
    .map_err(|e| check.error("rss.breakpoint_m", &e.to_string()))?;
    let f = &file.filters;
    let sigma_points = SigmaPointParameters::new(
        check.positive(f.alpha, "filters.alpha")?,
        check.finite(f.beta, "filters.beta")?,
        check.finite(f.kappa, "filters.kappa")?,
    )
    .map_err(|e| check.error("filters.alpha", &e.to_string()))?;
    if sigma_points.weights(4).is_err() || sigma_points.weights(5).is_err() {
        return Err(check.error("filters.kappa", "n + λ must be positive for the 4- and 5-state filters"));
    }
    for s in f.imm_sojourn_s {
        check.positive(s, "filters.imm_sojourn_s")?;
    }
    let nlos = match &file.nlos {
        Some(n) => Some(Seed001Nlos {
            bias: NlosBias::new(check.probability(n.probability, "nlos.probability", true)?, {
                check.positive(n.mean_bias_m, "nlos.mean_bias_m")?
            })?,
            gate_probability: check.probability(n.gate_probability, "nlos.gate_probability", false)?,
        }),
        None => None,
    };
    let config = Seed001Config {
        truth,
        stations_m: file.site.stations_m.clone(),
        range_std_m: check.positive(file.toa.range_std_m, "toa.range_std_m")?,
        rss_law,
        shadowing_std_db: check.positive(r.shadowing_std_db, "rss.shadowing_std_db")?,
        sigma_points,
        initial_position_std_m: check.positive(f.initial_position_std_m, "filters.initial_position_std_m")?,
        initial_velocity_std_mps: check.positive(f.initial_velocity_std_mps, "filters.initial_velocity_std_mps")?,
        turn_rate_prior_std_rad_s: check.positive(f.turn_rate_prior_std_rad_s, "filters.turn_rate_prior_std_rad_s")?,
        turn_rate_noise_std_rad_s2: check
            .non_negative(f.turn_rate_noise_std_rad_s2, "filters.turn_rate_noise_std_rad_s2")?,
        imm_sojourn_s: f.imm_sojourn_s,
        nlos,
    };
    // the simulation's own checks, as a last line (the fields were checked above)
    config
        .validate()
        .map_err(|e| check.error("(scenario)", &e.to_string()))?;
    Ok(config)
}

/// Variant `index` of the base: the base with the fields the variant sets replaced, and no
/// NLOS (the exploration is about the line-of-sight comparison).
fn variant(base: &Seed001Config, v: &VariantFile, index: usize, check: &Check<'_>) -> Result<Variant> {
    let field = |name: &str| format!("variants[{index}].{name}");
    if v.name.trim().is_empty() {
        return Err(check.error(&field("name"), "must not be empty"));
    }
    let mut config = base.clone();
    config.nlos = None;
    let mut changes = Vec::new();
    if let Some(form) = v.form {
        let law = &base.rss_law;
        config.rss_law = BreakpointPathLoss::new(
            law.p0_db(),
            law.reference_distance_m(),
            law.exponent(),
            law.breakpoint_m(),
            form.into(),
        )
        .map_err(|e| check.error(&field("form"), &e.to_string()))?;
        changes.push(match form {
            FormFile::Continuous => "continuous RSS law".to_string(),
            FormFile::AsPrinted => "RSS law as printed, with its jump at the breakpoint".to_string(),
        });
    }
    if let Some(alpha) = v.alpha {
        let alpha = check.positive(alpha, &field("alpha"))?;
        config.sigma_points = SigmaPointParameters::new(alpha, base.sigma_points.beta, base.sigma_points.kappa)
            .map_err(|e| check.error(&field("alpha"), &e.to_string()))?;
        changes.push(format!("α = {alpha}"));
    }
    if let Some(sigma) = v.range_std_m {
        config.range_std_m = check.positive(sigma, &field("range_std_m"))?;
        changes.push(format!("σ = {sigma} m"));
    }
    if let Some(shadowing) = v.shadowing_std_db {
        config.shadowing_std_db = check.positive(shadowing, &field("shadowing_std_db"))?;
        changes.push(format!("σ_s = {shadowing} dB"));
    }
    if let Some(q) = v.process_noise_std_mps2 {
        config.truth.process_noise_std_mps2 = check.non_negative(q, &field("process_noise_std_mps2"))?;
        changes.push(format!("σ_ω = {q} m/s²"));
    }
    if let Some(p0) = v.initial_position_std_m {
        config.initial_position_std_m = check.positive(p0, &field("initial_position_std_m"))?;
        changes.push(format!("P₀ position σ = {p0} m"));
    }
    if changes.is_empty() {
        return Err(check.error(&field("name"), "a variant must change at least one setting"));
    }
    config
        .validate()
        .map_err(|e| check.error(&field("name"), &e.to_string()))?;
    Ok(Variant {
        name: v.name.clone(),
        change: changes.join(", "),
        config,
    })
}

/// Field checks that name the file and the field.
struct Check<'a> {
    file: &'a str,
}

impl Check<'_> {
    fn error(&self, field: &str, reason: &str) -> SimError {
        SimError::Scenario {
            file: self.file.to_string(),
            reason: format!("field `{field}`: {reason}"),
        }
    }

    fn finite(&self, value: f64, field: &str) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(field, "must be a finite number"))
        }
    }

    fn positive(&self, value: f64, field: &str) -> Result<f64> {
        if self.finite(value, field)? > 0.0 {
            Ok(value)
        } else {
            Err(self.error(field, &format!("must be positive (found {value})")))
        }
    }

    fn non_negative(&self, value: f64, field: &str) -> Result<f64> {
        if self.finite(value, field)? >= 0.0 {
            Ok(value)
        } else {
            Err(self.error(field, &format!("must not be negative (found {value})")))
        }
    }

    /// A probability in `[0, 1]` (`closed`) or `(0, 1)`.
    fn probability(&self, value: f64, field: &str, closed: bool) -> Result<f64> {
        let v = self.finite(value, field)?;
        let inside = if closed {
            (0.0..=1.0).contains(&v)
        } else {
            v > 0.0 && v < 1.0
        };
        if inside {
            Ok(v)
        } else if closed {
            Err(self.error(field, &format!("must lie in [0, 1] (found {value})")))
        } else {
            Err(self.error(field, &format!("must lie strictly between 0 and 1 (found {value})")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::ExperimentId;

    fn sources() -> Vec<ScenarioSource> {
        ExperimentId::UkfUwb.embedded_scenarios()
    }

    #[test]
    fn the_shipped_files_parse() {
        let sources = sources();
        let cv = parse(&sources[0]).unwrap();
        assert!(cv.config.nlos.is_some());
        assert!(!cv.variants.is_empty());
        assert_eq!(cv.config.stations_m, vec![[2.0, 2.0], [20.0, 40.0]]);
        let turn = parse(&sources[1]).unwrap();
        assert!(matches!(
            turn.config.truth.motion,
            Seed001Motion::CoordinatedTurn { .. }
        ));
    }

    #[test]
    fn the_documented_defaults_are_the_shipped_values() {
        let mut cv = parse(&sources()[0]).unwrap().config;
        cv.nlos = None;
        assert_eq!(cv, Seed001Config::new(cv.truth).unwrap());
        let turn = parse(&sources()[1]).unwrap().config;
        assert_eq!(turn, Seed001Config::new(turn.truth).unwrap());
        assert_eq!(turn.truth.process_noise_std_mps2, cv.truth.process_noise_std_mps2);
    }

    #[test]
    fn bad_values_name_the_file_and_the_field() {
        let base = sources()[0].clone();
        let cases = [
            ("range_std_m = 0.2", "range_std_m = -0.2", "toa.range_std_m"),
            ("probability = 0.2", "probability = 1.2", "nlos.probability"),
            ("alpha = 0.01", "alpha = 0.0", "filters.alpha"),
            (
                "motion = \"constant-velocity\"",
                "motion = \"constant-velocity\"\nturn_rate_rad_s = 0.1",
                "truth.turn_rate_rad_s",
            ),
        ];
        for (from, to, field) in cases {
            assert!(base.text.contains(from), "{from}");
            let bad = ScenarioSource {
                name: base.name.clone(),
                text: base.text.replacen(from, to, 1),
            };
            let err = parse(&bad).unwrap_err().to_string();
            assert!(err.contains("001-cv.toml") && err.contains(field), "{err}");
        }
    }
}
