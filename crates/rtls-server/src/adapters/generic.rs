//! A generic gateway's JSON, its field names configured: [`GenericAdapter`].

use serde::Deserialize;
use serde_json::Value;

use super::{accuracy_or, fix, number, tag_id, AdapterError, Parsed, Refusal};
use crate::omlox::time::parse_timestamp;

/// `[adapters.generic]`: where a gateway's messages keep the tag, time and position.
///
/// Reads any position message whose field names are configured
/// (`[adapters.generic]` in the server's configuration), for a gateway with no adapter of its
/// own.
///
/// A payload is one message, an array of messages, or an object whose `items` path holds the
/// array. Each field is a path of keys separated by dots; a numeric key indexes an array
/// (`location.0`).
///
/// | setting | record field |
/// | --- | --- |
/// | `tag` | `tag` (a string, or an integer written in decimal) |
/// | `time` in `time_unit` (`s`, `ms`, or `rfc3339` text) | `t` (Unix s) |
/// | `x`, `y`, `z` (optional) in `position_unit` (`m`, `cm`, `mm`) | `position_m` |
/// | `accuracy` (optional, a radius in `position_unit`) | `covariance_m2` = `accuracy² I` (absent or 0: `default_accuracy_m² I`) |
/// | a message whose `x` or `y` is absent or null | refused, reason `no_position` |
///
/// # Examples
/// ```
/// use rtls_server::adapters::GenericAdapter;
/// // the Pozyx stream read through the generic adapter
/// let adapter: GenericAdapter = toml::from_str(r#"
///     tag = "tagId"
///     time = "timestamp"
///     x = "data.coordinates.x"
///     y = "data.coordinates.y"
///     position_unit = "mm"
/// "#).unwrap();
/// let parsed = adapter
///     .parse(br#"[{"tagId": "7", "timestamp": 2.5, "data": {"coordinates": {"x": 1500, "y": 20}}}]"#, 1.0)
///     .unwrap();
/// assert_eq!(parsed.records[0].time_s, 2.5);
///  ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GenericAdapter {
    /// The path of the array of messages in a payload object (e.g. `"tags"`); without it a
    /// payload is one message or an array of them.
    #[serde(default)]
    pub items: Option<String>,
    /// The tag id's path.
    pub tag: String,
    /// The time's path.
    pub time: String,
    /// The time's unit.
    #[serde(default)]
    pub time_unit: TimeUnit,
    /// The x coordinate's path.
    pub x: String,
    /// The y coordinate's path.
    pub y: String,
    /// The z coordinate's path (2-D fixes without it).
    #[serde(default)]
    pub z: Option<String>,
    /// The unit of the coordinates and of the accuracy.
    #[serde(default)]
    pub position_unit: LengthUnit,
    /// The accuracy radius's path (σ of each coordinate); without it, `default_accuracy_m`.
    #[serde(default)]
    pub accuracy: Option<String>,
}

/// The unit of a generic message's time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeUnit {
    /// Unix seconds (a number).
    #[default]
    S,
    /// Unix milliseconds (a number).
    Ms,
    /// RFC 3339 text, e.g. `2024-03-20T15:30:00Z`.
    Rfc3339,
}

/// The unit of a generic message's coordinates and accuracy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Metres.
    #[default]
    M,
    /// Centimetres.
    Cm,
    /// Millimetres.
    Mm,
}

impl LengthUnit {
    fn metres(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Cm => 0.01,
            LengthUnit::Mm => 0.001,
        }
    }
}

impl GenericAdapter {
    /// Checks that every path is non-empty.
    ///
    /// # Errors
    /// The setting with an empty path, and why.
    pub fn validate(&self) -> Result<(), String> {
        let paths = [
            ("tag", Some(&self.tag)),
            ("time", Some(&self.time)),
            ("x", Some(&self.x)),
            ("y", Some(&self.y)),
        ];
        let optional = [
            ("z", self.z.as_ref()),
            ("accuracy", self.accuracy.as_ref()),
            ("items", self.items.as_ref()),
        ];
        for (name, path) in paths.into_iter().chain(optional) {
            if path.is_some_and(|p| p.split('.').any(str::is_empty)) {
                return Err(format!(
                    "{name}: a path of keys separated by dots, e.g. \"data.coordinates.x\""
                ));
            }
        }
        Ok(())
    }

    /// Parses one payload of the gateway (paths, units and refusals as [`GenericAdapter`] says).
    ///
    /// # Errors
    /// [`AdapterError::Json`] when the payload is not JSON, [`AdapterError::Field`] naming the
    /// first malformed field by its path.
    pub fn parse(&self, payload: &[u8], default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
        let value: Value = serde_json::from_slice(payload).map_err(|e| AdapterError::Json(e.to_string()))?;
        let (prefix, root) = match &self.items {
            Some(path) => (
                path.as_str(),
                lookup(&value, path).ok_or_else(|| AdapterError::field(path, "required field is missing"))?,
            ),
            None => ("", &value),
        };
        let messages: Vec<&Value> = match root {
            Value::Array(items) => items.iter().collect(),
            other => vec![other],
        };
        let scale = self.position_unit.metres();
        let mut parsed = Parsed::default();
        for (index, message) in messages.into_iter().enumerate() {
            let at = format!("{prefix}[{index}]");
            let field = |path: &str| format!("{at}.{path}");
            let tag = tag_id(lookup(message, &self.tag), &field(&self.tag))?;
            let (Some(x), Some(y)) = (
                lookup(message, &self.x).filter(|v| !v.is_null()),
                lookup(message, &self.y).filter(|v| !v.is_null()),
            ) else {
                parsed.refusals.push(Refusal {
                    at,
                    tag: Some(tag),
                    reason: "no_position",
                    detail: format!("no {} and {}", self.x, self.y),
                });
                continue;
            };
            let mut position_m = vec![number(x, &field(&self.x))? * scale, number(y, &field(&self.y))? * scale];
            if let Some(z) = self.z.as_deref() {
                if let Some(v) = lookup(message, z).filter(|v| !v.is_null()) {
                    position_m.push(number(v, &field(z))? * scale);
                }
            }
            let time_field = field(&self.time);
            let time = lookup(message, &self.time)
                .ok_or_else(|| AdapterError::field(&time_field, "required field is missing"))?;
            let time_s = match self.time_unit {
                TimeUnit::S => number(time, &time_field)?,
                // milliseconds → seconds
                TimeUnit::Ms => number(time, &time_field)? / 1000.0,
                TimeUnit::Rfc3339 => {
                    let text = time.as_str().ok_or_else(|| {
                        AdapterError::field(&time_field, format!("expected RFC 3339 text, got {time}"))
                    })?;
                    parse_timestamp(text, &time_field).map_err(|_| {
                        AdapterError::field(
                            &time_field,
                            format!("`{text}` is not RFC 3339, e.g. 2024-03-20T15:30:00Z"),
                        )
                    })?
                }
            };
            let radius_m = match self
                .accuracy
                .as_deref()
                .and_then(|path| Some((path, lookup(message, path)?)))
            {
                None | Some((_, Value::Null)) => None,
                Some((path, v)) => Some(number(v, &field(path))? * scale),
            };
            parsed
                .records
                .push(fix(time_s, tag, position_m, accuracy_or(radius_m, default_accuracy_m)));
        }
        Ok(parsed)
    }
}

/// The value at a dotted path (numeric keys index arrays).
fn lookup<'a>(value: &'a Value, path: &str) -> Option<&'a Value> {
    path.split('.').try_fold(value, |v, key| match v {
        Value::Object(map) => map.get(key),
        Value::Array(items) => items.get(key.parse::<usize>().ok()?),
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::super::{parse, Vendor};
    use super::GenericAdapter;

    fn adapter(toml_text: &str) -> GenericAdapter {
        let adapter: GenericAdapter = toml::from_str(toml_text).unwrap();
        adapter.validate().unwrap();
        adapter
    }

    /// Conformance: configured for the Quuppa sample, the generic adapter gives exactly the
    /// Quuppa adapter's record.
    #[test]
    fn configured_for_quuppa_it_matches_the_quuppa_adapter() {
        let sample = r#"{"tagId": "d10000001111", "locationType": "position", "locationRadius": 0.09,
            "location": [-1.09, 0.38, 1.0], "locationTS": 1641888440139}"#;
        let generic = adapter(
            r#"tag = "tagId"
               time = "locationTS"
               time_unit = "ms"
               x = "location.0"
               y = "location.1"
               z = "location.2"
               accuracy = "locationRadius""#,
        );
        let ours = generic.parse(sample.as_bytes(), 1.0).unwrap();
        let theirs = parse(Vendor::Quuppa, sample.as_bytes(), 1.0).unwrap();
        assert_eq!(ours.records, theirs.records);
    }

    /// Conformance: configured for the Pozyx stream, millimetres included.
    #[test]
    fn configured_for_pozyx_it_matches_the_pozyx_adapter() {
        let sample = r#"[{"tagId": "10006789", "timestamp": 1671165464.3779979, "success": true,
            "data": {"coordinates": {"x": 29340, "y": 69521, "z": 1000}}}]"#;
        let generic = adapter(
            r#"tag = "tagId"
               time = "timestamp"
               x = "data.coordinates.x"
               y = "data.coordinates.y"
               z = "data.coordinates.z"
               position_unit = "mm""#,
        );
        let ours = generic.parse(sample.as_bytes(), 0.7).unwrap();
        let theirs = parse(Vendor::Pozyx, sample.as_bytes(), 0.7).unwrap();
        assert_eq!(ours.records, theirs.records);
    }

    #[test]
    fn items_rfc3339_times_and_missing_positions() {
        let generic = adapter(
            r#"items = "positions"
               tag = "asset.id"
               time = "at"
               time_unit = "rfc3339"
               x = "x"
               y = "y"
               position_unit = "cm""#,
        );
        let payload = r#"{"positions": [{"asset": {"id": 42}, "at": "2024-03-20T15:30:00Z", "x": 150, "y": -20},
                                        {"asset": {"id": 43}, "at": "2024-03-20T15:30:00Z", "x": null, "y": null}]}"#;
        let parsed = generic.parse(payload.as_bytes(), 1.0).unwrap();
        assert_eq!(parsed.records[0].tag, "42");
        assert!((parsed.records[0].time_s - 1_710_948_600.0).abs() < 1e-9);
        assert_eq!(parsed.refusals[0].at, "positions[1]");
        let bad = payload.replace("\"x\": 150", "\"x\": \"150\"");
        let error = generic.parse(bad.as_bytes(), 1.0).unwrap_err();
        assert_eq!(
            error.to_string(),
            r#"positions[0].x: expected a finite number, got "150""#
        );
    }

    #[test]
    fn an_empty_path_is_refused_at_configuration() {
        let generic: GenericAdapter = toml::from_str("tag = \"a..b\"\ntime = \"t\"\nx = \"x\"\ny = \"y\"").unwrap();
        assert!(generic.validate().unwrap_err().starts_with("tag:"));
        assert!(
            toml::from_str::<GenericAdapter>("tag = \"t\"\ntime = \"t\"\nx = \"x\"\ny = \"y\"\ncolour = 1").is_err()
        );
    }
}
