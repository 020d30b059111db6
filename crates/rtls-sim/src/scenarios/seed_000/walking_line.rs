//! The walking lines of the tunnels: what the mine map says about where a tag can be, as
//! linear constraints on its position (used by seed 000's tracker and bound).

use super::{plan_length, segment_distance, MineLayout};

/// One straight leg of a tunnel's walking line: what the map says about where a tag on that
/// leg can be. With `a` the leg's start, `d` its unit plan direction, `n = (−d_y, d_x)` the
/// lateral normal and `γ` the grade (rise per metre in plan), a tag at `p` on the walking line
/// satisfies
///
/// ```text
/// lateral:   n · (p_xy − a_xy) = 0
/// vertical:  p_z − γ d · (p_xy − a_xy) = a_z
/// ```
///
/// both linear in `p`; a walker is anywhere across the tunnel and wears his tag at some
/// height, so each holds up to a spread (see rtls-papers'
/// `reproduction::seed_000::PositionConstraint`).
///
/// # Example
/// ```
/// use rtls_sim::scenarios::seed_000::{MineLayout, Tunnel};
/// let t = vec![Tunnel::new("ramp", vec![[0.0, 0.0, 0.0], [10.0, 0.0, -1.0]], 2.0)?];
/// let mine = MineLayout::new(t, Vec::new(), Vec::new(), Vec::new(), 25.0)?;
/// let line = mine.nearest_walking_line([4.0, 0.5, 0.0]).expect("a tunnel");
/// let ([cx, cy, cz], rhs) = line.vertical();
/// assert!((cx - 0.1).abs() < 1e-12 && cy == 0.0 && cz == 1.0 && rhs == 0.0); // z + 0.1 x = 0
/// // both ends are dead ends: a point past the far end is held at x = 10
/// assert_eq!(line.overshoot([12.0, 0.0, 0.0]), Some(([1.0, 0.0, 0.0], 10.0)));
/// assert_eq!(line.overshoot([5.0, 1.0, 0.0]), None);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkingLine {
    /// Start of the leg `a`, m.
    pub start_m: [f64; 3],
    /// Unit plan direction `d`.
    pub direction: [f64; 2],
    /// Grade `γ` (m of rise per m in plan).
    pub grade: f64,
    /// Plan length of the leg `L`, m.
    pub length_m: f64,
    /// Whether the leg's start is a dead end (no other leg joins there).
    pub dead_start: bool,
    /// Whether the leg's end is a dead end.
    pub dead_end: bool,
}

impl WalkingLine {
    /// Plan distance from `point_m` to the nearest end of the leg that another leg joins (a
    /// junction or a bend), m; `None` if both ends are dead ends.
    #[must_use]
    pub fn distance_to_junction_m(&self, point_m: [f64; 3]) -> Option<f64> {
        let a = self.start_m;
        let b = [
            a[0] + self.length_m * self.direction[0],
            a[1] + self.length_m * self.direction[1],
            0.0,
        ];
        let d = |e: [f64; 3]| (point_m[0] - e[0]).hypot(point_m[1] - e[1]);
        match (self.dead_start, self.dead_end) {
            (true, true) => None,
            (false, true) => Some(d(a)),
            (true, false) => Some(d(b)),
            (false, false) => Some(d(a).min(d(b))),
        }
    }

    /// The along-track constraint `(c, r)`, `c · p = r`, that holds a point `point_m` lying beyond
    /// a dead end of the leg back at that end (`c = (d_x, d_y, 0)`, `r = d · a` or
    /// `d · a + L`); `None` within the leg or past a joined end.
    #[must_use]
    pub fn overshoot(&self, point_m: [f64; 3]) -> Option<([f64; 3], f64)> {
        let [dx, dy] = self.direction;
        let start = dx * self.start_m[0] + dy * self.start_m[1];
        // u = d · (p − a): the position along the leg
        let u = dx * point_m[0] + dy * point_m[1] - start;
        let c = [dx, dy, 0.0];
        if u < 0.0 && self.dead_start {
            Some((c, start))
        } else if u > self.length_m && self.dead_end {
            Some((c, start + self.length_m))
        } else {
            None
        }
    }

    /// The lateral constraint as `(c, r)` with `c · p = r`: `c = (n_x, n_y, 0)`, `r = n · a`.
    #[must_use]
    pub fn lateral(&self) -> ([f64; 3], f64) {
        let n = [-self.direction[1], self.direction[0]];
        // n · p = n · a
        ([n[0], n[1], 0.0], n[0] * self.start_m[0] + n[1] * self.start_m[1])
    }

    /// The vertical constraint as `(c, r)` with `c · p = r`: `c = (−γ d_x, −γ d_y, 1)`,
    /// `r = a_z − γ d · a_xy`.
    #[must_use]
    pub fn vertical(&self) -> ([f64; 3], f64) {
        let [dx, dy] = self.direction;
        let g = self.grade;
        // p_z − γ d · p_xy = a_z − γ d · a_xy
        (
            [-g * dx, -g * dy, 1.0],
            self.start_m[2] - g * (dx * self.start_m[0] + dy * self.start_m[1]),
        )
    }
}

impl MineLayout {
    /// The walking-line leg nearest to `point_m` in plan (the first of equally near legs).
    #[must_use]
    pub fn nearest_walking_line(&self, point_m: [f64; 3]) -> Option<WalkingLine> {
        let p = [point_m[0], point_m[1]];
        let legs: Vec<([f64; 3], [f64; 3], f64)> = self
            .tunnels
            .iter()
            .flat_map(|t| t.centreline_m.windows(2).map(|pair| (pair[0], pair[1], t.half_width_m)))
            .collect();
        let nearest = legs
            .iter()
            .enumerate()
            .map(|(i, (a, b, _))| (i, segment_distance(p, [a[0], a[1]], [b[0], b[1]])))
            .fold(None, |best: Option<(usize, f64)>, (i, d)| match best {
                Some((_, bd)) if bd <= d => best,
                _ => Some((i, d)),
            })?;
        let (a, b, _) = legs[nearest.0];
        // an end is joined if another leg passes within its half-width of it
        let joined = |e: [f64; 3]| {
            legs.iter().enumerate().any(|(j, (c, d, w))| {
                j != nearest.0 && segment_distance([e[0], e[1]], [c[0], c[1]], [d[0], d[1]]) <= *w
            })
        };
        let plan = plan_length(a, b);
        Some(WalkingLine {
            start_m: a,
            direction: [(b[0] - a[0]) / plan, (b[1] - a[1]) / plan],
            grade: (b[2] - a[2]) / plan,
            length_m: plan,
            dead_start: !joined(a),
            dead_end: !joined(b),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::l_mine;

    #[test]
    fn walking_lines_know_their_dead_ends_and_junctions() {
        let mine = l_mine();
        // on the east drift: its start is a dead end, its end joins the north drift
        let east = mine.nearest_walking_line([10.0, 0.5, 0.0]).unwrap();
        assert!(east.dead_start && !east.dead_end);
        assert_eq!(east.distance_to_junction_m([10.0, 0.0, 0.0]), Some(30.0));
        // behind the entrance the estimate is held at the dead end, past the junction it is not
        assert_eq!(east.overshoot([-3.0, 0.0, 0.0]), Some(([1.0, 0.0, 0.0], 0.0)));
        assert_eq!(east.overshoot([45.0, 0.0, 0.0]), None);
        let north = mine.nearest_walking_line([40.5, 30.0, -1.0]).unwrap();
        assert!(!north.dead_start && north.dead_end);
        assert_eq!(north.overshoot([40.0, 44.0, -1.0]), Some(([0.0, 1.0, 0.0], 40.0)));
        // lateral: the left normal of +y is −x, so x = 40 ⇔ −x = −40
        assert_eq!(north.lateral(), ([-1.0, 0.0, 0.0], -40.0));
    }
}
