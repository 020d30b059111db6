//! Pozyx Enterprise / Creator: the MQTT positioning stream (topic `tags`, or `tags/{tagId}`).
//!
//! Each MQTT packet is a JSON array of tag updates (the local stream sends one per packet, the
//! cloud stream may batch several); an update has `tagId` (string), `timestamp` (Unix
//! seconds, fractional), `success` (whether a position was computed) and, on success,
//! `data.coordinates.{x, y, z}` in millimetres. A single update object is accepted too.
//!
//! | Pozyx field | record field |
//! | --- | --- |
//! | `tagId` | `tag` |
//! | `timestamp` (s) | `t` |
//! | `data.coordinates.x`, `.y`, `.z` (mm) | `position_m` (÷ 1000; `z` optional) |
//! | — (the stream has no accuracy) | `covariance_m2` = `default_accuracy_m² I` |
//! | `success: false`, or no `data.coordinates` | refused, reason `no_position` |
//!
//! # References
//! - Pozyx, "MQTT positioning stream data structure",
//!   <https://docs.pozyx.io/enterprise/MQTT-data-structure.1224015817.html> (array of updates,
//!   `tagId`, `timestamp` in Epoch time) and "Triggers data structure",
//!   <https://docs.pozyx.io/enterprise/triggers-data-structure> (coordinates in mm).
//! - The example message of the tests: the Pozyx stream fields of the `UWBAnchor` example in
//!   FIWARE Smart Data Models, repository `smart-data-models/dataModel.Device`, file
//!   `UWBAnchor/doc/spec_FR.md` (tag `10006789`, `timestamp` 1671165464.3779979, coordinates
//!   29340, 69521, 1000 mm).

use serde_json::Value;

use super::{accuracy_or, fix, number, objects, tag_id, AdapterError, Parsed, Refusal};

/// Parses a Pozyx payload (an array of tag updates, or one update).
pub(super) fn parse(value: &Value, default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
    let updates = objects(value, "an array of tag updates")?;
    let mut parsed = Parsed::default();
    for (index, update) in updates.into_iter().enumerate() {
        let at = format!("[{index}]");
        let Value::Object(object) = update else {
            return Err(AdapterError::field(at, "expected a tag update object"));
        };
        let tag = tag_id(object.get("tagId"), &format!("{at}.tagId"))?;
        let success = match object.get("success") {
            None => true,
            Some(Value::Bool(b)) => *b,
            Some(other) => {
                return Err(AdapterError::field(
                    format!("{at}.success"),
                    format!("expected true or false, got {other}"),
                ))
            }
        };
        let coordinates = object.get("data").and_then(|d| d.get("coordinates"));
        if !success || coordinates.is_none_or(Value::is_null) {
            let why = if success {
                "no data.coordinates"
            } else {
                "success is false"
            };
            let code = object
                .get("errorCode")
                .map(|c| format!(" (errorCode {c})"))
                .unwrap_or_default();
            parsed.refusals.push(Refusal {
                at,
                tag: Some(tag),
                reason: "no_position",
                detail: format!("the update has no position: {why}{code}"),
            });
            continue;
        }
        let time_s = number(
            object
                .get("timestamp")
                .ok_or_else(|| AdapterError::field(format!("{at}.timestamp"), "required field is missing"))?,
            &format!("{at}.timestamp"),
        )?;
        let coordinates = coordinates.unwrap_or(&Value::Null);
        let mut position_m = Vec::with_capacity(3);
        for axis in ["x", "y", "z"] {
            let field = format!("{at}.data.coordinates.{axis}");
            match coordinates.get(axis) {
                // millimetres → metres
                Some(v) => position_m.push(number(v, &field)? / 1000.0),
                None if axis == "z" => {}
                None => return Err(AdapterError::field(field, "required field is missing")),
            }
        }
        parsed
            .records
            .push(fix(time_s, tag, position_m, accuracy_or(None, default_accuracy_m)));
    }
    Ok(parsed)
}

#[cfg(test)]
mod tests {

    use super::super::{fix_of, parse, Vendor};

    /// The Pozyx stream fields of the published example (see the module's references).
    const EXAMPLE: &str = r#"[{"version": "0.1", "tagId": "10006789", "timestamp": 1671165464.3779979, "success": true,
        "data": {"coordinates": {"x": 29340, "y": 69521, "z": 1000},
                 "tagData": {"blinkIndex": 1896215, "accelerometer": [{"x": 402, "y": -890, "z": -27}]},
                 "anchorData": [{"anchorId": "4678", "rss": -85}, {"anchorId": "5565", "rss": -100}]}}]"#;

    #[test]
    fn a_published_update_becomes_a_fix_in_metres_and_seconds() {
        let parsed = parse(Vendor::Pozyx, EXAMPLE.as_bytes(), 0.3).unwrap();
        assert!(parsed.refusals.is_empty());
        let record = &parsed.records[0];
        assert_eq!(record.tag, "10006789");
        assert!((record.time_s - 1_671_165_464.377_998).abs() < 1e-6);
        let (position_m, covariance_m2) = fix_of(record);
        assert_eq!(position_m, &vec![29.34, 69.521, 1.0]);
        // no accuracy in the stream: the default σ = 0.3 m on each axis
        let expected = [0.09, 0.0, 0.0, 0.0, 0.09, 0.0, 0.0, 0.0, 0.09];
        for (got, want) in covariance_m2.iter().zip(expected) {
            assert!((got - want).abs() < 1e-12, "{covariance_m2:?}");
        }
    }

    #[test]
    fn an_update_without_success_is_refused_with_its_tag() {
        // the published example as the stream sends it when no position was computed
        let failed = EXAMPLE
            .replace(r#""success": true"#, r#""success": false"#)
            .replace(r#""coordinates": {"x": 29340, "y": 69521, "z": 1000},"#, "");
        let batch = format!("[{}, {}]", &failed[1..failed.len() - 1], &EXAMPLE[1..EXAMPLE.len() - 1]);
        let parsed = parse(Vendor::Pozyx, batch.as_bytes(), 1.0).unwrap();
        assert_eq!(parsed.records.len(), 1);
        assert_eq!(parsed.refusals.len(), 1);
        let refusal = &parsed.refusals[0];
        assert_eq!((refusal.at.as_str(), refusal.reason), ("[0]", "no_position"));
        assert_eq!(refusal.tag.as_deref(), Some("10006789"));
    }

    #[test]
    fn a_malformed_coordinate_is_named() {
        let bad = EXAMPLE.replace(r#""y": 69521"#, r#""y": "69521""#);
        let error = parse(Vendor::Pozyx, bad.as_bytes(), 1.0).unwrap_err();
        assert_eq!(
            error.to_string(),
            r#"[0].data.coordinates.y: expected a finite number, got "69521""#
        );
    }
}
