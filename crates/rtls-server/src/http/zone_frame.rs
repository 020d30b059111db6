//! The geometry of omlox zones: the map between a zone's local `[x, y]` (m) and WGS-84, and
//! the ring of a fence made from a zone.
//!
//! A stored zone's frame comes from its ground control points, pairs of
//! `[longitude, latitude]` and `[x, y]`. Longitude and latitude are taken to east/north metres
//! on the plane tangent at their mean (equirectangular: `e = Δλ·R·cos φ₀`, `n = Δφ·R`), and a
//! least-squares affine map `[e, n] = A [x, y] + b` is fitted — exact for three points, a best
//! fit for more. Over a site's extent (≤ a few km) the plane's error is far below a
//! positioning system's (< 1 cm per km); a constant scale error in `R` is absorbed by `A`.

use axum::http::StatusCode;
use rtls_engine::site::FrameSettings;

use super::{ApiError, ApiResult};
use crate::omlox::Zone;

/// The Earth's mean radius, m (the plane's scale; see the module documentation).
const EARTH_RADIUS_M: f64 = 6_371_008.8;

/// How a zone's local positions map to WGS-84.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum ZoneFrame {
    /// The site's georeference (`[frame]`), for the site's own zone.
    Site(FrameSettings),
    /// An affine map fitted to a zone's ground control points.
    Fitted(Affine),
}

/// `[e, n] = A [x, y] + b` about the reference longitude and latitude (degrees).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Affine {
    /// Row-major 2 × 2.
    a: [[f64; 2]; 2],
    b: [f64; 2],
    reference_deg: [f64; 2],
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
                let [lon, lat] = affine.wgs84_of([local[0], local[1]]);
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
    /// `[x, y]` are on one line.
    fn fit(pairs: &[([f64; 2], [f64; 2])]) -> Option<Self> {
        let count = pairs.len() as f64;
        let reference_deg = [
            pairs.iter().map(|(g, _)| g[0]).sum::<f64>() / count,
            pairs.iter().map(|(g, _)| g[1]).sum::<f64>() / count,
        ];
        let plane = |g: [f64; 2]| en_of(g, reference_deg);
        // normal equations M p = r for e = a x + b y + c and n = d x + e y + f
        let mut m = [[0.0; 3]; 3];
        let mut r = [[0.0; 3]; 2];
        for (geo, local) in pairs {
            let row = [local[0], local[1], 1.0];
            let en = plane(*geo);
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += row[i] * row[j];
                }
                r[0][i] += row[i] * en[0];
                r[1][i] += row[i] * en[1];
            }
        }
        let east = solve3(m, r[0])?;
        let north = solve3(m, r[1])?;
        let affine = Self {
            a: [[east[0], east[1]], [north[0], north[1]]],
            b: [east[2], north[2]],
            reference_deg,
        };
        // the map must be invertible to transform back
        (affine.determinant().abs() > 1e-12).then_some(affine)
    }

    fn determinant(&self) -> f64 {
        self.a[0][0] * self.a[1][1] - self.a[0][1] * self.a[1][0]
    }

    fn wgs84_of(&self, local: [f64; 2]) -> [f64; 2] {
        let e = self.a[0][0] * local[0] + self.a[0][1] * local[1] + self.b[0];
        let n = self.a[1][0] * local[0] + self.a[1][1] * local[1] + self.b[1];
        let lat0 = self.reference_deg[1].to_radians();
        [
            self.reference_deg[0] + (e / (EARTH_RADIUS_M * lat0.cos())).to_degrees(),
            self.reference_deg[1] + (n / EARTH_RADIUS_M).to_degrees(),
        ]
    }

    fn local_of(&self, wgs84: [f64; 2]) -> Option<[f64; 2]> {
        let [e, n] = en_of(wgs84, self.reference_deg);
        let (de, dn) = (e - self.b[0], n - self.b[1]);
        let det = self.determinant();
        let x = (self.a[1][1] * de - self.a[0][1] * dn) / det;
        let y = (-self.a[1][0] * de + self.a[0][0] * dn) / det;
        (x.is_finite() && y.is_finite()).then_some([x, y])
    }
}

/// East/north metres of `[longitude, latitude]` on the plane tangent at `reference_deg`.
fn en_of(wgs84: [f64; 2], reference_deg: [f64; 2]) -> [f64; 2] {
    let lat0 = reference_deg[1].to_radians();
    [
        (wgs84[0] - reference_deg[0]).to_radians() * EARTH_RADIUS_M * lat0.cos(),
        (wgs84[1] - reference_deg[1]).to_radians() * EARTH_RADIUS_M,
    ]
}

/// Solves a 3 × 3 system by Cramer's rule; `None` when it is (nearly) singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    let scale = m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max).powi(3);
    if d.abs() <= 1e-12 * scale.max(1e-300) {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, slot) in out.iter_mut().enumerate() {
        let mut replaced = m;
        for i in 0..3 {
            replaced[i][k] = r[i];
        }
        *slot = det(replaced) / d;
    }
    Some(out)
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
        assert!((lon - 8.001).abs() < 1e-12 && (lat - 47.0).abs() < 1e-12);
        assert_eq!(frame.wgs84_of(&[10.0, 0.0, 2.0]).unwrap()[2], 2.0);
        let local = frame.local_of(&[8.0005, 47.0005]).unwrap();
        assert!(
            (local[0] - 5.0).abs() < 1e-6 && (local[1] - 5.0).abs() < 1e-6,
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
