//! Scalar float functions that work both with `std` and in `no_std` (through `libm`), and
//! small matrix helpers shared by the filters.

use nalgebra::{allocator::Allocator, DefaultAllocator, Dim, OMatrix};

use crate::error::{EstimationError, Result};

/// `√x`.
#[inline]
pub(crate) fn sqrt(x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        x.sqrt()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::sqrt(x)
    }
}

/// `sin x`, `cos x`.
#[inline]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    #[cfg(feature = "std")]
    {
        x.sin_cos()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::sincos(x)
    }
}

/// `atan2(y, x)`.
#[inline]
pub(crate) fn atan2(y: f64, x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        y.atan2(x)
    }
    #[cfg(not(feature = "std"))]
    {
        libm::atan2(y, x)
    }
}

/// `log10 x`.
#[inline]
pub(crate) fn log10(x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        x.log10()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::log10(x)
    }
}

/// `ln x`.
#[inline]
pub(crate) fn ln(x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        x.ln()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::log(x)
    }
}

/// `exp x`.
#[inline]
pub(crate) fn exp(x: f64) -> f64 {
    #[cfg(feature = "std")]
    {
        x.exp()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::exp(x)
    }
}

/// `|x|`.
#[inline]
pub(crate) fn abs(x: f64) -> f64 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// Wraps an angle to `(−π, π]` radians.
#[inline]
pub fn wrap_angle(angle_rad: f64) -> f64 {
    use core::f64::consts::{PI, TAU};
    let mut a = angle_rad % TAU;
    if a > PI {
        a -= TAU;
    } else if a <= -PI {
        a += TAU;
    }
    a
}

/// `P ← (P + Pᵀ)/2`: removes the asymmetry rounding leaves in a covariance.
#[inline]
pub(crate) fn symmetrize<D: Dim>(p: &mut OMatrix<f64, D, D>)
where
    DefaultAllocator: Allocator<D, D>,
{
    let n = p.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let m = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
}

/// Returns `Err(NonFinite { what })` unless every entry is finite.
#[inline]
pub(crate) fn ensure_finite<R: Dim, C: Dim>(m: &OMatrix<f64, R, C>, what: &'static str) -> Result<()>
where
    DefaultAllocator: Allocator<R, C>,
{
    if m.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EstimationError::NonFinite { what })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_maps_into_half_open_interval() {
        use core::f64::consts::PI;
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-15);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
    }
}
