//! How the omlox reads give coordinates back — and, inverted, how a fence written in a zone's
//! local frame comes to site metres ([`ReadFrame::of_written_fence`],
//! [`ReadFrame::site_region`]): the query parameters `crs`, `zone_id` and
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
use crate::omlox::{CollisionEvent, Fence, Location, Region, Trackable, TrackableMotion, Zone};

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

    /// Site metres (`local`, the site's own zone): the frame of a fence the hub makes itself
    /// (`createfence`).
    pub(super) fn site_metres(state: &AppState) -> Self {
        Self {
            projection: Projection::Site,
            geojson: false,
            site_zone_id: site_zone(state).id,
        }
    }

    /// The frame a fence's region is written in, from its `crs` and `zone_id`; a create
    /// answers in it. EPSG:4326 (also a fence without `crs`) is WGS-84 through the site's
    /// `[frame]` (as [`Self::fence_default`]); `local` with a `zone_id` is that zone's frame
    /// (the site's own zone: site metres; a stored zone: its ground control points' affine
    /// map, reached through WGS-84); `local` without one is the site's metres. A `zone_id`
    /// beside a CRS other than `local` is not read: WGS-84 is one frame whichever zone.
    ///
    /// # Errors
    /// 400 naming `crs` for a CRS other than `local` and `EPSG:4326`; 400 naming `zone_id` for
    /// a zone that does not exist or has no local frame (a proximity zone, fewer than three
    /// ground control points off one line, a site without a `[frame]`).
    pub(super) async fn of_written_fence(state: &AppState, fence: &Fence) -> ApiResult<Self> {
        // omlox: "If crs is not present, 'EPSG:4326' ("GPS") MUST be assumed as the default."
        let crs = match fence.crs.as_deref() {
            None => Crs::Wgs84,
            stated => Crs::parse(stated).map_err(|reason| ApiError::field("crs", reason))?,
        };
        let projection = match (crs, fence.zone_id.as_deref()) {
            (Crs::Wgs84, _) => return Ok(Self::fence_default(state)),
            (Crs::Local, None) => Projection::Site,
            (Crs::Local, Some(zone_id)) => {
                // a body's field, not a path or query: an unknown zone is a bad field (400)
                let zone = zone(state, zone_id).await.map_err(|e| {
                    if e.status == axum::http::StatusCode::NOT_FOUND {
                        ApiError::field("zone_id", format!("no zone has the id `{zone_id}`"))
                    } else {
                        e
                    }
                })?;
                zone_projection(state, zone)?
            }
        };
        Ok(Self {
            projection,
            geojson: false,
            site_zone_id: site_zone(state).id,
        })
    }

    /// The frame `query` asks for, `default` without `crs` and `zone_id`.
    async fn with_default(state: &AppState, query: Option<&str>, default: Fallback) -> ApiResult<Self> {
        let crs = query_value(query, "crs");
        let zone_id = query_value(query, "zone_id");
        Self::with_params(
            state,
            crs.as_deref(),
            zone_id.as_deref(),
            query_value(query, "geojson").as_deref() == Some("true"),
            default,
        )
        .await
    }

    /// The frame of a WebSocket subscription's `params.crs` and `params.zone_id` on a topic
    /// whose payloads carry Locations: as on the REST location reads ([`Self::of`]).
    ///
    /// # Errors
    /// As [`Self::of`].
    pub(super) async fn of_params(state: &AppState, crs: Option<&str>, zone_id: Option<&str>) -> ApiResult<Self> {
        Self::with_params(state, crs, zone_id, false, Fallback::Local).await
    }

    /// The frame of `crs`, `zone_id` and `geojson`, `default` without the first two.
    async fn with_params(
        state: &AppState,
        crs: Option<&str>,
        zone_id: Option<&str>,
        geojson: bool,
        default: Fallback,
    ) -> ApiResult<Self> {
        let wgs84 = match crs {
            None => None,
            Some(crs) => Some(Crs::parse(Some(crs)).map_err(|reason| ApiError::field("crs", reason))? == Crs::Wgs84),
        };
        let zone = match zone_id {
            Some(zone_id) => Some(zone(state, zone_id).await?),
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
            (_, Some(zone)) => zone_projection(state, zone)?,
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

    /// Whether this frame is the site's metres (positions stay as the trackers give them).
    pub(super) fn is_site_metres(&self) -> bool {
        self.projection == Projection::Site
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

    /// A position `[x, y(, z)]` given in this frame in site metres: the inverse of
    /// [`Self::position`] (a zone's `[x, y]` to longitude and latitude through its ground
    /// control points, then to site metres through the site's `[frame]`; a height stays).
    /// `None` when the frame cannot place it.
    fn site_position(&self, given: &[f64]) -> Option<Vec<f64>> {
        if given.len() < 2 || given.iter().any(|c| !c.is_finite()) {
            return None;
        }
        let site_m = match &self.projection {
            Projection::Site => given.to_vec(),
            Projection::Wgs84(frame) => frame.local_of(given)?,
            Projection::Zone { site, zone, .. } => {
                let geodetic = zone.wgs84_of(&given[..2])?;
                let mut site_m = site.local_of(&geodetic)?;
                site_m.extend(given.get(2));
                site_m
            }
        };
        site_m.iter().all(|c| c.is_finite()).then_some(site_m)
    }

    /// A fence's region given in this frame, in site metres ([`Self::site_position`] of
    /// every position); a Point's radius is metres in every frame.
    ///
    /// # Errors
    /// 400 naming the position (`region.coordinates`, `region.coordinates[r][i]`) the frame
    /// cannot place.
    pub(super) fn site_region(&self, region: &Region) -> ApiResult<Region> {
        let place = |position: &[f64], field: String| {
            self.site_position(position).ok_or_else(|| {
                ApiError::field(
                    field,
                    format!(
                        "{position:?} cannot be placed in the site from the fence's {} frame",
                        self.crs()
                    ),
                )
            })
        };
        region.try_map_positions(place)
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

    /// A collision event (site metres) in this frame: its `collision_area`, and each
    /// collision's `position` and `geometry`.
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn collision(&self, event: &CollisionEvent) -> ApiResult<CollisionEvent> {
        let mut event = event.clone();
        if self.projection == Projection::Site {
            return Ok(event);
        }
        if let Some(area) = event.collision_area.as_mut() {
            area.coordinates = self.position(&area.coordinates)?;
        }
        for collision in &mut event.collisions {
            if let Some(point) = collision.position.as_mut() {
                point.coordinates = self.position(&point.coordinates)?;
            }
            if let Some(polygon) = collision.geometry.as_mut() {
                for ring in &mut polygon.coordinates {
                    for position in ring.iter_mut() {
                        *position = self.position(position)?;
                    }
                }
            }
        }
        Ok(event)
    }

    /// A location (site metres) as the GeoJSON Feature of `location_updates:geojson` in this
    /// frame: local coordinates named by the foreign members `crs` and `zone_id`, as
    /// [`Self::answer`]'s `geojson=true` reads have them.
    ///
    /// # Errors
    /// As [`Self::position`].
    pub(super) fn location_feature(&self, location: Location) -> ApiResult<Value> {
        let mut feature = self.location(location)?.to_feature();
        self.name_local_frame(&mut feature);
        Ok(feature)
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
        fence.region = fence.region.try_map_positions(|p, _| self.position(p))?;
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
        self.name_local_frame(&mut body);
        ([(header::CONTENT_TYPE, "application/geo+json")], body.to_string()).into_response()
    }

    /// GeoJSON `body` in a local frame gets the foreign members `crs` (`local`) and, in a
    /// zone's frame, `zone_id`; WGS-84 (RFC 7946's own) gets neither.
    fn name_local_frame(&self, body: &mut Value) {
        match &self.projection {
            Projection::Wgs84(_) => {}
            Projection::Site => body["crs"] = json!("local"),
            Projection::Zone { id, .. } => {
                body["crs"] = json!("local");
                body["zone_id"] = json!(id);
            }
        }
    }
}

/// The projection to `zone`'s local frame: site metres for the site's own zone, else the
/// zone's fitted frame reached through the site's georeference.
///
/// # Errors
/// 400 naming `zone_id` for a proximity zone, a zone without a usable frame, or a site
/// without a `[frame]`.
fn zone_projection(state: &AppState, zone: Zone) -> ApiResult<Projection> {
    if zone.id == site_zone(state).id {
        return Ok(Projection::Site);
    }
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
    let site = state.site.frame.map(ZoneFrame::Site).ok_or_else(|| {
        ApiError::field(
            "zone_id",
            format!(
                "the site has no [frame] origin to relate its metres to zone `{}`'s ground control points",
                zone.id
            ),
        )
    })?;
    Ok(Projection::Zone {
        id: zone.id,
        site,
        zone: fitted,
    })
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
