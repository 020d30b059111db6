//! The geometry of omlox zones: the map between a zone's local `[x, y]` (m) and WGS-84, and
//! the ring of a fence made from a zone.
//!
//! A stored zone's frame comes from its ground control points, pairs of
//! `[longitude, latitude]` and `[x, y]`. Longitude and latitude are taken to east/north metres
//! in the WGS-84 local tangent frame at their mean (the site's own geodesy,
//! [`FrameSettings::site_of_wgs84`], at height 0), and a least-squares affine map
//! `[e, n] = A [x, y] + b` is fitted (nalgebra's SVD) — exact for three points, a best fit for
//! more; points whose `[x, y]` are (nearly) on one line are refused.

use axum::http::StatusCode;
use nalgebra::{DMatrix, Matrix2, Vector2};
use rtls_engine::site::{FrameSettings, GeodeticOrigin};

use super::{ApiError, ApiResult};
use crate::omlox::Zone;

/// The smallest ratio of the design matrix's singular values `[x, y, 1]` a fit accepts: below
/// it the control points are on one line.
const MIN_CONDITION: f64 = 1e-9;

/// How a zone's local positions map to WGS-84.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum ZoneFrame {
    /// The site's georeference (`[frame]`), for the site's own zone.
    Site(FrameSettings),
    /// An affine map fitted to a zone's ground control points.
    Fitted(Affine),
}

/// `[e, n] = A [x, y] + b` in the tangent frame `plane` (x east, y north).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Affine {
    a: Matrix2<f64>,
    b: Vector2<f64>,
    plane: FrameSettings,
}

impl ZoneFrame {
    /// The site's own zone's frame.
    ///
    /// # Errors
    /// 400 when the site has no `[frame]`.
    pub(super) fn of_site(frame: Option<&FrameSettings>, zone_id: &str) -> ApiResult<Self> {
        frame.copied().map(Self::Site).ok_or_else(|| {
            ApiError::new(
                StatusCode::BAD_REQUEST,
                format!("zone `{zone_id}` (the site) has no georeference: the site file has no [frame]"),
            )
        })
    }

    /// A stored zone's frame, from its ground control points.
    ///
    /// # Errors
    /// 400 with fewer than three pairs, or pairs whose `[x, y]` are all on one line.
    pub(super) fn of_zone(zone: &Zone) -> ApiResult<Self> {
        let pairs = control_pairs(zone);
        if pairs.len() < 3 {
            return Err(ApiError::field(
                "ground_control_points",
                format!("zone `{}` needs three ground control points to transform", zone.id),
            ));
        }
        Affine::fit(&pairs).map(Self::Fitted).ok_or_else(|| {
            ApiError::field(
                "ground_control_points",
                format!("zone `{}`'s ground control points are on one line", zone.id),
            )
        })
    }

    /// `[longitude, latitude(, height)]` of a local `[x, y(, z)]`.
    pub(super) fn wgs84_of(&self, local: &[f64]) -> Option<Vec<f64>> {
        match self {
            Self::Site(frame) => {
                let [lon, lat, h] = frame.wgs84_of([local[0], local[1], local.get(2).copied().unwrap_or(0.0)])?;
                Some(if local.len() == 3 {
                    vec![lon, lat, h]
                } else {
                    vec![lon, lat]
                })
            }
            Self::Fitted(affine) => {
                let [lon, lat] = affine.wgs84_of([local[0], local[1]])?;
                Some(with_third(lon, lat, local))
            }
        }
    }

    /// `[x, y(, z)]` of a `[longitude, latitude(, height)]`.
    pub(super) fn local_of(&self, wgs84: &[f64]) -> Option<Vec<f64>> {
        if !((-180.0..=180.0).contains(&wgs84[0]) && (-90.0..=90.0).contains(&wgs84[1])) {
            return None;
        }
        match self {
            Self::Site(frame) => {
                let height = wgs84.get(2).copied().unwrap_or(frame.origin.height_m);
                let [x, y, z] = frame.site_of_wgs84([wgs84[0], wgs84[1], height])?;
                Some(if wgs84.len() == 3 { vec![x, y, z] } else { vec![x, y] })
            }
            Self::Fitted(affine) => {
                let [x, y] = affine.local_of([wgs84[0], wgs84[1]])?;
                Some(with_third(x, y, wgs84))
            }
        }
    }
}

fn with_third(first: f64, second: f64, like: &[f64]) -> Vec<f64> {
    let mut out = vec![first, second];
    out.extend(like.get(2));
    out
}

/// A zone's ground control points as (`[longitude, latitude]`, `[x, y]`) pairs.
fn control_pairs(zone: &Zone) -> Vec<([f64; 2], [f64; 2])> {
    zone.ground_control_points
        .as_deref()
        .unwrap_or_default()
        .chunks_exact(2)
        .filter_map(|pair| match (pair[0].as_slice(), pair[1].as_slice()) {
            ([lon, lat], [x, y]) => Some(([*lon, *lat], [*x, *y])),
            _ => None,
        })
        .collect()
}

impl Affine {
    /// The least-squares fit to (`[longitude, latitude]`, `[x, y]`) pairs; `None` when the
    /// `[x, y]` are on one line or a position is not geodetic.
    fn fit(pairs: &[([f64; 2], [f64; 2])]) -> Option<Self> {
        let count = pairs.len() as f64;
        // the tangent frame at the mean control point, x east
        let plane = FrameSettings {
            origin: GeodeticOrigin {
                longitude_deg: pairs.iter().map(|(g, _)| g[0]).sum::<f64>() / count,
                latitude_deg: pairs.iter().map(|(g, _)| g[1]).sum::<f64>() / count,
                height_m: 0.0,
            },
            x_axis_bearing_deg: 90.0,
        };
        // rows [x, y, 1] and targets [e, n]:  [e, n] = [x, y, 1] [A | b]ᵀ
        let design = DMatrix::from_fn(pairs.len(), 3, |i, j| [pairs[i].1[0], pairs[i].1[1], 1.0][j]);
        let mut targets = DMatrix::zeros(pairs.len(), 2);
        for (i, (geo, _)) in pairs.iter().enumerate() {
            let [e, n, _] = plane.site_of_wgs84([geo[0], geo[1], 0.0])?;
            targets[(i, 0)] = e;
            targets[(i, 1)] = n;
        }
        let svd = design.svd(true, true);
        let (largest, smallest) = (svd.singular_values.max(), svd.singular_values.min());
        if smallest.is_nan() || smallest <= MIN_CONDITION * largest {
            return None;
        }
        // least squares: [A | b]ᵀ = X⁺ [e, n]
        let coefficients = svd.solve(&targets, 0.0).ok()?;
        let a = Matrix2::new(
            coefficients[(0, 0)],
            coefficients[(1, 0)],
            coefficients[(0, 1)],
            coefficients[(1, 1)],
        );
        let b = Vector2::new(coefficients[(2, 0)], coefficients[(2, 1)]);
        // the map must be invertible to transform back
        a.try_inverse().map(|_| Self { a, b, plane })
    }

    fn wgs84_of(&self, local: [f64; 2]) -> Option<[f64; 2]> {
        // [e, n] = A [x, y] + b
        let en = self.a * Vector2::new(local[0], local[1]) + self.b;
        self.plane.wgs84_of([en.x, en.y, 0.0]).map(|[lon, lat, _]| [lon, lat])
    }

    fn local_of(&self, wgs84: [f64; 2]) -> Option<[f64; 2]> {
        let [e, n, _] = self.plane.site_of_wgs84([wgs84[0], wgs84[1], 0.0])?;
        // [x, y] = A⁻¹ ([e, n] − b)
        let local = self.a.try_inverse()? * (Vector2::new(e, n) - self.b);
        (local.x.is_finite() && local.y.is_finite()).then_some([local.x, local.y])
    }
}

/// The closed ring (site metres) of a fence made from a non-proximity zone: its ground control
/// points in the order given — their WGS-84 positions placed by the site's georeference when
/// the site has one, else their `[x, y]` taken as site metres.
///
/// # Errors
/// 400 when the zone has fewer than three ground control points, or one the site cannot place.
pub(super) fn fence_ring_m(zone: &Zone, frame: Option<&FrameSettings>) -> ApiResult<Vec<Vec<f64>>> {
    let pairs = control_pairs(zone);
    if pairs.len() < 3 {
        return Err(ApiError::field(
            "ground_control_points",
            format!("zone `{}` needs three ground control points to make a fence", zone.id),
        ));
    }
    let mut ring = Vec::with_capacity(pairs.len() + 1);
    for (i, (geo, local)) in pairs.iter().enumerate() {
        let vertex = match frame {
            Some(frame) => frame
                .site_of_wgs84([geo[0], geo[1], frame.origin.height_m])
                .map(|[x, y, _]| vec![x, y])
                .ok_or_else(|| ApiError::field(format!("ground_control_points[{}]", 2 * i), "not a WGS-84 position"))?,
            None => local.to_vec(),
        };
        ring.push(vertex);
    }
    ring.push(ring[0].clone());
    Ok(ring)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zone_with(points: Vec<Vec<f64>>) -> Zone {
        serde_json::from_value(serde_json::json!({
            "id": "7c9e6679-7425-40de-944b-e07fc1f90ae7", "type": "uwb", "ground_control_points": points
        }))
        .unwrap()
    }

    #[test]
    fn an_affine_fit_maps_the_control_points_and_back() {
        // the spec's example: a 1 × 1 m zone
        let zone = zone_with(vec![
            vec![7.815694, 48.130216],
            vec![0.0, 0.0],
            vec![7.8157249, 48.13031],
            vec![0.0, 1.0],
            vec![7.816582, 48.130188],
            vec![1.0, 1.0],
            vec![7.816551, 48.130094],
            vec![1.0, 0.0],
        ]);
        let frame = ZoneFrame::of_zone(&zone).unwrap();
        let corner = frame.wgs84_of(&[0.0, 0.0]).unwrap();
        // four points, a best fit: the map and its inverse agree
        let back = frame.local_of(&corner).unwrap();
        assert!(back[0].abs() < 1e-6 && back[1].abs() < 1e-6, "{back:?}");
        let exact = zone_with(vec![
            vec![8.0, 47.0],
            vec![0.0, 0.0],
            vec![8.001, 47.0],
            vec![10.0, 0.0],
            vec![8.0, 47.001],
            vec![0.0, 10.0],
        ]);
        let frame = ZoneFrame::of_zone(&exact).unwrap();
        let [lon, lat] = [0, 1].map(|k| frame.wgs84_of(&[10.0, 0.0, 2.0]).unwrap()[k]);
        assert!((lon - 8.001).abs() < 1e-10 && (lat - 47.0).abs() < 1e-10, "{lon} {lat}");
        assert_eq!(frame.wgs84_of(&[10.0, 0.0, 2.0]).unwrap()[2], 2.0);
        // the middle of the square in longitude and latitude is its middle in metres to well
        // within a millimetre (the ellipsoid is not linear in them, over 76 × 111 m)
        let local = frame.local_of(&[8.0005, 47.0005]).unwrap();
        assert!(
            (local[0] - 5.0).abs() < 1e-3 && (local[1] - 5.0).abs() < 1e-3,
            "{local:?}"
        );
    }

    #[test]
    fn collinear_or_too_few_control_points_are_refused() {
        let collinear = zone_with(vec![
            vec![8.0, 47.0],
            vec![0.0, 0.0],
            vec![8.001, 47.0],
            vec![1.0, 0.0],
            vec![8.002, 47.0],
            vec![2.0, 0.0],
        ]);
        assert!(ZoneFrame::of_zone(&collinear).is_err());
        let two = zone_with(vec![vec![8.0, 47.0], vec![0.0, 0.0], vec![8.001, 47.0], vec![1.0, 0.0]]);
        assert!(ZoneFrame::of_zone(&two).is_err());
        assert!(fence_ring_m(&two, None).is_err());
    }
}
