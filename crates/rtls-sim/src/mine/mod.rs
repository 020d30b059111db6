//! A simulated coal mine at seed 000's scale, as a library: the deployment ([`MineLayout`]:
//! drifts, a cross-cut, 307 RSSI readers, a roof fall whose reader is broken), the site file
//! the tracker needs for it ([`MineLayout::site_toml`]), and a live, endless, deterministic
//! feed of the readers' scans of the miners ([`MineSimulation`]), for `rtls serve --demo` and
//! for the tests of the tracker on the mine.
//!
//! - [`MineLayout::seed000`] — seven drifts 600 m long, 40 m apart, with a reader every 15 m on
//!   alternating walls; a cross-cut at x = 300 m; the roof fall on drift 3 between x = 400 and
//!   440 m, shielded, its reader broken; log-distance radio with 3 dB shadowing.
//! - [`MineConfig::seed000_scenario`] — the scenario the mine test checks the tracker on (600
//!   miners patrolling their drifts, 30 walking into the collapse).
//! - [`MineConfig::default`] — the demo: miners who walk, rest, turn back, change drift through
//!   the cross-cut, and one sent into the collapse every 2 minutes, so predictive hazard alarms
//!   keep coming.
//!
//! This is a different model from [`crate::scenarios::seed_000`]'s mine section (3-D tunnels
//! with line-of-sight radio for the paper's reproduction): here the geometry is the flat grid of
//! the engine's scale test, and the feed is stepped in real time.
//!
//! # Examples
//! ```
//! use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, SiteOptions};
//! let layout = MineLayout::seed000();
//! let site_file = layout.site_toml(&SiteOptions::default());
//! assert!(site_file.contains("kind = \"hazard\""));
//! let config = MineConfig { miners: 20, entering_miners: 2, start_time_s: 1.7e9, ..MineConfig::default() };
//! let mut mine = MineSimulation::new(layout, config)?;
//! for second in 1..=3 {
//!     let records = mine.step(1.7e9 + f64::from(second)); // what the server does every second
//!     assert!(!records.is_empty());
//! }
//! # Ok::<(), rtls_sim::SimError>(())
//! ```
//!
//! # References
//! Seed 000 §3.3 and Fig. 2: 307 readers, 600 miners, predictive early warning around a
//! collapsed area whose reader is broken.

mod layout;
mod simulation;
mod site;
mod walk;

#[cfg(test)]
mod tests;

pub use layout::{Collapse, CrossCut, Drift, MineLayout, MineRadio, MineReader};
pub use simulation::{MineConfig, MineSimulation, RoamingSettings, WalkModel};
pub use site::SiteOptions;
