//! Joint probabilistic data association: marginal association probabilities by exact
//! enumeration of the feasible joint events of a cluster, and the moment-matched combined
//! update.
//!
//! # Joint events
//! A joint event `θ` of a cluster gives each track at most one of its gated detections and each
//! detection at most one track; detections left over are clutter. With `P_D` the detection
//! probability, `P_G` the gate probability, `λ` the clutter density of a detection's kind and
//! `N_td = N(ν_td; 0, S_td)` the Gaussian likelihood of detection `d` under track `t`,
//! ```text
//! P(θ | Z) ∝ Π_{(t,d) ∈ θ} P_D N_td / λ_d  ·  Π_{t undetected in θ} (1 − P_D P_G)
//! β_td = Σ_{θ ∋ (t,d)} P(θ | Z),        β_t0 = Σ_{θ: t undetected} P(θ | Z) = 1 − Σ_d β_td
//! ```
//! (the parametric JPDA of Bar-Shalom & Fortmann; with one track it is the PDA's
//! `β_d = L_d / (1 − P_D P_G + Σ L)`, `L_d = P_D N_d / λ`). Weights are accumulated in the log
//! domain with a running maximum, so very likely or unlikely events neither overflow nor
//! underflow.
//!
//! # Combined update
//! Each track's posterior is the Gaussian closest (moment-matched) to the mixture of its
//! prior (weight `β_t0`) and its per-detection Kalman posteriors `N(x_d, P_d)` (weights `β_td`):
//! ```text
//! x = β₀ x⁻ + Σ_d β_d x_d
//! P = β₀ (P⁻ + (x⁻ − x)(x⁻ − x)ᵀ) + Σ_d β_d (P_d + (x_d − x)(x_d − x)ᵀ)
//! ```
//! When every detection has the same `H` and `R` (so the same gain `K` and `P_d = P_c`), this is
//! exactly the textbook form with the spread-of-innovations term:
//! `x = x⁻ + K ν`, `ν = Σ β_d ν_d`, `P = β₀ P⁻ + (1 − β₀) P_c + K (Σ β_d ν_d ν_dᵀ − ν νᵀ) Kᵀ`.
//! The mixture form also covers detections of different kinds and noise in one cluster.
//!
//! # References
//! - T. E. Fortmann, Y. Bar-Shalom, M. Scheffé, "Sonar tracking of multiple targets using joint
//!   probabilistic data association", *IEEE J. Oceanic Engineering* 8(3), 173–184, 1983.
//! - Y. Bar-Shalom, T. E. Fortmann, *Tracking and Data Association*, Academic Press, 1988, §6.2
//!   (PDA) and §9.3 (parametric JPDA).
//! - Y. Bar-Shalom, F. Daum, J. Huang, "The probabilistic data association filter", *IEEE
//!   Control Systems Magazine* 29(6), 82–100, 2009, eq. (30)–(39).

use rtls_estimation::{Gaussian, Matrix, Vector};

use crate::error::{EngineError, Result};

/// The marginal association probabilities of one cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct JpdaMarginals {
    /// Number of feasible joint events enumerated.
    pub events: usize,
    /// `β_t0`: probability that track `t` was not detected (missed or outside its gate).
    pub miss: Vec<f64>,
    /// `β_td` for every gated `(detection, log_ratio)` of track `t`, in the input order:
    /// `(detection, β_td)`.
    pub association: Vec<Vec<(usize, f64)>>,
}

/// The result of [`jpda_marginals`].
#[derive(Debug, Clone, PartialEq)]
pub enum JpdaOutcome {
    /// The exact marginals.
    Marginals(JpdaMarginals),
    /// The cluster has more than `limit` joint events: not enumerated (use GNN).
    TooManyEvents {
        /// The limit that was exceeded.
        limit: usize,
    },
}

/// The exact JPDA marginals of a cluster (module documentation): `log_ratios[t]` lists the
/// gated detections of track `t` as `(detection, ln(P_D N_td / λ_d))`, `ln_miss` is
/// `ln(1 − P_D P_G)`. Enumeration stops after `max_events` joint events.
///
/// # Errors
/// [`EngineError::InvalidParameter`] naming `log_ratios` for a non-finite ratio or a detection
/// listed twice for one track, `ln_miss` unless finite.
///
/// # Example
/// One track, two detections with likelihood ratios 4 and 1, `1 − P_D P_G = 0.1`: the PDA
/// weights are `β = (4, 1, 0.1) / 5.1`.
/// ```
/// use rtls_engine::association::{jpda_marginals, JpdaOutcome};
/// let JpdaOutcome::Marginals(m) = jpda_marginals(&[vec![(0, 4f64.ln()), (1, 0.0)]], 0.1f64.ln(), 100)? else {
///     panic!("two events only");
/// };
/// assert_eq!(m.events, 3);
/// assert!((m.association[0][0].1 - 4.0 / 5.1).abs() < 1e-12);
/// assert!((m.miss[0] - 0.1 / 5.1).abs() < 1e-12);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
///
/// # References
/// Bar-Shalom & Fortmann (1988), §9.3; see the module documentation.
pub fn jpda_marginals(log_ratios: &[Vec<(usize, f64)>], ln_miss: f64, max_events: usize) -> Result<JpdaOutcome> {
    if !ln_miss.is_finite() {
        return Err(EngineError::InvalidParameter {
            name: "ln_miss",
            reason: "ln(1 − P_D P_G) must be finite: P_D P_G < 1",
        });
    }
    let mut detections = 0;
    for options in log_ratios {
        for (k, &(d, ratio)) in options.iter().enumerate() {
            if !ratio.is_finite() {
                return Err(EngineError::InvalidParameter {
                    name: "log_ratios",
                    reason: "a log likelihood ratio must be finite",
                });
            }
            if options[..k].iter().any(|&(e, _)| e == d) {
                return Err(EngineError::InvalidParameter {
                    name: "log_ratios",
                    reason: "a detection is listed twice for one track",
                });
            }
            detections = detections.max(d + 1);
        }
    }
    let mut search = Enumeration {
        log_ratios,
        ln_miss,
        max_events,
        events: 0,
        choice: vec![None; log_ratios.len()],
        used: vec![false; detections],
        max_log_weight: f64::NEG_INFINITY,
        total: 0.0,
        miss: vec![0.0; log_ratios.len()],
        association: log_ratios.iter().map(|o| vec![0.0; o.len()]).collect(),
    };
    if !search.visit(0, 0.0) {
        return Ok(JpdaOutcome::TooManyEvents { limit: max_events });
    }
    // β = accumulated weight / total (both scaled by the same e^{−max})
    let total = search.total;
    Ok(JpdaOutcome::Marginals(JpdaMarginals {
        events: search.events,
        miss: search.miss.iter().map(|w| w / total).collect(),
        association: log_ratios
            .iter()
            .zip(&search.association)
            .map(|(options, weights)| options.iter().zip(weights).map(|(&(d, _), w)| (d, w / total)).collect())
            .collect(),
    }))
}

/// Depth-first enumeration of joint events, one track per level.
struct Enumeration<'a> {
    log_ratios: &'a [Vec<(usize, f64)>],
    ln_miss: f64,
    max_events: usize,
    events: usize,
    /// The option chosen by each track on the current path (`None` = undetected).
    choice: Vec<Option<usize>>,
    used: Vec<bool>,
    /// Accumulators are scaled by `e^{−max_log_weight}`.
    max_log_weight: f64,
    total: f64,
    miss: Vec<f64>,
    association: Vec<Vec<f64>>,
}

impl Enumeration<'_> {
    /// Visits every completion of the current path from track `t`; `false` once the event
    /// budget is exceeded.
    fn visit(&mut self, t: usize, log_weight: f64) -> bool {
        if t == self.log_ratios.len() {
            self.events += 1;
            if self.events > self.max_events {
                return false;
            }
            self.accumulate(log_weight);
            return true;
        }
        // track t undetected: × (1 − P_D P_G)
        self.choice[t] = None;
        if !self.visit(t + 1, log_weight + self.ln_miss) {
            return false;
        }
        for k in 0..self.log_ratios[t].len() {
            let (d, ratio) = self.log_ratios[t][k];
            if self.used[d] {
                continue;
            }
            // track t takes detection d: × P_D N_td / λ_d
            self.used[d] = true;
            self.choice[t] = Some(k);
            let ok = self.visit(t + 1, log_weight + ratio);
            self.used[d] = false;
            if !ok {
                return false;
            }
        }
        self.choice[t] = None;
        true
    }

    /// Adds `e^{log_weight − max}` to the accumulators of the current event, rescaling them
    /// when a new maximum appears.
    fn accumulate(&mut self, log_weight: f64) {
        if log_weight > self.max_log_weight {
            // every accumulator was scaled by e^{−old max}: rescale to e^{−new max}
            let rescale = (self.max_log_weight - log_weight).exp();
            self.total *= rescale;
            self.miss.iter_mut().for_each(|w| *w *= rescale);
            self.association.iter_mut().flatten().for_each(|w| *w *= rescale);
            self.max_log_weight = log_weight;
        }
        let weight = (log_weight - self.max_log_weight).exp();
        self.total += weight;
        for (t, choice) in self.choice.iter().enumerate() {
            match choice {
                None => self.miss[t] += weight,
                Some(k) => self.association[t][*k] += weight,
            }
        }
    }
}

/// The moment-matched Gaussian of the mixture `β₀ N(prior) + Σ β_d N(posterior_d)` (module
/// documentation), at the prior's time.
///
/// # Errors
/// [`EngineError::Estimation`] if the result is not a valid Gaussian (non-finite).
pub(crate) fn combine(prior: &Gaussian<4>, miss: f64, posteriors: &[(f64, Gaussian<4>)]) -> Result<Gaussian<4>> {
    // x = β₀ x⁻ + Σ β_d x_d
    let mut mean: Vector<4> = prior.mean() * miss;
    for (beta, posterior) in posteriors {
        mean += posterior.mean() * *beta;
    }
    // P = β₀ (P⁻ + (x⁻ − x)(x⁻ − x)ᵀ) + Σ β_d (P_d + (x_d − x)(x_d − x)ᵀ)
    let spread = |state: &Gaussian<4>| -> Matrix<4> {
        let e = state.mean() - mean;
        state.covariance() + e * e.transpose()
    };
    let mut covariance = spread(prior) * miss;
    for (beta, posterior) in posteriors {
        covariance += spread(posterior) * *beta;
    }
    // exact symmetry against rounding in the sums
    let covariance = (covariance + covariance.transpose()) * 0.5;
    Ok(Gaussian::new(mean, covariance, prior.time_s())?)
}
