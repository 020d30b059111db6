//! omlox objects as GeoJSON (RFC 7946): what the `geojson=true` query parameter of the omlox
//! reads answers.
//!
//! - a [`Location`] is a Feature whose geometry is its `position` (a Point) and whose
//!   `properties` are its other fields (`source`, `provider_id`, `crs`, `accuracy`, …; its own
//!   `properties` object under `properties`); the Feature's `id` is the `provider_id`;
//! - a [`TrackableMotion`] is a Feature whose geometry is its location's position, `id` the
//!   trackable's, and `properties` its other fields, its `location` without the position;
//! - a [`Fence`] is a Feature whose geometry is its `region` (Polygon, or Point with `radius`
//!   among the properties), `id` the fence's, `properties` its other fields;
//! - a list is a FeatureCollection of those.
//!
//! The coordinates are taken as they are: choosing the CRS (RFC 7946 wants WGS-84 longitude
//! and latitude) is the caller's (`http::read_frame`).
//!
//! # References
//! H. Butler et al., "The GeoJSON Format", RFC 7946, IETF, 2016, §3.2 (Feature) and §3.3
//! (FeatureCollection).

use serde::Serialize;
use serde_json::{json, Map, Value};

use super::{Fence, Location, TrackableMotion};

/// An omlox object that has a GeoJSON Feature form.
pub trait ToFeature: Serialize {
    /// The object as a GeoJSON Feature (see the module documentation).
    #[must_use]
    fn to_feature(&self) -> Value;
}

/// A Feature with `id`, `geometry` and the object's other fields as `properties`.
fn feature(id: &str, geometry: Value, properties: Map<String, Value>) -> Value {
    json!({ "type": "Feature", "id": id, "geometry": geometry, "properties": properties })
}

/// `object`'s JSON fields, `geometry_key` taken out: (the geometry, the rest).
fn split<T: Serialize>(object: &T, geometry_key: &str) -> (Value, Map<String, Value>) {
    let Ok(Value::Object(mut fields)) = serde_json::to_value(object) else {
        // every omlox type serialises to a JSON object
        return (Value::Null, Map::new());
    };
    let geometry = fields.remove(geometry_key).unwrap_or(Value::Null);
    (geometry, fields)
}

impl ToFeature for Location {
    /// # Examples
    /// ```
    /// use rtls_server::omlox::geojson::ToFeature;
    /// use rtls_server::omlox::Location;
    /// let location: Location = serde_json::from_value(serde_json::json!({
    ///     "position": {"type": "Point", "coordinates": [8.5, 47.3]}, "crs": "EPSG:4326",
    ///     "source": "site", "provider_type": "uwb", "provider_id": "tag-1", "accuracy": 0.4
    /// })).unwrap();
    /// let feature = location.to_feature();
    /// assert_eq!(feature["type"], "Feature");
    /// assert_eq!(feature["id"], "tag-1");
    /// assert_eq!(feature["geometry"]["coordinates"][0], 8.5);
    /// assert_eq!(feature["properties"]["accuracy"], 0.4);
    /// assert!(feature["properties"].get("position").is_none());
    /// ```
    fn to_feature(&self) -> Value {
        let (geometry, properties) = split(self, "position");
        feature(&self.provider_id, geometry, properties)
    }
}

impl ToFeature for TrackableMotion {
    fn to_feature(&self) -> Value {
        let (_, mut properties) = split(self, "location");
        let (geometry, location) = split(&self.location, "position");
        properties.insert("location".into(), Value::Object(location));
        feature(&self.id, geometry, properties)
    }
}

impl ToFeature for Fence {
    fn to_feature(&self) -> Value {
        let (geometry, properties) = split(self, "region");
        feature(&self.id, geometry, properties)
    }
}

/// A FeatureCollection of `items`' Features.
#[must_use]
pub fn feature_collection<T: ToFeature>(items: &[T]) -> Value {
    let features: Vec<Value> = items.iter().map(ToFeature::to_feature).collect();
    json!({ "type": "FeatureCollection", "features": features })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn location() -> Location {
        serde_json::from_value(json!({
            "position": {"type": "Point", "coordinates": [3.0, 4.0, 1.5]}, "crs": "local",
            "source": "site", "provider_type": "uwb", "provider_id": "tag-1",
            "speed": 1.2, "properties": {"rtls:status": "confirmed"}
        }))
        .unwrap()
    }

    #[test]
    fn a_motion_is_a_point_feature_with_its_location_beside_the_shape() {
        let shape = json!({"type": "Polygon", "coordinates": [[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]]});
        let motion = TrackableMotion {
            id: "7c9e6679-7425-40de-944b-e07fc1f90ae7".into(),
            location: location(),
            name: Some("forklift".into()),
            extrusion: Some(2.0),
            geometry: Some(serde_json::from_value(shape.clone()).unwrap()),
            properties: None,
        };
        let feature = motion.to_feature();
        assert_eq!(feature["id"], motion.id);
        assert_eq!(
            feature["geometry"],
            json!({"type": "Point", "coordinates": [3.0, 4.0, 1.5]})
        );
        let properties = &feature["properties"];
        assert_eq!(properties["name"], "forklift");
        // the trackable's outline stays a property: one geometry per Feature
        assert_eq!(properties["geometry"], shape);
        assert_eq!(properties["location"]["provider_id"], "tag-1");
        assert_eq!(properties["location"]["properties"]["rtls:status"], "confirmed");
        assert!(properties["location"].get("position").is_none());
        assert!(properties.get("id").is_some_and(|id| id == &json!(motion.id)));
    }

    #[test]
    fn a_fence_is_its_region_and_a_list_a_collection() {
        let fence: Fence = serde_json::from_value(json!({
            "id": "7c9e6679-7425-40de-944b-e07fc1f90ae7", "crs": "local", "name": "yard",
            "region": {"type": "Polygon", "coordinates": [[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]]}
        }))
        .unwrap();
        let collection = feature_collection(&[fence.clone(), fence]);
        assert_eq!(collection["type"], "FeatureCollection");
        let first = &collection["features"][0];
        assert_eq!(first["geometry"]["type"], "Polygon");
        assert_eq!(first["properties"]["name"], "yard");
        assert_eq!(first["properties"]["crs"], "local");
        assert!(first["properties"].get("region").is_none());
        assert_eq!(
            feature_collection::<Location>(&[]),
            json!({"type": "FeatureCollection", "features": []})
        );
    }
}
