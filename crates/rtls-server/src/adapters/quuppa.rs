//! Quuppa Positioning Engine (QPE): tag data in the `DefaultLocation` format, as the QPE
//! serves it on `/qpe/getTagData?format=DefaultLocation` and pushes it to output targets.
//!
//! A payload is one tag object, an array of them, or a response object with a `tags` array.
//!
//! | Quuppa field | record field |
//! | --- | --- |
//! | `tagId` | `tag` |
//! | `locationTS` (Unix ms) | `t` (÷ 1000) |
//! | `location` `[x, y(, z)]` (m, the coordinate system `locationCoordSysId`) | `position_m` |
//! | `locationRadius` (m) | `covariance_m2` = `locationRadius² I` (else `default_accuracy_m² I`) |
//! | `locationType` other than `position` (a presence), or `location` null / absent | refused, reason `no_position` |
//!
//! # References
//! - Quuppa, "API Data Formats & Output Targets" (Quuppa Site Planner manual),
//!   <https://www.quuppa.com/documentation/QSP/topics/QSP_udp_logging_api.html> (the
//!   `DefaultLocation` format of `/getTagData` and of output targets).
//! - The example message of the tests: the push (UDP output target) sample JSON quoted in
//!   "Upload QPE data to cloud", <https://blog.csdn.net/wanghao_sh/article/details/122429471>
//!   (tag `d10000001111`, `location` [-1.09, 0.38, 1.0], `locationTS` 1641888440139,
//!   `locationRadius` 0.09).

use serde_json::Value;

use super::{accuracy_or, fix, number, tag_id, AdapterError, Parsed, Refusal};

/// Parses a Quuppa payload.
pub(super) fn parse(value: &Value, default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
    let (prefix, tags): (&str, Vec<&Value>) = match value {
        Value::Array(items) => ("", items.iter().collect()),
        Value::Object(object) => match object.get("tags") {
            Some(Value::Array(items)) => ("tags", items.iter().collect()),
            Some(other) => {
                return Err(AdapterError::field(
                    "tags",
                    format!("expected an array of tag objects, got {other}"),
                ))
            }
            None => ("", vec![value]),
        },
        other => {
            return Err(AdapterError::field(
                "-",
                format!("expected a tag object or an array of them, got {other}"),
            ))
        }
    };
    let mut parsed = Parsed::default();
    for (index, tag) in tags.into_iter().enumerate() {
        let at = format!("{prefix}[{index}]");
        let Value::Object(object) = tag else {
            return Err(AdapterError::field(at, "expected a tag object"));
        };
        let id = tag_id(object.get("tagId"), &format!("{at}.tagId"))?;
        let location_type = object.get("locationType").and_then(Value::as_str);
        let location = object.get("location").filter(|l| !l.is_null());
        if location_type.is_some_and(|t| t != "position") || location.is_none() {
            let detail = match location_type.filter(|t| *t != "position") {
                Some(t) => format!("locationType is {t:?}, not \"position\""),
                None => "no location".to_string(),
            };
            parsed.refusals.push(Refusal {
                at,
                tag: Some(id),
                reason: "no_position",
                detail,
            });
            continue;
        }
        let field = format!("{at}.location");
        let Some(Value::Array(coordinates)) = location else {
            return Err(AdapterError::field(field, "expected an array of 2 or 3 numbers (m)"));
        };
        if !(2..=3).contains(&coordinates.len()) {
            return Err(AdapterError::field(
                field,
                format!("expected 2 or 3 numbers (m), got {}", coordinates.len()),
            ));
        }
        let position_m = coordinates
            .iter()
            .enumerate()
            .map(|(i, c)| number(c, &format!("{field}[{i}]")))
            .collect::<Result<Vec<f64>, _>>()?;
        let ts_field = format!("{at}.locationTS");
        let time_ms = number(
            object
                .get("locationTS")
                .ok_or_else(|| AdapterError::field(&ts_field, "required field is missing"))?,
            &ts_field,
        )?;
        let radius_m = match object.get("locationRadius") {
            None | Some(Value::Null) => None,
            Some(v) => Some(number(v, &format!("{at}.locationRadius"))?),
        };
        // milliseconds → seconds
        let time_s = time_ms / 1000.0;
        parsed
            .records
            .push(fix(time_s, id, position_m, accuracy_or(radius_m, default_accuracy_m)));
    }
    Ok(parsed)
}

#[cfg(test)]
mod tests {

    use super::super::{fix_of, parse, Vendor};

    /// The published sample (see the module's references).
    const EXAMPLE: &str = r##"{
      "tagId": "d10000001111",
      "tagName": null,
      "color": "#FF0000",
      "tagGroupName": null,
      "locationType": "position",
      "locationMovementStatus": "stationary",
      "locationRadius": 0.09,
      "location": [-1.09, 0.38, 1.0],
      "locationTS": 1641888440139,
      "locationCoordSysId": "3e7c4371-42be-4019-b7c0-ec2012d448ad",
      "locationCoordSysName": "CoordSys001",
      "locationZoneIds": ["b9dae3fd-c055-4f29-b882-c23421635699", "176ca962-8b45-46f2-ba73-52978a6bc1b8"],
      "locationZoneNames": ["Desk_1", "Inside"]
    }"##;

    #[test]
    fn a_published_tag_becomes_a_fix_weighed_by_its_radius() {
        let parsed = parse(Vendor::Quuppa, EXAMPLE.as_bytes(), 1.0).unwrap();
        assert!(parsed.refusals.is_empty());
        let record = &parsed.records[0];
        assert_eq!(record.tag, "d10000001111");
        assert!((record.time_s - 1_641_888_440.139).abs() < 1e-6);
        let (position_m, covariance_m2) = fix_of(record);
        assert_eq!(position_m, &vec![-1.09, 0.38, 1.0]);
        // σ = locationRadius = 0.09 m → 0.0081 m² on the diagonal
        assert!((covariance_m2[0] - 0.0081).abs() < 1e-12);
        assert!((covariance_m2[4] - 0.0081).abs() < 1e-12);
        assert!((covariance_m2[8] - 0.0081).abs() < 1e-12);
        assert_eq!(covariance_m2[1], 0.0);
    }

    #[test]
    fn a_response_with_tags_and_a_presence_refuses_the_presence() {
        let presence = EXAMPLE
            .replace(r#""locationType": "position""#, r#""locationType": "presence""#)
            .replace("d10000001111", "d10000002222");
        let response = format!(r#"{{"code": 0, "status": "Ok", "tags": [{EXAMPLE}, {presence}]}}"#);
        let parsed = parse(Vendor::Quuppa, response.as_bytes(), 1.0).unwrap();
        assert_eq!(parsed.records.len(), 1);
        assert_eq!(parsed.refusals[0].at, "tags[1]");
        assert_eq!(parsed.refusals[0].tag.as_deref(), Some("d10000002222"));
        assert_eq!(parsed.refusals[0].reason, "no_position");
    }

    #[test]
    fn a_missing_time_stamp_is_named() {
        let bad = EXAMPLE.replace(r#""locationTS": 1641888440139,"#, "");
        let error = parse(Vendor::Quuppa, bad.as_bytes(), 1.0).unwrap_err();
        assert_eq!(error.to_string(), "[0].locationTS: required field is missing");
    }
}
