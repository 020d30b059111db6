//! Importer for UJIIndoorLoc (`../shared/data/ujiindoorloc`): one run, `validation`, whose radio
//! map is the training set and whose measurements are the validation scans.
//!
//! Written to `OUT/validation/`:
//! - `radio-map.csv` — the training fingerprints averaged per reference location (same
//!   `BUILDINGID`, `FLOOR`, `SPACEID`, `RELATIVEPOSITION` and coordinates): per access point the
//!   arithmetic mean (dBm) of the records that heard it, empty when none did; floor = `FLOOR`;
//! - `measurements.jsonl` — one `rssi_vector` per validation row (the detected access points;
//!   the dataset's 100 = not detected is already an absent reading), tag `phone-<PHONEID>`,
//!   time `TIMESTAMP` (s); rows of one phone with one time stamp are all kept, the later ones
//!   0.001 s apart; records in time order;
//! - `truth.csv` — the validation positions (2-D, same tag and time);
//! - `site.toml` — the access points heard in training as `wifi` readers at positions estimated
//!   from the training data, the radio map reference and the tracker settings.
//!
//! # Frame
//! `x = LONGITUDE − x0`, `y = LATITUDE − y0`, m, with `(x0, y0)` the floor of the training
//! minima: the dataset's EPSG:3857 metres shifted to a small local origin (so one unit is still
//! 0.766 ground metres at the campus, see [`crate::ujiindoorloc`]).
//!
//! Access points never heard in training have no fingerprint and no position: they are left
//! out of the site, the map and the scans, and the readings this removes from the validation
//! scans are counted in the notes.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use rtls_engine::radio_map::{radio_map_csv, RadioMapRow};
use rtls_engine::record::{AnchorReading, Measurement, Record};
use rtls_positioning::fingerprint::FingerprintDatabase;

use super::{create_dir, write_records, write_text, write_truth, ImportedRun, TruthRow};
use crate::ujiindoorloc::{self as uji, Fingerprint, ACCESS_POINTS};
use crate::{DataError, Result};

/// Reference points per access point in its power-weighted centroid position estimate (as in
/// `docs/FINGERPRINTING.md`).
const ANCHOR_STRONGEST: usize = 8;

/// Offset between validation rows of one phone with one time stamp, s.
const DUPLICATE_OFFSET_S: f64 = 0.001;

/// The run's name.
const RUN: &str = "validation";

pub(super) fn import(dataset_dir: &Path, out_dir: &Path) -> Result<Vec<ImportedRun>> {
    let training_path = dataset_dir.join("UJIndoorLoc").join("trainingData.csv");
    let training = uji::load(&training_path)?;
    let validation = uji::load(&dataset_dir.join("UJIndoorLoc").join("validationData.csv"))?;
    let converted = convert(&training, &validation).map_err(|error| match error {
        DataError::Positioning(source) => DataError::Content {
            file: training_path.clone(),
            reason: format!("access point positions could not be estimated: {source}"),
        },
        other => other,
    })?;

    let dir = out_dir.join(RUN);
    create_dir(&dir)?;
    let mut files = Vec::new();
    let path = dir.join("site.toml");
    write_text(&path, &site_toml(&converted))?;
    files.push(path);
    let path = dir.join("measurements.jsonl");
    write_records(&path, &converted.records)?;
    files.push(path);
    let path = dir.join("truth.csv");
    write_truth(&path, &converted.truth)?;
    files.push(path);
    let path = dir.join("radio-map.csv");
    let text = radio_map_csv(&converted.reader_ids, &converted.map).map_err(|error| DataError::Content {
        file: path.clone(),
        reason: error.to_string(),
    })?;
    write_text(&path, &text)?;
    files.push(path);

    Ok(vec![ImportedRun {
        name: RUN.to_string(),
        files,
        records: converted.records.len(),
        truth_rows: converted.truth.len(),
        notes: converted.notes,
    }])
}

/// Everything the run's files hold.
#[derive(Debug, Clone, PartialEq)]
struct Converted {
    /// Local origin `(x0, y0)` in EPSG:3857 m.
    origin_m: [f64; 2],
    /// `WAP…` ids of the access points heard in training, in column order.
    reader_ids: Vec<String>,
    /// Their estimated positions, local frame.
    reader_positions_m: Vec<[f64; 2]>,
    /// Radio map rows, in order of first appearance in the training file.
    map: Vec<RadioMapRow>,
    /// Validation scans and truth, in time order (ties in file order).
    records: Vec<Record>,
    truth: Vec<TruthRow>,
    notes: Vec<String>,
}

/// The access point id of column `ap` (0-based), as in the dataset's header.
fn wap_id(ap: usize) -> String {
    format!("WAP{:03}", ap + 1)
}

/// Converts the parsed training and validation sets.
fn convert(training: &[Fingerprint], validation: &[Fingerprint]) -> Result<Converted> {
    let mut notes = Vec::new();
    // (x0, y0) = ⌊min LONGITUDE⌋, ⌊min LATITUDE⌋ over the training set
    let origin_m = [0, 1].map(|axis| {
        training
            .iter()
            .map(|f| f.position_m[axis])
            .fold(f64::INFINITY, f64::min)
            .floor()
    });
    let local = |p: [f64; 2]| [p[0] - origin_m[0], p[1] - origin_m[1]];
    notes.push(format!(
        "local frame: x = LONGITUDE - ({}), y = LATITUDE - {} (EPSG:3857 m; floor of the training minima)",
        origin_m[0], origin_m[1]
    ));

    // readers: the access points heard at least once in training, positions estimated from it
    let mut heard = vec![false; ACCESS_POINTS];
    for f in training {
        for &(ap, _) in &f.readings_dbm {
            heard[ap] = true;
        }
    }
    let database = FingerprintDatabase::from_survey(uji::survey(training))?.with_estimated_anchors(ANCHOR_STRONGEST)?;
    let mut column_of = vec![None; ACCESS_POINTS];
    let mut reader_ids = Vec::new();
    let mut reader_positions_m = Vec::new();
    for ap in 0..ACCESS_POINTS {
        if let (true, Some(position)) = (heard[ap], database.anchors_m()[ap]) {
            column_of[ap] = Some(reader_ids.len());
            reader_ids.push(wap_id(ap));
            reader_positions_m.push(local(position));
        }
    }
    notes.push(format!(
        "{} of {ACCESS_POINTS} access points are heard in training and become readers, placed at the \
         power-weighted centroid of the {ANCHOR_STRONGEST} training fingerprints that hear each loudest; \
         the other {} are left out",
        reader_ids.len(),
        ACCESS_POINTS - reader_ids.len()
    ));

    let map = average_per_location(training, &column_of, reader_ids.len(), local);
    notes.push(format!(
        "radio map: {} training fingerprints averaged into {} reference locations \
         (BUILDINGID, FLOOR, SPACEID, RELATIVEPOSITION, coordinates)",
        training.len(),
        map.len()
    ));

    // validation scans, in file order, then sorted by time
    let mut scans: Vec<(Record, TruthRow)> = Vec::with_capacity(validation.len());
    let mut seen: HashMap<(u32, i64), usize> = HashMap::new();
    let (mut removed, mut duplicates, mut empty) = (0usize, 0usize, 0usize);
    for f in validation {
        let readings: Vec<AnchorReading> = f
            .readings_dbm
            .iter()
            .filter_map(|&(ap, rssi_dbm)| {
                column_of[ap].map(|_| AnchorReading {
                    anchor: wap_id(ap),
                    rssi_dbm,
                })
            })
            .collect();
        removed += f.readings_dbm.len() - readings.len();
        if readings.is_empty() {
            empty += 1;
            continue;
        }
        let repeat = seen.entry((f.phone_id, f.timestamp_s)).or_insert(0);
        duplicates += usize::from(*repeat > 0);
        let time_s = f.timestamp_s as f64 + *repeat as f64 * DUPLICATE_OFFSET_S;
        *repeat += 1;
        let tag = format!("phone-{}", f.phone_id);
        scans.push((
            Record {
                time_s,
                tag: tag.clone(),
                measurement: Measurement::RssiVector { readings },
            },
            TruthRow {
                time_s,
                tag,
                position_m: local(f.position_m).to_vec(),
            },
        ));
    }
    notes.push(format!(
        "{removed} readings of access points never heard in training were removed from the {} validation scans",
        validation.len()
    ));
    if empty > 0 {
        notes.push(format!(
            "{empty} validation rows were skipped: none of their access points is heard in training"
        ));
    }
    notes.push(format!(
        "{duplicates} validation rows repeat a phone's TIMESTAMP; they are kept, each {DUPLICATE_OFFSET_S} s \
         after the previous one of that phone and time stamp"
    ));
    // stable: equal times keep file order
    scans.sort_by(|a, b| a.0.time_s.total_cmp(&b.0.time_s));
    let (records, truth) = scans.into_iter().unzip();
    Ok(Converted {
        origin_m,
        reader_ids,
        reader_positions_m,
        map,
        records,
        truth,
        notes,
    })
}

/// Key of a reference location: building, floor, space, relative position, coordinates (bits).
type Location = (u32, i32, u32, u32, u64, u64);

/// The training fingerprints averaged per reference location (order of first appearance): per
/// reader column the mean RSSI (dBm) over the location's records that heard it.
fn average_per_location(
    training: &[Fingerprint],
    column_of: &[Option<usize>],
    columns: usize,
    local: impl Fn([f64; 2]) -> [f64; 2],
) -> Vec<RadioMapRow> {
    let mut index: HashMap<Location, usize> = HashMap::new();
    // per location: its first record, per column (Σ rssi, count)
    let mut sums: Vec<(&Fingerprint, Vec<(f64, usize)>)> = Vec::new();
    for f in training {
        let key = (
            f.building,
            f.floor,
            f.space_id,
            f.relative_position,
            f.position_m[0].to_bits(),
            f.position_m[1].to_bits(),
        );
        let k = *index.entry(key).or_insert_with(|| {
            sums.push((f, vec![(0.0, 0); columns]));
            sums.len() - 1
        });
        for &(ap, rssi_dbm) in &f.readings_dbm {
            if let Some(column) = column_of[ap] {
                sums[k].1[column].0 += rssi_dbm;
                sums[k].1[column].1 += 1;
            }
        }
    }
    sums.into_iter()
        .map(|(first, cells)| RadioMapRow {
            position_m: local(first.position_m),
            floor: Some(first.floor),
            rssi_dbm: cells.iter().map(|&(sum, n)| (n > 0).then(|| sum / n as f64)).collect(),
        })
        .collect()
}

/// The run's `site.toml`.
fn site_toml(c: &Converted) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Site of the UJIIndoorLoc validation run (Torres-Sospedra et al., IPIN 2014; CC BY 4.0), written by\n\
         # `rtls import`. Frame: x = LONGITUDE - ({x0}), y = LATITUDE - {y0}: the dataset's EPSG:3857 metres\n\
         # (0.766 ground metres each at the campus) shifted to the floor of the training minima (x0, y0).\n\
         # Floors (0-4 in 3 buildings) are labels in the radio map's floor column; their heights are not in\n\
         # the dataset, so no [[floors]] are declared.\n\
         name = \"UJIIndoorLoc, training radio map, validation scans\"\n\n\
         # Readers: the {n} access points heard at least once in training. Their positions are not in the\n\
         # dataset: each is the power-weighted centroid of the {ANCHOR_STRONGEST} training fingerprints that hear it\n\
         # loudest (rtls_positioning FingerprintDatabase::with_estimated_anchors), biased towards the surveyed\n\
         # area. The {left} access points never heard in training are left out.",
        x0 = c.origin_m[0],
        y0 = c.origin_m[1],
        n = c.reader_ids.len(),
        left = ACCESS_POINTS - c.reader_ids.len()
    );
    for (id, [x, y]) in c.reader_ids.iter().zip(&c.reader_positions_m) {
        let _ = writeln!(
            s,
            "[[readers]]\nid = \"{id}\"\nposition_m = [{x:?}, {y:?}]\ntechnology = \"wifi\""
        );
    }
    let readers: Vec<String> = c.reader_ids.iter().map(|id| format!("\"{id}\"")).collect();
    let _ = writeln!(
        s,
        "\n# Radio map: the training fingerprints averaged per reference location (same BUILDINGID, FLOOR,\n\
         # SPACEID, RELATIVEPOSITION and coordinates), {} rows; floor column = FLOOR.\n\
         [fingerprints]\npath = \"radio-map.csv\"\nformat = \"csv\"\nreaders = [{}]\n",
        c.map.len(),
        readers.join(", ")
    );
    s.push_str(
        "[tracker]\n\
         # The phones were carried by people on foot (the walker's speed limit, 6 m/s, among its defaults).\n\
         platform = \"walker\"\n\
         # Each scan becomes a fingerprint (WKNN) fix; the filter smooths a phone's fixes.\n\
         pipeline = \"fix-then-filter\"\n\
         # Fixes are positions, so the filter is linear.\n\
         filter = \"kf\"\n\
         # People walking between survey points: constant velocity with white-acceleration noise.\n\
         motion_model = \"cv\"\n\
         # Walking: starting, stopping and turning change the velocity by ~1 m/s within a second or two.\n\
         acceleration_noise_std_mps2 = 1.0\n\
         # Fingerprint errors are heavy-tailed (95th percentile ~19 m, docs/FINGERPRINTING.md): a wide gate\n\
         # rejects only gross mismatches.\n\
         gate_probability = 0.999\n\
         # Every scan comes from a known phone and there is no clutter to confirm against: one fix starts a\n\
         # confirmed track.\n\
         initiation = { confirm_updates = 1, within_s = 60.0 }\n\
         # A phone scans every 13-95 s (median gap per phone); 120 s without a scan ends coasting, and after\n\
         # 10 min the phone is in another recording session.\n\
         coast_timeout_s = 120.0\n\
         delete_timeout_s = 600.0\n\
         # The file is sorted; the window only matters for live streams.\n\
         reorder_window_s = 0.5\n\
         # Positions are 2-D (x, y) with a floor label.\n\
         dimensions = 2\n",
    );
    s
}

#[cfg(test)]
mod tests;
