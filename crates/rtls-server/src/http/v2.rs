//! The routes of the omlox hub API 2.0.0 under `/v2` (but the WebSocket's): every REST
//! operation of the spec. Static segments (`/v2/providers/locations`, `/v2/trackables/motions`)
//! take precedence over the `{provider_id}` / `{trackable_id}` captures.

use axum::routing::{get, put};
use axum::Router;

use super::{fences, hub, proximity, relations, sensors, zones, AppState};

/// The `/v2` REST routes.
pub(super) fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v2/providers/locations",
            put(hub::put_locations)
                .get(hub::get_locations)
                .delete(hub::delete_locations),
        )
        .route("/v2/providers/proximities", put(proximity::put_proximities))
        .route(
            "/v2/providers/{provider_id}/location",
            put(hub::put_provider_location)
                .get(hub::get_provider_location)
                .delete(hub::delete_provider_location),
        )
        .route("/v2/providers/{provider_id}/proximity", put(proximity::put_proximity))
        .route(
            "/v2/providers/{provider_id}/sensors",
            put(sensors::put_sensors).get(sensors::get_sensors),
        )
        .route("/v2/providers/{provider_id}/fences", get(relations::provider_fences))
        .route(
            "/v2/providers/{provider_id}/trackables",
            get(relations::provider_trackables),
        )
        .route(
            "/v2/providers",
            get(hub::list_providers)
                .post(hub::create_provider)
                .delete(hub::delete_all_providers),
        )
        .route("/v2/providers/summary", get(hub::provider_summary))
        .route(
            "/v2/providers/{provider_id}",
            get(hub::get_provider)
                .put(hub::put_provider)
                .delete(hub::delete_provider),
        )
        .route(
            "/v2/trackables",
            get(hub::list_trackables)
                .post(hub::create_trackable)
                .delete(hub::delete_all_trackables),
        )
        .route("/v2/trackables/summary", get(hub::trackable_summary))
        .route("/v2/trackables/motions", get(relations::trackable_motions))
        .route(
            "/v2/trackables/{trackable_id}",
            get(hub::get_trackable)
                .put(hub::put_trackable)
                .delete(hub::delete_trackable),
        )
        .route(
            "/v2/trackables/{trackable_id}/location",
            get(hub::get_trackable_location),
        )
        .route(
            "/v2/trackables/{trackable_id}/locations",
            get(relations::trackable_locations),
        )
        .route("/v2/trackables/{trackable_id}/motion", get(relations::trackable_motion))
        .route("/v2/trackables/{trackable_id}/fences", get(relations::trackable_fences))
        .route(
            "/v2/trackables/{trackable_id}/providers",
            get(relations::trackable_providers),
        )
        .route("/v2/trackables/{trackable_id}/sensors", get(sensors::trackable_sensors))
        .route(
            "/v2/zones",
            get(zones::list)
                .post(zones::create_zone)
                .delete(zones::delete_all_zones),
        )
        .route("/v2/zones/summary", get(zones::summary))
        .route(
            "/v2/zones/{zone_id}",
            get(zones::get).put(zones::replace_zone).delete(zones::delete_zone),
        )
        .route("/v2/zones/{zone_id}/transform", put(zones::transform))
        .route("/v2/zones/{zone_id}/createfence", get(zones::create_fence))
        .route(
            "/v2/fences",
            get(fences::list).post(fences::create).delete(fences::delete_all),
        )
        .route("/v2/fences/summary", get(fences::summary))
        .route(
            "/v2/fences/{fence_id}",
            get(fences::get).put(fences::replace).delete(fences::delete),
        )
        .route("/v2/fences/{fence_id}/locations", get(relations::fence_locations))
        .route("/v2/fences/{fence_id}/motions", get(relations::fence_motions))
        .route("/v2/fences/{fence_id}/providers", get(relations::fence_providers))
        .route("/v2/fences/{fence_id}/trackables", get(relations::fence_trackables))
}
