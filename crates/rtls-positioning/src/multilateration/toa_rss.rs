//! Joint TOA + RSS positioning (seed 001): ranges and received signal strengths stacked in
//! one weighted Gauss–Newton / Levenberg–Marquardt fix.

use core::fmt;

use nalgebra::SVector;

use super::linear::{resolve_reference, solve, ReferenceAnchor};
use super::solver::{finish, levenberg_marquardt, GaussNewtonFix, GaussNewtonOptions, Initial, Model, NormalEquations};
use super::validate::{self, unit_from};
use crate::error::{PositioningError, Result};
use crate::pathloss::PathLossModel;

/// A range (TOA × c, or a time-of-flight distance) to one anchor.
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::RangeObservation;
/// let toa = RangeObservation { anchor: 0, range_m: 12.3, variance_m2: 0.09 }; // σ = 0.3 m
/// assert_eq!(toa.anchor, 0);
/// ```
///
/// # References
/// Seed 001, TOA model `r = d + a`, `a ~ N(0, σ²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeObservation {
    /// Index of the anchor in the anchor table.
    pub anchor: usize,
    /// Measured range `r` (m, ≥ 0).
    pub range_m: f64,
    /// Range error variance `σ_r²` (m², > 0).
    pub variance_m2: f64,
}

/// A received signal strength from one anchor, with the path-loss law of that anchor.
///
/// The residual is `ρ − μ(‖p − a‖)` with variance `σ_X²` = the model's
/// [`PathLossModel::shadowing_std_db`] squared. Each observation carries its own model, so
/// anchors may differ (transmit power, antenna, calibrated exponent).
///
/// # Example
/// ```
/// use rtls_positioning::multilateration::RssObservation;
/// use rtls_positioning::pathloss::PathLossModel;
/// struct Free; // free space at 2.4 GHz: μ(d) = −40 − 20 lg d
/// impl PathLossModel for Free {
///     fn mean_rssi_dbm(&self, d: f64) -> f64 { -40.0 - 20.0 * d.log10() }
///     fn slope_db_per_m(&self, d: f64) -> f64 { -20.0 / (d * core::f64::consts::LN_10) }
///     fn shadowing_std_db(&self) -> f64 { 4.0 }
///     fn distance_m(&self, rssi: f64) -> rtls_positioning::Result<f64> { Ok(10f64.powf((-40.0 - rssi) / 20.0)) }
/// }
/// let rss = RssObservation { anchor: 2, rssi_dbm: -61.0, model: &Free };
/// assert_eq!(rss.anchor, 2);
/// ```
///
/// # References
/// Seed 001, RSS model `P = P0 + 10 n lg(d/d0) + θ`, `θ ~ N(0, σ_s²)`; seed 002 eq. (1).
#[derive(Clone, Copy)]
pub struct RssObservation<'a> {
    /// Index of the anchor in the anchor table.
    pub anchor: usize,
    /// Measured received power `ρ` (dBm).
    pub rssi_dbm: f64,
    /// The anchor's path-loss law `μ(d)` and shadowing `σ_X`.
    pub model: &'a dyn PathLossModel,
}

impl fmt::Debug for RssObservation<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RssObservation")
            .field("anchor", &self.anchor)
            .field("rssi_dbm", &self.rssi_dbm)
            .field("shadowing_std_db", &self.model.shadowing_std_db())
            .finish()
    }
}

/// Maximum-likelihood position from ranges and RSSI jointly (seed 001's `z = [z_TOA; z_RSS]`
/// as a single-epoch fix), in 2-D or 3-D.
///
/// Range observations `r_k` (variance `σ_k²`) and RSS observations `ρ_l` through the anchor's
/// path-loss law `μ_l` (variance `σ_X,l²`) are stacked; with `d = ‖p − a‖`, `u = (p − a)/d`:
/// ```text
/// e = [r_k − d_k(p);  ρ_l − μ_l(d_l(p))]             residuals
/// J = [u_kᵀ;  μ'_l(d_l) u_lᵀ]                          Jacobian (μ' = slope_db_per_m, dB/m)
/// W = diag(1/σ_k², 1/σ_X,l²)
/// minimise eᵀWe by Gauss–Newton / Levenberg–Marquardt (as super::gauss_newton)
/// P = (JᵀWJ)⁻¹ = (J_rᵀW_rJ_r + J_sᵀW_sJ_s)⁻¹         information adds: RSS never increases P
/// χ² = eᵀWe at the fix, dof = (#ranges + #rss) − D
/// ```
/// An anchor may contribute a range, an RSS, both, or several of either. The linear start
/// ([`Initial::Linear`]) uses one distance per anchor (its first range, else its first RSS
/// inverted through [`PathLossModel::distance_m`] with variance `(σ_X/μ'(d))²`,
/// [`PathLossModel::range_std_m`]) and needs
/// `D + 1` such anchors spanning the space; with a guess ([`Initial::Guess`]) `D` anchors
/// suffice (seed 001 has two base stations in the plane: the guess picks the side of their
/// line). GDOP is over the anchors that contribute.
///
/// # Units
/// Anchors and ranges in m, variances in m², RSSI in dBm, `σ_X` in dB, the fix in m and m².
///
/// # Errors
/// - [`PositioningError::Underdetermined`] for fewer than `D + 1` (`D` with a guess) anchors
///   with an observation;
/// - [`PositioningError::InvalidParameter`] (`ranges` / `rss`) for an anchor index out of
///   range, a negative range, a variance `≤ 0`, a model with `σ_X` not finite and positive;
///   (options) for invalid options;
/// - [`PositioningError::NonFiniteEntry`] for a NaN/∞ anchor coordinate or observation
///   (row = observation; column 0 = range/RSSI, 1 = variance);
///   [`PositioningError::NonFinite`] for a NaN/∞ guess or path-loss model output;
/// - [`PositioningError::DuplicateAnchors`], [`PositioningError::DegenerateGeometry`] and
///   [`PositioningError::DidNotConverge`] as [`super::gauss_newton`]; also
///   [`PositioningError::DegenerateGeometry`] when the linear start inverts an RSSI where the
///   law is flat.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::multilateration::{toa_rss, GaussNewtonOptions, Initial, RangeObservation, RssObservation};
/// use rtls_positioning::pathloss::PathLossModel;
/// /// log-distance law μ(d) = −45 − 20 lg d (dBm), σ_X = 2 dB
/// struct Uwb;
/// impl PathLossModel for Uwb {
///     fn mean_rssi_dbm(&self, d: f64) -> f64 { -45.0 - 20.0 * d.log10() }
///     fn slope_db_per_m(&self, d: f64) -> f64 { -20.0 / (d * core::f64::consts::LN_10) }
///     fn shadowing_std_db(&self) -> f64 { 2.0 }
///     fn distance_m(&self, rssi: f64) -> rtls_positioning::Result<f64> { Ok(10f64.powf((-45.0 - rssi) / 20.0)) }
/// }
/// // seed 001: base stations at (2, 2) and (20, 40), tag at (5, 12)
/// let anchors = [[2.0, 2.0], [20.0, 40.0]];
/// let truth = Vector2::new(5.0, 12.0);
/// let d: Vec<f64> = anchors.iter().map(|a| (truth - Vector2::from(*a)).norm()).collect();
/// let ranges = [0, 1].map(|i| RangeObservation { anchor: i, range_m: d[i], variance_m2: 0.09 });
/// let rss = [0, 1].map(|i| RssObservation { anchor: i, rssi_dbm: Uwb.mean_rssi_dbm(d[i]), model: &Uwb });
/// let guess = Initial::Guess(Vector2::new(4.0, 13.0)); // the UKF's prediction
/// let joint = toa_rss(&anchors, &ranges, &rss, guess, &GaussNewtonOptions::default())?;
/// let toa_only = toa_rss(&anchors, &ranges, &[], guess, &GaussNewtonOptions::default())?;
/// assert!((joint.fix.position - truth).norm() < 1e-9);
/// assert!(joint.fix.drms_m() < toa_only.fix.drms_m());
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 001 (joint measurement `z = [z_TOA; z_RSS]`, TOA `r = d + a`, RSS path loss with
/// shadowing `θ`); A. Catovic, Z. Sahinoglu, "The Cramér–Rao bounds of hybrid TOA/RSS and
/// TDOA/RSS location estimation schemes", *IEEE Commun. Letters* 8(10), 2004 (the stacked
/// Fisher information); Foy (1976) and Torrieri (1984) as in [`super::gauss_newton`].
pub fn toa_rss<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges: &[RangeObservation],
    rss: &[RssObservation<'_>],
    initial: Initial<D>,
    options: &GaussNewtonOptions,
) -> Result<GaussNewtonFix<D>> {
    options.validate()?;
    let scale = validate::anchors(anchors_m, 0, false)?;
    let n = anchors_m.len();
    let weights_rss = validate_observations(n, ranges, rss)?;
    // anchors that contribute at least one observation
    let mut used = vec![false; n];
    for anchor in ranges.iter().map(|o| o.anchor).chain(rss.iter().map(|o| o.anchor)) {
        used[anchor] = true;
    }
    let contributing = used.iter().filter(|&&u| u).count();
    let start = match initial {
        Initial::Linear => linear_start(anchors_m, ranges, rss, &used)?,
        Initial::Guess(p) => {
            if contributing < D {
                return Err(PositioningError::Underdetermined {
                    anchors: contributing,
                    needed: D,
                });
            }
            validate::finite_point(&p, "initial position")?;
            p
        }
    };
    let model = Joint {
        anchors_m,
        ranges,
        rss,
        weights_rss,
        floor_m: scale.coincidence_m,
    };
    let minimum = levenberg_marquardt(&model, start, options.relative_tolerance * scale.spread_m, options)?;
    let anchors_used = anchors_m.iter().zip(&used).filter(|(_, &u)| u).map(|(a, _)| a);
    finish(&minimum, anchors_used, ranges.len() + rss.len(), scale.coincidence_m)
}

/// Checks the observations; returns the RSS weights `1/σ_X²`.
fn validate_observations(n: usize, ranges: &[RangeObservation], rss: &[RssObservation<'_>]) -> Result<Vec<f64>> {
    const RANGES_WHAT: &str = "range observations (row = observation, column 0 = range, 1 = variance)";
    const RSS_WHAT: &str = "rss observations (row = observation, column 0 = rssi)";
    let bad_index = |name| PositioningError::InvalidParameter {
        name,
        reason: "an observation's anchor index must be below the number of anchors",
    };
    for (row, o) in ranges.iter().enumerate() {
        if o.anchor >= n {
            return Err(bad_index("ranges"));
        }
        if let Some(column) = [o.range_m, o.variance_m2].iter().position(|v| !v.is_finite()) {
            return Err(PositioningError::NonFiniteEntry {
                what: RANGES_WHAT,
                row,
                column,
            });
        }
        if o.range_m < 0.0 || o.variance_m2 <= 0.0 {
            return Err(PositioningError::InvalidParameter {
                name: "ranges",
                reason: "ranges must be non-negative and variances strictly positive",
            });
        }
    }
    rss.iter()
        .enumerate()
        .map(|(row, o)| {
            if o.anchor >= n {
                return Err(bad_index("rss"));
            }
            if !o.rssi_dbm.is_finite() {
                return Err(PositioningError::NonFiniteEntry {
                    what: RSS_WHAT,
                    row,
                    column: 0,
                });
            }
            let sigma_db = o.model.shadowing_std_db();
            if !(sigma_db.is_finite() && sigma_db > 0.0) {
                return Err(PositioningError::InvalidParameter {
                    name: "rss",
                    reason: "a path-loss model's shadowing standard deviation must be finite and positive",
                });
            }
            // w = 1/σ_X²
            Ok(1.0 / (sigma_db * sigma_db))
        })
        .collect()
}

/// Weighted linear LS over one distance per contributing anchor: its first range, else its
/// first RSS inverted, `d = μ⁻¹(ρ)`, `var d ≈ (σ_X / μ'(d))²`.
fn linear_start<const D: usize>(
    anchors_m: &[[f64; D]],
    ranges: &[RangeObservation],
    rss: &[RssObservation<'_>],
    used: &[bool],
) -> Result<SVector<f64, D>> {
    let mut sub_anchors = Vec::new();
    let mut distances_m = Vec::new();
    let mut variances_m2 = Vec::new();
    for (anchor, _) in used.iter().enumerate().filter(|(_, &u)| u) {
        let (distance_m, variance_m2) = match ranges.iter().find(|o| o.anchor == anchor) {
            Some(o) => (o.range_m, o.variance_m2),
            None => {
                let Some(o) = rss.iter().find(|o| o.anchor == anchor) else {
                    continue;
                };
                // d = μ⁻¹(ρ),  σ_d = σ_X / |μ'(d)|  (delta method)
                let d = o.model.distance_m(o.rssi_dbm)?;
                let sigma = o.model.range_std_m(d)?;
                (d, sigma * sigma)
            }
        };
        if !(distance_m.is_finite() && distance_m >= 0.0 && variance_m2.is_finite() && variance_m2 > 0.0) {
            return Err(PositioningError::NonFinite {
                what: "rss-derived distance or its variance (path-loss model inversion)",
            });
        }
        sub_anchors.push(anchors_m[anchor]);
        distances_m.push(distance_m);
        variances_m2.push(variance_m2);
    }
    validate::anchors(&sub_anchors, D + 1, true)?;
    let reference = resolve_reference(ReferenceAnchor::NearestRange, &distances_m)?;
    Ok(solve(&sub_anchors, &distances_m, Some(&variances_m2), reference)?.0)
}

/// The stacked TOA + RSS cost on validated inputs.
struct Joint<'a, 'm, const D: usize> {
    anchors_m: &'a [[f64; D]],
    ranges: &'a [RangeObservation],
    rss: &'a [RssObservation<'m>],
    /// `1/σ_X²` per RSS observation.
    weights_rss: Vec<f64>,
    floor_m: f64,
}

impl<const D: usize> Model<D> for Joint<'_, '_, D> {
    fn normal_equations(&self, p: &SVector<f64, D>) -> Result<NormalEquations<D>> {
        let mut normal = NormalEquations::zero();
        for o in self.ranges {
            // e = r − d,  J = uᵀ,  w = 1/σ_r²
            let (u, d) = unit_from(p, &self.anchors_m[o.anchor], self.floor_m)?;
            normal.add(o.range_m - d, &u, 1.0 / o.variance_m2);
        }
        for (o, &weight) in self.rss.iter().zip(&self.weights_rss) {
            let (u, d) = unit_from(p, &self.anchors_m[o.anchor], self.floor_m)?;
            // μ(d), μ'(d)
            let mean_dbm = o.model.mean_rssi_dbm(d);
            let slope_db_per_m = o.model.slope_db_per_m(d);
            if !(mean_dbm.is_finite() && slope_db_per_m.is_finite()) {
                return Err(PositioningError::NonFinite {
                    what: "path-loss model output (mean rssi or slope)",
                });
            }
            // e = ρ − μ(d),  J = μ'(d) uᵀ,  w = 1/σ_X²
            normal.add(o.rssi_dbm - mean_dbm, &(u * slope_db_per_m), weight);
        }
        Ok(normal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pathloss::LogDistance;
    use nalgebra::{Vector2, Vector3};

    /// The crate's log-distance law: −40 dBm at 1 m, η = 2.2, σ_X = 3 dB.
    fn model() -> LogDistance {
        LogDistance::new(-40.0, 2.2, 1.0, 3.0).unwrap()
    }

    fn observations<'m, const D: usize>(
        anchors: &[[f64; D]],
        truth: &SVector<f64, D>,
        model: &'m dyn PathLossModel,
    ) -> (Vec<RangeObservation>, Vec<RssObservation<'m>>) {
        let d: Vec<f64> = anchors.iter().map(|a| (truth - SVector::from(*a)).norm()).collect();
        let ranges = (0..anchors.len())
            .map(|i| RangeObservation {
                anchor: i,
                range_m: d[i],
                variance_m2: 0.25,
            })
            .collect();
        let rss = (0..anchors.len())
            .map(|i| RssObservation {
                anchor: i,
                rssi_dbm: model.mean_rssi_dbm(d[i]),
                model,
            })
            .collect();
        (ranges, rss)
    }

    #[test]
    fn rss_only_and_mixed_anchor_sets_recover_the_truth() {
        let anchors = [[0.0, 0.0, 0.0], [20.0, 0.0, 1.0], [0.0, 20.0, 2.0], [10.0, 10.0, 6.0]];
        let truth = Vector3::new(7.0, 11.0, 1.2);
        let model = model();
        let (ranges, rss) = observations(&anchors, &truth, &model);
        let options = GaussNewtonOptions::default();
        // RSS only
        let s = toa_rss(&anchors, &[], &rss, Initial::Linear, &options).unwrap();
        assert!((s.fix.position - truth).norm() < 1e-8);
        assert_eq!(s.degrees_of_freedom, 1);
        // ranges from anchors 0, 1, RSS from 2, 3 (the linear start mixes both)
        let s = toa_rss(&anchors, &ranges[..2], &rss[2..], Initial::Linear, &options).unwrap();
        assert!((s.fix.position - truth).norm() < 1e-8);
        // everything: 8 measurements
        let s = toa_rss(&anchors, &ranges, &rss, Initial::Linear, &options).unwrap();
        assert!((s.fix.position - truth).norm() < 1e-8);
        assert_eq!(s.degrees_of_freedom, 5);
    }

    #[test]
    fn adding_rss_never_increases_the_covariance() {
        let anchors = [[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [25.0, 18.0]];
        let options = GaussNewtonOptions::default();
        for truth in [
            Vector2::new(5.0, 5.0),
            Vector2::new(12.0, 3.0),
            Vector2::new(30.0, 30.0),
        ] {
            let model = model();
            let (ranges, rss) = observations(&anchors, &truth, &model);
            let toa = toa_rss(&anchors, &ranges, &[], Initial::Linear, &options).unwrap();
            let joint = toa_rss(&anchors, &ranges, &rss, Initial::Linear, &options).unwrap();
            // P_toa − P_joint is positive semi-definite
            let difference = toa.fix.covariance - joint.fix.covariance;
            let eigen = difference.symmetric_eigenvalues();
            assert!(eigen.min() >= -1e-12 * toa.fix.covariance.amax(), "{eigen}");
            assert!(joint.fix.drms_m() < toa.fix.drms_m());
        }
    }

    #[test]
    fn errors() {
        let anchors = [[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]];
        let truth = Vector2::new(5.0, 5.0);
        let model = model();
        let (ranges, rss) = observations(&anchors, &truth, &model);
        let options = GaussNewtonOptions::default();
        let mut bad = ranges.clone();
        bad[1].anchor = 3;
        assert!(matches!(
            toa_rss(&anchors, &bad, &rss, Initial::Linear, &options),
            Err(PositioningError::InvalidParameter { name: "ranges", .. })
        ));
        let mut bad = ranges.clone();
        bad[2].variance_m2 = f64::NAN;
        assert!(matches!(
            toa_rss(&anchors, &bad, &rss, Initial::Linear, &options),
            Err(PositioningError::NonFiniteEntry { row: 2, column: 1, .. })
        ));
        let mut bad = ranges.clone();
        bad[0].range_m = -1.0;
        assert!(matches!(
            toa_rss(&anchors, &bad, &rss, Initial::Linear, &options),
            Err(PositioningError::InvalidParameter { name: "ranges", .. })
        ));
        let mut bad = rss.clone();
        bad[0].rssi_dbm = f64::NEG_INFINITY;
        assert!(matches!(
            toa_rss(&anchors, &ranges, &bad, Initial::Linear, &options),
            Err(PositioningError::NonFiniteEntry { row: 0, column: 0, .. })
        ));
        let silent = LogDistance::new(-40.0, 2.2, 1.0, 0.0).unwrap();
        let mut bad = rss.clone();
        bad[1].model = &silent;
        assert!(matches!(
            toa_rss(&anchors, &ranges, &bad, Initial::Linear, &options),
            Err(PositioningError::InvalidParameter { name: "rss", .. })
        ));
        let mut bad = rss.clone();
        bad[1].anchor = 7;
        assert!(matches!(
            toa_rss(&anchors, &ranges, &bad, Initial::Linear, &options),
            Err(PositioningError::InvalidParameter { name: "rss", .. })
        ));
        // two contributing anchors: linear start impossible, a guess is fine
        assert_eq!(
            toa_rss(&anchors, &ranges[..2], &rss[..2], Initial::Linear, &options).unwrap_err(),
            PositioningError::Underdetermined { anchors: 2, needed: 3 }
        );
        assert_eq!(
            toa_rss(&anchors, &ranges[..1], &rss[..1], Initial::Guess(truth), &options).unwrap_err(),
            PositioningError::Underdetermined { anchors: 1, needed: 2 }
        );
        assert!(toa_rss(
            &anchors,
            &ranges[..2],
            &rss[..2],
            Initial::Guess(Vector2::new(4.0, 6.0)),
            &options
        )
        .is_ok());
        assert!(matches!(
            toa_rss(
                &[[0.0, 0.0], [10.0, 10.0], [20.0, 20.0]],
                &ranges,
                &rss,
                Initial::Linear,
                &options
            ),
            Err(PositioningError::DegenerateGeometry { .. })
        ));
        assert_eq!(
            toa_rss(
                &[[0.0, 0.0], [10.0, 10.0], [0.0, 0.0]],
                &ranges,
                &rss,
                Initial::Linear,
                &options
            )
            .unwrap_err(),
            PositioningError::DuplicateAnchors { first: 0, second: 2 }
        );
        // a model that returns NaN
        struct Broken;
        impl PathLossModel for Broken {
            fn mean_rssi_dbm(&self, _: f64) -> f64 {
                f64::NAN
            }
            fn slope_db_per_m(&self, _: f64) -> f64 {
                -1.0
            }
            fn shadowing_std_db(&self) -> f64 {
                1.0
            }
            fn distance_m(&self, _: f64) -> Result<f64> {
                Ok(5.0)
            }
        }
        let broken = [RssObservation {
            anchor: 0,
            rssi_dbm: -50.0,
            model: &Broken,
        }];
        assert!(matches!(
            toa_rss(&anchors, &ranges, &broken, Initial::Linear, &options),
            Err(PositioningError::NonFinite { .. })
        ));
        let _ = format!("{:?}", broken[0]);
    }
}
