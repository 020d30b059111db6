//! Readers' measurement biases (a UWB anchor's range offset from antenna delays and the tag's,
//! an RSSI offset) as slowly varying states a track estimates from its own innovations:
//! self-calibration without a survey.
//!
//! # Model
//! A reading of reader `i` is `zᵢ = hᵢ(p) + bᵢ + vᵢ`, `vᵢ ~ N(0, σᵢ²)`, each bias a random walk
//! from a zero-mean prior, all of a track's biases one vector `b` with covariance `P_b`:
//!
//! ```text
//! b₀ ~ N(0, σ_b² I),   bₖ = bₖ₋₁ + wₖ,   wₖ ~ N(0, q Δt I)      (q: random-walk density², unit²/s)
//! ```
//!
//! # Equations
//! The track's filter takes each reading bias-corrected, with the bias's uncertainty as extra
//! noise (`z' = z − b̂ᵢ`, `R' = R + P_bᵢᵢ`), so it is never more confident than the biases
//! allow. The biases learn from the readings of several readers taken together (an epoch, or a
//! round of a round robin), from the part of their innovations no change of the position can
//! explain. The innovations against the track's prediction are `ν = G δ + (b − b̂) + v`, `δ`
//! the prediction's position error, `G` (`n × d`) the readings' gradients `∂hᵢ/∂p`. Learning
//! from `ν` itself lets biases and position trade errors along `G` for ever (the filter drifts
//! along that null space); the weighted projection onto the complement of `G` removes every
//! position error:
//!
//! ```text
//! W = Σ⁻¹,   M = I − G (Gᵀ W G)⁻¹ Gᵀ W,   y = M ν = M (b − b̂) + M v
//! ```
//!
//! a linear measurement of the bias vector (rank `n − d`), taken by a Kalman step with the
//! pseudo-inverse of its singular innovation covariance:
//!
//! ```text
//! S = M (P_b + Σ) Mᵀ,   K = P_b Mᵀ S⁺,   b̂ ← b̂ + K y,   P_b ← P_b − K S Kᵀ
//! ```
//!
//! (`P_b` and `M` embedded in the track's whole bias vector, so biases of readers not in the
//! set move through their covariance with those that are). As the tag moves, `G` turns and
//! every bias, a part common to all readers included, becomes observable; a tag that stays
//! put learns only what its geometry shows. Each value is bounded by `b_max`.
//!
//! # Units
//! Whatever the measurement's: metres for a range, dB for an RSSI.
//!
//! # Example
//! ```
//! use rtls_estimation::bias::{BiasModel, BiasObservation, BiasVector};
//!
//! // four readers on a 10 m square; the tag circles inside; biases the site does not know
//! let readers = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
//! let truth = [0.3, 0.1, -0.2, 0.25];
//! let model = BiasModel::new(0.5, 0.0, 2.0)?;
//! let mut biases = BiasVector::default();
//! let slots: Vec<usize> = (0..4).map(|_| model.add_reader(&mut biases)).collect();
//! for k in 0..200 {
//!     let angle = f64::from(k) * 0.1;
//!     let p = [5.0 + 3.0 * angle.cos(), 5.0 + 3.0 * angle.sin()];
//!     let observations: Vec<BiasObservation> = readers.iter().zip(truth).zip(&slots).map(|((a, b), &slot)| {
//!         let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
//!         let gradient = [(p[0] - a[0]) / d, (p[1] - a[1]) / d, 0.0];
//!         // the prediction is 0.1 m off in x: ν = b − b̂ − gₓ·0.1
//!         BiasObservation { innovation: b - biases.value(slot) - 0.1 * gradient[0], variance: 0.01, noise_variance: 0.01, gradient }
//!     }).collect();
//!     biases = model.update_observable(&biases, &slots, &observations, 2)?;
//! }
//! for (&slot, b) in slots.iter().zip(truth) {
//!     assert!((biases.value(slot) - b).abs() < 0.02);
//! }
//! # Ok::<(), rtls_estimation::EstimationError>(())
//! ```
//!
//! # References
//! B. Friedland, "Treatment of bias in recursive filtering", IEEE TAC 14(4), 1969 (bias states
//! beside the state); Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to
//! Tracking and Navigation* (2001), §11.2 (sensor bias estimation); the projection is the
//! parity space of fault detection (Potter & Suman 1977).

use alloc::vec::Vec;
use nalgebra::{DMatrix, DVector};

use crate::error::{EstimationError, Result};
use crate::stats::chi_square_quantile;

/// The biases' process: a default prior, random walk and bound. An immutable strategy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasModel {
    prior: BiasPrior,
    random_walk_per_sqrt_s: f64,
}

/// One reader's bias prior `N(0, σ_b²)` and bound `b_max`: readers of different kinds (a UWB
/// anchor's antenna delay of decimetres, a Wi-Fi responder's offset of metres) or of
/// different calibration (a reader whose delay was measured) need different ones.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BiasPrior {
    std: f64,
    max_abs: f64,
}

impl BiasPrior {
    /// A prior of standard deviation `σ_b` (> 0) and bound `b_max` (> 0), unit of the reading.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a value that is not finite and > 0.
    pub fn new(std: f64, max_abs: f64) -> Result<Self> {
        let invalid = |name, reason| Err(EstimationError::InvalidParameter { name, reason });
        if !(std.is_finite() && std > 0.0) {
            return invalid("prior_std", "must be finite and > 0");
        }
        if !(max_abs.is_finite() && max_abs > 0.0) {
            return invalid("max_abs", "must be finite and > 0");
        }
        Ok(Self { std, max_abs })
    }

    /// `σ_b`.
    #[must_use]
    pub fn std(&self) -> f64 {
        self.std
    }

    /// `σ_b²`.
    #[must_use]
    pub fn variance(&self) -> f64 {
        self.std * self.std
    }

    /// `b_max`.
    #[must_use]
    pub fn max_abs(&self) -> f64 {
        self.max_abs
    }
}

/// A track's biases, one slot per reader it has heard: a value the track owns.
#[derive(Debug, Clone, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BiasVector {
    values: DVector<f64>,
    covariance: DMatrix<f64>,
    time_s: Option<f64>,
    /// Each slot's prior (slots beyond its length, from a vector stored before priors were
    /// per slot, take the model's).
    #[cfg_attr(feature = "serde", serde(default))]
    priors: Vec<BiasPrior>,
}

impl BiasVector {
    /// Number of readers (slots).
    #[must_use]
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether there is no slot.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// `b̂` of `slot`.
    ///
    /// # Panics
    /// For a slot that [`BiasModel::add_reader`] did not return.
    #[must_use]
    pub fn value(&self, slot: usize) -> f64 {
        self.values[slot]
    }

    /// `P_b` of `slot` (its diagonal element), unit².
    ///
    /// # Panics
    /// For a slot that [`BiasModel::add_reader`] did not return.
    #[must_use]
    pub fn variance(&self, slot: usize) -> f64 {
        self.covariance[(slot, slot)]
    }

    /// The covariance `P_b` of every slot (slot order), unit².
    #[must_use]
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.covariance
    }
}

/// A reading's part in [`BiasModel::update_observable`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasObservation {
    /// `νᵢ = zᵢ − b̂ᵢ − hᵢ(x⁻)`: the bias-corrected reading against the track's prediction.
    pub innovation: f64,
    /// `σᵢ²`: the reading's noise variance (without the bias's) as the Kalman step counts it,
    /// inflated for readings whose errors are correlated in time.
    pub variance: f64,
    /// The reading's own noise variance (one look, not inflated), for the round's consistency
    /// test.
    pub noise_variance: f64,
    /// `∂hᵢ/∂p`: the reading's gradient with respect to the position (unused components 0).
    pub gradient: [f64; 3],
}

/// Relative tolerance of the pseudo-inverse of `S` (singular values below it times the largest
/// are taken as zero: the `d` directions the projection removed).
const PSEUDO_INVERSE_TOLERANCE: f64 = 1e-9;

/// False-alarm probability of the round's parity test (a consistent round is refused this
/// often).
const PARITY_FALSE_ALARM: f64 = 1e-3;

impl BiasModel {
    /// A model with default prior standard deviation `σ_b` (> 0), random walk `√q` (≥ 0,
    /// unit/√s) and default bound `b_max` (> 0); [`Self::add_reader_with`] gives a reader its
    /// own prior and bound.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for a value outside those ranges or not finite.
    pub fn new(prior_std: f64, random_walk_per_sqrt_s: f64, max_abs: f64) -> Result<Self> {
        let prior = BiasPrior::new(prior_std, max_abs)?;
        if !(random_walk_per_sqrt_s.is_finite() && random_walk_per_sqrt_s >= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "random_walk_per_sqrt_s",
                reason: "must be finite and ≥ 0",
            });
        }
        Ok(Self {
            prior,
            random_walk_per_sqrt_s,
        })
    }

    /// The default prior: `σ_b` and `b_max` of readers added by [`Self::add_reader`].
    #[must_use]
    pub fn prior(&self) -> BiasPrior {
        self.prior
    }

    /// The prior of `slot` in `biases`.
    #[must_use]
    pub fn prior_of(&self, biases: &BiasVector, slot: usize) -> BiasPrior {
        biases.priors.get(slot).copied().unwrap_or(self.prior)
    }

    /// `(b̂, P_b⁻)` of `slot` predicted to `time_s` (the random walk since the vector's time,
    /// capped at the slot's `σ_b²`), without predicting the whole vector.
    #[must_use]
    pub fn predicted(&self, biases: &BiasVector, slot: usize, time_s: f64) -> (f64, f64) {
        let dt_s = biases.time_s.map_or(0.0, |t| (time_s - t).max(0.0));
        let cap = self.prior_of(biases, slot).variance();
        (
            biases.values[slot],
            self.walked(biases.covariance[(slot, slot)], dt_s, cap),
        )
    }

    /// `min(P + q Δt, σ_b²)`: a variance after `dt_s` of the random walk, never above the prior's
    /// `prior_variance`.
    fn walked(&self, variance: f64, dt_s: f64, prior_variance: f64) -> f64 {
        let q = self.random_walk_per_sqrt_s * self.random_walk_per_sqrt_s;
        (variance + q * dt_s).min(prior_variance)
    }

    /// Adds a reader to `biases` with the model's prior `N(0, σ_b²)`, uncorrelated with the
    /// others; returns its slot.
    pub fn add_reader(&self, biases: &mut BiasVector) -> usize {
        self.add_reader_with(biases, self.prior)
    }

    /// Adds a reader to `biases` with its own prior `N(0, σ_b²)` and bound, uncorrelated with
    /// the others; returns its slot.
    pub fn add_reader_with(&self, biases: &mut BiasVector, prior: BiasPrior) -> usize {
        let n = biases.values.len();
        // slots stored before priors were per slot take the model's
        while biases.priors.len() < n {
            biases.priors.push(self.prior);
        }
        biases.values = biases.values.clone().insert_row(n, 0.0);
        let mut covariance = DMatrix::zeros(n + 1, n + 1);
        covariance.view_mut((0, 0), (n, n)).copy_from(&biases.covariance);
        covariance[(n, n)] = prior.variance();
        biases.covariance = covariance;
        biases.priors.truncate(n);
        biases.priors.push(prior);
        n
    }

    /// `b⁻ = b`, `P_b⁻ = P_b + q Δt I` at `time_s`, each variance at most the prior's `σ_b²`
    /// (the random walk never makes a bias less known than before it was heard). A time
    /// before the vector's changes nothing.
    ///
    /// # Errors
    /// [`EstimationError::NonFinite`] for a non-finite time.
    pub fn predict(&self, biases: &BiasVector, time_s: f64) -> Result<BiasVector> {
        if !time_s.is_finite() {
            return Err(EstimationError::NonFinite { what: "bias time" });
        }
        let mut predicted = biases.clone();
        let dt_s = biases.time_s.map_or(0.0, |t| (time_s - t).max(0.0));
        // P_b⁻ = P_b + q Δt I, diagonal capped at each slot's σ_b²
        for i in 0..predicted.values.len() {
            let cap = self.prior_of(biases, i).variance();
            predicted.covariance[(i, i)] = self.walked(predicted.covariance[(i, i)], dt_s, cap);
        }
        predicted.time_s = Some(biases.time_s.map_or(time_s, |t| t.max(time_s)));
        Ok(predicted)
    }

    /// One learning step from readings of several readers taken together (see the module's
    /// equations): `slots[i]` is the slot of `observations[i]`'s reader, `dimensions` the
    /// position's (2 or 3). `biases` should be predicted to the readings' time.
    ///
    /// Fewer than `dimensions + 1` readings, or readers whose gradients do not span the
    /// position (`Gᵀ W G` singular), learn nothing: `biases` is returned unchanged.
    ///
    /// # Errors
    /// [`EstimationError::DimensionMismatch`] when `slots` and `observations` differ in
    /// length, a slot is out of range or `dimensions` is not 1–3;
    /// [`EstimationError::NonFinite`] for a non-finite innovation, variance or gradient, or a
    /// non-finite result; [`EstimationError::InvalidParameter`] for a variance that is not
    /// positive or a slot given twice.
    pub fn update_observable(
        &self,
        biases: &BiasVector,
        slots: &[usize],
        observations: &[BiasObservation],
        dimensions: usize,
    ) -> Result<BiasVector> {
        check_observations(biases, slots, observations, dimensions)?;
        let n = observations.len();
        if n <= dimensions {
            return Ok(biases.clone());
        }
        // G (n × d), W = diag(1/σᵢ²), ν
        let g = DMatrix::from_fn(n, dimensions, |i, j| observations[i].gradient[j]);
        let w = DVector::from_iterator(n, observations.iter().map(|o| 1.0 / o.variance));
        let nu = DVector::from_iterator(n, observations.iter().map(|o| o.innovation));
        // Gᵀ W and (Gᵀ W G)⁻¹
        let gt_w = DMatrix::from_fn(dimensions, n, |j, i| g[(i, j)] * w[i]);
        let Some(normal_inverse) = (&gt_w * &g).try_inverse() else {
            return Ok(biases.clone());
        };
        // M = I − G (Gᵀ W G)⁻¹ Gᵀ W (n × n), y = M ν
        let m = DMatrix::identity(n, n) - &g * &normal_inverse * &gt_w;
        let y = &m * &nu;
        // parity test: a round whose residuals no bias within its uncertainty explains (the
        // prediction is off by more than its covariance says, e.g. a start from a bad fix) is
        // not learnt from: yᵀ (M (P_b + Σ₁) Mᵀ)⁺ y ≤ χ²_{n−d}(1 − 10⁻³), Σ₁ the one-look noise
        let sub_covariance = DMatrix::from_fn(n, n, |i, j| biases.covariance[(slots[i], slots[j])]);
        let one_look = DMatrix::from_diagonal(&DVector::from_iterator(
            n,
            observations.iter().map(|o| o.noise_variance),
        ));
        let parity_covariance = &m * (sub_covariance + one_look) * m.transpose();
        let parity_covariance = (&parity_covariance + parity_covariance.transpose()) * 0.5;
        // a round whose test cannot be computed teaches nothing
        let Some(inverse) = bounded_pseudo_inverse(&parity_covariance) else {
            return Ok(biases.clone());
        };
        let statistic = (y.transpose() * inverse * &y)[(0, 0)];
        let threshold = chi_square_quantile(1.0 - PARITY_FALSE_ALARM, (n - dimensions) as f64)?;
        if statistic.is_nan() || statistic > threshold {
            return Ok(biases.clone());
        }
        // H = M embedded in the whole vector (n × N): column slots[j] holds M's column j
        let total = biases.values.len();
        let mut h = DMatrix::zeros(n, total);
        for (j, &slot) in slots.iter().enumerate() {
            h.set_column(slot, &m.column(j));
        }
        // S = H P_b Hᵀ + M Σ Mᵀ
        let sigma = DMatrix::from_diagonal(&DVector::from_iterator(n, observations.iter().map(|o| o.variance)));
        let p_ht = &biases.covariance * h.transpose();
        let s = &h * &p_ht + &m * sigma * m.transpose();
        let s = (&s + s.transpose()) * 0.5;
        let Some(s_pinv) = bounded_pseudo_inverse(&s) else {
            return Ok(biases.clone());
        };
        // K = P_b Hᵀ S⁺, b̂ ← b̂ + K y, P_b ← P_b − K S Kᵀ
        let k = &p_ht * s_pinv;
        // b̂ᵢ clamped to ±b_max of its slot
        let mut values = &biases.values + &k * y;
        for (slot, value) in values.iter_mut().enumerate() {
            let bound = self.prior_of(biases, slot).max_abs();
            *value = value.clamp(-bound, bound);
        }
        let covariance = &biases.covariance - &k * &s * k.transpose();
        let covariance = (&covariance + covariance.transpose()) * 0.5;
        if !(values.iter().all(|v| v.is_finite()) && covariance.iter().all(|v| v.is_finite())) {
            return Err(EstimationError::NonFinite { what: "bias posterior" });
        }
        Ok(BiasVector {
            values,
            covariance,
            time_s: biases.time_s,
            priors: biases.priors.clone(),
        })
    }
}

/// Most sweeps the SVD behind a pseudo-inverse may take (it converges in a few dozen on these
/// small symmetric matrices; nalgebra's default has no limit).
const MAX_SVD_ITERATIONS: usize = 1000;

/// `A⁺` with singular values below `PSEUDO_INVERSE_TOLERANCE · max|aᵢⱼ|` taken as zero; `None`
/// for a matrix with a non-finite entry or an SVD that does not converge (never a hang).
fn bounded_pseudo_inverse(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let tolerance = PSEUDO_INVERSE_TOLERANCE * a.amax().max(f64::MIN_POSITIVE);
    let svd = a.clone().try_svd(true, true, f64::EPSILON, MAX_SVD_ITERATIONS)?;
    svd.pseudo_inverse(tolerance)
        .ok()
        .filter(|p| p.iter().all(|v| v.is_finite()))
}

/// The checks of [`BiasModel::update_observable`]'s input.
fn check_observations(
    biases: &BiasVector,
    slots: &[usize],
    observations: &[BiasObservation],
    dimensions: usize,
) -> Result<()> {
    if slots.len() != observations.len() {
        return Err(EstimationError::DimensionMismatch {
            what: "bias slots and observations",
            expected: observations.len(),
            found: slots.len(),
        });
    }
    if !(1..=3).contains(&dimensions) {
        return Err(EstimationError::DimensionMismatch {
            what: "position dimensions",
            expected: 3,
            found: dimensions,
        });
    }
    if let Some(&slot) = slots.iter().find(|&&slot| slot >= biases.values.len()) {
        return Err(EstimationError::DimensionMismatch {
            what: "bias slot",
            expected: biases.values.len(),
            found: slot,
        });
    }
    if slots.iter().enumerate().any(|(i, s)| slots[..i].contains(s)) {
        return Err(EstimationError::InvalidParameter {
            name: "slots",
            reason: "a reader's slot is given twice in one step",
        });
    }
    for o in observations {
        if !(o.innovation.is_finite()
            && o.variance.is_finite()
            && o.noise_variance.is_finite()
            && o.gradient.iter().all(|g| g.is_finite()))
        {
            return Err(EstimationError::NonFinite {
                what: "bias observation",
            });
        }
        if o.variance <= 0.0 || o.noise_variance <= 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "variance",
                reason: "a reading's variance must be > 0",
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_are_checked() {
        assert!(BiasModel::new(0.0, 0.0, 1.0).is_err());
        assert!(BiasModel::new(0.1, -1.0, 1.0).is_err());
        assert!(BiasModel::new(0.1, 0.0, f64::INFINITY).is_err());
        assert!(BiasModel::new(0.1, 0.0, 1.0).is_ok());
    }

    /// Four readers at the corners of a 10 m square, a tag on a circle inside it, a position
    /// error that changes every epoch: every reader's bias (a common part included) is found,
    /// which learning from the raw innovations would trade against the position.
    #[test]
    fn biases_are_learnt_from_what_no_position_error_explains() {
        let readers = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let truth = [0.3, 0.1, -0.2, 0.25];
        let model = BiasModel::new(0.5, 0.0, 2.0).unwrap();
        let mut biases = BiasVector::default();
        // a fifth reader the tag never hears keeps its prior
        let slots: Vec<usize> = (0..5).map(|_| model.add_reader(&mut biases)).collect();
        for k in 0..400u32 {
            let angle = f64::from(k) * 0.05;
            let p = [5.0 + 3.0 * angle.cos(), 5.0 + 3.0 * angle.sin()];
            let delta = [0.2 * (1.7 * angle).sin(), -0.15 * (0.9 * angle).cos()];
            let observations: Vec<BiasObservation> = readers
                .iter()
                .zip(truth)
                .zip(&slots)
                .map(|((a, b), &slot)| {
                    let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
                    let u = [(p[0] - a[0]) / d, (p[1] - a[1]) / d];
                    // ν = z − b̂ − h(p + δ) ≈ b − b̂ − u·δ
                    BiasObservation {
                        innovation: b - biases.value(slot) - (u[0] * delta[0] + u[1] * delta[1]),
                        variance: 0.01,
                        noise_variance: 0.01,
                        gradient: [u[0], u[1], 0.0],
                    }
                })
                .collect();
            biases = model.update_observable(&biases, &slots[..4], &observations, 2).unwrap();
        }
        for (&slot, b) in slots.iter().zip(truth) {
            assert!((biases.value(slot) - b).abs() < 0.01, "{biases:?}");
            assert!(biases.variance(slot).sqrt() < 0.02, "{biases:?}");
        }
        assert_eq!((biases.value(4), biases.variance(4)), (0.0, 0.25));
    }

    /// A Wi-Fi responder's offset of metres among UWB anchors' decimetres: with the model's
    /// prior (σ_b 0.2 m, bound 1 m) it is clamped at 1 m; with its own (σ_b 2 m, bound 10 m) it
    /// is learnt. Each slot's random walk is capped at its own prior.
    #[test]
    fn a_reader_with_its_own_prior_learns_an_offset_beyond_the_models_bound() {
        let readers = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let truth = [0.1, -0.1, 0.05, 2.5];
        let model = BiasModel::new(0.2, 0.01, 1.0).unwrap();
        let wide = BiasPrior::new(2.0, 10.0).unwrap();
        let learn = |own_prior: bool| {
            let mut biases = BiasVector::default();
            let mut slots: Vec<usize> = (0..3).map(|_| model.add_reader(&mut biases)).collect();
            slots.push(if own_prior {
                model.add_reader_with(&mut biases, wide)
            } else {
                model.add_reader(&mut biases)
            });
            for k in 0..400u32 {
                let angle = f64::from(k) * 0.05;
                let p = [5.0 + 3.0 * angle.cos(), 5.0 + 3.0 * angle.sin()];
                let observations: Vec<BiasObservation> = readers
                    .iter()
                    .zip(truth)
                    .zip(&slots)
                    .map(|((a, b), &slot)| {
                        let d = ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
                        BiasObservation {
                            innovation: b - biases.value(slot),
                            variance: 0.01,
                            noise_variance: 0.01,
                            gradient: [(p[0] - a[0]) / d, (p[1] - a[1]) / d, 0.0],
                        }
                    })
                    .collect();
                biases = model.predict(&biases, f64::from(k) * 0.1).unwrap();
                biases = model.update_observable(&biases, &slots, &observations, 2).unwrap();
            }
            (biases, slots)
        };
        let (own, slots) = learn(true);
        assert!((own.value(slots[3]) - 2.5).abs() < 0.05, "{own:?}");
        assert_eq!(model.prior_of(&own, slots[3]), wide);
        assert_eq!(model.prior_of(&own, slots[0]), model.prior());
        let (shared, slots) = learn(false);
        assert!(shared.value(slots[3]) <= 1.0, "{shared:?}");
        // after a long gap each variance walks back to its own prior, not the model's
        let later = model.predict(&own, 1e6).unwrap();
        assert!((later.variance(slots[3]) - 4.0).abs() < 1e-12);
        assert!((later.variance(slots[0]) - 0.04).abs() < 1e-12);
        assert!((model.predicted(&own, slots[3], 1e6).1 - 4.0).abs() < 1e-12);
        assert!(BiasPrior::new(0.0, 1.0).is_err());
        assert!(BiasPrior::new(1.0, f64::NAN).is_err());
    }

    #[test]
    fn too_few_readings_learn_nothing_and_bad_input_is_an_error() {
        let model = BiasModel::new(0.5, 0.1, 0.3).unwrap();
        let mut biases = BiasVector::default();
        let slots = [model.add_reader(&mut biases), model.add_reader(&mut biases)];
        let observation = BiasObservation {
            innovation: 1.0,
            variance: 0.01,
            noise_variance: 0.01,
            gradient: [1.0, 0.0, 0.0],
        };
        assert_eq!(
            model.update_observable(&biases, &slots, &[observation; 2], 2).unwrap(),
            biases
        );
        assert!(model.update_observable(&biases, &slots, &[observation], 2).is_err());
        assert!(model.update_observable(&biases, &[0, 0], &[observation; 2], 1).is_err());
        assert!(model.update_observable(&biases, &[0, 7], &[observation; 2], 1).is_err());
        let bad = BiasObservation {
            innovation: f64::NAN,
            ..observation
        };
        assert!(model
            .update_observable(&biases, &slots, &[bad, observation], 1)
            .is_err());
        // the random walk: P_b + q Δt, capped at σ_b²
        let later = model.predict(&model.predict(&biases, 0.0).unwrap(), 1e6).unwrap();
        assert_eq!(later.variance(0), 0.25);
    }

    /// Variances at the edge of the representable (a random stream's) overflow the products:
    /// the step returns (unchanged or an error), it never hangs in the SVD.
    #[test]
    fn overflowing_values_return_instead_of_hanging() {
        let model = BiasModel::new(0.5, 0.0, 2.0).unwrap();
        let mut biases = BiasVector::default();
        let slots: Vec<usize> = (0..4).map(|_| model.add_reader(&mut biases)).collect();
        for (variance, innovation) in [(1e300, 1.0), (1e-300, 1e200), (1.0, 1e300)] {
            let observations: Vec<BiasObservation> = (0..4)
                .map(|i| {
                    let angle = f64::from(i) * 1.3;
                    BiasObservation {
                        innovation,
                        variance,
                        noise_variance: variance,
                        gradient: [angle.cos(), angle.sin(), 0.0],
                    }
                })
                .collect();
            if let Ok(learnt) = model.update_observable(&biases, &slots, &observations, 2) {
                assert!((0..4).all(|i| learnt.value(i).is_finite() && learnt.variance(i).is_finite()));
            }
        }
    }

    #[test]
    fn along_one_axis_a_common_offset_is_learnt_from_readers_on_both_sides() {
        // 1-D: readers at 0 and 10 m, the tag at 4 m; z = |p − a| + b with b = 0.2 for both.
        // Any position error moves the two ranges in opposite directions, a common offset in
        // the same: one step sees it.
        let model = BiasModel::new(0.5, 0.0, 2.0).unwrap();
        let mut biases = BiasVector::default();
        let slots = [model.add_reader(&mut biases), model.add_reader(&mut biases)];
        let observations = [
            BiasObservation {
                innovation: 0.2 - 0.05,
                variance: 1e-6,
                noise_variance: 1e-6,
                gradient: [1.0, 0.0, 0.0],
            },
            BiasObservation {
                innovation: 0.2 + 0.05,
                variance: 1e-6,
                noise_variance: 1e-6,
                gradient: [-1.0, 0.0, 0.0],
            },
        ];
        let learnt = model.update_observable(&biases, &slots, &observations, 1).unwrap();
        assert!(
            (learnt.value(0) - 0.2).abs() < 1e-3 && (learnt.value(1) - 0.2).abs() < 1e-3,
            "{learnt:?}"
        );
    }
}
