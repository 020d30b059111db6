//! The omlox boolean query parameters (`geojson`, `spatial_query`, `force_location_update`,
//! `georef`, `subdivide`: `#/components/parameters` of the spec) are checked on every `/v2`
//! request before its handler: a value other than `true` or `false` is a 400 naming the
//! parameter, whether or not the operation reads it, rather than a value silently ignored.

use axum::extract::Request;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::ApiError;

/// The spec's boolean query parameters.
const BOOLEAN_PARAMETERS: [&str; 5] = [
    "geojson",
    "spatial_query",
    "force_location_update",
    "georef",
    "subdivide",
];

/// The first boolean parameter of `query` whose value is not `true` or `false`, and that value.
#[must_use]
pub(super) fn bad_boolean(query: &str) -> Option<(String, String)> {
    url::form_urlencoded::parse(query.as_bytes())
        .find(|(key, value)| BOOLEAN_PARAMETERS.contains(&key.as_ref()) && value != "true" && value != "false")
        .map(|(key, value)| (key.into_owned(), value.into_owned()))
}

/// Refuses a `/v2` request whose boolean query parameter is not `true` or `false` (400).
pub(super) async fn check_boolean_parameters(request: Request, next: Next) -> Response {
    if request.uri().path().starts_with("/v2/") {
        if let Some((name, value)) = request.uri().query().and_then(bad_boolean) {
            return ApiError::field(name, format!("`{value}` is not true or false")).into_response();
        }
    }
    next.run(request).await
}

#[cfg(test)]
mod tests {
    use super::bad_boolean;

    #[test]
    fn only_true_and_false_pass() {
        assert_eq!(bad_boolean("geojson=true&crs=local"), None);
        assert_eq!(bad_boolean("spatial_query=false&geojson=true"), None);
        assert_eq!(bad_boolean("zone_id=null"), None);
        assert_eq!(
            bad_boolean("geojson=null&geojson=null"),
            Some(("geojson".into(), "null".into()))
        );
        assert_eq!(
            bad_boolean("crs=local&subdivide=1"),
            Some(("subdivide".into(), "1".into()))
        );
        assert_eq!(bad_boolean("georef="), Some(("georef".into(), String::new())));
    }
}
