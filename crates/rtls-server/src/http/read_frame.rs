//! How the omlox reads give coordinates back: the query parameters `crs`, `zone_id` and
//! `geojson` of `GET /v2/providers/locations`, `/v2/providers/{id}/location`,
//! `/v2/trackables/{id}/location`, `/v2/trackables/{id}/locations`,
//! `/v2/trackables/{id}/motion`, `/v2/trackables/motions`, `/v2/fences/summary`,
//! `/v2/fences/{id}`, `/v2/fences/{id}/locations` and `/v2/fences/{id}/motions`.
//!
//! - `crs`: `local` is the site's metres; `EPSG:4326` is WGS-84 (longitude and latitude in
//!   degrees, height in m above the ellipsoid) through the site's `[frame]` georeference; any
//!   other CRS is a 400 naming `crs`, as is `EPSG:4326` on a site without a frame. Without
//!   `crs` and `zone_id` a location or motion is in `local` (omlox's default for a Location)
//!   and a fence in `EPSG:4326` (omlox's for a Fence: "If crs is not present, 'EPSG:4326' MUST
//!   be assumed as the default", and getAllFences' "Returned fence objects use EPSG:4326") when
//!   the site has a `[frame]`; on a site without one a fence is `local`, with `zone_id` the
//!   site's own zone (omlox: `zone_id` "MUST be present in case crs projection is set to
//!   'local'"), since there is no WGS-84 to give. Every fence in `local` names that zone.
//! - `zone_id` ("the zone id to be used to project coordinates"): local coordinates in that
//!   zone's frame. The site's own zone is the site's metres; a stored zone's frame is the
//!   least-squares affine map of its ground control points (`zone_frame`, the map
//!   `PUT /v2/zones/{id}/transform` uses), reached from site metres through WGS-84, so the site
//!   needs a `[frame]`. A height stays the site's. An unknown zone is a 404; a proximity zone
//!   (a reader's position and radius, no frame), a zone without three usable ground control
//!   points, or a site without a `[frame]` is a 400 naming `zone_id`. With `crs=EPSG:4326` the
//!   zone is only checked to exist: WGS-84 is the same whichever zone it comes through.
//! - `geojson=true`: the answer is GeoJSON (RFC 7946, `application/geo+json`; the shapes are
//!   [`crate::omlox::geojson`]'s). RFC 7946 coordinates are WGS-84, so without `crs` and
//!   `zone_id` a GeoJSON answer is in EPSG:4326 when the site has a `[frame]`, as the
//!   `/api/v1/*.geojson` exports and the `location_updates:geojson` topic are. Asked for
//!   explicitly (`crs=local`, `zone_id`), or on a site without a frame, the coordinates are
//!   local and the Feature or FeatureCollection names them in the foreign members `crs`
//!   (`"local"`) and `zone_id` (RFC 7946 §4's "prior arrangement"), beside each object's own
//!   `crs` among its properties.
//!
//! Only positions change frame: `accuracy`, `radius` and `extrusion` stay metres (omlox's unit
//! in every CRS), `speed` m/s, and `course` is from true north in every frame (the partition
//! turned it through the frame's bearing, `crate::convert::true_course_deg`).

use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::Json;
use rtls_engine::site::FrameSettings;
use serde_json::{json, Value};

use super::zone_frame::ZoneFrame;
use super::zone_store::{is_proximity, site_zone, zone};
use super::{query_value, ApiError, ApiResult, AppState};
use crate::omlox::crs::Crs;
use crate::omlox::geojson::{feature_collection, ToFeature};
use crate::omlox::{Fence, Location, Region, Trackable, TrackableMotion};

/// Where the coordinates of a read go.
#[derive(Debug, Clone, PartialEq)]
enum Projection {
    /// The site's local metres (the site's own zone).
    Site,
    /// WGS-84 through the site's `[frame]` ([`ZoneFrame::Site`]).
    Wgs84(ZoneFrame),
    /// A stored zone's local frame: site metres to WGS-84 through `site`, then to the zone's
    /// `[x, y]` through its ground control points (`zone`).
    Zone {
        /// The zone's id.
        id: String,
        /// The site's georeference.
        site: ZoneFrame,
        /// The zone's fitted frame.
        zone: ZoneFrame,
    },
}

/// The frame a read without `crs` and `zone_id` answers in (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fallback {
    /// The site's metres: omlox's `local`, a Location's default.
    Local,
    /// WGS-84 when the site has a `[frame]`, else its metres: a Fence's default, and GeoJSON's.
    Wgs84WhenGeoreferenced,
}

/// The frame and form a read answers in, from its query (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ReadFrame {
    projection: Projection,
    geojson: bool,
    /// The site's own zone, named by a fence in its metres (`crs: "local"` needs a `zone_id`).
    site_zone_id: String,
}

impl ReadFrame {
    /// The frame `query` (a raw query string) asks for on a read of locations or motions:
    /// without `crs` and `zone_id`, `local` (site metres), unless `geojson=true`.
    ///
    /// # Errors
    /// 400 naming `crs` for a CRS other than `local` and `EPSG:4326`, or `EPSG:4326` on a site
    /// without a `[frame]`; 404 for an unknown `zone_id`; 400 naming `zone_id` for a zone whose
    /// frame cannot be computed.
    pub(super) async fn of(state: &AppState, query: Option<&str>) -> ApiResult<Self> {
        Self::with_default(state, query, Fallback::Local).await
    }

    /// The frame `query` asks for on a read of fences: without `crs` and `zone_id`, EPSG:4326
    /// when the site has a `[frame]`, else `local` with the site's zone as `zone_id`.
    ///
    /// # Errors
    /// As [`Self::of`].
    pub(super) async fn of_fences(state: &AppState, query: Option<&str>) -> ApiResult<Self> {
        Self::with_default(state, query, Fallback::Wgs84WhenGeoreferenced).await
    }

    /// The default frame of a fence read without a query (as [`Self::of_fences`]).
    pub(super) fn fence_default(state: &AppState) -> Self {
        Self {
            projection: state
                .site
                .frame
                .map_or(Projection::Site, |f| Projection::Wgs84(ZoneFrame::Site(f))),
            geojson: false,
            site_zone_id: site_zone(state).id,
        }
    }

    /// The frame a fence written in `crs` is answered in: the one it was written in (`local`
    /// as site metres, anything else as WGS-84 where the site has a `[frame]`).
    pub(super) fn written_in(state: &AppState, crs: Option<&str>) -> Self {
        let local = Self {
            projection: Projection::Site,
            geojson: false,
            site_zone_id: site_zone(state).id,
        };
        match Crs::parse(crs) {
            Ok(Crs::Local) if crs.is_some() => local,
            _ => Self::fence_default(state),
        }
    }

    /// The frame `query` asks for, `default` without `crs` and `zone_id`.
    async fn with_default(state: &AppState, query: Option<&str>, default: Fallback) -> ApiResult<Self> {
        let geojson = query_value(query, "geojson").as_deref() == Some("true");
        let wgs84 = match query_value(query, "crs") {
            None => None,
            Some(crs) => Some(Crs::parse(Some(&crs)).map_err(|reason| ApiError::field("crs", reason))? == Crs::Wgs84),
        };
        let zone = match query_value(query, "zone_id") {
            Some(zone_id) => Some(zone(state, &zone_id).await?),
            None => None,
        };
        let site_frame = state.site.frame.map(ZoneFrame::Site);
        let projection = match (wgs84, zone) {
            (Some(true), _) => Projection::Wgs84(site_frame.ok_or_else(|| {
                ApiError::field(
                    "crs",
                    "the site has no [frame] origin, so locations are only available in crs=local",
                )
            })?),
            (_, Some(zone)) if zone.id == site_zone(state).id => Projection::Site,
            (_, Some(zone)) => {
                if is_proximity(zone.kind) {
                    return Err(ApiError::field(
                        "zone_id",
                        format!(
                            "zone `{}` is a proximity zone (a reader's position and radius): it has no local frame",
                            zone.id
                        ),
                    ));
                }
                let fitted = ZoneFrame::of_zone(&zone).map_err(|e| ApiError::field("zone_id", e.message))?;
                let site = site_frame.ok_or_else(|| {
                    ApiError::field(
                        "zone_id",
                        format!(
                            "the site has no [frame] origin to relate its metres to zone `{}`'s ground control points",
                            zone.id
                        ),
                    )
                })?;
                Projection::Zone {
                    id: zone.id,
                    site,
                    zone: fitted,
                }
            }
            // RFC 7946: GeoJSON is WGS-84 when the site can give it; omlox: so is a fence
            (None, None) if geojson || default == Fallback::Wgs84WhenGeoreferenced => {
                site_frame.map_or(Projection::Site, Projection::Wgs84)
            }
            (_, None) => Projection::Site,
        };
        Ok(Self {
            projection,
            geojson,
            site_zone_id: site_zone(state).id,
        })
    }

    /// The omlox `crs` of the coordinates this frame gives.
    fn crs(&self) -> &'static str {
        match self.projection {
            Projection::Wgs84(_) => "EPSG:4326",
            Projection::Site | Projection::Zone { .. } => "local",
        }
    }

    /// A position in site metres `[x, y(, z)]` in this frame.
    ///
    /// # Errors
    /// 400 naming the parameter whose frame cannot take the position (not finite, or no
    /// longitude and latitude).
    fn position(&self, site_m: &[f64]) -> ApiResult<Vec<f64>> {
        let projected = match &self.projection {
            Projection::Site => Some(site_m.to_vec()),
            _ if site_m.len() < 2 => None,
            Projection::Wgs84(frame) => frame.wgs84_of(site_m),
            Projection::Zone { site, zone, .. } => site.wgs84_of(&site_m[..2]).and_then(|mut geodetic| {
                // the zone's [x, y] from longitude and latitude; a height stays the site's
                geodetic.extend(site_m.get(2));
                zone.local_of(&geodetic)
            }),
        };
        projected.ok_or_else(|| {
            let parameter = match self.projection {
                Projection::Zone { .. } => "zone_id",
                _ => "crs",
            };
            ApiError::field(parameter, format!("the position {site_m:?} cannot be projected"))
        })
    }

    /// A location (site metres) in this frame, `crs` set.
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn location(&self, mut location: Location) -> ApiResult<Location> {
        self.project(&mut location)?;
        Ok(location)
    }

    /// Takes `location` (site metres) to this frame in place; unchanged on an error.
    ///
    /// # Errors
    /// As [`Self::position`].
    fn project(&self, location: &mut Location) -> ApiResult<()> {
        if self.projection != Projection::Site {
            location.position.coordinates = self.position(&location.position.coordinates)?;
            location.crs = Some(self.crs().into());
        }
        Ok(())
    }

    /// Locations (site metres) in this frame.
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn locations(&self, locations: impl IntoIterator<Item = Location>) -> ApiResult<Vec<Location>> {
        locations.into_iter().map(|l| self.location(l)).collect()
    }

    /// `trackable`'s motion at `location` (site metres), the location in this frame.
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn motion(&self, trackable: &Trackable, location: Location) -> ApiResult<TrackableMotion> {
        Ok(TrackableMotion::of(trackable, self.location(location)?))
    }

    /// A fence (site metres) in this frame: its region's positions, `crs`, and `zone_id` in
    /// `local` (the site's zone in site metres, the zone's in a zone's frame; none in WGS-84).
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn fence(&self, mut fence: Fence) -> ApiResult<Fence> {
        if self.projection == Projection::Site {
            fence.crs = Some("local".into());
            fence.zone_id = Some(self.site_zone_id.clone());
            return Ok(fence);
        }
        fence.region = match fence.region {
            Region::Point { coordinates } => Region::Point {
                coordinates: self.position(&coordinates)?,
            },
            Region::Polygon { coordinates } => Region::Polygon {
                coordinates: coordinates
                    .iter()
                    .map(|ring| ring.iter().map(|p| self.position(p)).collect())
                    .collect::<ApiResult<_>>()?,
            },
        };
        fence.crs = Some(self.crs().into());
        fence.zone_id = match &self.projection {
            Projection::Zone { id, .. } => Some(id.clone()),
            _ => None,
        };
        Ok(fence)
    }

    /// One object as the answer: omlox JSON, or a GeoJSON Feature.
    pub(super) fn answer<T: ToFeature>(&self, object: &T) -> Response {
        if self.geojson {
            self.geojson_answer(object.to_feature())
        } else {
            Json(object).into_response()
        }
    }

    /// A list as the answer: an omlox JSON array, or a GeoJSON FeatureCollection.
    pub(super) fn answer_all<T: ToFeature>(&self, objects: &[T]) -> Response {
        if self.geojson {
            self.geojson_answer(feature_collection(objects))
        } else {
            Json(objects).into_response()
        }
    }

    /// GeoJSON as `application/geo+json`; local coordinates named by the foreign members
    /// `crs` and `zone_id`.
    fn geojson_answer(&self, mut body: Value) -> Response {
        match &self.projection {
            Projection::Wgs84(_) => {}
            Projection::Site => body["crs"] = json!("local"),
            Projection::Zone { id, .. } => {
                body["crs"] = json!("local");
                body["zone_id"] = json!(id);
            }
        }
        ([(header::CONTENT_TYPE, "application/geo+json")], body.to_string()).into_response()
    }
}

/// `location` in WGS-84 through `frame` when given (as it is without one): the WebSocket's
/// `params.crs = "EPSG:4326"`, through the same projection as the REST reads. A position the
/// frame cannot take is left as it is, in `crs: "local"`.
#[must_use]
pub(super) fn in_frame(mut location: Location, frame: Option<&FrameSettings>) -> Location {
    if let Some(frame) = frame {
        let wgs84 = ReadFrame {
            projection: Projection::Wgs84(ZoneFrame::Site(*frame)),
            geojson: false,
            site_zone_id: String::new(),
        };
        // (a position the frame cannot take stays as it is)
        let _ = wgs84.project(&mut location);
    }
    location
}
