//! What a paper reproduction returns: named metrics beside the paper's figure and the bound,
//! figures as plain data (the `rtls` binary renders them), and explanatory notes.
//!
//! The types are plain serialisable values so that the command line prints them as JSON, the
//! markdown report lists them and tests assert on them, all from the same runs.

use serde::Serialize;

/// One reported quantity: what the paper says, what we measure, and the best any estimator
/// could do on the same scenario (the posterior Cramér–Rao bound, where one applies).
///
/// # Example
/// ```
/// use rtls_papers::report::Metric;
/// let m = Metric::new("UKF position RMSE", "m", 0.21).paper(0.4).bound(0.15);
/// assert_eq!((m.paper, m.bound), (Some(0.4), Some(0.15)));
/// assert!((m.ratio_to_bound().unwrap() - 1.4).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metric {
    /// What is measured, with the scenario it belongs to, e.g. "CV: UKF position RMSE".
    pub name: String,
    /// Unit of `paper`, `ours` and `bound` (e.g. "m", "%", "" for ratios).
    pub unit: String,
    /// The paper's number for the same quantity, if it reports one.
    pub paper: Option<f64>,
    /// Our measured value.
    pub ours: f64,
    /// The bound for this quantity (√PCRB for an RMSE), if one applies.
    pub bound: Option<f64>,
}

impl Metric {
    /// A metric with our value only.
    #[must_use]
    pub fn new(name: impl Into<String>, unit: impl Into<String>, ours: f64) -> Self {
        Self {
            name: name.into(),
            unit: unit.into(),
            paper: None,
            ours,
            bound: None,
        }
    }

    /// Sets the paper's value.
    #[must_use]
    pub fn paper(mut self, value: f64) -> Self {
        self.paper = Some(value);
        self
    }

    /// Sets the bound.
    #[must_use]
    pub fn bound(mut self, value: f64) -> Self {
        self.bound = Some(value);
        self
    }

    /// `ours / bound`, when a positive bound is set (≥ 1 for a true bound on an RMSE).
    #[must_use]
    pub fn ratio_to_bound(&self) -> Option<f64> {
        self.bound.filter(|b| *b > 0.0).map(|b| self.ours / b)
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum SeriesStyle {
    /// Solid line through the points.
    Line,
    /// Dashed line (bounds, references).
    Dashed,
    /// Unconnected markers (raw fixes, scatter).
    Points,
}

/// One curve of a figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Drawing style.
    pub style: SeriesStyle,
    /// `(x, y)` points in the figure's axis units.
    pub points: Vec<[f64; 2]>,
}

impl Series {
    /// A series from its label, style and points.
    #[must_use]
    pub fn new(label: impl Into<String>, style: SeriesStyle, points: Vec<[f64; 2]>) -> Self {
        Self {
            label: label.into(),
            style,
            points,
        }
    }

    /// A line of `values[k]` against `x0 + k dx` (e.g. an error over time at 1 s steps).
    #[must_use]
    pub fn over_index(label: impl Into<String>, style: SeriesStyle, x0: f64, dx: f64, values: &[f64]) -> Self {
        let points = values
            .iter()
            .enumerate()
            .map(|(k, &v)| [x0 + dx * k as f64, v])
            .collect();
        Self::new(label, style, points)
    }
}

/// A figure as data: the `rtls` binary draws it as SVG and PNG named after `id`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Figure {
    /// File stem, unique within the report (e.g. "ukf-uwb-cv-rmse").
    pub id: String,
    /// Caption: what the figure shows and which paper figure it corresponds to.
    pub title: String,
    /// x-axis label with unit.
    pub x_label: String,
    /// y-axis label with unit.
    pub y_label: String,
    /// Draw x and y at the same scale (maps and trajectories).
    pub equal_aspect: bool,
    /// The curves.
    pub series: Vec<Series>,
}

impl Figure {
    /// A figure with no series yet.
    #[must_use]
    pub fn new(
        id: impl Into<String>,
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            id: id.into(),
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            equal_aspect: false,
            series: Vec::new(),
        }
    }

    /// Same scale on both axes.
    #[must_use]
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Adds a series.
    #[must_use]
    pub fn with(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }
}

/// A markdown table for results that are not one number each (sweeps, per-row tables).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table {
    /// Caption.
    pub title: String,
    /// Column headers.
    pub header: Vec<String>,
    /// Rows of cells, already formatted.
    pub rows: Vec<Vec<String>>,
}

/// Everything one reproduction produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExperimentReport {
    /// Command-line name (`mekf`, `ukf-uwb`, `lwknn`, `wsn-ekf`, `vdkf`).
    pub experiment: String,
    /// Heading for the report, naming the paper.
    pub title: String,
    /// Monte Carlo runs per configuration.
    pub runs: usize,
    /// Base seed; run `i` uses [`rtls_sim::montecarlo::run_seed`]`(seed, i)`.
    pub seed: u64,
    /// Scenario files the experiment read.
    pub scenarios: Vec<String>,
    /// Metric | paper | ours | bound rows.
    pub metrics: Vec<Metric>,
    /// Further tables (sweeps, per-row re-evaluations).
    pub tables: Vec<Table>,
    /// Figures to draw.
    pub figures: Vec<Figure>,
    /// Markdown paragraphs: setup, choices, and an explanation of every difference from the paper.
    pub notes: Vec<String>,
}

impl ExperimentReport {
    /// An empty report for `experiment`.
    #[must_use]
    pub fn new(experiment: impl Into<String>, title: impl Into<String>, runs: usize, seed: u64) -> Self {
        Self {
            experiment: experiment.into(),
            title: title.into(),
            runs,
            seed,
            scenarios: Vec::new(),
            metrics: Vec::new(),
            tables: Vec::new(),
            figures: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// The metric called `name`, if reported.
    #[must_use]
    pub fn metric(&self, name: &str) -> Option<&Metric> {
        self.metrics.iter().find(|m| m.name == name)
    }
}
