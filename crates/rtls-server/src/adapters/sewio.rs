//! Sewio RTLS Studio: feeds with `datastreams`, as the WebSockets connector sends them
//! (`{"body": feed, "resource": "/feeds/{id}"}`) and the REST API serves them (one feed, or
//! `{"results": [feed, …]}` from `sensmapserver/api/feeds`).
//!
//! | Sewio field | record field |
//! | --- | --- |
//! | feed `id` | `tag` |
//! | datastream `posX`, `posY`, `posZ` `current_value` (m, a decimal string) | `position_m` (`posZ` optional) |
//! | the later `at` of `posX` / `posY` (UTC `YYYY-MM-DD hh:mm:ss.sss`) | `t` |
//! | datastream `clr` (confidence level radius, m) | `covariance_m2` = `clr² I` (`clr` 0 or absent: `default_accuracy_m² I`) |
//! | a feed without `posX` / `posY` (battery, firmware, zone updates) | refused, reason `no_position` |
//! | a feed of `"type": "anchor"` (REST) | refused, reason `anchor` |
//!
//! # References
//! - Sewio, "WebSockets Connector", <http://rtlsstudio.com/studio/index.php/websockets-connector/>
//!   — the example messages of the tests: tag 18's position (`posX` " 6.34", `posY` " 2.27",
//!   `clr` " 0.10" at 2016-10-18 14:16:56.365) and tag 1's battery update.
//! - The REST feed list of the tests (`sewio_feeds.json`): the first three feeds of an RTLS
//!   Studio `feeds` response in repository `kedwards/reactls`, file
//!   `src/components/feedResultsFake.js` (anchors 1 and 2 — their `barometerCalibration` and
//!   `location` left out — and tag 3 "Mike Anderson" at `posX` -20.57852, `posY` -14.91251,
//!   `posZ` 0).

use serde_json::{Map, Value};

use super::{accuracy_or, fix, tag_id, AdapterError, Parsed, Refusal};
use crate::omlox::time::parse_timestamp;

/// Parses a Sewio payload.
pub(super) fn parse(value: &Value, default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
    let Value::Object(object) = value else {
        return Err(AdapterError::field("-", format!("expected a feed object, got {value}")));
    };
    let feeds: Vec<(String, &Value)> = if let Some(body) = object.get("body") {
        vec![("body".into(), body)]
    } else if let Some(results) = object.get("results") {
        let Value::Array(items) = results else {
            return Err(AdapterError::field("results", "expected an array of feeds"));
        };
        items
            .iter()
            .enumerate()
            .map(|(i, f)| (format!("results[{i}]"), f))
            .collect()
    } else {
        vec![(String::new(), value)]
    };
    let mut parsed = Parsed::default();
    for (at, feed) in feeds {
        let Value::Object(feed) = feed else {
            return Err(AdapterError::field(at, "expected a feed object"));
        };
        let dot = if at.is_empty() { String::new() } else { format!("{at}.") };
        let tag = tag_id(feed.get("id"), &format!("{dot}id"))?;
        let at = if at.is_empty() { "-".to_string() } else { at };
        if feed.get("type").and_then(Value::as_str) == Some("anchor") {
            parsed.refusals.push(Refusal {
                at,
                tag: Some(tag),
                reason: "anchor",
                detail: "the feed is an anchor, not a tag".into(),
            });
            continue;
        }
        let streams = datastreams(feed, &dot)?;
        let (Some(x), Some(y)) = (streams.get("posX"), streams.get("posY")) else {
            parsed.refusals.push(Refusal {
                at,
                tag: Some(tag),
                reason: "no_position",
                detail: "the feed update has no posX and posY datastreams".into(),
            });
            continue;
        };
        let mut position_m = vec![x.value, y.value];
        if let Some(z) = streams.get("posZ") {
            position_m.push(z.value);
        }
        let time_s = x.time_s.max(y.time_s);
        let clr = streams.get("clr").map(|c| c.value);
        parsed
            .records
            .push(fix(time_s, tag, position_m, accuracy_or(clr, default_accuracy_m)));
    }
    Ok(parsed)
}

/// One datastream's value and time.
struct Stream {
    value: f64,
    time_s: f64,
}

/// The numeric datastreams the adapter reads (`posX`, `posY`, `posZ`, `clr`), by id.
fn datastreams(
    feed: &Map<String, Value>,
    dot: &str,
) -> Result<std::collections::HashMap<String, Stream>, AdapterError> {
    let field = format!("{dot}datastreams");
    let streams = match feed.get("datastreams") {
        None | Some(Value::Null) => return Ok(std::collections::HashMap::new()),
        Some(Value::Array(streams)) => streams,
        Some(other) => return Err(AdapterError::field(field, format!("expected an array, got {other}"))),
    };
    let mut out = std::collections::HashMap::new();
    for (i, stream) in streams.iter().enumerate() {
        let at = format!("{field}[{i}]");
        let Some(id) = stream.get("id").and_then(Value::as_str) else {
            return Err(AdapterError::field(format!("{at}.id"), "expected a datastream id"));
        };
        if !matches!(id, "posX" | "posY" | "posZ" | "clr") {
            continue;
        }
        let value_field = format!("{at}.current_value");
        let value = match stream.get("current_value") {
            Some(Value::String(s)) => s.trim().parse::<f64>().ok(),
            Some(v) => v.as_f64(),
            None => None,
        }
        .filter(|v| v.is_finite())
        .ok_or_else(|| AdapterError::field(&value_field, format!("expected a number (m) for {id}")))?;
        let at_field = format!("{at}.at");
        let Some(text) = stream.get("at").and_then(Value::as_str) else {
            return Err(AdapterError::field(
                at_field,
                "expected a UTC time such as 2016-10-18 14:16:56.365",
            ));
        };
        out.insert(
            id.to_string(),
            Stream {
                value,
                time_s: utc_seconds(text, &at_field)?,
            },
        );
    }
    Ok(out)
}

/// Sewio's UTC time `YYYY-MM-DD hh:mm:ss[.f…]` as Unix seconds.
fn utc_seconds(text: &str, field: &str) -> Result<f64, AdapterError> {
    let iso = format!("{}Z", text.trim().replacen(' ', "T", 1));
    parse_timestamp(&iso, field).map_err(|_| {
        AdapterError::field(
            field,
            format!("`{text}` is not a UTC time such as 2016-10-18 14:16:56.365"),
        )
    })
}

#[cfg(test)]
mod tests {

    use super::super::{fix_of, parse, Vendor};

    /// Tag 18's position update, from the WebSockets connector documentation.
    const POSITION: &str = r#"{"body":{"id":"18","datastreams":[{"id":"posX","current_value":" 6.34","at":"2016-10-18 14:16:56.365"},{"id":"posY","current_value":" 2.27","at":"2016-10-18 14:16:56.365"},{"id":"clr","current_value":" 0.10","at":"2016-10-18 14:16:56.365"}]},"resource":"\/feeds\/18"}"#;
    /// Tag 1's battery update, from the same page.
    const BATTERY: &str = r#"{"body":{"id":"1","datastreams":[{"id":"battery_level","current_value":"77%","at":"2016-10-18 15:27:38.606"},{"id":"firmware_version","current_value":"3.115","at":"2016-10-18 15:27:38.606"}]},"resource":"\/feeds\/1"}"#;

    #[test]
    fn a_websocket_position_becomes_a_fix_weighed_by_clr() {
        let parsed = parse(Vendor::Sewio, POSITION.as_bytes(), 1.0).unwrap();
        let record = &parsed.records[0];
        assert_eq!(record.tag, "18");
        // 2016-10-18T14:16:56.365Z
        assert!((record.time_s - 1_476_800_216.365).abs() < 1e-6, "{}", record.time_s);
        let (position_m, covariance_m2) = fix_of(record);
        assert_eq!(position_m, &vec![6.34, 2.27]);
        // σ = clr = 0.10 m
        assert!((covariance_m2[0] - 0.01).abs() < 1e-12);
        assert!((covariance_m2[3] - 0.01).abs() < 1e-12);
    }

    #[test]
    fn a_battery_update_is_refused_not_dropped() {
        let parsed = parse(Vendor::Sewio, BATTERY.as_bytes(), 1.0).unwrap();
        assert!(parsed.records.is_empty());
        assert_eq!(parsed.refusals[0].reason, "no_position");
        assert_eq!(parsed.refusals[0].tag.as_deref(), Some("1"));
    }

    #[test]
    fn a_rest_feed_list_gives_tags_and_refuses_anchors() {
        let text = include_str!("sewio_feeds.json");
        let parsed = parse(Vendor::Sewio, text.as_bytes(), 0.5).unwrap();
        assert_eq!(parsed.records.len(), 1);
        assert_eq!(parsed.refusals.len(), 2);
        assert!(parsed.refusals.iter().all(|r| r.reason == "anchor"));
        let record = &parsed.records[0];
        assert_eq!(record.tag, "3");
        // the later of posX / posY: 2020-05-12T21:15:54.399Z
        assert!((record.time_s - 1_589_318_154.399).abs() < 1e-6, "{}", record.time_s);
        let (position_m, covariance_m2) = fix_of(record);
        assert_eq!(position_m, &vec![-20.57852, -14.91251, 0.0]);
        // no clr: the default σ = 0.5 m
        assert!((covariance_m2[8] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn a_bad_time_is_named() {
        let bad = POSITION.replacen("2016-10-18 14:16:56.365", "18/10/2016", 1);
        let error = parse(Vendor::Sewio, bad.as_bytes(), 1.0).unwrap_err();
        assert_eq!(
            error.to_string(),
            "body.datastreams[0].at: `18/10/2016` is not a UTC time such as 2016-10-18 14:16:56.365"
        );
    }
}
