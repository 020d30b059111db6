//! Zone geometry: validation, signed distance and segment entry for polygons (extruded over a
//! height range) and axis-aligned boxes.

use super::Shape;

type P2 = [f64; 2];

/// The first problem of a shape, as (field relative to the zone, reason), or `None`.
pub(super) fn problem(shape: &Shape) -> Option<(String, String)> {
    match shape {
        Shape::Polygon {
            vertices_m, z_range_m, ..
        } => polygon_problem(vertices_m).or_else(|| {
            z_range_m.and_then(|[lo, hi]| {
                (!(lo.is_finite() && hi.is_finite() && lo < hi)).then(|| {
                    (
                        "shape.z_range_m".to_string(),
                        format!("must be finite with z_min < z_max, got [{lo}, {hi}]"),
                    )
                })
            })
        }),
        Shape::Box { min_m, max_m } => {
            for (name, corner) in [("shape.min_m", min_m), ("shape.max_m", max_m)] {
                if corner.iter().any(|c| !c.is_finite()) {
                    return Some((name.to_string(), "coordinates must be finite".to_string()));
                }
            }
            let axes = ["x", "y", "z"];
            (0..3).find(|&k| min_m[k] >= max_m[k]).map(|k| {
                (
                    "shape.max_m".to_string(),
                    format!(
                        "must exceed min_m in every coordinate, but {} = {} ≤ {}",
                        axes[k], max_m[k], min_m[k]
                    ),
                )
            })
        }
    }
}

fn polygon_problem(v: &[P2]) -> Option<(String, String)> {
    let n = v.len();
    if n > crate::site::MAX_ZONE_VERTICES {
        return Some((
            "shape.vertices_m".into(),
            format!(
                "has {n} vertices; a zone may have at most {} (simplify the outline)",
                crate::site::MAX_ZONE_VERTICES
            ),
        ));
    }
    if n < 3 {
        return Some((
            "shape.vertices_m".into(),
            format!("a polygon needs at least 3 vertices, got {n}"),
        ));
    }
    if let Some(i) = v.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
        return Some((format!("shape.vertices_m[{i}]"), "coordinates must be finite".into()));
    }
    for i in 0..n {
        if v[i] == v[(i + 1) % n] {
            // name the later of the two: the last vertex when it repeats the first
            let (later, earlier) = if i + 1 == n { (i, 0) } else { (i + 1, i) };
            return Some((
                format!("shape.vertices_m[{later}]"),
                format!("repeats vertex {earlier} (do not close the polygon by repeating the first vertex)"),
            ));
        }
    }
    // every pair of edges: non-adjacent edges must not touch, adjacent ones must not fold back
    for i in 0..n {
        let (a, b) = (v[i], v[(i + 1) % n]);
        for j in (i + 1)..n {
            let (c, d) = (v[j], v[(j + 1) % n]);
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            let bad = if adjacent {
                // shared vertex; they overlap only when collinear and pointing back
                let (shared, p, q) = if j == i + 1 { (b, a, d) } else { (a, b, c) };
                cross(shared, p, q) == 0.0 && dot(sub(p, shared), sub(q, shared)) > 0.0
            } else {
                segments_touch(a, b, c, d)
            };
            if bad {
                return Some((
                    "shape.vertices_m".into(),
                    format!(
                        "edges {i}–{} and {j}–{} intersect: the polygon must be simple",
                        (i + 1) % n,
                        (j + 1) % n
                    ),
                ));
            }
        }
    }
    if area2(v) == 0.0 {
        return Some((
            "shape.vertices_m".into(),
            "the vertices are collinear: the polygon has no area".into(),
        ));
    }
    None
}

fn sub(a: P2, b: P2) -> P2 {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: P2, b: P2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// `(p − o) × (q − o)`: positive when o → p → q turns left.
fn cross(o: P2, p: P2, q: P2) -> f64 {
    let (u, w) = (sub(p, o), sub(q, o));
    u[0] * w[1] - u[1] * w[0]
}

/// Twice the signed area (shoelace).
fn area2(v: &[P2]) -> f64 {
    (0..v.len())
        .map(|i| {
            let (a, b) = (v[i], v[(i + 1) % v.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

fn on_segment(a: P2, b: P2, p: P2) -> bool {
    p[0] >= a[0].min(b[0]) && p[0] <= a[0].max(b[0]) && p[1] >= a[1].min(b[1]) && p[1] <= a[1].max(b[1])
}

/// Whether closed segments `ab` and `cd` share at least one point.
fn segments_touch(a: P2, b: P2, c: P2, d: P2) -> bool {
    let (d1, d2) = (cross(c, d, a), cross(c, d, b));
    let (d3, d4) = (cross(a, b, c), cross(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0)) {
        return true;
    }
    (d1 == 0.0 && on_segment(c, d, a))
        || (d2 == 0.0 && on_segment(c, d, b))
        || (d3 == 0.0 && on_segment(a, b, c))
        || (d4 == 0.0 && on_segment(a, b, d))
}

/// Distance from `p` to the closed segment `ab`.
fn distance_to_segment(p: P2, a: P2, b: P2) -> f64 {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    // t = clamp((p − a)·(b − a) / |b − a|², 0, 1); validated polygons have len2 > 0
    let t = if len2 > 0.0 {
        (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let closest = [a[0] + t * ab[0], a[1] + t * ab[1]];
    let d = sub(p, closest);
    d[0].hypot(d[1])
}

/// Even–odd crossing test (equal to the winding rule for simple polygons).
fn inside_polygon(v: &[P2], p: P2) -> bool {
    let mut inside = false;
    let mut j = v.len() - 1;
    for i in 0..v.len() {
        let (a, b) = (v[i], v[j]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// Signed 2-D distance to a polygon: negative inside.
fn polygon_signed_distance_m(v: &[P2], p: P2) -> f64 {
    let n = v.len();
    let d = (0..n)
        .map(|i| distance_to_segment(p, v[i], v[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min);
    if inside_polygon(v, p) {
        -d
    } else {
        d
    }
}

/// Combines two signed distances of an intersection of an extrusion and a slab.
fn combine(a: f64, b: f64) -> f64 {
    if a <= 0.0 && b <= 0.0 {
        a.max(b)
    } else {
        a.max(0.0).hypot(b.max(0.0))
    }
}

pub(super) fn signed_distance_m(shape: &Shape, p: [f64; 3]) -> f64 {
    match shape {
        Shape::Polygon {
            vertices_m, z_range_m, ..
        } => {
            let d_xy = polygon_signed_distance_m(vertices_m, [p[0], p[1]]);
            match z_range_m {
                // d_z = max(z_min − z, z − z_max)
                Some([lo, hi]) => combine(d_xy, (lo - p[2]).max(p[2] - hi)),
                None => d_xy,
            }
        }
        Shape::Box { min_m, max_m } => {
            // q = |p − c| − h per axis
            let q: Vec<f64> = (0..3)
                .map(|k| (p[k] - 0.5 * (min_m[k] + max_m[k])).abs() - 0.5 * (max_m[k] - min_m[k]))
                .collect();
            let outside = q.iter().map(|x| x.max(0.0).powi(2)).sum::<f64>().sqrt();
            let inside = q[0].max(q[1]).max(q[2]).min(0.0);
            outside + inside
        }
    }
}

/// Clips `[t0, t1]` to where `from + t·(to − from)` lies in `[lo, hi]` on one axis.
fn clip_slab(from: f64, to: f64, lo: f64, hi: f64, range: (f64, f64)) -> Option<(f64, f64)> {
    let delta = to - from;
    let (mut t0, mut t1) = range;
    if delta == 0.0 {
        return (from >= lo && from <= hi).then_some(range);
    }
    let (a, b) = ((lo - from) / delta, (hi - from) / delta);
    t0 = t0.max(a.min(b));
    t1 = t1.min(a.max(b));
    (t0 <= t1).then_some((t0, t1))
}

pub(super) fn segment_entry(shape: &Shape, from: [f64; 3], to: [f64; 3]) -> Option<f64> {
    match shape {
        Shape::Box { min_m, max_m } => {
            let mut range = (0.0, 1.0);
            for k in 0..3 {
                range = clip_slab(from[k], to[k], min_m[k], max_m[k], range)?;
            }
            Some(range.0)
        }
        Shape::Polygon {
            vertices_m, z_range_m, ..
        } => {
            let (t0, t1) = match z_range_m {
                Some([lo, hi]) => clip_slab(from[2], to[2], *lo, *hi, (0.0, 1.0))?,
                None => (0.0, 1.0),
            };
            let at = |t: f64| [from[0] + t * (to[0] - from[0]), from[1] + t * (to[1] - from[1])];
            if polygon_signed_distance_m(vertices_m, at(t0)) <= 0.0 {
                return Some(t0);
            }
            // the first crossing of a polygon edge within [t0, t1]
            let (o, d) = ([from[0], from[1]], [to[0] - from[0], to[1] - from[1]]);
            let n = vertices_m.len();
            let mut best: Option<f64> = None;
            for i in 0..n {
                let (a, b) = (vertices_m[i], vertices_m[(i + 1) % n]);
                if let Some(t) = first_hit(o, d, a, b, t0, t1) {
                    best = Some(best.map_or(t, |x: f64| x.min(t)));
                }
            }
            best
        }
    }
}

/// The smallest `t ∈ [t0, t1]` at which `o + t·d` lies on the closed segment `ab`.
fn first_hit(o: P2, d: P2, a: P2, b: P2, t0: f64, t1: f64) -> Option<f64> {
    let e = sub(b, a);
    let denom = d[0] * e[1] - d[1] * e[0];
    let ao = sub(a, o);
    if denom == 0.0 {
        // parallel: a hit only when collinear; then the overlap's start
        if ao[0] * d[1] - ao[1] * d[0] != 0.0 {
            return None;
        }
        let len2 = dot(d, d);
        if len2 == 0.0 {
            return None;
        }
        let (ta, tb) = (dot(ao, d) / len2, dot(sub(b, o), d) / len2);
        let (lo, hi) = (ta.min(tb).max(t0), ta.max(tb).min(t1));
        return (lo <= hi).then_some(lo);
    }
    // o + t d = a + u e  ⇒  t = (ao × e) / (d × e), u = (ao × d) / (d × e)
    let t = (ao[0] * e[1] - ao[1] * e[0]) / denom;
    let u = (ao[0] * d[1] - ao[1] * d[0]) / denom;
    ((t0..=t1).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}
