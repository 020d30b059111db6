//! `POST /api/v1/adapters/{vendor}`: a vendor's own position message through its adapter
//! ([`crate::adapters`]).

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::Json;
use serde_json::{json, Value};

use super::{ApiError, ApiResult, AppState};
use crate::adapters::Vendor;
use crate::auth::Access;

/// `POST /api/v1/adapters/{vendor}` (`pozyx`, `quuppa`, `sewio`, `zebra`, `openrtls`,
/// `generic`), with the
/// write token as `/api/v1/measurements`: the body is one payload of the vendor's feed,
/// unchanged (Zebra's: one or more Dart lines, as text). 200
/// `{"accepted": n, "refused": [{"at", "tag", "reason", "detail"}]}` once the fixes are
/// stored (messages without a position, and malformed Zebra lines among usable ones, are
/// listed and counted in `rtls_ingest_refused_total{reason}`); 400 naming the field of a
/// malformed message (nothing stored); 404 for an unknown vendor; 503 when overloaded.
pub(super) async fn ingest(
    State(state): State<AppState>,
    Path(vendor): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Write)?;
    let Some(vendor) = Vendor::from_name(&vendor) else {
        let known: Vec<&str> = Vendor::ALL.iter().map(|v| v.name()).collect();
        return Err(ApiError::not_found(format!(
            "adapter `{vendor}` (known: {})",
            known.join(", ")
        )));
    };
    let source = format!("http:adapters/{}", vendor.name());
    match state.pipeline.submit_adapter(vendor, &source, &body).await {
        Ok(outcome) => Ok(Json(json!({
            "accepted": outcome.accepted,
            "refused": outcome.refusals,
        }))),
        Err(error) => Err(super::api::refused_over_http(&state, error)),
    }
}
