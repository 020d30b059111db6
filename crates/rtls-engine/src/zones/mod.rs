//! Zones: geometry (2-D polygons with a floor or height range, 3-D boxes) and enter / exit /
//! dwell events with anti-flap hysteresis.
//!
//! - [`Zone`] and [`Shape`] — what a zone is, as written in the site file
//!   (see `examples/site.toml`), with [`Zone::contains`], [`Zone::signed_distance_m`] and
//!   [`Zone::segment_entry`] for predictive alarms (seed 000, capability 3: "the predicted next
//!   position enters a danger zone").
//! - [`ZoneMonitor`] — per tag and zone, turns positions into [`ZoneEvent`]s and keeps head
//!   counts.
//!
//! # References
//! - Seed 000 (ME-KF, mine personnel), predictive early warning around a collapsed area whose
//!   reader is broken.
//! - Signed distance of an extruded polygon: I. Quilez, "distance functions" (2-D distance
//!   combined with the slab distance, exact outside and inside).

mod geometry;
pub(crate) mod monitor;
mod muster;

pub use monitor::{AntiFlap, ZoneEvent, ZoneMonitor};
pub use muster::{missing_zones, muster_status, MusterSettings, MusterStatus};

use serde::{Deserialize, Serialize};

use crate::error::{EngineError, Result};

/// What a zone means to the control room.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZoneKind {
    /// Dangerous ground (collapse, gas, blasting): entering it raises an alarm.
    Hazard,
    /// Access restricted to authorised tags.
    Restricted,
    /// An area of interest: counted and reported, no alarm.
    AreaOfInterest,
}

/// The geometry of a zone, written as a `shape` table with `type = "polygon"` or `type = "box"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Shape {
    /// A simple (non-self-intersecting, possibly concave) polygon in the x–y plane, extruded over
    /// a height range.
    Polygon {
        /// Vertices `[x, y]`, m, in either winding order; the first vertex is not repeated.
        vertices_m: Vec<[f64; 2]>,
        /// The floor the polygon lies on (an id from the site's `floors`); the site loader copies
        /// that floor's height range into `z_range_m`.
        #[serde(default)]
        floor: Option<String>,
        /// Height range `[z_min, z_max]`, m; `None` (and no floor) means every height.
        #[serde(default)]
        z_range_m: Option<[f64; 2]>,
    },
    /// An axis-aligned 3-D box.
    Box {
        /// Lower corner `[x, y, z]`, m.
        min_m: [f64; 3],
        /// Upper corner `[x, y, z]`, m; every coordinate strictly greater than `min_m`'s.
        max_m: [f64; 3],
    },
}

/// One zone of a site.
///
/// # Examples
/// ```
/// use rtls_engine::zones::{Shape, Zone, ZoneKind};
/// let zone = Zone {
///     id: "stope-7".into(),
///     name: "Collapsed stope".into(),
///     kind: ZoneKind::Hazard,
///     readers: vec![],
///     shape: Shape::Box { min_m: [0.0, 0.0, 0.0], max_m: [10.0, 4.0, 3.0] },
/// };
/// zone.validate().unwrap();
/// assert!(zone.contains([5.0, 2.0, 1.0]));
/// assert_eq!(zone.signed_distance_m([12.0, 2.0, 1.0]), 2.0);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zone {
    /// Unique id, used in events and head counts.
    pub id: String,
    /// Human-readable name.
    pub name: String,
    /// What the zone means.
    pub kind: ZoneKind,
    /// Readers associated with the zone (e.g. the broken reader a hazard zone surrounds, or the
    /// readers through which an alarm reaches tags inside); ids of the site's readers.
    #[serde(default)]
    pub readers: Vec<String>,
    /// The geometry.
    pub shape: Shape,
}

impl Zone {
    /// Checks the geometry: finite coordinates, a polygon with at least 3 distinct vertices,
    /// non-zero area and no self-intersection (the first vertex not repeated at the end), and
    /// height ranges and boxes with `min < max`. Floor references are checked by the site
    /// loader, which resolves them.
    ///
    /// # Errors
    /// [`EngineError::Parse`] with file `-`, line 0, the offending field relative to the zone
    /// (e.g. `shape.vertices_m[3]`) and the reason.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{Shape, Zone, ZoneKind};
    /// let bow_tie = Zone {
    ///     id: "x".into(),
    ///     name: "bow tie".into(),
    ///     kind: ZoneKind::Restricted,
    ///     readers: vec![],
    ///     shape: Shape::Polygon {
    ///         vertices_m: vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]],
    ///         floor: None,
    ///         z_range_m: None,
    ///     },
    /// };
    /// assert!(bow_tie.validate().is_err());
    /// ```
    pub fn validate(&self) -> Result<()> {
        match geometry::problem(&self.shape) {
            None => Ok(()),
            Some((field, reason)) => Err(EngineError::Parse {
                file: "-".into(),
                line: 0,
                field,
                reason: format!("zone `{}`: {reason}", self.id),
            }),
        }
    }

    /// Whether a point lies inside the zone or on its boundary.
    ///
    /// # Units
    /// `point_m` is `[x, y, z]`, m.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{Shape, Zone, ZoneKind};
    /// let zone = Zone {
    ///     id: "l".into(),
    ///     name: "L-shaped hall".into(),
    ///     kind: ZoneKind::AreaOfInterest,
    ///     readers: vec![],
    ///     shape: Shape::Polygon {
    ///         vertices_m: vec![[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [1.0, 1.0], [1.0, 4.0], [0.0, 4.0]],
    ///         floor: None,
    ///         z_range_m: Some([0.0, 3.0]),
    ///     },
    /// };
    /// assert!(zone.contains([0.5, 3.0, 1.0]));
    /// assert!(!zone.contains([3.0, 3.0, 1.0])); // in the notch of the L
    /// assert!(!zone.contains([0.5, 3.0, 5.0])); // above the height range
    /// ```
    #[must_use]
    pub fn contains(&self, point_m: [f64; 3]) -> bool {
        self.signed_distance_m(point_m) <= 0.0
    }

    /// The signed Euclidean distance from a point to the zone's boundary, m: negative inside,
    /// zero on the boundary, positive outside.
    ///
    /// For a polygon, the 2-D distance to the polygon is combined with the distance to the
    /// height range as for an extruded solid: outside, `√(d_xy₊² + d_z₊²)`; inside,
    /// `max(d_xy, d_z)` (the nearer of the walls and the floor/ceiling). Without a height range
    /// it is the 2-D distance.
    ///
    /// # Units
    /// `point_m` is `[x, y, z]`, m; the result is in m. Finite for a validated zone and a finite
    /// point.
    ///
    /// # References
    /// I. Quilez, "distance functions" (box and extrusion), iquilezles.org.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{Shape, Zone, ZoneKind};
    /// let zone = Zone {
    ///     id: "b".into(),
    ///     name: "box".into(),
    ///     kind: ZoneKind::Hazard,
    ///     readers: vec![],
    ///     shape: Shape::Box { min_m: [0.0, 0.0, 0.0], max_m: [2.0, 2.0, 2.0] },
    /// };
    /// assert_eq!(zone.signed_distance_m([1.0, 1.0, 1.0]), -1.0);
    /// assert_eq!(zone.signed_distance_m([5.0, 6.0, 1.0]), 5.0);
    /// ```
    #[must_use]
    pub fn signed_distance_m(&self, point_m: [f64; 3]) -> f64 {
        geometry::signed_distance_m(&self.shape, point_m)
    }

    /// Where the straight segment from `from_m` to `to_m` first enters the zone, as the fraction
    /// `s ∈ [0, 1]` of the way along it (`0` when `from_m` is already inside), or `None` when the
    /// segment never touches the zone. Multiply by the prediction horizon to get the time to
    /// entry of a predicted path.
    ///
    /// # Units
    /// Points `[x, y, z]`, m; the result is dimensionless.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{Shape, Zone, ZoneKind};
    /// let zone = Zone {
    ///     id: "b".into(),
    ///     name: "box".into(),
    ///     kind: ZoneKind::Hazard,
    ///     readers: vec![],
    ///     shape: Shape::Box { min_m: [10.0, -1.0, 0.0], max_m: [12.0, 1.0, 3.0] },
    /// };
    /// // walking along +x from the origin, 20 m in the next step: enters at x = 10 m
    /// assert_eq!(zone.segment_entry([0.0, 0.0, 1.0], [20.0, 0.0, 1.0]), Some(0.5));
    /// assert_eq!(zone.segment_entry([0.0, 5.0, 1.0], [20.0, 5.0, 1.0]), None);
    /// ```
    #[must_use]
    pub fn segment_entry(&self, from_m: [f64; 3], to_m: [f64; 3]) -> Option<f64> {
        geometry::segment_entry(&self.shape, from_m, to_m)
    }

    /// Whether the segment from `from_m` to `to_m` touches the zone (see
    /// [`Zone::segment_entry`]).
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{Shape, Zone, ZoneKind};
    /// let zone = Zone {
    ///     id: "b".into(),
    ///     name: "box".into(),
    ///     kind: ZoneKind::Hazard,
    ///     readers: vec![],
    ///     shape: Shape::Box { min_m: [10.0, -1.0, 0.0], max_m: [12.0, 1.0, 3.0] },
    /// };
    /// assert!(zone.segment_enters([0.0, 0.0, 1.0], [11.0, 0.0, 1.0]));
    /// ```
    #[must_use]
    pub fn segment_enters(&self, from_m: [f64; 3], to_m: [f64; 3]) -> bool {
        self.segment_entry(from_m, to_m).is_some()
    }
}

#[cfg(test)]
mod tests;
