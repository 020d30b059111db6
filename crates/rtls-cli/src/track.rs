//! `rtls track`: a measurement file through the tracker of a site, file in, file out.
//!
//! ```text
//! rtls track --site SITE --input FILE [--output FILE] [--events FILE] [--fixes FILE]
//!            [--pipeline fix-then-filter|tightly-coupled] [--filter kf|ekf|ukf] [--motion-model cv|imm]
//!            [--correct CELLS.csv --correct-readers READERS.csv]
//! ```
//! One JSON line per track update to `--output` (standard output by default), one per event to
//! `--events`, and the fix-then-filter pipeline's raw fixes to `--fixes`. Input is JSON Lines,
//! or CSV when the file name ends in `.csv` (docs/FORMATS.md). Every input error names the
//! file, the line and the field.
//!
//! The summary on standard error counts records, updates, fixes and events, names each tag whose
//! fixes alternate between two places (two transmitters under one id), and counts the rejected
//! records by kind and reason (numbers in a reason are replaced by `#`, so reasons group),
//! and the range offsets the tracks learnt (`[tracker.range_bias]`, beyond the site's
//! `bias_m`: per anchor, the mean over the tags that learnt one and their spread). A tag that had records but no track output is named with its rejections, and the exit
//! status is then [`EXIT_UNTRACKED`] (3); 1 is an error that stopped the run (site, input,
//! outputs), 0 a run in which every tag with records was tracked.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use rtls_engine::lifecycle::LifecycleEvent;
use rtls_engine::radio_map::RadioMap;
use rtls_engine::site::{
    read_text_file, FilterKind, FingerprintFormat, MotionModelKind, Pipeline, Site, MAX_RADIO_MAP_BYTES, MAX_SITE_BYTES,
};
use rtls_engine::survey::{SurveyMap, SurveySettings};
use rtls_engine::tracker::{Event, NoiseFit, Output, SegmentFit, Smoother, Tracker, FIT_STATES_MIN};

use crate::malformed::InputRecords;

mod summary;

pub use summary::UntrackedTags;
use summary::{event_type, range_offsets_line, reason_category, rejections_line, untracked_tags, Counts};

/// A pipeline named on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PipelineArg {
    /// A positioning fix per epoch, then a Kalman filter.
    FixThenFilter,
    /// Raw measurements straight into an EKF or UKF.
    TightlyCoupled,
}

/// A filter named on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum FilterArg {
    /// Linear Kalman filter (fixes only).
    Kf,
    /// Extended Kalman filter.
    Ekf,
    /// Unscented Kalman filter.
    Ukf,
}

/// A motion model named on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MotionModelArg {
    /// Constant velocity.
    Cv,
    /// Interacting multiple models (CV / CA / coordinated turn), with model-switch events.
    Imm,
}

/// Exit status of a run that finished but left a tag with records without any track output.
pub const EXIT_UNTRACKED: u8 = 3;

/// Arguments of `rtls track`.
#[derive(Debug, Args)]
#[command(
    after_help = "Exit status: 0 when every tag with records got a track; 3 when the run finished \
but a tag with records got no track output (the summary names it, with its rejected records by \
reason); 1 when an error stopped the run (site, input or outputs). A record that cannot be used \
as written (a malformed line, a missing or mistyped field, an unknown reader id) costs only itself: \
a `malformed` event and a line of the summary, the run goes on (`--strict`: it stops there); a \
read error, an input of which no record could be used or whose first 1000 records are all \
malformed stops the run."
)]
pub struct TrackArgs {
    /// Site model (TOML; see examples/site.toml).
    #[arg(long)]
    pub site: PathBuf,
    /// Measurement records: JSON Lines, or CSV if the name ends in `.csv`.
    #[arg(long)]
    pub input: PathBuf,
    /// Track updates, one JSON line each (default: standard output).
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Events (zones, alarms, lifecycle, late and rejected measurements), one JSON line each.
    #[arg(long)]
    pub events: Option<PathBuf>,
    /// Raw fixes of the positioning stage (before the filter), in the track-file shape.
    #[arg(long)]
    pub fixes: Option<PathBuf>,
    /// `--pipeline`, `--filter`, `--motion-model`: the site's tracker settings overridden.
    #[command(flatten)]
    pub overrides: ModelOverrides,
    /// Correct ranges and RSSI with the bias learned by `rtls survey` (its cells CSV) at the
    /// tag's last tracked position before tracking them; needs `--correct-readers`.
    #[arg(long, requires = "correct_readers")]
    pub correct: Option<PathBuf>,
    /// The readers CSV of the same survey (`rtls survey --readers-out`).
    #[arg(long, requires = "correct")]
    pub correct_readers: Option<PathBuf>,
    /// Write the tracks smoothed over the whole recording: each segment of a track re-filtered
    /// with the process noise and noise scale that fit it best (maximum likelihood), then a
    /// Rauch–Tung–Striebel smoother; each update also knows the measurements after it, and
    /// carries `"smoothed": true`. For replays, reports and evaluation, not for what a live
    /// tracker knew; the history is held until the end (~1.3 kB per update).
    #[arg(long)]
    pub smooth: bool,
    /// Stop at the first record that cannot be used as written (a malformed line, a missing
    /// or mistyped field, an unknown reader id); without it each such record is skipped, a
    /// `malformed` event and counted in the summary.
    #[arg(long)]
    pub strict: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Counts bytes read, for the progress bar.
struct Counting<R> {
    inner: R,
    bar: ProgressBar,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.bar.inc(n as u64);
        Ok(n)
    }
}

fn create(path: &Path) -> anyhow::Result<BufWriter<File>> {
    Ok(BufWriter::new(
        File::create(path).with_context(|| format!("creating {}", path.display()))?,
    ))
}

/// The tracker settings `rtls track` and `rtls tune` let the command line override, so a
/// recording is tuned with the pipeline, filter and motion model it will be tracked with.
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct ModelOverrides {
    /// Override the site's `tracker.pipeline`.
    #[arg(long, value_enum)]
    pub pipeline: Option<PipelineArg>,
    /// Override the site's `tracker.filter`.
    #[arg(long, value_enum)]
    pub filter: Option<FilterArg>,
    /// Override the site's `tracker.motion_model`.
    #[arg(long, value_enum)]
    pub motion_model: Option<MotionModelArg>,
}

impl ModelOverrides {
    /// Writes the overrides into `site.tracker`.
    ///
    /// # Errors
    /// The tightly coupled pipeline with the linear KF (raw measurements are nonlinear).
    pub fn apply(&self, site: &mut Site) -> anyhow::Result<()> {
        if let Some(pipeline) = self.pipeline {
            site.tracker.pipeline = match pipeline {
                PipelineArg::FixThenFilter => Pipeline::FixThenFilter,
                PipelineArg::TightlyCoupled => Pipeline::TightlyCoupled,
            };
        }
        if let Some(filter) = self.filter {
            site.tracker.filter = match filter {
                FilterArg::Kf => FilterKind::Kf,
                FilterArg::Ekf => FilterKind::Ekf,
                FilterArg::Ukf => FilterKind::Ukf,
            };
        }
        if let Some(model) = self.motion_model {
            site.tracker.motion_model = match model {
                MotionModelArg::Cv => MotionModelKind::Cv,
                MotionModelArg::Imm => MotionModelKind::Imm,
            };
        }
        if site.tracker.pipeline == Pipeline::TightlyCoupled && site.tracker.filter == FilterKind::Kf {
            bail!("the tightly coupled pipeline needs --filter ekf or ukf (raw measurements are nonlinear)");
        }
        Ok(())
    }
}

/// Loads the site (with command-line overrides) and its radio map, if it names one.
fn load_site(args: &TrackArgs) -> anyhow::Result<(Site, Option<RadioMap>)> {
    let (mut site, radio_map) = load_site_file(&args.site)?;
    args.overrides.apply(&mut site)?;
    Ok((site, radio_map))
}

/// Loads a site file and the radio map it names, if any (`rtls track`, `rtls tune`).
pub(crate) fn load_site_file(path: &Path) -> anyhow::Result<(Site, Option<RadioMap>)> {
    let site_name = path.display().to_string();
    let text = read_text_file(path, MAX_SITE_BYTES, "site")?;
    let site = Site::from_toml_str(&text, &site_name)?;
    for line in site.advice() {
        eprintln!("{site_name}: {line}");
    }
    let radio_map = match &site.fingerprints {
        Some(database) if database.format != FingerprintFormat::Csv => bail!(
            "{site_name}: [fingerprints] format {:?}: rtls track loads radio maps in the \"csv\" format \
             (docs/FORMATS.md; `rtls import` writes UJIIndoorLoc in it)",
            database.format
        ),
        Some(database) => {
            let path = path.parent().unwrap_or(Path::new(".")).join(&database.path);
            let name = path.display().to_string();
            let text = read_text_file(&path, MAX_RADIO_MAP_BYTES, "radio map")
                .with_context(|| format!("reading the radio map named by {site_name} [fingerprints]"))?;
            let started = std::time::Instant::now();
            let map = RadioMap::from_csv_str(&text, &name, &site)?;
            eprintln!("{}", radio_map_summary(&name, &map, started.elapsed().as_secs_f64()));
            Some(map)
        }
        None => None,
    };
    Ok((site, radio_map))
}

/// One line on a loaded radio map: its size, the fix σ floor in use and where it comes from
/// (the leave-one-out calibration, the site's `min_std_m` or the spacing floor), and the load
/// time.
fn radio_map_summary(name: &str, map: &RadioMap, load_s: f64) -> String {
    let source = match (map.min_std_override_m(), map.calibration()) {
        (Some(_), _) => "the site's [fingerprints] min_std_m",
        (None, Some(_)) => "calibrated",
        (None, None) => "fewer than 3 distinct positions to cross-validate",
    };
    let loo = map
        .calibration()
        .map(|c| {
            format!(
                "; leave-one-out WKNN over {} points: RMSE {:.2} m, 95 % inside the 95 % ellipse at \
                 σ_f {:.2} m, mean NEES {:.2}",
                c.located, c.rmse_m, c.fitted_std_m, c.mean_nees
            )
        })
        .unwrap_or_default();
    format!(
        "radio map {name}: {} reference points, fix σ floor {:.2} m ({source}; spacing floor {:.2} m{loo}); \
         loaded in {load_s:.2} s",
        map.reference_point_count(),
        map.min_std_m(),
        map.spacing_std_m(),
    )
}

/// Runs `rtls track`.
///
/// # Errors
/// Unreadable or invalid site, radio map or input (naming file, line and field), unwritable
/// outputs.
pub fn run(args: &TrackArgs) -> anyhow::Result<()> {
    let (site, radio_map) = load_site(args)?;
    let mut tracker = Tracker::new(&site)?;
    if let Some(map) = radio_map {
        tracker = tracker.with_radio_map(map);
    }
    let input_name = args.input.display().to_string();
    let file = File::open(&args.input).with_context(|| format!("opening {input_name}"))?;
    let length = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(length)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {bytes}/{total_bytes} {bytes_per_sec} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let reader = BufReader::with_capacity(
        1 << 16,
        Counting {
            inner: file,
            bar: bar.clone(),
        },
    );

    let mut updates_out: Box<dyn Write> = match &args.output {
        Some(path) => Box::new(create(path)?),
        None => Box::new(BufWriter::new(std::io::stdout().lock())),
    };
    let mut events_out = args.events.as_deref().map(create).transpose()?;
    let mut fixes_out = args.fixes.as_deref().map(create).transpose()?;

    let correction = match (&args.correct, &args.correct_readers) {
        (Some(cells), Some(readers)) => {
            let read =
                |path: &Path| std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()));
            Some(SurveyMap::from_csv(
                &read(cells)?,
                &cells.display().to_string(),
                &read(readers)?,
                &readers.display().to_string(),
                &SurveySettings::default(),
            )?)
        }
        _ => None,
    };
    // the last tracked position of each tag, where its next readings are corrected
    let positions: RefCell<HashMap<String, [f64; 2]>> = RefCell::new(HashMap::new());

    let mut counts = Counts::default();
    // --smooth: the updates are kept with their states and written smoothed at the end
    let mut smoother = args.smooth.then(|| tracker.smoother());
    let mut out = if args.smooth {
        Output::keeping_states()
    } else {
        Output::default()
    };
    let mut write = |out: &mut Output, counts: &mut Counts, malformed: Vec<String>| -> anyhow::Result<()> {
        if correction.is_some() {
            let mut positions = positions.borrow_mut();
            for update in out.updates.iter().filter(|u| !u.predicted) {
                positions.insert(update.tag.to_string(), [update.position_m[0], update.position_m[1]]);
            }
        }
        if let Some(smoother) = smoother.as_mut() {
            smoother.take(out);
        }
        for update in &out.updates {
            if smoother.is_none() {
                writeln!(updates_out, "{}", update.to_json_line()).context("writing track updates")?;
            }
            counts.updates += 1;
            counts.predicted += usize::from(update.predicted);
            if let Some(tag) = counts.tags.get_mut(&*update.tag) {
                tag.updates += 1;
            }
        }
        for event in &out.events {
            *counts.events.entry(event_type(event)).or_default() += 1;
            match event {
                Event::Rejected { tag, kind, reason, .. } => {
                    let key = (*kind, reason_category(reason));
                    *counts.rejected.entry(key.clone()).or_default() += 1;
                    if let Some(tag) = counts.tags.get_mut(&**tag) {
                        *tag.rejected.entry(key).or_default() += 1;
                    }
                }
                Event::Late { tag, kind, .. } => {
                    if let Some(tag) = counts.tags.get_mut(&**tag) {
                        *tag.rejected
                            .entry((*kind, "late (after the re-ordering window)".into()))
                            .or_default() += 1;
                    }
                }
                Event::Lifecycle {
                    tag,
                    event: LifecycleEvent::Alternating,
                    position_m,
                    ..
                } => {
                    counts.alternating.insert(tag.to_string(), *position_m);
                }
                _ => {}
            }
            if let Some(w) = events_out.as_mut() {
                writeln!(w, "{}", event.to_json_line()).context("writing events")?;
            }
        }
        for event in malformed {
            *counts.events.entry("malformed").or_default() += 1;
            if let Some(w) = events_out.as_mut() {
                writeln!(w, "{event}").context("writing events")?;
            }
        }
        for fix in &out.fixes {
            counts.fixes += 1;
            if let Some(w) = fixes_out.as_mut() {
                writeln!(w, "{}", fix.to_json_line()).context("writing fixes")?;
            }
        }
        out.clear();
        Ok(())
    };
    // a record that cannot be used as written costs only itself (`malformed.rs`)
    let is_csv = args.input.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let mut records = InputRecords::new(reader, &input_name, is_csv, args.strict)?;
    while let Some((record, line)) = records.next_record()? {
        if let Err(error) = tracker.check_record(&record, &input_name, line) {
            records.refuse(error)?;
        } else {
            let record = match (&correction, positions.borrow().get(&record.tag)) {
                (Some(map), Some(position_m)) => map.correct_record(&record, *position_m),
                _ => record,
            };
            counts.tags.entry(record.tag.clone()).or_default().records += 1;
            tracker.push(record, &mut out)?;
            counts.records += 1;
        }
        write(&mut out, &mut counts, records.take_events())?;
    }
    let skipped = records.finish()?;
    tracker.finish(&mut out)?;
    write(&mut out, &mut counts, records.take_events())?;
    bar.finish_and_clear();
    if let Some(smoother) = smoother {
        write_smoothed(smoother, &mut updates_out)?;
    }
    updates_out.flush().context("writing track updates")?;
    if let Some(w) = events_out.as_mut() {
        w.flush().context("writing events")?;
    }
    if let Some(w) = fixes_out.as_mut() {
        w.flush().context("writing fixes")?;
    }
    let events: Vec<String> = counts.events.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!(
        "{} records, {} track updates ({} predicted), {} raw fixes; events: {}",
        counts.records,
        counts.updates,
        counts.predicted,
        counts.fixes,
        if events.is_empty() {
            "none".to_string()
        } else {
            events.join(", ")
        }
    );
    if !counts.rejected.is_empty() {
        eprintln!("rejected by reason: {}", rejections_line(&counts.rejected));
    }
    if let Some(line) = skipped {
        eprintln!("{line}");
    }
    for (tag, [x, y, _]) in &counts.alternating {
        eprintln!(
            "tag {tag}: its fixes alternate between its track and ({x:.1}, {y:.1}) m: two transmitters \
             sending as one id, or a recurring reflection (an `alternating` lifecycle event); from then \
             on the track keeps a state at each place and updates the one each fix is likelier from"
        );
    }
    let offsets = tracker.range_offsets();
    if !offsets.is_empty() {
        eprintln!("{}", range_offsets_line(&offsets));
    }
    untracked_tags(&counts)
}

/// Smooths the kept tracks and writes them; names each segment the backward pass failed on
/// (its filtered updates are written instead).
fn write_smoothed(smoother: Smoother, updates_out: &mut dyn Write) -> anyhow::Result<()> {
    let smoothed = smoother.finish();
    for update in &smoothed.updates {
        writeln!(updates_out, "{}", update.to_json_line()).context("writing track updates")?;
    }
    let count = smoothed.updates.iter().filter(|u| u.smoothed).count();
    eprintln!("smoothed {count} of {} track updates", smoothed.updates.len());
    let fitted = smoothed.fits.iter().filter(|f| f.fit.is_ok()).count();
    eprintln!(
        "{fitted} of {} segments smoothed with their own fitted noise",
        smoothed.fits.len()
    );
    // why the others kept the site's model, by reason (a short segment's count of measured
    // states folded into one reason)
    let mut site_model: BTreeMap<&str, usize> = BTreeMap::new();
    for segment in &smoothed.fits {
        if let Err(reason) = &segment.fit {
            let reason = if reason.ends_with(&format!("fewer than {FIT_STATES_MIN}")) {
                "too few measured states"
            } else {
                reason.as_str()
            };
            *site_model.entry(reason).or_default() += 1;
        }
    }
    for (reason, count) in site_model {
        eprintln!("{count} segments smoothed with the site's model: {reason}");
    }
    // each tag's longest fitted segment
    let mut longest: BTreeMap<&str, (&SegmentFit, &NoiseFit)> = BTreeMap::new();
    for segment in &smoothed.fits {
        let Ok(fit) = &segment.fit else { continue };
        let entry = longest.entry(&*segment.tag).or_insert((segment, fit));
        if segment.to_s - segment.from_s > entry.0.to_s - entry.0.from_s {
            *entry = (segment, fit);
        }
    }
    for (tag, (segment, fit)) in longest {
        eprintln!(
            "tag {tag}: smoothed with q {:.4} m²/s³ and the noise × {:.1} ({:.1}–{:.1} s)",
            fit.acceleration_psd_m2ps3, fit.noise_scale, segment.from_s, segment.to_s
        );
    }
    for failure in &smoothed.failures {
        eprintln!(
            "tag {}: not smoothed from {:.3} s to {:.3} s (its filtered updates are written): {}",
            failure.tag, failure.from_s, failure.to_s, failure.reason
        );
    }
    Ok(())
}
