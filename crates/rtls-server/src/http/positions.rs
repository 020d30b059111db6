//! Positions in columns: the `rtls:positions` WebSocket topic and its snapshot,
//! `GET /api/v1/positions` — what a map of thousands of tags reads.
//!
//! One object with one array per field, entry *i* of every array one tag:
//!
//! ```json
//! {"tag": ["m-1", "m-2"], "t": [1795000000.1, 1795000000.1], "x": [12.345, 40.0],
//!  "y": [3.2, 7.75], "z": [null, null], "cxx": [0.04, 0.09], "cxy": [0.0, 0.01],
//!  "cyy": [0.04, 0.09], "status": ["confirmed", "coasting"], "predicted": [0, 1]}
//! ```
//!
//! Positions are rounded to the millimetre and the covariance (the x–y block, m²) to single
//! precision: a third of the bytes of omlox `Location` objects and several times less for a
//! browser to parse, which at ten thousand tags decides whether the map keeps its frame rate.

use axum::extract::State;
use axum::http::HeaderMap;
use axum::Json;
use serde_json::{json, Map, Value};

use super::{ApiResult, AppState};
use crate::auth::Access;
use crate::omlox::Location;

/// Builds the columns from omlox `Location` objects.
#[derive(Debug, Default)]
pub struct PositionColumns {
    tag: Vec<Value>,
    t: Vec<Value>,
    x: Vec<Value>,
    y: Vec<Value>,
    z: Vec<Value>,
    cxx: Vec<Value>,
    cxy: Vec<Value>,
    cyy: Vec<Value>,
    status: Vec<Value>,
    predicted: Vec<Value>,
}

/// `v` rounded to the millimetre (m).
fn mm(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

impl PositionColumns {
    /// Adds a tag's location at `time_s` (s); a location without an x–y position is skipped.
    pub fn push(&mut self, tag: &str, time_s: f64, location: &Location) {
        let coordinates = &location.position.coordinates;
        let no_properties = Map::new();
        let properties = location.properties.as_ref().unwrap_or(&no_properties);
        let coordinate = |k: usize| coordinates.get(k).copied();
        let (Some(x), Some(y)) = (coordinate(0), coordinate(1)) else {
            return;
        };
        self.tag.push(Value::String(tag.to_string()));
        self.t.push(json!(mm(time_s)));
        self.x.push(json!(mm(x)));
        self.y.push(json!(mm(y)));
        self.z.push(coordinate(2).map_or(Value::Null, |z| json!(mm(z))));
        // the x–y block of the row-major covariance (2 × 2 or 3 × 3)
        let covariance = properties.get("rtls:covariance_m2").and_then(Value::as_array);
        let dimension = if covariance.is_some_and(|c| c.len() == 9) { 3 } else { 2 };
        let entry = |k: usize| {
            covariance
                .and_then(|c| c.get(k))
                .and_then(Value::as_f64)
                .map_or(Value::Null, |v| json!(v as f32))
        };
        self.cxx.push(entry(0));
        self.cxy.push(entry(1));
        self.cyy.push(entry(dimension + 1));
        self.status
            .push(properties.get("rtls:status").cloned().unwrap_or(Value::Null));
        let predicted = properties.get("rtls:predicted").and_then(Value::as_bool);
        self.predicted.push(json!(u8::from(predicted.unwrap_or(false))));
    }

    /// The columns, or `None` when no tag was added.
    #[must_use]
    pub fn finish(self) -> Option<Value> {
        (!self.tag.is_empty()).then(|| self.into_value())
    }

    fn into_value(self) -> Value {
        json!({
            "tag": self.tag, "t": self.t, "x": self.x, "y": self.y, "z": self.z,
            "cxx": self.cxx, "cxy": self.cxy, "cyy": self.cyy,
            "status": self.status, "predicted": self.predicted,
        })
    }
}

/// `GET /api/v1/positions`: every tag's latest state in columns (read token) — the
/// `rtls:positions` topic's snapshot, what the dashboard loads first and reconciles with.
pub(super) async fn positions(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let mut columns = PositionColumns::default();
    state
        .pipeline
        .live()
        .for_each_tag(|tag, s| columns.push(tag, s.time_s, &s.location));
    Ok(Json(columns.into_value()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_become_columns_in_millimetres_with_the_xy_covariance() {
        let mut columns = PositionColumns::default();
        let location = |value: Value| -> Location {
            let mut object = json!({ "source": "test", "provider_type": "uwb", "provider_id": "p" });
            object
                .as_object_mut()
                .unwrap()
                .extend(value.as_object().unwrap().clone());
            serde_json::from_value(object).unwrap()
        };
        let planar = location(json!({
            "position": { "type": "Point", "coordinates": [1.23456, 2.0] },
            "properties": { "rtls:covariance_m2": [0.04, 0.01, 0.01, 0.09], "rtls:status": "confirmed" },
        }));
        let spatial = location(json!({
            "position": { "type": "Point", "coordinates": [3.0, 4.0, 1.5004] },
            "properties": { "rtls:covariance_m2": [0.1, 0.2, 0.3, 0.2, 0.5, 0.6, 0.3, 0.6, 0.9],
                            "rtls:status": "coasting", "rtls:predicted": true },
        }));
        // a location built without a position (deserialising refuses one)
        let mut no_position = location(json!({ "position": { "type": "Point", "coordinates": [0.0, 0.0] } }));
        no_position.position.coordinates.clear();
        columns.push("a", 10.00049, &planar);
        columns.push("b", 11.0, &spatial);
        columns.push("no position", 12.0, &no_position);
        let value = columns.finish().unwrap();
        assert_eq!(value["tag"], json!(["a", "b"]));
        assert_eq!(value["t"], json!([10.0, 11.0]));
        assert_eq!(value["x"], json!([1.235, 3.0]));
        assert_eq!(value["z"], json!([null, 1.5]));
        // the x–y block: [0]/[1]/[3] of a 2 × 2, [0]/[1]/[4] of a 3 × 3
        assert_eq!(value["cyy"][0].as_f64().map(|v| v as f32), Some(0.09));
        assert_eq!(value["cyy"][1].as_f64().map(|v| v as f32), Some(0.5));
        assert_eq!(value["cxy"][1].as_f64().map(|v| v as f32), Some(0.2));
        assert_eq!(value["status"], json!(["confirmed", "coasting"]));
        assert_eq!(value["predicted"], json!([0, 1]));
        assert!(PositionColumns::default().finish().is_none());
    }
}
