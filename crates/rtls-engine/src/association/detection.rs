//! Anonymous detections (position fixes and ranges from known nodes), their measurement models,
//! and the allocation-free pair score `(d², ln |S|)` used for gating and costs.

use nalgebra::DVector;
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, Updated};
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance, Ranges};
use rtls_estimation::Gaussian;

use super::field_of_view::FieldOfView;
use crate::error::{EngineError, Result};

/// Below this track–node distance (m) the range Jacobian is undefined (as in
/// [`Ranges`]).
const MIN_RANGE_DISTANCE_M: f64 = 1e-9;

/// What an anonymous detection measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DetectionKind {
    /// A 2-D position fix `z = [x, y]` with covariance `R` (m²): `z = H x + v`, `H` picks the
    /// positions of `[x, vx, y, vy]`.
    Fix {
        /// `[x, y]`, m.
        position_m: [f64; 2],
        /// `R`, m², symmetric positive definite.
        covariance_m2: [[f64; 2]; 2],
    },
    /// A range from a node at a known position: `r = ‖p − a‖ + v`, `v ~ N(0, σ²)`, Jacobian
    /// `H = [(x − aₓ)/d, 0, (y − a_y)/d, 0]` (seed 003 eq. (8)).
    Range {
        /// Node position `a = [aₓ, a_y]`, m.
        node_m: [f64; 2],
        /// `r`, m (≥ 0).
        range_m: f64,
        /// `σ²`, m² (> 0).
        variance_m2: f64,
    },
}

/// One detection of an unknown target, checked at construction.
///
/// # Example
/// ```
/// use rtls_engine::association::Detection;
/// let fix = Detection::fix([1.0, 2.0], [[0.01, 0.0], [0.0, 0.01]])?;
/// assert_eq!(fix.dim(), 2);
/// let echo = Detection::range([0.0, 0.0], 1.5, 0.0004)?; // σ = 2 cm, seed 003's sonar
/// assert_eq!(echo.dim(), 1);
/// assert!(Detection::range([0.0, 0.0], -1.0, 0.0004).is_err());
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    kind: DetectionKind,
    /// The sector a range was measured in ([`Detection::within`]); `None`: all around.
    view: Option<FieldOfView>,
}

impl Detection {
    /// A position fix `[x, y]` (m) with covariance `covariance_m2` (m²).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `position_m` for a non-finite coordinate, or
    /// `covariance_m2` for a non-finite, asymmetric (beyond `1e-12` relative) or not positive
    /// definite covariance.
    pub fn fix(position_m: [f64; 2], covariance_m2: [[f64; 2]; 2]) -> Result<Self> {
        if position_m.iter().any(|c| !c.is_finite()) {
            return Err(EngineError::InvalidParameter {
                name: "position_m",
                reason: "a fix coordinate must be finite",
            });
        }
        let [[a, b], [c, d]] = covariance_m2;
        let scale = a.abs().max(b.abs()).max(c.abs()).max(d.abs());
        let bad = |reason| {
            Err(EngineError::InvalidParameter {
                name: "covariance_m2",
                reason,
            })
        };
        if ![a, b, c, d].iter().all(|v| v.is_finite()) {
            return bad("the fix covariance must be finite");
        }
        if (b - c).abs() > 1e-12 * scale {
            return bad("the fix covariance must be symmetric");
        }
        // positive definite ⇔ a > 0 and det > 0
        if !(a > 0.0 && a * d - b * c > 0.0) {
            return bad("the fix covariance must be positive definite");
        }
        let off = 0.5 * (b + c);
        Ok(Self {
            kind: DetectionKind::Fix {
                position_m,
                covariance_m2: [[a, off], [off, d]],
            },
            view: None,
        })
    }

    /// A range `range_m` (m) from a node at `node_m` (m) with variance `variance_m2` (m²).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming `node_m` for a non-finite coordinate,
    /// `range_m` for a negative or non-finite range, `variance_m2` unless finite and > 0.
    pub fn range(node_m: [f64; 2], range_m: f64, variance_m2: f64) -> Result<Self> {
        if node_m.iter().any(|c| !c.is_finite()) {
            return Err(EngineError::InvalidParameter {
                name: "node_m",
                reason: "a node coordinate must be finite",
            });
        }
        if !(range_m.is_finite() && range_m >= 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "range_m",
                reason: "a range must be finite and ≥ 0",
            });
        }
        if !(variance_m2.is_finite() && variance_m2 > 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "variance_m2",
                reason: "the range variance must be finite and > 0",
            });
        }
        Ok(Self {
            kind: DetectionKind::Range {
                node_m,
                range_m,
                variance_m2,
            },
            view: None,
        })
    }

    /// This range, measured by a directional sensor whose sector is `view` (apex at the node):
    /// only tracks whose prediction lies in the view are candidates for it (see
    /// [`FieldOfView`]).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`view`) for a fix: a field of view belongs to a
    /// ranging sensor.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::association::{Detection, FieldOfView};
    /// let view = FieldOfView::new(0.0, 0.5, 3.0)?;
    /// assert!(Detection::range([0.0, 0.0], 1.0, 0.0009)?.within(view).is_ok());
    /// assert!(Detection::fix([1.0, 0.0], [[0.01, 0.0], [0.0, 0.01]])?.within(view).is_err());
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn within(self, view: FieldOfView) -> Result<Self> {
        match self.kind {
            DetectionKind::Range { .. } => Ok(Self {
                view: Some(view),
                ..self
            }),
            DetectionKind::Fix { .. } => Err(EngineError::InvalidParameter {
                name: "view",
                reason: "only a range has a field of view (its apex is the node)",
            }),
        }
    }

    /// The field of view of a range from a directional sensor, if given.
    #[must_use]
    pub fn field_of_view(&self) -> Option<&FieldOfView> {
        self.view.as_ref()
    }

    /// Whether `prior` can have made this detection as far as its field of view goes (always,
    /// without one): its predicted position inside the sector and its predicted range not
    /// surely beyond the maximum range (`d̂ − 3 √S ≤ r_max`, [`FieldOfView`]). `None` where the
    /// range's `S` is undefined (the track on the node).
    pub(crate) fn in_view(&self, prior: &Gaussian<4>) -> Option<bool> {
        let (Some(view), DetectionKind::Range { node_m, .. }) = (&self.view, &self.kind) else {
            return Some(true);
        };
        let x = prior.mean();
        if !view.contains_bearing(*node_m, [x[0], x[2]]) {
            return Some(false);
        }
        let (predicted_m, s) = self.range_terms(prior)?;
        Some(view.within_range(predicted_m, s))
    }

    /// `|ν| = |r − d̂|` (m) and `S` (m²) of a range detection against `prior`; `None` for a fix
    /// or where `S` is undefined.
    pub(crate) fn range_innovation(&self, prior: &Gaussian<4>) -> Option<(f64, f64)> {
        let DetectionKind::Range { range_m, .. } = self.kind else {
            return None;
        };
        let (predicted_m, s) = self.range_terms(prior)?;
        Some(((range_m - predicted_m).abs(), s))
    }

    /// The predicted range `d̂ = ‖p − a‖` (m) of a range detection against `prior` and its
    /// innovation variance `S = uᵀ P_pos u + σ²` (m²); `None` for a fix or where `S` is
    /// undefined (a track on the node).
    pub(crate) fn range_terms(&self, prior: &Gaussian<4>) -> Option<(f64, f64)> {
        let DetectionKind::Range {
            node_m, variance_m2, ..
        } = self.kind
        else {
            return None;
        };
        let x = prior.mean();
        let p = prior.covariance();
        // δ = p − a, d = ‖δ‖
        let delta = [x[0] - node_m[0], x[2] - node_m[1]];
        let d = delta[0].hypot(delta[1]);
        if d.is_nan() || d < MIN_RANGE_DISTANCE_M {
            return None;
        }
        // u = δ / d  (H = [uₓ, 0, u_y, 0])
        let u = [delta[0] / d, delta[1] / d];
        // S = uᵀ P_pos u + σ²
        let s = u[0] * u[0] * p[(0, 0)] + 2.0 * u[0] * u[1] * p[(0, 2)] + u[1] * u[1] * p[(2, 2)] + variance_m2;
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        Some((d, s))
    }

    /// What was measured.
    #[must_use]
    pub fn kind(&self) -> &DetectionKind {
        &self.kind
    }

    /// Number of measurement components `m` (2 for a fix, 1 for a range).
    #[must_use]
    pub fn dim(&self) -> usize {
        match self.kind {
            DetectionKind::Fix { .. } => 2,
            DetectionKind::Range { .. } => 1,
        }
    }

    /// Whether this is a position fix (only fixes start tracks).
    #[must_use]
    pub fn is_fix(&self) -> bool {
        matches!(self.kind, DetectionKind::Fix { .. })
    }

    /// `d² = νᵀ S⁻¹ ν` and `ln |S|` of this detection against the predicted state `prior`
    /// (`[x, vx, y, vy]`), without allocating; `None` where `S` is undefined or singular (a
    /// track sitting on the node of a range). Equal to the NIS and `ln |S|` of the KF / EKF
    /// update ([`Detection::update`]).
    ///
    /// ```text
    /// fix:    ν = z − [x, y]ᵀ,       S = P_pos + R                    (2 × 2)
    /// range:  ν = r − d,             d = ‖p − a‖,  u = (p − a)/d,  S = uᵀ P_pos u + σ²
    /// ```
    #[must_use]
    pub(crate) fn score(&self, prior: &Gaussian<4>) -> Option<PairScore> {
        let x = prior.mean();
        let p = prior.covariance();
        match self.kind {
            DetectionKind::Fix {
                position_m,
                covariance_m2: r,
            } => {
                // ν = z − H x⁻
                let nu = [position_m[0] - x[0], position_m[1] - x[2]];
                // S = H P⁻ Hᵀ + R
                let s00 = p[(0, 0)] + r[0][0];
                let s01 = p[(0, 2)] + r[0][1];
                let s11 = p[(2, 2)] + r[1][1];
                let det = s00 * s11 - s01 * s01;
                if !(det > 0.0 && s00 > 0.0) {
                    return None;
                }
                // d² = νᵀ S⁻¹ ν with S⁻¹ = [[s11, −s01], [−s01, s00]] / |S|
                let nis = (s11 * nu[0] * nu[0] - 2.0 * s01 * nu[0] * nu[1] + s00 * nu[1] * nu[1]) / det;
                Some(PairScore {
                    nis,
                    log_det_s: det.ln(),
                })
            }
            DetectionKind::Range { range_m, .. } => {
                // d = ‖p − a‖, S = uᵀ P_pos u + σ²
                let (d, s) = self.range_terms(prior)?;
                // ν = r − d
                let nu = range_m - d;
                Some(PairScore {
                    nis: nu * nu / s,
                    log_det_s: s.ln(),
                })
            }
        }
    }

    /// The Kalman update of `prior` with this detection: the linear KF for a fix, the EKF for
    /// a range (rtls-estimation's filters, Joseph form).
    ///
    /// # Errors
    /// [`EngineError::Estimation`] when the filter fails (singular geometry, `S` not positive
    /// definite, non-finite result).
    pub(crate) fn update(&self, prior: &Gaussian<4>) -> Result<Updated<4>> {
        match self.kind {
            DetectionKind::Fix {
                position_m,
                covariance_m2: r,
            } => {
                let noise = if r[0][1] == 0.0 {
                    NoiseCovariance::diagonal(&[r[0][0], r[1][1]])?
                } else {
                    NoiseCovariance::full(nalgebra::DMatrix::from_row_slice(
                        2,
                        2,
                        &[r[0][0], r[0][1], r[1][0], r[1][1]],
                    ))?
                };
                let model = ComponentSelection::<4>::position(2, noise)?;
                let z = DVector::from_column_slice(&position_m);
                Ok(KalmanFilter::default().update(prior, &model, &z)?)
            }
            DetectionKind::Range {
                node_m,
                range_m,
                variance_m2,
            } => {
                let model = Ranges::planar(&[node_m], NoiseCovariance::isotropic(1, variance_m2)?)?;
                let z = DVector::from_element(1, range_m);
                Ok(ExtendedKalmanFilter::default().update(prior, &model, &z)?)
            }
        }
    }

    /// The interval of track x coordinates (m) that can pass the gate `γ` of this detection,
    /// given a bound `track_half_width_m` on the track's own contribution (see
    /// [`track_half_width_m`]).
    ///
    /// ```text
    /// fix:    |x_t − zₓ| ≤ √(γ Sₓₓ) ≤ √(γ P_xx) + √(γ Rₓₓ)
    /// range:  |x_t − aₓ| ≤ d ≤ r + √(γ S) ≤ r + √(γ (P_xx + P_yy)) + √γ σ
    /// ```
    /// A range's window also holds every track within `margin_m` of it, `|ν| = |r − d| ≤ m`
    /// (`|x_t − aₓ| ≤ d ≤ r + m`: the candidates of the manoeuvre fallback; 0 when it is off).
    pub(crate) fn x_window(&self, gate: f64, track_half_width_m: f64, margin_m: f64) -> (f64, f64) {
        let (center, own) = match self.kind {
            DetectionKind::Fix {
                position_m,
                covariance_m2,
            } => (position_m[0], (gate * covariance_m2[0][0]).sqrt()),
            DetectionKind::Range {
                node_m,
                range_m,
                variance_m2,
            } => (node_m[0], range_m + (gate * variance_m2).sqrt()),
        };
        let mut half = own + track_half_width_m;
        if let DetectionKind::Range { range_m, .. } = self.kind {
            half = half.max(range_m + margin_m);
        }
        (center - half, center + half)
    }
}

/// The track's share of a detection's x window for gate `γ` (the larger of the fix and range
/// bounds of [`Detection::x_window`]): `√(γ (P_xx + P_yy))`.
pub(crate) fn track_half_width_m(state: &Gaussian<4>, gate: f64) -> f64 {
    let p = state.covariance();
    (gate * (p[(0, 0)] + p[(2, 2)])).sqrt()
}

/// `d²` and `ln |S|` of a detection–track pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PairScore {
    /// `d² = νᵀ S⁻¹ ν`.
    pub(crate) nis: f64,
    /// `ln |S|`.
    pub(crate) log_det_s: f64,
}

impl PairScore {
    /// The GNN cost `d² + ln |S|` (`−2 ln N(ν; 0, S) − m ln 2π`).
    pub(crate) fn cost(&self) -> f64 {
        self.nis + self.log_det_s
    }

    /// `ln N(ν; 0, S) = −½ (d² + ln |S| + m ln 2π)`.
    pub(crate) fn log_likelihood(&self, dim: usize) -> f64 {
        -0.5 * (self.nis + self.log_det_s + dim as f64 * std::f64::consts::TAU.ln())
    }
}
