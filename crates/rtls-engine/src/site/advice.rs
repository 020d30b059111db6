//! Advice on a site that loads but may not say what its author meant: settings whose defaults
//! are a guess about the installation. `rtls track` and `rtls serve` print each line at start.

use super::Site;

/// Readers whose heights differ from 0 by less than this are taken as placed in the plane, m.
const IN_PLANE_M: f64 = 0.3;

/// The horizontal distance at which the advice quotes the range error, m.
const EXAMPLE_DISTANCE_M: f64 = 5.0;

/// The tag height the advice quotes, m (a tag on a belt or a helmet).
const EXAMPLE_TAG_HEIGHT_M: f64 = 1.0;

impl Site {
    /// One line per setting that loads but is probably not what the site's author meant:
    /// - a 2-D site whose readers hang above the plane (at 2.5 m, say) without
    ///   `tracker.tag_height_m`: every range is then taken as a distance in the plane, as if
    ///   the tag were at each reader's height, and a range to a reader 1.5 m above a tag 5 m
    ///   away is 0.22 m too long (`√(d² + Δz²) − d`).
    ///
    /// Empty when there is nothing to say.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::site::Site;
    /// let text = r#"
    /// readers = [{ id = "A1", position_m = [0.0, 0.0, 2.5], technology = "uwb" }]
    /// [tracker]
    /// "#;
    /// let site = Site::from_toml_str(text, "site.toml")?;
    /// assert!(site.advice()[0].contains("tag_height_m"));
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    #[must_use]
    pub fn advice(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let heights = || self.readers.iter().map(|r| r.position_xyz_m()[2]);
        let lowest_m = heights().fold(f64::INFINITY, f64::min);
        let highest_m = heights().fold(f64::NEG_INFINITY, f64::max);
        if self.tracker.dimensions == 2
            && self.tracker.tag_height_m.is_none()
            && highest_m.abs().max(lowest_m.abs()) > IN_PLANE_M
        {
            // √(d² + Δz²) − d at d = 5 m for a tag at 1 m under the highest reader
            let dz_m = highest_m - EXAMPLE_TAG_HEIGHT_M;
            let error_m = (EXAMPLE_DISTANCE_M.powi(2) + dz_m.powi(2)).sqrt() - EXAMPLE_DISTANCE_M;
            lines.push(format!(
                "readers hang at {lowest_m:.2}–{highest_m:.2} m but [tracker] states no tag_height_m: \
                 each range is taken as a distance in the plane, as if the tag were at its reader's \
                 height (a tag at {EXAMPLE_TAG_HEIGHT_M} m, {EXAMPLE_DISTANCE_M} m from a reader at \
                 {highest_m:.2} m, would read {error_m:.2} m long); set tracker.tag_height_m to the \
                 tags' height, or dimensions = 3"
            ));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn site(readers_z_m: f64, tracker: &str) -> Site {
        let text = format!(
            "readers = [{{ id = \"A1\", position_m = [0.0, 0.0, {readers_z_m}], technology = \"uwb\" }}, \
             {{ id = \"A2\", position_m = [9.0, 0.0, {readers_z_m}], technology = \"uwb\" }}]\n[tracker]\n{tracker}\n"
        );
        Site::from_toml_str(&text, "advice.toml").unwrap()
    }

    #[test]
    fn a_planar_site_with_readers_overhead_and_no_tag_height_is_told() {
        let advice = site(2.5, "").advice();
        assert_eq!(advice.len(), 1, "{advice:?}");
        // √(25 + 1.5²) − 5 = 0.22 m
        assert!(advice[0].contains("0.22 m long"), "{advice:?}");
        assert!(site(2.5, "tag_height_m = 1.0").advice().is_empty());
        assert!(site(2.5, "dimensions = 3").advice().is_empty());
        assert!(site(0.0, "").advice().is_empty());
    }
}
