//! Seed 000's Table 1: the file `000-table-1.toml` (the printed numbers, validated) and its
//! re-evaluation: per-axis mean error rates of
//! the RSSI, DV-Hop and ME-KF columns over the intact rows, our re-run of the ME-KF (paper
//! settings) on the printed RSSI column, and what a PEL of 6.7 % implies about the sample
//! count.

use nalgebra::DVector;
use rtls_estimation::filter::{CovarianceUpdate, KalmanFilter};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};

use serde::Deserialize;

use super::super::{parse_scenario, ScenarioSource};
use super::scenario::{check, check_finite, invalid};
use crate::error::{Result, SimError};
use crate::report::Table;
use crate::reproduction::seed_000::{MekfConfig, TrackerPrior};
use rtls_sim::metrics::{empty_location_percentage, error_rate, mean_axis_error_rates};
use rtls_sim::sensors::readers::distance_m;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TableFile {
    kf: TableKfSection,
    pel: PelSection,
    rows: Vec<TableRow>,
    #[serde(default)]
    excluded: Vec<Exclusion>,
    #[serde(default)]
    flagged: Vec<Flag>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TableKfSection {
    period_s: f64,
    process_variance: f64,
    measurement_variance: f64,
    initial_time_s: f64,
    initial_position_m: [f64; 3],
    initial_velocity_mps: [f64; 3],
    initial_position_variance_m2: f64,
    initial_velocity_variance_m2s2: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PelSection {
    paper_percent: f64,
}

/// One printed row of Table 1: cells as printed (absent when blank).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableRow {
    /// Time, s.
    pub time_s: f64,
    /// Actual coordinate, m.
    pub actual: [f64; 3],
    /// RSSI cell, as printed.
    pub rssi: Option<Vec<f64>>,
    /// DV-Hop cell, as printed.
    pub dv_hop: Option<Vec<f64>>,
    /// ME-KF cell, as printed.
    pub me_kf: Option<Vec<f64>>,
}

/// A row left out, and why.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Exclusion {
    /// The row's time, s.
    pub time_s: f64,
    /// Why.
    pub reason: String,
}

/// A suspicious cell that is kept, and why.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Flag {
    /// The row's time, s.
    pub time_s: f64,
    /// `rssi`, `dv_hop` or `me_kf`.
    pub column: String,
    /// Why.
    pub reason: String,
}

/// Table 1, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Table1 {
    /// Rows in time order.
    pub rows: Vec<TableRow>,
    /// Excluded rows.
    pub excluded: Vec<Exclusion>,
    /// Flagged cells.
    pub flagged: Vec<Flag>,
    /// The ME-KF we re-run on the RSSI column.
    pub kf: MekfConfig,
    /// Its period, s.
    pub period_s: f64,
    /// Its prior.
    pub prior: TrackerPrior,
    /// Its prior's time, s.
    pub initial_time_s: f64,
    /// The paper's PEL, %.
    pub paper_pel_percent: f64,
}

/// Parses and validates `000-table-1.toml`.
///
/// # Errors
/// [`SimError::Scenario`] naming the file and field: parse errors, unknown keys, a cell that is
/// not three numbers in a row that is not excluded, a zero actual coordinate (the error rate
/// divides by it), rows out of time order, exclusions or flags naming no row.
pub fn table_1(source: &ScenarioSource) -> Result<Table1> {
    let file = source.name.as_str();
    let raw: TableFile = parse_scenario(source)?;
    let k = &raw.kf;
    let period_s = check(file, "kf.period_s", k.period_s, false)?;
    let kf = MekfConfig {
        process_variance: check(file, "kf.process_variance", k.process_variance, false)?,
        measurement_variance: check(file, "kf.measurement_variance", k.measurement_variance, false)?,
    };
    check_finite(file, "kf.initial_time_s", &[k.initial_time_s])?;
    check_finite(file, "kf.initial_position_m", &k.initial_position_m)?;
    check_finite(file, "kf.initial_velocity_mps", &k.initial_velocity_mps)?;
    let prior = TrackerPrior {
        position_m: k.initial_position_m,
        velocity_mps: k.initial_velocity_mps,
        position_variance_m2: check(
            file,
            "kf.initial_position_variance_m2",
            k.initial_position_variance_m2,
            true,
        )?,
        velocity_variance_m2s2: check(
            file,
            "kf.initial_velocity_variance_m2s2",
            k.initial_velocity_variance_m2s2,
            true,
        )?,
    };
    let paper_pel_percent = check(file, "pel.paper_percent", raw.pel.paper_percent, true)?;
    if raw.rows.is_empty() {
        return Err(invalid(file, "`rows` must list at least one row".to_string()));
    }
    let is_excluded = |t: f64| raw.excluded.iter().any(|e| e.time_s == t);
    let mut previous_s = k.initial_time_s;
    for (i, row) in raw.rows.iter().enumerate() {
        check_finite(file, &format!("rows[{i}].time_s"), &[row.time_s])?;
        if row.time_s <= previous_s {
            return Err(invalid(
                file,
                format!("`rows[{i}].time_s` must increase and follow kf.initial_time_s"),
            ));
        }
        if (row.time_s - previous_s - period_s).abs() > 1e-9 {
            return Err(invalid(
                file,
                format!("`rows[{i}].time_s` must be one period (kf.period_s = {period_s} s) after the previous row"),
            ));
        }
        previous_s = row.time_s;
        check_finite(file, &format!("rows[{i}].actual"), &row.actual)?;
        if row.actual.contains(&0.0) {
            return Err(invalid(
                file,
                format!("`rows[{i}].actual` has a zero coordinate: the error rate |D − N|/N is undefined"),
            ));
        }
        for (column, cell) in [("rssi", &row.rssi), ("dv_hop", &row.dv_hop), ("me_kf", &row.me_kf)] {
            if let Some(values) = cell {
                check_finite(file, &format!("rows[{i}].{column}"), values)?;
            }
            let intact = cell.as_ref().is_some_and(|v| v.len() == 3);
            if !intact && !is_excluded(row.time_s) {
                return Err(invalid(
                    file,
                    format!(
                        "`rows[{i}].{column}` is not three numbers; list time_s = {} under [[excluded]] with a reason",
                        row.time_s
                    ),
                ));
            }
        }
    }
    let has_row = |t: f64| raw.rows.iter().any(|r| r.time_s == t);
    for (i, e) in raw.excluded.iter().enumerate() {
        if !has_row(e.time_s) {
            return Err(invalid(
                file,
                format!("`excluded[{i}].time_s` = {} names no row", e.time_s),
            ));
        }
    }
    for (i, f) in raw.flagged.iter().enumerate() {
        if !has_row(f.time_s) {
            return Err(invalid(
                file,
                format!("`flagged[{i}].time_s` = {} names no row", f.time_s),
            ));
        }
        if !["rssi", "dv_hop", "me_kf"].contains(&f.column.as_str()) {
            return Err(invalid(
                file,
                format!(
                    "`flagged[{i}].column` must be rssi, dv_hop or me_kf, got \"{}\"",
                    f.column
                ),
            ));
        }
    }
    Ok(Table1 {
        rows: raw.rows,
        excluded: raw.excluded,
        flagged: raw.flagged,
        kf,
        period_s,
        prior,
        initial_time_s: k.initial_time_s,
        paper_pel_percent,
    })
}

/// Largest sample count searched for the PEL's denominator.
const MAX_SAMPLES: usize = 1000;

/// Error rates of one column.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ColumnRates {
    /// Column name.
    pub(super) name: String,
    /// Mean error rate per axis over the intact rows (fraction).
    pub(super) rates: [f64; 3],
    /// The same without the flagged rows.
    pub(super) rates_unflagged: [f64; 3],
    /// 3-D RMSE over the intact rows, m.
    pub(super) rmse_m: f64,
    /// Mean signed x error `D − N` over the intact rows, m (negative: the column lags).
    pub(super) mean_x_error_m: f64,
    /// Intact rows whose x lies above the truth.
    pub(super) x_above_truth: usize,
}

/// Everything computed from Table 1.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Table1Evaluation {
    /// RSSI, DV-Hop, ME-KF (printed), our KF on the printed RSSI.
    pub(super) columns: Vec<ColumnRates>,
    /// RMS 3-D distance between our KF and the printed ME-KF column over the intact rows, m.
    pub(super) kf_vs_printed_m: f64,
    /// Rows used / printed.
    pub(super) intact_rows: usize,
    /// Rows printed.
    pub(super) rows: usize,
    /// PEL of the printed RSSI and DV-Hop columns (blank cells), %.
    pub(super) printed_pel_percent: [f64; 2],
    /// The PEL `k/n` closest to the paper's with `n` = the table's rows, %.
    pub(super) nearest_pel_percent: f64,
    /// The smallest `(k, n)` with `100 k/n` equal to the paper's PEL to its printed precision.
    pub(super) smallest_sample: Option<(usize, usize)>,
    /// Per column: `(t, x error rate %)` over the intact rows, for the figure.
    pub(super) x_rate_series: Vec<(String, Vec<[f64; 2]>)>,
}

/// Re-evaluates Table 1.
///
/// # Errors
/// [`SimError::Estimation`] if the KF fails; [`SimError::EmptyInput`] if no row is intact.
pub(super) fn evaluate(table: &Table1) -> Result<Table1Evaluation> {
    let excluded = |r: &TableRow| table.excluded.iter().any(|e| e.time_s == r.time_s);
    let flagged = |r: &TableRow| table.flagged.iter().any(|f| f.time_s == r.time_s);
    let kf = rerun_kf(table)?;
    let intact: Vec<usize> = (0..table.rows.len()).filter(|&i| !excluded(&table.rows[i])).collect();
    if intact.is_empty() {
        return Err(SimError::EmptyInput {
            what: "intact rows of Table 1",
        });
    }
    let cell = |v: &Option<Vec<f64>>| v.as_ref().and_then(|v| <[f64; 3]>::try_from(v.as_slice()).ok());
    let columns: [(&str, Vec<Option<[f64; 3]>>); 4] = [
        ("RSSI (printed)", table.rows.iter().map(|r| cell(&r.rssi)).collect()),
        ("DV-Hop (printed)", table.rows.iter().map(|r| cell(&r.dv_hop)).collect()),
        ("ME-KF (printed)", table.rows.iter().map(|r| cell(&r.me_kf)).collect()),
        (
            "our KF on the printed RSSI (Q = R = 5)",
            kf.iter().map(|p| Some(*p)).collect(),
        ),
    ];
    let mut rates = Vec::with_capacity(columns.len());
    let mut x_rate_series = Vec::with_capacity(columns.len());
    for (name, values) in &columns {
        let pick = |rows: &[usize]| -> (Vec<[f64; 3]>, Vec<Option<[f64; 3]>>) {
            rows.iter().map(|&i| (table.rows[i].actual, values[i])).unzip()
        };
        let (truth, located) = pick(&intact);
        let unflagged_rows: Vec<usize> = intact.iter().copied().filter(|&i| !flagged(&table.rows[i])).collect();
        let (truth_u, located_u) = pick(&unflagged_rows);
        let (mut squared, mut signed_x, mut above) = (0.0, 0.0, 0usize);
        let mut series = Vec::with_capacity(truth.len());
        for (&i, (n, d)) in intact.iter().zip(truth.iter().zip(&located)) {
            let d = d.ok_or(SimError::EmptyInput {
                what: "cell of an intact Table 1 row",
            })?;
            squared += distance_m(*n, d).powi(2);
            signed_x += d[0] - n[0];
            above += usize::from(d[0] > n[0]);
            series.push([table.rows[i].time_s, 100.0 * error_rate(n[0], Some(d[0]))?]);
        }
        rates.push(ColumnRates {
            name: (*name).to_string(),
            rates: mean_axis_error_rates(&truth, &located)?,
            rates_unflagged: mean_axis_error_rates(&truth_u, &located_u)?,
            rmse_m: (squared / truth.len() as f64).sqrt(),
            mean_x_error_m: signed_x / truth.len() as f64,
            x_above_truth: above,
        });
        x_rate_series.push(((*name).to_string(), series));
    }
    // RMS distance between our KF and the printed ME-KF on the intact rows
    let mut squared = 0.0;
    for &i in &intact {
        if let Some(printed) = cell(&table.rows[i].me_kf) {
            squared += distance_m(printed, kf[i]).powi(2);
        }
    }
    let n = table.rows.len();
    let printed_pel_percent = [
        empty_location_percentage(&table.rows.iter().map(|r| r.rssi.as_ref()).collect::<Vec<_>>())?,
        empty_location_percentage(&table.rows.iter().map(|r| r.dv_hop.as_ref()).collect::<Vec<_>>())?,
    ];
    // k = round(PEL n / 100): the closest PEL a table of n rows can show
    let k = (table.paper_pel_percent * n as f64 / 100.0).round();
    Ok(Table1Evaluation {
        columns: rates,
        kf_vs_printed_m: (squared / intact.len() as f64).sqrt(),
        intact_rows: intact.len(),
        rows: n,
        printed_pel_percent,
        nearest_pel_percent: 100.0 * k / n as f64,
        smallest_sample: smallest_sample(table.paper_pel_percent),
        x_rate_series,
    })
}

/// The ME-KF of the paper on the printed RSSI column: CV, `Q = σ_w² I₃` through `C`,
/// `R = σ_v² I₃`, from the file's prior; a row without a 3-number RSSI cell is a
/// predict-only step. Returns the position after each row.
fn rerun_kf(table: &Table1) -> Result<Vec<[f64; 3]>> {
    let t0 = table.initial_time_s;
    let estimation = SimError::estimation(t0);
    let motion = ConstantVelocity::new(ProcessNoise::discrete(
        table.kf.process_variance,
        NoiseGain::kinematic(),
    ))
    .map_err(estimation)?;
    let noise = NoiseCovariance::isotropic(3, table.kf.measurement_variance).map_err(SimError::estimation(t0))?;
    let fix = ComponentSelection::<6>::position(3, noise).map_err(SimError::estimation(t0))?;
    let kf = KalmanFilter::new(CovarianceUpdate::Simple);
    let mut state = table.prior.gaussian(t0)?;
    let mut out = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        // X⁻ = A X, P⁻ = A P Aᵀ + C Q Cᵀ
        let prior = kf
            .predict(&state, &motion, row.time_s)
            .map_err(SimError::estimation(row.time_s))?;
        state = match row.rssi.as_deref() {
            Some(z @ [_, _, _]) => {
                // K = P⁻ Hᵀ (H P⁻ Hᵀ + R)⁻¹, X = X⁻ + K (Z − H X⁻), P = (I − K H) P⁻
                kf.update(&prior, &fix, &DVector::from_column_slice(z))
                    .map_err(SimError::estimation(row.time_s))?
                    .state
            }
            _ => prior,
        };
        let m = state.mean();
        out.push([m[0], m[2], m[4]]);
    }
    Ok(out)
}

/// The smallest `(k, n)`, `n ≤ 1000`, with `100 k / n` equal to `percent` at its printed
/// precision (one decimal).
fn smallest_sample(percent: f64) -> Option<(usize, usize)> {
    (1..=MAX_SAMPLES).find_map(|n| {
        let k = (percent * n as f64 / 100.0).round();
        ((100.0 * k / n as f64 - percent).abs() < 0.05).then_some((k as usize, n))
    })
}

/// The report tables of Table 1: error rates per column, and the excluded and flagged rows.
pub(super) fn tables(table: &Table1, evaluation: &Table1Evaluation) -> Vec<Table> {
    let pct = |v: f64| format!("{:.1}", 100.0 * v);
    let rows = evaluation
        .columns
        .iter()
        .map(|c| {
            vec![
                c.name.clone(),
                pct(c.rates[0]),
                pct(c.rates[1]),
                pct(c.rates[2]),
                format!("{:.2}", c.rmse_m),
                format!("{:+.2}", c.mean_x_error_m),
                pct(c.rates_unflagged[0]),
                pct(c.rates_unflagged[1]),
            ]
        })
        .collect();
    let rates = Table {
        title: format!(
            "Table 1 re-evaluated from its printed numbers: mean error rate |D − N|/N per axis (%) and 3-D RMSE over the {} intact rows of {}, and the x and y rates without the flagged rows",
            evaluation.intact_rows, evaluation.rows
        ),
        header: [
            "column",
            "x (%)",
            "y (%)",
            "z (%)",
            "3-D RMSE (m)",
            "mean x error (m)",
            "x, unflagged (%)",
            "y, unflagged (%)",
        ]
            .map(String::from)
            .to_vec(),
        rows,
    };
    let mut notes = Vec::new();
    for e in &table.excluded {
        notes.push(vec![
            format!("{}", e.time_s),
            "excluded (all columns)".to_string(),
            e.reason.clone(),
        ]);
    }
    for f in &table.flagged {
        notes.push(vec![
            format!("{}", f.time_s),
            format!("flagged, kept ({})", f.column),
            f.reason.clone(),
        ]);
    }
    let listing = Table {
        title: "Table 1 rows excluded or flagged, and why".to_string(),
        header: ["time (s)", "status", "reason"].map(String::from).to_vec(),
        rows: notes,
    };
    vec![rates, listing]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pel_of_6_7_percent_needs_15_samples() {
        assert_eq!(smallest_sample(6.7), Some((1, 15)));
        assert_eq!(smallest_sample(5.0), Some((1, 20)));
        assert_eq!(smallest_sample(0.0), Some((0, 1)));
    }
}
