//! `?crs=` on the omlox location reads: a location in the site's local metres (`local`, or no
//! `crs`: omlox's default) or in WGS-84 (`EPSG:4326`: longitude and latitude in degrees,
//! height in m above the ellipsoid) through the site's `[frame]` georeference.
//!
//! Only the position changes frame: `accuracy` stays a radius in metres (omlox's unit in every
//! CRS), and `course` is from true north in either (the partition turned it through the
//! frame's bearing, `crate::convert::true_course_deg`).

use rtls_engine::site::FrameSettings;
use serde::Deserialize;
use serde_json::json;

use super::{ApiError, ApiResult, AppState};
use crate::convert::wgs84_geometry;
use crate::omlox::Location;

/// The `crs` query parameter.
#[derive(Debug, Default, Deserialize)]
pub(super) struct CrsQuery {
    crs: Option<String>,
}

impl CrsQuery {
    /// A `crs` read from a raw query string.
    pub(super) fn of(crs: Option<String>) -> Self {
        Self { crs }
    }
}

/// The frame `crs` asks for: `None` for the site's local metres.
///
/// # Errors
/// A 400 naming `crs` for a CRS other than `local` and `EPSG:4326`, or `EPSG:4326` on a site
/// without a `[frame]` origin.
pub(super) fn requested_frame<'a>(state: &'a AppState, query: &CrsQuery) -> ApiResult<Option<&'a FrameSettings>> {
    match query.crs.as_deref() {
        None | Some("local") => Ok(None),
        Some("EPSG:4326") => state.site.frame.as_ref().map(Some).ok_or_else(|| {
            ApiError::field(
                "crs",
                "the site has no [frame] origin, so locations are only available in crs=local",
            )
        }),
        Some(other) => Err(ApiError::field(
            "crs",
            format!("`{other}` is not one of local, EPSG:4326"),
        )),
    }
}

/// `location` in `frame` (as it is without one): its position converted and `crs` set.
#[must_use]
pub(super) fn in_frame(mut location: Location, frame: Option<&FrameSettings>) -> Location {
    let Some(frame) = frame else {
        return location;
    };
    let point = json!({ "type": "Point", "coordinates": location.position.coordinates });
    let converted = wgs84_geometry(Some(frame), &point);
    if let Some(coordinates) = converted["coordinates"].as_array() {
        location.position.coordinates = coordinates.iter().filter_map(serde_json::Value::as_f64).collect();
        location.crs = Some("EPSG:4326".into());
    }
    location
}
