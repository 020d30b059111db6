//! Track files: JSON Lines, one position per line; only the keys the evaluation needs are read.

use std::fmt;

use serde::de::{self, DeserializeSeed, IgnoredAny, MapAccess, Visitor};

use super::TrackSample;
use crate::error::{EngineError, Result};

/// The keys a track line is read for; all others are ignored.
#[derive(Debug, Default)]
struct TrackWire {
    t: Option<f64>,
    tag: Option<String>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    predicted: Option<bool>,
    cov: Option<Vec<f64>>,
}

/// Reads a [`TrackWire`], leaving in `key` the key being read when an error occurred.
struct TrackSeed<'a> {
    key: &'a mut String,
}

impl<'de> DeserializeSeed<'de> for TrackSeed<'_> {
    type Value = TrackWire;

    fn deserialize<D: de::Deserializer<'de>>(self, deserializer: D) -> core::result::Result<TrackWire, D::Error> {
        deserializer.deserialize_map(self)
    }
}

/// Sets `slot` from the next value, refusing a second occurrence of the key.
fn read_once<'de, A: MapAccess<'de>, T: de::Deserialize<'de>>(
    map: &mut A,
    slot: &mut Option<T>,
    key: &'static str,
) -> core::result::Result<(), A::Error> {
    if slot.is_some() {
        return Err(de::Error::duplicate_field(key));
    }
    *slot = Some(map.next_value()?);
    Ok(())
}

impl<'de> Visitor<'de> for TrackSeed<'_> {
    type Value = TrackWire;

    fn expecting(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str("a track object such as {\"t\": 1.0, \"tag\": \"a\", \"x\": 2.0, \"y\": 3.0}")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> core::result::Result<TrackWire, A::Error> {
        let mut wire = TrackWire::default();
        while let Some(key) = map.next_key::<String>()? {
            self.key.clone_from(&key);
            match key.as_str() {
                "t" => read_once(&mut map, &mut wire.t, "t")?,
                "tag" => read_once(&mut map, &mut wire.tag, "tag")?,
                "x" => read_once(&mut map, &mut wire.x, "x")?,
                "y" => read_once(&mut map, &mut wire.y, "y")?,
                "z" => read_once(&mut map, &mut wire.z, "z")?,
                "predicted" => read_once(&mut map, &mut wire.predicted, "predicted")?,
                "cov" => read_once(&mut map, &mut wire.cov, "cov")?,
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        self.key.clear();
        Ok(wire)
    }
}

/// Parses one line of a track file (JSON Lines, as written by `rtls track`).
///
/// Reads `t` (s), `tag`, `x`, `y` (m), optional `z` (m; absent for a 2-D position) and optional
/// `predicted` (bool, default false: a prediction without a measurement) and optional `cov` (the
/// position covariance, m², row-major: 4 entries for `x, y`, 9 for `x, y, z`); every other key
/// (`vx`, `status`, …) is ignored, so raw fixes in the same shape read too. A blank line
/// (empty or white space only) is `Ok(None)`.
///
/// # Errors
/// [`EngineError::Parse`] with `file` and `line` as given and the key at fault as the field (`-`
/// when the line is not a JSON object): malformed JSON, a missing `t`, `tag`, `x` or `y`, a value
/// of the wrong type (`"z": null` included: leave the key out for 2-D), a repeated key, an empty
/// tag, a `cov` whose length is not 4 or 9 or that holds a non-finite entry.
///
/// # Examples
/// ```
/// use rtls_engine::evaluation::parse_track_line;
///
/// let line = r#"{"t": 3.5, "tag": "miner-017", "x": 10.5, "y": -2, "vx": 1.0, "cov": [1, 0, 0, 1], "status": "coasting", "predicted": true}"#;
/// let sample = parse_track_line(line, "tracks.jsonl", 7)?.unwrap();
/// assert_eq!((sample.time_s, sample.position_m, sample.has_z, sample.predicted), (3.5, [10.5, -2.0, 0.0], false, true));
/// assert_eq!(parse_track_line("  ", "tracks.jsonl", 8)?, None);
///
/// let error = parse_track_line(r#"{"t": 4, "tag": "miner-017", "x": "10.5", "y": 0}"#, "tracks.jsonl", 9).unwrap_err();
/// assert!(error.to_string().starts_with("tracks.jsonl:9: field `x`"));
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
pub fn parse_track_line(text: &str, file: &str, line: usize) -> Result<Option<TrackSample>> {
    let text = text.trim();
    if text.is_empty() {
        return Ok(None);
    }
    let error = |field: &str, reason: String| EngineError::Parse {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    let mut key = String::new();
    let mut deserializer = serde_json::Deserializer::from_str(text);
    let parsed = TrackSeed { key: &mut key }
        .deserialize(&mut deserializer)
        .and_then(|wire| {
            deserializer.end()?;
            Ok(wire)
        });
    let wire = parsed.map_err(|e| error(if key.is_empty() { "-" } else { &key }, e.to_string()))?;
    let missing = |field: &str| error(field, "is missing; a track line needs t, tag, x and y".into());
    let time_s = wire.t.ok_or_else(|| missing("t"))?;
    let tag = wire.tag.ok_or_else(|| missing("tag"))?;
    if tag.is_empty() {
        return Err(error("tag", "is empty; every track line needs a tag id".into()));
    }
    let x = wire.x.ok_or_else(|| missing("x"))?;
    let y = wire.y.ok_or_else(|| missing("y"))?;
    let covariance_m2 = match wire.cov {
        None => None,
        Some(cov) if (cov.len() == 4 || cov.len() == 9) && cov.iter().all(|c| c.is_finite()) => Some(cov),
        Some(cov) => {
            return Err(error(
                "cov",
                format!(
                    "has {} entries or a non-finite one; a position covariance is 4 (x, y) or 9 (x, y, z) \
                     finite numbers, row-major, m²",
                    cov.len()
                ),
            ))
        }
    };
    Ok(Some(TrackSample {
        time_s,
        tag,
        position_m: [x, y, wire.z.unwrap_or(0.0)],
        has_z: wire.z.is_some(),
        predicted: wire.predicted.unwrap_or(false),
        covariance_m2,
        line,
    }))
}

/// Parses a whole track file with [`parse_track_line`], skipping blank lines (lines are numbered
/// from 1, blank ones included).
///
/// # Errors
/// The first line's [`EngineError::Parse`].
///
/// # Examples
/// ```
/// use rtls_engine::evaluation::parse_track_lines;
///
/// let text = "{\"t\": 0, \"tag\": \"a\", \"x\": 1, \"y\": 2}\n\n{\"t\": 1, \"tag\": \"a\", \"x\": 1, \"y\": 2, \"z\": 0.5}\n";
/// let samples = parse_track_lines(text, "tracks.jsonl")?;
/// assert_eq!(samples.len(), 2);
/// assert_eq!(samples[1].line, 3);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
pub fn parse_track_lines(text: &str, file: &str) -> Result<Vec<TrackSample>> {
    let mut samples = Vec::new();
    for (index, line_text) in text.lines().enumerate() {
        if let Some(sample) = parse_track_line(line_text, file, index + 1)? {
            samples.push(sample);
        }
    }
    Ok(samples)
}
