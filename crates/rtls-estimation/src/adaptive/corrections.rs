//! A test of a filter's own consistency from the corrections its updates make to the position,
//! and the covariance inflation (a fading factor) when the test fails: a filter whose estimate
//! is off by more than its covariance admits keeps correcting it the same way.
//!
//! # Equations
//! An update moves the state by `Δx = K ν` and shrinks its covariance by `K S Kᵀ`. When the
//! filter is consistent its innovations are white with covariance `S` (Mehra 1970), so the
//! position corrections `Δpₖ` (the position rows of `Kₖ νₖ`) of successive updates are
//! independent, zero-mean, with covariance `Cₖ` (the position block of `Kₖ Sₖ Kₖᵀ`). Their sum
//! over a window of `window_s` seconds and its test statistic
//!
//! ```text
//! g = Σₖ Δpₖ,   C = Σₖ Cₖ,   T = gᵀ C⁻¹ g  ~  χ²(d)    (d = 2 or 3 position axes)
//! ```
//!
//! A filter whose position error `δ` is larger than `P` says (an estimate started from a biased
//! fix and held by a tight velocity from odometry, errors that persist for seconds averaged as
//! independent, a model lagging a manoeuvre) pulls its estimate towards the truth update after
//! update, so `g ≈ δ` while `C` stays what `P` predicts, and `T` grows with the window. When
//! `T` exceeds the `χ²(d)` quantile of `probability`, the filter's covariance is scaled by the
//! ratio of the observed to the expected statistic (the fading factor of the strong tracking
//! filter, Zhou & Frank 1996; Xia, Rao, Ying & Shen 1994):
//!
//! ```text
//! λ = min(T / d, λ_max),   P ← λ P
//! ```
//!
//! so the next measurements correct the estimate at the rate its real error asks for, and its
//! reported ellipse holds the truth as often as it claims. A consistent filter's windows fail
//! the test with probability `1 − probability` and are then widened by a factor of a few for
//! one window; the next updates take the excess away again.
//!
//! The window then starts afresh. Only the directions the window's updates informed are
//! tested: the eigen-directions of `C` whose spread is at least 1 % of the largest (`T` is
//! `gᵀ C⁻¹ g` on them and `d` their number); along a barely informed direction the
//! linearisation's small errors would otherwise pass for a large statistic.
//!
//! # Example
//! ```
//! use rtls_estimation::adaptive::corrections::{CorrectionTest, CorrectionWindow};
//!
//! let test = CorrectionTest::new(2.0, 0.99, 100.0)?;
//! let mut window = CorrectionWindow::default();
//! // 20 updates in 2 s, each pulling the estimate 1 cm east where the filter expects ±1 mm
//! let mut inflation = None;
//! for k in 0..=20 {
//!     let reduction = [[1e-6, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 0.0]];
//!     inflation = test.observe(&mut window, 0.1 * f64::from(k), [0.01, 0.0, 0.0], reduction, 2)?;
//! }
//! // g = 0.21 m east against C = 21e-6 m²: T = 2100, λ = min(1050, 100)
//! assert_eq!(inflation, Some(100.0));
//! # Ok::<(), rtls_estimation::EstimationError>(())
//! ```
//!
//! # References
//! - R. K. Mehra, "On the identification of variances and adaptive Kalman filtering", IEEE
//!   Trans. Automatic Control 15(2), 1970 (innovations of an optimal filter are white).
//! - D. H. Zhou, P. M. Frank, "Strong tracking filtering of nonlinear time-varying stochastic
//!   systems with coloured noise", Int. J. Control 65(2), 1996 (the fading factor).
//! - Q. Xia, M. Rao, Y. Ying, X. Shen, "Adaptive fading Kalman filter with an application",
//!   Automatica 30(8), 1994.

use crate::error::{EstimationError, Result};
use crate::stats::chi_square_quantile;

/// The position corrections of the open window.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CorrectionWindow {
    /// Time of the window's first update, s; `None` before it.
    start_s: Option<f64>,
    /// `g = Σ Δp`, m.
    sum_m: [f64; 3],
    /// `C = Σ (K S Kᵀ)_pp`, m².
    covariance_m2: [[f64; 3]; 3],
}

/// The test's settings: window length, false-alarm probability and largest inflation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectionTest {
    window_s: f64,
    /// `χ²(d)` quantiles of the probability for d = 1, 2, 3.
    thresholds: [f64; 3],
    max_inflation: f64,
}

impl CorrectionTest {
    /// A test over windows of `window_s` seconds that passes a consistent filter's window with
    /// `probability`, and inflates by at most `max_inflation`.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a `window_s` that is not finite and positive,
    /// a `probability` outside (0, 1), or a `max_inflation` that is not finite and ≥ 1.
    pub fn new(window_s: f64, probability: f64, max_inflation: f64) -> Result<Self> {
        if !(window_s.is_finite() && window_s > 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "window_s",
                reason: "must be a finite number of seconds > 0",
            });
        }
        if !(probability > 0.0 && probability < 1.0) {
            return Err(EstimationError::InvalidParameter {
                name: "probability",
                reason: "must lie strictly between 0 and 1",
            });
        }
        if !(max_inflation.is_finite() && max_inflation >= 1.0) {
            return Err(EstimationError::InvalidParameter {
                name: "max_inflation",
                reason: "must be a finite number ≥ 1",
            });
        }
        let mut thresholds = [0.0; 3];
        for (dof, threshold) in (1u8..).zip(thresholds.iter_mut()) {
            *threshold = chi_square_quantile(probability, f64::from(dof))?;
        }
        Ok(Self {
            window_s,
            thresholds,
            max_inflation,
        })
    }

    /// Adds one update's position correction `Δp = (K ν)_p` (m) and covariance reduction
    /// `(K S Kᵀ)_pp` (m², row-major, the first `dimensions` rows and columns used) at `time_s`.
    /// When the window has spanned `window_s`, tests it and starts a new one (with this update);
    /// returns the inflation `λ > 1` the filter's covariance needs, or `None`.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a non-finite time, correction or reduction (the window
    /// is left as it was); [`EstimationError::InvalidParameter`] for `dimensions` outside 1–3.
    pub fn observe(
        &self,
        window: &mut CorrectionWindow,
        time_s: f64,
        correction_m: [f64; 3],
        reduction_m2: [[f64; 3]; 3],
        dimensions: usize,
    ) -> Result<Option<f64>> {
        if !(1..=3).contains(&dimensions) {
            return Err(EstimationError::InvalidParameter {
                name: "dimensions",
                reason: "must be 1, 2 or 3",
            });
        }
        if !time_s.is_finite()
            || correction_m.iter().any(|c| !c.is_finite())
            || reduction_m2.iter().flatten().any(|c| !c.is_finite())
        {
            return Err(EstimationError::NonFinite {
                what: "position correction",
            });
        }
        let mut inflation = None;
        match window.start_s {
            Some(start_s) if time_s - start_s >= self.window_s => {
                inflation = self.verdict(window, dimensions);
                *window = CorrectionWindow::default();
                window.start_s = Some(time_s);
            }
            Some(_) => {}
            None => window.start_s = Some(time_s),
        }
        // g ← g + Δp;  C ← C + (K S Kᵀ)_pp
        for (i, row) in reduction_m2.iter().enumerate().take(dimensions) {
            window.sum_m[i] += correction_m[i];
            for (sum, reduction) in window.covariance_m2[i].iter_mut().zip(row).take(dimensions) {
                *sum += reduction;
            }
        }
        Ok(inflation)
    }

    /// `λ = min(T/k, λ_max)` when `T` exceeds the `χ²(k)` threshold (see [`statistic`]).
    fn verdict(&self, window: &CorrectionWindow, dimensions: usize) -> Option<f64> {
        let (statistic, tested) = statistic(&window.covariance_m2, &window.sum_m, dimensions)?;
        (statistic > self.thresholds[tested - 1])
            .then(|| (statistic / tested as f64).min(self.max_inflation))
            .filter(|&lambda| lambda > 1.0)
    }
}

/// Directions whose expected spread is below this share of the largest are not tested.
const UNINFORMED_SHARE: f64 = 0.01;

/// `T = Σᵢ (uᵢᵀ g)² / μᵢ` over the eigenpairs `(μᵢ, uᵢ)` of `C` with `μᵢ ≥ 0.01 μ_max`, and
/// their number `k` (the degrees of freedom); `None` when no direction is informed.
///
/// On the informed directions this is `gᵀ C⁻¹ g`. A direction the window's readings barely
/// informed (two anchors seen from near their common line, a lone reader) has a tiny expected
/// spread, and the linearisation's small errors along it would pass for a large statistic: it
/// is left out of the test rather than divided by.
fn statistic(c: &[[f64; 3]; 3], g: &[f64; 3], d: usize) -> Option<(f64, usize)> {
    let mut matrix = nalgebra::Matrix3::<f64>::zeros();
    for i in 0..d {
        for j in 0..d {
            matrix[(i, j)] = 0.5 * (c[i][j] + c[j][i]);
        }
    }
    let eigen = matrix.symmetric_eigen();
    let largest = eigen.eigenvalues.max();
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    let g = nalgebra::Vector3::new(g[0], g[1], g[2]);
    let (mut statistic, mut tested) = (0.0, 0);
    for (i, &mu) in eigen.eigenvalues.iter().enumerate() {
        if mu >= UNINFORMED_SHARE * largest {
            // (uᵢᵀ g)² / μᵢ
            let projection = eigen.eigenvectors.column(i).dot(&g);
            statistic += projection * projection / mu;
            tested += 1;
        }
    }
    (tested > 0).then_some((statistic, tested))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic standard normal draws (Irwin–Hall sums of a linear congruential
    /// generator's uniforms).
    fn normals(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            (0..12)
                .map(|_| {
                    state = state
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        }
    }

    #[test]
    fn the_statistic_is_the_mahalanobis_distance_over_the_informed_directions() {
        // C = [[4, 2], [2, 3]], g = [1, 2]: C⁻¹ = [[3, −2], [−2, 4]] / 8, gᵀ C⁻¹ g = (3 − 8 + 16)/8
        let c = [[4.0, 2.0, 0.0], [2.0, 3.0, 0.0], [0.0, 0.0, 0.0]];
        let (t, k) = statistic(&c, &[1.0, 2.0, 0.0], 2).unwrap();
        assert!((t - 11.0 / 8.0).abs() < 1e-12 && k == 2, "{t} {k}");
        // a zero third axis is left out: the same statistic on 2 degrees of freedom
        let (t, k) = statistic(&c, &[1.0, 2.0, 5.0], 3).unwrap();
        assert!((t - 11.0 / 8.0).abs() < 1e-12 && k == 2, "{t} {k}");
        // an axis with 1e-4 of the other's spread is not divided by: only x is tested
        let c = [[1.0, 0.0, 0.0], [0.0, 1e-4, 0.0], [0.0; 3]];
        let (t, k) = statistic(&c, &[1.0, 0.05, 0.0], 2).unwrap();
        assert!((t - 1.0).abs() < 1e-12 && k == 1, "{t} {k}");
        assert!(statistic(&[[0.0; 3]; 3], &[1.0, 0.0, 0.0], 2).is_none());
    }

    /// Windows of independent corrections whose covariance is what the filter says fail the
    /// test at the false-alarm rate; corrections that keep one direction fail every window.
    #[test]
    fn consistent_corrections_pass_and_persistent_ones_fail() {
        let test = CorrectionTest::new(1.0, 0.99, 100.0).unwrap();
        let mut draw = normals(7);
        let (mut window, mut failed, windows) = (CorrectionWindow::default(), 0, 4000);
        // 10 updates a second, each Δp ~ N(0, diag(0.04², 0.02²))
        for k in 0..=10 * windows {
            let correction = [0.04 * draw(), 0.02 * draw(), 0.0];
            let reduction = [[0.04f64.powi(2), 0.0, 0.0], [0.0, 0.02f64.powi(2), 0.0], [0.0; 3]];
            let time_s = 0.1 * f64::from(k) + 1e-9;
            if test
                .observe(&mut window, time_s, correction, reduction, 2)
                .unwrap()
                .is_some()
            {
                failed += 1;
            }
        }
        let rate = f64::from(failed) / f64::from(windows);
        assert!((0.003..0.02).contains(&rate), "false alarms {rate}");

        // the same noise plus a steady pull of 2 σ per update: g_x ≈ 0.8 m against √C_xx = 0.126 m,
        // T ≈ 40 ≫ 9.21
        let mut window = CorrectionWindow::default();
        let mut failed = 0;
        for k in 0..=10 * 100 {
            let correction = [0.04 * draw() + 0.08, 0.02 * draw(), 0.0];
            let reduction = [[0.04f64.powi(2), 0.0, 0.0], [0.0, 0.02f64.powi(2), 0.0], [0.0; 3]];
            if let Some(lambda) = test
                .observe(&mut window, 0.1 * f64::from(k) + 1e-9, correction, reduction, 2)
                .unwrap()
            {
                assert!(lambda > 1.0 && lambda <= 100.0);
                failed += 1;
            }
        }
        assert!(failed >= 95, "{failed} of 100 windows failed");
    }

    #[test]
    fn bad_settings_and_inputs_are_errors() {
        assert!(CorrectionTest::new(0.0, 0.99, 10.0).is_err());
        assert!(CorrectionTest::new(1.0, 1.0, 10.0).is_err());
        assert!(CorrectionTest::new(1.0, 0.99, 0.5).is_err());
        let test = CorrectionTest::new(1.0, 0.99, 10.0).unwrap();
        let mut window = CorrectionWindow::default();
        assert!(test
            .observe(&mut window, 0.0, [f64::NAN, 0.0, 0.0], [[0.0; 3]; 3], 2)
            .is_err());
        assert_eq!(window, CorrectionWindow::default());
        assert!(test.observe(&mut window, 0.0, [0.0; 3], [[0.0; 3]; 3], 4).is_err());
    }
}
