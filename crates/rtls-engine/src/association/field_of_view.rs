//! The field of view of a directional ranging sensor (a sonar sector, a radar beam): which
//! predicted tracks could have made a range detection at all.

use crate::error::{EngineError, Result};

/// How many standard deviations of its predicted range a track may lie beyond the sensor's
/// maximum range and still be a candidate: `d̂ − 3 √S ≤ r_max`.
pub(crate) const VIEW_RANGE_SIGMAS: f64 = 3.0;

/// The sector a range detection was measured in, with its apex at the detection's node: a
/// track is a candidate for the detection only if its predicted position lies inside it.
///
/// A predicted position `p̂` (the track's prior at the scan time) with predicted range
/// `d̂ = ‖p̂ − a‖` from the node `a` and innovation variance `S = uᵀ P_pos u + σ²`
/// (`u = (p̂ − a)/d̂`) is in view when
/// ```text
/// |wrap(atan2(p̂_y − a_y, p̂_x − a_x) − θ_aim)| ≤ half-width      (bearing inside the sector)
/// d̂ − 3 √S ≤ r_max                                             (not surely out of range)
/// ```
/// A track outside the view is not gated against the detection (nor counted in
/// [`ScanReport::singular_pairs`](super::ScanReport::singular_pairs)): the sensor could not
/// have heard it, however well its range fits.
///
/// # Units
/// Angles in radians, counter-clockwise from the +x axis; `max_range_m` in metres.
///
/// # Errors
/// [`FieldOfView::new`] rejects a non-finite aim, a half-width outside `(0, π]` and a maximum
/// range that is NaN or not positive (`f64::INFINITY` means no range limit).
///
/// # Example
/// A 60° sonar sector aimed along +y, widened by 10° on each side, hearing up to 3 m:
/// ```
/// use rtls_engine::association::{Detection, FieldOfView};
/// let view = FieldOfView::new(90f64.to_radians(), 40f64.to_radians(), 3.0)?;
/// assert!(view.contains_bearing([0.0, 0.0], [0.2, 1.0]));
/// assert!(!view.contains_bearing([0.0, 0.0], [1.0, 0.2]));
/// let echo = Detection::range([0.0, 0.0], 1.02, 0.0009)?.within(view)?;
/// assert_eq!(echo.field_of_view(), Some(&view));
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Seed 003 §3.1: each node carries six 60° ultrasonic sectors and fires the one aimed at the
/// target's predicted position; an echo can only come from a robot inside that sector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldOfView {
    aim_rad: f64,
    half_width_rad: f64,
    max_range_m: f64,
}

impl FieldOfView {
    /// A sector centred on bearing `aim_rad` (rad) spanning `± half_width_rad` (rad, any
    /// margin included) out to `max_range_m` (m).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `aim_rad` (not finite), `half_width_rad` (not in
    /// `(0, π]`) or `max_range_m` (NaN or ≤ 0).
    pub fn new(aim_rad: f64, half_width_rad: f64, max_range_m: f64) -> Result<Self> {
        if !aim_rad.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "aim_rad",
                reason: "the aim bearing must be finite",
            });
        }
        if !(half_width_rad > 0.0 && half_width_rad <= std::f64::consts::PI) {
            return Err(EngineError::InvalidParameter {
                name: "half_width_rad",
                reason: "the half-width must be in (0, π] (π: all around)",
            });
        }
        if max_range_m.is_nan() || max_range_m <= 0.0 {
            return Err(EngineError::InvalidParameter {
                name: "max_range_m",
                reason: "the maximum range must be > 0 (f64::INFINITY for none)",
            });
        }
        Ok(Self {
            aim_rad,
            half_width_rad,
            max_range_m,
        })
    }

    /// The sector's centre bearing, rad.
    #[must_use]
    pub fn aim_rad(&self) -> f64 {
        self.aim_rad
    }

    /// Half the sector's width, rad.
    #[must_use]
    pub fn half_width_rad(&self) -> f64 {
        self.half_width_rad
    }

    /// The largest range the sensor reports, m.
    #[must_use]
    pub fn max_range_m(&self) -> f64 {
        self.max_range_m
    }

    /// Whether the bearing from `apex_m` to `point_m` lies inside the sector:
    /// `|wrap(bearing − θ_aim)| ≤ half-width`, `wrap` into `[−π, π)`. A point on the apex has
    /// no bearing and is inside.
    #[must_use]
    pub fn contains_bearing(&self, apex_m: [f64; 2], point_m: [f64; 2]) -> bool {
        let (dx, dy) = (point_m[0] - apex_m[0], point_m[1] - apex_m[1]);
        if dx == 0.0 && dy == 0.0 {
            return true;
        }
        // offset = wrap(atan2(Δy, Δx) − θ_aim) into [−π, π)
        let offset = (dy.atan2(dx) - self.aim_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        offset.abs() <= self.half_width_rad
    }

    /// Whether a predicted range `d̂` (m) with innovation variance `S` (m²) may lie within the
    /// maximum range: `d̂ − 3 √S ≤ r_max`.
    #[must_use]
    pub fn within_range(&self, predicted_m: f64, innovation_variance_m2: f64) -> bool {
        predicted_m - VIEW_RANGE_SIGMAS * innovation_variance_m2.max(0.0).sqrt() <= self.max_range_m
    }
}
