//! Residuals: each range / RSSI measurement against the site's model at the tag's tracked
//! position.

use std::collections::HashMap;

use super::{Residual, ResidualKind, Residuals, SurveySettings, Unmatched, RECORDS_SOURCE};
use crate::error::{EngineError, Result};
use crate::evaluation::{TrackSample, TRACKS_SOURCE};
use crate::record::{Measurement, Record};
use crate::site::{Reader, Site};
use crate::tracker::models::{AnchorLaw, AnchorMeasurement};
use crate::tracker::TrackUpdate;

/// A tag's non-predicted track positions, sorted by time: `(t, [x, y, z])`.
type Track = Vec<(f64, [f64; 3])>;

/// Where a tag was at a time, or why that is not known.
enum Located {
    At([f64; 3]),
    Unmatched(Reason),
}

/// The tag's position at `time_s`: the update at that time (the last one if several share
/// it), or the linear interpolation between the two updates that bracket it.
fn locate(track: &[(f64, [f64; 3])], time_s: f64, settings: &SurveySettings) -> Located {
    let (Some(first), Some(last)) = (track.first(), track.last()) else {
        return Located::Unmatched(|u| &mut u.no_track);
    };
    if time_s >= first.0 && time_s < first.0 + settings.skip_initial_s {
        return Located::Unmatched(|u| &mut u.initial_skipped);
    }
    if time_s < first.0 || time_s > last.0 {
        return Located::Unmatched(|u| &mut u.outside_track);
    }
    // first update at or after t
    let after = track.partition_point(|s| s.0 < time_s);
    let (t1, p1) = track[after];
    if t1 == time_s {
        let at = track.partition_point(|s| s.0 <= time_s) - 1;
        return Located::At(track[at].1);
    }
    // time_s > first.0, so after ≥ 1
    let (t0, p0) = track[after - 1];
    if t1 - t0 > settings.max_gap_s {
        return Located::Unmatched(|u| &mut u.track_gap);
    }
    // p = p₀ + (t − t₀) / (t₁ − t₀) · (p₁ − p₀)
    let w = (time_s - t0) / (t1 - t0);
    Located::At([
        p0[0] + w * (p1[0] - p0[0]),
        p0[1] + w * (p1[1] - p0[1]),
        p0[2] + w * (p1[2] - p0[2]),
    ])
}

/// Why a measurement has no residual: the counter of [`Unmatched`] it goes to.
type Reason = fn(&mut Unmatched) -> &mut usize;

/// What the site expects a reader to measure: the tracker's own measurement model (range, or
/// RSSI by the reader's log-distance law) at the tag position, less a configured range bias.
struct Model {
    expected: AnchorMeasurement,
    /// `‖p − a‖`, the slant distance the residual is filed under.
    distance: AnchorMeasurement,
    bias: f64,
    /// The range scale the bias-corrected range is divided by (1 for RSSI).
    scale: f64,
}

impl Model {
    /// The model of `reader` for measurements of `kind`, or why there is none.
    fn of(reader: Option<&Reader>, kind: ResidualKind) -> core::result::Result<Self, Reason> {
        let Some(reader) = reader else {
            return Err(|u| &mut u.unknown_reader);
        };
        if !reader.working {
            return Err(|u| &mut u.broken_reader);
        }
        let a = reader.position_xyz_m();
        let radio = reader.radio.as_ref();
        // the variance is not used: only h(p) is evaluated (3-D positions, so no tag height)
        let model = |law| AnchorMeasurement::new(a, 0.0, law, 1.0);
        let range = radio.and_then(|r| r.range.as_ref());
        let (law, bias, scale) = match kind {
            ResidualKind::Range => (
                AnchorLaw::Range,
                range.map_or(0.0, |r| r.bias_m),
                range.map_or(1.0, |r| r.scale),
            ),
            ResidualKind::Rssi => {
                let Some(law) = radio.and_then(|r| r.path_loss.as_ref()) else {
                    return Err(|u| &mut u.no_path_loss);
                };
                let law = AnchorLaw::LogDistance {
                    reference_power_dbm: law.reference_power_dbm,
                    reference_distance_m: law.reference_distance_m,
                    exponent: law.exponent,
                };
                (law, 0.0, 1.0)
            }
        };
        Ok(Self {
            expected: model(law),
            distance: model(AnchorLaw::Range),
            bias,
            scale,
        })
    }

    /// Measured minus expected at tag position `p` — `e = (r − b) / s − d` for a range,
    /// `e = ρ − (P₀ − 10 n log₁₀(d / d₀))` for RSSI — and the slant distance `d = ‖p − a‖`, m.
    fn residual(&self, measured: f64, p: [f64; 3]) -> (f64, f64) {
        (
            (measured - self.bias) / self.scale - self.expected.value(&p),
            self.distance.value(&p),
        )
    }
}

/// Groups the non-predicted samples by tag, sorted by time, with `z` = the tag height where
/// a sample has none.
fn tracks_by_tag(samples: &[TrackSample], tag_height_m: f64) -> Result<HashMap<&str, Track>> {
    let mut tracks: HashMap<&str, Track> = HashMap::new();
    for sample in samples {
        let fields = [
            ("t", sample.time_s),
            ("x", sample.position_m[0]),
            ("y", sample.position_m[1]),
            ("z", sample.position_m[2]),
        ];
        if let Some((field, value)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            return Err(EngineError::Parse {
                file: TRACKS_SOURCE.to_string(),
                line: sample.line,
                field: (*field).to_string(),
                reason: format!("{value} is not a finite number"),
            });
        }
        if sample.predicted {
            continue;
        }
        let z = if sample.has_z {
            sample.position_m[2]
        } else {
            tag_height_m
        };
        tracks
            .entry(sample.tag.as_str())
            .or_default()
            .push((sample.time_s, [sample.position_m[0], sample.position_m[1], z]));
    }
    for track in tracks.values_mut() {
        // stable: samples at equal times keep their file order (the last one is the latest)
        track.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok(tracks)
}

/// Computes the residual of every range and RSSI measurement of `records` against the site's
/// model at the tag's position in `tracks` (see the [module documentation](super) for the
/// equations).
///
/// Only non-predicted track samples are used; a measurement's position is interpolated
/// linearly in time between the two that bracket it (or taken from one at the same time).
/// Records need not be sorted. A 2-D track (no `z`) is placed at `tracker.tag_height_m`
/// (0 when absent), as the tracker does.
///
/// # Errors
/// [`EngineError::InvalidParameter`] for settings out of range; [`EngineError::Parse`] for a
/// record that fails [`Record::validate`] (file [`RECORDS_SOURCE`], line = its 1-based index
/// in `records`) and for a track sample with a non-finite number (file
/// [`crate::evaluation::TRACKS_SOURCE`], the sample's line).
///
/// # Examples
/// See the [module documentation](super).
pub fn residuals(
    site: &Site,
    records: &[Record],
    tracks: &[TrackSample],
    settings: &SurveySettings,
) -> Result<Residuals> {
    settings.validate()?;
    let tracks = tracks_by_tag(tracks, site.tracker.tag_height_m.unwrap_or(0.0))?;
    let readers: HashMap<&str, &Reader> = site.readers.iter().map(|r| (r.id.as_str(), r)).collect();
    let mut found = Residuals::default();
    for (index, record) in records.iter().enumerate() {
        record.validate(RECORDS_SOURCE, index + 1)?;
        let readings: Vec<(&str, ResidualKind, f64)> = match &record.measurement {
            Measurement::Range { anchor, range_m, .. } => vec![(anchor.as_str(), ResidualKind::Range, *range_m)],
            Measurement::Rssi { anchor, rssi_dbm } => vec![(anchor.as_str(), ResidualKind::Rssi, *rssi_dbm)],
            Measurement::RssiVector { readings } => readings
                .iter()
                .map(|r| (r.anchor.as_str(), ResidualKind::Rssi, r.rssi_dbm))
                .collect(),
            Measurement::Tdoa { .. } => {
                found.unmatched.tdoa += 1;
                continue;
            }
            _ => {
                found.unmatched.not_anchor_measurement += 1;
                continue;
            }
        };
        let track = tracks.get(record.tag.as_str()).map_or(&[][..], Vec::as_slice);
        for (reader_id, kind, measured) in readings {
            // reader problems first (they do not depend on the track)
            let located = Model::of(readers.get(reader_id).copied(), kind)
                .map(|model| (model, locate(track, record.time_s, settings)));
            match located {
                Ok((model, Located::At(p))) => {
                    let (value, distance_m) = model.residual(measured, p);
                    found.residuals.push(Residual {
                        time_s: record.time_s,
                        tag: record.tag.clone(),
                        reader: reader_id.to_string(),
                        kind,
                        position_m: p,
                        distance_m,
                        value,
                    });
                }
                Err(reason) | Ok((_, Located::Unmatched(reason))) => *reason(&mut found.unmatched) += 1,
            }
        }
    }
    Ok(found)
}

/// The tracker's updates as track samples (what [`crate::evaluation::parse_track_lines`]
/// reads from a track file), so a survey can run on the tracker's output in memory: `z` is
/// kept in 3-D only, `line` is the update's 1-based index.
///
/// # Examples
/// ```
/// use rtls_engine::lifecycle::TrackStatus;
/// use rtls_engine::survey::samples_from_updates;
/// use rtls_engine::tracker::{TrackUpdate, UpdateSource};
/// let update = TrackUpdate {
///     time_s: 2.0, tag: "w1".into(), dimensions: 2,
///     position_m: [1.0, 2.0, 1.2], velocity_mps: [0.5, 0.0, 0.0],
///     position_covariance_m2: [0.04, 0.0, 0.0, 0.04, 0.0, 0.0, 0.0, 0.0, 0.0],
///     predicted: true, status: TrackStatus::Coasting, source: UpdateSource::Prediction,
///     mode: None, revised: false, smoothed: false,
/// };
/// let samples = samples_from_updates(&[update]);
/// assert!(samples[0].predicted && !samples[0].has_z);
/// ```
#[must_use]
pub fn samples_from_updates(updates: &[TrackUpdate]) -> Vec<TrackSample> {
    updates
        .iter()
        .enumerate()
        .map(|(index, u)| TrackSample {
            time_s: u.time_s,
            tag: u.tag.to_string(),
            position_m: u.position_m,
            has_z: u.dimensions == 3,
            predicted: u.predicted,
            covariance_m2: Some(u.position_covariance_m2[..u.dimensions * u.dimensions].to_vec()),
            line: index + 1,
        })
        .collect()
}
