//! `rtls survey`: the radio-environment map (seed 000's obstacle analysis) from a measurement
//! file and the tracks `rtls track` made of it.
//!
//! ```text
//! rtls survey --site SITE --input RECORDS --tracks TRACKS --out CELLS.csv [--readers-out READERS.csv]
//!             [--png MAP.png] [--cell-m 10] [--max-gap-s 2] [--skip-initial-s 5] [--min-count 50]
//!             [--z 3.5] [--min-effect-db 3] [--min-effect-m 0.3] [--distance-band-m 10 | --one-population]
//!             [--flag-spread] [--top 10] [--strict]
//! ```
//! Every range / RSSI measurement is compared with the site's model at the tag's tracked position
//! (`rtls_engine::survey`); the residuals are summarised per (10 m cell, reader) and per reader,
//! and entries whose bias departs from their population's (RSSI lower, ranges longer) are
//! flagged. Prints a summary (what was matched, how many entries are flagged, the most
//! significant ones), writes the cell table (and the reader table), and draws the map: cells
//! coloured by bias, flagged cells outlined, readers, flagged readers in red.
//!
//! A measurement record that cannot be read as written costs only itself, as in `rtls track`
//! ([`crate::malformed`]): the summary counts the skipped records and names the first; `--strict`
//! stops at the first instead. A malformed track line stops the run (the tracks are this
//! program's own output).

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use clap::Args;
use plotters::prelude::*;

use crate::malformed::InputRecords;
use crate::plot::{padded_ranges, register_font};
use rtls_engine::evaluation::{parse_track_lines, TRACKS_SOURCE};
use rtls_engine::record::Record;
use rtls_engine::site::Site;
use rtls_engine::survey::{residuals, ResidualKind, SurveyMap, SurveySettings, RECORDS_SOURCE};
use rtls_engine::EngineError;

/// Arguments of `rtls survey`.
#[derive(Debug, Args)]
pub struct SurveyArgs {
    /// Site model (TOML): reader positions and their radio laws.
    #[arg(long)]
    pub site: PathBuf,
    /// Measurement records: JSON Lines, or CSV if the name ends in `.csv`.
    #[arg(long)]
    pub input: PathBuf,
    /// Track file of the same records (JSON Lines, as written by `rtls track`).
    #[arg(long)]
    pub tracks: PathBuf,
    /// Cell table to write (CSV: bounds, reader, kind, n, distance, bias, std, z, flags).
    #[arg(long, value_name = "CSV")]
    pub out: PathBuf,
    /// Reader table to write (CSV).
    #[arg(long, value_name = "CSV")]
    pub readers_out: Option<PathBuf>,
    /// Map to draw (PNG).
    #[arg(long, value_name = "PNG")]
    pub png: Option<PathBuf>,
    /// Side of the square area cells, m.
    #[arg(long, value_name = "M", default_value_t = 10.0, value_parser = positive)]
    pub cell_m: f64,
    /// Longest gap between two track updates a measurement may be interpolated in, s.
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = non_negative)]
    pub max_gap_s: f64,
    /// Measurements in each track's first S seconds are not used (filter convergence).
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = non_negative)]
    pub skip_initial_s: f64,
    /// Residuals an entry needs to be scored, flagged or used as a correction (≥ 2).
    #[arg(long, value_name = "N", default_value_t = 50, value_parser = clap::value_parser!(u32).range(2..))]
    pub min_count: u32,
    /// Robust z threshold.
    #[arg(long, value_name = "Z", default_value_t = 3.5, value_parser = positive)]
    pub z: f64,
    /// Minimum RSSI effect to flag, dB.
    #[arg(long, value_name = "DB", default_value_t = 3.0, value_parser = positive)]
    pub min_effect_db: f64,
    /// Minimum range effect to flag, m.
    #[arg(long, value_name = "M", default_value_t = 0.3, value_parser = positive)]
    pub min_effect_m: f64,
    /// Width of the distance-to-reader bands whose cells are compared with each other, m.
    #[arg(long, value_name = "M", default_value_t = 10.0, value_parser = positive, conflicts_with = "one_population")]
    pub distance_band_m: f64,
    /// Compare every cell with all cells, whatever its distance to its reader.
    #[arg(long)]
    pub one_population: bool,
    /// Flag entries whose spread is abnormal too.
    #[arg(long)]
    pub flag_spread: bool,
    /// How many flagged cells and readers the summary lists.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub top: usize,
    /// Stop at the first malformed measurement record instead of skipping it.
    #[arg(long)]
    pub strict: bool,
}

fn positive(text: &str) -> core::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() && value > 0.0 => Ok(value),
        _ => Err(format!("`{text}` is not a finite number > 0")),
    }
}

fn non_negative(text: &str) -> core::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() && value >= 0.0 => Ok(value),
        _ => Err(format!("`{text}` is not a finite number ≥ 0")),
    }
}

impl SurveyArgs {
    fn settings(&self) -> SurveySettings {
        SurveySettings {
            cell_size_m: self.cell_m,
            max_gap_s: self.max_gap_s,
            skip_initial_s: self.skip_initial_s,
            min_count: self.min_count as usize,
            z_threshold: self.z,
            min_rssi_effect_db: self.min_effect_db,
            min_range_effect_m: self.min_effect_m,
            distance_band_m: (!self.one_population).then_some(self.distance_band_m),
            flag_spread: self.flag_spread,
            ..SurveySettings::default()
        }
    }
}

fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// The usable records of the input file and their 1-based lines, and the summary's line on
/// the malformed ones skipped (see the module; errors name the file, line and field).
fn read_records(path: &Path, strict: bool) -> Result<(Vec<Record>, Vec<usize>, Option<String>)> {
    let name = path.display().to_string();
    let file = File::open(path).with_context(|| format!("opening {name}"))?;
    let csv = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let mut input = InputRecords::new(BufReader::new(file), &name, csv, strict)?;
    let (mut records, mut lines) = (Vec::new(), Vec::new());
    while let Some((record, line)) = input.next_record()? {
        records.push(record);
        lines.push(line);
    }
    let skipped = input.finish()?;
    Ok((records, lines, skipped))
}

/// Replaces the survey's placeholder file names with the real ones (and a record's index with
/// its line).
fn name_files(error: EngineError, records: &str, lines: &[usize], tracks: &str) -> anyhow::Error {
    match error {
        EngineError::Parse {
            file,
            line,
            field,
            reason,
        } => {
            let (file, line) = match file.as_str() {
                TRACKS_SOURCE => (tracks.to_string(), line),
                RECORDS_SOURCE => (
                    records.to_string(),
                    line.checked_sub(1).and_then(|i| lines.get(i)).copied().unwrap_or(0),
                ),
                _ => (file, line),
            };
            EngineError::Parse {
                file,
                line,
                field,
                reason,
            }
            .into()
        }
        other => other.into(),
    }
}

fn create(path: &Path) -> Result<BufWriter<File>> {
    Ok(BufWriter::new(
        File::create(path).with_context(|| format!("creating {}", path.display()))?,
    ))
}

/// Runs `rtls survey`.
///
/// # Errors
/// Unreadable or invalid site, records or tracks (naming file, line and field), unwritable
/// outputs, a failed drawing.
pub fn run(args: &SurveyArgs) -> Result<()> {
    let site_name = args.site.display().to_string();
    let site = Site::from_toml_str(&read(&args.site)?, &site_name)?;
    let (records, lines, skipped) = read_records(&args.input, args.strict)?;
    let tracks_name = args.tracks.display().to_string();
    let tracks = parse_track_lines(&read(&args.tracks)?, &tracks_name)?;
    let settings = args.settings();
    let input_name = args.input.display().to_string();
    let found =
        residuals(&site, &records, &tracks, &settings).map_err(|e| name_files(e, &input_name, &lines, &tracks_name))?;
    let map = SurveyMap::build(&found.residuals, &settings)?;

    let mut out = create(&args.out)?;
    map.write_cells_csv(&mut out)
        .and_then(|()| out.flush())
        .with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(path) = &args.readers_out {
        let mut out = create(path)?;
        map.write_readers_csv(&mut out)
            .and_then(|()| out.flush())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.png {
        draw_map(&site, &map, path).with_context(|| format!("drawing {}", path.display()))?;
    }

    let mut summary = format!("{} records: {} residuals", records.len(), found.residuals.len());
    let unmatched: Vec<String> = found
        .unmatched
        .reasons()
        .iter()
        .filter(|(_, n)| *n > 0)
        .map(|(reason, n)| format!("{reason} {n}"))
        .collect();
    if !unmatched.is_empty() {
        summary.push_str(&format!(
            "; {} measurements without one: {}",
            found.unmatched.total(),
            unmatched.join(", ")
        ));
    }
    println!("{summary}");
    if let Some(skipped) = skipped {
        println!("{skipped}");
    }
    let scored = |z: Option<f64>| usize::from(z.is_some());
    println!(
        "cells: {} entries ({} scored), {} flagged; readers: {} entries ({} scored), {} flagged",
        map.cells().len(),
        map.cells().iter().map(|e| scored(e.summary.z)).sum::<usize>(),
        map.flagged_cells().len(),
        map.readers().len(),
        map.readers().iter().map(|e| scored(e.summary.z)).sum::<usize>(),
        map.flagged_readers().len()
    );
    print_top(&map, args.top);
    Ok(())
}

fn optional(value: Option<f64>) -> String {
    value.map_or_else(|| "-".to_string(), |v| format!("{v:.2}"))
}

/// The most significant flagged cells and readers.
fn print_top(map: &SurveyMap, top: usize) {
    let cells = map.flagged_cells();
    if !cells.is_empty() {
        println!("flagged cells (most significant first):");
        println!(
            "  {:<10}  {:<5}  {:<24}  {:>6}  {:>9}  {:>6}  {:>7}  reason",
            "reader", "kind", "cell (m)", "n", "bias", "std", "z"
        );
        for entry in cells.iter().take(top) {
            let [x0, x1, y0, y1] = map.settings().cell_bounds_m(entry.cell);
            let s = &entry.summary;
            println!(
                "  {:<10}  {:<5}  {:<24}  {:>6}  {:>6.2} {:<2}  {:>6}  {:>7}  {}",
                entry.reader,
                entry.kind.name(),
                format!("[{x0}, {x1}) × [{y0}, {y1})"),
                s.count,
                s.bias,
                entry.kind.unit(),
                optional(s.std),
                optional(s.z),
                s.degraded.name()
            );
        }
    }
    let readers = map.flagged_readers();
    if !readers.is_empty() {
        println!("flagged readers:");
        println!(
            "  {:<10}  {:<5}  {:>6}  {:>9}  {:>7}  {:>13}  reason",
            "reader", "kind", "n", "bias", "z", "flagged cells"
        );
        for entry in readers.iter().take(top) {
            let s = &entry.summary;
            println!(
                "  {:<10}  {:<5}  {:>6}  {:>6.2} {:<2}  {:>7}  {:>13}  {}",
                entry.reader,
                entry.kind.name(),
                s.count,
                s.bias,
                entry.kind.unit(),
                optional(s.z),
                entry.flagged_cells,
                s.degraded.name()
            );
        }
    }
}

const SIZE_PX: (u32, u32) = (1200, 800);

/// Cells without a scored entry.
const UNSCORED: RGBColor = RGBColor(225, 225, 225);

/// A diverging colour for `value` in `[−limit, limit]`: vermilion in the obstacle's direction
/// (`sign · value > 0`: RSSI below the model, ranges above it), blue in the other, white at 0
/// (Okabe–Ito end points).
fn diverging(value: f64, limit: f64, sign: f64) -> RGBColor {
    let t = (sign * value / limit).clamp(-1.0, 1.0);
    let (end, t) = if t > 0.0 {
        ((213.0, 94.0, 0.0), t)
    } else {
        ((0.0, 114.0, 178.0), -t)
    };
    let mix = |e: f64| (255.0 + (e - 255.0) * t).round() as u8;
    RGBColor(mix(end.0), mix(end.1), mix(end.2))
}

/// How a cell is drawn.
#[derive(Debug, Clone, Copy, Default)]
struct CellPaint {
    /// Its most degraded scored entry: `(sign · z, bias)`.
    worst: Option<(f64, f64)>,
    /// Whether any of its entries is flagged.
    flagged: bool,
}

/// Draws the map of the most common kind: each cell filled with the bias of its most degraded
/// scored entry (grey when none is scored), flagged cells outlined, readers as triangles,
/// flagged readers as red circles with their ids.
fn draw_map(site: &Site, map: &SurveyMap, path: &Path) -> Result<()> {
    register_font();
    let count = |kind: ResidualKind| map.cells().iter().filter(|e| e.kind == kind).count();
    let kind = if count(ResidualKind::Range) > count(ResidualKind::Rssi) {
        ResidualKind::Range
    } else {
        ResidualKind::Rssi
    };
    let sign = kind.degradation_sign();
    let mut cells: std::collections::BTreeMap<[i64; 2], CellPaint> = Default::default();
    for entry in map.cells().iter().filter(|e| e.kind == kind) {
        let paint = cells.entry(entry.cell).or_default();
        paint.flagged |= entry.summary.degraded.any();
        if let Some(z) = entry.summary.z {
            // degradation score: sign · z (higher = more degraded)
            if paint.worst.is_none_or(|(score, _)| sign * z > score) {
                paint.worst = Some((sign * z, entry.summary.bias));
            }
        }
    }
    let limit = cells
        .values()
        .filter_map(|paint| paint.worst.map(|(_, bias)| bias.abs()))
        .fold(map.settings().min_effect(kind), f64::max);

    let mut points: Vec<[f64; 2]> = site
        .readers
        .iter()
        .map(|r| [r.position_m[0], r.position_m[1]])
        .collect();
    for cell in cells.keys() {
        let [x0, x1, y0, y1] = map.settings().cell_bounds_m(*cell);
        points.extend([[x0, y0], [x1, y1]]);
    }
    let ((x0, x1), (y0, y1)) = padded_ranges(points.iter().copied(), 1.0, true)
        .ok_or_else(|| anyhow!("nothing to draw: no readers, no cells"))?;

    let root = BitMapBackend::new(path, SIZE_PX).into_drawing_area();
    let error = |e: DrawingAreaErrorKind<_>| anyhow!("{e:?}");
    root.fill(&WHITE).map_err(error)?;
    let title = format!(
        "Radio survey: {} flagged cells, {} flagged readers ({} bias, {})",
        map.flagged_cells().len(),
        map.flagged_readers().len(),
        kind.name(),
        kind.unit()
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(&title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(error)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(error)?;
    let bounds = |cell: &[i64; 2]| {
        let [x0, x1, y0, y1] = map.settings().cell_bounds_m(*cell);
        [(x0, y0), (x1, y1)]
    };
    chart
        .draw_series(cells.iter().map(|(cell, paint)| {
            let colour = paint.worst.map_or(UNSCORED, |(_, bias)| diverging(bias, limit, sign));
            Rectangle::new(bounds(cell), colour.filled())
        }))
        .map_err(error)?;
    for (label, colour) in [
        (
            format!("bias {:+.1} {} (obstacle side)", sign * limit, kind.unit()),
            diverging(sign * limit, limit, sign),
        ),
        (
            format!("bias {:+.1} {}", -sign * limit, kind.unit()),
            diverging(-sign * limit, limit, sign),
        ),
        ("too few residuals to score".to_string(), UNSCORED),
    ] {
        chart
            .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())
            .map_err(error)?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], colour.filled()));
    }
    chart
        .draw_series(
            cells
                .iter()
                .filter(|(_, paint)| paint.flagged)
                .map(|(cell, _)| Rectangle::new(bounds(cell), BLACK.stroke_width(2))),
        )
        .map_err(error)?
        .label("flagged cell")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], BLACK.stroke_width(2)));
    chart
        .draw_series(
            site.readers
                .iter()
                .map(|r| TriangleMarker::new((r.position_m[0], r.position_m[1]), 5, BLACK.filled())),
        )
        .map_err(error)?
        .label("reader")
        .legend(|(x, y)| TriangleMarker::new((x + 10, y), 5, BLACK.filled()));
    let flagged: Vec<&str> = map.flagged_readers().iter().map(|e| e.reader.as_str()).collect();
    let red = RGBColor(213, 94, 0);
    let flagged_positions: Vec<(&str, (f64, f64))> = site
        .readers
        .iter()
        .filter(|r| flagged.contains(&r.id.as_str()))
        .map(|r| (r.id.as_str(), (r.position_m[0], r.position_m[1])))
        .collect();
    chart
        .draw_series(
            flagged_positions
                .iter()
                .map(|(_, p)| Circle::new(*p, 7, red.stroke_width(3))),
        )
        .map_err(error)?
        .label("flagged reader")
        .legend(move |(x, y)| Circle::new((x + 10, y), 6, red.stroke_width(3)));
    chart
        .draw_series(flagged_positions.iter().map(|(id, p)| {
            // the id beside the circle, offset in pixels
            EmptyElement::at(*p) + Text::new(id.to_string(), (9, -18), ("sans-serif", 15).into_font().color(&red))
        }))
        .map_err(error)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(error)?;
    root.present().map_err(error)?;
    Ok(())
}
