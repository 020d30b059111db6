//! Field-level validation of the ingest body `PUT /v2/providers/locations` (a JSON array of
//! Location objects): every problem is an error naming the array index and the field, never a
//! panic and never a silently dropped element. Members the schema does not name are ignored.

use serde_json::Value;

use super::{Location, ProviderType};
use crate::{Result, ServerError};

const NUMBER_FIELDS: [&str; 7] = [
    "accuracy",
    "floor",
    "true_heading",
    "magnetic_heading",
    "heading_accuracy",
    "speed",
    "course",
];
const STRING_FIELDS: [&str; 3] = ["crs", "elevation_ref", "source"];

/// Parses and validates an ingest body.
///
/// Checks per element: an object with only the spec's fields (vendor data belongs in
/// `properties`); `position` a GeoJSON Point with 2 or 3 finite coordinates; `source` and
/// `provider_id` non-empty strings; `provider_type` one of the spec's enum; timestamps in ISO
/// 8601; `accuracy` and `speed` finite and ≥ 0, other numbers finite; `crs` and `elevation_ref`
/// strings (`elevation_ref` `floor` or `wgs84`); `associated` a boolean; `trackables` an array of
/// strings; `properties` an object.
///
/// # Errors
/// [`ServerError::Body`] when the body is not a JSON array; [`ServerError::InvalidField`] with the
/// 0-based index and the field (`position.coordinates[1]`) for the first bad element.
///
/// # Examples
/// ```
/// use rtls_server::omlox::ingest::parse_locations;
/// let body = r#"[{"position":{"type":"Point","coordinates":[1,2]},"source":"s",
///                 "provider_type":"uwb","provider_id":"tag-1"},
///                {"position":{"type":"Point","coordinates":[1]},"source":"s",
///                 "provider_type":"uwb","provider_id":"tag-2"}]"#;
/// let error = parse_locations(body).unwrap_err();
/// assert_eq!(error.to_string(), "[1].position.coordinates: expected 2 or 3 numbers, got 1");
/// ```
pub fn parse_locations(body: &str) -> Result<Vec<Location>> {
    let value: Value = serde_json::from_str(body).map_err(|e| ServerError::Body {
        reason: format!("not valid JSON ({e})"),
    })?;
    let Value::Array(items) = value else {
        return Err(ServerError::Body {
            reason: "expected a JSON array of Location objects".into(),
        });
    };
    items
        .into_iter()
        .enumerate()
        .map(|(index, item)| {
            check_location(index, &item)?;
            serde_json::from_value(item).map_err(|e| ServerError::InvalidField {
                index,
                field: "-".into(),
                reason: e.to_string(),
            })
        })
        .collect()
}

fn check_location(index: usize, item: &Value) -> Result<()> {
    let err = |field: &str, reason: String| ServerError::InvalidField {
        index,
        field: field.into(),
        reason,
    };
    let Value::Object(object) = item else {
        return Err(err("-", "expected a Location object".into()));
    };
    // members the schema does not name are ignored: the spec's Location does not close its
    // object (vendor data belongs in `properties`, which is kept)
    for required in ["position", "source", "provider_type", "provider_id"] {
        if !object.contains_key(required) {
            return Err(err(required, "required field is missing".into()));
        }
    }
    // position
    let Some(Value::Object(position)) = object.get("position") else {
        return Err(err("position", "expected a GeoJSON Point object".into()));
    };
    if position.get("type").and_then(Value::as_str) != Some("Point") {
        return Err(err("position.type", "expected \"Point\"".into()));
    }
    let Some(Value::Array(coordinates)) = position.get("coordinates") else {
        return Err(err(
            "position.coordinates",
            "expected an array of 2 or 3 numbers".into(),
        ));
    };
    if !(2..=3).contains(&coordinates.len()) {
        return Err(err(
            "position.coordinates",
            format!("expected 2 or 3 numbers, got {}", coordinates.len()),
        ));
    }
    for (i, c) in coordinates.iter().enumerate() {
        if !c.as_f64().is_some_and(f64::is_finite) {
            return Err(err(
                &format!("position.coordinates[{i}]"),
                format!("expected a finite number, got {c}"),
            ));
        }
    }
    // strings
    for field in STRING_FIELDS.iter().chain(&["provider_id"]) {
        if let Some(v) = object.get(*field) {
            if !v.is_string() {
                return Err(err(field, format!("expected a string, got {v}")));
            }
        }
    }
    for field in ["source", "provider_id"] {
        if object.get(field).and_then(Value::as_str) == Some("") {
            return Err(err(field, "must not be empty".into()));
        }
    }
    let provider_type = object.get("provider_type");
    if !ProviderType::ALL
        .iter()
        .any(|t| provider_type.and_then(Value::as_str) == Some(t.name()))
    {
        let allowed: Vec<&str> = ProviderType::ALL.iter().map(|t| t.name()).collect();
        return Err(err("provider_type", format!("expected one of {}", allowed.join(", "))));
    }
    if let Some(v) = object.get("elevation_ref") {
        if !matches!(v.as_str(), Some("floor" | "wgs84")) {
            return Err(err("elevation_ref", "expected \"floor\" or \"wgs84\"".into()));
        }
    }
    for field in ["timestamp_generated", "timestamp_sent"] {
        if let Some(v) = object.get(field) {
            let Some(text) = v.as_str() else {
                return Err(err(field, format!("expected an ISO 8601 string, got {v}")));
            };
            super::time::parse_timestamp(text, field).map_err(|e| match e {
                ServerError::Unrepresentable { reason, .. } => err(field, reason),
                other => other,
            })?;
        }
    }
    for field in NUMBER_FIELDS {
        if let Some(v) = object.get(field) {
            let Some(x) = v.as_f64().filter(|x| x.is_finite()) else {
                return Err(err(field, format!("expected a finite number, got {v}")));
            };
            if matches!(field, "accuracy" | "speed") && x < 0.0 {
                return Err(err(field, format!("must be ≥ 0, got {x}")));
            }
        }
    }
    if let Some(v) = object.get("associated") {
        if !v.is_boolean() {
            return Err(err("associated", format!("expected a boolean, got {v}")));
        }
    }
    if let Some(v) = object.get("trackables") {
        let Value::Array(ids) = v else {
            return Err(err("trackables", "expected an array of ids".into()));
        };
        if let Some(i) = ids.iter().position(|id| !id.is_string()) {
            return Err(err(&format!("trackables[{i}]"), "expected a string".into()));
        }
    }
    if let Some(v) = object.get("properties") {
        if !v.is_object() {
            return Err(err("properties", "expected an object".into()));
        }
    }
    Ok(())
}
