//! The deployment: drifts, the cross-cut, readers on the walls, the collapse and its hazard
//! zone, and the radio model of the readers.

use rtls_engine::zones::{Shape, Zone, ZoneKind};

use crate::error::{Result, SimError};

/// Seed 000's drifts: how many, and their spacing and length, m.
const SEED_000_DRIFTS: usize = 7;
const SEED_000_DRIFT_SPACING_M: f64 = 40.0;
const SEED_000_DRIFT_LENGTH_M: f64 = 600.0;
/// Readers along a drift, one every this many metres, on alternating walls.
const SEED_000_READER_SPACING_M: f64 = 15.0;
/// Readers hang on the walls, this far from the drift's centreline, m.
const SEED_000_WALL_OFFSET_M: f64 = 2.5;

/// One fixed RSSI reader.
#[derive(Debug, Clone, PartialEq)]
pub struct MineReader {
    /// Unique id, e.g. `D3-28` (drift 3, 28th reader from the west end) or `X-04` (cross-cut).
    pub id: String,
    /// Position `[x, y]` in plan, m.
    pub position_m: [f64; 2],
    /// `false` for a broken reader: it hears nothing.
    pub working: bool,
}

/// A drift: a straight east–west tunnel at `y = y_m`.
#[derive(Debug, Clone, PartialEq)]
pub struct Drift {
    /// Human-readable name, e.g. `Drift 3`.
    pub name: String,
    /// The drift's centreline, m.
    pub y_m: f64,
    /// The drift's extent `[west, east]` along x, m.
    pub x_range_m: [f64; 2],
    /// Where miners walk on it along x `[west, east]`, m (inside `x_range_m`; on the collapsed
    /// drift, only the part west of the collapse with a margin).
    pub walkable_x_m: [f64; 2],
}

/// The north–south cross-cut at `x = x_m` that joins every drift.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossCut {
    /// Human-readable name.
    pub name: String,
    /// The cross-cut's centreline, m.
    pub x_m: f64,
    /// Its extent `[south, north]` along y, m: from the first drift's centreline to the last's.
    pub y_range_m: [f64; 2],
}

/// A roof fall across a drift: its reader is broken and the rubble shields the section, so a
/// miner inside is heard by no reader.
#[derive(Debug, Clone, PartialEq)]
pub struct Collapse {
    /// Index into [`MineLayout::drifts`] of the drift the roof fell on.
    pub drift: usize,
    /// The collapsed section `[west, east]` along x, m.
    pub x_range_m: [f64; 2],
    /// Id of the broken reader inside the section.
    pub broken_reader: String,
    /// Id of the hazard zone in the site file (used in alarms).
    pub zone_id: String,
    /// Name of the hazard zone.
    pub zone_name: String,
    /// The hazard zone's polygon `[x, y]`, m: the section as the map draws it, wider than the
    /// tunnel (see [`MineLayout::seed000`]).
    pub zone_polygon_m: Vec<[f64; 2]>,
    /// Where the miners who walk into the collapse at the start are placed along x, m (west of
    /// the collapse, so the tracker sees them approach).
    pub approach_start_x_m: [f64; 2],
}

/// The readers' radio: log-distance path loss with Gaussian shadowing, and the sensitivity
/// below which a scan does not hear a tag.
///
/// `ρ = P₀ − 10 η log₁₀(max(d, d_min)) + X`, `X ~ N(0, σ²)`, heard when `ρ ≥ ρ_min`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MineRadio {
    /// `P₀`: mean RSSI at 1 m, dBm.
    pub reference_power_dbm: f64,
    /// `η`: path-loss exponent.
    pub exponent: f64,
    /// `σ`: shadowing standard deviation, dB.
    pub shadowing_std_db: f64,
    /// `ρ_min`: the reader's sensitivity, dBm.
    pub sensitivity_dbm: f64,
    /// `d_min`: distances are clamped to at least this, m.
    pub min_distance_m: f64,
    /// Readers further than this from a tag are not simulated (and so never hear it), m; a
    /// speed-up that also fixes how much randomness a scan draws.
    pub max_range_m: f64,
}

/// A simulated coal mine: parallel drifts joined by a cross-cut, RSSI readers on the walls,
/// and a roof fall whose reader is broken.
///
/// All fields are public so a caller can draw the map; [`MineLayout::seed000`] gives seed
/// 000's deployment, and [`crate::mine::MineSimulation::new`] checks a layout before using it.
///
/// # Examples
/// ```
/// use rtls_sim::mine::MineLayout;
/// let mine = MineLayout::seed000();
/// assert_eq!(mine.readers.len(), 307);
/// assert!(mine.in_collapse([420.0, 120.5]));
/// assert!(!mine.in_collapse([420.0, 160.0]));
/// assert_eq!(mine.drift_at([100.0, 81.0]), Some(2));
/// assert!(!mine.inside_tunnels([100.0, 20.0])); // rock between drifts 0 and 1
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MineLayout {
    /// The mine's name (the site file's `name`).
    pub name: String,
    /// Every reader, working or not.
    pub readers: Vec<MineReader>,
    /// The drifts, south to north.
    pub drifts: Vec<Drift>,
    /// The cross-cut joining them.
    pub cross_cut: CrossCut,
    /// The roof fall.
    pub collapse: Collapse,
    /// Half the tunnels' width (centreline to wall), m.
    pub tunnel_half_width_m: f64,
    /// The readers' radio.
    pub radio: MineRadio,
}

impl MineLayout {
    /// Seed 000's deployment at its scale.
    ///
    /// Seven drifts 600 m long at `y = 0, 40, …, 240` m, a reader every 15 m on alternating
    /// walls (`y ∓ 2.5` m; 7 × 41 = 287 readers, `D{drift}-{k:02}`) and a cross-cut at
    /// `x = 300` m with 20 readers (`X-{k:02}` at `y = 6 + 12 k`, `x = 300 ∓ 2.5`): 307 readers.
    /// The roof fell on drift 3 (`y = 120` m) between `x = 400` and `440` m; its reader `D3-28`
    /// (`x = 420` m) is broken. The hazard zone is the band closer to drift 3 than to its
    /// neighbours (`y = 120 ± 19.5` m), since with readers along one line the estimate's
    /// cross-track error reaches several metres. Radio: `ρ = −40 − 30 log₁₀ d + N(0, 3²)` dBm,
    /// heard when `ρ ≥ −82` dBm (median range 25 m). Miners walk `x ∈ [10, 590]` m, on drift 3
    /// only `[10, 380]` m (west of the collapse with 20 m to spare).
    ///
    /// # References
    /// Seed 000 §3.3 and Fig. 2 (307 readers, 600 miners, a reader broken by a collapse).
    #[must_use]
    pub fn seed000() -> Self {
        let collapse_drift = 3;
        let collapse_x_m = [400.0, 440.0];
        let broken_reader = 28; // x = 420 m
        let readers_per_drift = (SEED_000_DRIFT_LENGTH_M / SEED_000_READER_SPACING_M) as usize + 1;
        let wall = |k: usize| {
            if k.is_multiple_of(2) {
                -SEED_000_WALL_OFFSET_M
            } else {
                SEED_000_WALL_OFFSET_M
            }
        };
        let mut readers = Vec::with_capacity(SEED_000_DRIFTS * readers_per_drift + 20);
        let mut drifts = Vec::with_capacity(SEED_000_DRIFTS);
        for drift in 0..SEED_000_DRIFTS {
            let y_m = drift as f64 * SEED_000_DRIFT_SPACING_M;
            for k in 0..readers_per_drift {
                readers.push(MineReader {
                    id: format!("D{drift}-{k:02}"),
                    position_m: [k as f64 * SEED_000_READER_SPACING_M, y_m + wall(k)],
                    working: !(drift == collapse_drift && k == broken_reader),
                });
            }
            let walkable_east_m = if drift == collapse_drift {
                collapse_x_m[0] - 20.0
            } else {
                SEED_000_DRIFT_LENGTH_M - 10.0
            };
            drifts.push(Drift {
                name: format!("Drift {drift}"),
                y_m,
                x_range_m: [0.0, SEED_000_DRIFT_LENGTH_M],
                walkable_x_m: [10.0, walkable_east_m],
            });
        }
        let cross_cut_x_m = 300.0;
        for k in 0..20 {
            readers.push(MineReader {
                id: format!("X-{k:02}"),
                position_m: [cross_cut_x_m + wall(k), 6.0 + 12.0 * k as f64],
                working: true,
            });
        }
        let y_m = collapse_drift as f64 * SEED_000_DRIFT_SPACING_M;
        let [x0, x1] = collapse_x_m;
        let (y0, y1) = (y_m - 19.5, y_m + 19.5);
        Self {
            name: "simulated mine (seed 000 scale)".into(),
            readers,
            cross_cut: CrossCut {
                name: "Cross-cut".into(),
                x_m: cross_cut_x_m,
                y_range_m: [0.0, (SEED_000_DRIFTS - 1) as f64 * SEED_000_DRIFT_SPACING_M],
            },
            drifts,
            collapse: Collapse {
                drift: collapse_drift,
                x_range_m: collapse_x_m,
                broken_reader: format!("D{collapse_drift}-{broken_reader:02}"),
                zone_id: "collapse".into(),
                zone_name: format!("Roof fall, drift {collapse_drift}"),
                zone_polygon_m: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
                approach_start_x_m: [260.0, 340.0],
            },
            tunnel_half_width_m: SEED_000_WALL_OFFSET_M,
            radio: MineRadio {
                reference_power_dbm: -40.0,
                exponent: 3.0,
                shadowing_std_db: 3.0,
                sensitivity_dbm: -82.0,
                min_distance_m: 0.1,
                max_range_m: 60.0,
            },
        }
    }

    /// The drift whose tunnel contains `position_m` (within the half-width of its centreline
    /// and inside its extent), if any.
    #[must_use]
    pub fn drift_at(&self, position_m: [f64; 2]) -> Option<usize> {
        let [x, y] = position_m;
        self.drifts.iter().position(|drift| {
            (y - drift.y_m).abs() <= self.tunnel_half_width_m && (drift.x_range_m[0]..=drift.x_range_m[1]).contains(&x)
        })
    }

    /// Whether `position_m` lies in the cross-cut's tunnel.
    #[must_use]
    pub fn in_cross_cut(&self, position_m: [f64; 2]) -> bool {
        let [x, y] = position_m;
        let [south, north] = self.cross_cut.y_range_m;
        (x - self.cross_cut.x_m).abs() <= self.tunnel_half_width_m
            && (south - self.tunnel_half_width_m..=north + self.tunnel_half_width_m).contains(&y)
    }

    /// Whether `position_m` lies in a tunnel (a drift or the cross-cut), not in the rock.
    #[must_use]
    pub fn inside_tunnels(&self, position_m: [f64; 2]) -> bool {
        self.drift_at(position_m).is_some() || self.in_cross_cut(position_m)
    }

    /// Whether `position_m` lies in the collapsed section of the tunnel (where no reader hears
    /// a tag). This is the tunnel section, narrower than the hazard zone's polygon.
    #[must_use]
    pub fn in_collapse(&self, position_m: [f64; 2]) -> bool {
        let [west, east] = self.collapse.x_range_m;
        self.drift_at(position_m) == Some(self.collapse.drift) && (west..=east).contains(&position_m[0])
    }

    /// The zones of the site: the collapse as a hazard zone (with its broken reader), then, if
    /// `options.drift_zones`, one area of interest per drift (the band closer to that drift
    /// than to its neighbours, over its length) for head counts per drift.
    ///
    /// # Examples
    /// ```
    /// use rtls_sim::mine::{MineLayout, SiteOptions};
    /// let mine = MineLayout::seed000();
    /// let zones = mine.zones(&SiteOptions::default());
    /// assert_eq!(zones.len(), 1);
    /// assert_eq!(zones[0].id, "collapse");
    /// let with_drifts = mine.zones(&SiteOptions { drift_zones: true, ..SiteOptions::default() });
    /// assert_eq!(with_drifts.len(), 8);
    /// ```
    #[must_use]
    pub fn zones(&self, options: &super::SiteOptions) -> Vec<Zone> {
        let mut zones = vec![Zone {
            id: self.collapse.zone_id.clone(),
            name: self.collapse.zone_name.clone(),
            kind: ZoneKind::Hazard,
            readers: vec![self.collapse.broken_reader.clone()],
            shape: polygon(self.collapse.zone_polygon_m.clone()),
        }];
        if options.drift_zones {
            for (index, drift) in self.drifts.iter().enumerate() {
                // half-way to the neighbouring drifts (or as far as the nearest one on the
                // outer edges)
                let south_m = index
                    .checked_sub(1)
                    .and_then(|i| self.drifts.get(i))
                    .map_or(drift.y_m - self.half_spacing_m(index), |d| (d.y_m + drift.y_m) / 2.0);
                let north_m = self
                    .drifts
                    .get(index + 1)
                    .map_or(drift.y_m + self.half_spacing_m(index), |d| (d.y_m + drift.y_m) / 2.0);
                let [west, east] = drift.x_range_m;
                zones.push(Zone {
                    id: format!("drift-{index}"),
                    name: drift.name.clone(),
                    kind: ZoneKind::AreaOfInterest,
                    readers: Vec::new(),
                    shape: polygon(vec![[west, south_m], [east, south_m], [east, north_m], [west, north_m]]),
                });
            }
        }
        zones
    }

    /// Half the distance from drift `index` to its nearest neighbour (the tunnel's half-width
    /// for a single drift).
    fn half_spacing_m(&self, index: usize) -> f64 {
        let y_m = self.drifts[index].y_m;
        self.drifts
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != index)
            .map(|(_, d)| (d.y_m - y_m).abs() / 2.0)
            .fold(None, |nearest: Option<f64>, d| Some(nearest.map_or(d, |n| n.min(d))))
            .unwrap_or(self.tunnel_half_width_m)
    }

    /// Checks what the simulation relies on: at least one drift and one reader, finite
    /// coordinates, ordered ranges, each drift's walkable part inside it and reaching the
    /// cross-cut, the cross-cut spanning every drift, the collapse on an existing drift, and a
    /// physical radio.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] for no drifts or readers; [`SimError::NonFinite`] for NaN/∞;
    /// [`SimError::InvalidParameter`] naming the field that breaks a rule.
    pub fn validate(&self) -> Result<()> {
        if self.drifts.is_empty() {
            return Err(SimError::EmptyInput {
                what: "mine layout drifts",
            });
        }
        if self.readers.is_empty() {
            return Err(SimError::EmptyInput {
                what: "mine layout readers",
            });
        }
        let invalid = |name, reason| Err(SimError::InvalidParameter { name, reason });
        if self.readers.iter().any(|r| !r.position_m.iter().all(|v| v.is_finite())) {
            return Err(SimError::NonFinite {
                what: "reader position",
            });
        }
        if !(self.tunnel_half_width_m.is_finite() && self.tunnel_half_width_m > 0.0) {
            return invalid("tunnel_half_width_m", "must be finite and > 0");
        }
        let [south, north] = self.cross_cut.y_range_m;
        if !(self.cross_cut.x_m.is_finite() && south.is_finite() && north.is_finite() && south <= north) {
            return invalid(
                "cross_cut",
                "needs a finite x_m and y_range_m = [south, north] with south ≤ north",
            );
        }
        for drift in &self.drifts {
            let [x0, x1] = drift.x_range_m;
            let [w0, w1] = drift.walkable_x_m;
            if ![drift.y_m, x0, x1, w0, w1].iter().all(|v| v.is_finite()) {
                return Err(SimError::NonFinite { what: "drift" });
            }
            if !(x0 <= w0 && w0 < w1 && w1 <= x1) {
                return invalid(
                    "drifts.walkable_x_m",
                    "must be [west, east] with west < east, inside x_range_m",
                );
            }
            if !(w0..=w1).contains(&self.cross_cut.x_m) || !(south..=north).contains(&drift.y_m) {
                return invalid("cross_cut", "must cross every drift within the drift's walkable part");
            }
        }
        let collapse = &self.collapse;
        let Some(drift) = self.drifts.get(collapse.drift) else {
            return invalid("collapse.drift", "must index one of the layout's drifts");
        };
        let [c0, c1] = collapse.x_range_m;
        let [a0, a1] = collapse.approach_start_x_m;
        if ![c0, c1, a0, a1].iter().all(|v| v.is_finite()) {
            return Err(SimError::NonFinite { what: "collapse" });
        }
        if !(c0 + 10.0 < c1 && drift.x_range_m[0] <= c0 && c1 <= drift.x_range_m[1]) {
            return invalid(
                "collapse.x_range_m",
                "must be [west, east], over 10 m long, inside its drift",
            );
        }
        // (all finite here)
        if drift.walkable_x_m[1] >= c0 {
            return invalid("collapse", "its drift's walkable part must end west of the collapse");
        }
        if !(drift.walkable_x_m[0] <= a0 && a0 <= a1 && a1 < c0) {
            return invalid(
                "collapse.approach_start_x_m",
                "must be [west, east] in the drift's walkable part west of the collapse",
            );
        }
        let radio = &self.radio;
        let radio_values = [
            radio.reference_power_dbm,
            radio.exponent,
            radio.shadowing_std_db,
            radio.sensitivity_dbm,
            radio.min_distance_m,
            radio.max_range_m,
        ];
        if !radio_values.iter().all(|v| v.is_finite()) {
            return Err(SimError::NonFinite { what: "mine radio" });
        }
        if !(radio.exponent >= 0.0 && radio.shadowing_std_db >= 0.0 && radio.min_distance_m > 0.0) {
            return invalid(
                "radio",
                "needs exponent ≥ 0, shadowing_std_db ≥ 0 and min_distance_m > 0",
            );
        }
        if radio.max_range_m <= 0.0 {
            return invalid("radio.max_range_m", "must be > 0");
        }
        Ok(())
    }
}

/// A polygon zone shape at every height.
fn polygon(vertices_m: Vec<[f64; 2]>) -> Shape {
    Shape::Polygon {
        vertices_m,
        floor: None,
        z_range_m: None,
    }
}
