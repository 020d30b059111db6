//! Floor-plan images: read from the site's folder when the server starts, served to the
//! dashboard at `GET /api/v1/site/floors/{floor_id}/plan`.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use axum::body::Bytes;
use axum::extract::{Path as UrlPath, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use rtls_engine::site::Site;

use super::{ApiError, ApiResult, AppState};
use crate::auth::Access;

/// The largest floor-plan image read, bytes (32 MiB: a scanned A0 plan as PNG is a few MB).
pub const MAX_PLAN_BYTES: u64 = 32 << 20;

/// A floor-plan image in memory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FloorPlanImage {
    /// Its media type (`image/png`, …).
    pub media_type: &'static str,
    /// The file's bytes.
    pub bytes: Bytes,
}

/// The site's floor-plan images by floor id.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FloorPlans(HashMap<String, FloorPlanImage>);

impl FloorPlans {
    /// Reads every floor's `plan.image`, relative to `site_dir` (the site file's folder).
    ///
    /// # Errors
    /// A message naming the floor's key (`floors[0].plan.image`) and the file when an image
    /// cannot be read, is larger than [`MAX_PLAN_BYTES`] or is of a kind browsers do not draw.
    pub fn load(site: &Site, site_dir: &Path) -> Result<Self, String> {
        let mut plans = HashMap::new();
        for (i, floor) in site.floors.iter().enumerate() {
            let Some(plan) = &floor.plan else { continue };
            let path = site_dir.join(&plan.image);
            let key = format!("floors[{i}].plan.image");
            let media_type = plan.media_type().ok_or_else(|| {
                format!(
                    "{key}: {} is not a .png, .jpg, .svg, .webp or .gif image",
                    path.display()
                )
            })?;
            let mut bytes = Vec::new();
            std::fs::File::open(&path)
                .and_then(|file| file.take(MAX_PLAN_BYTES + 1).read_to_end(&mut bytes))
                .map_err(|e| format!("{key}: cannot read {}: {e}", path.display()))?;
            if bytes.len() as u64 > MAX_PLAN_BYTES {
                return Err(format!(
                    "{key}: {} is larger than {} MiB",
                    path.display(),
                    MAX_PLAN_BYTES >> 20
                ));
            }
            plans.insert(
                floor.id.clone(),
                FloorPlanImage {
                    media_type,
                    bytes: bytes.into(),
                },
            );
        }
        Ok(Self(plans))
    }

    /// The image of a floor.
    #[must_use]
    pub fn get(&self, floor_id: &str) -> Option<&FloorPlanImage> {
        self.0.get(floor_id)
    }
}

/// The URL of a floor's plan image.
#[must_use]
pub fn plan_url(floor_id: &str) -> String {
    format!("/api/v1/site/floors/{}/plan", path_segment(floor_id))
}

/// `text` percent-encoded as one URL path segment (RFC 3986: everything but the unreserved
/// characters `A–Z a–z 0–9 - . _ ~`).
fn path_segment(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for byte in text.bytes() {
        if byte.is_ascii_alphanumeric() || b"-._~".contains(&byte) {
            out.push(char::from(byte));
        } else {
            out.push_str(&format!("%{byte:02X}"));
        }
    }
    out
}

/// `GET /api/v1/site/floors/{floor_id}/plan`: the floor-plan image (read token).
pub(super) async fn floor_plan(
    State(state): State<AppState>,
    UrlPath(floor_id): UrlPath<String>,
    headers: HeaderMap,
) -> ApiResult<Response> {
    state.authorize(&headers, Access::Read)?;
    let image = state
        .floor_plans
        .get(&floor_id)
        .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("floor `{floor_id}` has no plan image")))?;
    Ok((
        [
            (header::CONTENT_TYPE, image.media_type),
            (header::CACHE_CONTROL, "private, max-age=300"),
        ],
        image.bytes.clone(),
    )
        .into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_ids_are_percent_encoded_in_plan_urls() {
        assert_eq!(plan_url("level-1"), "/api/v1/site/floors/level-1/plan");
        assert_eq!(plan_url("B2/ramp ä"), "/api/v1/site/floors/B2%2Framp%20%C3%A4/plan");
    }

    #[test]
    fn the_example_site_plan_loads_and_a_missing_image_names_its_key() {
        let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples"));
        let text = std::fs::read_to_string(dir.join("site.toml")).unwrap();
        let mut site = Site::from_toml_str(&text, "site.toml").unwrap();
        let plans = FloorPlans::load(&site, dir).unwrap();
        let ground = plans.get("ground").expect("the example's ground floor has a plan");
        assert_eq!(ground.media_type, "image/svg+xml");
        assert!(ground.bytes.starts_with(b"<?xml"));
        assert!(plans.get("mezzanine").is_none());
        site.floors[0].plan.as_mut().unwrap().image = "plans/nowhere.png".into();
        let error = FloorPlans::load(&site, dir).unwrap_err();
        assert!(
            error.starts_with("floors[0].plan.image: cannot read") && error.contains("nowhere.png"),
            "{error}"
        );
    }
}
