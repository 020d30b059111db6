//! `X_b = cov(eₓ, e_b)`: a track's state error's cross-covariance with the errors of the range
//! offsets it has learnt ([`super::range_bias`]), so an offset's error is considered rather
//! than averaged away (Schmidt–Kalman).
//!
//! An anchor's offset error `e_bᵢ = bᵢ − b̂ᵢ` is the same in every range of that anchor until the
//! offsets learn again. Taken as fresh noise of each range (`R' = R + P_bᵢᵢ`), it is averaged
//! away over a few readings and the track reports ellipses smaller than its error (the
//! labyrinth robot's 95 % ellipses held the truth 38 % of the time with offsets learnt at
//! +0.07…+0.14 m against a prior of 0.2 m, docs/EVALUATION.md). Considered, each range is
//!
//! ```text
//! z' = r − b̂ᵢ = h(x) + J e_b + w,   J = eᵢᵀ (1 × K),   w ~ N(0, λ c σ²)
//! ```
//!
//! taken by [`rtls_estimation::filter::consider_update`] with `X_b`'s column `i` and `P_bᵢᵢ`;
//! the update gives column `i`, and every other column `j` follows from the same gain:
//!
//! ```text
//! A = I − K H,   X_bⱼ ← A X_bⱼ − K P_bᵢⱼ
//! ```
//!
//! Between updates `X_b ← F X_b` (the offsets' random walk is independent of the state); any
//! other update of the state carries it as `X_b ← P⁺ (P⁻)⁻¹ X_b`; a learning round of the
//! offsets, a measurement of `b` alone that no position error enters (its projection removes
//! them), gives `X_b ← X_b (P_b⁻)⁻¹ P_b⁺`.
//!
//! # References
//! Schmidt (1966); Simon (2006) §7.5; Bar-Shalom, Li & Kirubarajan (2001) §11.2 (sensor bias).

use nalgebra::{DMatrix, SVector};
use rtls_estimation::{Gaussian, Matrix};

use super::heading_cross::cv_transition;
use rtls_estimation::EstimationError;

use crate::error::Result;

/// `X_b` at `time_s`: one `N`-column per slot of the track's offset vector (slots beyond
/// `columns` have no correlation yet).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct OffsetCross<const N: usize> {
    time_s: f64,
    columns: Vec<SVector<f64, N>>,
}

impl<const N: usize> OffsetCross<N> {
    /// No correlation yet, at `time_s`.
    pub(super) fn new(time_s: f64) -> Self {
        Self {
            time_s,
            columns: Vec::new(),
        }
    }

    /// `X_b` predicted to `time_s`, `F(Δt) X_b`.
    pub(super) fn predicted(&self, time_s: f64) -> Self {
        let f = cv_transition::<N>((time_s - self.time_s).max(0.0));
        Self {
            time_s: time_s.max(self.time_s),
            columns: self.columns.iter().map(|c| f * c).collect(),
        }
    }

    /// Column `slot` (zero when the slot has no correlation yet).
    pub(super) fn column(&self, slot: usize) -> SVector<f64, N> {
        self.columns.get(slot).copied().unwrap_or_else(SVector::zeros)
    }

    /// `X_b ← F(Δt) X_b` in place, to `time_s` (no earlier than its time).
    pub(super) fn predict_to(&mut self, time_s: f64) {
        if time_s > self.time_s {
            let f = cv_transition::<N>(time_s - self.time_s);
            for column in &mut self.columns {
                *column = f * *column;
            }
            self.time_s = time_s;
        }
    }

    /// After a considered range of slot `slot` (this `X_b` at its time): column `slot` is the
    /// update's `considered`, every other `X_bⱼ ← A X_bⱼ − K P_b[slot, j]` with `A = I − K H`
    /// and `offset_row` the row `P_b[slot, ·]` before the update.
    pub(super) fn after_considered_range(
        &mut self,
        a: &Matrix<N>,
        gain: &SVector<f64, N>,
        offset_row: &[f64],
        slot: usize,
        considered: SVector<f64, N>,
    ) {
        let slots = offset_row.len().max(self.columns.len()).max(slot + 1);
        self.columns.resize(slots, SVector::zeros());
        for (j, column) in self.columns.iter_mut().enumerate() {
            if j == slot {
                *column = considered;
            } else {
                // X_bⱼ ← A X_bⱼ − K P_b[i, j]
                *column = a * *column - gain * offset_row.get(j).copied().unwrap_or(0.0);
            }
        }
    }

    /// After an update of the state that did not involve the offsets, from `prior` to
    /// `posterior`: `X_b ← P⁺ (P⁻)⁻¹ F X_b`.
    ///
    /// # Errors
    /// A prior covariance that is not positive definite; a non-finite result.
    pub(super) fn after_position_update(&self, prior: &Gaussian<N>, posterior: &Gaussian<N>) -> Result<Self> {
        let predicted = self.predicted(posterior.time_s());
        let chol = prior
            .covariance()
            .cholesky()
            .ok_or(EstimationError::NotPositiveDefinite {
                what: "prior covariance",
            })?;
        let columns: Vec<SVector<f64, N>> = predicted
            .columns
            .iter()
            // X⁺ = P⁺ (P⁻)⁻¹ X
            .map(|c| posterior.covariance() * chol.solve(c))
            .collect();
        finite(Self {
            time_s: predicted.time_s,
            columns,
        })
    }

    /// After an update with gain `K` of the measurement `H` that did not involve the offsets
    /// (a considered speed): `X_b ← (I − K H) F X_b`.
    pub(super) fn after_gain(&self, time_s: f64, a: &Matrix<N>) -> Self {
        let predicted = self.predicted(time_s);
        Self {
            time_s: predicted.time_s,
            columns: predicted.columns.iter().map(|c| a * c).collect(),
        }
    }

    /// After a learning round took the offsets' covariance from `prior` to `posterior`
    /// (`K × K`, slot order): `X_b ← X_b (P_b⁻)⁻¹ P_b⁺`, the state's mean and covariance kept;
    /// `None` when the prior cannot be factorised (the correlation is then forgotten).
    ///
    /// Conditioning state and offsets jointly on the round would also move the state,
    /// `x̂ ← x̂ + X_b (P_b⁻)⁻¹ Δb̂`, and shrink `P` by `X_b (P_b⁻)⁻¹ (P_b⁻ − P_b⁺) (P_b⁻)⁻¹ X_bᵀ`.
    /// But the round's readings have already updated the state, so that would take their
    /// noise twice: tried, it cost the labyrinth robot's tuned track 0.110 → 0.137 m
    /// (docs/EVALUATION.md). Keeping `P` is the conservative side.
    pub(super) fn after_learning(&self, prior: &DMatrix<f64>, posterior: &DMatrix<f64>) -> Option<Self> {
        let slots = prior.ncols();
        if slots == 0 {
            return Some(self.clone());
        }
        // X_b (N × K), zero columns for slots without a correlation yet
        let x = DMatrix::from_fn(N, slots, |row, slot| self.column(slot)[row]);
        // X_b (P_b⁻)⁻¹ P_b⁺ = ((P_b⁻)⁻¹ X_bᵀ)ᵀ P_b⁺
        let carried = prior.clone().cholesky()?.solve(&x.transpose()).transpose() * posterior;
        if carried.iter().any(|v| !v.is_finite()) {
            return None;
        }
        Some(Self {
            time_s: self.time_s,
            columns: (0..slots)
                .map(|slot| SVector::from_fn(|row, _| carried[(row, slot)]))
                .collect(),
        })
    }

    /// `X_b ← c X_b` (the state's covariance scaled by `c²`).
    pub(super) fn scale(&mut self, c: f64) {
        for column in &mut self.columns {
            *column *= c;
        }
    }
}

fn finite<const N: usize>(cross: OffsetCross<N>) -> Result<OffsetCross<N>> {
    if cross.columns.iter().all(|c| c.iter().all(|v| v.is_finite())) {
        Ok(cross)
    } else {
        Err(EstimationError::NonFinite {
            what: "offset cross-covariance",
        }
        .into())
    }
}
