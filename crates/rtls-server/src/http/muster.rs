//! `GET /api/v1/muster`: who is on site now, by the site's check-in/check-out rule
//! ([`rtls_engine::zones::muster_status`]: in through the entry zone, out through it).

use axum::extract::State;
use axum::http::HeaderMap;
use axum::Json;
use rtls_engine::zones::{missing_zones, muster_status, MusterStatus};
use serde_json::{json, Value};

use super::{ApiResult, AppState};
use crate::auth::Access;

/// The muster board: counts per status and every tag counted on site (missing first, then at
/// the entry, then on site; by tag within each), with its last known time and position.
/// `{"configured": false}` when the site has no `[muster]` section.
pub(super) async fn muster(State(state): State<AppState>, headers: HeaderMap) -> ApiResult<Json<Value>> {
    state.authorize(&headers, Access::Read)?;
    let Some(settings) = state.site.muster.as_ref() else {
        return Ok(Json(json!({
            "configured": false,
            "reason": "the site file has no [muster] section (entry_zone)",
        })));
    };
    let zones = state.pipeline.live().zones();
    let mut counted = Vec::new();
    let (mut on_site, mut missing, mut at_entry, mut off_site) = (0_usize, 0_usize, 0_usize, 0_usize);
    for (tag, seen) in state.pipeline.live().last_seen() {
        let status = muster_status(settings, &zones, seen.position_m, seen.lost);
        match status {
            MusterStatus::OnSite => on_site += 1,
            MusterStatus::Missing => missing += 1,
            MusterStatus::AtEntry => at_entry += 1,
            MusterStatus::OffSite => off_site += 1,
        }
        if status.counted() {
            counted.push((status, tag, seen));
        }
    }
    // the board's order: missing people first
    counted.sort_by(|a, b| {
        let rank = |s: MusterStatus| match s {
            MusterStatus::Missing => 0,
            MusterStatus::AtEntry => 1,
            _ => 2,
        };
        rank(a.0).cmp(&rank(b.0)).then_with(|| a.1.cmp(&b.1))
    });
    let tags: Vec<Value> = counted
        .into_iter()
        .map(|(status, tag, seen)| {
            json!({
                "tag": tag,
                "status": status,
                "time_s": seen.time_s,
                "position_m": seen.position_m,
            })
        })
        .collect();
    Ok(Json(json!({
        "configured": true,
        "entry_zone": settings.entry_zone,
        "outside_zones": settings.outside_zones,
        "missing_zones": missing_zones(settings, &zones),
        "on_site_total": on_site + missing + at_entry,
        "counts": {
            "on-site": on_site,
            "missing": missing,
            "at-entry": at_entry,
            "off-site": off_site,
        },
        "tags": tags,
    })))
}
