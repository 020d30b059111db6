//! What the Go client writes (its easyjson encoders, `json.Encoder`) and how it reads
//! (its easyjson decoders, `encoding/json`, geojson, uuid).

use serde_json::Value;

// ---- what the client writes (omlox_easyjson.go encoders, json.Encoder) ----

/// A JSON string as the client writes it (plain ASCII here, so `encoding/json`'s HTML escaping
/// does not come in).
pub fn go_str(text: &str) -> String {
    serde_json::to_string(text).unwrap()
}

/// A float as the client writes it: `strconv.AppendFloat(…, 'g' or 'f', -1, 64)`, which for the
/// values of this session is Rust's shortest round-trip form (`1`, `0.3`, `12.4`).
pub fn go_float(value: f64) -> String {
    assert!(
        value.is_finite() && value.abs() < 1e15,
        "{value} would be written differently"
    );
    format!("{value}")
}

/// Go's `time.Time` in `encoding/json` (RFC 3339 with nanoseconds, trailing zeros and a bare
/// `.` dropped), UTC as `Z`.
pub fn go_time(unix_ns: i128) -> String {
    let time = time::OffsetDateTime::from_unix_timestamp_nanos(unix_ns).unwrap();
    let seconds = time
        .format(time::macros::format_description!(
            "[year]-[month]-[day]T[hour]:[minute]:[second]"
        ))
        .unwrap();
    let fraction = format!("{:09}", time.nanosecond());
    let fraction = fraction.trim_end_matches('0');
    if fraction.is_empty() {
        format!("{seconds}Z")
    } else {
        format!("{seconds}.{fraction}Z")
    }
}

/// An `omlox.Trackable` as the client's encoder writes it: `id` and `type` always, the other
/// fields only when set (a `Duration` when defined, written as an integer, −1 for infinite).
#[derive(Default)]
pub struct GoTrackable<'a> {
    /// `uuid.UUID`; the zero value (the nil UUID) for a new trackable.
    pub id: &'a str,
    /// `TrackableType`: `omlox` (the zero value) or `virtual`.
    pub kind: &'a str,
    pub name: &'a str,
    pub extrusion: f64,
    pub location_providers: &'a [&'a str],
    pub fence_timeout_ms: Option<i64>,
    pub exit_tolerance: f64,
    pub tolerance_timeout_ms: Option<i64>,
    pub exit_delay_ms: Option<i64>,
    pub radius: f64,
    /// `json.RawMessage`.
    pub properties: Option<&'a str>,
    /// `(expression, priority)`.
    pub locating_rules: &'a [(&'a str, i64)],
}

impl GoTrackable<'_> {
    pub fn to_json(&self) -> String {
        let duration = |ms: i64| ms.max(-1).to_string();
        let mut fields = vec![
            format!("\"id\":{}", go_str(self.id)),
            format!("\"type\":{}", go_str(self.kind)),
        ];
        if !self.name.is_empty() {
            fields.push(format!("\"name\":{}", go_str(self.name)));
        }
        if self.extrusion != 0.0 {
            fields.push(format!("\"extrusion\":{}", go_float(self.extrusion)));
        }
        if !self.location_providers.is_empty() {
            let ids: Vec<String> = self.location_providers.iter().map(|p| go_str(p)).collect();
            fields.push(format!("\"location_providers\":[{}]", ids.join(",")));
        }
        if let Some(ms) = self.fence_timeout_ms {
            fields.push(format!("\"fence_timeout\":{}", duration(ms)));
        }
        if self.exit_tolerance != 0.0 {
            fields.push(format!("\"exit_tolerance\":{}", go_float(self.exit_tolerance)));
        }
        if let Some(ms) = self.tolerance_timeout_ms {
            fields.push(format!("\"tolerance_timeout\":{}", duration(ms)));
        }
        if let Some(ms) = self.exit_delay_ms {
            fields.push(format!("\"exit_delay\":{}", duration(ms)));
        }
        if self.radius != 0.0 {
            fields.push(format!("\"radius\":{}", go_float(self.radius)));
        }
        if let Some(raw) = self.properties {
            fields.push(format!("\"properties\":{raw}"));
        }
        if !self.locating_rules.is_empty() {
            let rules: Vec<String> = self
                .locating_rules
                .iter()
                .map(|(expression, priority)| {
                    format!("{{\"expression\":{},\"priority\":{priority}}}", go_str(expression))
                })
                .collect();
            fields.push(format!("\"locating_rules\":[{}]", rules.join(",")));
        }
        format!("{{{}}}", fields.join(","))
    }
}

/// An `omlox.LocationProvider` as the client writes it (`id`, `type`, then what is set).
pub fn go_provider_json(id: &str, kind: &str, name: &str) -> String {
    format!(
        "{{\"id\":{},\"type\":{},\"name\":{}}}",
        go_str(id),
        go_str(kind),
        go_str(name)
    )
}

/// One location of the walk: what the client pushes, and what comes back.
#[derive(Debug, Clone)]
pub struct Fix {
    pub provider_id: &'static str,
    pub position: [f64; 2],
    /// As the client writes it (RFC 3339, nanoseconds).
    pub timestamp_generated: String,
    /// The same instant, ms since the epoch (what matching the echo uses: the hub writes ms).
    pub unix_ms: i64,
    pub accuracy: f64,
}

/// The walk's `source`: the RTLS that computed the locations, as omlox names it.
pub const SOURCE: &str = "go-client-uwb-rtls";
/// The walk's application `properties` (kept by the hub, as omlox requires).
pub const FIX_PROPERTIES: &str = r#"{"battery":87,"firmware":"2.1.0"}"#;

impl Fix {
    /// An `omlox.Location` as the client's encoder writes it: `position` (tidwall/geojson's
    /// `{"type":"Point","coordinates":[…]}`), `source`, `provider_type`, `provider_id` always;
    /// `timestamp_generated`, `accuracy`, `properties` because they are set; `crs` empty (so
    /// absent: local), `floor` 0 (absent), no `trackables`.
    pub fn to_json(&self) -> String {
        format!(
            "{{\"position\":{{\"type\":\"Point\",\"coordinates\":[{},{}]}},\"source\":{},\"provider_type\":\"uwb\",\"provider_id\":{},\"timestamp_generated\":{},\"accuracy\":{},\"properties\":{}}}",
            go_float(self.position[0]),
            go_float(self.position[1]),
            go_str(SOURCE),
            go_str(self.provider_id),
            go_str(&self.timestamp_generated),
            go_float(self.accuracy),
            FIX_PROPERTIES
        )
    }
}

// ---- how the client reads (omlox_easyjson.go decoders, encoding/json, geojson, uuid) ----

/// `jlexer.String`.
pub fn go_string<'v>(value: &'v Value, field: &str) -> Result<&'v str, String> {
    value.as_str().ok_or_else(|| format!("{field}: not a string: {value}"))
}

/// `jlexer.Float64`.
pub fn go_number(value: &Value, field: &str) -> Result<f64, String> {
    value.as_f64().ok_or_else(|| format!("{field}: not a number: {value}"))
}

/// `jlexer.Int` (`strconv.ParseInt` of the number's text: `5000.0` and `5e3` are refused).
pub fn go_int(value: &Value, field: &str) -> Result<i64, String> {
    match value {
        Value::Number(n) if !n.is_f64() => n.as_i64().ok_or_else(|| format!("{field}: out of range: {value}")),
        _ => Err(format!("{field}: strconv.ParseInt refuses {value}")),
    }
}

/// `jlexer.Bool`.
pub fn go_bool(value: &Value, field: &str) -> Result<bool, String> {
    value.as_bool().ok_or_else(|| format!("{field}: not a bool: {value}"))
}

/// `uuid.UUID.UnmarshalText` (google/uuid accepts the 36-character form, with `urn:uuid:`
/// or braces, and 32 hex digits; so does `uuid::Uuid::parse_str`).
pub fn go_uuid(value: &Value, field: &str) -> Result<uuid::Uuid, String> {
    let text = go_string(value, field)?;
    uuid::Uuid::parse_str(text).map_err(|e| format!("{field}: not a UUID ({e}): {text}"))
}

/// `time.Time.UnmarshalJSON`: a string in RFC 3339.
pub fn go_timestamp(value: &Value, field: &str) -> Result<time::OffsetDateTime, String> {
    let text = go_string(value, field)?;
    time::OffsetDateTime::parse(text, &time::format_description::well_known::Rfc3339)
        .map_err(|e| format!("{field}: not RFC 3339 ({e}): {text}"))
}

/// An enum's `UnmarshalJSON` (`FromString`): one of `names`.
pub fn go_enum(value: &Value, field: &str, names: &[&str]) -> Result<(), String> {
    let text = go_string(value, field)?;
    if names.contains(&text) {
        Ok(())
    } else {
        Err(format!("{field}: {text} is not one of {names:?}"))
    }
}

/// `LocationProviderType` names.
pub const PROVIDER_TYPES: [&str; 7] = ["unknown", "uwb", "gps", "wifi", "rfid", "ibeacon", "virtual"];

/// Numbers of a GeoJSON position (tidwall/geojson: at least two).
pub fn geojson_position(value: &Value, field: &str) -> Result<Vec<f64>, String> {
    let numbers = value
        .as_array()
        .ok_or_else(|| format!("{field}: a position is an array: {value}"))?
        .iter()
        .map(|n| go_number(n, field))
        .collect::<Result<Vec<f64>, String>>()?;
    if numbers.len() < 2 {
        return Err(format!("{field}: a position has two or three numbers: {value}"));
    }
    Ok(numbers)
}

/// `omlox.Point.UnmarshalJSON`: `geojson.Parse` must give a Point.
pub fn go_point(value: &Value, field: &str) -> Result<Vec<f64>, String> {
    if value["type"] != "Point" {
        return Err(format!("{field}: not a valid geojson point: {value}"));
    }
    geojson_position(&value["coordinates"], field)
}

/// `omlox.Polygon.UnmarshalJSON`: `geojson.Parse` must give a Polygon.
pub fn go_polygon(value: &Value, field: &str) -> Result<(), String> {
    if value["type"] != "Polygon" {
        return Err(format!("{field}: not a valid geojson polygon: {value}"));
    }
    let rings = value["coordinates"]
        .as_array()
        .ok_or_else(|| format!("{field}: rings are an array: {value}"))?;
    for ring in rings {
        for position in ring.as_array().ok_or_else(|| format!("{field}: a ring is an array"))? {
            geojson_position(position, field)?;
        }
    }
    Ok(())
}

/// The object an easyjson decoder walks: the members it knows, `null` members skipped (as the
/// generated code skips them before its `switch`), names compared exactly.
pub fn go_object<'v>(value: &'v Value, what: &str) -> Result<Vec<(&'v str, &'v Value)>, String> {
    let object = value
        .as_object()
        .ok_or_else(|| format!("{what}: not an object: {value}"))?;
    Ok(object
        .iter()
        .filter(|(_, v)| !v.is_null())
        .map(|(k, v)| (k.as_str(), v))
        .collect())
}

/// `Duration.UnmarshalEasyJSON`: an integer number of ms.
pub fn go_duration(value: &Value, field: &str) -> Result<i64, String> {
    go_int(value, field)
}

/// What the client's `Trackable` decoder keeps of one, or its error (`Create`, `Get` and
/// `List` return that error instead of the trackable).
#[derive(Debug)]
pub struct DecodedTrackable {
    pub id: uuid::Uuid,
    pub name: String,
    pub location_providers: Vec<String>,
}

pub fn go_decode_trackable(value: &Value) -> Result<DecodedTrackable, String> {
    let mut decoded = DecodedTrackable {
        id: uuid::Uuid::nil(),
        name: String::new(),
        location_providers: Vec::new(),
    };
    for (key, member) in go_object(value, "Trackable")? {
        match key {
            "id" => decoded.id = go_uuid(member, key)?,
            "type" => go_enum(member, key, &["omlox", "virtual"])?,
            "name" => decoded.name = go_string(member, key)?.to_string(),
            "geometry" => go_polygon(member, key)?,
            "extrusion" | "exit_tolerance" | "radius" => {
                go_number(member, key)?;
            }
            "location_providers" => {
                for provider in member.as_array().ok_or("location_providers: not an array")? {
                    decoded.location_providers.push(go_string(provider, key)?.to_string());
                }
            }
            "fence_timeout" | "tolerance_timeout" | "exit_delay" => {
                go_duration(member, key)?;
            }
            "locating_rules" => {
                for rule in member.as_array().ok_or("locating_rules: not an array")? {
                    for (rule_key, rule_member) in go_object(rule, "LocatingRule")? {
                        match rule_key {
                            "expression" => {
                                go_string(rule_member, "locating_rules[].expression")?;
                            }
                            "priority" => {
                                go_int(rule_member, "locating_rules[].priority")?;
                            }
                            _ => {}
                        }
                    }
                }
            }
            // properties: json.RawMessage takes anything; other members are skipped
            _ => {}
        }
    }
    Ok(decoded)
}

/// What the client's `LocationProvider` decoder needs.
pub fn go_decode_provider(value: &Value) -> Result<String, String> {
    let mut id = String::new();
    for (key, member) in go_object(value, "LocationProvider")? {
        match key {
            "id" => id = go_string(member, key)?.to_string(),
            "type" => go_enum(member, key, &PROVIDER_TYPES)?,
            "name" => {
                go_string(member, key)?;
            }
            "fence_timeout" | "tolerance_timeout" | "exit_delay" => {
                go_duration(member, key)?;
            }
            "exit_tolerance" => {
                go_number(member, key)?;
            }
            _ => {}
        }
    }
    Ok(id)
}

/// What the client's `Location` decoder keeps of one (`ReceiveAs[Location]` drops a payload
/// object that does not decode; `GetLocation` returns the error).
#[derive(Debug, Default)]
pub struct DecodedLocation {
    pub position: Vec<f64>,
    pub source: String,
    pub provider_type: String,
    pub provider_id: String,
    pub timestamp_generated: Option<time::OffsetDateTime>,
    pub accuracy: Option<f64>,
    pub trackables: Vec<uuid::Uuid>,
    pub properties: Option<Value>,
}

pub fn go_decode_location(value: &Value) -> Result<DecodedLocation, String> {
    let mut decoded = DecodedLocation::default();
    for (key, member) in go_object(value, "Location")? {
        match key {
            "position" => decoded.position = go_point(member, key)?,
            "source" => decoded.source = go_string(member, key)?.to_string(),
            "provider_type" => {
                go_enum(member, key, &PROVIDER_TYPES)?;
                decoded.provider_type = go_string(member, key)?.to_string();
            }
            "provider_id" => decoded.provider_id = go_string(member, key)?.to_string(),
            "trackables" => {
                for id in member.as_array().ok_or("trackables: not an array")? {
                    decoded.trackables.push(go_uuid(id, key)?);
                }
            }
            "timestamp_generated" => decoded.timestamp_generated = Some(go_timestamp(member, key)?),
            "timestamp_sent" => {
                go_timestamp(member, key)?;
            }
            "crs" => {
                go_string(member, key)?;
            }
            "associated" => {
                go_bool(member, key)?;
            }
            "accuracy" => decoded.accuracy = Some(go_number(member, key)?),
            "floor" | "true_heading" | "magnetic_heading" | "heading_accuracy" | "speed" | "course" => {
                go_number(member, key)?;
            }
            "elevation_ref" => go_enum(member, key, &["floor", "wgs84"])?,
            "properties" => decoded.properties = Some(member.clone()),
            _ => {}
        }
    }
    Ok(decoded)
}
