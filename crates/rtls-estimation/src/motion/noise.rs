//! Process noise of the kinematic models: a discrete white-noise sequence entering through a
//! gain `G(dt)`, or continuous white noise integrated exactly over the step.

use crate::error::{EstimationError, Result};
use crate::gaussian::Matrix;

/// `xⁿ` for an integer `n`, by repeated squaring (no `powi`, so it also works in `no_std`).
///
/// `x⁰ = 1` for every `x`, including `0`; a negative `n` gives `1 / x^|n|`.
#[inline]
fn int_pow(x: f64, n: i32) -> f64 {
    let mut base = x;
    let mut exponent = n.unsigned_abs();
    let mut result = 1.0;
    while exponent > 0 {
        if exponent & 1 == 1 {
            result *= base;
        }
        base *= base;
        exponent >>= 1;
    }
    if n < 0 {
        1.0 / result
    } else {
        result
    }
}

/// One entry `g(dt) = coefficient · dtᵖᵒʷᵉʳ` of a per-axis noise gain.
///
/// # Units
/// `dt` in seconds; the entry's unit is whatever makes `g · w` the unit of its state component
/// (e.g. `dt²/2` in s² maps an acceleration `w` in m/s² to metres).
///
/// # Example
/// ```
/// use rtls_estimation::motion::GainTerm;
/// let half_dt_squared = GainTerm { coefficient: 0.5, power: 2 };
/// assert_eq!(half_dt_squared.value(2.0), 2.0);
/// ```
///
/// # References
/// Seed 000 eq. (5); Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
/// Navigation* (2001), §6.3.2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainTerm {
    /// Constant factor (dimensionless).
    pub coefficient: f64,
    /// Power of `dt`; must be `≥ 0` (see [`ProcessNoise::validate`]).
    pub power: i32,
}

impl GainTerm {
    /// The term `0 · dt⁰`, i.e. no noise enters this derivative order.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::GainTerm;
    /// assert_eq!(GainTerm::ZERO.value(3.0), 0.0);
    /// ```
    pub const ZERO: Self = Self {
        coefficient: 0.0,
        power: 0,
    };

    /// Builds the term `coefficient · dtᵖᵒʷᵉʳ`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::GainTerm;
    /// assert_eq!(GainTerm::new(1.0, 1).value(0.1), 0.1);
    /// ```
    #[inline]
    #[must_use]
    pub const fn new(coefficient: f64, power: i32) -> Self {
        Self { coefficient, power }
    }

    /// The value `coefficient · dtᵖᵒʷᵉʳ` for a step of `dt_s` seconds (`dt⁰ = 1`, also at `dt = 0`).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::GainTerm;
    /// assert_eq!(GainTerm::new(0.25, 2).value(2.0), 1.0);
    /// ```
    #[inline]
    #[must_use]
    pub fn value(&self, dt_s: f64) -> f64 {
        // g = c · dtᵖ
        self.coefficient * int_pow(dt_s, self.power)
    }
}

/// Per-axis noise gain `G(dt) = [g₀(dt), g₁(dt), g₂(dt)]ᵀ`, indexed by derivative order
/// (position, velocity, acceleration): the discrete noise `w` of one axis adds `gₖ(dt) · w` to
/// the `k`-th derivative.
///
/// The constant-velocity model uses `terms[0..2]`, the constant-acceleration model all three.
///
/// # Units
/// `dt` in seconds. With [`NoiseGain::kinematic`], `w` is an acceleration (m/s²) for the CV model
/// and an acceleration increment over the step (m/s²) for the CA model.
///
/// # Example
/// ```
/// use rtls_estimation::motion::NoiseGain;
/// assert_eq!(NoiseGain::kinematic().values(2.0), [2.0, 2.0, 1.0]);
/// ```
///
/// # References
/// Seed 000 eq. (5)–(6) and seed 001 (`[T²/2, T]ᵀ`); seed 004 eq. (8) and (10) (`[T/2, 1]ᵀ`,
/// `[T²/4, T/2, 1]ᵀ`); Bar-Shalom et al. (2001), §6.3.2–§6.3.3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseGain {
    /// `[g₀, g₁, g₂]`: gain onto position, velocity and acceleration.
    pub terms: [GainTerm; 3],
}

impl NoiseGain {
    /// A gain from explicit terms.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{GainTerm, NoiseGain};
    /// let g = NoiseGain::new([GainTerm::new(0.5, 2), GainTerm::new(1.0, 1), GainTerm::ZERO]);
    /// assert_eq!(g.values(1.0), [0.5, 1.0, 0.0]);
    /// ```
    #[inline]
    #[must_use]
    pub const fn new(terms: [GainTerm; 3]) -> Self {
        Self { terms }
    }

    /// Bar-Shalom's kinematic gain `G = [dt²/2, dt, 1]ᵀ`: a piecewise-constant white acceleration
    /// (CV) or acceleration increment (CA) integrated over the step.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::NoiseGain;
    /// assert_eq!(NoiseGain::kinematic().values(0.5), [0.125, 0.5, 1.0]);
    /// ```
    ///
    /// # References
    /// Seed 000 eq. (5)–(6) (matrix `C`); seed 001 (matrix `G`); Bar-Shalom et al. (2001),
    /// §6.3.2 (discrete white-noise acceleration) and §6.3.3 (discrete Wiener-process
    /// acceleration).
    #[inline]
    #[must_use]
    pub const fn kinematic() -> Self {
        Self::new([GainTerm::new(0.5, 2), GainTerm::new(1.0, 1), GainTerm::new(1.0, 0)])
    }

    /// Seed 004's constant-velocity gain, as printed: `G = [dt/2, 1, 0]ᵀ`.
    ///
    /// Reproduced for fidelity to the paper. Note that, unlike [`NoiseGain::kinematic`], it is
    /// not the integral of an acceleration over the step (position gets `dt/2 · w`, velocity
    /// `1 · w`, so `w` acts as a velocity increment in m/s); prefer the kinematic gain otherwise.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::NoiseGain;
    /// assert_eq!(NoiseGain::seed_004_cv().values(2.0), [1.0, 1.0, 0.0]);
    /// ```
    ///
    /// # References
    /// Seed 004 eq. (8) (matrix `G`).
    #[inline]
    #[must_use]
    pub const fn seed_004_cv() -> Self {
        Self::new([GainTerm::new(0.5, 1), GainTerm::new(1.0, 0), GainTerm::ZERO])
    }

    /// Seed 004's constant-acceleration gain, as printed: `G = [dt²/4, dt/2, 1]ᵀ`.
    ///
    /// Half the position and velocity gains of [`NoiseGain::kinematic`]; reproduced for fidelity
    /// to the paper.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::NoiseGain;
    /// assert_eq!(NoiseGain::seed_004_ca().values(2.0), [1.0, 1.0, 1.0]);
    /// ```
    ///
    /// # References
    /// Seed 004 eq. (10) (matrix `Gᵐ`).
    #[inline]
    #[must_use]
    pub const fn seed_004_ca() -> Self {
        Self::new([GainTerm::new(0.25, 2), GainTerm::new(0.5, 1), GainTerm::new(1.0, 0)])
    }

    /// The gain values `[g₀(dt), g₁(dt), g₂(dt)]` for a step of `dt_s` seconds.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::NoiseGain;
    /// let [g0, g1, _] = NoiseGain::kinematic().values(0.1);
    /// assert!((g0 - 0.005).abs() < 1e-15 && (g1 - 0.1).abs() < 1e-15);
    /// ```
    #[inline]
    #[must_use]
    pub fn values(&self, dt_s: f64) -> [f64; 3] {
        [
            self.terms[0].value(dt_s),
            self.terms[1].value(dt_s),
            self.terms[2].value(dt_s),
        ]
    }
}

/// How process noise enters a kinematic (CV/CA/CT) model, per axis; axes are independent and
/// share the same noise.
///
/// - [`ProcessNoise::DiscreteWhiteNoise`]: one noise sample `w ~ N(0, σ²)` per step and axis,
///   entering through the gain `G(dt)`: `Q_axis = G σ² Gᵀ`.
/// - [`ProcessNoise::Continuous`]: white noise of power spectral density `q` on the highest
///   derivative (acceleration for CV, jerk for CA), integrated exactly over the step:
///   `Q_axis = ∫₀^dt Φ(τ) L q Lᵀ Φ(τ)ᵀ dτ`, which gives
///   CV `q·[[dt³/3, dt²/2], [dt²/2, dt]]` and
///   CA `q·[[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]`.
///
/// # Units
/// Discrete `variance`: the square of `w`'s unit (m²/s⁴ with the kinematic gain);
/// continuous `spectral_density`: m²/s³ for CV (white acceleration), m²/s⁵ for CA (white jerk).
///
/// # Example
/// ```
/// use rtls_estimation::motion::{NoiseGain, ProcessNoise};
/// // Seed 000: σ_w² = 5 (m/s²)² per axis.
/// let noise = ProcessNoise::discrete(5.0, NoiseGain::kinematic());
/// assert!(noise.validate().is_ok());
/// assert!(ProcessNoise::continuous(-1.0).validate().is_err());
/// ```
///
/// # References
/// Seed 000 eq. (5)–(6) (`C Q Cᵀ`); seed 004 eq. (8) and (10); Bar-Shalom et al. (2001),
/// §6.2.2 (continuous white-noise acceleration), §6.2.3 (continuous Wiener-process
/// acceleration), §6.3.2–§6.3.3 (discrete white-noise models).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProcessNoise {
    /// Discrete white noise `w ~ N(0, variance)` per step and axis through `gain`.
    DiscreteWhiteNoise {
        /// `σ²` of `w` (square of `w`'s unit, m²/s⁴ with the kinematic gain); finite, `≥ 0`.
        variance: f64,
        /// Per-axis gain `G(dt)`.
        gain: NoiseGain,
    },
    /// Continuous white noise on the highest derivative, of power spectral density
    /// `spectral_density` (m²/s³ for CV, m²/s⁵ for CA); finite, `≥ 0`.
    Continuous {
        /// `q`, the power spectral density.
        spectral_density: f64,
    },
}

impl ProcessNoise {
    /// Discrete white noise of variance `variance` through `gain` (not validated here: the
    /// models' constructors call [`ProcessNoise::validate`]).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{NoiseGain, ProcessNoise};
    /// let noise = ProcessNoise::discrete(0.25, NoiseGain::seed_004_cv());
    /// assert!(matches!(noise, ProcessNoise::DiscreteWhiteNoise { variance, .. } if variance == 0.25));
    /// ```
    ///
    /// # References
    /// Seed 000 eq. (5)–(6); Bar-Shalom et al. (2001), §6.3.2.
    #[inline]
    #[must_use]
    pub const fn discrete(variance: f64, gain: NoiseGain) -> Self {
        Self::DiscreteWhiteNoise { variance, gain }
    }

    /// Continuous white noise of power spectral density `q` (not validated here).
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::ProcessNoise;
    /// let noise = ProcessNoise::continuous(0.1);
    /// assert_eq!(noise, ProcessNoise::Continuous { spectral_density: 0.1 });
    /// ```
    ///
    /// # References
    /// Bar-Shalom et al. (2001), §6.2.2–§6.2.3.
    #[inline]
    #[must_use]
    pub const fn continuous(q: f64) -> Self {
        Self::Continuous { spectral_density: q }
    }

    /// Checks the parameters: the variance or spectral density is finite and `≥ 0`, the gain
    /// coefficients are finite and the gain powers `≥ 0` (so `G(dt)` stays finite as `dt → 0`).
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] naming `variance`, `spectral_density` or `gain`.
    ///
    /// # Example
    /// ```
    /// use rtls_estimation::motion::{NoiseGain, ProcessNoise};
    /// assert!(ProcessNoise::discrete(f64::NAN, NoiseGain::kinematic()).validate().is_err());
    /// assert!(ProcessNoise::continuous(0.0).validate().is_ok());
    /// ```
    pub fn validate(&self) -> Result<()> {
        match self {
            Self::DiscreteWhiteNoise { variance, gain } => {
                if !variance.is_finite() || *variance < 0.0 {
                    return Err(EstimationError::InvalidParameter {
                        name: "variance",
                        reason: "the process noise variance must be finite and non-negative",
                    });
                }
                for term in &gain.terms {
                    if !term.coefficient.is_finite() {
                        return Err(EstimationError::InvalidParameter {
                            name: "gain",
                            reason: "every noise gain coefficient must be finite",
                        });
                    }
                    if term.power < 0 {
                        return Err(EstimationError::InvalidParameter {
                            name: "gain",
                            reason: "every noise gain power of dt must be non-negative",
                        });
                    }
                }
                Ok(())
            }
            Self::Continuous { spectral_density } => {
                if !spectral_density.is_finite() || *spectral_density < 0.0 {
                    return Err(EstimationError::InvalidParameter {
                        name: "spectral_density",
                        reason: "the process noise spectral density must be finite and non-negative",
                    });
                }
                Ok(())
            }
        }
    }

    /// Writes `blockdiag(Q_axis, …)` of constant-velocity blocks for `axes` axes into `q`, the
    /// block of axis `i` at rows/columns `2i, 2i+1` (the CV layout `[x, vx, y, vy, z, vz]`).
    #[inline]
    pub(crate) fn write_cv_blocks<const N: usize>(&self, dt_s: f64, axes: usize, q: &mut Matrix<N>) {
        // Q_axis = G σ² Gᵀ (discrete) or q·[[dt³/3, dt²/2], [dt²/2, dt]] (continuous)
        let block = self.cv_axis_block(dt_s);
        for axis in 0..axes {
            let base = 2 * axis;
            for (i, row) in block.iter().enumerate() {
                for (j, &value) in row.iter().enumerate() {
                    q[(base + i, base + j)] = value;
                }
            }
        }
    }

    /// Per-axis `2 × 2` process noise `[position, velocity]` of the constant-velocity model.
    ///
    /// Discrete: `G σ² Gᵀ` with `G = [g₀, g₁]ᵀ`; continuous: `q·[[dt³/3, dt²/2], [dt²/2, dt]]`.
    #[inline]
    pub(crate) fn cv_axis_block(&self, dt_s: f64) -> [[f64; 2]; 2] {
        match *self {
            Self::DiscreteWhiteNoise { variance, gain } => {
                // G = [g₀(dt), g₁(dt)]ᵀ
                let [g0, g1, _] = gain.values(dt_s);
                // Q = G σ² Gᵀ, as σ²·(gᵢ gⱼ) so that Q is exactly symmetric
                [
                    [variance * (g0 * g0), variance * (g0 * g1)],
                    [variance * (g1 * g0), variance * (g1 * g1)],
                ]
            }
            Self::Continuous { spectral_density: q } => {
                let dt2 = dt_s * dt_s;
                let dt3 = dt2 * dt_s;
                // Q = q·[[dt³/3, dt²/2], [dt²/2, dt]]
                [[q * dt3 / 3.0, q * dt2 / 2.0], [q * dt2 / 2.0, q * dt_s]]
            }
        }
    }

    /// Per-axis `3 × 3` process noise `[position, velocity, acceleration]` of the
    /// constant-acceleration model.
    ///
    /// Discrete: `G σ² Gᵀ` with `G = [g₀, g₁, g₂]ᵀ`; continuous (white jerk):
    /// `q·[[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]`.
    #[inline]
    pub(crate) fn ca_axis_block(&self, dt_s: f64) -> [[f64; 3]; 3] {
        match *self {
            Self::DiscreteWhiteNoise { variance, gain } => {
                // G = [g₀(dt), g₁(dt), g₂(dt)]ᵀ
                let g = gain.values(dt_s);
                // Q = G σ² Gᵀ, as σ²·(gᵢ gⱼ) so that Q is exactly symmetric
                let mut q = [[0.0; 3]; 3];
                for (i, row) in q.iter_mut().enumerate() {
                    for (j, entry) in row.iter_mut().enumerate() {
                        *entry = variance * (g[i] * g[j]);
                    }
                }
                q
            }
            Self::Continuous { spectral_density: q } => {
                let dt2 = dt_s * dt_s;
                let dt3 = dt2 * dt_s;
                let dt4 = dt3 * dt_s;
                let dt5 = dt4 * dt_s;
                // Q = q·[[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]
                [
                    [q * dt5 / 20.0, q * dt4 / 8.0, q * dt3 / 6.0],
                    [q * dt4 / 8.0, q * dt3 / 3.0, q * dt2 / 2.0],
                    [q * dt3 / 6.0, q * dt2 / 2.0, q * dt_s],
                ]
            }
        }
    }
}

/// Test helpers shared by the motion models' unit tests.
#[cfg(test)]
pub(super) mod test_support {
    use crate::gaussian::Matrix;

    /// `|a − b| ≤ tol · max(1, |a|, |b|)`.
    pub(crate) fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * 1.0_f64.max(a.abs()).max(b.abs())
    }

    /// Asserts `a ≈ b` entry-wise, relative to the largest entry of `b` (or 1).
    pub(crate) fn assert_matrix_close<const N: usize>(a: &Matrix<N>, b: &Matrix<N>, tol: f64) {
        let scale = b.amax().max(1.0);
        for i in 0..N {
            for j in 0..N {
                assert!(
                    (a[(i, j)] - b[(i, j)]).abs() <= tol * scale,
                    "entry ({i}, {j}): {} vs {} (tol {tol}, scale {scale})\n{a}{b}",
                    a[(i, j)],
                    b[(i, j)]
                );
            }
        }
    }

    /// Asserts that `q` is exactly symmetric and positive semi-definite (smallest eigenvalue
    /// `≥ −1e-12 · max|q|`).
    pub(crate) fn assert_symmetric_psd<const N: usize>(q: &Matrix<N>) {
        assert_eq!(*q, q.transpose(), "Q is not symmetric:\n{q}");
        // (dynamic copy: the eigen-decomposition of a generic `Const<N>` needs `DimSub` bounds)
        let dynamic = nalgebra::DMatrix::from_iterator(N, N, q.iter().copied());
        let min_eigenvalue = dynamic.symmetric_eigen().eigenvalues.min();
        assert!(
            min_eigenvalue >= -1e-12 * q.amax().max(1.0),
            "Q has eigenvalue {min_eigenvalue}:\n{q}"
        );
    }

    /// `∫₀^dt F(τ) L q Lᵀ F(τ)ᵀ dτ` by composite Simpson with `intervals` (even) sub-intervals,
    /// where `L` has one unit column per index in `driven` (the white-noise inputs).
    pub(crate) fn simpson_continuous_q<const N: usize>(
        transition: impl Fn(f64) -> Matrix<N>,
        driven: &[usize],
        q: f64,
        dt_s: f64,
        intervals: usize,
    ) -> Matrix<N> {
        assert!(intervals.is_multiple_of(2));
        let h = dt_s / intervals as f64;
        let integrand = |tau: f64| {
            let f = transition(tau);
            let mut m = Matrix::<N>::zeros();
            for &k in driven {
                // F L q Lᵀ Fᵀ = q Σ_k F[:, k] F[:, k]ᵀ
                let column = f.column(k);
                m += column * column.transpose() * q;
            }
            m
        };
        let mut sum = integrand(0.0) + integrand(dt_s);
        for i in 1..intervals {
            let weight = if i % 2 == 1 { 4.0 } else { 2.0 };
            sum += integrand(i as f64 * h) * weight;
        }
        sum * (h / 3.0)
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::close;
    use super::*;

    #[test]
    fn int_pow_matches_repeated_multiplication() {
        assert_eq!(int_pow(0.0, 0), 1.0);
        assert_eq!(int_pow(3.0, 0), 1.0);
        assert_eq!(int_pow(3.0, 1), 3.0);
        assert_eq!(int_pow(3.0, 5), 243.0);
        assert_eq!(int_pow(-2.0, 3), -8.0);
        assert_eq!(int_pow(2.0, -2), 0.25);
        assert!(close(int_pow(1.1, 7), 1.1 * 1.1 * 1.1 * 1.1 * 1.1 * 1.1 * 1.1, 1e-15));
    }

    #[test]
    fn named_gains_have_the_printed_values() {
        let dt = 0.3;
        let k = NoiseGain::kinematic().values(dt);
        assert!(close(k[0], dt * dt / 2.0, 1e-15) && close(k[1], dt, 1e-15) && k[2] == 1.0);
        let cv = NoiseGain::seed_004_cv().values(dt);
        assert!(close(cv[0], dt / 2.0, 1e-15) && cv[1] == 1.0 && cv[2] == 0.0);
        let ca = NoiseGain::seed_004_ca().values(dt);
        assert!(close(ca[0], dt * dt / 4.0, 1e-15) && close(ca[1], dt / 2.0, 1e-15) && ca[2] == 1.0);
    }

    #[test]
    fn discrete_cv_block_with_kinematic_gain_is_the_textbook_matrix() {
        let sigma2 = 5.0;
        let dt = 0.7;
        let q = ProcessNoise::discrete(sigma2, NoiseGain::kinematic()).cv_axis_block(dt);
        let expected = [
            [sigma2 * dt * dt * dt * dt / 4.0, sigma2 * dt * dt * dt / 2.0],
            [sigma2 * dt * dt * dt / 2.0, sigma2 * dt * dt],
        ];
        for i in 0..2 {
            for j in 0..2 {
                assert!(close(q[i][j], expected[i][j], 1e-14), "Q[{i}][{j}] = {}", q[i][j]);
            }
        }
    }

    #[test]
    fn discrete_ca_block_with_seed_004_gain_is_outer_product() {
        let sigma2 = 2.0;
        let dt = 0.5;
        let q = ProcessNoise::discrete(sigma2, NoiseGain::seed_004_ca()).ca_axis_block(dt);
        let g = [dt * dt / 4.0, dt / 2.0, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                assert!(close(q[i][j], g[i] * sigma2 * g[j], 1e-15));
            }
        }
        assert!(close(q[0][0], 2.0 / 256.0, 1e-15));
    }

    #[test]
    fn validate_rejects_bad_parameters() {
        let bad_variance = |v: f64| ProcessNoise::discrete(v, NoiseGain::kinematic()).validate();
        assert!(bad_variance(1.0).is_ok());
        assert!(bad_variance(0.0).is_ok());
        for v in [-1e-9, f64::NAN, f64::INFINITY] {
            assert_eq!(
                bad_variance(v),
                Err(EstimationError::InvalidParameter {
                    name: "variance",
                    reason: "the process noise variance must be finite and non-negative",
                })
            );
        }
        for q in [-0.5, f64::NAN, f64::NEG_INFINITY] {
            assert!(matches!(
                ProcessNoise::continuous(q).validate(),
                Err(EstimationError::InvalidParameter {
                    name: "spectral_density",
                    ..
                })
            ));
        }
        let negative_power = NoiseGain::new([GainTerm::new(1.0, -1), GainTerm::ZERO, GainTerm::ZERO]);
        assert!(matches!(
            ProcessNoise::discrete(1.0, negative_power).validate(),
            Err(EstimationError::InvalidParameter { name: "gain", .. })
        ));
        let nan_coefficient = NoiseGain::new([GainTerm::new(f64::NAN, 1), GainTerm::ZERO, GainTerm::ZERO]);
        assert!(ProcessNoise::discrete(1.0, nan_coefficient).validate().is_err());
    }
}
