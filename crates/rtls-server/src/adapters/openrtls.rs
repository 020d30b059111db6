//! OpenRTLS: the master's location (LS) output in JSON, one message per UDP datagram (port
//! 8787, API version 16040600).
//!
//! A message has `id` (the tag, e.g. `0xDECA343036200653`), `timestamp` (Unix seconds with
//! decimals), `msgid` and, when the tag was located, `coordinates` `{x, y, z, heading, pqf}`
//! and its measurements `meas` (TWR: `anchor`, `dist`, `tqf`, `rssi`). A payload is one message
//! or, for several at once over HTTP, an array of them.
//!
//! | OpenRTLS field | record field |
//! | --- | --- |
//! | `id` | `tag` |
//! | `timestamp` (s) | `t` |
//! | `coordinates.x`, `.y`, `.z` (m) | `position_m` (`z` optional) |
//! | — (`pqf`, a position quality factor, has no published scale) | `covariance_m2` = `default_accuracy_m² I` |
//! | no `coordinates` (the "basic" location message) | refused, reason `no_position` |
//!
//! The page states no unit for the coordinates: they are read as metres, which its example's
//! values (a tag 1.15 m and 2.38 m from two anchors at `x` 4.48, `y` 1.87) fit. `pqf` is not
//! turned into an accuracy: the page gives no scale for it (0–100 %?), so the server's
//! `default_accuracy_m` weighs the fixes. The TLV (binary) output is not read.
//!
//! # References
//! - OpenRTLS wiki, "Software:JsonCommands", API Interface (version 16040600),
//!   <https://wiki.openrtls.com/index.php?title=Software:JsonCommands> ("Location data",
//!   "JSON output data (UDP)": the basic location message and the TWR JSON message).
//! - The example messages of the tests: that page's basic message (`0xDECA343036200653`,
//!   `timestamp` 1459890647.818, `msgid` 6364) and its TWR example (`timestamp`
//!   1459933834.145, `msgid` 1638, `coordinates` 4.481, 1.868, 0.831, `heading` 0, `pqf` 95),
//!   whose `meas` list is cut after its first two entries here (the stored copy of the page
//!   this was written from breaks off inside the third).

use serde_json::Value;

use super::{fix, number, objects, tag_id, AdapterError, Parsed, Refusal};

/// Parses an OpenRTLS payload (one location message, or an array of them).
pub(super) fn parse(value: &Value, default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
    let messages = objects(value, "a location message object or an array of them")?;
    let mut parsed = Parsed::default();
    for (index, message) in messages.into_iter().enumerate() {
        let at = format!("[{index}]");
        let Value::Object(object) = message else {
            return Err(AdapterError::field(at, "expected a location message object"));
        };
        let id = tag_id(object.get("id"), &format!("{at}.id"))?;
        let Some(coordinates) = object.get("coordinates").filter(|c| !c.is_null()) else {
            parsed.refusals.push(Refusal {
                at,
                tag: Some(id),
                reason: "no_position",
                detail: "no coordinates (a location message without a position)".to_string(),
            });
            continue;
        };
        let field = |name: &str| format!("{at}.coordinates.{name}");
        let coordinate = |name: &str| match coordinates.get(name) {
            None => Err(AdapterError::field(field(name), "required field is missing")),
            Some(v) => number(v, &field(name)),
        };
        if !coordinates.is_object() {
            return Err(AdapterError::field(
                format!("{at}.coordinates"),
                format!("expected an object {{x, y, z, …}}, got {coordinates}"),
            ));
        }
        let mut position_m = vec![coordinate("x")?, coordinate("y")?];
        if coordinates.get("z").is_some_and(|z| !z.is_null()) {
            position_m.push(coordinate("z")?);
        }
        let time_field = format!("{at}.timestamp");
        let time_s = number(
            object
                .get("timestamp")
                .ok_or_else(|| AdapterError::field(&time_field, "required field is missing"))?,
            &time_field,
        )?;
        parsed.records.push(fix(time_s, id, position_m, default_accuracy_m));
    }
    Ok(parsed)
}

#[cfg(test)]
mod tests {

    use super::super::{fix_of, parse, Vendor};

    /// The page's TWR JSON message (see the module's references; `meas` cut to two entries).
    const TWR: &str = r#"{
      "id": "0xDECA343036200653",
      "timestamp": 1459933834.145,
      "msgid": 1638,
      "coordinates": {
        "x": 4.481,
        "y": 1.868,
        "z": 0.831,
        "heading": 0,
        "pqf": 95
      },
      "meas": [
        {
          "anchor": "0xDECA313032602090",
          "dist": 1.152,
          "tqf": 1,
          "rssi": -78
        },
        {
          "anchor": "0xDECA303033300BFA",
          "dist": 2.384,
          "tqf": 1,
          "rssi": -76.5
        }
      ]
    }"#;

    /// The page's basic location message: no coordinates.
    const BASIC: &str = r#"{"id":"0xDECA343036200653","timestamp":1459890647.818,"msgid":6364}"#;

    #[test]
    fn a_twr_message_becomes_a_3d_fix_weighed_by_the_default() {
        let parsed = parse(Vendor::OpenRtls, TWR.as_bytes(), 0.7).unwrap();
        assert!(parsed.refusals.is_empty());
        let record = &parsed.records[0];
        assert_eq!(record.tag, "0xDECA343036200653");
        assert_eq!(record.time_s, 1_459_933_834.145);
        let (position_m, covariance_m2) = fix_of(record);
        assert_eq!(position_m, &vec![4.481, 1.868, 0.831]);
        assert!((covariance_m2[0] - 0.49).abs() < 1e-12 && (covariance_m2[8] - 0.49).abs() < 1e-12);
    }

    #[test]
    fn a_basic_message_is_refused_and_an_array_is_read_message_by_message() {
        let payload = format!("[{BASIC}, {TWR}]");
        let parsed = parse(Vendor::OpenRtls, payload.as_bytes(), 1.0).unwrap();
        assert_eq!(parsed.records.len(), 1);
        assert_eq!(parsed.refusals[0].at, "[0]");
        assert_eq!(parsed.refusals[0].tag.as_deref(), Some("0xDECA343036200653"));
        assert_eq!(parsed.refusals[0].reason, "no_position");
    }

    #[test]
    fn a_malformed_field_is_named() {
        let bad = TWR.replace(r#""y": 1.868"#, r#""y": "1.868""#);
        let error = parse(Vendor::OpenRtls, bad.as_bytes(), 1.0).unwrap_err();
        assert_eq!(
            error.to_string(),
            r#"[0].coordinates.y: expected a finite number, got "1.868""#
        );
        let untimed = TWR.replace(r#""timestamp": 1459933834.145,"#, "");
        let error = parse(Vendor::OpenRtls, untimed.as_bytes(), 1.0).unwrap_err();
        assert_eq!(error.to_string(), "[0].timestamp: required field is missing");
    }
}
