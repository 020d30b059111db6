//! The regularised incomplete gamma function and a normal quantile, the numerical kernels of
//! the chi-square distribution.

use crate::error::{EstimationError, Result};
use crate::math::{abs, exp, ln, sqrt};

/// From this shape parameter `a` on, `Γ(a)` is taken from Stirling's series (see
/// [`stirling_correction`]) so that the prefactor `yᵃ e⁻ʸ / Γ(a)` keeps full relative accuracy.
const STIRLING_THRESHOLD: f64 = 10.0;

/// `2π`.
const TWO_PI: f64 = core::f64::consts::TAU;

// ---------------------------------------------------------------------------------------------
// Regularised incomplete gamma function
// ---------------------------------------------------------------------------------------------

/// `P(a, y)`, the logarithms of `P` and `Q(a, y) = 1 − P(a, y)`, and the log of the prefactor
/// `yᵃ e⁻ʸ / Γ(a)`.
///
/// The logarithms are computed without forming the (possibly underflowing) tail itself, so
/// the quantile iteration can work far out in either tail.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GammaTails {
    /// `P(a, y)`, the regularised lower incomplete gamma function.
    pub(crate) lower: f64,
    /// `ln P(a, y)`.
    pub(crate) ln_lower: f64,
    /// `ln Q(a, y)`.
    pub(crate) ln_upper: f64,
    /// `ln(yᵃ e⁻ʸ / Γ(a))`; `yᵃ e⁻ʸ / Γ(a)` is `y` times the gamma density at `y`.
    pub(crate) ln_prefix: f64,
}

/// `P(a, y)` and `Q(a, y)` for `a > 0`, `y > 0` (Numerical Recipes §6.2).
///
/// The tail that is small is computed directly and the other as its complement, so both keep
/// their relative accuracy where it matters: the series gives `P` for `y < a + 1`, the
/// continued fraction gives `Q` for `y ≥ a + 1`:
///
/// ```text
/// P(a, y) = exp(ln prefix + ln Σ),      Q(a, y) = exp(ln prefix + ln CF),
/// ```
///
/// and the complement's logarithm is `ln(1 − T) = log1p(−T)`.
pub(crate) fn regularized_gamma(a: f64, y: f64) -> Result<GammaTails> {
    let ln_prefix = ln_gamma_prefix(a, y);
    if y < a + 1.0 {
        let ln_lower = ln_prefix + ln(lower_gamma_series(a, y)?);
        let lower = exp(ln_lower).min(1.0);
        let ln_upper = libm::log1p(-lower);
        Ok(GammaTails {
            lower,
            ln_lower,
            ln_upper,
            ln_prefix,
        })
    } else {
        let ln_upper = ln_prefix + ln(upper_gamma_continued_fraction(a, y)?);
        let upper = exp(ln_upper).min(1.0);
        let ln_lower = libm::log1p(-upper);
        Ok(GammaTails {
            lower: 1.0 - upper,
            ln_lower,
            ln_upper,
            ln_prefix,
        })
    }
}

/// Most terms the series or continued fraction may use: both need `O(√a)` terms near
/// `y ≈ a` (about `√(2a · ln(1/ε)) ≈ 8.6 √a` for the series).
fn max_terms(a: f64) -> usize {
    // `as` saturates; a ≤ 5e9 keeps this below 1e6.
    (200.0 + 12.0 * sqrt(a)) as usize
}

/// `Σ_{n≥0} yⁿ / (a (a+1) ⋯ (a+n))`, so that `P(a, y) = yᵃ e⁻ʸ/Γ(a) · Σ` (NR eq. 6.2.5).
///
/// Converges for all `y`; used for `y < a + 1`, where every ratio `y/(a+n)` of consecutive
/// terms is below 1.
fn lower_gamma_series(a: f64, y: f64) -> Result<f64> {
    let mut denominator = a; // a + n
    let mut term = 1.0 / a; // yⁿ / (a (a+1) ⋯ (a+n))
    let mut sum = term;
    for _ in 0..max_terms(a) {
        denominator += 1.0;
        term *= y / denominator;
        sum += term;
        if term < sum * f64::EPSILON {
            return Ok(sum);
        }
    }
    Err(EstimationError::InvalidParameter {
        name: "dof",
        reason: "the incomplete gamma series did not converge (degrees of freedom too large)",
    })
}

/// The continued fraction for `Q(a, y) = yᵃ e⁻ʸ/Γ(a) · CF` (NR eq. 6.2.7),
///
/// ```text
/// CF = 1/(y+1−a−) 1·(1−a)/(y+3−a−) 2·(2−a)/(y+5−a−) ⋯
/// ```
///
/// i.e. partial numerators `aᵢ = −i (i − a)` and denominators `bᵢ = y + 2i + 1 − a`,
/// evaluated with the modified Lentz algorithm (NR §5.2). Converges fast for `y ≥ a + 1`.
fn upper_gamma_continued_fraction(a: f64, y: f64) -> Result<f64> {
    // Stand-in for zero, so no division by zero can occur in Lentz's recurrences.
    const TINY: f64 = f64::MIN_POSITIVE / f64::EPSILON;
    let mut b = y + 1.0 - a; // b₀
    let mut c = 1.0 / TINY; // Cᵢ = Aᵢ/Aᵢ₋₁
    let mut d = 1.0 / b; // Dᵢ = Bᵢ₋₁/Bᵢ
    let mut fraction = d; // fᵢ = Π Cⱼ Dⱼ
    for i in 1..=max_terms(a) {
        let i = i as f64;
        let an = -i * (i - a);
        b += 2.0;
        // Dᵢ = 1 / (bᵢ + aᵢ Dᵢ₋₁),  Cᵢ = bᵢ + aᵢ / Cᵢ₋₁.
        d = an * d + b;
        if abs(d) < TINY {
            d = TINY;
        }
        c = b + an / c;
        if abs(c) < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = c * d;
        fraction *= delta;
        if abs(delta - 1.0) <= f64::EPSILON {
            return Ok(fraction);
        }
    }
    Err(EstimationError::InvalidParameter {
        name: "dof",
        reason: "the incomplete gamma continued fraction did not converge (degrees of freedom too large)",
    })
}

/// `ln(yᵃ e⁻ʸ / Γ(a))`, the log of the prefactor common to the series and the continued
/// fraction.
///
/// For small `a` it is `a ln y − y − ln Γ(a)`. For large `a` those three terms are huge and
/// nearly cancel, so Stirling's series `ln Γ(a) = (a − ½) ln a − a + ln √(2π) + ε(a)` is
/// substituted and, with `d = (y − a)/a`,
///
/// ```text
/// ln(yᵃ e⁻ʸ / Γ(a)) = ½ ln(a/(2π)) + a · [ln(1 + d) − d] − ε(a),
/// ```
///
/// where `ln(1 + d) − d` is computed without cancellation (see [`ln1p_minus`]).
fn ln_gamma_prefix(a: f64, y: f64) -> f64 {
    if a < STIRLING_THRESHOLD {
        return a * ln(y) - y - libm::lgamma(a);
    }
    let d = (y - a) / a;
    0.5 * ln(a / TWO_PI) + a * ln1p_minus(d, y / a) - stirling_correction(a)
}

/// `ln(1 + d) − d`, where `ratio = 1 + d` is passed separately (it is known exactly as `y/a`).
///
/// For `|d| ≤ ½`, with `t = d / (2 + d)` (so `1 + d = (1 + t)/(1 − t)` and `t·d = d²/(2 + d)`),
///
/// ```text
/// ln(1 + d) − d = 2 atanh t − d = −t·d + 2 (t³/3 + t⁵/5 + t⁷/7 + ⋯),      |t| ≤ ⅓,
/// ```
///
/// which has no cancellation. Otherwise the direct formula is accurate.
fn ln1p_minus(d: f64, ratio: f64) -> f64 {
    if abs(d) > 0.5 {
        return ln(ratio) - d;
    }
    let t = d / (2.0 + d);
    let t2 = t * t;
    let mut power = t * t2; // t^(2k+1)
    let mut odd = 3.0; // 2k + 1
    let mut series = 0.0; // Σ_{k≥1} t^(2k+1)/(2k+1)
    loop {
        let term = power / odd;
        series += term;
        if abs(term) <= abs(series) * f64::EPSILON || power == 0.0 {
            break;
        }
        power *= t2;
        odd += 2.0;
    }
    -t * d + 2.0 * series
}

/// Stirling's correction `ε(a) = ln Γ(a) − [(a − ½) ln a − a + ln √(2π)]` (DLMF 5.11.1),
///
/// ```text
/// ε(a) = 1/(12a) − 1/(360a³) + 1/(1260a⁵) − 1/(1680a⁷) + 1/(1188a⁹) − 691/(360360a¹¹) + 1/(156a¹³) − ⋯
/// ```
///
/// whose first omitted term is below `3e-17` for `a ≥ 10`.
fn stirling_correction(a: f64) -> f64 {
    let r = 1.0 / (a * a);
    let series = 1.0 / 12.0
        - r * (1.0 / 360.0
            - r * (1.0 / 1260.0 - r * (1.0 / 1680.0 - r * (1.0 / 1188.0 - r * (691.0 / 360_360.0 - r / 156.0)))));
    series / a
}

// ---------------------------------------------------------------------------------------------
// Normal quantile (starting values only)
// ---------------------------------------------------------------------------------------------

/// Standard normal quantile `Φ⁻¹(p)` by Acklam's rational approximation (relative error below
/// `1.2e-9`) — used only as the Wilson–Hilferty starting value, which Newton then refines.
///
/// Central region `|p − ½| ≤ ½ − p_low`: `z = q · A(q²)/B(q²)` with `q = p − ½`;
/// tails: `z = ±C(s)/D(s)` with `s = √(−2 ln p_tail)`.
pub(crate) fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const P_LOW: f64 = 0.02425;

    // Horner evaluation of c₀xⁿ + c₁xⁿ⁻¹ + ⋯ + cₙ, extended by one more degree with constant
    // term 1 (i.e. `· x + 1`) if `plus_one`.
    fn horner(coefficients: &[f64], x: f64, plus_one: bool) -> f64 {
        let value = coefficients.iter().fold(0.0, |acc, &c| acc * x + c);
        if plus_one {
            value * x + 1.0
        } else {
            value
        }
    }

    let tail = |p_tail: f64| -> f64 {
        let s = sqrt(-2.0 * ln(p_tail));
        horner(&C, s, false) / horner(&D, s, true)
    };
    if p < P_LOW {
        tail(p)
    } else if p <= 1.0 - P_LOW {
        let q = p - 0.5;
        let r = q * q;
        q * horner(&A, r, false) / horner(&B, r, true)
    } else {
        -tail(1.0 - p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::test_support::assert_relative;

    #[test]
    fn normal_quantile_is_close_to_scipy() {
        let table = [
            (1e-9, -5.9978070150076865),
            (0.001, -3.090232306167813),
            (0.02, -2.053748910631823),
            (0.3, -0.5244005127080409),
            (0.98, 2.0537489106318225),
            (0.999999, 4.753424308817087),
        ];
        for &(p, z) in &table {
            assert_relative(normal_quantile(p), z, 2e-9, "normal quantile");
        }
        assert_eq!(normal_quantile(0.5), 0.0);
    }

    #[test]
    fn stirling_prefix_agrees_with_direct_formula() {
        // Where both are accurate, the two forms of ln(yᵃe⁻ʸ/Γ(a)) must agree.
        for &a in &[10.0, 12.5, 30.0] {
            for &y in &[0.5 * a, a, 1.5 * a, 3.0 * a] {
                let direct = a * ln(y) - y - libm::lgamma(a);
                let error = abs(ln_gamma_prefix(a, y) - direct);
                assert!(error < 1e-12, "ln gamma prefix at a = {a}, y = {y}: error {error:e}");
            }
        }
    }
}
