//! The box around the site's readers that a diverged track's position leaves.

use crate::site::Site;

/// The box around the site's readers that positions are checked against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SiteBounds {
    /// Smallest and largest reader coordinates, m; `None` for a site without readers (fixes
    /// only: then the position is not checked, as it may be in any projected frame).
    pub(super) extent_m: Option<([f64; 3], [f64; 3])>,
}

impl SiteBounds {
    /// The box around `site`'s readers.
    pub(crate) fn new(site: &Site) -> Self {
        let mut extent_m: Option<([f64; 3], [f64; 3])> = None;
        for reader in &site.readers {
            let p = reader.position_xyz_m();
            let (low, high) = extent_m.get_or_insert((p, p));
            for axis in 0..3 {
                low[axis] = low[axis].min(p[axis]);
                high[axis] = high[axis].max(p[axis]);
            }
        }
        Self { extent_m }
    }

    /// Distance from `position_m` (the first `d` axes) to the box, m (0 inside it).
    pub(super) fn distance_m(&self, position_m: &[f64], d: usize) -> Option<f64> {
        let (low, high) = self.extent_m?;
        let squared: f64 = (0..d)
            .map(|axis| {
                let outside = (low[axis] - position_m[axis])
                    .max(position_m[axis] - high[axis])
                    .max(0.0);
                outside * outside
            })
            .sum();
        Some(squared.sqrt())
    }
}
