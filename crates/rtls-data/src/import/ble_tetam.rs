//! Importer for the BLE RSSI tracks of Daniş et al. ("tetam" area, `../shared/data/
//! ble_rssi_tracking_danis_tetam`): one beacon carried along 9 tracks, 12 fixed sensors, camera
//! ground truth on every RSSI row.
//!
//! One run per track (`trk/<name>_all_sensors.mbd`), written to `OUT/<name>/`:
//! - `measurements.jsonl` — one `rssi` record per valid row (tag = beacon MAC, anchor = sensor
//!   alias), in time order;
//! - `measurements-vectors.jsonl` — one `rssi_vector` scan per 1-s window `[n, n + 1)` of Unix
//!   time, stamped at the window end `n + 1`, each heard sensor's RSSI averaged in dBm;
//! - `truth.csv` — the true 3-D beacon position at every distinct time stamp;
//! - `radio-map.csv` — mean RSSI per sensor in 0.5 m cells of the true position, from the
//!   **other 8 tracks** (leave one track out);
//! - `site.toml` — the 12 sensors (3-D positions from `cnf/tetam.dev`) with a log-distance
//!   path loss per sensor fitted on the other 8 tracks, the radio map reference and the tracker
//!   settings, every choice commented.
//!
//! Rows with an RSSI outside the Bluetooth controller's range (−127 … +20 dBm) are skipped and
//! listed in the run's notes; rows out of time order in the file are sorted and counted.
//!
//! # References
//! F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An indoor localization dataset and
//! data collection framework with high precision position annotation", *Pervasive and Mobile
//! Computing* 81, 2022 (the dataset, CC0).

mod model;
mod tracks;

use std::fmt::Write as _;
use std::path::Path;

use rtls_engine::radio_map::radio_map_csv;
use rtls_positioning::pathloss::LogDistanceFit;
use rtls_positioning::PositioningError;

use self::model::{CellMap, CELL_M, MIN_CELL_SAMPLES, REFERENCE_DISTANCE_M, WINDOW_S};
use self::tracks::{Sensor, Track, RSSI_RANGE_DBM};
use super::{create_dir, write_records, write_text, write_truth, ImportedRun};
use crate::{DataError, Result};

pub(super) fn import(dataset_dir: &Path, out_dir: &Path) -> Result<Vec<ImportedRun>> {
    let sensors = tracks::read_sensors(&dataset_dir.join("cnf").join("tetam.dev"))?;
    let tracks = tracks::track_names(dataset_dir)?
        .iter()
        .map(|name| tracks::read_track(dataset_dir, name, &sensors))
        .collect::<Result<Vec<Track>>>()?;
    let mut runs = Vec::with_capacity(tracks.len());
    for (k, track) in tracks.iter().enumerate() {
        let others: Vec<&Track> = tracks
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != k)
            .map(|(_, t)| t)
            .collect();
        runs.push(import_run(track, &others, &sensors, out_dir)?);
    }
    Ok(runs)
}

/// Writes the run of `track`, calibrated on `others`.
fn import_run(track: &Track, others: &[&Track], sensors: &[Sensor], out_dir: &Path) -> Result<ImportedRun> {
    let dir = out_dir.join(&track.name);
    create_dir(&dir)?;
    let mut notes = Vec::new();
    if !track.implausible_rssi.is_empty() {
        let rows: Vec<String> = track
            .implausible_rssi
            .iter()
            .map(|(line, rssi)| format!("line {line} ({rssi} dBm)"))
            .collect();
        notes.push(format!(
            "skipped {} of {} rows of {}: rssi outside the Bluetooth controller range [{}, {}] dBm: {}",
            rows.len(),
            track.rows,
            track.file.display(),
            RSSI_RANGE_DBM.0,
            RSSI_RANGE_DBM.1,
            rows.join(", ")
        ));
    }
    if track.out_of_order > 0 {
        notes.push(format!(
            "{} rows were earlier than a previous row in the file; all rows are written in time order",
            track.out_of_order
        ));
    }

    let fits = model::fit_path_loss(others, sensors).map_err(|error| DataError::Content {
        file: track.file.with_file_name(""),
        reason: format!(
            "path-loss calibration on the tracks other than `{}`: {error}",
            track.name
        ),
    })?;
    let training_samples: usize = others.iter().map(|t| t.samples.len()).sum();
    notes.push(fit_summary(&fits, sensors, others.len(), training_samples));
    let map = model::radio_map(others, sensors.len());
    notes.push(format!(
        "radio map from the other {} tracks: {} cells of {CELL_M} m × {CELL_M} m kept ({} samples), \
         {} cells with fewer than {MIN_CELL_SAMPLES} samples dropped ({} samples)",
        others.len(),
        map.rows.len(),
        map.samples_used,
        map.cells_dropped,
        map.samples_dropped
    ));
    let tag_height_m = model::median_height_m(others).ok_or_else(|| DataError::Content {
        file: track.file.clone(),
        reason: "no other track to calibrate on (leave-one-track-out needs at least two tracks)".into(),
    })?;
    notes.push(format!(
        "tag_height_m = {tag_height_m:.3} m: median true beacon height of the other tracks' samples"
    ));

    let mut files = Vec::new();
    let site_path = dir.join("site.toml");
    write_text(
        &site_path,
        &site_toml(track, others, sensors, &fits, &map, tag_height_m),
    )?;
    files.push(site_path);

    let records = model::rssi_records(track, sensors);
    let path = dir.join("measurements.jsonl");
    write_records(&path, &records)?;
    files.push(path);

    let scans = model::vector_records(track, sensors);
    notes.push(format!(
        "measurements-vectors.jsonl: {} rssi_vector scans of {WINDOW_S}-s windows [n, n + 1) of Unix time, \
         stamped at the window end n + 1; each heard sensor's rssi is the arithmetic mean in dBm",
        scans.len()
    ));
    let path = dir.join("measurements-vectors.jsonl");
    write_records(&path, &scans)?;
    files.push(path);

    let (truth, conflicts) = model::truth_rows(track);
    if conflicts > 0 {
        notes.push(format!(
            "{conflicts} rows repeat a time stamp with a different true position; the first position is kept"
        ));
    }
    let path = dir.join("truth.csv");
    write_truth(&path, &truth)?;
    files.push(path);

    let reader_ids: Vec<String> = sensors.iter().map(|s| s.alias.clone()).collect();
    let path = dir.join("radio-map.csv");
    let text = radio_map_csv(&reader_ids, &map.rows).map_err(|error| DataError::Content {
        file: path.clone(),
        reason: error.to_string(),
    })?;
    write_text(&path, &text)?;
    files.push(path);

    Ok(ImportedRun {
        name: track.name.clone(),
        files,
        records: records.len(),
        truth_rows: truth.len(),
        notes,
    })
}

/// One line per sensor: `alias ρ₀ η σ (n)`, or why its fit failed.
fn fit_summary(
    fits: &[core::result::Result<LogDistanceFit, PositioningError>],
    sensors: &[Sensor],
    tracks: usize,
    samples: usize,
) -> String {
    let mut text = format!(
        "path loss per sensor, OLS on the other {tracks} tracks ({samples} samples) against the true 3-D \
         distance, d0 = {REFERENCE_DISTANCE_M} m (reference power dBm, exponent, residual std dB, samples):"
    );
    for (sensor, fit) in sensors.iter().zip(fits) {
        match fit {
            Ok(fit) => {
                let _ = write!(
                    text,
                    " {} {:.1}/{:.2}/{:.1}/{};",
                    sensor.alias,
                    fit.model.reference_rssi_dbm(),
                    fit.model.exponent(),
                    fit.model.shadowing_std_db(),
                    fit.samples
                );
            }
            Err(error) => {
                let _ = write!(text, " {} not fitted ({error});", sensor.alias);
            }
        }
    }
    text
}

/// A TOML basic string.
fn quoted(text: &str) -> String {
    format!("\"{}\"", text.replace('\\', "\\\\").replace('"', "\\\""))
}

/// The run's `site.toml`.
fn site_toml(
    track: &Track,
    others: &[&Track],
    sensors: &[Sensor],
    fits: &[core::result::Result<LogDistanceFit, PositioningError>],
    map: &CellMap,
    tag_height_m: f64,
) -> String {
    let other_names: Vec<&str> = others.iter().map(|t| t.name.as_str()).collect();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Site of run `{}` of the BLE tetam dataset (Daniş et al., PMC 2022; CC0), written by `rtls import`.\n\
         # Frame: the dataset's, metres (x, y on the floor plan, z up); sensor positions from cnf/tetam.dev.\n\
         # Calibration (path loss, radio map, tag height) uses ONLY the other {} tracks, never this one:\n\
         #   {}\n",
        track.name,
        others.len(),
        other_names.join(", ")
    );
    let _ = writeln!(s, "name = {}\n", quoted(&format!("BLE tetam, track {}", track.name)));
    for (sensor, fit) in sensors.iter().zip(fits) {
        let [x, y, z] = sensor.position_m;
        let _ = writeln!(
            s,
            "[[readers]]\n# BLE sensor (receiver), MAC {}\nid = {}\nposition_m = [{x:?}, {y:?}, {z:?}]\ntechnology = \"ble\"",
            sensor.mac,
            quoted(&sensor.alias)
        );
        match fit {
            Ok(fit) => {
                let _ = writeln!(
                    s,
                    "# Log-distance law fitted by OLS to this sensor's {} samples of the other tracks against the\n\
                     # true 3-D beacon distance; shadowing_std_db = the fit's residual std (n − 2 dof).\n\
                     [readers.radio.path_loss]\n\
                     reference_power_dbm = {:.4}\nexponent = {:.4}\nshadowing_std_db = {:.4}\nreference_distance_m = {:?}\n",
                    fit.samples,
                    fit.model.reference_rssi_dbm(),
                    fit.model.exponent(),
                    fit.model.shadowing_std_db(),
                    REFERENCE_DISTANCE_M
                );
            }
            Err(error) => {
                let _ = writeln!(s, "# No path loss: the fit on the other tracks failed ({error}).\n");
            }
        }
    }
    let readers: Vec<String> = sensors.iter().map(|r| quoted(&r.alias)).collect();
    let _ = writeln!(
        s,
        "# Radio map: the other tracks' samples binned in {CELL_M} m x {CELL_M} m cells of the true (x, y); per cell\n\
         # the mean RSSI (dBm) of each sensor, empty where it was never heard, at the cell centre. {} cells\n\
         # kept ({} samples); {} cells with fewer than {MIN_CELL_SAMPLES} samples (one per sensor on average)\n\
         # dropped ({} samples).\n\
         [fingerprints]\npath = \"radio-map.csv\"\nformat = \"csv\"\nreaders = [{}]\n",
        map.rows.len(),
        map.samples_used,
        map.cells_dropped,
        map.samples_dropped,
        readers.join(", ")
    );
    let _ = writeln!(
        s,
        "[tracker]\n\
         # The beacon was carried by a person on foot (the walker's speed limit, 6 m/s, among its defaults).\n\
         platform = \"walker\"\n\
         # RSSI is turned into position fixes by multilateration with the path-loss laws above, then filtered.\n\
         pipeline = \"fix-then-filter\"\n\
         # A carried beacon walks at 0.15-0.74 m/s along straight, rectangular and zigzag tracks: constant\n\
         # velocity between fixes, with speed changes as process noise.\n\
         motion_model = \"cv\"\n\
         # Fixes are positions, so the filter is linear.\n\
         filter = \"kf\"\n\
         # White-acceleration std for a hand-carried beacon: starting, stopping and turning change the\n\
         # velocity by ~0.5 m/s within about a second at these walking speeds.\n\
         acceleration_noise_std_mps2 = 0.5\n\
         # RSSI fixes have heavy tails (shadowing ~5 dB per reading); a wide gate rejects only gross outliers.\n\
         gate_probability = 0.999\n\
         # One beacon and no clutter: two fixes within 5 s confirm the track.\n\
         initiation = {{ confirm_updates = 2, within_s = 5.0 }}\n\
         # The sensors report ~23 packets/s together; 5 s without any means the beacon is out of range.\n\
         coast_timeout_s = 5.0\n\
         delete_timeout_s = 120.0\n\
         # The files are sorted; the window only matters for live streams (sensor clocks and network delay).\n\
         reorder_window_s = 0.5\n\
         # Planar tracking: the beacon stays at hand height (z = {:.2}-{:.2} m in the other tracks).\n\
         dimensions = 2\n\
         # Fix-then-filter groups the beacon's RSSI readings of each 1 s into one multilateration fix\n\
         # (~23 readings from up to 12 sensors).\n\
         epoch_s = 1.0\n\
         # Height of the beacon for the 3-D ranges of the planar fix: the median true z of the other tracks.\n\
         tag_height_m = {tag_height_m:.3}",
        min_height_m(others),
        max_height_m(others)
    );
    s
}

fn min_height_m(tracks: &[&Track]) -> f64 {
    tracks
        .iter()
        .flat_map(|t| &t.samples)
        .map(|s| s.position_m[2])
        .fold(f64::INFINITY, f64::min)
}

fn max_height_m(tracks: &[&Track]) -> f64 {
    tracks
        .iter()
        .flat_map(|t| &t.samples)
        .map(|s| s.position_m[2])
        .fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests;
