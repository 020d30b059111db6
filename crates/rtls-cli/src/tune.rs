//! `rtls tune`: fits a site's noise and model settings to a recording and writes a tuned site.
//!
//! ```text
//! rtls tune --site SITE --input FILE --out TUNED.toml [--truth TRUTH.csv] [--until-s T]
//!           [--grid 0.1,0.2,0.5] [--json]
//! ```
//!
//! Without `--truth` the white-acceleration noise `σ_a` is chosen by the innovation
//! log-likelihood and each reader's range / RSSI noise grows by the factor the adaptive noise
//! found (`rtls_engine::tuning`); with it, every reader's range bias and noise and log-distance
//! law are fitted to the truth and `σ_a` minimises the RMSE. Only records up to `--until-s`
//! are used, so the rest of the recording can score the tuned site honestly. The tuned site
//! keeps the input file's layout and comments (`toml_edit`); only the tuned values change.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use rtls_engine::evaluation::parse_truth_csv;
use rtls_engine::record::Record;
use rtls_engine::tracker::{NoiseClass, Tracker};
use rtls_engine::tuning::{tune, Tuning, TuningSettings};
use toml_edit::{value, DocumentMut, InlineTable, Item, TableLike, Value};

use crate::malformed::InputRecords;
use crate::track::{load_site_file, ModelOverrides};

/// Arguments of `rtls tune`.
#[derive(Debug, Args)]
pub struct TuneArgs {
    /// Site model to start from (TOML; see examples/site.toml).
    #[arg(long)]
    pub site: PathBuf,
    /// Measurement records of the recording: JSON Lines, or CSV if the name ends in `.csv`.
    #[arg(long)]
    pub input: PathBuf,
    /// The tuned site file to write (the input site with the tuned values).
    #[arg(long)]
    pub out: PathBuf,
    /// Ground truth (CSV `t,tag,x,y,z`): calibrate the readers on it and choose `σ_a` by RMSE.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Use only the records (and truth) up to this time, s: the calibration part.
    #[arg(long, value_name = "T")]
    pub until_s: Option<f64>,
    /// Candidate `σ_a` values, m/s², comma-separated (default: 0.02 to 10 in 14 steps).
    #[arg(long, value_delimiter = ',')]
    pub grid: Option<Vec<f64>>,
    /// Print the result as one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Stop at the first record that cannot be used as written; without it each is skipped
    /// and counted (as in `rtls track`).
    #[arg(long)]
    pub strict: bool,
    /// `--pipeline`, `--filter`, `--motion-model`: tune the site as it will be tracked (the
    /// same flags as `rtls track`); the overrides are written into the tuned site.
    #[command(flatten)]
    pub overrides: ModelOverrides,
}

/// Reads every record of `path`, checking reader ids against the site, keeping those at or
/// before `until_s`. A record that cannot be used as written is skipped and counted, as in
/// `rtls track` ([`InputRecords`]; `strict`: it stops the run, naming file, line and field).
fn read_records(path: &Path, tracker: &Tracker, until_s: f64, strict: bool) -> anyhow::Result<Vec<Record>> {
    let name = path.display().to_string();
    let file = BufReader::new(File::open(path).with_context(|| format!("opening {name}"))?);
    let csv = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let mut input = InputRecords::new(file, &name, csv, strict)?;
    let mut records = Vec::new();
    while let Some((record, line)) = input.next_record()? {
        match tracker.check_record(&record, &name, line) {
            Err(error) => input.refuse(error)?,
            Ok(()) if record.time_s <= until_s => records.push(record),
            Ok(()) => {}
        }
    }
    // no event file here: the summary line names the first few
    if let Some(line) = input.finish()? {
        eprintln!("{line}");
    }
    Ok(records)
}

/// Runs `rtls tune`.
///
/// # Errors
/// Unreadable or invalid inputs (naming file, line and field), an invalid `--until-s` or grid,
/// nothing to tune on, an unwritable output.
pub fn run(args: &TuneArgs) -> anyhow::Result<()> {
    let until_s = args.until_s.unwrap_or(f64::INFINITY);
    if until_s.is_nan() {
        bail!("--until-s must be a number of seconds");
    }
    let (mut site, radio_map) = load_site_file(&args.site)?;
    args.overrides.apply(&mut site)?;
    let tracker = Tracker::new(&site)?;
    let records = read_records(&args.input, &tracker, until_s, args.strict)?;
    if records.is_empty() {
        bail!(
            "{}: no record at or before --until-s {until_s} s: nothing to tune on",
            args.input.display()
        );
    }
    let truth = match &args.truth {
        Some(path) => {
            let name = path.display().to_string();
            let text = std::fs::read_to_string(path).with_context(|| format!("reading {name}"))?;
            let mut truth = parse_truth_csv(&text, &name)?;
            truth.retain(|s| s.time_s <= until_s);
            Some(truth)
        }
        None => None,
    };
    let mut settings = TuningSettings::default();
    if let Some(grid) = &args.grid {
        settings.acceleration_grid_mps2.clone_from(grid);
    }
    let tuning = tune(&site, radio_map.as_ref(), &records, truth.as_deref(), &settings)?;

    let site_name = args.site.display().to_string();
    let text = std::fs::read_to_string(&args.site).with_context(|| format!("reading {site_name}"))?;
    let mut tuned = tuned_site_text(&text, &site_name, &tuning, truth.is_some(), &args.input, until_s)?;
    tuned = with_overrides(&tuned, &args.overrides)?;
    // the tuned text must load as a site, or the file would be a trap
    rtls_engine::site::Site::from_toml_str(&tuned, &args.out.display().to_string())
        .context("the tuned site does not load (a bug: please report it)")?;
    std::fs::write(&args.out, tuned).with_context(|| format!("writing {}", args.out.display()))?;

    if args.json {
        println!("{}", serde_json::to_string(&json_report(&tuning, records.len()))?);
    } else {
        print!("{}", text_report(&tuning, records.len(), &args.out));
    }
    Ok(())
}

/// The site text with the tuned values written in.
fn tuned_site_text(
    text: &str,
    site_name: &str,
    tuning: &Tuning,
    calibrated: bool,
    input: &Path,
    until_s: f64,
) -> anyhow::Result<String> {
    let mut document: DocumentMut = text.parse().with_context(|| format!("parsing {site_name}"))?;
    let tracker = document
        .get_mut("tracker")
        .and_then(Item::as_table_like_mut)
        .with_context(|| format!("{site_name}: no [tracker] table"))?;
    tracker.insert(
        "acceleration_noise_std_mps2",
        value(round(tuning.acceleration_noise_std_mps2)),
    );
    // the error-correlation settings, where the tuning changed them
    let own = tuning.model.tried[0].0;
    let model = tuning.model.settings();
    if model.correlation_s != own.correlation_s {
        sub_table(tracker, "adaptive_noise").insert("correlation_s", value(model.correlation_s));
    }
    if model.correlation_from_innovations != own.correlation_from_innovations {
        sub_table(tracker, "adaptive_noise").insert(
            "correlation_from_innovations",
            value(model.correlation_from_innovations),
        );
    }
    if model.heading_error_correlation_s != own.heading_error_correlation_s {
        sub_table(tracker, "heading").insert("heading_error_correlation_s", value(model.heading_error_correlation_s));
    }
    let factor_of = |class: NoiseClass| {
        tuning
            .noise_std_factors
            .iter()
            .find(|(c, _)| *c == class)
            .map_or(1.0, |(_, f)| *f)
    };
    // RSSI readings are the `rssi` class tightly coupled and, solved into fixes (fix-then-filter),
    // the `rssi-fix` class, whose fixes' σ grows with the shadowing's: either scales it (a class
    // not seen has factor 1, and a recording is tracked by one pipeline)
    let range_factor = factor_of(NoiseClass::Range);
    let rssi_factor = factor_of(NoiseClass::Rssi).max(factor_of(NoiseClass::RssiFix));
    for_each_reader(&mut document, |id, reader| {
        let radio = sub_table(reader, "radio");
        if calibrated {
            let Some(fit) = tuning.readers.iter().find(|r| r.reader == id) else {
                return;
            };
            if let Some(range) = fit.range {
                let errors = sub_table(radio, "range");
                errors.insert("range_std_m", value(round(range.range_std_m)));
                errors.insert("bias_m", value(round(range.bias_m)));
                if let Some(offset_std_m) = range.offset_std_m {
                    errors.insert("offset_std_m", value(round(offset_std_m)));
                }
                if range.scale != 1.0 {
                    errors.insert("scale", value((range.scale * 1e6).round() / 1e6));
                }
            }
            if let Some(law) = fit.path_loss {
                let path_loss = sub_table(radio, "path_loss");
                path_loss.insert("reference_power_dbm", value(round(law.reference_power_dbm)));
                path_loss.insert("exponent", value(round(law.exponent)));
                path_loss.insert("shadowing_std_db", value(round(law.shadowing_std_db)));
                path_loss.insert("reference_distance_m", value(1.0));
            }
        } else {
            scale_existing(radio, "range", "range_std_m", range_factor);
            scale_existing(radio, "path_loss", "shadowing_std_db", rssi_factor);
        }
    });
    let how = if calibrated {
        if tuning.covariance.is_some() {
            "readers calibrated on the ground truth, σ_a by RMSE, noises widened for 95 % ellipses"
        } else {
            "readers calibrated on the ground truth, σ_a by RMSE"
        }
    } else {
        "σ_a by innovation likelihood, reader noise by the adaptive noise scale"
    };
    let window = if until_s.is_finite() {
        format!(" up to t = {until_s} s")
    } else {
        String::new()
    };
    Ok(format!(
        "# Tuned by `rtls tune` on {}{window} ({how}).\n{document}",
        input.display()
    ))
}

/// The tuned site text with the command line's `--pipeline`, `--filter` and `--motion-model`
/// written into `[tracker]`: the values were tuned for them.
fn with_overrides(text: &str, overrides: &ModelOverrides) -> anyhow::Result<String> {
    let names = [
        ("pipeline", overrides.pipeline.and_then(|v| v.to_possible_value())),
        ("filter", overrides.filter.and_then(|v| v.to_possible_value())),
        (
            "motion_model",
            overrides.motion_model.and_then(|v| v.to_possible_value()),
        ),
    ];
    if names.iter().all(|(_, v)| v.is_none()) {
        return Ok(text.to_string());
    }
    let mut document: DocumentMut = text.parse().context("parsing the tuned site")?;
    let tracker = document
        .get_mut("tracker")
        .and_then(Item::as_table_like_mut)
        .context("the tuned site has no [tracker] table")?;
    for (key, name) in names {
        if let Some(name) = name {
            tracker.insert(key, value(name.get_name()));
        }
    }
    Ok(document.to_string())
}

/// Four significant decimals are plenty for noise settings and keep the file readable.
fn round(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// Calls `f(id, reader)` for every reader of `readers`, whether written as `[[readers]]` tables
/// or as an inline array.
fn for_each_reader(document: &mut DocumentMut, mut f: impl FnMut(&str, &mut dyn TableLike)) {
    let Some(readers) = document.get_mut("readers") else {
        return;
    };
    let mut visit = |table: &mut dyn TableLike| {
        if let Some(id) = table.get("id").and_then(Item::as_str).map(str::to_string) {
            f(&id, table);
        }
    };
    match readers {
        Item::ArrayOfTables(tables) => tables.iter_mut().for_each(|t| visit(t)),
        Item::Value(Value::Array(array)) => array
            .iter_mut()
            .filter_map(Value::as_inline_table_mut)
            .for_each(|t| visit(t)),
        _ => {}
    }
}

/// `parent.key` as a table, created as an inline table when absent (valid in both table
/// styles).
fn sub_table<'a>(parent: &'a mut dyn TableLike, key: &str) -> &'a mut dyn TableLike {
    if parent.get(key).and_then(Item::as_table_like).is_none() {
        parent.insert(key, Item::Value(Value::InlineTable(InlineTable::new())));
    }
    parent
        .get_mut(key)
        .and_then(Item::as_table_like_mut)
        .expect("just inserted as a table")
}

/// Multiplies `radio.section.key` by `factor` where the site states it.
fn scale_existing(radio: &mut dyn TableLike, section: &str, key: &str, factor: f64) {
    if let Some(item) = radio
        .get_mut(section)
        .and_then(Item::as_table_like_mut)
        .and_then(|t| t.get_mut(key))
    {
        if let Some(stated) = item.as_float().or_else(|| item.as_integer().map(|i| i as f64)) {
            *item = value(round(stated * factor));
        }
    }
}

fn text_report(tuning: &Tuning, records: usize, out: &Path) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(text, "tuned on {records} records; candidates (σ_a m/s²):");
    let _ = writeln!(
        text,
        "  {:>8}  {:>14}  {:>8}  {:>8}  {:>7}  {:>8}",
        "σ_a", "log-likelihood", "updates", "RMSE m", "± SE", "in 95 %"
    );
    for (i, c) in tuning.candidates.iter().enumerate() {
        let _ = writeln!(
            text,
            "{} {:>8}  {:>14.1}  {:>8}  {:>8}  {:>7}  {:>8}{}",
            if i == tuning.chosen { "*" } else { " " },
            c.acceleration_noise_std_mps2,
            c.log_likelihood,
            c.updates,
            c.rmse_m.map_or("-".into(), |r| format!("{r:.3}")),
            c.rmse_standard_error_m.map_or("-".into(), |r| format!("{r:.3}")),
            c.inside_95.map_or("-".into(), |r| format!("{:.1}%", 100.0 * r)),
            if i == tuning.chosen { "  ← chosen" } else { "" }
        );
    }
    let chosen = &tuning.candidates[tuning.chosen];
    let _ = writeln!(
        text,
        "measurement classes (chosen σ_a): mean NIS per dof, mean adaptive scale λ"
    );
    for class in NoiseClass::ALL {
        let totals = chosen.innovations.of(class);
        if let (Some(nis), Some(scale)) = (totals.mean_nis_per_dof(), totals.mean_noise_scale()) {
            let _ = writeln!(
                text,
                "  {:<12} {:>8} updates  NIS/dof {nis:>6.2}  λ {scale:>7.2}",
                class.name(),
                totals.updates
            );
        }
    }
    if tuning.model.tried.len() > 1 {
        let _ = writeln!(
            text,
            "error correlation (at the chosen σ_a): correlation_s, correlation_from_innovations, \
             heading_error_correlation_s"
        );
        for (i, (settings, run)) in tuning.model.tried.iter().enumerate() {
            let _ = writeln!(
                text,
                "{} {:>5} s {:>5} {:>6} s  log-likelihood {:>10.1}  RMSE {:>8}  in 95 % {:>7}{}",
                if i == tuning.model.chosen { "*" } else { " " },
                settings.correlation_s,
                settings.correlation_from_innovations,
                settings.heading_error_correlation_s,
                run.log_likelihood,
                run.rmse_m.map_or("-".into(), |r| format!("{r:.3} m")),
                run.inside_95.map_or("-".into(), |r| format!("{:.1}%", 100.0 * r)),
                if i == tuning.model.chosen { "  ← chosen" } else { "" }
            );
        }
    }
    if let Some(c) = tuning.covariance {
        let _ = writeln!(
            text,
            "covariance calibration: σ_a and the readers' σ × {:.3} (σ_a {:.4} m/s²): in 95 % {:.1} → {:.1} %, \
             RMSE {:.3} → {:.3} m",
            c.std_factor,
            tuning.acceleration_noise_std_mps2,
            100.0 * c.inside_95_before,
            100.0 * c.inside_95_after,
            c.rmse_before_m,
            c.rmse_after_m
        );
    }
    for fit in &tuning.readers {
        let _ = write!(text, "reader {}:", fit.reader);
        if let Some(r) = fit.range {
            let _ = write!(
                text,
                " range bias {:.3} m{}, σ {:.3} m, scale {:.4} ({} ranges)",
                r.bias_m,
                r.offset_std_m.map_or_else(
                    || " (too few ranges for its spread)".to_string(),
                    |s| format!(" ± {s:.3} m")
                ),
                r.range_std_m,
                r.scale,
                r.samples
            );
        }
        if let Some(p) = fit.path_loss {
            let _ = write!(
                text,
                " path loss ρ₀ {:.1} dBm, n {:.2}, σ {:.1} dB ({} samples; {}, held-out RMS {:.1} dB)",
                p.reference_power_dbm,
                p.exponent,
                p.shadowing_std_db,
                p.samples,
                p.choice.name(),
                p.held_out_rms_db
            );
        }
        text.push('\n');
    }
    let _ = writeln!(text, "wrote {}", out.display());
    text
}

fn json_report(tuning: &Tuning, records: usize) -> serde_json::Value {
    let candidates: Vec<_> = tuning
        .candidates
        .iter()
        .map(|c| {
            serde_json::json!({
                "acceleration_noise_std_mps2": c.acceleration_noise_std_mps2,
                "log_likelihood": c.log_likelihood,
                "updates": c.updates,
                "rmse_m": c.rmse_m,
                "rmse_standard_error_m": c.rmse_standard_error_m,
                "inside_95": c.inside_95,
            })
        })
        .collect();
    let readers: Vec<_> = tuning
        .readers
        .iter()
        .map(|r| {
            serde_json::json!({
                "reader": r.reader,
                "range": r.range.map(|f| serde_json::json!({"bias_m": f.bias_m, "offset_std_m": f.offset_std_m, "range_std_m": f.range_std_m, "scale": f.scale, "samples": f.samples})),
                "path_loss": r.path_loss.map(|f| serde_json::json!({
                    "reference_power_dbm": f.reference_power_dbm, "exponent": f.exponent,
                    "shadowing_std_db": f.shadowing_std_db, "samples": f.samples,
                    "choice": f.choice.name(), "held_out_rms_db": f.held_out_rms_db})),
            })
        })
        .collect();
    let factors: serde_json::Map<String, serde_json::Value> = tuning
        .noise_std_factors
        .iter()
        .map(|(class, factor)| (class.name().to_string(), (*factor).into()))
        .collect();
    serde_json::json!({
        "records": records,
        "acceleration_noise_std_mps2": tuning.acceleration_noise_std_mps2,
        "candidates": candidates,
        "readers": readers,
        "noise_std_factors": factors,
        "error_correlation": {
            "correlation_s": tuning.model.settings().correlation_s,
            "correlation_from_innovations": tuning.model.settings().correlation_from_innovations,
            "heading_error_correlation_s": tuning.model.settings().heading_error_correlation_s,
            "tried": tuning.model.tried.iter().map(|(s, c)| serde_json::json!({
                "correlation_s": s.correlation_s,
                "correlation_from_innovations": s.correlation_from_innovations,
                "heading_error_correlation_s": s.heading_error_correlation_s,
                "log_likelihood": c.log_likelihood,
                "rmse_m": c.rmse_m,
                "inside_95": c.inside_95,
            })).collect::<Vec<_>>(),
        },
        "covariance": tuning.covariance.map(|c| serde_json::json!({
            "std_factor": c.std_factor,
            "inside_95_before": c.inside_95_before,
            "inside_95_after": c.inside_95_after,
            "rmse_before_m": c.rmse_before_m,
            "rmse_after_m": c.rmse_after_m,
        })),
    })
}
