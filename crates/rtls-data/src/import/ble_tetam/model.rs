//! What the BLE importer derives from the tracks: path-loss fits, the cell radio map, the
//! RSSI records, the 1-s scans and the ground truth.

use std::collections::BTreeMap;

use rtls_engine::radio_map::RadioMapRow;
use rtls_engine::record::{AnchorReading, Measurement, Record};
use rtls_positioning::pathloss::{fit_per_anchor, LogDistanceFit, RssiSample};
use rtls_positioning::PositioningError;

use super::tracks::{Sensor, Track};
use crate::import::TruthRow;
use crate::Result;

/// Side of a radio-map cell, m.
pub(super) const CELL_M: f64 = 0.5;

/// A cell enters the radio map with at least this many samples (all sensors together).
///
/// 12 is one sample per sensor on average, about half a second of data at the dataset's ~23
/// samples/s: with fewer, most sensors of the cell would rest on a single reading, whose
/// shadowing alone is ~5 dB (1σ, the path-loss fit's residual), and the cell's fingerprint
/// could not list every sensor that hears it. Dropped cells are counted. A leave-one-track-out
/// WKNN check (numpy prototype, not kept) gave the same mean error, 1.90–1.91 m, for
/// thresholds 1, 5, 10 and 20, so the choice trades map coverage for cell quality, not accuracy.
pub(super) const MIN_CELL_SAMPLES: usize = 12;

/// Length of the scan windows of `measurements-vectors.jsonl`, s.
pub(super) const WINDOW_S: f64 = 1.0;

/// Reference distance of the fitted path-loss laws, m.
pub(super) const REFERENCE_DISTANCE_M: f64 = 1.0;

/// The radio map built from some tracks, and what went into it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct CellMap {
    /// One row per kept cell (cell centre, mean RSSI per sensor), cells in `(x, y)` index order.
    pub rows: Vec<RadioMapRow>,
    /// Samples in the kept cells.
    pub samples_used: usize,
    /// Cells dropped for having fewer than [`MIN_CELL_SAMPLES`] samples.
    pub cells_dropped: usize,
    /// Samples in the dropped cells.
    pub samples_dropped: usize,
}

/// The radio map of `tracks`: the samples binned in [`CELL_M`] × [`CELL_M`] cells of the true
/// `(x, y)`; per kept cell the arithmetic mean of each sensor's RSSI in dBm (a sensor never
/// heard in the cell is empty), at the cell centre.
pub(super) fn radio_map(tracks: &[&Track], sensors: usize) -> CellMap {
    // (ix, iy) → per sensor (Σ rssi, count)
    let mut cells: BTreeMap<(i64, i64), Vec<(f64, usize)>> = BTreeMap::new();
    for sample in tracks.iter().flat_map(|t| &t.samples) {
        let key = (
            (sample.position_m[0] / CELL_M).floor() as i64,
            (sample.position_m[1] / CELL_M).floor() as i64,
        );
        let cell = cells.entry(key).or_insert_with(|| vec![(0.0, 0); sensors]);
        cell[sample.sensor].0 += sample.rssi_dbm;
        cell[sample.sensor].1 += 1;
    }
    let mut map = CellMap {
        rows: Vec::new(),
        samples_used: 0,
        cells_dropped: 0,
        samples_dropped: 0,
    };
    for ((ix, iy), cell) in cells {
        let samples: usize = cell.iter().map(|&(_, n)| n).sum();
        if samples < MIN_CELL_SAMPLES {
            map.cells_dropped += 1;
            map.samples_dropped += samples;
            continue;
        }
        map.samples_used += samples;
        map.rows.push(RadioMapRow {
            // cell centre
            position_m: [(ix as f64 + 0.5) * CELL_M, (iy as f64 + 0.5) * CELL_M],
            floor: None,
            // mean RSSI (dBm) per sensor, None where never heard
            rssi_dbm: cell.iter().map(|&(sum, n)| (n > 0).then(|| sum / n as f64)).collect(),
        });
    }
    map
}

/// Per-sensor log-distance fits (OLS, `d₀` = [`REFERENCE_DISTANCE_M`]) on every sample of
/// `tracks` against the true 3-D beacon–sensor distance; one result per sensor (a sensor whose
/// fit fails keeps its error).
///
/// # Errors
/// The table errors of `fit_per_anchor` (a zero distance: the beacon on a sensor).
pub(super) fn fit_path_loss(
    tracks: &[&Track],
    sensors: &[Sensor],
) -> Result<Vec<core::result::Result<LogDistanceFit, PositioningError>>> {
    let samples: Vec<RssiSample> = tracks
        .iter()
        .flat_map(|t| &t.samples)
        .map(|s| RssiSample {
            anchor: s.sensor,
            distance_m: distance_m(s.position_m, sensors[s.sensor].position_m),
            rssi_dbm: s.rssi_dbm,
        })
        .collect();
    Ok(fit_per_anchor(&samples, sensors.len(), REFERENCE_DISTANCE_M)?)
}

/// `‖a − b‖`, m.
fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// One `rssi` record per sample, in time order.
pub(super) fn rssi_records(track: &Track, sensors: &[Sensor]) -> Vec<Record> {
    track
        .samples
        .iter()
        .map(|s| Record {
            time_s: s.time_s,
            tag: s.beacon.clone(),
            measurement: Measurement::Rssi {
                anchor: sensors[s.sensor].alias.clone(),
                rssi_dbm: s.rssi_dbm,
            },
        })
        .collect()
}

/// One `rssi_vector` scan per beacon and [`WINDOW_S`] window `[n, n + 1)` s of Unix time that
/// holds samples, stamped at the window end `n + 1`: per sensor heard in the window, the
/// arithmetic mean of its RSSI in dBm, sensors in list order. Time order, then beacon.
pub(super) fn vector_records(track: &Track, sensors: &[Sensor]) -> Vec<Record> {
    // (window, beacon) → per sensor (Σ rssi, count)
    let mut windows: BTreeMap<(i64, &str), Vec<(f64, usize)>> = BTreeMap::new();
    for s in &track.samples {
        let window = (s.time_s / WINDOW_S).floor() as i64;
        let cell = windows
            .entry((window, s.beacon.as_str()))
            .or_insert_with(|| vec![(0.0, 0); sensors.len()]);
        cell[s.sensor].0 += s.rssi_dbm;
        cell[s.sensor].1 += 1;
    }
    windows
        .into_iter()
        .map(|((window, beacon), cell)| Record {
            // the window's end
            time_s: (window + 1) as f64 * WINDOW_S,
            tag: beacon.to_string(),
            measurement: Measurement::RssiVector {
                readings: cell
                    .iter()
                    .zip(sensors)
                    .filter(|((_, n), _)| *n > 0)
                    .map(|(&(sum, n), sensor)| AnchorReading {
                        anchor: sensor.alias.clone(),
                        rssi_dbm: sum / n as f64,
                    })
                    .collect(),
            },
        })
        .collect()
}

/// The true 3-D beacon position at each distinct `(time stamp, beacon)`, in time order; and
/// the number of rows that repeat a time stamp with a *different* position (the first is kept).
pub(super) fn truth_rows(track: &Track) -> (Vec<TruthRow>, usize) {
    let mut rows: Vec<TruthRow> = Vec::new();
    let mut conflicts = 0;
    for s in &track.samples {
        // samples are time-sorted: a repeated stamp is among the rows of that stamp at the end
        let repeated = rows
            .iter()
            .rev()
            .take_while(|r| r.time_s == s.time_s)
            .find(|r| r.tag == s.beacon);
        match repeated {
            Some(row) => conflicts += usize::from(row.position_m[..] != s.position_m[..]),
            None => rows.push(TruthRow {
                time_s: s.time_s,
                tag: s.beacon.clone(),
                position_m: s.position_m.to_vec(),
            }),
        }
    }
    (rows, conflicts)
}

/// Median true beacon height of the samples of `tracks`, m (the mean of the two middle values
/// for an even count); `None` without samples.
pub(super) fn median_height_m(tracks: &[&Track]) -> Option<f64> {
    let mut z: Vec<f64> = tracks
        .iter()
        .flat_map(|t| &t.samples)
        .map(|s| s.position_m[2])
        .collect();
    if z.is_empty() {
        return None;
    }
    z.sort_unstable_by(f64::total_cmp);
    let n = z.len();
    Some(if n % 2 == 1 {
        z[n / 2]
    } else {
        0.5 * (z[n / 2 - 1] + z[n / 2])
    })
}
