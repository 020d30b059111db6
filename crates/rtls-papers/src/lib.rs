//! # rtls-papers
//!
//! The five seed papers' experiments on simulated data, behind `rtls repro`: each reads its
//! TOML scenario files, builds the truth and the sensor streams with `rtls-sim`, runs the
//! paper's method and ours through seeded Monte Carlo, and returns a report (metric | paper |
//! ours | bound, tables, figures as data, notes).
//!
//! ## What this crate owns
//! - [`experiments`] — the five reproductions (`mekf`, `ukf-uwb`, `lwknn`, `wsn-ekf`, `vdkf`),
//!   read from the scenario files in `crates/rtls-papers/scenarios/` (embedded at compile time;
//!   `rtls repro --scenarios DIR` reads edited copies), each returning a
//!   [`report::ExperimentReport`].
//! - [`reproduction`] — one seeded run of each paper's experiment, with every estimate (the
//!   examples in `examples/` print them).
//! - [`recording`] — a scenario as a site file, records and truth (what `rtls sim` writes),
//!   and `rtls_engine::tracker::Tracker` run on it: every "ours" row goes through it.
//! - [`report`] — the report's plain, serialisable types; the `rtls` binary renders them as
//!   tables, JSON lines, markdown and plots.
//! - The report prose: one markdown template per experiment in `crates/rtls-papers/templates/`
//!   (embedded at compile time), whose `{key}` placeholders the experiments fill with the
//!   numbers of the runs.
//!
//! ## What it may import
//! `rtls-sim` (trajectories, sensors, site layouts, metrics, the PCRB, Monte Carlo),
//! `rtls-engine`, `rtls-estimation` and `rtls-positioning`. Nothing in the workspace depends on
//! it except the `rtls` binary (crate rtls-cli): it is the top of the house, so the simulator,
//! the engine and the server never see the papers. Numeric only: no I/O, no async, no global
//! randomness.
//!
//! Errors are the simulation's [`SimError`] (re-exported): a bad scenario file names the file
//! and the field, a failing filter step its simulation time.
//!
//! ## Example: one experiment, two runs
//! ```
//! use rtls_papers::experiments::{ExperimentId, ReproOptions};
//! use rtls_sim::montecarlo::Progress;
//!
//! let id = ExperimentId::Vdkf;
//! let options = ReproOptions { runs: 2, seed: 7 };
//! let report = id.reproduce(&id.embedded_scenarios(), &options, Progress::none())?;
//! assert_eq!(report.experiment, "vdkf");
//! assert!(report.metrics.iter().all(|m| m.ours.is_finite()));
//! # Ok::<(), rtls_papers::SimError>(())
//! ```

mod error;
pub mod experiments;
pub mod recording;
pub mod report;
pub mod reproduction;

pub use error::{Result, SimError};
