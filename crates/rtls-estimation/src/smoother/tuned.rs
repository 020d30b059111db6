//! A fixed-interval smoother that fits its own process and measurement noise to the track it
//! smooths.
//!
//! The RTS smoother of a filter's states uses the filter's process noise. A tracker's process
//! noise is set for live tracking (it must follow a turn now); a smoother that knows the
//! future can average over a longer window wherever the track says the tag moved steadily.
//! This smoother re-filters a segment of a track from what each of the tracker's updates
//! added, with the noise chosen by maximum likelihood over the segment itself — no ground
//! truth:
//!
//! ```text
//! motion   x⁻ = F_cv(Δt) x,  Q = q · Q_cv(Δt)      (x = [p_x, v_x, p_y, v_y(, p_z, v_z)], q in m²/s³)
//! measure  each update k told  J_k x ≈ j_k         (J_k = P⁺⁻¹ − P⁻⁻¹, j_k = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻ of
//!          the tracker's own update): for J_k = Σ λᵢ uᵢ uᵢᵀ, the scalar measurements
//!          zᵢ = uᵢᵀ j_k / λᵢ = uᵢᵀ x + wᵢ,  wᵢ ~ N(0, c / λᵢ)
//! fit      (q, c) = argmax Σₖ Σᵢ −½ (νᵢ² / Sᵢ + ln Sᵢ + ln 2π)   over a grid (the innovations
//!          of the forward pass over the first [`FIT_STEPS_MAX`] steps)
//! smooth   the Rauch–Tung–Striebel backward pass with the fitted q ([`KalmanFilter::smooth`])
//! ```
//!
//! The grid: `q` from 10⁻³ to 10 × the tracker's own in half decades; `c` ∈ {0.5, 0.7, 1, 1.4,
//! 2}. With `q` and `c` at the tracker's own, and position updates, the passes are the
//! tracker's own filter and its RTS smoother (a unit test checks them against
//! [`crate::filter::KalmanFilter`]).
//!
//! The filtered and smoothed covariances are those of the fitted model, which assumes white
//! measurement errors: on recorded data, whose errors persist for seconds, they are
//! overconfident where the fit chose a small `q`, and a caller that reports a covariance takes
//! it from the tracker's own (calibrated) states (as `rtls_engine`'s smoother does).
//!
//! # References
//! Rauch, Tung, Striebel (1965); Bar-Shalom, Li, Kirubarajan (2001) §8.6 (the smoother), §5.2.5
//! (the likelihood of the innovations); Shumway, Stoffer (1982), "An approach to time series
//! smoothing and forecasting using the EM algorithm", J. Time Series Analysis 3(4)
//! (maximum-likelihood noise from the innovations).

use alloc::vec::Vec;

use nalgebra::DMatrix;

use crate::error::{EstimationError, Result};
use crate::filter::KalmanFilter;
use crate::gaussian::{Gaussian, Matrix, Vector};
use crate::math::ln;
use crate::motion::{ConstantVelocity, ProcessNoise};

/// The most steps the noise is fitted on (the first ones of a segment); the smoother then
/// runs over all of them.
pub const FIT_STEPS_MAX: usize = 20_000;

/// `ln 2π`.
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Multipliers of the tracker's `q`: 10^(k/2), k = −6 … 2.
const Q_FACTORS: [f64; 9] = [1e-3, 3.162e-3, 1e-2, 3.162e-2, 0.1, 0.3162, 1.0, 3.162, 10.0];
/// Noise scales `c`.
const NOISE_SCALES: [f64; 5] = [0.5, 0.7, 1.0, 1.4, 2.0];

/// What the measurements of one reported state added, in information form over the CV layout
/// state `x = [p_x, v_x, p_y, v_y(, p_z, v_z)]` (zero for a prediction).
///
/// # Example
/// ```
/// use rtls_estimation::smoother::InformationStep;
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// let prior = Gaussian::new(Vector::<2>::new(0.0, 0.0), Matrix::<2>::identity(), 1.0)?;
/// // a measurement z = 2 of the first component with variance 1 halves its variance
/// let posterior = Gaussian::new(Vector::<2>::new(1.0, 0.0), Matrix::<2>::new(0.5, 0.0, 0.0, 1.0), 1.0)?;
/// let step = InformationStep::between(&prior, &posterior)?;
/// assert!((step.information[(0, 0)] - 1.0).abs() < 1e-12); // J = R⁻¹
/// assert!((step.information_vector[0] - 2.0).abs() < 1e-12); // j = R⁻¹ z
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InformationStep<const N: usize> {
    /// Time of the state, s.
    pub time_s: f64,
    /// `J = P⁺⁻¹ − P⁻⁻¹`, m⁻² (positions) and (m/s)⁻² (velocities).
    pub information: Matrix<N>,
    /// `j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻`.
    pub information_vector: Vector<N>,
}

impl<const N: usize> InformationStep<N> {
    /// No measurement at `time_s` (a prediction, or a track's first state).
    #[must_use]
    pub fn none(time_s: f64) -> Self {
        Self {
            time_s,
            information: Matrix::<N>::zeros(),
            information_vector: Vector::<N>::zeros(),
        }
    }

    /// What an update from `prior` to `posterior` (the same time) added:
    /// `J = P⁺⁻¹ − P⁻⁻¹`, `j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻`.
    ///
    /// # Errors
    /// [`EstimationError::NotPositiveDefinite`] if either covariance cannot be inverted.
    pub fn between(prior: &Gaussian<N>, posterior: &Gaussian<N>) -> Result<Self> {
        let invert = |p: &Matrix<N>, what| {
            p.cholesky()
                .map(|c| c.inverse())
                .ok_or(EstimationError::NotPositiveDefinite { what })
        };
        let prior_information = invert(prior.covariance(), "prior covariance (update information)")?;
        let posterior_information = invert(posterior.covariance(), "posterior covariance (update information)")?;
        // J = P⁺⁻¹ − P⁻⁻¹
        let information = posterior_information - prior_information;
        // j = P⁺⁻¹ x⁺ − P⁻⁻¹ x⁻
        let information_vector = posterior_information * posterior.mean() - prior_information * prior.mean();
        Ok(Self {
            time_s: posterior.time_s(),
            information: (information + information.transpose()) * 0.5,
            information_vector,
        })
    }

    /// Adds another update's information at the same time (sequential updates telescope).
    pub fn add(&mut self, other: &Self) {
        self.information += other.information;
        self.information_vector += other.information_vector;
        self.time_s = self.time_s.max(other.time_s);
    }
}

/// The noise a track segment was smoothed with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseFit {
    /// `q`, the white-acceleration intensity, m²/s³.
    pub acceleration_psd_m2ps3: f64,
    /// `c`, the scale on the variances the updates stated.
    pub noise_scale: f64,
    /// The log-likelihood of the fitted steps' innovations.
    pub log_likelihood: f64,
}

/// A smoothed track segment and the filtered states of the same model.
#[derive(Debug, Clone, PartialEq)]
pub struct TunedSmoothing<const N: usize> {
    /// The fitted noise.
    pub fit: NoiseFit,
    /// `x̂ₖ|ₖ, Pₖ|ₖ` of the fitted model.
    pub filtered: Vec<Gaussian<N>>,
    /// `x̂ₖ|ₙ, Pₖ|ₙ`.
    pub smoothed: Vec<Gaussian<N>>,
}

/// One scalar measurement of a step: `z = h·x + w`, `w ~ N(0, c · variance)`.
#[derive(Debug, Clone, Copy)]
struct Scalar<const N: usize> {
    row: Vector<N>,
    value: f64,
    variance: f64,
}

/// A step's time and scalar measurements.
struct Prepared<const N: usize> {
    time_s: f64,
    scalars: Vec<Scalar<N>>,
}

/// Fits `q` and `c` to a track segment by maximum likelihood and smooths it.
///
/// `start` is the segment's first state (its prior); `steps` its reported states in time
/// order, the first at `start`'s time (whose information is ignored: it is in `start`);
/// `q_m2ps3` the tracker's own white-acceleration intensity `q`, m²/s³, the grid's centre.
///
/// # Errors
/// [`EstimationError::TimeWentBackwards`] if the steps are out of order;
/// [`EstimationError::InvalidParameter`] for an empty segment or `q ≤ 0`;
/// [`EstimationError::NonFinite`] if no model of the grid gives a finite likelihood;
/// [`EstimationError::NotPositiveDefinite`] / [`EstimationError::NonFinite`] if the final passes
/// fail.
///
/// # Example
/// ```
/// use rtls_estimation::smoother::{tuned_smooth, InformationStep};
/// use rtls_estimation::{Gaussian, Matrix, Vector};
/// // a walker at 1 m/s along x, fixes of σ = 0.5 m every second
/// let fix = |t: f64, x: f64| InformationStep::<4> {
///     time_s: t,
///     information: Matrix::<4>::from_diagonal(&Vector::<4>::new(4.0, 0.0, 4.0, 0.0)),
///     information_vector: Vector::<4>::new(4.0 * x, 0.0, 0.0, 0.0),
/// };
/// let steps: Vec<_> = (0..30).map(|k| fix(f64::from(k), f64::from(k) + if k % 2 == 0 { 0.4 } else { -0.4 })).collect();
/// let start = Gaussian::new(Vector::<4>::new(0.4, 0.0, 0.0, 0.0), Matrix::<4>::from_diagonal(&Vector::<4>::new(0.25, 4.0, 0.25, 4.0)), 0.0)?;
/// let smoothed = tuned_smooth(&start, &steps, 1.0)?;
/// // a steady walk: the fit chooses a q below the tracker's, and the track follows the line
/// assert!(smoothed.fit.acceleration_psd_m2ps3 < 1.0);
/// assert!((smoothed.smoothed[15].mean()[0] - 15.0).abs() < 0.3);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
pub fn tuned_smooth<const N: usize>(
    start: &Gaussian<N>,
    steps: &[InformationStep<N>],
    q_m2ps3: f64,
) -> Result<TunedSmoothing<N>> {
    if steps.is_empty() {
        return Err(EstimationError::InvalidParameter {
            name: "steps",
            reason: "a segment to smooth has at least one state",
        });
    }
    if !(q_m2ps3.is_finite() && q_m2ps3 > 0.0) {
        return Err(EstimationError::InvalidParameter {
            name: "q_m2ps3",
            reason: "the white-acceleration intensity is finite and > 0",
        });
    }
    for pair in steps.windows(2) {
        if pair[1].time_s < pair[0].time_s {
            return Err(EstimationError::TimeWentBackwards {
                state_time_s: pair[0].time_s,
                requested_time_s: pair[1].time_s,
            });
        }
    }
    let prepared: Vec<Prepared<N>> = steps
        .iter()
        .enumerate()
        .map(|(k, step)| prepare(step, k == 0))
        .collect();
    let fit_steps = &prepared[..prepared.len().min(FIT_STEPS_MAX)];
    // the whole grid (45 forward passes); a model whose pass fails numerically is never chosen
    let mut best: Option<NoiseFit> = None;
    for factor in Q_FACTORS {
        for noise_scale in NOISE_SCALES {
            let q = factor * q_m2ps3;
            let Ok((log_likelihood, _)) = forward(start, fit_steps, q, noise_scale, false) else {
                continue;
            };
            if best.is_none_or(|b| log_likelihood > b.log_likelihood) {
                best = Some(NoiseFit {
                    acceleration_psd_m2ps3: q,
                    noise_scale,
                    log_likelihood,
                });
            }
        }
    }
    let fit = best.ok_or(EstimationError::NonFinite {
        what: "tuned smoother likelihood",
    })?;
    let (_, filtered) = forward(start, &prepared, fit.acceleration_psd_m2ps3, fit.noise_scale, true)?;
    // x̂ₖ|ₙ, Pₖ|ₙ: the RTS backward pass with the fitted q
    let motion = ConstantVelocity::new(ProcessNoise::continuous(fit.acceleration_psd_m2ps3))?;
    let smoothed = KalmanFilter::default().smooth(&filtered, &motion)?;
    Ok(TunedSmoothing {
        fit,
        filtered,
        smoothed,
    })
}

/// A step's scalar measurements: `J = Σ λᵢ uᵢ uᵢᵀ` (λᵢ above 10⁻⁶ λ_max: the rest is the
/// rounding of `P⁺⁻¹ − P⁻⁻¹`), `zᵢ = uᵢᵀ j / λᵢ`, variance `1/λᵢ`, row `uᵢ`.
fn prepare<const N: usize>(step: &InformationStep<N>, first: bool) -> Prepared<N> {
    let mut scalars = Vec::new();
    let finite =
        step.information.iter().all(|v| v.is_finite()) && step.information_vector.iter().all(|v| v.is_finite());
    if !first && finite {
        // (the eigen-decomposition of a const-generic size needs the heap-sized matrix)
        let eigen = DMatrix::from_column_slice(N, N, step.information.as_slice()).symmetric_eigen();
        let largest = eigen.eigenvalues.max();
        for (i, &lambda) in eigen.eigenvalues.iter().enumerate() {
            if !(largest > 0.0 && lambda > 1e-6 * largest) {
                continue;
            }
            let row = Vector::<N>::from_iterator(eigen.eigenvectors.column(i).iter().copied());
            scalars.push(Scalar {
                row,
                // zᵢ = uᵢᵀ j / λᵢ
                value: row.dot(&step.information_vector) / lambda,
                variance: 1.0 / lambda,
            });
        }
    }
    Prepared {
        time_s: step.time_s,
        scalars,
    }
}

/// The forward (Kalman) pass with `q` and `c` over `steps` from `start`: the log-likelihood of
/// its innovations and, when `keep`, each step's posterior.
fn forward<const N: usize>(
    start: &Gaussian<N>,
    steps: &[Prepared<N>],
    q: f64,
    noise_scale: f64,
    keep: bool,
) -> Result<(f64, Vec<Gaussian<N>>)> {
    let kf = KalmanFilter::default();
    let motion = ConstantVelocity::new(ProcessNoise::continuous(q))?;
    let mut log_likelihood = 0.0;
    let mut filtered = Vec::with_capacity(if keep { steps.len() } else { 0 });
    let mut state = Gaussian::new(*start.mean(), *start.covariance(), steps[0].time_s)?;
    for step in steps {
        // x⁻ = F x,  P⁻ = F P Fᵀ + Q
        let prior = kf.predict(&state, &motion, step.time_s)?;
        let (mut x, mut p) = (*prior.mean(), *prior.covariance());
        for scalar in &step.scalars {
            let h = &scalar.row;
            // ν = z − h x,  S = h P hᵀ + c σ²,  K = P hᵀ / S
            let ph = p * h;
            let s = h.dot(&ph) + noise_scale * scalar.variance;
            if !(s.is_finite() && s > 0.0) {
                return Err(EstimationError::InnovationNotPositiveDefinite);
            }
            let nu = scalar.value - h.dot(&x);
            // ln L += −½ (ν²/S + ln S + ln 2π)
            log_likelihood -= 0.5 * (nu * nu / s + ln(s) + LN_2PI);
            let k = ph / s;
            // x ← x + K ν,  P ← P − K S Kᵀ
            x += k * nu;
            p -= k * k.transpose() * s;
        }
        if !log_likelihood.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "tuned smoother likelihood",
            });
        }
        // (validates the posterior: finite, symmetric after symmetrising)
        state = Gaussian::new(x, (p + p.transpose()) * 0.5, step.time_s)?;
        if keep {
            filtered.push(state);
        }
    }
    Ok((log_likelihood, filtered))
}

#[cfg(test)]
mod tests;
