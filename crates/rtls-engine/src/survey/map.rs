//! The survey map: residual statistics per (cell, reader, kind) and per (reader, kind), their
//! flags, and the bias-correction table.

use std::collections::{BTreeMap, HashMap};

use super::stats::{median_and_mad, RunningStats, MAD_TO_STD};
use super::{Residual, ResidualKind, SurveySettings, MIN_POPULATION};
use crate::error::{EngineError, Result};
use crate::record::{AnchorReading, Measurement, Record};

/// The `file` that [`SurveyMap::build`] names in errors about a residual (line = its 1-based
/// index).
const RESIDUALS_SOURCE: &str = "residuals";

/// Why an entry is flagged as degraded (all `false`: not flagged).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Degradation {
    /// Its bias departs from the population's in the obstacle's direction (RSSI lower, range
    /// longer) by at least the robust z threshold and the minimum effect.
    pub bias: bool,
    /// Its spread exceeds the population's by at least the robust z threshold and the minimum
    /// effect (only when [`SurveySettings::flag_spread`] is set).
    pub spread: bool,
    /// Reader entries only: at least one of the reader's cells (same kind) is flagged.
    pub cells: bool,
}

impl Degradation {
    /// `true` when degraded for any reason.
    #[must_use]
    pub fn any(self) -> bool {
        self.bias || self.spread || self.cells
    }

    /// The `reason` column: the reasons that hold, joined by `+` in field order (`bias`,
    /// `spread`, `cells`, e.g. `bias+cells`), empty when none does.
    #[must_use]
    pub fn name(self) -> String {
        let reasons = [(self.bias, "bias"), (self.spread, "spread"), (self.cells, "cells")];
        let names: Vec<&str> = reasons.iter().filter(|(on, _)| *on).map(|(_, name)| *name).collect();
        names.join("+")
    }

    /// The degradation named `name` (as [`Degradation::name`] writes it).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        (0..8u8)
            .map(|bits| Self {
                bias: bits & 1 != 0,
                spread: bits & 2 != 0,
                cells: bits & 4 != 0,
            })
            .find(|d| d.name() == name)
    }
}

/// The residual statistics of one entry and its score against the population.
///
/// # Units
/// `bias` and `std` in the kind's unit (dB for RSSI, m for ranges); `distance_m` in m; `z` and
/// `spread_z` without unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Number of residuals `n` (≥ 1).
    pub count: usize,
    /// Mean slant distance from the reader to the tracked positions, m.
    pub distance_m: f64,
    /// Mean residual `b`.
    pub bias: f64,
    /// Sample standard deviation of the residuals, `None` when `n < 2`.
    pub std: Option<f64>,
    /// Robust z score of the bias, `(b − m) / σ̂`; `None` when not scored (`n < min_count`,
    /// or a population smaller than [`MIN_POPULATION`]).
    pub z: Option<f64>,
    /// Robust z score of the spread, the same way; `None` when not scored.
    pub spread_z: Option<f64>,
    /// Whether (and why) the entry is degraded.
    pub degraded: Degradation,
}

/// Running statistics of an entry while residuals are added.
#[derive(Debug, Clone, Copy, Default)]
struct Accumulator {
    residuals: RunningStats,
    distance_sum_m: f64,
}

impl Accumulator {
    fn push(&mut self, residual: &Residual) {
        self.residuals.push(residual.value);
        self.distance_sum_m += residual.distance_m;
    }

    fn summary(&self) -> Summary {
        let count = self.residuals.count();
        Summary {
            count,
            distance_m: self.distance_sum_m / count.max(1) as f64,
            bias: self.residuals.mean().unwrap_or(0.0),
            std: self.residuals.std(),
            z: None,
            spread_z: None,
            degraded: Degradation::default(),
        }
    }
}

/// The residuals of one reader's measurements of one kind taken in one area cell.
#[derive(Debug, Clone, PartialEq)]
pub struct CellEntry {
    /// The cell `[i, j]` ([`SurveySettings::cell_of`], [`SurveySettings::cell_bounds_m`]).
    pub cell: [i64; 2],
    /// Reader id.
    pub reader: String,
    /// Range or RSSI.
    pub kind: ResidualKind,
    /// Statistics and flags.
    pub summary: Summary,
}

/// The residuals of one reader's measurements of one kind, over all cells.
#[derive(Debug, Clone, PartialEq)]
pub struct ReaderEntry {
    /// Reader id.
    pub reader: String,
    /// Range or RSSI.
    pub kind: ResidualKind,
    /// Statistics and flags (`degraded.cells` when `flagged_cells > 0`).
    pub summary: Summary,
    /// How many of the reader's cell entries of this kind are flagged.
    pub flagged_cells: usize,
}

/// Where a correction comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CorrectionSource {
    /// The reader's entry in the cell of the position.
    Cell,
    /// The reader's entry over all cells (its cell had fewer than `min_count` residuals).
    Reader,
}

/// A learned bias to subtract from a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correction {
    /// The bias, in the kind's unit (dB for RSSI, m for ranges).
    pub bias: f64,
    /// Residuals it was learned from.
    pub count: usize,
    /// Cell or reader entry.
    pub source: CorrectionSource,
}

/// Entry indices of one reader and kind.
#[derive(Debug, Clone, Default, PartialEq)]
struct KindIndex {
    reader: Option<usize>,
    cells: HashMap<[i64; 2], usize>,
}

/// The radio-environment map: residual statistics per (cell, reader, kind) and per (reader,
/// kind), flags of degraded entries, and the bias-correction table (see the
/// [module documentation](super) for the rule and an example).
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyMap {
    settings: SurveySettings,
    cells: Vec<CellEntry>,
    readers: Vec<ReaderEntry>,
    /// reader id → per kind ([`ResidualKind::index`]).
    index: HashMap<String, [KindIndex; 2]>,
}

impl SurveyMap {
    /// Accumulates `residuals` per (cell of the tracked position, reader, kind) and per (reader,
    /// kind), then scores and flags every entry against its population.
    ///
    /// Cells are sorted by `(i, j)`, then reader id, then kind; readers by id, then kind.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for settings out of range; [`EngineError::Parse`]
    /// (file `residuals`, line = the residual's 1-based index) for a non-finite value or
    /// position.
    ///
    /// # Examples
    /// See the [module documentation](super).
    pub fn build(residuals: &[Residual], settings: &SurveySettings) -> Result<Self> {
        settings.validate()?;
        let mut cells: BTreeMap<([i64; 2], &str, ResidualKind), Accumulator> = BTreeMap::new();
        let mut readers: BTreeMap<(&str, ResidualKind), Accumulator> = BTreeMap::new();
        for (index, r) in residuals.iter().enumerate() {
            let bad = if !r.value.is_finite() {
                Some("value")
            } else if !(r.distance_m.is_finite() && r.distance_m >= 0.0) {
                Some("distance_m")
            } else {
                r.position_m.iter().any(|v| !v.is_finite()).then_some("position_m")
            };
            if let Some(field) = bad {
                return Err(EngineError::Parse {
                    file: RESIDUALS_SOURCE.to_string(),
                    line: index + 1,
                    field: field.to_string(),
                    reason: "is not a finite number (distances also ≥ 0)".to_string(),
                });
            }
            let cell = settings.cell_of([r.position_m[0], r.position_m[1]]);
            cells.entry((cell, &r.reader, r.kind)).or_default().push(r);
            readers.entry((&r.reader, r.kind)).or_default().push(r);
        }
        let mut cells: Vec<CellEntry> = cells
            .into_iter()
            .map(|((cell, reader, kind), stats)| CellEntry {
                cell,
                reader: reader.to_string(),
                kind,
                summary: stats.summary(),
            })
            .collect();
        let mut readers: Vec<ReaderEntry> = readers
            .into_iter()
            .map(|((reader, kind), stats)| ReaderEntry {
                reader: reader.to_string(),
                kind,
                summary: stats.summary(),
                flagged_cells: 0,
            })
            .collect();
        for kind in ResidualKind::ALL {
            // cells: one population per distance band (the module documentation says why)
            let mut bands: BTreeMap<i64, Vec<&mut Summary>> = BTreeMap::new();
            for entry in cells.iter_mut().filter(|e| e.kind == kind) {
                let band = settings
                    .distance_band_m
                    .map_or(0, |width| (entry.summary.distance_m / width).floor() as i64);
                bands.entry(band).or_default().push(&mut entry.summary);
            }
            for population in bands.into_values() {
                score(population, kind, settings);
            }
            score(
                readers
                    .iter_mut()
                    .filter(|e| e.kind == kind)
                    .map(|e| &mut e.summary)
                    .collect(),
                kind,
                settings,
            );
        }
        let mut flagged_cells: HashMap<(&str, ResidualKind), usize> = HashMap::new();
        for entry in cells.iter().filter(|e| e.summary.degraded.any()) {
            *flagged_cells.entry((entry.reader.as_str(), entry.kind)).or_default() += 1;
        }
        for entry in &mut readers {
            entry.flagged_cells = flagged_cells
                .get(&(entry.reader.as_str(), entry.kind))
                .copied()
                .unwrap_or(0);
            entry.summary.degraded.cells = entry.flagged_cells > 0;
        }
        Ok(Self::assemble(*settings, cells, readers))
    }

    /// A map of given entries (as read from CSV), indexed for [`SurveyMap::correction`]. The
    /// caller has checked that (cell, reader, kind) and (reader, kind) are unique.
    pub(crate) fn assemble(settings: SurveySettings, cells: Vec<CellEntry>, readers: Vec<ReaderEntry>) -> Self {
        let mut index: HashMap<String, [KindIndex; 2]> = HashMap::new();
        for (i, entry) in cells.iter().enumerate() {
            let slot = &mut index.entry(entry.reader.clone()).or_default()[entry.kind.index()];
            slot.cells.insert(entry.cell, i);
        }
        for (i, entry) in readers.iter().enumerate() {
            index.entry(entry.reader.clone()).or_default()[entry.kind.index()].reader = Some(i);
        }
        Self {
            settings,
            cells,
            readers,
            index,
        }
    }

    /// The settings the map was built (or read) with.
    #[must_use]
    pub fn settings(&self) -> &SurveySettings {
        &self.settings
    }

    /// Every (cell, reader, kind) entry.
    #[must_use]
    pub fn cells(&self) -> &[CellEntry] {
        &self.cells
    }

    /// Every (reader, kind) entry.
    #[must_use]
    pub fn readers(&self) -> &[ReaderEntry] {
        &self.readers
    }

    /// The flagged cell entries, most significant first (by `|z|`, then `spread_z`).
    #[must_use]
    pub fn flagged_cells(&self) -> Vec<&CellEntry> {
        let mut flagged: Vec<&CellEntry> = self.cells.iter().filter(|e| e.summary.degraded.any()).collect();
        flagged.sort_by(|a, b| significance(&b.summary).total_cmp(&significance(&a.summary)));
        flagged
    }

    /// The flagged reader entries, most significant first (by `|z|`, then `spread_z`).
    #[must_use]
    pub fn flagged_readers(&self) -> Vec<&ReaderEntry> {
        let mut flagged: Vec<&ReaderEntry> = self.readers.iter().filter(|e| e.summary.degraded.any()).collect();
        flagged.sort_by(|a, b| significance(&b.summary).total_cmp(&significance(&a.summary)));
        flagged
    }

    /// The learned bias of `reader`'s `kind` measurements at `position_m` (`x, y`, m): its
    /// entry in the position's cell when that is flagged for its bias, else its entry over all
    /// cells when that is, else `None`. With [`SurveySettings::correct_unflagged`], any entry
    /// with at least `min_count` residuals corrects (the module documentation says why that
    /// is not the default).
    ///
    /// The kind is a parameter because a reader may measure both ranges and RSSI.
    ///
    /// # Examples
    /// See the [module documentation](super).
    #[must_use]
    pub fn correction(&self, reader: &str, kind: ResidualKind, position_m: [f64; 2]) -> Option<Correction> {
        let slot = &self.index.get(reader)?[kind.index()];
        let enough = |summary: &Summary| {
            summary.count >= self.settings.min_count && (summary.degraded.bias || self.settings.correct_unflagged)
        };
        let cell = self.settings.cell_of(position_m);
        if let Some(entry) = slot.cells.get(&cell).map(|&i| &self.cells[i]) {
            if enough(&entry.summary) {
                return Some(Correction {
                    bias: entry.summary.bias,
                    count: entry.summary.count,
                    source: CorrectionSource::Cell,
                });
            }
        }
        let entry = &self.readers[slot.reader?];
        enough(&entry.summary).then_some(Correction {
            bias: entry.summary.bias,
            count: entry.summary.count,
            source: CorrectionSource::Reader,
        })
    }

    /// `record` with the learned bias subtracted from its range or RSSI readings, given the
    /// tag's last known position `position_m` (`x, y`, m): `ρ' = ρ − b` (dB), `r' = max(r − b,
    /// 0)` (m, a range stays ≥ 0). Readings without a [`SurveyMap::correction`] and other kinds
    /// of record are unchanged.
    ///
    /// # Examples
    /// See the [module documentation](super).
    #[must_use]
    pub fn correct_record(&self, record: &Record, position_m: [f64; 2]) -> Record {
        let bias = |reader: &str, kind| self.correction(reader, kind, position_m).map_or(0.0, |c| c.bias);
        let measurement = match &record.measurement {
            Measurement::Range {
                anchor,
                range_m,
                std_m,
                anchor_position_m,
            } => Measurement::Range {
                anchor: anchor.clone(),
                range_m: (range_m - bias(anchor, ResidualKind::Range)).max(0.0),
                std_m: *std_m,
                anchor_position_m: anchor_position_m.clone(),
            },
            Measurement::Rssi { anchor, rssi_dbm } => Measurement::Rssi {
                anchor: anchor.clone(),
                rssi_dbm: rssi_dbm - bias(anchor, ResidualKind::Rssi),
            },
            Measurement::RssiVector { readings } => Measurement::RssiVector {
                readings: readings
                    .iter()
                    .map(|r| AnchorReading {
                        anchor: r.anchor.clone(),
                        rssi_dbm: r.rssi_dbm - bias(&r.anchor, ResidualKind::Rssi),
                    })
                    .collect(),
            },
            other => other.clone(),
        };
        Record {
            time_s: record.time_s,
            tag: record.tag.clone(),
            measurement,
        }
    }
}

/// How far an entry departs from its population, for ordering flagged entries.
fn significance(summary: &Summary) -> f64 {
    summary.z.map_or(0.0, f64::abs).max(summary.spread_z.unwrap_or(0.0))
}

/// Scores one population (one level and kind): robust z of the biases and of the spreads of
/// the entries with at least `min_count` residuals, and their flags (module documentation).
fn score(mut entries: Vec<&mut Summary>, kind: ResidualKind, settings: &SurveySettings) {
    entries.retain(|e| e.count >= settings.min_count);
    if entries.len() < MIN_POPULATION {
        return;
    }
    let (z_star, effect) = (settings.z_threshold, settings.min_effect(kind));
    let biases: Vec<f64> = entries.iter().map(|e| e.bias).collect();
    // min_count ≥ 2, so every scored entry has a spread
    let spreads: Vec<f64> = entries.iter().map(|e| e.std.unwrap_or(0.0)).collect();
    let (Some((bias_median, bias_mad)), Some((spread_median, spread_mad))) =
        (median_and_mad(&biases), median_and_mad(&spreads))
    else {
        return;
    };
    // σ̂ = max(1.4826 MAD, δ / z*)
    let bias_scale = (MAD_TO_STD * bias_mad).max(effect / z_star);
    let spread_scale = (MAD_TO_STD * spread_mad).max(effect / z_star);
    let sign = kind.degradation_sign();
    for (entry, spread) in entries.into_iter().zip(spreads) {
        // z = (b − m) / σ̂
        let z = (entry.bias - bias_median) / bias_scale;
        let spread_z = (spread - spread_median) / spread_scale;
        entry.z = Some(z);
        entry.spread_z = Some(spread_z);
        entry.degraded.bias = sign * z >= z_star && sign * (entry.bias - bias_median) >= effect;
        entry.degraded.spread = settings.flag_spread && spread_z >= z_star && spread - spread_median >= effect;
    }
}
