//! `X = cov(eₓ, e_h)`: a track's state error's cross-covariance with its heading channel's
//! error, and how every step of either filter carries it (the equations are in
//! [`super::consider`], which takes speeds with it).

use nalgebra::{Matrix3, SMatrix};
use rtls_estimation::aided::HeadingModel;
use rtls_estimation::filter::carry_cross_covariance;
use rtls_estimation::{Gaussian, Matrix};

use crate::error::Result;

/// `X = cov(eₓ, e_h)` (`N × 3`) at `time_s`, the position filter's side; the channel's side is
/// always its current state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct HeadingCross<const N: usize> {
    time_s: f64,
    cross: SMatrix<f64, N, 3>,
}

/// `F(Δt)` of the constant-velocity layout `[x, v_x, y, v_y, …]`: per axis `[[1, Δt], [0, 1]]`.
pub(super) fn cv_transition<const N: usize>(dt_s: f64) -> Matrix<N> {
    let mut f = Matrix::<N>::identity();
    // N / 2 tracked axes
    for axis in 0..N / 2 {
        f[(2 * axis, 2 * axis + 1)] = dt_s;
    }
    f
}

impl<const N: usize> HeadingCross<N> {
    /// `X` at `time_s`.
    pub(super) fn new(time_s: f64, cross: SMatrix<f64, N, 3>) -> Self {
        Self { time_s, cross }
    }

    /// `X` predicted to `time_s`, `F(Δt) X`.
    pub(super) fn predicted(&self, time_s: f64) -> SMatrix<f64, N, 3> {
        cv_transition::<N>((time_s - self.time_s).max(0.0)) * self.cross
    }

    /// After an update of the position filter from `prior` to `posterior` that did not involve
    /// the heading (a fix, a range): `X ← P⁺ (P⁻)⁻¹ F X`.
    ///
    /// # Errors
    /// A prior covariance that is not positive definite; a non-finite result.
    pub(super) fn after_position_update(&self, prior: &Gaussian<N>, posterior: &Gaussian<N>) -> Result<Self> {
        let time_s = posterior.time_s();
        let cross = carry_cross_covariance(prior.covariance(), posterior.covariance(), &self.predicted(time_s))?;
        Ok(Self { time_s, cross })
    }

    /// After an update with `A = I − K H` that did not involve the heading but whose
    /// covariance is not `A P⁻` (a considered range): `X ← A F X`.
    pub(super) fn after_gain(&self, time_s: f64, a: &Matrix<N>) -> Self {
        Self {
            time_s,
            cross: a * self.predicted(time_s),
        }
    }

    /// `X ← c X` (the state's covariance scaled by `c²`).
    pub(super) fn scale(&mut self, c: f64) {
        self.cross *= c;
    }

    /// After the heading channel predicted over `dt_s` (with a held yaw rate or not):
    /// `X ← X Φᵀ`.
    pub(super) fn after_heading_prediction(&mut self, dt_s: f64, rate_held: bool) {
        self.cross *= HeadingModel::transition(dt_s, rate_held).transpose();
    }

    /// After the heading channel's update from `prior` to `posterior` covariance:
    /// `X ← X (P_h⁺ (P_h⁻)⁻¹)ᵀ = X (P_h⁻)⁻¹ P_h⁺`; `None` when the prior cannot be factorised
    /// (the correlation is then forgotten).
    pub(super) fn after_heading_update(&self, prior: &Matrix3<f64>, posterior: &Matrix3<f64>) -> Option<Self> {
        // X (P_h⁻)⁻¹ = ((P_h⁻)⁻¹ Xᵀ)ᵀ
        let chol = prior.cholesky()?;
        Some(Self {
            time_s: self.time_s,
            cross: chol.solve(&self.cross.transpose()).transpose() * posterior,
        })
    }
}
