//! The Markov chain of mode switches.

use alloc::vec::Vec;

use nalgebra::DMatrix;

use crate::error::{EstimationError, Result};

/// Mode transition probabilities `pᵢⱼ = P(mode j at k | mode i at k−1)` of an IMM.
///
/// - [`ModeTransitions::per_step`]: a fixed row-stochastic matrix, for a fixed update rate.
/// - [`ModeTransitions::mean_sojourn`]: continuous-time switching with mean sojourn time `τᵢ`
///   in mode `i`, so irregular steps get consistent probabilities:
///   `pᵢᵢ(dt) = exp(−dt/τᵢ)`, `pᵢⱼ(dt) = (1 − pᵢᵢ(dt)) / (M − 1)` for `j ≠ i`.
///
/// # Example
/// ```
/// use rtls_estimation::imm::ModeTransitions;
/// let chain = ModeTransitions::mean_sojourn(vec![100.0, 20.0])?;
/// let p = chain.matrix(1.0)?;
/// assert!((p[(0, 0)] - (-0.01f64).exp()).abs() < 1e-15);
/// assert!((p[(1, 0)] + p[(1, 1)] - 1.0).abs() < 1e-15);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan (2001), §11.6.3 (Markov switching; sojourn time
/// `τ = T / (1 − pᵢᵢ)`).
#[derive(Debug, Clone, PartialEq)]
pub enum ModeTransitions {
    /// A fixed per-step matrix (rows sum to 1).
    PerStep(DMatrix<f64>),
    /// Mean sojourn time in each mode (s).
    MeanSojourn(Vec<f64>),
}

impl ModeTransitions {
    /// A fixed per-step transition matrix.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if the matrix is not square, has a negative or
    /// non-finite entry, or a row that does not sum to 1 (within `1e-9`).
    pub fn per_step(matrix: DMatrix<f64>) -> Result<Self> {
        if matrix.nrows() != matrix.ncols() || matrix.nrows() == 0 {
            return Err(EstimationError::InvalidParameter {
                name: "transition matrix",
                reason: "must be square with one row per mode",
            });
        }
        if matrix.iter().any(|p| !p.is_finite() || *p < 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "transition matrix",
                reason: "probabilities must be finite and non-negative",
            });
        }
        if matrix.row_iter().any(|row| (row.sum() - 1.0).abs() > 1e-9) {
            return Err(EstimationError::InvalidParameter {
                name: "transition matrix",
                reason: "every row must sum to 1",
            });
        }
        Ok(Self::PerStep(matrix))
    }

    /// Continuous-time switching with mean sojourn times `sojourn_s` (s), one per mode.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] for fewer than two modes or a sojourn time that is
    /// not positive and finite.
    pub fn mean_sojourn(sojourn_s: Vec<f64>) -> Result<Self> {
        if sojourn_s.len() < 2 {
            return Err(EstimationError::InvalidParameter {
                name: "sojourn times",
                reason: "an IMM needs at least two modes",
            });
        }
        if sojourn_s.iter().any(|t| !t.is_finite() || *t <= 0.0) {
            return Err(EstimationError::InvalidParameter {
                name: "sojourn times",
                reason: "every mean sojourn time must be positive and finite",
            });
        }
        Ok(Self::MeanSojourn(sojourn_s))
    }

    /// Number of modes.
    #[must_use]
    pub fn modes(&self) -> usize {
        match self {
            Self::PerStep(m) => m.nrows(),
            Self::MeanSojourn(t) => t.len(),
        }
    }

    /// The transition matrix for a step of `dt_s` seconds.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if `dt_s` is negative or not finite.
    pub fn matrix(&self, dt_s: f64) -> Result<DMatrix<f64>> {
        if !dt_s.is_finite() || dt_s < 0.0 {
            return Err(EstimationError::InvalidParameter {
                name: "dt_s",
                reason: "a mode transition step must be finite and non-negative",
            });
        }
        Ok(match self {
            Self::PerStep(m) => m.clone(),
            Self::MeanSojourn(tau) => {
                let n = tau.len();
                DMatrix::from_fn(n, n, |i, j| {
                    // pᵢᵢ = exp(−dt/τᵢ)
                    let stay = crate::math::exp(-dt_s / tau[i]);
                    if i == j {
                        stay
                    } else {
                        // pᵢⱼ = (1 − pᵢᵢ)/(M − 1)
                        (1.0 - stay) / (n - 1) as f64
                    }
                })
            }
        })
    }
}
