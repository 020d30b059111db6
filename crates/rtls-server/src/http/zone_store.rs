//! The omlox zones as the hub knows them: the site's own zone (from the site file) and those
//! stored through the API, looked up by id. Apart from the zone handlers (`zones.rs`) so that
//! the reads' frames (`read_frame`) can find a zone without importing them.

use crate::convert::uuid_for;
use crate::omlox::{Zone, ZoneType};

use super::stored::get_stored;
use super::{ApiError, ApiResult, AppState};

/// The configuration kind zones are stored under.
pub(super) const ZONE: &str = "zone";

/// The site as one omlox zone (its local frame).
pub(super) fn site_zone(state: &AppState) -> Zone {
    let name = state.site.name.clone().unwrap_or_else(|| "rtls".into());
    Zone {
        id: uuid_for("zone", &name),
        kind: ZoneType::Uwb,
        foreign_id: Some(name.clone()),
        position: None,
        radius: None,
        ground_control_points: None,
        incomplete_configuration: Some(true),
        measurement_timestamp: None,
        site: None,
        building: None,
        floor: None,
        name: Some(name),
        description: None,
        address: None,
        properties: None,
        wgs84_height: None,
    }
}

/// A zone by id, or a 404.
pub(super) async fn zone(state: &AppState, zone_id: &str) -> ApiResult<Zone> {
    let site = site_zone(state);
    if site.id == zone_id {
        return Ok(site);
    }
    get_stored(state, ZONE, zone_id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("zone `{zone_id}` not found")))
}

/// Whether a zone type is proximity-based (a fixed reader or beacon, not coordinates).
pub(super) fn is_proximity(kind: ZoneType) -> bool {
    matches!(kind, ZoneType::Rfid | ZoneType::Ibeacon)
}
